"""Speed against error: every reference scene with an exact answer, every applicable method, a
sweep of step sizes. Prints a table, writes bench/results/accuracy.csv, one work-precision chart
per scene (bench/results/accuracy_<scene>.png) and the summary table (accuracy_summary.md).

    python bench/bench_accuracy.py [--quick] [--scenes a,b] [--no-pybullet] [--out DIR]

contact_sim's figures are the accuracy studies' (config/studies/accuracy_<scene>.yaml: each
scene's models × step sizes, the error recorded by the study's ``reference``), run here with
``cs.run_study`` in this process, one run after the other (``--quick`` replaces the studies'
step sizes with three). Errors are relative (unitless) so that one threshold reads the same in
every scene; each scene's line below says relative to what. Cost is wall-clock seconds of
stepping per simulated second, measured in this process for this run (the study's ``cost``).
pybullet (optional, ``pip install pybullet``) runs the same scenes as a reference point where its
model matches (see ``PYBULLET_NOTES``).
"""
import argparse
import csv
import math
import os
import sys
import tempfile
import time

import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import contact_sim as cs  # noqa: E402
from contact_sim.study import Study  # noqa: E402

import exact  # noqa: E402

RESULTS = os.path.join(HERE, "results")
QUICK_DTS = [1 / 30, 1 / 120, 1 / 500]
G = 9.81
PYBULLET_NOTES = (
    "pybullet 3.2.7, default solver (50 iterations), linear/angular damping set to 0, restitution velocity "
    "threshold 0. Bullet multiplies the two bodies' restitution and friction, so the static body gets 1.0 "
    "and the moving body the scene's coefficient (product = scene value).")

#: scene → what its error measures (the summary's and the charts' text); the models, step sizes and
#: measure are the study config/studies/accuracy_<scene>.yaml's
SCENES = {
    "bouncing_ball": "max height error / drop height, 3 s, e 0.8",
    "two_spheres": "max position error / separation, e 1",
    "rod_impact": "post-impact v and L error, relative (lecture's j)",
    "sliding_block": "stop distance error / v0²/(2μg), μ 0.5",
    "incline": "acceleration error / g(sinθ − μcosθ), 35°, μ 0.5",
    "penalty_rest": "rest depth error / (m g / k)",
}
#: the incline of accuracy_incline.yaml's scene (pybullet builds the same)
THETA, MU_INCLINE = np.radians(35.0), 0.5


# ---------------------------------------------------------------------------- contact_sim: the studies
def accuracy_study(scene, dts=None):
    """The accuracy study of ``scene`` (``config/studies/accuracy_<scene>.yaml``), its step sizes
    (s) replaced by ``dts`` when given."""
    path = cs.resolve_study(f"accuracy_{scene}")
    with open(path) as fh:
        data = yaml.safe_load(fh)
    if dts is not None:
        data["grid"]["settings.dt"] = list(dts)
    return Study(data, where_dir=os.path.dirname(path), name=data.get("name"))


def study_rows(scene, dts, workdir):
    """contact_sim's rows of ``scene``: its accuracy study run by ``cs.run_study`` in this process
    (one run after the other, so that each run's cost is measured alone) into ``workdir``, as
    ``{scene, method (the model's label), dt (s), error, cost (s per simulated s)}`` in the
    study's order (model, then step size). A run that raised has error inf (its exception is printed)."""
    study = accuracy_study(scene, dts)
    path, _ = cs.run_study(study, os.path.join(workdir, scene), workers=1, progress=False, stream=False)
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            if r["exception"]:
                print(f"  {r['settings']} at dt {r['settings.dt']}: {r['exception']}", file=sys.stderr)
            err = math.inf if r["exception"] else float(r["error"])
            rows.append({"scene": scene, "method": r["settings"], "dt": float(r["settings.dt"]),
                         "error": err if math.isfinite(err) else math.inf,
                         "cost": float(r["cost"]) if r["cost"] else math.nan})
    return rows


