"""Before and after in one process: the step of each scene for an earlier commit and the working
tree, taking turns round by round.

    python bench/bench_ab.py 2b2d200 [--rounds 20] [--scenes resting_10,default_scene]

The earlier commit's package is copied as ``contact_sim_old`` (its imports are relative) into a
directory kept per commit under the system's temp dir, so its compiled kernels are cached there
after the first run. Both versions build the same scenes (``bench_versions``' list) and step them
in turns of 100 steps; the ratio reported is the median over rounds of old ÷ new within a round,
which cancels this shared machine's drift (2× over minutes) better than separate processes can.
It also says whether the two trajectories stayed bit-identical. Prints a table and writes
``bench/results/ab.csv``.
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def old_package(ref):
    """Directory holding the commit's package as ``contact_sim_old`` (made once per commit)."""
    sha = subprocess.run(["git", "-C", ROOT, "rev-parse", ref], capture_output=True, text=True,
                         check=True).stdout.strip()
    base = os.path.join(tempfile.gettempdir(), "contact_sim_ab", sha)
    target = os.path.join(base, "contact_sim_old")
    if not os.path.isdir(target):
        tree = os.path.join(base, "tree")
        subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", "-f", tree, sha], check=True,
                       capture_output=True)
        try:
            shutil.copytree(os.path.join(tree, "contact_sim"), target, ignore=shutil.ignore_patterns("__pycache__"))
        finally:
            subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", tree], capture_output=True)
    return base


def scenes(cs):
    """name -> (world of package ``cs``, steps per turn)."""
    import bench_response as br
    import bench_versions as bv
    import response_engines as re_

    def engine(make):
        # the engine class imports ``contact_sim``: hand it the package under test
        saved = sys.modules["contact_sim"]
        sys.modules["contact_sim"] = cs
        try:
            return re_.ContactSimEngine(make()).world
        finally:
            sys.modules["contact_sim"] = saved

    return {"ball_1": engine(br.ball_scene), "spheres_10": engine(br.spheres_scene),
            "resting_10": engine(lambda: br.resting_scene(10)), "resting_100": engine(lambda: br.resting_scene(100)),
            "stack_10": engine(br.stack_scene), "rod": engine(lambda: br.rotation_scene((1.0, 0.05, 0.05))),
            "default_scene": cs.load_scene(os.path.join(ROOT, "config", "scenes", "default.yaml")),
            "pile_fractional": bv.tumbling_pile(cs, "fractional"), "sweeper_30": sweeper(cs),
            "pile_1000": engine(br.pile_scene)}


def sweeper(cs, n=30):
    """A kinematic arm turning at 2 rad/s about the vertical through the middle of a walled pen of
    ``n`` balls and boxes (a push every step, for as long as it is stepped)."""
    import numpy as np

    rng = np.random.default_rng(3)
    w = cs.World(settings=cs.Settings(dt=0.004, toi="next_step"),
                 materials={"m": cs.Material(restitution=0.2, friction=0.5)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    for i, (x, y, sx, sy) in enumerate([(1.1, 0, 0.2, 2.4), (-1.1, 0, 0.2, 2.4), (0, 1.1, 2.4, 0.2), (0, -1.1, 2.4, 0.2)]):
        w.add_body(f"wall{i}", cs.Box((sx, sy, 0.4)), kind="static", position=(x, y, 0.2), material="m")
    w.add_body("arm", cs.Box((1.6, 0.06, 0.2)), kind="kinematic", position=(0, 0, 0.1), angular_velocity=(0, 0, 2.0),
               material="m")
    for i in range(n):
        r, a = rng.uniform(0.2, 0.9), rng.uniform(0, 2 * np.pi)
        shape = cs.Sphere(0.06) if i % 2 else cs.Box((0.1, 0.1, 0.1))
        w.add_body(f"b{i}", shape, mass=0.3, position=(r * np.cos(a), r * np.sin(a), 0.06), material="m")
    return w


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("old", help="the earlier commit")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--steps", type=int, default=100, help="steps per turn")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "ab.csv"))
    ap.add_argument("--scenes", help="comma-separated subset of the scenes (default: all)")
    args = ap.parse_args()
    sys.path[:0] = [old_package(args.old), ROOT, HERE]
    warnings.simplefilter("ignore")
    import numpy as np
    from report import write_rows

    import contact_sim as new
    import contact_sim_old as old

    worlds = {"old": scenes(old), "new": scenes(new)}
    rows = []
    print(f"{'scene':<16} {args.old + ' ms':>12} {'tree ms':>10} {'old/new':>8}  bit-identical")
    wanted = args.scenes.split(",") if args.scenes else list(worlds["new"])
    unknown = set(wanted) - set(worlds["new"])
    if unknown:
        ap.error(f"unknown scenes {sorted(unknown)}; the scenes are {', '.join(worlds['new'])}")
    for name in wanted:
        wo, wn = worlds["old"][name], worlds["new"][name]
        for _ in range(30):   # settle, and load or compile the kernels both take
            wo.step()
            wn.step()
        times = {"old": [], "new": []}
        for _ in range(args.rounds):
            for label, w in (("old", wo), ("new", wn)):
                t = time.perf_counter()
                for _ in range(args.steps):
                    w.step()
                times[label].append((time.perf_counter() - t) / args.steps * 1e3)
        same = all(np.array_equal(getattr(wo.s, a), getattr(wn.s, a)) for a in ("pos", "vel", "quat", "omega"))
        ratio = statistics.median(o / n for o, n in zip(times["old"], times["new"]))
        o, n = statistics.median(times["old"]), statistics.median(times["new"])
        rows.append({"scene": name, "old": args.old, "old_ms": f"{o:.4f}", "new_ms": f"{n:.4f}",
                     "old_over_new": f"{ratio:.3f}", "bit_identical": same})
        print(f"{name:<16} {o:>12.3f} {n:>10.3f} {ratio:>8.2f}  {'yes' if same else 'no'}")
    print(f"wrote {write_rows(args.out, rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
