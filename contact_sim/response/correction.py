"""Position correction: split-impulse pseudo-velocities that push penetrating bodies apart.

Planned once per step from its first contacts (``drift_sink``, ``plan``, ``cap``: kernels of the
sub-step's pipeline), applied as a displacement at the end of the step (``apply``) and then thrown
away: they move positions only, so no energy is added (the
potential energy the separation adds is reported as ``StepStats.correction_energy``)."""
import math

import numpy as np

from .. import quat
from ..constants import ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS
from ..free_motion import _qmul, _qrot, free_turn
from ..jit import njit
from .energy import potential_change
from .solver import solve_rows


@njit(cache=True)
def penetrating(depth, sink, soft, a, b, dynamic):
    """Indices (int64) of the contacts position correction pushes apart: overlapping at the step's
    end without it (``depth + sink`` (K,) > 0: the overlap now and what the drift's turn adds,
    ``drift_sink``), rigid (``soft`` (K,) bool, empty when no contact is compliant) and not
    touching a dynamic body that a compliant contact holds (``dynamic`` (N,) bool, ``a``/``b``
    (K,) body indices).

    A compliant contact's overlap is its spring's deflection, which its force needs. A body held
    by one is where the spring puts it: pushing it out of a rigid overlap moves it into the spring
    (a sphere spawned half in the ground and half in a compliant robot base was pushed 7.5 cm into
    the base in a step, the spring then gave it 1.4 kJ). Its rigid overlaps are left to the
    resting solve, which keeps them from growing."""
    k = depth.shape[0]
    held = np.zeros(dynamic.shape[0], np.bool_)
    for i in range(soft.shape[0]):
        if soft[i]:
            if dynamic[a[i]]:
                held[a[i]] = True
            if dynamic[b[i]]:
                held[b[i]] = True
    out = np.empty(k, np.int64)
    n = 0
    for i in range(k):
        if depth[i] + sink[i] > 0.0 and not (soft.shape[0] > 0 and soft[i]) and not held[a[i]] and not held[b[i]]:
            out[n] = i
            n += 1
    return out[:n]


