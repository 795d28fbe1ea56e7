"""Compiled torque-free rotation: ``dynamics.rotate_free``'s splitting as one loop over bodies.

The method (``dynamics`` module docstring): the torque-free Hamiltonian splits into an exact turn
about the world angular momentum ``L`` (which commutes with the rest) and turns about principal
axes 1 and 3 (Strang: ½ axis 1, axis 3, ½ axis 1 per sub-step). Sub-steps only where the two axis
flows both act and the body tumbles (``dynamics.tumbling_cone``); a spin about a principal axis,
or an axisymmetric body (a rod end over end), takes one exact sub-step.

Written per body in scalars (quaternions x, y, z, w), so a step of one body costs a few hundred
nanoseconds instead of ~25 numpy calls: a rod now costs what a cube does.

Also here, for kinematic bodies: ``pose_drive``, the velocities that carry them to their recorded
poses (``World.drive_poses``), in the same scalar quaternion arithmetic as their free motion.
"""
import math

import numpy as np

from .jit import njit


@njit
def _qmul(ax, ay, az, aw, bx, by, bz, bw):
    """Hamilton product a ⊗ b (apply b first)."""
    return (aw * bx + bw * ax + ay * bz - az * by,
            aw * by + bw * ay + az * bx - ax * bz,
            aw * bz + bw * az + ax * by - ay * bx,
            aw * bw - (ax * bx + ay * by + az * bz))


@njit
def _qrot(qx, qy, qz, qw, vx, vy, vz):
    """Rotate v by the unit quaternion q: v + w t + u × t with t = 2 u × v."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (vx + qw * tx + (qy * tz - qz * ty),
            vy + qw * ty + (qz * tx - qx * tz),
            vz + qw * tz + (qx * ty - qy * tx))


@njit
def _rotvec_quat(rx, ry, rz):
    """Quaternion of a rotation vector (series of sin(θ/2)/θ near zero: tiny turns keep precision)."""
    theta = math.sqrt(rx * rx + ry * ry + rz * rz)
    if theta < 1e-4:
        th2 = theta * theta
        s = 0.5 - th2 / 48.0 + th2 * th2 / 3840.0
    else:
        s = math.sin(0.5 * theta) / theta
    return rx * s, ry * s, rz * s, math.cos(0.5 * theta)


@njit
def _cone(p0, p1, p2, m0, m1, m2):
    """Sine of the half-angle of the tumbling cone (``dynamics.tumbling_cone`` for one body): the
    polhode's end points (where one ``Πᵢ² = 0``) give the least ``Π₁²`` and ``Π₃²`` on it."""
    l2 = p0 + p1 + p2
    e2 = p0 / m0 + p1 / m1 + p2 / m2
    low1 = p0
    low3 = p2
    for z in range(3):
        # the other two axes, a < b
        a = 1 if z == 0 else 0
        b = 1 if z == 2 else 2
        ma = m0 if a == 0 else m1
        mb = m2 if b == 2 else m1
        det = 1.0 / mb - 1.0 / ma
        if not abs(det) > 1e-12 / ma:
            continue
        pb = (e2 - l2 / ma) / det
        pa = l2 - pb
        if pa >= -1e-12 * l2 and pb >= -1e-12 * l2:
            low1 = min(low1, 0.0 if z == 0 else max(pa, 0.0))   # a = 0 unless z = 0
            low3 = min(low3, 0.0 if z == 2 else max(pb, 0.0))   # b = 2 unless z = 2
    l2s = max(l2, 1e-300)
    off = min(l2s - low1, l2s - low3)
    return math.sqrt(min(max(off / l2s, 0.0), 1.0))


