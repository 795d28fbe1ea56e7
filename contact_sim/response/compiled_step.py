"""A ``next_step`` sub-step's stages after detection in one compiled call.

With ``next_step`` times of impact (every world of more than a few bodies under ``auto``) a step
is one sub-step: prepare → impact (compression with friction, then restitution under the
energetic cap) → resting solve (exact, island by island; Gauss–Seidel finishing the islands that
slide) → position correction's plan → store impulses → advance. Run stage by stage from Python,
those stages cost more in array calls and argument passing than in arithmetic (in a 10-body
resting step the kernels are about a quarter of the time). ``run`` runs them as one compiled call, the same kernels in the same
order as the Python stages (``prepare.classify``, ``pgs.build_rows``, ``cache._local_points``,
``active_set.islands`` and ``solve_islands``, ``pgs.sweeps``, ``energy.restitution_cap``,
``pgs.normal_velocities``, ``cache._warm_start``, ``resting._work_bound``, ``cache._warm_record``,
``free_motion.advance``), so the step is the same bit for bit; a test steps scenes both ways.

The kernel answers why not when a Python stage would branch elsewhere (a solve that
``solver.solve_auto`` would not give to the dense active set), having changed nothing: the Python
stages then run the step as before. Contacts between two bodies nothing moves carry no impulse, and
where a kinematic body pushes, every solve is held to the push budget (``energy.push_cap``, the
same kernels as the Python stages'). It moves the bodies only once everything has succeeded. The
correction's cap and its displacement after the step stay in Python (``correction.cap``,
``correction.apply``).

Shapes: ``N`` bodies, ``K`` contacts.
"""
from operator import is_

import numpy as np

from ..free_motion import advance
from ..jit import njit
from ..settings import COMBINE_RULES
from . import correction, prepare
from . import toi as toi_mod
from .active_set import SOLVED, TOO_LARGE, islands, solve_islands
from .cache import _local_points, _warm_record, _warm_start
from ..constants import (DIRECT_CONSISTENCY, DIRECT_FIRST, DIRECT_ISLAND_MAX, DIRECT_MAX_CONTACTS, DIRECT_MAX_ROUNDS,
                         DIRECT_REGULARISATION, IMPACT_ROUNDS, ISOTROPIC_TOLERANCE, MATCH_FRACTION, MAX_SPLIT_ANGLE,
                         MAX_SUBSTEPS, REST_REBOUND_FRACTION, SIMULTANEOUS_FRACTION, TOI_TOLERANCE)
from .energy import (FRAME, NO_FRAME, dynamic_bodies, kinematic_work, frame_of, kinetic_in, push_cap_kernel, push_speed,
                     restitution_cap_in)
from .impact import next_round
from .pgs import apply_ids, build_rows, normal_velocities, sweeps
from .compliance import possible as may_be_compliant, soft_rows, stiffness_rows
from .correction import penetrating
from .resting import _work_bound

#: ``_step``'s answers: the step ran (``DONE``), or why a Python stage has to run it (``LARGE``: a
#: solve ``solver.solve_auto`` gives to another method; ``NONE_NEAR``: no speculative contact can
#: close, the step has no contact left)
DONE, LARGE, NONE_NEAR = range(3)


def applies(ctx):
    """Whether the step's models allow the compiled step at all: the impulse response with
    resting contact and ``next_step`` times of impact (one sub-step), the solver chosen
    automatically."""
    m, world = ctx.models, ctx.world
    return (ctx.first and m.response == "impulse" and m.resting and not ctx.exact_toi and not m.continuous
            and ctx.swept_pair is None and world.settings.solver_method == "auto")


