"""A sub-step's stages after detection, in one compiled call: the impulse step's one pipeline.

Every sub-step of the impulse (and kinematic) response runs here, whatever the models: the velocity
stage (the contact points' relative velocities; with speculative contacts the filter of the gaps
that can close) → prepare (coefficients, stiffnesses, rows, points in A's frame, the contact
classes: ``prepare.classify``) → impacts (``impact.impact_stage``) → resting contact
(``resting.rest_stage``) → the position correction's plan on the first sub-step
(``correction.drift_sink``, ``plan``, ``cap``) → store the impulses → advance
(``free_motion.advance``). Each stage's kernel lives in its stage's module; ``_substep`` reads as
this list. Every solve in them is ``solver.solve_rows`` (the settings' method: the exact active set
per island, Gauss–Seidel, the sparse active set for an island too large for the dense one).

With exact times of impact (``fractional``, ``swept``, or ``next_step`` with fast bodies) the
sub-step's length is known only after the solves: ``run`` then stops before storing, the stepper
finds the time of impact from the velocities the impacts left, and ``finish`` stores and advances
over the fraction of the rest of the step that the sub-step lasted. Otherwise (every step of a
world of more than a few bodies) ``run`` is the whole sub-step, and ``run_detected`` runs
detection in the same call before it (``_detect_substep``: the look-ahead margin, the broad
phase's pass on its pair cache, the bounding volumes and the narrow phase, each stage's kernel
from its module) wherever that cache holds and Python need not read the contacts first.

Run from Python stage by stage, these stages cost more in array calls and argument passing than in
arithmetic (in a 10-body resting step the kernels were about a quarter of the time): one call,
with the outputs in a few blocks, is what makes a small step cheap.

Shapes: ``N`` bodies, ``K`` contacts.
"""
import time
from operator import is_

import numpy as np

from ..collision import COMPILED_VOLUMES, _bodies_of, _NO_KEYS, contacts_of_rows, disabled_keys
from ..collision import broadphase, pair_kernels
from ..collision.vec3 import rotations
from ..free_motion import advance
from ..jit import njit
from ..kinds import DYNAMIC
from ..settings import COMBINE_RULES, SOLVER_METHODS
from .. import validate
from . import correction, prepare, step_model
from . import toi as toi_mod
from ..constants import (DIRECT_MAX_CONTACTS, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS,
                         PGS_TOLERANCE, REST_REBOUND_FRACTION, SIMULTANEOUS_FRACTION, TOI_TOLERANCE)
from .cache import local_points
from .compliance import possible as may_be_compliant, stiffness_rows
from .energy import kinematic_work, posed
from .impact import impact_stage
from .penalty import penalty_stage
from .pgs import build_rows
from .resting import rest_stage


def run(ctx, whole):
    """The stages after detection for the detected ``ctx.contacts`` in one compiled call. With
    ``whole`` (no time of impact can shorten the sub-step) the sub-step is done: the bodies moved,
    ``ctx`` holds what the step's end reads. Otherwise the bodies have their velocities after the
    impacts, ``ctx.touching``, ``ctx.rest_mask``, ``ctx.dv_rest`` say what the time-of-impact
    search needs, and ``finish`` completes the sub-step."""
    world = ctx.world
    c = ctx.contacts
    k = len(c)
    if not k:   # free flight: the stages have nothing to do, the advance is free motion
        ctx.first = False
        ctx.pending = ctx.pos0 = None
        if whole:
            ctx.drift += world._advance_free(ctx.t_left)
        else:
            ctx.touching = np.zeros(0, bool)
        return
    cc = np.ascontiguousarray
    look = ctx.look_ahead
    s, R = world.s, ctx.R
    model, any_kinematic, inertia_w = _step_model(ctx, _bodies_of(world))
    old, has_old = _warm_start(world)
    ctx.pos0 = _start_centres(world, any_kinematic)
    f3, f1, flags, wv, aux, idx, out = _substep(
        model, cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.point, dtype=float),
        cc(c.normal, dtype=float), cc(c.depth, dtype=float), look is not None,
        *(look if look is not None else _NO_LOOK), s.pos, s.vel, s.quat, s.omega,
        prepare.inv_inertia(world, ctx.models, R) if inertia_w is None else inertia_w, R, *old, has_old,
        float(ctx.t_left), ctx.first, whole)
    _take(ctx, whole, f3, f1, flags, wv, aux, idx, out)


def _warm_start(world):
    """``((a0, b0, p0, values), has_old)``: the contact cache's warm start, as ``_substep`` reads it.
    Its columns are of the kernel's types (int64, float64, C order) as it stores them (``_take``,
    ``ContactCache.remap``): handed as they are."""
    old = world.contact_cache.warm
    if old is not None and len(old[0]) > 0:
        return old, True
    return _NO_OLD, False


def _start_centres(world, any_kinematic):
    """The bodies' centres at the sub-step's start ``(N,3)`` when a body is kinematic, else None:
    the kinematic bodies' work is taken where the contact points are, at the sub-step's start, with
    their centres before the step moves them (a robot arm turning at 90 rad/s: 20 % of the work
    missed at the end)."""
    return world.s.pos.copy() if any_kinematic else None


