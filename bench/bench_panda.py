"""A robot cell at 1 kHz (issue 33): the Franka Panda of pybullet_data on a floor beside a table
with 20 objects on it, its seven joints driven by sinusoids, one step of 1 ms per tick.

Usage: ``python bench/bench_panda.py [--ticks 2000] [--rounds 5] [--objects 20]``

The URDF is pybullet_data's (``pip install pybullet``: ``make bench`` installs it), loaded with no
package path (its ``package://meshes/...`` URIs are found beside it). Measured per tick, in one
process, the engines taking turns round by round:

* **contact_sim tick**: ``set_joint_positions`` (each joint's own stamp) + ``world.step(0.001)``:
  what the node does per tick, without the messages;
* **contact_sim query**: ``set_joint_positions`` + ``world.detect()`` (contacts only);
* **FCL query**: the same link poses in python-fcl, as MoveIt checks a robot: link collision
  meshes as ``BVHModel`` (OBB-RSS), the table and objects as primitives at their current poses, one
  ``DynamicAABBTreeCollisionManager`` per side, robot against world with contact data.

Prints p50/p99 (ms) per measurement and the median of the per-round ratios to FCL; how many rows
the tick's contacts had from the base and the zero pose's touching links (0: they are excluded);
writes ``bench/results/panda.csv``.
"""
import argparse
import csv
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from contact_sim.robot import matrix_to_quat  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DT = 0.001
JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
HOME = np.array([0.0, -0.6, 0.0, -2.2, 0.0, 1.6, 0.8])


def panda_urdf():
    import pybullet_data

    return os.path.join(pybullet_data.getDataPath(), "franka_panda", "panda.urdf")


