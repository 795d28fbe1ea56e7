"""Shape geometry prepared once per shape, and the world's geometry table the kernels read.

Every kernel reads one ``GeomTable`` (MuJoCo's model, in miniature): per *shape* (bodies that share
a shape object share its row) a float row ``sf (S, NSF)`` and an int row ``si (S, NSI)`` (the
``SF_*``/``SI_*`` column constants below), and the polyhedra's geometry as flat arrays indexed by
the offsets in ``si``:

- ``verts (V, 3)`` object-space vertices;
- ``planes (P, 4)``: merged face planes ``n·x <= d`` inside (``n (3), d``); a mesh has one per
  triangle;
- ``faces (P, 2)``: each plane's face as a counter-clockwise loop (around the outward normal) of
  vertex indices: ``loops[faces[p, 0] : faces[p, 0] + faces[p, 1]]``;
- ``edges (E, 4)``: real edges ``v0, v1`` and the two planes they join (diagonals inside a merged
  face are dropped for convex shapes; a mesh keeps every edge);
- ``tris (T, 3)`` triangles.

Indices inside ``loops``, ``edges`` and ``tris`` are local to the shape (add ``si[s, SI_V0]``);
plane indices in ``edges`` are local too (add ``si[s, SI_P0]``).

Preparation is one compiled pass over all new shapes at once (``prepare_shapes``): planes of the
triangles, face loops, edges, bounding sphere (the lecture's construction), object AABB, centroid.
The result is cached on the shape (``shape._cs_geom``), so ``cs.collide`` in a loop prepares a shape
once; ``GeomTable`` only stacks cached rows.
"""
import numpy as np

from ..errors import ContactSimError
from ..jit import njit

# shape type -> rank; kernels take A with the higher rank (so a plane or sphere is always B)
RANK = {"plane": 0, "sphere": 1, "box": 2, "convex": 3, "mesh": 4}
PLANE, SPHERE, BOX, CONVEX, MESH = 0, 1, 2, 3, 4

# float columns of sf
SF_PLANE = 0        # plane normal (3) and offset (1)
SF_RADIUS = 4
SF_HALF = 5         # box half sizes (3)
SF_SPHERE = 8       # bounding sphere centre (3), radius (1)
SF_BOX = 12         # object AABB centre (3), half sizes (3)
SF_SCALE = 18       # largest extent: tolerances of a pair follow the smaller one's
SF_CENTROID = 19    # mean of the vertices (an interior point)
NSF = 22
# int columns of si
SI_RANK, SI_V0, SI_NV, SI_P0, SI_NP, SI_E0, SI_NE, SI_T0, SI_NT, SI_CLOSED, SI_L0 = range(11)
NSI = 11


@njit
def bounding_sphere_kernel(p):
    """The lecture's bounding sphere of ``p (V, 3)``: ``(centre (3,), radius)``. 1. the min/max pair of
    points along each axis; 2. the most separated pair is the first sphere; 3. every vertex in turn
    grows the sphere just enough to include it."""
    n = p.shape[0]
    best, c, r = -1.0, np.zeros(3), 0.0
    for ax in range(3):
        lo, hi = 0, 0
        for i in range(n):
            if p[i, ax] < p[lo, ax]:
                lo = i
            if p[i, ax] > p[hi, ax]:
                hi = i
        d = np.sqrt((p[hi, 0] - p[lo, 0]) ** 2 + (p[hi, 1] - p[lo, 1]) ** 2 + (p[hi, 2] - p[lo, 2]) ** 2)
        if d > best:
            best = d
            for k in range(3):
                c[k] = 0.5 * (p[hi, k] + p[lo, k])
            r = 0.5 * d
    for i in range(n):
        d = np.sqrt((p[i, 0] - c[0]) ** 2 + (p[i, 1] - c[1]) ** 2 + (p[i, 2] - c[2]) ** 2)
        if d > r:
            new_r = 0.5 * (r + d)
            f = (new_r - r) / d
            for k in range(3):
                c[k] += f * (p[i, k] - c[k])
            r = new_r
    for i in range(n):   # round-off guard: contain every vertex exactly as computed
        d = np.sqrt((p[i, 0] - c[0]) ** 2 + (p[i, 1] - c[1]) ** 2 + (p[i, 2] - c[2]) ** 2)
        r = max(r, d)
    return c, r * (1 + 1e-12) + 1e-15


