"""Scene loading and validation: every error names the path and the reason; no half-built worlds."""
import copy
import os
import shutil

import numpy as np
import pytest

import contact_sim as cs

BASE = {
    "gravity": [0, 0, -9.81],
    "settings": {"dt": 0.01},
    "materials": {"rubber": {"restitution": 0.8, "friction": 0.1}},
    "bodies": [
        {"name": "ground", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0}},
        {"name": "ball", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0, "position": [0, 0, 1],
         "material": "rubber"},
        {"name": "crate", "shape": {"type": "box", "size": [1, 2, 3]}, "density": 10.0},
        {"name": "rock", "shape": {"type": "convex", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]},
         "mass": 2.0},
    ],
}


def scene(**edits):
    d = copy.deepcopy(BASE)
    for path, value in edits.items():
        node = d
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        last = keys[-1]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return d


def test_valid_scene_builds_world():
    w = cs.load_scene(BASE)
    assert w.body_names == ["ground", "ball", "crate", "rock"]
    assert w.settings.dt == 0.01
    ball = w.body("ball")
    assert ball.mass == 1.0 and np.array_equal(ball.position, [0, 0, 1])
    crate = w.body("crate")
    assert crate.mass == pytest.approx(60.0, rel=1e-15)
    assert np.allclose(np.diag(crate.inertia), 60.0 / 12 * np.array([4 + 9, 1 + 9, 1 + 4]), rtol=1e-14)
    assert w.body("rock").mass == 2.0
    # unit right tetrahedron about its centroid: m·[[3/40, 1/80, 1/80], ...] (second moments of the simplex)
    expected = 2.0 * (np.full((3, 3), 1 / 80) + np.eye(3) * (3 / 40 - 1 / 80))
    assert np.allclose(w.body("rock").inertia, expected, rtol=0, atol=1e-14)
    assert np.allclose(w.body("rock").center_of_mass, [0.25, 0.25, 0.25], atol=1e-15)


