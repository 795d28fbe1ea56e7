"""Driving the node from Python: publish poses of a kinematic body, read the contacts back.

Start the node on the shipped paddle scene (a kinematic paddle, a ball on the ground), then run this
client on the same ROS domain:

    python -m msg_adapters --ros-args -p scene:=kinematic_paddle -p tracked_bodies:="[paddle]"
    python examples/drive_node.py

It sweeps the paddle (0.05 m thick) along +x at 0.5 m/s into the ball on ``body_poses`` (geometry_msgs/PoseArray: pose i drives
``tracked_bodies[i]``), reads ``contacts`` (sensor_msgs/PointCloud2, one point per contact) and the
latched ``body_names`` (which name ``body_a``/``body_b`` index), and prints the first contact
between the paddle and the ball, with its impulse. Exits 0 then, 1 after ``--timeout`` seconds.
"""
import argparse
import sys
import time

import rclpy
from geometry_msgs.msg import Pose, PoseArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String

from msg_adapters.conversions import pointcloud2_to_contacts

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=0.5, help="paddle speed along +x (m/s)")
    ap.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds")
    args = ap.parse_args()

    rclpy.init()
    node = rclpy.create_node("paddle_driver")
    got = {"names": None, "hit": None}
    node.create_subscription(String, "body_names", lambda m: got.update(names=m.data.split("\n")), LATCHED)

    def on_contacts(msg):
        if got["names"] is None or got["hit"] is not None:
            return
        c = pointcloud2_to_contacts(msg)            # contact_sim.Contacts, bit for bit from the float64 fields
        for k in range(len(c.depth)):
            pair = {got["names"][c.body_a[k]], got["names"][c.body_b[k]]}
            if pair == {"paddle", "ball"}:
                got["hit"] = (msg.header.stamp, c.point[k], c.normal_impulse[k], got["names"][c.body_a[k]])
                return

    node.create_subscription(PointCloud2, "contacts", on_contacts, 10)
    poses = node.create_publisher(PoseArray, "body_poses", 10)

    deadline = time.monotonic() + args.timeout
    while poses.get_subscription_count() == 0 or got["names"] is None:   # the node is up and matched
        if time.monotonic() > deadline:
            print("no node found (is it running, on this ROS_DOMAIN_ID?)", file=sys.stderr)
            return 1
        rclpy.spin_once(node, timeout_sec=0.05)
    print("bodies:", ", ".join(got["names"]))

    start = time.monotonic()

    def send():
        # towards the ball (radius 0.1 at the origin), stopping 1.5 cm into it: a tick that runs late
        # applies the newest pose, and the paddle must not jump past the ball
        x = min(-0.4 + args.speed * (time.monotonic() - start), -0.11)
        msg = PoseArray()
        msg.header.stamp = node.get_clock().now().to_msg()   # stamps give the paddle its velocity
        msg.header.frame_id = "world"
        p = Pose()
        p.position.x, p.position.y, p.position.z = float(x), 0.0, 0.16      # floats, never ints
        p.orientation.w = 1.0
        msg.poses = [p]
        poses.publish(msg)

    node.create_timer(0.01, send)                    # 100 Hz
    while got["hit"] is None:
        if time.monotonic() > deadline:
            print("no paddle-ball contact before the timeout", file=sys.stderr)
            return 1
        rclpy.spin_once(node, timeout_sec=0.05)
    stamp, point, impulse, body_a = got["hit"]
    print(f"paddle touches ball at t = {stamp.sec + stamp.nanosec * 1e-9:.3f} s, point "
          f"{[round(float(v), 4) for v in point]}, normal impulse {impulse:.4f} N·s on {body_a}")
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
