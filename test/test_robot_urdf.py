"""Robots from URDF: link poses from forward kinematics, contact at the geometric joint angle, the
input contract, adjacent links, mesh URIs and scene files. The arm is written in test/robot_arm.py."""
import os

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import contact_sim as cs
from robot_arm import (ARM_L, BASE_H, FINGER_MULT, FINGER_OFF, GRIP, SHOULDER_Z, SLIDE_LIMITS, SLIDE_X, arm_urdf,
                       rz, write_gripper_mesh)

ID = [0.0, 0.0, 0.0, 1.0]


@pytest.fixture
def mesh(tmp_path):
    return write_gripper_mesh(tmp_path / "grip.stl")


def arm_world(mesh, **kw):
    w = cs.World(gravity=[0, 0, 0])
    names = w.add_urdf(arm_urdf(mesh), **kw)
    return w, names


def hand_fk(theta, d, P0=np.zeros(3), R0=np.eye(3)):
    """Body frames ``{name: (position, rotation)}`` of the arm, written out joint by joint."""
    p_u, R_u = P0 + R0 @ [0, 0, SHOULDER_Z], R0 @ rz(theta)
    p_g = p_u + R_u @ [SLIDE_X + d, 0, 0]
    s = FINGER_MULT * d + FINGER_OFF
    ry = Rotation.from_euler("y", np.pi / 2).as_matrix()
    return {
        "base": (P0 + R0 @ [0, 0, BASE_H / 2], R0),
        "base#1": (P0 + R0 @ [0, 0, 0.15], R0),
        "upper": (p_u + R_u @ [ARM_L / 2, 0, 0], R_u @ ry),
        "gripper": (p_g, R_u),
        "finger": (p_g + R_u @ [0, -s, 0] + R_u @ [0, -0.005, 0], R_u),
    }


def frames(world):
    pos, quat = world.poses()
    R = Rotation.from_quat(quat).as_matrix()
    return {n: (pos[i], R[i]) for i, n in enumerate(world.body_names)}


@pytest.mark.exact
def test_link_poses_match_hand_computed_forward_kinematics(mesh):
    P0 = np.array([0.3, -0.2, 0.5])
    q0 = Rotation.from_rotvec([0.1, -0.2, 0.7]).as_quat()
    w, names = arm_world(mesh, prefix="", base_pose=(P0, q0), joint_positions={"shoulder": 0.3, "slide": 0.05})
    assert names == ["base", "base#1", "upper", "gripper", "finger"]
    R0 = Rotation.from_quat(q0).as_matrix()
    rng = np.random.default_rng(16)
    for k, (theta, d) in enumerate([(0.3, 0.05)] + [(rng.uniform(-3, 3), rng.uniform(*SLIDE_LIMITS))
                                                    for _ in range(20)]):
        if k:
            w.set_joint_positions(["shoulder", "slide"], [theta, d], stamp=float(k))
        got, want = frames(w), hand_fk(theta, d, P0, R0)
        for n in names:
            assert np.allclose(got[n][0], want[n][0], rtol=0, atol=1e-12), (n, theta, d)
            assert np.allclose(got[n][1], want[n][1], rtol=0, atol=1e-12), (n, theta, d)
    assert w.joint_positions() == {"shoulder": theta, "slide": d}


