"""Narrow-phase batch kernels, one per shape-type pair, vectorised over pairs.

Every kernel takes the two sides of ``n`` pairs already in world space and a ``margin`` and
returns ``(pair (K,), point (K, 3), normal (K, 3), depth (K,), feature (K,))``: ``pair`` indexes
the batch, ``normal`` is unit from the kernel's B to its A, ``depth = -separation`` (> 0
penetrating; a pair is reported when its separation is <= margin). ``point`` lies half-way
between the two surfaces along the normal, so swapping A and B keeps it.

Polyhedron pairs follow the lecture: (bounding volumes, in the pipeline) → a vertex of one inside
the other (inside every face plane) → an edge of one crossing a face of the other. The separating
axis test (face normals plus the edge×edge axes that are faces of the Minkowski difference,
Gregorius's Gauss-map test) gives the exact separation/depth and normal, and the contact
manifold is the intersection of the reference and incident faces computed with the same two
tests in the face plane: vertices of one polygon inside the other, and edge crossings.
"""
import numpy as np

from ..contacts import FEATURES
from ..vec import cross
from ..vec import dot as _dot

F_VERTEX, F_EDGE, F_FACE, F_SWEPT, F_SPHERE, F_PLANE = (FEATURES.index(n) for n in (
    "vertex_face", "edge_face", "face_face", "swept", "sphere", "plane"))

_EMPTY = (np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64))
TOUCH_TOLERANCE = 1e-9   # × the smaller body's size: a distance this short is touching, its direction noise
# elements of (pairs x edgesA x edgesB) handled at once by the edge-axis stage (memory bound)
EDGE_CHUNK = 300_000


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


class Counters:
    """What the polyhedron stages did (filled in by the kernels, read by ``DetectionStats``)."""

    def __init__(self):
        self.vertex = 0      # pairs settled by a vertex inside the other body
        self.edge_face = 0   # pairs that needed the edge-face test
        self.edge_hits = 0   # of those, pairs where an edge crosses a face


# ------------------------------------------------------------------ primitives
def sphere_plane(ca, ra, nb, db, margin):
    """Sphere A (centres ``(n, 3)``, radii ``(n,)``) against plane B (world unit normal ``(n, 3)``,
    offset ``(n,)``): exactly one contact per reported pair, the true signed distance."""
    sep = _dot(nb, ca) - ra - db
    k = np.flatnonzero(sep <= margin)
    n = nb[k]
    depth = -sep[k]
    point = ca[k] - n * (ra[k] - 0.5 * depth)[:, None]
    return k, point, n, depth, np.full(len(k), F_PLANE)


def sphere_sphere(ca, ra, cb, rb, margin):
    """Sphere A against sphere B, centres ``(n, 3)``, radii ``(n,)``."""
    d = ca - cb
    dist = np.linalg.norm(d, axis=1)
    sep = dist - ra - rb
    k = np.flatnonzero(sep <= margin)
    dist_k = dist[k]
    # concentric spheres: any direction is a valid normal; pick +z deterministically
    n = np.where(dist_k[:, None] > 1e-300, d[k] / np.where(dist_k > 1e-300, dist_k, 1.0)[:, None], [0.0, 0.0, 1.0])
    depth = -sep[k]
    point = cb[k] + n * (rb[k] - 0.5 * depth)[:, None]
    return k, point, n, depth, np.full(len(k), F_SPHERE)


def _sphere_result(sep, normal, cb, rb, margin):
    k = np.flatnonzero(sep <= margin)
    n = normal[k]
    depth = -sep[k]
    point = cb[k] + n * (rb[k] - 0.5 * depth)[:, None]
    return k, point, n, depth, np.full(len(k), F_SPHERE)


def box_sphere(pa, Ra, half, cb, rb, margin):
    """Box A (centre ``(n, 3)``, rotation ``(n, 3, 3)``, half sizes ``(n, 3)``) against sphere B:
    exact distance (clamp the centre into the box); inside, the nearest face."""
    q = np.einsum("nji,nj->ni", Ra, cb - pa)
    c = np.clip(q, -half, half)
    d = q - c
    dist = np.linalg.norm(d, axis=1)
    inside = dist <= 0.0
    gap = half - np.abs(q)
    ax = np.argmin(gap, axis=1)
    rows = np.arange(len(q))
    face = np.zeros_like(q)
    face[rows, ax] = np.where(q[rows, ax] >= 0, 1.0, -1.0)
    out_dir = np.where(inside[:, None], face, d / np.where(dist > 0, dist, 1.0)[:, None])
    sep = np.where(inside, -gap[rows, ax], dist) - rb
    normal = -np.einsum("nij,nj->ni", Ra, out_dir)   # from the sphere towards the box
    return _sphere_result(sep, normal, cb, rb, margin)


