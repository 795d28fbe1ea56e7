"""Free-motion integration between contacts, vectorised over bodies.

Translation: ``x += v dt + g dt²/2``, ``v += g dt`` — exact for constant acceleration, so ballistic
flight carries no integration error at any step size.

Rotation: the torque-free rigid body's energy is split as
``H = |L|²/(2 I₂) + Σᵢ Πᵢ² (1/Iᵢ − 1/I₂)/2`` (``Π`` body angular momentum, ``I₂`` the middle
principal moment). The first term commutes with the rest (``|L|`` is a Casimir): its flow is an
exact rotation about the world ``L`` at rate ``|L|/I₂``. The other two terms are exact rotations
about body axes 1 and 3 and are composed by Strang splitting. Consequences: ``L`` is conserved to
round-off; quaternions stay unit (only unit rotations multiply them); the method is symplectic
and second order, so energy error stays bounded and fast spin cannot blow up; and for spheres,
cubes and any body with two equal moments one split term vanishes, so the rotation is exact.
"""
import numpy as np

from . import quat


def principal_frame(inertia):
    """Principal moments ``(N, 3)`` and the rotation ``(N, 4)`` from the principal to the body frame.

    ``inertia (N, 3, 3)`` symmetric; ``inertia = R diag(moments) Rᵀ`` with ``R = to_matrix(rotation)``.
    """
    moments, vecs = np.linalg.eigh(inertia)
    # proper rotation (det +1): flip the last axis where eigh returned a reflection
    flip = np.linalg.det(vecs) < 0
    vecs[flip, :, 2] *= -1.0
    return moments, quat.from_matrix(vecs)


def world_inverse_inertia(q, inv_inertia_body):
    """``R I⁻¹ Rᵀ``: world-frame inverse inertia ``(N, 3, 3)`` from orientations ``(N, 4)``."""
    return rotate_inertia(quat.to_matrix(q), inv_inertia_body)


def rotate_inertia(R, inertia_body):
    """``R I Rᵀ (N, 3, 3)``: body-frame (inverse) inertia tensors ``(N, 3, 3)`` in the world frame of
    rotation matrices ``R (N, 3, 3)``."""
    return R @ inertia_body @ np.swapaxes(R, -1, -2)


def integrate_free(state, dt, gravity, moving, rotating):
    """Advance ``state`` by ``dt`` without contacts, in place.

    ``moving (N,) bool`` selects dynamic bodies (gravity applies) — kinematic bodies translate at
    constant velocity; ``rotating (N,) bool`` selects bodies whose orientation changes.
    ``state`` has arrays ``pos vel quat omega (N, 3|4)`` and ``principal_q (N, 4)``,
    ``principal_moments (N, 3)``. Returns the change (J) of rotational kinetic energy the
    splitting made for tumbling bodies (a bounded oscillation; 0 for every other motion, which is
    exact).
    """
    accel = np.where(moving[:, None], gravity, 0.0)
    state.pos += state.vel * dt + 0.5 * accel * dt * dt
    state.vel += accel * dt
    # a body that does not spin keeps its orientation exactly (L = 0: every factor is the identity)
    spin = rotating & state.omega.any(axis=1)
    if not spin.any():
        return 0.0
    # equal principal moments (spheres, cubes; equal to 1e-12 relative, the round-off of a mesh's
    # inertia): no split term and L = I ω is parallel to ω, so the exact turn is the whole motion:
    # q ← exp(ω dt) ⊗ q with ω unchanged
    m = state.principal_moments
    iso = m[:, 0] >= (1.0 - ISOTROPIC_TOLERANCE) * m[:, 2]   # ascending moments: smallest vs largest
    idx = np.flatnonzero(spin & iso)
    if idx.size:
        state.quat[idx] = quat.normalize(quat.mul(quat.from_rotvec(state.omega[idx] * dt), state.quat[idx]))
    idx = np.flatnonzero(spin & ~iso)
    if idx.size:
        q, w = rotate_free(state.quat[idx], state.omega[idx], state.principal_q[idx],
                           state.principal_moments[idx], dt)
        # the splitting keeps L exactly and the energy up to a bounded oscillation; report it
        # (KE = ½ ω·L with L unchanged, so the change is ½ L·Δω)
        qp = quat.mul(state.quat[idx], state.principal_q[idx])
        L = quat.rotate(qp, state.principal_moments[idx] * quat.rotate(quat.conj(qp), state.omega[idx]))
        drift = 0.5 * float(np.sum(L * (w - state.omega[idx])))
        state.quat[idx] = q
        state.omega[idx] = w
        return drift
    return 0.0


ISOTROPIC_TOLERANCE = 1e-12  # relative spread of principal moments below which a body spins as a sphere
MAX_SPLIT_ANGLE = 0.25  # rad: largest non-commuting sub-rotation per sub-step (accuracy knob)
MAX_SUBSTEPS = 64  # beyond this, spin stays stable and L exact but accuracy degrades gracefully


def polhode_ends(p2, moments):
    """End points ``(N, 3, 3)`` (vertex ``z`` has ``pᵢ = 0`` for ``i = z``; NaN where it does not
    exist) of the segment ``{p ≥ 0: Σ pᵢ = |L|², Σ pᵢ/Iᵢ = 2E}`` on which ``pᵢ = Πᵢ²`` moves in
    torque-free motion (``p2 (N, 3)`` the current ``Πᵢ²`` in the principal frame, ``moments (N, 3)``).
    Anything linear in ``p`` (``|ω|² = Σ pᵢ/Iᵢ²``, the part of ``Π`` off an axis) is extreme there."""
    l2 = p2.sum(axis=1)
    e2 = (p2 / moments).sum(axis=1)
    out = np.full(p2.shape[:1] + (3, 3), np.nan)
    for z in range(3):
        a, b = [x for x in range(3) if x != z]
        det = 1.0 / moments[:, b] - 1.0 / moments[:, a]
        ok = np.abs(det) > 1e-12 / moments[:, a]
        pb = (e2 - l2 / moments[:, a]) / np.where(ok, det, 1.0)
        pa = l2 - pb
        ok &= (pa >= -1e-12 * l2) & (pb >= -1e-12 * l2)
        out[ok, z, a] = np.maximum(pa[ok], 0.0)
        out[ok, z, b] = np.maximum(pb[ok], 0.0)
        out[ok, z, z] = 0.0
    return out


