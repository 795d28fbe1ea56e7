"""The node in its own process builds a robot from robot_description and follows joint_states sent from
this process: the gripper link's contact with a box is published under its name; unknown joints and
out-of-order joint states are counted in /diagnostics."""
import os
import signal
import subprocess
import sys

import pytest
import yaml

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from domain_coordinator import domain_id  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState, PointCloud2  # noqa: E402
from std_msgs.msg import Header, String  # noqa: E402

from msg_adapters import conversions as cv  # noqa: E402
from msg_adapters.node import DIAG_NAME  # noqa: E402
from msg_adapters.testing import Spinner, ros_context, ros_env  # noqa: E402
from robot_arm import SHOULDER_Z, arm_urdf, write_gripper_mesh  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def stamp(ns):
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def test_node_builds_the_robot_and_reports_the_gripper_touching_a_box(tmp_path, monkeypatch):
    scene = {"gravity": [0, 0, 0],
             "bodies": [{"name": "obstacle", "kind": "static", "shape": {"type": "box", "size": [0.15, 0.1, 0.2]},
                         "position": [0.5, 0.17, SHOULDER_Z]}]}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(scene))
    urdf = arm_urdf(write_gripper_mesh(tmp_path / "grip.stl"))
    with domain_id() as dom:
        env = ros_env(dom)
        # the node runs this source tree's code (not another checkout installed in the environment)
        repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        env["PYTHONPATH"] = os.pathsep.join([repo] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
        for k, v in env.items():
            monkeypatch.setenv(k, v)
        cmd = [sys.executable, "-m", "msg_adapters", "--ros-args", "-p", f"scene:={tmp_path / 'scene.yaml'}",
               "-p", "rate_hz:=50.0", "-p", "diagnostics_period:=0.0", "-p", "robot_prefix:=arm_",
               "-p", "pose_timeout:=5.0"]
        log = open(tmp_path / "node.log", "w+")
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)
        try:
            with ros_context(dom) as ctx:
                node = rclpy.create_node("robot_client", context=ctx)
                got = {"names": None, "contacts": [], "diag": None}
                node.create_subscription(String, "body_names", lambda m: got.update(names=m.data.split("\n")), LATCHED)
                node.create_subscription(PointCloud2, "contacts", got["contacts"].append, 50)

                def on_diag(m):
                    d = cv.diagnostics_to_dict(m, DIAG_NAME)
                    if d is not None:
                        got["diag"] = d

                node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
                desc = node.create_publisher(String, "robot_description", LATCHED)
                joints = node.create_publisher(JointState, "joint_states", 10)
                spin = Spinner(ctx, node)
                desc.publish(String(data=urdf))      # before the node is up: transient local delivers it
                spin.until(lambda: got["names"] is not None and "arm_gripper" in got["names"], 60.0,
                           "the robot's links in body_names")
                assert got["names"] == ["obstacle", "arm_base", "arm_base#1", "arm_upper", "arm_gripper", "arm_finger"]
                spin.until(lambda: joints.get_subscription_count() > 0, 20.0, "the node on joint_states")

                def send(names, positions, t_ns):
                    joints.publish(JointState(header=Header(stamp=stamp(t_ns), frame_id=""), name=names,
                                              position=[float(x) for x in positions]))

                # sweep the shoulder towards the box until its contact is published
                theta = [0.0]

                def gripper_contact():
                    for m in got["contacts"]:
                        c = cv.pointcloud2_to_contacts(m)
                        for a, b in zip(c.body_a, c.body_b):
                            if {got["names"][a], got["names"][b]} == {"arm_gripper", "obstacle"}:
                                return True
                    theta[0] = min(theta[0] + 0.01, 0.3)
                    send(["arm_shoulder", "arm_slide", "arm_finger_joint", "wheel"], [theta[0], 0.05, 0.035, 1.0],
                         node.get_clock().now().nanoseconds)
                    spin.executor.spin_once(timeout_sec=0.02)
                    return False

                spin.until(gripper_contact, 60.0, "a contact between arm_gripper and obstacle")
                assert 0.2 < theta[0] <= 0.3           # the geometric touch angle is 0.2155 rad
                # an out-of-order joint state is refused and counted; the unknown 'wheel' was counted
                send(["arm_shoulder"], [0.0], 1_000_000)
                spin.until(lambda: got["diag"] is not None
                           and int(got["diag"]["rejected_joint_state_out_of_order"]) >= 1
                           and int(got["diag"]["joint_states_unknown_joints"]) >= 1, 30.0, "the joint-state counters")
                assert int(got["diag"]["joint_states_accepted"]) >= 1 and int(got["diag"]["robot_descriptions"]) == 1
                # a description the engine refuses keeps the robot; a new one replaces it, the rest stays
                desc.publish(String(data=urdf.replace('radius="0.004"', 'radius="-1"')))
                spin.until(lambda: int(got["diag"]["rejected_robot_descriptions"]) >= 1, 30.0, "the refusal")
                assert got["names"][-1] == "arm_finger"
                finger = urdf.index('<link name="finger">')
                smaller = urdf[:finger] + urdf[urdf.index("</link>", finger) + 7:]
                smaller = smaller[:smaller.index('<joint name="finger_joint"')] + \
                    smaller[smaller.index("</joint>", smaller.index('<joint name="finger_joint"')) + 8:]
                desc.publish(String(data=smaller))
                spin.until(lambda: got["names"] == ["obstacle", "arm_base", "arm_base#1", "arm_upper", "arm_gripper"],
                           30.0, "body_names without the finger")
                spin.until(lambda: int(got["diag"]["robot_descriptions"]) == 2, 30.0, "the second description counted")
                # an SRDF: its pairs are never tested (the robot is rebuilt with them); one naming an
                # unknown link is refused
                semantic = node.create_publisher(String, "robot_description_semantic", LATCHED)
                semantic.publish(String(data='<robot name="arm"><disable_collisions link1="elbow" link2="base"/></robot>'))
                spin.until(lambda: int(got["diag"]["rejected_robot_descriptions"]) >= 2, 30.0, "the bad SRDF refused")
                semantic.publish(String(data='<robot name="arm"><disable_collisions link1="gripper" link2="base"/>'
                                             '</robot>'))
                spin.until(lambda: int(got["diag"]["robot_semantic_descriptions"]) == 1, 30.0, "the SRDF taken")
                spin.shutdown()
                node.destroy_node()
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=20) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
            log.seek(0)
            out = log.read()
            log.close()
        assert "robot 'arm_arm': 5 link bodies" in out, out[-3000:]
        # the adjacent pairs of the 4-link robot, then those and the SRDF's (gripper, base): two bodies of base
        assert "(arm_base, arm_base#1, arm_upper, arm_gripper); 4 body pairs never tested" in out, out[-3000:]
        assert "(arm_base, arm_base#1, arm_upper, arm_gripper); 6 body pairs never tested" in out, out[-3000:]


def test_robot_links_are_not_tracked_by_default(tmp_path):
    import contact_sim as cs
    from msg_adapters.config import resolve_tracked

    (tmp_path / "arm.urdf").write_text(arm_urdf(write_gripper_mesh(tmp_path / "grip.stl")))
    scene = {"bodies": [{"name": "paddle", "kind": "kinematic", "shape": {"type": "box", "size": [0.1, 0.1, 0.1]}}],
             "robots": [{"urdf": "arm.urdf"}]}
    world = cs.load_scene(scene, base_dir=str(tmp_path))
    assert resolve_tracked(world, [], "scene")[0] == ["paddle"]
    assert "robot arm: 5 link bodies, 2 joints" in world.describe()
