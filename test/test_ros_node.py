"""The contact_sim node in process: own rclpy.Context and ROS domain, services, bad input counted."""
import math
import os
import threading
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from domain_coordinator import domain_id  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from msg_adapters import conversions as cv  # noqa: E402
from msg_adapters.launch import main  # noqa: E402
from msg_adapters.node import DIAG_NAME, ConfigError, ContactSimNode  # noqa: E402
from msg_adapters.testing import Spinner, ros_context, ros_env  # noqa: E402

IDENTITY = np.array([[0.0, 0.0, 0.0, 1.0]])


class Client:
    """A test client node: latest messages of every node output, publishers and service clients."""

    def __init__(self, ctx):
        self.node = rclpy.create_node("client", context=ctx)
        self.last = {}
        self.count = {"contacts": 0, "body_states": 0}
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(String, "body_names", lambda m: self.last.__setitem__("names", m), latched)
        self.node.create_subscription(PoseArray, "body_states", self._on_states, 10)
        self.node.create_subscription(PointCloud2, "contacts", self._on_contacts, 10)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)
        self.node.create_subscription(MarkerArray, "contact_markers", lambda m: self.last.__setitem__("markers", m), 10)
        self.poses = self.node.create_publisher(PoseArray, "body_poses", 10)
        self.raw = self.node.create_publisher(PoseArray, "body_poses", 10)
        self.reset = self.node.create_client(Trigger, "/contact_sim/reset")
        self.pause = self.node.create_client(SetBool, "/contact_sim/pause")
        self.step = self.node.create_client(Trigger, "/contact_sim/step")

    def _on_states(self, m):
        self.last["states"] = m
        self.count["body_states"] += 1

    def _on_contacts(self, m):
        self.last["contacts"] = m
        self.count["contacts"] += 1

    def _on_diag(self, m):
        d = cv.diagnostics_to_dict(m, DIAG_NAME)
        if d is not None:
            self.last["diag"] = d

    def diag(self, key):
        d = self.last.get("diag")
        return None if d is None else d[key]

    def send(self, p, q, stamp_ns, frame_id="world"):
        self.poses.publish(cv.arrays_to_posearray(p, q, cv.make_header(frame_id, stamp_ns)))


@pytest.fixture
def ros(monkeypatch):
    with domain_id() as dom:
        for k, v in ros_env(dom).items():
            monkeypatch.setenv(k, v)
        with ros_context(dom) as ctx:
            yield ctx


def make_node(ctx, **params):
    base = {"scene": "kinematic_paddle", "rate_hz": 50, "diagnostics_period": 0.0, "pose_timeout": 0.1,
            "velocity_decay": 0.0}
    base.update(params)
    return ContactSimNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in base.items()])


@pytest.fixture
def running(ros):
    node = make_node(ros)
    client = Client(ros)
    spin = Spinner(ros, node, client.node)
    spin.until(lambda: "names" in client.last and "diag" in client.last and "states" in client.last,
               10, "first outputs of the node")
    yield node, client, spin
    spin.shutdown()
    client.node.destroy_node()
    node.destroy_node()


def test_outputs_services_and_integer_for_double_parameter(running):
    node, client, spin = running
    assert node.get_parameter("rate_hz").value == 50  # an int accepted for a double
    assert node.period == pytest.approx(0.02)
    names = client.last["names"].data.split("\n")
    assert names == ["ground", "paddle", "ball"] == node.world.body_names
    states = client.last["states"]
    assert len(states.poses) == 3 and states.header.frame_id == "world"
    assert states.header.stamp.sec > 0  # stamped from the node clock
    spin.until(lambda: "markers" in client.last, 5, "contact markers (publish_markers is on)")
    markers = client.last["markers"].markers
    assert markers[0].action == Marker.DELETEALL and markers[1].type == Marker.SPHERE_LIST

    r = spin.call(client.step, Trigger.Request())
    assert not r.success and "not paused" in r.message
    assert spin.call(client.pause, SetBool.Request(data=True)).success
    t0 = node.world.time
    contacts_before = client.count["contacts"]
    r = spin.call(client.step, Trigger.Request())
    assert r.success, r.message
    assert node.world.time == pytest.approx(t0 + 0.02, abs=1e-12)
    spin.until(lambda: client.count["contacts"] > contacts_before, 5, "contacts of the manual step")
    spin.until(lambda: client.diag("paused") == "true", 5, "diagnostics saying paused")
    assert node.world.time == pytest.approx(t0 + 0.02, abs=1e-12)  # paused: the timer does not step

    r = spin.call(client.reset, Trigger.Request())
    assert r.success and "kinematic_paddle" in r.message
    assert node.world.time == 0.0
    np.testing.assert_array_equal(node.world.body("ball").position, [0.0, 0.0, 0.1])
    assert spin.call(client.pause, SetBool.Request(data=False)).success
    spin.until(lambda: node.world.time > 0.05, 5, "the world running again")
    ticks = int(client.diag("ticks"))
    spin.until(lambda: int(client.diag("ticks")) > ticks, 5, "diagnostics counting ticks")
    for key in ("step_time_ms", "tick_time_ms_p99", "contacts", "max_penetration_m", "energy_J",
                "solver_residual", "tick_overruns", "rejected_poses", "rejected_parameters"):
        assert key in client.last["diag"]


