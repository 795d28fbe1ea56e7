"""The impact stage of a step: instantaneous impulses where contacts approach.

Compression first: the touching pairs that approach are stopped, and speculative ones (apart,
within the look-ahead) slowed to arrive touching, with Coulomb friction, inelastically (it can
only take energy away). Then restitution, its own stage (Box2D's restitution pass): the pairs that
were hit and bounce get normal impulses only, up to ``−e ×`` the approach speed recorded at
preparation (``ctx.vn0``), capped by Stronge's energetic bound. Friction stays in the compression,
so a sticking impact cannot gain energy (Newton's rule with friction in one solve can: Kane's
paradox); e = 1 keeps it. Under the kinematic response a dynamic body is a particle:
``v ← v − (1+k)(N·v)N`` (``response.kinematic``).
"""
import numpy as np

from ..jit import njit
from ..kinds import DYNAMIC
from ..constants import IMPACT_ROUNDS
from .energy import FRAME, NO_FRAME, dynamic_bodies, frame_of, kinetic_in, push_cap_kernel, push_speed, restitution_cap_in
from .kinematic import kinematic_impacts
from .pgs import normal_velocities
from .solver import solve_rows


@njit
def impact_stage(a, b, point, normal, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, rel_vel, touching, closing,
                 bounced, spec_target, e, e_material, soft, vn0, n_impact, n_closing, particles, resting, rebound_speed,
                 impact_speed, mu_s, mu_d, kinetic, kind, dynamic, kinematic, inv_mass, inv_inertia, mass, particle,
                 pos, quat, inertia_body, method, direct_max, max_iterations, tolerance, vel, omega, vel_ref, omega_ref,
                 lam, vn1):
    """The impacts of a sub-step on its ``K`` contacts (rows as ``rows.Rows``' arrays): writes the
    impulses ``lam (K,3)`` (zeros in) and the normal velocities after ``vn1 (K,)``, updates the
    bodies' ``vel, omega (N,3)`` and marks in ``bounced (K,)`` every contact that bounced. Returns
    ``(sweeps, residual, unconverged)`` (a solve stopped, at ``max_iterations`` or stalled, with
    impulses still changing by more than ``tolerance``: ``solver.solve_rows``).

    Impacts come in rounds. The first takes the touching pairs that approach and the closing
    speculative ones, at the approach speeds recorded at preparation (``vn0``). Its impulses can
    turn other contacts into an approach: a box whose corner rebounds from a wall swings its other
    corner into it within the same step. Each such contact is an impact of its own, at the approach
    speed it has now, so the next round takes the contacts that approach after the last one
    (``next_round``), until none does or ``IMPACT_ROUNDS`` rounds are done; the resting stage stops
    what still approaches then (inelastically). Left to the resting stage at once, a second
    corner's elastic impact lost its rebound: e = 1 lost energy.

    Under the kinematic response (``particles``) touching contacts are reflected one by one
    (``response.kinematic``), fastest approach first, unless a speculative contact closes (then the
    rows, whose levers sit at the bodies' centres, take them all). ``vel_ref, omega_ref (N,3)``:
    the velocities at the sub-step's start, which the push cap's budget is measured from in every
    solve of the sub-step (``energy.push_cap_kernel``)."""
    k = a.shape[0]
    if particles and n_impact and not n_closing:
        _kinematic_impacts(a, b, normal, rel_vel, e, touching, vn0, kind, inv_mass, vel, lam, vn1)
        return 0, 0.0, False
    if not (n_impact or n_closing):
        vn1[:] = vn0
        return 0, 0.0, False
    # a touching pair that separates takes no impact impulse: it was not hit; were it held at
    # v_n = 0 against the push of the others' impulses, the LCP would make it push a separating
    # body along (positive work: a corner gained energy). If the others' impulses turn it into an
    # approach, the next round hits it. Separating means by more than the solver's tolerance: a
    # resting box's corners part by round-off, and each left out would let an impact on the box
    # tip it about the others
    take = (touching & (vn0 <= tolerance)) | closing
    if soft.shape[0]:   # a compliant contact takes no impact: its spring and damper stop it
        take &= ~soft
    er, hit, vn = e, bounced.copy(), vn0
    e_next, hit_next = np.empty(k), np.empty(k, np.bool_)
    it, residual, unconverged = 0, 0.0, False
    for _ in range(IMPACT_ROUNDS):
        it_r, residual_r, stopped = _round(np.flatnonzero(take), a, b, point, dirs, ang_a, ang_b, iang_a, iang_b, ima,
                                           imb, K, touching, hit, spec_target, er, vn, mu_s, mu_d, kinetic, kind,
                                           dynamic, kinematic, inv_mass, inv_inertia, mass, particle, pos, quat,
                                           inertia_body, method, direct_max, max_iterations, tolerance, vel, omega,
                                           vel_ref, omega_ref, lam)
        it, residual, unconverged = max(it, it_r), max(residual, residual_r), unconverged or stopped
        normal_velocities(a, b, dirs, ang_a, ang_b, vel, omega, vn1)
        if not next_round(touching, spec_target, vn1, e_material, resting, rebound_speed, impact_speed, tolerance, soft,
                          take, e_next, hit_next):
            break
        for c in range(k):
            bounced[c] = bounced[c] or hit_next[c]
        er, hit, vn = e_next.copy(), hit_next.copy(), vn1.copy()
    return it, residual, unconverged