def run_detected(ctx):
    """Detection and the whole sub-step's stages in one compiled call (``_detect_substep``): the
    look-ahead margin (``prepare.speculative_reach``'s), the broad phase's pass on its pair cache
    (``broadphase.world_pairs``), the bounding volumes and the narrow phase
    (``pair_kernels.kept_contacts``), then ``_substep``, the same kernels in the same order as
    ``stepper._detect_stage`` and ``run`` (so the same state to the bit); ``ctx.contacts``,
    ``world.last_detection`` and what ``run`` leaves are then as theirs. Returns False, with
    nothing changed, where detection needs Python first: the pair cache not built or a body out of
    its fat box (the Python detection rebuilds it), a bounding volume filtered in Python, a
    sweep's hit to mark, or the first sub-step's pose work on compliant contacts when a kinematic
    body was posed since the last step (``energy.pose_work`` reads the contacts before the solve
    moves the bodies; with no pose given it is exactly 0, ``energy.posed``)."""
    world, m, st = ctx.world, ctx.models, ctx.settings
    if ctx.swept_pair is not None or st.bounding_volume not in COMPILED_VOLUMES or (
            ctx.first and ctx.any_kinematic and m.response == "impulse" and may_be_compliant(world)
            and posed(world)):
        return False
    bodies = _bodies_of(world)
    cache = bodies.pair_cache
    if bodies.n < 2 or cache.fat_c is None:
        return False
    t0 = time.perf_counter()
    s = world.s
    R = np.empty((bodies.n, 3, 3))
    rotations(s.quat, R)
    model, any_kinematic, inertia_w = _step_model(ctx, bodies)
    old, has_old = _warm_start(world)
    pos0 = _start_centres(world, any_kinematic)   # before the call moves the bodies
    counters = np.zeros(2, np.int64)
    status, candidates, kept, pairs, unsupported, margin, look, rows_i, rows_f, body_a, body_b, normal, f3, f1, \
        flags, wv, aux, idx, out = _detect_substep(
            model, cache.fat_c, cache.fat_h, cache.i, cache.j, cache.margin,
            disabled_keys(world) if world.disabled_pairs else _NO_KEYS, counters, s.pos, s.vel, s.quat, s.omega,
            prepare.inv_inertia(world, m, R) if inertia_w is None else inertia_w, R, *old, has_old,
            float(ctx.t_left), ctx.first)
    if status == STALE:
        return False
    cache.reuses += 1
    ctx.R, ctx.pos0 = R, pos0
    ctx.look_ahead = (ctx.t_left, float(st.contact_margin)) if look else None
    ctx.touching = ctx.rest_mask = ctx.dv_rest = None
    ctx.contacts = c = contacts_of_rows(rows_i, rows_f, body_a, body_b, normal)
    n_settled, n_edge_face = counters.tolist()
    # ``DetectionStats``' fields in their order, made into it when read (``World.last_detection``); the
    # seconds are the call's, the sub-step's stages included
    world._last_detection = (len(world.shapes), candidates, candidates - kept, n_settled, n_edge_face, None, pairs,
                             len(c), unsupported, st.bounding_volume, margin, {"total": time.perf_counter() - t0})
    if status == NO_CONTACT:
        run(ctx, True)   # free motion
    else:
        _take(ctx, True, f3, f1, flags, wv, aux, idx, out)
    return True


#: ``_detect_substep``'s answers: the sub-step is done; no contact was found (nothing else done:
#: the sub-step is free motion); a body left its fat box (nothing done: the pair cache must be rebuilt)
DONE, NO_CONTACT, STALE = 0, 1, 2
_NO_FACTS = (np.zeros(0, np.bool_), np.zeros(0), np.inf, False)


