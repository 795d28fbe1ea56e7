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
from .pgs import _row_velocity
from .cache import warm_record, warm_start
from .compliance import soft_rows
from .energy import kinematic_push, push_cap


def resting_solve(ctx):
    """Writes ``ctx.rest_impulse (K,3)``, ``ctx.rest_mask (K,) bool`` (the contacts that rest),
    ``ctx.dv_rest, ctx.dw_rest (N,3)`` (the force's velocity change over ``ctx.t_left``) and what
    the contact cache keeps (``ctx.warm_out``); the bodies' velocities are not changed here (the
    advance stage applies the force as two half-kicks)."""
    m = ctx.models
    if not m.resting or not (ctx.counts.touching or not ctx.exact_toi) \
            or (ctx.counts.bounced and np.all(ctx.vn1 > ctx.impact_speed)):
        return
    world = ctx.world
    s = world.s
    c = ctx.contacts
    t_left = ctx.t_left
    v_end = s.vel + ctx.gravity * t_left
    w_end = s.omega.copy()
    v_start_end = v_end.copy()
    w_start_end = w_end.copy()
    # a contact that just rebounded is leaving: no resting force may hold it back. With exact times
    # of impact only touching or slowly approaching contacts rest (a fast one within the margin gets
    # its impact time); with next_step every contact within the margin is a speculative one
    leaving = ctx.bounced & (ctx.vn1 > ctx.impact_speed)
    if ctx.soft.shape[0]:
        # beside a compliant contact it stays in: its row (v⁺ ≥ −vn1, never pulling) lets it leave
        # and keeps the spring from driving the pair back through each other (a ball squeezed by a
        # compliant paddle into a box it had just bounced off went 4 cm into the box at 4 m/s)
        leaving = np.zeros_like(leaving)
    if ctx.exact_toi:
        rmask = (ctx.touching | (ctx.vn0 >= -ctx.gdt)) & ~leaving
    else:
        rmask = ~leaving
    # every contact rests (the usual case): read the arrays as they are, no gathers
    ri = slice(None) if rmask.all() else np.flatnonzero(rmask)
    r2 = ctx.rows.select(rmask)
    target = np.minimum(2.0 * np.minimum(c.depth[ri], 0.0) / t_left - ctx.vn1[ri], 0.0)
    compliance = None
    if ctx.soft.shape[0]:   # the compliant rows: their spring's target and compliance (compliance.soft_rows)
        compliance = np.zeros(len(target))
        ids = np.arange(len(c)) if isinstance(ri, slice) else ri
        soft_rows(ids, ctx.rows.K, np.ascontiguousarray(c.depth, dtype=float), ctx.vn1, ctx.stiffness, ctx.zeta,
                  t_left, target, compliance)
    warm = warm_start(world, c.body_a[ri], c.body_b[ri], ctx.local[ri], t_left, r2, ctx.mu_d[ri])
    fr = ctx.friction
    res = ctx.solve(r2, v_end, w_end, target_n=target, mu_s=ctx.mu_s[ri] if fr else None,
                    mu_d=ctx.mu_d[ri] if fr else None, warm=warm, compliance=compliance)
    ctx.note(res)
    # the push cap is the rigid contacts' answer to a squeeze; a compliant one obeys its spring law,
    # and what it stores is counted (World.contact_energy)
    if compliance is None:
        pushed = kinematic_push(world, r2.a, r2.b, c.point[ri])
    else:
        rigid = compliance == 0.0
        pushed = kinematic_push(world, r2.a[rigid], r2.b[rigid], c.point[ri][rigid])
    if pushed is not None:   # where kinematic bodies push, no body ends faster than a push can make it
        bodies = pushed[0]
        ref = None if ctx.push_ref is None else (ctx.push_ref[0][bodies] + ctx.gravity[bodies] * t_left,
                                                 ctx.push_ref[1][bodies])   # the impact stage's start
        f = push_cap(world, *pushed, v_start_end[bodies], w_start_end[bodies], v_end, w_end, ref=ref)
        if f < 1.0:
            res.impulse = res.impulse * f
    lam2 = np.zeros((len(c), 3))
    lam2[ri] = res.impulse
    # the constant-force model is first order in what the force does while the contact point moves
    # during the interval: its work is right to within ½|λ|·|v_point| (and what a solve stopped
    # before convergence leaves: _work_bound)
    c_ = np.ascontiguousarray
    ctx.rest_bound += _work_bound(c_(r2.a, dtype=np.int64), c_(r2.b, dtype=np.int64), c_(r2.dirs), c_(r2.ang_a),
                                  c_(r2.ang_b), c_(s.vel, dtype=float), c_(s.omega, dtype=float), v_end, w_end,
                                  c_(target, dtype=float), c_(res.impulse, dtype=float))
    ctx.rest_impulse = lam2
    ctx.rest_mask = rmask
    ctx.dv_rest = v_end - v_start_end
    ctx.dw_rest = w_end - w_start_end
    # copies: kept across steps, never views of this step's contacts
    ctx.warm_out = (c.body_a[ri].copy(), c.body_b[ri].copy(), ctx.local[ri].copy(),
                    warm_record(res.impulse, r2) / t_left)


@njit
def _work_bound(a, b, dirs, ang_a, ang_b, vel, omega, vel_end, omega_end, target, lam):
    """A bound (J) on the work of the resting force, ``λ·(u_start + u_end)/2`` summed over the
    contacts (``u`` the contact points' relative velocity in the (n, t1, t2) basis, at the start
    from ``vel, omega (N,3)`` and at the end of the interval from ``vel_end, omega_end``; ``lam
    (K,3)`` the impulses, ``target (K,)`` the normal rows' targets, ≤ 0).

    ``½λ·u_start ≤ ½|λ|·|u_start|``: the constant-force model's first-order error while the point
    moves. ``½λ·u_end`` is ``½λn·target ≤ 0`` plus ``½λn·(u_end,n − target)`` plus ``½λt·u_end,t``;
    a converged solve makes the last two zero or negative (complementarity; friction sticking or
    opposing the slide), a solve stopped at the iteration limit may not (a body wedged between a
    plane and a static mesh that overlaps it: opposite normals at one point, and Gauss–Seidel
    creeps along the squeeze its friction grows with). Their positive parts are counted, so the
    bound holds for whatever impulses the solve returned."""
    total = 0.0
    rv = np.empty(3)
    for c in range(a.shape[0]):
        _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel, omega, rv)
        total += math.sqrt(lam[c, 0] ** 2 + lam[c, 1] ** 2 + lam[c, 2] ** 2) * math.sqrt(
            rv[0] ** 2 + rv[1] ** 2 + rv[2] ** 2)
        _row_velocity(c, a[c], b[c], dirs, ang_a, ang_b, vel_end, omega_end, rv)
        total += lam[c, 0] * max(rv[0] - target[c], 0.0) + max(lam[c, 1] * rv[1] + lam[c, 2] * rv[2], 0.0)
    return 0.5 * total