def test_poses_drive_the_paddle_and_it_holds_after_the_timeout(running):
    node, client, spin = running
    stamp = node.get_clock().now().nanoseconds
    x0 = -0.4
    client.send([[x0, 0.0, 0.16]], IDENTITY, stamp)
    client.send([[x0 + 0.01, 0.0, 0.16]], IDENTITY, stamp + 10_000_000)  # 1 m/s along x
    spin.until(lambda: node.counts["poses_accepted"] >= 2, 5, "two accepted poses")
    # the next tick drives it on along x (the exact drive: test_each_tick_drives_the_tracked_bodies...)
    spin.until(lambda: node.world.body("paddle").velocity[0] > 0.0, 5, "the paddle driven along x")
    v = node.world.body("paddle").velocity
    assert v[1] == v[2] == 0.0 and not node.world.body("paddle").angular_velocity.any()
    # no more poses: after pose_timeout (0.1 s) it is put back at the last pose and stops (the drive
    # may stop it before, a pose interval and a period past the last pose, where its carry ends: a
    # slow machine's ticks then reach the timeout later)
    last = [x0 + 0.01, 0.0, 0.16]
    spin.until(lambda: np.allclose(node.world.body("paddle").position, last, rtol=0.0, atol=1e-12)
               and not np.any(node.world.body("paddle").velocity), 5, "the paddle held at the last pose")
    ticks = node.counts["ticks"]
    spin.until(lambda: node.counts["ticks"] > ticks + 2, 5, "more ticks")
    np.testing.assert_allclose(node.world.body("paddle").position, last, atol=1e-12)   # and it stays there
    assert not np.any(node.world.body("paddle").velocity)


def test_bad_poses_are_rejected_counted_and_change_nothing(running):
    node, client, spin = running
    stamp = node.get_clock().now().nanoseconds
    good = np.array([[-0.4, 0.0, 0.16]])
    client.send(good, IDENTITY, stamp)
    spin.until(lambda: node.counts["poses_accepted"] == 1, 5, "the good pose")
    before = node.world.body("paddle")
    bad = [
        ("length", np.vstack([good, good]), np.vstack([IDENTITY, IDENTITY]), "world"),
        ("length", np.zeros((0, 3)), np.zeros((0, 4)), "world"),
        ("nonfinite", [[np.nan, 0.0, 0.16]], IDENTITY, "world"),
        ("nonfinite", good, [[0.0, 0.0, 0.0, np.inf]], "world"),
        ("zero_quaternion", good, [[0.0, 0.0, 0.0, 0.0]], "world"),
        ("non_unit_quaternion", good, [[0.0, 0.0, 0.0, 2.0]], "world"),
        ("frame_id", good + 0.1, IDENTITY, "map"),
    ]
    for i, (_, p, q, frame) in enumerate(bad):
        client.send(p, q, stamp + (i + 1) * 1_000_000, frame)
    client.send(good + 0.1, IDENTITY, stamp)  # not after the accepted one
    client.raw.publish(b"\x00\x01\x00\x00\x01\x02")  # serialized garbage
    spin.until(lambda: client.diag("rejected_poses") == str(len(bad) + 2), 10, "all bad poses counted")
    d = client.last["diag"]
    for reason in ("length", "nonfinite"):
        assert d["rejected_pose_" + reason] == "2"
    for reason in ("zero_quaternion", "non_unit_quaternion", "frame_id", "stamp", "malformed"):
        assert d["rejected_pose_" + reason] == "1", reason
    assert node.counts["poses_accepted"] == 1
    after = node.world.body("paddle")
    np.testing.assert_array_equal(after.orientation, before.orientation)
    assert np.all(np.isfinite(node.body_poses()[0]))
    # and the node still runs and accepts a good pose
    ticks = node.counts["ticks"]
    client.send(good + [[0.001, 0.0, 0.0]], IDENTITY, stamp + 100_000_000)
    spin.until(lambda: node.counts["poses_accepted"] == 2 and node.counts["ticks"] > ticks, 5, "recovery")


