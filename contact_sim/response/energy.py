"""Energy bookkeeping of a step: what position correction, kinematic bodies and the resting model
may add to the total energy (reported in ``StepStats``), and the restitution stage's energetic cap."""
import math

import numpy as np

from ..free_motion import _qrot, turn_vector
from ..jit import njit
from ..kinds import DYNAMIC, KINEMATIC, STATIC
from ..vec import cross
from . import compliance, prepare


def potential_change(world, dx):
    """Gravitational potential energy (J) gained by moving the dynamic bodies' centres by
    ``dx (N,3)``: what position correction may add to the total energy (it raises bodies out of
    penetration; it never adds kinetic energy)."""
    dyn = world.kind == DYNAMIC
    return float(-np.sum(world.mass[dyn] * (dx[dyn] @ world.gravity)))


def kinematic_work(world, c, pos=None):
    """Work (J) done on the dynamic bodies by kinematic ones through the contacts ``c`` of a
    step: impulse on the dynamic side · velocity of the kinematic body's material point (its
    centre at ``pos (N,3)``, default where the bodies are now). A kinematic body is driven from
    outside, so this is energy the world may gain."""
    if len(c) == 0 or not world.body_masks().any_kinematic or not _touches(world.kind, c.body_a, c.body_b, KINEMATIC):
        return 0.0
    s = world.s
    pos = s.pos if pos is None else pos
    total = 0.0
    for side, sign in ((c.body_a, -1.0), (c.body_b, 1.0)):   # A gets +impulse, B its negative
        k = world.kind[side] == KINEMATIC
        if k.any():
            i = side[k]
            u = s.vel[i] + cross(s.omega[i], c.point[k] - pos[i])
            total += float(np.sum(sign * c.impulse[k] * u))
    return total


def pose_work(world, c, m):
    """Work (J) the kinematic bodies did on the compliant contacts ``c`` (stiffness from
    ``prepare.stiffnesses`` under the models ``m``) when poses moved them at once since the last
    step left them (``s.stepped``). A contact ``d`` deep now was ``d + Δs`` deep before, ``Δs`` the
    separation the move made at its point (the relative velocity's formula with the moves for
    velocities: each body's centre move and the rotation vector of its turn), and its spring gained
    ``½ k (d⁺² − (d + Δs)⁺²)``. A pose, a robot's joint positions, puts a kinematic body where it
    is given; the springs it compresses on the way store what the body did as work
    (``StepStats.pose_work``; the work through the step's impulses is ``kinematic_work``). Only
    contacts with a dynamic body store anything."""
    if len(c) == 0 or not compliance.possible(world):
        return 0.0
    k, _ = prepare.stiffnesses(world, c, m)
    s = world.s
    cc = np.ascontiguousarray
    return _pose_work(cc(c.body_a, dtype=np.int64), cc(c.body_b, dtype=np.int64), cc(c.point, dtype=float),
                      cc(c.normal, dtype=float), cc(c.depth, dtype=float), k, world.kind, s.pos, s.quat, s.stepped)


def posed(world):
    """Whether a kinematic body is not where the last step left it (``s.stepped``): a pose given
    since. Where none is, ``pose_work`` is exactly 0 (no move, no separation made)."""
    s = world.s
    return _posed(world.kind, s.pos, s.quat, s.stepped)


@njit(_nrt=False)
def _posed(kind, pos, quat, stepped):
    """``posed``'s loop over the bodies ``kind (N,)``, ``pos (N,3)``, ``quat (N,4)``, ``stepped (N,7)``."""
    for i in range(kind.shape[0]):
        if kind[i] != KINEMATIC:
            continue
        for x in range(3):
            if pos[i, x] != stepped[i, x]:
                return True
        for x in range(4):
            if quat[i, x] != stepped[i, 3 + x]:
                return True
    return False


