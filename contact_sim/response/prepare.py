"""Preparing a step's contacts: the stage between detection and the solves.

What the stages after detection need of each contact: the velocity of A's material point relative
to B's (``relative_velocity``; with speculative contacts, the look-ahead margin and the filter of
the gaps that can close in the step), the constraint rows, the point in A's frame (its identity
across steps), the combined coefficients, and the contact's class from its approach speed
(``classify``: touching, impact, closing, bounced). The per-contact arithmetic is kernels over
the contacts; numpy sets them up.

Shapes: ``N`` bodies, ``K`` contacts.
"""
import math
from typing import NamedTuple

import numpy as np

from .. import dynamics
from ..jit import njit
from . import compliance
from ..kinds import DYNAMIC
from ..memo import derived
from ..settings import COMBINE_RULES, combine_pair
from . import models as _models
from . import solver
from . import toi as toi_mod
from ..constants import SPECULATIVE_MAX_FRACTION, SPECULATIVE_MAX_TURN


@njit
def classify(a, b, normal, depth, rel_vel, gravity, ext, exact_toi, toi_tolerance, simultaneous, margin, resting,
             rebound_speed, impact_speed, speculative, t, tolerance, soft, e, vn0, touching, impact, closing,
             spec_target, bounced):
    """The contact classes of ``prepare_contacts``, per contact: writes ``vn0`` (the approach speed
    ``n·rel_vel``), ``touching``, ``impact``, ``closing``, ``bounced (K,) bool``, ``spec_target
    (K,)`` and zeroes ``e (K,)`` where the rebound rests. ``gravity (N,3)`` per body; ``ext (N,)``
    the bodies' extents (read with ``exact_toi``); ``soft (K,) bool`` the compliant contacts (or
    empty: none), which are never impacts nor closing (their spring stops them: ``compliance``);
    ``tolerance`` (m/s) the solver's, which keeps round-off out of an approach.

    With exact times of impact a contact apart whose pair also touches somewhere is a speculative
    one (``closing`` marks it for the impacts unless it separates; it counts as closing when it
    approaches): the time-of-impact search takes only the pairs apart
    (``stepper._time_of_impact``), so were it left out of the impacts, nothing would stop what they
    make approach before the resting stage, which holds the end velocity and lets the point go on
    at its start speed for half the step (a plate with two corners 3 nm above the floor, kicked by
    a box landing on its other edge, sank 0.29 mm).

    Returns ``Counts`` of the classes and the deepest depth (what the stages test before doing
    anything)."""
    n_touch, n_impact, n_closing, n_bounced, deepest = 0, 0, 0, 0, -np.inf
    k = a.shape[0]
    n_apart = 0
    for c in range(k):
        ia, ib = a[c], b[c]
        v = normal[c, 0] * rel_vel[c, 0] + normal[c, 1] * rel_vel[c, 1] + normal[c, 2] * rel_vel[c, 2]
        vn0[c] = v
        if exact_toi:
            # within the time-of-impact search's tolerance of touching, relative to size; and contacts
            # that close within a millionth of a step of the impact found are hit in the same instant
            # (a box landing flat, tilted by round-off, hits all four corners at once; one corner alone
            # would kick it into a spin)
            touch = depth[c] >= -toi_tolerance * min(ext[ia], ext[ib]) or depth[c] >= v * simultaneous
        else:
            touch = depth[c] >= -margin
        touching[c] = touch
        n_apart += not touch
    # exact times of impact: the apart contacts of the pairs that touch are speculative ones
    held = _of_touching_pairs(a, b, touching, gravity.shape[0]) if exact_toi and 0 < n_apart < k \
        else touching[:0]
    for c in range(k):
        ia, ib = a[c], b[c]
        v, touch = vn0[c], touching[c]
        # a rebound whose flight is shorter than a step comes to rest (ends Zeno bounces)
        if resting and e[c] * max(-v, 0.0) < rebound_speed:
            e[c] = 0.0
        compliant = soft.shape[0] > 0 and soft[c]
        if compliant:
            e[c] = 0.0
        impact[c] = touch and v < (-impact_speed if resting else 0.0) and not compliant
        # speculative contacts (apart, within the look-ahead): the impulse leaves the normal velocity
        # at what closes exactly the gap over the step under gravity, v_n ≥ (−gap − g_n T²/2)/T, so
        # the pair arrives touching instead of overlapping; one that bounces (e > 0) does so in this
        # step from the approach speed it has now (Box2D's restitution rule: the rebound starts up
        # to one gap early, and e = 1 loses nothing). Never positive: a pair nearer than gravity's
        # sag over the step is only stopped here (pushing it apart to arrive touching would be work
        # done by the contact); the resting stage's constant force then lands it exactly. The
        # target is kept under exact times of impact too: a contact that a later impact round
        # (``impact.next_round``) finds closing takes it
        g_n = (normal[c, 0] * (gravity[ia, 0] - gravity[ib, 0]) + normal[c, 1] * (gravity[ia, 1] - gravity[ib, 1])
               + normal[c, 2] * (gravity[ia, 2] - gravity[ib, 2]))
        st = min((depth[c] - 0.5 * g_n * t * t) / t, 0.0)
        spec_target[c] = st
        if speculative:
            close = not touch and v < st and not compliant
            closing[c] = close
        else:   # held like a touching contact that does not separate: in every impact, at its target
            close = held.shape[0] > 0 and held[c] and v < st - tolerance and not compliant
            closing[c] = held.shape[0] > 0 and held[c] and v <= tolerance and not compliant
        bounced[c] = impact[c] or (close and e[c] > 0)
        n_touch += touch
        n_impact += impact[c]
        n_closing += close
        n_bounced += bounced[c]
        deepest = max(deepest, depth[c])
    return Counts(n_touch, n_impact, n_closing, n_bounced, deepest)


