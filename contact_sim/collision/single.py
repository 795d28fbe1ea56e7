"""The stateless one-pair query's fast path (``collide`` called in a loop).

For plainly valid input (numbers, finite, within ``LENGTH_LIMIT``, a non-zero quaternion, margin a
plain number, default bounding volume, no settings, no statistics) the pair skips the batch
machinery: one compiled call (``_one_pair``; ``_one_pair_trees`` for mesh–mesh; both ``_pair``)
checks the numbers, builds both rotations and runs the pair's kernel (``pair_kernels.call``).
Anything else returns ``None`` here and goes through the full checks (which name the problem) and
the batch pipeline; both paths run the same kernels, so they give the same contacts.

Most of a call's time is its Python side (reading the poses, numba checking each argument's type,
building the ``Contacts`` views), so that side is kept to the fewest operations: what does not
change between calls is prepared once per shape pair (``PairPlan``).
"""
import numpy as np

from ..contacts import Contacts
from ..jit import njit
from ..constants import LENGTH_LIMIT
from . import pair_kernels
from .vec3 import unit_rotations

NUMBER = (float, int)   # a plain margin's types (not bool: the checks refuse booleans for numbers)


def _plain(v, n):
    """``v`` as ``n`` Python floats (a list, or ``v`` itself when it holds only floats) when it is
    plainly ``n`` numbers, else None. (The compiled call takes floats: an int would compile another
    version of it, and a float passed as it is costs nothing to convert.)"""
    t = type(v)
    if t is np.ndarray:
        if v.shape != (n,):
            return None
        k = v.dtype.kind
        if k == "f" and v.dtype.itemsize <= 8:
            return v.tolist()   # Python floats already (a long double's elements would not be)
        return [float(x) for x in v.tolist()] if k == "f" or k == "i" else None
    if (t is tuple or t is list) and len(v) == n:
        convert = False
        for x in v:
            tx = type(x)
            if tx is not float:
                # numpy scalars too (a tuple made from an array's elements): not numpy's bool
                if tx is not int and tx is not np.float64 and tx is not np.int64:
                    return None
                convert = True
        return [float(x) for x in v] if convert else v
    return None


class PairPlan:
    """What a shape pair needs for the fast path: its compiled entry and the arguments that do not
    change from call to call (``tail``: the kernel's place in ``pair_kernels``, whether the kernel's
    A is the second shape, the geometry arrays packed (``pack``), the two shapes' geometry rows,
    [the mesh trees]).

    Fewer arguments make a cheaper call: numba checks the type of each one on every call (an
    array costs about four numbers, a tuple of arrays most), so the eight geometry arrays go as two,
    the mesh–mesh trees only to that kernel's entry, and the body index arrays ``a``, ``b``,
    ``shape_of`` are made inside the compiled call."""

    def __init__(self, bodies):
        r = bodies.rank
        swap = bool(r[0] < r[1])
        which = pair_kernels.index(int(max(r)), int(min(r)))
        s0, s1 = int(bodies.shape_of[0]), int(bodies.shape_of[1])
        self.tail = (which, swap, *pack(bodies.geom.arrays()), s0, s1, LENGTH_LIMIT)
        self.entry = _one_pair
        if which == pair_kernels.MESH_MESH:
            self.entry = _one_pair_trees
            self.tail += tuple(pair_kernels.trees(bodies.geom))


_OUT_I = np.zeros((4, 5), np.int64)
_OUT_I[:, 4] = 1      # the kernel writes columns 0-2; columns 3 and 4 are body_a = 0 and body_b = 1


def collide_fast(plan, pose_a, pose_b, margin):
    """Contacts of one pair on the fast path (``body_a = 0``, ``body_b = 1``), or None when the
    poses are not plainly valid (the full checks then say why)."""
    # each pose as 3 and 4 Python floats when it is plainly that (their values are checked in the
    # compiled call); written out here, not a helper per pose: a Python call costs what this does
    ta, tb = type(pose_a), type(pose_b)
    if (ta is not tuple and ta is not list) or (tb is not tuple and tb is not list) or len(pose_a) != 2 \
            or len(pose_b) != 2:
        return None
    pa, qa, pb, qb = _plain(pose_a[0], 3), _plain(pose_a[1], 4), _plain(pose_b[0], 3), _plain(pose_b[1], 4)
    if pa is None or qa is None or pb is None or qb is None:
        return None
    # one block per kind: the kernel's rows (point, normal, depth; pair, feature, id) and, beside
    # them, the zero response columns and the body indices (views into the blocks, as the batch's)
    out_i, out_f = _OUT_I.copy(), np.zeros((4, 15))
    k = plan.entry(*pa, *qa, *pb, *qb, float(margin), out_i, out_f, *plan.tail)
    if k <= 0:
        # no contact: the shared zero-length columns (nothing in them to change), not eleven views
        return None if k < 0 else Contacts.empty()
    fr, i = out_f[:k], out_i[:k]
    return Contacts(i[_C3], i[_C4], fr[_C0_3], fr[_C3_6], fr[_C6], fr[_C7_10], fr[_C10], fr[_C11_14], fr[_C14],
                    i[_C1], i[_C2])


# the column views' index tuples, built once (an index written in place is built on every call)
_C0_3, _C3_6, _C7_10, _C11_14 = (np.s_[:, j:j + 3] for j in (0, 3, 7, 11))
_C1, _C2, _C3, _C4, _C6, _C10, _C14 = (np.s_[:, j] for j in (1, 2, 3, 4, 6, 10, 14))


