"""Scene and call-sequence generators for the property-based tests (hypothesis).

A generated scene has a static ground plane, optionally walls (a corner or a closed box of
planes), a static concave mesh step or an open flat terrain tile, and up to a few dozen bodies of
every shape type (sphere, box, convex hull, closed concave mesh), sizes over four decades (one
scale per scene, bodies within a factor of ten of it), masses spread up to a factor 1e3, random
poses that may overlap each other and the walls, velocities, spins, materials, and every response
and time-of-impact option; some bodies are kinematic and are driven (posed) into the others.

Everything random is drawn from hypothesis, so a failure shrinks to a small scene.
"""
import os

import numpy as np
import trimesh
from hypothesis import strategies as st

import contact_sim as cs

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
L_STEP_FILE = "config/meshes/l_step.obj"   # as a scene names it: generated scenes load with base_dir=REPO
L_STEP = os.path.join(REPO, L_STEP_FILE)
_L = trimesh.load(L_STEP, force="mesh", process=False)
L_VERTS, L_FACES = np.asarray(_L.vertices, float), np.asarray(_L.faces, np.int64)

RESPONSES = ("auto", "impulse", "kinematic", "penalty")
TOIS = ("auto", "next_step", "fractional", "swept")
SHAPES = ("sphere", "box", "convex", "mesh")


def unit_quaternion(draw):
    q = np.array(draw(st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 4)))
    n = np.linalg.norm(q)
    return (q / n).tolist() if n > 0.1 else [0.0, 0.0, 0.0, 1.0]


@st.composite
def shapes(draw, scale, kinds=SHAPES):
    """A finite shape (its scene mapping) about ``scale`` m across (within a factor of ten)."""
    kind = draw(st.sampled_from(kinds))
    size = scale * draw(st.floats(0.3, 3.0))
    if kind == "sphere":
        return {"type": "sphere", "radius": size / 2}
    if kind == "box":
        return {"type": "box", "size": (size * np.array(draw(st.tuples(*[st.floats(0.1, 1.0)] * 3)))).tolist()}
    if kind == "convex":
        if draw(st.integers(0, 3)) == 0:   # the hull of a mesh file, as a URDF's convex collision mesh is
            return {"type": "convex", "file": L_STEP_FILE, "scale": size / 2}
        seed = draw(st.integers(0, 2 ** 16))
        pts = np.random.default_rng(seed).normal(size=(draw(st.integers(6, 24)), 3))
        return {"type": "convex", "points": (pts * size / 4).tolist()}
    # a closed concave mesh: the L-shaped step from its OBJ file, or its vertices scaled unevenly
    if draw(st.booleans()):
        return {"type": "mesh", "file": L_STEP_FILE, "scale": size / 2}
    stretch = size * np.array(draw(st.tuples(*[st.floats(0.3, 1.0)] * 3))) / 2
    return {"type": "mesh", "vertices": (L_VERTS * stretch).tolist(), "faces": L_FACES.tolist()}


def robot_urdf(scale):
    """A small arm (URDF text) about ``3·scale`` m long, as a user's robot reaches the engine: a box
    base, a cylinder upper arm on a revolute shoulder about z, the L-step mesh (an OBJ file through
    ``package://``) on a prismatic slide along the arm, and a sphere finger that mimics the slide.
    Its movable joints and their limits are ``ROBOT_JOINTS`` (× ``scale`` for the slide)."""
    h, r, l = 0.5 * scale, 0.15 * scale, 2.0 * scale
    return f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><collision><origin xyz="0 0 {h / 2}"/><geometry><box size="{h} {h} {h}"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="{l / 2} 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="{r}" length="{l}"/></geometry></collision></link>
  <link name="hand"><collision><geometry>
    <mesh filename="package://cs_fuzz/{L_STEP_FILE}" scale="{0.25 * scale} {0.25 * scale} {0.25 * scale}"/>
  </geometry></collision></link>
  <link name="finger"><collision><geometry><sphere radius="{0.1 * scale}"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 {h + r}"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="hand"/><origin xyz="{l} 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="{0.5 * scale}" effort="1" velocity="1"/></joint>
  <joint name="finger_joint" type="prismatic"><parent link="hand"/><child link="finger"/><origin xyz="0 0 {-h}"/>
    <axis xyz="0 0 -1"/><limit lower="0" upper="{scale}" effort="1" velocity="1"/>
    <mimic joint="slide" multiplier="1" offset="0"/></joint>
