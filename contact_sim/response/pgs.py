"""Compiled projected Gauss–Seidel: one loop over contacts per sweep, the way Box2D's solver reads.

The contact rows (``rows.Rows``: directions ``n, t1, t2``, angular Jacobians ``r×d`` and their
images under the inverse inertia, effective inverse masses ``K``) are built once per solve by the
kernel ``build_rows`` below; the sweeps, where the time goes, are a kernel over them. Contacts are
visited in their order (detection's, which is deterministic), each sees every impulse applied before it in the same
sweep (sequential Gauss–Seidel, which converges in fewer sweeps than the coloured, vectorised
variant it replaces: a colour's contacts could not see each other), and the result is
bit-identical run to run.

One contact's update (normal, then friction):

* normal: ``λn ← max(λn + (target − v_n − c·λn) / (K_nn + c), 0)`` (``c`` the compliance of a soft
  row, 0 for a rigid one);
* friction: the sticking impulse ``λt − K_tt⁻¹ v_t`` (``v_t`` the tangential velocity after the
  normal update) is taken when it lies in the static cone ``|λt| ≤ μ_s λn``; otherwise the impulse
  on the kinetic disc ``|λt| ≤ μ_d λn`` nearest to it in the metric of ``K_tt`` (``disc``), where
  friction opposes the resulting sliding velocity (maximal dissipation) and the contact's energy
  can only go down.
"""
import math

import numpy as np

from ..jit import njit

_TINY = 1e-300

#: ``sweeps``' row of numbers per contact: columns of the 3 × 3 blocks (direction ``d``, coordinate
#: ``x`` at ``3d + x``) and of the scalars
_DIRS, _ANG_A, _ANG_B, _IANG_A, _IANG_B = 0, 9, 18, 27, 36
_IMA, _IMB, _KN, _K10, _K20, _K11, _K12, _K21, _K22 = 45, 46, 47, 48, 49, 50, 51, 52, 53
_TARGET, _COMPLIANCE, _MU_S, _MU_D, _INV_KN, _IKT = 54, 55, 56, 57, 58, 59
_P = 63


@njit
def disc(k00, k01, k11, f0, f1, radius, newton):
    """The friction impulse ``(x0, x1)`` on the disc ``|x| ≤ radius`` nearest, in the metric of the
    tangential block ``[[k00, k01], [k01, k11]]``, to the sticking impulse ``−K⁻¹ f`` (``f`` the
    sliding velocity without this contact's friction), for a sticking impulse outside the disc:
    ``x = −(K + νI)⁻¹ f`` with ``ν ≥ 0`` such that ``|x| = radius`` (the secular equation of a trust
    region, Newton on ``1/|x(ν)| − 1/radius``, monotone from ``ν = 0``)."""
    vmag = math.hypot(f0, f1)   # no overflow of the squares for huge velocities
    if not (radius > 0.0) or not (vmag > 0.0):
        return 0.0, 0.0
    trace = k00 + k11
    if abs(k01) <= 1e-15 * trace and abs(k00 - k11) <= 1e-15 * trace:
        # an isotropic block (a sphere's contact, any pair of point masses): K + νI is a multiple
        # of I, so the nearest point is the radial one, x = −radius f/|f| (what Newton converges
        # to, to round-off, in 3–5 steps)
        return -radius / vmag * f0, -radius / vmag * f1
    if radius * trace <= 1e-14 * vmag:
        # a disc far smaller than the sticking impulse: ν is so large that x = −radius f/|f| to
        # round-off (and Newton would overflow on 1/radius)
        return -radius / vmag * f0, -radius / vmag * f1
    # ν depends on f and the radius only through their ratio: Newton on the unit sliding velocity and
    # radius / |f|, so that neither underflows (a sliding velocity of 1e-162 m/s squared to 0, then 0/0)
    g0, g1, rad = f0 / vmag, f1 / vmag, radius / vmag
    nu = 0.0
    for _ in range(newton):
        p = k00 + nu
        q = k11 + nu
        det = p * q - k01 * k01
        x0 = -(q * g0 - k01 * g1) / det
        x1 = -(p * g1 - k01 * g0) / det
        y0 = (q * x0 - k01 * x1) / det
        y1 = (p * x1 - k01 * x0) / det
        n2 = x0 * x0 + x1 * x1
        norm = math.sqrt(n2)
        step = (1.0 / norm - 1.0 / rad) * norm * n2 / (x0 * y0 + x1 * y1)
        nu_next = max(nu - step, 0.0)
        # converged to round-off: further steps change ν by less than its last bits (Newton from
        # ν = 0 is monotone on this convex secular function: typically 3-5 steps, not 12)
        if abs(nu_next - nu) <= 1e-15 * nu_next:
            nu = nu_next
            break
        nu = nu_next
    p = k00 + nu
    q = k11 + nu
    det = p * q - k01 * k01
    x0 = -(q * g0 - k01 * g1) / det
    x1 = -(p * g1 - k01 * g0) / det
    # the last Newton step leaves |x| = radius to round-off; scale onto the disc exactly
    s = radius / max(math.sqrt(x0 * x0 + x1 * x1), _TINY)
    return x0 * s, x1 * s


