"""Response benchmark: 1000 spheres (r 5 cm) from a 10×10×10 grid into a walled 1.4 m box
(friction 0.5, no restitution, dt 1/240) and the 10-box stack. Reports wall time per simulated
second, contacts per step, solver iterations and maximum penetration; CSV to bench/results/.

    .venv/bin/python bench/bench_response.py [--seconds 2.0]
"""
import argparse
import csv
import os
import time
import warnings

import numpy as np

import contact_sim as cs

HERE = os.path.dirname(os.path.abspath(__file__))


def spheres_scene():
    walls = [([0, 0, 1], 0.0), ([1, 0, 0], -0.7), ([-1, 0, 0], -0.7), ([0, 1, 0], -0.7), ([0, -1, 0], -0.7)]
    bodies = [{"name": f"wall{i}", "kind": "static", "shape": {"type": "plane", "normal": n, "offset": o},
               "material": "m"} for i, (n, o) in enumerate(walls)]
    g = (np.arange(10) - 4.5) * 0.12
    k = 0
    for x in g:
        for y in g:
            for z in range(10):
                bodies.append({"name": f"s{k}", "shape": {"type": "sphere", "radius": 0.05}, "mass": 0.5,
                               "position": [float(x), float(y), 0.1 + 0.12 * z], "material": "m"})
                k += 1
    return {"gravity": [0, 0, -9.81],
            "settings": {"dt": 1 / 240, "response": "impulse", "friction": True, "resting": True},
            "materials": {"m": {"restitution": 0.0, "friction": 0.5}}, "bodies": bodies}


def run(name, world, seconds):
    steps = int(round(seconds / world.settings.dt))
    contacts, iters, pen = [], [], []
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(steps):
            world.step()
            ls = world.last_solve
            contacts.append(ls["contacts"])
            iters.append(ls["iterations"])
            pen.append(ls["max_penetration"])
    wall = time.perf_counter() - t0
    row = {"scene": name, "bodies": len(world), "simulated_s": steps * world.settings.dt,
           "wall_s_per_sim_s": wall / (steps * world.settings.dt), "contacts_per_step": float(np.mean(contacts)),
           "solver_iterations_mean": float(np.mean(iters)), "max_penetration_mm": 1e3 * float(np.max(pen)),
           "final_penetration_mm": 1e3 * float(np.max(pen[-24:]))}
    print(row)
    return row


def run_pybullet(seconds):
    """The same 1000-sphere scene in pybullet (optional): wall time per simulated second and the
    largest penetration it reports. Friction 0.5 on both bodies (Bullet multiplies: 0.25 per pair
    would be wrong, so each gets sqrt(0.5)), restitution 0, dt 1/240, its default 50 iterations."""
    try:
        import pybullet as p
    except ImportError:
        return None
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -9.81)
    p.setTimeStep(1 / 240)
    mu = float(np.sqrt(0.5))
    for n, o in [([0, 0, 1], 0.0), ([1, 0, 0], -0.7), ([-1, 0, 0], -0.7), ([0, 1, 0], -0.7), ([0, -1, 0], -0.7)]:
        shape = p.createCollisionShape(p.GEOM_PLANE, planeNormal=n)
        b = p.createMultiBody(0, shape, basePosition=[o * n[0], o * n[1], 0])
        p.changeDynamics(b, -1, lateralFriction=mu, restitution=0.0)
    sph = p.createCollisionShape(p.GEOM_SPHERE, radius=0.05)
    g = (np.arange(10) - 4.5) * 0.12
    for x in g:
        for y in g:
            for z in range(10):
                b = p.createMultiBody(0.5, sph, basePosition=[float(x), float(y), 0.1 + 0.12 * z])
                p.changeDynamics(b, -1, lateralFriction=mu, restitution=0.0)
    steps = int(round(seconds * 240))
    pen, final = 0.0, 0.0
    wall = 0.0
    ncontacts = []
    for k in range(steps):
        t0 = time.perf_counter()
        p.stepSimulation()
        wall += time.perf_counter() - t0          # only the step is timed, not the contact query
        pts = p.getContactPoints()
        ncontacts.append(len(pts))
        if pts:
            d = -min(c[8] for c in pts)
            pen = max(pen, d)
            if k >= steps - 24:
                final = max(final, d)
    p.disconnect(cid)
    return {"scene": "spheres_1000_pybullet", "bodies": 1005, "simulated_s": steps / 240,
            "wall_s_per_sim_s": wall / (steps / 240), "contacts_per_step": float(np.mean(ncontacts)),
            "solver_iterations_mean": 50.0, "max_penetration_mm": 1e3 * pen, "final_penetration_mm": 1e3 * final}


def run_variant(method, iterations, coloring, seconds):
    """The sphere scene with the large-set solver forced to ``method`` (``gs`` coloured Gauss–Seidel,
    ``jacobi`` mass-splitting Jacobi), ``iterations`` per solve and the Gauss–Seidel colouring:
    ``hybrid`` (the default: few Luby colours, index-ordered colours for large impact solves),
    ``luby`` (few colours everywhere) or ``greedy`` (index order everywhere): the speed/penetration
    trade-off."""
    from contact_sim import stepper
    from contact_sim.response import solver

    old = stepper.SOLVER_METHOD, solver.COLORING, stepper.IMPACT_COLORING
    stepper.SOLVER_METHOD = method
    solver.COLORING = "greedy" if coloring == "greedy" else "luby"
    stepper.IMPACT_COLORING = {"hybrid": "greedy", "luby": None, "greedy": None}[coloring]
    try:
        world = cs.load_scene(spheres_scene())
        world.settings.solver_iterations = iterations
        return run(f"spheres_1000_{method}{iterations}_{coloring}", world, seconds)
    finally:
        stepper.SOLVER_METHOD, solver.COLORING, stepper.IMPACT_COLORING = old


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--variants", nargs="*", default=[], metavar="METHOD:ITERATIONS[:COLORING]",
                    help="extra runs of the sphere scene, e.g. gs:10 gs:20:luby gs:20:greedy jacobi:20 "
                         "(solver trade-off; colouring hybrid (default), luby or greedy)")
    args = ap.parse_args()
    rows = [run("spheres_1000", cs.load_scene(spheres_scene()), args.seconds),
            run("box_stack_10", cs.load_scene(os.path.join(HERE, "..", "config", "scenes", "box_stack.yaml")),
                args.seconds)]
    for v in args.variants:
        method, iters, *col = v.split(":")
        rows.append(run_variant(method, int(iters), col[0] if col else "hybrid", args.seconds))
    pb = run_pybullet(args.seconds)
    if pb is not None:
        print(pb)
        rows.append(pb)
    print(f"\n{'scene':28s} {'wall s/sim s':>12s} {'contacts':>9s} {'iters':>6s} {'max pen mm':>10s} "
          f"{'last 0.1 s':>10s}")
    for r in rows:
        print(f"{r['scene']:28s} {r['wall_s_per_sim_s']:12.3f} {r['contacts_per_step']:9.1f} "
              f"{r['solver_iterations_mean']:6.1f} {r['max_penetration_mm']:10.3f} {r['final_penetration_mm']:10.4f}")
    if pb is not None:
        print(f"ratio contact_sim / pybullet (spheres): {rows[0]['wall_s_per_sim_s'] / pb['wall_s_per_sim_s']:.2f}")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    out = os.path.join(HERE, "results", "response.csv")
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("wrote", out)


if __name__ == "__main__":
    main()
