"""Differential tests on thousands of random poses per shape pair (fixed seeds).

References: python-fcl for the collide/no-collide verdict and for distances of pairs with a
sphere or a plane; an independent brute-force separating-axis test written here (every face
normal and every edge x edge axis, plain projections of all vertices) for the penetration depth
and normal of polyhedron pairs, because fcl's EPA depth is only approximate (~1e-3..1e-6).
Each pair of a test is put 100 m from the others in one World and detected with one
``detect_world`` call, so the world pipeline (broad phase, bounding volumes, kernels) is what
is tested.
"""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat as Q
from contact_sim.collision import collide_pairs

fcl = pytest.importorskip("fcl")

BAND = 1e-9


def rand_quat(rng, n):
    return Q.normalize(rng.normal(size=(n, 4)))


def hull(rng, n=32, scale=0.5):
    p = rng.normal(size=(n, 3))
    p = p / np.linalg.norm(p, axis=1, keepdims=True) * rng.uniform(0.5, 1.0, size=(n, 1)) * scale
    c = cs.Convex(p * [1.0, 0.7, 1.3])
    # centred on its centre of mass, so every body of a test shares this one shape object
    return c.translated(-c.mass_properties(1.0)[1])


def fcl_geom(shape):
    if shape.type == "sphere":
        return fcl.Sphere(shape.radius)
    if shape.type == "box":
        return fcl.Box(*shape.size)
    if shape.type == "plane":
        return fcl.Halfspace(shape.normal, shape.offset)
    f = np.asarray(shape.faces)
    flat = np.column_stack([np.full(len(f), 3), f]).ravel()
    return fcl.Convex(np.asarray(shape.vertices, float), len(f), flat)


class Pairs:
    """Pair i is bodies 2i (shape A) and 2i + 1 (shape B), like a world's arrays."""

    def __init__(self, a, b, pos_a, pos_b, quat_a, quat_b):
        n = len(pos_a)
        self.shapes = [a, b] * n
        self.pos = np.empty((2 * n, 3))
        self.pos[0::2], self.pos[1::2] = pos_a, pos_b
        self.quat = np.empty((2 * n, 4))
        self.quat[0::2], self.quat[1::2] = quat_a, quat_b


def run_pairs(shape_a, shape_b, n, seed, spread, margin=10.0):
    """Random poses: A at the origin, B at a random direction and distance; all pairs detected
    in one batch with a big margin, so the separation of every pair comes back."""
    rng = np.random.default_rng(seed)
    qa, qb = rand_quat(rng, n), rand_quat(rng, n)
    d = rng.normal(size=(n, 3))
    d = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(spread[0], spread[1], size=(n, 1))
    w = Pairs(shape_a, shape_b, np.zeros((n, 3)), d, qa, qb)
    pairs = np.column_stack([np.arange(0, 2 * n, 2), np.arange(1, 2 * n, 2)])
    c, _ = collide_pairs(w.shapes, w.pos, w.quat, pairs, margin=margin)
    return w, c


def our_pairs(w, c):
    """Per pair (a = 2i, b = 2i + 1): max depth (-separation) and the normal of the deepest row."""
    m = len(w.shapes) // 2
    depth = np.full(m, -np.inf)
    normal = np.zeros((m, 3))
    i = c.body_a // 2
    order = np.lexsort((c.depth, i))
    last = np.r_[i[order][1:] != i[order][:-1], True]
    k = order[last]
    depth[i[k]] = c.depth[k]
    normal[i[k]] = c.normal[k]
    return depth, normal


def fcl_pairs(w, distances=True):
    m = len(w.shapes) // 2
    hit = np.zeros(m, bool)
    dist = np.full(m, np.nan)
    geoms = [fcl_geom(s) for s in w.shapes[:2]]
    for p in range(m):
        objs = []
        for k in (2 * p, 2 * p + 1):
            R = Q.to_matrix(w.quat[k])
            objs.append(fcl.CollisionObject(geoms[k - 2 * p], fcl.Transform(R, w.pos[k])))
        res = fcl.CollisionResult()
        hit[p] = fcl.collide(objs[0], objs[1], fcl.CollisionRequest(), res) > 0
        if distances and not hit[p]:
            dres = fcl.DistanceResult()
            dist[p] = fcl.distance(objs[0], objs[1], fcl.DistanceRequest(), dres)
    return hit, dist


