"""Kinematic bodies: velocity from successive poses and stamps; bad poses change nothing."""
import dataclasses

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT


def world_with_paddle():
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("paddle", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[5, 5, 5])
    return w


def test_velocity_from_successive_poses():
    w = world_with_paddle()
    q0 = np.array([0, 0, 0, 1.0])
    w.set_pose("paddle", [0, 0, 0], q0, stamp=10.0)
    assert np.array_equal(w.body("paddle").velocity, [0, 0, 0])  # one pose: no velocity yet
    axis_angle = np.array([0.0, 0.0, 0.3])  # 0.3 rad about z in 0.25 s → 1.2 rad/s
    q1 = quat.from_rotvec(axis_angle)
    w.set_pose("paddle", [0.5, -0.25, 0.1], q1, stamp=10.25)
    b = w.body("paddle")
    assert np.allclose(b.velocity, [2.0, -1.0, 0.4], rtol=0, atol=1e-12)
    assert np.allclose(b.angular_velocity, [0, 0, 1.2], rtol=0, atol=1e-12)
    assert np.allclose(b.position, [0.5, -0.25, 0.1], atol=0) and np.allclose(b.orientation, q1, atol=1e-15)


def test_quaternion_sign_flip_is_the_same_rotation():
    w = world_with_paddle()
    q = quat.from_rotvec([0.1, 0.0, 0.0])
    w.set_pose("paddle", [0, 0, 0], q, stamp=0.0)
    w.set_pose("paddle", [0, 0, 0], -quat.from_rotvec([0.2, 0.0, 0.0]), stamp=0.1)
    assert np.allclose(w.body("paddle").angular_velocity, [1.0, 0, 0], atol=1e-12)


def test_kinematic_body_moves_with_its_velocity_between_poses():
    w = world_with_paddle()
    w.set_pose("paddle", [0, 0, 0], [0, 0, 0, 1], stamp=0.0)
    w.set_pose("paddle", [0.1, 0, 0], [0, 0, 0, 1], stamp=0.1)
    for _ in range(10):
        w.step(0.01)
    assert np.allclose(w.body("paddle").position, [0.2, 0, 0], atol=1e-14)
    assert np.allclose(w.body("paddle").velocity, [1.0, 0, 0], atol=1e-14)  # no gravity on kinematic bodies


@pytest.mark.parametrize("args, message", [
    (("ghost", [0, 0, 0], [0, 0, 0, 1], 1.0), "unknown body 'ghost'"),
    (("ball", [0, 0, 0], [0, 0, 0, 1], 1.0), "only kinematic bodies are posed"),
    (("paddle", [0, np.nan, 0], [0, 0, 0, 1], 1.0), r"position: must be finite"),
    (("paddle", [0, 0], [0, 0, 0, 1], 1.0), r"position: must be 3 numbers"),
    (("paddle", [0, 0, 0], [0, 0, 0, 0], 1.0), "zero quaternion"),
    (("paddle", [0, 0, 0], [0, 0, 1, 1], 1.0), "must be unit length"),
    (("paddle", [0, 0, 0], [0, 0, np.inf, 1], 1.0), "orientation: must be finite"),
    (("paddle", [0, 0, 0], [0, 0, 0, 1], 0.5), "must be after the previous pose"),
    (("paddle", [0, 0, 0], [0, 0, 0, 1], float("nan")), "stamp: must be a finite number"),
])
def test_bad_poses_are_refused_and_change_nothing(args, message):
    w = world_with_paddle()
    w.set_pose("paddle", [1, 2, 3], [0, 0, 0, 1], stamp=0.5)
    before = [a.copy() for a in (w.s.pos, w.s.vel, w.s.quat, w.s.omega, w.s.stamp)]
    with pytest.raises(cs.ContactSimError, match=message):
        w.set_pose(*args)
    after = (w.s.pos, w.s.vel, w.s.quat, w.s.omega, w.s.stamp)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(before, after))