@pytest.mark.parametrize("edits, message", [
    ({"bodies__3__mass": -1}, r"bodies\[3\]\.mass: must be > 0, got -1"),
    ({"bodies__1__mass": 0}, r"bodies\[1\]\.mass: must be > 0, got 0"),
    ({"bodies__2__density": float("nan")}, r"bodies\[2\]\.density: must be a finite number > 0, got nan"),
    ({"bodies__2__name": "ball"}, r"bodies\[2\]\.name: duplicate body name 'ball'"),
    ({"bodies__1__colour": "red"}, r"bodies\[1\]\.colour: unknown key"),
    ({"gravty": [0, 0, 1]}, r"^gravty: unknown key"),
    ({"settings__dt": 0}, r"settings\.dt: must be > 0"),
    ({"settings__dt": -0.01}, r"settings\.dt: must be > 0"),
    ({"settings__toi": "sometimes"}, r"settings\.toi: must be one of"),
    ({"settings__response": "magic"}, r"settings\.response: must be one of"),
    ({"settings__penalty": {"stiffness": 0}}, r"settings\.penalty\.stiffness: must be > 0"),
    ({"settings__solver_iterations": 2.5}, r"settings\.solver_iterations: must be a whole number"),
    ({"materials__rubber__restitution": 1.5}, r"materials\.rubber\.restitution: must be <= 1"),
    ({"materials__rubber__restitution": -0.1}, r"materials\.rubber\.restitution: must be >= 0"),
    ({"materials__rubber__friction": -0.5}, r"materials\.rubber\.friction: must be >= 0"),
    ({"bodies__1__material": "steel"}, r"bodies\[1\]\.material: unknown material 'steel'"),
    ({"bodies__1__kind": "floating"}, r"bodies\[1\]\.kind: must be one of static, kinematic, dynamic"),
    ({"bodies__1__model": "soft"}, r"bodies\[1\]\.model: must be one of rigid, particle"),
    ({"bodies__1__shape": {"type": "sphere", "radius": 0}}, r"bodies\[1\]\.shape\.radius: must be > 0"),
    ({"bodies__1__shape": {"type": "cone"}}, r"bodies\[1\]\.shape\.type: must be one of"),
    ({"bodies__2__shape": {"type": "box", "size": [1, -2, 3]}}, r"bodies\[2\]\.shape\.size: every edge length must be > 0"),
    ({"bodies__2__shape": {"type": "box", "size": [1, 2]}}, r"bodies\[2\]\.shape\.size: must be 3 numbers"),
    ({"bodies__3__shape": {"type": "convex", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}},
     r"bodies\[3\]\.shape\.points: all 4 points are coplanar"),
    ({"bodies__3__shape": {"type": "convex", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}},
     r"bodies\[3\]\.shape\.points: needs at least 4 points"),
    ({"bodies__3__shape": {"type": "convex", "points": [[0, 0, 0], [1, 0, float("nan")], [0, 1, 0], [0, 0, 1]]}},
     r"bodies\[3\]\.shape\.points\[1\]: must be finite"),
    ({"bodies__2__shape": {"type": "mesh", "file": "x.stl"}}, r"bodies\[2\]\.shape\.file: no such file 'x\.stl'"),
    ({"bodies__2__shape": {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": []}},
     r"bodies\[2\]\.shape\.faces: must be a non-empty"),
    ({"bodies__2__shape": {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 5]]}},
     r"bodies\[2\]\.shape\.faces: indices must be in \[0, 2\]"),
    ({"bodies__2__shape": {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}},
     r"bodies\[2\]\.shape: mesh is not closed"),
    ({"bodies__1__position": [0, 0]}, r"bodies\[1\]\.position: must be 3 numbers"),
    ({"bodies__1__position": [0, 0, float("inf")]}, r"bodies\[1\]\.position: must be finite"),
    ({"bodies__1__orientation": [0, 0, 0, 0]}, r"bodies\[1\]\.orientation: zero quaternion"),
    ({"bodies__1__orientation": [0, 0, 0, 2]}, r"bodies\[1\]\.orientation: quaternion must be unit length"),
    ({"bodies__1__orientation": [0, float("nan"), 0, 1]}, r"bodies\[1\]\.orientation: must be finite"),
    ({"bodies__0__kind": "dynamic"}, r"bodies\[0\]\.shape: a plane is a half-space with no mass"),
    ({"bodies__0__velocity": [1, 0, 0]}, r"bodies\[0\]: a static body never moves"),
    ({"bodies__1__density": 5.0}, r"bodies\[1\]: give mass or density, not both"),
    ({"bodies__1__collision": {"group": -1}}, r"bodies\[1\]\.group: must be an integer bit mask"),
])
def test_validation_errors_name_path_and_reason(edits, message):
    with pytest.raises(cs.SceneError, match=message):
        cs.load_scene(scene(**edits))


def test_missing_required_keys():
    d = scene()
    del d["bodies"][1]["shape"]
    with pytest.raises(cs.SceneError, match=r"bodies\[1\]\.shape: required"):
        cs.load_scene(d)
    d = scene()
    del d["bodies"][2]["name"]
    with pytest.raises(cs.SceneError, match=r"bodies\[2\]\.name: required"):
        cs.load_scene(d)


def test_bad_scene_file(tmp_path):
    with pytest.raises(cs.SceneError, match="no such scene file"):
        cs.load_scene(str(tmp_path / "nope.yaml"))
    bad = tmp_path / "bad.yaml"
    bad.write_text("bodies: [\n  - {name: a")
    with pytest.raises(cs.SceneError, match="not valid YAML"):
        cs.load_scene(str(bad))


def test_mesh_paths_resolve_relative_to_scene_file(tmp_path, repo):
    mesh_src = os.path.join(repo, "config", "meshes", "l_step.obj")
    (tmp_path / "meshes").mkdir()
    shutil.copy(mesh_src, tmp_path / "meshes" / "step.obj")
    (tmp_path / "s.yaml").write_text(
        "bodies:\n  - {name: step, kind: static, shape: {type: mesh, file: meshes/step.obj}}\n"
        "  - {name: lump, shape: {type: convex, file: meshes/step.obj, scale: 2.0}, density: 100}\n")
    w = cs.load_scene(str(tmp_path / "s.yaml"))
    assert w.body("step").shape.type == "mesh"
    # the hull of the L prism: polygon area 2.25 m² (shoelace) × depth 1 m, scaled by 2 → 8 × 2.25 m³
    assert w.body("lump").mass == pytest.approx(100.0 * 8 * 2.25, rel=1e-12)


