"""The narrow phase, by concern (this module only gathers the names older code imports):

- ``dispatch``: the table of kernels keyed by shape-type pair, one signature for all;
- ``primitives``: pairs with a sphere or a plane (exact closest points);
- ``polyhedra``: convex polyhedron pairs (SAT with Gauss-map pruning);
- ``manifold``: the face–face patch and the reduction to at most 4 points;
- ``meshes``: triangle mesh against sphere and convex polyhedron (ray-parity inside-ness, closest
  points on triangles);
- ``mesh_mesh``: concave against concave, over per-mesh AABB trees;
- ``inside``: the lecture's vertex-inside tests by name (``vertex_inside``).
"""
from .manifold import F_EDGE, F_FACE, F_PLANE, F_SPHERE, F_SWEPT, F_VERTEX, TOUCH_TOLERANCE  # noqa: F401
from .meshes import RAYS as _RAYS, points_in_meshes  # noqa: F401
