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
L_STEP = os.path.join(REPO, "config", "meshes", "l_step.obj")
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
        seed = draw(st.integers(0, 2 ** 16))
        pts = np.random.default_rng(seed).normal(size=(draw(st.integers(6, 24)), 3))
        return {"type": "convex", "points": (pts * size / 4).tolist()}
    # a closed concave mesh: the L-shaped step, scaled unevenly
    stretch = size * np.array(draw(st.tuples(*[st.floats(0.3, 1.0)] * 3))) / 2
    return {"type": "mesh", "vertices": (L_VERTS * stretch).tolist(), "faces": L_FACES.tolist()}


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
    kin = []
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
    return cs.load_scene(scene), {"kinematic": kin, "scale": scale, "response": response, "scene": scene}


@st.composite
def calls(draw, names, kinematic, n=12):
    """A sequence of API calls on a generated world: mostly steps, with poses of kinematic
    bodies driven towards the others, velocity changes, resets, detection and stateless queries."""
    out = []
    for _ in range(n):
        kind = draw(st.sampled_from(["step"] * 6 + ["pose"] * (2 if kinematic else 0)
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
        elif kind == "collide":
            out.append(("collide", draw(st.sampled_from(names)), draw(st.sampled_from(names))))
        else:
            out.append((kind,))
    return out
