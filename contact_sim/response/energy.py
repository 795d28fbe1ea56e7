"""Energy bookkeeping of a step: what position correction, kinematic bodies and the resting model
may add to the total energy (reported in ``StepStats``), and the restitution stage's energetic cap."""
import math

import numpy as np

from .. import dynamics, quat
from ..free_motion import _qrot
from ..jit import njit
from ..kinds import DYNAMIC, KINEMATIC, STATIC
from ..vec import cross


def potential_change(world, dx):
    """Gravitational potential energy (J) gained by moving the dynamic bodies' centres by
    ``dx (N,3)``: what position correction may add to the total energy (it raises bodies out of
    penetration; it never adds kinetic energy)."""
    dyn = world.kind == DYNAMIC
    return float(-np.sum(world.mass[dyn] * (dx[dyn] @ world.gravity)))


def kinematic_work(world, c):
    """Work (J) done on the dynamic bodies by kinematic ones through the contacts ``c`` of a
    step: impulse on the dynamic side · velocity of the kinematic body's material point. A
    kinematic body is driven from outside, so this is energy the world may gain."""
    if len(c) == 0 or not world.body_masks().any_kinematic or not _touches(world.kind, c.body_a, c.body_b, KINEMATIC):
        return 0.0
    s = world.s
    total = 0.0
    for side, sign in ((c.body_a, -1.0), (c.body_b, 1.0)):   # A gets +impulse, B its negative
        k = world.kind[side] == KINEMATIC
        if k.any():
            i = side[k]
            u = s.vel[i] + cross(s.omega[i], c.point[k] - s.pos[i])
            total += float(np.sum(sign * c.impulse[k] * u))
    return total


@njit
def _touches(kind, a, b, which):
    """Whether a contact ``a, b (K,)`` has a body of kind ``which``."""
    for c in range(a.shape[0]):
        if kind[a[c]] == which or kind[b[c]] == which:
            return True
    return False


def impact_frame(world, a, b):
    """The frame an impact's kinetic energy is measured in, for the contacts ``a, b (K,)``: ``None``
    (the world's) when no kinematic body takes part; the rigid motion ``(v, ω, x) (3,)`` of the one
    kinematic body that does, with no static body in the impact; ``False`` otherwise (no frame).

    Against a moving kinematic body a rebound gains kinetic energy in the world frame (a paddle at
    v sends a resting ball off at 2v with e = 1): capped there, the rebound was lost. In the frame
    that moves with the body's rigid motion (each dynamic body's velocity less that field's at its
    centre, its spin less ω) every contact velocity is what it was, so the impulses are the same and
    Stronge's bound holds there; a static body or a second kinematic one moves differently, and no
    frame serves (the push cap, ``push_cap``, bounds the impact then)."""
    kind = world.kind
    kin = np.unique(np.concatenate([a[kind[a] == KINEMATIC], b[kind[b] == KINEMATIC]]))
    if kin.size == 0:
        return None
    if kin.size > 1 or np.any(kind[a] == STATIC) or np.any(kind[b] == STATIC):
        return False
    k = int(kin[0])
    s = world.s
    return s.vel[k].copy(), s.omega[k].copy(), s.pos[k].copy()


def _in_frame(world, idx, frame, vel, omega):
    """``vel, omega (k,3)`` of the bodies ``idx (k,)`` in ``frame`` (``impact_frame``; None: as they are)."""
    if frame is None:
        return vel, omega
    v, w, x = frame
    return vel - (v + cross(w, world.s.pos[idx] - x)), omega - w


def kinetic_energy(world, idx, frame=None):
    """Kinetic energy (J, a float) of the bodies ``idx (k,)``, linear plus rotational, in ``frame``
    (``impact_frame``; default the world's)."""
    s = world.s
    c = np.ascontiguousarray
    idx = c(idx, dtype=np.int64)
    vel, omega = s.vel, s.omega
    if frame is not None:
        vel, omega = vel.copy(), omega.copy()
        vel[idx], omega[idx] = _in_frame(world, idx, frame, s.vel[idx], s.omega[idx])
    return float(kinetic(idx, c(world.mass, dtype=float), c(world.particle), s.quat, c(world.inertia_body), vel,
                         omega))


