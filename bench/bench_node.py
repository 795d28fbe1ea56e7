"""Benchmark of the contact_sim ROS 2 node, with the node in its own process.

Measures
  * tick time p50/p99/max (ms) over the window's ticks, and the tick thread's CPU time p99/max in
    them; overruns (ticks longer than the period; off-CPU: those whose CPU time fitted the period,
    the thread descheduled or blocked for the rest) and
    skipped ticks (periods the timer did not honour, the executor late) from the window's start to
    the diagnostics that close it, and overruns before it (start-up and warm-up), at 100 Hz for scenes of 10, 100 and 500 bodies (a ground plane, the
    kinematic paddle and dynamic spheres resting on the ground, so every sphere has a contact each
    tick; markers off), for 100 bodies at 1 kHz, and for the shipped default scene at 100 Hz with
    the node's defaults (markers on), as the node itself computes them over its last
    ``stats_window`` ticks (set to the measured window, after a 1 s warm-up) and reports in
    ``/diagnostics`` at its default 1 Hz;
  * beside each 1 kHz case, the platform probe (``platform_probe.py``): constant work as long as
    that case's tick p50, at the same rate and scheduler, timed the same way; its overruns are the
    machine's own (interrupts, the hypervisor), the ones a tick of that length has at no fault of its
    own;
  * pose-to-contacts latency: stamp of a ``body_poses`` message to receipt of the first ``contacts``
    message stamped at or after it (the first tick that could use it);
  * ``body_poses`` messages dropped at 100 Hz and 1 kHz input: sent by this script minus
    ``poses_received`` counted by the node.

Prints a table and writes bench/results/node.csv.
Run: .venv/bin/python bench/bench_node.py [--seconds 5]
"""
import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from domain_coordinator import domain_id
from geometry_msgs.msg import PoseArray
from sensor_msgs.msg import PointCloud2

from msg_adapters import conversions as cv
from msg_adapters.node import DIAG_NAME
from msg_adapters.testing import Spinner, ros_context, ros_env

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results", "node.csv")


def grid_scene(n_bodies, path):
    """Ground + kinematic paddle + (n_bodies - 2) spheres resting on the ground, 0.3 m apart."""
    k = n_bodies - 2
    side = int(np.ceil(np.sqrt(k)))
    bodies = [{"name": "ground", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0.0}},
              {"name": "paddle", "kind": "kinematic", "shape": {"type": "box", "size": [0.05, 0.5, 0.3]},
               "position": [-1.0, 0.0, 0.16]}]
    for i in range(k):
        r, c = divmod(i, side)
        bodies.append({"name": f"ball{i}", "kind": "dynamic", "shape": {"type": "sphere", "radius": 0.1},
                       "mass": 0.5, "position": [0.3 * c, 0.3 * r, 0.1]})
    with open(path, "w") as fh:
        yaml.safe_dump({"name": f"grid_{n_bodies}", "gravity": [0, 0, -9.81],
                        "settings": {"dt": 0.01}, "bodies": bodies}, fh)
    return path


class Node:
    def __init__(self, dom, scene, log_path, rate_hz=100.0, window=500, defaults=False, thread_priority=0, extra=()):
        """The node on ``scene``; ``defaults``: the node's own defaults (markers on, the scene's
        tracked bodies), else the grid scenes' set-up (no markers, the paddle tracked);
        ``thread_priority``: its parameter (SCHED_FIFO for the ticks' thread, 0 none); ``extra``:
        more ``name:=value`` parameters."""
        self.log = open(log_path, "w")
        cmd = [sys.executable, "-m", "msg_adapters", "--ros-args", "-p", f"scene:={scene}",
               "-p", f"rate_hz:={rate_hz}", "-p", f"stats_window:={window}", "-p", f"thread_priority:={thread_priority}"]
        if not defaults:
            cmd += ["-p", "publish_markers:=false", "-p", "tracked_bodies:=[paddle]", "-p", "pose_timeout:=5.0"]
        for p in extra:
            cmd += ["-p", p]
        self.proc = subprocess.Popen(cmd, env=ros_env(dom), stdout=self.log, stderr=subprocess.STDOUT)

    def stop(self):
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout=10)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
            self.log.close()


