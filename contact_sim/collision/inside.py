"""The lecture's vertex-inside test, by name: ``vertex_inside(points, polyhedron, pose)``.

* A vertex is inside a **convex** polyhedron iff it is on the inside of every face plane
  (``n·x ≤ d`` for each merged face plane ``(n, d)``): ``plane_excess`` / ``outside_plane``, the
  compiled helpers the convex narrow-phase kernels call (``polyhedra.face_query``, the mesh kernels'
  vertex tests).
* A vertex is inside a **concave** polyhedron (a closed ``TriMesh``) iff a semi-infinite ray from it
  crosses an odd number of faces: ``parity_inside``, the compiled kernel the mesh kernels
  call (three generic rays; a ray grazing an edge or vertex gives way to the next).

A point on the boundary counts as inside for the convex test (``≤``); for the parity test a point
within round-off of a face may go either way (it is touching, not penetrating).
"""
import numpy as np

from ..errors import ContactSimError
from ..jit import njit
from ..shapes import Shape
from ..validate import ANY_ORIENTATION, COORDINATES, POINTS
from .geometry import prepare_shapes


# rays for the parity test: generic directions, so a ray through an edge or vertex is rare; when
# one is (a barycentric coordinate or the distance within a tolerance of 0) the next ray decides
_R = np.array([[0.5773, 0.3141, 0.7537], [-0.2718, 0.8414, -0.4667], [0.6931, -0.6180, 0.3711]])
RAYS = _R / np.linalg.norm(_R, axis=1, keepdims=True)


@njit
def ray_triangle(px, py, pz, rx, ry, rz, V, i0, i1, i2, eps):
    """The ray ``p + t r`` (t > 0) against the triangle of rows ``i0, i1, i2`` of ``V (n, 3)``
    (Möller–Trumbore): ``1`` when it crosses, plus ``2`` when it grazes an edge or vertex or starts
    on the triangle (within ``eps``), where the parity cannot be trusted."""
    e1x, e1y, e1z = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]
    e2x, e2y, e2z = V[i2, 0] - V[i0, 0], V[i2, 1] - V[i0, 1], V[i2, 2] - V[i0, 2]
    hx, hy, hz = ry * e2z - rz * e2y, rz * e2x - rx * e2z, rx * e2y - ry * e2x
    det = e1x * hx + e1y * hy + e1z * hz
    if not abs(det) > 1e-14:
        return 0
    inv = 1.0 / det
    sx, sy, sz = px - V[i0, 0], py - V[i0, 1], pz - V[i0, 2]
    u = (sx * hx + sy * hy + sz * hz) * inv
    qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
    v = (qx * rx + qy * ry + qz * rz) * inv
    tt = (e2x * qx + e2y * qy + e2z * qz) * inv
    w = 1.0 - u - v
    hit = tt > 0 and u >= 0 and v >= 0 and w >= 0
    bad = (tt > -eps and (abs(u) < eps or abs(v) < eps or abs(w) < eps) and u > -eps and v > -eps
           and w > -eps) or (hit and abs(tt) < eps * (np.sqrt(abs(det)) + 1e-300))
    return (1 if hit else 0) + (2 if bad else 0)


@njit
def parity_inside(p, V, tris, t0, nt, eps=1e-9):
    """Odd ray-crossing parity of point ``p (3,)`` against triangles ``tris[t0:t0+nt]`` of vertices
    ``V`` (any one frame); rays that graze an edge or vertex are discarded in favour of the next
    (when all three graze, the majority vote of their parities)."""
    votes = 0
    px, py, pz = p[0], p[1], p[2]
    for r in range(RAYS.shape[0]):
        rx, ry, rz = RAYS[r, 0], RAYS[r, 1], RAYS[r, 2]
        hits, bad = 0, False
        for t in range(nt):
            code = ray_triangle(px, py, pz, rx, ry, rz, V, tris[t0 + t, 0], tris[t0 + t, 1], tris[t0 + t, 2], eps)
            hits += code & 1
            bad |= code >= 2
        odd = hits % 2 == 1
        if not bad:
            return odd
        votes += odd
    return votes >= 2