def cell(n_objects):
    """The world: floor, a table 0.4 m high in front of the robot, objects on it, the Panda."""
    w = cs.World(settings=cs.Settings(dt=DT))
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("table", cs.Box([0.6, 1.0, 0.4]), kind="static", position=[0.75, 0.0, 0.2])
    for i in range(n_objects):
        box = i % 2 == 0
        shape = cs.Box([0.05, 0.05, 0.05]) if box else cs.Sphere(0.03)
        w.add_body(f"obj{i}", shape, mass=0.2, position=[0.55 + 0.1 * (i % 5), -0.35 + 0.2 * (i // 5),
                                                          0.4 + (0.025 if box else 0.03)])
    w.add_urdf(panda_urdf(), joint_positions=dict(zip(JOINTS, HOME)))
    for _ in range(200):   # the objects settle on the table before the robot moves
        w.step()
    return w


def angles(t):
    """Joint positions at time ``t`` (s): the home pose plus 0.4 rad sinusoids, one per joint."""
    k = np.arange(7)
    return HOME + 0.4 * np.sin(2 * np.pi * (0.2 + 0.05 * k) * t + k)


class ContactSim:
    def __init__(self, n_objects, step):
        self.w, self.step, self.t = cell(n_objects), step, 0.0
        self.robot = set(self.w.robots[0].bodies)

    def tick(self):
        self.t += DT
        self.w.set_joint_positions(JOINTS, angles(self.t), stamp=self.w.time + DT)
        if self.step:
            self.w.step()
            return self.w.contacts
        return self.w.detect()

    def quiet_rows(self, c):
        """Contact rows from the robot's base or between two of its links (none when excluded)."""
        names = self.w.body_names
        base = [names[a] == "panda_link0" or names[b] == "panda_link0" for a, b in zip(c.body_a, c.body_b)]
        self_pairs = [names[a] in self.robot and names[b] in self.robot for a, b in zip(c.body_a, c.body_b)]
        return int(np.sum(np.array(base, bool) | np.array(self_pairs, bool)))


class FCL:
    """MoveIt's check of the same poses: robot links against the table and objects."""

    def __init__(self, world):
        import fcl
        import trimesh

        self.fcl, self.world, self.t = fcl, world, 0.0
        self.robot = world.robots[0]
        self.links = []
        for b in self.robot.bodies:
            sh = world.user_shapes[world.index(b)]
            m = trimesh.Trimesh(sh.vertices, sh.faces) if sh.type == "mesh" else trimesh.convex.convex_hull(sh.vertices)
            model = fcl.BVHModel()
            model.beginModel(len(m.vertices), len(m.faces))
            model.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int32))
            model.endModel()
            self.links.append(fcl.CollisionObject(model, fcl.Transform()))
        statics = []
        for name in world.body_names:
            if name in self.robot.bodies or name == "floor":
                continue
            i = world.index(name)
            sh = world.user_shapes[i]
            g = fcl.Box(*sh.size) if sh.type == "box" else fcl.Sphere(sh.radius)
            b = world.body(name)
            statics.append(fcl.CollisionObject(g, self._tf(b.position, b.orientation)))
        self.wm = fcl.DynamicAABBTreeCollisionManager()
        self.wm.registerObjects(statics)
        self.wm.setup()
        self.rm = fcl.DynamicAABBTreeCollisionManager()
        self.rm.registerObjects(self.links)
        self.rm.setup()
        self.names = [n for n in self.robot.q]

    def _tf(self, p, q):
        x, y, z, w = q
        return self.fcl.Transform(np.array([w, x, y, z]), np.asarray(p, float))   # fcl: w, x, y, z

    def tick(self):
        self.t += DT
        q = dict(zip(JOINTS, angles(self.t)))
        q.update({n: self.robot.q[n] for n in self.names if n not in q})
        T = self.robot.link_transforms(q)
        W = np.array([T[lk] for lk in self.robot.body_link]) @ self.robot.body_origin   # the same FK
        quats = matrix_to_quat(W[:, :3, :3])
        for obj, Wk, qk in zip(self.links, W, quats):
            obj.setTransform(self._tf(Wk[:3, 3], qk))
        self.rm.update()
        data = self.fcl.CollisionData(request=self.fcl.CollisionRequest(num_max_contacts=100000,
                                                                         enable_contact=True))
        self.rm.collide(self.wm, data, self.fcl.defaultCollisionCallback)
        return data.result.contacts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=2000, help="ticks per engine per round")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--objects", type=int, default=20)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", cs.response.ContactModelWarning)
    engines = {"contact_sim tick (set joints + 1 ms step)": ContactSim(args.objects, True),
               "contact_sim query (set joints + detect)": ContactSim(args.objects, False)}
    try:
        engines["python-fcl query (BVH meshes, contact data)"] = FCL(engines[next(iter(engines))].w)
    except ImportError:
        print("python-fcl not installed: no FCL row (make bench installs it)")
    times = {k: [] for k in engines}
    medians = {k: [] for k in engines}
    quiet = 0
    for r in range(args.rounds):
        for name, e in engines.items():
            for _ in range(200):   # warm: caches, the first steps of a round
                e.tick()
            ts = np.empty(args.ticks)
            for k in range(args.ticks):
                t0 = time.perf_counter()
                c = e.tick()
                ts[k] = time.perf_counter() - t0
                if isinstance(e, ContactSim) and e.step:
                    quiet += e.quiet_rows(c)
            times[name].append(ts)
            medians[name].append(float(np.median(ts)))
    fcl_name = next((k for k in engines if k.startswith("python-fcl")), None)
    print(f"Panda (pybullet_data, {len(engines[next(iter(engines))].robot)} link meshes) on a floor, "
          f"{args.objects} objects on a table, {args.rounds} rounds x {args.ticks} ticks of 1 ms")
    print(f"{'':46s} {'p50 ms':>8s} {'p99 ms':>8s} {'max ms':>8s} {'x FCL':>7s}")
    rows = []
    for name in engines:
        t = np.concatenate(times[name]) * 1e3
        ratio = (float(np.median(np.array(medians[name]) / np.array(medians[fcl_name]))) if fcl_name else np.nan)
        rows.append((name, np.percentile(t, 50), np.percentile(t, 99), t.max(), ratio))
        print(f"{name:46s} {rows[-1][1]:8.3f} {rows[-1][2]:8.3f} {rows[-1][3]:8.3f} {ratio:7.2f}")
    print(f"contact rows from the base or between two links over every tick: {quiet}")
    os.makedirs(os.path.join(HERE, "results"), exist_ok=True)
    with open(os.path.join(HERE, "results", "panda.csv"), "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["measurement", "objects", "ticks", "p50_ms", "p99_ms", "max_ms", "ratio_to_fcl",
                     "base_or_self_rows"])
        for name, p50, p99, mx, ratio in rows:
            wr.writerow([name, args.objects, args.rounds * args.ticks, f"{p50:.4f}", f"{p99:.4f}", f"{mx:.4f}",
                         f"{ratio:.3f}", quiet])
    return 0


if __name__ == "__main__":
    sys.exit(main())
