"""Hull cases the SAT's Gauss-map pruning could get wrong, and the contacts' feature ids.

The reference is a brute-force separating-axis test written here (every face normal of both
bodies and every edge × edge cross product, with plain projections of all vertices), so a pruned
edge pair that mattered would show as a different depth or normal.
"""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat as Q
from contact_sim.collision import collide, collide_pairs
from contact_sim.contacts import (FID_EDGE, FID_FACE_A, FID_FACE_B, FID_PLANE, FID_POINT, Contacts, fid,
                                  split_fid)

I = np.array([0.0, 0.0, 0.0, 1.0])


def brute_sat(sa, pa, qa, sb, pb, qb):
    """``(separation, normal B→A)`` of the best axis over every face normal and edge × edge axis."""
    Ra, Rb = Q.to_matrix(np.asarray(qa, float)), Q.to_matrix(np.asarray(qb, float))
    va, vb = sa.vertices @ Ra.T + pa, sb.vertices @ Rb.T + pb
    ea = (sa.vertices[sa.edges[:, 1]] - sa.vertices[sa.edges[:, 0]]) @ Ra.T
    eb = (sb.vertices[sb.edges[:, 1]] - sb.vertices[sb.edges[:, 0]]) @ Rb.T
    ex = np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3)
    ln = np.linalg.norm(ex, axis=1)
    scale = np.linalg.norm(ea, axis=1).max() * np.linalg.norm(eb, axis=1).max()
    ex = ex[ln > 1e-9 * scale] / ln[ln > 1e-9 * scale, None]
    axes = np.concatenate([sa.plane_normals @ Ra.T, sb.plane_normals @ Rb.T, ex])
    ja, jb = va @ axes.T, vb @ axes.T
    gap_ab = jb.min(axis=0) - ja.max(axis=0)
    gap_ba = ja.min(axis=0) - jb.max(axis=0)
    sep = np.maximum(gap_ab, gap_ba)
    k = int(np.argmax(sep))
    return sep[k], (axes[k] if gap_ba[k] >= gap_ab[k] else -axes[k])


def prism(length=1.0, w=0.4):
    """A triangular prism along x (parallel long edges, coplanar side faces)."""
    tri = np.array([[0.0, -w / 2, 0.0], [0.0, w / 2, 0.0], [0.0, 0.0, w * 0.8]])
    return cs.Convex(np.vstack([tri + [-length / 2, 0, 0], tri + [length / 2, 0, 0]]))


def tetra(s=0.3):
    return cs.Convex(np.array([[0, 0, 0], [s, 0, 0], [0, s, 0], [0, 0, s]], float) - s / 4)


def check_against_sat(a, pa, qa, b, pb, qb, margin=1e-9):
    sep, nrm = brute_sat(a, pa, qa, b, pb, qb)
    c = collide(a, (pa, qa), b, (pb, qb), margin=margin)
    if sep > margin:
        assert len(c) == 0
        return sep, c
    assert len(c) >= 1
    k = int(np.argmax(c.depth))
    scale = 1.0
    assert abs(c.depth[k] - (-sep)) <= 1e-9 * scale, (c.depth[k], -sep)
    return sep, c


@pytest.mark.exact
@pytest.mark.parametrize("gap", [-1e-3, -1e-9, -1e-10, 0.0, 1e-10, 1e-9, 1e-3])
def test_parallel_edges_of_two_prisms_near_touching(gap):
    """Ridge on ridge: the top edges of an upside-down prism and an upright one are parallel (their
    cross product is zero: no edge axis), so a face axis must give the exact answer."""
    p = prism()
    flip = Q.axis_rotation(0, [np.pi])[0]
    top = 0.4 * 0.8
    sep, c = check_against_sat(p, np.array([0.3, 0.0, 2 * top + gap]), flip, p, np.zeros(3), I, margin=2e-9)
    if gap <= 1e-9:
        assert len(c) >= 1 and np.all(np.isfinite(c.normal))