@njit
def behind_open(px, py, pz, qx, qy, qz, V, tris, t0, nt, t):
    """Point ``p`` behind an open mesh (triangle rows ``t0 .. t0+nt`` of ``tris``, vertices ``V``)
    whose nearest point to it is ``q``, on triangle row ``t``: behind that triangle's plane, and not
    beside the rim. An open mesh is a sheet: a point whose nearest point lies on its rim (an edge
    only one triangle has, or a vertex on such an edge) and that is not over the triangle is beside
    the sheet, whatever side of the plane it is on, and its distance to the sheet is its distance to
    the rim. (Taken as behind, a box corner 0.25 m beyond a terrain's rim and 3 cm below its plane
    was 0.25 m deep, a contact that came and went with the margin.)"""
    i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
    ax, ay, az = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]
    bx, by, bz = V[i2, 0] - V[i0, 0], V[i2, 1] - V[i0, 1], V[i2, 2] - V[i0, 2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    dx, dy, dz = px - qx, py - qy, pz - qz
    s = dx * nx + dy * ny + dz * nz
    if not s < 0:
        return False
    # over the triangle: p - q along its normal (q the foot of the perpendicular); then not beside
    n2, d2 = nx * nx + ny * ny + nz * nz, dx * dx + dy * dy + dz * dz
    if d2 - s * s / n2 <= 1e-18 * d2:
        return True
    # q on an edge or a vertex of t: beside the rim when one of the edges it lies on is a rim edge
    scale = np.sqrt(max(ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz))
    on = np.zeros(3, np.bool_)   # q on vertex k of t
    for k in range(3):
        v = tris[t, k]
        on[k] = (V[v, 0] - qx) ** 2 + (V[v, 1] - qy) ** 2 + (V[v, 2] - qz) ** 2 <= (1e-9 * scale) ** 2
    for k in range(3):
        if on[k]:
            return not _rim_vertex(tris, t0, nt, tris[t, k])
    for k in range(3):   # q on the edge from vertex k to k+1: the one opposite the third vertex
        u, w = tris[t, k], tris[t, (k + 1) % 3]
        ex, ey, ez = V[w, 0] - V[u, 0], V[w, 1] - V[u, 1], V[w, 2] - V[u, 2]
        fx, fy, fz = qx - V[u, 0], qy - V[u, 1], qz - V[u, 2]
        cx, cy, cz = ey * fz - ez * fy, ez * fx - ex * fz, ex * fy - ey * fx
        if cx * cx + cy * cy + cz * cz <= (1e-9 * scale) ** 2 * (ex * ex + ey * ey + ez * ez):
            return _edge_uses(tris, t0, nt, u, w) > 1
    return True


@njit
def in_front(px, py, pz, qx, qy, qz, V, tris, t):
    """Point ``p`` in front of (or on) the plane of triangle row ``t`` of an open mesh, at its nearest
    point ``q`` on it. A body with a point behind an open mesh and none in front has gone through
    it; a point below the plane but beside the rim (``behind_open`` false) is neither, so a body
    under a terrain's rim, part under the sheet and part beyond it, has gone through too."""
    i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
    ax, ay, az = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]
    bx, by, bz = V[i2, 0] - V[i0, 0], V[i2, 1] - V[i0, 1], V[i2, 2] - V[i0, 2]
    return ((px - qx) * (ay * bz - az * by) + (py - qy) * (az * bx - ax * bz)
            + (pz - qz) * (ax * by - ay * bx)) >= 0


@njit
def _edge_uses(tris, t0, nt, u, w):
    """How many triangles of rows ``t0 .. t0+nt`` have the edge between vertices ``u`` and ``w``."""
    n = 0
    for t in range(t0, t0 + nt):
        hit = 0
        for k in range(3):
            if tris[t, k] == u or tris[t, k] == w:
                hit += 1
        n += hit == 2
    return n


@njit
def _rim_vertex(tris, t0, nt, v):
    """Vertex ``v`` lies on the rim: one of its edges has one triangle (an inner vertex's fan closes,
    as many edges as triangles; a rim vertex's is open, one edge more)."""
    for t in range(t0, t0 + nt):
        for k in range(3):
            if tris[t, k] == v:
                if _edge_uses(tris, t0, nt, v, tris[t, (k + 1) % 3]) == 1 or \
                        _edge_uses(tris, t0, nt, v, tris[t, (k + 2) % 3]) == 1:
                    return True
    return False


