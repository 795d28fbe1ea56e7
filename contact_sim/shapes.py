"""Collision shapes, their validation and their mass properties.

A shape lives in its body's frame. Polyhedral shapes (box, convex, mesh) carry their geometry as
arrays computed once here: vertices ``(V, 3)``, triangles ``(F, 3)`` int, unique edges ``(E, 2)``
int, and (convex shapes) the merged face planes ``normals (P, 3)``, ``offsets (P,)`` with
``normals @ x <= offsets`` inside. Bounding volumes are derived from the same arrays.
"""
import numpy as np

from .errors import ContactSimError
from .validate import (LENGTH, OFFSET, PLANE_OFFSET, POINTS, REACH, SCALE, THINNEST, Rows, Vector,
                       numbers_array, show)

_TINY = 1e-12


class Shape:
    """Base class. ``type`` is the key of the shape in scenes and in the narrow-phase table."""

    type = "shape"
    finite = True
    convex = True         # a plane (its half-space), a sphere, a box, a hull; a mesh says
    size_field = "size"   # the argument that sets the shape's size, named when it is out of bounds

    def mass_properties(self, density):
        """``(mass, center_of_mass (3,), inertia (3, 3) about the center of mass)`` for a density."""
        raise NotImplementedError

    def thinnest(self):
        """Smallest extent of the shape (m): how far it may move in a step before it can tunnel."""
        raise NotImplementedError

    def sizes(self):
        """``(thinnest, reach)`` in m: the smallest thickness the world must resolve, and the
        farthest point of the shape from its origin."""
        raise NotImplementedError

    def check_fits(self, settings, path):
        """Refuse (``BoundsError`` naming ``path``) a shape outside the world's size bounds:
        thinner than ``settings.min_size`` or reaching farther than ``settings.max_size``."""
        thin, reach = self.sizes()
        THINNEST.check(thin, f"{path}.{self.size_field} (thickness)", settings)
        REACH.check(reach, f"{path}.{self.size_field} (reach from the origin)", settings)


class Plane(Shape):
    """Half-space ``{x : normal·x <= offset}`` in the body frame; ``normal·P - offset`` is the signed distance."""

    type = "plane"
    finite = False

    def __init__(self, normal=(0.0, 0.0, 1.0), offset=0.0, *, name="plane"):
        n = Vector(3).check(normal, f"{name}.normal")
        big = float(np.abs(n).max())
        length = big * float(np.linalg.norm(n / big)) if big > 0 else 0.0   # no overflow for huge entries
        if length < _TINY:
            raise ContactSimError(f"{name}.normal: must be non-zero, got {n.tolist()}")
        off = OFFSET.check(offset, f"{name}.offset")
        self.normal = n / length
        self.offset = off / length

    def mass_properties(self, density):
        raise ContactSimError("plane: a half-space has no finite mass; use kind static or kinematic")

    def thinnest(self):
        return np.inf

    def check_fits(self, settings, path):
        """A plane has no size; its offset places it, within ``settings.max_position``."""
        PLANE_OFFSET.check(self.offset, f"{path}.offset", settings)

    def __repr__(self):
        return f"Plane(normal={self.normal.tolist()}, offset={self.offset})"


class Sphere(Shape):
    """A sphere of ``radius`` (m), centred on the body origin."""

    type = "sphere"
    size_field = "radius"

    def __init__(self, radius, *, name="sphere"):
        self.radius = LENGTH.check(radius, f"{name}.radius")

    def mass_properties(self, density):
        r = self.radius
        m = density * 4.0 / 3.0 * np.pi * r**3
        return m, np.zeros(3), np.eye(3) * (0.4 * m * r * r)

    def thinnest(self):
        return 2.0 * self.radius

    def sizes(self):
        return 2.0 * self.radius, self.radius

    def aabb_local(self):
        return -np.full(3, self.radius), np.full(3, self.radius)

    def __repr__(self):
        return f"Sphere(radius={self.radius})"


def _unique_edges(faces):
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    return np.unique(e, axis=0)


