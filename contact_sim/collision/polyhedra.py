"""Convex polyhedron pairs (box–box, convex–box, convex–convex): the separating-axis test with
Gauss-map pruning, and the contact manifold.

Per pair, in the lecture's order and cheapest first:

1. face axes: for each face plane of A the deepest vertex of B (and the reverse); a face
   separating by more than the margin ends the pair. A vertex of one inside every face plane of
   the other is the lecture's vertex test (counted in ``counters[0]``);
2. edge axes, only for edge pairs whose arcs cross on the Gauss map (the pairs that build a face
   of the Minkowski difference: Gregorius, GDC 2013; MJX ``_arcs_intersect``). For an edge of A the
   side of its arc's great circle is computed once per face normal of B, so an edge of B is
   rejected by two look-ups; the survivors (a few percent) get the other arc's test and the axis;
3. for pairs that touch with no vertex inside, the lecture's edge–face test (an edge of one
   crossing a face polygon of the other), for the statistics (a pair that an axis separates,
   within the margin, has no crossing: it is counted without the test);
4. the deepest axis decides: an edge axis gives one contact at the closest points of the two
   edges; a face axis gives the face–face patch (``manifold.face_patch``, at most 4 points).

The SAT is exact (every candidate axis of the brute-force test that can be a separating or
minimum-penetration axis is tried), so depth and normal equal the brute-force SAT's; GJK + EPA
was not used because EPA's depth is approximate (FCL's is good to ~1e-3..1e-6), and the face
axes, which settle most pairs, are as cheap as a GJK iteration.
"""
import numpy as np

from ..contacts import FID_EDGE, fid
from ..jit import njit
from .inside import outside_plane
from .geometry import BOX, SF_CENTROID, SF_HALF, SF_SCALE, SI_E0, SI_NE, SI_NP, SI_NV, SI_P0, SI_RANK, SI_V0
from .manifold import F_EDGE, face_patch, put
from .vec3 import col_max, cross, dot, dotr, edge_through_face, norm, transform_rows
from ..constants import PROBE_WORK


@njit
def world_poly(verts, planes, si, s, p, R, V, N, d):
    """World vertices ``V[:nv]``, plane normals ``N[:np]`` and offsets ``d[:np]`` of shape ``s``."""
    v0, p0 = si[s, SI_V0], si[s, SI_P0]
    transform_rows(verts[v0:v0 + si[s, SI_NV]], p, R, V, si[s, SI_NV])
    for q in range(si[s, SI_NP]):
        x, y, z = planes[p0 + q, 0], planes[p0 + q, 1], planes[p0 + q, 2]
        for i in range(3):
            N[q, i] = R[i, 0] * x + R[i, 1] * y + R[i, 2] * z
        d[q] = planes[p0 + q, 3] + N[q, 0] * p[0] + N[q, 1] * p[1] + N[q, 2] * p[2]


@njit
def face_query(N, d, npl, V, nv, margin):
    """Best face axis of the body with planes ``N, d`` against vertices ``V``: ``(separation, face,
    any vertex inside every plane)``; once a face separates by more than ``margin`` that face is
    returned at once (the pair is apart, nothing else is read).

    Each face's scan starts at the vertex deepest below the previous face (neighbouring faces
    share their deepest vertices) and stops as soon as a vertex is at or below the best face's
    separation, since that face can no longer win: the result is the full scan's, and a large hull
    costs about one vertex per face instead of all of them (two 1000-point hulls: 3 ms → far less)."""
    best, face = -np.inf, 0
    start = 0
    for p in range(npl):
        m = np.inf
        for t in range(nv):
            v = start + t
            if v >= nv:
                v -= nv
            x = dotr(N, p, V, v) - d[p]
            if x < m:
                m = x
                if m <= best:
                    start = v
                    break
        if m > best:
            best, face = m, p
            if best > margin:
                return best, face, False
    inside = False
    if best < 0:   # the lecture's vertex test: a vertex of the other inside every face plane
        last = 0
        for v in range(nv):
            last = outside_plane(N, d, npl, V, v, last)
            if last < 0:
                inside = True
                break
    return best, face, inside


