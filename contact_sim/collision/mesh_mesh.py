"""Concave–concave pairs (triangle mesh against triangle mesh), by the lecture's tests, after the
bounding volumes, over a per-mesh bounding-volume hierarchy.

Per pair, cheapest first (the pair's bounding sphere and OBB have already overlapped):

1. **vertex inside**: each vertex of one mesh inside the other's object box is tested against the
   other mesh: odd ray-crossing parity (``inside.ray_triangle``, the same test as
   ``inside.parity_inside``, three generic rays) for a closed mesh, "behind the nearest triangle"
   for an open one; its depth is the distance to the nearest triangle of the other mesh (as
   mesh–polyhedron does), the normal the direction to that point (the nearest face's normal when
   the two are within round-off of touching). Vertices within the margin outside are reported
   with a negative depth (speculative contacts).
2. **edge crossing face**, for pairs where no vertex is inside (two interlocked rings): each
   edge of one crosses a triangle of the other when its endpoints lie strictly on opposite sides
   of the triangle's plane and the crossing point is inside the triangle. Normal: the crossed
   face's normal (oriented to push the meshes apart), depth: the shorter of the shallower
   endpoint's distance to the face plane and the crossing point's distance to the face's border
   (an estimate; exactly 0 for faces that only touch).

Every query walks an **AABB tree over the mesh's triangles** (``build_bvh``: median splits on the
longest axis, at most ``LEAF_SIZE`` triangles per leaf), built once per mesh shape and kept on it
(``shape._cs_bvh``): ray parity and nearest triangle walk one tree, the edge–face test walks both
at once (B's boxes carried into A's frame as the boxes of their rotated boxes, a conservative
overlap test). A pair costs O((V + crossings) log T) instead of O(V·T + T²). Work is done in A's
object frame (A's vertices are never transformed). At most 4 contacts per pair
(``manifold.reduce4`` over the deepest).
"""
import numpy as np

from ..contacts import FID_CROSSING, FID_MESH_VERTEX, FID_POLY_VERTEX, fid
from ..jit import njit
from .geometry import MESH, SF_BOX, SF_SCALE, SI_CLOSED, SI_NT, SI_NV, SI_P0, SI_T0, SI_V0
from .inside import RAYS, behind_open, in_front, ray_triangle
from .manifold import F_EDGE, F_VERTEX, emit_deepest4
from .vec3 import closest_on_triangle, col_max
from ..constants import LEAF_SIZE, STACK, TOUCH_TOLERANCE


def build_bvh(verts, tris):
    """AABB tree over the triangles ``tris (T, 3)`` of ``verts (V, 3)`` (object space):
    ``nodes (B, 4) int64`` (left, right, first, count; a leaf has ``count > 0`` and holds triangles
    ``perm[first:first + count]``), ``boxes (B, 6)`` (lo (3), hi (3)), ``perm (T,) int64``. Node 0
    is the root. Built once per mesh (numpy, median split on the longest centroid axis)."""
    tv = np.asarray(verts, float)[np.asarray(tris, np.int64)]
    lo_t, hi_t = tv.min(axis=1), tv.max(axis=1)
    cen = 0.5 * (lo_t + hi_t)
    T = len(tv)
    perm = np.arange(T, dtype=np.int64)
    nodes = np.zeros((max(2 * T, 1), 4), np.int64)
    boxes = np.zeros((max(2 * T, 1), 6))
    todo = [(0, 0, T)]
    count = 1
    while todo:
        k, s, e = todo.pop()
        idx = perm[s:e]
        boxes[k, :3], boxes[k, 3:] = lo_t[idx].min(axis=0), hi_t[idx].max(axis=0)
        if e - s <= LEAF_SIZE:
            nodes[k] = (-1, -1, s, e - s)
            continue
        c = cen[idx]
        ax = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        perm[s:e] = idx[np.argsort(c[:, ax], kind="stable")]
        m = (s + e) // 2
        left, right = count, count + 1
        count += 2
        nodes[k] = (left, right, 0, 0)
        todo.append((right, m, e))
        todo.append((left, s, m))
    return nodes[:count], boxes[:count], perm