def test_set_state_and_reset():
    w = cs.load_scene({"bodies": [{"name": "b", "shape": {"type": "sphere", "radius": 0.1}, "position": [0, 0, 1]}]})
    w.set_state("b", velocity=[1, 0, 0])
    w.step(0.1)
    assert not np.allclose(w.body("b").position, [0, 0, 1])
    w.reset()
    assert np.array_equal(w.body("b").position, [0, 0, 1]) and w.time == 0.0
    assert np.array_equal(w.body("b").velocity, [0, 0, 0])


def two_paddles():
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("left", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    w.add_body("right", cs.Box([0.3, 0.3, 0.05]), kind="kinematic")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[5, 5, 5])
    return w


def test_set_poses_batch_differences_each_body():
    w = two_paddles()
    w.set_pose("left", [0, 0, 0], [0, 0, 0, 1], stamp=1.0)  # right has no pose yet
    q = quat.from_rotvec([0.2, 0.0, 0.0])
    w.set_poses(["left", "right"], [[0.1, 0, 0], [3, 3, 3]], [q, [0, 0, 0, 1]], stamp=1.5)
    assert np.allclose(w.body("left").velocity, [0.2, 0, 0], atol=1e-15)
    assert np.allclose(w.body("left").angular_velocity, [0.4, 0, 0], atol=1e-12)
    assert np.array_equal(w.body("right").velocity, [0, 0, 0])  # first pose: position only
    assert np.array_equal(w.body("right").position, [3, 3, 3])


@pytest.mark.parametrize("names, positions, orientations, message", [
    (["left", "right"], [[0, 0, 0], [0, np.nan, 0]], [[0, 0, 0, 1]] * 2, r"set_pose\('right'\)\.position: must be finite"),
    (["left", "right"], [[0, 0, 0], [0, 0, 0]], [[0, 0, 0, 1], [0, 0, 0, 3]], r"set_pose\('right'\)\.orientation: quaternion must be unit"),
    (["left", "right"], [[0, 0, 0], [0, 0]], [[0, 0, 0, 1]] * 2, r"set_pose\('right'\)\.position: must be 3 numbers"),
    (["left", "left"], [[0, 0, 0]] * 2, [[0, 0, 0, 1]] * 2, "named twice"),
    (["left", "right"], [[0, 0, 0]], [[0, 0, 0, 1]] * 2, "2 names but 1 positions"),
    (["left", "ball"], [[0, 0, 0]] * 2, [[0, 0, 0, 1]] * 2, r"set_pose\('ball'\): only kinematic"),
])
def test_set_poses_refuses_the_whole_batch(names, positions, orientations, message):
    w = two_paddles()
    w.set_poses(["left", "right"], [[1, 1, 1], [2, 2, 2]], [[0, 0, 0, 1]] * 2, stamp=0.0)
    before = [a.copy() for a in (w.s.pos, w.s.vel, w.s.quat, w.s.omega, w.s.stamp)]
    with pytest.raises(cs.ContactSimError, match=message):
        w.set_poses(names, positions, orientations, stamp=1.0)
    after = (w.s.pos, w.s.vel, w.s.quat, w.s.omega, w.s.stamp)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(before, after))


def test_push_cap_scales_to_the_budget_of_the_fastest_body():
    """``energy.push_cap_kernel``: a velocity change within every body's budget is kept (f = 1); one beyond
    it is scaled so that the body over budget ends exactly on it (``½m(|v₀| + 2u)² + ½m(2u)²`` plus
    its rotation before), the formula solved here by hand for a translation-only change."""
    import numpy as np

    import contact_sim as cs
    from contact_sim.response.energy import push_cap_kernel

    def push_cap(w, bodies, u, v0, w0, vel, omega):
        return push_cap_kernel(bodies, u, w.mass, w.particle, w.s.quat, w.inertia_body, v0, w0, v0, w0, vel, omega)

    w = cs.World()
    w.add_body("a", cs.Sphere(0.1), mass=2.0)
    w.add_body("b", cs.Sphere(0.1), mass=1.0, position=(1.0, 0.0, 0.0))
    bodies, u = np.array([0, 1]), 0.5
    v0, w0 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), np.zeros((2, 3))
    small = v0 + np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])
    assert push_cap(w, bodies, u, v0, w0, small, w0) == 1.0
    big = v0 + np.array([[0.5, 0.0, 0.0], [0.0, 30.0, 0.0]])   # b thrown out at 30 m/s
    f = push_cap(w, bodies, u, v0, w0, big, w0)
    # b: ½·1·(30 f)² = ½·1·(0 + 1)² + ½·1·1²  →  f = √2 / 30
    assert abs(f - np.sqrt(2.0) / 30.0) < 1e-15
    assert abs(np.linalg.norm(big[1]) - np.sqrt(2.0)) < 1e-14   # applied in place: b ends on its budget
    assert push_cap(w, bodies, 0.0, v0, w0, v0, w0) == 1.0