@njit
def _rotate_body(q, omega, principal_q, moments, i, dt, max_split_angle, max_substeps):
    """Torque-free rotation of body ``i`` over ``dt`` (``rotate_free``'s loop body): ``(qx, qy, qz,
    qw, wx, wy, wz, drift)``."""
    # principal frame orientation qp = q ⊗ principal_q
    px, py, pz, pw = _qmul(q[i, 0], q[i, 1], q[i, 2], q[i, 3],
                           principal_q[i, 0], principal_q[i, 1], principal_q[i, 2], principal_q[i, 3])
    m0, m1, m2 = moments[i, 0], moments[i, 1], moments[i, 2]
    i0, i1, i2 = 1.0 / m0, 1.0 / m1, 1.0 / m2
    bx, by, bz = _qrot(-px, -py, -pz, pw, omega[i, 0], omega[i, 1], omega[i, 2])
    pi0, pi1, pi2 = m0 * bx, m1 * by, m2 * bz
    lx, ly, lz = _qrot(px, py, pz, pw, pi0, pi1, pi2)       # world L, fixed in free flight
    r0, r2 = i0 - i1, i2 - i1
    s0, s1, s2 = pi0 * pi0, pi1 * pi1, pi2 * pi2
    theta1 = math.sqrt(s0 + s1) * abs(r0) * dt
    theta3 = math.sqrt(s1 + s2) * abs(r2) * dt
    big_theta = max(theta1, theta3)
    if big_theta > 0.0:
        alone = min(theta1, theta3) <= 1e-12 * big_theta
        if alone:
            n_sub = 1
        else:
            norm_l = math.sqrt(lx * lx + ly * ly + lz * lz)
            big = norm_l * max(abs(r0), 0.0, abs(r2)) * dt
            cone = _cone(s0, s1, s2, m0, m1, m2)
            need = big / max_split_angle * min(1.0, cone / max_split_angle)
            n_sub = int(min(max(math.ceil(need), 1.0), max_substeps))
        h = dt / n_sub
        for _ in range(n_sub):
            for axis, frac in ((0, 0.5), (2, 1.0), (0, 0.5)):
                bl = _qrot(-px, -py, -pz, pw, lx, ly, lz)
                if axis == 0:
                    angle = bl[0] * r0 * frac * h
                    sx, sw = math.sin(0.5 * angle), math.cos(0.5 * angle)
                    px, py, pz, pw = _qmul(px, py, pz, pw, sx, 0.0, 0.0, sw)
                else:
                    angle = bl[2] * r2 * frac * h
                    sz, sw = math.sin(0.5 * angle), math.cos(0.5 * angle)
                    px, py, pz, pw = _qmul(px, py, pz, pw, 0.0, 0.0, sz, sw)
    # the |L| turn commutes: one exact turn for the whole step
    tx, ty, tz, tw = _rotvec_quat(lx * (i1 * dt), ly * (i1 * dt), lz * (i1 * dt))
    px, py, pz, pw = _qmul(tx, ty, tz, tw, px, py, pz, pw)
    n = math.sqrt(px * px + py * py + pz * pz + pw * pw)   # round-off only: every factor is unit
    px, py, pz, pw = px / n, py / n, pz / n, pw / n
    bl = _qrot(-px, -py, -pz, pw, lx, ly, lz)
    wx, wy, wz = _qrot(px, py, pz, pw, bl[0] * i0, bl[1] * i1, bl[2] * i2)
    drift = 0.5 * (lx * (wx - omega[i, 0]) + ly * (wy - omega[i, 1]) + lz * (wz - omega[i, 2]))
    qx, qy, qz, qw = _qmul(px, py, pz, pw, -principal_q[i, 0], -principal_q[i, 1], -principal_q[i, 2],
                           principal_q[i, 3])
    return qx, qy, qz, qw, wx, wy, wz, drift


