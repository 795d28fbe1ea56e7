"""Mesh–mesh query cost with and without the per-mesh AABB tree (issue 14), and python-fcl's BVH
verdict beside it.

Usage: ``python bench/bench_mesh_mesh.py [--poses 200] [--sections 8 16 32 64 128]``

Two tori (``sections`` × ``sections/2`` segments, ``sections²`` triangles each) at random poses within
2.4 m of each other (the hits column says how many intersect); ``cs.collide`` per pair, median of the
per-query time over the poses. "no tree" is the same kernel with a tree of one leaf holding every triangle (each vertex
ray-cast against every triangle, every triangle pair of the two meshes examined): the cost of the
lecture's tests without the hierarchy. Writes ``bench/results/mesh_mesh.csv``.
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from contact_sim.collision import mesh_mesh  # noqa: E402
from report import write_rows  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def torus(sections):
    import trimesh
    t = trimesh.creation.torus(1.0, 0.3, major_sections=sections, minor_sections=max(sections // 2, 4))
    return t, cs.TriMesh(t.vertices, t.faces)


def poses(n, seed=0):
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(seed)
    p = rng.uniform([-2.4, -2.4, -0.8], [2.4, 2.4, 0.8], size=(n, 3))
    return p, Rotation.random(n, random_state=rng).as_quat()


def time_queries(A, B, P, Q):
    I = (0.0, 0.0, 0.0, 1.0)
    cs.collide(A, ((0, 0, 0), I), B, (P[0], Q[0]))      # compile / build the trees outside the timing
    out, hits = [], 0
    for p, q in zip(P, Q):
        t0 = time.perf_counter()
        c = cs.collide(A, ((0, 0, 0), I), B, (p, q))
        out.append(time.perf_counter() - t0)
        hits += len(c) > 0
    return float(np.median(out)), hits


def time_fcl(t, P, Q):
    import fcl
    from scipy.spatial.transform import Rotation
    m = fcl.BVHModel()
    m.beginModel(len(t.vertices), len(t.faces))
    m.addSubModel(np.asarray(t.vertices, float), np.asarray(t.faces, np.int32))
    m.endModel()
    oa = fcl.CollisionObject(m, fcl.Transform())
    out, hits = [], 0
    for p, q in zip(P, Q):
        t0 = time.perf_counter()
        ob = fcl.CollisionObject(m, fcl.Transform(Rotation.from_quat(q).as_matrix(), p))
        hits += fcl.collide(oa, ob, fcl.CollisionRequest(), fcl.CollisionResult()) > 0
        out.append(time.perf_counter() - t0)
    return float(np.median(out)), hits


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=200)
    ap.add_argument("--sections", type=int, nargs="+", default=[8, 16, 32, 64, 128])
    ap.add_argument("--no-tree-max", type=int, default=5000, help="skip 'no tree' above this many triangles")
    args = ap.parse_args(argv)
    P, Q = poses(args.poses)
    rows = []
    for s in args.sections:
        t, A = torus(s)
        tree, hits = time_queries(A, A, P, Q)
        flat, hits0 = float("nan"), hits
        if len(t.faces) <= args.no_tree_max:
            _, A2 = torus(s)
            keep = mesh_mesh.LEAF_SIZE
            mesh_mesh.LEAF_SIZE = 1 << 40          # one leaf: every triangle in it
            try:
                flat, hits0 = time_queries(A2, A2, P, Q)
            finally:
                mesh_mesh.LEAF_SIZE = keep
        try:
            f, fh = time_fcl(t, P, Q)
        except ImportError:
            f, fh = float("nan"), -1
        rows.append({"triangles": len(t.faces), "tree_ms": tree * 1e3, "no_tree_ms": flat * 1e3,
                     "fcl_ms": f * 1e3, "hits": hits, "hits_no_tree": hits0, "fcl_hits": fh})
        r = rows[-1]
        print(f"{r['triangles']:7d} triangles: tree {r['tree_ms']:.3f} ms, no tree {r['no_tree_ms']:.3f} ms, "
              f"fcl {r['fcl_ms']:.3f} ms per query; hits {hits}/{len(P)} (no tree {hits0}, fcl {fh})", flush=True)
    write_rows(os.path.join(HERE, "results", "mesh_mesh.csv"), rows)


if __name__ == "__main__":
    main()
