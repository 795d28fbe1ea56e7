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
from . import kinematic as kinematic_mod
from . import pgs
from ..constants import IMPACT_ROUNDS, REST_REBOUND_FRACTION
from .energy import energetic_cap, impact_frame, kinematic_push, kinetic_energy, push_cap


def impact_solve(ctx):
    """Writes ``ctx.impulse (K,3)`` (the impacts' impulses) and ``ctx.vn1 (K,)`` (normal velocities
    after), updating the bodies' velocities and marking in ``ctx.bounced`` every contact that bounced.

    Impacts come in rounds. The first takes the touching pairs that approach and the closing
    speculative ones, at the approach speeds recorded at preparation (``ctx.vn0``). Its impulses
    can turn other contacts into an approach: a box whose corner rebounds from a wall swings its
    other corner into it within the same step. Each such contact is an impact of its own, at the
    approach speed it has now, so the next round takes the contacts that approach after the last
    one (``next_round``), until none does or ``IMPACT_ROUNDS`` rounds are done; the resting stage
    stops what still approaches then (inelastically). Left to the resting stage at once, a second
    corner's elastic impact lost its rebound: e = 1 lost energy."""
    world = ctx.world
    c = ctx.contacts
    vn0, touching, closing = ctx.vn0, ctx.touching, ctx.closing
    lam = np.zeros((len(c), 3))
    ctx.impulse = lam
    s = world.s
    ctx.push_ref = (s.vel.copy(), s.omega.copy()) if world.body_masks().any_kinematic else None
    n = ctx.counts
    if ctx.models.response == "kinematic" and n.impact and not n.closing:
        lam[:, 0], ctx.vn1 = _kinematic_impacts(world, c, ctx.rel_vel, ctx.restitution, touching & (vn0 <= 0.0))
        return
    if not (n.impact or n.closing):
        ctx.vn1 = vn0
        return
    # a touching pair that separates takes no impact impulse: it was not hit; were it held at
    # v_n = 0 against the push of the others' impulses, the LCP would make it push a separating
    # body along (positive work: a corner gained energy). If the others' impulses turn it into an
    # approach, the next round hits it. Separating means by more than the solver's tolerance: a
    # resting box's corners part by round-off, and each left out would let an impact on the box
    # tip it about the others
    st = ctx.settings
    tol = float(st.solver_tolerance)
    take = (touching & (vn0 <= tol)) | closing
    if ctx.soft.shape[0]:   # a compliant contact takes no impact: its spring and damper stop it
        take &= ~ctx.soft
    e, bounced, vn = ctx.restitution, ctx.bounced, vn0
    r = ctx.rows
    cc = np.ascontiguousarray
    a, b = cc(r.a, dtype=np.int64), cc(r.b, dtype=np.int64)
    dirs, ang_a, ang_b = cc(r.dirs), cc(r.ang_a), cc(r.ang_b)
    more = np.empty(len(c), bool), np.empty(len(c)), np.empty(len(c), bool)
    for _ in range(IMPACT_ROUNDS):
        _round(ctx, np.flatnonzero(take), vn, e, bounced, lam)
        vn = np.empty(len(c))
        pgs.normal_velocities(a, b, dirs, ang_a, ang_b, world.s.vel, world.s.omega, vn)
        take, e_next, hit = more
        if not next_round(touching, ctx.spec_target, vn, ctx.e_material, ctx.models.resting,
                          REST_REBOUND_FRACTION * ctx.gdt, ctx.impact_speed, tol, ctx.soft, take, e_next, hit):
            break
        ctx.bounced = ctx.bounced | hit
        e, bounced = e_next, hit
    ctx.vn1 = vn