def test_poses_beyond_the_world_bounds_are_rejected_as_out_of_bounds(running):
    """A finite pose beyond settings.max_position (1e4 m), or one whose finite difference from the
    last accepted pose is faster than max_speed (1e4 m/s), is refused by the engine and counted
    under its own reason; the paddle keeps its last good pose and velocity."""
    node, client, spin = running
    stamp = node.get_clock().now().nanoseconds
    good = np.array([[-0.4, 0.0, 0.16]])
    client.send(good, IDENTITY, stamp)
    spin.until(lambda: node.counts["poses_accepted"] == 1, 5, "the good pose")
    before = node.world.body("paddle")
    client.send([[1e300, 0.0, 0.16]], IDENTITY, stamp + 1_000_000)
    client.send([[2e4, 0.0, 0.16]], IDENTITY, stamp + 2_000_000)
    client.send(good + [[1.0, 0.0, 0.0]], IDENTITY, stamp + 3_000)   # 1 m in 3 µs: 3.3e5 m/s
    spin.until(lambda: client.diag("rejected_pose_out_of_bounds") == "3", 10, "three out-of-bounds poses counted")
    d = client.last["diag"]
    assert d["rejected_poses"] == "3" and d["rejected_pose_engine"] == "0"
    assert node.counts["poses_accepted"] == 1
    after = node.world.body("paddle")
    np.testing.assert_array_equal(after.position, before.position)     # it had no velocity: it stayed
    np.testing.assert_array_equal(after.velocity, [0.0, 0.0, 0.0])
    # a pose within the bounds is still accepted
    client.send(good + [[0.001, 0.0, 0.0]], IDENTITY, stamp + 100_000_000)
    spin.until(lambda: node.counts["poses_accepted"] == 2, 5, "a good pose after the bad ones")


def test_bad_parameters_at_run_time_are_rejected_and_counted(running):
    node, client, spin = running
    world = node.world
    bad = [
        Parameter("substeps", value=0),
        Parameter("substeps", value="two"),
        Parameter("pose_timeout", value=-1.0),
        Parameter("pose_timeout", value=math.nan),
        Parameter("scene", value="/no/such/scene.yaml"),
        Parameter("tracked_bodies", value=["ball"]),
        Parameter("tracked_bodies", value=["nobody"]),
        Parameter("model.toi", value="sometimes"),
        Parameter("rate_hz", value=10.0),  # read-only
    ]
    for prm in bad:
        result = node.set_parameters([prm])[0]
        assert not result.successful, prm.name
        assert result.reason
    assert node.counts["rejected_parameters"] == len(bad)
    assert node.world is world and node.tracked == ["paddle"] and node.cfg["substeps"] == 1
    assert node.get_parameter("substeps").value == 1
    spin.until(lambda: client.diag("rejected_parameters") == str(len(bad)), 5, "diagnostics count")

    scene_toi = world.settings.toi
    assert node.set_parameters([Parameter("model.toi", value="next_step")])[0].successful
    assert world.settings.toi == "next_step"
    assert node.set_parameters([Parameter("model.toi", value="")])[0].successful
    assert world.settings.toi == scene_toi
    assert node.set_parameters([Parameter("substeps", value=3), Parameter("pose_timeout", value=2)])[0].successful
    assert node.cfg["substeps"] == 3 and node.cfg["pose_timeout"] == 2.0
    assert node.set_parameters([Parameter("tracked_bodies", value=["paddle"])])[0].successful
    assert node.world is world and node.tracked == ["paddle"]  # no scene reload for that
    t = node.world.time
    spin.until(lambda: node.world.time > t, 5, "ticks with substeps")
    assert node.counts["step_errors"] == 0


