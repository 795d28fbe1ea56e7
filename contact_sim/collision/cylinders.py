"""Narrow-phase kernels of the cylinder (``contact_sim.cylinder``): exact against planes and spheres.

Same signature as every kernel (``dispatch.KERNEL_ARGS``). The cylinder is A (its rank is above
plane and sphere); its radius is ``sf[s, SF_RADIUS]``, its half length ``sf[s, SF_HALF + 2]``, its
axis the body's local z. Every other pair with a cylinder goes through the generic convex kernels
on its prism hull (``pair_kernels.COLLIDERS``), with the error bound of
``contact_sim.cylinder``.
"""
import numpy as np

from ..jit import njit
from .geometry import SF_HALF, SF_RADIUS
from ..constants import TOUCH_TOLERANCE
from .primitives import plane_contacts, plane_world, sphere_row
from .vec3 import mv, unit3


@njit
def cylinder_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                   out_i, out_f):
    """Cylinder A against plane B. On each cap circle the deepest rim point is ``c ± (h/2) a + r w``
    with ``w`` the unit direction of ``-(n - (n·a) a)`` (the plane normal's part across the axis);
    with it, the opposite point and the two at ±90° are candidates (a cap flat on the plane, where
    ``w`` is any direction (the body's x axis is used), gives its four; a cylinder on its side the
    deepest point of each cap). Candidates within the margin, at most 4 (``reduce4``), are the
    contacts: exact rim points, separations ``n·p - d``."""
    pts, dep, val, keep = np.empty((8, 3)), np.empty(8), np.empty(8, np.bool_), np.empty(8, np.bool_)
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa = shape_of[a[i]]
        nb, db = plane_world(sf, shape_of[b[i]], pos[b[i]], R[b[i]])
        r, hh = sf[sa, SF_RADIUS], sf[sa, SF_HALF + 2]
        Ra, c = R[a[i]], pos[a[i]]
        ax = np.array([Ra[0, 2], Ra[1, 2], Ra[2, 2]])
        na = nb[0] * ax[0] + nb[1] * ax[1] + nb[2] * ax[2]
        w = -(nb - na * ax)
        wl = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        if wl < 1e-12:   # the caps are parallel to the plane: every rim point is as deep; use the body's x
            w = np.array([Ra[0, 0], Ra[1, 0], Ra[2, 0]])
        else:
            w = w / wl
        u = np.array([ax[1] * w[2] - ax[2] * w[1], ax[2] * w[0] - ax[0] * w[2], ax[0] * w[1] - ax[1] * w[0]])
        for cap in range(2):
            s = hh if cap == 1 else -hh
            for j in range(4):
                m = cap * 4 + j
                for q in range(3):
                    d = w[q] if j == 0 else (-w[q] if j == 1 else (u[q] if j == 2 else -u[q]))
                    pts[m, q] = c[q] + s * ax[q] + r * d
        k = plane_contacts(pts, dep, val, keep, nb, db, margin, out_i, out_f, k, i)
    return k


@njit
def cylinder_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters,
                    out_i, out_f):
    """Cylinder A against sphere B: the closest point of the solid cylinder to the centre (radial
    part clamped to ``r``, axial part to ``±h/2``); a centre inside exits through the nearer of the
    side and the nearer cap (the side through the body's x axis for a centre on the axis)."""
    k = np.int64(0)   # not a literal 0: a literal argument would compile callees twice
    for i in range(a.shape[0]):
        margin = margins[i]   # the pair's own margin (its bodies' speeds: prepare.speculative_reach)
        sa, sb = shape_of[a[i]], shape_of[b[i]]
        Ra, pa, cb, rb = R[a[i]], pos[a[i]], pos[b[i]], sf[sb, SF_RADIUS]
        r, hh = sf[sa, SF_RADIUS], sf[sa, SF_HALF + 2]
        d = cb - pa
        x = Ra[0, 0] * d[0] + Ra[1, 0] * d[1] + Ra[2, 0] * d[2]   # the centre in the cylinder's frame
        y = Ra[0, 1] * d[0] + Ra[1, 1] * d[1] + Ra[2, 1] * d[2]
        z = Ra[0, 2] * d[0] + Ra[1, 2] * d[1] + Ra[2, 2] * d[2]
        ex, ey, _, rho = unit3(x, y, 0.0)   # the radial direction, of unit length however close to the axis
        if rho == 0.0:
            ex, ey = 1.0, 0.0
        if rho <= r and abs(z) <= hh:   # inside: leave by the nearest surface
            side, cap = r - rho, hh - abs(z)
            if side < cap:
                nl = np.array([ex, ey, 0.0])
                sep = -side - rb
            else:
                nl = np.array([0.0, 0.0, 1.0 if z >= 0 else -1.0])
                sep = -cap - rb
            normal = -mv(Ra, nl)          # B→A: into the cylinder, against its outward normal
        else:
            qr, qz = min(rho, r), min(max(z, -hh), hh)
            ql = np.array([qr * ex, qr * ey, qz])
            g = mv(Ra, ql) + pa - cb       # from the centre to the closest point
            dist = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
            sep = dist - rb
            if dist > TOUCH_TOLERANCE * min(r, rb):
                normal = g / dist
            else:   # the centre on the surface (outside by round-off): against the outward normal there
                on_side, on_cap = rho >= r, abs(z) >= hh
                nz = (1.0 if z >= 0 else -1.0) if on_cap else 0.0
                nl = np.array([ex if on_side else 0.0, ey if on_side else 0.0, nz])
                normal = -mv(Ra, nl / np.sqrt(nl[0] * nl[0] + nl[1] * nl[1] + nl[2] * nl[2]))
        k = sphere_row(out_i, out_f, k, i, sep, normal, cb, rb, margin)
    return k
