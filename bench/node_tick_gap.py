"""Why the node's tick is slower at 100 Hz than in a loop: the same tick timed back to back, after a
9 ms sleep and after a 9 ms busy wait (one process, no subscriber, no executor).

    .venv/bin/python bench/node_tick_gap.py [--ticks 400] [--gap 0.009] [--scene PATH]

The node is built on the scene (default: the shipped default scene, markers on, as in
``bench_node.py``'s default-scene row) and ``_on_timer`` is called directly, ``--ticks`` times per
mode, the modes taking turns twice. Each mode prints the tick's p50/p99 and the median of its parts
(the engine step, the publications). A tick that is slow after a gap whether the gap sleeps or
spins is not waiting on the executor or on an idle CPU: its code and data were evicted meanwhile.
"""
import argparse
import collections
import functools
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=400)
    ap.add_argument("--gap", type=float, default=0.009, help="seconds between ticks in the gap modes")
    ap.add_argument("--scene", default=None, help="scene file (default: the shipped default scene)")
    args = ap.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", "87")
    import rclpy
    from rclpy.parameter import Parameter

    from msg_adapters.node import ContactSimNode

    rclpy.init()
    params = [Parameter("scene", value=args.scene)] if args.scene else []
    node = ContactSimNode(parameter_overrides=params)
    node.timer.cancel()   # ticks are called below, not by the executor
    parts = collections.defaultdict(list)

    def timed(name, f):
        @functools.wraps(f)
        def g(*a, **k):
            t = time.perf_counter()
            r = f(*a, **k)
            parts[name].append(time.perf_counter() - t)
            return r
        return g

    node.world.step = timed("world.step", node.world.step)
    node._publish_tick = timed("publications", node._publish_tick)
    for _ in range(100):
        node._on_timer()

    def gap(mode):
        if mode == "sleep":
            time.sleep(args.gap)
        elif mode == "busy wait":
            t = time.perf_counter()
            while time.perf_counter() - t < args.gap:
                pass

    try:
        for mode in ("back to back", "sleep", "busy wait") * 2:
            parts.clear()
            ticks = []
            for _ in range(args.ticks):
                gap(mode)
                t = time.perf_counter()
                node._on_timer()
                ticks.append(time.perf_counter() - t)
            v = 1e3 * np.array(ticks)
            print(f"{mode:>12}: tick p50 {np.median(v):.3f} ms, p99 {np.percentile(v, 99):.3f} ms; "
                  + ", ".join(f"{k} {1e3 * np.median(x):.3f}" for k, x in parts.items()))
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    main()