def test_bad_scene_at_start_up_is_a_clear_error(ros, tmp_path, capsys):
    scene = tmp_path / "broken.yaml"
    scene.write_text("bodies:\n  - {name: b, kind: dynamic, mass: -1, shape: {type: sphere, radius: 0.1}}\n")
    with pytest.raises(ConfigError, match=r"bodies\[0\]\.mass"):
        make_node(ros, scene=str(scene))
    with pytest.raises(ConfigError, match="tracked_bodies: unknown body 'lid'"):
        make_node(ros, tracked_bodies=["lid"])
    # the console-script entry point: message on stderr, non-zero status
    assert main(["contact_sim_node", "--ros-args", "-p", f"scene:={scene}"]) == 2
    err = capsys.readouterr().err
    assert "cannot start" in err and "bodies[0].mass" in err and str(scene) in err
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_tick_time_statistics_cover_the_last_stats_window_ticks(ros):
    node = make_node(ros, stats_window=5)
    try:
        node.timer.cancel()                 # ticks driven here, one by one
        for _ in range(12):
            node._on_timer()
        assert node.counts["ticks"] == 12
        window = node._tick_buf * 1e3       # the 5 most recent tick times, in ring order
        assert len(window) == 5 and np.all(window > 0)
        d = node.diagnostics_values()
        assert d["tick_time_ms_max"] == pytest.approx(window.max(), rel=1e-12)
        assert d["tick_time_ms_p50"] == pytest.approx(np.median(window), rel=1e-12)
        assert d["tick_time_ms_last"] == pytest.approx(node._tick_buf[(12 - 1) % 5] * 1e3, rel=1e-12)
        # the thread's CPU time in each of those ticks: positive, and never more than the wall time (the
        # CPU clock is read inside the wall clock's interval; 10 µs for the two clocks' sources and
        # resolution, under the 0.1 ms and more that a CPU interval wider than the tick would add)
        cpu = node._tick_cpu_buf * 1e3
        assert np.all(cpu > 0) and np.all(cpu <= window + 1e-2)
        assert d["tick_cpu_ms_max"] == pytest.approx(cpu.max(), rel=1e-12)
        assert d["tick_cpu_ms_p99"] == pytest.approx(np.percentile(cpu, 99), rel=1e-12)
    finally:
        node.destroy_node()
    with pytest.raises(ConfigError, match="stats_window"):
        make_node(ros, stats_window=0)


def test_an_overrun_is_told_off_cpu_when_the_tick_thread_did_not_run_for_it(ros):
    """A tick longer than the period is an overrun; it also counts as off-CPU when the thread's own
    CPU time stayed within the period (here: asleep; in the benchmark: descheduled by the OS)."""
    node = make_node(ros)
    try:
        node.timer.cancel()
        period, publish = node.period, node._publish_tick

        def asleep(*args):
            time.sleep(2 * period)
            publish(*args)

        def busy(*args):
            c0 = time.thread_time()
            while time.thread_time() - c0 < 2 * period:   # CPU time past the period, whatever the load
                pass
            publish(*args)

        warned = []
        node._warn = lambda key, text, period=1.0: warned.append((key, text))
        node._publish_tick = asleep
        node._on_timer()
        assert (node.counts["overruns"], node.counts["overruns_off_cpu"]) == (1, 1)
        assert [k for k, _ in warned] == ["overrun"] and "descheduled or blocked" in warned[0][1]
        node._publish_tick = busy
        node._on_timer()
        assert (node.counts["overruns"], node.counts["overruns_off_cpu"]) == (2, 1)
        assert [k for k, _ in warned] == ["overrun"] * 2 and "descheduled" not in warned[1][1]
        assert f"overran its {period * 1e3:.3g} ms period" in warned[1][1] and "engine step" in warned[1][1]
        d = node.diagnostics_values()
        assert (d["tick_overruns"], d["tick_overruns_off_cpu"]) == (2, 1)
        assert d["tick_cpu_ms_max"] >= 2e3 * period
    finally:
        node.destroy_node()


def test_steps_whose_solve_stopped_unconverged_are_counted_in_the_diagnostics(ros):
    """A step whose solve stopped at the iteration limit still changing (``last_solve.unconverged``)
    is counted: ``unconverged_steps`` in /diagnostics, a WARN counter (its growth since the last
    report makes the status WARN)."""
    from msg_adapters.publishing import WARN_COUNTERS

    node = make_node(ros)
    try:
        node.timer.cancel()
        world, step = node.world, node.world.step

        def unconverged(dt=None):
            step(dt)
            world.last_solve.unconverged = True

        node._on_timer()
        assert node.diagnostics_values()["unconverged_steps"] == 0
        world.step = unconverged
        node._on_timer()
        node._on_timer()
        assert node.diagnostics_values()["unconverged_steps"] == 2 * node.cfg["substeps"]
        assert "unconverged_steps" in WARN_COUNTERS
    finally:
        node.destroy_node()


