"""Invariants on every contact of random poses: finite values, unit normals, points within ``depth``
of both surfaces, and symmetry under swapping A and B."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat

RNG_POINTS = np.random.default_rng(7).normal(size=(24, 3)) * [0.3, 0.2, 0.25]
SHAPES = {
    "sphere": cs.Sphere(0.3),
    "box": cs.Box([0.6, 0.4, 0.3]),
    "convex": cs.Convex(RNG_POINTS),
}


def excess(shape, pos, q, p):
    """Lower bound of the signed distance from points ``p (K, 3)`` to a shape (exact for spheres):
    the largest face-plane excess of a polyhedron, ``|p − c| − r`` for a sphere."""
    local = quat.rotate(quat.conj(q), p - pos)
    if shape.type == "sphere":
        return np.linalg.norm(local, axis=1) - shape.radius
    return (local @ shape.plane_normals.T - shape.plane_offsets).max(axis=1)


def random_pose(rng, spread):
    return rng.uniform(-spread, spread, 3), quat.normalize(rng.normal(size=4))


@pytest.mark.parametrize("ta, tb", [("sphere", "sphere"), ("sphere", "box"), ("box", "box"), ("convex", "box"),
                                    ("convex", "convex"), ("convex", "sphere")])
def test_contact_invariants_on_random_poses(ta, tb):
    rng = np.random.default_rng(hash((ta, tb)) % 2**32)
    a, b = SHAPES[ta], SHAPES[tb]
    hits = 0
    for _ in range(300):
        pa, qa = random_pose(rng, 0.1)
        pb, qb = random_pose(rng, 0.6)
        c = cs.collide(a, (pa, qa), b, (pb, qb))
        if not len(c):
            continue
        hits += 1
        assert np.all(np.isfinite(c.point)) and np.all(np.isfinite(c.normal)) and np.all(np.isfinite(c.depth))
        assert np.allclose(np.linalg.norm(c.normal, axis=1), 1.0, atol=1e-12)
        assert np.all(c.depth >= -1e-12)
        slack = c.depth + 1e-9
        assert np.all(excess(a, pa, qa, c.point) <= slack), "point farther outside A than the depth"
        assert np.all(excess(b, pb, qb, c.point) <= slack), "point farther outside B than the depth"
        # B → A: moving A along the normal by the depth (plus a little) separates the pair
        moved = cs.collide(a, (pa + c.normal[np.argmax(c.depth)] * (c.depth.max() + 1e-6), qa), b, (pb, qb))
        assert len(moved) == 0 or moved.depth.max() < 1e-6
        s = cs.collide(b, (pb, qb), a, (pa, qa))
        assert len(s) and np.isclose(s.depth.max(), c.depth.max(), rtol=0, atol=1e-9)
        ia, ib = np.argmax(c.depth), np.argmax(s.depth)
        assert np.allclose(s.normal[ib], -c.normal[ia], atol=1e-6)
    assert hits > 30  # the poses really produce contacts


def test_detection_keeps_no_reference_to_discarded_worlds():
    import gc
    import weakref

    w = cs.load_scene(cs.default_scene_path())
    w.detect()
    refs = [weakref.ref(w)] + [weakref.ref(s) for s in w.shapes]
    del w
    gc.collect()
    assert all(r() is None for r in refs)  # the cached shape arrays went with the world



ID = np.array([0.0, 0.0, 0.0, 1.0])


@pytest.mark.exact
@pytest.mark.parametrize("tb", ["sphere", "box", "convex"])
@pytest.mark.parametrize("offset", [1.79e-162, 1e-200, 5e-324])
def test_unit_normals_when_the_centres_differ_below_the_square_roots_range(tb, offset):
    """A sphere whose centre is ``offset`` (m) from another body's centre, so small that its square
    underflows: 1.79e-162² is below the smallest double, and ``d / sqrt(d · d)`` was 0.806 long
    (fresh draws, seed 20261220, sphere–sphere). The normal is of unit length, and between two
    spheres along the offset, with the coincident pose's depth."""
    for axis in range(3):
        pa = np.zeros(3)
        pa[axis] = offset
        c = cs.collide(cs.Sphere(0.0188), (pa, ID), SHAPES[tb], (np.zeros(3), ID))
        assert len(c)
        np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0, rtol=0, atol=1e-15)
        if tb == "sphere":
            np.testing.assert_array_equal(c.normal[0], np.eye(3)[axis])   # B → A: along A's offset
            np.testing.assert_allclose(c.depth[0], 0.0188 + 0.3, rtol=1e-15)