@njit
def _of_touching_pairs(a, b, touching, n):
    """``(K,) bool``: the contacts apart (not ``touching (K,) bool``) whose pair ``a, b (K,)`` of
    ``n`` bodies has a touching contact (a sorted array of the touching pairs' keys, searched)."""
    k = a.shape[0]
    keys = np.empty(k, np.int64)
    m = 0
    for c in range(k):
        if touching[c]:
            keys[m] = min(a[c], b[c]) * n + max(a[c], b[c])
            m += 1
    keys = np.sort(keys[:m])
    out = np.zeros(k, np.bool_)
    for c in range(k):
        if not touching[c]:
            key = min(a[c], b[c]) * n + max(a[c], b[c])
            j = np.searchsorted(keys, key)
            out[c] = j < m and keys[j] == key
    return out


class Counts(NamedTuple):
    """What ``classify`` counted over a sub-step's contacts."""
    touching: int
    impact: int
    closing: int
    bounced: int
    deepest: float      # the largest depth (m; > 0 penetrating)


def relative_velocity(world, c, m, closing=None):
    """Velocity ``(K,3)`` of A's material point at each contact relative to B's, ``ṗ_A − ṗ_B``
    (computed once per detection: the closing filter, the tangent choice and ``v_n`` share it).
    Under the kinematic response a dynamic body is a particle, ``v ← v − (1+k)(N·v)N`` acts on the
    velocity of its centre: its spin is neither seen nor changed (counting it made a spinning box
    bounce higher than it fell).

    With ``closing = (dt, base)`` returns ``(rel_vel, near (K,) bool)`` from the same pass: the
    speculative contacts worth keeping, those within ``base`` (touching) and the separated ones
    whose gap can close within ``dt`` at the current normal velocity, ``gap ≤ max(−v_n, 0)·dt +
    |g|·dt² + base``; ``near`` is None when every contact is kept (the usual case)."""
    s = world.s
    k = len(c)
    out = np.empty((k, 3))
    near = np.empty(k if closing is not None else 0, np.bool_)
    dt, base = closing if closing is not None else (0.0, 0.0)
    cc = np.ascontiguousarray
    kept = _relative_velocity(cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.point, dtype=float),
                              s.pos, s.vel, s.omega, world.kind, m.response == "kinematic", out,
                              cc(c.normal, dtype=float), cc(c.depth, dtype=float), world.gravity_norm(), float(dt),
                              float(base), near)
    return out if closing is None else (out, None if kept == k else near)


