"""Contacts as a structure of arrays (one row per contact point), and the feature-id encoding.

``feature_id (K,) int64`` names a contact point *within its pair* by the features of the two shapes
that make it (Box2D's contact ids), so the same point keeps its id from one step to the next while
the same features touch, so a caller can key per-point data (its own warm starts, a contact's
history) on ``(body_a, body_b, feature_id)``. The engine's own warm start does not use it: it matches
contacts by pair and by the point in body A's frame (``response/cache.py``). Ids are
unique within a pair in one detection. An id packs four fields (``fid(kind, x, y, z)``, read back
by ``split_fid``): ``kind`` 3 bits (60–62), ``x`` and ``y`` 20 bits each (40–59, 20–39), ``z`` 20
bits (0–19). "A" and "B" are the narrow-phase kernel's sides: A is the shape of higher rank
(plane < sphere < box < convex < cylinder < mesh), whichever of ``body_a``/``body_b`` that is; for a given pair
of bodies the sides never change, so neither do the ids.

| kind | contact | x | y | z |
|---|---|---|---|---|
| 0 ``FID_POINT`` | a pair with a sphere (one point) | 0 | 0 | 0 |
| 1 ``FID_PLANE`` | polyhedron or mesh vertex on a plane | vertex of A | 0 | 0 |
| 2 / 3 ``FID_FACE_A`` / ``+1`` | face–face patch, reference face on A / on B | reference face | incident face | point code |
| 4 ``FID_EDGE`` | edge–edge (the SAT's edge axis) | edge of A | edge of B | 0 |
| 5 ``FID_MESH_VERTEX`` | polyhedron B's vertex against mesh A | vertex of B | nearest triangle of A | 0 |
| 6 ``FID_POLY_VERTEX`` | mesh A's vertex inside polyhedron B | vertex of A | face of B | 0 |
| 7 ``FID_CROSSING`` | an edge of one crossing a face of the other (mesh pairs) | edge | face | 0: B's edge in A's face, 1: the reverse |

Face and edge indices are the shape's merged face planes and real edges (``collision.geometry``);
vertices are the shape's vertex indices. The point code of a face patch says what the point is:
``0 << 18 | v`` incident vertex ``v``; ``1 << 18 | m << 9 | q`` the crossing of the reference face's
``m``-th loop edge with the incident face's ``q``-th; ``2 << 18 | v`` reference vertex ``v``
(carried onto the incident face); ``3 << 18 | v`` the incident body's deepest vertex (deep
overlaps only). Faces with more than 512 vertices and shapes with more than 2^18 vertices or 2^20
faces alias (ids then may repeat within a pair).
"""
from dataclasses import dataclass, field, fields

import numpy as np

from .jit import njit

FEATURES = ("vertex_face", "edge_face", "face_face", "swept", "sphere", "plane")
"""What produced a contact: ``Contacts.feature`` indexes this tuple. ``vertex_face``: one vertex against
a face (a one-point patch, a vertex inside a mesh or a polyhedron); ``edge_face``: an edge against a face
(a two-point patch, an edge crossing a mesh face) or an edge–edge contact; ``face_face``: a point of a
face–face patch of three or more points; ``swept``: found by the swept-volume time of impact;
``sphere``: a pair with a sphere; ``plane``: a shape's point on a plane."""

FID_POINT, FID_PLANE, FID_FACE_A, FID_FACE_B, FID_EDGE, FID_MESH_VERTEX, FID_POLY_VERTEX, FID_CROSSING = range(8)
_MASK20 = (1 << 20) - 1


@njit
def fid(kind, x, y, z):
    """The feature id of fields ``kind`` (0–7) and ``x``, ``y``, ``z`` (each 0 to 2^20 − 1)."""
    return (kind << 60) | ((x & _MASK20) << 40) | ((y & _MASK20) << 20) | (z & _MASK20)


def split_fid(ids):
    """``(kind, x, y, z)`` arrays of feature ids ``(K,)``."""
    ids = np.asarray(ids, np.int64)
    return ids >> 60, (ids >> 40) & _MASK20, (ids >> 20) & _MASK20, ids & _MASK20


def _f(shape):
    return field(default_factory=lambda: np.zeros(shape))


@dataclass
class Contacts:
    """Contact points of one detection or step.

    ``body_a, body_b (K,) int`` index ``World.body_names``; ``point (K, 3)`` world position;
    ``normal (K, 3)`` unit, from B to A; ``depth (K,)`` > 0 when penetrating; ``impulse (K, 3)``
    total impulse applied to A during the step (B received its negative), split into
    ``normal_impulse (K,)`` (along ``normal``) and ``friction_impulse (K, 3)`` (tangential);
    ``relative_normal_velocity (K,)`` is ``n·(ṗ_A − ṗ_B)`` before the response (< 0 approaching);
    ``feature (K,) int`` indexes ``FEATURES``; ``feature_id (K,) int64`` names the point within its
    pair, stable across steps while the same features touch (module docstring).
    """

    body_a: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    body_b: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    point: np.ndarray = _f((0, 3))
    normal: np.ndarray = _f((0, 3))
    depth: np.ndarray = _f((0,))
    impulse: np.ndarray = _f((0, 3))
    normal_impulse: np.ndarray = _f((0,))
    friction_impulse: np.ndarray = _f((0, 3))
    relative_normal_velocity: np.ndarray = _f((0,))
    feature: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    feature_id: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def __len__(self):
        return len(self.depth)

    @classmethod
    def empty(cls):
        """No contacts (zero-length columns, shared by every empty ``Contacts``)."""
        return cls(*_EMPTY)

    def select(self, mask):
        """A new ``Contacts`` with the rows picked by a boolean mask ``(K,)`` or an index array."""
        rows = np.asarray(mask)
        if rows.dtype == bool:
            if rows.shape != (len(self),):
                raise IndexError(f"Contacts.select: a mask of shape {rows.shape} for {len(self)} contacts")
            rows = np.flatnonzero(rows)
        # ``take`` of the row indices: the same rows as indexing by the mask, at a quarter of its cost
        return Contacts(*[getattr(self, n).take(rows, axis=0) for n in COLUMNS])

    @classmethod
    def concat(cls, parts):
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls()
        return cls(*[np.concatenate([getattr(p, n) for p in parts]) for n in COLUMNS])


#: the column names in field order (``dataclasses.fields`` costs more than a step's selection)
COLUMNS = tuple(f.name for f in fields(Contacts))
# zero-length columns of every empty ``Contacts`` (no element to write; not flagged read-only, which
# compiled kernels would type apart)
_EMPTY = tuple(getattr(Contacts(), n) for n in COLUMNS)
