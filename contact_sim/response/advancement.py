"""Conservative advancement, compiled: the time of impact of a general pair (``toi.pair_toi``).

One call searches one pair: poses along the step's motion (centres ``x + v τ + a τ²/2``, the
torque-free rotation of ``free_motion._rotate_body``), the signed distance at each pose (closed
forms for a plane, two spheres, a sphere and a box; otherwise the pair's narrow-phase kernel from
``collision.dispatch`` with a wide margin, as ``collision.collide`` runs it), the closing-speed
bound, the advancement, the bounded sampling and Brent's refinement of a sign change. The method
is ``toi``'s (its module docstring); here it runs without a Python call per distance.

Per-body inputs (``shape_facts``): ``code (N,)`` (``D_PLANE``, ``D_SPHERE``, ``D_BOX``,
``D_POLY``: any other polyhedron, meshes and cylinders included), ``facts (N, 10)`` (plane normal
and offset, sphere radius, box half sizes, extent, thinnest size) and each polyhedron's vertices
``verts (M, 3)`` at ``vrange (N, 2)`` (start, count). The motion is ``motion = (pos, vel, acc,
quat, omega, principal_q, moments)``, ``(N, 3)``/``(N, 4)`` arrays, ``flags (N, 3)`` bool
(rotating, kinematic, dynamic).
"""
import math

import numpy as np

from ..collision.pair_kernels import call
from ..collision.vec3 import unit_rotations
from ..free_motion import _qrot, _rotate_body, _rotvec_quat  # quat.rotate's and from_rotvec's arithmetic
from ..jit import njit
from ..constants import WIDE, MAX_BRENT

D_PLANE, D_SPHERE, D_BOX, D_POLY = range(4)
F_NORMAL, F_OFFSET, F_RADIUS, F_HALF, F_EXTENT, F_THIN = 0, 3, 4, 5, 8, 9


@njit
def qmul(ax, ay, az, aw, bx, by, bz, bw):
    """``quat.mul`` (Hamilton product ``a ⊗ b``) of one pair, in its order: the cross product is
    added last. ``free_motion._qmul`` adds its terms one by one and can differ in the last bit;
    the search keeps ``quat``'s arithmetic, which the Python search used (kinematic spins,
    ``max_spin``)."""
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return (aw * bx + bw * ax + cx, aw * by + bw * ay + cy, aw * bz + bw * az + cz,
            aw * bw - (ax * bx + ay * by + az * bz))


@njit
def pose(k, tau, motion, flags, split, out_p, out_q, row):
    """Centre and orientation of body ``k`` at ``tau`` into ``out_p[row]``, ``out_q[row]``
    (``toi.Motion.pose``'s arithmetic; ``split = (max split angle, max sub-steps)``)."""
    pos, vel, acc, quat, omega, principal_q, moments = motion
    for x in range(3):
        out_p[row, x] = pos[k, x] + vel[k, x] * tau + 0.5 * acc[k, x] * tau * tau
    qx, qy, qz, qw = quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3]
    spins = omega[k, 0] != 0.0 or omega[k, 1] != 0.0 or omega[k, 2] != 0.0
    if flags[k, 0] and spins:
        qx, qy, qz, qw, _, _, _, _ = _rotate_body(quat, omega, principal_q, moments, k, tau, split[0],
                                                  np.int64(split[1]))
    elif flags[k, 1] and spins:
        rx, ry, rz, rw = _rotvec_quat(omega[k, 0] * tau, omega[k, 1] * tau, omega[k, 2] * tau)
        qx, qy, qz, qw = qmul(rx, ry, rz, rw, qx, qy, qz, qw)
    out_q[row, 0], out_q[row, 1], out_q[row, 2], out_q[row, 3] = qx, qy, qz, qw


