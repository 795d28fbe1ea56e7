"""Issue #11, one test per violation found on main, and the settings table that keeps them away:
every case is refused with a ContactSimError naming the argument and the reason (or, where the
input is legitimate, handled), and nothing changes."""
import copy
import dataclasses

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat
from contact_sim.collision import collide_pairs
from contact_sim.settings import parse_material, parse_settings
from contact_sim.validate import Choice, build, declare

pytestmark = pytest.mark.timeout(20)

NAN = float("nan")
I = (0.0, 0.0, 0.0, 1.0)
TET = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def world():
    w = cs.World()
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 1])
    w.add_body("paddle", cs.Box([0.4, 0.4, 0.05]), kind="kinematic", position=[1, 0, 0.5])
    w.mark_initial()
    return w


def state(w):
    return [a.copy() for a in (w.s.pos, w.s.vel, w.s.quat, w.s.omega, w.s.stamp)] + [w.time]


def same(a, b):
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


# ---------------------------------------------------------------------------- hangs and crashes in Settings
def test_settings_dt_nan_is_refused_so_step_cannot_hang():
    with pytest.raises(cs.ContactSimError, match=r"^settings\.dt: must be a finite number > 0, got nan$"):
        cs.Settings(dt=NAN)
    w = world()
    with pytest.raises(cs.ContactSimError, match=r"^settings\.dt: must be a finite number > 0 and <= max_step"):
        w.settings.dt = NAN                  # a later assignment is checked too, and changes nothing
    assert w.settings.dt == 1 / 60
    w.step()
    assert w.time == 1 / 60


def test_settings_dt_zero_is_refused():
    with pytest.raises(cs.ContactSimError, match=r"^settings\.dt: must be > 0, got 0$"):
        cs.Settings(dt=0)


# ---------------------------------------------------------------------------- accepted silently on main
@pytest.mark.parametrize("make, message", [
    (lambda: cs.Settings(dt=-1), r"^settings\.dt: must be > 0, got -1$"),
    (lambda: cs.Settings(toi="sometimes"), r"^settings\.toi: must be one of auto, next_step, fractional, swept"),
    (lambda: cs.Settings(response="magic"), r"^settings\.response: must be one of auto, kinematic, penalty"),
    (lambda: cs.World(settings="x"), r"^settings: must be a Settings or a mapping of its fields, got str$"),
    (lambda: cs.World(materials={"m": 5}), r"^materials\['m'\]: must be a Material or a mapping of its fields"),
    (lambda: cs.Settings(split_beta=5), r"^settings\.split_beta: must be <= 1, got 5$"),
    (lambda: cs.Settings(solver_iterations=0), r"^settings\.solver_iterations: must be >= 1, got 0$"),
    (lambda: cs.Material(restitution=2), r"^material\.restitution: must be <= 1, got 2$"),
    (lambda: cs.Material(friction=-1), r"^material\.friction: must be >= 0, got -1$"),
    (lambda: cs.Material(restitution=NAN), r"^material\.restitution: must be a finite number >= 0 and <= 1, got nan"),
    (lambda: cs.collide(cs.Sphere(1), ((0, 0, 0), I), cs.Sphere(1), ((0, 0, 1), I), bounding_volume="bogus"),
     r"^collide: bounding_volume: must be one of auto, sphere, aabb, obb, slabs, hull; got 'bogus'$"),
    (lambda: collide_pairs([cs.Sphere(1)] * 2, [[0, 0, 0], [0, 0, 1]], [I, I], [[0, 1]], margin=NAN),
     r"^collide_pairs: margin: must be a finite number >= 0 and <= 1e\+12 m, got nan$"),
    (lambda: cs.Box([True, 1, 1]), r"^box\.size: must be 3 numbers, got \[True, 1, 1\]$"),
    (lambda: cs.TriMesh(TET, [[0.5, 1, 2]]), r"^mesh\.faces: face 0 has an index that is not a whole number"),
])
def test_once_silently_accepted_now_refused(make, message):
    with pytest.raises(cs.ContactSimError, match=message):
        make()


def test_a_material_accepted_on_main_would_have_gained_energy():
    """Material(restitution=2) took a ball from 20.5 J to 1056 J on main; now it cannot be made,
    and the world built with the refused material never exists."""
    with pytest.raises(cs.ContactSimError, match="restitution"):
        cs.World(materials={"bouncy": {"restitution": 2.0}})