@pytest.mark.parametrize("spin", [0.0, 3.0, -40.0])
def test_the_work_of_a_turning_moving_kinematic_body_is_taken_where_it_touches(spin):
    """A kinematic box moving at v and turning at ω about z hits a resting ball (e = 1, no friction,
    no gravity): the ball gains exactly the work ``λ·(v + ω × (p − x))`` of the box's contact point
    at the impact, which ``last_solve.kinematic_work`` reports. Taken after the step, with the box's
    centre moved on by v·dt, it was off by ``λ·(ω × v dt)``."""
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(toi="next_step", dt=0.01, kinematic_stiffness=0.0),
                 materials={"m": cs.Material(restitution=1.0, friction=0.0)})
    w.add_body("paddle", cs.Box([1.0, 1.0, 1.0]), kind="kinematic", material="m")
    w.set_state("paddle", velocity=[2.0, 0.0, 0.0], angular_velocity=[0.0, 0.0, spin])
    w.add_body("ball", cs.Sphere(0.1), mass=0.7, position=[0.6, 0.2, 0.0], material="m")
    e0 = w.energy()
    w.step()
    assert w.last_solve.kinematic_work > 0
    assert abs((w.energy() - e0) - w.last_solve.kinematic_work) <= 1e-12 * w.last_solve.kinematic_work


@pytest.mark.parametrize("theta_deg", [5.0, 10.0])
def test_a_ball_squeezed_in_a_closing_wedge_ends_within_the_push_budget(theta_deg):
    """Rigid contacts (``kinematic_stiffness`` 0). A ball touching a static wall (normal −x) and a
    kinematic paddle tilted by θ from facing it
    (normal (cos θ, sin θ, 0)) that moves at u = 0.5 m/s along +x: staying out of both needs
    ``v_y = u cot θ`` (5.7 m/s at 5°, 2.8 m/s at 10°), beyond the push budget (``½m(|v₀| + 2u)² +
    ½m(2u)²``: from rest, a speed of 2√2·u = 1.41 m/s), which caps it. Each impact round measured
    the budget from its own start, so every round added to it (rounds follow while the capped
    contacts still approach): the ball left at the full u cot θ, and in a pile a body squeezed
    between a paddle and a wall went to 12 m/s in a step. The budget is the stage's: the ball ends
    on it."""
    u, r = 0.5, 0.1
    th = np.radians(theta_deg)
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(toi="next_step", dt=0.01, kinematic_stiffness=0.0),
                 materials={"m": cs.Material(restitution=0.0, friction=0.0)})
    w.add_body("wall", cs.Plane([-1.0, 0.0, 0.0], -r), kind="static", material="m")
    n = np.array([np.cos(th), np.sin(th), 0.0])          # the paddle's face normal, towards the ball
    half = 0.05
    w.add_body("paddle", cs.Box([2 * half, 1.0, 1.0]), kind="kinematic", material="m",
               position=-(r + half) * n, orientation=quat.from_rotvec([0.0, 0.0, th]))
    w.set_state("paddle", velocity=[u, 0.0, 0.0])
    w.add_body("ball", cs.Sphere(r), mass=1.0, material="m")
    w.step()
    v = w.body("ball").velocity
    assert abs(np.linalg.norm(v) - 2.0 * np.sqrt(2.0) * u) < 1e-12
    assert w.last_solve.contacts >= 2


