"""The step pipeline: detection, impacts, resting contact, time of impact, free motion.

``World.step`` calls ``step(world, dt)``. One step of ``dt``, with ``T`` the time left:

1. detect contacts (margin ``settings.contact_margin``, or the speculative look-ahead), and
   prepare them (rows, coefficients, approach speeds);
2. **impacts** (``response.impact``): touching contacts that approach get instantaneous impulses with restitution
   (kinematic response: ``v+ = v − (1+k)(N·v)N`` without rotation; impulse response: the lecture's
   ``j`` with both bodies' world inverse inertia, Coulomb friction), solved together by projected
   Gauss–Seidel (``response.solver``);
3. **resting contact** (when on; ``response.resting``, warm started from ``World.contact_cache``): contacts that stay touching get the impulse that acts as a constant
   force over ``T``: non-negative, zero when separating, the normal velocity at the end of ``T`` not
   approaching (no sinking), friction inside the cone (sticking = stopped at the end of ``T``);
4. **time of impact**: ``next_step`` advances by ``T``; ``fractional`` and ``swept`` find the first
   instant in ``(0, T]`` at which a pair that is apart touches (closed form for sphere–plane and
   sphere–sphere, bracket + Brent otherwise; ``swept`` guarantees that nothing passes through a
   thin body; a pair in contact: the instant it sinks ``TOI_DEEPEN`` deeper), advance exactly to
   it and go back to 1 with the rest of the step — at most ``settings.max_impacts_per_step`` times;
5. positions of penetrating contacts are corrected by split-impulse pseudo-velocities, which move
   bodies and are then discarded (no energy is added; ``response.correction``).

``_impulse_step`` reads as this list: detection, then one compiled call per sub-step for the
stages after it (``response.substep``: 1's preparation, 2, 3, 5's plan, and the advance), whatever
the models; the time-of-impact search (4) runs between its solves and its advance when the models
ask for exact times of impact. A sub-step that no time of impact can shorten (every step of
``next_step`` without fast bodies) runs detection in that same call (``substep.run_detected``)
wherever the broad phase's pair cache holds; detection runs in Python first where it does not
(the first step, a body out of its fat box), and where Python must read the contacts before the
solve (a pose's work on compliant contacts, a sweep's hit). Each stage's kernel lives in its
stage's module (``prepare``, ``impact``, ``resting``, ``correction``, ``free_motion``), every
solve is ``solver.solve_rows``.

Penalty response replaces 2–5 by a spring ``k·depth`` and damper ``−c·v_n`` along the normal, and
(friction on) regularised Coulomb friction (``response.penalty``), in one compiled call too
(``substep.run_penalty``).

``world.contacts`` gets the contacts of the step with the impulses applied to A (normal and
friction parts), ``world.last_solve`` a ``StepStats`` with the solver's iterations, residual,
maximum penetration at the start of the step, contact and impact counts, the models used and the
energy terms the step declares.
"""
import time
from dataclasses import fields
from operator import is_

import numpy as np

from .constants import FAT_STEPS, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS
from .contacts import Contacts
from .free_motion import advance, all_finite
from . import validate
from .jit import njit
from .response import models as _models
from .collision import (DetectionStats, _bodies_of, _NO_KEYS, broadphase, detect_world, disabled_keys,
                        rebuild_pair_cache)
from .collision.vec3 import rotations
from .response import toi as toi_mod
from .response import compliance, correction, prepare, substep, swept
from .response.cache import merge_records
from .response.context import StepContext
from .response.energy import pose_work


def describe_models(world):
    """What ``step`` will use for ``world`` and why (``list[str]``), with preflight warnings."""
    return _models.describe(world)


def step(world, dt, m):
    """Advance ``world`` by ``dt`` (already validated, > 0) with the models ``m`` (``models.choose``'s
    for this step: ``flight`` chose them)."""
    if world.contact_cache.preflight_dt != dt:
        world.contact_cache.preflight_dt = dt
        _models.warn_preflight(world, m, dt)
    if m.response == "penalty":
        _penalty_step(world, dt, m)
    else:
        _impulse_step(world, dt, m)
    s = world.s
    # where this step left the bodies (centre, then orientation): a pose given before the next moves
    # a kinematic one at once (energy.pose_work)
    _stepped(s.pos, s.quat, s.stepped)
    world.time += dt