@njit
def _arc_max(n1, n2, wx, wy, wz):
    """Largest ``L·w`` over the unit normals ``L`` on the great-circle arc from ``n1`` to ``n2``
    (an edge's normals on the Gauss map, less than π apart): at an end, or where the arc meets
    ``w``'s projection on the arcs' plane."""
    w1 = n1[0] * wx + n1[1] * wy + n1[2] * wz
    w2 = n2[0] * wx + n2[1] * wy + n2[2] * wz
    best = max(w1, w2)
    c = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]
    det = 1.0 - c * c
    if det > 1e-12:
        al, be = (w1 - c * w2) / det, (w2 - c * w1) / det
        if al > 0.0 and be > 0.0:
            best = max(best, np.sqrt(max(al * w1 + be * w2, 0.0)))
    return best


@njit
def edge_query(VA, NA, EA, ea_n, cA, VB, NB, EB, eb_n, npb, margin, side, NBt, eb2, eb3, probe, floor):
    """Best edge×edge separation over the edge pairs that build a face of the Minkowski difference
    (Gauss-map arcs crossing), ``(separation, edge of A, edge of B)``; stops early once an axis
    separates by more than ``margin``. Edges ``E* (E, 4)`` hold local vertex and plane indices.
    Scratch: ``side (P,)``, B's normals transposed ``NBt (3, P)`` (so the side loop is one SIMD
    sweep) and B's edge planes ``eb2, eb3 (E,)`` as contiguous columns.

    Only the pairs separated by more than ``floor`` matter to the caller (the face axes' best,
    less a tolerance). An edge of A whose axis ``L`` lies on its arc has A's support there, and B's
    support along ``L`` is below any point of B, so every pair of that edge separates by at most
    ``max over the arc of L·(b − a0)`` for each of B's points ``probe (k, 3)``; an edge whose bound
    is below ``floor`` is skipped without the sweep over B (the far side of a large hull: two
    1000-point hulls touching, 35 ms → about a millisecond). The result is the full query's
    whenever the best pair separates by ``floor`` or more, and otherwise below ``floor`` too."""
    best, bea, beb = -np.inf, 0, 0
    for p in range(npb):
        NBt[0, p], NBt[1, p], NBt[2, p] = NB[p, 0], NB[p, 1], NB[p, 2]
    for j in range(eb_n):
        eb2[j], eb3[j] = EB[j, 2], EB[j, 3]
    cx, cy, cz = cA[0], cA[1], cA[2]
    for i in range(ea_n):
        i0, i1, q1, q2 = EA[i, 0], EA[i, 1], EA[i, 2], EA[i, 3]
        a1x, a1y, a1z = NA[q1, 0], NA[q1, 1], NA[q1, 2]
        a2x, a2y, a2z = NA[q2, 0], NA[q2, 1], NA[q2, 2]
        # b × a: the arc's great-circle normal (A's edge direction on the Gauss map)
        bx = a2y * a1z - a2z * a1y
        by = a2z * a1x - a2x * a1z
        bz = a2x * a1y - a2y * a1x
        if probe.shape[0]:
            i0v = EA[i, 0]
            bound = np.inf
            for k in range(probe.shape[0]):
                bound = min(bound, _arc_max(NA[q1], NA[q2], probe[k, 0] - VA[i0v, 0], probe[k, 1] - VA[i0v, 1],
                                            probe[k, 2] - VA[i0v, 2]))
            if bound < floor:
                continue
        for p in range(npb):          # which side of that great circle each of B's normals lies
            side[p] = NBt[0, p] * bx + NBt[1, p] * by + NBt[2, p] * bz
        A0x, A0y, A0z = VA[i0, 0], VA[i0, 1], VA[i0, 2]
        dax, day, daz = VA[i1, 0] - A0x, VA[i1, 1] - A0y, VA[i1, 2] - A0z
        la = -1.0
        for j in range(eb_n):
            cba, dba = -side[eb2[j]], -side[eb3[j]]
            if not cba * dba < 0:
                continue
            c, d = eb2[j], eb3[j]
            # (-d) × (-c) = d × c
            xx = NB[d, 1] * NB[c, 2] - NB[d, 2] * NB[c, 1]
            xy = NB[d, 2] * NB[c, 0] - NB[d, 0] * NB[c, 2]
            xz = NB[d, 0] * NB[c, 1] - NB[d, 1] * NB[c, 0]
            adc = a1x * xx + a1y * xy + a1z * xz
            bdc = a2x * xx + a2y * xy + a2z * xz
            if not (adc * bdc < 0 and cba * bdc > 0):
                continue
            j0, j1 = EB[j, 0], EB[j, 1]
            B0x, B0y, B0z = VB[j0, 0], VB[j0, 1], VB[j0, 2]
            dbx, dby, dbz = VB[j1, 0] - B0x, VB[j1, 1] - B0y, VB[j1, 2] - B0z
            ax = day * dbz - daz * dby
            ay = daz * dbx - dax * dbz
            az = dax * dby - day * dbx
            length = np.sqrt(ax * ax + ay * ay + az * az)
            if la < 0:
                la = np.sqrt(dax * dax + day * day + daz * daz)
            if not length > 1e-9 * la * np.sqrt(dbx * dbx + dby * dby + dbz * dbz):
                sep = -np.inf
            else:
                ax, ay, az = ax / length, ay / length, az / length
                if ax * (A0x - cx) + ay * (A0y - cy) + az * (A0z - cz) < 0:
                    ax, ay, az = -ax, -ay, -az
                sep = ax * (B0x - A0x) + ay * (B0y - A0y) + az * (B0z - A0z)
            if sep >= best:
                best, bea, beb = sep, i, j
                if sep > margin:
                    return best, bea, beb
    return best, bea, beb


