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
from .vec3 import counting_order

# shape type -> rank; kernels take A with the higher rank (so a plane or sphere is always B)
# (a cylinder is a convex prism for the generic kernels, with exact kernels against planes and spheres)
RANK = {"plane": 0, "sphere": 1, "box": 2, "convex": 3, "cylinder": 4, "mesh": 5}
PLANE, SPHERE, BOX, CONVEX, CYLINDER, MESH = 0, 1, 2, 3, 4, 5
NRANK = 6           # pair keys are rank A * NRANK + rank B

# float columns of sf
SF_PLANE = 0        # plane normal (3) and offset (1)
SF_RADIUS = 4      # sphere and cylinder radius
SF_HALF = 5         # box half sizes (3); a cylinder's half length at SF_HALF + 2
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
        lo_k, hi_k = v[0, k], v[0, k]
        for i in range(nv):
            lo_k, hi_k = min(lo_k, v[i, k]), max(hi_k, v[i, k])
        scale = max(scale, hi_k - lo_k)
    tri_plane = np.empty(nt, np.int64)
    for t in range(nt):
        if not convex:
            tri_plane[t] = t
            continue
        fo = fn[t, 0] * v[f[t, 0], 0] + fn[t, 1] * v[f[t, 0], 1] + fn[t, 2] * v[f[t, 0], 2]
        tri_plane[t] = -1
        # merged planes are numbered in order of their first triangle: try the next new plane and
        # the last one matched first (a hull of distinct faces matches in one test), then all
        last = tri_plane[t - 1] if t > 0 else -1
        for k in range(npl + 2):
            p = last + 1 if k == 0 else (last if k == 1 else k - 2)
            if p < 0 or p >= npl:
                continue
            if (fn[t, 0] * pn[p, 0] + fn[t, 1] * pn[p, 1] + fn[t, 2] * pn[p, 2] > 1 - 1e-9
                    and abs(fo - pd[p]) < 1e-9 * scale):
                tri_plane[t] = p
                break
        if tri_plane[t] < 0:
            return -1, -1
    # face loops: the plane's vertices (ascending index), ordered by angle about their mean
    # (scalar code and insertion sorts on scratch arrays: faces have a handful of vertices)
    by_plane = np.empty(nt, np.int64)
    counting_order(tri_plane, npl, by_plane)
    stamp = -np.ones(nv, np.int64)
    ids = np.empty(nv, np.int64)
    ang = np.empty(nv)
    nl = 0
    k = 0
    for p in range(npl):
        if (k + 1 == nt or tri_plane[by_plane[k + 1]] != p) and k < nt and tri_plane[by_plane[k]] == p:
            # a face of one triangle: its winding is already counter-clockwise about its normal
            # (the face normal is computed from the winding, and the plane is that normal)
            t = by_plane[k]
            faces[p, 0], faces[p, 1] = nl, 3
            loops[nl], loops[nl + 1], loops[nl + 2] = f[t, 0], f[t, 1], f[t, 2]
            nl += 3
            k += 1
            continue
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
        for i in range(1, m):
            x, j = ids[i], i - 1
            while j >= 0 and ids[j] > x:
                ids[j + 1] = ids[j]
                j -= 1
            ids[j + 1] = x
        mx, my, mz = 0.0, 0.0, 0.0
        for j in range(m):
            mx, my, mz = mx + v[ids[j], 0], my + v[ids[j], 1], mz + v[ids[j], 2]
        mx, my, mz = mx / m, my / m, mz / m
        nx, ny, nz = pn[p, 0], pn[p, 1], pn[p, 2]
        ux, uy, uz = v[ids[0], 0] - mx, v[ids[0], 1] - my, v[ids[0], 2] - mz
        if np.sqrt(ux * ux + uy * uy + uz * uz) < 1e-15:
            if abs(nx) < 0.9:      # n × x
                ux, uy, uz = 0.0, nz, -ny
            else:                  # n × y
                ux, uy, uz = -nz, 0.0, nx
        un = ux * nx + uy * ny + uz * nz
        ux, uy, uz = ux - nx * un, uy - ny * un, uz - nz * un
        ul = np.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / ul, uy / ul, uz / ul
        wx, wy, wz = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
        for j in range(m):
            rx, ry, rz = v[ids[j], 0] - mx, v[ids[j], 1] - my, v[ids[j], 2] - mz
            ang[j] = np.arctan2(rx * wx + ry * wy + rz * wz, rx * ux + ry * uy + rz * uz)
        for i in range(1, m):     # stable insertion sort of the loop by angle
            x, y, j = ang[i], ids[i], i - 1
            while j >= 0 and ang[j] > x:
                ang[j + 1], ids[j + 1] = ang[j], ids[j]
                j -= 1
            ang[j + 1], ids[j + 1] = x, y
        faces[p, 0], faces[p, 1] = nl, m
        for j in range(m):
            loops[nl + j] = ids[j]
        nl += m
    # edges: the 3T directed edges as (low, high) keys, stable-sorted, grouped
    key = np.empty(3 * nt, np.int64)
    for s in range(3):
        for t in range(nt):
            a, b = f[t, s], f[t, (s + 1) % 3]
            key[s * nt + t] = min(a, b) * nv + max(a, b)
    # stable sort by (low, high): two counting passes (least significant first)
    part, hi, order = np.empty(3 * nt, np.int64), np.empty(3 * nt, np.int64), np.empty(3 * nt, np.int64)
    for i in range(3 * nt):
        hi[i] = key[i] % nv
    counting_order(hi, nv, part)
    lo = np.empty(3 * nt, np.int64)
    for i in range(3 * nt):
        lo[i] = key[part[i]] // nv
    counting_order(lo, nv, order)
    for i in range(3 * nt):
        order[i] = part[order[i]]
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