@pytest.mark.exact
def test_link_velocities_follow_each_joints_own_finite_differences(mesh):
    """Each joint's velocity is the finite difference of its own consecutive positions over their
    stamps (as robot_state_publisher keeps each joint's); the links move with those joint velocities
    at the new configuration: the gripper at ``θ̇ ẑ × (p − p_shoulder) + ḋ (cos θ, sin θ, 0)``, and
    a joint given at another time than the others keeps its own stamps."""
    w, _ = arm_world(mesh)
    w.set_joint_positions(["shoulder", "slide"], [0.2, 0.02], stamp=1.0)
    w.set_joint_positions(["shoulder", "slide"], [0.25, 0.03], stamp=1.1)
    vel, omega = w.velocities()
    g = w.index("gripper")
    theta, thetad, dd = 0.25, 0.05 / 0.1, 0.01 / 0.1
    p_g, p_u = hand_fk(0.25, 0.03)["gripper"][0], np.array([0, 0, SHOULDER_Z])
    want = np.cross([0, 0, thetad], p_g - p_u) + dd * np.array([np.cos(theta), np.sin(theta), 0.0])
    assert np.allclose(vel[g], want, rtol=0, atol=1e-12)
    assert np.allclose(omega[g], [0, 0, 0.5], rtol=0, atol=1e-12)
    assert np.allclose(omega[w.index("base")], 0, atol=0)
    # the slide alone at 1.15 (another driver): its velocity from its own stamps, the shoulder's kept
    w.set_joint_positions(["slide"], [0.035], stamp=1.15)
    vel, omega = w.velocities()
    want = np.cross([0, 0, thetad], hand_fk(0.25, 0.035)["gripper"][0] - p_u) + \
        0.005 / 0.05 * np.array([np.cos(theta), np.sin(theta), 0.0])
    assert np.allclose(vel[g], want, rtol=0, atol=1e-12)
    # the shoulder at 1.12, before the slide's last stamp but after its own: accepted
    w.set_joint_positions(["shoulder"], [0.26], stamp=1.12)
    assert np.allclose(w.velocities()[1][g], [0, 0, 0.01 / 0.02], rtol=0, atol=1e-12)


@pytest.mark.exact
def test_a_second_position_at_the_same_stamp_replaces_the_first(mesh):
    """Two calls before a step at the default stamp (the world time): the second replaces the first,
    its velocity taken from the position before that stamp (it raised "stamp must be after the
    previous pose")."""
    w, _ = arm_world(mesh)
    w.set_joint_positions(["shoulder"], [0.1])
    w.set_joint_positions(["shoulder"], [0.2])
    assert w.joint_positions()["shoulder"] == 0.2
    w.step(0.01)
    w.set_joint_positions(["shoulder"], [0.25])
    w.set_joint_positions(["shoulder"], [0.3])
    assert np.allclose(w.velocities()[1][w.index("gripper")], [0, 0, 0.1 / 0.01], rtol=0, atol=1e-9)


@pytest.mark.exact
def test_joint_positions_recorded_without_placing_leave_the_bodies_where_they_are(mesh):
    """``place=False`` records the joint positions, stamps and velocities, checked, and moves no
    body; the next placed call takes its velocity from the recorded stamps."""
    w, _ = arm_world(mesh)
    w.set_joint_positions(["shoulder"], [0.1], stamp=1.0)
    state = w.s.pos.copy(), w.s.quat.copy(), w.s.vel.copy(), w.s.omega.copy()
    w.set_joint_positions(["shoulder"], [0.2], stamp=1.1, place=False)
    for a, b in zip(state, (w.s.pos, w.s.quat, w.s.vel, w.s.omega)):
        assert np.array_equal(a, b)
    robot = w.robots[0]
    assert w.joint_positions()["shoulder"] == 0.2 and robot.qd["shoulder"] == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(cs.ContactSimError, match="outside its limits"):
        w.set_joint_positions(["shoulder"], [9.0], stamp=1.2, place=False)
    assert w.joint_positions()["shoulder"] == 0.2
    w.set_joint_positions(["shoulder"], [0.25], stamp=1.15)
    assert np.allclose(w.velocities()[1][w.index("gripper")], [0, 0, 0.05 / 0.05], rtol=0, atol=1e-12)
    assert np.allclose(w.body("gripper").position, hand_fk(0.25, 0.0)["gripper"][0], rtol=0, atol=1e-12)