@njit
def _detect_substep(model, fat_c, fat_h, ci, cj, fat_margin, disabled, counters, pos, vel, quat, omega, inv_inertia, R,
                    a0, b0, p0, values, has_old, t, first):
    """``run_detected``'s kernel: detection, then ``_substep`` for the whole sub-step. ``model``:
    what the scene fixes (``step_model.StepModel``: the look-ahead's facts, the broad phase's
    bodies and masks, the narrow phase's tables, ``_substep``'s fixed arguments); the others are
    what stepping changes: the broad phase's pair cache ``fat_c, fat_h (M,3), ci, cj (C,)`` and its
    margin, the ``disabled`` pairs' keys, the counts of the narrow phase into ``counters (2,)``, the
    motion ``pos, vel, quat, omega``, the world inverse inertia and rotations ``(N,3,3)``, the
    contact cache's warm start ``a0, b0, p0, values, has_old``, the time left ``t`` (s) and whether
    this is the step's first sub-step. Detection as ``stepper._detect_stage`` runs it: with
    ``speculative`` the look-ahead margin and each body's reach (``prepare._reach`` over ``t``;
    ``margin`` the contact margin), the broad phase's pass (``broadphase.world_pairs``), the
    bounding volumes and the narrow phase (``pair_kernels.kept_contacts``). Returns ``(status,
    candidate pairs, pairs kept by the bounding volumes, colliding pairs, unsupported pairs, the
    detection margin, whether the look-ahead filters the contacts, rows_i, rows_f, body_a, body_b,
    normal, *_substep's outputs)``; ``status`` ``STALE`` (nothing done), ``NO_CONTACT`` (no
    contact: the state untouched) or ``DONE``."""
    moving, caps, cap, plane = model.moving, model.caps, model.cap, model.plane
    fin, centre, half, planes, plane_n, plane_d = (model.fin, model.centre, model.half, model.planes, model.plane_n,
                                                   model.plane_d)
    which, sf, si, verts, gplanes, faces, loops, edges, tris, bvh, shape_of, rank = (
        model.which, model.sf, model.si, model.verts, model.gplanes, model.faces, model.loops, model.edges, model.tris,
        model.bvh, model.shape_of, model.rank)
    g, kind, ext, margin, speculative = model.g, model.kind, model.ext, model.margin, model.speculative
    n = pos.shape[0]
    det, plane_det, floor = margin, margin, 0.0
    reach = np.empty((2, n if speculative else 0))
    if speculative:   # prepare.speculative_reach over t
        det, plane_det, floor = prepare.look_ahead(vel, omega, ext, moving, caps, cap, plane, margin, g * t * t, t,
                                                   reach)
    look = det > margin
    if not look:   # no speculative contact: every pair takes the contact margin
        reach, plane_det = np.empty((2, 0)), det
    ok, ia, ib = broadphase.world_pairs(pos, R, fin, centre, half, planes, plane_n, plane_d, fat_c, fat_h, ci, cj,
                                        fat_margin, det, plane_det, kind, model.group, model.mask, disabled)
    f3, f1, flags = np.empty((3, 0, 3)), np.empty((2, 0)), np.empty((3, 0), np.bool_)
    wv, aux, idx, out = np.empty((0, 4)), np.empty(0), np.empty(0, np.int64), np.empty(12)
    if not ok or ia.shape[0] == 0:
        rows_i, rows_f, body_a, body_b, normal = (np.empty((0, 3), np.int64), np.empty((0, 7)),
                                                  np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, 3)))
        return (NO_CONTACT if ok else STALE), ia.shape[0], 0, 0, 0, det, look, rows_i, rows_f, body_a, body_b, \
            normal, f3, f1, flags, wv, aux, idx, out
    rows_i, rows_f, body_a, body_b, normal, pairs, unsupported, kept = pair_kernels.kept_contacts(
        which, sf, si, verts, gplanes, faces, loops, edges, tris, bvh, shape_of, rank, ia, ib, model.use_sphere,
        model.use_obb, pos, R, det, reach, floor, plane_det, counters, False, np.empty(2))
    if body_a.shape[0] == 0:
        return NO_CONTACT, ia.shape[0], kept, pairs, unsupported, det, look, rows_i, rows_f, body_a, body_b, normal, \
            f3, f1, flags, wv, aux, idx, out
    point, depth = np.ascontiguousarray(rows_f[:, 0:3]), np.ascontiguousarray(rows_f[:, 6])
    look_dt, look_base = (t, margin) if look else (0.0, 0.0)
    f3, f1, flags, wv, aux, idx, out = _substep(model, body_a, body_b, point, normal, depth, look, look_dt, look_base,
                                                pos, vel, quat, omega, inv_inertia, R, a0, b0, p0, values, has_old, t,
                                                first, True)
    return DONE, ia.shape[0], kept, pairs, unsupported, det, look, rows_i, rows_f, body_a, body_b, normal, f3, f1, \
        flags, wv, aux, idx, out


def _take(ctx, whole, f3, f1, flags, wv, aux, idx, out):
    """What the step keeps of ``_substep``'s outputs for ``ctx.contacts`` (``run``, and
    ``run_detected`` after its detection): the solves' statistics, the correction's
    pseudo-velocities, the contact cache's warm start; with ``whole`` the sub-step's records, else
    what the time-of-impact search and ``finish`` read."""
    world, c = ctx.world, ctx.contacts
    k = len(c)
    residual, deepest, rest_bound, drift, kick_error, sweeps, kept, rested, n_rest, unconverged, dropped, n_pen = \
        out.tolist()
    if dropped:   # speculative contacts that cannot close are not the step's (idx: the kept ones first)
        k = f1.shape[1]
        c = ctx.contacts = c.select(idx[:k])
    n = len(world.s.pos)
    ctx.iterations = max(ctx.iterations, int(sweeps))
    ctx.residual = max(ctx.residual, residual)
    ctx.unconverged = ctx.unconverged or bool(unconverged)
    if ctx.first and k:
        ctx.max_penetration = max(ctx.max_penetration, deepest)
    ctx.rest_bound += rest_bound
    if n_pen:   # the correction moves the bodies after the step (correction.apply)
        pw = aux[:6 * n].reshape(2, n, 3)
        ctx.pseudo = (pw[0], pw[1])
    local = f3[0]
    used, resting, touching = flags[0], flags[1], flags[2]
    if rested:
        # what the contact cache keeps of the resting solve (copies: never views of the step's
        # contacts; ``local`` is the kernel's own, no contact's column)
        if n_rest == k:
            ctx.warm_out = (c.body_a.copy(), c.body_b.copy(), local, wv)
        else:
            ri = np.flatnonzero(resting)
            ctx.warm_out = (c.body_a[ri].copy(), c.body_b[ri].copy(), local[ri].copy(), wv[:int(n_rest)].copy())
    ctx.first = False
    if whole:
        _record(ctx, c, f3, f1, used, kept, drift, kick_error)
    else:
        ctx.touching, ctx.rest_mask = touching, (resting if rested else None)
        dvw, keep = aux[6 * n:12 * n].reshape(2, n, 3), aux[12 * n:].reshape(4, k, 3)
        ctx.dv_rest = dvw[0] if rested else None
        ctx.pending = (c, f3, f1, used, keep, dvw, bool(rested))


def finish(ctx, tau, frac):
    """Store the impulses of the sub-step ``run`` left pending (the impacts', and the resting
    force's over the fraction ``frac`` of the rest of the step it lasted) and advance the bodies
    by ``tau`` (s), with the resting force's velocity change over ``frac`` as two half-kicks."""
    world = ctx.world
    if ctx.pending is None:   # no contact: free motion
        ctx.drift += world._advance_free(tau)
        return
    s, bm = world.s, world.body_masks()
    c, f3, f1, used, keep, dvw, rested = ctx.pending
    ctx.pending = None
    kept, drift, kick_error = _finish(
        float(frac), float(tau), keep, dvw, rested, np.ascontiguousarray(c.normal, dtype=float), ctx.speculative,
        ctx.touching, s.pos, s.vel, s.quat, s.omega, *_body_arrays(world)[:3], world._gravity, bm.dynamic,
        bm.rotating, bm.kinematic, f1[0], f3[1], f3[2], used)
    _record(ctx, c, f3, f1, used, kept, drift, kick_error)


