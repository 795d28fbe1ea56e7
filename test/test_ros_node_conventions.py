"""The node as ROS users expect it (issue 15), in process: sim time and clock jumps, one stamp per
tick, /clock from the world, RViz-displayable contacts, body states with names, twists and contact
wrenches, markers cleared, dropped poses counted, QoS overrides, diagnostics names, run-time body
control, and engine failures reported as errors. Own rclpy.Context and ROS domain per test; ticks
are driven by hand where timing matters."""
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PoseArray, Transform, Twist  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data)  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import MultiDOFJointState, PointCloud2, PointField  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

import contact_sim  # noqa: E402
from msg_adapters import conversions as cv  # noqa: E402
from msg_adapters.node import ConfigError, ContactSimNode  # noqa: E402
from msg_adapters.testing import Spinner, ros_context, ros_env  # noqa: E402

IDENTITY = np.array([[0.0, 0.0, 0.0, 1.0]])
S = 1_000_000_000


class Client:
    """Every output of the node (lists of messages), its inputs as publishers."""

    def __init__(self, ctx, ns="/contact_sim"):
        self.node = rclpy.create_node("client", context=ctx)
        self.got = {k: [] for k in ("contacts", "states", "multidof", "markers", "diag", "clock", "names")}
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        sub = self.node.create_subscription
        sub(String, "body_names", self._keep("names"), latched)
        sub(PointCloud2, "contacts", self._keep("contacts"), 100)
        sub(PoseArray, "body_states", self._keep("states"), 100)
        sub(MultiDOFJointState, "body_multidof_states", self._keep("multidof"), 100)
        sub(MarkerArray, "contact_markers", self._keep("markers"), 100)
        sub(DiagnosticArray, "/diagnostics", self._keep("diag"), 100)
        sub(Clock, "/clock", self._keep("clock"), 100)
        self.poses = self.node.create_publisher(PoseArray, "body_poses", 10)
        self.clock = self.node.create_publisher(Clock, "/clock", 10)
        self.set_states = self.node.create_publisher(MultiDOFJointState, ns + "/set_body_states", 10)
        self.spawn = self.node.create_publisher(String, ns + "/spawn", 10)
        self.delete = self.node.create_publisher(String, ns + "/delete", 10)

    def _keep(self, key):
        return lambda m: self.got[key].append(m)

    def last(self, key):
        return self.got[key][-1] if self.got[key] else None

    def diag(self, name="contact_sim: world"):
        for m in reversed(self.got["diag"]):
            for s in m.status:
                if s.name == name:
                    return s
        return None

    def send(self, p, stamp_ns, q=IDENTITY):
        self.poses.publish(cv.arrays_to_posearray(p, q, cv.make_header("world", stamp_ns)))

    def tick_clock(self, seconds):
        self.clock.publish(Clock(clock=Time(sec=int(seconds), nanosec=int(round((seconds % 1) * 1e9)))))


@pytest.fixture
def ros(monkeypatch):
    from domain_coordinator import domain_id

    with domain_id() as dom:
        for k, v in ros_env(dom).items():
            monkeypatch.setenv(k, v)
        with ros_context(dom) as ctx:
            yield ctx


def make_node(ctx, name=None, **params):
    base = {"scene": "kinematic_paddle", "rate_hz": 50.0, "diagnostics_period": 0.0, "pose_timeout": 0.1,
            "velocity_decay": 0.0}
    base.update(params)
    kw = {"cli_args": ["--ros-args", "-r", f"__node:={name}"]} if name else {}
    return ContactSimNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in base.items()], **kw)


@pytest.fixture
def manual(ros):
    """A node whose ticks are driven by the test (timer cancelled), and a client."""
    made = []

    def start(**params):
        node = make_node(ros, **params)
        node.timer.cancel()
        client = Client(ros)
        spin = Spinner(ros, node, client.node)
        spin.until(lambda: client.got["names"], 10, "body_names")
        made.append((node, client, spin))
        return node, client, spin

    yield start
    for node, client, spin in made:
        spin.shutdown()
        client.node.destroy_node()
        node.destroy_node()


def tick(node, spin, client, key="states"):
    n = len(client.got[key])
    node._on_timer()
    spin.until(lambda: len(client.got[key]) > n, 5, f"{key} of the tick")


