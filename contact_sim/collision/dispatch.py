"""The narrow phase's kernels' one signature, and the batch's grouping by type pair around them.

Each shape-type pair (A of the higher rank, see ``geometry.RANK``) has one kernel, in the literal
table ``pair_kernels.COLLIDERS`` (as MJX's ``_COLLISION_FUNC``). Every kernel is a compiled loop
over its pairs with the arguments ``KERNEL_ARGS`` and returns the number of contact rows written
(at most 4 per pair):

    kernel(sf, si, verts, planes, faces, loops, edges, tris,   # geometry.GeomTable.arrays()
           shape_of (N,), a (K,), b (K,),                       # body -> table row; the pairs' bodies
           pos (N, 3), R (N, 3, 3), margins (K,), counters (3,), # poses; each pair's margin; [vertex, edge_face, edge_hits]
           out_i (4K, 3), out_f (4K, 7)) -> rows               # (pair, feature, feature id), (point, normal, depth)

``counters`` may also be ``(2,)``: then the edge–face crossings are not counted, and a kernel
skips an edge–face test whose answer only counts (the polyhedra's: their separating-axis test
decides the contact; a step's detection does not take the census, 1.3 µs a resting box pair).

``pair_kernels.pair_contacts`` groups a batch's pairs by type pair (``group_by_type``) and calls each
group's kernel through ``pair_kernels.call``, all in one compiled call per detection.
"""
import numpy as np

from ..jit import njit
from .vec3 import counting_order

KERNEL_ARGS = ("sf", "si", "verts", "planes", "faces", "loops", "edges", "tris", "shape_of", "a", "b", "pos", "R",
               "margins", "counters", "out_i", "out_f")
@njit
def group_by_type(a, b, ranks, nrank):
    """Pairs ``a, b (K,)`` in the stable order of their type-pair key ``rank A · nrank + rank B``:
    ``(order (K,), A (K,), B (K,), starts (G + 1,), keys (G,))``, group ``g`` being
    ``A[starts[g]:starts[g + 1]]`` with key ``keys[g]``. The order is a counting sort of the
    keys (``vec3.counting_order``: stable, as a merge sort)."""
    K = a.shape[0]
    ints = np.empty((6, K + 1), np.int64)   # one block: key, order, A, B, keys (K,), starts (K + 1,)
    key, order, A, B, keys, starts = ints[0, :K], ints[1, :K], ints[2, :K], ints[3, :K], ints[4, :K], ints[5]
    for k in range(K):
        key[k] = ranks[a[k]] * nrank + ranks[b[k]]
    counting_order(key, nrank * nrank, order)
    g = 0
    for k in range(K):
        o = order[k]
        A[k], B[k] = a[o], b[o]
        if k == 0 or key[o] != keys[g - 1]:
            starts[g], keys[g] = k, key[o]
            g += 1
    starts[g] = K
    return order, A, B, starts[:g + 1], keys[:g]


@njit
def contact_columns(rows_i, rows_f, kk, ia, ib, swap):
    """The narrow phase's rows ``rows_i (M, 3)``, ``rows_f (M, 7)`` (``pair`` indexing the kept
    pairs ``kk`` of the batch ``ia, ib, swap (K,)``) as contact columns: ``(body_a (M,), body_b
    (M,), normal (M, 3)`` (from ``body_b`` to ``body_a``: the kernels' normal, negated where the
    pair was swapped), ``colliding pairs)``."""
    M = rows_i.shape[0]
    bodies = np.empty((2, M), np.int64)   # body_a, body_b: one block
    body_a, body_b = bodies[0], bodies[1]
    normal = np.empty((M, 3))
    seen = np.zeros(ia.shape[0], np.bool_)
    pairs = 0
    for r in range(M):
        p = kk[rows_i[r, 0]]
        body_a[r], body_b[r] = ia[p], ib[p]
        for i in range(3):
            normal[r, i] = -rows_f[r, 3 + i] if swap[p] else rows_f[r, 3 + i]
        if not seen[p]:
            seen[p] = True
            pairs += 1
    return body_a, body_b, normal, pairs