class _InBatch:
    """A shape's prepared geometry as row ``k`` of a preparation batch: the ``ShapeGeom`` is cut
    out of the batch only when asked for (a world built from new shapes uses the batch whole)."""

    __slots__ = ("batch", "k", "_geom")

    def __init__(self, batch, k):
        self.batch, self.k, self._geom = batch, k, None

    def __getattr__(self, name):
        # only the geometry's fields come here (a copy without its slots set must not recurse)
        if name not in ShapeGeom.__slots__:
            raise AttributeError(name)
        if self._geom is None:
            todo, SF, SI, verts, planes, faces, loops, edges, tris = self.batch
            k, g = self.k, ShapeGeom()
            v0, nv, p0, npl, t0, nt, ne = (int(SI[k, c]) for c in (SI_V0, SI_NV, SI_P0, SI_NP, SI_T0, SI_NT, SI_NE))
            g.sf, g.si = SF[k].copy(), SI[k].copy()
            g.si[[SI_V0, SI_P0, SI_E0, SI_T0, SI_L0]] = 0
            g.verts, g.planes, g.tris = verts[v0:v0 + nv], planes[p0:p0 + npl], tris[t0:t0 + nt]
            g.faces = faces[p0:p0 + npl].copy()
            g.faces[:, 0] -= 3 * t0
            g.loops = loops[3 * t0:3 * t0 + 3 * nt]
            g.edges = edges[3 * t0:3 * t0 + ne]
            self._geom = g
        return getattr(self._geom, name)


_NONE_F3, _NONE_F4 = np.zeros((0, 3)), np.zeros((0, 4))
_NONE_I, _NONE_I2, _NONE_I3, _NONE_I4 = (np.zeros((0,) + s, np.int64) for s in ((), (2,), (3,), (4,)))