def stamp_ns(msg):
    return cv.stamp_to_ns(msg.header.stamp)


# ---------------------------------------------------------------------------- time
def test_sim_time_clock_jump_back_resets_pose_history_and_diagnostics_go_on(manual):
    node, client, spin = manual(use_sim_time=True, diagnostics_period=1.0)
    client.tick_clock(100.0)
    spin.until(lambda: node.get_clock().now().nanoseconds == 100 * S, 5, "sim time 100 s")
    client.send([[-0.4, 0.0, 0.16]], 99 * S)
    client.send([[-0.39, 0.0, 0.16]], 101 * S)
    spin.until(lambda: node.counts["poses_accepted"] == 2, 5, "two poses")
    tick(node, spin, client, "diag")
    client.tick_clock(102.5)
    spin.until(lambda: node.get_clock().now().nanoseconds == 102_500_000_000, 5, "sim time 102.5 s")
    tick(node, spin, client, "diag")
    client.tick_clock(50.0)                     # back: a restarted simulation, a looped bag
    spin.until(lambda: node.counts["clock_jumps_back"] == 1, 5, "the jump seen")
    client.send([[-0.3, 0.0, 0.16]], 10_300_000_000)
    spin.until(lambda: node.counts["poses_accepted"] == 3, 5, "a pose stamped before the old ones, accepted")
    assert node.counts["rejected_poses"] == 0
    np.testing.assert_array_equal(node.world.body("paddle").position, [-0.3, 0.0, 0.16])
    tick(node, spin, client, "diag")            # not silent although the clock is behind the last report
    d = cv.diagnostics_to_dict(client.last("diag"))
    assert d["clock_jumps_back"] == "1" and d["rejected_poses"] == "0"
    assert client.diag().level == DiagnosticStatus.WARN and "clock jumps back: 1" in client.diag().message
    n = len(client.got["diag"])
    client.tick_clock(50.5)
    spin.until(lambda: node.get_clock().now().nanoseconds == 50_500_000_000, 5, "50.5 s")
    node._on_timer()                            # within the 1 s period: no report
    spin.until(lambda: len(client.got["states"]) > 3, 5, "states")
    assert len(client.got["diag"]) == n


def test_sim_time_zero_stamps_within_one_clock_tick_take_the_latest(manual):
    node, client, spin = manual(use_sim_time=True)
    client.tick_clock(60.0)
    spin.until(lambda: node.get_clock().now().nanoseconds == 60 * S, 5, "sim time 60 s")
    for x in (-0.3, -0.2, -0.1):                # three poses, "time of receipt", one clock instant
        client.send([[x, 0.0, 0.16]], 0)
    spin.until(lambda: node.counts["poses_received"] == 3, 5, "three poses")
    assert node.counts["rejected_poses"] == 0
    assert node.counts["poses_accepted"] == 1 and node.counts["poses_superseded"] == 1
    client.tick_clock(60.02)
    spin.until(lambda: node.get_clock().now().nanoseconds == 60_020_000_000, 5, "the clock moves")
    node._on_timer()                            # the latest is applied with the tick's time
    assert node.counts["poses_accepted"] == 2
    w = node.world
    i = w.index("paddle")
    np.testing.assert_allclose(w.s.pose_vel[i], [0.2 / 0.02, 0, 0], rtol=1e-9)   # over the tick's 0.02 s
    # and the tick drove the paddle from the first pose to the latest carried on to its end
    np.testing.assert_allclose(w.s.vel[i], [(-0.1 + 10.0 * 0.02 + 0.3) / 0.02, 0, 0], rtol=1e-9)
    tick(node, spin, client, "diag")
    assert cv.diagnostics_to_dict(client.last("diag"))["rejected_pose_stamp"] == "0"


def test_one_stamp_per_tick_and_publish_clock_gives_world_time_even_when_ticks_run_slow(manual):
    node, client, spin = manual(publish_clock=True)
    for k in range(1, 4):
        time.sleep(0.05)                        # 2.5 periods of wall time per tick
        tick(node, spin, client, "multidof")
        spin.until(lambda: len(client.got["clock"]) >= k and len(client.got["contacts"]) >= k, 5, "clock, contacts")
        world_ns = round(node.world.time * 1e9)
        assert world_ns == k * 20_000_000
        for key in ("contacts", "states", "multidof"):
            assert stamp_ns(client.last(key)) == world_ns, key
        assert cv.stamp_to_ns(client.last("clock").clock) == world_ns
        assert stamp_ns(client.last("markers").markers[1]) == world_ns
    with pytest.raises(ConfigError, match="publish_clock and use_sim_time"):
        make_node(client.node.context, name="other", publish_clock=True, use_sim_time=True)


