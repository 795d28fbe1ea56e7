"""The narrow phase's table, ``COLLIDERS``: shape-type pair → kernel, and ``call(which, ...)``,
the table callable from compiled code.

Compiled code cannot look a kernel up in a dict, and a kernel handed to a compiled function as an
argument breaks numba's on-disk cache (its index pickles the argument's type, a reference to the
kernel that a later process cannot restore). So ``KERNELS`` numbers the table's distinct kernels
in the order they first appear in it, ``index(ra, rb)`` maps a type pair to its number, and
``call`` branches on that number (a test calls every type pair both ways).
Used by the compiled time-of-impact search (``response.advancement``) for the distance of a pair,
and by ``pair_contacts``, the whole narrow phase of a detection in one compiled call.
"""
import functools
import time

import numpy as np

from ..jit import njit, objmode
from .bounding import kept_pairs
from .dispatch import contact_columns, group_by_type
from .geometry import BOX, CONVEX, CYLINDER, MESH, NRANK, PLANE, SPHERE
from .cylinders import cylinder_plane, cylinder_sphere
from .mesh_mesh import mesh_mesh, table_bvh
from .meshes import mesh_poly, mesh_sphere
from .polyhedra import poly_poly
from .primitives import box_sphere, poly_plane, poly_sphere, sphere_plane, sphere_sphere

#: the narrow phase: (rank A, rank B) → kernel, A of the higher rank (``geometry.RANK``); plane–plane
#: has none (two planes are no contact). Every pair with a cylinder but plane and sphere goes through
#: the generic convex and mesh kernels on its prism hull (``contact_sim.cylinder``'s error bound).
COLLIDERS = {
    (SPHERE, PLANE): sphere_plane,
    (SPHERE, SPHERE): sphere_sphere,
    (BOX, PLANE): poly_plane, (CONVEX, PLANE): poly_plane, (MESH, PLANE): poly_plane,
    (BOX, SPHERE): box_sphere,
    (BOX, BOX): poly_poly, (CONVEX, BOX): poly_poly, (CONVEX, CONVEX): poly_poly,
    (CYLINDER, BOX): poly_poly, (CYLINDER, CONVEX): poly_poly, (CYLINDER, CYLINDER): poly_poly,
    (CONVEX, SPHERE): poly_sphere,
    (CYLINDER, PLANE): cylinder_plane,
    (CYLINDER, SPHERE): cylinder_sphere,
    (MESH, SPHERE): mesh_sphere,
    (MESH, BOX): mesh_poly, (MESH, CONVEX): mesh_poly, (MESH, CYLINDER): mesh_poly,
    (MESH, MESH): mesh_mesh,
}
#: the table's distinct kernels in the order of their first entry: ``call``'s branch numbers
KERNELS = tuple(dict.fromkeys(COLLIDERS.values()))
#: the place of the one kernel that reads ``trees``
MESH_MESH = KERNELS.index(mesh_mesh)


def index(ra, rb):
    """The place in ``KERNELS`` of the kernel of ranks ``ra >= rb`` (``COLLIDERS``), −1 when no
    kernel takes the pair (plane–plane)."""
    kernel = COLLIDERS.get((ra, rb))
    return -1 if kernel is None else KERNELS.index(kernel)


def trees(geom):
    """The extra arrays ``call`` passes to the mesh–mesh kernel (``mesh_mesh.table_bvh``)."""
    return table_bvh(geom)


@njit
def call(which, sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins, counters, out_i,
         out_f, bvh):
    """``KERNELS[which]`` with the kernel signature (``dispatch``), ``bvh = trees(geom)`` for
    mesh–mesh; returns the rows written (0 for ``which`` −1)."""
    if which == 0:
        return sphere_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                            counters, out_i, out_f)
    if which == 1:
        return sphere_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                             counters, out_i, out_f)
    if which == 2:
        return poly_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                          counters, out_i, out_f)
    if which == 3:
        return box_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                          counters, out_i, out_f)
    if which == 4:
        return poly_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                         counters, out_i, out_f)
    if which == 5:
        return poly_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                           counters, out_i, out_f)
    if which == 6:
        return cylinder_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                              counters, out_i, out_f)
    if which == 7:
        return cylinder_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                               counters, out_i, out_f)
    if which == 8:
        return mesh_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                           counters, out_i, out_f)
    if which == 9:
        return mesh_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                         counters, out_i, out_f)
    if which == 10:
        return mesh_mesh(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margins,
                         counters, out_i, out_f, bvh[0], bvh[1], bvh[2], bvh[3], bvh[4])
    return 0


@functools.cache
def which_table():
    """``(NRANK·NRANK,) int64``: the place in ``KERNELS`` of each type-pair key
    ``rank A · NRANK + rank B`` (``dispatch.group_by_type``'s keys), −1 where no kernel takes it."""
    return np.array([index(ra, rb) for ra in range(NRANK) for rb in range(NRANK)], np.int64)


