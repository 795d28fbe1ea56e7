"""Triangle-mesh pairs (concave allowed): mesh–sphere and mesh–polyhedron kernels, and the
inside tests they share.

A closed mesh is a solid: a point is inside by odd ray-crossing parity over three generic rays
(a ray that grazes an edge or vertex is discarded for the next). An open mesh (a terrain tile, a
flat floor) has no inside; it is a one-sided surface whose back is below it: a point is inside
when it lies behind the nearest triangle, so a body pressed through a terrain is pushed back out
the way it came. A body with a vertex behind it and none in front (the others below its plane
beside the rim; a sphere whose centre is behind by more than its radius) has gone through and has no contact with it: the broad phase pairs such a
body with the surface only within the margin, so a contact there would come and go with the
margin (a box resting on the ground 0.4 m under a terrain tile was pushed up through the tile
when a fast body elsewhere widened the step's speculative margin). A distance below ``TOUCH_TOLERANCE`` × the smaller body's size is touching, and
its direction round-off noise: the triangle's normal is the answer there.
"""
import numpy as np

from ..contacts import FID_CROSSING, FID_MESH_VERTEX, FID_POINT, FID_POLY_VERTEX, fid
from ..jit import njit
from .geometry import SF_RADIUS, SF_SCALE, SI_CLOSED, SI_E0, SI_NE, SI_NP, SI_NT, SI_NV, SI_P0, SI_V0, \
    SI_T0
from .inside import behind_open, in_front, parity_inside, plane_excess
from ..constants import TOUCH_TOLERANCE
from .manifold import F_EDGE, F_SPHERE, F_VERTEX, emit_deepest4, put
from .polyhedra import world_poly
from .primitives import nearest_triangle, world_verts
from .vec3 import col_max, cross, dot, edge_through_face, norm


@njit
def tri_normal(V, tris, t):
    """Unnormalised normal of triangle ``t`` (global row) of world vertices ``V``."""
    T0 = V[tris[t, 0]]
    return cross(V[tris[t, 1]] - T0, V[tris[t, 2]] - T0)


@njit
def inside_mesh(p, V, tris, t0, nt, closed, q, j):
    """Point ``p`` inside the mesh: parity for a closed mesh; behind the nearest triangle ``j``
    (nearest point ``q``) and not beside the rim for an open one (``inside.behind_open``)."""
    if closed:
        return parity_inside(p, V, tris, t0, nt)
    return behind_open(p[0], p[1], p[2], q[0], q[1], q[2], V, tris, t0, nt, t0 + j)


def points_in_meshes(p, T, valid_t, eps=1e-9):
    """``(n,)`` bool: point ``p[i] (3,)`` inside the closed mesh of world triangles ``T[i] (F, 3, 3)``
    (``valid_t (n, F)`` masks padding), by ray-crossing parity (numpy front end of the kernel)."""
    out = np.zeros(len(p), bool)
    for i in range(len(p)):
        tri = T[i][np.asarray(valid_t[i], bool)]
        V = np.ascontiguousarray(tri.reshape(-1, 3))
        idx = np.arange(len(V), dtype=np.int64).reshape(-1, 3)
        out[i] = parity_inside(np.asarray(p[i], float), V, idx, 0, len(idx), eps)
    return out


@njit
def mesh_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                out_i, out_f):
    """Triangle mesh A against sphere B: the nearest triangle; a centre inside is penetrating by
    the distance to the surface."""
    V = np.empty((col_max(si, SI_NV, shape_of, a, b), 3))
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        cb, rb = pos[b[i]], sf[sb, SF_RADIUS]
        world_verts(verts, si[sa, SI_V0], si[sa, SI_NV], pos[a[i]], R[a[i]], V)
        t0, nt = si[sa, SI_T0], si[sa, SI_NT]
        j, qb, dist = nearest_triangle(V, tris, t0, nt, cb)
        closed = si[sa, SI_CLOSED] != 0
        sgn = -1.0 if inside_mesh(cb, V, tris, t0, nt, closed, qb, j) else 1.0
        sep = sgn * dist - rb
        if sep > margin or (not closed and sgn < 0 and dist > rb):   # entirely behind an open mesh
            continue
        if dist > TOUCH_TOLERANCE * min(sf[sa, SF_SCALE], rb):
            normal = sgn * (qb - cb) / dist
        else:
            tn = tri_normal(V, tris, t0 + j)
            normal = -tn / norm(tn)
        depth = -sep
        k = put(out_i, out_f, k, i, cb + normal * (rb - 0.5 * depth), normal, depth, F_SPHERE,
                fid(FID_POINT, 0, 0, 0))
    return k


