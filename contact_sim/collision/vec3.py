"""3-vector helpers for compiled kernels: plain arithmetic (numba's ``@`` on 3-vectors calls BLAS,
whose call costs more than the product)."""
import numpy as np

from ..jit import njit


@njit
def dot(a, b):
    """``a · b`` of 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit
def cross(a, b):
    """``a × b`` of 3-vectors, a new ``(3,)`` array."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit
def mv(R, v):
    """``R v`` for ``R (3, 3)``, ``v (3,)``."""
    out = np.empty(3)
    for i in range(3):
        out[i] = R[i, 0] * v[0] + R[i, 1] * v[1] + R[i, 2] * v[2]
    return out


@njit
def mtv(R, v):
    """``Rᵀ v``."""
    out = np.empty(3)
    for i in range(3):
        out[i] = R[0, i] * v[0] + R[1, i] * v[1] + R[2, i] * v[2]
    return out


@njit
def norm(a):
    return np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
