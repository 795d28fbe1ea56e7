"""The machine's own timing noise, measured the way the node measures its ticks (a cyclictest for
a Python tick loop).

Runs, in its own process, a loop of constant work at ``--rate-hz``: each period it does
``--work-ms`` of pure-Python arithmetic (calibrated at start-up; no allocation, no I/O, no
middleware), timed with ``time.perf_counter`` and ``time.thread_time`` exactly as the node times a
tick, then sleeps to the next period's deadline. The work never changes, so any iteration much
longer than the median is the platform's: interrupts (this kernel charges their time to the
running thread, ``CONFIG_IRQ_TIME_ACCOUNTING`` unset, so they show as CPU time), the hypervisor,
cache and TLB misses after other work. Its overruns (iterations longer than the period) are the
overruns a tick of that length would have had with no fault of its own.

``bench_node.py`` runs it beside the node's 1 kHz cases, with the work set to the node's measured
tick p50 and the same ``thread_priority``. Prints one JSON line.
Run: .venv/bin/python bench/platform_probe.py --work-ms 0.4 --rate-hz 1000 --seconds 5 [--priority 50]
"""
import argparse
import json
import os
import time

import numpy as np


def spin(n):
    """``n`` iterations of integer arithmetic: the constant unit of work."""
    s = 0
    for i in range(n):
        s += i * i
    return s


def calibrate(work_ms, trials=50):
    """Iterations of ``spin`` that take ``work_ms`` (the median of ``trials`` timings)."""
    n = 10000
    spin(n)
    per = np.median([_timed(n) for _ in range(trials)]) / n
    return max(1, int(round(work_ms * 1e-3 / per)))


def _timed(n):
    t0 = time.perf_counter()
    spin(n)
    return time.perf_counter() - t0


def probe(work_ms, rate_hz, seconds, priority=0):
    """Run the loop; returns a dict of wall and CPU-time statistics (ms) and overrun counts."""
    if priority:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except (OSError, AttributeError):
            priority = 0
    n = calibrate(work_ms)
    period = 1.0 / rate_hz
    count = int(round(seconds * rate_hz))
    wall, cpu = np.empty(count), np.empty(count)
    deadline = time.perf_counter()
    for k in range(count):
        start, cpu_start = time.perf_counter(), time.thread_time()
        spin(n)
        wall[k], cpu[k] = time.perf_counter() - start, time.thread_time() - cpu_start
        deadline = max(deadline + period, time.perf_counter())   # late: the next period starts now
        rest = deadline - time.perf_counter()
        if rest > 0:
            time.sleep(rest)
    wall, cpu = wall * 1e3, cpu * 1e3
    over = wall > period * 1e3
    return dict(work_ms=work_ms, rate_hz=rate_hz, thread_priority=priority, samples=count,
                p50_ms=float(np.percentile(wall, 50)), p99_ms=float(np.percentile(wall, 99)),
                max_ms=float(wall.max()), cpu_p99_ms=float(np.percentile(cpu, 99)), cpu_max_ms=float(cpu.max()),
                overruns=int(over.sum()), overruns_off_cpu=int((over & (cpu <= period * 1e3)).sum()),
                excess_max_ms=float(wall.max() - np.percentile(wall, 50)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work-ms", type=float, default=0.4, help="constant work per period (ms)")
    ap.add_argument("--rate-hz", type=float, default=1000.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--priority", type=int, default=0, help="SCHED_FIFO priority (0: normal scheduler)")
    args = ap.parse_args()
    print(json.dumps(probe(args.work_ms, args.rate_hz, args.seconds, args.priority)))


if __name__ == "__main__":
    main()
