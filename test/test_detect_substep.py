"""Detection and the whole sub-step in one compiled call (``substep.run_detected``): where the
broad phase's pair cache holds, the look-ahead, broad phase, bounding volumes, narrow phase and the
sub-step's stages run as one call. It must leave exactly what detection in Python followed by
``substep.run`` leaves (state, contacts, statistics, contact cache, time), and decline, with the
world unchanged, what it does not cover."""
import numpy as np
import pytest
import trimesh

import contact_sim as cs
from contact_sim.response import substep
from contact_sim.response.context import StepContext
from contact_sim.jit import COMPILED
from contact_sim.response import models

from test_flight import _tumbling, step_diff
from test_substep import _pile


def _resting(speculative=True, bounding_volume="auto"):
    """Spheres and boxes on a plane, a row of three boxes touching side by side, one ball rolling
    into them, and a disabled pair among them."""
    w = cs.World(settings=cs.Settings(toi="next_step", dt=0.01, speculative=speculative,
                                      bounding_volume=bounding_volume),
                 materials={"m": cs.Material(restitution=0.1, friction=0.5)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    for i in range(3):
        w.add_body(f"box{i}", cs.Box((0.2, 0.2, 0.2)), mass=1.0, material="m", position=(0.2 * i, 0, 0.1))
    for i in range(3):
        w.add_body(f"ball{i}", cs.Sphere(0.1), mass=0.5, material="m", position=(0.2 * i, 1.0, 0.1))
    w.add_body("roller", cs.Sphere(0.1), mass=2.0, material="m", position=(-1.0, 0, 0.1), velocity=(2.0, 0, 0))
    w.disabled_pairs = [("ball0", "ball1")]
    return w


def _on_a_mesh():
    """A box and a hull dropped onto a static triangle-mesh step (its tree in the narrow phase)."""
    w = cs.World(settings=cs.Settings(toi="next_step", dt=0.005))
    step = trimesh.creation.box((1.0, 1.0, 0.2))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("step", cs.TriMesh(step.vertices, step.faces), kind="static", position=(0, 0, 0.1))
    w.add_body("box", cs.Box((0.2, 0.15, 0.1)), mass=1.0, position=(0.1, 0, 0.35), angular_velocity=(1.0, 2.0, 0))
    rng = np.random.default_rng(3)
    w.add_body("hull", cs.Convex(rng.uniform(-0.08, 0.08, (12, 3))), mass=0.5, position=(-0.2, 0.1, 0.4))
    return w


def _squeeze():
    """Two kinematic jaws with a stiffness closing on a cube on a plane: contacts with a kinematic
    body are compliant, so the first sub-step's pose work needs the contacts before the solve."""
    w = cs.World(settings=cs.Settings(toi="next_step", dt=0.005, kinematic_stiffness=2e4))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("cube", cs.Box((0.1, 0.1, 0.1)), mass=0.2, position=(0, 0, 0.05))
    w.add_body("left", cs.Box((0.02, 0.2, 0.2)), kind="kinematic", position=(-0.06, 0, 0.1), velocity=(0.05, 0, 0))
    w.add_body("right", cs.Box((0.02, 0.2, 0.2)), kind="kinematic", position=(0.06, 0, 0.1), velocity=(-0.05, 0, 0))
    return w


def _both_ways(make, steps, monkeypatch):
    """Step a scene as a step does and a copy with detection always in Python, comparing every
    step; returns the first world and how many of its sub-steps ``run_detected`` took."""
    wa, wb = make(), make()
    real = substep.run_detected
    taken = 0
    for i in range(steps):
        taken += _calls(wa, real, monkeypatch)
        monkeypatch.setattr(substep, "run_detected", lambda ctx: False)
        wb.step()
        diff = step_diff(wa, wb)
        assert not diff, f"step {i}: {diff}"
    monkeypatch.setattr(substep, "run_detected", real)
    return wa, taken


@pytest.mark.exact
@pytest.mark.parametrize("speculative", [True, False])
def test_resting_and_rolling_bodies_step_bit_for_bit_with_detection_in_the_call(speculative, monkeypatch):
    w, taken = _both_ways(lambda: _resting(speculative), 150, monkeypatch)
    # not vacuous: all but the steps that built or rebuilt the pair cache, with contacts
    assert 100 < taken < 150
    assert w.last_solve.contacts >= 5 and w.s.pos[-1, 0] > -0.9   # the roller rolled


@pytest.mark.exact
@pytest.mark.parametrize("bounding_volume", ["sphere", "obb"])
def test_each_compiled_bounding_volume_steps_bit_for_bit(bounding_volume, monkeypatch):
    _, taken = _both_ways(lambda: _resting(bounding_volume=bounding_volume), 60, monkeypatch)
    assert taken > 30


@pytest.mark.exact
def test_a_falling_pile_with_hulls_steps_bit_for_bit(monkeypatch):
    def make():
        w = _pile(1)
        w.settings.toi = "next_step"
        return w

    w, taken = _both_ways(make, 200, monkeypatch)
    assert taken > 100 and w.last_solve.contacts > 0


@pytest.mark.exact
def test_tumbling_bodies_and_a_kinematic_paddle_step_bit_for_bit(monkeypatch):
    _, taken = _both_ways(_tumbling, 150, monkeypatch)
    assert taken > 20   # the landing and the resting after it (the flight step takes the rest)


@pytest.mark.exact
def test_bodies_on_a_triangle_mesh_step_bit_for_bit(monkeypatch):
    w, taken = _both_ways(_on_a_mesh, 120, monkeypatch)
    assert taken > 60 and w.last_solve.contacts > 0


@pytest.mark.exact
def test_jaws_posed_every_other_step_squeeze_a_cube_bit_for_bit(monkeypatch):
    """Compliant contacts with kinematic jaws: a step after a pose computes the poses' work on the
    springs from the contacts first (in Python); a step without one takes the call, its pose work
    exactly 0."""
    def make():
        w = _squeeze()
        w.step()
        return w

    wa, wb = make(), make()
    real = substep.run_detected
    taken, work = 0, []
    for i in range(60):
        for w in (wa, wb):
            if i % 2 == 0:   # the jaws posed where they are carried, 0.2 mm further in
                for name, side in (("left", 1.0), ("right", -1.0)):
                    b = w.index(name)
                    w.set_pose(name, w.s.pos[b] + (side * 2e-4, 0, 0), w.s.quat[b], stamp=w.time)
        taken += _calls(wa, real, monkeypatch)
        monkeypatch.setattr(substep, "run_detected", lambda ctx: False)
        wb.step()
        work.append(wa.last_solve.pose_work)
        diff = step_diff(wa, wb)
        assert not diff, f"step {i}: {diff}"
    monkeypatch.setattr(substep, "run_detected", real)
    assert 25 <= taken <= 30   # the steps without a pose, but those that rebuilt the pair cache
    assert any(x != 0.0 for x in work[0::2]) and all(x == 0.0 for x in work[1::2])
    assert wa.last_solve.contacts >= 2


def _calls(w, real, monkeypatch):
    """Step ``w``, returning how many sub-steps ``run_detected`` took."""
    taken = 0

    def counted(ctx):
        nonlocal taken
        done = real(ctx)
        taken += done
        return done

    monkeypatch.setattr(substep, "run_detected", counted)
    w.step()
    return taken


def _context(w):
    """The context of ``w``'s next step, as ``_impulse_step`` starts it."""
    dt = w.settings.dt
    return StepContext.start(w, dt, models.choose(w, dt))


@pytest.mark.exact
@pytest.mark.parametrize("what", ["aabb", "swept", "pose work", "stale", "no cache"])
def test_it_declines_what_detection_must_do_in_python_and_leaves_the_world_unchanged(what):
    """A bounding volume filtered in Python, a sweep's hit to mark, the first sub-step's pose work
    on compliant contacts with a kinematic body, a body out of its fat box, a pair cache not built."""
    w = _squeeze() if what == "pose work" else _resting(bounding_volume="aabb" if what == "aabb" else "auto")
    if what != "no cache":
        for _ in range(3):
            w.step()
    if what == "stale":   # far out of its fat box
        w.set_state("roller", position=(5.0, 0, 0.1))
    if what == "pose work":   # a jaw posed 1 mm further in since the last step
        w.set_pose("left", w.s.pos[2] + (0.001, 0, 0), (0, 0, 0, 1), stamp=w.time)
    ctx = _context(w)
    if what == "swept":
        ctx.swept_pair = (0, 1)
    before, detection = w.snapshot(), w.last_detection
    assert substep.run_detected(ctx) is False
    after = w.snapshot()
    for f in ("pos", "vel", "quat", "omega", "stepped"):
        assert np.array_equal(getattr(before.state, f), getattr(after.state, f))
    assert w.last_detection is detection and ctx.contacts is None and ctx.first
    # and where it does not decline, it takes the sub-step (the same world, the pair cache fresh)
    if what in ("stale", "no cache"):
        w.step()
        assert substep.run_detected(_context(w)) is True


@pytest.mark.exact
def test_the_step_detection_statistics_say_the_call_timed_detection_and_stages_together():
    w = _resting()
    for _ in range(5):
        w.step()
    d = w.last_detection
    assert set(d.seconds) == {"total"} and d.seconds["total"] > 0
    assert d.candidate_pairs >= d.colliding_pairs > 0 and d.contacts >= d.colliding_pairs
    assert d.edge_face_hits is None   # a step's detection takes no edge–face census


@pytest.mark.exact
@pytest.mark.parametrize("make", [_resting, _on_a_mesh, _squeeze, lambda: _pile(0)])
def test_the_call_takes_the_same_array_layouts_in_every_world(make):
    """The per-body columns the call reads from the shape table are C-ordered copies in every world
    (as column views their layout followed the table's width and row count, and each new layout
    cost the call a compile of about two minutes: a test with a 20 s budget timed out on one)."""
    from contact_sim.collision import _bodies_of

    w = make()
    w.step()
    b = _bodies_of(w)
    for name in ("aabb_c", "aabb_h", "plane_n", "plane_d", "finite", "planes", "shape_of", "rank"):
        assert getattr(b, name).flags.c_contiguous, name


@pytest.mark.exact
def test_the_step_model_is_built_once_and_rebuilt_for_what_the_scene_changes(monkeypatch):
    """``StepModel`` (what the scene fixes, one compiled argument) is the same object from step to
    step while nothing changes, and a new one after each change of what it holds (a setting, gravity,
    the contact margin, friction off); the disabled pairs are the call's own argument, not the
    model's. The steps after each change still match detection in Python bit for bit, so the call
    read the new values."""
    wa, wb = _resting(), _resting()
    real = substep.run_detected
    changes = {10: lambda w: setattr(w.settings, "solver_method", "gs"),
               20: lambda w: setattr(w, "gravity", (0.5, 0.0, -3.0)),
               30: lambda w: setattr(w, "disabled_pairs", [*w.disabled_pairs, ("box0", "box1")]),
               40: lambda w: setattr(w.settings, "contact_margin", 3e-3),
               50: lambda w: setattr(w.settings, "friction", False)}
    seen = {}   # step -> the StepModel the call read
    for i in range(60):
        if i in changes:
            changes[i](wa)
            changes[i](wb)
        if _calls(wa, real, monkeypatch):
            seen[i] = wa._derived["step_model"][-1]
        monkeypatch.setattr(substep, "run_detected", lambda ctx: False)
        wb.step()
        diff = step_diff(wa, wb)
        assert not diff, f"step {i}: {diff}"
    monkeypatch.setattr(substep, "run_detected", real)
    bounds = [0, *changes, 60]
    spans = [[m for i, m in seen.items() if lo <= i < hi] for lo, hi in zip(bounds, bounds[1:])]
    assert all(len(span) >= 5 for span in spans)   # the call took most steps of every span
    assert all(m is span[0] for span in spans for m in span)   # one model a span
    firsts = [span[0] for span in spans]
    rebuilt = [firsts[k] is not firsts[k - 1] for k in range(1, len(firsts))]
    assert rebuilt == [step != 30 for step in changes]   # a new one after each change but the pairs'


@pytest.mark.exact
@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copied_world_makes_its_own_step_model_and_steps_as_the_original(how, monkeypatch):
    """A world's copy does not carry the original's compiled ``StepModel`` (made before the copy's
    gravity is read-only again, it would be another type to numba): its first step makes one from
    its own arrays, takes the one-call sub-step and stays bit-identical to the original."""
    import copy
    import pickle

    w = _resting()
    for _ in range(5):
        w.step()
    twin = copy.deepcopy(w) if how == "deepcopy" else pickle.loads(pickle.dumps(w))
    # compiled, the copy holds None in its place; without numba the record is a named tuple, copied
    assert (twin._derived["step_model"][-1] is None) == COMPILED
    real = substep.run_detected
    versions = len(getattr(substep._detect_substep, "signatures", ()))
    taken = 0
    for i in range(20):
        took = _calls(w, real, monkeypatch)
        assert _calls(twin, real, monkeypatch) == took, f"step {i}"
        taken += took
        diff = step_diff(w, twin)
        assert not diff, f"step {i}: {diff}"
    assert taken >= 15
    assert len(getattr(substep._detect_substep, "signatures", ())) == versions   # no second compile
    model = twin._derived["step_model"][-1]
    assert model is not None and model is not w._derived["step_model"][-1]
