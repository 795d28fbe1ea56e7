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
    if len(c) == 0 or not (world.kind == KINEMATIC).any():
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
