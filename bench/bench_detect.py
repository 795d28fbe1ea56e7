"""Detection benchmark: contact_sim beside MuJoCo, FCL (primitives and trimesh's mesh manager) and
pybullet, one process, engines taking turns on the same bodies and poses.

Usage: ``python bench/bench_detect.py [--repeat 7] [--sizes 100 300 1000 3000 10000] [--quick]``

Scenes (seeded): 500 mixed bodies, a third spheres (radius 0.05–0.15 m), a third boxes (edges
0.1–0.3 m), a third convex hulls of 32 random points (on spheres of radius 0.05–0.15 m), uniform
random positions and orientations in a 6 m cube (~24 touching pairs) and a 3 m cube (~160).

* **cold**: the first query after building the world (``cs.load_scene`` for contact_sim, so shape
  preparation is included; the compiled kernels are already loaded in this process: their one-time
  cost is printed separately); for the peers the first query after building their world. Each
  engine builds its world ``--cold-repeat`` times (default 5) and the median first query is
  reported: one first query of a few ms is at the mercy of this shared machine's drift.
* **warm**: the same query repeated on the same poses (median of ``repeat``). The ratio to each
  peer is the median of per-round ratios with the two queries timed back to back, taking turns
  (``taking_turns``, ``5 × repeat`` rounds): the warm times are medians taken one engine after the
  other, seconds apart, and their quotient would carry this shared machine's drift.
* peers: MuJoCo ``mj_collision`` on an MJCF of the same bodies (mesh geoms for the hulls),
  python-fcl's ``DynamicAABBTreeCollisionManager`` on fcl.Sphere/Box/Convex (verdict only, and
  with contact data), trimesh's ``CollisionManager`` (FCL on meshes: an icosphere for a sphere),
  pybullet ``performCollisionDetection`` + ``getContactPoints``.
* scale: the same mix at the 6 m scene's density from 100 to 10,000 bodies, contact_sim against
  FCL primitives, with the fitted exponent of contact_sim's warm time (``t ∝ n^k``).

Writes ``bench/results/detect.csv`` (scenes) and ``bench/results/detect_scale.csv``.
"""
import argparse
import csv
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from contact_sim import quat as Q  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


# ------------------------------------------------------------------ the bodies
def mixed_bodies(n, side, seed=0):
    """``n`` bodies as dicts (type, geometry, position, orientation), uniform in a cube of ``side`` m."""
    rng = np.random.default_rng(seed)
    out = []
    kinds = np.arange(n) % 3
    pos = rng.uniform(0, side, size=(n, 3))
    quat = Q.normalize(rng.normal(size=(n, 4)))
    for i in range(n):
        b = {"name": f"b{i}", "position": pos[i], "orientation": quat[i]}
        if kinds[i] == 0:
            b.update(type="sphere", radius=float(rng.uniform(0.05, 0.15)))
        elif kinds[i] == 1:
            b.update(type="box", size=rng.uniform(0.1, 0.3, size=3))
        else:
            p = rng.normal(size=(32, 3))
            b.update(type="convex", points=p / np.linalg.norm(p, axis=1, keepdims=True) * rng.uniform(0.05, 0.15))
        out.append(b)
    return out


def scene_of(bodies):
    def shape(b):
        if b["type"] == "sphere":
            return {"type": "sphere", "radius": b["radius"]}
        if b["type"] == "box":
            return {"type": "box", "size": b["size"].tolist()}
        return {"type": "convex", "points": b["points"].tolist()}

    return {"gravity": [0, 0, 0], "settings": {"contact_margin": 0.0},
            "bodies": [{"name": b["name"], "shape": shape(b), "mass": 1.0, "position": b["position"].tolist(),
                        "orientation": b["orientation"].tolist()} for b in bodies]}


def hull_geometry(world, bodies):
    """Vertices and triangles of each hull as the world holds them, in the body's origin frame."""
    out = {}
    for i, b in enumerate(bodies):
        if b["type"] == "convex":
            s = world.shapes[i]
            out[i] = (s.vertices + world.com_local[i], s.faces)
    return out


def median_time(fn, repeat):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


# ------------------------------------------------------------------ the engines
def run_ours(bodies, repeat):
    world = cs.load_scene(scene_of(bodies))
    t = time.perf_counter()
    c = world.detect()
    cold = time.perf_counter() - t
    cold_stats = world.last_detection
    warm = median_time(world.detect, repeat)
    c = world.detect()
    st = world.last_detection
    pairs = len(set(zip(c.body_a.tolist(), c.body_b.tolist())))
    return dict(cold=cold, warm=warm, pairs=pairs, contacts=len(c), stats=st, cold_stats=cold_stats), world