def run(ctx):
    """The stages after detection (``stepper._impulse_step``'s prepare, impact, resting,
    correction plan, time of impact, store and advance) for the detected ``ctx.contacts`` in one
    compiled call. Returns True when it ran the step (the bodies moved;
    ``ctx`` holds what ``_finish`` reads), False when the Python stages must (nothing changed)."""
    if not applies(ctx):
        return False
    world, m = ctx.world, ctx.models
    st = world.settings
    s = world.s
    bm = world.body_masks()
    c = ctx.contacts
    k = len(c)
    cc = np.ascontiguousarray
    old = world.contact_cache.warm
    has_old = old is not None and len(old[0]) > 0
    if not has_old:
        old = _NO_OLD
    look = ctx.look_ahead
    bodies = _body_arrays(world)
    # the kinematic bodies' work is taken where the contact points are, at the sub-step's start
    # (stepper._store_impulses): their centres before the step moves them
    pos0 = s.pos.copy() if bm.any_kinematic else None
    status, near, f3, f1, flags, wv, pw, out = _step(
        cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.point, dtype=float),
        cc(c.normal, dtype=float), cc(c.depth, dtype=float), look is not None,
        *(look if look is not None else _NO_LOOK), world.gravity_norm(), world.kind,
        s.pos, s.vel, s.quat, s.omega, *bodies[:4], prepare.inv_inertia(world, m, ctx.R), ctx.R, world._gravity,
        ctx.gravity, bm.dynamic, bm.rotating, bm.kinematic, *bodies[4:9], may_be_compliant(world), *bodies[10:12],
        float(st.kinematic_stiffness), COMBINE_RULES.index(st.combine), m.friction and m.response != "kinematic",
        cc(old[0], dtype=np.int64), cc(old[1], dtype=np.int64), cc(old[2], dtype=float), cc(old[3], dtype=float),
        has_old, bodies[9],
        float(ctx.dt), float(st.contact_margin), ctx.speculative, TOI_TOLERANCE,
        SIMULTANEOUS_FRACTION * ctx.dt, REST_REBOUND_FRACTION * ctx.gdt, ctx.impact_speed,
        float(st.split_slop), float(st.split_beta),
        DIRECT_MAX_CONTACTS if st.direct_max_contacts is None else int(st.direct_max_contacts),
        int(st.solver_iterations), float(st.solver_tolerance))
    if status == NONE_NEAR:   # no contact left: the sub-step is free motion, which the Python stages run
        ctx.contacts = c.select(near)
    if status != DONE:
        return False
    if near.shape[0]:   # speculative contacts that cannot close are not the step's
        c = ctx.contacts = c.select(near)
        k = len(c)
    local, friction_impulse, impulse = f3   # views of the kernel's blocks (one returned array each)
    normal_impulse, vn0 = f1
    used, resting = flags
    vp, wp = pw
    residual, deepest, rest_bound, drift, kick_error, sweeps, kept, planned, rested, n_rest, unconverged = out.tolist()
    ctx.iterations = max(ctx.iterations, int(sweeps))
    ctx.residual = max(ctx.residual, residual)
    ctx.unconverged = ctx.unconverged or bool(unconverged)
    ctx.max_penetration = max(ctx.max_penetration, deepest)
    ctx.rest_bound += rest_bound
    if planned:   # the correction moves the bodies after the step (correction.apply)
        correction.cap(ctx, np.flatnonzero(c.depth > 0), vp, wp)
    ctx.drift += drift
    ctx.kick_error += kick_error
    # what the contact cache keeps of the resting solve (copies: never views of the step's contacts;
    # ``local`` is the kernel's own, no contact's column)
    if rested and n_rest == k:
        ctx.warm_out = (c.body_a.copy(), c.body_b.copy(), local, wv)
    elif rested:
        ri = np.flatnonzero(resting)
        ctx.warm_out = (c.body_a[ri].copy(), c.body_b[ri].copy(), local[ri].copy(), wv[:int(n_rest)].copy())
    c.normal_impulse, c.friction_impulse, c.impulse = normal_impulse, friction_impulse, impulse
    c.relative_normal_velocity = vn0
    if kept < k:   # speculative contacts that did nothing are not contacts of this step
        c, local = c.select(used), local[used]
    ctx.records.append((c, local))
    if pos0 is not None:
        ctx.kinematic_work += kinematic_work(world, c, pos0)
    ctx.first = False
    return True


def _body_arrays(world):
    """The per-body arrays ``_step`` reads that a step never replaces, in its argument order:
    ``(principal_q, principal_moments, inertia_body, inv_mass, mass, particle, restitution, friction,
    static_friction, extents, stiffness, damping_ratio)``, contiguous and of the kernel's types. Kept
    on the world while the very same arrays are there (a body added or removed, or a material assigned, replaces them) and
    only when they needed no conversion, so an edit in place is still seen."""
    s = world.s
    raw = (s.principal_q, s.principal_moments, world.inertia_body, world.inv_mass, world.mass, world.particle,
           world.restitution, world.friction, world.static_friction, world.kind, world.stiffness,
           world.damping_ratio)
    hit = world._derived.get("step_bodies")
    if hit is not None and all(map(is_, hit[0], raw)):
        return hit[1]
    cc = np.ascontiguousarray
    arrays = (cc(raw[0], dtype=float), cc(raw[1], dtype=float), cc(raw[2], dtype=float), cc(raw[3], dtype=float),
              cc(raw[4], dtype=float), cc(raw[5]), cc(raw[6], dtype=float), cc(raw[7], dtype=float),
              cc(raw[8], dtype=float), toi_mod._extents(world), cc(raw[10], dtype=float), cc(raw[11], dtype=float))
    # the extents are derived (from the shapes, which change with world.kind): the others must be the raw arrays
    if all(map(is_, arrays[:9] + arrays[10:], raw[:9] + raw[10:])):
        world._derived["step_bodies"] = (raw, arrays)
    return arrays