@njit
def edge_crosses_face(VX, EX, ne, NY, dY, npl, faces, loops, VY, eps=1e-12):
    """The lecture's edge–face test: does an edge of X cross a face polygon of Y?"""
    for e in range(ne):
        i0, i1 = EX[e, 0], EX[e, 1]
        for p in range(npl):
            if edge_through_face(VX, i0, i1, NY, dY, p, VY, loops, faces[p, 0], faces[p, 1], eps)[0]:
                return True
    return False


@njit
def segment_closest(p1, q1, p2, q2):
    """Closest points of segments ``p1 q1`` and ``p2 q2`` (Ericson 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = dot(d1, d1), dot(d2, d2), dot(d2, r)
    c, b = dot(d1, r), dot(d1, d2)
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-300 else 0.0
    t = (b * s + f) / (e if e > 0 else 1.0)
    t = min(max(t, 0.0), 1.0)
    s = min(max((b * t - c) / (a if a > 0 else 1.0), 0.0), 1.0)
    return p1 + d1 * s, p2 + d2 * t


@njit
def _probes(V, nv, toward, out, use):
    """Points of a body (vertices ``V[:nv]``) for ``edge_query``'s bound: its support vertices along
    ±x, ±y, ±z and towards the point ``toward`` and away (``out[:8]``), or none (``out[:0]``)
    when ``use`` is false."""
    if not use:
        return out[:0]
    cx, cy, cz = 0.0, 0.0, 0.0
    for v in range(nv):
        cx += V[v, 0]
        cy += V[v, 1]
        cz += V[v, 2]
    ux, uy, uz = toward[0] - cx / nv, toward[1] - cy / nv, toward[2] - cz / nv
    for k in range(8):
        if k < 6:
            dx, dy, dz = (1.0 if k == 0 else -1.0 if k == 1 else 0.0), (1.0 if k == 2 else -1.0 if k == 3 else 0.0), \
                (1.0 if k == 4 else -1.0 if k == 5 else 0.0)
        else:
            sg = 1.0 if k == 6 else -1.0
            dx, dy, dz = sg * ux, sg * uy, sg * uz
        best, j = -np.inf, 0
        for v in range(nv):
            x = V[v, 0] * dx + V[v, 1] * dy + V[v, 2] * dz
            if x > best:
                best, j = x, v
        out[k, 0], out[k, 1], out[k, 2] = V[j, 0], V[j, 1], V[j, 2]
    return out[:8]


@njit
def centroid(sf, s, p, R, out):
    """``out (3,)``: the centroid of shape ``s`` carried by ``p (3,)``, ``R (3, 3)`` (``R c + p``,
    into the caller's buffer)."""
    for i in range(3):
        out[i] = (R[i, 0] * sf[s, SF_CENTROID] + R[i, 1] * sf[s, SF_CENTROID + 1] + R[i, 2] * sf[s, SF_CENTROID + 2]) \
            + p[i]


@njit
def _box_edges_below(sf, sa, sb, pa, pb, Ra, Rb, limit):
    """Whether boxes ``sa`` and ``sb`` (centres ``pa, pb``, axes the columns of ``Ra, Rb``, half
    sizes ``sf[:, SF_HALF:]``) separate by at most ``limit`` (m) along every cross product of their
    edge directions: then ``edge_query``, which takes the separation along some of those axes (the
    edge pairs that build a face of the Minkowski difference), returns at most that too, and the
    pair's contact is the face contact whatever it would find (the separating-axis test of two boxes
    over their 9 edge axes, as MuJoCo's and ODE's box–box, instead of 12 × 12 edge pairs).

    Exact, not approximate: the bound is lowered by the round-off both computations can carry
    (16 ulps of the largest coordinate or size involved, times the boxes' elongation: ``edge_query``
    takes its axis from the world vertices' differences, whose direction carries their coordinates'
    round-off over the shortest edge), parallel directions (``|a × b| < 1e-12``) are no axis here as
    in ``edge_query``, and nearly parallel ones (below 1e-3), whose axis ``edge_query`` takes with
    round-off this one does not share, answer False (undecided: the query runs)."""
    ha, hb = sf[sa, SF_HALF:SF_HALF + 3], sf[sb, SF_HALF:SF_HALF + 3]
    dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
    extent = sf[sa, SF_SCALE] + sf[sb, SF_SCALE]
    size = max(abs(pa[0]), abs(pa[1]), abs(pa[2])) + max(abs(pb[0]), abs(pb[1]), abs(pb[2])) + extent
    shortest = 2.0 * min(ha[0], ha[1], ha[2], hb[0], hb[1], hb[2])
    limit = limit - 16.0 * 2.220446049250313e-16 * size * (1.0 + extent / shortest)
    for i in range(3):
        ax, ay, az = Ra[0, i], Ra[1, i], Ra[2, i]
        for j in range(3):
            bx, by, bz = Rb[0, j], Rb[1, j], Rb[2, j]
            lx, ly, lz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            ln = np.sqrt(lx * lx + ly * ly + lz * lz)
            if ln < 1e-12:
                continue
            if ln < 1e-3:
                return False
            lx, ly, lz = lx / ln, ly / ln, lz / ln
            sep = abs(dx * lx + dy * ly + dz * lz)
            for k in range(3):
                sep -= ha[k] * abs(Ra[0, k] * lx + Ra[1, k] * ly + Ra[2, k] * lz)
                sep -= hb[k] * abs(Rb[0, k] * lx + Rb[1, k] * ly + Rb[2, k] * lz)
            if sep > limit:
                return False
    return True


@njit
def poly_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
              out_i, out_f):
    """Convex polyhedra A and B: SAT with Gauss-map pruning, then the edge or face contacts."""
    nv, npl, ne = col_max(si, SI_NV, shape_of, a, b), col_max(si, SI_NP, shape_of, a, b), col_max(si, SI_NE, shape_of, a, b)
    # scratch as row ranges of a few blocks (an allocation, or a reshape, costs about what a box's
    # face axes do; a row range is free)
    G = np.empty((2 * nv + 2 * npl + 8, 3))
    VA, VB, NA, NB = G[:nv], G[nv:2 * nv], G[2 * nv:2 * nv + npl], G[2 * nv + npl:2 * nv + 2 * npl]
    probe_all = G[2 * nv + 2 * npl:]
    H = np.empty(3 * npl)
    dA, dB, side = H[:npl], H[npl:2 * npl], H[2 * npl:]
    NBt = np.empty((3, npl))
    eb = np.empty(2 * ne, np.int64)
    eb2, eb3 = eb[:ne], eb[ne:]
    cAB = np.empty((2, 3))   # the world centroids of A and B
    cA, cB = cAB[0], cAB[1]
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        Ra, Rb, pa, pb = R[a[i]], R[b[i]], pos[a[i]], pos[b[i]]
        world_poly(verts, planes, si, sa, pa, Ra, VA, NA, dA)
        world_poly(verts, planes, si, sb, pb, Rb, VB, NB, dB)
        nva, npa, nvb, npb = si[sa, SI_NV], si[sa, SI_NP], si[sb, SI_NV], si[sb, SI_NP]
        sepA, fa, inA = face_query(NA, dA, npa, VB, nvb, margin)
        if sepA > margin:
            continue
        sepB, fb, inB = face_query(NB, dB, npb, VA, nva, margin)
        if sepB > margin:
            continue
        face_sep = max(sepA, sepB)
        vertex_hit = inA or inB
        counters[0] += vertex_hit
        # tolerances follow the smaller body: a 1 mm box against a 1 km one needs mm-relative
        # round-off (1e-9 of the larger size would be a micrometre, a third of a shallow penetration)
        scale = min(sf[sa, SF_SCALE], sf[sb, SF_SCALE])
        centroid(sf, sa, pa, Ra, cA)
        EA = edges[si[sa, SI_E0]:si[sa, SI_E0] + si[sa, SI_NE]]
        EB = edges[si[sb, SI_E0]:si[sb, SI_E0] + si[sb, SI_NE]]
        fA = faces[si[sa, SI_P0]:si[sa, SI_P0] + npa]
        fB = faces[si[sb, SI_P0]:si[sb, SI_P0] + npb]
        # the Gauss-map test is symmetric in the two bodies: loop over the body with fewer edges
        # outside (each outer edge costs a sweep over the other body's normals)
        centroid(sf, sb, pb, Rb, cB)
        # edge pairs that cannot beat the face axes (by more than round-off) change nothing below
        floor = face_sep - 1e-9 * scale
        if counters.shape[0] == 2 and si[sa, SI_RANK] == BOX and si[sb, SI_RANK] == BOX and _box_edges_below(
                sf, sa, sb, pa, pb, Ra, Rb, min(face_sep + 1e-9 * scale, margin)):
            # two boxes whose edge axes cannot beat their face axes: the face contact below
            esep, ea, eb = -np.inf, 0, 0
        elif EB.shape[0] < EA.shape[0]:
            probe = _probes(VA, nva, cB, probe_all, EB.shape[0] * npa > PROBE_WORK)
            esep, eb, ea = edge_query(VB, NB, EB, EB.shape[0], cB, VA, NA, EA, EA.shape[0], npa, margin, side, NBt,
                                      eb2, eb3, probe, floor)
        else:
            probe = _probes(VB, nvb, cA, probe_all, EA.shape[0] * npb > PROBE_WORK)
            esep, ea, eb = edge_query(VA, NA, EA, EA.shape[0], cA, VB, NB, EB, EB.shape[0], npb, margin, side, NBt,
                                      eb2, eb3, probe, floor)
        if not vertex_hit:   # the lecture's step 3, for the statistics: an edge through a face
            counters[1] += 1
            # a separating axis (within the margin) means no edge can cross a face: the test (every
            # edge of one against every face of the other, 267 ms for two 1000-vertex hulls) is
            # needed only for pairs that touch; and only for the census (``counters (3,)``, not a step's)
            if counters.shape[0] > 2 and max(face_sep, esep) <= 0:
                counters[2] += edge_crosses_face(VA, EA, EA.shape[0], NB, dB, npb, fB, loops, VB) or \
                    edge_crosses_face(VB, EB, EB.shape[0], NA, dA, npa, fA, loops, VA)
        if esep > margin:
            continue
        if esep > face_sep + 1e-9 * scale:
            a0, a1, b0, b1 = VA[EA[ea, 0]], VA[EA[ea, 1]], VB[EB[eb, 0]], VB[EB[eb, 1]]
            cpa, cpb = segment_closest(a0, a1, b0, b1)
            nrm = cross(a1 - a0, b1 - b0)
            nrm /= norm(nrm)
            if dot(nrm, a0 - cA) < 0:   # outward from A
                nrm = -nrm
            k = put(out_i, out_f, k, i, 0.5 * (cpa + cpb), -nrm, -esep, F_EDGE, fid(FID_EDGE, ea, eb, 0))
        else:
            # reference face on the body with the larger face separation; the incident body's
            # deepest vertex below it is always a candidate (one call site: one compiled version)
            ref_a = sepA >= sepB
            VR, NR, dR, fr, fR, npr = (VA, NA, dA, fa, fA, npa) if ref_a else (VB, NB, dB, fb, fB, npb)
            VI, NI, dI, fI, npi, nvi = (VB, NB, dB, fB, npb, nvb) if ref_a else (VA, NA, dA, fA, npa, nva)
            j, low = np.int64(0), np.inf
            for v in range(nvi):
                x = dotr(NR, fr, VI, v) - dR[fr]
                if x < low:
                    j, low = v, x
            loopR = loops[fR[fr, 0]:fR[fr, 0] + fR[fr, 1]]
            k = face_patch(VR, NR[:npr], dR[:npr], fr, loopR, VI, NI[:npi], dI[:npi], fI, loops, scale, margin,
                           VI[j], max(sepA, sepB), j, ref_a, i, out_i, out_f, k)
    return k