def run_fcl(bodies, hulls, repeat, contacts):
    query = fcl_query(bodies, hulls, contacts)
    t = time.perf_counter()
    query()
    cold = time.perf_counter() - t
    warm = median_time(query, repeat)
    return dict(cold=cold, warm=warm, query=query)


def fcl_query(bodies, hulls, contacts):
    """python-fcl's dynamic AABB tree over the bodies as primitives: the query (every colliding
    pair; ``contacts``: with contact data)."""
    import fcl

    objs = []
    for i, b in enumerate(bodies):
        if b["type"] == "sphere":
            g = fcl.Sphere(b["radius"])
        elif b["type"] == "box":
            g = fcl.Box(*b["size"])
        else:
            v, f = hulls[i]
            g = fcl.Convex(np.asarray(v, float), len(f), np.column_stack([np.full(len(f), 3), f]).ravel())
        objs.append(fcl.CollisionObject(g, fcl.Transform(Q.to_matrix(b["orientation"]), b["position"])))
    m = fcl.DynamicAABBTreeCollisionManager()
    m.registerObjects(objs)
    m.setup()
    # every colliding pair (the default callback stops once the result holds num_max_contacts)
    req = fcl.CollisionRequest(num_max_contacts=1_000_000, enable_contact=contacts)

    def query():
        data = fcl.CollisionData(request=req)
        m.collide(data, fcl.defaultCollisionCallback)
        return data

    return query


def taking_turns(ours, peer, rounds):
    """Median over ``rounds`` of ``ours() time ÷ peer() time``, the two timed back to back in each
    round (the order alternating): the ratio without the drift of a shared machine between them."""
    ratios = []
    for r in range(rounds):
        times = {}
        for name, fn in ((("ours", ours), ("peer", peer)) if r % 2 == 0 else (("peer", peer), ("ours", ours))):
            t = time.perf_counter()
            fn()
            times[name] = time.perf_counter() - t
        ratios.append(times["ours"] / times["peer"])
    return float(np.median(ratios))


def run_fcl_pairs(bodies, hulls):
    """Touching pairs by python-fcl's pair query (a reference count for the scene)."""
    import fcl

    objs = {}
    for i, b in enumerate(bodies):
        if b["type"] == "sphere":
            g = fcl.Sphere(b["radius"])
        elif b["type"] == "box":
            g = fcl.Box(*b["size"])
        else:
            v, f = hulls[i]
            g = fcl.Convex(np.asarray(v, float), len(f), np.column_stack([np.full(len(f), 3), f]).ravel())
        objs[id(g)] = i
        b["_fcl"] = fcl.CollisionObject(g, fcl.Transform(Q.to_matrix(b["orientation"]), b["position"]))
    m = fcl.DynamicAABBTreeCollisionManager()
    m.registerObjects([b["_fcl"] for b in bodies])
    m.setup()
    data = fcl.CollisionData(request=fcl.CollisionRequest(num_max_contacts=100000, enable_contact=True))
    m.collide(data, fcl.defaultCollisionCallback)
    found = {tuple(sorted((objs[id(c.o1)], objs[id(c.o2)]))) for c in data.result.contacts}
    for b in bodies:
        b.pop("_fcl")
    return len(found)


def run_trimesh(bodies, hulls, repeat):
    import trimesh

    m = trimesh.collision.CollisionManager()
    for i, b in enumerate(bodies):
        if b["type"] == "sphere":
            mesh = trimesh.creation.icosphere(subdivisions=2, radius=b["radius"])
        elif b["type"] == "box":
            mesh = trimesh.creation.box(b["size"])
        else:
            mesh = trimesh.Trimesh(*hulls[i], process=False)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Q.to_matrix(b["orientation"]), b["position"]
        m.add_object(str(i), mesh, transform=T)

    def query():
        return m.in_collision_internal(return_names=True, return_data=True)

    t = time.perf_counter()
    query()
    cold = time.perf_counter() - t
    return dict(cold=cold, warm=median_time(query, repeat), query=query)


