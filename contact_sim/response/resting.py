"""The resting stage of a step: contacts that stay touching get the impulse that acts as a
constant force over the rest of the step ``T`` (held against gravity).

Warm started from the previous step's matched contacts (``cache.warm_start``). The constraints
are on the velocity at the *end* of ``T``: the normal velocity at least ``min(depth, 0)/T``-ish
(the force acts on the displacement ``(v_start + v_end)/2·T``, which may close a gap exactly,
never more, and never asks a pair to separate; an approaching pair ends at rest, a separating one
may come back by its own displacement, so the force does no work: an end-velocity target of 0 held
a separating body up, and added energy), friction sticking at the end or kinetic.
"""
import math

import numpy as np

from ..jit import njit
from ..constants import MATCH_FRACTION
from .cache import warm_record, warm_start
from .compliance import soft_rows
from .energy import dynamic_bodies, push_cap_kernel, push_speed
from .pgs import _row_velocity
from .solver import solve_rows


@njit
def _min(x, y):
    """numpy's ``minimum`` of two floats (the second on a tie: ``min(-0.0, 0.0)`` is ``0.0``)."""
    return x if x < y else y


@njit
def rest_stage(a, b, point, depth, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, local, vn0, vn1, touching, bounced,
               soft, stiff, zeta, mu_s, mu_d, kinetic, exact_toi, gdt, impact_speed, t, step, gravity_rows, dynamic,
               kinematic, mass, particle, pos, quat, inertia_body, inv_mass, inv_inertia, vel, omega, vel_ref, omega_ref,
               a0, b0, p0, values, has_old, ext, method, direct_max, max_iterations, tolerance, resting, lam_r, dv, dw,
               wv):
    """The resting solve of a sub-step over the time ``t`` left in the step, on its ``K`` contacts
    (rows as ``rows.Rows``' arrays; ``local (K,3)`` the points in A's frame, the warm start's key;
    the contact cache ``a0, b0 (K0,)``, ``p0 (K0,3)``, ``values (K0,4)``, read when ``has_old``).

    Which contacts rest: all but those that just rebounded (``bounced`` and leaving faster than
    ``impact_speed``), and beside a compliant contact every one (its row, ``v⁺ ≥ −vn1``, never
    pulling, lets a rebounding contact leave and keeps the spring from driving the pair back
    through each other: a ball squeezed by a compliant paddle into a box it had just bounced off
    went 4 cm into the box at 4 m/s). With exact times of impact only touching or slowly
    approaching ones (a fast one within the margin gets its impact time). Marks them in
    ``resting (K,) bool``; writes their impulses into ``lam_r (K,3)`` (zeros in), the force's
    velocity change over ``t`` into ``dv, dw (N,3)`` (the bodies' velocities are not changed: the
    advance applies it as two half-kicks) and the cache's values of the resting contacts into the
    first rows of ``wv (K,4)``: their impulses per unit of the step's time ``step`` (s), which the
    next step's warm start multiplies by its own. Not per unit of ``t``: after a time of impact late
    in the step ``t`` is short, and what the solve stops then (a box reaching a wall at 3 cm/s in
    the last 1e-3 of a step) read as a force 1000× the step's; in a pile that Gauss–Seidel solves
    alone, such warm starts kept the sweeps from converging. Returns ``(n_rest, sweeps, residual,
    unconverged, work_bound)``."""
    k = a.shape[0]
    n = vel.shape[0]
    kr = 0
    for c in range(k):
        leaving = bounced[c] and vn1[c] > impact_speed and soft.shape[0] == 0
        resting[c] = not leaving and (not exact_toi or touching[c] or vn0[c] >= -gdt)
        kr += resting[c]
    ri = np.flatnonzero(resting)
    # every contact rests (the usual case): the arrays as they are, no gathers
    whole = kr == k
    sa, sb = (a, b) if whole else (a[ri], b[ri])
    sdirs, sang_a, sang_b = (dirs, ang_a, ang_b) if whole else (dirs[ri], ang_a[ri], ang_b[ri])
    siang_a, siang_b, sK = (iang_a, iang_b, K) if whole else (iang_a[ri], iang_b[ri], K[ri])
    sima, simb, slocal = (ima, imb, local) if whole else (ima[ri], imb[ri], local[ri])
    smu_s, smu_d = (mu_s, mu_d) if whole else (mu_s[ri], mu_d[ri])
    ends = np.empty((4, n, 3))   # one block: the end velocities the solve updates, and their start
    v_end, w_end, v_start_end, w_start_end = ends[0], ends[1], ends[2], ends[3]
    for i in range(n):
        for x in range(3):
            v_end[i, x] = vel[i, x] + gravity_rows[i, x] * t
            w_end[i, x] = omega[i, x]
            v_start_end[i, x] = v_end[i, x]
            w_start_end[i, x] = w_end[i, x]
    # the constraints are on the velocity at the end of t: the normal velocity at least
    # min(depth, 0)/t-ish (the force acts on the displacement (v_start + v_end)/2·t, which may close a
    # gap exactly, never more, and never asks a pair to separate)
    per = np.zeros((2, kr))   # one block: the normal rows' targets and compliances
    target, compliance = per[0], per[1]
    for j in range(kr):
        c = ri[j]
        target[j] = _min(2.0 * _min(depth[c], 0.0) / t - vn1[c], 0.0)
    impulses = np.zeros((2, kr, 3))   # one block: the warm start, the solve's impulses
    warm, lam = impulses[0], impulses[1]
    use_warm = has_old and kr > 0 and warm_start(a0, b0, p0, sa, sb, slocal, ext, MATCH_FRACTION, values, t, sdirs,
                                                  smu_d, warm)
    if soft.shape[0]:   # the compliant rows: their spring's target and compliance (compliance.soft_rows)
        soft_rows(ri, K, depth, vn1, stiff, zeta, t, target, compliance)
    it, residual, unconverged = solve_rows(method, sa, sb, sdirs, sang_a, sang_b, siang_a, siang_b, sima, simb, sK,
                                           target, compliance, smu_s, smu_d, kinetic, warm, use_warm, dynamic,
                                           inv_mass, inv_inertia, direct_max, max_iterations, tolerance, v_end, w_end,
                                           lam)
    # where kinematic bodies push, no body ends faster than a push can make it (energy.push_cap_kernel),
    # measured from the impact stage's start; the push cap is the rigid contacts' answer to a
    # squeeze, a compliant one obeys its spring law (what it stores is counted: World.contact_energy)
    ca, cb, cpoint = sa, sb, point if whole else point[ri]
    if soft.shape[0]:
        rig = np.flatnonzero(compliance == 0.0)
        ca, cb, cpoint = ca[rig], cb[rig], cpoint[rig]
    u = push_speed(ca, cb, cpoint, kinematic, dynamic, pos, vel, omega)
    if u >= 0.0:
        pb = dynamic_bodies(ca, cb, dynamic)
        vref = vel_ref[pb]
        for j in range(pb.shape[0]):
            for x in range(3):
                vref[j, x] = vref[j, x] + gravity_rows[pb[j], x] * t
        f = push_cap_kernel(pb, u, mass, particle, quat, inertia_body, v_start_end[pb], w_start_end[pb], vref,
                            omega_ref[pb], v_end, w_end)
        if f < 1.0:
            for j in range(kr):
                for x in range(3):
                    lam[j, x] = lam[j, x] * f
    # the constant-force model is first order in what the force does while the contact point moves
    # during the interval: its work is right to within ½|λ|·|v_point| (and what a solve stopped
    # before convergence leaves: _work_bound)
    bound = _work_bound(sa, sb, sdirs, sang_a, sang_b, vel, omega, v_end, w_end, target, lam)
    warm_record(lam, sdirs, wv[:kr])
    for j in range(kr):
        for x in range(4):
            wv[j, x] = wv[j, x] / step
        for x in range(3):
            lam_r[ri[j], x] = lam[j, x]
    for i in range(n):
        for x in range(3):
            dv[i, x] = v_end[i, x] - v_start_end[i, x]
            dw[i, x] = w_end[i, x] - w_start_end[i, x]
    return kr, it, residual, unconverged, bound


