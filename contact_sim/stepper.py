"""The step pipeline: detection, impacts, resting contact, time of impact, free motion.

``World.step`` calls ``step(world, dt)``. One step of ``dt``, with ``T`` the time left:

1. detect contacts (margin ``settings.contact_margin``);
2. **impacts**: touching contacts that approach get instantaneous impulses with restitution
   (kinematic response: ``v+ = v − (1+k)(N·v)N`` without rotation; impulse response: the lecture's
   ``j`` with both bodies' world inverse inertia, Coulomb friction), solved together by projected
   Gauss–Seidel (``response.solver``);
3. **resting contact** (when on): contacts that stay touching get the impulse that acts as a constant
   force over ``T``: non-negative, zero when separating, the normal velocity at the end of ``T`` not
   approaching (no sinking), friction inside the cone (sticking = stopped at the end of ``T``);
4. **time of impact**: ``next_step`` advances by ``T``; ``fractional`` and ``swept`` find the first
   instant in ``(0, T]`` at which a pair that is apart touches (closed form for sphere–plane and
   sphere–sphere, bracket + Brent otherwise; ``swept`` guarantees that nothing passes through a
   thin body), advance exactly to it and go back to 1 with the rest of the step — at most
   ``settings.max_impacts_per_step`` times;
5. positions of penetrating contacts are corrected by split-impulse pseudo-velocities, which move
   bodies and are then discarded (no energy is added).

Penalty response replaces 2–3 by a spring ``k·depth`` and damper ``−c·v_n`` along the normal, and
(friction on) regularised Coulomb friction (``response.penalty_friction``).

``world.contacts`` gets the contacts of the step with the impulses applied to A (normal and
friction parts), ``world.last_solve`` a dict with the solver's iterations, residual, maximum
penetration at the start of the step, contact and impact counts, and the models used.
"""
import numpy as np

from . import dynamics, quat
from .contacts import Contacts
from .kinds import DYNAMIC, STATIC
from .memo import derived
from .settings import combine
from .stats import StepStats
from .vec import cross
from .response import models as _models
from .collision import detect_world
from .response import solver
from .response import toi as toi_mod
from .response.cache import local_points, merge_records, project_warm, record, warm_lookup, warm_record
from .response.energy import energetic_cap, kinematic_work, kinetic_energy, potential_change, rotational_energy
from .response import kinematic as kinematic_mod
from .response import penalty_friction

SIMULTANEOUS_FRACTION = 1e-6  # contacts closing within this × dt of an impact are hit together with it
IMPACT_SPEED_FRACTION = 0.25  # approach slower than this × |g|·dt: no bounce, the resting solve holds it
REST_REBOUND_FRACTION = 0.5  # rebound slower than this × |g|·dt (airborne less than a step): it rests
SPECULATIVE_MAX_FRACTION = 0.5  # the look-ahead is at most this × the thinnest finite body (beyond: swept's job)


def describe_models(world):
    """What ``step`` will use for ``world`` and why (``list[str]``), with preflight warnings."""
    return _models.describe(world)


def forget(world):
    """Drop what the stepper carries between steps (warm starts, preflight done): after a reset."""
    world._cs_warm = None
    world._cs_preflight_dt = None


def step(world, dt):
    """Advance ``world`` by ``dt`` (already validated, > 0)."""
    m = _models.choose(world, dt)
    if getattr(world, "_cs_preflight_dt", None) != dt:
        world._cs_preflight_dt = dt
        _models.warn_preflight(world, m, dt)
    if m.response == "penalty":
        _penalty_step(world, dt, m)
    else:
        _impulse_step(world, dt, m)
    world.time += dt


# ---------------------------------------------------------------------------- helpers
def _detect(world, margin):
    """Contacts of the current state within ``margin``; the detection statistics go to
    ``world.last_detection``."""
    contacts, world.last_detection = detect_world(world, margin=margin)
    return contacts