def test_failed_add_body_leaves_world_unchanged():
    w = cs.load_scene(BASE)
    before = (w.body_names, w.s.pos.copy(), w.mass.copy())
    with pytest.raises(cs.ContactSimError, match="mass: must be > 0"):
        w.add_body("new", cs.Sphere(1.0), mass=-3)
    with pytest.raises(cs.ContactSimError, match="duplicate body name"):
        w.add_body("ball", cs.Sphere(1.0), mass=1)
    assert w.body_names == before[0]
    assert np.array_equal(w.s.pos, before[1]) and np.array_equal(w.mass, before[2])
    assert len(w.s.quat) == len(w.kind) == len(w.inv_inertia_body) == 4


def test_same_material_combines_to_itself():
    from contact_sim.settings import COMBINE_RULES, combine

    e = np.array([0.8, 0.3, 0.1, 0.0, 1.0, 0.7071])
    for rule in COMBINE_RULES:  # multiply too: Bullet's rule would square them
        assert np.array_equal(combine(e, e, rule), e), rule
    assert combine(np.array([0.5]), np.array([0.8]), "multiply")[0] == 0.4


def test_shipped_scenes_all_load(scenes_dir):
    names = cs.list_scenes()
    assert "default" in names
    for name in names:
        w = cs.load_scene(cs.resolve_scene(name))
        assert len(w) > 0
        w.step()


def test_default_scene_has_several_shapes_on_a_ground_plane():
    w = cs.load_scene(cs.default_scene_path())
    types = {s.type for s in w.user_shapes}
    assert {"plane", "sphere", "box", "convex", "mesh"} <= types
    assert int(np.sum(w.kind == 2)) >= 4


def test_slab_normals_scene_key():
    d = scene(bodies__2__shape={"type": "box", "size": [1, 2, 3], "slab_normals": [[1, 1, 0], [0, 0, 2]]})
    w = cs.load_scene(d)
    n = w.shapes[2].slab_normals
    assert np.allclose(n, [[2 ** -0.5, 2 ** -0.5, 0], [0, 0, 1]], atol=1e-15)
    with pytest.raises(cs.SceneError, match=r"bodies\[2\]\.shape\.slab_normals: normal 1 is zero"):
        cs.load_scene(scene(bodies__2__shape={"type": "box", "size": [1, 2, 3], "slab_normals": [[1, 0, 0], [0, 0, 0]]}))


def test_off_centre_convex_geometry_is_shifted_not_rebuilt():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], float) + 5.0
    shape = cs.Convex(pts)
    w = cs.World()
    w.add_body("t", shape, mass=1.0)
    centred = w.shapes[0]
    com = w.body("t").center_of_mass
    assert np.allclose(centred.vertices, shape.vertices - com, atol=1e-14)
    # each face plane moved with the vertices: every vertex still on or inside every plane
    assert np.all(centred.vertices @ centred.plane_normals.T <= centred.plane_offsets + 1e-12)
    assert np.allclose(centred._hull.center_mass, 0, atol=1e-12)


def test_shipped_scenes_start_without_interpenetration():
    for name in cs.list_scenes():
        if "overlap" in name:
            continue  # deliberately starts overlapped (a hard case)
        w = cs.load_scene(cs.resolve_scene(name))
        c = w.detect()
        deepest = float(c.depth.max()) if len(c) else 0.0
        assert deepest <= 1e-6, f"{name}: bodies overlap by {deepest} m at start"


def test_default_scene_produces_contacts_and_settles():
    w = cs.load_scene(cs.default_scene_path())
    seen = 0
    for _ in range(int(round(3.0 / w.settings.dt))):
        w.step()
        seen = max(seen, len(w.contacts))
    assert seen >= 5
    assert len(w.contacts) >= 4 and w.contacts.depth.max() < 1e-3
    dyn = w.kind == 2
    assert np.abs(w.s.vel[dyn]).max() < 1e-2  # everything has come to rest