def energetic_cap(world, idx, kinetic0, vel_c, omega_c, frame=None):
    """Scale the restitution stage's velocity change back so that the impact ends with no more
    kinetic energy than it started with (``kinetic0``, J, over the bodies ``idx (k,)``, in ``frame``:
    ``impact_frame``, default the world's); ``vel_c, omega_c (k,3)`` their velocities after
    compression; returns the factor applied (1 when nothing was needed). The kernel,
    ``restitution_cap``, is the one the compiled step calls."""
    s = world.s
    c = np.ascontiguousarray
    idx = c(idx, dtype=np.int64)
    if frame is None:
        return float(restitution_cap(idx, c(world.mass, dtype=float), c(world.particle), s.quat,
                                     c(world.inertia_body), float(kinetic0), c(vel_c, dtype=float),
                                     c(omega_c, dtype=float), s.vel, s.omega))
    vel, omega = s.vel.copy(), s.omega.copy()
    vel[idx], omega[idx] = _in_frame(world, idx, frame, s.vel[idx], s.omega[idx])
    vc, wc = _in_frame(world, idx, frame, vel_c, omega_c)
    f = float(restitution_cap(idx, c(world.mass, dtype=float), c(world.particle), s.quat, c(world.inertia_body),
                              float(kinetic0), c(vc, dtype=float), c(wc, dtype=float), vel, omega))
    if f < 1.0:   # back from the frame
        s.vel[idx] = vel_c + f * (s.vel[idx] - vel_c)
        s.omega[idx] = omega_c + f * (s.omega[idx] - omega_c)
    return f


@njit
def _spin_product(quat, inertia_body, i, ux, uy, uz, wx, wy, wz):
    """``uᵀ R I Rᵀ w`` for body ``i``: the body-frame vectors ``Rᵀu, Rᵀw`` (the conjugate turn)
    through its body-frame inertia, as ``free_motion.rotational_energies`` forms ``ωᵀIω``."""
    qx, qy, qz, qw = -quat[i, 0], -quat[i, 1], -quat[i, 2], quat[i, 3]
    u = _qrot(qx, qy, qz, qw, ux, uy, uz)
    w = _qrot(qx, qy, qz, qw, wx, wy, wz)
    e = 0.0
    for r in range(3):
        e += u[r] * (inertia_body[i, r, 0] * w[0] + inertia_body[i, r, 1] * w[1] + inertia_body[i, r, 2] * w[2])
    return e


@njit
def kinetic(idx, mass, particle, quat, inertia_body, vel, omega):
    """Kinetic energy (J) of the bodies ``idx (k,)``: ``½ Σ m|v|² + ½ Σ ωᵀI_wω`` (no rotation for
    particles); ``quat (N,4)``, ``inertia_body (N,3,3)``, ``vel, omega (N,3)``. A loop, not numpy's
    pairwise sums, so that the compiled step and the Python stages add in one order."""
    lin = 0.0
    rot = 0.0
    for i in idx:
        lin += mass[i] * (vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1] + vel[i, 2] * vel[i, 2])
        if not particle[i]:
            rot += _spin_product(quat, inertia_body, i, omega[i, 0], omega[i, 1], omega[i, 2], omega[i, 0],
                                 omega[i, 1], omega[i, 2])
    return 0.5 * lin + 0.5 * rot


@njit
def restitution_cap(idx, mass, particle, quat, inertia_body, kinetic0, vel_c, omega_c, vel, omega):
    """``energetic_cap``'s kernel: ``idx (k,)`` the bodies, ``vel_c, omega_c (k,3)`` their velocities
    after compression, ``vel, omega (N,3)`` after restitution (rescaled in place). Returns the factor.

    Newton's rule, one target ``−e·v_n0`` per contact, is exact for one contact and for contacts
    that close at one speed; contacts closing at different speeds (a tumbling box meeting a wall
    corner first, the others within the speculative margin) can be given more rebound than the
    approach had: energy from nothing. Stronge's energetic view bounds the rebound by the energy the
    compression stored; the velocities after restitution are ``v_c + s·Δv`` and the kinetic energy is
    quadratic in ``s``, so the largest ``s ≤ 1`` that keeps it at ``kinetic0`` is a root."""
    if idx.shape[0] == 0:
        return 1.0
    if kinetic(idx, mass, particle, quat, inertia_body, vel, omega) <= kinetic0:
        return 1.0
    # K(s) = K_c + b s + a s², K_c the energy after compression
    a, b, kc = 0.0, 0.0, 0.0
    for j in range(idx.shape[0]):
        i = idx[j]
        dv = vel[i] - vel_c[j]
        dw = omega[i] - omega_c[j]
        m = mass[i]
        a += m * (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2])
        b += m * (vel_c[j, 0] * dv[0] + vel_c[j, 1] * dv[1] + vel_c[j, 2] * dv[2])
        kc += m * (vel_c[j, 0] * vel_c[j, 0] + vel_c[j, 1] * vel_c[j, 1] + vel_c[j, 2] * vel_c[j, 2])
        if not particle[i]:
            wc = omega_c[j]
            a += _spin_product(quat, inertia_body, i, dw[0], dw[1], dw[2], dw[0], dw[1], dw[2])
            b += _spin_product(quat, inertia_body, i, wc[0], wc[1], wc[2], dw[0], dw[1], dw[2])
            kc += _spin_product(quat, inertia_body, i, wc[0], wc[1], wc[2], wc[0], wc[1], wc[2])
    a *= 0.5
    kc *= 0.5
    room = max(kinetic0 - kc, 0.0)
    if a <= 0.0:
        return 1.0
    f = min(max((-b + math.sqrt(max(b * b + 4.0 * a * room, 0.0))) / (2.0 * a), 0.0), 1.0)
    for j in range(idx.shape[0]):
        i = idx[j]
        for x in range(3):
            vel[i, x] = vel_c[j, x] + f * (vel[i, x] - vel_c[j, x])
            omega[i, x] = omega_c[j, x] + f * (omega[i, x] - omega_c[j, x])
    return f