def test_an_arm_driver_and_a_gripper_driver_each_move_their_own_joints(ros, tmp_path):
    """Two JointState publishers, as a ros2_control arm and a separate gripper driver: the arm's
    joint at 100 Hz, the gripper's at 20 Hz with stamps 5 ms older than the arm's latest when they
    arrive. Each joint keeps its own stamp, so none is refused, and each joint's velocity is the
    finite difference of its own stamps (one stamp for the whole robot refused 89 of ~109 gripper
    messages as out of order)."""
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header

    from robot_arm import arm_urdf, write_gripper_mesh

    node = make_node(ros)
    try:
        node.timer.cancel()
        mesh = write_gripper_mesh(tmp_path / "gripper.stl")
        node._on_robot_description(String(data=arm_urdf("file://" + mesh)))
        t0 = node.get_clock().now().nanoseconds

        def send(names, values, t_ns):
            s = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
            node._on_joint_states(JointState(header=Header(stamp=s), name=names, position=values))

        for k in range(20):                                  # 200 ms of arm messages, every 10 ms
            t = t0 + k * 10_000_000
            send(["shoulder"], [0.01 * k], t)
            if k % 5 == 4:                                    # the gripper's, 5 ms older, every 50 ms
                send(["slide", "finger_joint"], [0.002 * k, 0.5 * 0.002 * k + 0.01], t - 5_000_000)
        assert node.counts["rejected_joint_states"] == 0 and node.counts["joint_states_accepted"] == 24
        q, robot = node.world.joint_positions(), node._robot
        assert q["shoulder"] == pytest.approx(0.19) and q["slide"] == pytest.approx(0.002 * 19)
        assert robot.qd["shoulder"] == pytest.approx(1.0) and robot.qd["slide"] == pytest.approx(0.01 / 0.05)
        # a gripper message older than the gripper's own last one is refused as out of order
        send(["slide"], [0.0], t0 + 150_000_000)
        assert node.counts["rejected_joint_state_out_of_order"] == 1
    finally:
        node.destroy_node()


def test_each_tick_drives_the_links_from_where_the_last_left_them_to_the_latest_joint_state(ros, tmp_path):
    """A tick poses the links at the joint positions the last tick drove them to and moves them at
    the joint velocities that take them, over the period T, to the latest joint state carried on at
    its stamp velocity to the tick's end (at most the last stamps' interval and a period past the
    last stamp): the step carries each link ``velocity × T`` from there, whatever the stamps (two
    joint states in one tick; a tick with none moves on at the stamps' velocity; a repeated
    position stops the joint). Paused (``~/step``) and on resuming, the links are placed at the
    joint state at rest. A drive faster than the world's speed bound
    (here 2 m/s; a scene without gravity, so such a bound is valid) places the links at the goal at
    rest instead, counted in ``robot_jumps``. The node's clock is the test's."""
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header
    from std_srvs.srv import SetBool, Trigger

    from robot_arm import arm_urdf, write_gripper_mesh

    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"gravity": [0, 0, 0], "settings": {"max_speed": 2.0, "split_max_speed": 0.5},
                                     "bodies": [{"name": "ball", "shape": {"type": "sphere", "radius": 0.05},
                                                 "position": [2.0, 0, 1.0]}]}))
    node = make_node(ros, scene=str(scene), pose_timeout=60.0)
    try:
        node.timer.cancel()
        node._on_robot_description(String(data=arm_urdf("file://" + write_gripper_mesh(tmp_path / "gripper.stl"))))
        assert node._robot is not None, node._last_reason
        robot, world, T = node._robot, node.world, node.period
        idx = [world.index(b) for b in robot.bodies]
        t0 = node.get_clock().now().nanoseconds
        clock = {"ns": t0}
        node._now_ns = lambda: clock["ns"]

        def send(value, ms):
            t_ns = t0 + round(ms * 1e6)
            s = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
            node._on_joint_states(JointState(header=Header(stamp=s), name=["shoulder"], position=[value]))

        def tick(ms, start, goal):
            """A tick at ``ms``: the links leave ``start`` at (goal - start) / T, and end there + v·T."""
            clock["ns"] = t0 + round(ms * 1e6)
            q0, q1 = dict(robot.q, shoulder=start), dict(robot.q, shoulder=goal)
            p, _, v, w = robot.body_states(q0, {n: (q1[n] - q0[n]) / T for n in q1})
            node._on_timer()
            np.testing.assert_allclose(world.s.vel[idx], v, rtol=0, atol=1e-14)
            np.testing.assert_allclose(world.s.omega[idx], w, rtol=0, atol=1e-14)
            np.testing.assert_allclose(world.s.pos[idx], p + v * T, rtol=0, atol=1e-14)
            return w[:, 2].max()

        send(0.0, 0)
        assert tick(0, 0.0, 0.0) == 0.0                      # the first joint state places the links at rest
        send(0.01, 10)
        send(0.03, 20)                                       # stamp velocity 2 rad/s
        assert tick(20, 0.0, 0.07) == pytest.approx(3.5)     # to 0.03 + 2 × (20 + 20 - 20) ms
        # no joint state: on at the stamps' velocity, to at most 10 + 20 ms past the last stamp
        assert tick(40, 0.07, 0.09) == pytest.approx(1.0)
        send(0.13, 60)
        send(0.13, 70)                                       # stopped
        assert tick(70, 0.09, 0.13) == pytest.approx(2.0)
        assert tick(90, 0.13, 0.13) == 0.0
        # paused, ~/step's time is not the clock's: a step places the links at the joint state at
        # rest, and so does the first tick after resuming (never a sweep across the pause)
        node._on_pause(SetBool.Request(data=True), SetBool.Response())
        send(0.2, 200)
        send(0.2, 210)
        node._on_step(Trigger.Request(), Trigger.Response())
        assert not world.s.vel[idx].any() and not world.s.omega[idx].any()
        send(0.3, 400)
        send(0.3, 410)
        node._on_pause(SetBool.Request(data=False), SetBool.Response())
        assert tick(410, 0.3, 0.3) == 0.0
        assert node.counts["robot_jumps"] == 0
        send(1.0, 2410)                                      # 0.35 rad/s by the stamps, ~35 rad/s in one tick
        clock["ns"] = t0 + 2_410_000_000
        node._on_timer()
        assert node.counts["robot_jumps"] == 1 and node.counts["rejected_joint_states"] == 0
        goal = dict(robot.q, shoulder=1.0 + (1.0 - 0.3) / 2.0 * T)
        assert not world.s.vel[idx].any() and not world.s.omega[idx].any()
        np.testing.assert_allclose(world.s.pos[idx], robot.body_states(goal, {n: 0.0 for n in goal})[0], atol=1e-14)
        assert "robot_jumps" in node.diagnostics_values()
    finally:
        node.destroy_node()