@njit
def _plane_poly(code, facts, verts, vrange, o, pl, p, q):
    """Signed distance of body ``o`` (sphere or polyhedron; rows ``0``/``1`` of ``p, q`` are the
    pair's poses, ``o``/``pl`` name the rows) to the plane body ``pl``; NaN for another shape."""
    f = facts[pl[0]]
    r = pl[1]
    nx, ny, nz = _qrot(q[r, 0], q[r, 1], q[r, 2], q[r, 3], f[F_NORMAL], f[F_NORMAL + 1], f[F_NORMAL + 2])
    off = f[F_OFFSET] + (nx * p[r, 0] + ny * p[r, 1] + nz * p[r, 2])
    k, ro = o[0], o[1]
    if code[k] == D_SPHERE:
        return (p[ro, 0] * nx + p[ro, 1] * ny + p[ro, 2] * nz) - off - facts[k, F_RADIUS]
    if code[k] == D_PLANE:
        return np.nan
    low = np.inf
    for v in range(vrange[k, 0], vrange[k, 0] + vrange[k, 1]):
        wx, wy, wz = _qrot(q[ro, 0], q[ro, 1], q[ro, 2], q[ro, 3], verts[v, 0], verts[v, 1], verts[v, 2])
        low = min(low, (p[ro, 0] + wx) * nx + (p[ro, 1] + wy) * ny + (p[ro, 2] + wz) * nz)
    return low - off


@njit
def pair_rows(i, j, shape_of, rank):
    """What the narrow-phase kernel of bodies ``i, j`` reads besides poses, set up once per pair:
    ``(shape rows (2,), a (1,), b (1,), counters (3,), margins (1,))``, A the body of higher rank
    (pose row 0 is ``i``, row 1 is ``j``), the margin ``WIDE``."""
    two = np.empty(2, np.int64)
    two[0], two[1] = shape_of[i], shape_of[j]
    a, b = np.empty(1, np.int64), np.empty(1, np.int64)
    a[0], b[0] = (1, 0) if rank[i] < rank[j] else (0, 1)
    return two, a, b, np.zeros(3, np.int64), np.full(1, WIDE)


@njit
def distance(which, geo, bvh, rows, code, facts, verts, vrange, i, j, p, q, R, scratch_i, scratch_f):
    """Signed distance (m; negative: penetrating) of bodies ``i`` (pose row 0 of ``p (2,3)``,
    ``q (2,4)``) and ``j`` (row 1), as ``toi.signed_distance``: closed forms for a plane, two
    spheres and a sphere with a box, else the pair's narrow-phase kernel (``pair_kernels.call``'s
    ``which``) over the geometry ``geo`` (``GeomTable.arrays()``, ``bvh`` its mesh trees) within
    ``WIDE``: minus the deepest contact's depth, ``WIDE`` when none (``q`` is then normalised in
    place; ``rows`` from ``pair_rows``). ``R (2,3,3)``, ``scratch_i (4,3)``, ``scratch_f (4,7)``
    are workspace."""
    ci, cj = code[i], code[j]
    if ci == D_PLANE and cj != D_PLANE:
        d = _plane_poly(code, facts, verts, vrange, (j, 1), (i, 0), p, q)
        if not math.isnan(d):
            return d
    elif cj == D_PLANE:
        d = _plane_poly(code, facts, verts, vrange, (i, 0), (j, 1), p, q)
        if not math.isnan(d):
            return d
    if ci == D_SPHERE and cj == D_SPHERE:
        dx, dy, dz = p[0, 0] - p[1, 0], p[0, 1] - p[1, 1], p[0, 2] - p[1, 2]
        return math.sqrt(dx * dx + dy * dy + dz * dz) - facts[i, F_RADIUS] - facts[j, F_RADIUS]
    if (ci == D_SPHERE and cj == D_BOX) or (ci == D_BOX and cj == D_SPHERE):
        s, b = (0, 1) if ci == D_SPHERE else (1, 0)
        sb = j if b == 1 else i
        lx, ly, lz = _qrot(-q[b, 0], -q[b, 1], -q[b, 2], q[b, 3], p[s, 0] - p[b, 0], p[s, 1] - p[b, 1],
                             p[s, 2] - p[b, 2])
        ox = abs(lx) - facts[sb, F_HALF]
        oy = abs(ly) - facts[sb, F_HALF + 1]
        oz = abs(lz) - facts[sb, F_HALF + 2]
        mx, my, mz = max(ox, 0.0), max(oy, 0.0), max(oz, 0.0)
        outside = math.sqrt(mx * mx + my * my + mz * mz)
        return outside + min(max(ox, oy, oz), 0.0) - facts[i if s == 0 else j, F_RADIUS]
    # collide()'s one-pair path: unit quaternions (q is overwritten), rotations, the kernel of A
    # (higher rank) and B (``rows``: ``pair_rows``)
    unit_rotations(q, R)
    two, a, b, counters, wide = rows
    k = call(which, *geo, two, a, b, p, R, wide, counters, scratch_i, scratch_f, bvh)
    if k == 0:
        return WIDE
    deepest = -np.inf
    for r in range(k):
        deepest = max(deepest, scratch_f[r, 6])
    return -deepest