def test_stamps_of_one_tick_agree_on_the_node_clock(manual):
    node, client, spin = manual()
    tick(node, spin, client, "multidof")
    spin.until(lambda: client.got["contacts"] and client.got["states"], 5, "outputs")
    spin.until(lambda: client.got["diag"], 5, "diagnostics")
    stamps = {key: stamp_ns(client.last(key)) for key in ("contacts", "states", "multidof")}
    assert len(set(stamps.values())) == 1, stamps
    assert client.last("diag").header.frame_id == ""


# ---------------------------------------------------------------------------- outputs
def test_contacts_cloud_has_float32_xyz_for_rviz_and_exact_points(manual):
    node, client, spin = manual()
    tick(node, spin, client, "contacts")
    msg = client.last("contacts")
    fields = {f.name: f for f in msg.fields}
    assert all(fields[a].datatype == PointField.FLOAT32 for a in "xyz")
    c = cv.pointcloud2_to_contacts(msg)
    assert len(c) > 0
    np.testing.assert_array_equal(c.point, node.contacts.point)      # bit-exact through point_*
    a = cv.pointcloud2_to_array(msg)
    np.testing.assert_array_equal(a["x"], node.contacts.point[:, 0].astype(np.float32))


def test_multidof_states_carry_names_poses_twists_and_contact_wrenches(manual):
    node, client, spin = manual()
    node.world.set_state("paddle", velocity=[0.5, 0, 0], angular_velocity=[0, 0, 0.25])
    for _ in range(5):
        tick(node, spin, client, "multidof")
    m = client.last("multidof")
    assert list(m.joint_names) == node.world.body_names == ["ground", "paddle", "ball"]
    p, q = node.world.poses()
    v, w = node.world.velocities()
    names, p2, q2, v2, w2 = cv.multidof_to_arrays(m)
    np.testing.assert_array_equal(p2, p)
    np.testing.assert_array_equal(q2, q)
    np.testing.assert_array_equal(v2, v)          # primitives: origin = centre of mass
    np.testing.assert_array_equal(w2, w)
    assert v2[1, 0] == 0.5 and w2[1, 2] == 0.25
    # the ball rests on the ground: the contact force on it carries its weight, the ground's the opposite
    f = np.array([(x.force.x, x.force.y, x.force.z) for x in m.wrench])
    np.testing.assert_allclose(f[2], [0, 0, 0.5 * 9.81], rtol=1e-3, atol=1e-6)
    np.testing.assert_allclose(f[0], -f[2], atol=1e-9)
    np.testing.assert_array_equal(f[1], 0.0)
    torque = np.array([(x.torque.x, x.torque.y, x.torque.z) for x in m.wrench])
    np.testing.assert_allclose(torque[2], 0.0, atol=1e-9)     # under its centre: no torque


def test_markers_cleared_when_turned_off_and_at_shutdown(manual):
    node, client, spin = manual()
    tick(node, spin, client, "markers")
    assert len(client.last("markers").markers) >= 2
    n = len(client.got["markers"])
    assert node.set_parameters([Parameter("publish_markers", value=False)])[0].successful
    spin.until(lambda: len(client.got["markers"]) > n, 5, "DELETEALL")
    (only,) = client.last("markers").markers
    assert only.action == Marker.DELETEALL
    tick(node, spin, client, "states")
    assert len(client.got["markers"]) == n + 1      # off: no more markers
    assert node.set_parameters([Parameter("publish_markers", value=True)])[0].successful
    tick(node, spin, client, "markers")
    n = len(client.got["markers"])
    node.close_outputs()
    spin.until(lambda: len(client.got["markers"]) > n, 5, "DELETEALL at shutdown")
    assert [m.action for m in client.last("markers").markers] == [Marker.DELETEALL]