@njit(_nrt=False)
def _relative_velocity(a, b, point, pos, vel, omega, kind, particles, out, normal, depth, g, dt, base, near):
    """``out[c] = (v_a + ω_a × (p − x_a)) − (v_b + ω_b × (p − x_b))``, ω not counted for dynamic
    bodies when ``particles``; ``near[c]`` (when ``near`` has ``K`` rows) the closing filter
    ``−depth ≤ max(−n·out, 0)·dt + g·dt² + base``. Returns how many are near."""
    kept = 0
    for c in range(a.shape[0]):
        ia, ib = a[c], b[c]
        for side in range(2):
            i = ia if side == 0 else ib
            sgn = 1.0 if side == 0 else -1.0
            rx, ry, rz = point[c, 0] - pos[i, 0], point[c, 1] - pos[i, 1], point[c, 2] - pos[i, 2]
            spin = not particles or kind[i] != DYNAMIC
            wx, wy, wz = (omega[i, 0], omega[i, 1], omega[i, 2]) if spin else (0.0, 0.0, 0.0)
            vx = vel[i, 0] + (wy * rz - wz * ry)
            vy = vel[i, 1] + (wz * rx - wx * rz)
            vz = vel[i, 2] + (wx * ry - wy * rx)
            if side == 0:
                out[c, 0], out[c, 1], out[c, 2] = vx, vy, vz
            else:
                out[c, 0] += sgn * vx
                out[c, 1] += sgn * vy
                out[c, 2] += sgn * vz
        if near.shape[0]:
            vn = normal[c, 0] * out[c, 0] + normal[c, 1] * out[c, 1] + normal[c, 2] * out[c, 2]
            near[c] = -depth[c] <= max(-vn, 0.0) * dt + g * dt * dt + base
            kept += near[c]
    return kept


def speculative_reach(world, dt):
    """Detection margin (m) of a ``next_step`` step with speculative contacts, and each body's share
    of it: ``(margin, reach (2,N), floor, plane_margin)``.

    ``reach[1]`` is the farthest a body's points move in ``dt`` (``_speed · dt``, 0 for a body that
    does not move), ``reach[0]`` the same at most ``SPECULATIVE_MAX_FRACTION`` × the body's own
    thinnest size, and ``floor = contact_margin + |g| dt²``. A pair can close by at most ``floor +
    reach[a] + reach[b]`` (the look-ahead keeps nothing farther), so the narrow phase takes that as
    the pair's margin (``detect_world``'s ``reach``): a hull at rest beside a fast ball then builds
    its manifold from the points that touch, not from vertices a centimetre up that the look-ahead
    would drop, leaving its support short of a corner. Between two finite bodies the capped
    ``reach[0]``: a look-ahead longer than half a body's thickness stops it on the features of
    things it only passes by (a body moving farther in a step is ``swept``'s case); against a plane
    the whole ``reach[1]``: a half-space has nothing to pass by, and a box falling or turning
    farther than half its thickness in a step reached the floor unseen (a 1 cm box at 1.8 m/s went
    1.5 mm in; a spinning penalty box's corners 3.9 mm, their springs' energy from nothing). Only
    while the body turns by at most ``SPECULATIVE_MAX_TURN`` in the step: a speculative contact
    moves its points along straight lines (their velocities at the step's start), which the
    points of a body turning farther leave (bodies tumbling at 0.3–0.9 rad a step in a pile took
    a dozen wall contacts each from 4–11 cm off, stops that the turning points need not make).

    ``margin`` finds the pairs of finite bodies and bounds their margins: the largest closing
    distance of two finite bodies in ``dt`` (twice the fastest body's speed, including spin × size,
    times ``dt``, plus ``|g| dt²``), at most ``SPECULATIVE_MAX_FRACTION`` × the thickest finite
    body, at least ``settings.contact_margin``; ``plane_margin`` the planes': at least ``floor``
    plus the farthest a finite body's points move (``margin`` in a world without a plane)."""
    s = world.s
    ext, moving, caps, cap, plane = _margin_facts(world)
    reach = np.empty((2, len(s.vel)))
    margin, plane_margin, floor = look_ahead(s.vel, s.omega, ext, moving, caps, cap, plane,
                                             world.settings.contact_margin, world.gravity_norm() * dt * dt, dt, reach)
    return margin, reach, floor, plane_margin