@njit
def _face_separates(N, d, npl, X, nx):
    """Whether a face plane of the convex polyhedron (``N[p]·x = d[p]``, the first ``npl``) has every
    vertex ``X[:nx]`` strictly in front of it: the polyhedron behind it and the mesh's vertices (so
    its hull, so the mesh) in front, nothing can cross. O(faces × vertices) where the edge–face test
    is O(edges × faces) both ways: a robot link near another, apart, took it every step."""
    for p in range(npl):
        apart = True
        for v in range(nx):
            if N[p, 0] * X[v, 0] + N[p, 1] * X[v, 1] + N[p, 2] * X[v, 2] - d[p] <= 0.0:
                apart = False
                break
        if apart:
            return True
    return False


@njit
def _crossings(VX, EX, NY, dY, npl, facesY, loops, VY, sgn, tag, P, Nn, D, F, I, c, eps=1e-12):
    """Every crossing of an edge of X through a face polygon of Y as a candidate (point, the face
    normal times ``sgn``, depth = the shallower endpoint's distance to the face plane)."""
    for e in range(EX.shape[0]):
        i0, i1 = EX[e, 0], EX[e, 1]
        for p in range(npl):
            crossed, s0, s1, x, y, z = edge_through_face(VX, i0, i1, NY, dY, p, VY, loops, facesY[p, 0],
                                                         facesY[p, 1], eps)
            if crossed and c < P.shape[0]:
                P[c, 0], P[c, 1], P[c, 2] = x, y, z
                for j in range(3):
                    Nn[c, j] = sgn * NY[p, j]
                D[c], F[c], I[c] = min(abs(s0), abs(s1)), F_EDGE, fid(FID_CROSSING, e, p, tag)
                c += 1
    return c


@njit
def _project(V, idx, n0, n1, n2, count):
    """``(min, max)`` of ``V[idx[j]]·n`` over ``j < count`` (``idx`` None-like: ``V``'s first rows)."""
    lo, hi = np.inf, -np.inf
    for j in range(count):
        r = idx[j] if idx.shape[0] else j
        x = V[r, 0] * n0 + V[r, 1] * n1 + V[r, 2] * n2
        lo = min(lo, x)
        hi = max(hi, x)
    return lo, hi


@njit
def _face_sat(VP, nvp, NP, npp, EP, VM, loop, nf, df):
    """Separating axes between convex polyhedron P (world vertices ``VP[:nvp]``, face normals
    ``NP[:npp]``, edges ``EP``) and one planar face polygon of a mesh (vertex rows ``loop`` of
    ``VM``, outward normal ``nf (3,)``, plane offset ``df``), the face's solid side behind it.

    Returns ``(overlap, a0, a1, a2)``: the smallest translation of P along unit ``a`` that separates
    it from the face (the face normal one-sided: P must get out in front; P's face normals and the
    edge-pair cross products either way), or a negative overlap when an axis separates them."""
    none = np.empty(0, np.int64)
    lo, _ = _project(VP, none, nf[0], nf[1], nf[2], nvp)
    best, b0, b1, b2 = df - lo, nf[0], nf[1], nf[2]
    if best < 0:
        return best, b0, b1, b2
    m = loop.shape[0]
    for q in range(npp + EP.shape[0] * m):
        if q < npp:
            a0, a1, a2 = NP[q, 0], NP[q, 1], NP[q, 2]
        else:   # edge of P × edge of the face
            e, j = divmod(q - npp, m)
            u0 = VP[EP[e, 1], 0] - VP[EP[e, 0], 0]
            u1 = VP[EP[e, 1], 1] - VP[EP[e, 0], 1]
            u2 = VP[EP[e, 1], 2] - VP[EP[e, 0], 2]
            w0 = VM[loop[(j + 1) % m], 0] - VM[loop[j], 0]
            w1 = VM[loop[(j + 1) % m], 1] - VM[loop[j], 1]
            w2 = VM[loop[(j + 1) % m], 2] - VM[loop[j], 2]
            a0, a1, a2 = u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0
            ln = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            if ln <= 1e-12 * np.sqrt((u0 * u0 + u1 * u1 + u2 * u2) * (w0 * w0 + w1 * w1 + w2 * w2)):
                continue   # parallel edges: their plane's normal is a face axis already tried
            a0, a1, a2 = a0 / ln, a1 / ln, a2 / ln
        plo, phi = _project(VP, none, a0, a1, a2, nvp)
        flo, fhi = _project(VM, loop, a0, a1, a2, m)
        up, down = fhi - plo, phi - flo      # P moved along +a, or along −a
        o = min(up, down)
        if o < 0:
            return o, a0, a1, a2
        if o < best:
            best = o
            if up <= down:
                b0, b1, b2 = a0, a1, a2
            else:
                b0, b1, b2 = -a0, -a1, -a2
    return best, b0, b1, b2


