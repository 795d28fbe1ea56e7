"""The library quick start: load the shipped default scene, step it for two seconds, read the bodies
and the last step's contacts.

    python examples/quickstart.py
"""
import contact_sim as cs

world = cs.load_scene(cs.default_scene_path())   # a path, a shipped scene's name via cs.resolve_scene, or a dict
print(world.describe())                           # bodies, shapes, and which models the engine chose and why

for _ in range(int(round(2.0 / world.settings.dt))):
    world.step()                                  # one step of settings.dt

ball = world.body("ball")                         # a snapshot: position (3,), orientation (4,) x y z w, velocity, ...
print(f"t = {world.time:.3f} s  ball at {ball.position.round(4).tolist()} m, speed {float((ball.velocity ** 2).sum() ** 0.5):.4f} m/s")

c = world.contacts                                # the last step's contacts, a structure of arrays (one row a point)
print(f"{len(c.depth)} contact points")
for k in range(len(c.depth)):
    a, b = world.body_names[c.body_a[k]], world.body_names[c.body_b[k]]
    print(f"  {a:>10} on {b:<10} point {c.point[k].round(4).tolist()} normal {c.normal[k].round(3).tolist()} "
          f"depth {c.depth[k]:+.2e} m  normal impulse {c.normal_impulse[k]:.4f} N·s  ({cs.FEATURES[c.feature[k]]})")
