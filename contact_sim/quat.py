"""Vectorised quaternion helpers. Quaternions are ``(..., 4)`` float arrays ordered x, y, z, w (as ROS).

All functions broadcast over leading dimensions and never loop in Python.
"""
import numpy as np

from .vec import cross


def normalize(q):
    """Unit quaternion(s) ``(..., 4)``; the sign is kept."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def conj(q):
    """Conjugate (inverse for unit quaternions), ``(..., 4)``."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([-q[..., :3], q[..., 3:]], axis=-1)


def mul(a, b):
    """Hamilton product ``a ⊗ b`` of ``(..., 4)`` arrays: apply ``b`` first, then ``a``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    av, aw = a[..., :3], a[..., 3:]
    bv, bw = b[..., :3], b[..., 3:]
    v = aw * bv + bw * av + cross(av, bv)
    w = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    return np.concatenate([v, w], axis=-1)


def rotate(q, v):
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)``."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def _matrix_coefficients():
    """``(16, 9)``: each rotation-matrix entry as a linear form in the products ``q_i q_j``."""
    x, y, z, w = range(4)
    terms = {(0, 0): [(y, y, -2), (z, z, -2)], (0, 1): [(x, y, 2), (w, z, -2)], (0, 2): [(x, z, 2), (w, y, 2)],
             (1, 0): [(x, y, 2), (w, z, 2)], (1, 1): [(x, x, -2), (z, z, -2)], (1, 2): [(y, z, 2), (w, x, -2)],
             (2, 0): [(x, z, 2), (w, y, -2)], (2, 1): [(y, z, 2), (w, x, 2)], (2, 2): [(x, x, -2), (y, y, -2)]}
    c = np.zeros((16, 9))
    for (r, col), lin in terms.items():
        for i, j, coef in lin:
            c[4 * i + j, 3 * r + col] += coef
    return c


_TO_MATRIX = _matrix_coefficients()
_EYE9 = np.eye(3).ravel()


def to_matrix(q):
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions ``(..., 4)``: ``I + 2 w [v]× + 2 [v]×²``
    written as one product of the 16 ``q_i q_j`` with a constant ``(16, 9)`` matrix (3 numpy calls
    instead of ~25 on the short arrays of a step)."""
    q = np.asarray(q, dtype=float)
    lead = q.shape[:-1]
    qq = (q[..., :, None] * q[..., None, :]).reshape(lead + (16,))
    return (qq @ _TO_MATRIX + _EYE9).reshape(lead + (3, 3))


def from_matrix(m):
    """Unit quaternion(s) ``(..., 4)`` x,y,z,w of rotation matrices ``(..., 3, 3)``."""
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, dtype=float)
    flat = Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat()  # scipy is scalar-last too
    return flat.reshape(m.shape[:-2] + (4,))


def from_rotvec(r):
    """Quaternion(s) ``(..., 4)`` of rotation vectors ``r (..., 3)`` (axis times angle, radians).

    Uses ``sin(θ/2)/θ`` with a series near zero so tiny rotations keep full precision.
    """
    r = np.asarray(r, dtype=float)
    theta = np.linalg.norm(r, axis=-1, keepdims=True)
    small = theta < 1e-4
    th2 = theta * theta
    # series of sin(θ/2)/θ = 1/2 - θ²/48 + θ⁴/3840
    safe = np.where(small, 1.0, theta)
    s = np.where(small, 0.5 - th2 / 48.0 + th2 * th2 / 3840.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([r * s, np.cos(0.5 * theta)], axis=-1)


def to_rotvec(q):
    """Rotation vector(s) ``(..., 3)`` of unit quaternions, taking the shorter way round (angle ≤ π)."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., 3:] < 0, -q, q)
    v = q[..., :3]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:])
    small = s < 1e-12
    scale = np.where(small, 2.0 / np.maximum(q[..., 3:], 1e-300), angle / np.where(small, 1.0, s))
    return v * scale


def axis_rotation(axis_index, angle):
    """Quaternions ``(N, 4)`` for rotations by ``angle (N,)`` about a coordinate axis (0, 1 or 2)."""
    angle = np.asarray(angle, dtype=float)
    q = np.zeros(angle.shape + (4,))
    q[..., axis_index] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q
