"""Position correction: split-impulse pseudo-velocities that push penetrating bodies apart.

Planned once per step from its first contacts (``plan``), applied as a displacement at the end of
the step (``apply``) and then thrown away: they move positions only, so no energy is added (the
potential energy the separation adds is reported as ``StepStats.correction_energy``)."""
import numpy as np

from .. import quat
from .energy import potential_change


def plan(ctx):
    """``ctx.pseudo = (vp, wp) (N,3)``: pseudo-velocities removing ``settings.split_beta`` of each
    penetration over the step (normal rows only, non-negative), or ``None`` when nothing penetrates
    deeper than ``settings.split_slop``."""
    world, c = ctx.world, ctx.contacts
    st = world.settings
    if len(c) == 0 or ctx.counts.deepest <= st.split_slop:
        return
    pen = np.flatnonzero(c.depth > 0)
    if pen.size == 0:
        return
    vp = np.zeros_like(world.s.vel)
    wp = np.zeros_like(world.s.omega)
    ctx.solve(ctx.rows.select(pen), vp, wp, target_n=st.split_beta * c.depth[pen] / ctx.dt)
    cap(ctx, pen, vp, wp)


def cap(ctx, pen, vp, wp):
    """``ctx.pseudo = (vp, wp)`` (N,3), the plan's solution for the penetrating contacts ``pen``,
    scaled down where it would move a body farther than the overlaps justify, and each body's
    ``vp`` at most ``settings.split_max_speed`` (``wp`` scaled with it)."""
    # no body needs to move farther than all the overlaps together (a stack's top box moves by the
    # sum of the ones below). A body squeezed between immovable ones (a kinematic paddle and a
    # wall) has no separation that clears both: the solve's pseudo-velocities then grow with every
    # sweep and threw such a body metres up in one step; twice that sum caps the plan's scale
    st = ctx.world.settings
    reach = 2.0 * st.split_beta * float(ctx.contacts.depth[pen].sum())
    speed = np.sqrt(np.einsum("ij,ij->i", vp, vp))
    far = float(speed.max()) * ctx.dt
    if far > reach:
        vp *= reach / far
        wp *= reach / far
        speed *= reach / far
    # in a pile of 150 contacts that sum is a metre or more, and a body squeezed between a paddle
    # and a wall went 2.4 m up in one step: each body is moved out at most at split_max_speed (an
    # overlap goes over several steps; Box2D clamps its push-out velocity alike)
    fast = speed > st.split_max_speed
    if fast.any():
        f = st.split_max_speed / speed[fast]
        vp[fast] *= f[:, None]
        wp[fast] *= f[:, None]
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
