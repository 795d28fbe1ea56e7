"""Free-motion integration between contacts (the kernel is ``free_motion.advance``): the method.

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

from . import free_motion, quat
from .constants import MAX_SPLIT_ANGLE, MAX_SUBSTEPS


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
    ``β`` about an end axis (``free_motion._cone``, fixed by the conserved ``|L|`` and energy), and
    splitting errors stay within that cone: a tumbling body is sub-stepped until
    ``|L|·max|1/Iᵢ − 1/I₂|·dt`` per sub-step is at most ``MAX_SPLIT_ANGLE``, scaled by
    ``min(1, β/MAX_SPLIT_ANGLE)`` (at most ``MAX_SUBSTEPS``), so one spinning about a principal axis
    with a micro-radian wobble (left by a contact) takes one sub-step, not 64.
    """
    q_new, omega_new, _ = free_motion.rotate(q, omega, principal_q, moments, dt, MAX_SPLIT_ANGLE, MAX_SUBSTEPS)
    return q_new, omega_new