class Polyhedron(Shape):
    """Shared geometry of box, convex and mesh shapes (see the module docstring for the arrays)."""

    def _set_geometry(self, vertices, faces):
        self.vertices = np.ascontiguousarray(vertices, dtype=float)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.edges = _unique_edges(self.faces)
        tri = self.vertices[self.faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.face_normals = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        if self.convex:
            self._merge_planes()

    def _merge_planes(self):
        # coplanar triangles share one plane: merge them so the vertex-inside test uses each face once
        offs = np.einsum("ij,ij->i", self.face_normals, self.vertices[self.faces[:, 0]])
        key = np.round(np.column_stack([self.face_normals, offs / self.scale_hint]), 9)
        _, first = np.unique(key, axis=0, return_index=True)
        first.sort()
        self.plane_normals = self.face_normals[first]
        self.plane_offsets = offs[first]

    @property
    def scale_hint(self):
        return max(float(np.ptp(self.vertices, axis=0).max()), _TINY)

    def aabb_local(self):
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def translated(self, offset):
        """A copy moved by ``offset (3,)`` (puts a body's origin at its centre of mass). Geometry is
        shifted, not recomputed: no second qhull run, faces and normals shared."""
        import copy

        off = np.asarray(offset, float)
        out = copy.copy(self)
        out.vertices = self.vertices + off
        if self.convex:
            out.plane_offsets = self.plane_offsets + self.plane_normals @ off
        for attr in ("_hull", "_mesh"):
            if hasattr(self, attr):
                setattr(out, attr, getattr(self, attr).copy().apply_translation(off))
        for cached in ("_cs_bounds", "_cs_geom"):   # bounding volumes and prepared geometry are cached per
            out.__dict__.pop(cached, None)          # shape: the copy builds its own
        return out

    def with_slabs(self, normals, name="shape"):
        """Set the bounding-slab directions ``(K, 3)`` (each a plane-pair normal) used when the
        bounding volume is ``slabs``; returns ``self``."""
        n = Rows(3).check(normals, f"{name}.slab_normals", min_rows=1, what="normals")
        big = np.abs(n).max(axis=1)
        n[big >= 1e150] /= big[big >= 1e150, None]   # directions: scaled first, so their squares stay finite
        length = np.linalg.norm(n, axis=1)
        if np.any(length < _TINY):
            raise ContactSimError(f"{name}.slab_normals: normal {int(np.argmin(length))} is zero")
        self.slab_normals = n / length[:, None]
        self.__dict__.pop("_cs_bounds", None)
        return self

    def thinnest(self):
        if self.convex:
            # width of a convex body: smallest distance between a face plane and the farthest vertex
            support = (self.vertices @ self.plane_normals.T).max(axis=0)
            depth = support - (self.vertices @ self.plane_normals.T).min(axis=0)
            return float(depth.min())
        lo, hi = self.aabb_local()
        return float((hi - lo).min())

    def sizes(self):
        # an open mesh may be flat (a static floor): its largest extent is what must be resolved
        thin = self.thinnest() if self.convex or self.watertight else float(np.ptp(self.vertices, axis=0).max())
        return thin, float(np.linalg.norm(self.vertices, axis=1).max())


class Box(Polyhedron):
    """Box of full edge lengths ``size (3,)`` centred on the body origin (as URDF/SDF)."""

    type = "box"

    def __init__(self, size, *, name="box"):
        s = Vector(3).check(size, f"{name}.size")
        if np.any(s <= 0):
            raise ContactSimError(f"{name}.size: every edge length must be > 0, got {s.tolist()}")
        for x in s:
            LENGTH.check(x, f"{name}.size")
        self.size = s
        self.half = 0.5 * s
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        verts = corners * self.half
        # 12 outward-wound triangles
        faces = np.array(
            [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
        )
        self._set_geometry(verts, faces)

    def mass_properties(self, density):
        a, b, c = self.size
        m = density * a * b * c
        return m, np.zeros(3), np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * (m / 12.0)

    def thinnest(self):
        return float(self.size.min())

    def __repr__(self):
        return f"Box(size={self.size.tolist()})"


def _check_points(points, what, min_count):
    """``(N, 3)`` finite points, N >= ``min_count``, within the engine's length range."""
    return POINTS.check(points, what, min_rows=min_count, what="points")


def _load_mesh(path, what):
    import os

    import trimesh

    if not os.path.isfile(path):
        raise ContactSimError(f"{what}: no such file {str(path)!r}")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise ContactSimError(f"{what}: cannot read mesh {str(path)!r}: {exc}") from None
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)


class Convex(Polyhedron):
    """Convex polyhedron: the convex hull (trimesh/qhull) of ``points (N, 3)``, N ≥ 4, not coplanar."""

    type = "convex"
    size_field = "points"

    def __init__(self, points, *, name="convex"):
        import trimesh

        p = _check_points(points, f"{name}.points", 4)
        centred = p - p.mean(axis=0)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[-1] <= 1e-9 * max(sv[0], _TINY):
            raise ContactSimError(
                f"{name}.points: all {len(p)} points are coplanar or collinear; a convex solid needs "
                "4 points not in one plane"
            )
        try:
            with np.errstate(all="ignore"):   # a collapsing hull divides by its zero volume; refused below
                hull = trimesh.convex.convex_hull(p)
                volume = float(hull.volume) if len(hull.faces) >= 4 else 0.0
        except Exception as exc:  # qhull refuses some near-degenerate sets; trimesh raises many types
            raise ContactSimError(f"{name}.points: no convex hull: {exc}") from None
        if len(hull.vertices) < 4 or len(hull.faces) < 4 or not volume > 0:
            # trimesh merges vertices closer than its tolerance (1e-8 m): tiny point sets collapse
            span = float(np.ptp(p, axis=0).max())
            raise ContactSimError(
                f"{name}.points: their convex hull is degenerate ({len(hull.vertices)} vertices, volume {volume:.3g}); "
                f"the points span only {span:.3g} m (vertices closer than 1e-8 m merge)")
        self._hull = hull
        self._set_geometry(hull.vertices, hull.faces)

    @classmethod
    def from_file(cls, path, scale=1.0, *, name="convex"):
        scale = SCALE.check(scale, f"{name}.scale")
        verts, _ = _load_mesh(path, f"{name}.file")
        return cls(_check_points(verts, f"{name}.file", 4) * scale, name=name)

    def mass_properties(self, density):
        mp = self._hull.mass_properties  # volume, center_mass, inertia (about the centre of mass)
        m = density * mp["volume"]
        return m, np.asarray(mp["center_mass"], float), np.asarray(mp["inertia"], float) * density


    def __repr__(self):
        return f"Convex({len(self.vertices)} vertices, {len(self.plane_normals)} faces)"


class TriMesh(Polyhedron):
    """Triangle mesh, concave allowed: ``vertices (V, 3)``, ``faces (F, 3)`` int.

    Static and kinematic bodies may use any mesh with faces; a dynamic body needs a closed
    (watertight) mesh so that its mass properties exist.
    """

    type = "mesh"
    convex = False
    size_field = "vertices"

    def __init__(self, vertices, faces, *, name="mesh"):
        import trimesh

        v = _check_points(vertices, f"{name}.vertices", 3)
        f = numbers_array(faces, f"{name}.faces", "a list of [i, j, k] vertex indices")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ContactSimError(f"{name}.faces: must be a non-empty (F, 3) array of indices, got shape {f.shape}")
        if not (np.isfinite(f).all() and np.all(f == np.floor(f))):
            bad = int(np.flatnonzero(~(np.isfinite(f) & (f == np.floor(f))).all(axis=1))[0])
            raise ContactSimError(f"{name}.faces: face {bad} has an index that is not a whole number: "
                                  f"{show(f[bad])}")
        if f.min() < 0 or f.max() >= len(v):
            raise ContactSimError(f"{name}.faces: indices must be in [0, {len(v) - 1}], "
                                  f"got {f.min():.0f}..{f.max():.0f}")
        f = f.astype(np.int64)
        tri = v[f]
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        scale = max(float(np.ptp(v, axis=0).max()), _TINY)
        keep = area2 > 1e-12 * scale * scale
        if not np.ptp(v, axis=0).any():
            raise ContactSimError(f"{name}.vertices: all {len(v)} vertices are the same point {v[0].tolist()}")
        if not keep.any():
            raise ContactSimError(f"{name}.faces: every triangle has zero area")
        f = f[keep]  # degenerate slivers carry no surface; dropping them keeps normals finite
        self._mesh = trimesh.Trimesh(v, f, process=False)
        self._set_geometry(v, f)

    @classmethod
    def from_file(cls, path, scale=1.0, *, name="mesh"):
        scale = SCALE.check(scale, f"{name}.scale")
        verts, faces = _load_mesh(path, f"{name}.file")
        return cls(_check_points(verts, f"{name}.file", 3) * scale, faces, name=name)

    @property
    def watertight(self):
        return bool(self._mesh.is_watertight)

    def thinnest(self):
        # an open mesh (terrain, a floor tile) is a one-sided surface: everything behind it is inside
        # (see collision.meshes), so, like a plane, it has no far side for a body to pass out of
        return super().thinnest() if self.watertight else np.inf

    def mass_properties(self, density):
        if not self.watertight:
            raise ContactSimError("mesh is not closed (watertight), so it has no volume or inertia; "
                                  "make the body static or kinematic, or use a convex shape")
        mp = self._mesh.mass_properties
        if mp["volume"] <= 0:
            raise ContactSimError("mesh faces wind inwards (negative volume); flip them")
        m = density * mp["volume"]
        return m, np.asarray(mp["center_mass"], float), np.asarray(mp["inertia"], float) * density


    def __repr__(self):
        return f"TriMesh({len(self.vertices)} vertices, {len(self.faces)} faces)"