def _record(ctx, c, f3, f1, used, kept, drift, kick_error):
    """The sub-step's contacts with their impulses into the step's records, the kinematic bodies'
    work through them, the free rotation's drift and the half-kicks' error bound."""
    ctx.drift += drift
    ctx.kick_error += kick_error
    k = len(c)
    if not k:
        return
    local = f3[0]
    c.normal_impulse, c.friction_impulse, c.impulse = f1[0], f3[1], f3[2]
    c.relative_normal_velocity = f1[1]
    if kept < k:   # speculative contacts that did nothing are not contacts of this step
        c, local = c.select(used), local[used]
    ctx.records.append((c, local))
    if ctx.pos0 is not None:
        ctx.kinematic_work += kinematic_work(ctx.world, c, ctx.pos0)


def _body_arrays(world):
    """The per-body arrays ``_substep`` reads that a step never replaces, in its argument order:
    ``(principal_q, principal_moments, inertia_body, inv_mass, mass, particle, restitution,
    friction, static_friction, extents, stiffness, damping_ratio)``, contiguous and of the kernel's
    types. Kept on the world while the very same arrays are there (a body added or removed, or a
    material assigned, replaces them) and only when they needed no conversion, so an edit in place
    is still seen."""
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


def _step_model(ctx, shapes):
    """``(model, any_kinematic, inertia_w)`` for the step ``ctx`` (``StepContext``: its world, models
    ``m``, ``dt`` and the products it holds) and the world's shape arrays ``shapes``
    (``collision._bodies_of``): the ``StepModel`` (``step_model``: what the compiled sub-step reads
    that the scene fixes), whether a body is kinematic, and the world inverse inertia ``(N,3,3)``
    when it is the same in every frame (``prepare.inv_inertia``'s answer, which the kernels only
    read), else None.

    They follow from the body arrays (``_body_arrays``: the very same tuple while no array is
    replaced), gravity, the models ``m``, the step ``dt`` (s), the settings (``ctx.gdt``,
    ``ctx.impact_speed`` and ``ctx.speculative`` follow from them too), the look-ahead's facts
    (``prepare._margin_facts``), the shape arrays and the collision masks; kept on the world while
    those are the same objects and no settings field was assigned since (``validate.edits``), so a
    change is seen at the next step with one check instead of a model built again."""
    world, m, dt = ctx.world, ctx.models, ctx.dt
    arrays = _body_arrays(world)
    st = world.settings
    gravity, ib, group, mask = world._gravity, world.inv_inertia_body, world.group, world.mask
    facts = prepare._margin_facts(world) if ctx.speculative else None
    hit = world._derived.get("step_model")
    if (hit is not None and hit[0] is arrays and hit[1] is st and hit[2] == validate.edits and hit[3] is m
            and hit[4] == dt and hit[5] is gravity and hit[6] is ib and hit[7] is facts and hit[8] is shapes
            and hit[9] is group and hit[10] is mask and hit[-1] is not None):   # None: a copied world's
        return hit[-1], hit[-3], hit[-2]
    edits = validate.edits
    bm = world.body_masks()
    particles = m.response == "kinematic"
    gdt, bv = ctx.gdt, st.bounding_volume
    model = step_model.make((
        # detection: the look-ahead's facts, the broad phase's bodies and masks, the narrow phase's tables
        *(facts[1:] if facts is not None else _NO_FACTS), shapes.finite, shapes.aabb_c, shapes.aabb_h, shapes.planes,
        shapes.plane_n, shapes.plane_d, group, mask, *shapes.narrow_args(), bv != "obb", bv != "sphere",
        # the bodies: kinds, inertia, gravity, materials, stiffnesses, extents
        world.gravity_norm(), world.kind, *arrays[:4], gravity, bm.gravity, bm.dynamic, bm.rotating, bm.kinematic,
        *arrays[4:9], m.response == "impulse" and m.resting and may_be_compliant(world), *arrays[10:12],
        float(st.kinematic_stiffness), COMBINE_RULES.index(st.combine), m.friction and not particles, arrays[9],
        # the step and the solve
        float(dt), ctx.exact_toi, particles, m.resting, float(st.contact_margin), ctx.speculative, TOI_TOLERANCE,
        SIMULTANEOUS_FRACTION * dt, gdt, REST_REBOUND_FRACTION * gdt, ctx.impact_speed, float(st.split_slop),
        float(st.split_beta), float(st.split_max_speed), SOLVER_METHODS.index(st.solver_method),
        DIRECT_MAX_CONTACTS if st.direct_max_contacts is None else int(st.direct_max_contacts),
        int(st.solver_iterations), float(st.solver_tolerance)))
    inertia_w = prepare.inv_inertia(world, m, None) if prepare.frame_free(world, m) else None
    world._derived["step_model"] = (arrays, st, edits, m, dt, gravity, ib, facts, shapes, group, mask,
                                    bm.any_kinematic, inertia_w, model)
    return model, bm.any_kinematic, inertia_w


_NO_OLD = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 4)))
_NO_LOOK = (0.0, 0.0)


