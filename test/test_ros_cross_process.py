"""The node as a real client sees it: a subprocess started by its console script with the
parameter file, a client in this process on the same (private) ROS domain."""
import contextlib
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from domain_coordinator import domain_id  # noqa: E402
from geometry_msgs.msg import PoseArray  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from msg_adapters import conversions as cv  # noqa: E402
from msg_adapters.node import DIAG_NAME  # noqa: E402
from msg_adapters.testing import PARAMS_FILE, Spinner, ros_context, ros_env  # noqa: E402

SCRIPT = os.path.join(os.path.dirname(sys.executable), "contact_sim_node")
IDENTITY = np.array([[0.0, 0.0, 0.0, 1.0]])


def node_command(*ros_args):
    """The console script if installed (pip install -e .), else ``python -m msg_adapters``."""
    exe = [SCRIPT] if os.access(SCRIPT, os.X_OK) else [sys.executable, "-m", "msg_adapters"]
    return exe + ["--ros-args", "--params-file", PARAMS_FILE, *ros_args]


class NodeProcess:
    def __init__(self, dom, tmp_path, *ros_args, params_file=True, log="node.log"):
        self.log = open(tmp_path / log, "w+")
        cmd = node_command(*ros_args)
        if not params_file:
            cmd.remove("--params-file")
            cmd.remove(PARAMS_FILE)
        self.proc = subprocess.Popen(cmd, env=ros_env(dom), stdout=self.log, stderr=subprocess.STDOUT, cwd=tmp_path)

    def catches_sigterm(self):
        """The process has installed its SIGTERM handler (/proc: SigCgt), i.e. it runs our code."""
        try:
            with open(f"/proc/{self.proc.pid}/status") as fh:
                for line in fh:
                    if line.startswith("SigCgt:"):
                        return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
        except FileNotFoundError:
            pass
        return False

    def output(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def stop(self, timeout=10.0):
        """SIGINT and the exit status."""
        self.proc.send_signal(signal.SIGINT)
        return self.proc.wait(timeout=timeout)

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)
        self.log.close()


class Client:
    def __init__(self, ctx):
        self.node = rclpy.create_node("paddle_client", context=ctx)
        self.names = None
        self.contacts = []       # (receipt time, message)
        self.diag = None
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(String, "body_names", self._on_names, latched)
        self.node.create_subscription(PointCloud2, "contacts", lambda m: self.contacts.append(m), 50)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)
        self.markers = []
        self.node.create_subscription(MarkerArray, "contact_markers", lambda m: self.markers.append(m), 50)
        self.pub = self.node.create_publisher(PoseArray, "body_poses", 10)
        self.reset = self.node.create_client(Trigger, "/contact_sim/reset")
        self.pause = self.node.create_client(SetBool, "/contact_sim/pause")
        self.step = self.node.create_client(Trigger, "/contact_sim/step")

    def _on_names(self, m):
        self.names = m.data.split("\n")

    def _on_diag(self, m):
        d = cv.diagnostics_to_dict(m, DIAG_NAME)
        if d is not None:
            self.diag = d

    def now_ns(self):
        return self.node.get_clock().now().nanoseconds


@pytest.fixture
def dom(monkeypatch):
    with domain_id() as d:
        for k, v in ros_env(d).items():
            monkeypatch.setenv(k, v)
        yield d


