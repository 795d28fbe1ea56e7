"""Editing a world at run time: removing and adding bodies (all or nothing), setting several
bodies' states at once, and kinematic bodies driven by velocity or by poses."""
import copy
import dataclasses

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import world as world_mod
from contact_sim.scene import add_scene_bodies

PILE = {
    "gravity": [0, 0, -9.81],
    "settings": {"dt": 0.01},
    "materials": {"rubber": {"restitution": 0.5, "friction": 0.4}},
    "bodies": [
        {"name": "ground", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0.0}},
        {"name": "far", "kind": "dynamic", "shape": {"type": "sphere", "radius": 0.2}, "mass": 3.0,
         "position": [40.0, 0, 0.2]},
        {"name": "box", "kind": "dynamic", "shape": {"type": "box", "size": [0.4, 0.4, 0.4]}, "mass": 2.0,
         "position": [0, 0, 0.25], "material": "rubber"},
        {"name": "paddle", "kind": "kinematic", "shape": {"type": "box", "size": [0.5, 0.5, 0.05]},
         "position": [2.0, 0, 0.5]},
        {"name": "hull", "kind": "dynamic", "shape": {"type": "convex", "points": [
            [0, 0, 0], [0.3, 0, 0], [0, 0.3, 0], [0, 0, 0.3], [0.3, 0.3, 0.3]]}, "density": 500.0,
         "position": [0.05, 0.05, 0.6], "angular_velocity": [0.3, -0.2, 1.0]},
        {"name": "ball", "kind": "dynamic", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0,
         "position": [1.0, 0, 0.3], "velocity": [0.5, 0, 0]},
    ],
}


def scene(without=()):
    d = copy.deepcopy(PILE)
    d["bodies"] = [b for b in d["bodies"] if b["name"] not in without]
    return cs.load_scene(d)


def state_of(w):
    return (w.body_names, w.s.pos.copy(), w.s.quat.copy(), w.s.vel.copy(), w.s.omega.copy())


def assert_same_world(a, b):
    sa, sb = state_of(a), state_of(b)
    assert sa[0] == sb[0]
    for x, y in zip(sa[1:], sb[1:]):
        np.testing.assert_array_equal(x, y)


def test_every_per_body_array_is_listed_for_removal():
    """A per-body array added to World or its state later must be removed with its body too."""
    w = scene()
    n = len(w)
    rows = {k for k, v in vars(w).items() if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n}
    assert rows <= set(world_mod.BODY_ARRAYS), rows - set(world_mod.BODY_ARRAYS)
    lists = {k for k, v in vars(w).items() if isinstance(v, list) and len(v) == n}
    assert lists <= set(world_mod.BODY_LISTS), lists - set(world_mod.BODY_LISTS)
    state = {k for k, v in vars(w.s).items() if isinstance(v, np.ndarray)}
    assert state == set(w.s.NAMES)


def test_removal_gives_the_world_built_without_those_bodies():
    w = scene()
    w.step(0.01)                  # caches and warm starts exist
    w.reset()
    w.remove_bodies(["far", "paddle"])
    ref = scene(without=("far", "paddle"))
    assert w.body_names == ["ground", "box", "hull", "ball"]
    assert w.index("ball") == 3
    for _ in range(15):
        w.step(0.01)
        ref.step(0.01)
    assert_same_world(w, ref)
    np.testing.assert_array_equal(w.contacts.body_a, ref.contacts.body_a)
    w.reset()                    # the initial state shrank with the bodies
    assert_same_world(w, scene(without=("far", "paddle")))


