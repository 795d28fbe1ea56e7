"""The package is a real ament_python package: package.xml, resource marker, colcon build and test,
and the node started from a plain (copying, not symlinking) colcon install."""
import contextlib
import glob
import os
import signal
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


# import name -> rosdep key of what the engine and the node import; None: optional, not declared
ROSDEP = {"numpy": "python3-numpy", "scipy": "python3-scipy", "yaml": "python3-yaml", "trimesh": "python3-trimesh-pip",
          "tqdm": "python3-tqdm", "matplotlib": None, "numba": "python3-numba",
          "yourdfpy": None,   # no rosdep key: pip installs it (setup.py install_requires; a comment in package.xml)
          "ray": None}        # optional: the cluster extra (contact-sim study --cluster), imported only then


def imported_packages(repo):
    """Top-level names of every non-standard-library module imported anywhere in the engine and the node."""
    import ast

    names = set()
    for path in glob.glob(os.path.join(repo, "contact_sim", "**", "*.py"), recursive=True) + \
            glob.glob(os.path.join(repo, "msg_adapters", "*.py")):
        with open(path) as fh:
            for node in ast.walk(ast.parse(fh.read())):
                if isinstance(node, ast.Import):
                    names |= {a.name.split(".")[0] for a in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n not in ("contact_sim", "msg_adapters")}


def test_package_xml_declares_every_runtime_import(repo):
    root = ET.parse(os.path.join(repo, "package.xml")).getroot()
    deps = {e.text for e in root.iter("exec_depend")}
    missing = []
    for name in sorted(imported_packages(repo)):
        key = ROSDEP.get(name, name)     # ROS packages: the import name is the package name
        if name not in ROSDEP and not (name.endswith("_msgs") or name.endswith("_srvs") or name.startswith(
                ("rcl", "ament_", "builtin_interfaces"))):
            missing.append(f"{name} (add it to ROSDEP in this test, with its rosdep key)")
        elif key is not None and key not in deps:
            missing.append(f"{name} -> <exec_depend>{key}</exec_depend>")
    assert not missing, "package.xml lacks: " + "; ".join(missing)


def test_ci_runs_the_readme_test_command(repo):
    with open(os.path.join(repo, "README.md")) as fh:
        readme = fh.read()
    with open(os.path.join(repo, ".ci", "run")) as fh:
        ci = fh.read()
    assert "make test" in readme and "make run" in readme
    commands = [line.strip() for line in ci.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert "make test" in commands
    with open(os.path.join(repo, "Makefile")) as fh:
        targets = {line.split(":")[0] for line in fh if line[:1].isalpha() and ":" in line}
    # besides the README's test command, only the project's own make targets (the long fuzz profile)
    for cmd in commands[commands.index("make test") + 1:]:
        assert cmd.startswith("make ") and cmd.split()[1] in targets, cmd


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_colcon_build_and_test_in_a_workspace(repo, tmp_path):
    """A colcon build, test and install run as a ROS user runs them, without the JIT: the install's
    hook (setup.py ``InstallAndCompile``) runs ``contact_sim.warmup`` and the node's on the
    installed copy, which with numba compiles every kernel again into the install's own cache
    (~12 minutes on a 2-core machine) for code the rest of the suite runs compiled. Here the hook, the
    package's own test and the installed node run the same source interpreted
    (``NUMBA_DISABLE_JIT=1``, a supported mode: CI reruns the exact tests that way)."""
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
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""),
               NUMBA_DISABLE_JIT="1")
    ws = tmp_path / "ws"
    build = subprocess.run([colcon, "build", "--event-handlers", "console_direct+"], cwd=ws, env=env,
                           capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    # the hook ran the warmup on the installed copy (it prints its time; never fails the build)
    assert "contact_sim: kernels compiled or loaded in" in build.stdout + build.stderr, build.stdout[-3000:]
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

    # the node from the plain install, as after `source install/setup.sh` (plus the venv's prefix, which
    # holds the ROS wheels: see the ROS notes), from an unrelated folder: it finds its shipped scenes
    # through the ament index, with default parameters and with the installed parameter file
    pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
    prefix = ws / "install" / "contact_sim"
    (site,) = glob.glob(str(prefix / "lib" / "python3*" / "site-packages"))
    installed_env = dict(env, AMENT_PREFIX_PATH=os.pathsep.join([str(prefix), sys.prefix]),
                         PYTHONPATH=os.pathsep.join([site] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    params = share / "contact_sim" / "config" / "contact_sim.params.yaml"
    run_installed_node(prefix / "lib" / "contact_sim" / "contact_sim_node", installed_env, tmp_path,
                       [[], ["--ros-args", "--params-file", str(params)]],
                       [share / "contact_sim" / "config" / "scenes" / name for name in ("default.yaml",
                                                                                       "kinematic_paddle.yaml")])


def run_installed_node(script, env, cwd, argvs, scenes):
    """Start the installed node once per ``argvs`` entry (in parallel, own domains), see contacts
    from each, stop each with SIGINT (exit 0); each must say it loaded the scene in ``scenes``."""
    import rclpy
    from domain_coordinator import domain_id
    from sensor_msgs.msg import PointCloud2

    from msg_adapters.testing import Spinner, ros_context, ros_env

    with contextlib.ExitStack() as stack:
        runs = []
        for argv in argvs:
            dom = stack.enter_context(domain_id())
            log = stack.enter_context(open(cwd / f"installed{len(runs)}.log", "w+"))
            proc = subprocess.Popen([str(script)] + argv, env=ros_env(dom, env), cwd=cwd, stdout=log,
                                    stderr=subprocess.STDOUT)
            stack.callback(lambda p=proc: p.poll() is None and (p.kill(), p.wait()))
            runs.append((dom, proc, log))
        for (dom, proc, log), scene in zip(runs, scenes):
            def output(log=log):
                log.flush()
                log.seek(0)
                return log.read()

            with ros_context(dom) as ctx:
                node = rclpy.create_node("installed_client", context=ctx)
                got = []
                node.create_subscription(PointCloud2, "contacts", lambda m: got.append(m.width), 10)
                spin = Spinner(ctx, node)
                try:
                    spin.until(lambda: any(got) or proc.poll() is not None, 60, "contacts from the installed node")
                finally:
                    spin.shutdown()
                    node.destroy_node()
            out = output()
            assert proc.poll() is None, out
            assert f"scene {scene}:" in out, out       # from the install's share folder, not a source tree
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=20) == 0, output()