@njit(cache=True)
def _pose_work(a, b, point, normal, depth, stiffness, kind, pos, quat, stepped):
    """``pose_work``'s loop: contacts ``a, b (K,)``, ``point, normal (K,3)``, ``depth, stiffness
    (K,)``; bodies ``kind (N,)``, centres ``pos (N,3)``, orientations ``quat (N,4)`` x,y,z,w, and
    ``stepped (N,7)`` the centres and orientations the last step left."""
    total = 0.0
    for c in range(a.shape[0]):
        k = stiffness[c]
        if k <= 0.0 or (kind[a[c]] != DYNAMIC and kind[b[c]] != DYNAMIC):
            continue
        sep = 0.0   # n · (u_a − u_b): the separation the moves made at the point
        for side in range(2):
            i = a[c] if side == 0 else b[c]
            if kind[i] != KINEMATIC:
                continue
            # the turn since the step as a rotation vector (the shorter way round)
            tx, ty, tz = turn_vector(quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3], stepped[i, 3], stepped[i, 4],
                                     stepped[i, 5], stepped[i, 6])
            px, py, pz = point[c, 0] - pos[i, 0], point[c, 1] - pos[i, 1], point[c, 2] - pos[i, 2]
            ux = pos[i, 0] - stepped[i, 0] + ty * pz - tz * py
            uy = pos[i, 1] - stepped[i, 1] + tz * px - tx * pz
            uz = pos[i, 2] - stepped[i, 2] + tx * py - ty * px
            u = normal[c, 0] * ux + normal[c, 1] * uy + normal[c, 2] * uz
            sep += u if side == 0 else -u
        if sep == 0.0:
            continue
        now = max(depth[c], 0.0)
        before = max(depth[c] + sep, 0.0)
        total += 0.5 * k * (now * now - before * before)
    return total


@njit
def _touches(kind, a, b, which):
    """Whether a contact ``a, b (K,)`` has a body of kind ``which``."""
    for c in range(a.shape[0]):
        if kind[a[c]] == which or kind[b[c]] == which:
            return True
    return False


#: ``frame_of``'s answers: no kinematic body in the impact (the world's frame), one kinematic body's
#: frame, or no frame (a static body or a second kinematic one)
NO_KINEMATIC, FRAME, NO_FRAME = range(3)


@njit
def frame_of(kind, a, b, vel, omega, pos, out):
    """The frame an impact's kinetic energy is measured in, for the contacts ``a, b (K,)``:
    ``NO_KINEMATIC`` (the world's) when no kinematic body takes part; ``FRAME``, with ``out (3,3)``
    the rigid motion ``v, ω, x`` (rows) of the one kinematic body that does, with no static body in
    the impact; ``NO_FRAME`` otherwise.

    Against a moving kinematic body a rebound gains kinetic energy in the world frame (a paddle at
    v sends a resting ball off at 2v with e = 1): capped there, the rebound was lost. In the frame
    that moves with the body's rigid motion (each dynamic body's velocity less that field's at its
    centre, its spin less ω) every contact velocity is what it was, so the impulses are the same and
    Stronge's bound holds there; a static body or a second kinematic one moves differently, and no
    frame serves (the push cap, ``push_cap_kernel``, bounds the impact then)."""
    k = -1
    static = False
    for c in range(a.shape[0]):
        for i in (a[c], b[c]):
            if kind[i] == KINEMATIC:
                if k >= 0 and i != k:
                    return NO_FRAME
                k = i
            elif kind[i] == STATIC:
                static = True
    if k < 0:
        return NO_KINEMATIC
    if static:
        return NO_FRAME
    for x in range(3):
        out[0, x], out[1, x], out[2, x] = vel[k, x], omega[k, x], pos[k, x]
    return FRAME


@njit
def _frame_velocity(pos, frame, i, vx, vy, vz, wx, wy, wz, out):
    """``out[0:3]``, ``out[3:6]``: the velocity ``(vx, vy, vz)`` and spin ``(wx, wy, wz)`` of body ``i``
    (centre ``pos[i]``) in ``frame (3,3)`` (``v, ω, x``): less the frame's velocity field at the
    centre, ``v + ω × (pos − x)``, and less ``ω``."""
    rx, ry, rz = pos[i, 0] - frame[2, 0], pos[i, 1] - frame[2, 1], pos[i, 2] - frame[2, 2]
    fw0, fw1, fw2 = frame[1, 0], frame[1, 1], frame[1, 2]
    out[0] = vx - (frame[0, 0] + (fw1 * rz - fw2 * ry))
    out[1] = vy - (frame[0, 1] + (fw2 * rx - fw0 * rz))
    out[2] = vz - (frame[0, 2] + (fw0 * ry - fw1 * rx))
    out[3], out[4], out[5] = wx - fw0, wy - fw1, wz - fw2