@njit(_nrt=False)
def look_ahead(vel, omega, ext, moving, caps, cap, plane, base, g, dt, reach):
    """``speculative_reach``'s rule, for it and for the compiled steps that detect in their own
    call (``stepper._flight``, ``substep._detect_substep``): with ``_margin_facts``' ``ext, moving,
    caps (N,), cap, plane``, the contact margin ``base`` (m) and ``g = |g| dt²`` (m), each body's
    reach into ``reach (2,N)`` (``_reach``); returns ``(margin, plane_margin, floor)`` (m)."""
    vmax, free = _reach(vel, omega, ext, moving, caps, dt, reach)
    floor = base + g
    if vmax < 0:   # nothing moves
        return base, base, floor
    margin = max(base, min(2.0 * vmax * dt + g, cap))
    return margin, (max(margin, floor + free) if plane else margin), floor


@njit(_nrt=False)
def _reach(vel, omega, ext, moving, caps, dt, out):
    """``out (2,N)``: ``_speed · dt`` of the ``moving`` bodies at most their ``caps (N,)`` (row 0),
    and the same uncapped (row 1) for a body that turns by at most ``SPECULATIVE_MAX_TURN`` in
    ``dt`` (else capped too), 0 for the others; returns the largest ``_speed`` (m/s), −1 when none
    moves, and the largest row-1 reach of a body of finite extent (m)."""
    best, free = -1.0, 0.0
    for i in range(vel.shape[0]):
        out[0, i] = out[1, i] = 0.0
        if moving[i]:
            speed = _speed(vel, omega, ext, i)
            best = max(best, speed)
            out[0, i] = min(speed * dt, caps[i])
            turn = math.sqrt(omega[i, 0] ** 2 + omega[i, 1] ** 2 + omega[i, 2] ** 2) * dt
            out[1, i] = speed * dt if turn <= SPECULATIVE_MAX_TURN else out[0, i]
            if math.isfinite(ext[i]):
                free = max(free, out[1, i])
    return best, free


def _margin_facts(world):
    """What ``speculative_reach`` reads of the bodies, kept while they are the same (the kind
    array and the shape list are replaced when a body is added or removed): ``(extents (N,),
    moving (N,) bool, each body's largest reach (N,): SPECULATIVE_MAX_FRACTION × its thinnest size,
    the largest look-ahead between finite bodies (m): that fraction of the thickest finite body,
    whether a body is a plane)``. Each body's own: with
    the world's thinnest body setting every reach, a 2 cm ball kept a 12 cm box spinning at 19 rad/s
    to a 1 cm look-ahead, and its corners 1.7 cm up entered the ground unseen."""
    bm = world.body_masks()
    kind, last = world.kind, world.shapes[-1] if len(world) else None
    hit = world._derived.get("margin_facts")   # read every step: identity checks, no closure
    if hit is not None and hit[0] is kind and hit[1] is last and hit[2] is bm:
        return hit[3]
    thin = _models.body_thinness(world)
    finite = np.isfinite(thin)
    facts = (toi_mod._extents(world), bm.moving, SPECULATIVE_MAX_FRACTION * thin,
             SPECULATIVE_MAX_FRACTION * float(thin[finite].max()) if finite.any() else np.inf,
             any(sh.type == "plane" for sh in world.shapes))
    world._derived["margin_facts"] = (kind, last, bm, facts)
    return facts