def _inv_inertia(world, m, R):
    """World inverse inertia ``R I⁻¹ Rᵀ (N,3,3)`` from the bodies' rotation matrices ``R (N,3,3)``
    (zeros when the models skip rotation)."""
    if not m.rotation:
        return np.zeros((len(world), 3, 3))
    ib = world.inv_inertia_body
    # c·I (spheres, cubes, and the zeros of static/kinematic bodies) is the same in every frame
    turn = derived(world, "anisotropic_inertia", (ib,),
                   lambda: np.flatnonzero(~np.all(ib == ib[:, :1, :1] * np.eye(3), axis=(1, 2))))
    if turn.size == len(ib):
        return dynamics.rotate_inertia(R, ib)
    out = ib.copy()
    if turn.size:
        out[turn] = dynamics.rotate_inertia(R[turn], ib[turn])
    return out


def _coefficients(world, c, m):
    """Per-contact restitution, static and dynamic friction ``(K,)`` combined by ``settings.combine``."""
    rule = world.settings.combine
    a, b = c.body_a, c.body_b
    k = len(a)
    kinetic = m.friction and m.response != "kinematic"
    uniform = _uniform_material(world)
    if uniform is not None:   # one material everywhere: every rule gives its own values
        e, mu_s, mu_d = uniform
        z = np.zeros(k)
        return (np.full(k, e), np.full(k, mu_s), np.full(k, mu_d)) if kinetic else (np.full(k, e), z, z)
    e = combine(world.restitution[a], world.restitution[b], rule)
    if not kinetic:
        z = np.zeros(k)
        return e, z, z
    mu_d = combine(world.friction[a], world.friction[b], rule)
    mu_s = np.maximum(combine(world.static_friction[a], world.static_friction[b], rule), mu_d)
    return e, mu_s, mu_d


def _uniform_material(world):
    """``(restitution, static friction, dynamic friction)`` when every body has the same
    coefficients, else ``None`` (cached; the arrays are replaced when a body is added)."""
    r, f, sf = world.restitution, world.friction, world.static_friction

    def build():
        same = len(r) and (r == r[0]).all() and (f == f[0]).all() and (sf == sf[0]).all()
        # combine() keeps equal coefficients exactly; static friction is at least the dynamic one
        return (float(r[0]), max(float(sf[0]), float(f[0])), float(f[0])) if same else None

    return derived(world, "uniform_material", (r, f, sf), build)


def _rows(world, c, inv_inertia, rel_vel, m):
    return solver.build_rows(c.body_a, c.body_b, c.point, c.normal, world.s.pos, world.inv_mass, inv_inertia,
                             movable=world.kind == DYNAMIC, rel_vel=rel_vel,
                             dynamic_levers=m.response != "kinematic")


def _relative_velocity(world, c, m):
    """Velocity ``(K,3)`` of A's material point at each contact relative to B's, ``ṗ_A − ṗ_B``
    (computed once per detection: the closing filter, the tangent choice and ``v_n`` share it).
    Under the kinematic response a dynamic body is a particle, ``v ← v − (1+k)(N·v)N`` acts on the
    velocity of its centre: its spin is neither seen nor changed (counting it made a spinning box
    bounce higher than it fell)."""
    s = world.s
    a, b = c.body_a, c.body_b
    if not s.omega.any():   # nothing spins: the points move with their bodies' centres
        return s.vel[a] - s.vel[b]
    wa, wb = s.omega[a], s.omega[b]
    if m.response == "kinematic":
        dyn = world.kind == DYNAMIC
        wa = np.where(dyn[a][:, None], 0.0, wa)
        wb = np.where(dyn[b][:, None], 0.0, wb)
    return (s.vel[a] + cross(wa, c.point - s.pos[a])) - (s.vel[b] + cross(wb, c.point - s.pos[b]))


def _solve(st, rows, vel, omega, **kw):
    """``solver.solve_auto`` with the settings ``st``' solver choice, iterations and tolerance."""
    return solver.solve_auto(rows, vel, omega, iterations=st.solver_iterations, tolerance=st.solver_tolerance,
                             method=st.solver_method, direct_max=st.direct_max_contacts, **kw)


