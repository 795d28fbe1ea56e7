"""Command line: ``contact-sim run [SCENE]``, ``contact-sim describe SCENE``, ``contact-sim scenes``,
``contact-sim study STUDY``, ``contact-sim studies``, ``contact-sim bench NAME``. Also ``python -m contact_sim``."""
import argparse
import os
import sys
import time

import numpy as np

from .errors import ContactSimError
from .kinds import DYNAMIC
from .scene import default_scene_path, list_scenes, load_scene, resolve_scene
from .settings import Settings


class Recorder:
    """Collects the trajectory of every body at every step (arrays grow by whole steps)."""

    def __init__(self, world):
        self.names = world.body_names
        self.time, self.position, self.orientation, self.velocity, self.angular_velocity = [], [], [], [], []
        self.energy, self.contacts, self.max_penetration = [], [], []
        self.add(world)

    def add(self, world):
        pos, q = world.poses()
        v, w = world.velocities()
        self.time.append(world.time)
        self.position.append(pos)
        self.orientation.append(q)
        self.velocity.append(v)
        self.angular_velocity.append(w)
        self.energy.append(world.energy())
        c = world.contacts
        self.contacts.append(len(c))
        self.max_penetration.append(float(max(c.depth.max(), 0.0)) if len(c) else 0.0)

    def arrays(self):
        return {k: np.asarray(getattr(self, k)) for k in
                ("time", "position", "orientation", "velocity", "angular_velocity", "energy", "contacts",
                 "max_penetration")}

    def save(self, path):
        a = self.arrays()
        if path.endswith(".npz"):
            np.savez_compressed(path, body_names=np.array(self.names), **a)
            return
        if not path.endswith(".csv"):
            raise ContactSimError(f"--trajectory {path!r}: use a .csv or .npz file name")
        t, n = a["position"].shape[:2]
        cols = np.concatenate([
            np.repeat(a["time"], n)[:, None], a["position"].reshape(-1, 3), a["orientation"].reshape(-1, 4),
            a["velocity"].reshape(-1, 3), a["angular_velocity"].reshape(-1, 3)], axis=1)
        names = np.tile(np.array(self.names, dtype=object), t)
        with open(path, "w") as fh:
            fh.write("time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz\n")
            for name, row in zip(names, cols):  # writing text is I/O-bound; not the simulation hot path
                fh.write(f"{row[0]:.9f},{name}," + ",".join(f"{x:.17g}" for x in row[1:]) + "\n")

    def plot(self, path, world):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        a = self.arrays()
        up = -world.gravity / np.linalg.norm(world.gravity) if np.any(world.gravity) else np.array([0, 0, 1.0])
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for i, name in enumerate(self.names):
            if world.kind[i] == DYNAMIC:
                ax1.plot(a["time"], a["position"][:, i] @ up, label=name)
        ax1.set_ylabel("height (m)")
        if len(self.names) <= 12:
            ax1.legend(fontsize=8)
        ax2.plot(a["time"], a["energy"])
        ax2.set_ylabel("kinetic + potential energy (J)")
        ax2.set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)


def cmd_run(args):
    path = resolve_scene(args.scene) if args.scene else default_scene_path()
    world = load_scene(path)
    # the rule of settings.dt, so --dt is bounded by the scene's max_step like step(dt)
    dt = world.settings.dt if args.dt is None else Settings.rule("dt").check(args.dt, "--dt", world.settings)
    if not (args.duration > 0 and np.isfinite(args.duration)):
        raise ContactSimError(f"--duration: must be > 0, got {args.duration}")
    steps = int(round(args.duration / dt))
    out = sys.stdout
    print(f"scene {os.path.relpath(path)}", file=out)
    print(world.describe(), file=out)
    print(f"{'time s':>8} {'bodies':>6} {'contacts':>8} {'max pen. m':>11} {'energy J':>14}", file=out)
    rec = Recorder(world) if (args.trajectory or args.plot) else None
    progress = None
    if not args.no_progress and args.duration > 2.0 and sys.stderr.isatty():
        from tqdm import tqdm

        progress = tqdm(total=steps, unit="step", file=sys.stderr, leave=False)
    per_second = max(1, int(round(1.0 / dt)))
    window_pen, window_contacts = 0.0, 0
    t0 = time.perf_counter()
    for k in range(1, steps + 1):
        world.step(dt)
        c = world.contacts
        window_contacts = max(window_contacts, len(c))
        if len(c):
            window_pen = max(window_pen, float(c.depth.max()))
        if rec is not None:
            rec.add(world)
        if progress is not None:
            progress.update(1)
        if k % per_second == 0 or k == steps:
            if progress is not None:
                progress.clear()
            print(f"{world.time:8.3f} {len(world):6d} {window_contacts:8d} {window_pen:11.3e} {world.energy():14.6f}",
                  file=out, flush=True)
            window_pen, window_contacts = 0.0, 0
    wall = time.perf_counter() - t0
    if progress is not None:
        progress.close()
    print(f"{steps} steps of {dt:.6g} s in {wall:.3f} s wall ({wall / max(args.duration, 1e-12):.3f} s per simulated s)",
          file=out)
    if rec is not None and args.trajectory:
        rec.save(args.trajectory)
        print(f"trajectory written to {args.trajectory}", file=out)
    if rec is not None and args.plot:
        rec.plot(args.plot, world)
        print(f"plot written to {args.plot}", file=out)
    return 0