@njit
def max_spin(k, motion, flags):
    """The largest ``|ω|`` body ``k`` reaches in torque-free motion (``bounds.max_spin`` says why the
    vertices of the conserved set bound it); kinematic bodies and particles spin as told."""
    pos, vel, acc, quat, omega, principal_q, moments = motion
    wx, wy, wz = omega[k, 0], omega[k, 1], omega[k, 2]
    m0, m1, m2 = moments[k, 0], moments[k, 1], moments[k, 2]
    if not flags[k, 2] or not (math.isfinite(m0) and math.isfinite(m1) and math.isfinite(m2)) \
            or min(m0, m1, m2) <= 0:
        return math.sqrt(wx * wx + wy * wy + wz * wz)
    px, py, pz, pw = qmul(quat[k, 0], quat[k, 1], quat[k, 2], quat[k, 3],
                          principal_q[k, 0], principal_q[k, 1], principal_q[k, 2], principal_q[k, 3])
    bx, by, bz = _qrot(-px, -py, -pz, pw, wx, wy, wz)
    mom = (m0, m1, m2)
    p0, p1, p2 = (m0 * bx) ** 2, (m1 * by) ** 2, (m2 * bz) ** 2
    l2 = p0 + p1 + p2
    e2 = p0 / m0 + p1 / m1 + p2 / m2
    best = p0 / m0 ** 2 + p1 / m1 ** 2 + p2 / m2 ** 2
    for z in range(3):   # vertices: one pᵢ = 0, the other two from the two conserved sums
        a = 1 if z == 0 else 0
        b = 1 if z == 2 else 2
        det = 1.0 / mom[b] - 1.0 / mom[a]
        if abs(det) <= 1e-12 / mom[a]:
            continue
        pb = (e2 - l2 / mom[a]) / det
        pa = l2 - pb
        if pa >= -1e-12 * l2 and pb >= -1e-12 * l2:
            best = max(best, max(pa, 0.0) / mom[a] ** 2 + max(pb, 0.0) / mom[b] ** 2)
    return math.sqrt(best)


@njit
def spin_reach(motion, flags, code, facts, out):
    """How fast each body's spin can move its surface relative to its centre (m/s, into ``out
    (N,)``): ``max_spin`` × its extent; 0 for a body that does not spin and for a sphere (its spin
    moves no point of its surface off it), ``inf`` for a spinning plane."""
    omega = motion[4]
    for k in range(out.shape[0]):
        if code[k] != D_SPHERE and (omega[k, 0] != 0.0 or omega[k, 1] != 0.0 or omega[k, 2] != 0.0):
            ext = facts[k, F_EXTENT]
            out[k] = max_spin(k, motion, flags) * ext if ext < np.inf else np.inf
        else:
            out[k] = 0.0


@njit
def closing_bound(i, j, T, motion, flags, facts):
    """An upper bound (m/s) on how fast any point of body ``i`` can approach any point of body
    ``j`` during ``[0, T]``: relative centre speed, plus what the relative acceleration adds over
    the interval, plus each body's largest spin over its torque-free motion (``max_spin``) times
    its extent."""
    pos, vel, acc, quat, omega, principal_q, moments = motion
    dvx, dvy, dvz = vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1], vel[i, 2] - vel[j, 2]
    dax, day, daz = acc[i, 0] - acc[j, 0], acc[i, 1] - acc[j, 1], acc[i, 2] - acc[j, 2]
    rel = math.sqrt(dvx * dvx + dvy * dvy + dvz * dvz) + math.sqrt(dax * dax + day * day + daz * daz) * T
    for k in (i, j):
        ext = facts[k, F_EXTENT]
        if math.isfinite(ext) and (omega[k, 0] != 0.0 or omega[k, 1] != 0.0 or omega[k, 2] != 0.0):
            rel += max_spin(k, motion, flags) * ext
    return rel