_NO_OLD = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 4)))
_NO_LOOK = (0.0, 0.0)


@njit
def _min(x, y):
    """numpy's ``minimum`` of two floats (the second on a tie: ``min(-0.0, 0.0)`` is ``0.0``)."""
    return x if x < y else y


@njit
def _step(a, b, point, normal, depth, look, look_dt, look_base, g, kind, pos, vel, quat, omega, principal_q, moments,
          inertia_body, inv_mass, inv_inertia, R, gravity, gravity_rows, dynamic, rotating, kinematic, mass, particle,
          restitution, friction, static_friction, may_soften, stiffness, damping_ratio, k_kinematic, rule, kinetic, a0,
          b0, p0, values, has_old, ext, dt, margin,
          speculative, toi_tolerance, simultaneous, rebound_speed, impact_speed, split_slop, split_beta, direct_max,
          max_iterations, tolerance):
    """``run``'s kernel: the stages in the Python stages' order and arithmetic. Contacts ``a, b
    (K,)``, ``point, normal (K,3)``, ``depth (K,)``; with ``look`` only the speculative ones whose
    gap can close within ``look_dt`` are kept (``stepper._velocity_stage``'s filter, with
    ``look_base`` the contact margin and ``g`` gravity's magnitude); bodies ``kind (N,)``, as
    ``free_motion.advance`` and ``pgs.build_rows`` take them, ``R (N,3,3)``, ``gravity (3,)``,
    ``gravity_rows (N,3)``, ``mass (N,)``, ``particle (N,) bool``, their materials ``restitution,
    friction, static_friction (N,)`` combined by ``rule`` (``prepare.coefficient_rows``), their
    ``stiffness, damping_ratio (N,)`` and ``k_kinematic`` (``compliance.stiffness_rows``, read when
    ``may_soften``: ``compliance.possible``); the contact
    cache ``a0, b0 (K0,)``, ``p0 (K0,3)``, ``values (K0,4)``. Returns ``(status, near (K,) or (0,), f3 (3,K,3), f1 (2,K), flags
    (2,K), wv (K,4), pw (2,N,3), out (10,))``: ``status`` ``DONE``, or with the world untouched why
    not (``LARGE``, ``NONE_NEAR``); the contacts kept by the filter when
    it dropped some (the other outputs are of those); ``f3`` the points in A's frame, the friction
    impulses and the impulses; ``f1`` the normal impulses and the approach speeds; ``flags`` the
    contacts that count and those the resting solve took; ``wv`` the cache's values of those (its
    first rows); ``pw`` the correction's pseudo-velocities ``vp, wp``; ``out = [residual, deepest,
    rest_bound, drift, kick_error, sweeps, used, planned, resting solve ran, contacts resting,
    a solve stopped unconverged]``.
    The outputs are allocated here, in blocks: from Python each allocation and argument, and here
    each array handed back, costs more than the arithmetic."""
    k, n = a.shape[0], pos.shape[0]
    # ---- relative velocity (stepper._velocity_stage): the points' velocities, the look-ahead's filter
    rel_vel = np.empty((k, 3))
    near = np.empty(k if look else 0, np.bool_)
    kept = prepare._relative_velocity(a, b, point, pos, vel, omega, kind, False, rel_vel, normal, depth, g, look_dt,
                                      look_base, near)
    if look and kept < k:
        if kept == 0:
            return (NONE_NEAR, near, np.zeros((3, 0, 3)), np.zeros((2, 0)), np.zeros((2, 0), np.bool_),
                    np.zeros((0, 4)), np.zeros((2, n, 3)), np.zeros(11))
        a, b, point, normal, depth, rel_vel = a[near], b[near], point[near], normal[near], depth[near], rel_vel[near]
        k = kept
    else:
        near = near[:0]
    # the outputs in blocks: each array handed back to Python costs more than its arithmetic here
    f3, f1, flags, wv, pw = np.empty((3, k, 3)), np.empty((2, k)), np.empty((2, k), np.bool_), np.empty((k, 4)), \
        np.zeros((2, n, 3))
    local, friction_impulse, impulse = f3[0], f3[1], f3[2]
    normal_impulse, vn0, used, resting, vp, wp = f1[0], f1[1], flags[0], flags[1], pw[0], pw[1]
    out = np.zeros(11)
    e, mu_s, mu_d = np.empty(k), np.empty(k), np.empty(k)
    prepare.coefficient_rows(a, b, restitution, friction, static_friction, rule, kinetic, e, mu_s, mu_d)
    stiff, zeta = np.zeros(k), np.zeros(k)
    n_soft = 0
    if may_soften:
        n_soft = stiffness_rows(a, b, depth, margin, stiffness, damping_ratio, kinematic, k_kinematic, rule, stiff,
                                zeta)
    soft = stiff > 0.0 if n_soft else np.zeros(0, np.bool_)
    status = _step_into(a, b, point, normal, depth, rel_vel, kind, pos, vel, quat, omega, principal_q, moments,
                        inertia_body, inv_mass, inv_inertia, R, gravity, gravity_rows, dynamic, rotating, kinematic,
                        mass, particle, e, mu_s, mu_d, stiff, zeta, soft, kinetic, a0, b0, p0, values, has_old, ext,
                        dt, margin,
                        speculative, toi_tolerance, simultaneous, rebound_speed, impact_speed, split_slop,
                        split_beta, direct_max, max_iterations, tolerance, local, normal_impulse, friction_impulse,
                        impulse, vn0, used, resting, wv, vp, wp, out)
    return status, near, f3, f1, flags, wv, pw, out


