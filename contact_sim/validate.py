"""Input checks shared by shapes, bodies and poses: each error names the thing and the reason."""
import numpy as np

from .errors import ContactSimError


def vector(value, n, what):
    """``value`` as a finite ``(n,)`` float array, or ``ContactSimError`` naming ``what``."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ContactSimError(f"{what}: must be {n} numbers, got {value!r}") from None
    if a.shape != (n,):
        raise ContactSimError(f"{what}: must be {n} numbers, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ContactSimError(f"{what}: must be finite, got {a.tolist()}")
    return a


def positive(value, what):
    """``value`` as a finite float > 0 (booleans refused), or ``ContactSimError`` naming ``what``."""
    if isinstance(value, bool):
        raise ContactSimError(f"{what}: must be a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ContactSimError(f"{what}: must be a number, got {value!r}") from None
    if not np.isfinite(x) or x <= 0:
        raise ContactSimError(f"{what}: must be > 0, got {value!r}")
    return x


def unit_quaternion(value, what, tolerance):
    """``value`` (x, y, z, w) normalised; refused when not finite, zero, or when its norm differs
    from 1 by more than ``tolerance``."""
    q = vector(value, 4, what)
    norm = float(np.linalg.norm(q))
    if norm < 1e-12:
        raise ContactSimError(f"{what}: zero quaternion is not a rotation")
    if abs(norm - 1.0) > tolerance:
        raise ContactSimError(f"{what}: quaternion must be unit length (x, y, z, w), got norm {norm:.6g}")
    return q / norm