def closest_on_triangles(p, a, b, c):
    """Closest points ``(..., 3)`` on triangles ``a, b, c (..., 3)`` to points ``p (..., 3)``
    (Ericson, Real-Time Collision Detection 5.1.5, branch-free)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        den = np.where(den != 0, den, 1.0)
        res = a + ab * (vb / den)[..., None] + ac * (vc / den)[..., None]
        wbc = (d4 - d3) / np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) + (d5 - d6), 1.0)
        res = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[..., None], b + (c - b) * wbc[..., None], res)
        wac = d2 / np.where(d2 - d6 != 0, d2 - d6, 1.0)
        res = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], a + ac * wac[..., None], res)
        res = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, res)
        vab = d1 / np.where(d1 - d3 != 0, d1 - d3, 1.0)
        res = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], a + ab * vab[..., None], res)
        res = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, res)
        res = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, res)
    return res


def _world(tab, rows, pos, R):
    V = np.einsum("nij,nvj->nvi", R, tab.verts[rows]) + pos[:, None, :]
    N = np.einsum("nij,npj->npi", R, tab.plane_n[rows])
    d = tab.plane_d[rows] + np.einsum("npi,ni->np", N, pos)
    return V, N, d


def poly_sphere(tab, rows, pa, Ra, cb, rb, margin, counters=None):
    """Convex polyhedron A (table rows ``(n,)``) against sphere B: exact distance from the centre
    to the triangles outside; inside, the distance to the nearest face plane."""
    V, N, d = _world(tab, rows, pa, Ra)
    tri = tab.tris[rows]                                    # (n, F, 3)
    T = np.take_along_axis(V[:, :, None, :], tri[..., None], axis=1)  # (n, F, 3, 3)
    q = closest_on_triangles(cb[:, None, :], T[:, :, 0], T[:, :, 1], T[:, :, 2])
    dd = np.linalg.norm(q - cb[:, None, :], axis=2)
    j = np.argmin(dd, axis=1)
    rows_n = np.arange(len(rows))
    qbest, dist = q[rows_n, j], dd[rows_n, j]
    plane_sep = _dot(N, cb[:, None, :]) - d                # (n, P)
    pmax = np.argmax(plane_sep, axis=1)
    m = plane_sep[rows_n, pmax]
    inside = m <= 0
    fn = N[rows_n, pmax]
    sep = np.where(inside, m, dist) - rb
    out = (qbest - cb) / np.where(dist > 0, dist, 1.0)[:, None]
    normal = np.where((inside | (dist <= 1e-300))[:, None], -fn, out)
    return _sphere_result(sep, normal, cb, rb, margin)


def mesh_sphere(tab, rows, pa, Ra, cb, rb, margin, closed, counters=None):
    """Triangle mesh A (concave allowed) against sphere B: the nearest triangle; a centre inside a
    closed mesh (odd ray-crossing parity) is penetrating by the distance to the surface."""
    V, _, _ = _world(tab, rows, pa, Ra)
    tri = tab.tris[rows]
    T = np.take_along_axis(V[:, :, None, :], tri[..., None], axis=1)
    q = closest_on_triangles(cb[:, None, :], T[:, :, 0], T[:, :, 1], T[:, :, 2])
    dd = np.linalg.norm(q - cb[:, None, :], axis=2)
    valid_t = np.arange(tri.shape[1])[None, :] < tab.tri_count[rows][:, None]
    dd = np.where(valid_t, dd, np.inf)
    j = np.argmin(dd, axis=1)
    rn = np.arange(len(rows))
    qbest, dist = q[rn, j], dd[rn, j]
    inside = _inside_mesh(cb[:, None, :], T, valid_t, closed, qbest[:, None, :], j[:, None])[:, 0]
    sgn = np.where(inside, -1.0, 1.0)
    sep = sgn * dist - rb
    tn = cross(T[rn, j, 1] - T[rn, j, 0], T[rn, j, 2] - T[rn, j, 0])
    touch_tol = TOUCH_TOLERANCE * np.minimum(tab.scale[rows], rb)
    normal = np.where((dist > touch_tol)[:, None], sgn[:, None] * (qbest - cb) / np.where(dist > 0, dist, 1)[:, None],
                      -_unit(tn))
    return _sphere_result(sep, normal, cb, rb, margin)


# rays for the parity test: generic directions, so a ray through an edge or vertex is rare; when
# one is (a barycentric coordinate or the distance within a tolerance of 0) the next ray decides
_RAYS = _unit(np.array([[0.5773, 0.3141, 0.7537], [-0.2718, 0.8414, -0.4667], [0.6931, -0.6180, 0.3711]]))


def points_in_meshes(p, T, valid_t, eps=1e-9):
    """Odd ray-crossing parity: ``(n,)`` bool, point ``p[i] (3,)`` inside the closed mesh whose
    world triangles are ``T[i] (F, 3, 3)`` (``valid_t (n, F)`` masks padding). Rays that graze an
    edge or vertex are discarded in favour of the next direction."""
    e1 = T[:, :, 1] - T[:, :, 0]
    e2 = T[:, :, 2] - T[:, :, 0]
    s = p[:, None, :] - T[:, :, 0]
    result = np.zeros(len(p), bool)
    decided = np.zeros(len(p), bool)
    votes = np.zeros(len(p), np.int64)
    for r in _RAYS:
        h = cross(r, e2)
        det = _dot(e1, h)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            u = _dot(s, h) * inv
            qv = cross(s, e1)
            v = _dot(qv, r) * inv
            t = _dot(e2, qv) * inv
        scale = np.sqrt(np.abs(det)) + 1e-300
        w = 1.0 - u - v
        hit = valid_t & (np.abs(det) > 1e-14) & (t > 0) & (u >= 0) & (v >= 0) & (w >= 0)
        grazing = valid_t & (np.abs(det) > 1e-14) & (t > -eps) & (
            ((np.abs(u) < eps) | (np.abs(v) < eps) | (np.abs(w) < eps)) & (u > -eps) & (v > -eps) & (w > -eps))
        parallel = valid_t & (np.abs(det) <= 1e-14)
        bad = (grazing | (hit & (np.abs(t) < eps * scale))).any(axis=1) | parallel.any(axis=1) & False
        odd = (hit.sum(axis=1) % 2) == 1
        votes += odd
        take = ~decided & ~bad
        result[take] = odd[take]
        decided |= take
    result[~decided] = votes[~decided] >= 2
    return result


def _inside_mesh(p, T, valid_t, closed, q, j):
    """``(n, K) bool``: points ``p (n, K, 3)`` inside mesh ``n``'s triangles ``T (n, F, 3, 3)``.
    A closed mesh (``closed (n,)``) is a solid: odd ray-crossing parity. An open mesh (a terrain
    tile, a flat floor) has no inside; it is a one-sided surface whose back is below it: a point
    is inside when it lies behind the nearest triangle ``j (n, K)`` (nearest point ``q (n, K, 3)``),
    so a body pressed through a terrain is pushed back out the way it came."""
    n, K = p.shape[:2]
    out = np.zeros((n, K), bool)
    c = np.flatnonzero(closed)
    if c.size:
        out[c] = _parity(p[c], T[c], valid_t[c])
    o = np.flatnonzero(~closed)
    if o.size:
        tt = np.take_along_axis(T[o], j[o][..., None, None], axis=1)              # (o, K, 3, 3)
        tn = cross(tt[..., 1, :] - tt[..., 0, :], tt[..., 2, :] - tt[..., 0, :])
        out[o] = _dot(p[o] - q[o], tn) < 0
    return out


def poly_plane(tab, rows, pa, Ra, nb, db, margin, counters=None):
    """Polyhedron or mesh A against plane B: every vertex within the margin is a contact; a
    resting face keeps at most 4 of them, spanning the patch."""
    V = np.einsum("nij,nvj->nvi", Ra, tab.verts[rows]) + pa[:, None, :]
    valid = np.arange(V.shape[1])[None, :] < tab.vert_count[rows][:, None]
    sep = _dot(V, nb[:, None, :]) - db[:, None]
    keep = valid & (sep <= margin)
    hit = np.flatnonzero(keep.any(axis=1))
    if hit.size == 0:
        return _EMPTY
    keep = keep[hit]
    V, sep, n = V[hit], sep[hit], nb[hit]
    pts = V - 0.5 * sep[..., None] * n[:, None, :]
    keep = reduce_manifold(pts, -sep, keep, n)
    pi, vi = np.nonzero(keep)
    return hit[pi], pts[pi, vi], n[pi], -sep[pi, vi], np.full(len(pi), F_PLANE)


def reduce_manifold(pts, depth, valid, normal):
    """At most 4 of the candidate points ``(n, C, 3)`` per pair: the deepest, the farthest from
    it, the one making the largest triangle, and the one farthest on the other side. ``(n, C)`` bool."""
    n = len(pts)
    rows = np.arange(n)
    keep = np.zeros(valid.shape, bool)
    # the deepest point; among points equally deep to round-off (a face resting flat on a face),
    # the one farthest from the patch's centre, so that a flat patch keeps its corners, not an
    # interior point picked by the noise of the last bit (which left a lopsided support)
    dmax = np.max(np.where(valid, depth, -np.inf), axis=1)
    cnt = np.maximum(valid.sum(axis=1), 1)
    centre = np.where(valid[..., None], pts, 0.0).sum(axis=1) / cnt[:, None]
    rel_c = pts - centre[:, None, :]
    spread = np.where(valid, _dot(rel_c, rel_c), 0.0)
    tol = TOUCH_TOLERANCE * np.sqrt(spread.max(axis=1)) + 1e-300
    flat = valid & (depth >= (dmax - tol)[:, None])
    i0 = np.argmax(np.where(flat, spread, -1.0), axis=1)
    p0 = pts[rows, i0]
    keep[rows, i0] = True
    rel = pts - p0[:, None, :]
    d2 = np.where(valid, _dot(rel, rel), -1.0)
    i1 = np.argmax(d2, axis=1)
    far = d2[rows, i1]
    tiny = 1e-20 + 1e-18 * far
    keep[rows, i1] |= far > tiny
    area = _dot(cross(rel[rows, i1][:, None, :], rel), normal[:, None, :])
    a = np.where(valid, np.abs(area), -1.0)
    i2 = np.argmax(a, axis=1)
    big = a[rows, i2]
    keep[rows, i2] |= big > np.sqrt(far) * 1e-9 * np.sqrt(far) + 1e-20
    side = np.sign(area[rows, i2])
    opp = np.where(valid, -side[:, None] * area, -1.0)
    i3 = np.argmax(opp, axis=1)
    keep[rows, i3] |= opp[rows, i3] > far * 1e-9 + 1e-20
    return keep & valid


# ------------------------------------------------------------------ polyhedron pairs
def poly_poly(ta, ra, pa, Ra, tb, rb, pb, Rb, margin, counters=None):
    """Convex polyhedra A and B (tables and rows ``(n,)``, poses ``(n, 3)``, ``(n, 3, 3)``)."""
    n = len(ra)
    rows = np.arange(n)
    VA, NA, dA = _world(ta, ra, pa, Ra)
    VB, NB, dB = _world(tb, rb, pb, Rb)
    DB = np.einsum("npi,nvi->npv", NB, VA) - dB[:, :, None]   # A's vertices against B's planes
    DA = np.einsum("npi,nvi->npv", NA, VB) - dA[:, :, None]
    # lecture step 2: a vertex inside every face plane of the other body
    vertex_hit = (DB.max(axis=1) < 0).any(axis=1) | (DA.max(axis=1) < 0).any(axis=1)
    minA = DA.min(axis=2)
    fa = np.argmax(minA, axis=1)
    sepA = minA[rows, fa]
    minB = DB.min(axis=2)
    fb = np.argmax(minB, axis=1)
    sepB = minB[rows, fb]
    face_sep = np.maximum(sepA, sepB)
    # tolerances follow the smaller body: a 1 mm box against a 1 km one needs mm-relative round-off, not
    # km-relative (1e-9 of the larger size would be a micrometre, a third of a shallow penetration)
    scale = np.minimum(ta.scale[ra], tb.scale[rb])
    alive = np.flatnonzero(face_sep <= margin)
    if counters is not None:
        counters.vertex += int(vertex_hit.sum())
    if alive.size == 0:
        return _EMPTY
    # lecture step 3 for pairs with no vertex inside: does an edge cross a face?
    need_ef = alive[~vertex_hit[alive]]
    if counters is not None and need_ef.size:
        counters.edge_face += int(need_ef.size)
        hit = edge_face_any(VA[need_ef], ta.edges[ra[need_ef]], NB[need_ef], dB[need_ef], VB[need_ef],
                            tb.loops[rb[need_ef]]) | \
            edge_face_any(VB[need_ef], tb.edges[rb[need_ef]], NA[need_ef], dA[need_ef], VA[need_ef],
                          ta.loops[ra[need_ef]])
        counters.edge_hits += int(hit.sum())
    # separating axis test, edge x edge axes
    esep, ea, eb = _edge_axes(ta, ra[alive], VA[alive], NA[alive], Ra[alive], pa[alive],
                              tb, rb[alive], VB[alive], NB[alive])
    fs = face_sep[alive]
    total = np.maximum(fs, esep)
    use_edge = esep > fs + 1e-9 * scale[alive]
    ok = total <= margin
    out = []
    # edge-edge contacts: the closest points of the two edges
    ke = np.flatnonzero(ok & use_edge)
    if ke.size:
        g = alive[ke]
        a0 = VA[g, ta.edges[ra[g], ea[ke], 0]]
        a1 = VA[g, ta.edges[ra[g], ea[ke], 1]]
        b0 = VB[g, tb.edges[rb[g], eb[ke], 0]]
        b1 = VB[g, tb.edges[rb[g], eb[ke], 1]]
        cp_a, cp_b = _segment_closest(a0, a1, b0, b1)
        nrm = _unit(cross(a1 - a0, b1 - b0))
        ca = np.einsum("nij,nj->ni", Ra[g], ta.centroid[ra[g]]) + pa[g]
        nrm = np.where((_dot(nrm, a0 - ca) < 0)[:, None], -nrm, nrm)   # outward from A
        out.append((g, 0.5 * (cp_a + cp_b), -nrm, -esep[ke], np.full(len(ke), F_EDGE)))
    kf = np.flatnonzero(ok & ~use_edge)
    if kf.size:
        g = alive[kf]
        refA = sepA[g] >= sepB[g]
        for is_a in (True, False):
            sel = g[refA == is_a]
            if sel.size == 0:
                continue
            # the incident body's deepest vertex below the reference face is always a candidate, so
            # the deepest contact of the pair has exactly the SAT depth
            if is_a:
                j = np.argmin(DA[sel, fa[sel], :], axis=1)
                res = _face_contacts(ta, ra[sel], VA[sel], NA[sel], dA[sel], fa[sel],
                                     tb, rb[sel], VB[sel], NB[sel], dB[sel], scale[sel], margin,
                                     VB[sel, j], sepA[sel])
                k, pt, nref, dep, ft = res
                out.append((sel[k], pt, -nref, dep, ft))
            else:
                j = np.argmin(DB[sel, fb[sel], :], axis=1)
                res = _face_contacts(tb, rb[sel], VB[sel], NB[sel], dB[sel], fb[sel],
                                     ta, ra[sel], VA[sel], NA[sel], dA[sel], scale[sel], margin,
                                     VA[sel, j], sepB[sel])
                k, pt, nref, dep, ft = res
                out.append((sel[k], pt, nref, dep, ft))
    if not out:
        return _EMPTY
    return tuple(np.concatenate(parts) for parts in zip(*out))


def _segment_closest(p1, q1, p2, q2):
    """Closest points ``(n, 3)`` of segments ``p1q1`` and ``p2q2`` (Ericson 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    den = a * e - b * b
    s = np.where(den > 1e-300, np.clip((b * f - c * e) / np.where(den > 1e-300, den, 1), 0, 1), 0.0)
    t = (b * s + f) / np.where(e > 0, e, 1)
    t = np.clip(t, 0, 1)
    s = np.clip((b * t - c) / np.where(a > 0, a, 1), 0, 1)
    return p1 + d1 * s[:, None], p2 + d2 * t[:, None]


def _edge_axes(ta, ra, VA, NA, Ra, pa, tb, rb, VB, NB):
    """Best edge x edge separation ``(n,)`` (-inf when no edge pair builds a face of the
    Minkowski difference) and the edge indices ``(n,)`` that give it."""
    n = len(ra)
    best = np.full(n, -np.inf)
    bea = np.zeros(n, np.int64)
    beb = np.zeros(n, np.int64)
    EA, EB = ta.edges.shape[1], tb.edges.shape[1]
    step = max(1, EDGE_CHUNK // max(EA * EB, 1))
    ca_all = np.einsum("nij,nj->ni", Ra, ta.centroid[ra]) + pa
    for s in range(0, n, step):     # loop over chunks of pairs (memory), not over pairs
        sl = slice(s, min(n, s + step))
        m = sl.stop - sl.start
        rr = np.arange(m)[:, None]
        eA, eB = ta.edges[ra[sl]], tb.edges[rb[sl]]
        pA = ta.edge_planes[ra[sl]]
        pB = tb.edge_planes[rb[sl]]
        a1, a2 = NA[sl][rr, pA[..., 0]], NA[sl][rr, pA[..., 1]]
        b1, b2 = NB[sl][rr, pB[..., 0]], NB[sl][rr, pB[..., 1]]
        c, d = -b1, -b2
        bxa = cross(a2, a1)
        dxc = cross(d, c)
        cba = np.einsum("nbi,nai->nab", c, bxa)
        dba = np.einsum("nbi,nai->nab", d, bxa)
        adc = np.einsum("nai,nbi->nab", a1, dxc)
        bdc = np.einsum("nai,nbi->nab", a2, dxc)
        mink = (cba * dba < 0) & (adc * bdc < 0) & (cba * bdc > 0)
        pi, ia, ib = np.nonzero(mink)
        if pi.size == 0:
            continue
        A0 = VA[sl][pi, eA[pi, ia, 0]]
        A1 = VA[sl][pi, eA[pi, ia, 1]]
        B0 = VB[sl][pi, eB[pi, ib, 0]]
        B1 = VB[sl][pi, eB[pi, ib, 1]]
        da, db = A1 - A0, B1 - B0
        axis = cross(da, db)
        length = np.linalg.norm(axis, axis=1)
        good = length > 1e-9 * np.linalg.norm(da, axis=1) * np.linalg.norm(db, axis=1)
        axis = axis / np.where(good, length, 1.0)[:, None]
        axis = np.where((_dot(axis, A0 - ca_all[sl][pi]) < 0)[:, None], -axis, axis)
        sep = np.where(good, _dot(axis, B0 - A0), -np.inf)
        order = np.lexsort((sep, pi))
        last = np.flatnonzero(np.r_[pi[order][1:] != pi[order][:-1], True])
        w = order[last]
        g = pi[w] + sl.start
        best[g] = sep[w]
        bea[g] = ia[w]
        beb[g] = ib[w]
    return best, bea, beb


def edge_face_any(V, edges, N, d, VF, loops, eps=1e-12):
    """Lecture step 3, batched: ``(n,)`` bool, does an edge of one body (world vertices
    ``V (n, Va, 3)``, ``edges (n, E, 2)``) cross a face of the other (planes ``N (n, P, 3)``,
    ``d (n, P)``, face loops ``loops (n, P, M)`` into world vertices ``VF (n, Vb, 3)``)? The
    endpoints must lie on opposite sides of the face plane and the crossing point inside the face."""
    rr = np.arange(len(V))[:, None]
    E0, E1 = V[rr, edges[..., 0]], V[rr, edges[..., 1]]           # (n, E, 3)
    s0 = np.einsum("npi,nei->nep", N, E0) - d[:, None, :]           # (n, E, P)
    s1 = np.einsum("npi,nei->nep", N, E1) - d[:, None, :]
    straddles = (s0 * s1 < 0)
    pi, ei, fi = np.nonzero(straddles)
    if pi.size == 0:
        return np.zeros(len(V), bool)
    t = s0[pi, ei, fi] / (s0[pi, ei, fi] - s1[pi, ei, fi])
    X = E0[pi, ei] + t[:, None] * (E1[pi, ei] - E0[pi, ei])         # (H, 3) on the plane
    loop = VF[pi[:, None], loops[pi, fi]]                          # (H, M, 3)
    nxt = np.roll(loop, -1, axis=1)
    side = cross(nxt - loop, N[pi, fi][:, None, :])            # outward edge normals
    inside = np.all(_dot(side, X[:, None, :] - loop) <= eps, axis=1)
    hit = np.zeros(len(V), bool)
    hit[pi[inside]] = True
    return hit


def _face_contacts(tr, rr_, VR, NR, dR, fr, ti, ri, VI, NI, dI, scale, margin, sup_u, sup_sep):
    """Contact manifold on the reference face ``fr (n,)`` of body R with the most anti-parallel
    face of body I: the intersection of the two face polygons in the reference plane, found with
    the lecture's tests in 2-D (a vertex of one inside the other, edge crossings), keeping the
    points within the margin of the reference plane; at most 4 per pair."""
    n = len(rr_)
    rows = np.arange(n)
    nref = NR[rows, fr]
    dref = dR[rows, fr]
    fi = np.argmin(_dot(NI, nref[:, None, :]), axis=1)
    ni = NI[rows, fi]
    di = dI[rows, fi]
    P = VR[rows[:, None], tr.loops[rr_, fr]]          # (n, M1, 3)
    Q = VI[rows[:, None], ti.loops[ri, fi]]           # (n, M2, 3)
    tol = 1e-9 * scale
    eP = np.roll(P, -1, axis=1) - P
    sP = cross(eP, nref[:, None, :])
    lenP = np.linalg.norm(eP, axis=2)
    eQ = np.roll(Q, -1, axis=1) - Q
    sQ = cross(eQ, ni[:, None, :])
    lenQ = np.linalg.norm(eQ, axis=2)
    # 1. incident vertices inside the reference face prism
    g = np.einsum("nmi,nqi->nqm", sP, Q) - _dot(sP, P)[:, None, :]
    in1 = np.all(g <= (tol[:, None] * lenP)[:, None, :], axis=2)
    u1 = Q
    sep1 = _dot(Q, nref[:, None, :]) - dref[:, None]
    # 2. reference vertices, projected along the normal onto the incident face, inside it
    den = _dot(ni, nref)
    den = np.where(np.abs(den) > 1e-12, den, -1e-12)
    t = (di[:, None] - _dot(P, ni[:, None, :])) / den[:, None]
    S = P + t[..., None] * nref[:, None, :]
    h = np.einsum("nqi,nmi->nmq", sQ, S) - _dot(sQ, Q)[:, None, :]
    in2 = np.all(h <= (tol[:, None] * lenQ)[:, None, :], axis=2)
    u2 = S
    sep2 = t + _dot(P, nref[:, None, :]) - dref[:, None]
    # 3. edge crossings, in the reference plane
    Qp = Q - (_dot(Q, nref[:, None, :]) - dref[:, None])[..., None] * nref[:, None, :]
    eQp = np.roll(Qp, -1, axis=1) - Qp
    nr = nref[:, None, None, :]
    den3 = _dot(cross(eP[:, :, None, :], eQp[:, None, :, :]), nr)       # (n, M1, M2)
    w = Qp[:, None, :, :] - P[:, :, None, :]
    ok3 = np.abs(den3) > 1e-12 * (lenP[:, :, None] * lenQ[:, None, :]) + 1e-300
    dd = np.where(ok3, den3, 1.0)
    alpha = _dot(cross(w, eQp[:, None, :, :]), nr) / dd
    beta = _dot(cross(w, eP[:, :, None, :]), nr) / dd
    in3 = ok3 & (alpha >= 0) & (alpha <= 1) & (beta >= 0) & (beta <= 1)
    u3 = Q[:, None, :, :] + beta[..., None] * eQ[:, None, :, :]
    sep3 = _dot(u3, nr) - dref[:, None, None]
    M1, M2 = P.shape[1], Q.shape[1]
    U = np.concatenate([sup_u[:, None, :], u1, u2, u3.reshape(n, M1 * M2, 3)], axis=1)
    SEP = np.concatenate([sup_sep[:, None], sep1, sep2, sep3.reshape(n, M1 * M2)], axis=1)
    VAL = np.concatenate([np.zeros((n, 1), bool), in1, in2, in3.reshape(n, M1 * M2)], axis=1) & (SEP <= margin)
    # the support point only when the clipped patch misses the deepest penetration (deep overlaps)
    best = np.where(VAL, SEP, np.inf).min(axis=1)
    VAL[:, 0] = best > sup_sep + tol
    pts = U - 0.5 * SEP[..., None] * nref[:, None, :]
    keep = reduce_manifold(pts, -SEP, VAL, nref)
    count = keep.sum(axis=1)
    pi, ci = np.nonzero(keep)
    feat = np.where(count >= 3, F_FACE, np.where(count == 2, F_EDGE, F_VERTEX))[pi]
    return pi, pts[pi, ci], nref[pi], -SEP[pi, ci], feat


def _parity(p, T, valid_t, eps=1e-9):
    """Ray-crossing parity for points ``p (n, K, 3)`` against triangles ``T (n, F, 3, 3)``: (n, K) bool."""
    n, K = p.shape[:2]
    flat = p.reshape(n * K, 3)
    idx = np.repeat(np.arange(n), K)
    return points_in_meshes(flat, T[idx], valid_t[idx], eps).reshape(n, K)


def mesh_poly(tm, rm, pm, Rm, closed, tp, rp, pp, Rp, margin, counters=None):
    """Triangle mesh A (concave allowed) against convex polyhedron B, in the lecture's order:
    mesh vertices inside B (inside every face plane; depth from the nearest face plane), B's
    vertices inside a closed mesh (odd ray-crossing parity; depth = distance to the nearest
    triangle) or within the margin of it, and for pairs with neither an edge of one crossing a face
    of the other (contact at the crossing, depth = the shallower endpoint's distance to the face
    plane: an estimate, not an exact penetration depth)."""
    n = len(rm)
    VM, NM, dM = _world(tm, rm, pm, Rm)
    VP, NP, dP = _world(tp, rp, pp, Rp)
    vm_ok = np.arange(VM.shape[1])[None, :] < tm.vert_count[rm][:, None]
    # (b) mesh vertices against the polyhedron's planes
    D = np.einsum("npi,nvi->nvp", NP, VM) - dP[:, None, :]        # (n, Vm, P)
    pmax = np.argmax(D, axis=2)
    m = np.take_along_axis(D, pmax[..., None], axis=2)[..., 0]      # (n, Vm)
    kb = vm_ok & (m <= margin)
    pi_b, vi_b = np.nonzero(kb)
    nb = NP[pi_b, pmax[pi_b, vi_b]]
    dep_b = -m[pi_b, vi_b]
    pt_b = VM[pi_b, vi_b] + 0.5 * dep_b[:, None] * nb
    # (a) polyhedron vertices against the mesh triangles
    tri = tm.tris[rm]
    T = np.take_along_axis(VM[:, :, None, :], tri[..., None], axis=1)   # (n, F, 3, 3)
    valid_t = np.arange(tri.shape[1])[None, :] < tm.tri_count[rm][:, None]
    vp_ok = np.arange(VP.shape[1])[None, :] < tp.vert_count[rp][:, None]
    q = closest_on_triangles(VP[:, :, None, :], T[:, None, :, 0], T[:, None, :, 1], T[:, None, :, 2])
    dd = np.linalg.norm(q - VP[:, :, None, :], axis=3)
    dd = np.where(valid_t[:, None, :], dd, np.inf)
    j = np.argmin(dd, axis=2)                                        # (n, Vp)
    dist = np.take_along_axis(dd, j[..., None], axis=2)[..., 0]
    qb = np.take_along_axis(q, j[..., None, None], axis=2)[:, :, 0]
    inside = _inside_mesh(VP, T, valid_t, closed, qb, j)
    sep = np.where(inside, -dist, dist)
    ka = vp_ok & (sep <= margin)
    pi_a, vi_a = np.nonzero(ka)
    d_a = dist[pi_a, vi_a]
    dirn = (VP[pi_a, vi_a] - qb[pi_a, vi_a]) / np.where(d_a > 0, d_a, 1)[:, None]
    tt = T[pi_a, j[pi_a, vi_a]]
    tn = _unit(cross(tt[:, 1] - tt[:, 0], tt[:, 2] - tt[:, 0]))
    # a vertex (nearly) on the surface has no direction to the surface: the nearest triangle's
    # normal is the answer there (the direction of a round-off-sized vector is noise)
    touch_tol = TOUCH_TOLERANCE * np.minimum(tm.scale[rm], tp.scale[rp])[pi_a]
    na = np.where((d_a > touch_tol)[:, None], np.where(inside[pi_a, vi_a][:, None], dirn, -dirn), -tn)
    dep_a = -sep[pi_a, vi_a]
    pt_a = VP[pi_a, vi_a] + 0.5 * dep_a[:, None] * na
    found = np.zeros(n, bool)
    found[pi_a] = True
    found[pi_b] = True
    if counters is not None:
        counters.vertex += int(found.sum())
    out = [(pi_b, pt_b, nb, dep_b, np.full(len(pi_b), F_VERTEX)),
           (pi_a, pt_a, na, dep_a, np.full(len(pi_a), F_VERTEX))]
    # (c) edge-face for the pairs no vertex settled
    rest = np.flatnonzero(~found)
    if rest.size:
        if counters is not None:
            counters.edge_face += int(rest.size)
        r = rest
        h1 = edge_face_hits(VP[r], tp.edges[rp[r]], NM[r], dM[r], VM[r], tm.loops[rm[r]])
        h2 = edge_face_hits(VM[r], tm.edges[rm[r]], NP[r], dP[r], VP[r], tp.loops[rp[r]])
        # an edge of B through a face of A: push A along its face normal; and the reverse
        for (hp, X, fn, depth), sgn in ((h1, 1.0), (h2, -1.0)):
            if hp.size:
                out.append((r[hp], X, sgn * fn, depth, np.full(len(hp), F_EDGE)))
        if counters is not None:
            counters.edge_hits += int(np.unique(np.concatenate([h1[0], h2[0]])).size)
    res = tuple(np.concatenate(p) for p in zip(*out))
    if len(res[0]) == 0:
        return _EMPTY
    # at most 4 per pair: keep the deepest points of each pair spread as reduce_manifold does
    return _reduce_rows(*res)


def edge_face_hits(V, edges, N, d, VF, loops, eps=1e-12):
    """Like ``edge_face_any`` but returns every crossing: ``(pair (H,), point (H, 3), face normal
    (H, 3), depth (H,))`` with depth the shallower endpoint's distance to the face plane."""
    rr = np.arange(len(V))[:, None]
    E0, E1 = V[rr, edges[..., 0]], V[rr, edges[..., 1]]
    s0 = np.einsum("npi,nei->nep", N, E0) - d[:, None, :]
    s1 = np.einsum("npi,nei->nep", N, E1) - d[:, None, :]
    pi, ei, fi = np.nonzero(s0 * s1 < 0)
    if pi.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    a, b = s0[pi, ei, fi], s1[pi, ei, fi]
    t = a / (a - b)
    X = E0[pi, ei] + t[:, None] * (E1[pi, ei] - E0[pi, ei])
    loop = VF[pi[:, None], loops[pi, fi]]
    side = cross(np.roll(loop, -1, axis=1) - loop, N[pi, fi][:, None, :])
    inside = np.all(_dot(side, X[:, None, :] - loop) <= eps, axis=1)
    k = np.flatnonzero(inside)
    return pi[k], X[k], N[pi[k], fi[k]], np.minimum(np.abs(a[k]), np.abs(b[k]))


def _reduce_rows(pair, point, normal, depth, feature):
    """Keep at most 4 rows per pair (the deepest, then spread out), rows in any order."""
    order = np.lexsort((-depth, pair))
    pair, point, normal, depth, feature = pair[order], point[order], normal[order], depth[order], feature[order]
    start = np.flatnonzero(np.r_[True, pair[1:] != pair[:-1]])
    counts = np.diff(np.r_[start, len(pair)])
    if counts.max() <= 4:
        return pair, point, normal, depth, feature
    C = int(counts.max())
    g = np.repeat(np.arange(len(start)), counts)
    slot = np.arange(len(pair)) - np.repeat(start, counts)
    pts = np.zeros((len(start), C, 3))
    dep = np.full((len(start), C), -np.inf)
    val = np.zeros((len(start), C), bool)
    pts[g, slot], dep[g, slot], val[g, slot] = point, depth, True
    keep = reduce_manifold(pts, dep, val, normal[start])
    return tuple(x[keep[g, slot]] for x in (pair, point, normal, depth, feature))
