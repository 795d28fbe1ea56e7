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
    ``principal_moments (N, 3)``.
    """
    accel = np.where(moving[:, None], gravity, 0.0)
    state.pos += state.vel * dt + 0.5 * accel * dt * dt
    state.vel += accel * dt
    # a body that does not spin keeps its orientation exactly (L = 0: every factor is the identity)
    spin = rotating & state.omega.any(axis=1)
    if not spin.any():
        return
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
        state.quat[idx] = q
        state.omega[idx] = w


ISOTROPIC_TOLERANCE = 1e-12  # relative spread of principal moments below which a body spins as a sphere
MAX_SPLIT_ANGLE = 0.25  # rad: largest non-commuting sub-rotation per sub-step (accuracy knob)
MAX_SUBSTEPS = 64  # beyond this, spin stays stable and L exact but accuracy degrades gracefully


def rotate_free(q, omega, principal_q, moments, dt):
    """Torque-free rotation over ``dt`` (see module docstring). Returns new ``(q, omega)``.

    ``q (N, 4)`` body orientation, ``omega (N, 3)`` world angular velocity, ``principal_q (N, 4)``
    principal-to-body rotation, ``moments (N, 3)`` principal moments in ascending order.

    The exact ``|L|`` rotation takes any angle in one go; only the split (non-commuting) rotations
    limit accuracy, so a body whose split rotation would exceed ``MAX_SPLIT_ANGLE`` in a step is
    sub-stepped (per body; slowly or symmetrically spinning bodies take one sub-step).
    """
    qp = quat.mul(q, principal_q)  # orientation of the principal frame
    inv_m = 1.0 / moments
    body_w = quat.rotate(quat.conj(qp), omega)
    L = quat.rotate(qp, moments * body_w)  # world angular momentum, fixed during free flight
    rate = inv_m - inv_m[:, 1:2]           # (1/I_i - 1/I_2): zero on the middle axis
    split_rate = np.linalg.norm(L, axis=1) * np.abs(rate).max(axis=1)
    # isotropic bodies (spheres, cubes) and non-spinning ones have no split term: only the exact turn
    sp = np.flatnonzero(split_rate > 0)
    if sp.size:
        n_sub = np.clip(np.ceil(split_rate[sp] * dt / MAX_SPLIT_ANGLE), 1, MAX_SUBSTEPS).astype(int)
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