@njit
def _prepare_one(v, f, fn, pn, pd, convex, loops, faces, edges):
    """Face loops ``faces (P, 2)`` into ``loops``, edges ``(E, 4)`` of one polyhedron; returns
    ``(loop count, edge count)``, or ``(-1, -1)`` when a triangle lies on no merged plane."""
    nv, nt, npl = v.shape[0], f.shape[0], pn.shape[0]
    scale = 1e-12
    for k in range(3):
        scale = max(scale, v[:, k].max() - v[:, k].min())
    tri_plane = np.empty(nt, np.int64)
    for t in range(nt):
        if not convex:
            tri_plane[t] = t
            continue
        fo = fn[t, 0] * v[f[t, 0], 0] + fn[t, 1] * v[f[t, 0], 1] + fn[t, 2] * v[f[t, 0], 2]
        tri_plane[t] = -1
        for p in range(npl):
            if (fn[t, 0] * pn[p, 0] + fn[t, 1] * pn[p, 1] + fn[t, 2] * pn[p, 2] > 1 - 1e-9
                    and abs(fo - pd[p]) < 1e-9 * scale):
                tri_plane[t] = p
                break
        if tri_plane[t] < 0:
            return -1, -1
    # face loops: the plane's vertices (ascending index), ordered by angle about their mean
    by_plane = np.argsort(tri_plane, kind="mergesort")
    stamp = np.full(nv, -1, np.int64)
    ids = np.empty(nv, np.int64)
    nl = 0
    k = 0
    for p in range(npl):
        m = 0
        while k < nt and tri_plane[by_plane[k]] == p:
            t = by_plane[k]
            for j in range(3):
                vi = f[t, j]
                if stamp[vi] != p:
                    stamp[vi] = p
                    ids[m] = vi
                    m += 1
            k += 1
        sel = np.sort(ids[:m])
        mean = np.zeros(3)
        for j in range(m):
            mean += v[sel[j]]
        mean /= m
        n = pn[p]
        u = v[sel[0]] - mean
        if np.sqrt(u @ u) < 1e-15:
            u = np.cross(n, np.array([1.0, 0, 0])) if abs(n[0]) < 0.9 else np.cross(n, np.array([0, 1.0, 0]))
        u = u - n * (u @ n)
        u /= np.sqrt(u @ u)
        w = np.cross(n, u)
        ang = np.empty(m)
        for j in range(m):
            rel = v[sel[j]] - mean
            ang[j] = np.arctan2(rel @ w, rel @ u)
        order = np.argsort(ang, kind="mergesort")
        faces[p, 0], faces[p, 1] = nl, m
        for j in range(m):
            loops[nl + j] = sel[order[j]]
        nl += m
    # edges: the 3T directed edges as (low, high) keys, stable-sorted, grouped
    key = np.empty(3 * nt, np.int64)
    for s in range(3):
        for t in range(nt):
            a, b = f[t, s], f[t, (s + 1) % 3]
            key[s * nt + t] = min(a, b) * nv + max(a, b)
    order = np.argsort(key, kind="mergesort")
    ne = 0
    i = 0
    while i < 3 * nt:
        j = i
        while j + 1 < 3 * nt and key[order[j + 1]] == key[order[i]]:
            j += 1
        pa, pb = tri_plane[order[i] % nt], tri_plane[order[j] % nt]
        if not convex or (j == i + 1 and pa != pb):
            edges[ne, 0], edges[ne, 1] = key[order[i]] // nv, key[order[i]] % nv
            edges[ne, 2], edges[ne, 3] = pa, pb
            ne += 1
        i = j + 1
    return nl, ne


class ShapeGeom:
    """Prepared geometry of one shape: ``sf (NSF,)``, ``si (NSI,)`` with zero offsets, and the
    polyhedron arrays (empty for spheres and planes)."""

    __slots__ = ("sf", "si", "verts", "planes", "faces", "loops", "edges", "tris")


def _primitive(shape):
    g = ShapeGeom()
    g.sf, g.si = np.zeros(NSF), np.zeros(NSI, np.int64)
    g.si[SI_RANK] = RANK[shape.type]
    g.verts, g.planes = np.zeros((0, 3)), np.zeros((0, 4))
    g.faces, g.loops = np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    g.edges, g.tris = np.zeros((0, 4), np.int64), np.zeros((0, 3), np.int64)
    if shape.type == "plane":
        g.sf[SF_PLANE:SF_PLANE + 3], g.sf[SF_PLANE + 3] = shape.normal, shape.offset
    else:
        r = shape.radius
        g.sf[SF_RADIUS] = r
        g.sf[SF_SPHERE + 3] = r * (1 + 1e-12) + 1e-15
        g.sf[SF_BOX + 3:SF_BOX + 6] = r
        g.sf[SF_SCALE] = 2 * r
    return g