@njit
def _substep(model, a, b, point, normal, depth, look, look_dt, look_base, pos, vel, quat, omega, inv_inertia, R, a0, b0,
             p0, values, has_old, t, first, whole):
    """``run``'s kernel, a sub-step of ``t`` (s) left of a step of ``model.dt``. ``model``: what
    the scene fixes (``step_model.StepModel``: the bodies' kinds, inertia, gravity, materials
    combined by ``rule`` (``prepare.coefficient_rows``), stiffnesses (``compliance.stiffness_rows``,
    read when ``may_soften``), the solve's settings, ``method`` an index of
    ``settings.SOLVER_METHODS``, ``particles`` the kinematic response). Contacts ``a, b (K,)``,
    ``point, normal (K,3)``, ``depth (K,)``; with ``look`` only the speculative ones whose gap can
    close within ``look_dt`` are kept (``look_base`` the contact margin); the motion ``pos, vel,
    quat, omega``, the world inverse inertia and rotations ``inv_inertia, R (N,3,3)``; the contact
    cache ``a0, b0 (K0,)``, ``p0 (K0,3)``, ``values (K0,4)`` when ``has_old``; ``first`` the step's
    first sub-step; ``whole`` no time of impact can shorten it.

    Returns ``(f3, f1, flags, wv, aux, idx, out)`` (the outputs are of the contacts the filter kept); ``f3
    (3,K,3)`` the points in A's frame, the friction impulses and the impulses; ``f1 (2,K)`` the
    normal impulses and the approach speeds; ``flags (3,K)`` the contacts that count, those the
    resting solve took, those touching; ``wv (K,4)`` the cache's values of the resting ones (its
    first rows); ``aux`` one block of ``pw (2,N,3)`` the correction's pseudo-velocities, then
    ``dvw (2,N,3)``, ``keep (4,K,3)`` (``K`` 0 when ``whole``): what ``_finish`` reads (the
    resting force's velocity change, the impacts' and the resting impulses, the tangents), filled
    when not ``whole``; ``idx`` the contacts the filter kept (their places among the ``K`` given,
    when it dropped some); ``out =
    [residual, deepest, rest_bound, drift, kick_error, sweeps, used, resting solve ran, contacts
    resting, a solve stopped unconverged, the filter dropped some, contacts the correction
    pushes]``. The outputs are allocated here, in blocks, and the rarely read ones share one:
    from Python each allocation and argument, and here each array handed back (~0.3 µs), costs
    more than the arithmetic."""
    g, kind, principal_q, moments, inertia_body, inv_mass = (model.g, model.kind, model.principal_q, model.moments,
                                                             model.inertia_body, model.inv_mass)
    gravity, gravity_rows, dynamic, rotating, kinematic, mass, particle = (
        model.gravity, model.gravity_rows, model.dynamic, model.rotating, model.kinematic, model.mass, model.particle)
    restitution, friction, static_friction, may_soften, stiffness, damping_ratio = (
        model.restitution, model.friction, model.static_friction, model.may_soften, model.stiffness,
        model.damping_ratio)
    k_kinematic, rule, kinetic, ext, dt = model.k_kinematic, model.rule, model.kinetic, model.ext, model.dt
    exact_toi, particles, resting = model.exact_toi, model.particles, model.resting
    margin, speculative, toi_tolerance, simultaneous, gdt = (model.margin, model.speculative, model.toi_tolerance,
                                                             model.simultaneous, model.gdt)
    rebound_speed, impact_speed, split_slop, split_beta, split_max_speed = (
        model.rebound_speed, model.impact_speed, model.split_slop, model.split_beta, model.split_max_speed)
    method, direct_max, max_iterations, tolerance = (model.method, model.direct_max, model.max_iterations,
                                                     model.tolerance)
    k, n = a.shape[0], pos.shape[0]
    # ---- velocity stage: the points' relative velocities, the look-ahead's filter
    rel_vel = np.empty((k, 3))
    near = np.empty(k if look else 0, np.bool_)
    kept = prepare._relative_velocity(a, b, point, pos, vel, omega, kind, particles, rel_vel, normal, depth, g, look_dt,
                                      look_base, near)
    dropped = look and kept < k
    if dropped:
        a, b, point, normal, depth, rel_vel = a[near], b[near], point[near], normal[near], depth[near], rel_vel[near]
        k = kept
    f3, f1, flags, wv = np.empty((3, k, 3)), np.empty((2, k)), np.empty((3, k), np.bool_), np.empty((k, 4))
    kw = k if not whole else 0
    aux = np.zeros(12 * n + 12 * kw)   # pw, dvw, keep: one block (aux)
    pw, dvw = aux[:6 * n].reshape((2, n, 3)), aux[6 * n:12 * n].reshape((2, n, 3))
    keep = aux[12 * n:].reshape((4, kw, 3))
    local, friction_impulse, impulse = f3[0], f3[1], f3[2]
    normal_impulse, vn0, used, rest_mask, touching = f1[0], f1[1], flags[0], flags[1], flags[2]
    vp, wp = pw[0], pw[1]
    out = np.zeros(12)
    # ---- prepare: coefficients, stiffnesses, rows, points in A's frame, classes
    # the per-contact numbers, one block: restitution (as the impact rounds rule it, and the
    # material's), friction, stiffness, damping ratio, speculative target, normal velocity after
    # the impacts
    per = np.zeros((8, k))
    e, e_material, mu_s, mu_d = per[0], per[1], per[2], per[3]
    stiff, zeta, spec_target, vn1 = per[4], per[5], per[6], per[7]
    prepare.coefficient_rows(a, b, restitution, friction, static_friction, rule, kinetic, e, mu_s, mu_d)
    n_soft = 0
    if may_soften and k:
        n_soft = stiffness_rows(a, b, depth, margin, stiffness, damping_ratio, kinematic, k_kinematic, rule, stiff,
                                zeta)
    classes = np.empty((4, k), np.bool_)   # impact, closing, bounced, and the compliant contacts
    imp, closing, bounced = classes[0], classes[1], classes[2]
    soft = classes[3] if n_soft else classes[3, :0]   # empty: none is compliant
    for c in range(soft.shape[0]):
        soft[c] = stiff[c] > 0.0
    vec, mat, num = np.empty((4, k, 3)), np.empty((6, k, 3, 3)), np.empty((2, k))   # the rows (rows.build_rows' blocks)
    t1, t2, ra, rb = vec[0], vec[1], vec[2], vec[3]
    ang_a, ang_b, iang_a, iang_b, K, dirs = mat[0], mat[1], mat[2], mat[3], mat[4], mat[5]
    ima, imb = num[0], num[1]
    build_rows(a, b, point, normal, pos, inv_mass, inv_inertia, rel_vel, dynamic, not particles, t1, t2, ra, rb, ang_a,
               ang_b, iang_a, iang_b, ima, imb, K, dirs)
    local_points(a, point, pos, R, local)
    for c in range(k):   # classify zeroes e where a rebound rests; a later impact round rules again
        e_material[c] = e[c]
    counts = prepare.classify(a, b, normal, depth, rel_vel, gravity_rows, ext, exact_toi, toi_tolerance, simultaneous,
                              margin, resting, rebound_speed, impact_speed, speculative, t, tolerance, soft, e, vn0,
                              touching, imp, closing, spec_target, bounced)
    # ---- impacts: compression with friction, then restitution, capped; the push cap's budget is
    # measured from the velocities at the sub-step's start in every solve of it
    refs = np.empty((2, n, 3))
    vel_ref, omega_ref = refs[0], refs[1]
    for i in range(n):
        for x in range(3):
            vel_ref[i, x], omega_ref[i, x] = vel[i, x], omega[i, x]
    lams = np.zeros((2, k, 3))   # the impacts' and the resting impulses
    lam_i, lam_r = lams[0], lams[1]
    it_i, residual_i, unconverged = impact_stage(a, b, point, normal, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K,
                                                 rel_vel, touching, closing, bounced, spec_target, e, e_material, soft,
                                                 vn0, counts.impact, counts.closing, particles, resting, rebound_speed,
                                                 impact_speed, mu_s, mu_d, kinetic, kind, dynamic, kinematic, inv_mass,
                                                 inv_inertia, mass, particle, pos, quat, inertia_body, method,
                                                 direct_max, max_iterations, tolerance, vel, omega, vel_ref, omega_ref,
                                                 lam_i, vn1)
    # ---- resting contact: the constant force over the rest of the step, warm started, on every
    # contact but those that just rebounded (none when every contact rebounded)
    rested = resting and k > 0 and (counts.touching > 0 or not exact_toi) \
        and not (counts.bounced > 0 and _all_above(vn1, impact_speed))
    dv, dw = dvw[0], dvw[1]
    kr, it_r, residual_r, rest_bound = 0, 0, 0.0, 0.0
    if rested:
        kr, it_r, residual_r, stopped, rest_bound = rest_stage(
            a, b, point, depth, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, local, vn0, vn1, touching, bounced,
            soft, stiff, zeta, mu_s, mu_d, kinetic, exact_toi, gdt, impact_speed, t, dt, gravity_rows, dynamic,
            kinematic, mass, particle, pos, quat, inertia_body, inv_mass, inv_inertia, vel, omega, vel_ref, omega_ref, a0,
            b0, p0, values, has_old, ext, method, direct_max, max_iterations, tolerance, rest_mask, lam_r, dv, dw, wv)
        unconverged = unconverged or stopped
    else:
        rest_mask[:] = False
    # ---- the position correction's plan (first sub-step): split-impulse pseudo-velocities for
    # the contacts overlapping at the step's end without it (the overlap now and the drift's curve
    # of the resting ones, which needs the resting force's spin change), capped in how far they
    # move a body
    pen = np.zeros(0, np.int64)
    if first and k:
        sink = np.zeros(k)
        deepest = counts.deepest
        if split_beta > 0.0 and rested:
            deepest = max(deepest, correction.drift_sink(a, b, point, normal, depth, rest_mask, pos, quat, omega, dw,
                                                         principal_q, moments, dynamic, rotating, ext, t, split_slop,
                                                         sink))
        if deepest > split_slop:
            pen, push = correction.plan(a, b, depth, sink, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, soft,
                                        dynamic, inv_mass, inv_inertia, split_beta, split_slop, dt, method, direct_max,
                                        max_iterations, tolerance, vp, wp)
            correction.cap(a, b, pen, push, split_max_speed, dt, vp, wp)
    out[0], out[1], out[2], out[5] = max(residual_i, residual_r), counts.deepest, rest_bound, max(it_i, it_r)
    out[7], out[8], out[9] = rested, kr, unconverged
    if not whole:   # a time of impact may shorten the sub-step: _finish stores and advances
        for c in range(k):
            for x in range(3):
                keep[0, c, x], keep[1, c, x] = lam_i[c, x], lam_r[c, x]
                keep[2, c, x], keep[3, c, x] = t1[c, x], t2[c, x]
        out[6] = k
        return f3, f1, flags, wv, aux, _indices(near, dropped, k, pen, out), out
    # ---- store the impulses, advance: the whole rest of the step
    out[6] = _store(1.0, lam_i, lam_r, rested, t1, t2, normal, speculative, touching, normal_impulse,
                    friction_impulse, impulse, used)
    out[3], out[4] = _move(1.0, t, dvw, rested, pos, vel, quat, omega, principal_q, moments, inertia_body, gravity,
                           dynamic, rotating, kinematic)
    return f3, f1, flags, wv, aux, _indices(near, dropped, k, pen, out), out