def test_queue_drops_are_counted_from_sequence_gaps(manual):
    node, client, spin = manual(pose_timeout=100.0, diagnostics_period=0.0)   # diagnostics every tick
    burst = 2500                                 # more than the subscription's depth of 1000
    pub = client.node.create_publisher(PoseArray, "body_poses", QoSProfile(depth=burst))
    # the node learns the count from the middleware's matched events, as the executor delivers them
    spin.until(lambda: node._pose_publishers == 2, 5, "the client's two publishers matched")
    assert node.count_publishers("/body_poses") == 2   # gaps cannot be counted: the sequences interleave
    client.node.destroy_publisher(client.poses)
    spin.until(lambda: node._pose_publishers == 1, 5, "one publisher left")
    assert node.count_publishers("/body_poses") == 1
    msg = cv.arrays_to_posearray([[-0.4, 0.0, 0.16]], IDENTITY, cv.make_header("world", 0))
    base = node.get_clock().now().nanoseconds

    def publish(k):
        msg.header.stamp = cv.ns_to_stamp(base + k * 1000)
        msg.poses[0].position.x = -0.4 + 1e-6 * k
        pub.publish(msg)

    publish(0)                                   # the stream has started: its sequence is known
    spin.until(lambda: node.counts["poses_received"] == 1, 5, "the first pose")
    for k in range(1, burst + 1):                # published without spinning: the queue overflows
        publish(k)
    spin.until(lambda: node.counts["poses_received"] + node.counts["poses_dropped"] == burst + 1, 10, "the burst")
    c = node.counts
    assert 0 < c["poses_dropped"] < burst and c["poses_accepted"] == c["poses_received"]
    # the last one came (recorded: the next tick drives the paddle there)
    np.testing.assert_allclose(node.world.s.pose_pos[node.world.index("paddle"), 0], -0.4 + 1e-6 * burst)
    node._on_timer()
    # earlier ticks' diagnostics may still be in flight under load: wait for this tick's own
    spin.until(lambda: client.last("diag") is not None and cv.diagnostics_to_dict(client.last("diag")).get(
        "poses_dropped") == str(c["poses_dropped"]), 5, "the diagnostics of the burst")
    d = cv.diagnostics_to_dict(client.last("diag"))
    assert d["pose_publishers"] == "1"
    assert client.diag().level == DiagnosticStatus.WARN and "poses dropped" in client.diag().message


def test_best_effort_publishers_match_and_qos_is_overridable(ros):
    node = make_node(ros)
    other = make_node(ros, name="reliable_sim", **{"qos_overrides./body_poses.subscription.reliability": "reliable"})
    try:
        assert node.sub_poses.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
        assert other.sub_poses.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        client = rclpy.create_node("driver", context=ros)
        sensor = client.create_publisher(PoseArray, "body_poses", qos_profile_sensor_data)   # a driver's QoS
        spin = Spinner(ros, node, client)
        spin.until(lambda: sensor.get_subscription_count() >= 1, 5, "best effort publisher matched")
        assert sensor.get_subscription_count() == 1      # not the reliable-only override
        stamp = node.get_clock().now().nanoseconds
        sensor.publish(cv.arrays_to_posearray([[-0.4, 0.0, 0.16]], IDENTITY, cv.make_header("world", stamp)))
        spin.until(lambda: node.counts["poses_accepted"] == 1, 5, "the pose")
        spin.shutdown()
        client.destroy_node()
    finally:
        other.destroy_node()
        node.destroy_node()
    with pytest.raises(ConfigError, match="QoS override"):
        make_node(ros, name="bad_qos", **{"qos_overrides./body_poses.subscription.reliability": "sometimes"})


def test_two_nodes_are_told_apart_in_diagnostics(ros):
    a, b = make_node(ros, name="sim_a"), make_node(ros, name="sim_b")
    client = Client(ros)
    spin = Spinner(ros, a, b, client.node)
    try:
        spin.until(lambda: client.diag("sim_a: world") and client.diag("sim_b: world"), 10, "both statuses")
        sa, sb = client.diag("sim_a: world"), client.diag("sim_b: world")
        assert (sa.hardware_id, sb.hardware_id) == ("/sim_a", "/sim_b")
        assert all(m.header.frame_id == "" for m in client.got["diag"])
    finally:
        spin.shutdown()
        client.node.destroy_node()
        a.destroy_node()
        b.destroy_node()


