"""The narrow phase's table: one compiled kernel per shape-type pair, one signature for all.

As MJX's ``_COLLISION_FUNC`` and its ``collider`` decorator: ``@collider((BOX, SPHERE), ...)``
registers a kernel under the (A rank, B rank) pairs it handles (A of the higher rank, see
``geometry.RANK``). Every kernel is a compiled loop over its pairs with the arguments
``KERNEL_ARGS`` and returns the number of contact rows written (at most 4 per pair):

    kernel(sf, si, verts, planes, faces, loops, edges, tris,   # geometry.GeomTable.arrays()
           shape_of (N,), a (K,), b (K,),                       # body -> table row; the pairs' bodies
           pos (N, 3), R (N, 3, 3), margin, counters (3,),      # poses; [vertex, edge_face, edge_hits]
           out_i (4K, 3), out_f (4K, 7)) -> rows               # (pair, feature, feature id), (point, normal, depth)

``run`` calls the kernel of each type pair present in a batch (a handful of calls per detection).
"""
import numpy as np

KERNEL_ARGS = ("sf", "si", "verts", "planes", "faces", "loops", "edges", "tris", "shape_of", "a", "b", "pos", "R",
               "margin", "counters", "out_i", "out_f")
TABLE = {}   # (rank A, rank B) -> kernel


def collider(*keys):
    """Register the decorated kernel for the shape-type pairs ``keys`` ((rank A, rank B) tuples)."""
    def register(kernel):
        for key in keys:
            TABLE[key] = kernel
        return kernel
    return register


def _load():
    # the modules that register kernels (imported here, not above: they import ``collider``)
    from . import meshes, polyhedra, primitives  # noqa: F401


def kernel_for(ra, rb):
    """The kernel of ranks ``ra >= rb``, or None (plane–plane, mesh–mesh: no kernel)."""
    if not TABLE:
        _load()
    return TABLE.get((ra, rb))


def run(geom, shape_of, ranks, a, b, pos, R, margin, counters):
    """Contacts of pairs ``a, b (K,)`` (``ranks[a] >= ranks[b]``): ``(rows_i (M, 3), rows_f (M, 7),
    unsupported)``: the kernels' rows (``pair`` indexing the batch) and the number of pairs no kernel
    handles (mesh–mesh; plane–plane pairs are not contacts)."""
    if not TABLE:
        _load()
    arrays = geom.arrays()
    key = ranks[a] * 5 + ranks[b]
    present = np.flatnonzero(np.bincount(key, minlength=25)) if len(key) else ()
    outs, unsupported = [], 0
    for kk in present:
        kernel = TABLE.get(divmod(int(kk), 5))
        sel = None if len(present) == 1 else np.flatnonzero(key == kk)
        A, B = (a, b) if sel is None else (a[sel], b[sel])
        if kernel is None:
            unsupported += len(A) if kk != 0 else 0
            continue
        out_i = np.empty((4 * len(A), 3), np.int64)
        out_f = np.empty((4 * len(A), 7))
        n = kernel(*arrays, shape_of, A, B, pos, R, margin, counters, out_i, out_f)
        out_i, out_f = out_i[:n], out_f[:n]
        if sel is not None:
            out_i[:, 0] = sel[out_i[:, 0]]
        outs.append((out_i, out_f))
    if not outs:
        return np.zeros((0, 3), np.int64), np.zeros((0, 7)), unsupported
    if len(outs) == 1:
        return outs[0][0], outs[0][1], unsupported
    return np.concatenate([o[0] for o in outs]), np.concatenate([o[1] for o in outs]), unsupported