def test_removal_mid_run_keeps_the_others_and_remaps_contacts_and_warm_starts():
    w = scene(without=("hull",))
    for _ in range(40):
        w.step(0.01)

    def pairs(a, b, names):
        return sorted((names[i], names[j]) for i, j in zip(a.tolist(), b.tolist()))

    names = w.body_names
    contacts = pairs(w.contacts.body_a, w.contacts.body_b, names)
    warm = pairs(w.contact_cache.warm[0], w.contact_cache.warm[1], names)
    assert ("box", "ground") in contacts or ("ground", "box") in contacts
    box = w.body("box")
    w.remove_bodies("far")       # resting on the ground, before the others in index order
    names = w.body_names
    assert ("far", "ground") in contacts or ("ground", "far") in contacts
    assert pairs(w.contacts.body_a, w.contacts.body_b, names) == [p for p in contacts if "far" not in p]
    assert pairs(w.contact_cache.warm[0], w.contact_cache.warm[1], names) == [p for p in warm if "far" not in p]
    w.step(0.01)                 # the resting box, warm-started, stays at rest
    np.testing.assert_allclose(w.body("box").position, box.position, atol=1e-6)
    assert np.abs(w.body("box").velocity).max() < 1e-3


def test_removal_refused_as_a_whole():
    w = scene()
    before = state_of(w)
    with pytest.raises(cs.ContactSimError, match="unknown body 'nobody'"):
        w.remove_bodies(["ball", "nobody"])
    with pytest.raises(cs.ContactSimError, match="named twice"):
        w.remove_bodies(["ball", "ball"])
    assert_same_world(w, scene())
    assert state_of(w)[0] == before[0]
    w.remove_bodies([])
    assert len(w) == len(PILE["bodies"])


def test_add_bodies_is_all_or_nothing_and_reset_returns_them_to_where_they_were_added():
    w = scene()
    for _ in range(5):
        w.step(0.01)
    arrays = {k: getattr(w, k) for k in world_mod.BODY_ARRAYS}
    bad = [{"name": "b1", "shape": {"type": "sphere", "radius": 0.1}, "position": [3, 0, 1]},
           {"name": "b2", "shape": {"type": "sphere", "radius": 0.1}, "mass": -1}]
    with pytest.raises(cs.SceneError, match=r"spawn\[1\]\.mass"):
        add_scene_bodies(w, bad, path="spawn")
    with pytest.raises(cs.SceneError, match=r"spawn\[1\]\.name: duplicate body name 'b1'"):
        add_scene_bodies(w, [bad[0], dict(bad[0])], path="spawn")
    with pytest.raises(cs.SceneError, match=r"spawn\[0\]\.shape\.radius"):
        add_scene_bodies(w, [{"name": "x", "shape": {"type": "sphere"}}], path="spawn")
    with pytest.raises(cs.SceneError, match="must be a list"):
        add_scene_bodies(w, {"name": "x"}, path="spawn")
    assert len(w) == len(PILE["bodies"]) and "b1" not in w.body_names
    for k, v in arrays.items():
        assert getattr(w, k) is v, k       # the very same arrays: the world's caches stay valid
    idx = add_scene_bodies(w, [bad[0], {"name": "b3", "kind": "kinematic", "shape": {"type": "box", "size": [1, 1, 1]},
                                        "position": [6, 0, 2]}])
    assert idx == [6, 7] and w.body_names[-2:] == ["b1", "b3"]
    for _ in range(10):
        w.step(0.01)
    assert w.body("b1").position[2] < 1.0  # it falls
    w.reset()
    np.testing.assert_array_equal(w.body("b1").position, [3, 0, 1])
    assert w.time == 0.0


def test_add_bodies_plain_api_refuses_bad_items():
    w = cs.World()
    with pytest.raises(cs.ContactSimError, match=r"add_bodies\[1\]"):
        w.add_bodies([{"name": "a", "shape": cs.Sphere(0.1)}, {"name": "b"}])
    with pytest.raises(cs.ContactSimError, match=r"add_bodies\[0\].*unexpected keyword"):
        w.add_bodies([{"name": "a", "shape": cs.Sphere(0.1), "colour": "red"}])
    assert len(w) == 0
    assert w.add_bodies([{"name": "a", "shape": cs.Sphere(0.1), "position": [0, 0, 1]}]) == [0]