@njit
def search(which, geo, bvh, shape_of, rank, code, facts, verts, vrange, motion, flags, split, i, j, T, tolerance,
           max_advances, max_samples, xtol, rtol, deepen):
    """First touching time of bodies ``i, j`` in ``(0, T]`` (``inf`` if none) by conservative
    advancement, then bounded sampling and Brent's method on a sign change (``toi.pair_toi``);
    ``tolerance`` × the smaller extent counts as touching. Returns ``(τ, distance evaluations)``.

    ``deepen > 0`` (a fraction of the thinner body's thinnest size) searches a pair already in
    contact: the first time it is that much deeper than it is now (a spinning body's other corner
    swinging in), the root of ``distance − (min(distance(0), 0) − deepen × thinnest)``. With
    ``deepen = 0`` the target is ``0``: the first touch of a pair apart."""
    p, q, R = np.empty((2, 3)), np.empty((2, 4)), np.empty((2, 3, 3))
    si, sf = np.empty((4, 3), np.int64), np.empty((4, 7))
    rows = pair_rows(i, j, shape_of, rank)
    tol = tolerance * min(facts[i, F_EXTENT], facts[j, F_EXTENT])
    rate = closing_bound(i, j, T, motion, flags, facts)
    if rate <= 0:
        return np.inf, 0
    evals = 1
    d0 = _at(0.0, which, geo, bvh, rows, code, facts, verts, vrange, motion, flags, split, i, j, p, q, R, si, sf)
    target = min(d0, 0.0) - deepen * min(facts[i, F_THIN], facts[j, F_THIN]) if deepen > 0 else 0.0
    tau, d = 0.0, d0 - target
    if d <= 0:
        return np.inf, evals
    lo, hi, f_lo, f_hi = 0.0, 0.0, 0.0, 0.0
    found = False
    for _ in range(max_advances):
        if d <= tol:
            return tau, evals
        nxt = tau + d / rate
        if nxt > T:
            return np.inf, evals
        dn = _at(nxt, which, geo, bvh, rows, code, facts, verts, vrange, motion, flags, split, i, j, p, q,
                 R, si, sf) - target
        evals += 1
        if dn < 0:   # the bound was beaten by round-off: the root is between the two, find it exactly
            lo, hi, f_lo, f_hi, found = tau, nxt, d, dn, True
            break
        tau, d = nxt, dn
    if not found:
        # the bound is far from the motion (a fast spin about the contact normal closes nothing):
        # sample the rest of the interval so that neither body moves more than half the thinner
        # one between samples, at most max_samples times (np.linspace's points)
        thin = min(facts[i, F_THIN], facts[j, F_THIN])
        x = rate * (T - tau) / (0.5 * thin)
        n = max_samples if not x < max_samples else max(int(math.ceil(x)), 1)
        step = (T - tau) / n
        prev, f_prev = tau, d
        for s in range(1, n + 1):
            t = T if s == n else s * step + tau
            ft = _at(t, which, geo, bvh, rows, code, facts, verts, vrange, motion, flags, split, i, j,
                     p, q, R, si, sf) - target
            evals += 1
            if ft <= tol:
                if not ft < 0:
                    return t, evals
                lo, hi, f_lo, f_hi, found = prev, t, f_prev, ft, True
                break
            prev, f_prev = t, ft
        if not found:
            return np.inf, evals
    # Brent's method (Brent 1973, ch. 4): inverse quadratic interpolation or secant steps while
    # they shrink the bracket fast enough, bisection otherwise; b is the best estimate
    a, b, fa, fb = lo, hi, f_lo, f_hi
    c, fc = a, fa
    dstep = estep = b - a
    for _ in range(MAX_BRENT):
        if (fb > 0) == (fc > 0):
            c, fc = a, fa
            dstep = estep = b - a
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        half = 0.5 * (xtol + rtol * abs(b))
        mid = 0.5 * (c - b)
        if abs(mid) <= half or fb == 0:
            break
        if abs(estep) >= half and abs(fa) > abs(fb):
            s_ = fb / fa
            if a == c:
                pp, qq = 2.0 * mid * s_, 1.0 - s_
            else:
                qa, rb = fa / fc, fb / fc
                pp = s_ * (2.0 * mid * qa * (qa - rb) - (b - a) * (rb - 1.0))
                qq = (qa - 1.0) * (rb - 1.0) * (s_ - 1.0)
            if pp > 0:
                qq = -qq
            else:
                pp = -pp
            if 2.0 * pp < min(3.0 * mid * qq - abs(half * qq), abs(estep * qq)):
                estep, dstep = dstep, pp / qq
            else:
                dstep = estep = mid
        else:
            dstep = estep = mid
        a, fa = b, fb
        b += dstep if abs(dstep) > half else (half if mid > 0 else -half)
        fb = _at(b, which, geo, bvh, rows, code, facts, verts, vrange, motion, flags, split, i, j, p, q,
                 R, si, sf) - target
        evals += 1
    return b, evals


