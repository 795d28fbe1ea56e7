"""Bounding volumes: built once in object space, carried by the body pose, tested in batches.

Per shape (``bounds(shape)``, cached on the shape):

- bounding sphere by the lecture's construction (``bounding_sphere``),
- object AABB ``lo, hi (3,)`` — also the OBB once carried by the pose,
- bounding slabs: pairs of parallel planes ``d2 < N·P < d1`` for the shape's slab normals
  (``shape.slab_normals (K, 3)`` if set, else the 7 directions of a 14-DOP),
- the convex hull (for meshes; convex shapes and boxes are their own hull).

Planes are infinite and carry no bounding volume.
"""
from dataclasses import dataclass

import numpy as np

from .. import quat
from ..jit import njit
from .geometry import SF_BOX, SF_RADIUS, SF_SPHERE

# 14-DOP: the three axes and the four cube diagonals
DEFAULT_SLAB_NORMALS = np.array(
    [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, -1, 1], [1, 1, -1], [1, -1, -1]], float)
DEFAULT_SLAB_NORMALS /= np.linalg.norm(DEFAULT_SLAB_NORMALS, axis=1, keepdims=True)


def bounding_sphere(points):
    """Bounding sphere ``(centre (3,), radius)`` of ``points (V, 3)`` as in the lecture.

    1. the min/max pair of points along each axis; 2. the most separated of those three pairs
    is the first sphere (its midpoint the centre); 3. every vertex in turn grows the sphere
    just enough to include it (the new sphere contains the old one, so earlier vertices stay
    inside). Step 3 jumps from one outside vertex to the next with numpy instead of visiting
    each vertex, which gives exactly the sequential result.
    """
    p = np.asarray(points, float)
    lo, hi = p.argmin(axis=0), p.argmax(axis=0)
    spans = np.linalg.norm(p[hi] - p[lo], axis=1)
    k = int(np.argmax(spans))
    c = 0.5 * (p[hi[k]] + p[lo[k]])
    r = 0.5 * spans[k]
    i = 0
    while i < len(p):
        d = np.linalg.norm(p[i:] - c, axis=1)
        out = np.flatnonzero(d > r)
        if out.size == 0:
            break
        j = i + out[0]
        dj = d[out[0]]
        new_r = 0.5 * (r + dj)
        c = c + (new_r - r) / dj * (p[j] - c)
        r = new_r
        i = j + 1
    # round-off guard: contain every vertex exactly as computed
    r = max(r, float(np.linalg.norm(p - c, axis=1).max()))
    return c, r * (1 + 1e-12) + 1e-15


@dataclass
class Bounds:
    """Object-space bounding volumes of one shape."""

    sphere_c: np.ndarray     # (3,)
    sphere_r: float
    lo: np.ndarray           # (3,) object AABB / OBB
    hi: np.ndarray
    slab_n: np.ndarray       # (K, 3) unit
    slab_lo: np.ndarray      # (K,) d2
    slab_hi: np.ndarray      # (K,) d1
    hull_n: np.ndarray       # (P, 3) hull planes, n·x <= d inside (empty for spheres)
    hull_d: np.ndarray       # (P,)


def bounds(shape):
    """Cached ``Bounds`` of a finite shape (sphere, box, convex, mesh)."""
    b = getattr(shape, "_cs_bounds", None)
    if b is not None:
        return b
    slab_n = np.asarray(getattr(shape, "slab_normals", None) if getattr(shape, "slab_normals", None) is not None
                        else DEFAULT_SLAB_NORMALS, float)
    if shape.type == "sphere":
        r = shape.radius
        b = Bounds(np.zeros(3), r, -np.full(3, r), np.full(3, r), slab_n, -np.full(len(slab_n), r),
                   np.full(len(slab_n), r), np.zeros((0, 3)), np.zeros(0))
    else:
        v = shape.vertices
        c, r = bounding_sphere(v)
        proj = v @ slab_n.T
        if shape.type == "mesh":
            hn, hd = hull_planes(v)
        else:
            hn, hd = shape.plane_normals, shape.plane_offsets
        b = Bounds(c, r, v.min(axis=0), v.max(axis=0), slab_n, proj.min(axis=0), proj.max(axis=0), hn, hd)
    shape._cs_bounds = b
    return b


def hull_planes(points):
    """Face planes ``(normals (P, 3), offsets (P,))`` of the convex hull of ``points (V, 3)``,
    ``n·x <= d`` inside (qhull). A flat point set (a terrain tile, a floor mesh) has a hull of zero
    thickness: its two sides and the edges of its 2-D hull, which qhull in 3-D refuses."""
    from scipy.spatial import ConvexHull, QhullError

    p = np.asarray(points, float)
    centre = p.mean(axis=0)
    _, sv, vt = np.linalg.svd(p - centre, full_matrices=False)
    if sv[-1] > 1e-9 * max(sv[0], 1e-300):
        try:
            eq = ConvexHull(p).equations          # n·x + c <= 0 inside
            return eq[:, :3].copy(), -eq[:, 3]
        except QhullError:
            pass
    normal = vt[2]
    u, w = vt[0], vt[1]
    flat = np.column_stack([(p - centre) @ u, (p - centre) @ w])
    eq2 = ConvexHull(flat).equations            # 2-D edges: a·(u, w) + c <= 0 inside
    side = eq2[:, :1] * u + eq2[:, 1:2] * w
    off = -eq2[:, 2] + side @ centre
    h = float(normal @ centre)
    return np.vstack([normal, -normal, side]), np.concatenate([[h, -h], off])