@pytest.mark.exact
@pytest.mark.parametrize("gap", [-1e-3, -1e-9, 0.0, 1e-9])
def test_crossed_prism_ridges_edge_edge(gap):
    """Ridges crossed at 90 degrees: the only contact is edge on edge (a Minkowski face from an edge
    pair); the depth is exact and the feature id names the two edges."""
    p = prism()
    q = Q.mul(Q.axis_rotation(2, [np.pi / 2])[0], Q.axis_rotation(0, [np.pi])[0])
    top = 0.4 * 0.8
    sep, c = check_against_sat(p, np.array([0.0, 0.0, 2 * top + gap]), q, p, np.zeros(3), I, margin=2e-9)
    assert abs(sep - gap) < 1e-12
    if gap <= 1e-9:
        assert len(c) == 1 and np.allclose(c.normal[0], [0, 0, 1], atol=1e-9)
        kind = split_fid(c.feature_id)[0]
        assert kind[0] == FID_EDGE


@pytest.mark.exact
@pytest.mark.parametrize("gap", [-1e-3, -1e-9, 0.0, 1e-9])
def test_coplanar_faces_hull_on_box(gap):
    """A prism lying on its side face on a box: coplanar faces, a patch of 4 points at one depth."""
    p = prism()
    box = cs.Box((2.0, 2.0, 0.5))
    sep, c = check_against_sat(p, np.array([0.1, 0.2, 0.25 + gap]), I, box, np.zeros(3), I, margin=2e-9)
    if gap <= 1e-9:
        assert len(c) == 4
        np.testing.assert_allclose(c.depth, -gap, atol=1e-12)
        np.testing.assert_allclose(c.normal, np.tile([0, 0, 1.0], (4, 1)), atol=1e-12)
        assert len(set(c.feature_id.tolist())) == 4


@pytest.mark.exact
@pytest.mark.parametrize("gap", [-1e-3, -1e-9, 0.0, 1e-9, 1e-6])
def test_vertex_on_face(gap):
    """A tetrahedron standing on a vertex over a box face."""
    t = tetra()
    # turn the tetrahedron so that the vertex (0, 0, 0) - s/4 points straight down
    v = t.vertices[np.argmin(np.linalg.norm(t.vertices - (-0.075), axis=1))]
    axis = np.cross(v / np.linalg.norm(v), [0, 0, -1.0])
    angle = np.arccos(np.clip(v @ [0, 0, -1.0] / np.linalg.norm(v), -1, 1))
    q = Q.from_rotvec(axis / np.linalg.norm(axis) * angle)
    low = (Q.rotate(q, t.vertices) @ [0, 0, 1]).min()
    box = cs.Box((1.0, 1.0, 0.5))
    sep, c = check_against_sat(t, np.array([0.05, -0.1, 0.25 - low + gap]), q, box, np.zeros(3), I, margin=2e-9)
    assert abs(sep - gap) < 1e-12
    if gap <= 1e-9:
        assert len(c) == 1 and np.allclose(c.normal[0], [0, 0, 1], atol=1e-12)


def random_hull(rng, n=32, s=0.5):
    p = rng.normal(size=(n, 3))
    return cs.Convex(p / np.linalg.norm(p, axis=1, keepdims=True) * rng.uniform(0.5, 1, size=(n, 1)) * s)


def test_random_hull_pairs_exact_against_brute_force_sat():
    """Random 32-point hulls at random poses, many touching within 1e-9: the depth of the deepest
    contact equals the brute-force SAT's to 1e-9 relative, the normal too where the best axis is
    unique; the verdict matches at margin 0."""
    rng = np.random.default_rng(21)
    checked = 0
    for trial in range(60):
        a, b = random_hull(rng), random_hull(rng)
        qa, qb = Q.normalize(rng.normal(size=4)), Q.normalize(rng.normal(size=4))
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        pb = np.zeros(3)
        # place A along d so that the SAT separation is a chosen small number (bisection on the offset)
        target = rng.choice([-1e-2, -1e-6, -1e-9, 0.0, 1e-9, 1e-6])
        lo, hi = 0.0, 2.0
        for _ in range(45):
            mid = 0.5 * (lo + hi)
            if brute_sat(a, d * mid, qa, b, pb, qb)[0] < target:
                lo = mid
            else:
                hi = mid
        pa = d * lo
        sep, nrm = brute_sat(a, pa, qa, b, pb, qb)
        c = collide(a, (pa, qa), b, (pb, qb), margin=0.0)
        assert (len(c) > 0) == (sep <= 0) or abs(sep) < 1e-12, (trial, sep, len(c))
        if len(c) == 0:
            continue
        k = int(np.argmax(c.depth))
        assert abs(c.depth[k] + sep) <= 1e-9 * max(abs(sep), 1e-3), (trial, c.depth[k], -sep)
        if sep < -1e-6:
            assert np.linalg.norm(c.normal[k] - nrm) < 1e-6 or abs(c.depth[k] + sep) < 1e-12
        checked += 1
    assert checked > 25