@njit(_nrt=False)
def _stepped(pos, quat, stepped):
    """``stepped (N,7)`` = ``pos (N,3)``, then ``quat (N,4)``, per row (``np.concatenate``'s values at a
    quarter of its call's cost)."""
    for i in range(pos.shape[0]):
        for x in range(3):
            stepped[i, x] = pos[i, x]
        for x in range(4):
            stepped[i, 3 + x] = quat[i, x]


# ---------------------------------------------------------------------------- free flight
#: ``_flight``'s answers: the step is done; a body left its fat box (the pair cache must be rebuilt);
#: the full pipeline must take it (a pair is near, or the motion would not be finite: the full step
#: then names the bodies)
FLOWN, STALE, DECLINED = 0, 1, 2


def flight(world, dt):
    """The step of ``dt`` when nothing is near anything: one compiled call (``_flight``) runs the
    stages that have work in it, detection's broad phase (with the look-ahead margin) and the
    advance, and the step's outputs are those of a step without contacts. Returns None when it
    stepped the world; otherwise the world is unchanged and it returns the models it chose, for
    ``step`` to take the step through the whole pipeline.

    It is tried only where the step before found no candidate pair (``world.last_detection``): in a
    scene at rest the broad phase would find pairs and run twice. It declines what the pipeline
    does besides the advance even without contacts: the penalty response, exact times of impact and
    the time-of-impact search of ``next_step``'s fast bodies, a pair cache never built, the
    first step of a ``dt`` (its preflight warnings). All or nothing: the state arrays are written
    only when the step is done and finite. The same kernels in the same order as the pipeline, so
    the same state, contacts and statistics to the bit (``test/test_flight.py``); only the pair
    cache's counters can differ, where a cache rebuilt here finds a pair: the pipeline's pass on it
    then counts a reuse that a rebuild inside the pipeline would not."""
    plan = _plan(world, dt)
    m = plan[0]
    if plan[1] is not None and _models._any_too_fast(world.s.vel, world.kind, plan[1], world.gravity_norm(),
                                                     float(dt)):
        return _models.choose(world, dt)   # a thin body is fast this step: its own models (swept), declined
    det = world._last_detection   # a DetectionStats, or its fields (``World.last_detection``)
    bodies = plan[3]
    cache = bodies.pair_cache
    cached = cache.args if bodies.n >= 2 else _NO_PAIRS
    if (plan[2] is None or cached is None or det is None
            or (det[_CANDIDATES] if det.__class__ is tuple else det.candidate_pairs)
            or world.contact_cache.preflight_dt != dt):
        return m
    t0 = time.perf_counter()
    s = world.s
    status, drift, margin = _flight(s.pos, s.vel, s.quat, s.omega, s.stepped, *plan[2], *cached)
    rebuilt = status == STALE
    if rebuilt:
        # a body left its fat box: the cache rebuilt as detection rebuilds it, then the pass again
        R = np.empty((len(s.pos), 3, 3))
        rotations(s.quat, R)
        rebuild_pair_cache(world, bodies, s.pos, R, margin, FAT_STEPS * dt)
        status, drift, margin = _flight(s.pos, s.vel, s.quat, s.omega, s.stepped, *plan[2], *cache.args)
    if status != FLOWN:
        return m
    if not rebuilt and bodies.n >= 2:
        cache.reuses += 1
    seconds = time.perf_counter() - t0
    # what a step without contacts leaves (``_finish``): no warm start, no contact, its statistics
    # (the statistics as their fields, made into their classes when read: ``World.last_solve``)
    world.contact_cache.warm = None
    if world.contacts.depth.shape[0]:   # an empty one stays: it says the same
        world.contacts = Contacts.empty()
    world._last_detection = (plan[3].n, 0, 0, 0, 0, None, 0, 0, 0, plan[4], margin,
                             {"prepare": 0.0, "broad": seconds, "total": seconds})
    world._last_solve = (0, 0.0, False, 0.0, 0, 0, m.toi, m.response, 0.0, 0.0, 0.0, 0.0 + drift,
                         0.0, 0.0)   # 0.0 + drift: the sum the pipeline forms (-0.0 -> 0.0)
    world.time += dt
    return None