def _primitive(shape):
    g = ShapeGeom()
    g.sf, g.si = np.zeros(NSF), np.zeros(NSI, np.int64)
    g.si[SI_RANK] = RANK[shape.type]
    # shared empty arrays (never written): a sphere or plane has no polyhedron geometry
    g.verts, g.planes, g.faces, g.loops, g.edges, g.tris = _NONE_F3, _NONE_F4, _NONE_I2, _NONE_I, _NONE_I4, _NONE_I3
    if shape.type == "plane":
        g.sf[SF_PLANE:SF_PLANE + 3], g.sf[SF_PLANE + 3] = shape.normal, shape.offset
    else:
        r = shape.radius
        g.sf[SF_RADIUS] = r
        g.sf[SF_SPHERE + 3] = r * (1 + 1e-12) + 1e-15
        g.sf[SF_BOX + 3:SF_BOX + 6] = r
        g.sf[SF_SCALE] = 2 * r
    return g


@njit
def _prepare_batch(vs, verts, ts, tris, fnorm, ps, pnorm, poff, convex, loops, faces, edges, counts, fl):
    """``_prepare_one`` for shapes ``s`` whose vertices are ``verts[vs[s]:vs[s+1]]``, triangles
    (and normals) ``tris[ts[s]:ts[s+1]]``, planes ``pnorm/poff[ps[s]:ps[s+1]]``: loops, faces and
    edges at the same offsets (loops and edges sized 3 per triangle); ``counts (S, 2)`` loop and
    edge counts (-1: a triangle on no plane); ``fl (S, 14)`` bounding sphere (4), AABB centre and
    half sizes (6), scale (the largest extent), centroid (3)."""
    for s in range(vs.shape[0] - 1):
        v = verts[vs[s]:vs[s + 1]]
        t0, t1, p0, p1 = ts[s], ts[s + 1], ps[s], ps[s + 1]
        nl, ne = _prepare_one(v, tris[t0:t1], fnorm[t0:t1], pnorm[p0:p1], poff[p0:p1], convex[s],
                              loops[3 * t0:3 * t1], faces[p0:p1], edges[3 * t0:3 * t1])
        counts[s, 0], counts[s, 1] = nl, ne
        c, r = bounding_sphere_kernel(v)
        fl[s, 0], fl[s, 1], fl[s, 2], fl[s, 3] = c[0], c[1], c[2], r
        for k in range(3):
            lo, hi, tot = v[0, k], v[0, k], 0.0
            for i in range(v.shape[0]):
                lo, hi, tot = min(lo, v[i, k]), max(hi, v[i, k]), tot + v[i, k]
            fl[s, 4 + k], fl[s, 7 + k] = 0.5 * (lo + hi), 0.5 * (hi - lo)
            fl[s, 11 + k] = tot / v.shape[0]
        fl[s, 10] = max(max(fl[s, 7], fl[s, 8], fl[s, 9]) * 2.0, 1e-12)