# ---------------------------------------------------------------------------- body control
def body_states_msg(names, transforms=(), twists=()):
    m = MultiDOFJointState(joint_names=list(names))
    for p, q in transforms:
        t = Transform()
        t.translation.x, t.translation.y, t.translation.z = map(float, p)
        t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = map(float, q)
        m.transforms.append(t)
    for v, w in twists:
        t = Twist()
        t.linear.x, t.linear.y, t.linear.z = map(float, v)
        t.angular.x, t.angular.y, t.angular.z = map(float, w)
        m.twist.append(t)
    return m


def test_set_body_states_teleports_drives_kinematic_by_velocity_and_refuses_whole(manual):
    node, client, spin = manual()
    world = node.world
    before = world.s.copy()
    bad = [
        body_states_msg(["ball", "ghost"], twists=[([1, 0, 0], [0, 0, 0])] * 2),          # unknown name
        body_states_msg(["ball", "ground"], twists=[([1, 0, 0], [0, 0, 0])] * 2),         # static
        body_states_msg(["ball", "paddle"], twists=[([1, 0, 0], [0, 0, 0])]),             # one twist for two
        body_states_msg(["ball"], transforms=[([0, 0, np.nan], [0, 0, 0, 1])]),           # NaN
        body_states_msg(["ball"], transforms=[([0, 0, 1], [0, 0, 0, 3])]),                # not a rotation
        body_states_msg(["ball"], twists=[([0, np.inf, 0], [0, 0, 0])]),                  # inf
    ]
    for m in bad:
        client.set_states.publish(m)
    spin.until(lambda: node.counts["rejected_body_states"] == len(bad), 5, "all refused")
    for name in before.NAMES:
        np.testing.assert_array_equal(getattr(world.s, name), getattr(before, name), err_msg=name)
    # teleport the ball, drive the paddle (tracked, kinematic) by velocity
    client.set_states.publish(body_states_msg(["ball"], transforms=[([0.5, 0.0, 0.1], [0, 0, 0, 1])]))
    client.set_states.publish(body_states_msg(["paddle"], twists=[([1.0, 0, 0], [0, 0, 0])]))
    spin.until(lambda: node.counts["body_states_set"] == 2, 5, "both applied")
    np.testing.assert_array_equal(world.body("ball").position, [0.5, 0.0, 0.1])
    x0 = world.body("paddle").position[0]
    for _ in range(10):                         # 0.2 s: beyond pose_timeout (0.1 s), not held back
        node._on_timer()
    np.testing.assert_allclose(world.body("paddle").position[0], x0 + 0.2, atol=1e-12)
    tick(node, spin, client, "diag")
    d = cv.diagnostics_to_dict(client.last("diag"))
    assert d["rejected_body_states"] == str(len(bad)) and d["body_states_set"] == "2"


def test_spawn_and_delete_are_atomic_and_visible(manual):
    node, client, spin = manual()
    good = ("- {name: box1, shape: {type: box, size: [0.2, 0.2, 0.2]}, mass: 1.0, position: [1.0, 0, 0.5]}\n"
            "- {name: rock, shape: {type: sphere, radius: 0.05}, density: 2000, position: [1.5, 0, 0.3]}\n")
    client.spawn.publish(String(data=good))
    spin.until(lambda: node.counts["spawned_bodies"] == 2, 5, "two bodies spawned")
    spin.until(lambda: client.last("names").data.split("\n") == ["ground", "paddle", "ball", "box1", "rock"], 5,
               "body_names updated")
    bad_spawns = [
        "- {name: box2, shape: {type: sphere, radius: 0.1}}\n- {name: box3, shape: {type: sphere, radius: -1}}",
        "- {name: ball, shape: {type: sphere, radius: 0.1}}",              # duplicate name
        "[unclosed", "42",
    ]
    for text in bad_spawns:
        client.spawn.publish(String(data=text))
    spin.until(lambda: node.counts["rejected_spawns"] == len(bad_spawns), 5, "bad spawns refused")
    assert "box2" not in node.world.body_names and len(node.world) == 5
    for text in ("ghost", "ball\nghost", "paddle", "\n"):               # unknown, partly unknown, tracked, empty
        client.delete.publish(String(data=text))
    spin.until(lambda: node.counts["rejected_deletes"] == 4, 5, "bad deletes refused")
    assert len(node.world) == 5
    client.delete.publish(String(data="ball\n box1 \n"))
    spin.until(lambda: node.counts["deleted_bodies"] == 2, 5, "deleted")
    spin.until(lambda: client.last("names").data == "ground\npaddle\nrock", 5, "names after delete")
    for _ in range(3):
        tick(node, spin, client, "multidof")
    assert list(client.last("multidof").joint_names) == ["ground", "paddle", "rock"]
    stamp = node.get_clock().now().nanoseconds
    client.send([[-0.4, 0.0, 0.16]], stamp)     # the paddle is still driven, at its new index
    spin.until(lambda: node.counts["poses_accepted"] == 1, 5, "a pose")
    tick(node, spin, client, "diag")
    d = cv.diagnostics_to_dict(client.last("diag"))
    assert (d["spawned_bodies"], d["rejected_spawns"], d["deleted_bodies"], d["rejected_deletes"], d["bodies"]) == \
        ("2", "4", "2", "4", "3")