@pytest.mark.exact
def test_pose_robot_places_the_links_with_the_given_joint_velocities_and_keeps_the_record(mesh):
    """``pose_robot``: the links at the forward kinematics of ``q``, moving as the joint velocities
    say (the gripper at ``θ̇ ẑ × (p − p_shoulder) + ḋ (cos θ, sin θ, 0)``, its frame turning at
    ``θ̇``); the joints' record (positions, stamps) as it was. A link faster than ``max_speed``, or
    another world's robot, is refused and changes nothing."""
    w, _ = arm_world(mesh)
    w.set_joint_positions(["shoulder", "slide"], [0.1, 0.01], stamp=1.0)
    robot, record = w.robots[0], dict(w.joint_positions())
    w.pose_robot(robot, {"shoulder": 0.25, "slide": 0.03}, {"shoulder": 0.5, "slide": 0.1})
    g = w.index("gripper")
    p_g, p_u = hand_fk(0.25, 0.03)["gripper"][0], np.array([0, 0, SHOULDER_Z])
    assert np.allclose(w.body("gripper").position, p_g, rtol=0, atol=1e-12)
    want = np.cross([0, 0, 0.5], p_g - p_u) + 0.1 * np.array([np.cos(0.25), np.sin(0.25), 0.0])
    assert np.allclose(w.s.vel[g], want, rtol=0, atol=1e-12)
    assert np.allclose(w.s.omega[g], [0, 0, 0.5], rtol=0, atol=1e-12)
    assert w.joint_positions() == record and robot.t["shoulder"] == 1.0
    state = w.s.pos.copy(), w.s.vel.copy()
    fast = cs.World(gravity=[0, 0, 0], settings=cs.Settings(max_speed=1.0, split_max_speed=0.5))
    fast.add_urdf(arm_urdf(mesh))
    with pytest.raises(cs.BoundsError, match="link 'gripper' velocity"):
        fast.pose_robot(fast.robots[0], {"shoulder": 0.0, "slide": 0.0}, {"shoulder": 3.0, "slide": 0.0})
    with pytest.raises(cs.ContactSimError, match="not a robot of this world"):
        w.pose_robot(fast.robots[0], {"shoulder": 0.0, "slide": 0.0}, {"shoulder": 0.0, "slide": 0.0})
    assert np.array_equal(state[0], w.s.pos) and np.array_equal(state[1], w.s.vel)


@pytest.mark.exact
def test_a_mimic_joint_that_agrees_with_its_leader_is_accepted(mesh):
    """A driver's JointState lists mimic joints too: a value within 1e-9 of ``multiplier × leader +
    offset`` is accepted (and ignored), with the leader given in the same call or before."""
    w, _ = arm_world(mesh)
    w.set_joint_positions(["slide", "finger_joint"], [0.04, FINGER_MULT * 0.04 + FINGER_OFF], stamp=1.0)
    w.set_joint_positions(["finger_joint"], [FINGER_MULT * 0.04 + FINGER_OFF + 5e-10], stamp=2.0)
    assert w.joint_positions()["slide"] == 0.04
    with pytest.raises(cs.ContactSimError, match="joint 'finger_joint' mimics 'slide'.*disagrees"):
        w.set_joint_positions(["finger_joint"], [FINGER_MULT * 0.04 + FINGER_OFF + 1e-6], stamp=3.0)


@pytest.mark.exact
def test_gripper_touches_a_box_at_the_joint_angle_geometry_gives(mesh):
    # shoulder turns about z; the gripper cube (half edge a) at L = SLIDE_X + d from the axis first
    # reaches the face y = y0 with its corner: L sin t + a (sin t + cos t) = y0
    d, a, y0 = 0.05, GRIP / 2, 0.12
    w, _ = arm_world(mesh, joint_positions={"slide": d})
    w.add_body("obstacle", cs.Box([0.15, 0.1, 0.2]), kind="static", position=[0.5, y0 + 0.05, SHOULDER_Z])
    L = SLIDE_X + d
    exact = np.arcsin(y0 / np.hypot(L + a, a)) - np.arctan2(a, L + a)
    stamp = [0.0]

    def touching(theta):
        stamp[0] += 1.0
        w.set_joint_positions(["shoulder"], [theta], stamp=stamp[0])
        c, _ = cs.collision.detect_world(w, margin=0.0)
        pairs = {frozenset((w.body_names[i], w.body_names[j])) for i, j in zip(c.body_a, c.body_b)}
        assert pairs <= {frozenset(("gripper", "obstacle"))}, pairs      # nothing else ever touches
        return len(c.depth) > 0

    lo, hi = 0.0, 0.3
    assert not touching(lo) and touching(hi)
    while hi - lo > 1e-9:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if touching(mid) else (mid, hi)
    assert abs(0.5 * (lo + hi) - exact) < 1e-6
    w.set_joint_positions(["shoulder"], [exact + 1e-4], stamp=stamp[0] + 1)
    c = w.detect()
    assert {w.body_names[c.body_a[0]], w.body_names[c.body_b[0]]} == {"gripper", "obstacle"}