@njit
def _at(tau, which, geo, bvh, rows, code, facts, verts, vrange, motion, flags, split, i, j, p, q, R, si, sf):
    """The pair's signed distance at ``tau`` (poses into ``p, q``)."""
    pose(i, tau, motion, flags, split, p, q, 0)
    pose(j, tau, motion, flags, split, p, q, 1)
    return distance(which, geo, bvh, rows, code, facts, verts, vrange, i, j, p, q, R, si, sf)


# ---------------------------------------------------------------------------- candidate pairs
@njit
def path_spheres(pos, vel, acc, ext, T, mid, rad):
    """The sphere bounding each body's path over ``[0, T]``: centre ``mid (N,3)`` (the path's
    midpoint in time) and radius ``rad (N,)`` (extent ``ext`` plus half the chord plus the sag
    ``|a| T²/8``; infinite for planes)."""
    for k in range(pos.shape[0]):
        cx = vel[k, 0] * T + 0.5 * acc[k, 0] * T * T
        cy = vel[k, 1] * T + 0.5 * acc[k, 1] * T * T
        cz = vel[k, 2] * T + 0.5 * acc[k, 2] * T * T
        for x in range(3):
            mid[k, x] = pos[k, x] + 0.5 * vel[k, x] * T + 0.125 * acc[k, x] * T * T
        a = math.sqrt(acc[k, 0] * acc[k, 0] + acc[k, 1] * acc[k, 1] + acc[k, 2] * acc[k, 2])
        rad[k] = ext[k] + (0.5 * math.sqrt(cx * cx + cy * cy + cz * cz) + 0.125 * a * T * T)


@njit
def path_pairs(bi, bj, finite, planes, pos, quat, vel, acc, omega, mid, rad, facts, T, kind, dynamic_code, group,
               mask, only, exclude, out_i, out_j):
    """``toi.candidate_pairs`` after the broad phase: the pairs ``bi, bj`` of bounded bodies whose
    path spheres overlap, then (finite body, plane) pairs whose path reaches the plane (``planes``,
    their normal and offset in ``facts``; a moving plane widens by its own path), in that order;
    kept when a dynamic body takes part, the collision groups allow it, something moves relative
    to the other, ``only`` (bool per body, or empty) has one of them, and the key ``min·N + max``
    is not in the sorted ``exclude``. Writes ``out_i, out_j`` (``i < j``); returns how many."""
    n = kind.shape[0]
    k = 0
    total = bi.shape[0] + finite.shape[0] * planes.shape[0]
    for c in range(total):
        if c < bi.shape[0]:
            i, j = bi[c], bj[c]
        else:
            r = c - bi.shape[0]
            f, pl = finite[r // planes.shape[0]], planes[r % planes.shape[0]]
            nx, ny, nz = _qrot(quat[pl, 0], quat[pl, 1], quat[pl, 2], quat[pl, 3], facts[pl, F_NORMAL],
                               facts[pl, F_NORMAL + 1], facts[pl, F_NORMAL + 2])
            off = facts[pl, F_OFFSET] + (nx * pos[pl, 0] + ny * pos[pl, 1] + nz * pos[pl, 2])
            speed = math.sqrt(vel[pl, 0] ** 2 + vel[pl, 1] ** 2 + vel[pl, 2] ** 2)
            if not (mid[f, 0] * nx + mid[f, 1] * ny + mid[f, 2] * nz) - off <= rad[f] + speed * T:
                continue
            i, j = min(pl, f), max(pl, f)
        if kind[i] != dynamic_code and kind[j] != dynamic_code:
            continue
        if (group[i] & mask[j]) == 0 or (group[j] & mask[i]) == 0:
            continue
        moves = False
        for x in range(3):
            if vel[i, x] != vel[j, x] or acc[i, x] != acc[j, x] or omega[i, x] != 0.0 or omega[j, x] != 0.0:
                moves = True
        if not moves:      # no relative motion: a pair apart now stays apart
            continue
        if only.shape[0] and not (only[i] or only[j]):
            continue
        if exclude.shape[0]:
            key = i * n + j
            e = np.searchsorted(exclude, key)
            if e < exclude.shape[0] and exclude[e] == key:
                continue
        out_i[k], out_j[k] = i, j
        k += 1
    return k