def squeeze_at_a_wall():
    """Ground; a kinematic paddle (bodies: 1) moving at 0.5 m/s along x, pressed 1 cm into the ground;
    a ball (2, 0.5 kg, r 0.1) in its way, then a box (3, 1 kg) standing at a static wall (4); one
    material, e = 0.2, μ = 0.4, ``next_step``, rigid contacts (``kinematic_stiffness`` 0: the push
    cap is the rigid model's answer to a squeeze). By t = 0.85 s the three contacts cannot all hold."""
    w = cs.World(settings=cs.Settings(toi="next_step", kinematic_stiffness=0.0),
                 materials={"m": cs.Material(restitution=0.2, friction=0.4)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("paddle", cs.Box((0.05, 0.5, 0.3)), kind="kinematic", position=(-0.4, 0, 0.14),
               velocity=(0.5, 0, 0), material="m")
    w.add_body("ball", cs.Sphere(0.1), mass=0.5, position=(0, 0, 0.1), material="m")
    w.add_body("box", cs.Box((0.2, 0.2, 0.2)), mass=1.0, position=(0.35, 0, 0.1), material="m")
    w.add_body("wall", cs.Box((0.1, 1.0, 1.0)), kind="static", position=(0.5, 0, 0.5), material="m")
    return w


@pytest.mark.parametrize("toi", ["next_step", "fractional"])
def test_a_ball_squeezed_between_a_paddle_and_a_box_at_a_wall_rebounds_within_the_push_budget(toi):
    """A paddle at u = 0.5 m/s pushes a ball (e = 0.2, μ = 0.4) into a box standing at a static wall:
    no impulse holds all three contacts, and the restitution stage's solve grew without bound. With a
    static body in the impact there is no frame for the energetic cap, so the push cap bounds the
    rebound as it bounds the compression: in every step each dynamic body ends no faster than
    ``√((|v₀| + 2u)² + (2u)²)`` (its budget, ``energy.push_cap_kernel``) plus gravity's ``g·dt``. Before,
    the ball left at 25 m/s. Both sub-step paths: whole (``next_step``) and split at times of impact
    (``fractional``)."""
    w = squeeze_at_a_wall()
    w.settings = dataclasses.replace(w.settings, toi=toi)
    u, dt, squeezed = 0.5, 0.01, 0
    for _ in range(150):
        v0 = np.linalg.norm(w.s.vel[2:4], axis=1)
        w.step(dt)
        v1 = np.linalg.norm(w.s.vel[2:4], axis=1)
        assert np.all(v1 <= np.sqrt((v0 + 2 * u) ** 2 + (2 * u) ** 2) + 9.81 * dt + 1e-12), (w.time, v0, v1)
        names = {frozenset((int(a), int(b))) for a, b in zip(w.contacts.body_a, w.contacts.body_b)}
        squeezed += {frozenset((1, 2)), frozenset((2, 3)), frozenset((3, 4))} <= names
    assert squeezed > 3     # not vacuous: the three contacts held at once


def test_a_recorded_pose_leaves_the_body_and_the_drive_takes_it_there_in_the_period():
    """``set_pose(place=False)`` records the pose and its finite-difference velocity without moving
    the body (a first pose places it: nothing to drive from); ``drive_poses`` gives the body the
    velocity and angular velocity that take its centre of mass and orientation, over ``period``,
    to that pose carried on at its velocity to ``until`` (at most its stamps' interval plus the
    period past its stamp), and the steps over the period end there."""
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("pad", cs.Box([0.2, 0.1, 0.1]), kind="kinematic", position=[1.0, 0.0, 0.0])
    w.set_pose("pad", [0.5, 0.0, 0.0], [0, 0, 0, 1], stamp=0.0, place=False)    # a first pose: placed
    np.testing.assert_allclose(w.body("pad").position, [0.5, 0.0, 0.0], rtol=0, atol=1e-15)
    q1 = quat.from_rotvec([0.0, 0.0, 0.02])
    w.set_pose("pad", [0.52, 0.0, 0.0], q1, stamp=0.01, place=False)           # 2 m/s, 2 rad/s (origin)
    np.testing.assert_allclose(w.body("pad").position, [0.5, 0.0, 0.0], rtol=0, atol=1e-15)   # not moved
    assert not w.body("pad").velocity.any()
    T = 0.004
    w.drive_poses(["pad"], until=0.015, period=T)        # carried on 5 ms: the pose at 0.015 s
    turn = quat.from_rotvec([0.0, 0.0, 2.0 * 0.005])
    goal_q = quat.mul(turn, q1)
    goal_c = np.array([0.52, 0.0, 0.0]) + w.s.pose_vel[0] * 0.005
    c0 = np.array([0.5, 0.0, 0.0])
    np.testing.assert_allclose(w.s.vel[0], (goal_c - c0) / T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(w.s.omega[0], quat.to_rotvec(goal_q) / T, rtol=0, atol=1e-12)
    for _ in range(4):
        w.step(T / 4)
    np.testing.assert_allclose(w.s.pos[0], goal_c, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w.body("pad").orientation, goal_q, rtol=0, atol=1e-15)
    # the next pose still differences from the last one (the record was kept), and a drive ahead of
    # the stamps by more than their interval and the period is held there
    w.set_pose("pad", [0.54, 0.0, 0.0], quat.from_rotvec([0.0, 0.0, 0.04]), stamp=0.02, place=False)
    np.testing.assert_allclose(w.s.pose_omega[0], [0, 0, 2.0], rtol=0, atol=1e-12)
    assert w.s.pose_gap[0] == pytest.approx(0.01, abs=1e-15)
    w.drive_poses(["pad"], until=1.0, period=T, at_rest=True)
    np.testing.assert_allclose(quat.to_rotvec(w.s.quat[0]), [0, 0, 0.04 + 2.0 * (0.01 + T)], rtol=0, atol=1e-14)
    assert not w.s.vel[0].any() and not w.s.omega[0].any()


def test_drive_poses_refuses_what_it_cannot_do_and_changes_nothing():
    w = world_with_paddle()
    w.settings.max_speed = 5.0
    w.settings.split_max_speed = 1.0
    w.drive_poses(["paddle"], until=1.0, period=0.01)    # no pose given yet: left as it is
    assert not w.s.vel.any()
    w.set_pose("paddle", [0, 0, 0], [0, 0, 0, 1], stamp=0.0, place=False)
    w.set_pose("paddle", [1.0, 0, 0], [0, 0, 0, 1], stamp=0.5, place=False)   # 2 m/s: a valid pose
    before = w.snapshot()
    with pytest.raises(cs.BoundsError, match=r"drive_poses\('paddle'\): reaching .* takes 102 m/s, above max_speed"):
        w.drive_poses(["paddle"], until=0.51, period=0.01)   # 1.02 m in 0.01 s
    with pytest.raises(cs.ContactSimError, match="only kinematic bodies are driven"):
        w.drive_poses(["paddle", "ball"], until=0.51, period=0.01)
    with pytest.raises(cs.ContactSimError, match="period: must be > 0"):
        w.drive_poses(["paddle"], until=0.51, period=0.0)
    with pytest.raises(cs.ContactSimError, match="unknown body 'ghost'"):
        w.drive_poses(["ghost"], until=0.51, period=0.01)
    w.set_pose("paddle", [w.settings.max_position - 0.01, 0, 0], [0, 0, 0, 1], stamp=1e6, place=False)
    with pytest.raises(cs.BoundsError, match="beyond max_position"):
        w.drive_poses(["paddle"], until=2e6, period=0.01, at_rest=True)
    after = w.snapshot()
    for n in ("pos", "vel", "quat", "omega"):
        assert np.array_equal(getattr(before.state, n), getattr(after.state, n))
