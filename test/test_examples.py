"""The scripts in examples/ run as a user runs them (their own process, from the repository) and
print what their docstrings promise: each test checks the printed figures against an answer computed
here independently, so an example that drifts from the engine fails."""
import math
import os
import re
import signal
import subprocess
import sys

import numpy as np
import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(REPO, "examples")


def env_with_repo(base=None):
    env = dict(os.environ if base is None else base)
    env["PYTHONPATH"] = os.pathsep.join([REPO] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run_example(name, env=None, timeout=120):
    out = subprocess.run([sys.executable, os.path.join(EXAMPLES, name)], env=env or env_with_repo(), cwd=REPO,
                         capture_output=True, text=True, timeout=timeout)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return out.stdout


def test_quickstart_ball_comes_to_rest_on_the_ground():
    out = run_example("quickstart.py")
    assert "response impulse" in out                 # describe() says what the engine chose
    m = re.search(r"t = ([\d.]+) s  ball at \[([^\]]+)\] m, speed ([\d.]+) m/s", out)
    assert m, out
    t, pos, speed = float(m.group(1)), [float(v) for v in m.group(2).split(",")], float(m.group(3))
    assert abs(t - 2.0) < 1e-9
    assert speed < 0.05                               # dropped from 1.5 m, it has settled after 2 s
    assert pos[2] < 1.0                               # and fell
    n = int(re.search(r"(\d+) contact points", out).group(1))
    rows = re.findall(r"depth ([-+.\de]+) m", out)
    assert n > 0 and len(rows) == n
    assert max(abs(float(d)) for d in rows) < 1e-3   # resting contacts: within a millimetre


def test_robot_urdf_first_contact_is_the_tip_on_the_post_at_the_exact_angle():
    sys.path.insert(0, EXAMPLES)
    try:
        import robot_urdf as ex                       # runs the example in this process too (a few ms)
    finally:
        sys.path.remove(EXAMPLES)
    out = run_example("robot_urdf.py")
    assert "never tested: arm_base - floor (touching at the initial configuration)" in out
    assert "never tested: arm_base - arm_upper (adjacent links)" in out
    m = re.search(r"first contact at shoulder = ([\d.]+) rad: (\w+) touches (\w+)", out)
    assert m, out
    q, link, obstacle = float(m.group(1)), m.group(2), m.group(3)
    assert (link, obstacle) == ("arm_tip", "post")

    # independent answer: the smallest angle at which the tip sphere comes within the contact margin
    # of the post (an axis-aligned box), by bisection on the point-to-box distance
    lo_box = np.array([-0.02, 0.51, 0.0])
    hi_box = np.array([0.02, 0.55, 0.4])
    reach = ex.TIP_R + 1e-4                           # the default contact_margin

    def gap(theta):
        c = np.array([ex.ARM_L * math.cos(theta), ex.ARM_L * math.sin(theta), ex.SHOULDER_Z])
        return np.linalg.norm(c - np.clip(c, lo_box, hi_box)) - reach

    a, b = 0.0, math.pi / 2
    assert gap(a) > 0 > gap(b)
    for _ in range(60):
        mid = 0.5 * (a + b)
        a, b = (mid, b) if gap(mid) > 0 else (a, mid)
    step = 0.5 * math.pi / 900
    assert b - 1e-9 <= q <= b + step + 1e-9, (q, b)


def test_collide_loop_depths_are_exact():
    out = run_example("collide_loop.py")
    rows = re.findall(r"z = ([\d.]+): 1 contact, depth ([-+.\d]+) m, normal \[([^\]]+)\]", out)
    assert "z = 0.400: apart" in out
    assert [r[0] for r in rows] == ["0.355", "0.350", "0.325", "0.300"]
    for z, depth, normal in rows:
        assert abs(float(depth) - (0.1 + 0.25 - float(z))) < 5e-5     # the box's top at 0.1, radius 0.25
        assert [float(v) for v in normal.split(",")] == [0.0, 0.0, 1.0]
    turned = re.findall(r"(\d+) deg: (\d+) contacts, depths \[([^\]]+)\], features \[([^\]]+)\]", out)
    assert [t[0] for t in turned] == ["0", "15", "30", "45"]
    for _, n, depths, feats in turned:
        assert int(n) == 4                                               # a flat patch keeps its corners
        assert all(abs(float(d) - 0.001) < 1e-9 for d in depths.split(","))
        assert feats == "'face_face'"


@pytest.mark.ros
def test_drive_node_sweeps_the_paddle_into_the_ball(tmp_path):
    pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
    from domain_coordinator import domain_id

    from msg_adapters.testing import ros_env

    with domain_id() as dom:
        env = env_with_repo(ros_env(dom))            # its own domain, localhost only
        with open(tmp_path / "node.log", "w+") as log:
            node_log, code, out = _run_with_node(env, log, tmp_path)
        assert code == 0, node_log[-3000:]
    assert "bodies: ground, paddle, ball" in out, out
    m = re.search(r"paddle touches ball at t = ([\d.]+) s, point \[([^\]]+)\], normal impulse ([-\d.]+)", out)
    assert m, out
    point = [float(v) for v in m.group(2).split(",")]
    # the paddle's face meets the ball (radius 0.1 at the origin, on the ground) at its equator
    assert abs(point[0] + 0.1) < 0.02 and abs(point[1]) < 1e-6 and abs(point[2] - 0.1) < 0.02, point
    assert float(m.group(3)) >= 0.0


def _run_with_node(env, log, cwd):
    """The node on the paddle scene in its own process, the example beside it; the node stopped with
    SIGINT after. Returns (node's log, node's exit code, example's output)."""
    node = subprocess.Popen([sys.executable, "-m", "msg_adapters", "--ros-args", "-p", "scene:=kinematic_paddle",
                            "-p", "tracked_bodies:=[paddle]"], env=env, stdout=log, stderr=subprocess.STDOUT,
                            cwd=cwd)
    try:
        out = run_example("drive_node.py", env=env, timeout=90)
    finally:
        node.send_signal(signal.SIGINT)
        try:
            code = node.wait(timeout=20)
        except subprocess.TimeoutExpired:
            node.kill()
            code = node.wait()
        log.seek(0)
        node_log = log.read()
    return node_log, code, out
