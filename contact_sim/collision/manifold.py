"""Contact manifolds: at most four points per pair, and the face–face patch of two polyhedra.

``reduce4`` keeps every candidate when there are at most four (one of two that coincide), puts the
points inside or touching the other body before those apart, and of more than four keeps the
deepest point, the farthest from it, the one making the largest triangle with those two and the one
farthest on the other side (a flat patch keeps its corners: among points equally deep to round-off
the one farthest from the patch centre is the first pick).
``face_patch`` is the intersection of a reference face and the most anti-parallel face of the other
body, which is what Sutherland–Hodgman clipping of the incident face against the reference face's
side planes produces: incident vertices inside the reference face's prism, reference vertices
inside the incident face (taken onto it along the normal) and the crossings of their edges.

Kernel helpers write rows into the output arrays of a narrow-phase kernel: ``out_i (K, 3)``
(pair, feature, feature id) and ``out_f (K, 7)`` (point (3), normal B→A (3), depth).
"""
import numpy as np

from ..contacts import FEATURES, FID_FACE_A, fid
from ..jit import njit
from .vec3 import dot, dotr, set_row
from ..constants import TOUCH_TOLERANCE, COINCIDE_FRACTION

F_VERTEX, F_EDGE, F_FACE, F_SWEPT, F_SPHERE, F_PLANE = (FEATURES.index(n) for n in (
    "vertex_face", "edge_face", "face_face", "swept", "sphere", "plane"))
# point codes of a face patch (the feature id's last field): what the point is on
CODE_INCIDENT, CODE_CROSSING, CODE_REFERENCE, CODE_SUPPORT = 0, 1 << 18, 2 << 18, 3 << 18


@njit
def reduce4(pts, depth, valid, normal, keep):
    """``keep (C,)`` bool: at most 4 of the ``valid (C,)`` candidates ``pts (C, 3)`` with ``depth (C,)``;
    returns how many. With at most four candidates every one stays (of two that coincide, within
    ``COINCIDE_FRACTION`` of the patch's size, the deeper: a face's corner found both as a vertex
    and as an edge crossing). Of more, the points inside or touching the other body (apart by less
    than ``COINCIDE_FRACTION`` of the patch's size) come before those apart: when more than four
    are, four of them span the patch (``_span4``); when at most four are, they all stay and the apart
    points nearest to touching fill the four. Spanning over every point dropped a corner 15 cm deep
    for one 3 cm apart (a tumbling box, its spring missing), and one of four corners below a plane.
    Inside and touching are one class, and touching is wider than round-off here: a face resting on
    a face, tilted by a few nanoradians, is inside at some corners and apart at others by 1e-10 m,
    and keeping the few inside in place of the patch's corners tipped a resting pyramid of boxes.
    (Scalar arithmetic throughout: a temporary array costs more than the math.)"""
    C = pts.shape[0]
    cnt = 0
    cx, cy, cz = 0.0, 0.0, 0.0
    for i in range(C):
        keep[i] = False
        if valid[i]:
            cnt += 1
            cx, cy, cz = cx + pts[i, 0], cy + pts[i, 1], cz + pts[i, 2]
    if cnt == 0:
        return 0
    cx, cy, cz = cx / cnt, cy / cnt, cz / cnt
    smax = 0.0
    for i in range(C):
        if valid[i]:
            smax = max(smax, (pts[i, 0] - cx) ** 2 + (pts[i, 1] - cy) ** 2 + (pts[i, 2] - cz) ** 2)
    same = COINCIDE_FRACTION * np.sqrt(smax)
    if cnt <= 4:
        return _keep_all(pts, depth, valid, -np.inf, same, keep)
    n = _keep_all(pts, depth, valid, -same, same, keep)   # the distinct points inside or touching
    if n > 4:
        for i in range(C):
            keep[i] = False
        return _span4(pts, depth, valid, -same, normal, keep, cx, cy, cz)
    if n == 0:
        return _span4(pts, depth, valid, -np.inf, normal, keep, cx, cy, cz)
    while n < 4:   # the apart points nearest to touching, deepest first, one of each place
        best, bd = -1, -np.inf
        for i in range(C):
            if valid[i] and not keep[i] and depth[i] <= -same and depth[i] > bd \
                    and _kept_near(pts, keep, i, same) < 0:
                best, bd = i, depth[i]
        if best < 0:
            break
        keep[best] = True
        n += 1
    return n