def _gravity(world):
    return np.where((world.kind == DYNAMIC)[:, None], world.gravity, 0.0)


def _speculative_margin(world, dt):
    """Detection margin (m) of a ``next_step`` step with speculative contacts: the largest closing
    distance of any pair in ``dt`` (twice the fastest body's speed, including spin × size, times
    ``dt``, plus ``|g| dt²``), at least ``settings.contact_margin`` and at most
    ``SPECULATIVE_MAX_FRACTION`` × the thinnest finite body (a body moving farther than that in a
    step is the tunnelling case that ``swept`` handles and the preflight warns about)."""
    s = world.s
    base = world.settings.contact_margin
    moving = world.kind != STATIC
    if not moving.any():
        return base
    vmax = 0.0   # everything at rest: only gravity closes gaps
    if s.vel.any() or s.omega.any():
        ext = toi_mod._extents(world)
        v2 = np.einsum("ij,ij->i", s.vel, s.vel)
        w2 = np.einsum("ij,ij->i", s.omega, s.omega)
        speed = np.sqrt(v2) + np.sqrt(w2) * np.where(np.isfinite(ext), ext, 0.0)
        vmax = float(speed[moving].max())
    reach = 2.0 * vmax * dt + float(np.linalg.norm(world.gravity)) * dt * dt
    return max(base, min(reach, SPECULATIVE_MAX_FRACTION * _models.thinnest_finite(world)))


def _closing_filter(world, c, rel_vel, dt, base):
    """Keep the contacts of ``c`` within ``base`` (touching) and the separated ones whose gap can
    close within ``dt`` at the current normal velocity (``(K,) bool``): ``gap ≤ max(−v_n, 0)·dt +
    |g|·dt² + base``, with ``v_n = n·rel_vel`` (``rel_vel (K,3)`` from ``_relative_velocity``)."""
    vn = np.einsum("ij,ij->i", c.normal, rel_vel)
    g = float(np.linalg.norm(world.gravity))
    return -c.depth <= np.maximum(-vn, 0.0) * dt + g * dt * dt + base