@njit(cache=True)
def drift_sink(a, b, point, normal, depth, rest_mask, pos, quat, omega, dw, principal_q, moments, dynamic, rotating,
               ext, t, floor, sink):
    """How much deeper the drift's turn over ``t`` (s) curves each resting contact than the turn's
    first-order part, into ``sink (K,)`` (m, ≥ 0; 0 where it is not above ``floor`` (m) or the
    resting solve did not take the contact, ``rest_mask (K,)``); returns the deepest ``depth +
    sink`` (``depth (K,)``).

    The resting solve holds the contact points' velocities, a first-order view of the step: the
    drift (``free_motion.advance``) then turns each dynamic body freely from the half-kicked ``ω +
    dw/2`` (``dw (N,3)`` the resting force's spin change). A body spinning about an axis that is
    not principal (an L-shaped block or a skewed pyramid spun flat on the floor) precesses in free
    motion, and over a step its lowest points curve down by ``O(|ω|² t² r)``, which no velocity
    row sees: with the correction taking ``split_beta`` of an overlap a step, such a body rested
    at the curve (and the approach it leaves) ÷ ``split_beta``, beyond the contact margin (a
    skewed pyramid at 2 rad/s, dt 1/60: 1.34e-4 m). Counted here, the correction pushes the body
    out of the curve as it comes.

    For a body the drift turns from ``q`` to ``q'`` (``free_motion.free_turn``, as the drift does), a
    contact point ``p`` moves by ``Δ = (q'q⁻¹)(p − x) − (p − x) − t ω × (p − x)`` beyond its
    first-order motion (``x`` the centre; the translation is ballistic, exactly what the rows and
    the kicks take); the contact sinks by ``n · (Δ_B − Δ_A)`` (``normal (K,3)`` from B to A),
    counted when positive: it is the material point's, and a convex surface's deepest point goes
    at least that deep (a rolling ball's lowest material point rises while its surface does not,
    so a rise is not counted). The first-order part's own error, the half-kick's lag (the drift
    moves at the mean of the step's start and end velocities, the rows hold the end), is left to
    ``split_beta``: counted in full it made a jammed heap of ten boxes jitter at 0.1 m/s for 10 s
    instead of settling. Bodies whose turn bends their points by less than 1 % of ``floor``
    (``½ (|ω| t)² · ext · (1 + I_max/I_min)``, ``ext (N,)`` bounding radii) are not turned here:
    a resting body's bend is ~1e-14 m. ``pos, omega (N,3)``, ``quat, principal_q (N,4)``,
    ``moments (N,3)`` ascending, ``dynamic, rotating (N,)`` bool."""
    n, k = pos.shape[0], a.shape[0]
    wh = np.empty((n, 3))   # the half-kicked spin
    seen = np.zeros(n, np.bool_)
    turned = np.zeros(n, np.bool_)
    qn = np.empty((n, 4))   # the turned orientation, and spin (the drift's turn, on copies)
    wt = np.empty((n, 3))
    for c in range(k):
        if not rest_mask[c]:
            continue
        for j in range(2):
            i = a[c] if j == 0 else b[c]
            if seen[i]:
                continue
            seen[i] = True
            if not (dynamic[i] and rotating[i]):
                continue
            for x in range(3):
                wh[i, x] = omega[i, x] + 0.5 * dw[i, x]
            spin2 = wh[i, 0] * wh[i, 0] + wh[i, 1] * wh[i, 1] + wh[i, 2] * wh[i, 2]
            if not 0.5 * spin2 * t * t * ext[i] * (1.0 + moments[i, 2] / moments[i, 0]) >= 0.01 * floor:
                continue
            turned[i] = True
            for x in range(4):
                qn[i, x] = quat[i, x]
            for x in range(3):
                wt[i, x] = wh[i, x]
            free_turn(qn, wt, principal_q, moments, i, t, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS)
    deepest = -np.inf
    for c in range(k):
        s = 0.0
        if rest_mask[c]:
            for j in range(2):
                i = a[c] if j == 0 else b[c]
                if not turned[i]:
                    continue
                rx, ry, rz = point[c, 0] - pos[i, 0], point[c, 1] - pos[i, 1], point[c, 2] - pos[i, 2]
                dx, dy, dz, dq = _qmul(qn[i, 0], qn[i, 1], qn[i, 2], qn[i, 3], -quat[i, 0], -quat[i, 1], -quat[i, 2],
                                       quat[i, 3])
                ux, uy, uz = _qrot(dx, dy, dz, dq, rx, ry, rz)   # q' q⁻¹ applied to r
                ex = ux - rx - t * (wh[i, 1] * rz - wh[i, 2] * ry)
                ey = uy - ry - t * (wh[i, 2] * rx - wh[i, 0] * rz)
                ez = uz - rz - t * (wh[i, 0] * ry - wh[i, 1] * rx)
                e = normal[c, 0] * ex + normal[c, 1] * ey + normal[c, 2] * ez
                s += e if j == 1 else -e
        sink[c] = s if s > floor else 0.0
        deepest = max(deepest, depth[c] + sink[c])
    return deepest