def inside_obb(points, lo, hi, pos, q):
    """Which world ``points (K, 3)`` are inside the OBB (object AABB ``lo, hi (3,)`` carried by the
    pose ``pos (3,)``, ``q (4,)``): inside all six face planes. Returns ``(K,)`` bool."""
    local = quat.rotate(quat.conj(q), np.asarray(points, float) - pos)
    return np.all((local > lo) & (local < hi), axis=1)


def inside_slabs(points, slab_n, slab_lo, slab_hi, pos, q):
    """Which world ``points (K, 3)`` satisfy ``d2 < N·P < d1`` for every slab (object-space
    normals ``slab_n (S, 3)``, ``d2 = slab_lo``, ``d1 = slab_hi``) carried by the pose."""
    local = quat.rotate(quat.conj(q), np.asarray(points, float) - pos)
    d = local @ np.asarray(slab_n).T
    return np.all((d > slab_lo) & (d < slab_hi), axis=1)


# ---------------------------------------------------------------- batch overlap tests (pairs)
def sphere_overlap(ca, ra, cb, rb, margin):
    """``(n,)`` bool: world sphere centres ``(n, 3)`` and radii ``(n,)`` within ``margin``."""
    d = ca - cb
    return np.einsum("ij,ij->i", d, d) <= (ra + rb + margin) ** 2


def obb_overlap(ca, Ra, ha, cb, Rb, hb, margin):
    """``(n,)`` bool: OBBs (centres ``(n, 3)``, rotations ``(n, 3, 3)`` (columns are the box axes),
    half sizes ``(n, 3)``) overlap within ``margin``; the 15-axis separating-axis test."""
    t = np.einsum("nji,nj->ni", Ra, cb - ca)               # B's centre in A's frame
    C = np.einsum("nki,nkj->nij", Ra, Rb)                  # A axes · B axes
    absC = np.abs(C) + 1e-12
    ok = np.all(np.abs(t) <= ha + np.einsum("nij,nj->ni", absC, hb) + margin, axis=1)
    tb = np.einsum("nij,ni->nj", C, t)
    ok &= np.all(np.abs(tb) <= hb + np.einsum("nij,ni->nj", absC, ha) + margin, axis=1)
    # edge-edge axes A_i x B_j
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            ra = ha[:, i1] * absC[:, i2, j] + ha[:, i2] * absC[:, i1, j]
            rb = hb[:, j1] * absC[:, i, j2] + hb[:, j2] * absC[:, i, j1]
            dist = np.abs(t[:, i2] * C[:, i1, j] - t[:, i1] * C[:, i2, j])
            # the axis is not unit; scale the margin by its length
            length = np.sqrt(np.maximum(1.0 - C[:, i, j] ** 2, 0.0))
            ok &= dist <= ra + rb + margin * length
    return ok


def slab_overlap(sn_a, lo_a, hi_a, pa, Ra, cb, Rb, hb, margin):
    """``(n,)`` bool: B's OBB (world centre ``cb``, rotation ``Rb``, half sizes ``hb``) meets
    A's slabs (object normals ``sn_a (n, K, 3)``, ``lo_a, hi_a (n, K)``) carried by ``pa, Ra``."""
    nw = np.einsum("nij,nkj->nki", Ra, sn_a)
    off = np.einsum("nki,ni->nk", nw, pa)
    centre = np.einsum("nki,ni->nk", nw, cb)
    ext = np.einsum("nkj,nj->nk", np.abs(np.einsum("nki,nij->nkj", nw, Rb)), hb)
    return np.all((centre + ext >= lo_a + off - margin) & (centre - ext <= hi_a + off + margin), axis=1)