@njit
def _kept_near(pts, keep, i, tol):
    """The first kept candidate within ``tol`` of candidate ``i`` (−1: none)."""
    for j in range(pts.shape[0]):
        if j != i and keep[j] and (pts[i, 0] - pts[j, 0]) ** 2 + (pts[i, 1] - pts[j, 1]) ** 2 \
                + (pts[i, 2] - pts[j, 2]) ** 2 <= tol * tol:
            return j
    return -1


@njit
def _keep_all(pts, depth, valid, dmin, tol, keep):
    """Keep every valid candidate deeper than ``dmin``, but for one of two within ``tol`` of each
    other (the deeper); returns how many."""
    n = 0
    for i in range(pts.shape[0]):
        if not (valid[i] and depth[i] > dmin):
            continue
        dup = _kept_near(pts, keep, i, tol)
        if dup < 0:
            keep[i] = True
            n += 1
        elif depth[i] > depth[dup]:
            keep[dup], keep[i] = False, True
    return n


@njit
def _span4(pts, depth, valid, dmin, normal, keep, cx, cy, cz):
    """Four of the valid candidates deeper than ``dmin`` that span the patch: the deepest point (among
    points equally deep to round-off, a face resting flat on a face, the one farthest from the
    patch's centre ``c``, so that a flat patch keeps its corners), the farthest from it, the one
    making the largest triangle with those two and the one farthest on the other side. Returns how
    many (fewer where the points are collinear or coincide)."""
    C = pts.shape[0]
    dmax, smax = -np.inf, 0.0
    for i in range(C):
        if valid[i] and depth[i] > dmin:
            dmax = max(dmax, depth[i])
            smax = max(smax, (pts[i, 0] - cx) ** 2 + (pts[i, 1] - cy) ** 2 + (pts[i, 2] - cz) ** 2)
    tol = TOUCH_TOLERANCE * np.sqrt(smax) + 1e-300
    i0, best = 0, -1.0
    for i in range(C):
        if valid[i] and depth[i] > dmin and depth[i] >= dmax - tol:
            sp = (pts[i, 0] - cx) ** 2 + (pts[i, 1] - cy) ** 2 + (pts[i, 2] - cz) ** 2
            if sp > best:
                i0, best = i, sp
    keep[i0] = True
    x0, y0, z0 = pts[i0, 0], pts[i0, 1], pts[i0, 2]
    i1, far = 0, -1.0
    for i in range(C):
        if valid[i] and depth[i] > dmin:
            d2 = (pts[i, 0] - x0) ** 2 + (pts[i, 1] - y0) ** 2 + (pts[i, 2] - z0) ** 2
            if d2 > far:
                i1, far = i, d2
    if far > 1e-20 + 1e-18 * far:
        keep[i1] = True
    ax, ay, az = pts[i1, 0] - x0, pts[i1, 1] - y0, pts[i1, 2] - z0
    i2, big, a2 = 0, -1.0, 0.0
    for i in range(C):
        if valid[i] and depth[i] > dmin:
            rx, ry, rz = pts[i, 0] - x0, pts[i, 1] - y0, pts[i, 2] - z0
            ar = (ay * rz - az * ry) * normal[0] + (az * rx - ax * rz) * normal[1] + (ax * ry - ay * rx) * normal[2]
            if abs(ar) > big:
                i2, big, a2 = i, abs(ar), ar
    if big > np.sqrt(far) * 1e-9 * np.sqrt(far) + 1e-20:
        keep[i2] = True
    side = np.sign(a2)
    i3, opp = 0, -1.0
    for i in range(C):
        if valid[i] and depth[i] > dmin:
            rx, ry, rz = pts[i, 0] - x0, pts[i, 1] - y0, pts[i, 2] - z0
            ar = (ay * rz - az * ry) * normal[0] + (az * rx - ax * rz) * normal[1] + (ax * ry - ay * rx) * normal[2]
            if -side * ar > opp:
                i3, opp = i, -side * ar
    if opp > far * 1e-9 + 1e-20:
        keep[i3] = True
    n = 0
    for i in range(C):
        n += keep[i]
    return n


@njit
def put(out_i, out_f, k, pair, point, normal, depth, feature, feature_id):
    """Write contact row ``k``; returns ``k + 1``."""
    out_i[k, 0], out_i[k, 1], out_i[k, 2] = pair, feature, feature_id
    for j in range(3):
        out_f[k, j] = point[j]
        out_f[k, 3 + j] = normal[j]
    out_f[k, 6] = depth
    return k + 1