def border_edges(tris, normals):
    """``(T, 3) bool``: edge ``e`` of triangle ``t`` (from its vertex ``e`` to ``e + 1``) is a border
    of a face, not a diagonal inside a flat quad (the triangle across it has another normal, or
    there is none). A crossing point's distance to the face border counts only these."""
    T = len(tris)
    a = tris.reshape(-1)
    b = np.roll(tris, -1, axis=1).reshape(-1)
    key = np.minimum(a, b) * (int(tris.max()) + 1) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    k = key[order]
    border = np.ones(3 * T, bool)
    same = np.flatnonzero(k[1:] == k[:-1])      # consecutive half-edges of one edge
    i, j = order[same], order[same + 1]
    flat = np.einsum("ij,ij->i", normals[i // 3], normals[j // 3]) > 1.0 - 1e-9
    border[i[flat]] = False
    border[j[flat]] = False
    return border.reshape(T, 3)


def shape_bvh(shape):
    """The tree of a mesh shape and its border edges (built on first use, then kept on the shape):
    ``(nodes, boxes, perm, border)``."""
    bvh = getattr(shape, "_cs_bvh", None)
    if bvh is None:
        g = shape._cs_geom
        bvh = shape._cs_bvh = build_bvh(g.verts, g.tris) + (border_edges(np.asarray(g.tris), g.planes[:, :3]),)
    return bvh


def table_bvh(geom):
    """The trees of a ``GeomTable``'s meshes stacked: ``(nodes (B, 4), boxes (B, 6), perm (T,),
    root (S,), border (T, 3))``, child and triangle indices made global, ``root[s]`` the root node
    of shape row ``s`` (-1 for other shapes), ``border`` per triangle row of the table (see
    ``border_edges``; true for non-mesh rows). Built once per table and kept on it."""
    hit = getattr(geom, "_cs_bvh", None)
    if hit is not None:
        return hit
    from .geometry import SI_RANK
    root = np.full(len(geom.shapes), -1, np.int64)
    N, Bx, P = [np.zeros((1, 4), np.int64)], [np.zeros((1, 6))], [np.zeros(1, np.int64)]
    border = np.ones((len(geom.tris), 3), np.bool_)
    nb = 1
    for s in np.flatnonzero(geom.si[:, SI_RANK] == MESH).tolist():   # the meshes' rows only
        nodes, boxes, perm, bd = shape_bvh(geom.shapes[s])
        border[geom.si[s, SI_T0]:geom.si[s, SI_T0] + len(bd)] = bd
        nodes = nodes.copy()
        inner = nodes[:, 3] == 0
        nodes[inner, 0] += nb
        nodes[inner, 1] += nb
        N.append(nodes)
        Bx.append(boxes)
        P.append(perm + geom.si[s, SI_T0])
        root[s] = nb
        nb += len(nodes)
    # leaves index the stacked perm: shift each shape's first-triangle field by its perm offset
    off = 1
    for k in range(1, len(N)):
        leaf = N[k][:, 3] > 0
        N[k][leaf, 2] += off
        off += len(P[k])
    hit = (np.ascontiguousarray(np.concatenate(N)), np.ascontiguousarray(np.concatenate(Bx)),
           np.ascontiguousarray(np.concatenate(P)), root, border)
    geom._cs_bvh = hit
    return hit


@njit
def _ray_box(px, py, pz, rx, ry, rz, boxes, k, tol):
    """The ray ``p + t r`` (t ≥ 0) meets box ``k`` widened by ``tol``."""
    t0, t1 = 0.0, np.inf
    for ax in range(3):
        o = px if ax == 0 else (py if ax == 1 else pz)
        d = rx if ax == 0 else (ry if ax == 1 else rz)
        lo, hi = boxes[k, ax] - tol, boxes[k, 3 + ax] + tol
        if d == 0.0:
            if o < lo or o > hi:
                return False
            continue
        a, b = (lo - o) / d, (hi - o) / d
        if a > b:
            a, b = b, a
        t0, t1 = max(t0, a), min(t1, b)
        if t0 > t1:
            return False
    return True


@njit
def _box_dist2(px, py, pz, boxes, k):
    """Squared distance from ``p`` to box ``k`` (0 inside)."""
    d2 = 0.0
    for ax in range(3):
        o = px if ax == 0 else (py if ax == 1 else pz)
        if o < boxes[k, ax]:
            d2 += (boxes[k, ax] - o) ** 2
        elif o > boxes[k, 3 + ax]:
            d2 += (o - boxes[k, 3 + ax]) ** 2
    return d2


@njit
def bvh_parity(px, py, pz, V, tris, nodes, boxes, perm, root, tol, stack, eps=1e-9):
    """``parity_inside`` over a tree: only the triangles in boxes the ray meets are tested."""
    votes = 0
    for r in range(RAYS.shape[0]):
        rx, ry, rz = RAYS[r, 0], RAYS[r, 1], RAYS[r, 2]
        hits, bad = 0, False
        sp = 1
        stack[0] = root
        while sp > 0:
            sp -= 1
            k = stack[sp]
            if not _ray_box(px, py, pz, rx, ry, rz, boxes, k, tol):
                continue
            if nodes[k, 3] > 0:
                for q in range(nodes[k, 2], nodes[k, 2] + nodes[k, 3]):
                    t = perm[q]
                    code = ray_triangle(px, py, pz, rx, ry, rz, V, tris[t, 0], tris[t, 1], tris[t, 2], eps)
                    hits += code & 1
                    bad |= code >= 2
            else:
                stack[sp], stack[sp + 1] = nodes[k, 0], nodes[k, 1]
                sp += 2
        odd = hits % 2 == 1
        if not bad:
            return odd
        votes += odd
    return votes >= 2


@njit
def bvh_nearest(px, py, pz, V, tris, nodes, boxes, perm, root, bound, stack):
    """``(triangle row, x, y, z, distance)`` of the triangle nearest ``p`` within ``bound`` (branch
    and bound over the tree); row -1 and distance ``inf`` when none is that near."""
    best2 = bound * bound if bound < np.inf else np.inf
    j, bx, by, bz = -1, 0.0, 0.0, 0.0
    sp = 1
    stack[0] = root
    while sp > 0:
        sp -= 1
        k = stack[sp]
        if _box_dist2(px, py, pz, boxes, k) > best2:
            continue
        if nodes[k, 3] > 0:
            for q in range(nodes[k, 2], nodes[k, 2] + nodes[k, 3]):
                t = perm[q]
                qx, qy, qz = closest_on_triangle(px, py, pz, V, tris[t, 0], tris[t, 1], tris[t, 2])
                d2 = (qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2
                if d2 < best2 or (j < 0 and d2 <= best2):
                    best2, j, bx, by, bz = d2, t, qx, qy, qz
        else:
            # the nearer child last, so it is taken first
            l, r = nodes[k, 0], nodes[k, 1]
            if _box_dist2(px, py, pz, boxes, l) < _box_dist2(px, py, pz, boxes, r):
                l, r = r, l
            stack[sp], stack[sp + 1] = l, r
            sp += 2
    return j, bx, by, bz, (np.sqrt(best2) if j >= 0 else np.inf)


@njit
def _vertices(X, nx, VY, tris, planes, p0Y, t0Y, ntY, nodes, boxes, perm, rootY, closedY, box, margin, tol, side,
              RY, pY, kind, P, Nn, D, F, I, c):
    """Step 1 for the vertices ``X[:nx]`` of one mesh (in the frame of the other, Y: vertices
    ``VY``): each one inside Y or within ``margin`` of it becomes a candidate (world point, normal
    B→A, depth). ``side`` +1 when X is B's vertices (Y = A), -1 for A's. Returns ``(c, any inside, gone
    through)``: a mesh with a vertex behind an open mesh Y and none in front of it has gone through
    Y (no contact; ``inside.in_front``)."""
    stack = np.empty(STACK, np.int64)
    anyin = False
    front = closedY    # only asked of an open Y (whose every vertex is looked at)
    behind = False
    reach = margin + tol
    for u in range(nx):
        px, py, pz = X[u, 0], X[u, 1], X[u, 2]
        # outside Y's box (and its margin) nothing is inside a closed mesh; an open mesh's inside
        # is everything behind it, so its vertices are all asked
        if closedY and (abs(px - box[0]) > box[3] + reach or abs(py - box[1]) > box[4] + reach
                        or abs(pz - box[2]) > box[5] + reach):
            continue
        if closedY:
            inside = bvh_parity(px, py, pz, VY, tris, nodes, boxes, perm, rootY, tol, stack)
            j, qx, qy, qz, dist = bvh_nearest(px, py, pz, VY, tris, nodes, boxes, perm, rootY,
                                              np.inf if inside else margin, stack)
            if j < 0:
                continue
        else:   # an open mesh: behind its nearest triangle is inside
            j, qx, qy, qz, dist = bvh_nearest(px, py, pz, VY, tris, nodes, boxes, perm, rootY, np.inf, stack)
            inside = behind_open(px, py, pz, qx, qy, qz, VY, tris, t0Y, ntY, j)
            behind |= inside
            if not front:
                front = in_front(px, py, pz, qx, qy, qz, VY, tris, j)
        sep = -dist if inside else dist
        if sep > margin or c >= P.shape[0]:
            continue
        anyin |= inside
        f = p0Y + j - t0Y
        if dist > tol:
            s = side / dist if inside else -side / dist
            nx_, ny_, nz_ = s * (px - qx), s * (py - qy), s * (pz - qz)
        else:   # touching: the direction is round-off; the face normal pushes the two apart
            nx_, ny_, nz_ = -side * planes[f, 0], -side * planes[f, 1], -side * planes[f, 2]
        # half-way between the surfaces: X's vertex moved half the depth into the other
        h = 0.5 * side * sep
        mx, my, mz = px + h * nx_, py + h * ny_, pz + h * nz_
        for r in range(3):
            P[c, r] = RY[r, 0] * mx + RY[r, 1] * my + RY[r, 2] * mz + pY[r]
            Nn[c, r] = RY[r, 0] * nx_ + RY[r, 1] * ny_ + RY[r, 2] * nz_
        D[c], F[c], I[c] = -sep, F_VERTEX, fid(kind, u, j - t0Y, 0)
        c += 1
    return c, anyin, behind and not front


@njit
def _in_triangle(V, i0, i1, i2, nx, ny, nz, x, y, z, border, t):
    """Point ``x`` on the plane of triangle ``t`` = ``i0 i1 i2`` of ``V`` (counter-clockwise about the
    unit normal ``n``): ``(inside, its distance to the nearest border edge line)`` (negative:
    outside that edge; ``inf`` when no edge of the triangle is a border, ``border (T, 3)``)."""
    inside, best = np.inf, np.inf
    for e in range(3):
        a, b = (i0, i1) if e == 0 else ((i1, i2) if e == 1 else (i2, i0))
        ex, ey, ez = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
        wx, wy, wz = x - V[a, 0], y - V[a, 1], z - V[a, 2]
        s = (ey * wz - ez * wy) * nx + (ez * wx - ex * wz) * ny + (ex * wy - ey * wx) * nz
        dist = s / np.sqrt(ex * ex + ey * ey + ez * ez)
        inside = min(inside, dist)
        if border[t, e]:
            best = min(best, dist)
    return inside, best


@njit
def _edges_through(VE, tE, tris, VF, tF, nx, ny, nz, d, sgn, tag, eps, R, p, P, Nn, D, F, I, c, tE_local, tF_local,
                   border):
    """The edges of triangle ``tE`` (vertices ``VE``; each edge once: from the lower vertex index)
    crossing triangle ``tF`` (vertices ``VF``, plane ``n·x = d``, in the same frame; within ``eps``
    of its border counts): candidates with normal ``sgn·n`` (world)."""
    for e in range(3):
        i0, i1 = tris[tE, e], tris[tE, (e + 1) % 3]
        if i0 > i1 or c >= P.shape[0]:
            continue
        s0 = nx * VE[i0, 0] + ny * VE[i0, 1] + nz * VE[i0, 2] - d
        s1 = nx * VE[i1, 0] + ny * VE[i1, 1] + nz * VE[i1, 2] - d
        if not s0 * s1 < 0:
            continue
        t = s0 / (s0 - s1)
        x = VE[i0, 0] + t * (VE[i1, 0] - VE[i0, 0])
        y = VE[i0, 1] + t * (VE[i1, 1] - VE[i0, 1])
        z = VE[i0, 2] + t * (VE[i1, 2] - VE[i0, 2])
        inside, inner = _in_triangle(VF, tris[tF, 0], tris[tF, 1], tris[tF, 2], nx, ny, nz, x, y, z, border, tF)
        if inside < -eps:
            continue
        for r in range(3):
            P[c, r] = R[r, 0] * x + R[r, 1] * y + R[r, 2] * z + p[r]
            Nn[c, r] = sgn * (R[r, 0] * nx + R[r, 1] * ny + R[r, 2] * nz)
        # the depth: the shorter way out, along the normal (the shallower endpoint back through the
        # plane) or within the plane (the crossing point out of the face); 0 for an edge that only
        # touches the face's border (coplanar resting faces)
        D[c] = max(min(abs(s0), abs(s1), inner), 0.0)
        F[c], I[c] = F_EDGE, fid(FID_CROSSING, 3 * tE_local + e, tF_local, tag)
        c += 1
    return c


@njit
def _crossings(VA, XB, tris, planes, p0A, t0A, p0B, t0B, nodes, boxes, perm, rootA, rootB, Rr, tr, tol, eps,
               Ra, pa, P, Nn, D, F, I, c, border):
    """Step 2: both trees walked at once (in A's frame; B's boxes carried there as the boxes of
    their rotated boxes); each pair of triangles in overlapping leaves has each one's edges tested
    against the other's face. ``XB`` B's vertices in A's frame, ``Rr, tr`` B's frame to A's."""
    st = np.empty((STACK, 2), np.int64)
    st[0, 0], st[0, 1] = rootA, rootB
    sp = 1
    while sp > 0:
        sp -= 1
        ka, kb = st[sp, 0], st[sp, 1]
        ok = True
        for r in range(3):
            cb = tr[r]
            hb = 0.0
            for q in range(3):
                cq = 0.5 * (boxes[kb, q] + boxes[kb, 3 + q])
                cb += Rr[r, q] * cq
                hb += abs(Rr[r, q]) * 0.5 * (boxes[kb, 3 + q] - boxes[kb, q])
            if cb - hb > boxes[ka, 3 + r] + tol or cb + hb < boxes[ka, r] - tol:
                ok = False
                break
        if not ok:
            continue
        la, lb = nodes[ka, 3] > 0, nodes[kb, 3] > 0
        if la and lb:
            for qa in range(nodes[ka, 2], nodes[ka, 2] + nodes[ka, 3]):
                ta = perm[qa]
                fa = p0A + ta - t0A
                for qb in range(nodes[kb, 2], nodes[kb, 2] + nodes[kb, 3]):
                    tb = perm[qb]
                    # triangle boxes first (most pairs of neighbouring leaves are apart)
                    apart = False
                    for ax in range(3):
                        lo_a = min(VA[tris[ta, 0], ax], VA[tris[ta, 1], ax], VA[tris[ta, 2], ax])
                        hi_a = max(VA[tris[ta, 0], ax], VA[tris[ta, 1], ax], VA[tris[ta, 2], ax])
                        lo_b = min(XB[tris[tb, 0], ax], XB[tris[tb, 1], ax], XB[tris[tb, 2], ax])
                        hi_b = max(XB[tris[tb, 0], ax], XB[tris[tb, 1], ax], XB[tris[tb, 2], ax])
                        if lo_b > hi_a + tol or hi_b < lo_a - tol:
                            apart = True
                            break
                    if apart:
                        continue
                    # B's edges through A's face: A pushed against its face normal
                    c = _edges_through(XB, tb, tris, VA, ta, planes[fa, 0], planes[fa, 1], planes[fa, 2],
                                       planes[fa, 3], -1.0, 0, eps, Ra, pa, P, Nn, D, F, I, c, tb - t0B, ta - t0A, border)
                    # A's edges through B's face (its plane carried into A's frame): A pushed along it
                    fb = p0B + tb - t0B
                    nx = Rr[0, 0] * planes[fb, 0] + Rr[0, 1] * planes[fb, 1] + Rr[0, 2] * planes[fb, 2]
                    ny = Rr[1, 0] * planes[fb, 0] + Rr[1, 1] * planes[fb, 1] + Rr[1, 2] * planes[fb, 2]
                    nz = Rr[2, 0] * planes[fb, 0] + Rr[2, 1] * planes[fb, 1] + Rr[2, 2] * planes[fb, 2]
                    db = planes[fb, 3] + nx * tr[0] + ny * tr[1] + nz * tr[2]
                    c = _edges_through(VA, ta, tris, XB, tb, nx, ny, nz, db, 1.0, 1, eps, Ra, pa, P, Nn, D, F, I, c,
                                       ta - t0A, tb - t0B, border)
            continue
        # split the node that is not a leaf (the larger box when neither is)
        split_a = lb or (not la and (boxes[ka, 3] - boxes[ka, 0]) + (boxes[ka, 4] - boxes[ka, 1])
                         + (boxes[ka, 5] - boxes[ka, 2]) >= (boxes[kb, 3] - boxes[kb, 0])
                         + (boxes[kb, 4] - boxes[kb, 1]) + (boxes[kb, 5] - boxes[kb, 2]))
        if sp + 2 > STACK:
            continue   # never reached: the stack holds the two trees' depths
        if split_a:
            st[sp, 0], st[sp, 1] = nodes[ka, 0], kb
            st[sp + 1, 0], st[sp + 1, 1] = nodes[ka, 1], kb
        else:
            st[sp, 0], st[sp, 1] = ka, nodes[kb, 0]
            st[sp + 1, 0], st[sp + 1, 1] = ka, nodes[kb, 1]
        sp += 2
    return c


@njit
def mesh_mesh(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
              out_i, out_f, nodes, boxes, perm, root, border):
    """Triangle mesh A against triangle mesh B (either concave): vertices inside (ray parity) or
    within the margin, then, when no vertex is inside, edges crossing faces (module docstring)."""
    nv = col_max(si, SI_NV, shape_of, a, b)
    XA, XB = np.empty((nv, 3)), np.empty((nv, 3))
    cap = 2 * nv + 4096
    P, Nn, D = np.empty((cap, 3)), np.empty((cap, 3)), np.empty(cap)
    F, I = np.empty(cap, np.int64), np.empty(cap, np.int64)
    Rr, tr = np.empty((3, 3)), np.empty(3)
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        Ra, Rb, pa, pb = R[a[i]], R[b[i]], pos[a[i]], pos[b[i]]
        # B's frame to A's: x_A = Rr x_B + tr, Rr = Raᵀ Rb, tr = Raᵀ (pb − pa)
        for r in range(3):
            tr[r] = Ra[0, r] * (pb[0] - pa[0]) + Ra[1, r] * (pb[1] - pa[1]) + Ra[2, r] * (pb[2] - pa[2])
            for q in range(3):
                Rr[r, q] = Ra[0, r] * Rb[0, q] + Ra[1, r] * Rb[1, q] + Ra[2, r] * Rb[2, q]
        va0, nva, vb0, nvb = si[sa, SI_V0], si[sa, SI_NV], si[sb, SI_V0], si[sb, SI_NV]
        VA, VB = verts[va0:va0 + nva], verts[vb0:vb0 + nvb]
        for u in range(nvb):
            for r in range(3):
                XB[u, r] = Rr[r, 0] * VB[u, 0] + Rr[r, 1] * VB[u, 1] + Rr[r, 2] * VB[u, 2] + tr[r]
        for u in range(nva):
            for r in range(3):
                XA[u, r] = (Rr[0, r] * (VA[u, 0] - tr[0]) + Rr[1, r] * (VA[u, 1] - tr[1])
                            + Rr[2, r] * (VA[u, 2] - tr[2]))
        tol = TOUCH_TOLERANCE * min(sf[sa, SF_SCALE], sf[sb, SF_SCALE])
        p0A, t0A, p0B, t0B = si[sa, SI_P0], si[sa, SI_T0], si[sb, SI_P0], si[sb, SI_T0]
        c = np.int64(0)
        c, inB, goneB = _vertices(XB, nvb, VA, tris, planes, p0A, t0A, si[sa, SI_NT], nodes, boxes, perm, root[sa],
                                 si[sa, SI_CLOSED] != 0, sf[sa, SF_BOX:SF_BOX + 6], margin, tol, 1.0, Ra, pa,
                                 FID_MESH_VERTEX, P, Nn, D, F, I, c)
        c, inA, goneA = _vertices(XA, nva, VB, tris, planes, p0B, t0B, si[sb, SI_NT], nodes, boxes, perm, root[sb],
                                 si[sb, SI_CLOSED] != 0, sf[sb, SF_BOX:SF_BOX + 6], margin, tol, -1.0, Rb, pb,
                                 FID_POLY_VERTEX, P, Nn, D, F, I, c)
        if goneA or goneB:   # one gone through the other, an open mesh: no contact
            continue
        if inA or inB:
            counters[0] += 1
        else:   # no vertex inside: the edge–face test (it finds the penetrations no vertex test sees)
            counters[1] += 1
            c0 = c
            c = _crossings(VA, XB, tris, planes, p0A, t0A, p0B, t0B, nodes, boxes, perm, root[sa], root[sb], Rr, tr,
                           tol, tol, Ra, pa, P, Nn, D, F, I, c, border)
            if counters.shape[0] > 2:   # the census (not a step's)
                counters[2] += c > c0
        k = emit_deepest4(out_i, out_f, k, i, P, Nn, D, F, I, c)
    return k
