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

from ..kinds import DYNAMIC
from . import kinematic as kinematic_mod
from . import pgs
from .energy import energetic_cap, kinematic_push, kinetic_energy, push_cap


def impact_solve(ctx):
    """Writes ``ctx.impulse (K,3)`` (the impacts' impulses) and ``ctx.vn1 (K,)`` (normal velocities
    after), updating the bodies' velocities."""
    world = ctx.world
    s = world.s
    c = ctx.contacts
    e, vn0, touching, closing = ctx.restitution, ctx.vn0, ctx.touching, ctx.closing
    lam = np.zeros((len(c), 3))
    ctx.impulse = lam
    n = ctx.counts
    if ctx.models.response == "kinematic" and n.impact and not n.closing:
        lam[:, 0], ctx.vn1 = _kinematic_impacts(world, c, ctx.rel_vel, e, touching & (vn0 <= 0.0))
        return
    if not (n.impact or n.closing):
        ctx.vn1 = vn0
        return
    # a touching pair that separates takes no impact impulse: it was not hit; were it held at
    # v_n = 0 against the push of the others' impulses, the LCP would make it push a separating
    # body along (positive work: a corner gained energy). If the others' impulses turn it into an
    # approach, the resting stage stops it inelastically
    ti = np.flatnonzero((touching & (vn0 <= 0.0)) | closing)
    bounced = ctx.bounced
    # the kinetic energy the impact starts from, for the restitution stage's cap (only where
    # something bounces: with e = 0 there is no restitution stage)
    bounces = bool(np.any(e[ti] * bounced[ti] > 0))
    if bounces:
        bodies0 = np.unique(np.concatenate([c.body_a[ti], c.body_b[ti]]))
        bodies0 = bodies0[(world.kind == DYNAMIC)[bodies0]]
        kinetic0 = kinetic_energy(world, bodies0)
    target = np.where(touching[ti], 0.0, ctx.spec_target[ti] if ctx.speculative else 0.0)
    fr = ctx.friction
    pushed = kinematic_push(world, c.body_a[ti], c.body_b[ti], c.point[ti])
    if pushed is not None:
        v0, w0 = s.vel[pushed[0]].copy(), s.omega[pushed[0]].copy()
    res = ctx.solve(ctx.rows.select(ti), s.vel, s.omega, target_n=target, mu_s=ctx.mu_s[ti] if fr else None,
                    mu_d=ctx.mu_d[ti] if fr else None)
    ctx.note(res)
    # where kinematic bodies push, no body ends faster than a push can make it
    scale = 1.0 if pushed is None else push_cap(world, *pushed, v0, w0, s.vel, s.omega)
    lam[ti] += res.impulse * scale
    if bounces:   # the velocities after compression
        vel_c, omega_c = s.vel[bodies0].copy(), s.omega[bodies0].copy()
    hit = bounced & (lam[:, 0] > 0) & (e > 0)   # e = 0: the compression was the whole impact
    if hit.any():
        hi = np.flatnonzero(hit)
        res = ctx.solve(ctx.rows.select(hi), s.vel, s.omega, target_n=-e[hi] * vn0[hi])
        lam[hi, 0] += res.impulse[:, 0] * energetic_cap(world, bodies0, kinetic0, vel_c, omega_c)
        ctx.note(res, residual=False)
    r = ctx.rows
    cc = np.ascontiguousarray
    ctx.vn1 = np.empty(len(c))
    pgs.normal_velocities(cc(r.a, dtype=np.int64), cc(r.b, dtype=np.int64), cc(r.dirs), cc(r.ang_a), cc(r.ang_b),
                          s.vel, s.omega, ctx.vn1)


def _kinematic_impacts(world, c, rel_vel, e, which):
    """The kinematic response ``v ← v − (1+k)(N·v)N`` (``response.kinematic``) on the contacts
    ``which (K,) bool``: ``(normal impulses (K,), normal velocities after (K,))``."""
    s = world.s
    inv_m = np.where(world.kind == DYNAMIC, world.inv_mass, 0.0)
    before = s.vel[c.body_a] - s.vel[c.body_b]
    lam = kinematic_mod.kinematic_impacts(s.vel, inv_m, c.body_a, c.body_b, c.normal, rel_vel, e, which)
    rv = rel_vel + (s.vel[c.body_a] - s.vel[c.body_b]) - before
    return lam, np.einsum("ij,ij->i", c.normal, rv)