# ---------------------------------------------------------------- feature ids
def _pairs_unique(c):
    key = np.stack([c.body_a, c.body_b, c.feature_id], axis=1)
    return len(np.unique(key, axis=0)) == len(c)


@pytest.mark.exact
def test_feature_ids_stable_while_the_same_features_touch():
    b = cs.Box((1, 1, 1))
    ids = None
    for dx in (0.2, 0.2001, 0.2002, 0.19):   # a box sliding on a box: same corners, same ids
        c = collide(b, ((dx, 0.1, 0.99), I), b, ((0, 0, 0), I))
        assert len(c) == 4 and len(set(c.feature_id.tolist())) == 4
        s = sorted(c.feature_id.tolist())
        assert ids is None or s == ids
        ids = s
    assert set(split_fid(np.array(ids))[0].tolist()) <= {FID_FACE_A, FID_FACE_B}
    # sphere pairs: one point, id 0; box on a plane: the box's vertex indices
    assert collide(cs.Sphere(0.5), ((0, 0, 0.4), I), cs.Plane(), ((0, 0, 0), I)).feature_id.tolist() == \
        [fid(FID_POINT, 0, 0, 0)]
    c = collide(b, ((0, 0, 0.49), I), cs.Plane(), ((0, 0, 0), I))
    kind, x, _, _ = split_fid(c.feature_id)
    assert np.all(kind == FID_PLANE) and np.all(b.vertices[x][:, 2] < 0)


def test_feature_ids_unique_within_each_pair_of_a_crowded_world():
    rng = np.random.default_rng(3)
    shapes = [cs.Sphere(0.3), cs.Box((0.6, 0.5, 0.4)), random_hull(rng, 24, 0.35)]
    n = 200
    sh = [shapes[k] for k in rng.integers(0, 3, n)] + [cs.Plane()]
    pos = np.vstack([rng.uniform(0, 3, size=(n, 3)), np.zeros(3)])
    q = Q.normalize(rng.normal(size=(n + 1, 4)))
    i, j = np.triu_indices(n + 1, 1)
    c, _ = collide_pairs(sh, pos, q, np.column_stack([i, j]), margin=0.01)
    assert len(c) > 100 and c.feature_id.dtype == np.int64
    assert _pairs_unique(c)


def test_contacts_select_concat_keep_feature_ids():
    c = collide(cs.Box((1, 1, 1)), ((0.2, 0.1, 0.99), I), cs.Box((1, 1, 1)), ((0, 0, 0), I))
    s = c.select(c.depth > -1)
    assert np.array_equal(s.feature_id, c.feature_id)
    both = Contacts.concat([c, Contacts.empty(), s])
    assert len(both.feature_id) == 2 * len(c) and both.feature_id.dtype == np.int64
    assert Contacts.empty().feature_id.shape == (0,)


def test_a_translated_copy_does_not_reuse_the_prepared_geometry():
    """A hull used in a query, then added to a world (which moves its origin to the centre of
    mass), collides at its new geometry."""
    h = cs.Convex(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]))
    collide(h, ((0, 0, 0), I), cs.Plane(), ((0, 0, -1), I))          # prepares and caches h's geometry
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("h", h, density=1000.0, position=(0, 0, 0.01))
    c = w.detect()
    assert len(c) == 0                                                   # 1 cm above the floor
    w.set_state("h", position=(0, 0, -0.01))
    c = w.detect()
    assert len(c) == 3 and np.allclose(c.depth, 0.01)


def test_prepared_shapes_copy_and_deepcopy():
    """A shape whose geometry came from a preparation batch copies like any other object."""
    import copy

    shapes = [cs.Convex(np.random.default_rng(k).normal(size=(10, 3))) for k in range(3)]
    w = cs.World(gravity=(0, 0, 0))
    for k, s in enumerate(shapes):
        w.add_body(f"h{k}", s, mass=1.0, position=(3.0 * k, 0, 0))
    w.detect()
    for s in w.shapes:
        d = copy.deepcopy(s)
        c = collide(d, ((0, 0, 0), I), s, ((0.01, 0, 0), I))
        assert len(c) >= 1 and np.all(np.isfinite(c.depth))
        copy.copy(s)


