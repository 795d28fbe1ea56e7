"""The engine never imports ROS: checked in a fresh interpreter, and ROS tests skip cleanly without ROS."""
import os
import subprocess
import sys

import pytest

PROBE = r"""
import sys
import contact_sim as cs
w = cs.load_scene(cs.default_scene_path())
for _ in range(5):
    w.step()
w.detect() if hasattr(w, "detect") else None
bad = sorted(m for m in sys.modules if m.split(".")[0] in ROS or m.endswith("_msgs") or m.endswith("_srvs"))
print("LOADED:" + ",".join(bad))
"""


def test_import_contact_sim_loads_no_ros(repo):
    from conftest import ROS_MODULES

    code = f"ROS = {ROS_MODULES + ('msg_adapters', 'rosidl_parser', 'rpyutils')!r}\n" + PROBE
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=repo, timeout=120)
    assert out.returncode == 0, out.stderr
    loaded = out.stdout.strip().splitlines()[-1]
    assert loaded == "LOADED:", f"contact_sim pulled in ROS modules: {loaded}"


def test_engine_source_has_no_ros_imports(repo):
    import re

    pattern = re.compile(r"^\s*(import|from)\s+(rclpy|[a-z_]+_msgs|std_srvs|msg_adapters)\b", re.M)
    offenders = []
    for root, _, files in os.walk(os.path.join(repo, "contact_sim")):
        for f in files:
            if f.endswith(".py"):
                path = os.path.join(root, f)
                with open(path) as fh:
                    if pattern.search(fh.read()):
                        offenders.append(os.path.relpath(path, repo))
    assert offenders == []


@pytest.mark.slow
def test_without_ros_the_ros_tests_skip_with_reason_and_engine_tests_pass(repo):
    env = dict(os.environ, CONTACT_SIM_BLOCK_ROS="1")
    ros_files = sorted(f for f in os.listdir(os.path.join(repo, "test"))
                       if f.startswith(("test_ros_node", "test_ros_cross", "test_msg_adapters")) and f.endswith(".py"))
    if not ros_files:
        pytest.fail("no ROS test modules found to check")
    args = [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
            *[os.path.join("test", f) for f in ros_files], "test/test_kinematic.py"]
    out = subprocess.run(args, capture_output=True, text=True, cwd=repo, env=env, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert "ROS 2 Jazzy wheels not installed" in out.stdout
    assert " passed" in out.stdout and "failed" not in out.stdout
