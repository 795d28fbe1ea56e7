"""Robot benchmark (issue 16): a 10-link arm of mesh links sweeping through 100 objects at 100 Hz.

Usage: ``python bench/bench_robot.py [--ticks 300] [--faces 2000] [--objects 100]``

The arm: a URDF written here, 10 links in a chain of revolute joints (alternating z and y axes),
each link a capsule mesh of about ``--faces`` triangles (trimesh, STL; convex, so a ``Convex`` of
its hull). The scene: ``--objects`` static boxes, spheres and cylinders at seeded random places
within the arm's reach. Each tick at 100 Hz sets the joints (sinusoids) and:

* **contact_sim tick**: ``set_joint_positions`` + ``world.step(0.01)`` (what the node does per tick,
  without messages);
* **contact_sim query**: ``set_joint_positions`` + ``world.detect()`` (contacts only);
* **FCL query**: the same poses in python-fcl, MoveIt's checker: link meshes as ``BVHModel``
  (OBB-RSS), objects as primitives, one ``DynamicAABBTreeCollisionManager`` per side, robot against
  world with contact data (every contact of every colliding pair).

Prints p50/p99 (ms) and colliding link–object pairs per tick (the two engines must agree up to the
cylinders' prism and FCL's own tolerances); writes ``bench/results/robot.csv``.
"""
import argparse
import csv
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from contact_sim.robot import matrix_to_quat  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
LINK_L, LINK_R = 0.25, 0.04


def arm_urdf(mesh, n_links):
    links = "".join(f'<link name="l{i}"><collision><origin xyz="0 0 {LINK_L / 2}"/><geometry>'
                    f'<mesh filename="{mesh}"/></geometry></collision></link>' for i in range(n_links))
    joints = "".join(
        f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
        f'<origin xyz="0 0 {LINK_L}"/><axis xyz="{"0 0 1" if i % 2 else "0 1 0"}"/>'
        f'<limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>' for i in range(1, n_links))
    return f'<robot name="bench_arm">{links}{joints}</robot>'


def capsule_mesh(path, faces):
    import trimesh

    n = max(4, int(np.sqrt(faces / 2)))
    m = trimesh.creation.capsule(height=LINK_L - 2 * LINK_R - 0.01, radius=LINK_R, count=[n, n])
    m.export(path)
    return m


def objects(n, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        p = rng.uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.5])
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        kind = k % 3
        if kind == 0:
            s = rng.uniform(0.05, 0.2, 3)
            out.append(("box", s, p, q))
        elif kind == 1:
            out.append(("sphere", rng.uniform(0.03, 0.12), p, q))
        else:
            out.append(("cylinder", (rng.uniform(0.03, 0.1), rng.uniform(0.1, 0.3)), p, q))
    return out


def joint_angles(t, n):
    k = np.arange(1, n)
    return 1.2 * np.sin(2 * np.pi * (0.2 + 0.05 * k) * t + k)


def percentile_ms(x, p):
    return 1e3 * float(np.percentile(x, p))


def run_contact_sim(urdf, objs, ticks, step):
    w = cs.World(gravity=[0, 0, 0], settings={"dt": 0.01})
    for k, (kind, size, p, q) in enumerate(objs):
        shape = (cs.Box(size) if kind == "box" else cs.Sphere(size) if kind == "sphere" else cs.Cylinder(*size))
        w.add_body(f"obj{k}", shape, kind="static", position=p, orientation=q)
    names = w.add_urdf(urdf)
    joints = [n for n in w.joint_positions()]
    times, contacts = [], []
    for t in range(ticks + 20):
        t0 = time.perf_counter()
        w.set_joint_positions(joints, joint_angles(t * 0.01, len(joints) + 1), stamp=t * 0.01)
        if step:
            w.step(0.01)
            c = w.contacts
        else:
            c = w.detect()
        if t >= 20:   # after the first ticks (compilation, caches)
            times.append(time.perf_counter() - t0)
            link = np.array([n.startswith("l") for n in w.body_names])   # link–object pairs only (as FCL's query)
            pair = (link[c.body_a] != link[c.body_b]) & (c.depth >= 0)   # touching, not just within the margin
            contacts.append(len(set(zip(c.body_a[pair].tolist(), c.body_b[pair].tolist()))))
    return np.array(times), np.array(contacts), w, names