# ---------------------------------------------------------------------------- impulse / kinematic
def _impulse_step(world, dt, m):
    """One step of the impulse (or kinematic) response. Per sub-step (split at times of impact):
    detect once, build the constraint rows once, then

    * impacts: when a contact touches and approaches faster than ``IMPACT_SPEED_FRACTION·|g|·dt``,
      the touching contacts get the instantaneous impulses of the lecture together (target
      ``-e·v_n``; a rebound slower than ``REST_REBOUND_FRACTION·|g|·dt`` rests instead, e = 0);
    * resting (all contacts within the margin): the impulse of a constant force over the rest of
      the step ``T`` such that the *end* normal velocity is at least ``min(depth,0)/T`` (never
      approaching; a gap may close exactly), friction sticking at the end or kinetic; warm
      started from the previous step's matched contacts;
    * split impulse: pseudo-velocities remove ``split_beta`` of each penetration, then are dropped.
    """
    st = world.settings
    s = world.s
    margin = st.contact_margin
    exact_toi = m.toi in ("fractional", "swept")
    gdt = float(np.linalg.norm(world.gravity)) * dt
    v_imp = IMPACT_SPEED_FRACTION * gdt
    dyn = world.kind == DYNAMIC
    rotating = dyn & ~world.particle
    g = _gravity(world)
    t_left = dt
    events = 0
    records = []
    iters, residual, max_pen = 0, 0.0, 0.0
    pseudo = None
    warm_out = None
    first = True
    drift = 0.0
    rest_bound = 0.0
    world._cs_kick_error = 0.0
    spec = st.speculative and not exact_toi
    swept_pair = None
    while True:
        det_margin = _speculative_margin(world, t_left) if spec else margin
        c = toi_mod.mark_swept(_detect(world, det_margin), swept_pair)   # the sweep's hit: feature swept
        swept_pair = None
        rel_vel = _relative_velocity(world, c, m)
        if spec and det_margin > margin and len(c):
            near = _closing_filter(world, c, rel_vel, t_left, margin)
            if not near.all():
                c, rel_vel = c.select(near), rel_vel[near]
        k = len(c)
        dv_rest = None
        dw_rest = None
        exclude = np.zeros(0, np.int64)
        if k:
            if first:
                max_pen = max(max_pen, float(c.depth.max()))
            R = quat.to_matrix(s.quat)
            rows = _rows(world, c, _inv_inertia(world, m, R), rel_vel, m)
            local = local_points(world, c, R)
            e, mu_s, mu_d = _coefficients(world, c, m)
            fr = m.friction and m.response != "kinematic"
            vn0 = np.einsum("ij,ij->i", c.normal, rel_vel)
            if exact_toi:   # within the time-of-impact search's tolerance of touching, relative to size
                ext = toi_mod._extents(world)
                touching = c.depth >= -toi_mod.TOI_TOLERANCE * np.minimum(ext[c.body_a], ext[c.body_b])
            else:
                touching = c.depth >= -margin
            if exact_toi:
                # contacts that close within a millionth of a step of the impact found are hit in the
                # same instant (a box landing flat, tilted by round-off, hits all four corners at once;
                # one corner alone would kick it into a spin)
                touching |= c.depth >= vn0 * (SIMULTANEOUS_FRACTION * dt)
            if m.resting:   # a rebound whose flight is shorter than a step comes to rest (ends Zeno bounces)
                e = np.where(e * np.maximum(-vn0, 0.0) < REST_REBOUND_FRACTION * gdt, 0.0, e)
            lam = np.zeros((k, 3))
            impact = touching & (vn0 < (-v_imp if m.resting else 0.0))
            closing = np.zeros(k, bool)
            if spec:
                # speculative contacts (apart, within the look-ahead): the impulse leaves the normal
                # velocity at what closes exactly the gap over the step under gravity, v_n ≥ (−gap −
                # g_n T²/2)/T, so the pair arrives touching instead of overlapping; one that bounces
                # (e > 0) does so in this step from the approach speed it has now (Box2D's
                # restitution rule: the rebound starts up to one gap early, and e = 1 loses nothing)
                g_n = np.einsum("ij,ij->i", c.normal, g[c.body_a] - g[c.body_b])
                # never positive: a pair nearer than gravity's sag over the step is only stopped here
                # (pushing it apart to arrive touching would be work done by the contact); the resting
                # stage's constant force then lands it exactly
                spec_target = np.minimum((c.depth - 0.5 * g_n * t_left * t_left) / t_left, 0.0)
                closing = ~touching & (vn0 < spec_target)
            bounced = impact | (closing & (e > 0))
            if m.response == "kinematic" and impact.any() and not closing.any():
                lam[:, 0], vn1 = _kinematic_impacts(world, c, rel_vel, e, touching & (vn0 <= 0.0))
            elif impact.any() or closing.any():
                # a touching pair that separates takes no impact impulse: it was not hit; were it
                # held at v_n = 0 against the push of the others' impulses, the LCP would make it
                # push a separating body along (positive work: a corner gained energy). If the
                # others' impulses turn it into an approach, the resting stage stops it inelastically
                ti = np.flatnonzero((touching & (vn0 <= 0.0)) | closing)
                r1 = rows.select(ti)
                # the kinetic energy the impact starts from, for the restitution stage's cap below
                # (only where something bounces: with e = 0 there is no restitution stage)
                bounces = bool(np.any(e[ti] * bounced[ti] > 0))
                if bounces:
                    bodies0 = np.unique(np.concatenate([c.body_a[ti], c.body_b[ti]]))
                    bodies0 = bodies0[dyn[bodies0]]
                    kinetic0 = kinetic_energy(world, bodies0)
                # compression: the pairs are stopped (touching) or slowed to arrive touching
                # (speculative), with friction; inelastic, so it can only take energy away
                target = np.where(touching[ti], 0.0, spec_target[ti] if spec else 0.0)
                res = _solve(st, r1, s.vel, s.omega, target_n=target, mu_s=mu_s[ti] if fr else None,
                             mu_d=mu_d[ti] if fr else None)
                lam[ti] += res.impulse
                iters = max(iters, res.iterations)
                residual = max(residual, res.residual)
                if bounces:   # the velocities after compression
                    vel_c, omega_c = s.vel[bodies0].copy(), s.omega[bodies0].copy()
                # restitution, its own stage (Box2D's restitution pass): the pairs that were hit and
                # bounce get normal impulses only, up to −e × the approach speed recorded before the
                # step. Friction stays in the compression, so a sticking impact cannot gain energy
                # (Newton's rule with friction in one solve can: Kane's paradox); e = 1 keeps it
                hit = bounced & (lam[:, 0] > 0) & (e > 0)   # e = 0: the compression was the whole impact
                if hit.any():
                    hi = np.flatnonzero(hit)
                    res = _solve(st, rows.select(hi), s.vel, s.omega, target_n=-e[hi] * vn0[hi])
                    lam[hi, 0] += res.impulse[:, 0] * energetic_cap(world, bodies0, kinetic0, vel_c, omega_c)
                    iters = max(iters, res.iterations)
                vn1 = solver.row_velocity(rows, s.vel, s.omega)[:, 0]
            else:
                vn1 = vn0
            if m.resting and (touching.any() or not exact_toi) and not (bounced.any() and np.all(vn1 > v_imp)):
                v_end = s.vel + g * t_left
                w_end = s.omega.copy()
                v_start_end = v_end.copy()
                w_start_end = w_end.copy()
                # with exact times of impact only touching contacts rest (the others get their impact
                # time); with next_step every contact within the margin is a speculative one
                # a contact that just rebounded is leaving: no resting force may hold it back
                leaving = bounced & (vn1 > v_imp)
                if exact_toi:   # touching or slowly approaching; a fast one within the margin gets its impact time
                    rmask = (touching | (vn0 >= -gdt)) & ~leaving
                else:
                    rmask = ~leaving
                # every contact rests (the usual case): read the arrays as they are, no gathers
                ri = slice(None) if rmask.all() else np.flatnonzero(rmask)
                r2 = rows.select(rmask)
                # the constant contact force acts over T on the displacement (v_start + v_end)/2·T: that
                # may close a gap exactly, never more, and never asks the pair to separate; an
                # approaching pair ends at rest (inelastic), a separating one may come back by its own
                # displacement: the force then does no work (an end-velocity target of 0 made a force
                # that held a separating body up, and added energy)
                target = np.minimum(2.0 * np.minimum(c.depth[ri], 0.0) / t_left - vn1[ri], 0.0)
                warm = project_warm(warm_lookup(world, c.body_a[ri], c.body_b[ri], local[ri]) * t_left, r2,
                                     mu_d[ri])
                res = _solve(st, r2, v_end, w_end, target_n=target, mu_s=mu_s[ri] if fr else None,
                             mu_d=mu_d[ri] if fr else None, warm=warm)
                iters = max(iters, res.iterations)
                residual = max(residual, res.residual)
                lam2 = np.zeros((k, 3))
                lam2[ri] = res.impulse
                # the constant-force model is first order in what the force does while the contact
                # point moves during the interval: its work is right to within ½|λ|·|v_point|
                vs_rows = solver.row_velocity(r2, s.vel, s.omega)
                rest_bound += 0.5 * float(np.sum(np.linalg.norm(res.impulse, axis=1) * np.linalg.norm(vs_rows, axis=1)))
                dv_rest = v_end - v_start_end
                dw_rest = w_end - w_start_end
                # copies: stored across steps, never views of this step's contacts
                warm_out = (c.body_a[ri].copy(), c.body_b[ri].copy(), local[ri].copy(),
                            warm_record(res.impulse, r2) / t_left)
            if first:
                pseudo = _split_impulse(world, c, rows, dt)
            near = touching.copy()
            if dv_rest is not None:
                near[ri] = True
            if exact_toi or m.continuous:   # pairs already in contact: keys min·N + max (no time of impact for them)
                ea, eb = c.body_a[near], c.body_b[near]
                exclude = np.minimum(ea, eb) * len(world) + np.maximum(ea, eb)
        first = False
        tau = t_left
        if (exact_toi or m.continuous) and events < st.max_impacts_per_step:
            acc = g if dv_rest is None else g + dv_rest / t_left
            motion = toi_mod.Motion(world, acc, rotating)
            # next_step with continuous bodies: a search for the fast bodies' pairs only
            ev, pair = toi_mod.earliest_event(world, motion, t_left, exclude, swept=m.toi == "swept",
                                              only=m.continuous if not exact_toi else None)
            if ev < t_left:
                tau = ev
                events += 1
                swept_pair = motion.swept_pair
        frac = tau / t_left
        if k:
            if dv_rest is not None:
                lam += lam2 * frac
            rec = record(c, rows, lam, vn0)
            if spec:   # speculative contacts that did nothing are not contacts of this step
                used = touching | (lam[:, 0] > 0)
                rec, loc_rec = (rec, local) if used.all() else (rec.select(used), local[used])
            else:
                loc_rec = local
            records.append((rec, loc_rec))
        if dv_rest is None:
            drift += world._advance_free(tau)
        else:
            drift += _advance(world, tau, 0.5 * dv_rest * frac, 0.5 * dw_rest * frac)
        if frac >= 1.0:
            break
        t_left -= tau
    correction = 0.0
    if pseudo is not None:
        vp, wp = pseudo
        _move(world, vp * dt, wp * dt)
        correction = potential_change(world, vp * dt)
    world._cs_warm = warm_out
    world.contacts = merge_records(world, records)
    world.last_solve = StepStats(iterations=iters, residual=residual, max_penetration=max_pen,
                                 contacts=len(world.contacts), impacts=events, toi=m.toi, response=m.response,
                                 correction_energy=correction, kinematic_work=kinematic_work(world, world.contacts),
                                 rotation_drift=drift, kick_error_bound=world.__dict__.pop("_cs_kick_error"),
                                 rest_work_bound=rest_bound)