@njit
def _indices(near, dropped, k, pen, out):
    """``_substep``'s ``idx``: the places of the ``k`` contacts the filter kept (``near (K,)``,
    when ``dropped``); whether it dropped some and how many contacts the correction's ``pen``
    pushes apart into ``out[10:12]``."""
    idx = np.empty(k if dropped else 0, np.int64)
    j = 0
    if dropped:
        for c in range(near.shape[0]):
            if near[c]:
                idx[j] = c
                j += 1
    out[10], out[11] = dropped, pen.shape[0]
    return idx


@njit
def _all_above(x, bound):
    """Every value of ``x (K,)`` above ``bound`` (``np.all(x > bound)`` without the temporary mask)."""
    for c in range(x.shape[0]):
        if not x[c] > bound:
            return False
    return True


@njit(_nrt=False)
def _finish(frac, tau, keep, dvw, rested, normal, speculative, touching, pos, vel, quat, omega, principal_q, moments,
            inertia_body, gravity, dynamic, rotating, kinematic, normal_impulse, friction_impulse, impulse, used):
    """``finish``'s kernel: store what ``_substep`` kept (``keep (4,K,3)``: the impacts' and the
    resting impulses, the tangents) over the fraction ``frac`` and advance by ``tau`` (s).
    Returns ``(used, drift, kick_error)``."""
    kept = _store(frac, keep[0], keep[1], rested, keep[2], keep[3], normal, speculative, touching, normal_impulse,
                  friction_impulse, impulse, used)
    drift, kick_error = _move(frac, tau, dvw, rested, pos, vel, quat, omega, principal_q, moments, inertia_body,
                              gravity, dynamic, rotating, kinematic)
    return kept, drift, kick_error