@njit(_nrt=False)
def rotate_free(q, omega, principal_q, moments, dt, max_split_angle, max_substeps, q_out, omega_out):
    """Torque-free rotation over ``dt`` of ``N`` bodies, written to ``q_out (N,4)`` and
    ``omega_out (N,3)``. ``q (N,4)`` orientations (x, y, z, w), ``omega (N,3)`` world angular
    velocities, ``principal_q (N,4)`` principal-to-body rotations, ``moments (N,3)`` principal
    moments ascending. Same method and sub-step rule as ``dynamics.rotate_free``. Returns the
    change (J) of rotational kinetic energy the splitting made, ``½ L·Δω`` summed (a bounded
    oscillation; 0 where the step is exact)."""
    drift = 0.0
    for i in range(q.shape[0]):
        qx, qy, qz, qw, wx, wy, wz, d = _rotate_body(q, omega, principal_q, moments, i, dt, max_split_angle,
                                                     max_substeps)
        drift += d
        omega_out[i, 0], omega_out[i, 1], omega_out[i, 2] = wx, wy, wz
        q_out[i, 0], q_out[i, 1], q_out[i, 2], q_out[i, 3] = qx, qy, qz, qw
    return drift


@njit
def _turned(qx, qy, qz, qw, rx, ry, rz):
    """``normalize(exp(r) ⊗ q)``: the orientation ``q`` turned by the rotation vector ``r`` (rad)."""
    tx, ty, tz, tw = _rotvec_quat(rx, ry, rz)
    x, y, z, w = _qmul(tx, ty, tz, tw, qx, qy, qz, qw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


@njit
def turn_vector(x1, y1, z1, w1, qx, qy, qz, qw):
    """The rotation vector (rad, the shorter way round) that turns the unit quaternion ``q`` into
    ``(x1, y1, z1, w1)``: ``log(q₁ ⊗ q⁻¹)``."""
    x0, y0, z0, w0 = -qx, -qy, -qz, qw
    rw = w1 * w0 - x1 * x0 - y1 * y0 - z1 * z0
    rx = w1 * x0 + w0 * x1 + y1 * z0 - z1 * y0
    ry = w1 * y0 + w0 * y1 + z1 * x0 - x1 * z0
    rz = w1 * z0 + w0 * z1 + x1 * y0 - y1 * x0
    if rw < 0.0:
        rw, rx, ry, rz = -rw, -rx, -ry, -rz
    sv = math.sqrt(rx * rx + ry * ry + rz * rz)
    f = 2.0 * math.atan2(sv, rw) / sv if sv > 1e-300 else 2.0
    return f * rx, f * ry, f * rz


@njit
def _turn(quat, omega, i, dt):
    """``quat[i] ← normalize(exp(ω dt) ⊗ quat[i])``: the exact turn of a body whose ω is constant
    (equal principal moments, or a kinematic body)."""
    quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3] = _turned(quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3],
                                                             omega[i, 0] * dt, omega[i, 1] * dt, omega[i, 2] * dt)


@njit
def free_turn(quat, omega, principal_q, moments, i, dt, iso_tolerance, max_split_angle, max_substeps):
    """Body ``i``'s torque-free turn over ``dt`` (s), in place in ``quat[i]``, ``omega[i]``: the
    exact turn where its principal moments are equal within ``iso_tolerance`` (no split term, L ∥ ω:
    the exact turn is the whole motion), ``_rotate_body``'s splitting otherwise. Returns the
    splitting's rotational energy change (J; 0 for the exact turn)."""
    if moments[i, 0] >= (1.0 - iso_tolerance) * moments[i, 2]:
        _turn(quat, omega, i, dt)
        return 0.0
    qx, qy, qz, qw, wx, wy, wz, d = _rotate_body(quat, omega, principal_q, moments, i, dt, max_split_angle,
                                                 max_substeps)
    quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3] = qx, qy, qz, qw
    omega[i, 0], omega[i, 1], omega[i, 2] = wx, wy, wz
    return d


@njit
def _rot_energy(quat, inertia_body, omega, i):
    bx, by, bz = _qrot(-quat[i, 0], -quat[i, 1], -quat[i, 2], quat[i, 3], omega[i, 0], omega[i, 1], omega[i, 2])
    e = 0.0
    for r in range(3):
        wr = bx if r == 0 else (by if r == 1 else bz)
        e += wr * (inertia_body[i, r, 0] * bx + inertia_body[i, r, 1] * by + inertia_body[i, r, 2] * bz)
    return 0.5 * e