_EXACT = ("fractional", "swept")
#: where ``candidate_pairs`` is among a ``DetectionStats``' fields, as a step keeps them (``World.last_detection``)
_CANDIDATES = [f.name for f in fields(DetectionStats)].index("candidate_pairs")
_NO_BOX = np.zeros((0, 3))
#: the pair cache's arguments of ``_flight`` for one body or none (no pair: never read)
_NO_PAIRS = (_NO_BOX, _NO_BOX, _NO_KEYS, _NO_KEYS, -1.0, np.empty(64, np.int64))


def _plan(world, dt):
    """What ``flight`` reads that the scene fixes, for a step of ``dt`` (s): ``(models, limit,
    args, shapes, bounding_volume)``: the models when no body is thin-and-fast (``models.choose``'s
    kept answer) and, for an ``auto`` time of impact, the limits ``(N,)`` its velocity test reads
    (else None); ``_flight``'s arguments after the state arrays and before the pair cache's
    (``pack``'s blocks and the kind array), or None where the flight declines whatever the motion
    (the penalty response, exact or continuous times of impact); the world's shape arrays
    (``collision._bodies_of``). Kept on the world while the settings object, its edits
    (``validate.edits``), ``dt``, the body and material arrays, gravity, the masks and the disabled
    pairs are the same, so a step in flight checks once what it would otherwise gather anew."""
    st, s, shapes = world.settings, world.s, world.shapes
    key = (st, shapes[-1] if shapes else None, world.kind, world.particle, world.friction, world.restitution,
           world.stiffness, world.damping_ratio, world._gravity, world.group, world.mask, world.disabled_pairs,
           s.principal_q, s.principal_moments, world.inertia_body)
    hit = world._derived.get("flight_plan")
    if (hit is not None and hit[1] == validate.edits and hit[2] == dt and all(map(is_, hit[0], key))
            and hit[3] == world.kind.tobytes()):
        return hit[4]
    edits = validate.edits
    m, limit = _models._kept_models(world, st, dt)
    bodies = _bodies_of(world)
    args = None
    if not (m.response == "penalty" or m.toi in _EXACT or m.continuous):
        bm = world.body_masks()
        args = (*pack(s.principal_q, s.principal_moments, world.inertia_body, world._gravity, bm.dynamic, bm.rotating,
                      bm.kinematic, st.speculative, *prepare._margin_facts(world), float(st.contact_margin),
                      world.gravity_norm() * dt * dt, bodies.n >= 2, bodies.finite, bodies.aabb_c, bodies.aabb_h,
                      bodies.planes, bodies.plane_n, bodies.plane_d, world.group, world.mask,
                      disabled_keys(world) if world.disabled_pairs else _NO_KEYS, float(dt)),
                world.kind)
    plan = (m, limit if st.toi == "auto" else None, args, bodies, st.bounding_volume)
    world._derived["flight_plan"] = (key, edits, dt, world.kind.tobytes(), plan)
    return plan


def pack(principal_q, moments, inertia_body, gravity, dynamic, rotating, kinematic, speculative, ext, moving, caps, cap,
         plane, base, g, pairs, fin, centre, half, planes, plane_n, plane_d, group, mask, disabled, dt):
    """What ``_flight`` reads that the scene fixes, in four blocks by type, so that the call takes
    four arguments for ~30 (numba wraps each argument at every call, ~30 ns each): ``(F, B, I,
    U)``, copies. ``F`` float64: ``principal_q (N,4), moments (N,3), inertia_body (N,3,3),
    gravity (3,), ext, caps (N,), centre, half, plane_n (N,3), plane_d (N,)``, then ``cap, base,
    g, dt`` and the workspace ``(24N + 6M,)``; ``B`` bool: ``dynamic, rotating, kinematic, moving
    (N,)``, then ``speculative, plane, pairs``; ``I`` int64: ``M, P, E``, then ``fin (M,), planes
    (P,), disabled (E,)``; ``U`` uint32: ``group, mask (N,)``. Arguments as ``_flight``'s before
    (``prepare._margin_facts``' ``ext, moving, caps, cap, plane``; ``base`` the contact margin (m),
    ``g = |g| dt²`` (m), ``dt`` (s); ``collision._bodies_of``' shape arrays; ``world_pairs``'
    masks and disabled keys). The World replaces these arrays when it changes them, never edits
    them in place, so a plan's copies hold while the plan's key does."""
    n, m = len(principal_q), len(fin)
    F = np.concatenate((principal_q.ravel(), moments.ravel(), inertia_body.ravel(), gravity, ext, caps, centre.ravel(),
                        half.ravel(), plane_n.ravel(), plane_d, (cap, base, g, dt), np.zeros(24 * n + 6 * m)))
    B = np.concatenate((dynamic, rotating, kinematic, moving, (speculative, plane, pairs))).astype(np.bool_)
    I = np.concatenate(((m, len(planes), len(disabled)), fin, planes, disabled)).astype(np.int64)
    U = np.concatenate((group, mask)).astype(np.uint32)
    return F, B, I, U