def _round(ctx, ti, vn, e, bounced, lam):
    """One impact round on the contacts ``ti (T,)`` approaching at ``vn (K,)``: compression with
    friction (touching ones stopped, speculative ones slowed to arrive touching), then restitution
    (normal only, up to ``−e·vn`` where ``bounced (K,)``, the other pressed touching contacts held at
    ``v_n ≥ 0``) scaled by Stronge's energetic cap over the round's bodies. Adds the round's
    impulses to ``lam (K,3)``; updates the bodies' velocities."""
    world = ctx.world
    s = world.s
    c = ctx.contacts
    # the kinetic energy the round starts from, for the restitution stage's cap (only where
    # something bounces: with e = 0 there is no restitution stage)
    bounces = bool(np.any(e[ti] * bounced[ti] > 0))
    if bounces:
        bodies0 = np.unique(np.concatenate([c.body_a[ti], c.body_b[ti]]))
        bodies0 = bodies0[(world.kind == DYNAMIC)[bodies0]]
        frame = impact_frame(world, c.body_a[ti], c.body_b[ti])   # against a moving kinematic body: its frame
        kinetic0 = kinetic_energy(world, bodies0, frame) if frame is not False else 0.0
    target = np.where(ctx.touching[ti], 0.0, ctx.spec_target[ti])
    fr = ctx.friction
    pushed = kinematic_push(world, c.body_a[ti], c.body_b[ti], c.point[ti])
    if pushed is not None:   # the cap is measured from the stage's start: each round within it
        v0, w0 = s.vel[pushed[0]].copy(), s.omega[pushed[0]].copy()
    res = ctx.solve(ctx.rows.select(ti), s.vel, s.omega, target_n=target, mu_s=ctx.mu_s[ti] if fr else None,
                    mu_d=ctx.mu_d[ti] if fr else None)
    ctx.note(res)
    # where kinematic bodies push, no body ends faster than a push can make it
    scale = 1.0 if pushed is None else push_cap(world, *pushed, v0, w0, s.vel, s.omega,
                                                ref=(ctx.push_ref[0][pushed[0]], ctx.push_ref[1][pushed[0]]))
    lam_r = np.zeros((len(c), 3))
    lam_r[ti] = res.impulse * scale
    if bounces:   # the velocities after compression
        vel_c, omega_c = s.vel[bodies0].copy(), s.omega[bodies0].copy()
    pressed = lam_r[:, 0] > 0
    hit = bounced & pressed & (e > 0)   # e = 0: the compression was the whole impact
    if hit.any():
        # the touching contacts the compression pressed and that do not bounce hold through the
        # restitution (v_n ≥ 0): a ball's rebound from a box on the ground does not push the box
        # into the ground, where nothing would give it back
        hi = np.flatnonzero(hit | (pressed & ctx.touching & ~bounced))
        res = ctx.solve(ctx.rows.select(hi), s.vel, s.omega, target_n=np.where(hit[hi], -e[hi] * vn[hi], 0.0))
        f = 1.0 if frame is False else energetic_cap(world, bodies0, kinetic0, vel_c, omega_c, frame)
        if pushed is not None:   # the rebound within the push budget too (with a static body: no frame)
            f *= push_cap(world, *pushed, vel_c, omega_c, s.vel, s.omega,
                          ref=(ctx.push_ref[0][pushed[0]], ctx.push_ref[1][pushed[0]]))
        lam_r[hi, 0] += res.impulse[:, 0] * f
        ctx.note(res, residual=False)
    lam += lam_r


@njit
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


def _kinematic_impacts(world, c, rel_vel, e, which):
    """The kinematic response ``v ← v − (1+k)(N·v)N`` (``response.kinematic``) on the contacts
    ``which (K,) bool``: ``(normal impulses (K,), normal velocities after (K,))``."""
    s = world.s
    inv_m = np.where(world.kind == DYNAMIC, world.inv_mass, 0.0)
    before = s.vel[c.body_a] - s.vel[c.body_b]
    lam = kinematic_mod.kinematic_impacts(s.vel, inv_m, c.body_a, c.body_b, c.normal, rel_vel, e, which)
    rv = rel_vel + (s.vel[c.body_a] - s.vel[c.body_b]) - before
    return lam, np.einsum("ij,ij->i", c.normal, rv)