@njit
def put3(out_i, out_f, k, pair, px, py, pz, nx, ny, nz, depth, feature, feature_id):
    """``put`` of the point ``(px, py, pz)`` and the normal ``(nx, ny, nz)`` given as numbers (a
    kernel that computes them needs no temporary array per contact); returns ``k + 1``."""
    out_i[k, 0], out_i[k, 1], out_i[k, 2] = pair, feature, feature_id
    out_f[k, 0], out_f[k, 1], out_f[k, 2] = px, py, pz
    out_f[k, 3], out_f[k, 4], out_f[k, 5] = nx, ny, nz
    out_f[k, 6] = depth
    return k + 1


@njit
def _cross_dot(a, b, n):
    """``(a × b)·n``."""
    return (a[1] * b[2] - a[2] * b[1]) * n[0] + (a[2] * b[0] - a[0] * b[2]) * n[1] + (a[0] * b[1] - a[1] * b[0]) * n[2]


@njit
def _edges(P, n, e, s, length):
    """Loop edges ``e[m] = P[m+1] - P[m]``, their outward side normals ``s = e × n`` and lengths."""
    M = P.shape[0]
    for m in range(M):
        for j in range(3):
            e[m, j] = P[(m + 1) % M, j] - P[m, j]
        s[m, 0] = e[m, 1] * n[2] - e[m, 2] * n[1]
        s[m, 1] = e[m, 2] * n[0] - e[m, 0] * n[2]
        s[m, 2] = e[m, 0] * n[1] - e[m, 1] * n[0]
        length[m] = np.sqrt(e[m, 0] ** 2 + e[m, 1] ** 2 + e[m, 2] ** 2)