def cmd_describe(args):
    world = load_scene(resolve_scene(args.scene) if args.scene else default_scene_path())
    print(world.describe())
    return 0


def cmd_scenes(args):
    for name in list_scenes():
        print(name)
    return 0


def cmd_study(args):
    from .study import load_study, run_study

    study = load_study(args.study)
    out = args.out or os.path.join("study_results", study.name)
    if args.limit is not None and args.limit < 1:
        raise ContactSimError(f"--limit: must be >= 1, got {args.limit}")
    print(f"study {study.name}: {len(study)} runs ({study.cells} cells × {study.replicates}), rows in "
          f"{os.path.join(out, 'runs.csv')}", flush=True)
    run_study(study, out, workers=args.workers, cluster=args.cluster, progress=not args.no_progress, limit=args.limit)
    print(f"summary written to {os.path.join(out, 'summary.csv')}")
    return 0


def cmd_studies(args):
    from .study import list_studies

    for name in list_studies():
        print(name)
    return 0


def cmd_bench(args):
    import runpy

    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench")
    script = os.path.join(here, f"bench_{args.name}.py")
    if not os.path.isfile(script):
        avail = sorted(f[6:-3] for f in os.listdir(here) if f.startswith("bench_")) if os.path.isdir(here) else []
        raise ContactSimError(f"bench {args.name!r}: no such benchmark (available: {', '.join(avail) or 'none'}; "
                              "benchmarks run from a source checkout)")
    sys.argv = [script] + args.rest
    runpy.run_path(script, run_name="__main__")
    return 0


def cmd_warmup(args):
    from .warmup import main as warm

    return warm()


def build_parser():
    p = argparse.ArgumentParser(prog="contact-sim", description="Collision detection and contact response for rigid bodies.")
    sub = p.add_subparsers(dest="command")
    r = sub.add_parser("run", help="step a scene and print a per-second summary")
    r.add_argument("scene", nargs="?", help="scene file, or the name of a shipped scene (default: the default scene)")
    r.add_argument("--duration", type=float, default=3.0, help="simulated seconds (default 3)")
    r.add_argument("--dt", type=float, default=None, help="step size in s (default: the scene's)")
    r.add_argument("--trajectory", metavar="FILE", help="write every body's state at every step (.csv or .npz)")
    r.add_argument("--plot", metavar="PNG", help="plot heights and energy over time")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_run)
    d = sub.add_parser("describe", help="what a scene holds and which models it uses")
    d.add_argument("scene", nargs="?")
    d.set_defaults(func=cmd_describe)
    s = sub.add_parser("scenes", help="list the shipped scenes")
    s.set_defaults(func=cmd_scenes)
    st = sub.add_parser("study", help="run a study: a scene over a grid of parameters and perturbations, summarised")
    st.add_argument("study", help="study file, or the name of a shipped study (contact-sim studies)")
    st.add_argument("--out", metavar="DIR", help="where runs.csv, summary.csv and plot.png go "
                                                 "(default study_results/NAME); run again to resume")
    st.add_argument("--workers", type=int, default=None, help="processes on this machine (default: every core; "
                                                              "1 runs in this process)")
    st.add_argument("--cluster", metavar="auto|local|ray://HOST:PORT", default=None,
                    help="run as Ray tasks: auto (the running cluster), local (a new local Ray), or a Ray client "
                         "address (pip install 'contact_sim[cluster]')")
    st.add_argument("--limit", type=int, default=None, help="only the first N runs")
    st.add_argument("--no-progress", action="store_true", help="no progress bar")
    st.set_defaults(func=cmd_study)
    ss = sub.add_parser("studies", help="list the shipped studies")
    ss.set_defaults(func=cmd_studies)
    b = sub.add_parser("bench", help="run a benchmark from bench/ (detect, response, node, accuracy); `make bench` runs all")
    b.add_argument("name")
    b.add_argument("rest", nargs=argparse.REMAINDER)
    b.set_defaults(func=cmd_bench)
    w = sub.add_parser("warmup", help="compile the kernels once (first run after an install), so later runs load them")
    w.set_defaults(func=cmd_warmup)
    return p


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["run"] + list(argv or []))
    try:
        return args.func(args)
    except ContactSimError as exc:
        print(f"contact-sim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