def run_mujoco(bodies, hulls, repeat):
    import mujoco

    assets, geoms = [], []
    for i, b in enumerate(bodies):
        p = " ".join(f"{x:.17g}" for x in b["position"])
        q = b["orientation"]
        quat = f"{q[3]:.17g} {q[0]:.17g} {q[1]:.17g} {q[2]:.17g}"   # MuJoCo: w x y z
        if b["type"] == "sphere":
            g = f'type="sphere" size="{b["radius"]:.17g}"'
        elif b["type"] == "box":
            g = 'type="box" size="' + " ".join(f"{0.5 * x:.17g}" for x in b["size"]) + '"'
        else:
            v, _ = hulls[i]
            assets.append(f'<mesh name="m{i}" vertex="' + " ".join(f"{x:.17g}" for x in np.ravel(v)) + '"/>')
            g = f'type="mesh" mesh="m{i}"'
        geoms.append(f'<body pos="{p}" quat="{quat}"><freejoint/><geom {g}/></body>')
    xml = ('<mujoco><option><flag gravity="disable"/></option><asset>' + "".join(assets) + "</asset><worldbody>"
           + "".join(geoms) + "</worldbody></mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    t = time.perf_counter()
    mujoco.mj_collision(model, data)
    cold = time.perf_counter() - t
    warm = median_time(lambda: mujoco.mj_collision(model, data), repeat)
    return dict(cold=cold, warm=warm, contacts=int(data.ncon), query=lambda: mujoco.mj_collision(model, data))


def run_pybullet(bodies, hulls, repeat):
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:   # the connection stays open for ``taking_turns``: ``close`` ends it
        for i, b in enumerate(bodies):
            if b["type"] == "sphere":
                s = pb.createCollisionShape(pb.GEOM_SPHERE, radius=b["radius"], physicsClientId=cid)
            elif b["type"] == "box":
                s = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=(0.5 * b["size"]).tolist(), physicsClientId=cid)
            else:
                s = pb.createCollisionShape(pb.GEOM_MESH, vertices=np.asarray(hulls[i][0]).tolist(),
                                            physicsClientId=cid)
            pb.createMultiBody(1.0, s, -1, b["position"].tolist(), b["orientation"].tolist(), physicsClientId=cid)

        def query():
            pb.performCollisionDetection(physicsClientId=cid)
            return pb.getContactPoints(physicsClientId=cid)

        t = time.perf_counter()
        query()
        cold = time.perf_counter() - t
        warm = median_time(query, repeat)
        return dict(cold=cold, warm=warm, query=query, close=lambda: pb.disconnect(cid))
    except BaseException:
        pb.disconnect(cid)
        raise


def repeated(fn, n, *args):
    """``fn(*args)`` ``n`` times, each building its world afresh: the last result, with ``cold`` the
    median of the ``n`` first queries (``fn`` returns a dict, or a tuple starting with one)."""
    results = [fn(*args) for _ in range(n)]
    first = [r[0] if isinstance(r, tuple) else r for r in results]
    for r in first[:-1]:   # only the last world is queried again
        r.get("close", lambda: None)()
    d = dict(first[-1], cold=float(np.median([r["cold"] for r in first])))
    return (d,) + results[-1][1:] if isinstance(results[-1], tuple) else d


def guarded(name, fn, *args):
    try:
        return fn(*args)
    except ImportError as exc:
        print(f"  ({name} unavailable: {exc})")
    return dict(cold=float("nan"), warm=float("nan"))


# ------------------------------------------------------------------ main
def scenes(args, w):
    rows = []
    for side in (6.0, 3.0):
        bodies = mixed_bodies(500, side, seed=13)
        n = args.cold_repeat
        ours, world = repeated(run_ours, n, bodies, args.repeat)
        hulls = hull_geometry(world, bodies)
        fcl_pairs = guarded("fcl", run_fcl_pairs, bodies, hulls)
        peers = {
            "mujoco": guarded("mujoco", repeated, run_mujoco, n, bodies, hulls, args.repeat),
            "fcl": guarded("fcl", repeated, run_fcl, n, bodies, hulls, args.repeat, False),
            "fcl+contacts": guarded("fcl", repeated, run_fcl, n, bodies, hulls, args.repeat, True),
            "pybullet": guarded("pybullet", repeated, run_pybullet, n, bodies, hulls, args.repeat),
            "trimesh": guarded("trimesh", repeated, run_trimesh, n, bodies, hulls, args.repeat),
        }
        st, cst = ours["stats"], ours["cold_stats"]
        # the warm ratios from the two queries taking turns, not from the medians taken one engine after
        # the other (issue 13's target: warm ≤ 1× FCL)
        turns = {}
        for name, r in peers.items():
            turns[name] = taking_turns(world.detect, r["query"], 5 * args.repeat) if "query" in r else float("nan")
            r.get("close", lambda: None)()
        print(f"\n500 bodies in a {side:g} m cube: contact_sim {ours['pairs']} touching pairs "
              f"({ours['contacts']} contacts), fcl {fcl_pairs} pairs")
        print(f"  {'engine':<14} {'cold ms':>9} {'warm ms':>9} {'ours/peer warm, taking turns':>29} {'ours/peer cold':>15}")
        print(f"  {'contact_sim':<14} {1e3 * ours['cold']:>9.3f} {1e3 * ours['warm']:>9.3f}")
        for name, r in peers.items():
            print(f"  {name:<14} {1e3 * r['cold']:>9.3f} {1e3 * r['warm']:>9.3f} {turns[name]:>29.2f} "
                  f"{ours['cold'] / r['cold']:>15.2f}")
        print("  contact_sim stages, warm ms: " + ", ".join(f"{k} {1e3 * v:.3f}" for k, v in st.seconds.items()))
        print("  contact_sim stages, cold ms: " + ", ".join(f"{k} {1e3 * v:.3f}" for k, v in cst.seconds.items()))
        row = dict(scene=f"{side:g} m cube", bodies=500, touching_pairs=ours["pairs"], fcl_touching_pairs=fcl_pairs,
                   contacts=ours["contacts"], ours_cold_ms=1e3 * ours["cold"], ours_warm_ms=1e3 * ours["warm"])
        for k, v in st.seconds.items():
            row[f"ours_warm_{k}_ms"] = 1e3 * v
        row["ours_cold_prepare_ms"] = 1e3 * cst.seconds.get("prepare", float("nan"))
        for name, r in peers.items():
            row[f"{name}_cold_ms"], row[f"{name}_warm_ms"] = 1e3 * r["cold"], 1e3 * r["warm"]
            row[f"ours_over_{name}_warm"] = turns[name]
        rows.append(row)
    w(rows, "detect.csv")