@pytest.mark.exact
@pytest.mark.parametrize("offset", [1.79e-162, 1e-200, 5e-324])
def test_unit_normal_of_a_sphere_outside_a_face_through_the_origin_by_less_than_the_square_roots_range(offset):
    """A convex block whose face lies on x = 0 in world coordinates, and a sphere whose centre is
    outside that face by ``offset``: the centre-to-surface difference is ``offset`` itself, its
    square underflows, and the normal is the face's, of unit length."""
    block = cs.Convex(np.array([[x, y, z] for x in (-0.6, 0.0) for y in (-0.2, 0.2) for z in (-0.15, 0.15)]))
    c = cs.collide(block, (np.zeros(3), ID), cs.Sphere(0.05), (np.array([offset, 0.01, 0.02]), ID))
    assert len(c) == 1
    np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(c.normal[0], [-1.0, 0.0, 0.0], atol=1e-15)   # B → A
    np.testing.assert_allclose(c.depth[0], 0.05, rtol=0, atol=1e-15)   # the closest point to round-off of 0.6 m


def _every_shape():
    import trimesh

    box = trimesh.creation.box((0.6, 0.4, 0.3))
    return dict(SHAPES, plane=cs.Plane(), cylinder=cs.Cylinder(0.2, 0.5), mesh=cs.TriMesh(box.vertices, box.faces))


@pytest.mark.exact
def test_every_pair_gives_unit_normals_for_offsets_whose_squares_underflow():
    """Every pair of shape types with A's centre ``offset`` from B's (along the axes and a diagonal,
    offsets down to the smallest double), and a sphere just outside a face that lies on a world
    coordinate plane: every contact finite, its normal of unit length. Squares of such offsets are
    below the normal doubles, so a normal formed as ``d / sqrt(d · d)`` comes out of any length."""
    shapes = _every_shape()
    dirs = [np.eye(3)[0], np.eye(3)[1], np.eye(3)[2], np.array([1.0, -1.0, 1.0])]
    checked = 0
    for ta, a in shapes.items():
        for tb, b in shapes.items():
            if ta == tb == "plane":
                continue
            for offset in (1.79e-162, 1e-200, 5e-324, 0.0):
                for d in dirs:
                    c = cs.collide(a, (d * offset, ID), b, (np.zeros(3), ID))
                    checked += len(c)
                    assert np.isfinite(c.point).all() and np.isfinite(c.depth).all(), (ta, tb, offset, d)
                    np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0, rtol=0, atol=1e-12,
                                               err_msg=f"{ta} against {tb}, offset {offset} along {d}")
    # a sphere outside B's +x face (on x = 0) by the offset: the centre-to-surface difference is it
    block = cs.Convex(np.array([[x, y, z] for x in (-0.6, 0.0) for y in (-0.2, 0.2) for z in (-0.15, 0.15)]))
    for tb, b, at in (("box", shapes["box"], -0.3), ("convex", block, 0.0), ("cylinder", shapes["cylinder"], -0.2),
                      ("mesh", shapes["mesh"], -0.3)):
        for offset in (1.79e-162, 1e-200, 5e-324):
            c = cs.collide(cs.Sphere(0.05), (np.array([offset, 0.0, 0.02]), ID), b, (np.array([at, 0.0, 0.0]), ID))
            assert len(c)
            checked += len(c)
            np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0, rtol=0, atol=1e-12, err_msg=tb)
            np.testing.assert_allclose(c.normal[np.argmax(c.depth)], [1.0, 0.0, 0.0], atol=1e-9, err_msg=tb)
    assert checked > 500