@njit
def plan(a, b, depth, sink, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, soft, dynamic, inv_mass, inv_inertia,
         split_beta, split_slop, dt, method, direct_max, max_iterations, tolerance, vp, wp):
    """Pseudo-velocities ``vp, wp (N,3)`` (zeros in) pushing the contacts ``penetrating`` picks
    apart over the step ``dt``: each by ``split_beta`` of its overlap ``depth (K,)`` and by all of
    the drift's ``sink (K,)`` (``drift_sink``; zeros without), a contact not yet overlapping by
    what of the sink would overlap (normal rows only, non-negative: the step's solve,
    ``solver.solve_rows``); rows as ``rows.Rows``' arrays. Returns ``(pen, push)``: the
    penetrating contacts' indices (empty: nothing to correct) and each one's push-out (m).

    The solve stops (where it iterates: Gauss–Seidel on a large island) once a sweep changes no
    contact's push-out over the step by more than ``split_slop`` (m): Gauss–Seidel measures a
    sweep's change as a speed (``pgs.sweeps``: an impulse change ``δ`` on a row of effective
    inverse mass ``K_nn`` changes its contact's velocity by ``δ·K_nn``, its push-out over the step
    by ``δ·K_nn·dt``), so the tolerance is ``split_slop / dt`` (m/s; never tighter than
    ``tolerance``), whatever the masses. Penetrations up to the slop are the resting solve's, not
    the correction's, so a finer push-out buys nothing, and from zero (no warm start) a settled
    1000-sphere pile's correction would take all ``max_iterations`` sweeps every step."""
    pen = penetrating(depth, sink, soft, a, b, dynamic)
    p = pen.shape[0]
    push = np.empty(p)
    if p:
        target = np.empty(p)
        for i in range(p):
            d = depth[pen[i]]
            push[i] = sink[pen[i]] + (split_beta * d if d > 0.0 else d)
            target[i] = push[i] / dt
        tol = max(tolerance, split_slop / dt)
        zeros = np.zeros(p)
        solve_rows(method, a[pen], b[pen], dirs[pen], ang_a[pen], ang_b[pen], iang_a[pen], iang_b[pen], ima[pen],
                   imb[pen], K[pen], target, zeros, zeros, zeros, False, np.zeros((p, 3)), False, dynamic, inv_mass,
                   inv_inertia, direct_max, max_iterations, tol, vp, wp, np.zeros((p, 3)))
    return pen, push


@njit(cache=True)
def cap(a, b, pen, push, split_max_speed, dt, vp, wp):
    """Scale each body's pseudo-velocities ``vp, wp (N,3)`` (the plan's for the contacts ``pen``,
    each pushed out by ``push`` (m)) down where they would move it farther in the step ``dt`` than
    ``max(split_max_speed · dt, 2 × its own contacts' largest push)``, and never farther than
    twice all the pushes together.

    A body squeezed between immovable ones (a kinematic paddle and a wall) has no separation that
    clears both: the plan's pseudo-velocities then grow with every sweep, and threw such a body
    metres up in one step. No body needs to move farther than all the pushes together (a stack's
    top box moves by the sum of those below), but in a pile of 150 contacts that sum is a metre and
    more, and a body 0.1 m deep went 2.4 m up. So a body moves out of its own overlap at the split
    rate, and beyond that (pushed out by others) at most at ``split_max_speed`` (as Box2D clamps
    its push-out speed): a body placed 8 m deep still comes out at half its depth a step, and a
    tall stack's overlaps go over several steps."""
    own = np.zeros(vp.shape[0])
    total = 0.0
    for j in range(pen.shape[0]):
        c = pen[j]
        own[a[c]] = max(own[a[c]], push[j])
        own[b[c]] = max(own[b[c]], push[j])
        total += push[j]
    for i in range(vp.shape[0]):
        limit = min(max(split_max_speed * dt, 2.0 * own[i]), 2.0 * total)
        far = math.sqrt(vp[i, 0] * vp[i, 0] + vp[i, 1] * vp[i, 1] + vp[i, 2] * vp[i, 2]) * dt
        if far > limit:
            f = limit / far
            for x in range(3):
                vp[i, x] *= f
                wp[i, x] *= f


def apply(ctx):
    """Move the bodies by the planned pseudo-velocities over the step; returns the potential energy
    that added (J), 0 without a plan."""
    if ctx.pseudo is None:
        return 0.0
    vp, wp = ctx.pseudo
    move(ctx.world, vp * ctx.dt, wp * ctx.dt)
    return potential_change(ctx.world, vp * ctx.dt)


def move(world, dx, dtheta):
    """Displace centres by ``dx (N,3)`` and rotate by rotation vectors ``dtheta (N,3)``. The angular
    velocity turns with the body (its body-frame spin is kept): a world-frame ω left behind while
    the body turns under it changes ½ωᵀI_wω, and a spinning body gained energy from being pushed out
    of an overlap."""
    s = world.s
    s.pos += dx
    turn = np.flatnonzero(np.any(dtheta != 0, axis=1))
    if turn.size:
        dq = quat.from_rotvec(dtheta[turn])
        s.quat[turn] = quat.normalize(quat.mul(dq, s.quat[turn]))
        s.omega[turn] = quat.rotate(dq, s.omega[turn])
