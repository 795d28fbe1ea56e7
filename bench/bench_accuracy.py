"""Speed against error: every reference scene with an exact answer, every applicable method, a
sweep of step sizes. Prints a table, writes bench/results/accuracy.csv, one work-precision chart
per scene (bench/results/accuracy_<scene>.png) and the summary table (accuracy_summary.md).

    python bench/bench_accuracy.py [--quick] [--scenes a,b] [--no-pybullet]

Errors are relative (unitless) so that one threshold reads the same in every scene; each
scene's line below says relative to what. Cost is wall-clock seconds per simulated second,
measured in this process for this run. pybullet (optional, ``pip install pybullet``) runs the
same scenes as a reference point where its model matches (see ``PYBULLET_NOTES``).
"""
import argparse
import csv
import os
import sys
import time
import warnings

import numpy as np
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import contact_sim as cs  # noqa: E402
from contact_sim import dynamics, quat  # noqa: E402

import exact  # noqa: E402

SCENES_DIR = os.path.join(os.path.dirname(HERE), "config", "scenes")
RESULTS = os.path.join(HERE, "results")
DTS = [1 / 30, 1 / 60, 1 / 120, 1 / 240, 1 / 500, 1 / 1000, 1 / 2000]
QUICK_DTS = [1 / 30, 1 / 120, 1 / 500]
G = 9.81
PYBULLET_NOTES = (
    "pybullet 3.2.7, default solver (50 iterations), linear/angular damping set to 0, restitution velocity "
    "threshold 0. Bullet multiplies the two bodies' restitution and friction, so the static body gets 1.0 "
    "and the moving body the scene's coefficient (product = scene value).")


def scene_dict(name):
    with open(os.path.join(SCENES_DIR, name + ".yaml")) as fh:
        return yaml.safe_load(fh)


def build(d, dt, settings):
    d = dict(d)
    s = dict(d.get("settings") or {})
    s.update(settings)
    s["dt"] = dt
    d["settings"] = s
    return cs.load_scene(d, base_dir=SCENES_DIR)


def timed_steps(world, n, record):
    """Step ``n`` times calling ``record(world)`` after each; returns wall seconds of the stepping."""
    wall = 0.0
    for _ in range(n):
        t0 = time.perf_counter()
        world.step()
        wall += time.perf_counter() - t0
        record(world)
    return wall


# ---------------------------------------------------------------------------- the scenes
IMPULSE_TOI = {
    "impulse + fractional": {"response": "impulse", "toi": "fractional"},
    "impulse + swept": {"response": "impulse", "toi": "swept"},
    "impulse + next_step": {"response": "impulse", "toi": "next_step"},
}
KINEMATIC_TOI = {
    "kinematic + fractional": {"response": "kinematic", "toi": "fractional"},
    "kinematic + next_step": {"response": "kinematic", "toi": "next_step"},
}


def penalty_damping_for(e, k, m):
    """Damping of a linear spring–damper whose bounce has restitution ``e`` (ζ from e = exp(−ζπ/√(1−ζ²)))."""
    a = -np.log(e) / np.pi
    zeta = a / np.sqrt(1 + a * a)
    return 2 * zeta * np.sqrt(k * m)


def bouncing_ball(method, dt):
    """Max |z − z_exact| over 3 s, relative to the drop height (1 m)."""
    d = scene_dict("bouncing_ball")
    w = build(d, dt, method)
    b = d["bodies"][1]
    h0, r, e = b["position"][2], b["shape"]["radius"], d["materials"]["rubber"]["restitution"]
    ts, zs = [], []
    n = int(round(3.0 / dt))
    wall = timed_steps(w, n, lambda w: (ts.append(w.time), zs.append(w.body("ball").position[2])))
    err = np.max(np.abs(np.array(zs) - exact.bouncing_height(np.array(ts), h0, r, e, G))) / h0
    return err, wall / (n * dt)


def bouncing_methods():
    k, m = 1e5, 1.0
    c = penalty_damping_for(0.8, k, m)
    return {**IMPULSE_TOI, **KINEMATIC_TOI,
            "penalty (k 1e5, ζ for e 0.8)": {"response": "penalty", "toi": "next_step",
                                              "penalty": {"stiffness": k, "damping": float(c)}}}