@njit(_nrt=False)
def advance(pos, vel, quat, omega, principal_q, moments, inertia_body, gravity, dynamic, rotating, kinematic,
            half_dv, half_dw, kick, dt, iso_tolerance, max_split_angle, max_substeps):
    """Every body's motion over ``dt`` without contacts, in place: dynamic bodies ballistically
    (``x += v dt + g dt²/2``, exact) with torque-free rotation (an exact turn for equal principal
    moments, ``_rotate_body``'s splitting otherwise), kinematic bodies at constant velocity and
    spin. With ``kick`` the drift sits between two half-kicks ``half_dv, half_dw (N,3)`` of a
    constant contact force (kick, drift, kick).

    ``pos, vel, omega (N,3)``, ``quat (N,4)``, ``principal_q (N,4)``, ``moments (N,3)``,
    ``inertia_body (N,3,3)``, ``gravity (3,)``, ``dynamic, rotating, kinematic (N,) bool``.
    Returns ``(drift, kick_error)`` (J): the splitting's rotational energy change, and the half-kicks'
    first-order error bound ``Σ |ΔE_rot|·|ω|·dt`` over the bodies the torque kicked."""
    drift = 0.0
    kick_error = 0.0
    for i in range(pos.shape[0]):
        kicked = False
        ke0 = 0.0
        if kick:
            for x in range(3):
                vel[i, x] += half_dv[i, x]
            kicked = half_dw[i, 0] != 0.0 or half_dw[i, 1] != 0.0 or half_dw[i, 2] != 0.0
            if kicked:
                ke0 = _rot_energy(quat, inertia_body, omega, i)
            for x in range(3):
                omega[i, x] += half_dw[i, x]
        for x in range(3):
            g = gravity[x] if dynamic[i] else 0.0
            pos[i, x] += vel[i, x] * dt + 0.5 * g * dt * dt
            vel[i, x] += g * dt
        spins = omega[i, 0] != 0.0 or omega[i, 1] != 0.0 or omega[i, 2] != 0.0
        if spins and rotating[i]:
            drift += free_turn(quat, omega, principal_q, moments, i, dt, iso_tolerance, max_split_angle, max_substeps)
        elif spins and kinematic[i]:
            _turn(quat, omega, i, dt)
        if kick:
            for x in range(3):
                vel[i, x] += half_dv[i, x]
                omega[i, x] += half_dw[i, x]
            if kicked:
                # the torque's two half-kicks around a turning drift are exact to first order in the
                # angle turned: what they move of the rotational energy is right to within |ω|·dt of it
                moved = abs(_rot_energy(quat, inertia_body, omega, i) - ke0)
                turned = math.sqrt(omega[i, 0] ** 2 + omega[i, 1] ** 2 + omega[i, 2] ** 2) * dt
                kick_error += moved * turned
    return drift, kick_error


def rotate(q, omega, principal_q, moments, dt, max_split_angle, max_substeps):
    """Array front of the kernel: ``(q (N,4), omega (N,3), drift J)`` after ``dt``."""
    c = np.ascontiguousarray
    q_out = np.empty((len(q), 4))
    w_out = np.empty((len(q), 3))
    drift = rotate_free(c(q, dtype=float), c(omega, dtype=float), c(principal_q, dtype=float),
                        c(moments, dtype=float), float(dt), float(max_split_angle), int(max_substeps), q_out, w_out)
    return q_out, w_out, float(drift)


@njit
def rotational_energies(q, inertia_body, omega, idx, out):
    """``out[k] = ½ ωᵀ R I Rᵀ ω`` (J) for the bodies ``idx (k,)``: ``q (N,4)`` orientations,
    ``inertia_body (N,3,3)``, ``omega (N,3)`` world angular velocities. The body-frame ``ω`` is
    ``Rᵀ ω`` (the conjugate turn), so no matrix is formed."""
    for k in range(idx.shape[0]):
        out[k] = _rot_energy(q, inertia_body, omega, idx[k])