@njit
def _step_into(a, b, point, normal, depth, rel_vel, kind, pos, vel, quat, omega, principal_q, moments, inertia_body,
               inv_mass, inv_inertia, R, gravity, gravity_rows, dynamic, rotating, kinematic, mass, particle, e, mu_s,
               mu_d, stiff, zeta, soft, kinetic, a0, b0, p0, values, has_old, ext, dt, margin, speculative, toi_tolerance,
               simultaneous, rebound_speed, impact_speed, split_slop, split_beta, direct_max, max_iterations, tolerance, local,
               normal_impulse, friction_impulse, impulse, vn0, used, resting, wv, vp, wp, out):
    """``_step`` into its outputs (``e`` is overwritten: zero where the rebound rests); returns the status."""
    k = a.shape[0]
    n = pos.shape[0]
    # ---- prepare (prepare.prepare_contacts): rows, points in A's frame, classes
    vec, mat, num = np.empty((4, k, 3)), np.empty((6, k, 3, 3)), np.empty((2, k))   # the rows (rows.build_rows' blocks)
    t1, t2, ra, rb = vec[0], vec[1], vec[2], vec[3]
    ang_a, ang_b, iang_a, iang_b, K, dirs = mat[0], mat[1], mat[2], mat[3], mat[4], mat[5]
    ima, imb = num[0], num[1]
    build_rows(a, b, point, normal, pos, inv_mass, inv_inertia, rel_vel, dynamic, True, t1, t2, ra, rb, ang_a, ang_b,
               iang_a, iang_b, ima, imb, K, dirs)
    _local_points(a, point, pos, R, local)
    flags = np.empty((4, k), np.bool_)
    touching, imp, closing, bounced = flags[0], flags[1], flags[2], flags[3]
    spec_target = np.empty(k)
    e_material = e.copy()   # classify zeroes e where a rebound rests; a later impact round rules again
    counts = prepare.classify(a, b, normal, depth, rel_vel, gravity_rows, np.zeros(0), False, toi_tolerance,
                              simultaneous, margin, True, rebound_speed, impact_speed, speculative, dt, soft, e, vn0,
                              touching, imp, closing, spec_target, bounced)
    # the step's velocities: the world's only once nothing can decline any more (below: a solve
    # solver.solve_auto gives to another method); with a kinematic body, those the push cap's budget
    # is measured from in every solve of the sub-step (impact.impact_solve's ``push_ref``)
    vel_s, omega_s = vel.copy(), omega.copy()
    vel_ref, omega_ref = vel_s.copy(), omega_s.copy()
    # ---- impact (impact.impact_solve): compression with friction, then restitution, capped
    lam_i = np.zeros((k, 3))
    vn1 = vn0
    it_i, residual_i, unconverged = 0, 0.0, False
    if counts.impact or counts.closing:
        vn1 = np.empty(k)
        status, it_i, residual_i, unconverged = _impact(a, b, point, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K,
                                                        touching, closing, bounced, spec_target, e, e_material, soft,
                                                        vn0, rebound_speed, impact_speed, mu_s, mu_d, kinetic, kind,
                                                        dynamic, kinematic, mass, particle, pos, quat, inertia_body,
                                                        direct_max, max_iterations, tolerance, vel_s, omega_s,
                                                        vel_ref, omega_ref, lam_i, vn1)
        if status != DONE:
            return status
    # ---- position correction's plan (correction.plan): split-impulse pseudo-velocities ``vp, wp``
    # for the penetrating contacts, frictionless; the cap on how far they move stays in Python
    planned = False
    if counts.deepest > split_slop:
        pen = penetrating(depth, soft, a, b, dynamic)   # correction.penetrating: rigid, no body held by a spring
        if pen.shape[0]:
            p = pen.shape[0]
            ptarget = np.empty(p)
            for i in range(p):
                ptarget[i] = split_beta * depth[pen[i]] / dt
            pzeros = np.zeros(p)
            plan, _, _ = _exact(a[pen], b[pen], dirs[pen], ang_a[pen], ang_b[pen], iang_a[pen], iang_b[pen], ima[pen],
                                imb[pen], K[pen], ptarget, pzeros, pzeros, pzeros, False, np.zeros((p, 3)), False, dynamic,
                                direct_max, max_iterations, tolerance, vp, wp, np.zeros((p, 3)))
            if plan != DONE:
                return plan
            planned = True
    # ---- resting solve (resting.resting_solve): the constant force over the step, warm started, on
    # every contact but those that just rebounded (none when every contact rebounded)
    rested = not (counts.bounced > 0 and np.all(vn1 > impact_speed))
    kr, it_r, residual_r, rest_bound = 0, 0, 0.0, 0.0
    lam_r = np.zeros((k, 3))
    half_dv, half_dw = np.zeros((0, 3)), np.zeros((0, 3))   # the force's half-kicks (none unless it rests)
    if rested:
        for c in range(k):
            # beside a compliant contact a rebounding one stays in (resting.resting_solve)
            resting[c] = soft.shape[0] > 0 or not (bounced[c] and vn1[c] > impact_speed)
            kr += resting[c]
        ri = np.flatnonzero(resting)
        # every contact rests (the usual case): the arrays as they are, no gathers
        whole = kr == k
        sa, sb = (a, b) if whole else (a[ri], b[ri])
        sdirs, sang_a, sang_b = (dirs, ang_a, ang_b) if whole else (dirs[ri], ang_a[ri], ang_b[ri])
        siang_a, siang_b, sK = (iang_a, iang_b, K) if whole else (iang_a[ri], iang_b[ri], K[ri])
        sima, simb, slocal = (ima, imb, local) if whole else (ima[ri], imb[ri], local[ri])
        smu_s, smu_d = (mu_s, mu_d) if whole else (mu_s[ri], mu_d[ri])
        v_end = np.empty((n, 3))
        for i in range(n):
            for x in range(3):
                v_end[i, x] = vel_s[i, x] + gravity_rows[i, x] * dt
        w_end = omega_s.copy()
        v_start_end = v_end.copy()
        w_start_end = w_end.copy()
        target = np.empty(kr)
        for j in range(kr):
            c = ri[j]
            target[j] = _min(2.0 * _min(depth[c], 0.0) / dt - vn1[c], 0.0)
        warm = np.zeros((kr, 3))
        use_warm = has_old and kr > 0 and _warm_start(a0, b0, p0, sa, sb, slocal, ext, MATCH_FRACTION, values, dt,
                                                      sdirs, smu_d, warm)
        lam = np.zeros((kr, 3))
        compliance = np.zeros(kr)
        if soft.shape[0]:   # the compliant rows: their spring's target and compliance (compliance.soft_rows)
            soft_rows(ri, K, depth, vn1, stiff, zeta, dt, target, compliance)
        solved, it_r, residual_r = _exact(sa, sb, sdirs, sang_a, sang_b, siang_a, siang_b, sima, simb, sK, target,
                                          compliance, smu_s, smu_d, kinetic, warm, use_warm, dynamic, direct_max, max_iterations,
                                          tolerance, v_end, w_end, lam)
        if solved != DONE:
            return solved
        # where kinematic bodies push, no body ends faster than a push can make it (resting.resting_solve)
        ca, cb, cpoint = sa, sb, point if whole else point[ri]
        if soft.shape[0]:   # the push cap is the rigid contacts' (resting.resting_solve)
            rig = np.flatnonzero(compliance == 0.0)
            ca, cb, cpoint = ca[rig], cb[rig], cpoint[rig]
        u = push_speed(ca, cb, cpoint, kinematic, pos, vel_s, omega_s)
        if u >= 0.0:
            pb = dynamic_bodies(ca, cb, dynamic)
            vref = vel_ref[pb]
            for j in range(pb.shape[0]):
                for x in range(3):
                    vref[j, x] = vref[j, x] + gravity_rows[pb[j], x] * dt
            f = push_cap_kernel(pb, u, mass, particle, quat, inertia_body, v_start_end[pb], w_start_end[pb], vref,
                                omega_ref[pb], v_end, w_end)
            if f < 1.0:
                for j in range(kr):
                    for x in range(3):
                        lam[j, x] = lam[j, x] * f
        rest_bound = _work_bound(sa, sb, sdirs, sang_a, sang_b, vel_s, omega_s, v_end, w_end, target, lam)
        _warm_record(lam, sdirs, wv[:kr])
        for j in range(kr):
            for x in range(4):
                wv[j, x] = wv[j, x] / dt
            for x in range(3):
                lam_r[ri[j], x] = lam[j, x]
        # the force's velocity change over the step, as two half-kicks (stepper._advance_stage)
        half_dv, half_dw = np.empty((n, 3)), np.empty((n, 3))
        for i in range(n):
            for x in range(3):
                half_dv[i, x] = 0.5 * (v_end[i, x] - v_start_end[i, x]) * 1.0
                half_dw[i, x] = 0.5 * (w_end[i, x] - w_start_end[i, x]) * 1.0
    # ---- store impulses (stepper._store_impulses, record): the impact impulse plus the resting
    # impulse over the whole step
    kept = 0
    for c in range(k):
        if rested:
            ln, l1, l2 = lam_i[c, 0] + lam_r[c, 0] * 1.0, lam_i[c, 1] + lam_r[c, 1] * 1.0, lam_i[c, 2] + lam_r[c, 2] * 1.0
        else:
            ln, l1, l2 = lam_i[c, 0], lam_i[c, 1], lam_i[c, 2]
        normal_impulse[c] = ln
        for x in range(3):
            friction_impulse[c, x] = l1 * t1[c, x] + l2 * t2[c, x]
            impulse[c, x] = ln * normal[c, x] + friction_impulse[c, x]
        used[c] = not speculative or touching[c] or ln > 0.0
        kept += used[c]
    # ---- advance (stepper._advance_stage): kick half, drift, kick half (free motion when nothing rests)
    vel[:] = vel_s
    omega[:] = omega_s
    drift, kick_error = advance(pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating,
                                kinematic, half_dv, half_dw, rested, dt, ISOTROPIC_TOLERANCE,
                                MAX_SPLIT_ANGLE, MAX_SUBSTEPS)
    out[0], out[1], out[2], out[3] = max(residual_i, residual_r), counts.deepest, rest_bound, drift
    out[4] = kick_error if rested else 0.0
    out[5], out[6], out[7], out[8], out[9] = max(it_i, it_r), kept, planned, rested, kr
    out[10] = unconverged or (it_r >= max_iterations and residual_r > tolerance)
    return DONE