def pack(arrays):
    """The geometry arrays ``GeomTable.arrays()`` (``sf, si, verts, planes, faces, loops, edges,
    tris``) as one float block and one int block, for ``_unpack``: ``(F (·,), I (·,))``, ``I``
    starting with each array's rows and columns (``loops`` is 1-D: columns 0)."""
    sf, si, verts, planes, faces, loops, edges, tris = arrays
    head = [n for x in arrays for n in (x.shape[0], x.shape[1] if x.ndim == 2 else 0)]
    return (np.concatenate([np.ravel(x).astype(np.float64) for x in (sf, verts, planes)]),
            np.concatenate([np.array(head, np.int64)] + [np.ravel(x).astype(np.int64) for x in (si, faces, loops, edges,
                                                                                                  tris)]))


@njit
def _unpack(F, I):
    """The eight geometry arrays from ``pack``'s blocks: contiguous views, so of the arrays' own
    types (no other compiled version of a kernel)."""
    sf = F[:I[0] * I[1]].reshape((I[0], I[1]))
    o = I[0] * I[1]
    verts = F[o:o + I[4] * I[5]].reshape((I[4], I[5]))
    o += I[4] * I[5]
    planes = F[o:o + I[6] * I[7]].reshape((I[6], I[7]))
    o = 16
    si = I[o:o + I[2] * I[3]].reshape((I[2], I[3]))
    o += I[2] * I[3]
    faces = I[o:o + I[8] * I[9]].reshape((I[8], I[9]))
    o += I[8] * I[9]
    loops = I[o:o + I[10]]
    o += I[10]
    edges = I[o:o + I[12] * I[13]].reshape((I[12], I[13]))
    o += I[12] * I[13]
    tris = I[o:o + I[14] * I[15]].reshape((I[14], I[15]))
    return sf, si, verts, planes, faces, loops, edges, tris


@njit
def _one_pair(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1, margin, out_i, out_f, which, swap,
              F, I, s0, s1, limit):
    """``_one_pair_trees`` for every kernel but mesh–mesh (which reads no trees: placeholders)."""
    bvh = (np.zeros((1, 4), np.int64), np.zeros((1, 6)), np.zeros(1, np.int64), np.full(2, -1, np.int64),
           np.ones((1, 3), np.bool_))
    sf, si, verts, planes, faces, loops, edges, tris = _unpack(F, I)
    return _pair(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1, margin, out_i, out_f, which, swap,
                 sf, si, verts, planes, faces, loops, edges, tris, s0, s1, limit, bvh)


@njit
def _one_pair_trees(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1, margin, out_i, out_f, which,
                    swap, F, I, s0, s1, limit, nodes, boxes, perm, root, border):
    """The pair's contacts from its two poses (14 numbers), the geometry as ``pack``'s two blocks,
    ``pair_kernels.trees`` as its five arrays (``_pair``)."""
    sf, si, verts, planes, faces, loops, edges, tris = _unpack(F, I)
    return _pair(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1, margin, out_i, out_f, which, swap,
                 sf, si, verts, planes, faces, loops, edges, tris, s0, s1, limit, (nodes, boxes, perm, root, border))


@njit
def _pair(x0, y0, z0, qx0, qy0, qz0, qw0, x1, y1, z1, qx1, qy1, qz1, qw1, margin, out_i, out_f, which, swap, sf, si,
          verts, planes, faces, loops, edges, tris, s0, s1, limit, bvh):
    """The pair's contacts from its two poses (14 numbers): −1 when a coordinate is not finite or
    beyond ``limit``, or a quaternion is not finite or (near) zero; else the quaternions
    normalised, the rotations (``vec3.rotations``), the kernel ``which`` (``pair_kernels.call``) on
    geometry rows ``s0, s1`` (A = the second when ``swap``) into ``out_i (4, ≥3)``,
    ``out_f (4, ≥7)``, normals from B to A (negated when ``swap``); returns the rows written."""
    pos, q, R = np.empty((2, 3)), np.empty((2, 4)), np.empty((2, 3, 3))
    pos[0, 0], pos[0, 1], pos[0, 2], pos[1, 0], pos[1, 1], pos[1, 2] = x0, y0, z0, x1, y1, z1
    q[0, 0], q[0, 1], q[0, 2], q[0, 3], q[1, 0], q[1, 1], q[1, 2], q[1, 3] = qx0, qy0, qz0, qw0, qx1, qy1, qz1, qw1
    for r in range(2):
        for x in range(3):
            if not abs(pos[r, x]) <= limit:
                return -1   # NaN, inf or too far: the full check says which
        for x in range(4):
            if not abs(q[r, x]) < 1e150:
                return -1
        if not np.sqrt(q[r, 0] * q[r, 0] + q[r, 1] * q[r, 1] + q[r, 2] * q[r, 2] + q[r, 3] * q[r, 3]) >= 1e-12:
            return -1
    unit_rotations(q, R)
    ints = np.zeros(7, np.int64)
    shape_of, a, b, counters = ints[:2], ints[2:3], ints[3:4], ints[4:]
    shape_of[0], shape_of[1] = s0, s1
    a[0], b[0] = (1, 0) if swap else (0, 1)   # bodies in the kernel's order: A of the higher rank
    margins = np.empty(1)
    margins[0] = margin
    k = pair_kernels.call(which, sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                          counters, out_i, out_f, bvh)
    if swap:
        for r in range(k):
            for x in range(3, 6):
                out_f[r, x] = -out_f[r, x]
    return k