def _kinematic_impacts(world, c, rel_vel, e, which):
    """The kinematic response ``v ← v − (1+k)(N·v)N`` (``response.kinematic``) on the contacts
    ``which``: ``(normal impulses (K,), normal velocities after (K,))``."""
    s = world.s
    inv_m = np.where(world.kind == DYNAMIC, world.inv_mass, 0.0)
    before = s.vel[c.body_a] - s.vel[c.body_b]
    lam = kinematic_mod.kinematic_impacts(s.vel, inv_m, c.body_a, c.body_b, c.normal, rel_vel, e, which)
    rv = rel_vel + (s.vel[c.body_a] - s.vel[c.body_b]) - before
    return lam, np.einsum("ij,ij->i", c.normal, rv)


def _advance(world, tau, half_dv, half_dw):
    """Free motion over ``tau`` with a constant contact force whose velocity change over ``tau`` is
    ``2·half_dv (N,3)`` (angular ``2·half_dw``): kick half, drift exactly, kick half."""
    s = world.s
    s.vel += half_dv
    kicked = np.flatnonzero(np.any(half_dw != 0, axis=1))
    if kicked.size:
        ke0 = rotational_energy(world, kicked)
    s.omega += half_dw
    drift = world._advance_free(tau)
    s.vel += half_dv
    s.omega += half_dw
    if kicked.size:
        # the torque's two half-kicks around a turning drift are exact to first order in the angle
        # turned: what they move of a body's rotational energy is right to within |ω|·τ of itself
        moved = np.abs(rotational_energy(world, kicked) - ke0)
        turned = np.linalg.norm(s.omega[kicked], axis=1) * tau
        world._cs_kick_error = getattr(world, "_cs_kick_error", 0.0) + float(moved @ turned)
    return drift