def sat_reference(w, p):
    """Brute-force SAT of pair p: (separation, normal B->A of the best axis, margin to the next
    best axis of a different direction)."""
    va, vb = [], []
    planes = []
    edges = []
    for k in (2 * p, 2 * p + 1):
        s = w.shapes[k]
        R = Q.to_matrix(w.quat[k])
        v = s.vertices @ R.T + w.pos[k]
        (va if k == 2 * p else vb).append(v)
        planes.append(s.plane_normals @ R.T)
        e = s.vertices[s.edges[:, 1]] - s.vertices[s.edges[:, 0]]
        edges.append(e @ R.T)
    va, vb = va[0], vb[0]
    ex = np.cross(edges[0][:, None, :], edges[1][None, :, :]).reshape(-1, 3)
    ln = np.linalg.norm(ex, axis=1)
    ex = ex[ln > 1e-6] / ln[ln > 1e-6, None]
    axes = np.concatenate([planes[0], planes[1], ex])
    pa, pb = va @ axes.T, vb @ axes.T
    gap_ab = pb.min(axis=0) - pa.max(axis=0)   # B beyond A along +axis
    gap_ba = pa.min(axis=0) - pb.max(axis=0)
    sep = np.maximum(gap_ab, gap_ba)
    normal = np.where((gap_ba >= gap_ab)[:, None], axes, -axes)   # B -> A
    best = int(np.argmax(sep))
    other = np.abs(axes @ axes[best]) < 1 - 1e-9
    runner = sep[other].max() if other.any() else -np.inf
    return sep[best], normal[best], sep[best] - runner


CONVEX_PAIRS = {
    "box_box": (lambda r: cs.Box((1.0, 0.6, 0.3)), lambda r: cs.Box((0.5, 0.8, 0.4)), (0.3, 1.4)),
    "convex_box": (lambda r: hull(r), lambda r: cs.Box((0.5, 0.8, 0.4)), (0.3, 1.4)),
    "convex_convex": (lambda r: hull(r), lambda r: hull(r), (0.3, 1.4)),
}


@pytest.mark.parametrize("name", sorted(CONVEX_PAIRS))
def test_polyhedra_against_fcl_and_sat(name):
    fa, fb, spread = CONVEX_PAIRS[name]
    rng = np.random.default_rng(7)
    a, b = fa(rng), fb(rng)
    n = 1000
    w, c = run_pairs(a, b, n, seed=11, spread=spread)
    depth, normal = our_pairs(w, c)
    assert np.all(np.isfinite(depth))                 # margin 10 reaches every pair
    hit, _ = fcl_pairs(w, distances=False)
    ours = depth >= 0
    clear = np.abs(depth) > BAND
    assert 0.2 < hit.mean() < 0.8                      # both verdicts well represented
    bad = np.flatnonzero(clear & (ours != hit))
    assert bad.size == 0, f"{name}: verdict differs from fcl at pairs {bad[:10]}, depths {depth[bad[:10]]}"
    checked = 0
    for p in np.flatnonzero(depth > BAND):             # penetrating: exact SAT depth and normal
        sep, nrm, gap = sat_reference(w, p)
        assert abs(-sep - depth[p]) < 1e-6, (name, p, -sep, depth[p])
        if gap > 1e-6:
            assert np.linalg.norm(nrm - normal[p]) < 1e-6, (name, p, nrm, normal[p])
            checked += 1
    assert checked > 0.3 * (depth > BAND).sum()
    check_rows(c)


def check_rows(c):
    assert np.all(np.isfinite(c.point)) and np.all(np.isfinite(c.normal)) and np.all(np.isfinite(c.depth))
    assert np.allclose(np.linalg.norm(c.normal, axis=1), 1.0, atol=1e-12)


