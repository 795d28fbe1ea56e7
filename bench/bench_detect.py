"""All-pairs detection benchmark: time per stage and contacts/s over mixed bodies.

Usage: ``python bench/bench_detect.py [--sizes 100 500 2000 10000] [--repeat 5] [--no-fcl]``

Bodies are spheres, boxes and 32-vertex convex hulls (a third each, ~1 m across) on a jittered
grid; about 10% of them are moved against a neighbour so they touch or overlap. One dynamic world
per size is detected ``repeat`` times with ``contact_sim.collision.detect_world`` (the median is
reported), then the same poses go to trimesh's FCL-backed ``CollisionManager`` (meshes: an
icosphere, the box, the hull) and the ratio is printed. Writes ``bench/results/detect.csv``.
"""
import argparse
import csv
import os
import sys
import time
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from contact_sim import quat as Q  # noqa: E402
from contact_sim.collision import detect_world  # noqa: E402
from contact_sim.settings import Settings  # noqa: E402


def make_shapes(rng):
    pts = rng.normal(size=(32, 3))
    pts = pts / np.linalg.norm(pts, axis=1, keepdims=True) * 0.5
    hull = cs.Convex(pts)
    while len(hull.vertices) != 32:   # all points on a sphere are hull vertices; be sure
        pts = rng.normal(size=(32, 3))
        hull = cs.Convex(pts / np.linalg.norm(pts, axis=1, keepdims=True) * 0.5)
    return [cs.Sphere(0.5), cs.Box((0.9, 0.8, 0.7)), hull]


def make_scene(n, seed=0):
    """A world-like structure of ``n`` bodies (what ``detect_world`` reads) and the shape ids."""
    rng = np.random.default_rng(seed)
    shapes = make_shapes(rng)
    kinds = rng.integers(0, 3, size=n)
    side = int(np.ceil(n ** (1 / 3)))
    g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    spacing = 2.0
    pos = g * spacing + rng.uniform(-0.2, 0.2, size=(n, 3))
    # ~10% of bodies touching: 5% of them are moved against their +x neighbour
    movers = rng.choice(n, size=max(1, n // 20), replace=False)
    pos[movers, 0] += spacing - 0.95 + rng.uniform(-0.05, 0.02, size=len(movers))
    quat = Q.normalize(rng.normal(size=(n, 4)))
    s = SimpleNamespace(pos=pos, quat=quat)
    world = SimpleNamespace(shapes=[shapes[k] for k in kinds], s=s, kind=np.full(n, 2, np.int8),
                            group=np.ones(n, np.uint32), mask=np.full(n, 0xFFFFFFFF, np.uint32),
                            settings=Settings())
    return world, shapes, kinds


def bench_ours(world, repeat):
    detect_world(world)   # prepare the per-world tables once
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        c, st = detect_world(world)
        runs.append((time.perf_counter() - t, c, st))
    runs.sort(key=lambda r: r[0])
    return runs[len(runs) // 2]


def bench_fcl(world, shapes, kinds, repeat):
    import trimesh

    meshes = [trimesh.creation.icosphere(subdivisions=2, radius=0.5), trimesh.creation.box(shapes[1].size),
              trimesh.Trimesh(shapes[2].vertices, shapes[2].faces)]
    m = trimesh.collision.CollisionManager()
    R = Q.to_matrix(world.s.quat)
    t_build = time.perf_counter()
    for i, k in enumerate(kinds):
        T = np.eye(4)
        T[:3, :3] = R[i]
        T[:3, 3] = world.s.pos[i]
        m.add_object(str(i), meshes[k], transform=T)
    t_build = time.perf_counter() - t_build
    times, times_data = [], []
    for _ in range(repeat):
        t = time.perf_counter()
        hit, names = m.in_collision_internal(return_names=True)
        times.append(time.perf_counter() - t)
        # with contact data (points, normals, depths): the work our detection does
        t = time.perf_counter()
        m.in_collision_internal(return_names=True, return_data=True)
        times_data.append(time.perf_counter() - t)
    return float(np.median(times)), len(names), t_build, float(np.median(times_data))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 500, 2000, 10000])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-fcl", action="store_true")
    ap.add_argument("--csv", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "detect.csv"))
    args = ap.parse_args(argv)
    rows = []
    print(f"{'bodies':>7} {'cand':>6} {'bvrej':>6} {'vert':>5} {'e-f':>5} {'pairs':>6} {'contacts':>8} "
          f"{'broad ms':>9} {'bv ms':>7} {'narrow ms':>9} {'total ms':>9} {'contacts/s':>11} {'fcl ms':>8} "
          f"{'fcl/ours':>8} {'fcl+data ms':>11}")
    for n in args.sizes:
        world, shapes, kinds = make_scene(n)
        total, c, st = bench_ours(world, args.repeat)
        fcl_ms, fcl_pairs, ratio, fcl_data_ms = float("nan"), -1, float("nan"), float("nan")
        if not args.no_fcl:
            try:
                f, fcl_pairs, _, fd = bench_fcl(world, shapes, kinds, max(1, min(args.repeat, 3)))
                fcl_ms, fcl_data_ms = 1e3 * f, 1e3 * fd
                ratio = f / total
            except Exception as exc:  # fcl missing or failing: report, keep our numbers
                print(f"  (fcl manager unavailable: {exc})")
        sec = st.seconds
        row = dict(bodies=n, candidate_pairs=st.candidate_pairs, rejected_by_bv=st.rejected_by_bounding_volume,
                   settled_by_vertex=st.settled_by_vertex, needed_edge_face=st.needed_edge_face,
                   colliding_pairs=st.colliding_pairs, contacts=st.contacts,
                   broad_ms=1e3 * sec["broad"], bounding_ms=1e3 * sec["bounding"], narrow_ms=1e3 * sec["narrow"],
                   total_ms=1e3 * total, contacts_per_s=st.contacts / total, fcl_ms=fcl_ms,
                   fcl_colliding_pairs=fcl_pairs, fcl_over_ours=ratio, fcl_with_data_ms=fcl_data_ms)
        rows.append(row)
        print(f"{n:>7} {st.candidate_pairs:>6} {st.rejected_by_bounding_volume:>6} {st.settled_by_vertex:>5} "
              f"{st.needed_edge_face:>5} {st.colliding_pairs:>6} {st.contacts:>8} {row['broad_ms']:>9.2f} "
              f"{row['bounding_ms']:>7.2f} {row['narrow_ms']:>9.2f} {row['total_ms']:>9.2f} "
              f"{row['contacts_per_s']:>11.0f} {fcl_ms:>8.2f} {ratio:>8.2f} {fcl_data_ms:>11.2f}")
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