# ---------------------------------------------------------------------------- pybullet reference
def pybullet_run(scene, dt):
    import pybullet as p

    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -G, physicsClientId=cid)
        p.setTimeStep(dt, physicsClientId=cid)
        p.setPhysicsEngineParameter(restitutionVelocityThreshold=0.0, physicsClientId=cid)

        def body(shape, mass, pos, orn=(0, 0, 0, 1), vel=(0, 0, 0), e=0.0, mu=0.0):
            b = p.createMultiBody(mass, shape, basePosition=pos, baseOrientation=orn, physicsClientId=cid)
            p.changeDynamics(b, -1, restitution=e, lateralFriction=mu, linearDamping=0, angularDamping=0,
                             rollingFriction=0, spinningFriction=0, physicsClientId=cid)
            if mass:
                p.resetBaseVelocity(b, vel, (0, 0, 0), physicsClientId=cid)
            return b

        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        if scene == "bouncing_ball":
            body(plane, 0, (0, 0, 0), e=1.0, mu=1.0)
            ball = body(p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid), 1.0, (0, 0, 1.0), e=0.8)
            n = int(round(3.0 / dt))
            ts, zs = [], []
            t0 = time.perf_counter()
            for k in range(n):
                p.stepSimulation(physicsClientId=cid)
                ts.append((k + 1) * dt)
                zs.append(p.getBasePositionAndOrientation(ball, physicsClientId=cid)[0][2])
            wall = time.perf_counter() - t0
            h0 = 1.0  # relative to the drop height, as for contact_sim
            err = np.max(np.abs(np.array(zs) - exact.bouncing_height(np.array(ts), h0, 0.1, 0.8, G))) / h0
            return err, wall / (n * dt)
        if scene == "two_spheres":
            p.setGravity(0, 0, 0, physicsClientId=cid)
            s = p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid)
            a = body(s, 1.0, (-0.5, 0, 0), vel=(1.5, 0, 0), e=1.0)
            b = body(s, 1.0, (0.5, 0, 0), vel=(-0.5, 0, 0), e=1.0)
            n = int(round(1.0 / dt))
            ts, p1, p2 = [], [], []
            t0 = time.perf_counter()
            for k in range(n):
                p.stepSimulation(physicsClientId=cid)
                ts.append((k + 1) * dt)
                p1.append(p.getBasePositionAndOrientation(a, physicsClientId=cid)[0][0])
                p2.append(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0][0])
            wall = time.perf_counter() - t0
            x1, x2, _ = exact.head_on(np.array(ts), -0.5, 0.5, 1.5, -0.5, 1, 1, 0.1, 0.1, 1.0)
            sep = 1.0  # relative to the initial separation, as for contact_sim
            return max(np.abs(np.array(p1) - x1).max(), np.abs(np.array(p2) - x2).max()) / sep, wall / (n * dt)
        if scene in ("sliding_block", "incline"):
            box = p.createCollisionShape(p.GEOM_BOX, halfExtents=(0.1, 0.1, 0.1), physicsClientId=cid)
            if scene == "sliding_block":
                body(plane, 0, (0, 0, 0), mu=1.0)
                blk = body(box, 1.0, (0, 0, 0.1), vel=(2.0, 0, 0), mu=0.5)
                p0, down, expect = np.zeros(3), np.array([1.0, 0, 0]), exact.sliding_stop_distance(2.0, 0.5, G)
            else:
                th = THETA
                body(plane, 0, (0, 0, 0), orn=(0, np.sin(th / 2), 0, np.cos(th / 2)), mu=1.0)
                p0 = np.array([0.1 * np.sin(th), 0, 0.1 * np.cos(th)])
                blk = body(box, 1.0, tuple(p0), orn=(0, np.sin(th / 2), 0, np.cos(th / 2)), mu=MU_INCLINE)
                down, expect = np.array([np.cos(th), 0, -np.sin(th)]), exact.incline_acceleration(th, MU_INCLINE, G)
            n = int(round(1.0 / dt))
            t0 = time.perf_counter()
            for _ in range(n):
                p.stepSimulation(physicsClientId=cid)
            wall = time.perf_counter() - t0
            pos = np.array(p.getBasePositionAndOrientation(blk, physicsClientId=cid)[0])
            moved = (pos - (p0 if scene == "incline" else np.array([0, 0, 0.1]))) @ down
            value = moved if scene == "sliding_block" else 2 * moved / (n * dt) ** 2
            return abs(value - expect) / expect, wall / (n * dt)
        return None
    finally:
        p.disconnect(physicsClientId=cid)


# ---------------------------------------------------------------------------- report
def dt_label(dt):
    return f"1/{round(1 / dt)}"