def test_paddle_hits_ball_then_reset_pause_step_and_sigint(dom, tmp_path):
    node = NodeProcess(dom, tmp_path)
    try:
        with ros_context(dom) as ctx:
            client = Client(ctx)
            spin = Spinner(ctx, client.node)
            try:
                spin.until(lambda: client.names is not None and client.pub.get_subscription_count() > 0
                           and client.diag is not None or node.proc.poll() is not None,
                           20, "the node to come up")
                assert node.proc.poll() is None, node.output()
                assert client.names == ["ground", "paddle", "ball"]
                paddle, ball = client.names.index("paddle"), client.names.index("ball")

                # drive the paddle along +x at 2 m/s, a pose every 10 ms, until a contact
                # between paddle and ball carries an impulse
                x, speed, period = -0.4, 2.0, 0.01
                state = {"next": time.monotonic(), "x": x}
                hits = []

                def drive_and_check():
                    now = time.monotonic()
                    if now >= state["next"] and state["x"] < 0.3:
                        client.pub.publish(cv.arrays_to_posearray(
                            [[state["x"], 0.0, 0.16]], IDENTITY, cv.make_header("world", client.now_ns())))
                        state["x"] += speed * period
                        state["next"] = now + period
                    while client.contacts:
                        c = cv.pointcloud2_to_contacts(client.contacts.pop(0))
                        pair = ((c.body_a == paddle) & (c.body_b == ball)) | ((c.body_a == ball) & (c.body_b == paddle))
                        if np.any(pair & (np.linalg.norm(c.impulse, axis=1) > 0)):
                            hits.append(c.select(pair))
                    return bool(hits)

                spin.until(drive_and_check, 15, "a paddle-ball contact with an impulse")
                hit = hits[0]
                assert {client.names[hit.body_a[0]], client.names[hit.body_b[0]]} == {"paddle", "ball"}
                assert np.linalg.norm(hit.impulse, axis=1).max() > 0

                r = spin.call(client.reset, Trigger.Request())
                assert r.success, r.message
                assert spin.call(client.pause, SetBool.Request(data=True)).success
                spin.until(lambda: client.diag["paused"] == "true", 5, "a diagnostics message while paused")
                t_paused = float(client.diag["sim_time_s"])
                r = spin.call(client.step, Trigger.Request())
                assert r.success, r.message
                spin.until(lambda: float(client.diag["sim_time_s"]) != t_paused, 5, "the manual step")
                assert float(client.diag["sim_time_s"]) == pytest.approx(t_paused + 0.01, abs=1e-5)
                assert client.diag["rejected_poses"] == "0" and client.diag["step_errors"] == "0"
                assert client.markers and client.markers[-1].markers[0].action == Marker.DELETEALL
                assert len(client.markers[-1].markers) > 1       # a tick's markers: clear, then draw
                assert node.stop() == 0, node.output()
                # the node cleared its markers on the way out (and waited for this reliable reader)
                spin.until(lambda: [m.action for m in client.markers[-1].markers] == [Marker.DELETEALL], 5,
                           "the DELETEALL sent at shutdown")
            finally:
                spin.shutdown()
                client.node.destroy_node()
    finally:
        node.close()


def test_bad_scene_exits_non_zero_with_a_clear_message(dom, tmp_path):
    node = NodeProcess(dom, tmp_path, "-p", "scene:=no_such_scene")
    try:
        assert node.proc.wait(timeout=30) == 2
        out = node.output()
        assert "cannot start" in out and "no_such_scene" in out and "kinematic_paddle" in out
    finally:
        node.close()


RUNS = 10


def test_sigterm_while_running_and_signals_during_start_up_exit_0(tmp_path):
    """SIGTERM on the default scene while it ticks (rclpy's handler used to invalidate the context
    under a running tick: exit 1, "publisher's context is invalid"), and SIGINT/SIGTERM at spread
    moments of the start-up, from the moment the process runs our code (its SIGTERM handler is
    installed; before that the interpreter itself is starting) to about a second later, through
    the imports, rclpy.init and the node's construction. 10 runs each, all processes at once,
    each on its own domain."""
    with contextlib.ExitStack() as stack:
        doms = [stack.enter_context(domain_id()) for _ in range(2 * RUNS)]
        running = [NodeProcess(d, tmp_path, "-p", "scene:=default", params_file=False, log=f"run{i}.log")
                   for i, d in enumerate(doms[:RUNS])]
        starting = [NodeProcess(d, tmp_path, log=f"start{i}.log") for i, d in enumerate(doms[RUNS:])]
        for p in running + starting:
            stack.callback(p.close)
        # when to signal, once each process is far enough: start-up run k at k x 0.11 s after its
        # handler is in place; running run k 30-150 ms after its start-up log line (ticks running)
        ready = {}
        when = {}
        for k, p in enumerate(starting):
            ready[p] = p.catches_sigterm
            when[p] = (0.11 * k, signal.SIGTERM if k % 2 else signal.SIGINT)
        for k, p in enumerate(running):
            ready[p] = lambda p=p: "tracking" in p.output()
            when[p] = (0.03 + 0.013 * k, signal.SIGTERM)
        t_ready, left = {}, set(ready)
        deadline = time.monotonic() + 90
        while left and time.monotonic() < deadline:
            now = time.monotonic()
            for p in list(left):
                if p not in t_ready and (ready[p]() or p.proc.poll() is not None):
                    t_ready[p] = now
                if p in t_ready and now >= t_ready[p] + when[p][0]:
                    p.proc.send_signal(when[p][1])
                    left.discard(p)
            time.sleep(0.005)
        assert not left, "some nodes never got far enough to be signalled"
        for name, procs in (("start-up", starting), ("running", running)):
            for k, p in enumerate(procs):
                rc = p.proc.wait(timeout=30)
                out = p.output()
                assert rc == 0, f"{name} run {k}: exit {rc}: {out}"
                assert "Traceback" not in out and "context is invalid" not in out, out
        assert all("tracking" in p.output() for p in running)