def kinematic_push(world, a, b, point):
    """What a solve over the contacts ``a, b (K,)`` at ``point (K,3)`` may give where kinematic bodies
    push: ``(dynamic bodies (k,), speed u of the fastest kinematic contact point)``, or ``None``
    when no contact has a kinematic body (between dynamic and static bodies the compression and
    the resting force only take energy away)."""
    bm = world.body_masks()
    if not bm.any_kinematic:
        return None
    ka, kb = bm.kinematic[a], bm.kinematic[b]
    if not (ka.any() or kb.any()):
        return None
    s = world.s
    k = np.where(ka, a, b)[ka | kb]
    p = point[ka | kb]
    u = float(np.sqrt(np.max(np.sum((s.vel[k] + cross(s.omega[k], p - s.pos[k])) ** 2, axis=1))))
    bodies = np.unique(np.concatenate([a, b]))
    return bodies[(world.kind == DYNAMIC)[bodies]], u


def push_cap(world, bodies, u, vel0, omega0, vel, omega, ref=None):
    """Scale a solve's velocity change back so that no body of ``bodies (k,)`` ends with more
    kinetic energy than a body pushed inelastically by a kinematic one whose contact point moves
    at ``u`` can have: ``½m(|v₀| + 2u)²`` of translation and ``½m(2u)²`` more rotation than it had.
    ``vel0, omega0 (k,3)`` the bodies' velocities before the solve; ``vel, omega (N,3)`` after it,
    set to ``vel0 + f·(vel[bodies] − vel0)`` (angular alike) with the largest ``f ≤ 1`` that
    keeps every body within that; returns ``f`` (scale the solve's impulses by it). ``ref``
    ``(vel (k,3), omega (k,3))``: the velocities the budget is measured from, when the solve is one
    of several in a stage (default ``vel0, omega0``): each of an impact's rounds measured from its
    own start let a body gain up to ``2u`` a round, and 128 rounds threw a body squeezed between a
    paddle at 0.5 m/s and a wall out at 12 m/s in one step.

    A body squeezed between a kinematic paddle and a wall (or a chain of bodies ending at one) has
    no impulse that holds every contact: Gauss–Seidel's impulses then grow with every sweep, and a
    40-body pile swept by a paddle at 0.5 m/s threw bodies out at 40–500 m/s. Capped, such a body
    moves on at about the paddle's speed and the position correction resolves the overlap."""
    if len(bodies) == 0:
        return 1.0
    m = world.mass[bodies]
    iw = dynamics.rotate_inertia(quat.to_matrix(world.s.quat[bodies]), world.inertia_body[bodies])
    iw[world.particle[bodies]] = 0.0
    dv, dw = vel[bodies] - vel0, omega[bodies] - omega0
    vr, wr = (vel0, omega0) if ref is None else ref
    speed_r = np.sqrt(np.einsum("ij,ij->i", vr, vr))
    budget = 0.5 * m * (speed_r + 2.0 * u) ** 2 + 0.5 * m * (2.0 * u) ** 2 \
        + 0.5 * np.einsum("ni,nij,nj->n", wr, iw, wr)
    # K_i(f) = K0_i + b_i f + a_i f²
    k0 = 0.5 * (m * np.einsum("ij,ij->i", vel0, vel0) + np.einsum("ni,nij,nj->n", omega0, iw, omega0))
    qa = 0.5 * (m * np.einsum("ij,ij->i", dv, dv) + np.einsum("ni,nij,nj->n", dw, iw, dw))
    qb = m * np.einsum("ij,ij->i", vel0, dv) + np.einsum("ni,nij,nj->n", omega0, iw, dw)
    over = (k0 + qb + qa > budget) & (qa > 0.0)
    if not over.any():
        return 1.0
    qa, qb, room = qa[over], qb[over], np.maximum(budget[over] - k0[over], 0.0)
    roots = (-qb + np.sqrt(np.maximum(qb * qb + 4.0 * qa * room, 0.0))) / (2.0 * qa)
    f = float(np.clip(roots.min(), 0.0, 1.0))
    if f < 1.0:
        vel[bodies] = vel0 + f * dv
        omega[bodies] = omega0 + f * dw
    return f