def snapshot(w):
    return (w.poses(), w.velocities(), dict(w.joint_positions()), len(w), set(w.disabled_pairs), len(w.robots))


def same(a, b):
    (pa, qa), (va, oa), ja, na, da, ra = a
    (pb, qb), (vb, ob), jb, nb, db, rb = b
    return (np.array_equal(pa, pb) and np.array_equal(qa, qb) and np.array_equal(va, vb) and np.array_equal(oa, ob)
            and ja == jb and na == nb and da == db and ra == rb)


@pytest.mark.exact
@pytest.mark.parametrize("names, positions, stamp, message", [
    (["elbow"], [0.1], 5.0, "unknown joint 'elbow'"),
    (["shoulder"], [float("nan")], 5.0, "joint 'shoulder' position must be finite"),
    (["shoulder", "slide"], [0.1, float("inf")], 5.0, "joint 'slide' position must be finite"),
    (["slide"], [SLIDE_LIMITS[1] + 2e-9], 5.0, "joint 'slide' position"),
    (["slide"], [-1e-3], 5.0, "outside its limits"),
    (["finger_joint"], [0.02], 5.0, "joint 'finger_joint' mimics 'slide': its position 0.02 disagrees"),
    (["shoulder", "shoulder"], [0.1, 0.2], 5.0, "named twice"),
    (["shoulder"], [0.1, 0.2], 5.0, "1 joint names but 2 positions"),
    ("shoulder", [0.1], 5.0, "names: must be a list"),
    (["shoulder"], [0.1], 1.0, "joint 'shoulder': stamp 1.0 is before its previous one (2.0)"),
    (["tool"], [0.0], 5.0, "unknown joint 'tool'"),          # a fixed joint has no position
    (["shoulder"], [True], 5.0, "set_joint_positions.positions: must be 1 numbers"),
    (["shoulder"], ["0.1"], 5.0, "set_joint_positions.positions"),
    (["shoulder"], 0.1, 5.0, "set_joint_positions.positions"),
])
def test_bad_joint_positions_are_refused_by_name_and_change_nothing(mesh, names, positions, stamp, message):
    w, _ = arm_world(mesh)
    w.set_joint_positions(["shoulder", "slide"], [0.2, 0.02], stamp=1.0)
    w.set_joint_positions(["shoulder", "slide"], [0.25, 0.03], stamp=2.0)
    before = snapshot(w)
    with pytest.raises(cs.ContactSimError) as err:
        w.set_joint_positions(names, positions, stamp=stamp)
    assert message in str(err.value)
    assert same(before, snapshot(w))


@pytest.mark.exact
def test_limit_tolerance_is_1e_9(mesh):
    w, _ = arm_world(mesh)
    w.set_joint_positions(["slide"], [SLIDE_LIMITS[1] + 0.5e-9], stamp=1.0)
    assert w.joint_positions()["slide"] == SLIDE_LIMITS[1] + 0.5e-9
    with pytest.raises(cs.ContactSimError, match="outside its limits"):
        w.set_joint_positions(["slide"], [SLIDE_LIMITS[0] - 1.5e-9], stamp=2.0)