def test_large_hull_pairs_exact_against_brute_force_sat():
    """Hulls of 80 points (round and elongated; above ``PROBE_WORK``, so the edge query bounds
    each edge of A by B's probe points and skips the far side) at separations from 1 cm deep to
    within the margin: the deepest contact's depth equals the brute-force SAT's to 1e-9 relative,
    the normal too where the best axis is unique, and both edge–edge and face contacts occur."""
    from contact_sim.collision import polyhedra
    from contact_sim.collision.manifold import F_EDGE

    rng = np.random.default_rng(5)
    margin = 0.01
    kinds = set()
    for trial in range(10):
        stretch = [1.0, 1.0, 1.0] if trial % 2 == 0 else [3.0, 0.25, 0.25]   # crossed rods: edge–edge
        p = rng.normal(size=(80, 3))
        a = cs.Convex(p / np.linalg.norm(p, axis=1, keepdims=True) * 0.3 * np.array(stretch))
        p = rng.normal(size=(80, 3))
        b = cs.Convex(p / np.linalg.norm(p, axis=1, keepdims=True) * 0.3 * np.array(stretch))
        assert len(a.edges) * len(b.plane_normals) > polyhedra.PROBE_WORK
        qa = Q.normalize(rng.normal(size=4)) if trial % 2 == 0 else Q.from_rotvec([0.0, 0.0, np.pi / 2])
        qb = Q.normalize(rng.normal(size=4)) if trial % 2 == 0 else Q.normalize([0.05, 0.03, 0.0, 1.0])
        d = rng.normal(size=3) if trial % 2 == 0 else np.array([0.05, -0.03, 1.0])
        d /= np.linalg.norm(d)
        target = [-1e-2, -1e-6, 0.0, 1e-6, 5e-3, -3e-3, 2e-3][trial % 7]
        lo, hi = 0.0, 2.0
        for _ in range(26):
            mid = 0.5 * (lo + hi)
            if brute_sat(a, d * mid, qa, b, np.zeros(3), qb)[0] < target:
                lo = mid
            else:
                hi = mid
        pa = d * lo
        sep, nrm = brute_sat(a, pa, qa, b, np.zeros(3), qb)
        c = collide(a, (pa, qa), b, (np.zeros(3), qb), margin=margin)
        assert len(c) > 0, (trial, sep)
        k = int(np.argmax(c.depth))
        assert abs(c.depth[k] + sep) <= 1e-9 * max(abs(sep), 1e-3), (trial, c.depth[k], -sep)
        if sep < -1e-6:
            assert np.linalg.norm(c.normal[k] - nrm) < 1e-6 or abs(c.depth[k] + sep) < 1e-12, trial
        kinds.add("edge" if c.feature[k] == F_EDGE else "face")
    assert kinds == {"edge", "face"}, kinds


@pytest.mark.exact
def test_arc_max_is_the_largest_projection_over_the_arc():
    """``polyhedra._arc_max`` (the edge query's bound) against the arc sampled densely: never
    below any sample (a bound that undershoots would skip an edge pair that matters), and within
    the sampling's error above the largest."""
    from contact_sim.collision import polyhedra

    rng = np.random.default_rng(3)
    for _ in range(300):
        n1 = rng.normal(size=3)
        n1 /= np.linalg.norm(n1)
        n2 = n1 + rng.uniform(0.01, 1.5) * rng.normal(size=3)
        n2 /= np.linalg.norm(n2)
        w = rng.normal(size=3)
        t = np.linspace(0.0, 1.0, 2001)[:, None]
        ang = np.arccos(np.clip(n1 @ n2, -1, 1))
        L = (np.sin((1 - t) * ang) * n1 + np.sin(t * ang) * n2) / np.sin(ang)   # slerp: the arc
        sampled = float((L @ w).max())
        got = polyhedra._arc_max(n1, n2, *w)
        assert got >= sampled - 1e-12
        assert got <= sampled + 1e-5 * np.linalg.norm(w)