# ---------------------------------------------------------------------------- finite but absurd
def test_a_speed_beyond_max_speed_is_refused_at_add_body_and_set_state():
    w = world()
    before = state(w)
    with pytest.raises(cs.BoundsError, match=r"^body 'x'\.velocity: magnitude 1e\+200 m/s is above max_speed "
                                             r"\(10000 m/s\)$"):
        w.add_body("x", cs.Sphere(0.1), velocity=[1e200, 0, 0])
    with pytest.raises(cs.BoundsError, match=r"^set_state\('ball'\)\.velocity: magnitude"):
        w.set_state("ball", velocity=[1e200, 0, 0])
    with pytest.raises(cs.BoundsError, match=r"^set_state\('ball'\)\.angular_velocity: .* max_angular_speed"):
        w.set_state("ball", angular_velocity=[0, 2e4, 0])
    assert same(state(w), before) and w.body_names == ["ground", "ball", "paddle"]
    assert np.isfinite(w.energy())


def test_a_step_beyond_max_step_is_refused():
    w = world()
    before = state(w)
    with pytest.raises(cs.BoundsError, match=r"^step\.dt: must be <= max_step \(1 s\), got 1e\+300$"):
        w.step(1e300)
    assert same(state(w), before)
    w.step(1.0)                              # the bound itself is a legal step
    assert np.all(np.isfinite(w.s.pos))


def test_a_pose_beyond_max_position_is_refused():
    w = world()
    w.set_pose("paddle", [1, 0, 0.5], I, stamp=0.0)
    before = state(w)
    with pytest.raises(cs.BoundsError, match=r"^set_pose\('paddle'\)\.position: every coordinate must be within "
                                             r"±max_position \(10000 m\), got \[1e\+300, 0\.0, 0\.0\]$"):
        w.set_pose("paddle", [1e300, 0, 0], I, stamp=0.1)
    with pytest.raises(cs.BoundsError, match="max_position"):
        w.set_state("paddle", position=[0, -2e4, 0])
    assert same(state(w), before)


def test_successive_poses_implying_a_speed_beyond_the_bounds_are_refused():
    """1 m in a nanosecond is finite in and finite out, but 1e9 m/s: refused like the speed itself."""
    w = world()
    w.set_pose("paddle", [1, 0, 0.5], I, stamp=0.0)
    before = state(w)
    with pytest.raises(cs.BoundsError, match=r"^set_pose\('paddle'\): moving since the previous pose 1e-09 s ago "
                                             r"implies 1e\+09 m/s, above max_speed \(10000 m/s\)$"):
        w.set_pose("paddle", [2, 0, 0.5], I, stamp=1e-9)
    turn = quat.from_rotvec([0.0, 0.0, 1.0])
    with pytest.raises(cs.BoundsError, match=r"implies 1e\+06 rad/s, above max_angular_speed"):
        w.set_pose("paddle", [1, 0, 0.5], turn, stamp=1e-6)
    assert same(state(w), before)
    w.set_pose("paddle", [2, 0, 0.5], I, stamp=1.0)   # 1 m/s: fine
    np.testing.assert_allclose(w.body("paddle").velocity, [1.0, 0, 0], rtol=1e-15)


def test_world_bounds_are_settings():
    """Raising a bound admits what the default refuses; lowering one refuses more."""
    w = cs.World(settings={"max_position": 1e6, "max_speed": 1e5})
    w.add_body("far", cs.Sphere(1.0), position=[5e5, 0, 0], velocity=[5e4, 0, 0])
    w.step()
    assert np.all(np.isfinite(w.s.pos)) and w.body("far").position[0] > 5e5
    small = cs.World(settings=cs.Settings(min_size=1e-9, min_mass=1e-30))
    small.add_body("dust", cs.Sphere(1e-7))
    small.step()
    assert np.all(np.isfinite(small.s.pos))
    with pytest.raises(cs.BoundsError, match=r"^gravity: magnitude 20 m/s² is above max_speed / max_step \(10 m/s²\)"):
        cs.World(gravity=[0, 0, -20], settings={"max_speed": 10.0})


# ---------------------------------------------------------------------------- wrong exception types on main
def test_an_empty_pose_batch_changes_nothing():
    w = world()
    before = state(w)
    w.set_poses([], [], [])
    w.set_poses([], np.zeros((0, 3)), np.zeros((0, 4)), stamp=1.0)
    assert same(state(w), before)