def test_bad_robots_are_refused_by_name_and_change_nothing(mesh, tmp_path):
    w, _ = arm_world(mesh)
    before = snapshot(w)
    cases = [
        (arm_urdf("package://nopkg/meshes/grip.stl"), {}, ["link 'gripper'", "package://nopkg/meshes/grip.stl"]),
        (arm_urdf(str(tmp_path / "missing.stl")), {"prefix": "b_"}, ["link 'gripper'", "missing.stl"]),
        (arm_urdf(mesh), {}, ["body 'base' already exists"]),
        (arm_urdf(mesh), {"prefix": "b_", "joint_positions": {"slide": 0.5}}, ["joint 'b_slide'", "limits"]),
        (arm_urdf(mesh), {"prefix": "b_", "joint_positions": {"elbow": 0.5}}, ["unknown joint 'elbow'"]),
        (arm_urdf(mesh), {"prefix": "b_", "base_pose": ([0, 0, float("nan")], ID)}, ["base_pose.position"]),
        (str(tmp_path / "none.urdf"), {}, ["no such URDF file"]),
        ('<robot name="r"><link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="zz"/>'
         '</joint></robot>', {}, ["joint 'j' names an unknown link 'zz'"]),
        ('<robot name="r"><link name="a"><collision><geometry><cylinder radius="-1" length="1"/></geometry>'
         '</collision></link></robot>', {}, ["link 'a' collision 0", "radius"]),
        ('<robot name="r"><link name="a"></robot>', {}, ["add_urdf: not well-formed XML"]),
        ('<model name="r"/>', {}, ["the root element is <model>"]),
    ]
    for urdf, kw, parts in cases:
        with pytest.raises(cs.ContactSimError) as err:
            w.add_urdf(urdf, **kw)
        for p in parts:
            assert p in str(err.value), (p, str(err.value))
        assert same(before, snapshot(w))


def robot_pairs(w):
    c = w.detect()
    return {tuple(sorted((w.body_names[i], w.body_names[j]))) for i, j in zip(c.body_a, c.body_b)}


def test_adjacent_links_never_report_contacts_but_other_robots_links_do(mesh):
    w, names = arm_world(mesh, exclude_touching=False)
    # overlapping by construction: the upper arm lies in the base's top face and through its sphere,
    # the finger is inside the gripper; all adjacent (or one link's own bodies)
    assert {("base", "upper"), ("base#1", "upper"), ("base", "base#1"), ("gripper", "upper"),
            ("finger", "gripper")} == w.disabled_pairs
    for k, theta in enumerate(np.linspace(-3, 3, 13)):
        w.set_joint_positions(["shoulder", "slide"], [theta, 0.02 + 0.08 * k / 12], stamp=k + 1.0)
        assert robot_pairs(w) == set()
    # links two joints apart are not adjacent: slid fully in, the finger touches the upper arm's end
    w.set_joint_positions(["slide"], [0.0], stamp=14.0)
    assert robot_pairs(w) == {("finger", "upper")}
    # a second arm overlapping the first: its links touch the first's (not adjacent)
    w.add_urdf(arm_urdf(mesh), prefix="b_", base_pose=([0.2, 0.0, 0.0], ID), joint_positions={"slide": 0.05},
               exclude_touching=False)
    w.set_joint_positions(["shoulder", "slide"], [0.0, 0.05], stamp=20.0)
    pairs = robot_pairs(w)
    assert ("b_upper", "upper") in pairs and all(p[0].startswith("b_") != p[1].startswith("b_") for p in pairs)
    w.disable_collisions([("upper", "b_upper")])
    assert ("b_upper", "upper") not in robot_pairs(w)
    # removing a robot removes its bodies and its pairs; the other robot still moves
    w.remove_robot("b_arm")
    assert w.body_names == names and all(not p[0].startswith("b_") for p in w.disabled_pairs)
    w.set_joint_positions(["shoulder"], [0.1], stamp=21.0)
    with pytest.raises(cs.ContactSimError, match="unknown joint 'b_shoulder'"):
        w.set_joint_positions(["b_shoulder"], [0.1], stamp=22.0)