@njit(_nrt=False)
def _flight(pos, vel, quat, omega, stepped, F, B, I, U, kind, fat_c, fat_h, ci, cj, fat_margin, keys):
    """``flight``'s compiled step: the detection margin as ``prepare.speculative_reach`` and
    ``_detect_stage`` make it (``base`` the contact margin, ``g = |g| dt²``; with ``speculative``
    the look-ahead of ``ext, moving, caps (N,)``, ``cap``, ``plane``: ``prepare._margin_facts``),
    then with ``pairs`` (two bodies or more) the broad phase's pass on the pair cache ``fat_c,
    fat_h (M,3), ci, cj (C,)``, ``fat_margin`` (``broadphase.cached_keys`` and ``may_touch``,
    arguments as ``world_pairs``'); when it finds no pair, the advance (``free_motion.advance``,
    no kicks) in place, with where the step left the bodies into ``stepped (N,7)`` when all is
    finite, else the state put back. What the scene fixes comes in the blocks ``F, B, I, U``
    (``pack``: F's tail is the workspace) and ``kind (N,) int8``; ``keys (≥ C + P·M,) int64`` is
    a workspace (``world_pairs``' sizes). It allocates nothing, so it is compiled without
    reference counts: its arrays would otherwise each be wrapped for numba's counting at every
    call. Returns ``(FLOWN, STALE or DECLINED, drift (J), margin (m))``, the state unchanged
    unless ``FLOWN``."""
    n, m, p, e = pos.shape[0], I[0], I[1], I[2]
    fin, planes, disabled = I[3:3 + m], I[3 + m:3 + m + p], I[3 + m + p:3 + m + p + e]
    group, mask = U[:n], U[n:2 * n]
    dynamic, rotating, kinematic, moving = B[:n], B[n:2 * n], B[2 * n:3 * n], B[3 * n:4 * n]
    speculative, plane, pairs = B[4 * n], B[4 * n + 1], B[4 * n + 2]
    principal_q = F[:4 * n].reshape((n, 4))
    moments = F[4 * n:7 * n].reshape((n, 3))
    inertia_body = F[7 * n:16 * n].reshape((n, 3, 3))
    gravity = F[16 * n:16 * n + 3]
    o = 16 * n + 3
    ext, caps = F[o:o + n], F[o + n:o + 2 * n]
    centre = F[o + 2 * n:o + 5 * n].reshape((n, 3))
    half = F[o + 5 * n:o + 8 * n].reshape((n, 3))
    plane_n = F[o + 8 * n:o + 11 * n].reshape((n, 3))
    plane_d = F[o + 11 * n:o + 12 * n]
    o += 12 * n
    cap, base, g, dt = F[o], F[o + 1], F[o + 2], F[o + 3]
    o += 4
    no_kick = F[o:o].reshape((0, 3))
    reach = F[o:o + 2 * n].reshape((2, n))
    R = F[o + 2 * n:o + 11 * n].reshape((n, 3, 3))
    kept = F[o + 11 * n:o + 24 * n].reshape((n, 13))
    boxes = F[o + 24 * n:o + 24 * n + 6 * m].reshape((2, m, 3))
    margin, plane_margin = base, base
    if speculative:
        look, plane_look, _ = prepare.look_ahead(vel, omega, ext, moving, caps, cap, plane, base, g, dt, reach)
        if look > base:   # else no speculative contact: every pair takes the contact margin
            margin, plane_margin = look, plane_look
    if pairs:
        rotations(quat, R)
        count = broadphase.cached_keys(pos, R, fin, centre, half, planes, plane_n, plane_d, fat_c, fat_h, ci, cj,
                                       fat_margin, margin, plane_margin, boxes[0], boxes[1], keys)
        if count < 0:
            return STALE, 0.0, margin
        for k in range(count):
            if broadphase.may_touch(keys[k], n, kind, group, mask, disabled):
                return DECLINED, 0.0, margin
    for i in range(n):   # the state before, put back if the motion is not finite
        for x in range(3):
            kept[i, x], kept[i, 3 + x], kept[i, 6 + x] = pos[i, x], vel[i, x], omega[i, x]
        for x in range(4):
            kept[i, 9 + x] = quat[i, x]
    drift, _ = advance(pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating, kinematic,
                       no_kick, no_kick, False, dt, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS)
    finite = all_finite(pos, vel, quat, omega)
    for i in range(n):
        for x in range(3):
            if finite:
                stepped[i, x] = pos[i, x]
            else:
                pos[i, x], vel[i, x], omega[i, x] = kept[i, x], kept[i, 3 + x], kept[i, 6 + x]
        for x in range(4):
            if finite:
                stepped[i, 3 + x] = quat[i, x]
            else:
                quat[i, x] = kept[i, 9 + x]
    return (FLOWN if finite else DECLINED), drift, margin