def test_set_states_is_atomic_and_names_the_bad_body():
    w = scene()
    before = state_of(w)
    cases = [
        (dict(names=["ball", "ground"], velocities=[[1, 0, 0], [0, 0, 0]]), "'ground' is static"),
        (dict(names=["ball", "ghost"]), "unknown body 'ghost'"),
        (dict(names=["ball", "box"], positions=[[0, 0, 1], [0, np.nan, 0]]), r"set_states\('box'\)\.position"),
        (dict(names=["ball", "box"], orientations=[[0, 0, 0, 1], [0, 0, 0, 2]]), r"'box'\)\.orientation"),
        (dict(names=["ball", "box"], velocities=[[1, 0, 0]]), "1 rows for 2 bodies"),
        (dict(names=["ball", "ball"]), "named twice"),
    ]
    for kwargs, message in cases:
        with pytest.raises(cs.ContactSimError, match=message):
            w.set_states(**kwargs)
        for x, y in zip(before[1:], state_of(w)[1:]):
            np.testing.assert_array_equal(x, y)
    w.set_states(["ball", "paddle"], positions=[[0, 1, 2], [0, 2, 3]], velocities=[[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(w.body("ball").position, [0, 1, 2])
    np.testing.assert_array_equal(w.body("paddle").velocity, [4, 5, 6])
    np.testing.assert_array_equal(w.body("ball").orientation, [0, 0, 0, 1])   # not given: unchanged


def test_kinematic_body_driven_by_velocity_until_the_next_pose():
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("paddle", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    w.set_pose("paddle", [0, 0, 0], [0, 0, 0, 1], stamp=0.0)
    w.set_pose("paddle", [0.01, 0, 0], [0, 0, 0, 1], stamp=0.01)       # 1 m/s from poses
    w.set_states(["paddle"], velocities=[[0, 2.0, 0]], angular_velocities=[[0, 0, 1.0]])
    for _ in range(10):
        w.step(0.01)
    b = w.body("paddle")
    np.testing.assert_allclose(b.position, [0.01, 0.2, 0], atol=1e-12)
    np.testing.assert_array_equal(b.velocity, [0, 2.0, 0])
    np.testing.assert_allclose(b.angular_velocity, [0, 0, 1.0])
    # the next pose places it without a finite difference across the velocity-driven stretch
    w.set_pose("paddle", [1.0, 0, 0], [0, 0, 0, 1], stamp=0.5)
    np.testing.assert_array_equal(w.body("paddle").velocity, [0, 2.0, 0])
    w.set_pose("paddle", [1.01, 0, 0], [0, 0, 0, 1], stamp=0.51)
    np.testing.assert_allclose(w.body("paddle").velocity, [1.0, 0, 0], atol=1e-9)


def test_steady_poses_between_steps_give_a_steady_velocity():
    """Poses every step: the velocity is the difference of successive *poses*, not of where the
    body had drifted since (which gave 1, 0, 1, 0 ... m/s for a paddle at 1 m/s)."""
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("paddle", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    for k in range(10):
        w.set_pose("paddle", [0.01 * k, 0, 0], [0, 0, 0, 1], stamp=0.01 * k)
        if k:
            np.testing.assert_allclose(w.body("paddle").velocity, [1.0, 0, 0], atol=1e-9)
        w.step(0.01)


def test_restart_pose_history():
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("paddle", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    w.set_pose("paddle", [0, 0, 0], [0, 0, 0, 1], stamp=100.0)
    w.restart_pose_history(["paddle"])
    w.set_pose("paddle", [0.5, 0, 0], [0, 0, 0, 1], stamp=3.0)         # earlier stamp: a new history
    np.testing.assert_array_equal(w.body("paddle").velocity, [0, 0, 0])
    w.set_pose("paddle", [0.6, 0, 0], [0, 0, 0, 1], stamp=3.1)
    np.testing.assert_allclose(w.body("paddle").velocity, [1.0, 0, 0], atol=1e-9)
    with pytest.raises(cs.ContactSimError, match="unknown body"):
        w.restart_pose_history(["nobody"])


def test_scenes_dir_search_path(tmp_path):
    (tmp_path / "mine.yaml").write_text("bodies: []\n")
    assert cs.resolve_scene("mine", search=[str(tmp_path)]) == str(tmp_path / "mine.yaml")
    assert cs.list_scenes(search=[str(tmp_path)]) == ["mine"]
    with pytest.raises(cs.ContactSimError, match="no shipped scene"):
        cs.resolve_scene("default", search=[str(tmp_path)])
    assert cs.resolve_scene("default").endswith("default.yaml")   # the source tree's


def test_gravity_is_assigned_not_edited_in_place():
    # the step reads |g| and the per-body gravity rows from caches kept for the assigned array:
    # writing into it is refused, assigning a new one (checked) takes effect in the next step
    w = cs.World(gravity=(0, 0, -9.81))
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 10.0])
    with pytest.raises(ValueError):
        w.gravity[2] = -1.0
    assert w.gravity_norm() == 9.81 and np.array_equal(w.body_masks().gravity[0], [0, 0, -9.81])
    w.gravity = (0, 0, -1.62)
    assert w.gravity_norm() == 1.62 and np.array_equal(w.body_masks().gravity[0], [0, 0, -1.62])
    w.step(0.1)
    assert w.body("ball").velocity[2] == pytest.approx(-0.162, rel=1e-12)


# ---------------------------------------------------------------- snapshot / restore
def _contact_state(w):
    warm = w.contact_cache.warm
    return (w.time, w.s.pos.copy(), w.s.vel.copy(), w.s.quat.copy(), w.s.omega.copy(),
            None if warm is None else tuple(x.copy() for x in warm), w.contact_cache.preflight_dt)


def _assert_same(x, y):
    assert len(x) == len(y)
    for u, v in zip(x, y):
        if isinstance(u, tuple):
            _assert_same(u, v)
        elif isinstance(u, np.ndarray):
            np.testing.assert_array_equal(u, v)
        else:
            assert u == v


def test_restore_returns_the_state_a_step_changes_and_the_steps_after_repeat_bit_for_bit():
    """``snapshot`` holds the motion, time, contact cache (warm starts) and the last step's outputs:
    after ``restore`` the same steps give the same states and warm starts, bit for bit."""
    w = scene()
    for _ in range(30):
        w.step()
    assert w.contact_cache.warm is not None and len(w.contact_cache.warm[0])   # warm starts to restore
    snap = w.snapshot()
    before, contacts, solve = _contact_state(w), w.contacts, w.last_solve
    run = []
    for _ in range(20):
        w.step()
        run.append(_contact_state(w))
    w.restore(snap)
    _assert_same(_contact_state(w), before)
    assert w.contacts is contacts and w.last_solve is solve
    for k in range(20):
        w.step()
        _assert_same(_contact_state(w), run[k])
    w.restore(snap)                          # a snapshot restores as often as asked
    _assert_same(_contact_state(w), before)


def test_restore_puts_back_the_poses_given_and_the_robots_joint_record(tmp_path):
    from robot_arm import arm_urdf, write_gripper_mesh

    w = cs.World()
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_urdf(arm_urdf(write_gripper_mesh(tmp_path / "grip.stl")), prefix="arm_")
    w.add_body("paddle", cs.Box([0.1] * 3), kind="kinematic", position=[1, 0, 0.5])
    w.set_joint_positions(["arm_shoulder"], [0.1], stamp=0.01)
    w.set_pose("paddle", [1, 0, 0.6], [0, 0, 0, 1], stamp=0.01)
    w.step()
    snap = w.snapshot()
    q, s = dict(w.robots[0].q), w.s.copy()
    w.set_joint_positions(["arm_shoulder"], [0.3], stamp=0.02)
    w.set_pose("paddle", [1, 0, 0.9], [0, 0, 0, 1], stamp=0.02)
    w.restore(snap)
    assert w.robots[0].q == q
    for n in s.NAMES:
        np.testing.assert_array_equal(getattr(w.s, n), getattr(s, n))
    # the joint's and the pose's last stamps are those of the snapshot: 0.02 is after them again
    w.set_joint_positions(["arm_shoulder"], [0.3], stamp=0.02)
    w.set_pose("paddle", [1, 0, 0.9], [0, 0, 0, 1], stamp=0.02)
    assert w.robots[0].q["arm_shoulder"] == 0.3


def test_restore_refuses_a_snapshot_of_another_body_set_and_changes_nothing():
    w = scene()
    snap = w.snapshot()
    w.step()
    w.add_body("late", cs.Sphere(0.1), mass=1.0, position=[5, 0, 1])
    before = _contact_state(w)
    with pytest.raises(cs.ContactSimError, match=r"restore: the snapshot is of other bodies \(6 then, 7 now\)"):
        w.restore(snap)
    _assert_same(_contact_state(w), before)
    with pytest.raises(cs.ContactSimError, match="restore: snapshot must be a World.snapshot"):
        w.restore(before)


@pytest.mark.parametrize("settings", [dict(), dict(response="penalty"), dict(toi="fractional"),
                                      dict(toi="swept"), dict(response="kinematic")])
def test_stepping_adds_no_attribute_to_the_world(settings):
    """What a step keeps between steps is declared in ``World.__init__`` (state, contact cache,
    derived tables): no stage adds an attribute to the world at run time."""
    import warnings

    w = scene()
    declared = set(vars(w))
    assert declared == set(vars(cs.World()))
    w.settings = cs.Settings(**settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(40):
            w.set_pose("paddle", [2.0 - 0.02 * i, 0, 0.5], [0, 0, 0, 1], stamp=w.time + w.settings.dt)
            w.step()
    w.detect()
    w.describe()
    assert set(vars(w)) == declared


@pytest.mark.parametrize("field, value", [("split_beta", 0.9), ("combine", "max"), ("solver_method", "gs"),
                                          ("contact_margin", 0.02)])
def test_a_settings_field_assigned_between_steps_is_seen_by_the_next_step(field, value):
    """The step keeps the arguments it derives from the settings across steps: a field assigned in
    place takes effect at the next step exactly as a replaced settings object does."""
    worlds = [scene() for _ in range(3)]
    for w in worlds:
        for _ in range(5):
            w.step()
    edited, replaced, kept = worlds
    setattr(edited.settings, field, value)
    replaced.settings = dataclasses.replace(replaced.settings, **{field: value})
    for w in worlds:
        for _ in range(20):
            w.step()
    for a, b in zip(state_of(edited)[1:], state_of(replaced)[1:]):
        assert np.array_equal(a, b)
    assert not all(np.array_equal(a, b) for a, b in zip(state_of(edited)[1:], state_of(kept)[1:]))


def test_the_chosen_models_follow_every_edit_between_steps():
    """The models a step uses are kept across steps: an assigned settings field, a replaced
    settings object, a replaced material array, a kind edited in place and another ``dt`` each
    make the next choice anew; with no edit the kept choice is the one returned."""
    from contact_sim.response.models import choose

    w = scene()
    w.step()
    m = choose(w)
    assert choose(w) is m and m.friction
    w.settings.friction = False
    assert not choose(w).friction
    w.settings = dataclasses.replace(w.settings, friction=True)
    assert choose(w).friction
    w.settings.friction = "auto"
    assert choose(w).friction
    w.friction = np.zeros(len(w))   # no dynamic material has friction left
    assert not choose(w).friction
    m = choose(w)
    kind = w.kind.copy()
    w.kind[w.index("box")] = cs.kinds.KINDS.index("static")
    assert choose(w) is not m
    w.kind[:] = kind
    m = choose(w)
    assert choose(w, dt=0.005) is not m
    w.step()