@pytest.mark.parametrize("call, message", [
    (lambda w: w.set_pose("paddle", 5.0, I), r"^set_pose\('paddle'\)\.position: must be 3 numbers, got 5\.0$"),
    (lambda w: w.set_poses(["paddle"], 5.0, [I]), r"^set_poses\.positions: must be an \(1, 3\) array, got shape \(\)$"),
    (lambda w: w.set_poses(["paddle"], [[1, 0, 0]], None), r"^set_poses\.orientations: must be an \(1, 4\) array, "
                                                           r"got None$"),
    (lambda w: w.set_pose("paddle", [1, 0, 0], None), r"^set_pose\('paddle'\)\.orientation: must be 4 numbers"),
    (lambda w: w.set_poses("paddle", [[1, 0, 0]], [I]), r"^set_poses\.names: must be a list of body names"),
])
def test_pose_arguments_of_the_wrong_type_are_contact_sim_errors(call, message):
    w = world()
    before = state(w)
    with pytest.raises(cs.ContactSimError, match=message):
        call(w)
    assert same(state(w), before)


def test_a_scene_material_that_is_not_a_name():
    scene = {"bodies": [{"name": "b", "shape": {"type": "sphere", "radius": 0.1}, "material": ["m"]}]}
    with pytest.raises(cs.SceneError, match=r"^bodies\[0\]\.material: unknown material \['m'\]"):
        cs.load_scene(scene)


def test_collide_pairs_names_its_pairs_argument():
    args = ([cs.Sphere(1)] * 2, [[0, 0, 0], [0, 0, 1]], [I, I])
    with pytest.raises(cs.ContactSimError, match=r"^collide_pairs: pairs: must be an \(M, 2\) array, got shape \(3,\)$"):
        collide_pairs(*args, [0, 1, 1])
    with pytest.raises(cs.ContactSimError, match=r"^collide_pairs: pairs\[1\]: indices must be in \[0, 1\]"):
        collide_pairs(*args, [[0, 1], [0, 2]])
    with pytest.raises(cs.ContactSimError, match=r"^collide_pairs: pairs\[0\]: indices must be whole numbers"):
        collide_pairs(*args, [[0.5, 1]])
    c, _ = collide_pairs(*args, [[0, 1]])
    assert len(c) == 1 and c.depth[0] == pytest.approx(1.0)


# ---------------------------------------------------------------------------- degenerate shapes
def test_a_convex_hull_that_collapses_is_refused_when_built():
    with pytest.raises(cs.ContactSimError, match=r"^convex\.points: their convex hull is degenerate \(1 vertices, "
                                                 r"volume 0\); the points span only 1e-09 m"):
        cs.Convex(TET * 1e-9)


def test_a_sphere_below_the_length_tolerance_is_refused_where_it_would_be_simulated():
    w = world()
    before = state(w)
    tiny = cs.Sphere(1e-100)                 # a sphere as such; the world's min_size decides
    with pytest.raises(cs.BoundsError, match=r"^body 'x'\.shape\.radius \(thickness\): must be >= min_size "
                                             r"\(1e-06 m\), got 2e-100$"):
        w.add_body("x", tiny)
    with pytest.raises(cs.BoundsError, match=r"^collide: shape_a\.radius \(thickness\): must be >= min_size"):
        cs.collide(tiny, ((0, 0, 0), I), cs.Plane(), ((0, 0, 0), I), settings=cs.Settings())
    assert same(state(w), before) and len(w) == 3
    # geometry alone has no length tolerance: without a world's settings the query is exact
    c = cs.collide(tiny, ((0, 0, 0), I), cs.Plane(), ((0, 0, 0), I))
    assert len(c) == 1 and c.depth[0] == 1e-100


def test_a_body_too_light_for_the_world_is_refused_naming_its_density():
    w = world()
    with pytest.raises(cs.BoundsError, match=r"^body 'x'\.density \(a mass of 4\.19e-10 kg at 1e-07 kg/m³\): "
                                             r"must be >= min_mass \(1e-09 kg\)"):
        w.add_body("x", cs.Sphere(0.1), density=1e-7)
    with pytest.raises(cs.BoundsError, match=r"^body 'x'\.mass: must be <= max_mass \(1e\+09 kg\), got 1e\+300$"):
        w.add_body("x", cs.Sphere(0.1), mass=1e300)


# ---------------------------------------------------------------------------- the table behind the rules
def test_code_and_scene_files_get_the_same_rule_and_message():
    """Settings(...) and a scene's settings: are checked by the same declaration, word for word."""
    bad = {"dt": -1, "toi": "never", "solver_iterations": 2.5, "split_beta": NAN, "friction": "yes",
           "penalty": {"stiffness": 0}, "max_step": 1e300, "contact_margin": 2e4}
    for key, value in bad.items():
        with pytest.raises(cs.ContactSimError) as code:
            cs.Settings(**{key: value})
        with pytest.raises(cs.ContactSimError) as scene:
            parse_settings({key: value})
        assert str(code.value) == str(scene.value), key
    with pytest.raises(cs.ContactSimError) as code:
        cs.Material(friction=0.5, static_friction=0.2)
    with pytest.raises(cs.ContactSimError) as scene:
        parse_material({"friction": 0.5, "static_friction": 0.2}, "materials.rubber")
    assert str(code.value) == "material.static_friction: must be >= friction (0.5), got 0.2"
    assert str(scene.value) == "materials.rubber.static_friction: must be >= friction (0.5), got 0.2"