class Client:
    def __init__(self, ctx):
        self.node = rclpy.create_node("bench_client", context=ctx)
        self.diag = None
        self.diag_count = 0
        self.record = False
        self.contact_rx = []  # (receipt ns, header stamp ns)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.node.create_subscription(PointCloud2, "contacts", self._on_contacts, 100)
        self.pub = self.node.create_publisher(PoseArray, "body_poses", 1000)

    def _on_diag(self, m):
        d = cv.diagnostics_to_dict(m, DIAG_NAME)
        if d is None:
            return
        self.diag = d
        self.diag_count += 1

    def _on_contacts(self, m):
        if self.record:
            self.contact_rx.append((time.time_ns(), cv.stamp_to_ns(m.header.stamp)))


def run_scene(n_bodies, seconds, tmp, rows, pose_rates=(), rate_hz=100, scene=None, test="tick_time", thread_priority=0):
    """Tick times of the node on the grid scene of ``n_bodies`` (or on ``scene``, with the node's
    defaults) at ``rate_hz``, then pose input at ``pose_rates``."""
    defaults = scene is not None
    scene = scene or grid_scene(n_bodies, os.path.join(tmp, f"grid_{n_bodies}.yaml"))
    with domain_id() as dom:
        os.environ.update(ros_env(dom))
        window = int(round(seconds * rate_hz))
        name, k = os.path.join(tmp, f"node_{test}_{n_bodies}_{rate_hz}_p{thread_priority}"), 1
        log = name + ".log"
        while os.path.exists(log):   # a later round of the same case
            k += 1
            log = f"{name}_{k}.log"
        node = Node(dom, scene, log, rate_hz=rate_hz,
                    window=window, defaults=defaults, thread_priority=thread_priority)
        try:
            with ros_context(dom) as ctx:
                cl = Client(ctx)
                spin = Spinner(ctx, cl.node)
                spin.until(lambda: cl.diag is not None and cl.pub.get_subscription_count() > 0, 30, "the node")
                # warm-up (1 s and a fresh diagnostics message), then the node's statistics over the
                # next `window` ticks at 100 Hz with no input: the first message counting them all
                t_end = time.monotonic() + 1.0
                spin.until(lambda: time.monotonic() > t_end, 5)
                seen = cl.diag_count
                spin.until(lambda: cl.diag_count > seen, 5, "diagnostics after the warm-up")
                start_ticks = int(cl.diag["ticks"])
                # the node counts overruns from its start: those before this point (start-up, when the
                # first ticks load the kernels' caches, and the warm-up second) are reported apart. The
                # counts below span from here to the diagnostics that close the window (``ticks``, up to
                # a diagnostics period more than the ``window`` ticks of p50/p99/max)
                start_overruns, start_skipped = int(cl.diag["tick_overruns"]), int(cl.diag["skipped_ticks"])
                start_off_cpu = int(cl.diag["tick_overruns_off_cpu"])
                # a node that cannot keep the rate (1 kHz on a loaded machine) takes longer than the
                # window's nominal seconds to tick through it: wait for it, the overruns say so
                spin.until(lambda: int(cl.diag["ticks"]) >= start_ticks + window, seconds * (1 + rate_hz / 200) + 10,
                           "the measured window")
                d = cl.diag
                if int(d["thread_priority"]) != thread_priority:
                    print(f"thread_priority {thread_priority} refused on this machine: measured at "
                          f"{d['thread_priority']}", file=sys.stderr)
                rows.append(dict(test=test, bodies=n_bodies, rate_hz=rate_hz, samples=window,
                                 thread_priority=int(d["thread_priority"]),
                                 p50_ms=float(d["tick_time_ms_p50"]), p99_ms=float(d["tick_time_ms_p99"]),
                                 max_ms=float(d["tick_time_ms_max"]), ticks=int(d["ticks"]) - start_ticks,
                                 cpu_p99_ms=float(d["tick_cpu_ms_p99"]), cpu_max_ms=float(d["tick_cpu_ms_max"]),
                                 overruns=int(d["tick_overruns"]) - start_overruns, overruns_startup=start_overruns,
                                 overruns_off_cpu=int(d["tick_overruns_off_cpu"]) - start_off_cpu,
                                 skipped_ticks=int(d["skipped_ticks"]) - start_skipped, contacts=int(d["contacts"])))
                for rate in pose_rates:
                    rows.append(pose_input(cl, spin, rate, seconds, n_bodies))
                spin.shutdown()
                cl.node.destroy_node()
        finally:
            rc = node.stop()
            if rc != 0:
                print(f"node for {n_bodies} bodies exited with {rc}; log in {tmp}", file=sys.stderr)


