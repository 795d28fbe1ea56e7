"""The narrow-phase table (``dispatch.TABLE``) callable from compiled code: ``call(which, ...)``.

Compiled code cannot look a kernel up in a dict, and a kernel handed to a compiled function as an
argument breaks numba's on-disk cache (its index pickles the argument's type, a reference to the
kernel that a later process cannot restore). So the table's distinct kernels are listed here in a
fixed order, ``index(ra, rb)`` maps a type pair to its place through ``dispatch.TABLE`` itself,
and ``call`` branches on that place. A test checks that the list is exactly the table's kernels.
Used by the compiled time-of-impact search (``response.advancement``) for the distance of a pair.
"""
from ..jit import njit
from . import dispatch
from .cylinders import cylinder_plane, cylinder_sphere
from .mesh_mesh import mesh_mesh, table_bvh
from .meshes import mesh_poly, mesh_sphere
from .polyhedra import poly_poly
from .primitives import box_sphere, poly_plane, poly_sphere, sphere_plane, sphere_sphere

#: the table's kernels, in the order ``call`` branches on
KERNELS = (sphere_plane, sphere_sphere, poly_plane, box_sphere, poly_poly, poly_sphere, cylinder_plane,
           cylinder_sphere, mesh_sphere, mesh_poly, mesh_mesh)


def index(ra, rb):
    """The place in ``KERNELS`` of the kernel of ranks ``ra >= rb`` (``dispatch.kernel_for``), −1
    when no kernel takes the pair (plane–plane)."""
    kernel = dispatch.kernel_for(ra, rb)
    return -1 if kernel is None else KERNELS.index(kernel)


def trees(geom):
    """The extra arrays ``call`` passes to the mesh–mesh kernel (``mesh_mesh.table_bvh``)."""
    return table_bvh(geom)


@njit
def call(which, sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin, counters, out_i,
         out_f, bvh):
    """``KERNELS[which]`` with the kernel signature (``dispatch``), ``bvh = trees(geom)`` for
    mesh–mesh; returns the rows written (0 for ``which`` −1)."""
    if which == 0:
        return sphere_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                            counters, out_i, out_f)
    if which == 1:
        return sphere_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                             counters, out_i, out_f)
    if which == 2:
        return poly_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                          counters, out_i, out_f)
    if which == 3:
        return box_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                          counters, out_i, out_f)
    if which == 4:
        return poly_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                         counters, out_i, out_f)
    if which == 5:
        return poly_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                           counters, out_i, out_f)
    if which == 6:
        return cylinder_plane(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                              counters, out_i, out_f)
    if which == 7:
        return cylinder_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                               counters, out_i, out_f)
    if which == 8:
        return mesh_sphere(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                           counters, out_i, out_f)
    if which == 9:
        return mesh_poly(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                         counters, out_i, out_f)
    if which == 10:
        return mesh_mesh(sf, si, verts, planes, faces, loops, edges, tris, shape_of, a, b, pos, R, margin,
                         counters, out_i, out_f, bvh[0], bvh[1], bvh[2], bvh[3], bvh[4])
    return 0