@njit
def _in_frame(idx, pos, frame, vel_rows, omega_rows, vel, omega):
    """Rows ``j`` of ``vel_rows, omega_rows (k,3)`` (bodies ``idx (k,)``) in ``frame`` into
    ``vel[idx[j]], omega[idx[j]]`` (``(N,3)``)."""
    t = np.empty(6)
    for j in range(idx.shape[0]):
        i = idx[j]
        _frame_velocity(pos, frame, i, vel_rows[j, 0], vel_rows[j, 1], vel_rows[j, 2], omega_rows[j, 0],
                        omega_rows[j, 1], omega_rows[j, 2], t)
        for x in range(3):
            vel[i, x], omega[i, x] = t[x], t[3 + x]


@njit
def kinetic_in(idx, mass, particle, quat, inertia_body, vel, omega, pos, frame, has_frame):
    """``kinetic`` of the bodies ``idx (k,)``, in ``frame (3,3)`` (``frame_of``'s) when ``has_frame``."""
    if not has_frame:
        return kinetic(idx, mass, particle, quat, inertia_body, vel, omega)
    vf, wf = vel.copy(), omega.copy()
    _in_frame(idx, pos, frame, vel[idx], omega[idx], vf, wf)
    return kinetic(idx, mass, particle, quat, inertia_body, vf, wf)


@njit
def restitution_cap_in(idx, mass, particle, quat, inertia_body, kinetic0, vel_c, omega_c, vel, omega, pos, frame,
                       has_frame):
    """``restitution_cap``, in ``frame (3,3)`` when ``has_frame``: the factor is found there and the
    velocities ``vel, omega (N,3)`` rescaled about those after compression, ``vel_c, omega_c (k,3)``."""
    if not has_frame:
        return restitution_cap(idx, mass, particle, quat, inertia_body, kinetic0, vel_c, omega_c, vel, omega)
    k = idx.shape[0]
    vf, wf = vel.copy(), omega.copy()
    _in_frame(idx, pos, frame, vel[idx], omega[idx], vf, wf)
    vcf, wcf = np.empty((vel.shape[0], 3)), np.empty((vel.shape[0], 3))
    _in_frame(idx, pos, frame, vel_c, omega_c, vcf, wcf)
    vc, wc = vcf[idx], wcf[idx]
    f = restitution_cap(idx, mass, particle, quat, inertia_body, kinetic0, vc, wc, vf, wf)
    if f < 1.0:   # back from the frame
        for j in range(k):
            i = idx[j]
            for x in range(3):
                vel[i, x] = vel_c[j, x] + f * (vel[i, x] - vel_c[j, x])
                omega[i, x] = omega_c[j, x] + f * (omega[i, x] - omega_c[j, x])
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


@njit(_nrt=False)
def kinetic(idx, mass, particle, quat, inertia_body, vel, omega):
    """Kinetic energy (J) of the bodies ``idx (k,)``: ``½ Σ m|v|² + ½ Σ ωᵀI_wω`` (no rotation for
    particles); ``quat (N,4)``, ``inertia_body (N,3,3)``, ``vel, omega (N,3)``. A loop, not numpy's
    pairwise sums, so that every caller adds in one order."""
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


@njit(_nrt=False)
def push_speed(a, b, point, kinematic, dynamic, pos, vel, omega):
    """The speed (m/s) of the fastest kinematic contact point among the contacts ``a, b (K,)`` at
    ``point (K,3)`` where a kinematic body meets a ``dynamic`` one (the kinematic body's velocity
    field ``v + ω × (p − x)`` there), −1 when no contact is such a push. A kinematic body against
    a static or another kinematic one pushes nothing (no impulse acts there); counted as a push at
    rest (u = 0), it would hold every body of the solve to its start speed, the springs of
    compliant contacts releasing their energy included."""
    best = -1.0
    for c in range(a.shape[0]):
        if kinematic[a[c]] and dynamic[b[c]]:
            k = a[c]
        elif kinematic[b[c]] and dynamic[a[c]]:
            k = b[c]
        else:
            continue
        rx, ry, rz = point[c, 0] - pos[k, 0], point[c, 1] - pos[k, 1], point[c, 2] - pos[k, 2]
        ux = vel[k, 0] + (omega[k, 1] * rz - omega[k, 2] * ry)
        uy = vel[k, 1] + (omega[k, 2] * rx - omega[k, 0] * rz)
        uz = vel[k, 2] + (omega[k, 0] * ry - omega[k, 1] * rx)
        best = max(best, ux * ux + uy * uy + uz * uz)
    return math.sqrt(best) if best >= 0.0 else -1.0


@njit
def dynamic_bodies(a, b, dynamic):
    """The dynamic bodies of the contacts ``a, b (K,)``, ascending (``np.unique``'s order)."""
    mark = np.zeros(dynamic.shape[0], np.bool_)
    for c in range(a.shape[0]):
        mark[a[c]] = True
        mark[b[c]] = True
    return np.flatnonzero(mark & dynamic)


