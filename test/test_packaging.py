"""The package is a real ament_python package: package.xml, resource marker, colcon build and test."""
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest


def test_package_xml_is_format3_ament_python(repo):
    root = ET.parse(os.path.join(repo, "package.xml")).getroot()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == "contact_sim"
    assert root.find("export/build_type").text == "ament_python"
    deps = {e.text for e in root.iter("exec_depend")}
    assert {"rclpy", "geometry_msgs", "sensor_msgs", "std_srvs", "diagnostic_msgs", "visualization_msgs",
            "python3-numpy", "python3-scipy", "python3-yaml"} <= deps
    assert os.path.isfile(os.path.join(repo, "resource", "contact_sim"))


def test_ci_runs_the_readme_test_command(repo):
    with open(os.path.join(repo, "README.md")) as fh:
        readme = fh.read()
    with open(os.path.join(repo, ".ci", "run")) as fh:
        ci = fh.read()
    assert "make test" in readme and "make run" in readme
    commands = [line.strip() for line in ci.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert commands[-1] == "make test"


@pytest.mark.slow
def test_colcon_build_and_test_in_a_workspace(repo, tmp_path):
    colcon = shutil.which("colcon", path=os.path.dirname(sys.executable))
    if colcon is None:
        pytest.fail("colcon is not installed in this environment (make test installs it)")
    src = tmp_path / "ws" / "src" / "contact_sim"
    src.mkdir(parents=True)
    for item in ("package.xml", "setup.py", "setup.cfg", "resource", "contact_sim", "msg_adapters", "config"):
        s = os.path.join(repo, item)
        (shutil.copytree if os.path.isdir(s) else shutil.copy)(s, src / item)
    # colcon test runs pytest in the package: give it a small test of its own, not this whole suite
    (src / "test").mkdir()
    shutil.copy(os.path.join(repo, "test", "test_kinematic.py"), src / "test")
    (src / "pytest.ini").write_text("[pytest]\ntestpaths = test\n")
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    ws = tmp_path / "ws"
    build = subprocess.run([colcon, "build"], cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    share = ws / "install" / "contact_sim" / "share"
    assert (share / "ament_index" / "resource_index" / "packages" / "contact_sim").is_file()
    assert (share / "contact_sim" / "package.xml").is_file()
    assert (share / "contact_sim" / "config" / "scenes" / "default.yaml").is_file()
    assert (ws / "install" / "contact_sim" / "lib" / "contact_sim" / "contact_sim_node").is_file()  # for ros2 run
    test = subprocess.run([colcon, "test", "--event-handlers", "console_direct+"], cwd=ws, env=env,
                          capture_output=True, text=True, timeout=300)
    assert test.returncode == 0, test.stdout[-3000:] + test.stderr[-3000:]
    result = subprocess.run([colcon, "test-result", "--all"], cwd=ws, env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout
    assert "0 errors, 0 failures" in result.stdout and " tests," in result.stdout
