"""Object-space polyhedron geometry prepared once per shape, and padded tables for batch kernels.

A ``PolyGeom`` holds what the narrow phase needs of a box, convex hull or mesh:
``verts (V, 3)``, merged face planes ``plane_n (P, 3)``, ``plane_d (P,)`` (``n·x <= d`` inside),
each face as a counter-clockwise loop of vertex indices around its outward normal
``loops (P, M)`` (padded by repeating the last vertex, so padded edges have zero length),
real edges ``edges (E, 2)`` with the two planes they join ``edge_planes (E, 2)`` (diagonals inside
a merged face are dropped), triangles ``tris (F, 3)`` and an interior point ``centroid (3,)``.

A ``PolyTable`` stacks the geometry of several shapes padded to common sizes: vertices padded
with vertex 0, planes with plane 0, edges with edge 0 — all harmless for the min/max reductions
the kernels do.
"""
import numpy as np

from ..errors import ContactSimError


class PolyGeom:
    def __init__(self, shape):
        v = np.asarray(shape.vertices, float)
        f = np.asarray(shape.faces, np.int64)
        self.verts = v
        self.tris = f
        self.convex = bool(getattr(shape, "convex", True))
        scale = max(float(np.ptp(v, axis=0).max()), 1e-12)
        self.scale = scale
        fn = np.asarray(shape.face_normals, float)
        if self.convex:
            pn = np.asarray(shape.plane_normals, float)
            pd = np.asarray(shape.plane_offsets, float)
        else:
            pn = fn
            pd = np.einsum("ij,ij->i", fn, v[f[:, 0]])
        self.plane_n = pn
        self.plane_d = pd
        # triangle -> merged plane
        fo = np.einsum("ij,ij->i", fn, v[f[:, 0]])
        match = (fn @ pn.T > 1 - 1e-9) & (np.abs(fo[:, None] - pd[None, :]) < 1e-9 * scale)
        if self.convex:
            if not match.any(axis=1).all():
                raise ContactSimError(f"{shape!r}: a face does not lie on any hull plane")
            tri_plane = np.argmax(match, axis=1)
        else:
            tri_plane = np.arange(len(f))
        self.tri_plane = tri_plane
        # face loops, CCW around the outward normal
        loops = []
        for p in range(len(pn)):
            idx = np.unique(f[tri_plane == p])
            pts = v[idx]
            n = pn[p]
            u = pts[0] - pts.mean(axis=0)
            if np.linalg.norm(u) < 1e-15:
                u = np.cross(n, [1.0, 0, 0]) if abs(n[0]) < 0.9 else np.cross(n, [0, 1.0, 0])
            u = u - n * (u @ n)
            u /= np.linalg.norm(u)
            w = np.cross(n, u)
            rel = pts - pts.mean(axis=0)
            ang = np.arctan2(rel @ w, rel @ u)
            loops.append(idx[np.argsort(ang)])
        m = max(len(lp) for lp in loops)
        self.loops = np.array([np.concatenate([lp, np.full(m - len(lp), lp[-1])]) for lp in loops], np.int64)
        self.loop_count = np.array([len(lp) for lp in loops], np.int64)
        # edges and their adjacent planes
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        tp = np.concatenate([tri_plane, tri_plane, tri_plane])
        e.sort(axis=1)
        order = np.lexsort((e[:, 1], e[:, 0]))
        e, tp = e[order], tp[order]
        uniq, start, counts = np.unique(e, axis=0, return_index=True, return_counts=True)
        if self.convex:
            two = counts == 2
            pa = tp[start[two]]
            pb = tp[start[two] + 1]
            real = pa != pb
            self.edges = uniq[two][real]
            self.edge_planes = np.column_stack([pa[real], pb[real]])
        else:
            self.edges = uniq
            self.edge_planes = np.column_stack([tp[start], tp[start + counts - 1]])
        self.centroid = v.mean(axis=0)


def poly_geom(shape):
    """The cached ``PolyGeom`` of a box, convex or mesh shape."""
    g = getattr(shape, "_cs_geom", None)
    if g is None:
        g = PolyGeom(shape)
        shape._cs_geom = g
    return g


def pad_row(table, s, items):
    """``table[s]`` = ``items`` followed by copies of its first item (padding that repeats a real
    vertex, plane or edge never changes a min/max over the row)."""
    table[s, :len(items)] = items
    table[s, len(items):] = items[0]


class PolyTable:
    """Geometry of ``S`` shapes padded to common sizes: ``verts (S, V, 3)``, ``plane_n (S, P, 3)``,
    ``plane_d (S, P)``, ``loops (S, P, M)``, ``edges (S, E, 2)``, ``edge_planes (S, E, 2)``,
    ``centroid (S, 3)``, ``scale (S,)``, ``tris (S, F, 3)`` and ``tri_count (S,)``."""

    def __init__(self, geoms):
        S = len(geoms)
        V = max(len(g.verts) for g in geoms)
        P = max(len(g.plane_n) for g in geoms)
        M = max(g.loops.shape[1] for g in geoms)
        E = max(max(len(g.edges), 1) for g in geoms)
        F = max(len(g.tris) for g in geoms)
        self.verts = np.empty((S, V, 3))
        self.plane_n = np.empty((S, P, 3))
        self.plane_d = np.empty((S, P))
        self.loops = np.empty((S, P, M), np.int64)
        self.edges = np.zeros((S, E, 2), np.int64)
        self.edge_planes = np.zeros((S, E, 2), np.int64)
        self.tris = np.zeros((S, F, 3), np.int64)
        self.tri_count = np.array([len(g.tris) for g in geoms], np.int64)
        self.vert_count = np.array([len(g.verts) for g in geoms], np.int64)
        self.centroid = np.array([g.centroid for g in geoms]).reshape(S, 3)
        self.scale = np.array([g.scale for g in geoms])
        for s, g in enumerate(geoms):
            pad_row(self.verts, s, g.verts)
            pad_row(self.plane_n, s, g.plane_n)
            pad_row(self.plane_d, s, g.plane_d)
            lp = g.loops
            if lp.shape[1] < M:
                lp = np.concatenate([lp, np.repeat(lp[:, -1:], M - lp.shape[1], axis=1)], axis=1)
            pad_row(self.loops, s, lp)
            if len(g.edges):
                pad_row(self.edges, s, g.edges)
                pad_row(self.edge_planes, s, g.edge_planes)
            pad_row(self.tris, s, g.tris)