@njit
def kept_contacts(which, sf, si, verts, planes, faces, loops, edges, tris, bvh, shape_of, rank, ia, ib, use_sphere,
                  use_obb, pos, R, margin, reach, floor, plane_margin, counters, timed, seconds):
    """The bounding volumes (``bounding.kept_pairs``: ``use_sphere``, ``use_obb``) then the narrow
    phase (``pair_contacts``, the same arguments) of the pairs ``ia, ib (K,)``, in one call: the
    kept pairs' arrays stay in compiled code (from Python, each array handed back and in again cost
    more than the bounding stage's arithmetic on a small world). Returns ``pair_contacts``' tuple
    and the number of pairs kept. With ``timed`` the two stages' seconds go to ``seconds (2,)``
    (a step's detection runs untimed)."""
    t0 = _clock(timed)
    swap, kk, a, b = kept_pairs(ia, ib, rank, use_sphere, use_obb, shape_of, sf, pos, R, margin)
    t1 = _clock(timed)
    rows_i, rows_f, body_a, body_b, normal, pairs, unsupported = pair_contacts(
        which, sf, si, verts, planes, faces, loops, edges, tris, bvh, shape_of, rank, ia, ib, swap, kk, a, b, pos, R,
        margin, reach, floor, plane_margin, counters)
    if timed:
        seconds[0], seconds[1] = t1 - t0, _clock(timed) - t1
    return rows_i, rows_f, body_a, body_b, normal, pairs, unsupported, kk.shape[0]


@njit
def _clock(timed):
    """``time.perf_counter()`` (s) when ``timed`` (run as Python from the kernel), else 0."""
    t = 0.0
    if timed:
        with objmode(t="float64"):
            t = time.perf_counter()
    return t


@njit
def pair_contacts(which, sf, si, verts, planes, faces, loops, edges, tris, bvh, shape_of, rank, ia, ib, swap, kk,
                  a, b, pos, R, margin, reach, floor, plane_margin, counters):
    """The narrow phase of a batch in one compiled call: the pairs grouped by type pair
    (``dispatch.group_by_type``), each group through its kernel (``call``), then the contact
    columns (``dispatch.contact_columns``).

    ``which = which_table()``; the geometry arrays as ``GeomTable.arrays()``, ``bvh = trees(geom)``;
    ``ia, ib, swap (K,)`` the batch and ``kk (M,)`` its kept pairs, ``a, b (M,)`` their bodies in the
    kernels' order (``bounding.kept_pairs``). Each pair's margin is ``margin`` (``plane_margin`` with
    a plane), or with ``reach (2,N)`` (empty: none) ``min(margin, floor + reach[0, a] + reach[0,
    b])``, with a plane ``min(plane_margin, floor + reach[1, a] + reach[1, b])``: how far its two
    bodies can close (``prepare.speculative_reach``), so that a pair at rest beside a fast body does
    not take candidates it cannot reach into its manifold. Returns ``(rows_i (R, 3), rows_f (R, 7),
    body_a (R,), body_b (R,), normal (R, 3), colliding pairs, unsupported pairs)``: the kernels' rows
    (``rows_i[:, 0]`` indexing ``kk``), the columns of ``contact_columns``, and the number of pairs
    no kernel takes (plane–plane pairs are no contacts)."""
    M = a.shape[0]
    out_i, out_f = np.empty((4 * M, 3), np.int64), np.empty((4 * M, 7))
    n, unsupported = 0, 0
    if M > 0:
        order, A, B, starts, keys = group_by_type(a, b, rank, NRANK)
        margins = np.empty(M)
        for i in range(M):
            if rank[B[i]] == PLANE:   # (a plane is always B: the lower rank) the bodies' whole reach
                margins[i] = plane_margin if reach.shape[1] == 0 else \
                    min(plane_margin, floor + reach[1, A[i]] + reach[1, B[i]])
            else:
                margins[i] = margin if reach.shape[1] == 0 else min(margin, floor + reach[0, A[i]] + reach[0, B[i]])
        for g in range(keys.shape[0]):
            s, e = starts[g], starts[g + 1]
            w = which[keys[g]]
            if w < 0:
                if keys[g] != 0:   # plane–plane pairs are no contacts
                    unsupported += e - s
                continue
            m = call(w, sf, si, verts, planes, faces, loops, edges, tris, shape_of, A[s:e], B[s:e], pos, R, margins[s:e],
                     counters, out_i[n:], out_f[n:], bvh)
            for r in range(n, n + m):
                out_i[r, 0] = order[out_i[r, 0] + s]
            n += m
    rows_i, rows_f = out_i[:n], out_f[:n]
    body_a, body_b, normal, pairs = contact_columns(rows_i, rows_f, kk, ia, ib, swap)
    return rows_i, rows_f, body_a, body_b, normal, pairs, unsupported
