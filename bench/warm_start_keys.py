"""How two warm-start keys agree: for each contact of a step, is there a contact of the same pair in
the previous step (a) within ``MATCH_FRACTION`` x the smaller body's size of it in A's frame (the
engine's key, ``response.cache``), (b) with the same ``feature_id`` (Box2D's key)? Counts per
scene: contacts, matched by distance, by feature, by both, by distance only, by feature only.
Prints the table and writes ``bench/results/warm_start_keys.csv``.

Usage: ``python bench/warm_start_keys.py``
"""
import csv
import os
import sys
import warnings

import numpy as np
import contact_sim as cs
from contact_sim import quat
from contact_sim.constants import MATCH_FRACTION
from contact_sim.response.bounds import _extents

sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))


def local(w, c):
    R = quat.to_matrix(w.s.quat[c.body_a])
    return np.einsum("kji,kj->ki", R, c.point - w.s.pos[c.body_a])


def scenes():
    yield "default", cs.load_scene(cs.scene.default_scene_path()), 600
    import bench_versions as bv
    yield "tumbling_pile", bv.tumbling_pile(cs, "next_step"), 600
    w = cs.World(settings=cs.Settings(toi="next_step"), materials={"m": cs.Material(friction=0.3)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("box", cs.Box((0.4, 0.3, 0.2)), mass=1.0, position=(0, 0, 0.1), velocity=(2, 0.3, 0), material="m")
    yield "sliding_box", w, 120
    import trimesh
    m = trimesh.creation.box(extents=[6, 6, 0.2]).subdivide().subdivide()
    w = cs.World(settings=cs.Settings(toi="next_step"), materials={"m": cs.Material(friction=0.2)})
    w.add_body("floor", cs.TriMesh(m.vertices, m.faces), kind="static", position=(0, 0, -0.1), material="m")
    w.add_body("box", cs.Box((0.4, 0.3, 0.2)), mass=1.0, position=(-2, 0, 0.1), velocity=(3, 0.5, 0), material="m")
    yield "box_sliding_on_mesh", w, 200


warnings.simplefilter("ignore")
rows = []
print(f"{'scene':<22}{'contacts':>9}{'dist':>7}{'feat':>7}{'both':>7}{'dist only':>10}{'feat only':>10}")
for name, w, n in scenes():
    ext = _extents(w)
    prev = None
    tot = dict(k=0, d=0, f=0, both=0, donly=0, fonly=0)
    for _ in range(n):
        w.step()
        c = w.contacts
        if len(c) == 0:
            prev = None
            continue
        loc = local(w, c)
        if prev is not None:
            pc, ploc = prev
            for i in range(len(c)):
                same = (pc.body_a == c.body_a[i]) & (pc.body_b == c.body_b[i])
                tol = MATCH_FRACTION * min(ext[c.body_a[i]], ext[c.body_b[i]])
                d = bool(np.any(same & (np.linalg.norm(ploc - loc[i], axis=1) <= tol)))
                f = bool(np.any(same & (pc.feature_id == c.feature_id[i])))
                tot["k"] += 1; tot["d"] += d; tot["f"] += f; tot["both"] += d and f
                tot["donly"] += d and not f; tot["fonly"] += f and not d
        prev = (c, loc)
    rows.append(dict(scene=name, contacts=tot["k"], by_distance=tot["d"], by_feature=tot["f"], both=tot["both"],
                     distance_only=tot["donly"], feature_only=tot["fonly"]))
    print(f"{name:<22}{tot['k']:>9}{tot['d']:>7}{tot['f']:>7}{tot['both']:>7}{tot['donly']:>10}{tot['fonly']:>10}")
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "warm_start_keys.csv")
with open(out, "w", newline="") as fh:
    wr = csv.DictWriter(fh, list(rows[0]))
    wr.writeheader()
    wr.writerows(rows)
print(f"wrote {out}")