@njit
def _speed(vel, omega, ext, i):
    """``|v| + |ω|·extent`` of body ``i``: the fastest any of its points moves. A spinning body of
    infinite extent (a turning kinematic plane) has no such bound: infinite, so its pairs take the
    step's whole (capped) margin."""
    v = math.sqrt(vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
    w = math.sqrt(omega[i, 0] ** 2 + omega[i, 1] ** 2 + omega[i, 2] ** 2)
    if math.isfinite(ext[i]):
        return v + w * ext[i]
    return v + (math.inf if w > 0.0 else 0.0)


def inv_inertia(world, m, R):
    """World inverse inertia ``R I⁻¹ Rᵀ (N,3,3)`` from the bodies' rotation matrices ``R (N,3,3)``
    (zeros when the models skip rotation). The kernels only read it: when every body's is the
    same in every frame it is ``world.inv_inertia_body`` itself (of the kernels' type), no copy,
    and ``R`` is not read (``frame_free``)."""
    if not m.rotation:
        return np.zeros((len(world), 3, 3))
    ib = world.inv_inertia_body
    turn, as_is = _isotropic(world)
    if turn.size == len(ib):
        return dynamics.rotate_inertia(R, ib)
    if not turn.size and as_is:
        return ib
    out = ib.copy()
    if turn.size:
        out[turn] = dynamics.rotate_inertia(R[turn], ib[turn])
    return out


def frame_free(world, m):
    """Whether ``inv_inertia`` is the same whatever the bodies' orientations: no rotation in the
    models, or every body's inverse inertia ``c·I`` and handed as it is."""
    if not m.rotation:
        return True
    turn, as_is = _isotropic(world)
    return 0 < len(world.inv_inertia_body) and not turn.size and as_is


def _isotropic(world):
    """``(turn, as_is)``: the bodies whose inverse inertia is not ``c·I`` (spheres, cubes, and the
    zeros of static/kinematic bodies are the same in every frame), and whether
    ``world.inv_inertia_body`` has the type a copy would have (C order, float64, writable), so it
    can stand for one. Kept while the array is the same."""
    ib = world.inv_inertia_body
    return derived(world, "anisotropic_inertia", (ib,), lambda: (
        np.flatnonzero(~np.all(ib == ib[:, :1, :1] * np.eye(3), axis=(1, 2))),
        ib.dtype == np.float64 and ib.flags.c_contiguous and ib.flags.writeable))


def coefficients(world, c, m):
    """Per-contact restitution, static and dynamic friction ``(K,)`` combined by ``settings.combine``
    (friction zero unless the models' friction acts): ``coefficient_rows``, the sub-step's too."""
    k = len(c)
    out = np.empty((3, k))   # one block, three rows
    cc = np.ascontiguousarray
    coefficient_rows(cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(world.restitution, dtype=float),
                     cc(world.friction, dtype=float), cc(world.static_friction, dtype=float),
                     COMBINE_RULES.index(world.settings.combine), m.friction and m.response != "kinematic",
                     out[0], out[1], out[2])
    return out[0], out[1], out[2]


def stiffnesses(world, c, m):
    """Per contact of ``c``: stiffness (N/m, 0 rigid) and damping ratio ``(K,)``
    (``compliance.stiffness_rows``, the sub-step's too); rigid throughout under the kinematic
    response and the resting stage off (a compliant row lives in the resting solve)."""
    k = len(c)
    out = np.zeros((2, k))
    if m.response == "impulse" and m.resting and k and compliance.possible(world):
        st = world.settings
        cc = np.ascontiguousarray
        compliance.stiffness_rows(cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.depth, dtype=float),
                       float(st.contact_margin), world.stiffness, world.damping_ratio, world.body_masks().kinematic,
                       float(st.kinematic_stiffness), COMBINE_RULES.index(st.combine), out[0], out[1])
    return out[0], out[1]


@njit(_nrt=False)
def coefficient_rows(a, b, restitution, friction, static_friction, rule, kinetic, e, mu_s, mu_d):
    """``coefficients`` in a loop, for the sub-step: ``a, b (K,)`` the contacts' bodies, the
    bodies' materials ``(N,)``, ``rule`` the index of ``settings.combine`` in ``COMBINE_RULES``;
    writes ``e, mu_s, mu_d (K,)`` (friction zero unless ``kinetic``), static friction at least the
    dynamic (``settings.combine_pair``: the one place the rules are written)."""
    for c in range(a.shape[0]):
        ia, ib = a[c], b[c]
        e[c] = combine_pair(restitution[ia], restitution[ib], rule)
        if kinetic:
            d = combine_pair(friction[ia], friction[ib], rule)
            st = combine_pair(static_friction[ia], static_friction[ib], rule)
            mu_s[c] = st if st >= d else d
            mu_d[c] = d
        else:
            mu_s[c] = 0.0
            mu_d[c] = 0.0


def rows(world, c, inv_inertia_w, rel_vel, m):
    """Constraint rows (``solver.build_rows``) of contacts ``c``; under the kinematic response a
    movable body's contact acts at its centre."""
    return solver.build_rows(c.body_a, c.body_b, c.point, c.normal, world.s.pos, world.inv_mass, inv_inertia_w,
                             movable=world.body_masks().dynamic, rel_vel=rel_vel,
                             dynamic_levers=m.response != "kinematic")


def gravity(world):
    """Gravity ``(N,3)`` of the dynamic bodies, 0 for the others."""
    return world.body_masks().gravity