@njit
def _impact(a, b, point, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, touching, closing, bounced, spec_target, e,
            e_material, soft, vn0, rebound_speed, impact_speed, mu_s, mu_d, kinetic, kind, dynamic, kinematic, mass,
            particle, pos, quat, inertia_body, direct_max, max_iterations, tolerance, vel, omega, vel_ref, omega_ref,
            lam, vn1):
    """``impact.impact_solve`` (the impulse response) on the rows of ``_step``, round by round
    (``impact.next_round``; ``bounced (K,)`` gains every contact that bounced in a later round).
    Updates ``vel, omega (N,3)``, writes the impulses ``lam (K,3)`` and the normal velocities after
    ``vn1 (K,)``. Returns ``(DONE, sweeps, residual, unconverged)`` (a solve stopped at
    ``max_iterations`` with its impulses still changing by more than ``tolerance``), or ``(LARGE, 0,
    0.0, False)`` for a solve ``solver.solve_auto`` gives to another method."""
    k = a.shape[0]
    take = (touching & (vn0 <= tolerance)) | closing
    if soft.shape[0]:   # a compliant contact takes no impact (impact.impact_solve)
        take &= ~soft
    er, hit, vn = e, bounced, vn0
    e_next, hit_next = np.empty(k), np.empty(k, np.bool_)
    it, residual, unconverged = 0, 0.0, False
    for _ in range(IMPACT_ROUNDS):
        status, it_r, residual_r, stopped = _impact_round(np.flatnonzero(take), a, b, point, dirs, ang_a, ang_b,
                                                          iang_a, iang_b, ima, imb, K, touching, hit, spec_target, er,
                                                          vn, mu_s, mu_d, kinetic, kind, dynamic, kinematic, mass,
                                                          particle, pos, quat, inertia_body, direct_max,
                                                          max_iterations, tolerance, vel, omega, vel_ref, omega_ref,
                                                          lam)
        if status != DONE:
            return status, 0, 0.0, False
        it, residual, unconverged = max(it, it_r), max(residual, residual_r), unconverged or stopped
        normal_velocities(a, b, dirs, ang_a, ang_b, vel, omega, vn1)
        if not next_round(touching, spec_target, vn1, e_material, True, rebound_speed, impact_speed, tolerance, soft, take,
                          e_next, hit_next):
            break
        for c in range(k):
            bounced[c] = bounced[c] or hit_next[c]
        er, hit, vn = e_next.copy(), hit_next.copy(), vn1.copy()
    return DONE, it, residual, unconverged