def plot(scene, rows, what, out=RESULTS):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    floor = 1e-16
    methods = sorted({r["method"] for r in rows}, key=lambda m: (m.startswith("pybullet"), m))
    for m in methods:
        rs = sorted([r for r in rows if r["method"] == m and np.isfinite(r["error"])], key=lambda r: -r["dt"])
        if not rs:
            continue
        x = [r["cost"] for r in rs]
        y = [max(r["error"], floor) for r in rs]
        style = dict(marker="s", linestyle="--", color="black") if m.startswith("pybullet") else dict(marker="o")
        ax.loglog(x, y, label=m, **style)
        for xi, yi, r in zip(x, y, rs):
            ax.annotate(dt_label(r["dt"]), (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=6)
    ax.set_xlabel("wall time per simulated second (s)")
    ax.set_ylabel("relative error")
    ax.set_title(f"{scene}: {what}\n(errors below 1e-16 drawn at 1e-16)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out, f"accuracy_{scene}.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def cheapest(rows, threshold):
    ok = [r for r in rows if r["error"] <= threshold and not r["method"].startswith("pybullet")]
    if not ok:
        best = min((r for r in rows if not r["method"].startswith("pybullet")), key=lambda r: r["error"])
        return f"not reached (best {best['error']:.1e}: {best['method']} at dt {dt_label(best['dt'])})"
    r = min(ok, key=lambda r: r["cost"])
    return f"{r['method']}, dt {dt_label(r['dt'])}: {r['cost']:.3g} s/s (error {r['error']:.1e})"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help=f"only dt in {[dt_label(d) for d in QUICK_DTS]}")
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated subset")
    ap.add_argument("--no-pybullet", action="store_true")
    ap.add_argument("--out", default=RESULTS, help="folder of the CSV, charts and summary (default bench/results)")
    args = ap.parse_args(argv)
    out = args.out
    os.makedirs(out, exist_ok=True)
    dts = QUICK_DTS if args.quick else None
    try:
        import pybullet  # noqa: F401

        have_pb = not args.no_pybullet
    except ImportError:
        have_pb = False
    all_rows = []
    summary = ["| scene | error measured | cheapest within 1e-3 | cheapest within 1e-6 |", "|---|---|---|---|"]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench_accuracy_") as workdir:
        for scene in args.scenes.split(","):
            what = SCENES[scene]
            print(f"\n== {scene}: {what} (study accuracy_{scene})")
            print(f"{'method':<34} {'dt':>7} {'error':>10} {'s/sim s':>9}")
            rows = study_rows(scene, dts, workdir)
            for r in rows:
                print(f"{r['method']:<34} {dt_label(r['dt']):>7} {r['error']:10.2e} {r['cost']:9.4f}", flush=True)
            if have_pb:
                for dt in sorted({r["dt"] for r in rows}, reverse=True):
                    res = pybullet_run(scene, dt)
                    if res is None:
                        break
                    err = res[0]
                    rows.append({"scene": scene, "method": "pybullet (reference)", "dt": dt, "error": float(err),
                                 "cost": res[1]})
                    print(f"{'pybullet (reference)':<34} {dt_label(dt):>7} {err:10.2e} {res[1]:9.4f}", flush=True)
            plot(scene, rows, what, out)
            summary.append(f"| {scene} | {what} | {cheapest(rows, 1e-3)} | {cheapest(rows, 1e-6)} |")
            all_rows += rows
    with open(os.path.join(out, "accuracy.csv"), "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=["scene", "method", "dt", "error", "cost"])
        wr.writeheader()
        wr.writerows(all_rows)
    text = "\n".join(summary) + ("\n\ncontact_sim's rows are the accuracy studies' (config/studies/accuracy_<scene>.yaml, "
                                  "`contact-sim study accuracy_<scene>`), run one after the other in one process"
                                  + (", at dt 1/30, 1/120 and 1/500 only (--quick)." if args.quick else "."))
    if have_pb:
        text += "\n\nReference: " + PYBULLET_NOTES
    with open(os.path.join(out, "accuracy_summary.md"), "w") as fh:
        fh.write(text + "\n")
    print("\n" + text)
    print(f"\nwrote {os.path.relpath(out)}/accuracy.csv, accuracy_summary.md and accuracy_<scene>.png "
          f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
