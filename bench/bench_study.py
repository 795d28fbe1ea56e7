"""Studies on several workers: the same study of 200 one-second runs of the default scene (every run
with the ball, the crate and the brick dropped from perturbed positions) on one worker (in this
process), on a local process pool of two, and, when Ray is installed, as Ray tasks on a local Ray
of two CPUs. Prints a table, writes bench/results/study.csv.

    python bench/bench_study.py [--runs 200] [--duration 1.0] [--no-ray]

speed-up: one worker's wall time ÷ this one's. Per-run overhead: (wall × workers − the runs' own
wall time) ÷ runs — scheduling, start-up (spawning and importing the workers, loading the kernels
from numba's cache) and writing the rows, spread over the runs. Start-up alone: the wall time of
two runs on two fresh workers minus one run's own time. Memory: the driver's peak resident size
(``ru_maxrss``) running 1,000 and 10,000 one-step runs in a fresh process (rows streamed to
``runs.csv``, none held; the summary at the end reads the figures back).
"""
import argparse
import csv
import os
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from contact_sim.study import load_study, run_study  # noqa: E402

RESULTS = os.path.join(HERE, "results")


def study(runs, duration):
    """The benchmark's study: the default scene, ``runs`` replicates of one cell, positions perturbed."""
    return load_study({
        "name": "bench_study", "scene": "default", "duration": duration, "seed": 1, "replicates": runs,
        "perturb": {"drop": {"paths": ["bodies.ball.position[0]", "bodies.crate.position[1]",
                                       "bodies.brick.position[2]"], "distribution": "normal", "std": 0.05}},
        "record": ["final_pose", "max_penetration", "energy_drift", "contacts"]})


def measure(s, label, workers, cluster=None, limit=None):
    """Run ``s`` into a fresh folder; returns ``(label, workers, runs, wall s, Σ run wall s)``."""
    out = tempfile.mkdtemp(prefix="bench_study_")
    try:
        t0 = time.perf_counter()
        path, _ = run_study(s, out, workers=workers, cluster=cluster, progress=False, limit=limit, stream=False)
        wall = time.perf_counter() - t0
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert not any(r["exception"] for r in rows), [r["exception"] for r in rows if r["exception"]][:3]
        return label, workers, len(rows), wall, sum(float(r["wall_time"]) for r in rows)
    finally:
        shutil.rmtree(out, ignore_errors=True)


TINY = """
import resource, sys, tempfile
from contact_sim.study import run_study
scene = {"settings": {"dt": 0.01}, "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}},
         {"name": "ball", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0, "position": [0, 0, 0.1]}]}
study = {"scene": scene, "duration": 0.01, "replicates": int(sys.argv[1]), "record": ["max_penetration"],
         "perturb": {"p": {"paths": ["bodies.ball.position[2]"], "distribution": "uniform", "low": 0, "high": 0.01}}}
with tempfile.TemporaryDirectory() as out:
    run_study(study, out, workers=1, progress=False, stream=False)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def peak_memory(runs):
    """Peak resident size (MB) of a fresh process running a study of ``runs`` one-step runs, and its wall s."""
    import subprocess

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.dirname(HERE), os.environ.get("PYTHONPATH", "")]))
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", TINY, str(runs)], capture_output=True, text=True, env=env, check=True)
    return int(out.stdout.split()[-1]) / 1024, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--memory-runs", default="1000,10000", help="study lengths of the memory check ('' skips it)")
    args = ap.parse_args(argv)
    s = study(args.runs, args.duration)
    try:
        import ray  # noqa: F401

        have_ray = not args.no_ray
    except ImportError:
        have_ray = False
    load0 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    measure(s, "warm", 1, limit=2)      # the kernels in numba's cache and this process, before any timing
    rows = [measure(s, "in this process", 1), measure(s, "process pool", 2)]
    startup = [measure(s, "process pool start-up (2 runs)", 2, limit=2)]
    if have_ray:
        rows.append(measure(s, "Ray, local, 2 CPUs", 2, cluster="local"))
        startup.append(measure(s, "Ray start-up (2 runs)", 2, cluster="local", limit=2))
    base = rows[0][3]
    one_run = rows[0][4] / rows[0][2]
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"{args.runs} runs of {args.duration:g} s of the default scene; one run takes {one_run * 1e3:.1f} ms "
          f"in this process; {os.cpu_count()} cores, load average before {load0[0]:.2f}, after {load[0]:.2f} "
          "(other processes' load takes cores from the workers)")
    print(f"{'executor':<32} {'workers':>7} {'runs':>5} {'wall s':>8} {'speed-up':>8} {'overhead ms/run':>15}")
    table = []
    for label, workers, n, wall, busy in rows:
        overhead = (wall * workers - busy) / n
        table.append({"executor": label, "workers": workers, "runs": n, "wall_s": wall, "speedup": base / wall,
                      "overhead_ms_per_run": overhead * 1e3, "run_ms": busy / n * 1e3})
        print(f"{label:<32} {workers:>7} {n:>5} {wall:8.2f} {base / wall:8.2f} {overhead * 1e3:15.2f}")
    for label, workers, n, wall, busy in startup:
        print(f"{label:<32} {workers:>7} {n:>5} {wall:8.2f}   start-up {wall - busy / n:.2f} s")
        table.append({"executor": label, "workers": workers, "runs": n, "wall_s": wall, "speedup": "",
                      "overhead_ms_per_run": "", "run_ms": busy / n * 1e3, "startup_s": wall - busy / n})
    for n in [int(x) for x in args.memory_runs.split(",") if x]:
        mb, wall = peak_memory(n)
        print(f"driver peak memory, {n} one-step runs in one process: {mb:.0f} MB ({wall:.1f} s)")
        table.append({"executor": f"memory: {n} one-step runs", "workers": 1, "runs": n, "wall_s": wall,
                      "peak_mb": mb})
    os.makedirs(RESULTS, exist_ok=True)
    with open(os.path.join(RESULTS, "study.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["executor", "workers", "runs", "wall_s", "speedup", "overhead_ms_per_run",
                                           "run_ms", "startup_s", "peak_mb"])
        w.writeheader()
        w.writerows(table)
    print(f"wrote {os.path.relpath(os.path.join(RESULTS, 'study.csv'))}")


if __name__ == "__main__":
    main()