def tumbling_cone(p2, moments):
    """``(N,)`` sine of the half-angle of the cone on which ``Π`` circles an end principal axis (1 or
    3) in torque-free motion: ``sqrt(max over the polhode of the off-axis part of |Π|²) / |L|``,
    for the axis it circles (the smaller of the two). 0 for a spin about a principal axis."""
    ends = polhode_ends(p2, moments)
    l2 = np.maximum(p2.sum(axis=1), 1e-300)
    with np.errstate(invalid="ignore"):
        low1 = np.fmin(np.nanmin(np.where(np.isnan(ends[:, :, 0]), np.inf, ends[:, :, 0]), axis=1), p2[:, 0])
        low3 = np.fmin(np.nanmin(np.where(np.isnan(ends[:, :, 2]), np.inf, ends[:, :, 2]), axis=1), p2[:, 2])
    off = np.minimum(l2 - low1, l2 - low3)
    return np.sqrt(np.clip(off / l2, 0.0, 1.0))


def rotate_free(q, omega, principal_q, moments, dt):
    """Torque-free rotation over ``dt`` (see module docstring). Returns new ``(q, omega)``.

    ``q (N, 4)`` body orientation, ``omega (N, 3)`` world angular velocity, ``principal_q (N, 4)``
    principal-to-body rotation, ``moments (N, 3)`` principal moments in ascending order.

    The exact ``|L|`` rotation takes any angle in one go; only the split rotations limit accuracy,
    and only through their failure to commute. The axis-1 flow turns ``Π`` in the 2–3 plane, the
    axis-3 flow in the 1–2 plane, by at most ``θ₁ = |Π₁₂|·|1/I₁ − 1/I₂|·dt`` and
    ``θ₃ = |Π₂₃|·|1/I₃ − 1/I₂|·dt`` in a step. When one of them is nil (to round-off) the other acts
    alone and the step is exact: an axisymmetric body (a factor ``1/Iᵢ − 1/I₂`` is 0, e.g. a rod
    spinning end over end) takes one sub-step. Otherwise the body tumbles on a cone of half-angle
    ``β`` about an end axis (``tumbling_cone``, fixed by the conserved ``|L|`` and energy), and
    splitting errors stay within that cone: a tumbling body is sub-stepped until
    ``|L|·max|1/Iᵢ − 1/I₂|·dt`` per sub-step is at most ``MAX_SPLIT_ANGLE``, scaled by
    ``min(1, β/MAX_SPLIT_ANGLE)`` (at most ``MAX_SUBSTEPS``), so one spinning about a principal axis
    with a micro-radian wobble (left by a contact) takes one sub-step, not 64.
    """
    qp = quat.mul(q, principal_q)  # orientation of the principal frame
    inv_m = 1.0 / moments
    body_w = quat.rotate(quat.conj(qp), omega)
    pi_body = moments * body_w             # Π, body angular momentum in the principal frame
    L = quat.rotate(qp, pi_body)           # world angular momentum, fixed during free flight
    rate = inv_m - inv_m[:, 1:2]           # (1/I_i - 1/I_2): zero on the middle axis
    p2 = pi_body * pi_body
    theta1 = np.sqrt(p2[:, 0] + p2[:, 1]) * np.abs(rate[:, 0]) * dt
    theta3 = np.sqrt(p2[:, 1] + p2[:, 2]) * np.abs(rate[:, 2]) * dt
    alone = np.minimum(theta1, theta3) <= 1e-12 * np.maximum(theta1, theta3)   # one flow: exact
    norm_l = np.linalg.norm(L, axis=1)
    cone = tumbling_cone(p2, moments)
    sp = np.flatnonzero(np.maximum(theta1, theta3) > 0)
    if sp.size:
        # the larger angle as |L| has it (Π turns during the step), scaled by the tumbling cone
        big = norm_l[sp] * np.abs(rate[sp]).max(axis=1) * dt
        need = np.where(alone[sp], 1.0, big / MAX_SPLIT_ANGLE * np.minimum(1.0, cone[sp] / MAX_SPLIT_ANGLE))
        n_sub = np.clip(np.ceil(need), 1, MAX_SUBSTEPS).astype(int)
        h = dt / n_sub
        qs, Ls, rs = qp[sp], L[sp], rate[sp]
        for k in range(int(n_sub.max())):
            active = k < n_sub
            for axis, frac in ((0, 0.5), (2, 1.0), (0, 0.5)):
                pi_axis = quat.rotate(quat.conj(qs), Ls)[:, axis]
                angle = np.where(active, pi_axis * rs[:, axis] * frac * h, 0.0)
                qs = quat.mul(qs, quat.axis_rotation(axis, angle))
        qp[sp] = qs
    qp = quat.mul(quat.from_rotvec(L * (inv_m[:, 1:2] * dt)), qp)  # commutes: one exact turn for the whole step
    qp = quat.normalize(qp)  # removes round-off only; every factor above is unit
    omega_new = quat.rotate(qp, quat.rotate(quat.conj(qp), L) * inv_m)
    return quat.mul(qp, quat.conj(principal_q)), omega_new