def test_engine_step_error_is_an_error_in_diagnostics_and_the_world_is_kept(manual, monkeypatch):
    node, client, spin = manual()
    tick(node, spin, client, "diag")
    world = node.world
    before, t, warm = world.s.copy(), world.time, world.contact_cache.warm
    assert warm is not None                # the node's scene rests: warm starts to keep

    def broken(dt=None):
        world.s.pos[2] = np.nan                  # what a half-done step could leave
        world.contact_cache.warm = None
        raise contact_sim.ContactSimError("step: non-finite state of body 'ball' (velocity)")

    monkeypatch.setattr(world, "step", broken)
    n = len(client.got["diag"])
    node._on_timer()
    spin.until(lambda: len(client.got["diag"]) > n, 5, "diagnostics of the failed tick")
    status = client.diag()
    assert status.level == DiagnosticStatus.ERROR
    assert "non-finite state of body 'ball'" in status.message
    d = cv.diagnostics_to_dict(client.last("diag"))
    assert d["step_errors"] == "1" and "non-finite" in d["last_step_error"]
    np.testing.assert_array_equal(world.s.pos, before.pos)
    assert world.time == t
    for x, y in zip(world.contact_cache.warm, warm):   # warm starts as they were (World.restore)
        np.testing.assert_array_equal(x, y)
    monkeypatch.undo()
    tick(node, spin, client, "diag")             # and the node goes on
    assert world.time > t and client.diag().level != DiagnosticStatus.ERROR


def test_the_node_process_freezes_its_heap_and_a_new_scene_frees_the_old_world(ros):
    """``launch.main`` freezes the heap once the node is built (a full collection of the node's
    objects takes tens of milliseconds, tens of ticks at 1 kHz); a scene reload refreezes after a
    collection, so the old world's reference cycles are freed, not kept frozen forever."""
    import gc
    import weakref

    node = make_node(ros)
    try:
        node.world.held_by_a_cycle = [node.world]      # refcounts alone would never free it
        node.freeze_heap()
        assert gc.get_freeze_count() > 1000
        old = weakref.ref(node.world)
        assert node.set_parameters([Parameter("scene", value="box_stack")])[0].successful
        assert node.world is not old() and old() is None    # collected, though it was frozen
        assert gc.get_freeze_count() > 1000
    finally:
        gc.unfreeze()            # the test process goes on as it was
        node.destroy_node()


def test_without_matched_events_the_node_counts_pose_publishers_every_tick(ros, monkeypatch):
    """A middleware without the subscription matched event: the node still starts, and asks for the
    publishers' count each tick instead."""
    from rclpy.event_handler import UnsupportedEventTypeError

    real = ContactSimNode.create_subscription

    def no_matched_events(self, *args, event_callbacks=None, **kwargs):
        if event_callbacks is not None and event_callbacks.matched is not None:
            raise UnsupportedEventTypeError("matched events are not supported")
        return real(self, *args, event_callbacks=event_callbacks, **kwargs)

    monkeypatch.setattr(ContactSimNode, "create_subscription", no_matched_events)
    node = make_node(ros)
    try:
        node.timer.cancel()
        assert node._poll_publishers
        client = Client(ros)
        spin = Spinner(ros, node, client.node)
        spin.until(lambda: node.count_publishers("/body_poses") == 1, 5, "the client's publisher")
        node._on_timer()
        assert node._pose_publishers == 1
        spin.shutdown()
        client.node.destroy_node()
    finally:
        node.destroy_node()