@njit
def _round(ti, a, b, point, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, touching, bounced, spec_target, e, vn, mu_s,
           mu_d, kinetic, kind, dynamic, kinematic, inv_mass, inv_inertia, mass, particle, pos, quat, inertia_body,
           method, direct_max, max_iterations, tolerance, vel, omega, vel_ref, omega_ref, lam):
    """One impact round on the contacts ``ti (T,)`` approaching at ``vn (K,)``: compression with
    friction (touching ones stopped, speculative ones slowed to ``spec_target``), then restitution
    (normal only, up to ``−e·vn`` where ``bounced (K,)``, the other pressed touching contacts held at
    ``v_n ≥ 0``) scaled by Stronge's energetic cap over the round's bodies
    (``energy.restitution_cap_in``). Adds the round's impulses to ``lam (K,3)``; updates ``vel,
    omega``. Returns ``(sweeps, residual, unconverged)``."""
    k = a.shape[0]
    nt = ti.shape[0]
    bounces = False
    for c in ti:
        bounces = bounces or e[c] * bounced[c] > 0.0
    # the kinetic energy the round starts from, for the restitution stage's cap (only where
    # something bounces: with e = 0 there is no restitution stage), in the frame of the kinematic
    # body the impact is against (energy.frame_of)
    ta, tb = a[ti], b[ti]
    bodies0 = dynamic_bodies(ta, tb, dynamic)
    frame = np.zeros((3, 3))
    code = frame_of(kind, ta, tb, vel, omega, pos, frame) if bounces else NO_FRAME
    kinetic0 = kinetic_in(bodies0, mass, particle, quat, inertia_body, vel, omega, pos, frame, code == FRAME) \
        if bounces and code != NO_FRAME else 0.0
    # where kinematic bodies push, no body ends faster than a push can make it (energy.push_cap_kernel)
    u = push_speed(ta, tb, point[ti], kinematic, dynamic, pos, vel, omega)
    pb = bodies0
    # the pushed bodies' velocities before the solve: only the push cap reads them
    v0, w0 = (vel[pb], omega[pb]) if u >= 0.0 else (vel[:0], omega[:0])
    target = np.empty(nt)
    for j in range(nt):
        target[j] = 0.0 if touching[ti[j]] else spec_target[ti[j]]
    lam_t = np.zeros((nt, 3))
    zeros = np.zeros(nt)
    it, residual, unconverged = solve_rows(method, ta, tb, dirs[ti], ang_a[ti], ang_b[ti], iang_a[ti], iang_b[ti],
                                           ima[ti], imb[ti], K[ti], target, zeros, mu_s[ti], mu_d[ti], kinetic,
                                           np.zeros((nt, 3)), False, dynamic, inv_mass, inv_inertia, direct_max,
                                           max_iterations, tolerance, vel, omega, lam_t)
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
    if np.any(hit):
        # the contacts the compression pressed and that do not bounce hold through the restitution
        # at the compression's targets (touching v_n ≥ 0, apart the speculative target): a ball's
        # rebound from a box on the ground does not push the box into the ground, where nothing
        # would give it back
        hi = np.flatnonzero(hit | (pressed & ~bounced))
        nh = hi.shape[0]
        target_h = np.empty(nh)
        for j in range(nh):
            c = hi[j]
            target_h[j] = -e[c] * vn[c] if hit[c] else (0.0 if touching[c] else spec_target[c])
        zeros_h = np.zeros(nh)
        lam_h = np.zeros((nh, 3))
        it_h, residual_h, stopped_h = solve_rows(method, a[hi], b[hi], dirs[hi], ang_a[hi], ang_b[hi], iang_a[hi],
                                                 iang_b[hi], ima[hi], imb[hi], K[hi], target_h, zeros_h, zeros_h,
                                                 zeros_h, False, np.zeros((nh, 3)), False, dynamic, inv_mass,
                                                 inv_inertia, direct_max, max_iterations, tolerance, vel, omega, lam_h)
        unconverged = unconverged or stopped_h
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
    return it, residual, unconverged


