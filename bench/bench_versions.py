"""Before and after: per-step wall time of the response benchmark's scenes for two versions of
the engine, in separate processes taking turns (this machine's speed drifts by 2×; alternating
runs and taking medians is what makes the ratio mean something).

    python bench/bench_versions.py 9d0061a            # that commit against the working tree
    python bench/bench_versions.py 9d0061a HEAD~3 --rounds 5

The older version is checked out into a temporary git worktree, its kernels compiled once before
timing. Prints a table (ms per step, median over rounds, and old ÷ new) and writes
``bench/results/versions.csv``.
"""
import argparse
import inspect
import os
import statistics
import subprocess
import sys
import tempfile

from report import write_rows

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# run inside each version's tree: ms per step of each scene (steps after 30 to settle; median of 3)
PROBE = r'''
import statistics, sys, time, warnings
repo = sys.argv[1]
sys.path[:0] = [repo, repo + "/bench"]
warnings.simplefilter("ignore")
import contact_sim
assert contact_sim.__file__.startswith(repo), contact_sim.__file__
import bench_response as br, response_engines as re_
from contact_sim.scene import default_scene_path

def timed(step, n):
    for _ in range(30):
        step()
    ts = []
    for _ in range(3):
        t = time.perf_counter()
        for _ in range(n):
            step()
        ts.append((time.perf_counter() - t) / n * 1e3)
    return statistics.median(ts)

scenes = {"resting_10": (lambda: br.resting_scene(10), 200), "resting_100": (lambda: br.resting_scene(100), 60),
          "stack_10": (br.stack_scene, 200), "rod": (lambda: br.rotation_scene((1.0, 0.05, 0.05)), 200)}
for name, (make, n) in scenes.items():
    print(name, timed(re_.ContactSimEngine(make()).step, n))
print("default_scene", timed(contact_sim.load_scene(default_scene_path()).step, 240))
# PILE

print("pile_fractional", timed(tumbling_pile(contact_sim, "fractional").step, 60))
'''


def tumbling_pile(cs, toi):
    """Ten boxes and 16-point hulls tumbling onto a floor under ``toi`` (``cs``: the package): with exact
    times of impact, the time-of-impact search's own cost for general pairs."""
    import numpy as np

    rng = np.random.default_rng(1)
    bodies = [{"name": "floor", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0.0}}]
    for k in range(10):
        q = rng.normal(size=4)
        shape = {"type": "box", "size": [0.2, 0.15, 0.1]} if k % 2 else \
            {"type": "convex", "points": (rng.normal(size=(16, 3)) * 0.08).tolist()}
        bodies.append({"name": f"b{k}", "shape": shape, "position": [0.3 * (k % 4), 0.3 * (k // 4), 0.3 + 0.25 * k],
                       "orientation": (q / np.linalg.norm(q)).tolist(), "mass": 1.0,
                       "angular_velocity": rng.normal(size=3).tolist()})
    return cs.load_scene({"gravity": [0, 0, -9.81], "settings": {"dt": 1 / 240, "toi": toi}, "bodies": bodies})


def run(tree):
    probe = PROBE.replace("# PILE", inspect.getsource(tumbling_pile))
    out = subprocess.run([sys.executable, "-c", probe, tree], capture_output=True, text=True, check=True).stdout
    return {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if line.strip()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("old", help="the earlier commit")
    ap.add_argument("new", nargs="?", default=None, help="the later commit (default: the working tree)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "versions.csv"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {}
        for label, ref in (("old", args.old), ("new", args.new)):
            if ref is None:
                trees[label] = ROOT
                continue
            path = os.path.join(tmp, label)
            subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", "-f", path, ref], check=True,
                           capture_output=True)
            trees[label] = path
        try:
            for path in trees.values():   # compile (or load) each version's kernels before timing
                subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {path!r}); "
                                "import contact_sim.warmup as w; w.warm_up()"], check=True, capture_output=True)
            times = {"old": [], "new": []}
            for _ in range(args.rounds):
                for label in ("old", "new"):
                    times[label].append(run(trees[label]))
        finally:
            for label, ref in (("old", args.old), ("new", args.new)):
                if ref is not None:
                    subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", trees[label]],
                                   capture_output=True)
    names = list(times["old"][0])
    rows = []
    print(f"{'scene':<14} {args.old + ' ms':>14} {(args.new or 'tree') + ' ms':>14} {'old/new':>8}")
    for n in names:
        o = statistics.median(t[n] for t in times["old"])
        w = statistics.median(t[n] for t in times["new"])
        rows.append({"scene": n, "old": args.old, "new": args.new or "working tree", "old_ms": f"{o:.4f}",
                     "new_ms": f"{w:.4f}", "old_over_new": f"{o / w:.2f}"})
        print(f"{n:<14} {o:>14.3f} {w:>14.3f} {o / w:>8.2f}")
    print(f"wrote {write_rows(args.out, rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
