"""A robot from URDF checked against obstacles: a two-link arm (written here as URDF text) on a floor
beside a post and a table; the shoulder sweeps from 0 towards pi/2 and every pose is checked with
``world.detect()`` (no stepping: the links are kinematic bodies, the obstacles static). Prints the
excluded pairs and the first contact between the robot and an obstacle.

    python examples/robot_urdf.py
"""
import math

import contact_sim as cs

ARM_L, ARM_R, TIP_R, SHOULDER_Z = 0.5, 0.03, 0.05, 0.2

URDF = f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="base">
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.2 0.1"/></geometry></collision>
  </link>
  <link name="upper">
    <collision><origin xyz="{ARM_L / 2} 0 0" rpy="0 {math.pi / 2} 0"/>
      <geometry><cylinder radius="{ARM_R}" length="{ARM_L}"/></geometry></collision>
  </link>
  <link name="tip">
    <collision><geometry><sphere radius="{TIP_R}"/></geometry></collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 {SHOULDER_Z}"/><axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" effort="10" velocity="2"/>
  </joint>
  <joint name="wrist" type="fixed">
    <parent link="upper"/><child link="tip"/><origin xyz="{ARM_L} 0 0"/>
  </joint>
</robot>
"""

world = cs.World(gravity=[0, 0, -9.81])
world.add_body("floor", cs.Plane([0, 0, 1], 0.0), kind="static")
world.add_body("post", cs.Box([0.04, 0.04, 0.4]), kind="static", position=[0.0, 0.53, 0.2])
world.add_body("table", cs.Box([0.4, 0.4, 0.05]), kind="static", position=[-0.6, 0.0, 0.5])

# the URDF as a path or as XML text; links become kinematic bodies named with the prefix
names = world.add_urdf(URDF, prefix="arm_")
print("robot bodies:", ", ".join(names))
for pair, why in sorted(world.robots[0].exclusions.items()):
    print(f"never tested: {pair[0]} - {pair[1]} ({why})")

robot = set(names)
steps = 900
for i in range(steps + 1):
    q = 0.5 * math.pi * i / steps
    world.set_joint_positions(["arm_shoulder"], [q], stamp=i * 0.01)   # each joint keeps its own stamp
    c = world.detect()                                                  # contacts of this pose, no step
    hits = [(world.body_names[a], world.body_names[b], d) for a, b, d in zip(c.body_a, c.body_b, c.depth)
            if (world.body_names[a] in robot) != (world.body_names[b] in robot)]
    if hits:
        a, b, depth = hits[0]
        link, obstacle = (a, b) if a in robot else (b, a)
        print(f"first contact at shoulder = {q:.4f} rad: {link} touches {obstacle} (depth {depth:.2e} m)")
        break
else:
    print("no contact in the sweep")
