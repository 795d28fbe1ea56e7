"""Energy bookkeeping of a step: what position correction, kinematic bodies and the resting model
may add to the total energy (reported in ``StepStats``), and the restitution stage's energetic cap."""
import numpy as np

from .. import dynamics, free_motion, quat
from ..kinds import DYNAMIC, KINEMATIC
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
    if len(c) == 0 or not world.body_masks().any_kinematic:
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


def kinetic_energy(world, idx):
    """Kinetic energy (J, a float) of the bodies ``idx (k,)``, linear plus rotational."""
    s = world.s
    rigid = idx[~world.particle[idx]]
    return float(0.5 * np.sum(world.mass[idx] * np.einsum("ij,ij->i", s.vel[idx], s.vel[idx]))
                 + rotational_energy(world, rigid).sum())


def energetic_cap(world, idx, kinetic0, vel_c, omega_c):
    """Scale the restitution stage's velocity change back so that the impact ends with no more
    kinetic energy than it started with (``kinetic0``, J, over the bodies ``idx``); returns the
    factor applied (1 when nothing was needed).

    Newton's rule, one target ``−e·v_n0`` per contact, is exact for one contact and for contacts
    that close at one speed; contacts closing at different speeds (a tumbling box meeting a wall
    corner first, the others within the speculative margin) can be given more rebound than the
    approach had: energy from nothing. Stronge's energetic view bounds the rebound by the energy the
    compression stored; the velocities after restitution are ``v_c + s·Δv`` and the kinetic energy is
    quadratic in ``s``, so the largest ``s ≤ 1`` that keeps it at ``kinetic0`` is a root."""
    s = world.s
    if idx.size == 0:
        return 1.0
    kinetic1 = kinetic_energy(world, idx)
    if kinetic1 <= kinetic0:
        return 1.0
    dv, dw = s.vel[idx] - vel_c, s.omega[idx] - omega_c
    rigid = ~world.particle[idx]
    iw = dynamics.rotate_inertia(quat.to_matrix(s.quat[idx]), world.inertia_body[idx])
    iw[~rigid] = 0.0
    m = world.mass[idx]
    # K(s) = K_c + b s + a s², K_c the energy after compression
    a = 0.5 * (np.sum(m * np.einsum("ij,ij->i", dv, dv)) + np.einsum("ni,nij,nj->", dw, iw, dw))
    b = np.sum(m * np.einsum("ij,ij->i", vel_c, dv)) + np.einsum("ni,nij,nj->", omega_c, iw, dw)
    kc = 0.5 * (np.sum(m * np.einsum("ij,ij->i", vel_c, vel_c)) + np.einsum("ni,nij,nj->", omega_c, iw, omega_c))
    room = max(kinetic0 - kc, 0.0)
    if a <= 0.0:
        return 1.0
    f = float(np.clip((-b + np.sqrt(max(b * b + 4.0 * a * room, 0.0))) / (2.0 * a), 0.0, 1.0))
    s.vel[idx] = vel_c + f * dv
    s.omega[idx] = omega_c + f * dw
    return f


def rotational_energy(world, idx):
    """Rotational kinetic energy ``(k,)`` (J) of the bodies ``idx``."""
    s = world.s
    out = np.empty(len(idx))
    free_motion.rotational_energies(s.quat, world.inertia_body, s.omega, np.asarray(idx, dtype=np.int64), out)
    return out


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


def push_cap(world, bodies, u, vel0, omega0, vel, omega):
    """Scale a solve's velocity change back so that no body of ``bodies (k,)`` ends with more
    kinetic energy than a body pushed inelastically by a kinematic one whose contact point moves
    at ``u`` can have: ``½m(|v₀| + 2u)²`` of translation and ``½m(2u)²`` more rotation than it had.
    ``vel0, omega0 (k,3)`` the bodies' velocities before the solve; ``vel, omega (N,3)`` after it,
    set to ``vel0 + f·(vel[bodies] − vel0)`` (angular alike) with the largest ``f ≤ 1`` that
    keeps every body within that; returns ``f`` (scale the solve's impulses by it).

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
    speed0 = np.sqrt(np.einsum("ij,ij->i", vel0, vel0))
    rot0 = 0.5 * np.einsum("ni,nij,nj->n", omega0, iw, omega0)
    budget = 0.5 * m * (speed0 + 2.0 * u) ** 2 + 0.5 * m * (2.0 * u) ** 2 + rot0
    # K_i(f) = K0_i + b_i f + a_i f²
    k0 = 0.5 * m * speed0 ** 2 + rot0
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
