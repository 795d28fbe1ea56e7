"""Hand-made configurations for plane, sphere and box pairs, and invariants of every result."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat as Q
from contact_sim.collision import collide, detect_world, DetectionStats
from contact_sim.contacts import FEATURES

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

I = (0.0, 0.0, 0.0, 1.0)


def check(c, a=None, pa=None, b=None, pb=None, margin=0.0):
    """Invariants: finite, unit normals, and (when the inputs are given) symmetry under swapping."""
    assert np.all(np.isfinite(c.point)) and np.all(np.isfinite(c.normal)) and np.all(np.isfinite(c.depth))
    if len(c):
        assert np.allclose(np.linalg.norm(c.normal, axis=1), 1.0, atol=1e-12)
        assert np.all(c.depth >= -margin - 1e-12)
    if a is not None:
        s = collide(b, pb, a, pa, margin)
        assert len(s) == len(c)
        if len(c):
            assert np.isclose(s.depth.max(), c.depth.max(), atol=1e-12)
            # same points and depths, normals flipped (order may differ)
            key = lambda x: np.lexsort(np.round(x.point, 9).T)
            i, j = key(c), key(s)
            assert np.allclose(c.point[i], s.point[j], atol=1e-9)
            assert np.allclose(c.normal[i], -s.normal[j], atol=1e-9)
            assert np.allclose(c.depth[i], s.depth[j], atol=1e-12)
    return c


def both(a, pa, b, pb, margin=0.0):
    return check(collide(a, pa, b, pb, margin), a, pa, b, pb, margin)


def test_sphere_plane_exact():
    pl, sp = cs.Plane((0, 0, 1), 0.0), cs.Sphere(0.5)
    c = both(sp, ((1, 2, 0.4), I), pl, ((0, 0, 0), I))
    assert len(c) == 1
    assert np.allclose(c.normal[0], [0, 0, 1]) and np.isclose(c.depth[0], 0.1)
    assert np.allclose(c.point[0], [1, 2, -0.05])
    assert FEATURES[c.feature[0]] == "plane"
    # touching: depth exactly 0; apart by 1e-9: nothing without margin, depth -1e-9 with one
    c = both(sp, ((0, 0, 0.5), I), pl, ((0, 0, 0), I))
    assert len(c) == 1 and c.depth[0] == 0.0
    assert len(both(sp, ((0, 0, 0.5 + 1e-9), I), pl, ((0, 0, 0), I))) == 0
    c = both(sp, ((0, 0, 0.5 + 1e-9), I), pl, ((0, 0, 0), I), margin=1e-6)
    assert np.isclose(c.depth[0], -1e-9, atol=1e-15)
    # tilted and offset plane, deep
    pl2 = cs.Plane((1, 0, 1), 1.0)  # x + z <= sqrt2 after normalising
    c = both(sp, ((0, 0, 0), I), pl2, ((0, 0, 0), I))
    assert np.isclose(c.depth[0], 0.5 + 1 / np.sqrt(2)) and np.allclose(c.normal[0], [2**-0.5, 0, 2**-0.5])


def test_sphere_sphere():
    a, b = cs.Sphere(0.5), cs.Sphere(0.25)
    c = both(a, ((0.7, 0, 0), I), b, ((0, 0, 0), I))
    assert np.isclose(c.depth[0], 0.05) and np.allclose(c.normal[0], [1, 0, 0])
    assert np.allclose(c.point[0], [0.25 - 0.025, 0, 0])
    assert collide(a, ((0.75, 0, 0), I), b, ((0, 0, 0), I)).depth[0] == 0.0
    assert len(collide(a, ((0.75 + 1e-9, 0, 0), I), b, ((0, 0, 0), I))) == 0
    # concentric (one inside the other): any normal is right, so no symmetry check
    c = check(collide(a, ((0, 0, 0), I), b, ((0, 0, 0), I)))
    assert np.isclose(c.depth[0], 0.75)


def test_box_plane_manifold():
    pl, bx = cs.Plane(), cs.Box((1, 2, 0.5))
    c = both(bx, ((3, 4, 0.2), I), pl, ((0, 0, 0), I))
    assert len(c) == 4
    assert np.allclose(c.depth, 0.05) and np.allclose(c.normal, [0, 0, 1])
    assert np.allclose(np.sort(c.point[:, 0]), [2.5, 2.5, 3.5, 3.5])
    assert np.allclose(np.sort(c.point[:, 1]), [3, 3, 5, 5])
    # on an edge (45 deg about x): 2 contacts; on a corner: 1
    q = Q.axis_rotation(0, [np.pi / 4])[0]
    h = np.sqrt(2) * 0.5 * np.hypot(2, 0.5) * np.cos(np.pi / 4 - np.arctan2(0.5, 2))
    lowest = (Q.rotate(q, Box_vertices(bx)) @ [0, 0, 1]).min()
    c = both(bx, ((0, 0, -lowest - 0.01), q), pl, ((0, 0, 0), I))
    assert len(c) == 2 and np.allclose(c.depth, 0.01)
    del h


def Box_vertices(bx):
    return bx.vertices


def test_box_sphere():
    bx, sp = cs.Box((2, 2, 2)), cs.Sphere(0.5)
    c = both(bx, ((0, 0, 0), I), sp, ((0, 0, 1.4), I))     # face
    assert np.isclose(c.depth[0], 0.1) and np.allclose(c.normal[0], [0, 0, -1])
    c = both(bx, ((0, 0, 0), I), sp, ((1.2, 1.2, 1.2), I))  # vertex region: true distance
    assert np.isclose(c.depth[0], 0.5 - np.sqrt(3 * 0.04))
    c = both(bx, ((0, 0, 0), I), sp, ((1.2, 1.2, 0), I))    # edge region
    assert np.isclose(c.depth[0], 0.5 - np.sqrt(2 * 0.04))
    c = both(bx, ((0, 0, 0), I), sp, ((0, 0, 0.8), I))      # centre inside
    assert np.isclose(c.depth[0], 0.7) and np.allclose(c.normal[0], [0, 0, -1])
    assert collide(bx, ((0, 0, 0), I), sp, ((0, 0, 1.5), I)).depth[0] == 0.0
    assert len(collide(bx, ((0, 0, 0), I), sp, ((0, 0, 1.5 + 1e-9), I))) == 0


def test_box_box_face_edge_vertex():
    b = cs.Box((1, 1, 1))
    # face-face resting, offset: 4 points spanning the overlap patch
    c = both(b, ((0.2, 0.1, 0.99), I), b, ((0, 0, 0), I))
    assert len(c) == 4 and np.allclose(c.depth, 0.01) and np.allclose(c.normal, [0, 0, 1])
    assert np.allclose(np.sort(np.unique(np.round(c.point[:, 0], 9))), [-0.3, 0.5])
    assert all(FEATURES[f] == "face_face" for f in c.feature)
    # coplanar faces, exactly touching: depth 0
    c = both(b, ((0, 0, 1.0), I), b, ((0, 0, 0), I))
    assert len(c) == 4 and np.all(c.depth == 0)
    assert len(collide(b, ((0, 0, 1.0 + 1e-9), I), b, ((0, 0, 0), I))) == 0
    # vertex down onto a face
    q = Q.normalize(Q.mul(Q.axis_rotation(0, [np.arctan(np.sqrt(0.5))])[0], Q.axis_rotation(2, [np.pi / 4])[0]))
    low = (Q.rotate(q, b.vertices) @ [0, 0, 1]).min()
    c = both(b, ((0, 0, 0.5 - low - 0.02), q), b, ((0, 0, 0), I))
    assert len(c) == 1 and np.isclose(c.depth[0], 0.02) and np.allclose(c.normal[0], [0, 0, 1])
    # one inside the other
    small = cs.Box((0.2, 0.2, 0.2))
    c = both(small, ((0, 0, 0.1), I), b, ((0, 0, 0), I))
    assert np.isclose(c.depth.max(), 0.5)


def test_crossed_boxes_edge_face():
    """Two long boxes crossed at 90 deg, rotated 45 deg about their long axes so that only the
    edges interpenetrate: no vertex is inside, the edge-face test and an edge x edge axis find it."""
    lb = cs.Box((4, 0.5, 0.5))
    qx = Q.axis_rotation(0, [np.pi / 4])[0]
    qy = Q.mul(Q.axis_rotation(2, [np.pi / 2])[0], qx)
    d = 0.5 * np.sqrt(2) - 0.01      # each edge reaches 0.25*sqrt2 from the axis
    c, st = collide(lb, ((0, 0, d), qy), lb, ((0, 0, 0), qx), stats=True)
    check(c, lb, ((0, 0, d), qy), lb, ((0, 0, 0), qx))
    assert len(c) == 1 and np.isclose(c.depth[0], 0.01) and np.allclose(c.normal[0], [0, 0, 1])
    assert np.allclose(c.point[0], [0, 0, d / 2])
    assert FEATURES[c.feature[0]] == "edge_face"
    assert st.settled_by_vertex == 0 and st.needed_edge_face == 1 and st.edge_face_hits == 1
    # 1 cm apart, within a 2 cm margin: an edge axis separates them, so no edge crosses a face
    # (counted without running the crossing test); the contact is the edges' gap
    d = 0.5 * np.sqrt(2) + 0.01
    c, st = collide(lb, ((0, 0, d), qy), lb, ((0, 0, 0), qx), margin=0.02, stats=True)
    assert len(c) == 1 and np.isclose(c.depth[0], -0.01, rtol=1e-9) and np.allclose(c.normal[0], [0, 0, 1])
    assert st.settled_by_vertex == 0 and st.needed_edge_face == 1 and st.edge_face_hits == 0


def test_parallel_edges():
    lb = cs.Box((4, 0.5, 0.5))
    qx = Q.axis_rotation(0, [np.pi / 4])[0]
    d = 0.5 * np.sqrt(2) - 0.01      # same orientation, top edge against bottom edge
    c = both(lb, ((0.5, 0, d), qx), lb, ((0, 0, 0), qx))
    # the shallowest way out is along a 45 deg face normal: depth 0.01/sqrt2, and the contact is the
    # thin sliver where the two faces overlap, spanning the common length x in [-1.5, 2]
    assert len(c) == 4 and np.allclose(c.depth, 0.01 / np.sqrt(2))
    assert np.allclose(np.abs(c.normal), [0, 2**-0.5, 2**-0.5])
    assert np.isclose(c.point[:, 0].min(), -1.5) and np.isclose(c.point[:, 0].max(), 2.0)
    # touching edge on edge (the edges coincide along a line, up to the round-off of sqrt2)
    c = both(lb, ((0.5, 0, 0.5 * np.sqrt(2)), qx), lb, ((0, 0, 0), qx), margin=1e-12)
    assert len(c) >= 2 and np.allclose(c.depth, 0, atol=1e-15)


@pytest.mark.parametrize("q", [(float("nan"), 0, 0, 1), (0, 0, 0, 0)])
def test_bad_pose_refused(q):
    with pytest.raises(cs.ContactSimError, match="pose_b.orientation"):
        collide(cs.Sphere(1), ((0, 0, 0), I), cs.Sphere(1), ((0, 0, 0), q))
    with pytest.raises(cs.ContactSimError, match="pose_a.position"):
        collide(cs.Sphere(1), ((0, float("nan"), 0), I), cs.Sphere(1), ((0, 0, 0), I))
    with pytest.raises(cs.ContactSimError, match="margin"):
        collide(cs.Sphere(1), ((0, 0, 0), I), cs.Sphere(1), ((0, 0, 0), I), margin=-1)


def test_detect_world_filters_and_stats():
    w = cs.World()
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("ball", cs.Sphere(0.5), position=(0, 0, 0.45))
    w.add_body("box", cs.Box((1, 1, 1)), position=(2, 0, 0.49))
    w.add_body("box2", cs.Box((1, 1, 1)), position=(2, 0, 1.48))
    w.add_body("static_box", cs.Box((1, 1, 1)), kind="static", position=(5, 0, 0.4))  # static-static: skipped
    w.add_body("ghost", cs.Sphere(0.5), position=(-2, 0, 0.4), group=2, mask=2)        # filtered vs ground
    w.add_body("far", cs.Sphere(0.5), position=(0, 30, 30))
    c, st = detect_world(w)
    assert isinstance(st, DetectionStats)
    pairs = sorted(set(zip(c.body_a.tolist(), c.body_b.tolist())))
    assert pairs == [(0, 1), (0, 2), (2, 3)]
    assert st.candidate_pairs == 3 and st.colliding_pairs == 3 and st.contacts == len(c) == 9
    assert np.all(c.body_a < c.body_b)
    ball = c.select(c.body_b == 1)
    assert np.allclose(ball.normal, [0, 0, -1]) and np.isclose(ball.depth[0], 0.05)  # from ball to ground
    top = c.select(c.body_b == 3)
    assert len(top) == 4 and np.allclose(top.normal, [0, 0, -1]) and np.allclose(top.depth, 0.01)
    assert set(st.seconds) >= {"broad", "bounding", "narrow", "total"}
    # margin override: the far-apart stack now separated by 0.005 is reported with negative depth
    w.set_state("box2", position=(2, 0, 1.495))
    c, st = detect_world(w, margin=0.01)
    top = c.select(c.body_b == 3)
    assert len(top) == 4 and np.allclose(top.depth, -0.005)
    assert len(w.detect()) == len(c) - 4  # default margin 1e-4 does not reach



@pytest.mark.exact
def test_collide_takes_poses_as_lists_tuples_arrays_or_numpy_scalars_alike():
    """The one-pair query gives the same contacts whatever holds the pose's numbers (a tuple of
    numpy scalars, e.g. from iterating an array, is as plain as one of floats), and refuses a NaN
    in any of them by name."""
    q = np.array([0.1, 0.2, 0.3, 0.9])
    q = q / np.linalg.norm(q)
    a, b = cs.Box((0.2, 0.2, 0.2)), cs.Box((0.2, 0.2, 0.2))
    ref = collide(a, (np.zeros(3), np.array(I)), b, (np.array([0.0, 0.0, 0.22]), q))
    assert len(ref) >= 1
    for pose in (((0.0, 0.0, 0.22), tuple(float(x) for x in q)), ((0, 0, 0.22), tuple(q)),
                 ([np.float64(0), np.int64(0), np.float64(0.22)], list(q))):
        c = collide(a, ((0, 0, 0), I), b, pose)
        assert np.array_equal(c.point, ref.point) and np.array_equal(c.depth, ref.depth)
        assert np.array_equal(c.normal, ref.normal)
    with pytest.raises(cs.ContactSimError, match="position"):
        collide(a, ((0, 0, 0), I), b, ((np.float64("nan"), 0.0, 0.22), tuple(q)))


def test_a_step_detection_skips_the_edge_face_census_and_finds_the_same_contacts():
    # two long boxes crossed edge into edge (no vertex inside: the edge–face test runs and finds
    # the crossing, as in test_crossed_boxes_edge_face) and a box on the floor: the census
    # (detect_world) and a step's detection (census=False) give the same contacts, bit for bit;
    # only the crossing count differs (None: not taken)
    from contact_sim.collision import detect_world

    qx = Q.axis_rotation(0, [np.pi / 4])[0]
    qy = Q.mul(Q.axis_rotation(2, [np.pi / 2])[0], qx)
    d = 0.5 * np.sqrt(2) - 0.01
    w = cs.World(gravity=(0.0, 0.0, 0.0))
    w.add_body("floor", cs.Plane((0.0, 0.0, 1.0), 0.0), kind="static")
    w.add_body("low", cs.Box((4, 0.5, 0.5)), position=(0.0, 0.0, 1.0), orientation=tuple(qx), mass=1.0)
    w.add_body("high", cs.Box((4, 0.5, 0.5)), position=(0.0, 0.0, 1.0 + d), orientation=tuple(qy), mass=1.0)
    w.add_body("cube", cs.Box((0.2, 0.2, 0.2)), position=(3.0, 3.0, 0.1 - 1e-4), mass=1.0)
    full, st_full = detect_world(w, margin=0.01)
    step, st_step = detect_world(w, margin=0.01, timed=False, census=False)
    assert st_full.needed_edge_face == st_step.needed_edge_face == 1 and st_full.edge_face_hits == 1
    assert st_step.edge_face_hits is None
    assert len(full) == len(step) == 5   # the edges' contact, the cube's four corners
    for col in ("body_a", "body_b", "point", "normal", "depth", "feature", "feature_id"):
        assert np.array_equal(getattr(full, col), getattr(step, col)), col
    w.step(1e-3)
    assert w.last_detection.edge_face_hits is None and w.last_detection.needed_edge_face == 1


def test_box_pairs_skip_the_edge_axes_only_where_the_face_contact_wins():
    """Two boxes whose 9 edge axes separate them no more than their face axes do skip the edge
    query in a step's detection (``polyhedra._box_edges_below``); the census's detection runs it.
    Over random box pairs — resting face to face (a stack), tilted onto an edge or a corner,
    nearly aligned (turned by 1e-9 to 1e-2 rad), far from the origin, thin plates, of very
    different sizes — both give the same contacts bit for bit, and the skip is taken in the
    stacked cases."""
    from contact_sim.collision import _bodies_of, detect_world, polyhedra
    from contact_sim.collision.geometry import SF_SCALE

    rng = np.random.default_rng(11)
    skipped = 0
    for trial in range(300):
        kind = trial % 5
        size_a = rng.uniform(0.05, 1.0, 3)
        size_b = size_a * (rng.uniform(0.5, 2.0) if kind != 4 else 50.0)
        if trial % 11 == 0:   # a thin plate
            size_a[rng.integers(3)] *= 1e-3
        if kind in (0, 1):     # stacked, aligned (0) or nearly aligned by a tiny turn (1)
            angle = 0.0 if kind == 0 else 10.0 ** rng.uniform(-9, -2)
            qa = np.array([0.0, 0.0, 0.0, 1.0])
            qb = Q.axis_rotation(2, [angle])[0]
            offset = np.array([rng.uniform(-0.2, 0.2) * size_a[0], rng.uniform(-0.2, 0.2) * size_a[1],
                               0.5 * (size_a[2] + size_b[2]) + rng.uniform(-1e-3, 1e-3)])
        else:                  # random orientations, near touching
            qa, qb = (q / np.linalg.norm(q) for q in rng.normal(size=(2, 4)))
            offset = rng.normal(size=3)
            offset *= 0.45 * (np.linalg.norm(size_a) + np.linalg.norm(size_b)) / np.linalg.norm(offset)
        base = rng.uniform(-1e3, 1e3, 3) if trial % 7 == 0 else np.zeros(3)
        w = cs.World(gravity=(0.0, 0.0, 0.0))
        w.add_body("a", cs.Box(tuple(size_a)), position=tuple(base), orientation=tuple(qa), mass=1.0)
        w.add_body("b", cs.Box(tuple(size_b)), position=tuple(base + offset), orientation=tuple(qb), mass=1.0)
        full, _ = detect_world(w, margin=0.01)
        step, _ = detect_world(w, margin=0.01, timed=False, census=False)
        for col in ("body_a", "body_b", "point", "normal", "depth", "feature", "feature_id"):
            assert np.array_equal(getattr(full, col), getattr(step, col)), (trial, col)
        if kind == 0 and len(step):   # aligned and flat: every point as deep, the face axis's separation
            bodies = _bodies_of(w)
            R = np.stack([Q.to_matrix(np.array(w.s.quat[i])) for i in range(2)])
            sa, sb = bodies.shape_of
            face_sep = -float(np.max(step.depth))
            scale = min(bodies.geom.sf[sa, SF_SCALE], bodies.geom.sf[sb, SF_SCALE])
            skipped += polyhedra._box_edges_below(bodies.geom.sf, sa, sb, w.s.pos[0], w.s.pos[1], R[0], R[1],
                                                  min(face_sep + 1e-9 * scale, 0.01))
    assert skipped >= 50   # every aligned stack (60 of them): its edge axes never beat its face axes