ROUND_PAIRS = {
    "sphere_sphere": (cs.Sphere(0.4), cs.Sphere(0.3), (0.2, 1.0)),
    "box_sphere": (cs.Box((1.0, 0.6, 0.3)), cs.Sphere(0.3), (0.1, 1.2)),
    "convex_sphere": (None, cs.Sphere(0.3), (0.1, 1.2)),
}


@pytest.mark.parametrize("name", sorted(ROUND_PAIRS))
def test_sphere_pairs_against_fcl(name):
    a, b, spread = ROUND_PAIRS[name]
    if a is None:
        a = hull(np.random.default_rng(3))
    w, c = run_pairs(a, b, 2000, seed=5, spread=spread)
    depth, _ = our_pairs(w, c)
    hit, dist = fcl_pairs(w, distances=a.type != "convex")
    ours = depth >= 0
    clear = np.abs(depth) > BAND
    assert 0.2 < hit.mean() < 0.8
    bad = np.flatnonzero(clear & (ours != hit))
    assert bad.size == 0, f"{name}: verdict differs from fcl at {bad[:10]}"
    # separated: our separation is the true distance. fcl's GJK distance is good to ~1e-3 only for
    # convex hulls, so those are compared with trimesh's exact closest points on the hull instead
    sep = ~hit
    if a.type == "convex":
        import trimesh

        m = trimesh.Trimesh(a.vertices, a.faces)
        ctr = np.einsum("nji,nj->ni", Q.to_matrix(w.quat[0::2]), w.pos[1::2] - w.pos[0::2])
        _, dist, _ = trimesh.proximity.closest_point(m, ctr[sep])
        dist = dist - b.radius
        assert np.allclose(-depth[sep], dist, atol=1e-9), np.abs(-depth[sep] - dist).max()
    else:
        assert np.allclose(-depth[sep], dist[sep], atol=1e-6), np.abs(-depth[sep] - dist[sep]).max()
    check_rows(c)


@pytest.mark.parametrize("shape", ["sphere", "box", "convex"])
def test_plane_pairs_against_fcl(shape):
    a = {"sphere": cs.Sphere(0.3), "box": cs.Box((1.0, 0.6, 0.3)), "convex": hull(np.random.default_rng(4))}[shape]
    plane = cs.Plane((0.2, -0.3, 1.0), 0.1)
    rng = np.random.default_rng(9)
    n = 2000
    qa = rand_quat(rng, n)
    pos = rng.uniform(-1, 1, size=(n, 3))
    pos[:, 2] = rng.uniform(-0.3, 1.0, size=n)
    shapes = [plane] + [a] * n
    P = np.vstack([np.zeros(3), pos])
    q = np.vstack([[0, 0, 0, 1.0], qa])
    pairs = np.column_stack([np.zeros(n, np.int64), np.arange(1, n + 1)])
    c, _ = collide_pairs(shapes, P, q, pairs, margin=10.0)
    i = c.body_b - 1
    depth = np.full(n, -np.inf)
    np.maximum.at(depth, i, c.depth)
    og = fcl.CollisionObject(fcl_geom(plane), fcl.Transform())
    ga = fcl_geom(a)
    hit = np.zeros(n, bool)
    for k in range(n):
        o = fcl.CollisionObject(ga, fcl.Transform(Q.to_matrix(qa[k]), pos[k]))
        hit[k] = fcl.collide(o, og, fcl.CollisionRequest(), fcl.CollisionResult()) > 0
    # exact reference: lowest vertex (or centre - r) against the plane
    nrm = plane.normal
    if shape == "sphere":
        ref = plane.offset - (pos @ nrm - 0.3)
    else:
        v = np.einsum("nij,vj->nvi", Q.to_matrix(qa), a.vertices) + pos[:, None]
        ref = plane.offset - (v @ nrm).min(axis=1)
    assert np.allclose(depth, ref, atol=1e-12)
    clear = np.abs(depth) > BAND
    assert 0.2 < hit.mean() < 0.8
    assert np.all((depth >= 0)[clear] == hit[clear])
    assert np.allclose(c.normal, -nrm)   # from the body (B) to the ground (A)
    counts = np.bincount(i[c.depth >= 0], minlength=n)
    if shape == "sphere":
        assert counts.max() == 1
    assert counts.max() <= 4
    check_rows(c)
