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
           "solver_iterations_mean": float(np.mean(iters)), "max_penetration_mm": 1e3 * float(np.max(pen))}
    print(row)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=2.0)
    args = ap.parse_args()
    rows = [run("spheres_1000", cs.load_scene(spheres_scene()), args.seconds),
            run("box_stack_10", cs.load_scene(os.path.join(HERE, "..", "config", "scenes", "box_stack.yaml")),
                args.seconds)]
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    out = os.path.join(HERE, "results", "response.csv")
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("wrote", out)


if __name__ == "__main__":
    main()