def prepare_shapes(shapes):
    """Prepare (and cache on each shape) the geometry of ``shapes`` that lack it."""
    todo = [s for s in shapes if getattr(s, "_cs_geom", None) is None]
    for s in todo:
        if s.type in ("plane", "sphere"):
            s._cs_geom = _primitive(s)
            continue
        v = np.ascontiguousarray(s.vertices, float)
        f = np.ascontiguousarray(s.faces, np.int64)
        fn = np.ascontiguousarray(s.face_normals, float)
        convex = bool(getattr(s, "convex", True))
        if convex:
            pn, pd = np.ascontiguousarray(s.plane_normals, float), np.ascontiguousarray(s.plane_offsets, float)
        else:
            pn, pd = fn, np.einsum("ij,ij->i", fn, v[f[:, 0]])
        loops = np.empty(3 * len(f), np.int64)
        faces = np.empty((len(pn), 2), np.int64)
        edges = np.empty((3 * len(f), 4), np.int64)
        nl, ne = _prepare_one(v, f, fn, pn, pd, convex, loops, faces, edges)
        if nl < 0:
            raise ContactSimError(f"{s!r}: a face does not lie on any hull plane")
        g = ShapeGeom()
        g.verts, g.tris, g.faces, g.loops, g.edges = v, f, faces, loops[:nl], edges[:ne]
        g.planes = np.column_stack([pn, pd])
        g.sf, g.si = np.zeros(NSF), np.zeros(NSI, np.int64)
        g.si[SI_RANK] = RANK[s.type]
        g.si[SI_NV], g.si[SI_NP], g.si[SI_NE], g.si[SI_NT] = len(v), len(pn), ne, len(f)
        g.si[SI_CLOSED] = bool(s.watertight) if s.type == "mesh" else 1
        if s.type == "box":
            g.sf[SF_HALF:SF_HALF + 3] = s.half
        c, r = bounding_sphere_kernel(v)
        g.sf[SF_SPHERE:SF_SPHERE + 3], g.sf[SF_SPHERE + 3] = c, r
        lo, hi = v.min(axis=0), v.max(axis=0)
        g.sf[SF_BOX:SF_BOX + 3], g.sf[SF_BOX + 3:SF_BOX + 6] = 0.5 * (lo + hi), 0.5 * (hi - lo)
        g.sf[SF_SCALE] = max(float((hi - lo).max()), 1e-12)
        g.sf[SF_CENTROID:SF_CENTROID + 3] = v.mean(axis=0)
        s._cs_geom = g


class GeomTable:
    """The geometry of a list of shapes, stacked (see the module docstring). ``shape_of (N,)`` maps
    each input position to its row (a shape object given several times is stored once)."""

    def __init__(self, shapes):
        prepare_shapes(shapes)
        row, uniq = {}, []
        shape_of = np.empty(len(shapes), np.int64)
        for i, s in enumerate(shapes):
            k = row.get(id(s))
            if k is None:
                k = row[id(s)] = len(uniq)
                uniq.append(s)
            shape_of[i] = k
        self.shape_of = shape_of
        self.shapes = uniq
        gs = [s._cs_geom for s in uniq]
        self.sf = np.array([g.sf for g in gs]).reshape(len(gs), NSF)
        si = np.array([g.si for g in gs]).reshape(len(gs), NSI)
        for col, key in ((SI_V0, "verts"), (SI_P0, "planes"), (SI_E0, "edges"), (SI_T0, "tris"), (SI_L0, "loops")):
            counts = np.array([len(getattr(g, key)) for g in gs], np.int64)
            si[:, col] = np.cumsum(counts) - counts
        self.si = si

        def cat(key, empty):
            parts = [getattr(g, key) for g in gs if len(getattr(g, key))]
            return np.ascontiguousarray(np.concatenate(parts)) if parts else empty

        self.verts = cat("verts", np.zeros((1, 3)))
        self.planes = cat("planes", np.zeros((1, 4)))
        self.faces = cat("faces", np.zeros((1, 2), np.int64))
        self.loops = cat("loops", np.zeros(1, np.int64))
        self.edges = cat("edges", np.zeros((1, 4), np.int64))
        self.tris = cat("tris", np.zeros((1, 3), np.int64))
        # the face rows point into the stacked loops: add each shape's loop offset once here
        counts = si[:, SI_NP]
        if counts.sum():
            self.faces = self.faces.copy()
            self.faces[:, 0] += np.repeat(si[:, SI_L0], counts)

    def arrays(self):
        """The arrays every kernel takes first, in the kernels' order."""
        return self.sf, self.si, self.verts, self.planes, self.faces, self.loops, self.edges, self.tris