@njit(_nrt=False)
def disc_rows(kt, vfree, radius, out):
    """``disc`` for ``k`` contacts: ``kt (k,2,2)``, ``vfree (k,2)``, ``radius (k,)``; ``out (k,2)``."""
    for c in range(kt.shape[0]):
        out[c, 0], out[c, 1] = disc(kt[c, 0, 0], kt[c, 0, 1], kt[c, 1, 1], vfree[c, 0], vfree[c, 1], radius[c], 12)


@njit(inline="always")   # a call per contact update costs more than its arithmetic
def _row_velocity(c, ia, ib, dirs, ang_a, ang_b, vel, omega):
    """Relative velocity of contact ``c``'s points in its (n, t1, t2) basis, as three numbers
    (no buffer to allocate or pass)."""
    s0, s1, s2 = 0.0, 0.0, 0.0
    for x in range(3):
        s0 += (dirs[c, 0, x] * (vel[ia, x] - vel[ib, x]) + ang_a[c, 0, x] * omega[ia, x]
               - ang_b[c, 0, x] * omega[ib, x])
        s1 += (dirs[c, 1, x] * (vel[ia, x] - vel[ib, x]) + ang_a[c, 1, x] * omega[ia, x]
               - ang_b[c, 1, x] * omega[ib, x])
        s2 += (dirs[c, 2, x] * (vel[ia, x] - vel[ib, x]) + ang_a[c, 2, x] * omega[ia, x]
               - ang_b[c, 2, x] * omega[ib, x])
    return s0, s1, s2


@njit(_nrt=False)
def normal_velocities(a, b, dirs, ang_a, ang_b, vel, omega, out):
    """The contacts' normal relative velocities ``out (K,)`` (``_row_velocity``'s first row)."""
    for c in range(a.shape[0]):
        out[c] = _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel, omega)[0]


@njit(inline="always")
def _apply(c, ia, ib, d0, d1, d2, dirs, iang_a, iang_b, ima, imb, vel, omega):
    """Apply the impulse change ``(d0, d1, d2)`` of contact ``c`` (on A; its negative on B)."""
    for x in range(3):
        p = d0 * dirs[c, 0, x] + d1 * dirs[c, 1, x] + d2 * dirs[c, 2, x]
        vel[ia, x] += ima[c] * p
        vel[ib, x] -= imb[c] * p
        omega[ia, x] += d0 * iang_a[c, 0, x] + d1 * iang_a[c, 1, x] + d2 * iang_a[c, 2, x]
        omega[ib, x] -= d0 * iang_b[c, 0, x] + d1 * iang_b[c, 1, x] + d2 * iang_b[c, 2, x]