def test_assignments_are_checked_and_a_refused_one_changes_nothing():
    s = cs.Settings()
    before = s.as_dict()
    with pytest.raises(cs.ContactSimError, match=r"^settings\.max_step: 0\.001 would leave settings\.dt: must be "
                                                 r"<= max_step \(0\.001 s\), got 0\.0166"):
        s.max_step = 0.001                   # dt (1/60 s) would be beyond it
    with pytest.raises(cs.ContactSimError, match=r"^settings\.dtt: unknown field \(known: dt, toi,"):
        s.dtt = 0.01                         # a typo is not a new attribute
    with pytest.raises(cs.ContactSimError, match=r"^settings\.penalty\.damping: must be >= 0, got -1$"):
        s.penalty.damping = -1
    with pytest.raises(cs.ContactSimError, match=r"^settings\.penalty: must be a Penalty or a mapping"):
        s.penalty = 5
    assert s.as_dict() == before
    s.max_step = 0.5
    s.dt = 0.25
    s.penalty = {"stiffness": 10.0}
    assert (s.dt, s.max_step, s.penalty.stiffness, s.penalty.damping) == (0.25, 0.5, 10.0, 100.0)
    w = world()
    with pytest.raises(cs.ContactSimError, match=r"^settings: must be a Settings"):
        w.settings = None
    with pytest.raises(cs.BoundsError, match=r"^gravity: magnitude"):
        w.gravity = [0, 0, -1e5]
    assert w.settings.dt == 1 / 60 and np.array_equal(w.gravity, [0, 0, -9.81])


def test_a_new_setting_is_one_declaration():
    """What another engineer adds: one line, and both code and scenes check it."""
    @dataclasses.dataclass(eq=True)
    class MoreSettings(cs.Settings):
        solver: str = declare("pgs", Choice(("pgs", "exact")), "the resting-contact solver")

    assert MoreSettings().solver == "pgs" and MoreSettings(solver="exact").solver == "exact"
    with pytest.raises(cs.ContactSimError, match=r"^settings\.solver: must be one of pgs, exact; got 'lu'$"):
        MoreSettings(solver="lu")
    with pytest.raises(cs.ContactSimError, match=r"^settings\.solver: must be one of pgs, exact; got 3$"):
        build(MoreSettings, {"solver": 3}, "settings")
    s = MoreSettings()
    with pytest.raises(cs.ContactSimError, match=r"^settings\.solver: must be one of"):
        s.solver = None
    w = cs.World(settings=s)
    assert w.settings.solver == "pgs" and build(MoreSettings, {"dt": 0.01}, "settings").dt == 0.01


def test_settings_copy_and_compare_like_values():
    s = cs.Settings(dt=0.01)
    c = copy.deepcopy(s)
    assert c == s and c is not s and c.penalty is not s.penalty
    c.toi = "swept"
    assert s.toi == "auto" and c != s
    with pytest.raises(cs.ContactSimError, match="settings.dt"):
        c.dt = 0


# ---------------------------------------------------------------------------- a step is all or nothing
def test_a_step_that_fails_inside_the_engine_leaves_the_world_as_it_was(monkeypatch):
    from test_input_contract import snapshot

    from contact_sim import stepper
    w = world()
    w.step()
    before = snapshot(vars(w))
    real = stepper.step

    def half_a_step_then_raise(world, dt, m=None):
        real(world, dt, m)               # moves bodies, replaces contacts and caches, advances time
        world.s.pos[1, 2] += 1.0         # and edits the state arrays in place
        raise RuntimeError("engine bug")

    monkeypatch.setattr(stepper, "step", half_a_step_then_raise)
    with pytest.raises(RuntimeError, match="engine bug"):
        w.step()
    assert snapshot(vars(w)) == before

    def nan_result(world, dt, m=None):
        real(world, dt, m)
        world.s.vel[2] = np.nan          # a solver failure that raises nothing

    monkeypatch.setattr(stepper, "step", nan_result)
    with pytest.raises(cs.EngineError, match=r"^step: the state of 1 body \('paddle'\) would have become non-finite"
                                             r".* as it was before"):
        w.step()
    assert snapshot(vars(w)) == before
    monkeypatch.setattr(stepper, "step", real)
    w.step()
    assert w.time == pytest.approx(2 / 60, abs=1e-15) and np.all(np.isfinite(w.s.pos))
