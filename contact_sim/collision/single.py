"""The stateless one-pair query's fast path (``collide`` called in a loop).

For plainly valid input (numbers, finite, within ``LENGTH_LIMIT``, a non-zero quaternion, margin a
plain number, default bounding volume, no settings, no statistics) the pair skips the batch
machinery: one compiled call builds both rotations, one calls the pair's kernel. Anything else
returns ``None`` here and goes through the full checks (which name the problem) and the batch
pipeline; both paths run the same kernels, so they give the same contacts.
"""
import math

import numpy as np

from ..contacts import Contacts
from ..jit import njit
from ..validate import LENGTH_LIMIT
from . import dispatch
from .vec3 import rotations

_NUMBER = (float, int)   # not bool: the checks refuse booleans for numbers


def _plain(v, n):
    """``v`` as ``n`` Python numbers (a list, or ``v`` itself) when it is plainly that, else None."""
    t = type(v)
    if t is np.ndarray:
        return v.tolist() if v.shape == (n,) and v.dtype.kind in "fi" else None
    if (t is tuple or t is list) and len(v) == n:
        for x in v:
            tx = type(x)
            # numpy scalars too (a tuple made from an array's elements): not numpy's bool
            if tx is not float and tx is not int and tx is not np.float64 and tx is not np.int64:
                return None
        return v
    return None


def fast_pose(pose):
    """``(position (3 numbers), orientation (4 numbers, normalised))`` of a plainly valid pose, else None."""
    if (type(pose) is not tuple and type(pose) is not list) or len(pose) != 2:
        return None
    p, q = _plain(pose[0], 3), _plain(pose[1], 4)
    if p is None or q is None:
        return None
    x, y, z, w = q
    if not (abs(p[0]) <= LENGTH_LIMIT and abs(p[1]) <= LENGTH_LIMIT and abs(p[2]) <= LENGTH_LIMIT
            and abs(x) < 1e150 and abs(y) < 1e150 and abs(z) < 1e150 and abs(w) < 1e150):
        return None   # NaN, inf or too far: the full check says which
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not norm >= 1e-12:
        return None
    return p, (x / norm, y / norm, z / norm, w / norm)


def plain_margin(margin):
    return type(margin) in _NUMBER and 0 <= margin <= LENGTH_LIMIT


def pose_arrays(pa, qa, pb, qb):
    """``pos (2, 3)`` and rotation matrices ``R (2, 3, 3)`` of two poses (quaternions x, y, z, w)."""
    return _frames(*pa, *qa, *pb, *qb)


@njit
def _frames(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1):
    """``pose_arrays`` from 14 numbers in one call (``vec3.rotations``' formula)."""
    pos, q, R = np.empty((2, 3)), np.empty((2, 4)), np.empty((2, 3, 3))
    pos[0, 0], pos[0, 1], pos[0, 2], pos[1, 0], pos[1, 1], pos[1, 2] = x0, y0, z0, x1, y1, z1
    q[0, 0], q[0, 1], q[0, 2], q[0, 3], q[1, 0], q[1, 1], q[1, 2], q[1, 3] = qx0, qy0, qz0, qw0, qx1, qy1, qz1, qw1
    rotations(q, R)
    return pos, R


class PairPlan:
    """What a shape pair needs for the fast path: its kernel, the kernel's A/B order."""

    def __init__(self, bodies):
        r = bodies.rank
        self.swap = bool(r[0] < r[1])
        self.a = np.array([1 if self.swap else 0], np.int64)
        self.b = np.array([0 if self.swap else 1], np.int64)
        self.kernel = dispatch.kernel_for(int(max(r)), int(min(r)))
        self.arrays = bodies.geom.arrays()
        more = dispatch.EXTRA.get((int(max(r)), int(min(r))))
        self.more = more(bodies.geom) if more is not None else ()   # mesh–mesh: the trees
        self.shape_of = bodies.shape_of


def collide_fast(plan, pa, qa, pb, qb, margin):
    """Contacts of one pair on the fast path (``body_a = 0``, ``body_b = 1``)."""
    pos, R = pose_arrays(pa, qa, pb, qb)
    out_i, out_f = np.empty((4, 3), np.int64), np.empty((4, 7))
    k = 0
    if plan.kernel is not None:
        k = plan.kernel(*plan.arrays, plan.shape_of, plan.a, plan.b, pos, R, float(margin), np.zeros(3, np.int64),
                        out_i, out_f, *plan.more)
    if plan.swap:
        out_f[:k, 3:6] *= -1.0
    # the response columns are zero: one block, split into its columns (separate arrays to the user)
    zero = np.zeros((8, k))
    ids = np.zeros((2, k), np.int64)
    ids[1] = 1
    f, i = out_f[:k], out_i[:k]
    return Contacts(ids[0], ids[1], f[:, 0:3], f[:, 3:6], f[:, 6], zero[0:3].T, zero[3], zero[4:7].T, zero[7],
                    i[:, 1], i[:, 2])