def test_each_tick_drives_the_tracked_bodies_to_the_latest_pose_carried_on(ros, tmp_path):
    """A tick gives each tracked body the velocity and angular velocity that carry it, over the
    period T, from where it is to its latest pose carried on at the poses' stamp velocity to the
    tick's end (at most the last stamps' interval and a period past the last stamp): the step then
    takes it there, whatever the stamps (two poses in one tick; a tick with none moves on at the
    stamps' velocity; a late tick catches up by velocity, not by a jump). A first pose places the
    body. Paused (``~/step``), the bodies are placed at the pose at rest. A drive faster than the
    world's speed bound (here 5 m/s; no gravity, so such a bound is valid) places them at the goal
    at rest instead, counted in ``pose_jumps``; one whose goal is beyond the world's bounds even
    at rest stops the bodies where they are. The node's clock is the test's."""
    from contact_sim import quat

    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"gravity": [0, 0, 0], "settings": {"max_speed": 5.0, "split_max_speed": 0.5,
                                                                              "max_position": 1.1},
                                     "bodies": [{"name": "pad", "kind": "kinematic",
                                                 "shape": {"type": "box", "size": [0.1, 0.1, 0.1]},
                                                 "position": [0.0, 0.0, 1.0]}]}))
    node = make_node(ros, scene=str(scene), pose_timeout=60.0, tracked_bodies=["pad"])
    try:
        node.timer.cancel()
        world, T = node.world, node.period
        t0 = node.get_clock().now().nanoseconds
        clock = {"ns": t0}
        node._now_ns = lambda: clock["ns"]

        def send(x, angle, ms):
            q = quat.from_rotvec([0.0, 0.0, angle])
            node._handle_pose(cv.posearray_cdr(np.array([[x, 0.0, 1.0]]), q[None], "world", t0 + round(ms * 1e6)))

        def tick(ms, x, angle, vx, wz):
            """A tick at ``ms``: the pad leaves ``x, angle`` at ``vx, wz`` and ends ``T`` later on."""
            clock["ns"] = t0 + round(ms * 1e6)
            np.testing.assert_allclose(world.s.pos[0], [x, 0.0, 1.0], rtol=0, atol=1e-15)
            np.testing.assert_allclose(quat.to_rotvec(world.s.quat[0]), [0.0, 0.0, angle], rtol=0, atol=1e-15)
            node._on_timer()
            np.testing.assert_allclose(world.s.vel[0], [vx, 0.0, 0.0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(world.s.omega[0], [0.0, 0.0, wz], rtol=0, atol=1e-12)
            np.testing.assert_allclose(world.s.pos[0], [x + vx * T, 0.0, 1.0], rtol=0, atol=1e-14)
            np.testing.assert_allclose(quat.to_rotvec(world.s.quat[0]), [0.0, 0.0, angle + wz * T], rtol=0,
                                       atol=1e-14)

        assert T == 0.02
        send(0.0, 0.0, 0)                                  # a first pose places the pad
        tick(0, 0.0, 0.0, 0.0, 0.0)
        send(0.01, 0.01, 10)
        send(0.03, 0.03, 20)                               # stamp velocity 2 m/s, 2 rad/s; not placed
        tick(20, 0.0, 0.0, 3.5, 3.5)                       # to 0.03 + 2 × (20 + 20 − 20) ms over 20 ms
        # no pose: on at the stamps' velocity, to at most 10 + 20 ms past the last stamp
        tick(40, 0.07, 0.07, 1.0, 1.0)
        send(0.13, 0.13, 60)
        send(0.13, 0.13, 70)                               # stopped
        tick(70, 0.09, 0.09, 2.0, 2.0)
        tick(90, 0.13, 0.13, 0.0, 0.0)
        # poses at 1 m/s, then a tick late by one period: it catches up by velocity, not by a jump
        send(0.14, 0.13, 100)
        send(0.15, 0.13, 110)
        tick(130, 0.13, 0.13, 2.5, 0.0)                    # to 0.15 + 1 × min(130 + 20 − 110, 10 + 20) ms
        tick(150, 0.18, 0.13, 0.0, 0.0)
        # paused, ~/step's time is not the clock's: a step places the pad at the pose at rest
        node._on_pause(SetBool.Request(data=True), SetBool.Response())
        send(0.2, 0.2, 200)
        send(0.2, 0.2, 210)
        node._on_step(Trigger.Request(), Trigger.Response())
        assert not world.s.vel.any() and not world.s.omega.any()
        np.testing.assert_allclose(world.s.pos[0], [0.2, 0.0, 1.0], rtol=0, atol=1e-15)
        node._on_pause(SetBool.Request(data=False), SetBool.Response())
        assert node.counts["pose_jumps"] == 0
        send(1.0, 0.2, 2210)                               # 0.4 m/s by the stamps, ~40 m/s in one tick
        clock["ns"] = t0 + 2_210_000_000
        node._on_timer()
        assert node.counts["pose_jumps"] == 1 and node.counts["rejected_poses"] == 0
        assert not world.s.vel.any() and not world.s.omega.any()
        np.testing.assert_allclose(world.s.pos[0], [1.0 + 0.4 * T, 0.0, 1.0], rtol=0, atol=1e-14)
        assert "pose_jumps" in node.diagnostics_values()
        # a pose carried on beyond the world's bounds (max_position 1.1 m) even at rest: the pad stops
        # where it is, and its next pose places it
        send(1.05, 0.2, 2300)
        tick(2300, 1.0 + 0.4 * T, 0.2, (1.05 + 0.05 / 0.09 * 0.02 - 1.0 - 0.4 * T) / T, 0.0)
        send(1.09, 0.2, 2320)                              # 2 m/s: on to 1.17 m by a late tick's end
        clock["ns"] = t0 + 2_360_000_000
        x = world.s.pos[0, 0]
        node._on_timer()
        assert node.counts["pose_jumps"] == 2 and not world.s.vel.any() and world.s.pos[0, 0] == x
        send(1.095, 0.2, 2380)
        np.testing.assert_allclose(world.s.pos[0], [1.095, 0.0, 1.0], rtol=0, atol=1e-15)
    finally:
        node.destroy_node()


def test_every_refusal_reason_is_in_the_next_diagnostics_report(ros):
    """Three spawns refused within one period (a YAML error, a typo'd key, a clashing name): the log
    warns once (throttled, saying how many were suppressed), and /diagnostics carries each reason
    with its count since the last report, and the last one."""
    node = make_node(ros)
    try:
        node.timer.cancel()
        node._on_spawn(String(data="- {name: a, shape: {type: sphere, radius: 0.1}"))
        node._on_spawn(String(data="- {name: b, shap: {type: sphere, radius: 0.1}}"))
        node._on_spawn(String(data="- {name: paddle, shape: {type: sphere, radius: 0.1}}"))
        d = node.diagnostics_values()
        assert d["rejected_spawns"] == 3
        reasons = d["reasons.spawns"].split(" | ")
        assert len(reasons) == 3 and all(r.startswith("1× ") for r in reasons)
        assert any("not valid YAML" in r for r in reasons) and any("shap" in r for r in reasons)
        assert "paddle" in d["last_reason.spawns"]
        node._maybe_diagnostics(node._now_ns())          # a report: the next one starts afresh
        d = node.diagnostics_values()
        assert "reasons.spawns" not in d and "paddle" in d["last_reason.spawns"]
    finally:
        node.destroy_node()


def test_the_robot_stands_where_the_parameters_put_it_and_starts_quiet(ros, tmp_path):
    """robot_base_pose places the root link; the base standing on the ground and the links touching
    at the zero pose are never tested (robot_exclude_touching, the default), robot_disable_collisions
    adds 'link:body' pairs, and /diagnostics says what is excluded and why."""
    from robot_arm import arm_urdf, write_gripper_mesh

    node = make_node(ros, robot_base_pose=[2.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
                     robot_disable_collisions=["gripper:paddle"], robot_prefix="arm_")
    try:
        node.timer.cancel()
        mesh = write_gripper_mesh(tmp_path / "gripper.stl")
        node._on_robot_description(String(data=arm_urdf("file://" + mesh)))
        w = node.world
        assert np.allclose(w.body("arm_base").position, [2.0, 1.0, 0.05])
        ex = node._robot.exclusions
        assert ex[("arm_base", "ground")] == "touching at the initial configuration"
        assert ex[("arm_gripper", "paddle")] == "given"
        c = w.detect()
        assert not any("arm_" in w.body_names[i] for i in np.concatenate([c.body_a, c.body_b]))   # quiet
        d = node.diagnostics_values()["robot_exclusions"]
        assert "touching at the initial configuration: arm_base–ground" in d and "1 given: arm_gripper–paddle" in d
    finally:
        node.destroy_node()
    with pytest.raises(ConfigError, match="robot_disable_collisions: each pair is 'a:b'"):
        make_node(ros, robot_disable_collisions=["gripper"])
    with pytest.raises(ConfigError, match="robot_base_pose"):
        make_node(ros, robot_base_pose=[0.0, 0.0, 0.0])


def _in_thread(fn):
    """fn() in a new thread (SCHED_FIFO set there stays there); its result, or its exception raised."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as exc:   # re-raised in the test's thread
            out["error"] = exc
    t = threading.Thread(target=run)
    t.start()
    t.join()
    if "error" in out:
        raise out["error"]
    return out["value"]


def _fifo_allowed():
    def probe():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
            return True
        except (OSError, AttributeError):
            return False
    return _in_thread(probe)


def test_thread_priority_runs_the_spinning_thread_under_sched_fifo(ros):
    node = make_node(ros, thread_priority=50)
    try:
        assert node.diagnostics_values()["thread_priority"] == 0       # not yet: the process's owner sets it
        allowed = _fifo_allowed()   # as root or with CAP_SYS_NICE (this project's CI); else the refusal
        got = _in_thread(lambda: (node.set_thread_priority(), os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))
        want = 50 if allowed else 0
        assert got == (want, os.SCHED_FIFO if allowed else os.SCHED_OTHER, want)
        assert node.diagnostics_values()["thread_priority"] == want
        assert os.sched_getscheduler(0) == os.SCHED_OTHER              # only the calling thread changed
    finally:
        node.destroy_node()


def test_thread_priority_refused_warns_and_keeps_the_normal_scheduler(ros, monkeypatch):
    node = make_node(ros, thread_priority=50)
    warnings = []
    try:
        def refuse(*args):
            raise PermissionError(1, "Operation not permitted")
        monkeypatch.setattr(os, "sched_setscheduler", refuse)
        monkeypatch.setattr(node, "get_logger", lambda: type("L", (), {"warning": staticmethod(warnings.append)})())
        assert _in_thread(node.set_thread_priority) == 0
        assert node.diagnostics_values()["thread_priority"] == 0
        assert len(warnings) == 1 and "thread_priority" in warnings[0] and "Operation not permitted" in warnings[0]
    finally:
        node.destroy_node()
    # the default, 0, asks for nothing; out of range is a clear error
    default = make_node(ros)
    try:
        assert _in_thread(default.set_thread_priority) == 0
    finally:
        default.destroy_node()
    with pytest.raises(ConfigError, match=r"thread_priority"):
        make_node(ros, thread_priority=100)