@njit(_nrt=False)
def all_finite(pos, vel, quat, omega):
    """Every entry of the state arrays ``pos, vel, omega (N,3)``, ``quat (N,4)`` finite."""
    for i in range(pos.shape[0]):
        for k in range(3):
            if not (math.isfinite(pos[i, k]) and math.isfinite(vel[i, k]) and math.isfinite(omega[i, k])):
                return False
        for k in range(4):
            if not math.isfinite(quat[i, k]):
                return False
    return True


#: ``pose_drive``'s answers: every body within the bounds, or the bound the first refused body breaks
DRIVE_OK, DRIVE_POSITION, DRIVE_SPEED, DRIVE_ANGULAR_SPEED = range(4)


@njit(_nrt=False)
def pose_drive(idx, until, period, at_rest, pose_pos, pose_quat, pose_vel, pose_omega, stamp, gap, pos, quat,
               max_position, max_speed, max_angular_speed, out):
    """``World.drive_poses``' arithmetic for the kinematic bodies ``idx (M,)`` (a kinematic body's
    origin is its centre of mass): each one's recorded pose ``pose_pos (N,3)``, ``pose_quat
    (N,4)`` carried on at ``pose_vel, pose_omega (N,3)`` to ``until`` (s), never back and at most
    ``gap (N,)`` + ``period`` past its ``stamp (N,)``; then the velocity and angular velocity that
    take the body from ``pos, quat`` there in ``period`` (s), the shorter way round (zero
    ``at_rest``). Writes ``out (M,13)``: goal centre, goal orientation, velocity, angular velocity.
    Returns ``(code, row)``: ``DRIVE_OK``, or the bound the body ``idx[row]`` breaks first
    (``DRIVE_POSITION``: its goal beyond ``max_position`` in a coordinate; ``DRIVE_SPEED``,
    ``DRIVE_ANGULAR_SPEED``: its drive beyond ``max_speed`` / ``max_angular_speed``), its row of
    ``out`` written."""
    for r in range(idx.shape[0]):
        i = idx[r]
        ahead = min(max(until - stamp[i], 0.0), gap[i] + period)
        cx = pose_pos[i, 0] + pose_vel[i, 0] * ahead
        cy = pose_pos[i, 1] + pose_vel[i, 1] * ahead
        cz = pose_pos[i, 2] + pose_vel[i, 2] * ahead
        gx, gy, gz, gw = _turned(pose_quat[i, 0], pose_quat[i, 1], pose_quat[i, 2], pose_quat[i, 3],
                                 pose_omega[i, 0] * ahead, pose_omega[i, 1] * ahead, pose_omega[i, 2] * ahead)
        vx = vy = vz = wx = wy = wz = 0.0
        if not at_rest:
            vx, vy, vz = (cx - pos[i, 0]) / period, (cy - pos[i, 1]) / period, (cz - pos[i, 2]) / period
            tx, ty, tz = turn_vector(gx, gy, gz, gw, quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3])
            wx, wy, wz = tx / period, ty / period, tz / period
        out[r, 0], out[r, 1], out[r, 2] = cx, cy, cz
        out[r, 3], out[r, 4], out[r, 5], out[r, 6] = gx, gy, gz, gw
        out[r, 7], out[r, 8], out[r, 9] = vx, vy, vz
        out[r, 10], out[r, 11], out[r, 12] = wx, wy, wz
        if max(abs(cx), abs(cy), abs(cz)) > max_position:
            return DRIVE_POSITION, r
        if math.sqrt(vx * vx + vy * vy + vz * vz) > max_speed:
            return DRIVE_SPEED, r
        if math.sqrt(wx * wx + wy * wy + wz * wz) > max_angular_speed:
            return DRIVE_ANGULAR_SPEED, r
    return DRIVE_OK, 0