def prepare_shapes(shapes):
    """Prepare (and cache on each shape) the geometry of ``shapes`` that lack it: one compiled pass
    over all new polyhedra."""
    todo, seen = [], set()
    for s in shapes:
        if getattr(s, "_cs_geom", None) is None and id(s) not in seen:
            seen.add(id(s))
            if s.type in ("plane", "sphere"):
                s._cs_geom = _primitive(s)
            else:
                todo.append(s)
    if not todo:
        return None
    V = [np.asarray(s.vertices, float) for s in todo]
    T = [np.asarray(s.faces, np.int64) for s in todo]
    FN = [np.asarray(s.face_normals, float) for s in todo]
    convex = np.array([bool(getattr(s, "convex", True)) for s in todo])
    PN, PD = [], []
    for s, v, f, fn, cv in zip(todo, V, T, FN, convex):
        if cv:
            PN.append(np.asarray(s.plane_normals, float))
            PD.append(np.asarray(s.plane_offsets, float))
        else:
            PN.append(fn)
            PD.append(np.einsum("ij,ij->i", fn, v[f[:, 0]]))
    offs = [np.concatenate([[0], np.cumsum([len(x) for x in X])]).astype(np.int64) for X in (V, T, PN)]
    vs, ts, ps = offs
    tris, fn = np.concatenate(T), np.concatenate(FN)
    pn, pd = np.concatenate(PN), np.concatenate(PD)
    nt = len(tris)
    loops, edges = np.empty(3 * nt, np.int64), np.empty((3 * nt, 4), np.int64)
    faces = np.empty((len(pn), 2), np.int64)
    counts, fl = np.empty((len(todo), 2), np.int64), np.empty((len(todo), 14))
    verts = np.concatenate(V)
    _prepare_batch(vs, verts, ts, tris, fn, ps, pn, pd, convex, loops, faces, edges, counts, fl)
    planes = np.column_stack([pn, pd])
    bad = np.flatnonzero(counts[:, 0] < 0)
    if bad.size:
        raise ContactSimError(f"{todo[int(bad[0])]!r}: a face does not lie on any hull plane")
    S = len(todo)
    SF, SI = np.zeros((S, NSF)), np.zeros((S, NSI), np.int64)
    SI[:, SI_RANK] = [RANK[s.type] for s in todo]
    SI[:, SI_NV], SI[:, SI_NP], SI[:, SI_NE], SI[:, SI_NT] = np.diff(vs), np.diff(ps), counts[:, 1], np.diff(ts)
    SI[:, SI_CLOSED] = [bool(s.watertight) if s.type == "mesh" else 1 for s in todo]
    SF[:, SF_SPHERE:SF_SPHERE + 4], SF[:, SF_BOX:SF_BOX + 6] = fl[:, 0:4], fl[:, 4:10]
    SF[:, SF_SCALE], SF[:, SF_CENTROID:SF_CENTROID + 3] = fl[:, 10], fl[:, 11:14]
    for k, s in enumerate(todo):
        if s.type == "box":
            SF[k, SF_HALF:SF_HALF + 3] = s.half
        elif s.type == "cylinder":
            SF[k, SF_RADIUS], SF[k, SF_HALF + 2] = s.radius, 0.5 * s.length
    # the batch as a table of its own (loops and edges keep their slack of 3 per triangle)
    SI[:, SI_V0], SI[:, SI_P0], SI[:, SI_T0] = vs[:-1], ps[:-1], ts[:-1]
    SI[:, SI_E0] = SI[:, SI_L0] = 3 * ts[:-1]
    faces_t = faces.copy()
    faces_t[:, 0] += np.repeat(3 * ts[:-1], np.diff(ps))
    batch = (todo, SF, SI, verts, planes, faces_t, loops, edges, tris)
    for k, s in enumerate(todo):
        s._cs_geom = _InBatch(batch, k)
    return batch


class GeomTable:
    """The geometry of a list of shapes, stacked (see the module docstring). ``shape_of (N,)`` maps
    each input position to its row (a shape object given several times is stored once)."""

    def __init__(self, shapes):
        batch = prepare_shapes(shapes)
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
        polys = [s for s in uniq if s.type not in ("plane", "sphere")]
        if batch is not None and len(batch[0]) == len(polys):
            self._from_batch(uniq, batch)    # every polyhedron was new: its batch is the table
            return
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

    def _from_batch(self, uniq, batch):
        todo, SF, SI, self.verts, self.planes, self.faces, self.loops, self.edges, self.tris = batch
        S = len(uniq)
        poly = np.array([s.type not in ("plane", "sphere") for s in uniq], bool)
        self.sf, self.si = np.zeros((S, NSF)), np.zeros((S, NSI), np.int64)
        self.sf[poly], self.si[poly] = SF, SI     # batch order = order of first appearance
        for k in np.flatnonzero(~poly):
            self.sf[k], self.si[k] = uniq[k]._cs_geom.sf, uniq[k]._cs_geom.si

    def arrays(self):
        """The arrays every kernel takes first, in the kernels' order."""
        return self.sf, self.si, self.verts, self.planes, self.faces, self.loops, self.edges, self.tris