@njit(_nrt=False)
def _store(frac, lam_i, lam_r, rested, t1, t2, normal, speculative, touching, normal_impulse, friction_impulse, impulse,
           used):
    """The sub-step's impulses on A: the impacts' ``lam_i (K,3)`` plus the resting ones ``lam_r``
    over the fraction ``frac`` of the rest of the step the sub-step lasted, in (n, t1, t2) to the
    world's vectors; ``used (K,)`` the contacts that count (a speculative one that did nothing is
    no contact of the step). Returns how many count."""
    kept = 0
    for c in range(lam_i.shape[0]):
        if rested:
            ln, l1, l2 = lam_i[c, 0] + lam_r[c, 0] * frac, lam_i[c, 1] + lam_r[c, 1] * frac, \
                lam_i[c, 2] + lam_r[c, 2] * frac
        else:
            ln, l1, l2 = lam_i[c, 0], lam_i[c, 1], lam_i[c, 2]
        normal_impulse[c] = ln
        for x in range(3):
            friction_impulse[c, x] = l1 * t1[c, x] + l2 * t2[c, x]
            impulse[c, x] = ln * normal[c, x] + friction_impulse[c, x]
        used[c] = not speculative or touching[c] or ln > 0.0
        kept += used[c]
    return kept


@njit
def _move(frac, tau, dvw, rested, pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating,
          kinematic):
    """Free motion over ``tau`` (``free_motion.advance``), with the resting force's velocity change
    over the fraction ``frac`` (``dvw (2,N,3)``, when ``rested``) as two half-kicks around the
    drift. Returns ``(drift, kick_error)`` (J; the error bound 0 without kicks)."""
    n = pos.shape[0]
    if rested:
        half = np.empty((2, n, 3))
        half_dv, half_dw = half[0], half[1]
        for i in range(n):
            for x in range(3):
                half_dv[i, x] = 0.5 * dvw[0, i, x] * frac
                half_dw[i, x] = 0.5 * dvw[1, i, x] * frac
    else:
        half = np.zeros((2, 0, 3))
        half_dv, half_dw = half[0], half[1]
    drift, kick_error = advance(pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating,
                                kinematic, half_dv, half_dw, rested, tau, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE,
                                MAX_SUBSTEPS)
    return drift, (kick_error if rested else 0.0)


def run_penalty(ctx):
    """A penalty step's stages after detection (``ctx.contacts``) in one compiled call: relative
    velocities, rows, the springs and dampers with their friction (``penalty.penalty_stage``),
    store, and the move: bodies in contact ``x += dt·v⁺`` (symplectic Euler), free bodies the exact
    ballistic step. No contact: free motion."""
    world, m = ctx.world, ctx.models
    c = ctx.contacts
    if not len(c):
        ctx.drift += world._advance_free(ctx.dt)
        return
    st = world.settings
    s = world.s
    bm = world.body_masks()
    cc = np.ascontiguousarray
    bodies = _body_arrays(world)
    ctx.pos0 = s.pos.copy() if bm.any_kinematic else None
    ctx.max_penetration = max(ctx.max_penetration, float(c.depth.max()))
    f3, f1, used, out = _penalty_substep(
        cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.point, dtype=float),
        cc(c.normal, dtype=float), cc(c.depth, dtype=float), world.kind, s.pos, s.vel, s.quat, s.omega,
        *bodies[:4], prepare.inv_inertia(world, m, ctx.R), world._gravity, ctx.gravity, bm.dynamic, bm.rotating,
        bm.kinematic, *bodies[7:9], COMBINE_RULES.index(st.combine), m.friction,
        float(st.penalty.stiffness), float(st.penalty.damping), float(st.penalty.friction_velocity), float(ctx.dt),
        DIRECT_MAX_CONTACTS if st.direct_max_contacts is None else int(st.direct_max_contacts),
        int(st.solver_iterations), float(st.solver_tolerance), PGS_TOLERANCE)
    iters, residual, sweeps, kept, drift, stopped = out.tolist()
    ctx.iterations, ctx.residual = int(iters), residual
    # the friction solve stopped by the sweep limit, not its tolerance, counts as unconverged too
    ctx.unconverged = bool(stopped) or sweeps >= st.solver_iterations
    ctx.drift += drift
    c.normal_impulse, c.friction_impulse, c.impulse = f1[0], f3[0], f3[1]
    c.relative_normal_velocity = f1[1]
    if kept < len(c):   # a speculative contact that did nothing is none
        c = c.select(used)
    ctx.records.append((c, None))
    if ctx.pos0 is not None:
        ctx.kinematic_work += kinematic_work(world, c, ctx.pos0)