@njit
def _impact_round(ti, a, b, point, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, touching, bounced, spec_target, e,
                  vn, mu_s, mu_d, kinetic, kind, dynamic, kinematic, mass, particle, pos, quat, inertia_body,
                  direct_max, max_iterations, tolerance, vel, omega, vel_ref, omega_ref, lam):
    """``impact._round``: compression on the contacts ``ti`` (touching ones stopped, the others
    slowed to ``spec_target``), then restitution up to ``−e·vn`` where ``bounced`` (the other pressed
    touching contacts held), scaled by the energetic cap (``energy.restitution_cap``); the round's
    impulses added to ``lam (K,3)``.
    Returns ``(DONE, sweeps, residual, unconverged)`` or ``(LARGE, 0, 0.0, False)``."""
    k = a.shape[0]
    nt = ti.shape[0]
    bounces = False
    for c in ti:
        bounces = bounces or e[c] * bounced[c] > 0.0
    # the kinetic energy the round starts from, for the restitution stage's cap, in the frame of the
    # kinematic body the impact is against (energy.impact_frame)
    ta, tb = a[ti], b[ti]
    bodies0 = dynamic_bodies(ta, tb, dynamic)
    frame = np.zeros((3, 3))
    code = frame_of(kind, ta, tb, vel, omega, pos, frame) if bounces else NO_FRAME
    kinetic0 = kinetic_in(bodies0, mass, particle, quat, inertia_body, vel, omega, pos, frame, code == FRAME) \
        if bounces and code != NO_FRAME else 0.0
    # where kinematic bodies push, no body ends faster than a push can make it (energy.push_cap)
    u = push_speed(ta, tb, point[ti], kinematic, pos, vel, omega)
    if u >= 0.0:
        pb = bodies0
        v0, w0 = vel[pb], omega[pb]
    target = np.empty(nt)
    for j in range(nt):
        target[j] = 0.0 if touching[ti[j]] else spec_target[ti[j]]
    lam_t = np.zeros((nt, 3))
    status, it, residual = _exact(a[ti], b[ti], dirs[ti], ang_a[ti], ang_b[ti], iang_a[ti], iang_b[ti], ima[ti],
                                  imb[ti], K[ti], target, np.zeros(nt), mu_s[ti], mu_d[ti], kinetic, np.zeros((nt, 3)), False,
                                  dynamic, direct_max, max_iterations, tolerance, vel, omega, lam_t)
    if status != DONE:
        return status, 0, 0.0, False
    unconverged = it >= max_iterations and residual > tolerance
    scale = 1.0
    if u >= 0.0:
        scale = push_cap_kernel(pb, u, mass, particle, quat, inertia_body, v0, w0, vel_ref[pb], omega_ref[pb], vel,
                                omega)
    lam_r = np.zeros((k, 3))
    for j in range(nt):
        for x in range(3):
            lam_r[ti[j], x] = lam_t[j, x] * scale
    vel_c, omega_c = vel[bodies0], omega[bodies0]   # copies: the velocities after compression
    pressed = lam_r[:, 0] > 0.0
    hit = bounced & pressed & (e > 0.0)   # e = 0: the compression was the whole impact
    nh = 0
    hi = np.zeros(0, np.int64)
    if np.any(hit):   # with the pressed touching contacts that do not bounce, held at v_n ≥ 0
        hi = np.flatnonzero(hit | (pressed & touching & ~bounced))
        nh = hi.shape[0]
    if nh:
        target_h = np.empty(nh)
        for j in range(nh):
            target_h[j] = -e[hi[j]] * vn[hi[j]] if hit[hi[j]] else 0.0
        zeros = np.zeros(nh)
        lam_h = np.zeros((nh, 3))
        status, it_h, residual_h = _exact(a[hi], b[hi], dirs[hi], ang_a[hi], ang_b[hi], iang_a[hi], iang_b[hi],
                                          ima[hi], imb[hi], K[hi], target_h, zeros, zeros, zeros, False, np.zeros((nh, 3)),
                                          False, dynamic, direct_max, max_iterations, tolerance, vel, omega, lam_h)
        if status != DONE:
            return status, 0, 0.0, False
        unconverged = unconverged or (it_h >= max_iterations and residual_h > tolerance)
        f = 1.0 if code == NO_FRAME else restitution_cap_in(bodies0, mass, particle, quat, inertia_body, kinetic0,
                                                            vel_c, omega_c, vel, omega, pos, frame, code == FRAME)
        if u >= 0.0:   # the rebound within the push budget too (with a static body: no frame)
            f *= push_cap_kernel(pb, u, mass, particle, quat, inertia_body, vel_c, omega_c, vel_ref[pb],
                                 omega_ref[pb], vel, omega)
        for j in range(nh):
            lam_r[hi[j], 0] += lam_h[j, 0] * f
        it = max(it, it_h)
    for c in range(k):
        for x in range(3):
            lam[c, x] += lam_r[c, x]
    return DONE, it, residual, unconverged


