"""Narrow-phase kernels of pairs with a sphere or a plane: exact closest points.

Every kernel has the one signature of ``dispatch.KERNEL_ARGS``: the geometry table's arrays, the
pairs ``a, b (K,)`` (body indices, kernel A of the higher rank), body poses ``pos (N, 3)``,
``R (N, 3, 3)``, the margin, ``counters (3,)``, and the output rows ``out_i (4K, 3)``,
``out_f (4K, 7)`` (``manifold.put``); it returns the number of rows written. A pair is reported
when its separation is <= margin, with ``depth = -separation`` and the point half-way between the
two surfaces along the normal (so swapping A and B keeps it).
"""
import numpy as np

from ..constants import TOUCH_TOLERANCE
from ..contacts import FID_PLANE, FID_POINT, fid
from ..jit import njit
from .geometry import SF_HALF, SF_PLANE, SF_RADIUS, SF_SCALE, SI_NP, SI_NT, SI_NV, SI_P0, SI_T0, \
    SI_V0
from .manifold import F_PLANE, F_SPHERE, put, put3, reduce4
from .vec3 import col_max, closest_on_triangle, dot, mtv, mv, transform_rows, unit3


@njit
def plane_world(sf, s, p, R):
    """World normal ``(3,)`` and offset of plane shape ``s`` carried by ``p (3,)``, ``R (3, 3)``."""
    n = np.empty(3)
    return n, plane_world_to(sf, s, p, R, n)


@njit
def plane_world_to(sf, s, p, R, n):
    """``plane_world`` into the caller's ``n (3,)`` (one buffer for a kernel's pairs, not an array
    per pair): writes the world normal, returns the offset."""
    for i in range(3):
        n[i] = R[i, 0] * sf[s, SF_PLANE] + R[i, 1] * sf[s, SF_PLANE + 1] + R[i, 2] * sf[s, SF_PLANE + 2]
    return sf[s, SF_PLANE + 3] + dot(n, p)


@njit
def sphere_row(out_i, out_f, k, pair, sep, normal, cb, rb, margin):
    """The one contact of a pair with a sphere B (centre ``cb``, radius ``rb``) at ``sep``."""
    return sphere_row3(out_i, out_f, k, pair, sep, normal[0], normal[1], normal[2], cb, rb, margin)


@njit
def sphere_row3(out_i, out_f, k, pair, sep, nx, ny, nz, cb, rb, margin):
    """``sphere_row`` of the normal ``(nx, ny, nz)`` given as numbers."""
    if sep > margin:
        return k
    depth = -sep
    s = rb - 0.5 * depth
    return put3(out_i, out_f, k, pair, cb[0] + nx * s, cb[1] + ny * s, cb[2] + nz * s, nx, ny, nz, depth, F_SPHERE,
                fid(FID_POINT, 0, 0, 0))


@njit
def sphere_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                 out_i, out_f):
    """Sphere A against plane B: the true signed distance, one contact."""
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    nb = np.empty(3)  # the plane's world normal, one buffer for all pairs
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa = shape_of[a[i]]
        db = plane_world_to(sf, shape_of[b[i]], pos[b[i]], R[b[i]], nb)
        ra = sf[sa, SF_RADIUS]
        ca = pos[a[i]]
        sep = dot(nb, ca) - ra - db
        if sep <= margin:
            depth = -sep
            s = ra - 0.5 * depth
            k = put3(out_i, out_f, k, i, ca[0] - nb[0] * s, ca[1] - nb[1] * s, ca[2] - nb[2] * s, nb[0], nb[1], nb[2],
                     depth, F_PLANE, fid(FID_POINT, 0, 0, 0))
    return k


@njit
def sphere_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                  out_i, out_f):
    """Sphere A against sphere B (concentric: the normal is +z, any direction being right)."""
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        ra, rb = sf[shape_of[a[i]], SF_RADIUS], sf[shape_of[b[i]], SF_RADIUS]
        dx, dy, dz = pos[a[i], 0] - pos[b[i], 0], pos[a[i], 1] - pos[b[i], 1], pos[a[i], 2] - pos[b[i], 2]
        nx, ny, nz, dist = unit3(dx, dy, dz)
        if dist == 0.0:
            nx, ny, nz = 0.0, 0.0, 1.0
        k = sphere_row3(out_i, out_f, k, i, dist - ra - rb, nx, ny, nz, pos[b[i]], rb, margin)
    return k


@njit
def box_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
               out_i, out_f):
    """Box A against sphere B: clamp the centre into the box; a centre inside exits by the nearest face."""
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        h = sf[sa, SF_HALF:SF_HALF + 3]
        Ra, cb, rb = R[a[i]], pos[b[i]], sf[sb, SF_RADIUS]
        q = mtv(Ra, cb - pos[a[i]])
        d = np.empty(3)
        for j in range(3):
            d[j] = q[j] - min(max(q[j], -h[j]), h[j])
        dist = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if dist <= 0.0:
            ax, gap = 0, h[0] - abs(q[0])
            for j in range(1, 3):
                g = h[j] - abs(q[j])
                if g < gap:
                    ax, gap = j, g
            out = np.zeros(3)
            out[ax] = 1.0 if q[ax] >= 0 else -1.0
            sep = -gap - rb
        else:
            out = d / dist
            sep = dist - rb
        k = sphere_row(out_i, out_f, k, i, sep, -mv(Ra, out), cb, rb, margin)
    return k