@njit
def sweeps(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target_n, compliance, mu_s, mu_d, friction,
           lam, vel, omega, iterations, tolerance, stall):
    """Projected Gauss–Seidel sweeps over ``K`` contacts, in place.

    ``a, b (K,) int64`` bodies; ``dirs, ang_a, ang_b, iang_a, iang_b (K,3,3)`` rows of ``Rows``;
    ``ima, imb (K,)``; ``K (K,3,3)`` effective inverse masses; ``target_n, compliance, mu_s, mu_d
    (K,)``; ``friction`` bool; ``lam (K,3)`` accumulated (n, t1, t2) impulses on A, holding the
    warm start on entry (already applied to the velocities) and the result on return; ``vel, omega
    (N,3)`` updated in place.

    Stops when a sweep changes no contact's velocity by more than ``tolerance`` (m/s: each row's
    impulse change times its effective inverse mass, the diagonal of ``K`` plus the normal row's
    compliance, as Bullet measures its residual), after ``iterations`` sweeps, or when ``stall``
    sweeps in a row (0: never) brought no new smallest change. With friction the sweeps need not
    converge: Coulomb's cone, whose radius follows the normal impulse,
    makes the problem no convex program's optimality condition, and on a pile of spheres the
    largest change settles on a plateau (the same after 20 sweeps as after 1000: docs/limits.md)
    where each further sweep only moves impulses around the cycle. Returns ``(sweeps done, largest
    velocity change of the last sweep (m/s), stopped above tolerance)``."""
    k = a.shape[0]
    # one row of ``_P`` numbers per contact, read in order by every sweep (one stream through memory
    # instead of thirteen arrays): the rows' directions and angular parts, the inverse masses, the
    # entries of K the update reads, the normal row's target, compliance and 1/(K_nn + c), the
    # friction coefficients and K_tt⁻¹ row by row (zero where singular; 1/(K_nn + c) zero where not
    # positive)
    P = np.empty((k, _P))
    for c in range(k):
        for d in range(3):
            for x in range(3):
                P[c, _DIRS + 3 * d + x] = dirs[c, d, x]
                P[c, _ANG_A + 3 * d + x] = ang_a[c, d, x]
                P[c, _ANG_B + 3 * d + x] = ang_b[c, d, x]
                P[c, _IANG_A + 3 * d + x] = iang_a[c, d, x]
                P[c, _IANG_B + 3 * d + x] = iang_b[c, d, x]
        P[c, _IMA], P[c, _IMB] = ima[c], imb[c]
        kn = K[c, 0, 0] + compliance[c]
        P[c, _KN], P[c, _K10], P[c, _K20] = kn, K[c, 1, 0], K[c, 2, 0]
        P[c, _K11], P[c, _K12], P[c, _K21], P[c, _K22] = K[c, 1, 1], K[c, 1, 2], K[c, 2, 1], K[c, 2, 2]
        P[c, _TARGET], P[c, _COMPLIANCE], P[c, _MU_S], P[c, _MU_D] = target_n[c], compliance[c], mu_s[c], mu_d[c]
        P[c, _INV_KN] = 1.0 / max(kn, _TINY) if kn > 0.0 else 0.0
        det = K[c, 1, 1] * K[c, 2, 2] - K[c, 1, 2] * K[c, 2, 1]
        if det > 1e-300:
            P[c, _IKT], P[c, _IKT + 1] = K[c, 2, 2] / det, -K[c, 1, 2] / det
            P[c, _IKT + 2], P[c, _IKT + 3] = -K[c, 2, 1] / det, K[c, 1, 1] / det
        else:
            P[c, _IKT] = P[c, _IKT + 1] = P[c, _IKT + 2] = P[c, _IKT + 3] = 0.0
    done = 0
    residual = 0.0
    best = np.inf   # the smallest largest-change of a sweep so far, and the sweeps since
    since = 0
    for it in range(iterations):
        residual = 0.0
        for c in range(k):
            ia = a[c]
            ib = b[c]
            # the relative velocity in the contact's (n, t1, t2) basis (_row_velocity's sums)
            s0, s1, s2 = 0.0, 0.0, 0.0
            for x in range(3):
                dv = vel[ia, x] - vel[ib, x]
                wa = omega[ia, x]
                wb = omega[ib, x]
                s0 += P[c, _DIRS + x] * dv + P[c, _ANG_A + x] * wa - P[c, _ANG_B + x] * wb
                s1 += P[c, _DIRS + 3 + x] * dv + P[c, _ANG_A + 3 + x] * wa - P[c, _ANG_B + 3 + x] * wb
                s2 += P[c, _DIRS + 6 + x] * dv + P[c, _ANG_A + 6 + x] * wa - P[c, _ANG_B + 6 + x] * wb
            old0 = lam[c, 0]
            old1 = lam[c, 1]
            old2 = lam[c, 2]
            new0 = max(old0 + (P[c, _TARGET] - P[c, _COMPLIANCE] * old0 - s0) * P[c, _INV_KN], 0.0)
            new1 = old1
            new2 = old2
            if friction:
                dn = new0 - old0
                vt0 = s1 + P[c, _K10] * dn
                vt1 = s2 + P[c, _K20] * dn
                tr0 = old1 - (P[c, _IKT] * vt0 + P[c, _IKT + 1] * vt1)
                tr1 = old2 - (P[c, _IKT + 2] * vt0 + P[c, _IKT + 3] * vt1)
                if math.sqrt(tr0 * tr0 + tr1 * tr1) <= P[c, _MU_S] * new0:
                    new1 = tr0
                    new2 = tr1
                else:
                    free0 = vt0 - (P[c, _K11] * old1 + P[c, _K12] * old2)
                    free1 = vt1 - (P[c, _K21] * old1 + P[c, _K22] * old2)
                    new1, new2 = disc(P[c, _K11], P[c, _K12], P[c, _K22], free0, free1, P[c, _MU_D] * new0, 12)
            d0 = new0 - old0
            d1 = new1 - old1
            d2 = new2 - old2
            lam[c, 0] = new0
            lam[c, 1] = new1
            lam[c, 2] = new2
            # the impulse change on A, its negative on B (_apply's sums)
            for x in range(3):
                p = d0 * P[c, _DIRS + x] + d1 * P[c, _DIRS + 3 + x] + d2 * P[c, _DIRS + 6 + x]
                vel[ia, x] += P[c, _IMA] * p
                vel[ib, x] -= P[c, _IMB] * p
                omega[ia, x] += d0 * P[c, _IANG_A + x] + d1 * P[c, _IANG_A + 3 + x] + d2 * P[c, _IANG_A + 6 + x]
                omega[ib, x] -= d0 * P[c, _IANG_B + x] + d1 * P[c, _IANG_B + 3 + x] + d2 * P[c, _IANG_B + 6 + x]
            # the velocity change each row made at its own contact (m/s): |Δλ| times the row's
            # effective inverse mass (and compliance), so the tolerance is one speed at any mass
            residual = max(residual, abs(d0) * P[c, _KN], abs(d1) * P[c, _K11], abs(d2) * P[c, _K22])
        done = it + 1
        if residual <= tolerance:
            break
        if residual < best:
            best = residual
            since = 0
        else:
            since += 1
            if since == stall:
                break
    return done, residual, residual > tolerance


