"""The lecture's kinematic response and vertex-inside test, by name, and the engine using them
(issue 14, part 4). Exact-answer tests."""
import numpy as np
import pytest
import trimesh

import contact_sim as cs
from contact_sim.response import kinematic as kin

pytestmark = pytest.mark.exact


# ------------------------------------------------------------------ kinematic response
def test_kinematic_response_is_the_formula():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(50, 3))
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    k = rng.uniform(0, 1, 50)
    out = kin.kinematic_response(v, n, k)
    expect = v - ((1 + k) * np.sum(n * v, axis=1))[:, None] * n
    assert out.shape == (50, 3)
    assert np.abs(out - expect).max() <= 1e-15
    # k = 1: the normal component is negated, the tangential kept, the speed unchanged
    e1 = kin.kinematic_response(v, n, 1.0)
    assert np.allclose(np.sum(e1 * n, axis=1), -np.sum(v * n, axis=1), rtol=0, atol=1e-14)
    assert np.allclose(np.linalg.norm(e1, axis=1), np.linalg.norm(v, axis=1), rtol=0, atol=1e-14)
    # k = 0: the normal component is removed
    e0 = kin.kinematic_response(v, n, 0.0)
    assert np.abs(np.sum(e0 * n, axis=1)).max() <= 1e-14


def test_kinematic_response_broadcasts_one_normal():
    v = np.array([[1.0, 2.0, -3.0], [0.0, 0.0, -1.0]])
    out = kin.kinematic_response(v, [0, 0, 1.0], 0.5)
    assert np.array_equal(out, [[1.0, 2.0, 1.5], [0.0, 0.0, 0.5]])
    assert np.array_equal(kin.kinematic_response([0, -2.0, 0], [0, 1.0, 0], 1.0), [0, 2.0, 0])


def _particle_on_plane(k, v0):
    return cs.load_scene({
        "gravity": [0, 0, 0],
        "settings": {"dt": 1 / 60, "toi": "fractional", "response": "kinematic"},
        "materials": {"m": {"restitution": k, "friction": 0.0}},
        "bodies": [
            {"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
            {"name": "p", "model": "particle", "shape": {"type": "sphere", "radius": 0.05},
             "mass": 2.0, "position": [0, 0, 0.5], "velocity": list(v0), "material": "m"},
        ],
    })


def test_engine_applies_kinematic_response():
    """The step under ``response: kinematic`` gives the named kernel's answer (``kinematic_impacts``,
    which the impact stage calls) and the formula's: a particle landing on a plane leaves with
    ``v − (1+k)(N·v)N``, and the normal impulse is ``m (1+k) |v_n|``."""
    v0 = np.array([0.75, 0.5, -3.0])
    w = _particle_on_plane(0.6, v0)
    hit = None
    for _ in range(20):
        w.step()
        if hit is None and len(w.contacts):
            hit = w.contacts.normal_impulse.copy()
    expect = kin.kinematic_response(v0, [0, 0, 1.0], 0.6)
    assert np.abs(w.body("p").velocity - expect).max() <= 1e-12
    assert hit is not None and hit.sum() == pytest.approx(2.0 * 1.6 * 3.0, rel=1e-12)
    # the kernel by itself: the particle (1) on the ground (0), approaching at v0
    vel = np.array([[0.0, 0.0, 0.0], v0])
    lam = np.empty(1)
    kin.kinematic_impacts(vel, np.array([0.0, 0.5]), np.array([1]), np.array([0]), np.array([[0.0, 0.0, 1.0]]),
                          np.array([v0]), np.array([0.6]), np.array([True]), lam)
    assert np.array_equal(vel[1], kin.kinematic_response(v0, [0, 0, 1.0], 0.6))
    assert lam[0] == pytest.approx(2.0 * 1.6 * 3.0, rel=1e-15)


def test_kinematic_two_particles_share_the_change_by_mass():
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "fractional", "response": "kinematic", "dt": 0.01},
                 materials={"m": {"restitution": 0.5, "friction": 0.0}})
    w.add_body("a", cs.Sphere(0.1), model="particle", mass=1.0, position=[0, 0, 0], velocity=[1.0, 0, 0],
               material="m")
    w.add_body("b", cs.Sphere(0.1), model="particle", mass=3.0, position=[0.5, 0, 0], velocity=[-1.0, 0, 0],
               material="m")
    for _ in range(30):
        w.step()
    va, vb = w.body("a").velocity, w.body("b").velocity
    # relative velocity reflected with k = 0.5, momentum kept: vrel' = -0.5·(-2) = 1 along +x (b - a)
    assert abs((vb[0] - va[0]) - 1.0) <= 1e-12
    assert abs((1.0 * va[0] + 3.0 * vb[0]) - (1.0 - 3.0)) <= 1e-12