@njit
def world_verts(verts, v0, nv, p, R, out):
    """``out[:nv]`` = vertices ``v0 .. v0 + nv`` carried by ``p (3,)``, ``R (3, 3)``."""
    transform_rows(verts[v0:v0 + nv], p, R, out, nv)


@njit
def nearest_triangle(V, tris, t0, nt, c):
    """``(index, closest point (3,), distance)`` of the triangle nearest ``c`` (world vertices ``V``)."""
    best, j, bx, by, bz = np.inf, 0, 0.0, 0.0, 0.0
    cx, cy, cz = c[0], c[1], c[2]
    for t in range(nt):
        qx, qy, qz = closest_on_triangle(cx, cy, cz, V, tris[t0 + t, 0], tris[t0 + t, 1], tris[t0 + t, 2])
        dd = np.sqrt((qx - cx) ** 2 + (qy - cy) ** 2 + (qz - cz) ** 2)
        if dd < best:
            best, j, bx, by, bz = dd, t, qx, qy, qz
    return j, np.array([bx, by, bz]), best


@njit
def poly_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
               out_i, out_f):
    """Polyhedron or mesh A against plane B: every vertex within the margin is a candidate; a
    resting face keeps at most 4 of them, spanning the patch."""
    nmax = col_max(si, SI_NV, shape_of, a, b)
    pts, dep, flags = np.empty((nmax, 3)), np.empty(nmax), np.empty((2, nmax), np.bool_)
    val, keep = flags[0], flags[1]
    nb = np.empty(3)  # the plane's world normal, one buffer for all pairs
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa = shape_of[a[i]]
        db = plane_world_to(sf, shape_of[b[i]], pos[b[i]], R[b[i]], nb)
        v0, nv = si[sa, SI_V0], si[sa, SI_NV]
        Ra, pa = R[a[i]], pos[a[i]]
        transform_rows(verts[v0:v0 + nv], pa, Ra, pts, nv)
        k = plane_contacts(pts[:nv], dep[:nv], val[:nv], keep[:nv], nb, db, margin, out_i, out_f, k, i)
    return k


@njit
def plane_contacts(pts, dep, val, keep, nb, db, margin, out_i, out_f, k, i):
    """Candidate points ``pts (n, 3)`` (world) of pair ``i`` against the plane ``nb·x = db``: those
    within the margin, at most 4 spanning the patch (``reduce4``), become contacts at the midpoint
    between the point and the plane; ``dep, val, keep (n,)`` scratch. Returns the new ``k``."""
    hit = False
    for v in range(pts.shape[0]):
        sep = dot(pts[v], nb) - db
        val[v] = sep <= margin
        hit |= val[v]
        for j in range(3):
            pts[v, j] -= 0.5 * sep * nb[j]
        dep[v] = -sep
    if not hit:
        return k
    reduce4(pts, dep, val, nb, keep)
    for v in range(pts.shape[0]):
        if keep[v]:
            k = put(out_i, out_f, k, i, pts[v], nb, dep[v], F_PLANE, fid(FID_PLANE, v, 0, 0))
    return k


@njit
def poly_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                out_i, out_f):
    """Convex polyhedron A against sphere B: the exact distance from the centre to the nearest
    triangle; a centre inside exits through the nearest face plane."""
    V = np.empty((col_max(si, SI_NV, shape_of, a, b), 3))
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        Ra, pa, cb, rb = R[a[i]], pos[a[i]], pos[b[i]], sf[sb, SF_RADIUS]
        world_verts(verts, si[sa, SI_V0], si[sa, SI_NV], pa, Ra, V)
        j, qb, dist = nearest_triangle(V, tris, si[sa, SI_T0], si[sa, SI_NT], cb)
        p0, m, fp = si[sa, SI_P0], -np.inf, 0
        for p in range(si[sa, SI_NP]):
            n = planes[p0 + p]
            nx = Ra[0, 0] * n[0] + Ra[0, 1] * n[1] + Ra[0, 2] * n[2]
            ny = Ra[1, 0] * n[0] + Ra[1, 1] * n[1] + Ra[1, 2] * n[2]
            nz = Ra[2, 0] * n[0] + Ra[2, 1] * n[1] + Ra[2, 2] * n[2]
            s = nx * cb[0] + ny * cb[1] + nz * cb[2] - (n[3] + (nx * pa[0] + ny * pa[1] + nz * pa[2]))
            if s > m:
                m, fp = s, p
        fn = mv(Ra, planes[p0 + fp, :3])
        inside = m <= 0
        sep = (m if inside else dist) - rb
        # touching (outside by round-off): the difference's direction is noise, the face's is not
        touching = dist <= TOUCH_TOLERANCE * min(sf[sa, SF_SCALE], rb)
        normal = -fn if (inside or touching) else (qb - cb) / dist
        k = sphere_row(out_i, out_f, k, i, sep, normal, cb, rb, margin)
    return k