@njit
def _finish(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d, kinetic, lam,
            vel, omega, iterations, tolerance):
    """Gauss–Seidel on the contacts ``ids (U,)`` that the active set left unfinished, from their
    impulses in ``lam (K,3)`` (``solver.solve`` on ``rows.select(ids)``: the warm impulses applied,
    then ``pgs.sweeps`` on the gathered rows); writes their impulses into ``lam`` and the
    velocities into ``vel, omega``. Returns ``(sweeps, residual)``."""
    u = ids.shape[0]
    ua, ub = a[ids], b[ids]
    udirs, uang_a, uang_b, uiang_a, uiang_b, uK = dirs[ids], ang_a[ids], ang_b[ids], iang_a[ids], iang_b[ids], K[ids]
    uima, uimb, utarget = ima[ids], imb[ids], target[ids]
    ulam = lam[ids]
    friction = kinetic and np.any(mu_s[ids] > 0.0)
    zeros = np.zeros(u)
    umus = mu_s[ids] if friction else zeros
    umud = mu_d[ids] if friction else zeros
    if np.any(ulam != 0.0):
        apply_ids(np.arange(u), ua, ub, udirs, uiang_a, uiang_b, uima, uimb, ulam, vel, omega)
    it, residual = sweeps(ua, ub, udirs, uang_a, uang_b, uiang_a, uiang_b, uima, uimb, uK, utarget, compliance[ids],
                          umus, umud, friction, ulam, vel, omega, iterations, tolerance)
    for i in range(u):
        for x in range(3):
            lam[ids[i], x] = ulam[i, x]
    return it, residual