def _move(world, dx, dtheta):
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


def _split_impulse(world, c, rows, dt):
    """Pseudo-velocities ``(vp, wp) (N,3)`` removing ``settings.split_beta`` of each penetration over
    ``dt`` (normal rows only, non-negative), or ``None`` when nothing penetrates deeper than
    ``settings.split_slop``. ``rows`` are the
    constraint rows of all contacts ``c``; only the penetrating ones take part."""
    if len(c) == 0 or c.depth.max() <= world.settings.split_slop:
        return None
    pen = np.flatnonzero(c.depth > 0)
    if pen.size == 0:
        return None
    vp = np.zeros_like(world.s.vel)
    wp = np.zeros_like(world.s.omega)
    st = world.settings
    _solve(st, rows.select(pen), vp, wp, target_n=st.split_beta * c.depth[pen] / dt)
    return vp, wp


# ---------------------------------------------------------------------------- penalty
def _penalty_step(world, dt, m):
    """Penalty response: a spring ``k·depth`` and damper ``−c·v_n`` along each contact normal (never
    pulling), integrated implicitly (backward Euler): the force uses the depth and normal velocity
    at the *end* of the step, ``F = k·(d − dt·v_n⁺) − c·v_n⁺``, which makes the impulse of each
    contact ``λ = dt·F`` the solution of ``v_n⁺ + γλ = k·d/(dt·k + c)`` with compliance
    ``γ = 1/(dt·(dt·k + c))`` (the soft-constraint form of Catto's soft step and ODE's CFM/ERP).
    Stable for every stiffness and step (the explicit spring exploded above sqrt(k/m)·dt = 2, which
    the old defaults crossed for a 1 kg body at the default dt); rest is still exactly k·depth = m g.
    Bodies in contact move by ``x += dt·v⁺`` (symplectic Euler), free bodies ballistically."""
    st = world.settings
    s = world.s
    c = _detect(world, 0.0)
    k = len(c)
    max_pen = float(c.depth.max()) if k else 0.0
    if k:
        rel_vel = _relative_velocity(world, c, m)
        rows = _rows(world, c, _inv_inertia(world, m, quat.to_matrix(s.quat)), rel_vel, m)
        vn0 = np.einsum("ij,ij->i", c.normal, rel_vel)
        stiff, damp = st.penalty.stiffness, st.penalty.damping
        gamma = np.full(k, 1.0 / (dt * (dt * stiff + damp)))
        target = stiff * np.maximum(c.depth, 0.0) / (dt * stiff + damp)
        g = _gravity(world)
        v_end = s.vel + g * dt          # the velocity the step would end with without contact
        w_end = s.omega.copy()
        res = solver.solve_soft(rows, v_end, w_end, target_n=target, compliance=gamma,
                                iterations=st.solver_iterations, tolerance=st.solver_tolerance,
                                direct_max=st.direct_max_contacts)
        if m.friction:   # regularised Coulomb friction, implicit (response.penalty_friction)
            penalty_friction.solve_with_friction(rows, v_end, w_end, res.impulse, target, gamma,
                                                 _coefficients(world, c, m)[2], st.penalty.friction_velocity)
        world.contacts = record(c, rows, res.impulse, vn0)
        # bodies in contact: x += dt·v⁺ (the kick, then half of gravity's kick shifted so that the
        # exact ballistic drift below ends at that position); free bodies keep the exact ballistic step
        touched = np.zeros(len(world), bool)
        touched[c.body_a] = True
        touched[c.body_b] = True
        shift = np.where((touched & (world.kind == DYNAMIC))[:, None], 0.5 * world.gravity * dt, 0.0)
        s.vel += (v_end - g * dt - s.vel) + shift
        s.omega[...] = w_end
        drift = world._advance_free(dt)
        s.vel -= shift
        iters, residual = res.iterations, res.residual
    else:
        world.contacts = Contacts.empty()
        drift = world._advance_free(dt)
        iters, residual = 0, 0.0
    world.last_solve = StepStats(iterations=iters, residual=residual, max_penetration=max_pen, contacts=k,
                                 toi=m.toi, response=m.response,
                                 kinematic_work=kinematic_work(world, world.contacts), rotation_drift=drift)