@njit(_nrt=False)
def apply_ids(ids, a, b, dirs, iang_a, iang_b, ima, imb, lam, vel, omega):
    """``rows.apply`` for the contacts ``ids``: impulses ``lam (K,3)`` onto ``vel, omega (N,3)``, in
    its order (A's linear parts over the contacts, then B's, then the angular parts), so the sums
    round as they do there."""
    for side in range(4):
        for j in range(ids.shape[0]):
            c = ids[j]
            for x in range(3):
                if side == 0:
                    vel[a[c], x] += ima[c] * (lam[c, 0] * dirs[c, 0, x] + lam[c, 1] * dirs[c, 1, x]
                                              + lam[c, 2] * dirs[c, 2, x])
                elif side == 1:
                    vel[b[c], x] += -imb[c] * (lam[c, 0] * dirs[c, 0, x] + lam[c, 1] * dirs[c, 1, x]
                                               + lam[c, 2] * dirs[c, 2, x])
                elif side == 2:
                    omega[a[c], x] += lam[c, 0] * iang_a[c, 0, x] + lam[c, 1] * iang_a[c, 1, x] \
                        + lam[c, 2] * iang_a[c, 2, x]
                else:
                    omega[b[c], x] += -(lam[c, 0] * iang_b[c, 0, x] + lam[c, 1] * iang_b[c, 1, x]
                                        + lam[c, 2] * iang_b[c, 2, x])


