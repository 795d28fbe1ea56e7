"""Position correction: split-impulse pseudo-velocities that push penetrating bodies apart.

Planned once per step from its first contacts (``plan``, a kernel of the sub-step's pipeline), applied as a displacement at the end of
the step (``apply``) and then thrown away: they move positions only, so no energy is added (the
potential energy the separation adds is reported as ``StepStats.correction_energy``)."""
import numpy as np

from .. import quat
from ..jit import njit
from .energy import potential_change
from .solver import solve_rows


@njit(cache=True)
def penetrating(depth, soft, a, b, dynamic):
    """Indices (int64) of the contacts position correction pushes apart: overlapping (``depth``
    (K,) > 0), rigid (``soft`` (K,) bool, empty when no contact is compliant) and not touching a
    dynamic body that a compliant contact holds (``dynamic`` (N,) bool, ``a``/``b`` (K,) body
    indices).

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
        if depth[i] > 0.0 and not (soft.shape[0] > 0 and soft[i]) and not held[a[i]] and not held[b[i]]:
            out[n] = i
            n += 1
    return out[:n]


@njit
def plan(a, b, depth, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, soft, dynamic, inv_mass, inv_inertia, split_beta,
         split_slop, dt, method, direct_max, max_iterations, tolerance, vp, wp):
    """Pseudo-velocities ``vp, wp (N,3)`` (zeros in) removing ``split_beta`` of each penetration of
    the contacts ``penetrating`` picks over the step ``dt`` (normal rows only, non-negative: the
    step's solve, ``solver.solve_rows``); rows as ``rows.Rows``' arrays. Returns the penetrating
    contacts' indices (empty: nothing to correct).

    The solve stops (where it iterates: Gauss–Seidel on a large island) once a sweep changes no
    contact's push-out over the step by more than ``split_slop`` (m): Gauss–Seidel measures a
    sweep's change as a speed (``pgs.sweeps``: an impulse change ``δ`` on a row of effective
    inverse mass ``K_nn`` changes its contact's velocity by ``δ·K_nn``, its push-out over the step
    by ``δ·K_nn·dt``), so the tolerance is ``split_slop / dt`` (m/s; never tighter than
    ``tolerance``), whatever the masses. Penetrations
    up to the slop are the resting solve's, not the correction's, so a finer push-out buys
    nothing, and from zero (no warm start) a settled 1000-sphere pile's correction would take
    all ``max_iterations`` sweeps every step."""
    pen = penetrating(depth, soft, a, b, dynamic)
    p = pen.shape[0]
    if p:
        target = np.empty(p)
        for i in range(p):
            target[i] = split_beta * depth[pen[i]] / dt
        tol = max(tolerance, split_slop / dt)
        zeros = np.zeros(p)
        solve_rows(method, a[pen], b[pen], dirs[pen], ang_a[pen], ang_b[pen], iang_a[pen], iang_b[pen], ima[pen],
                   imb[pen], K[pen], target, zeros, zeros, zeros, False, np.zeros((p, 3)), False, dynamic, inv_mass,
                   inv_inertia, direct_max, max_iterations, tol, vp, wp, np.zeros((p, 3)))
    return pen


def cap(ctx, pen, vp, wp):
    """``ctx.pseudo = (vp, wp)`` (N,3), the plan's solution for the penetrating contacts ``pen``,
    each body's scaled down (``wp`` with ``vp``) where it would move the body farther in the step
    than ``max(split_max_speed · dt, 2 · split_beta · its own deepest overlap)``, and never farther
    than ``2 · split_beta`` × all the overlaps together.

    A body squeezed between immovable ones (a kinematic paddle and a wall) has no separation that
    clears both: the plan's pseudo-velocities then grow with every sweep, and threw such a body
    metres up in one step. No body needs to move farther than all the overlaps together (a stack's
    top box moves by the sum of those below), but in a pile of 150 contacts that sum is a metre and
    more, and a body 0.1 m deep went 2.4 m up. So a body moves out of its own overlap at the split
    rate, and beyond that (pushed out by others) at most at ``split_max_speed`` (as Box2D clamps
    its push-out speed): a body placed 8 m deep still comes out at half its depth a step, and a
    tall stack's overlaps go over several steps."""
    st = ctx.world.settings
    c, dt = ctx.contacts, ctx.dt
    depth = c.depth[pen]
    own = np.zeros(len(vp))
    np.maximum.at(own, c.body_a[pen], depth)
    np.maximum.at(own, c.body_b[pen], depth)
    limit = np.minimum(np.maximum(st.split_max_speed * dt, 2.0 * st.split_beta * own),
                       2.0 * st.split_beta * float(depth.sum()))
    far = np.sqrt(np.einsum("ij,ij->i", vp, vp)) * dt
    over = far > limit
    if over.any():
        f = limit[over] / far[over]
        vp[over] *= f[:, None]
        wp[over] *= f[:, None]
    ctx.pseudo = (vp, wp)


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