@njit(_nrt=False)
def next_round(touching, spec_target, vn, e_material, resting, rebound_speed, impact_speed, tolerance, soft, take, e,
               bounced):
    """The next impact round, from the normal velocities ``vn (K,)`` the last round left: whether
    one is due, and its contacts. It is due when a contact approaches now, a touching one faster
    than a bounce needs (``impact_speed`` with resting contact, else at all), an apart one (within
    the look-ahead, or the margin of an exact time of impact) fast enough to close its gap within
    the step (``vn < spec_target``); ``tolerance`` (m/s) keeps round-off out. It takes them and, as
    the first round does, the touching contacts that do not separate; never a compliant one (``soft
    (K,) bool``, or empty: none). Writes ``take (K,) bool``, the
    restitution ``e (K,)`` (zero where the rebound would rest, as ``prepare.classify`` rules) and
    ``bounced (K,) bool``; returns how many approach and, with resting contact, bounce (0: no
    further round: with e = 0 a 200-body pile ran rounds to the limit of 128 a sub-step, 8 times
    slower, for what the resting stage does alike)."""
    threshold = (impact_speed if resting else 0.0) + tolerance
    count = 0
    for c in range(vn.shape[0]):
        v = vn[c]
        if touching[c]:
            approach = v < -threshold
            take[c] = v <= tolerance
        else:
            approach = v < spec_target[c] - tolerance
            take[c] = approach
        if soft.shape[0] > 0 and soft[c]:
            approach = False
            take[c] = False
        er = e_material[c]
        if resting and er * max(-v, 0.0) < rebound_speed:
            er = 0.0
        e[c] = er
        bounced[c] = approach and (touching[c] or er > 0.0)
        # with resting contact, an approach that does not bounce is the resting stage's (which stops
        # it, as an inelastic impact would): only a bounce needs a round of its own
        count += approach and (er > 0.0 or not resting)
    return count


@njit
def _kinematic_impacts(a, b, normal, rel_vel, e, touching, vn0, kind, inv_mass, vel, lam, vn1):
    """The kinematic response ``v ← v − (1+k)(N·v)N`` (``kinematic.kinematic_impacts``) on the
    touching contacts that approach (``vn0 ≤ 0``): writes their normal impulses on A into ``lam[:,
    0]`` and every contact's normal velocity after into ``vn1 (K,)``; ``vel (N,3)`` updated. A
    dynamic body is a particle: its spin is neither seen nor changed."""
    k = a.shape[0]
    inv_m = np.zeros(inv_mass.shape[0])
    for i in range(inv_mass.shape[0]):
        if kind[i] == DYNAMIC:
            inv_m[i] = inv_mass[i]
    before = np.empty((k, 3))
    for c in range(k):
        for x in range(3):
            before[c, x] = vel[a[c], x] - vel[b[c], x]
    out = np.empty(k)
    kinematic_impacts(vel, inv_m, a, b, normal, rel_vel, e, touching & (vn0 <= 0.0), out)
    for c in range(k):
        lam[c, 0] = out[c]
        v = 0.0
        for x in range(3):
            v += normal[c, x] * (rel_vel[c, x] + (vel[a[c], x] - vel[b[c], x]) - before[c, x])
        vn1[c] = v