def pose_input(cl, spin, rate, seconds, n_bodies):
    """Publish paddle poses at ``rate`` Hz (stamped now) for ``seconds``; count drops and latency."""
    received0 = int(cl.diag["poses_received"])
    cl.contact_rx.clear()
    stamps = []
    period_ns = int(1e9 / rate)
    start = time.time_ns()
    cl.record = True
    sent = 0
    n_total = int(seconds * rate)

    def publish_due():
        nonlocal sent
        now = time.time_ns()
        while sent < n_total and now >= start + sent * period_ns:
            x = -1.0 + 1e-4 * sent
            cl.pub.publish(cv.posearray_cdr([[x, 0.0, 0.16]], [[0.0, 0.0, 0.0, 1.0]], "world", now))
            stamps.append(now)
            sent += 1
        return sent >= n_total

    # spin with short waits so the publishing keeps its rate
    deadline = time.monotonic() + seconds + 10
    while not publish_due():
        spin.executor.spin_once(timeout_sec=0.0002)
        if time.monotonic() > deadline:
            break
    # the node has counted everything it will ever get once its count stops changing over more
    # than two diagnostics periods (1 s)
    last = [None, time.monotonic()]

    def settled():
        v = cl.diag["poses_received"]
        if v != last[0]:
            last[:] = [v, time.monotonic()]
        return time.monotonic() - last[1] > 2.5

    spin.until(settled, 10, "the node to count all poses")
    cl.record = False
    received = int(cl.diag["poses_received"]) - received0
    rx = np.array(cl.contact_rx, dtype=np.int64).reshape(-1, 2)
    lat = []
    if len(rx):
        order = np.argsort(rx[:, 1])
        hdr, got = rx[order, 1], rx[order, 0]
        idx = np.searchsorted(hdr, np.array(stamps, np.int64), side="left")
        ok = idx < len(hdr)
        lat = (got[idx[ok]] - np.array(stamps, np.int64)[ok]) * 1e-6
    lat = np.asarray(lat, float)
    return dict(test=f"poses_{rate}Hz", bodies=n_bodies, rate_hz=100, samples=sent, sent=sent, received=received,
                dropped=sent - received,
                latency_p50_ms=np.percentile(lat, 50) if lat.size else np.nan,
                latency_p99_ms=np.percentile(lat, 99) if lat.size else np.nan)