# ------------------------------------------------------------------ vertex inside
def test_vertex_inside_convex_is_every_face_plane():
    box = cs.Box([2.0, 1.0, 0.5])
    pts = np.array([[0, 0, 0], [0.99, 0.49, 0.24], [1.01, 0, 0], [0, 0.51, 0], [0, 0, -0.26], [1.0, 0.5, 0.25]])
    assert cs.vertex_inside(pts, box).tolist() == [True, True, False, False, False, True]   # the boundary is inside
    # a rotated, moved box: 90° about z swaps x and y extents
    q = [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)]
    got = cs.vertex_inside([[5.0, 0.9, 0], [5.9, 0, 0], [5.0, 1.1, 0]], box, pose=([5.0, 0, 0], q))
    assert got.tolist() == [True, False, False]
    assert cs.vertex_inside([0, 0, 0], box) is True


def test_vertex_inside_convex_matches_hull_equations():
    rng = np.random.default_rng(3)
    hull = cs.Convex(rng.normal(size=(30, 3)))
    pts = rng.uniform(-2, 2, size=(400, 3))
    from scipy.spatial import ConvexHull
    eq = ConvexHull(hull.vertices).equations
    expect = np.all(pts @ eq[:, :3].T + eq[:, 3] <= 0, axis=1)
    margin = np.min(np.abs(pts @ eq[:, :3].T + eq[:, 3]), axis=1)
    ok = margin > 1e-9      # away from the boundary: the verdicts must agree
    assert np.array_equal(cs.vertex_inside(pts, hull)[ok], expect[ok])


def test_vertex_inside_concave_by_parity():
    t = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    torus = cs.TriMesh(t.vertices, t.faces)
    # the hole is outside, the tube inside: a convex test would call the centre inside
    pts = np.array([[0, 0, 0], [1.0, 0, 0], [0, -1.0, 0.0], [0, 1.0, 0.29], [0, 1.0, 0.31], [1.5, 0, 0]])
    assert cs.vertex_inside(pts, torus).tolist() == [False, True, True, True, False, False]
    rng = np.random.default_rng(0)
    p = rng.uniform(-1.5, 1.5, size=(500, 3))
    expect = t.contains(p)
    d = np.abs(trimesh.proximity.signed_distance(t, p))
    ok = d > 1e-6
    assert np.array_equal(cs.vertex_inside(p, torus)[ok], expect[ok])


def test_vertex_inside_bad_input():
    with pytest.raises(cs.ContactSimError, match="vertex_inside: polyhedron: .*open mesh"):
        cs.vertex_inside([0, 0, 0], cs.TriMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))
    with pytest.raises(cs.ContactSimError, match="vertex_inside: polyhedron must be"):
        cs.vertex_inside([0, 0, 0], cs.Sphere(1.0))
    with pytest.raises(cs.ContactSimError, match="vertex_inside: points"):
        cs.vertex_inside([[0, np.nan, 0]], cs.Box([1, 1, 1]))


def test_engine_counts_vertex_inside_through_the_named_test():
    # box A's corner inside box B: the convex kernels' vertex test (settled_by_vertex) agrees
    a, b = cs.Box([1, 1, 1]), cs.Box([1, 1, 1])
    pa, pb = np.array([0.0, 0, 0]), np.array([0.9, 0.9, 0.9])
    c, st = cs.collide(a, (pa, [0, 0, 0, 1]), b, (pb, [0, 0, 0, 1]), stats=True)
    corner = pa + 0.5
    assert cs.vertex_inside(corner, b, pose=(pb, [0, 0, 0, 1]))
    assert st.settled_by_vertex == 1 and len(c)