@njit(_nrt=False)
def _work_bound(a, b, dirs, ang_a, ang_b, vel, omega, vel_end, omega_end, target, lam):
    """A bound (J) on the work of the resting force, ``λ·(u_start + u_end)/2`` summed over the
    contacts (``u`` the contact points' relative velocity in the (n, t1, t2) basis, at the start
    from ``vel, omega (N,3)`` and at the end of the interval from ``vel_end, omega_end``; ``lam
    (K,3)`` the impulses, ``target (K,)`` the normal rows' targets, ≤ 0).

    ``½λ·u_start ≤ ½|λ|·|u_start|``: the constant-force model's first-order error while the point
    moves. ``½λ·u_end`` is ``½λn·target ≤ 0`` plus ``½λn·(u_end,n − target)`` plus ``½λt·u_end,t``;
    a converged solve makes the last two zero or negative (complementarity; friction sticking or
    opposing the slide), a solve stopped unconverged (limit or stall) may not (a body wedged between a
    plane and a static mesh that overlaps it: opposite normals at one point, and Gauss–Seidel
    creeps along the squeeze its friction grows with). Their positive parts are counted, so the
    bound holds for whatever impulses the solve returned."""
    total = 0.0
    for c in range(a.shape[0]):
        rv = _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel, omega)
        total += math.sqrt(lam[c, 0] ** 2 + lam[c, 1] ** 2 + lam[c, 2] ** 2) * math.sqrt(
            rv[0] ** 2 + rv[1] ** 2 + rv[2] ** 2)
        rv = _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel_end, omega_end)
        total += lam[c, 0] * max(rv[0] - target[c], 0.0) + max(lam[c, 1] * rv[1] + lam[c, 2] * rv[2], 0.0)
    return 0.5 * total