</robot>
"""


ROBOT_JOINTS = {"shoulder": (-3.0, 3.0), "slide": (0.0, 0.5)}   # (lower, upper); the slide's × scale


def flat_tile(half, n=3):
    """An open flat triangle mesh (terrain tile) of ``n × n`` quads, ``2·half`` m across, faces up
    (its scene mapping; ``flat_tile_mesh`` gives the shape)."""
    g = np.linspace(-half, half, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    f = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            f += [[a, b, c], [a, c, d]]
    return {"type": "mesh", "vertices": v.tolist(), "faces": f}


def flat_tile_mesh(half, n=3):
    """``flat_tile`` as a ``cs.TriMesh``."""
    tile = flat_tile(half, n)
    return cs.TriMesh(np.array(tile["vertices"]), np.array(tile["faces"]))


def random_contacts(rng, nb, k):
    """``nb`` bodies' centres, velocities and spins ``(nb, 3)`` and ``k`` contacts between random
    pairs of them, with random unit normals, at the pairs' midpoints, drawn from the numpy
    generator ``rng`` in that order: the solver tests' coupled systems. Returns ``(pos, vel, omega,
    a, b, normal, point)``."""
    pos = rng.normal(size=(nb, 3))
    vel, omega = rng.normal(size=(nb, 3)), rng.normal(size=(nb, 3))
    a = rng.integers(0, nb, k)
    b = (a + rng.integers(1, nb, k)) % nb
    normal = rng.normal(size=(k, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return pos, vel, omega, a, b, normal, 0.5 * (pos[a] + pos[b])


@st.composite
def scenes(draw, max_bodies=6, responses=RESPONSES, tois=TOIS, kinematic=True, elastic=None, gravity=True,
           separated=False, kinds=SHAPES):
    """``(world, info)``: a generated world and what the invariants need to know about it
    (``info["kinematic"]`` names of kinematic bodies, ``info["scale"]`` the scene's size,
    ``info["scene"]`` the scene mapping it was loaded from: a failure prints it, and it becomes
    a regression test as it is). ``separated``: bodies start apart (on a lattice, walls and meshes
    left out), for properties that only hold from a valid state."""
    scale = 10 ** draw(st.floats(-2.0, 1.0))          # body sizes over four decades: 3 mm to 30 m
    dt = draw(st.sampled_from([1 / 60, 1 / 120, 1 / 240]))
    response = draw(st.sampled_from(responses))
    settings = {"dt": dt, "response": response, "toi": draw(st.sampled_from(tois))}
    if response == "penalty":
        settings["penalty"] = {"stiffness": draw(st.floats(1e2, 1e6)), "damping": draw(st.floats(0.0, 1e3))}
    friction = draw(st.floats(0.0, 1.2))
    restitution = draw(st.floats(0.0, 1.0)) if elastic is None else elastic
    scene = {"gravity": [0.0, 0.0, -9.81 if gravity else 0.0], "settings": settings,
             "materials": {"m": {"restitution": restitution, "friction": 0.0 if elastic is not None else friction}},
             "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"}]}
    bodies = scene["bodies"]
    extent = (8.0 if separated else 4.0) * scale
    walls = draw(st.sampled_from(["none", "corner", "box"])) if not separated else "box"
    planes = {"corner": [("wall_x0", [1, 0, 0]), ("wall_y0", [0, 1, 0])],
              "box": [("wall_x0", [1, 0, 0]), ("wall_y0", [0, 1, 0]), ("wall_x1", [-1, 0, 0]), ("wall_y1", [0, -1, 0])]}
    for name, normal in planes.get(walls, []):
        bodies.append({"name": name, "kind": "static", "shape": {"type": "plane", "normal": normal, "offset": -extent},
                       "material": "m"})
    extra = draw(st.sampled_from(["none", "step", "terrain"])) if not separated else "none"
    if extra == "step":
        bodies.append({"name": "step", "kind": "static", "material": "m",
                       "shape": {"type": "mesh", "vertices": (L_VERTS * scale * 2).tolist(), "faces": L_FACES.tolist()}})
    elif extra == "terrain":
        bodies.append({"name": "terrain", "kind": "static", "shape": flat_tile(extent), "position": [0, 0, 0.5 * scale],
                       "material": "m"})
    n = draw(st.integers(1, max_bodies))
    m0 = draw(st.floats(0.1, 10.0))
    kin, joints = [], {}
    if kinematic and not separated and draw(st.integers(0, 3)) == 0:   # a robot among the bodies, its links kinematic
        yaw = draw(st.floats(-np.pi, np.pi))
        scene["robots"] = [{"urdf": robot_urdf(scale), "prefix": "r_", "package_paths": {"cs_fuzz": "."},
                            "base_pose": {"position": [draw(st.floats(-extent, extent)), draw(st.floats(-extent, extent)),
                                                       0.0],
                                          "orientation": [0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2))]}}]
        joints = {"r_" + j: [lo * (scale if j == "slide" else 1.0), hi * (scale if j == "slide" else 1.0)]
                  for j, (lo, hi) in ROBOT_JOINTS.items()}
    for i in range(n):
        shape = draw(shapes(scale, kinds))
        is_kin = kinematic and i > 0 and draw(st.booleans()) and draw(st.booleans())   # about a quarter
        if separated:   # cells 7 scales apart (a body is at most 3√3 across), 4.5 from the walls
            pos = [(-3.5 + 7 * (i % 2)) * scale, (-3.5 + 7 * ((i // 2) % 2)) * scale, (3.0 + 7.0 * (i // 4)) * scale]
        else:
            pos = [draw(st.floats(-extent, extent)), draw(st.floats(-extent, extent)), draw(st.floats(0.0, 3 * extent))]
        b = {"shape": shape, "position": pos, "orientation": unit_quaternion(draw), "material": "m"}
        speed = scale * draw(st.floats(0.0, 20.0))      # up to twenty body sizes per second
        direction = np.array(unit_quaternion(draw)[:3]) + 1e-9
        b["velocity"] = (speed * direction / np.linalg.norm(direction)).tolist()
        if is_kin:
            b.update(name=f"k{i}", kind="kinematic")
            kin.append(f"k{i}")
        else:
            spin = draw(st.floats(0.0, 20.0))
            b.update(name=f"b{i}", kind="dynamic", mass=m0 * 10 ** draw(st.floats(0.0, 3.0)),
                     angular_velocity=(spin * np.array(unit_quaternion(draw)[:3])).tolist())
        bodies.append(b)
    return cs.load_scene(scene, base_dir=REPO), {"kinematic": kin, "joints": joints, "scale": scale, "response": response,
                                                 "scene": scene}


@st.composite
def calls(draw, names, kinematic, n=12, joints=None):
    """A sequence of API calls on a generated world: mostly steps, with poses of kinematic
    bodies driven towards the others, a robot's joints moved within their limits (``joints``: name →
    [lower, upper]), velocity changes, resets, detection and stateless queries."""
    out = []
    for _ in range(n):
        kind = draw(st.sampled_from(["step"] * 6 + ["pose"] * (2 if kinematic else 0) + ["joints"] * (2 if joints else 0)
                                    + ["state", "reset", "detect", "collide"]))
        if kind == "step":
            out.append(("step", draw(st.integers(1, 6))))
        elif kind == "pose":   # a move of up to a body size, a turn of up to 0.3 rad, in one step
            axis = np.array(unit_quaternion(draw)[:3]) + 1e-9
            turn = draw(st.floats(0.0, 0.3)) * axis / np.linalg.norm(axis)
            out.append(("pose", draw(st.sampled_from(kinematic)), draw(st.floats(-1.0, 1.0)),
                        draw(st.floats(-1.0, 0.0)), turn.tolist()))
        elif kind == "state":
            out.append(("state", draw(st.sampled_from(names)), draw(st.floats(-3.0, 3.0))))
        elif kind == "joints":   # some of the robot's joints, anywhere within their limits
            moved = draw(st.lists(st.sampled_from(sorted(joints)), min_size=1, max_size=len(joints), unique=True))
            out.append(("joints", {j: draw(st.floats(*joints[j])) for j in moved}))
        elif kind == "collide":
            out.append(("collide", draw(st.sampled_from(names)), draw(st.sampled_from(names))))
        else:
            out.append((kind,))
    return out
