"""Shared test set-up.

``CONTACT_SIM_BLOCK_ROS=1`` makes rclpy and the message packages unimportable, to prove that the
engine's tests pass and the ROS tests skip (with their reason) on a machine without ROS.
"""
import os
import sys

import pytest

ROS_MODULES = ("rclpy", "geometry_msgs", "sensor_msgs", "std_msgs", "std_srvs", "visualization_msgs",
               "diagnostic_msgs", "builtin_interfaces", "rosidl_runtime_py", "domain_coordinator")

if os.environ.get("CONTACT_SIM_BLOCK_ROS") == "1":
    for _name in ROS_MODULES:
        sys.modules[_name] = None  # `import rclpy` now raises ImportError

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(REPO, "config", "scenes")
# pybullet_data's Franka Panda (URDF and collision meshes, Apache 2.0: test/data/franka_panda/README.md)
PANDA_URDF = os.path.join(REPO, "test", "data", "franka_panda", "panda.urdf")


@pytest.fixture
def repo():
    return REPO


@pytest.fixture
def scenes_dir():
    return SCENES