@njit(_nrt=False)
def build_rows(a, b, point, normal, pos, inv_mass, inv_inertia, hint, movable, dynamic_levers,
               t1, t2, ra, rb, ang_a, ang_b, iang_a, iang_b, ima, imb, K, dirs):
    """Constraint rows of ``K`` contacts (``rows.build_rows``' arithmetic, one contact at a time),
    written to the preallocated outputs. ``hint (K,3)`` the contact points' relative velocity (``t1``
    follows its tangential part where it is above 1e-12; else ``t1 = n × e``, ``e`` the coordinate
    axis least aligned with ``n``); ``dynamic_levers`` False puts a movable body's contact at its
    centre (the kinematic response)."""
    for c in range(a.shape[0]):
        ia = a[c]
        ib = b[c]
        nx, ny, nz = normal[c, 0], normal[c, 1], normal[c, 2]
        for x in range(3):
            ra[c, x] = point[c, x] - pos[ia, x]
            rb[c, x] = point[c, x] - pos[ib, x]
        if not dynamic_levers:
            if movable[ia]:
                ra[c, 0] = ra[c, 1] = ra[c, 2] = 0.0
            if movable[ib]:
                rb[c, 0] = rb[c, 1] = rb[c, 2] = 0.0
        # first tangent: along the sliding direction when there is one
        ax, ay, az = abs(nx), abs(ny), abs(nz)
        if ax <= ay and ax <= az:
            ux, uy, uz = 0.0, nz, -ny            # n × e_x
        elif ay <= az:
            ux, uy, uz = -nz, 0.0, nx            # n × e_y
        else:
            ux, uy, uz = ny, -nx, 0.0            # n × e_z
        hn_dot = hint[c, 0] * nx + hint[c, 1] * ny + hint[c, 2] * nz
        hx = hint[c, 0] - hn_dot * nx
        hy = hint[c, 1] - hn_dot * ny
        hz = hint[c, 2] - hn_dot * nz
        hn = math.sqrt(hx * hx + hy * hy + hz * hz)
        if hn > 1e-12:
            ux, uy, uz = hx / hn, hy / hn, hz / hn
        un = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / un, uy / un, uz / un
        vx, vy, vz = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
        t1[c, 0], t1[c, 1], t1[c, 2] = ux, uy, uz
        t2[c, 0], t2[c, 1], t2[c, 2] = vx, vy, vz
        dirs[c, 0, 0], dirs[c, 0, 1], dirs[c, 0, 2] = nx, ny, nz
        dirs[c, 1, 0], dirs[c, 1, 1], dirs[c, 1, 2] = ux, uy, uz
        dirs[c, 2, 0], dirs[c, 2, 1], dirs[c, 2, 2] = vx, vy, vz
        ima[c] = ma = inv_mass[ia]
        imb[c] = mb = inv_mass[ib]
        # K = (ima + imb) D Dᵀ + Σ_sides ang I⁻¹ angᵀ, ang = rows r × d: in scalars, each sum in the
        # order of its index (0.0 + the terms left to right), stored once (a value read back from
        # an output array is a load the compiler cannot drop: it cannot tell the arrays apart)
        m = ma + mb
        k00 = m * _dot3(nx, ny, nz, nx, ny, nz)
        k01 = m * _dot3(nx, ny, nz, ux, uy, uz)
        k02 = m * _dot3(nx, ny, nz, vx, vy, vz)
        k10 = m * _dot3(ux, uy, uz, nx, ny, nz)
        k11 = m * _dot3(ux, uy, uz, ux, uy, uz)
        k12 = m * _dot3(ux, uy, uz, vx, vy, vz)
        k20 = m * _dot3(vx, vy, vz, nx, ny, nz)
        k21 = m * _dot3(vx, vy, vz, ux, uy, uz)
        k22 = m * _dot3(vx, vy, vz, vx, vy, vz)
        for side in range(2):
            body = ia if side == 0 else ib
            r = ra if side == 0 else rb
            ang = ang_a if side == 0 else ang_b
            iang = iang_a if side == 0 else iang_b
            r0, r1, r2 = r[c, 0], r[c, 1], r[c, 2]
            # the rows' angular parts r × d
            a00, a01, a02 = r1 * nz - r2 * ny, r2 * nx - r0 * nz, r0 * ny - r1 * nx
            a10, a11, a12 = r1 * uz - r2 * uy, r2 * ux - r0 * uz, r0 * uy - r1 * ux
            a20, a21, a22 = r1 * vz - r2 * vy, r2 * vx - r0 * vz, r0 * vy - r1 * vx
            # their images under the inverse inertia I⁻¹ (r × d)
            i00, i01, i02 = _rot3(inv_inertia, body, a00, a01, a02)
            i10, i11, i12 = _rot3(inv_inertia, body, a10, a11, a12)
            i20, i21, i22 = _rot3(inv_inertia, body, a20, a21, a22)
            ang[c, 0, 0], ang[c, 0, 1], ang[c, 0, 2] = a00, a01, a02
            ang[c, 1, 0], ang[c, 1, 1], ang[c, 1, 2] = a10, a11, a12
            ang[c, 2, 0], ang[c, 2, 1], ang[c, 2, 2] = a20, a21, a22
            iang[c, 0, 0], iang[c, 0, 1], iang[c, 0, 2] = i00, i01, i02
            iang[c, 1, 0], iang[c, 1, 1], iang[c, 1, 2] = i10, i11, i12
            iang[c, 2, 0], iang[c, 2, 1], iang[c, 2, 2] = i20, i21, i22
            k00 += _dot3(a00, a01, a02, i00, i01, i02)
            k01 += _dot3(a00, a01, a02, i10, i11, i12)
            k02 += _dot3(a00, a01, a02, i20, i21, i22)
            k10 += _dot3(a10, a11, a12, i00, i01, i02)
            k11 += _dot3(a10, a11, a12, i10, i11, i12)
            k12 += _dot3(a10, a11, a12, i20, i21, i22)
            k20 += _dot3(a20, a21, a22, i00, i01, i02)
            k21 += _dot3(a20, a21, a22, i10, i11, i12)
            k22 += _dot3(a20, a21, a22, i20, i21, i22)
        K[c, 0, 0], K[c, 0, 1], K[c, 0, 2] = k00, k01, k02
        K[c, 1, 0], K[c, 1, 1], K[c, 1, 2] = k10, k11, k12
        K[c, 2, 0], K[c, 2, 1], K[c, 2, 2] = k20, k21, k22