@njit
def plane_excess(N, d, npl, X, v):
    """``(max_p N[p]·X[v] − d[p], p)`` over the first ``npl`` planes: how far vertex ``v`` of
    ``X (n, 3)`` lies outside the convex polyhedron's deepest-violated face plane, and which one
    (``≤ 0``: inside every plane, so inside the polyhedron; the value is then minus the distance
    to the nearest face plane)."""
    m, pm = -np.inf, 0
    for p in range(npl):
        x = N[p, 0] * X[v, 0] + N[p, 1] * X[v, 1] + N[p, 2] * X[v, 2] - d[p]
        if x > m:
            m, pm = x, p
    return m, pm


@njit
def outside_plane(N, d, npl, X, v, first):
    """A face plane that vertex ``v`` of ``X (n, 3)`` is not strictly inside (``N[p]·x ≥ d[p]``), or
    −1 when it is inside every one. Plane ``first`` is tried first (the one that rejected the
    previous vertex usually rejects this one), then the others in order until one rejects it: the
    cheap form when only the verdict is needed."""
    if N[first, 0] * X[v, 0] + N[first, 1] * X[v, 1] + N[first, 2] * X[v, 2] - d[first] >= 0:
        return first
    for p in range(npl):
        if N[p, 0] * X[v, 0] + N[p, 1] * X[v, 1] + N[p, 2] * X[v, 2] - d[p] >= 0:
            return p
    return -1


@njit
def _vertex_inside_kernel(P, planes, npl, verts, tris, nt, convex, out):
    """``out[i]`` = point ``P[i]`` (shape frame) inside: every plane for a convex shape, ray parity
    over the triangles otherwise."""
    N = planes[:, :3]
    d = planes[:, 3]
    for i in range(P.shape[0]):
        if convex:
            out[i] = plane_excess(N, d, npl, P, i)[0] <= 0.0
        else:
            out[i] = parity_inside(P[i], verts, tris, 0, nt)
    return out


def vertex_inside(points, polyhedron, pose=None):
    """Which ``points (K, 3)`` (or one point ``(3,)``) lie inside ``polyhedron`` placed at ``pose``.

    ``polyhedron`` a ``cs.Box`` or ``cs.Convex`` (convex: inside every face plane, the boundary
    included) or a closed ``cs.TriMesh`` (concave allowed: odd ray-crossing parity); ``pose =
    (position (3,), orientation (4,) x, y, z, w)`` of the shape frame, identity when omitted.
    Returns ``(K,)`` bool (a bool for a single point). The narrow-phase kernels use the same
    compiled tests (``plane_excess`` / ``outside_plane`` and ``parity_inside``).
    Raises ``cs.ContactSimError`` for other shapes, an open mesh (it has no inside) or bad points.
    """
    if not isinstance(polyhedron, Shape) or polyhedron.type not in ("box", "convex", "mesh"):
        got = polyhedron.type if isinstance(polyhedron, Shape) else type(polyhedron).__name__
        raise ContactSimError(f"vertex_inside: polyhedron must be a Box, Convex or TriMesh, got {got}")
    if polyhedron.type == "mesh" and not polyhedron.watertight:
        raise ContactSimError("vertex_inside: polyhedron: an open mesh has no inside (close it, or use its "
                              "convex hull)")
    single = np.ndim(points) == 1
    P = COORDINATES.check(points, "vertex_inside: points")[None, :] if single else \
        POINTS.check(points, "vertex_inside: points", None, what="points")
    if pose is not None:
        try:
            p, q = pose
        except (TypeError, ValueError):
            raise ContactSimError(f"vertex_inside: pose: must be (position (3,), orientation (4,)), got {pose!r}") \
                from None
        p = COORDINATES.check(p, "vertex_inside: pose.position")
        q = ANY_ORIENTATION.check(q, "vertex_inside: pose.orientation")
        from ..quat import to_matrix
        P = (P - p) @ to_matrix(q)            # into the shape frame: Rᵀ (x − p), row-wise
    prepare_shapes([polyhedron])
    g = polyhedron._cs_geom
    convex = polyhedron.type != "mesh"
    out = np.empty(len(P), bool)
    _vertex_inside_kernel(np.ascontiguousarray(P, float), np.ascontiguousarray(g.planes), len(g.planes),
                          np.ascontiguousarray(g.verts), np.ascontiguousarray(g.tris), len(g.tris), convex, out)
    return bool(out[0]) if single else out