@njit
def _crossing_sat(VP, nvp, NP, npp, EP, VM, NM, dM, npm, fM, loops, lo, hi):
    """For a polyhedron crossing a mesh's faces edge-first (no vertex of either inside the other):
    the separating-axis answer of P against each mesh face polygon whose box overlaps P's box
    (``lo, hi (3,)``), and of those the binding one (the largest overlap). Returns ``(depth, a0, a1,
    a2)``, ``a`` the unit direction that moves P out; depth ≤ 0 when no face overlaps."""
    depth, b0, b1, b2 = 0.0, 0.0, 0.0, 0.0
    for p in range(npm):
        loop = loops[fM[p, 0]:fM[p, 0] + fM[p, 1]]
        out = False
        for x in range(3):
            flo, fhi = np.inf, -np.inf
            for j in range(loop.shape[0]):
                flo = min(flo, VM[loop[j], x])
                fhi = max(fhi, VM[loop[j], x])
            out = out or flo > hi[x] or fhi < lo[x]
        if out:
            continue
        o, a0, a1, a2 = _face_sat(VP, nvp, NP, npp, EP, VM, loop, NM[p], dM[p])
        if o > depth:
            depth, b0, b1, b2 = o, a0, a1, a2
    return depth, b0, b1, b2


@njit
def mesh_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
              out_i, out_f):
    """Triangle mesh A against convex polyhedron B, in the lecture's order: mesh vertices inside B
    (inside every face plane; depth from the nearest face plane), B's vertices inside the mesh or
    within the margin of it (depth = distance to the nearest triangle), and for pairs with neither
    an edge of one crossing a face of the other (depth = the shallower endpoint's distance to the
    face plane: an estimate, not an exact penetration depth). At most 4 per pair."""
    nv, npl = col_max(si, SI_NV, shape_of, a, b), col_max(si, SI_NP, shape_of, a, b)
    VM, VP = np.empty((nv, 3)), np.empty((nv, 3))
    NM, NP = np.empty((npl, 3)), np.empty((npl, 3))
    dM, dP = np.empty(npl), np.empty(npl)
    # candidates of a pair: every vertex of both, and up to 4096 edge-face crossings (more are
    # dropped: reduced to 4 anyway, and a pair only gets there when no vertex settled it)
    cap = 2 * nv + 4096
    P, Nn, D = np.empty((cap, 3)), np.empty((cap, 3)), np.empty(cap)
    F, I = np.empty(cap, np.int64), np.empty(cap, np.int64)
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sm, sp = shape_of[a[i]], shape_of[b[i]]
        world_poly(verts, planes, si, sm, pos[a[i]], R[a[i]], VM, NM, dM)
        world_poly(verts, planes, si, sp, pos[b[i]], R[b[i]], VP, NP, dP)
        nvm, nvp, npm, npp = si[sm, SI_NV], si[sp, SI_NV], si[sm, SI_NP], si[sp, SI_NP]
        t0, nt, closed = si[sm, SI_T0], si[sm, SI_NT], si[sm, SI_CLOSED] != 0
        touch_tol = TOUCH_TOLERANCE * min(sf[sm, SF_SCALE], sf[sp, SF_SCALE])
        c = np.int64(0)
        for v in range(nvm):       # (b) mesh vertices against the polyhedron's planes
            m, pm = plane_excess(NP, dP, npp, VM, v)   # vertex inside iff m <= 0
            if m <= margin:
                for j in range(3):
                    P[c, j], Nn[c, j] = VM[v, j] - 0.5 * m * NP[pm, j], NP[pm, j]
                D[c], F[c], I[c] = -m, F_VERTEX, fid(FID_POLY_VERTEX, v, pm, 0)
                c += 1
        front = False              # a vertex of B in front of an open mesh: B has not gone through it
        behind = False             # a vertex of B behind it
        for u in range(nvp):       # (a) polyhedron vertices against the mesh triangles
            j, qb, dist = nearest_triangle(VM, tris, t0, nt, VP[u])
            inside = inside_mesh(VP[u], VM, tris, t0, nt, closed, qb, j)
            behind |= inside
            if not (closed or front):
                front = in_front(VP[u, 0], VP[u, 1], VP[u, 2], qb[0], qb[1], qb[2], VM, tris, t0 + j)
            sep = -dist if inside else dist
            if sep > margin:
                continue
            if dist > touch_tol:
                dirn = (VP[u] - qb) / (dist if dist > 0 else 1.0)
                na = dirn if inside else -dirn
            else:
                tn = tri_normal(VM, tris, t0 + j)
                na = -tn / norm(tn)
            for jj in range(3):   # midway between the vertex and the mesh (na points from B to A)
                P[c, jj], Nn[c, jj] = VP[u, jj] + 0.5 * sep * na[jj], na[jj]
            D[c], F[c], I[c] = -sep, F_VERTEX, fid(FID_MESH_VERTEX, u, j, 0)
            c += 1
        if not (closed or front) and behind:   # behind an open mesh, none in front: gone through, no contact
            continue
        if c:
            counters[0] += 1
        elif _face_separates(NP, dP, npp, VM, nvm):
            continue               # a face plane of B with the whole mesh in front: apart, no crossing
        else:                      # (c) edge-face for the pairs no vertex settled
            counters[1] += 1
            fM = faces[si[sm, SI_P0]:si[sm, SI_P0] + npm]
            fP = faces[si[sp, SI_P0]:si[sp, SI_P0] + npp]
            EM = edges[si[sm, SI_E0]:si[sm, SI_E0] + si[sm, SI_NE]]
            EP = edges[si[sp, SI_E0]:si[sp, SI_E0] + si[sp, SI_NE]]
            # an edge of B through a face of A: push A along its face normal; and the reverse
            c = _crossings(VP, EP, NM, dM, npm, fM, loops, VM, 1.0, 0, P, Nn, D, F, I, c)
            c = _crossings(VM, EM, NP, dP, npp, fP, loops, VP, -1.0, 1, P, Nn, D, F, I, c)
            if c:
                # the crossings say where they touch; how deep and which way out is the separating
                # axis test of the polyhedron against the mesh faces it overlaps (an endpoint's
                # distance to a face plane can be the whole length of a long edge). The binding
                # face decides: exact for a convex mesh, an estimate in a concave corner
                lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
                for v in range(nvp):
                    for x in range(3):
                        lo[x] = min(lo[x], VP[v, x])
                        hi[x] = max(hi[x], VP[v, x])
                depth, a0, a1, a2 = _crossing_sat(VP, nvp, NP, npp, EP, VM, NM, dM, npm, fM, loops, lo, hi)
                if depth > 0:
                    for r in range(c):   # the normal from B to A: A moves opposite to P's way out
                        Nn[r, 0], Nn[r, 1], Nn[r, 2] = -a0, -a1, -a2
                        D[r] = depth
            if counters.shape[0] > 2:   # the census (not a step's)
                counters[2] += c > 0
        k = emit_deepest4(out_i, out_f, k, i, P, Nn, D, F, I, c)
    return k