@njit
def _dot3(x0, x1, x2, y0, y1, y2):
    """``x · y`` summed from 0.0 in index order (``build_rows``' sums, bit for bit)."""
    return 0.0 + x0 * y0 + x1 * y1 + x2 * y2


@njit
def _rot3(m, i, x0, x1, x2):
    """``m[i] @ x`` for ``m (N,3,3)``, each component summed from 0.0 in index order."""
    return (0.0 + x0 * m[i, 0, 0] + x1 * m[i, 0, 1] + x2 * m[i, 0, 2],
            0.0 + x0 * m[i, 1, 0] + x1 * m[i, 1, 1] + x2 * m[i, 1, 2],
            0.0 + x0 * m[i, 2, 0] + x1 * m[i, 2, 1] + x2 * m[i, 2, 2])


@njit
def soft_friction_sweeps(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target_n, compliance, mu, v_reg,
                         lam, vel, omega, iterations, tolerance):
    """Sequential Gauss–Seidel over the penalty response's soft normal rows and their regularised
    Coulomb friction (``penalty.penalty_stage``), in place: per contact, the normal
    row ``n·v + γ λn ≥ target ⟂ λn ≥ 0``, then the friction damper ``μλn/v_reg`` integrated
    implicitly, ``(K_tt + γ_t) Δλt = −(v_t + γ_t λt)`` with ``γ_t = v_reg/(μλn)``, capped at
    ``μλn`` along the sliding velocity the point would have without this contact's friction.
    Arrays as ``sweeps``; ``mu (K,)``. Stops when a sweep changes no impulse by more than
    ``tolerance`` × the largest one. Returns the sweeps done."""
    k = a.shape[0]
    done = 0
    for it in range(iterations):
        change = 0.0
        for c in range(k):
            if K[c, 0, 0] <= 0.0:
                # between two bodies nothing moves (a kinematic link pressed into a static floor):
                # no impulse, as solver.solve_soft gives it none (the compliance alone would)
                continue
            ia = a[c]
            ib = b[c]
            rv = _row_velocity(c, ia, ib, dirs, ang_a, ang_b, vel, omega)
            old0 = lam[c, 0]
            old1 = lam[c, 1]
            old2 = lam[c, 2]
            kn = K[c, 0, 0] + compliance[c]
            new0 = max(old0 + (target_n[c] - rv[0] - compliance[c] * old0) / kn, 0.0)
            vt0 = rv[1] + K[c, 1, 0] * (new0 - old0)
            vt1 = rv[2] + K[c, 2, 0] * (new0 - old0)
            cap = mu[c] * new0
            new1 = 0.0
            new2 = 0.0
            if cap > 0.0:
                # (K_tt + γ_t I) Δλt = −(v_t + γ_t λt) times s = 1/γ_t = μλn/v_reg, the damper's
                # conductance: (s K_tt + I) Δλt = −(s v_t + λt), finite however small μλn is (γ_t
                # overflowed to inf for a denormal μ, and inf/inf made the impulses NaN)
                cond = cap / v_reg
                p = cond * K[c, 1, 1] + 1.0
                q = cond * K[c, 1, 2]
                r = cond * K[c, 2, 1]
                u = cond * K[c, 2, 2] + 1.0
                r0 = -(cond * vt0 + old1)
                r1 = -(cond * vt1 + old2)
                det = p * u - q * r
                new1 = old1 + (u * r0 - q * r1) / det
                new2 = old2 + (p * r1 - r * r0) / det
                mag = math.sqrt(new1 * new1 + new2 * new2)
                if mag > cap:
                    # sliding: Coulomb's force against the velocity the point would have without this
                    # contact's friction (maximal dissipation)
                    f0 = vt0 - (K[c, 1, 1] * old1 + K[c, 1, 2] * old2)
                    f1 = vt1 - (K[c, 2, 1] * old1 + K[c, 2, 2] * old2)
                    fm = math.sqrt(f0 * f0 + f1 * f1)
                    if fm > 0.0:
                        new1, new2 = -cap * f0 / fm, -cap * f1 / fm
                    else:
                        m = max(mag, 1e-300)
                        new1, new2 = cap * new1 / m, cap * new2 / m
            d0 = new0 - old0
            d1 = new1 - old1
            d2 = new2 - old2
            lam[c, 0] = new0
            lam[c, 1] = new1
            lam[c, 2] = new2
            _apply(c, ia, ib, d0, d1, d2, dirs, iang_a, iang_b, ima, imb, vel, omega)
            change = max(change, abs(d0), abs(d1), abs(d2))
        done = it + 1
        biggest = 1e-300
        for c in range(k):
            for d in range(3):
                biggest = max(biggest, abs(lam[c, d]))
        if change <= tolerance * biggest:
            break
    return done
