"""Compile (or load from the cache) every compiled kernel once: ``python -m contact_sim.warmup``.

numba compiles a kernel the first time it runs and caches the machine code beside the source, so
the first run after an install pays the compile time (about ten minutes for all of them on this
project's 2-core machine, two of them for the one-call sub-step, ``response.substep.run_detected``)
and every later process loads them in seconds. ``make venv`` and a colcon
build run this once, so neither a user's first scene nor the node's first ticks stall on it.
Without numba (or with ``NUMBA_DISABLE_JIT=1``) it only runs the queries.
"""
import sys
import time

import numpy as np


def warm_up():
    """Run one query of every detection kernel and a short step; returns the seconds it took."""
    t0 = time.perf_counter()
    import trimesh

    import contact_sim as cs

    I = (0.0, 0.0, 0.0, 1.0)
    rng = np.random.default_rng(0)
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    shapes = {"plane": cs.Plane(), "sphere": cs.Sphere(0.3), "box": cs.Box((0.5, 0.4, 0.3)),
              "convex": cs.Convex(rng.normal(size=(12, 3)) * 0.2), "mesh": cs.TriMesh(box.vertices, box.faces),
              "cylinder": cs.Cylinder(0.2, 0.5)}
    names = list(shapes)
    for i, a in enumerate(names):
        for b in names[:i + 1]:
            if a == b == "plane":
                continue
            cs.collide(shapes[a], ((0.0, 0.0, 0.1), I), shapes[b], ((0.0, 0.0, 0.0), I), margin=0.01)
    world = cs.World()        # a step of every kind of body (the stepper's kernels too)
    world.add_body("ground", shapes["plane"], kind="static")
    world.add_body("step", shapes["mesh"], kind="static", position=(3.0, 0.0, 0.0))
    for k, name in enumerate(("sphere", "box", "convex")):
        world.add_body(name, shapes[name], density=1000.0, position=(k * 0.8, 0.0, 0.25),
                       angular_velocity=(0.0, 0.0, 0.0) if name == "sphere" else (0.3, 0.2, 0.1))
    for _ in range(5):
        world.step(0.01)
    # the sub-step's whole exit (``response.substep``), which worlds of more than a few bodies take
    # (the one above, with ``auto``, gets exact times of impact: the split exit)
    rest = cs.World(settings=cs.Settings(toi="next_step"))
    rest.add_body("ground", shapes["plane"], kind="static")
    rest.add_body("box", shapes["box"], density=1000.0, position=(0.0, 0.0, 0.15))
    for _ in range(3):
        rest.step(0.01)
    # the free-flight step (``stepper.flight``): a ball far above the ground, after its first step
    fly = cs.World(settings=cs.Settings(toi="next_step"))
    fly.add_body("ground", shapes["plane"], kind="static")
    fly.add_body("ball", shapes["sphere"], density=1000.0, position=(0.0, 0.0, 5.0))
    for _ in range(3):
        fly.step(0.01)
    # the compiled Gauss–Seidel (large contact sets) and the penalty response's friction sweeps
    from .response import solver

    z = np.zeros((2, 3))
    rows = solver.build_rows(np.array([1]), np.array([0]), np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), z,
                             np.array([0.0, 1.0]), np.zeros((2, 3, 3)), z, z)
    solver.solve(rows, z.copy(), z.copy(), target_n=np.zeros(1), mu_s=np.ones(1), mu_d=np.ones(1))
    soft = cs.World(settings=cs.Settings(response="penalty"))
    soft.add_body("ground", shapes["plane"], kind="static")
    soft.add_body("box", shapes["box"], density=1000.0, position=(0.0, 0.0, 0.149), velocity=(0.1, 0.0, 0.0))
    for _ in range(3):
        soft.step(0.01)
    return time.perf_counter() - t0


def main():
    seconds = warm_up()
    print(f"contact_sim: kernels compiled or loaded in {seconds:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