def scale(args, w):
    rows = []
    print(f"\nscale (6 m scene's density): {'bodies':>7} {'ours ms':>9} {'fcl ms':>9} {'ours/fcl':>9} "
          f"{'pairs':>6} {'cold ms':>9}")
    for n in args.sizes:
        side = 6.0 * (n / 500) ** (1 / 3)
        bodies = mixed_bodies(n, side, seed=17)
        ours, world = run_ours(bodies, args.repeat)
        hulls = hull_geometry(world, bodies)
        f = guarded("fcl", run_fcl, bodies, hulls, max(3, args.repeat // 2), False)
        rows.append(dict(bodies=n, side_m=side, ours_warm_ms=1e3 * ours["warm"], ours_cold_ms=1e3 * ours["cold"],
                         fcl_warm_ms=1e3 * f["warm"],
                         ours_over_fcl=(taking_turns(world.detect, f["query"], max(3, args.repeat // 2))
                                        if "query" in f else float("nan")),
                         touching_pairs=ours["pairs"]))
        r = rows[-1]
        print(f"{'':>28}{n:>7} {r['ours_warm_ms']:>9.3f} {r['fcl_warm_ms']:>9.3f} {r['ours_over_fcl']:>9.2f} "
              f"{r['touching_pairs']:>6} {r['ours_cold_ms']:>9.2f}")
    if len(rows) > 1:
        n = np.log([r["bodies"] for r in rows])
        k = np.polyfit(n, np.log([r["ours_warm_ms"] for r in rows]), 1)[0]
        kf = np.polyfit(n, np.log([r["fcl_warm_ms"] for r in rows]), 1)[0]
        print(f"fitted exponent of the warm time, t ∝ n^k, {rows[0]['bodies']}..{rows[-1]['bodies']} bodies: "
              f"contact_sim k = {k:.3f}, fcl k = {kf:.3f} (n log n over this range fits k ≈ 1.1)")
        for r in rows:
            r["fitted_exponent"], r["fcl_fitted_exponent"] = k, kf
    w(rows, "detect_scale.csv")


def compile_report():
    """Seconds to load (or compile) the detection kernels in this process: one small world."""
    t = time.perf_counter()
    w = cs.load_scene(scene_of(mixed_bodies(30, 0.6, seed=1)))
    w.detect()
    return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--cold-repeat", type=int, default=5, help="fresh builds per engine; the median first query")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000, 3000, 10000])
    ap.add_argument("--quick", action="store_true", help="only the two 500-body scenes")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    args = ap.parse_args(argv)
    print(f"kernels loaded (or compiled) in {compile_report():.2f} s (first world in this process)")

    def write(rows, name):
        os.makedirs(args.out, exist_ok=True)
        path = os.path.join(args.out, name)
        keys = list(dict.fromkeys(k for r in rows for k in r))
        with open(path, "w", newline="") as fh:
            wr = csv.DictWriter(fh, fieldnames=keys)
            wr.writeheader()
            wr.writerows(rows)
        print(f"wrote {path}")

    scenes(args, write)
    if not args.quick:
        scale(args, write)


if __name__ == "__main__":
    main()