def two_spheres(method, dt):
    """Max position error of either sphere over 1 s, relative to their initial separation (1 m)."""
    d = scene_dict("two_spheres")
    w = build(d, dt, method)
    left, right = d["bodies"]
    e = d["materials"]["elastic"]["restitution"]
    ts, p1, p2 = [], [], []
    n = int(round(1.0 / dt))

    def rec(w):
        ts.append(w.time)
        p1.append(w.body("left").position[0])
        p2.append(w.body("right").position[0])

    wall = timed_steps(w, n, rec)
    x1, x2, _ = exact.head_on(np.array(ts), left["position"][0], right["position"][0], left["velocity"][0],
                              right["velocity"][0], left["mass"], right["mass"], left["shape"]["radius"],
                              right["shape"]["radius"], e)
    err = max(np.abs(np.array(p1) - x1).max(), np.abs(np.array(p2) - x2).max()) / (right["position"][0] - left["position"][0])
    return err, wall / (n * dt)


def rod_impact(method, dt):
    """Post-impact linear velocity and angular momentum (gravity since the impact removed) at 30 ms
    after the exact impact, relative to their exact values (the larger of the two)."""
    d = scene_dict("rod_impact")
    w = build(d, dt, method)
    rod = d["bodies"][1]
    e = d["materials"]["steel"]["restitution"]
    q = quat.normalize(np.array(rod["orientation"], float))
    half = 0.5 * np.array(rod["shape"]["size"], float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    com = np.array(rod["position"], float)
    corners_w = com + quat.rotate(q, corners)
    body = w.body("rod")
    inv_i = dynamics.world_inverse_inertia(q[None], np.linalg.inv(body.inertia)[None])[0]
    tc, v_plus, l_plus = exact.rod_impact(corners_w, com, np.array(rod["velocity"], float), rod["mass"], inv_i, e, G)
    t_end = tc + 0.03
    n = int(np.ceil(t_end / dt))
    wall = timed_steps(w, n, lambda w: None)
    v = w.body("rod").velocity - np.array([0, 0, -G]) * (w.time - tc)
    L = w.angular_momentum() - np.cross(w.s.pos[1], rod["mass"] * w.s.vel[1])  # spin part only
    err = max(np.linalg.norm(v - v_plus) / np.linalg.norm(v_plus), np.linalg.norm(L - l_plus) / np.linalg.norm(l_plus))
    return err, wall / (n * dt)


def sliding_block(method, dt):
    """Stop distance after 1 s against v0²/(2μg), relative."""
    d = scene_dict("sliding_block")
    w = build(d, dt, method)
    block = d["bodies"][1]
    v0, mu = block["velocity"][0], d["materials"]["wood"]["friction"]
    n = int(round(1.0 / dt))
    wall = timed_steps(w, n, lambda w: None)
    dist = w.body("block").position[0] - block["position"][0]
    expect = exact.sliding_stop_distance(v0, mu, G)
    return abs(dist - expect) / expect, wall / (n * dt)


def solver_methods():
    out = {f"impulse, {it} iterations": {"response": "impulse", "toi": "next_step", "solver_iterations": it}
           for it in (4, 20)}
    # penalty with its regularised Coulomb friction (issue 14): k 5e4, damping ratio 0.7 for 1 kg
    k = 5e4
    out["penalty + friction (k 5e4)"] = {"response": "penalty", "toi": "next_step", "friction": True,
                                         "penalty": {"stiffness": k, "damping": float(2 * 0.7 * np.sqrt(k))}}
    return out


THETA, MU_INCLINE = np.radians(35.0), 0.5


def incline_dict():
    th = THETA
    n = [np.sin(th), 0.0, np.cos(th)]
    return {
        "gravity": [0, 0, -G],
        "materials": {"wood": {"restitution": 0.0, "friction": MU_INCLINE}},
        "bodies": [
            {"name": "slope", "kind": "static", "shape": {"type": "plane", "normal": n, "offset": 0.0}, "material": "wood"},
            {"name": "block", "shape": {"type": "box", "size": [0.2, 0.2, 0.2]}, "mass": 1.0,
             "position": [0.1 * n[0], 0, 0.1 * n[2]], "orientation": [0, np.sin(th / 2), 0, np.cos(th / 2)],
             "material": "wood"},
        ],
    }


def incline(method, dt):
    """Acceleration down a 35° incline (μ 0.5) from the distance slid in 1 s, against g(sinθ − μcosθ), relative."""
    d = incline_dict()
    w = build(d, dt, method)
    p0 = np.array(d["bodies"][1]["position"])
    n = int(round(1.0 / dt))
    wall = timed_steps(w, n, lambda w: None)
    down = np.array([np.cos(THETA), 0, -np.sin(THETA)])
    a = 2 * (w.body("block").position - p0) @ down / w.time ** 2
    expect = exact.incline_acceleration(THETA, MU_INCLINE, G)
    return abs(a - expect) / expect, wall / (n * dt)


def penalty_rest(method, dt):
    """Penetration after 2 s against m g / k, relative."""
    d = scene_dict("penalty_rest")
    w = build(d, dt, method)
    n = int(round(2.0 / dt))
    wall = timed_steps(w, n, lambda w: None)
    k = (method.get("penalty") or {}).get("stiffness", d["settings"]["penalty"]["stiffness"])
    depth = 0.1 - w.body("ball").position[2]
    expect = exact.penalty_rest_depth(1.0, G, k)
    err = abs(depth - expect) / expect
    return (err if np.isfinite(err) else np.inf), wall / (n * dt)


def penalty_methods():
    return {f"penalty k {k:g}": {"response": "penalty", "penalty": {"stiffness": k, "damping": 2 * 0.25 * np.sqrt(k)}}
            for k in (1e4, 1e6)}


SCENES = {
    "bouncing_ball": (bouncing_ball, bouncing_methods, "max height error / drop height, 3 s, e 0.8"),
    "two_spheres": (two_spheres, lambda: {**IMPULSE_TOI, **KINEMATIC_TOI}, "max position error / separation, e 1"),
    "rod_impact": (rod_impact, lambda: IMPULSE_TOI, "post-impact v and L error, relative (lecture's j)"),
    "sliding_block": (sliding_block, solver_methods, "stop distance error / v0²/(2μg), μ 0.5"),
    "incline": (incline, solver_methods, "acceleration error / g(sinθ − μcosθ), 35°, μ 0.5"),
    "penalty_rest": (penalty_rest, penalty_methods, "rest depth error / (m g / k)"),
}


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


def plot(scene, rows, what):
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
    path = os.path.join(RESULTS, f"accuracy_{scene}.png")
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
    args = ap.parse_args(argv)
    os.makedirs(RESULTS, exist_ok=True)
    dts = QUICK_DTS if args.quick else DTS
    try:
        import pybullet  # noqa: F401

        have_pb = not args.no_pybullet
    except ImportError:
        have_pb = False
    all_rows = []
    summary = ["| scene | error measured | cheapest within 1e-3 | cheapest within 1e-6 |", "|---|---|---|---|"]
    for scene in args.scenes.split(","):
        fn, methods, what = SCENES[scene]
        rows = []
        print(f"\n== {scene}: {what}")
        print(f"{'method':<34} {'dt':>7} {'error':>10} {'s/sim s':>9}")
        for name, settings in methods().items():
            for dt in dts:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # preflight warnings (e.g. next_step tunnelling) are expected
                    with np.errstate(all="ignore"):
                        err, cost = fn(settings, dt)
                rows.append({"scene": scene, "method": name, "dt": dt, "error": float(err), "cost": cost})
                print(f"{name:<34} {dt_label(dt):>7} {err:10.2e} {cost:9.4f}", flush=True)
        if have_pb:
            for dt in dts:
                res = pybullet_run(scene, dt)
                if res is None:
                    break
                err = res[0]
                rows.append({"scene": scene, "method": "pybullet (reference)", "dt": dt, "error": float(err),
                             "cost": res[1]})
                print(f"{'pybullet (reference)':<34} {dt_label(dt):>7} {err:10.2e} {res[1]:9.4f}", flush=True)
        plot(scene, rows, what)
        summary.append(f"| {scene} | {what} | {cheapest(rows, 1e-3)} | {cheapest(rows, 1e-6)} |")
        all_rows += rows
    with open(os.path.join(RESULTS, "accuracy.csv"), "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=["scene", "method", "dt", "error", "cost"])
        wr.writeheader()
        wr.writerows(all_rows)
    text = "\n".join(summary)
    if have_pb:
        text += "\n\nReference: " + PYBULLET_NOTES
    with open(os.path.join(RESULTS, "accuracy_summary.md"), "w") as fh:
        fh.write(text + "\n")
    print("\n" + text)
    print(f"\nwrote {os.path.relpath(RESULTS)}/accuracy.csv, accuracy_summary.md and accuracy_<scene>.png")


if __name__ == "__main__":
    main()