# ---------------------------------------------------------------- compiled pair filter (auto/sphere/obb)
@njit
def bv_filter(use_sphere, use_obb, a, b, shape_of, sf, pos, R, margin, keep):
    """``keep (K,)``: pairs ``a, b`` whose bounding spheres (``use_sphere``) and OBBs (``use_obb``)
    overlap within ``margin``; the same tests as ``sphere_overlap`` and ``obb_overlap``, one pass.
    Planes and sphere–sphere pairs are always kept (a sphere is its own bounding sphere)."""
    # the OBB test's workspace, one block for all pairs: B's centre from A's (world, then in A's
    # frame), A's axes · B's axes and their absolute values
    work = np.empty((8, 3))
    dc, t, C, absC = work[0], work[1], work[2:5], work[5:8]
    for k in range(a.shape[0]):
        sa, sb = shape_of[a[k]], shape_of[b[k]]
        ok = True
        if sf[sb, SF_SPHERE + 3] == 0.0 or (sf[sa, SF_RADIUS] > 0 and sf[sb, SF_RADIUS] > 0):
            keep[k] = True   # a plane (no bounding volume), or two spheres
            continue
        Ra, Rb = R[a[k]], R[b[k]]
        if use_sphere:
            d2 = 0.0
            for i in range(3):
                ca = pos[a[k], i] + Ra[i, 0] * sf[sa, SF_SPHERE] + Ra[i, 1] * sf[sa, SF_SPHERE + 1] \
                    + Ra[i, 2] * sf[sa, SF_SPHERE + 2]
                cb = pos[b[k], i] + Rb[i, 0] * sf[sb, SF_SPHERE] + Rb[i, 1] * sf[sb, SF_SPHERE + 1] \
                    + Rb[i, 2] * sf[sb, SF_SPHERE + 2]
                d2 += (ca - cb) ** 2
            ok = d2 <= (sf[sa, SF_SPHERE + 3] + sf[sb, SF_SPHERE + 3] + margin) ** 2
        if ok and use_obb:
            ha, hb = sf[sa, SF_BOX + 3:SF_BOX + 6], sf[sb, SF_BOX + 3:SF_BOX + 6]
            for i in range(3):
                dc[i] = (pos[b[k], i] + Rb[i, 0] * sf[sb, SF_BOX] + Rb[i, 1] * sf[sb, SF_BOX + 1]
                         + Rb[i, 2] * sf[sb, SF_BOX + 2]) - (pos[a[k], i] + Ra[i, 0] * sf[sa, SF_BOX]
                                                             + Ra[i, 1] * sf[sa, SF_BOX + 1] + Ra[i, 2] * sf[sa, SF_BOX + 2])
            for i in range(3):
                t[i] = Ra[0, i] * dc[0] + Ra[1, i] * dc[1] + Ra[2, i] * dc[2]
            for i in range(3):
                for j in range(3):
                    C[i, j] = Ra[0, i] * Rb[0, j] + Ra[1, i] * Rb[1, j] + Ra[2, i] * Rb[2, j]
                    absC[i, j] = abs(C[i, j]) + 1e-12
            for i in range(3):
                ok = ok and abs(t[i]) <= ha[i] + (absC[i, 0] * hb[0] + absC[i, 1] * hb[1] + absC[i, 2] * hb[2]) + margin
            for j in range(3):
                tb = C[0, j] * t[0] + C[1, j] * t[1] + C[2, j] * t[2]
                ok = ok and abs(tb) <= hb[j] + (absC[0, j] * ha[0] + absC[1, j] * ha[1] + absC[2, j] * ha[2]) + margin
            for i in range(3):
                i1, i2 = (i + 1) % 3, (i + 2) % 3
                for j in range(3):
                    j1, j2 = (j + 1) % 3, (j + 2) % 3
                    ra = ha[i1] * absC[i2, j] + ha[i2] * absC[i1, j]
                    rb = hb[j1] * absC[i, j2] + hb[j2] * absC[i, j1]
                    dist = abs(t[i2] * C[i1, j] - t[i1] * C[i2, j])
                    ok = ok and dist <= ra + rb + margin * np.sqrt(max(1.0 - C[i, j] ** 2, 0.0))
        keep[k] = ok


@njit
def kept_pairs(ia, ib, rank, use_sphere, use_obb, shape_of, sf, pos, R, margin):
    """The bounding-volume stage of a batch of pairs ``ia, ib (K,)`` in one pass: each pair in the
    narrow phase's order (A of the higher rank, ``swap (K,)`` where that flips it), then
    ``bv_filter``. Returns ``(swap (K,), kk (M,), a (M,), b (M,))``: the kept pairs' batch indices
    and their bodies in that order."""
    K = ia.shape[0]
    flags = np.empty((2, K), np.bool_)     # swap, and the filter's keep
    swap, keep = flags[0], flags[1]
    ints = np.empty((3, K), np.int64)      # a, b (all pairs, then the kept ones first), kk
    a, b, kk = ints[0], ints[1], ints[2]
    for k in range(K):
        swap[k] = rank[ia[k]] < rank[ib[k]]
        a[k], b[k] = (ib[k], ia[k]) if swap[k] else (ia[k], ib[k])
    bv_filter(use_sphere, use_obb, a, b, shape_of, sf, pos, R, margin, keep)
    m = 0
    for k in range(K):   # the kept pairs to the front, in order (m <= k: nothing unread is overwritten)
        if keep[k]:
            kk[m], a[m], b[m] = k, a[k], b[k]
            m += 1
    return swap, kk[:m], a[:m], b[:m]
