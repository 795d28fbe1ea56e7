"""Free-motion integration between contacts, vectorised over bodies.

Translation: ``x += v dt + g dt²/2``, ``v += g dt`` — exact for constant acceleration, so ballistic
flight carries no integration error at any step size.

Rotation: the torque-free rigid body is split into three rotations about its principal axes
(Strang splitting 1-2-3-2-1, McLachlan 1993 / Dullweber–Leimkuhler–McLachlan 1997). Each
sub-flow is an exact rotation about one body axis at the rate ``L_i / I_i``, during which the
world angular momentum ``L`` does not change: so ``L`` is conserved to round-off, quaternions
stay unit length (they are only ever multiplied by unit rotations), energy error stays bounded
(symplectic, second order) and fast spin cannot blow up.
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
    r = quat.to_matrix(q)
    return r @ inv_inertia_body @ np.swapaxes(r, -1, -2)


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
    idx = np.flatnonzero(rotating)
    if idx.size:
        q, w = rotate_free(state.quat[idx], state.omega[idx], state.principal_q[idx],
                           state.principal_moments[idx], dt)
        state.quat[idx] = q
        state.omega[idx] = w


def rotate_free(q, omega, principal_q, moments, dt):
    """Torque-free rotation over ``dt`` (see module docstring). Returns new ``(q, omega)``.

    ``q (N, 4)`` body orientation, ``omega (N, 3)`` world angular velocity, ``principal_q (N, 4)``
    principal-to-body rotation, ``moments (N, 3)`` principal moments (``inf`` = locked axis).
    """
    qp = quat.mul(q, principal_q)  # orientation of the principal frame
    inv_m = np.where(np.isfinite(moments), 1.0 / moments, 0.0)
    # world angular momentum L = R_p diag(I) R_pᵀ ω, held fixed during the splitting
    body_w = quat.rotate(quat.conj(qp), omega)
    L = quat.rotate(qp, np.where(np.isfinite(moments), moments * body_w, 0.0))
    for axis, frac in ((0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)):
        pi_axis = quat.rotate(quat.conj(qp), L)[:, axis]
        angle = pi_axis * inv_m[:, axis] * (frac * dt)
        qp = quat.mul(qp, quat.axis_rotation(axis, angle))
    qp = quat.normalize(qp)  # removes round-off only; every factor above is unit
    omega_new = quat.rotate(qp, quat.rotate(quat.conj(qp), L) * inv_m)
    return quat.mul(qp, quat.conj(principal_q)), omega_new