# ---------------------------------------------------------------------------- helpers
def _detect(world, margin, dt, R=None, reach=None, floor=0.0, plane_margin=None):
    """Contacts of the current state within ``margin`` (``R (N,3,3)`` the rotation matrices, when
    known; ``reach, floor``: each pair's own margin, ``detect_world``) in a step of ``dt`` (s): the
    broad phase's cache covers ``FAT_STEPS`` such steps of motion; the detection statistics go
    to ``world.last_detection`` (untimed stages: the broad phase's seconds and the total; no
    edge–face census: ``detect_world``'s ``census``)."""
    contacts, world.last_detection = detect_world(world, margin=margin, R=R, reach=reach, floor=floor,
                                                  plane_margin=plane_margin, timed=False,
                                                  horizon=FAT_STEPS * dt, census=False)
    return contacts


# ---------------------------------------------------------------------------- impulse / kinematic
def _impulse_step(world, dt, m):
    """One step of the impulse (or kinematic) response, as named stages around a ``StepContext``
    (Box2D's step context): per sub-step (the step splits at times of impact) detect, then the
    stages after detection in one compiled call (a whole sub-step: detection too, in the same call,
    where ``substep.run_detected`` takes it) (``response.substep``: prepare the contacts, solve
    impacts and resting contact, plan position correction on the first sub-step, store the
    impulses and advance; with exact times of impact the time of impact is found between the
    solves and the advance); then apply the position correction and keep what the next step reuses."""
    ctx = StepContext.start(world, dt, m)
    limit = ctx.settings.max_impacts_per_step
    while True:
        whole = not (ctx.exact_toi or m.continuous) or ctx.events >= limit
        if whole and substep.run_detected(ctx):   # detect and the stages below in one compiled call
            break
        _detect_stage(ctx)               # contacts within the (speculative) margin
        if ctx.first and ctx.any_kinematic and ctx.k and m.response == "impulse":
            ctx.pose_work = pose_work(world, ctx.contacts, m)   # what poses given since stored in springs
        substep.run(ctx, whole)          # prepare, impacts, correction plan, resting (, store, advance)
        if whole:
            break
        tau = _time_of_impact(ctx)       # the first instant a pair apart touches, else the rest of the step
        frac = tau / ctx.t_left
        substep.finish(ctx, tau, frac)   # the sub-step's impulses; free motion with the resting force
        if frac >= 1.0:
            break
        ctx.t_left -= tau
    energy = correction.apply(ctx)       # the correction moves the bodies, then is dropped
    _finish(ctx, energy)                 # contact cache, the step's contacts and statistics


def _detect_stage(ctx):
    """``ctx.contacts``: the contacts within the margin (with speculative contacts, the
    look-ahead: ``ctx.look_ahead = (t_left, margin)`` then says which of them the sub-step keeps:
    the separated ones whose gap can close within the rest of the step)."""
    world = ctx.world
    margin = ctx.settings.contact_margin
    det_margin, reach, floor, plane_margin = prepare.speculative_reach(world, ctx.t_left) if ctx.speculative \
        else (margin, None, 0.0, None)
    if det_margin <= margin:   # no speculative contact: every pair takes the contact margin
        reach = plane_margin = None
    ctx.R = np.empty((len(world), 3, 3))
    rotations(world.s.quat, ctx.R)   # quat.to_matrix's values in one compiled pass; prepare reads them too
    # the speculative margin finds the pairs; each pair's narrow phase takes only what its bodies can close
    c = _detect(world, det_margin, ctx.dt, ctx.R, reach, floor, plane_margin)
    if ctx.swept_pair is not None:   # the sweep's hit: feature swept
        c = swept.mark_swept(c, ctx.swept_pair)
        ctx.swept_pair = None
    ctx.look_ahead = (ctx.t_left, margin) if ctx.speculative and det_margin > margin else None
    ctx.contacts = c
    ctx.touching = ctx.rest_mask = ctx.dv_rest = None


