"""A small arm written as URDF text for the robot tests: box base (and a sphere on it), cylinder
upper arm on a revolute shoulder (about z), mesh gripper on a prismatic slide (along the arm), and a
finger that mimics the slide. Dimensions are module constants so tests compute FK by hand."""
import numpy as np

BASE_H = 0.1          # base box 0.2 x 0.2 x BASE_H, its collision origin at z = BASE_H / 2
SHOULDER_Z = 0.1      # shoulder joint above the base link origin
ARM_R, ARM_L = 0.03, 0.4
SLIDE_X = 0.4         # slide joint origin along the upper arm
GRIP = 0.04           # gripper cube edge (a mesh file)
FINGER_MULT, FINGER_OFF = 0.5, 0.01
SHOULDER_LIMITS, SLIDE_LIMITS = (-3.0, 3.0), (0.0, 0.1)


def arm_urdf(mesh_uri, name="arm"):
    return f"""<?xml version="1.0"?>
<robot name="{name}">
  <link name="base">
    <collision><origin xyz="0 0 {BASE_H / 2}"/><geometry><box size="0.2 0.2 {BASE_H}"/></geometry></collision>
    <collision><origin xyz="0 0 0.15"/><geometry><sphere radius="0.04"/></geometry></collision>
  </link>
  <link name="upper">
    <collision><origin xyz="{ARM_L / 2} 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="{ARM_R}" length="{ARM_L}"/></geometry></collision>
  </link>
  <link name="gripper">
    <collision><geometry><mesh filename="{mesh_uri}" scale="1 1 1"/></geometry></collision>
  </link>
  <link name="finger">
    <collision><origin xyz="0 -0.005 0"/><geometry><sphere radius="0.004"/></geometry></collision>
  </link>
  <link name="tool_frame"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 {SHOULDER_Z}"/><axis xyz="0 0 1"/>
    <limit lower="{SHOULDER_LIMITS[0]}" upper="{SHOULDER_LIMITS[1]}" effort="10" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="upper"/><child link="gripper"/><origin xyz="{SLIDE_X} 0 0"/><axis xyz="1 0 0"/>
    <limit lower="{SLIDE_LIMITS[0]}" upper="{SLIDE_LIMITS[1]}" effort="10" velocity="1"/>
  </joint>
  <joint name="finger_joint" type="prismatic">
    <parent link="gripper"/><child link="finger"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.1" effort="1" velocity="1"/>
    <mimic joint="slide" multiplier="{FINGER_MULT}" offset="{FINGER_OFF}"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="gripper"/><child link="tool_frame"/><origin xyz="0.05 0 0"/>
  </joint>
</robot>
"""


def write_gripper_mesh(path):
    """The gripper: a cube of edge GRIP made by trimesh, exported as STL."""
    import trimesh

    trimesh.creation.box([GRIP] * 3).export(str(path))
    return str(path)


def rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