def test_mesh_uris_package_file_and_relative(mesh, tmp_path, monkeypatch):
    pkg = tmp_path / "ws" / "arm_description"
    (pkg / "meshes").mkdir(parents=True)
    write_gripper_mesh(pkg / "meshes" / "grip.stl")
    uri = "package://arm_description/meshes/grip.stl"
    for i, kw in enumerate([{"package_paths": {"arm_description": str(pkg)}},
                            {"package_paths": [str(tmp_path / "ws")]}]):
        w = cs.World()
        w.add_urdf(arm_urdf(uri), **kw)
        assert w.body("gripper").shape.type == "convex"
    monkeypatch.setenv("CONTACT_SIM_PACKAGE_PATH", str(tmp_path / "ws"))
    cs.World().add_urdf(arm_urdf(uri))
    cs.World().add_urdf(arm_urdf("file://" + mesh))
    # relative to the URDF file; OBJ as well as STL, and the scale applies
    import trimesh

    trimesh.creation.box([GRIP] * 3).export(str(pkg / "meshes" / "grip.obj"))
    urdf = pkg / "arm.urdf"
    urdf.write_text(arm_urdf("meshes/grip.obj").replace('scale="1 1 1"', 'scale="2 1 0.5"'))
    w = cs.World()
    w.add_urdf(str(urdf))
    assert np.allclose(np.ptp(w.body("gripper").shape.vertices, axis=0), [2 * GRIP, GRIP, 0.5 * GRIP], atol=1e-12)
    # COLLADA (pycollada comes with yourdfpy's trimesh[easy])
    trimesh.creation.box([GRIP] * 3).export(str(pkg / "meshes" / "grip.dae"))
    urdf.write_text(arm_urdf("meshes/grip.dae"))
    w = cs.World()
    w.add_urdf(str(urdf))
    assert np.allclose(np.ptp(w.body("gripper").shape.vertices, axis=0), GRIP, atol=1e-12)


def test_concave_mesh_is_a_trimesh_unless_hulls_are_asked_for(tmp_path):
    import trimesh

    a = trimesh.creation.box([0.1, 0.02, 0.02])
    b = trimesh.creation.box([0.02, 0.1, 0.02])
    b.apply_translation([0.04, 0.04, 0.0])
    ell = trimesh.util.concatenate([a, b])          # an L: not convex
    path = str(tmp_path / "ell.stl")
    ell.export(path)
    urdf = f'<robot name="r"><link name="a"><collision><geometry><mesh filename="{path}"/></geometry>' \
           '</collision></link></robot>'
    w = cs.World()
    w.add_urdf(urdf)
    assert w.body("a").shape.type == "mesh"
    w = cs.World()
    w.add_urdf(urdf, convex_meshes=True)
    assert w.body("a").shape.type == "convex"


def test_scene_file_robots_and_reset(mesh, tmp_path):
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "arm.urdf").write_text(arm_urdf(mesh))
    scene = {
        "gravity": [0, 0, -9.81],
        "bodies": [{"name": "floor", "kind": "static", "shape": {"type": "plane"}},
                   {"name": "ball", "shape": {"type": "sphere", "radius": 0.05}, "position": [2, 0, 1]}],
        "robots": [{"urdf": "robots/arm.urdf", "prefix": "r1_", "base_pose": {"position": [0, 1, 0]},
                    "joint_positions": {"shoulder": 0.4, "slide": 0.02},
                    "disable_collisions": [["base", "gripper"]]}],
    }
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene))
    w = cs.load_scene(str(path))
    assert w.body_names == ["floor", "ball", "r1_base", "r1_base#1", "r1_upper", "r1_gripper", "r1_finger"]
    want = hand_fk(0.4, 0.02, P0=np.array([0.0, 1.0, 0.0]))
    got = frames(w)
    for n, (p, R) in want.items():
        assert np.allclose(got["r1_" + n][0], p, atol=1e-12) and np.allclose(got["r1_" + n][1], R, atol=1e-12)
    assert ("r1_base", "r1_gripper") in w.disabled_pairs
    w.set_joint_positions(["r1_shoulder"], [1.0], stamp=1.0)
    w.step()
    w.reset()
    assert w.joint_positions() == {"r1_shoulder": 0.4, "r1_slide": 0.02}
    assert np.allclose(frames(w)["r1_gripper"][0], want["gripper"][0], atol=1e-12)
    # errors name the scene path
    bad = dict(scene, robots=[dict(scene["robots"][0], joint_positions={"shoulder": 9.0})])
    with pytest.raises(cs.SceneError, match=r"robots\[0\].joint_positions: joint 'r1_shoulder'"):
        cs.load_scene(bad, base_dir=str(tmp_path))
    bad = dict(scene, robots=[{"urdf": "robots/none.urdf"}])
    with pytest.raises(cs.SceneError, match=r"robots\[0\].urdf: no such file"):
        cs.load_scene(bad, base_dir=str(tmp_path))
    bad = dict(scene, robots=[dict(scene["robots"][0], colour="red")])
    with pytest.raises(cs.SceneError, match=r"robots\[0\]"):
        cs.load_scene(bad, base_dir=str(tmp_path))