@njit
def _penalty_substep(a, b, point, normal, depth, kind, pos, vel, quat, omega, principal_q, moments, inertia_body,
                     inv_mass, inv_inertia, gravity, gravity_rows, dynamic, rotating, kinematic, friction,
                     static_friction, rule, kinetic, stiffness, damping, v_reg, dt, direct_max, iterations, tolerance,
                     friction_tolerance):
    """``run_penalty``'s kernel, on ``K > 0`` contacts (arrays as ``_substep``'s). Returns ``(f3
    (2,K,3), f1 (2,K), used (K,), out)``: the friction impulses and the impulses, the normal
    impulses and the approach speeds, the contacts that count (inside, or pushed), ``out = [sweeps,
    residual, friction sweeps, used, drift, the normal rows' solve stopped unconverged]``."""
    k, n = a.shape[0], pos.shape[0]
    # ---- velocity stage, rows
    rel_vel = np.empty((k, 3))
    prepare._relative_velocity(a, b, point, pos, vel, omega, kind, False, rel_vel, normal, depth, 0.0, 0.0, 0.0,
                               np.empty(0, np.bool_))
    vec, mat, num = np.empty((4, k, 3)), np.empty((6, k, 3, 3)), np.empty((2, k))
    t1, t2, ra, rb = vec[0], vec[1], vec[2], vec[3]
    ang_a, ang_b, iang_a, iang_b, K, dirs = mat[0], mat[1], mat[2], mat[3], mat[4], mat[5]
    ima, imb = num[0], num[1]
    build_rows(a, b, point, normal, pos, inv_mass, inv_inertia, rel_vel, dynamic, True, t1, t2, ra, rb, ang_a, ang_b,
               iang_a, iang_b, ima, imb, K, dirs)
    f3, f1, used, out = np.empty((2, k, 3)), np.empty((2, k)), np.empty(k, np.bool_), np.zeros(6)
    friction_impulse, impulse, normal_impulse, vn0 = f3[0], f3[1], f1[0], f1[1]
    inside = np.empty(k, np.bool_)
    for c in range(k):
        vn0[c] = normal[c, 0] * rel_vel[c, 0] + normal[c, 1] * rel_vel[c, 1] + normal[c, 2] * rel_vel[c, 2]
        inside[c] = depth[c] >= 0.0
    e, mu_s, mu_d = np.empty(k), np.empty(k), np.empty(k)
    prepare.coefficient_rows(a, b, np.zeros(n), friction, static_friction, rule, kinetic, e, mu_s, mu_d)
    # ---- the springs and dampers, with friction: on the velocities the step would end with
    v_end = np.empty((n, 3))
    for i in range(n):
        for x in range(3):
            v_end[i, x] = vel[i, x] + gravity_rows[i, x] * dt
    w_end = omega.copy()
    lam = np.zeros((k, 3))
    it, residual, sweeps, stopped = penalty_stage(a, b, depth, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, mu_d,
                                                  kinetic, stiffness, damping, v_reg, dt, dynamic, inv_mass,
                                                  inv_inertia, direct_max, iterations, tolerance, friction_tolerance,
                                                  v_end, w_end, lam)
    # ---- store: a speculative contact that did nothing is none
    kept = _store(1.0, lam, lam, False, t1, t2, normal, True, inside, normal_impulse, friction_impulse, impulse, used)
    # ---- move: bodies in contact x += dt·v⁺ (the kick, then half of gravity's kick shifted so that
    # the exact ballistic drift ends at that position); free bodies keep the exact ballistic step
    touched = np.zeros(n, np.bool_)
    for c in range(k):
        if used[c]:
            touched[a[c]] = True
            touched[b[c]] = True
    shift = np.zeros((n, 3))
    for i in range(n):
        if touched[i] and kind[i] == DYNAMIC:
            for x in range(3):
                shift[i, x] = 0.5 * gravity[x] * dt
    for i in range(n):
        for x in range(3):
            vel[i, x] = vel[i, x] + (((v_end[i, x] - gravity_rows[i, x] * dt) - vel[i, x]) + shift[i, x])
            omega[i, x] = w_end[i, x]
    drift, _ = advance(pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating, kinematic,
                       np.zeros((0, 3)), np.zeros((0, 3)), False, dt, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE,
                       MAX_SUBSTEPS)
    for i in range(n):
        for x in range(3):
            vel[i, x] = vel[i, x] - shift[i, x]
    out[0], out[1], out[2], out[3], out[4], out[5] = it, residual, sweeps, kept, drift, stopped
    return f3, f1, used, out