@njit(_nrt=False)
def push_cap_kernel(bodies, u, mass, particle, quat, inertia_body, vel0, omega0, vref, wref, vel, omega):
    """The push cap: scale a solve's velocity change back so that no body of ``bodies (k,)`` ends
    with more kinetic energy than a body pushed inelastically by a kinematic one whose contact
    point moves at ``u`` (``push_speed``) can have: ``½m(|v₀| + 2u)²`` of translation and ``½m(2u)²``
    more rotation than it had. ``vel0, omega0 (k,3)`` the bodies' velocities before the solve;
    ``vref, wref (k,3)`` those the budget is measured from (the sub-step's start: each of an
    impact's rounds measured from its own start let a body gain up to ``2u`` a round, and 128
    rounds threw a body squeezed between a paddle at 0.5 m/s and a wall out at 12 m/s in one step);
    ``vel, omega (N,3)`` after the solve, set to ``vel0 + f·(vel[bodies] − vel0)`` (angular alike)
    with the largest ``f ≤ 1`` that keeps every body within that. Returns ``f`` (scale the solve's
    impulses by it). The kinetic energy of body ``i`` along the scale ``f`` is ``K0 + b f + a f²``;
    the factor is the smallest root that meets a budget, within ``[0, 1]``.

    A body squeezed between a kinematic paddle and a wall (or a chain of bodies ending at one) has
    no impulse that holds every contact: Gauss–Seidel's impulses then grow with every sweep, and a
    40-body pile swept by a paddle at 0.5 m/s threw bodies out at 40–500 m/s. Capped, such a body
    moves on at about the paddle's speed and the position correction resolves the overlap."""
    f = 1.0
    for j in range(bodies.shape[0]):
        i = bodies[j]
        m = mass[i]
        dv0, dv1, dv2 = vel[i, 0] - vel0[j, 0], vel[i, 1] - vel0[j, 1], vel[i, 2] - vel0[j, 2]
        dw0, dw1, dw2 = omega[i, 0] - omega0[j, 0], omega[i, 1] - omega0[j, 1], omega[i, 2] - omega0[j, 2]
        speed_r = math.sqrt(vref[j, 0] * vref[j, 0] + vref[j, 1] * vref[j, 1] + vref[j, 2] * vref[j, 2])
        rot_r, rot0, rot_a, rot_b = 0.0, 0.0, 0.0, 0.0
        if not particle[i]:
            rot_r = _spin_product(quat, inertia_body, i, wref[j, 0], wref[j, 1], wref[j, 2], wref[j, 0], wref[j, 1],
                                  wref[j, 2])
            rot0 = _spin_product(quat, inertia_body, i, omega0[j, 0], omega0[j, 1], omega0[j, 2], omega0[j, 0],
                                 omega0[j, 1], omega0[j, 2])
            rot_a = _spin_product(quat, inertia_body, i, dw0, dw1, dw2, dw0, dw1, dw2)
            rot_b = _spin_product(quat, inertia_body, i, omega0[j, 0], omega0[j, 1], omega0[j, 2], dw0, dw1, dw2)
        budget = 0.5 * m * (speed_r + 2.0 * u) ** 2 + 0.5 * m * (2.0 * u) ** 2 + 0.5 * rot_r
        k0 = 0.5 * (m * (vel0[j, 0] * vel0[j, 0] + vel0[j, 1] * vel0[j, 1] + vel0[j, 2] * vel0[j, 2]) + rot0)
        qa = 0.5 * (m * (dv0 * dv0 + dv1 * dv1 + dv2 * dv2) + rot_a)
        qb = m * (vel0[j, 0] * dv0 + vel0[j, 1] * dv1 + vel0[j, 2] * dv2) + rot_b
        if k0 + qb + qa > budget and qa > 0.0:
            room = max(budget - k0, 0.0)
            f = min(f, (-qb + math.sqrt(max(qb * qb + 4.0 * qa * room, 0.0))) / (2.0 * qa))
    f = min(max(f, 0.0), 1.0)
    if f < 1.0:
        for j in range(bodies.shape[0]):
            i = bodies[j]
            for x in range(3):
                vel[i, x] = vel0[j, x] + f * (vel[i, x] - vel0[j, x])
                omega[i, x] = omega0[j, x] + f * (omega[i, x] - omega0[j, x])
    return f