def test_a_robot_link_pushes_a_dynamic_ball(mesh):
    # the links are ordinary kinematic bodies to the solver: the sweeping arm pushes a ball aside
    w = cs.World(gravity=[0, 0, 0], settings={"dt": 0.01})
    w.add_urdf(arm_urdf(mesh), joint_positions={"shoulder": -0.5, "slide": 0.05})
    w.add_body("ball", cs.Sphere(0.03), mass=0.1, position=[0.45, 0.1, SHOULDER_Z])
    for k in range(1, 60):
        w.set_joint_positions(["shoulder"], [-0.5 + 0.02 * k], stamp=0.01 * k)
        w.step()
    b = w.body("ball")
    assert b.velocity[1] > 0.05 and np.hypot(*b.position[:2]) > 0.45 - 1e-3
    assert os.path.basename(__file__) == "test_robot_urdf.py"


def test_srdf_disable_collisions(mesh, tmp_path):
    srdf = '<robot name="arm"><disable_collisions link1="finger" link2="upper" reason="Never"/>' \
           '<disable_collisions link1="tool_frame" link2="base" reason="Never"/></robot>'
    w, _ = arm_world(mesh, srdf=srdf, prefix="p_")
    assert ("p_finger", "p_upper") in w.disabled_pairs       # tool_frame has no geometry: no pair
    w.set_joint_positions(["p_slide"], [0.0], stamp=1.0)       # finger against the upper arm's end
    assert robot_pairs(w) == set()
    (tmp_path / "arm.srdf").write_text(srdf.replace('link2="upper"', 'link2="elbow"'))
    with pytest.raises(cs.ContactSimError, match=r"add_urdf.srdf: disable_collisions 0 names an unknown link 'elbow'"):
        cs.World().add_urdf(arm_urdf(mesh), srdf=str(tmp_path / "arm.srdf"))


@pytest.mark.exact
def test_pairs_touching_at_the_initial_configuration_are_excluded_and_said_why(mesh):
    """MoveIt's "Default": at the initial configuration (slide at 0) the finger touches the upper
    arm, and the base stands on the floor: those pairs are never tested, and ``describe()`` and the
    robot's ``exclusions`` say why; a dynamic ball resting on the base stays tested. Pairs given by
    name (a link without the prefix, a scene body) are excluded too."""
    w = cs.World(gravity=[0, 0, 0])
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("table", cs.Box([1.0, 1.0, 0.1]), kind="static", position=[2.0, 0.0, 0.05])
    w.add_body("ball", cs.Sphere(0.02), mass=0.1, position=[-0.07, -0.07, BASE_H + 0.02])
    w.add_urdf(arm_urdf(mesh), prefix="r_", disable_collisions=[["gripper", "table"]])
    r = w.robots[0]
    assert r.exclusions[("r_finger", "r_upper")] == "touching at the initial configuration"
    assert r.exclusions[("floor", "r_base")] == "touching at the initial configuration"
    assert r.exclusions[("r_gripper", "table")] == "given"
    assert r.exclusions[("r_gripper", "r_upper")] == "adjacent links"
    assert not any("ball" in pair for pair in w.disabled_pairs)
    c = w.detect()
    touching = {tuple(sorted((w.body_names[a], w.body_names[b]))) for a, b in zip(c.body_a, c.body_b)}
    assert touching == {("ball", "r_base")}
    text = w.describe()
    assert "pairs never tested (touching at the initial configuration): floor–r_base, r_finger–r_upper" in text
    with pytest.raises(cs.ContactSimError, match=r"disable_collisions\[0\]: 'elbow' is neither a link"):
        w.add_urdf(arm_urdf(mesh), prefix="s_", disable_collisions=[["elbow", "table"]])
    assert len(w.robots) == 1 and "s_base" not in w.body_names