def run_fcl(mesh, objs, world, names, ticks):
    import fcl

    def bvh(m):
        model = fcl.BVHModel()
        model.beginModel(len(m.vertices), len(m.faces))
        model.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int32))
        model.endModel()
        return model

    def tf(p, q):
        x, y, z, w = q
        return fcl.Transform(np.array([w, x, y, z]), np.asarray(p, float))   # fcl's quaternion is w, x, y, z

    statics = []
    for kind, size, p, q in objs:
        g = fcl.Box(*size) if kind == "box" else fcl.Sphere(size) if kind == "sphere" else fcl.Cylinder(*size)
        statics.append(fcl.CollisionObject(g, tf(p, q)))
    wm = fcl.DynamicAABBTreeCollisionManager()
    wm.registerObjects(statics)
    wm.setup()
    links = [fcl.CollisionObject(bvh(mesh), fcl.Transform()) for _ in names]   # a model each: pairs by identity
    rm = fcl.DynamicAABBTreeCollisionManager()
    rm.registerObjects(links)
    rm.setup()
    robot = world.robots[-1]
    joints = list(robot.q)
    times, contacts = [], []
    for t in range(ticks + 20):
        t0 = time.perf_counter()
        q = dict(zip(joints, joint_angles(t * 0.01, len(joints) + 1)))
        T = robot.link_transforms(q)
        W = np.array([T[lk] for lk in robot.body_link]) @ robot.body_origin   # the same FK as contact_sim
        quats = matrix_to_quat(W[:, :3, :3])
        for obj, Wk, qk in zip(links, W, quats):
            obj.setTransform(tf(Wk[:3, 3], qk))
        rm.update()
        # contact data for every colliding pair (the default callback stops the whole query once
        # num_max_contacts contacts are found, so the cap is set well above what a tick produces)
        data = fcl.CollisionData(request=fcl.CollisionRequest(num_max_contacts=100000, enable_contact=True))
        rm.collide(wm, data, fcl.defaultCollisionCallback)
        if t >= 20:
            times.append(time.perf_counter() - t0)
            contacts.append(len({(id(c.o1), id(c.o2)) for c in data.result.contacts}))
    return np.array(times), np.array(contacts)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=300)
    ap.add_argument("--faces", type=int, default=2000)
    ap.add_argument("--objects", type=int, default=100)
    ap.add_argument("--links", type=int, default=10)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "link.stl")
        mesh = capsule_mesh(path, args.faces)
        urdf = arm_urdf(path, args.links)
        objs = objects(args.objects)
        rows = []
        for label, step in (("contact_sim tick (set joints + step)", True), ("contact_sim query (set joints + detect)",
                                                                              False)):
            t, c, w, names = run_contact_sim(urdf, objs, args.ticks, step)
            rows.append((label, percentile_ms(t, 50), percentile_ms(t, 99), float(c.mean())))
        try:
            t, c = run_fcl(mesh, objs, w, names, args.ticks)
            rows.append(("python-fcl query (BVH meshes, contact data)", percentile_ms(t, 50), percentile_ms(t, 99),
                         float(c.mean())))
        except ImportError:
            print("python-fcl not installed: no FCL row (make bench installs it)")
    print(f"{args.links} links of {len(mesh.faces)} triangles, {args.objects} objects, {args.ticks} ticks at 100 Hz")
    print(f"{'':46s} {'p50 ms':>8s} {'p99 ms':>8s} {'pairs/tick':>14s}")
    for label, p50, p99, c in rows:
        print(f"{label:46s} {p50:8.2f} {p99:8.2f} {c:14.1f}")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "robot.csv"), "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["measurement", "links", "triangles_per_link", "objects", "p50_ms", "p99_ms",
                     "colliding_pairs_per_tick"])
        for label, p50, p99, c in rows:
            wr.writerow([label, args.links, len(mesh.faces), args.objects, f"{p50:.3f}", f"{p99:.3f}", f"{c:.1f}"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