def _time_of_impact(ctx):
    """The length of this sub-step: the first instant in ``(0, t_left)`` at which a pair that is
    apart touches, or one in contact sinks deeper than a tolerance (``fractional``/``swept``, or
    ``next_step`` for the fast bodies of ``Models.continuous``: ``toi.earliest_event``), else
    ``t_left``."""
    world, m = ctx.world, ctx.models
    if not (ctx.exact_toi or m.continuous) or ctx.events >= world.settings.max_impacts_per_step:
        return ctx.t_left
    held = np.zeros(0, np.int64)
    if ctx.k:   # pairs in contact: keys min·N + max
        near = ctx.touching if ctx.rest_mask is None else ctx.touching | ctx.rest_mask
        ea, eb = ctx.contacts.body_a[near], ctx.contacts.body_b[near]
        held = np.minimum(ea, eb) * len(world) + np.maximum(ea, eb)
    acc = ctx.gravity if ctx.dv_rest is None else ctx.gravity + ctx.dv_rest / ctx.t_left
    motion = toi_mod.Motion(world, acc, ctx.rotating)
    # next_step with continuous bodies: a search for the fast bodies' pairs only
    ev, _ = toi_mod.earliest_event(world, motion, ctx.t_left, held, swept=m.toi == "swept",
                                   only=m.continuous if not ctx.exact_toi else None,
                                   soft=m.response == "impulse" and m.resting and compliance.possible(world))
    if ev >= ctx.t_left:
        return ctx.t_left
    ctx.events += 1
    ctx.swept_pair = motion.swept_pair
    return ev


def _finish(ctx, correction_energy):
    """What the step leaves: the contact cache for the next step, ``world.contacts`` (one row per
    contact point over the sub-steps) and ``world.last_solve``."""
    world, m = ctx.world, ctx.models
    world.contact_cache.warm = ctx.warm_out
    world.contacts = merge_records(world, ctx.records)
    # StepStats' fields in their order (iterations, residual, unconverged, max_penetration, contacts,
    # impacts, toi, response, correction_energy, kinematic_work, pose_work, rotation_drift,
    # kick_error_bound, rest_work_bound), made into it when read (``World.last_solve``)
    world._last_solve = (ctx.iterations, ctx.residual, ctx.unconverged, ctx.max_penetration, len(world.contacts),
                         ctx.events, m.toi, m.response, correction_energy, ctx.kinematic_work, ctx.pose_work,
                         ctx.drift, ctx.kick_error, ctx.rest_bound)


# ---------------------------------------------------------------------------- penalty
def _penalty_step(world, dt, m):
    """Penalty response (``response.penalty``): a spring ``k·depth`` and damper ``−c·v_n`` along each
    contact normal (never pulling), with regularised Coulomb friction, both integrated implicitly;
    bodies in contact move by ``x += dt·v⁺`` (symplectic Euler), free bodies ballistically. Detect,
    then the stages after detection in one compiled call (``substep.run_penalty``)."""
    ctx = StepContext.start(world, dt, m)
    # speculative contacts: a point apart now that can reach the other body within the step (a
    # spinning box's corner swinging into the ground) is in the solve, so its spring acts on the
    # depth it reaches by the end of the step; seen only once inside, its first step in compressed
    # the spring with nothing resisting, energy from no work
    margin, reach, floor, plane_margin = prepare.speculative_reach(world, dt) if world.settings.speculative \
        else (0.0, None, 0.0, None)
    ctx.R = np.empty((len(world), 3, 3))
    rotations(world.s.quat, ctx.R)
    ctx.contacts = _detect(world, margin, dt, ctx.R, reach, floor, plane_margin)
    ctx.warm_out = world.contact_cache.warm   # the springs take no warm start: the cache is kept as it is
    substep.run_penalty(ctx)
    _finish(ctx, 0.0)
