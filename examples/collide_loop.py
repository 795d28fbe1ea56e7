"""The stateless query in a loop: ``cs.collide`` asks one pair of shapes, at given poses, for their
contacts (no world, no state). Here a sphere is lowered onto a box's top face, then a box is turned
on the box; each line prints the contact count, the deepest depth (> 0 penetrating, < 0 apart within
the margin) and its normal (from B to A).

    python examples/collide_loop.py
"""
import math

import numpy as np

import contact_sim as cs

box = cs.Box([1.0, 1.0, 0.2])              # full edge lengths; its top face at z = 0.1 in its frame
ball = cs.Sphere(0.25)
at_rest = ([0.0, 0.0, 0.0], [0, 0, 0, 1])  # a pose: position (3,), orientation (4,) as x, y, z, w

print("sphere over the box (margin 0.01 m)")
for z in (0.40, 0.355, 0.35, 0.325, 0.30):
    c = cs.collide(ball, ([0.1, 0.0, z], [0, 0, 0, 1]), box, at_rest, margin=0.01)
    if len(c.depth) == 0:
        print(f"  z = {z:.3f}: apart")
        continue
    k = int(np.argmax(c.depth))
    print(f"  z = {z:.3f}: {len(c.depth)} contact, depth {c.depth[k]:+.4f} m, normal {c.normal[k].round(6).tolist()}")

print("a 0.2 m cube turned about z, resting 1 mm into the box")
for deg in (0, 15, 30, 45):
    t = math.radians(deg)
    q = [0.0, 0.0, math.sin(t / 2), math.cos(t / 2)]
    c = cs.collide(cs.Box([0.2, 0.2, 0.2]), ([0.0, 0.0, 0.199], q), box, at_rest)
    print(f"  {deg:2d} deg: {len(c.depth)} contacts, depths {np.round(c.depth, 6).tolist()}, "
          f"features {sorted({cs.FEATURES[f] for f in c.feature})}")