@njit
def face_patch(VR, NR, dR, fr, loopR, VI, NI, dI, facesI, loopsI, scale, margin, sup_u, sup_sep, sup_v,
               ref_is_a, pair, out_i, out_f, k):
    """Contacts of a face–face patch; returns the new row count.

    Reference body R: world vertices ``VR (Vr, 3)``, planes ``NR (Pr, 3)``, ``dR (Pr,)``, reference
    face ``fr`` with vertex loop ``loopR (M1,)``; incident body I: ``VI``, ``NI``, ``dI``, its face
    rows ``facesI (Pi, 2)`` into ``loopsI``. ``sup_u (3,)``, ``sup_sep``, ``sup_v``: I's deepest
    vertex below the reference plane (a candidate whenever the patch misses the deepest
    penetration, so the pair's deepest contact has exactly the SAT depth). Normals point B→A:
    ``-n_ref`` when the reference body is the kernel's A."""
    nref, dref = NR[fr], dR[fr]
    fi, low = 0, np.inf
    for p in range(NI.shape[0]):
        x = NI[p, 0] * nref[0] + NI[p, 1] * nref[1] + NI[p, 2] * nref[2]
        if x < low:
            fi, low = p, x
    ni, di = NI[fi], dI[fi]
    l0, M2 = facesI[fi, 0], facesI[fi, 1]
    M1 = loopR.shape[0]
    C = 1 + M2 + M1 + M1 * M2
    # the scratch arrays below as row ranges of one block per shape and type: an allocation (or a
    # reshape) costs about as much as the arithmetic of a box's patch, a row range nothing
    G = np.empty((3 * M1 + 5 * M2 + 2 * C, 3))
    P, Q, eP, sP = G[:M1], G[M1:M1 + M2], G[M1 + M2:2 * M1 + M2], G[2 * M1 + M2:3 * M1 + M2]
    o = 3 * M1 + M2
    eQ, sQ, Qp, eQp = G[o:o + M2], G[o + M2:o + 2 * M2], G[o + 2 * M2:o + 3 * M2], G[o + 3 * M2:o + 4 * M2]
    o += 4 * M2
    U, pts = G[o:o + C], G[o + C:o + 2 * C]
    H = np.empty(M1 + M2 + 2 * C)
    lenP, lenQ, SEP, DEP = H[:M1], H[M1:M1 + M2], H[M1 + M2:M1 + M2 + C], H[M1 + M2 + C:]
    flags = np.zeros(2 * C, np.bool_)
    VAL, keep = flags[:C], flags[C:]
    CODE = np.empty(C, np.int64)
    for m in range(M1):
        set_row(P, m, VR[loopR[m]])
    for q in range(M2):
        set_row(Q, q, VI[loopsI[l0 + q]])
    tol = 1e-9 * scale
    _edges(P, nref, eP, sP, lenP)
    _edges(Q, ni, eQ, sQ, lenQ)
    set_row(U, 0, sup_u)
    SEP[0], CODE[0] = sup_sep, CODE_SUPPORT + sup_v
    c = 1
    for q in range(M2):      # 1. incident vertices inside the reference face's prism
        inside = True
        for m in range(M1):
            if dotr(sP, m, Q, q) - dotr(sP, m, P, m) > tol * lenP[m]:
                inside = False
                break
        set_row(U, c, Q[q])
        SEP[c] = Q[q, 0] * nref[0] + Q[q, 1] * nref[1] + Q[q, 2] * nref[2] - dref
        CODE[c] = CODE_INCIDENT + loopsI[l0 + q]
        VAL[c] = inside
        c += 1
    den = dot(ni, nref)
    if not abs(den) > 1e-12:
        den = -1e-12
    for m in range(M1):      # 2. reference vertices, along the normal onto the incident face, inside it
        t = (di - dot(P[m], ni)) / den
        for j in range(3):
            U[c, j] = P[m, j] + t * nref[j]
        inside = True
        for q in range(M2):
            if dotr(sQ, q, U, c) - dotr(sQ, q, Q, q) > tol * lenQ[q]:
                inside = False
                break
        SEP[c], CODE[c] = t + dot(P[m], nref) - dref, CODE_REFERENCE + loopR[m]
        VAL[c] = inside
        c += 1
    for q in range(M2):
        h = dot(Q[q], nref) - dref
        for j in range(3):
            Qp[q, j] = Q[q, j] - h * nref[j]
    for q in range(M2):
        for j in range(3):
            eQp[q, j] = Qp[(q + 1) % M2, j] - Qp[q, j]
    for m in range(M1):      # 3. edge crossings, in the reference plane
        for q in range(M2):
            den3 = _cross_dot(eP[m], eQp[q], nref)
            wx, wy, wz = Qp[q, 0] - P[m, 0], Qp[q, 1] - P[m, 1], Qp[q, 2] - P[m, 2]
            ok = abs(den3) > 1e-12 * (lenP[m] * lenQ[q]) + 1e-300
            dd = den3 if ok else 1.0
            e, f = eQp[q], eP[m]
            alpha = ((wy * e[2] - wz * e[1]) * nref[0] + (wz * e[0] - wx * e[2]) * nref[1]
                     + (wx * e[1] - wy * e[0]) * nref[2]) / dd
            beta = ((wy * f[2] - wz * f[1]) * nref[0] + (wz * f[0] - wx * f[2]) * nref[1]
                    + (wx * f[1] - wy * f[0]) * nref[2]) / dd
            for j in range(3):
                U[c, j] = Q[q, j] + beta * eQ[q, j]
            SEP[c] = U[c, 0] * nref[0] + U[c, 1] * nref[1] + U[c, 2] * nref[2] - dref
            CODE[c] = CODE_CROSSING + (m << 9) + q
            VAL[c] = ok and 0 <= alpha <= 1 and 0 <= beta <= 1
            c += 1
    best = np.inf
    for i in range(1, C):
        VAL[i] = VAL[i] and SEP[i] <= margin
        if VAL[i]:
            best = min(best, SEP[i])
    VAL[0] = best > sup_sep + tol
    for i in range(C):
        DEP[i] = -SEP[i]
        for j in range(3):
            pts[i, j] = U[i, j] - 0.5 * SEP[i] * nref[j]
    n = reduce4(pts, DEP, VAL, nref, keep)
    feat = F_FACE if n >= 3 else (F_EDGE if n == 2 else F_VERTEX)
    normal = -nref if ref_is_a else nref
    kind = FID_FACE_A if ref_is_a else FID_FACE_A + 1
    for i in range(C):
        if keep[i]:
            k = put(out_i, out_f, k, pair, pts[i], normal, DEP[i], feat, fid(kind, fr, fi, CODE[i]))
    return k


@njit
def emit_deepest4(out_i, out_f, k, pair, P, Nn, D, F, I, c):
    """Write the ``c`` candidates ``P (C, 3)``, ``Nn (C, 3)``, ``D``, ``F``, ``I (C,)`` of one pair, or
    when there are more than 4 the deepest 4 spread as ``reduce4`` picks them (in order of
    depth, about the deepest one's normal); returns the next row."""
    if c <= 4:
        for r in range(c):
            k = put(out_i, out_f, k, pair, P[r], Nn[r], D[r], F[r], I[r])
        return k
    order = np.arange(c)
    for r in range(1, c):     # stable insertion sort, deepest first
        o, j = order[r], r - 1
        while j >= 0 and D[order[j]] < D[o]:
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = o
    ps, ds = P[order], D[order]
    keep = np.empty(c, np.bool_)
    reduce4(ps, ds, np.ones(c, np.bool_), Nn[order[0]], keep)
    for r in range(c):
        if keep[r]:
            o = order[r]
            k = put(out_i, out_f, k, pair, P[o], Nn[o], D[o], F[o], I[o])
    return k