def test_a_urdf_written_for_another_simulator_finds_its_meshes_beside_it(tmp_path):
    """pybullet_data's Panda names its meshes ``package://meshes/collision/link0.obj``, ``meshes``
    being a folder beside the URDF, no ROS package: with no package path it is found there (as
    pybullet and yourdfpy look); a mesh found nowhere names every place looked and how to add one."""
    (tmp_path / "meshes" / "collision").mkdir(parents=True)
    write_gripper_mesh(tmp_path / "meshes" / "collision" / "grip.stl")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(arm_urdf("package://meshes/collision/grip.stl"))
    w = cs.World()
    assert "gripper" in w.add_urdf(str(urdf))
    urdf.write_text(arm_urdf("package://meshes/collision/missing.stl"))
    with pytest.raises(cs.ContactSimError) as err:
        cs.World().add_urdf(str(urdf))
    text = str(err.value)
    assert str(tmp_path / "meshes" / "collision" / "missing.stl") in text
    assert "add the folder that holds the package 'meshes' to package_paths" in text


def test_a_collision_mesh_that_is_its_own_hull_becomes_a_convex_body(tmp_path):
    """A robot's collision mesh is usually its link's hull; one with a seam (here: a box missing a
    face, as pybullet_data's Panda meshes are to trimesh) is neither watertight nor convex to
    trimesh, yet it is its hull: it becomes that ``Convex``, and not an open ``TriMesh`` with a
    one-sided inside. A mesh with a vertex 10 cm inside its hull stays a mesh."""
    import trimesh

    box = trimesh.creation.box([0.1, 0.2, 0.3])
    trimesh.Trimesh(box.vertices, box.faces[1:], process=False).export(tmp_path / "seam.stl")
    dent = trimesh.Trimesh(np.vstack([box.vertices, [[0.0, 0.0, 0.1]]]),
                           np.vstack([box.faces[2:], [[8, 0, 1], [8, 1, 3]]]), process=False)
    dent.export(tmp_path / "dent.stl")
    w = cs.World()
    w.add_urdf(arm_urdf("file://" + str(tmp_path / "seam.stl")))
    assert w.user_shapes[w.index("gripper")].type == "convex"
    np.testing.assert_allclose(np.ptp(w.user_shapes[w.index("gripper")].vertices, axis=0), [0.1, 0.2, 0.3])
    w2 = cs.World()
    w2.add_urdf(arm_urdf("file://" + str(tmp_path / "dent.stl")))
    assert w2.user_shapes[w2.index("gripper")].type == "mesh"


def test_the_panda_of_pybullet_data_loads_its_links_as_their_hulls():
    """pybullet_data's Panda (its copy in test/data) loads with no package path; its collision
    meshes, within 0.23 mm of their hulls, are those hulls but link6's, which has a real
    concavity; at its zero pose nothing touches that is not excluded."""
    from conftest import PANDA_URDF

    w = cs.World()
    w.add_body("floor", cs.Plane(), kind="static")
    names = w.add_urdf(PANDA_URDF)
    kinds = {n: w.user_shapes[w.index(n)].type for n in names}
    assert kinds.pop("panda_link6") == "mesh" and set(kinds.values()) == {"convex"}
    assert len(w.detect()) == 0
