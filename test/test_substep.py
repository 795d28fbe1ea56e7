"""The sub-step pipeline (``response.substep``): every impulse and kinematic sub-step's stages after
detection in one compiled call. Its two exits (the whole sub-step, or stopped before the store and
advance so that a time of impact can shorten it, then ``finish``) must give the same step bit for
bit when nothing shortens it; every solver method runs in it; islands too large for the dense
active set take the sparse one there."""
import dataclasses

import numpy as np
import pytest

import contact_sim as cs
from contact_sim.response import substep
from contact_sim.scene import default_scene_path


def _pile(seed, n=6):
    """Boxes, spheres and hulls dropped just above a plane, some onto each other."""
    rng = np.random.default_rng(seed)
    w = cs.World(materials={"m": cs.Material(restitution=0.2, friction=0.5)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    for i in range(n):
        kind = i % 3
        q = rng.normal(size=4)
        shape = (cs.Box(tuple(rng.uniform(0.1, 0.3, 3))) if kind == 0 else cs.Sphere(float(rng.uniform(0.05, 0.15)))
                 if kind == 1 else cs.Convex(rng.uniform(-0.1, 0.1, (12, 3))))
        w.add_body(f"b{i}", shape, mass=float(rng.uniform(0.5, 2.0)), material="m",
                   position=(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.2 + 0.25 * i),
                   orientation=tuple(q / np.linalg.norm(q)))
    return w


def _slider():
    """A box sliding on a plane (friction 0.2): its contacts slide, so the active set leaves its
    island unfinished and Gauss–Seidel finishes it. ``next_step``: with a few bodies ``auto`` would
    pick exact times of impact."""
    w = cs.World(settings=cs.Settings(toi="next_step"), materials={"m": cs.Material(restitution=0.0, friction=0.2)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("box", cs.Box((0.4, 0.3, 0.2)), mass=1.0, material="m", position=(0, 0, 0.1), velocity=(2.0, 0.5, 0))
    return w


def _state(w):
    return [getattr(w.s, f).copy() for f in ("pos", "quat", "vel", "omega")]


def _same_step(wa, wb):
    """What differs between two worlds after a step (state, contacts, statistics, contact cache)."""
    diff = [f for f, x, y in zip(("pos", "quat", "vel", "omega"), _state(wa), _state(wb)) if not np.array_equal(x, y)]
    for f in dataclasses.fields(wa.contacts):
        x, y = getattr(wa.contacts, f.name), getattr(wb.contacts, f.name)
        if not (x.shape == y.shape and np.array_equal(x, y)):
            diff.append("contacts." + f.name)
    if dataclasses.asdict(wa.last_solve) != dataclasses.asdict(wb.last_solve):
        diff.append("last_solve")
    ca, cb = wa.contact_cache.warm, wb.contact_cache.warm
    if (ca is None) != (cb is None) or (ca is not None and not all(np.array_equal(x, y) for x, y in zip(ca, cb))):
        diff.append("contact_cache")
    return diff


def _both_ways(make, steps, monkeypatch, dt=None):
    """Step two copies of a scene, one through the whole sub-step (with detection in the same call
    where ``run_detected`` takes it, as a step does) and one detected in Python then through the
    split exit (``run(ctx, False)`` then ``finish(ctx, t_left, 1)``: what the stepper does when no
    time of impact shortens the sub-step), comparing each step; returns the first world and, per
    step, its ``last_solve`` and the fastest approach among its contacts (m/s, 0 without)."""
    wa, wb = make(), make()
    real = substep.run

    def split(ctx, whole):
        real(ctx, False)
        if whole:
            substep.finish(ctx, ctx.t_left, 1.0)

    real_detected = substep.run_detected
    solves = []
    for i in range(steps):
        monkeypatch.setattr(substep, "run", real)
        monkeypatch.setattr(substep, "run_detected", real_detected)
        wa.step(dt)
        monkeypatch.setattr(substep, "run", split)
        monkeypatch.setattr(substep, "run_detected", lambda ctx: False)
        wb.step(dt)
        diff = _same_step(wa, wb)
        assert not diff, f"step {i}: {diff}"
        vn = wa.contacts.relative_normal_velocity
        solves.append((wa.last_solve, float(max(-vn.min(), 0.0)) if len(vn) else 0.0))
    monkeypatch.setattr(substep, "run", real)
    monkeypatch.setattr(substep, "run_detected", real_detected)
    return wa, solves


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_a_settling_pile_steps_bit_for_bit_through_both_exits(seed, monkeypatch):
    _, solves = _both_ways(lambda: _pile(seed), 400, monkeypatch, dt=0.005)
    # not vacuous: the pile falls (impacts, some bouncing) and then rests, some steps with a
    # position correction planned
    assert _bounces(solves) > 0
    assert any(s.correction_energy != 0.0 for s, _ in solves)
    assert sum(s.contacts > 0 for s, _ in solves) > 300


def _bounces(solves):
    """Steps with an impact fast enough to bounce (approach beyond 0.5 m/s)."""
    return sum(approach > 0.5 for _, approach in solves)


def test_sliding_friction_is_finished_by_gauss_seidel_in_the_sub_step(monkeypatch):
    w, solves = _both_ways(_slider, 60, monkeypatch, dt=0.005)
    assert max(s.iterations for s, _ in solves) > 1   # Gauss–Seidel sweeps
    # the box slid and slowed at the kinetic rate: μ g = 0.2 × 9.81 (the step's end velocity)
    assert 0.0 < np.linalg.norm(w.s.vel[1, :2]) < np.hypot(2.0, 0.5) - 0.2 * 9.81 * 0.005 * 30


def test_the_default_scene_steps_bit_for_bit_through_both_exits(monkeypatch):
    w0 = cs.load_scene(default_scene_path())
    _, solves = _both_ways(lambda: cs.load_scene(default_scene_path()), 900, monkeypatch, dt=w0.settings.dt)
    assert sum(s.contacts > 0 for s, _ in solves) > 800 and _bounces(solves) > 5


@pytest.mark.exact
@pytest.mark.parametrize("method", cs.settings.SOLVER_METHODS)
@pytest.mark.parametrize("toi", ["next_step", "fractional"])
def test_a_resting_box_holds_its_weight_by_every_solver_method(method, toi):
    """A box on a plane, at rest, under each ``solver_method`` and both sub-step exits: the resting
    impulse over a step is m g dt over its four corners, with no moment, no net friction and
    nothing moving: exact to round-off for the active set (``auto``, ``direct``); within the
    solver's tolerance (1e-9 N·s a contact) for the iterative methods (``gs`` keeps the four
    coupled corners for Gauss–Seidel, ``jacobi`` is mass-splitting Jacobi)."""
    w = cs.World(settings=cs.Settings(toi=toi, solver_method=method))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("box", cs.Box((0.4, 0.4, 0.2)), mass=2.0, position=(0, 0, 0.1))
    dt = 0.01
    for _ in range(3):
        w.step(dt)
    exact = method in ("auto", "direct")
    tol = 4 * w.settings.solver_tolerance   # N·s: the iterative methods' four corners
    assert len(w.contacts) == 4
    assert w.contacts.normal_impulse.sum() == pytest.approx(2.0 * 9.81 * dt, rel=1e-12 if exact else 0, abs=0 if exact else tol)
    # no torque about the centre of mass: the corners' impulses balance under it (their split
    # among the four redundant corners is not unique; the moment is)
    moment = (w.contacts.normal_impulse[:, None] * (w.contacts.point[:, :2] - w.s.pos[1, :2])).sum(axis=0)
    assert np.abs(moment).max() < (1e-15 if exact else tol * 0.2)
    # the corners' friction is redundant too (it may pull them in pairs): none in total
    assert np.abs(w.contacts.friction_impulse.sum(axis=0)).max() < (1e-15 if exact else tol)
    # nothing moves; for the iterative methods, within what ten times the tolerance on each corner
    # gives the 2 kg box (and its inertia, 0.033 kg m²) in 3 steps
    assert np.abs(w.s.vel[1]).max() < (1e-15 if exact else 3 * 10 * tol / 2.0)
    assert np.abs(w.s.omega[1]).max() < (1e-15 if exact else 3 * 10 * tol * 0.2 / 0.033)
    assert w.s.pos[1, 2] == pytest.approx(0.1, abs=1e-15 if exact else 3 * 10 * tol * dt)


@pytest.mark.parametrize("rule", cs.settings.COMBINE_RULES)
def test_mixed_materials_combine_in_the_kernel_by_each_rule(rule, monkeypatch):
    """Three materials under each combine rule (a bouncing ball on a sliding box on the ground): the
    contacts' coefficients (``prepare.coefficient_rows``, which the sub-step calls) are each rule's
    formula exactly, and the scene steps bit for bit through both exits."""
    def scene():
        w = cs.World(settings=cs.Settings(toi="next_step", combine=rule),
                     materials={"rubber": cs.Material(restitution=0.8, friction=0.9, static_friction=1.1),
                                "steel": cs.Material(restitution=0.3, friction=0.2),
                                "wood": cs.Material(restitution=0.5, friction=0.6, static_friction=0.7)})
        w.add_body("ground", cs.Plane(), kind="static", material="wood")
        w.add_body("box", cs.Box((0.6, 0.6, 0.2)), mass=2.0, position=(0, 0, 0.1), velocity=(1.0, 0, 0),
                   material="steel")
        w.add_body("ball", cs.Sphere(0.1), mass=0.5, position=(0.1, 0, 0.5), velocity=(0.5, 0, -1.0),
                   material="rubber")
        return w

    from contact_sim.response import models, prepare
    from test_response_impulse import combined as combine

    w = scene()
    w.s.pos[2, 2] = 0.3   # the ball on the box: two pairs, each of two materials
    c = w.detect()
    assert len(set(zip(c.body_a.tolist(), c.body_b.tolist()))) == 2
    e, mu_s, mu_d = prepare.coefficients(w, c, models.choose(w, 0.005))
    a, b = c.body_a, c.body_b
    assert np.array_equal(e, combine(w.restitution[a], w.restitution[b], rule))
    assert np.array_equal(mu_d, combine(w.friction[a], w.friction[b], rule))
    assert np.array_equal(mu_s, np.maximum(combine(w.static_friction[a], w.static_friction[b], rule), mu_d))

    _, solves = _both_ways(scene, 80, monkeypatch, dt=0.005)
    assert _bounces(solves) > 0


@pytest.mark.exact
def test_a_ball_bounces_by_newtons_rule_through_the_sub_step():
    """A ball falling onto a plane (e = 0.5, no friction), ``next_step``: the normal impulse is m (1 + e) |v_n| of the approach speed recorded, and the ball ends the step at
    −e v_n less the step's gravity (leaving: no resting force holds it)."""
    w = cs.World(settings=cs.Settings(toi="next_step"), materials={"m": cs.Material(restitution=0.5, friction=0.0)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("ball", cs.Sphere(0.1), mass=0.5, position=(0, 0, 0.3), velocity=(0, 0, -2.0), material="m")
    dt = 0.005
    for _ in range(200):
        w.step(dt)
        if len(w.contacts) and w.contacts.normal_impulse[0] > 0:
            break
    assert len(w.contacts) == 1
    vn = w.contacts.relative_normal_velocity[0]
    assert vn < -2.0
    assert w.contacts.normal_impulse[0] == pytest.approx(0.5 * 1.5 * -vn, rel=1e-13)
    assert w.s.vel[1, 2] == pytest.approx(-0.5 * vn - 9.81 * dt, rel=1e-13)
    assert np.abs(w.s.vel[1, :2]).max() == 0.0 and np.abs(w.s.omega[1]).max() == 0.0


def test_an_island_too_large_for_the_dense_solve_takes_the_sparse_active_set(monkeypatch):
    """A tower of 36 boxes: one island of 144 contacts, more than the dense kernel takes
    (``DIRECT_ISLAND_MAX``): the sub-step's solve gives it to the sparse active set (SciPy, from the
    kernel), which holds the tower exactly: the ground carries the whole weight, 36 m g dt a step,
    each layer the weight above it, and nothing moves."""
    def tower():
        w = cs.World(settings=cs.Settings(toi="next_step"))
        w.add_body("ground", cs.Plane(), kind="static")
        for i in range(36):
            w.add_body(f"b{i}", cs.Box((0.3, 0.3, 0.1)), mass=1.0, position=(0, 0, 0.05 + 0.1 * i))
        return w

    from contact_sim.response import direct

    calls = []
    real = direct._active_set
    monkeypatch.setattr("contact_sim.response.solver._active_set",
                        lambda *a, **k: calls.append(len(a[0].a)) or real(*a, **k))
    dt = 0.005
    w, _ = _both_ways(tower, 10, monkeypatch, dt=dt)
    assert calls and set(calls) == {144}
    assert len(w.contacts) == 144
    c = w.contacts
    for layer in range(36):   # the contacts under box `layer` carry the 36 - layer boxes on and above it
        under = (c.body_a == layer + 1) & (c.body_b == layer) | (c.body_b == layer + 1) & (c.body_a == layer)
        assert c.normal_impulse[under].sum() == pytest.approx((36 - layer) * 9.81 * dt, rel=1e-9)
    assert np.abs(w.s.vel[1:]).max() < 1e-12
    assert np.abs(w.s.pos[1:, 2] - (0.05 + 0.1 * np.arange(36))).max() < 1e-12


def test_a_kinematic_push_steps_bit_for_bit_through_both_exits(monkeypatch):
    """A kinematic paddle at 0.5 m/s, pressed 1 cm into the static ground (a contact nothing can
    move: no impulse), pushes a ball into a box standing at a wall: the ball is squeezed, and the
    push cap (``energy.push_cap_kernel``) scales the solves back."""
    from test_kinematic import squeeze_at_a_wall as paddle

    w, solves = _both_ways(paddle, 100, monkeypatch, dt=0.01)
    pairs = {frozenset((int(x), int(y))) for x, y in zip(w.contacts.body_a, w.contacts.body_b)}
    assert frozenset((0, 1)) in pairs                 # the paddle in the ground: a contact with no impulse
    assert w.s.pos[2, 0] > 0.05                       # the ball was pushed
    assert np.abs(w.s.vel[2:4]).max() < 3.0           # within the push budget of a 0.5 m/s paddle


@pytest.mark.parametrize("seed", [0, 2])
def test_hulls_and_boxes_in_a_pile_beside_rolling_balls_come_to_rest(seed):
    """The piles where a ball rolling at up to 1.6 m/s set every pair's margin to ~3 cm: a hull's
    manifold took a vertex 1.3 cm up over a support, the look-ahead dropped it, and the hull rocked
    on an edge forever (up to 1.7 rad/s after 5 s). Each pair's own margin lets them settle
    (test_response_speculative checks the margins themselves)."""
    w = _pile(seed)
    spheres = np.array([isinstance(s, cs.Sphere) for s in w.shapes])
    worst = 0.0
    for k in range(int(6.0 / w.settings.dt)):
        w.step()
        if w.time > 5.0:
            worst = max(worst, np.abs(w.s.omega[~spheres]).max())
    assert worst < 1e-6


def _one_contact(rng, static_b):
    """Random rows of one contact (``rows.Rows``' arrays, K = 1): an orthonormal (n, t1, t2), lever
    arms, inverse masses and inertias (B immovable when ``static_b``)."""
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    t1 = np.cross(n, rng.normal(size=3))
    t1 /= np.linalg.norm(t1)
    dirs = np.array([[n, t1, np.cross(n, t1)]])
    sides = []
    for static in (False, static_b):
        m = rng.uniform(0.2, 0.5) * rng.normal(size=(3, 3))
        inv_i = np.zeros((3, 3)) if static else m @ m.T + 0.1 * np.eye(3)
        ang = np.cross(rng.normal(size=3), dirs[0])[None]
        sides.append((np.zeros(1) if static else np.array([rng.uniform(0.1, 2.0)]), ang, ang @ inv_i.T))
    (ima, ang_a, iang_a), (imb, ang_b, iang_b) = sides
    return dirs, ang_a, ang_b, iang_a, iang_b, ima, imb


@pytest.mark.parametrize("seed", range(40))
def test_a_one_contact_island_is_solved_as_the_island_kernel_solves_it(seed):
    """``active_set._single`` restates ``_island`` for one contact (a kernel call costs more than its
    arithmetic): the same status, residual and impulses, bit for bit, sticking, sliding, separating,
    warm started or not, with or without friction and compliance."""
    from contact_sim.response import active_set

    rng = np.random.default_rng(seed)
    dirs, ang_a, ang_b, iang_a, iang_b, ima, imb = _one_contact(rng, static_b=seed % 3 != 0)
    a, b = np.array([1]), np.array([0 if seed % 3 else 2])
    v0 = rng.normal(size=(1, 3))
    target = np.array([min(0.0, rng.normal())])
    compliance = np.array([0.0 if seed % 4 else rng.uniform(0, 0.5)])
    mu_s = np.array([rng.uniform(0.0, 1.0)])
    mu_d = mu_s * rng.uniform(0.5, 1.0)
    warm = rng.normal(size=(1, 3))
    friction, use_warm = seed % 2 == 0, seed % 5 != 0
    answers = []
    for kernel in ("island", "single"):
        lam = np.full((1, 3), np.nan)
        A, sub, L, vecs = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((5, 3))
        S, nz, act = np.empty(3, np.int64), np.empty(3, np.int64), np.empty(1, np.bool_)
        args = (a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, v0, target, compliance, mu_s, mu_d, friction,
                warm, use_warm, 1e-10, 1e-7, 12, lam)
        if kernel == "island":
            band = np.empty((6, 4), np.int64)
            st, res = active_set._island(np.array([0]), *args, A, sub, L, vecs, S, nz, act, band)
        else:
            st, res = active_set._single(0, *args, A, L, vecs, S)
        answers.append((st, res, lam))
    (st0, res0, lam0), (st1, res1, lam1) = answers
    assert st1 == st0 and (res1 == res0 or (np.isinf(res0) and np.isinf(res1)))
    assert np.array_equal(lam1, lam0)


def test_the_step_statistics_name_what_the_step_did():
    """``World.last_solve`` is built from the step's context by field position: each field holds
    its own figure (the field order is the one the stepper writes)."""
    from contact_sim.response.models import choose

    assert [f.name for f in dataclasses.fields(cs.StepStats)] == [
        "iterations", "residual", "unconverged", "max_penetration", "contacts", "impacts", "toi", "response",
        "correction_energy", "kinematic_work", "pose_work", "rotation_drift", "kick_error_bound", "rest_work_bound"]
    w = cs.load_scene(default_scene_path())
    for _ in range(1000):   # to the first step with contacts
        w.step()
        if len(w.contacts):
            break
    st, m = w.last_solve, choose(w)
    assert st.contacts == len(w.contacts) > 0
    assert (st.toi, st.response) == (m.toi, m.response)
    assert isinstance(st.iterations, int) and isinstance(st.unconverged, bool)
    assert st.residual >= 0 and st.max_penetration >= 0 and st.kick_error_bound >= 0 and st.rest_work_bound >= 0


@pytest.mark.exact
@pytest.mark.parametrize("dropped", [False, True])
def test_the_sub_step_kernels_index_output_holds_the_kept_contacts(dropped):
    """``_substep``'s ``idx``: the places of the contacts the look-ahead kept (only when it dropped
    some); ``out[10:12]`` say whether it dropped some and how many contacts the correction pushes
    (``run`` reads them)."""
    near = np.array([True, False, True, True, False])
    pen = np.array([0, 2], np.int64)
    out = np.zeros(12)
    k = 3 if dropped else 5
    idx = substep._indices(near if dropped else near[:0], dropped, k, pen, out)
    assert idx.tolist() == ([0, 2, 3] if dropped else [])
    assert out[10:].tolist() == [float(dropped), 2.0]
    all_dropped = substep._indices(np.zeros(4, bool), True, 0, np.zeros(0, np.int64), out)
    assert all_dropped.tolist() == [] and out[10:].tolist() == [1.0, 0.0]