@njit
def _exact(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d, kinetic, warm,
           use_warm, dynamic, direct_max, max_iterations, tolerance, vel, omega, lam):
    """``solver.solve_auto``'s exact branch on the rows given (``k`` contacts; ``warm (k,3)`` read
    when ``use_warm``; ``compliance (k,)`` the normal rows' regulariser, 0 rigid): the active set per island (``active_set.solve_islands``), the impulses
    applied to ``vel, omega (N,3)``, Gauss–Seidel finishing the islands it left unfinished
    (``_finish``). Returns ``(DONE, sweeps, residual)``, or ``LARGE`` where ``solve_auto`` would
    take another branch (more than ``direct_max`` contacts; Gauss–Seidel first for a large island;
    the sparse active set for an island the dense kernel does not take): ``vel, omega`` may then
    hold part of a solve, and the caller discards them."""
    k = a.shape[0]
    # contacts between two bodies that cannot move (a kinematic link pressed into a static floor)
    # carry no impulse: their rows have no effective mass (solver.solve_auto)
    n_live = 0
    for c in range(k):
        n_live += dynamic[a[c]] or dynamic[b[c]]
    if n_live < k:
        li = np.empty(n_live, np.int64)
        j = 0
        for c in range(k):
            if dynamic[a[c]] or dynamic[b[c]]:
                li[j] = c
                j += 1
        if n_live == 0:
            return DONE, 0, 0.0
        lam_l = np.zeros((n_live, 3))
        status, it, residual = _exact(a[li], b[li], dirs[li], ang_a[li], ang_b[li], iang_a[li], iang_b[li], ima[li],
                                      imb[li], K[li], target[li], compliance[li], mu_s[li], mu_d[li], kinetic,
                                      warm[li], use_warm, dynamic, direct_max, max_iterations, tolerance, vel,
                                      omega, lam_l)
        for j in range(n_live):
            for x in range(3):
                lam[li[j], x] = lam_l[j, x]
        return status, it, residual
    if k > direct_max:
        return LARGE, 0, 0.0
    order, start = islands(a, b, dynamic, vel.shape[0])
    if DIRECT_FIRST < k:
        for i in range(start.shape[0] - 1):
            if start[i + 1] - start[i] > DIRECT_ISLAND_MAX:
                return LARGE, 0, 0.0
    friction = kinetic and np.any(mu_s > 0.0)
    zeros = np.zeros(k)
    mus = mu_s if friction else zeros
    mud = mu_d if friction else zeros
    status = np.empty(k, np.int64)
    residual = solve_islands(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance, mus,
                             mud,
                             friction, warm, use_warm, DIRECT_ISLAND_MAX, DIRECT_REGULARISATION, DIRECT_CONSISTENCY,
                             DIRECT_MAX_ROUNDS, vel, omega, True, lam, status)
    for c in range(k):
        if status[c] == TOO_LARGE:   # larger than the dense kernel takes, or its factorisation failed
            return LARGE, 0, 0.0
    unfinished = np.flatnonzero(status != SOLVED)
    if unfinished.shape[0] == 0:
        return DONE, 1, residual
    # sliding friction or an inconsistent set: Gauss–Seidel finishes those islands from the start
    # the active set left (solver.solve_auto's direct branch, solver.solve)
    sweeps, res = _finish(unfinished, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s,
                          mu_d, kinetic, lam, vel, omega, max_iterations, tolerance)
    return DONE, sweeps, max(res, residual)