def panda_scene(path, n_objects=20):
    """``bench_panda``'s cell without the robot (the node gets it on ``robot_description``): a
    floor, a table 0.4 m high, ``n_objects`` boxes and spheres on it."""
    bodies = [{"name": "floor", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0.0}},
              {"name": "table", "kind": "static", "shape": {"type": "box", "size": [0.6, 1.0, 0.4]},
               "position": [0.75, 0.0, 0.2]}]
    for i in range(n_objects):
        box = i % 2 == 0
        bodies.append({"name": f"obj{i}", "kind": "dynamic", "mass": 0.2,
                       "shape": {"type": "box", "size": [0.05, 0.05, 0.05]} if box else {"type": "sphere", "radius": 0.03},
                       "position": [0.55 + 0.1 * (i % 5), -0.35 + 0.2 * (i // 5), 0.4 + (0.025 if box else 0.03)]})
    with open(path, "w") as fh:
        yaml.safe_dump({"name": "panda_cell", "gravity": [0, 0, -9.81], "bodies": bodies}, fh)
    return path


def run_panda(seconds, tmp, rows, thread_priority=0, round_=1):
    """The node at 1 kHz (one 1 ms step a tick) with ``bench_panda``'s cell: the Panda of
    pybullet_data sent on ``robot_description`` as robot_state_publisher sends it (its meshes found
    through the ``package_paths`` parameter: the text has no folder of its own), its seven joints
    driven by ``joint_states`` at 1 kHz (``bench_panda``'s sinusoids, stamped now). The node's tick
    statistics over ``seconds`` after a 2 s warm-up (the objects settle), and the joint states
    sent, received, accepted and refused in the window (sent is counted here and received by the
    node between two diagnostics messages, so their difference is not a count of drops: the node
    applies the newest state each tick and needs no other)."""
    import pybullet_data
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header, String

    from bench_panda import JOINTS, angles, panda_urdf

    scene = panda_scene(os.path.join(tmp, "panda_cell.yaml"))
    folder = os.path.join(pybullet_data.getDataPath(), "franka_panda")
    rate_hz, window = 1000, int(round(seconds * 1000))
    with domain_id() as dom:
        os.environ.update(ros_env(dom))
        log = os.path.join(tmp, f"node_panda_p{thread_priority}_{round_}.log")
        node = Node(dom, scene, log, rate_hz=rate_hz, window=window, defaults=True, thread_priority=thread_priority,
                    extra=("publish_markers:=false", "pose_timeout:=5.0", f"package_paths:=[{folder}]"))
        try:
            with ros_context(dom) as ctx:
                cl = Client(ctx)
                latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
                desc = cl.node.create_publisher(String, "robot_description", latched)
                joints = cl.node.create_publisher(JointState, "joint_states", 100)
                with open(panda_urdf()) as fh:
                    desc.publish(String(data=fh.read()))
                spin = Spinner(ctx, cl.node)
                spin.until(lambda: cl.diag is not None and int(cl.diag.get("robot_descriptions", 0)) == 1, 60,
                           "the node with the Panda")
                t0 = time.time_ns()
                sent = [0]

                def pump(pred, timeout, what):
                    """Joint states at 1 kHz while waiting for ``pred``."""
                    deadline = time.monotonic() + timeout
                    while not pred():
                        now = time.time_ns()
                        while t0 + sent[0] * 1_000_000 <= now:
                            t = (now - t0) * 1e-9
                            joints.publish(JointState(header=Header(stamp=cv.ns_to_stamp(now)), name=JOINTS,
                                                      position=[float(x) for x in angles(t)]))
                            sent[0] += 1
                        spin.executor.spin_once(timeout_sec=0.0002)
                        if time.monotonic() > deadline:
                            raise TimeoutError(f"waiting for {what}")

                t_end = time.monotonic() + 2.0
                pump(lambda: time.monotonic() > t_end, 10, "the warm-up")
                seen = cl.diag_count
                pump(lambda: cl.diag_count > seen, 5, "diagnostics after the warm-up")
                d0, sent0 = dict(cl.diag), sent[0]
                pump(lambda: int(cl.diag["ticks"]) >= int(d0["ticks"]) + window, seconds * 6 + 10, "the measured window")
                d = cl.diag
                delta = {k: int(d[k]) - int(d0[k]) for k in ("ticks", "tick_overruns", "tick_overruns_off_cpu",
                                                             "skipped_ticks", "joint_states_received",
                                                             "joint_states_accepted", "rejected_joint_states")}
                rows.append(dict(test="tick_panda", round=round_, bodies=int(d["bodies"]), rate_hz=rate_hz,
                                 samples=window, thread_priority=int(d["thread_priority"]),
                                 p50_ms=float(d["tick_time_ms_p50"]), p99_ms=float(d["tick_time_ms_p99"]),
                                 max_ms=float(d["tick_time_ms_max"]), ticks=delta["ticks"],
                                 cpu_p99_ms=float(d["tick_cpu_ms_p99"]), cpu_max_ms=float(d["tick_cpu_ms_max"]),
                                 overruns=delta["tick_overruns"], overruns_startup=int(d0["tick_overruns"]),
                                 overruns_off_cpu=delta["tick_overruns_off_cpu"], skipped_ticks=delta["skipped_ticks"],
                                 contacts=int(d["contacts"]), sent=sent[0] - sent0,
                                 received=delta["joint_states_received"],
                                 accepted=delta["joint_states_accepted"], refused=delta["rejected_joint_states"]))
                spin.shutdown()
                cl.node.destroy_node()
        finally:
            rc = node.stop()
            if rc != 0:
                print(f"node for the Panda exited with {rc}; log in {tmp}", file=sys.stderr)


def platform_probe(tick_row, seconds):
    """``bench/platform_probe.py`` in its own process, as the node runs: a loop of constant work as
    long as the tick's p50 in ``tick_row``, at its rate and scheduler, over ``seconds``. Its overruns
    are the machine's, not the node's: the probe's work never changes."""
    out = subprocess.run([sys.executable, os.path.join(HERE, "platform_probe.py"), "--work-ms", str(tick_row["p50_ms"]),
                          "--rate-hz", str(tick_row["rate_hz"]), "--seconds", str(seconds),
                          "--priority", str(tick_row["thread_priority"])],
                         capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    return dict(test="platform_probe", bodies="", rate_hz=int(r["rate_hz"]), thread_priority=r["thread_priority"],
                samples=r["samples"], ticks=r["samples"],
                **{k: r[k] for k in ("p50_ms", "p99_ms", "max_ms", "cpu_p99_ms", "cpu_max_ms", "overruns",
                                      "overruns_off_cpu")}, overruns_startup=0, skipped_ticks=0)


def engine_timing(n_bodies, seconds, tmp):
    """Direct engine timing of the same grid scene (no ROS): ``world.step()`` at the node's dt
    (0.01 s), after a 1 s warm-up; p50/p99/max ms over ``seconds`` of simulated ticks."""
    import warnings

    import contact_sim as cs

    world = cs.load_scene(grid_scene(n_bodies, os.path.join(tmp, f"grid_{n_bodies}.yaml")))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(100):
            world.step()
        ms = []
        for _ in range(int(round(seconds / world.settings.dt))):
            t0 = time.perf_counter()
            world.step()
            ms.append(1e3 * (time.perf_counter() - t0))
    ms = np.array(ms)
    return dict(test="engine_step", bodies=n_bodies, rate_hz=100, samples=len(ms), p50_ms=np.percentile(ms, 50),
                p99_ms=np.percentile(ms, 99), max_ms=ms.max(), contacts=len(world.contacts))


COLUMNS = ["test", "round", "bodies", "rate_hz", "thread_priority", "samples", "p50_ms", "p99_ms", "max_ms", "cpu_p99_ms", "cpu_max_ms", "ticks",
           "overruns", "overruns_off_cpu", "overruns_startup",
           "skipped_ticks", "contacts", "sent", "received", "dropped", "accepted", "refused", "latency_p50_ms",
           "latency_p99_ms"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0, help="measurement window per case")
    ap.add_argument("--bodies", type=int, nargs="+", default=[10, 100, 500])
    ap.add_argument("--engine", action="store_true",
                    help="time only the engine's step on the same scenes (no ROS); writes bench/results/response.engine_step.csv")
    ap.add_argument("--thread-priority", type=int, default=50,
                    help="the node's thread_priority for the second 1 kHz run (SCHED_FIFO; default 50)")
    ap.add_argument("--rounds", type=int, default=3,
                    help="rounds of the 1 kHz cases (node and probe, both schedulers, taking turns; default 3)")
    ap.add_argument("--panda", action="store_true",
                    help="only the Panda cell at 1 kHz (bench_panda's, through robot_description and joint_states; "
                         "needs pybullet_data); writes bench/results/node_panda.csv")
    args = ap.parse_args()
    rows = []
    tmp = tempfile.mkdtemp(prefix="bench_node_")
    if args.panda:
        for k in range(args.rounds):
            for prio in (0, args.thread_priority):
                run_panda(args.seconds, tmp, rows, thread_priority=prio, round_=k + 1)
                rows.append(dict(platform_probe(rows[-1], args.seconds), round=k + 1))
        _write(rows, os.path.join(HERE, "results", "node_panda.csv"))
        return
    if args.engine:
        rows = [engine_timing(n, args.seconds, tmp) for n in args.bodies]
        out = os.path.join(HERE, "results", "response.engine_step.csv")
        with open(out, "w", newline="") as fh:
            w = csv.DictWriter(fh, ["test", "bodies", "rate_hz", "samples", "p50_ms", "p99_ms", "max_ms", "contacts"])
            w.writeheader()
            for r in rows:
                w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
        for r in rows:
            print(f"engine step {r['bodies']:>4} bodies: p50 {r['p50_ms']:.2f} ms  p99 {r['p99_ms']:.2f} ms  "
                  f"max {r['max_ms']:.2f} ms  contacts {r['contacts']}")
        print(f"wrote {out}")
        return
    print(f"scenes and node logs in {tmp}")
    for n in args.bodies:
        run_scene(n, args.seconds, tmp, rows, pose_rates=(100, 1000) if n == 100 else ())
        if n == 100:   # the 1 kHz case: every tick must finish within its 1 ms; under the normal
            # scheduler, then with the ticks' thread at SCHED_FIFO 50 (ros2_control's 1 kHz set-up)
            # after each, the platform probe: constant work of the tick's p50, same rate and scheduler;
            # `--rounds` times, taking turns, since a few overruns in 5,000 ticks vary run to run
            for k in range(args.rounds):
                for prio in (0, args.thread_priority):
                    run_scene(n, args.seconds, tmp, rows, rate_hz=1000, thread_priority=prio)
                    rows[-1]["round"] = k + 1
                    rows.append(dict(platform_probe(rows[-1], args.seconds), round=k + 1))
    # the scene a new user sees first, with the node's defaults (markers on)
    from contact_sim.scene import default_scene_path
    import contact_sim as cs
    run_scene(len(cs.load_scene(default_scene_path())), args.seconds, tmp, rows, scene=default_scene_path(),
              test="tick_default")
    _write(rows, RESULTS)


def _write(rows, path):
    """``rows`` to the CSV ``path`` and as a table."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
    print(f"{'test':<14}{'bodies':>7}{'p50 ms':>9}{'p99 ms':>9}{'max ms':>9}{'cpu max':>9}{'overrun':>8}{'offcpu':>7}"
          f"{'start':>6}{'contacts':>9}"
          f"{'sent':>7}{'dropped':>8}{'refused':>8}{'lat p50':>9}{'lat p99':>9}")
    for r in rows:
        def f(k):
            v = r.get(k, "")
            return f"{v:.3g}" if isinstance(v, float) else str(v)
        print(f"{r['test']:<14}{r['bodies']:>7}{f('p50_ms'):>9}{f('p99_ms'):>9}{f('max_ms'):>9}{f('cpu_max_ms'):>9}"
              f"{f('overruns'):>8}{f('overruns_off_cpu'):>7}"
              f"{f('overruns_startup'):>6}{f('contacts'):>9}{f('sent'):>7}{f('dropped'):>8}{f('refused'):>8}{f('latency_p50_ms'):>9}{f('latency_p99_ms'):>9}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
