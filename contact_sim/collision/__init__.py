"""Collision detection: broad phase → bounding volumes → narrow-phase batch kernels.

``detect_world(world, margin=None)`` returns every contact of the world's current state and a
``DetectionStats``; ``collide(shape_a, pose_a, shape_b, pose_b, margin=0.0)`` is the stateless
query for one pair and runs exactly the same stages and kernels on a two-body table.

Pipeline (cheapest test first, no Python loop over bodies, pairs or contacts):

1. broad phase: world AABBs (object AABB carried by the pose), paired by the cheapest exact
   method for the layout (``broadphase.candidate_pairs``: all pairs for a few bodies,
   sweep-and-prune while the sweep axis stays sparse, else a uniform hash grid: sorted cell keys
   + ``searchsorted`` over the 14 forward neighbour cells), kept across steps on fat boxes while no
   body leaves its fat box (``broadphase.PairCache``); planes against every AABB; static–static pairs and pairs whose
   ``group``/``mask`` bits exclude each other are dropped;
2. bounding volumes of the pair (``settings.bounding_volume``): ``sphere`` (the lecture's
   bounding sphere), ``aabb`` (world AABB = the broad phase itself), ``obb`` (object AABB
   carried by the pose, 15-axis test), ``slabs`` (per-shape slab normals, default 14-DOP),
   ``hull`` (face planes of the convex hull against the other's vertices / centre).
   ``auto`` = bounding sphere, then OBB: both are O(1) per pair and the OBB is exact for boxes,
   so together they reject most broad-phase survivors before any per-vertex work;
3. narrow phase: one batch kernel per shape-type pair (the table ``pair_kernels.COLLIDERS``;
   ``primitives``: pairs with a sphere or a plane, exact closest points; ``polyhedra``: convex
   pairs, SAT with Gauss-map pruning; ``manifold``: the face–face patch and its reduction to 4
   points; ``meshes``, ``mesh_mesh``: triangle meshes, ray-parity inside-ness and AABB trees;
   ``cylinders``; ``inside``: the lecture's vertex-inside tests by name), polyhedra in the
   lecture's order (vertex inside → edge–face) with the separating axis test for depth/normal.

Margin semantics: a pair whose separation is ≤ ``margin`` is reported, with ``depth =
-separation`` (negative when apart). The separation is the true distance for pairs with a
sphere or a plane and the separating-axis separation for two polyhedra (≤ the true distance,
exact at 0), so depth is continuous in the poses and exactly 0 when touching.
"""
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..contacts import Contacts
from ..errors import ContactSimError
from ..memo import derived
from ..settings import Settings
from ..shapes import Shape
from ..constants import LENGTH_LIMIT
from ..validate import (ANY_ORIENTATION, COORDINATES, DISTANCE, POINTS, POSITION, POSITIONS, Flag,
                        Nested, Rows, show)
from . import bounding, broadphase, pair_kernels, single
from .geometry import RANK, SF_BOX, SF_PLANE, SI_RANK, GeomTable
from .vec3 import rotations

from .inside import vertex_inside

__all__ = ["collide", "collide_pairs", "detect_world", "DetectionStats", "RANK", "vertex_inside"]



@dataclass
class DetectionStats:
    """Counts and timings of one detection.

    ``candidate_pairs``: pairs after the broad phase (and group/mask/static filters);
    ``rejected_by_bounding_volume``: of those, rejected by the bounding volumes;
    ``settled_by_vertex``: polyhedron pairs where a vertex of one is inside the other;
    ``needed_edge_face``: polyhedron pairs that got past the bounding volumes and the face-axis
    test with no vertex inside, so the edge–face test ran (``edge_face_hits`` of them crossed; None
    in a step's detection, ``World.last_detection``, which skips the test where it only counts:
    the polyhedra's separating-axis test decides their contacts);
    ``colliding_pairs``, ``contacts``: what was reported; ``unsupported_pairs``: pairs no
    kernel handles (none since mesh–mesh has one); ``seconds``: per stage (``broad``, ``bounding``,
    ``narrow``, ``total``). A step's detection (``World.last_detection``) is timed less: detected
    in Python (the first step, a pair cache rebuilt, a sub-step a time of impact may shorten) it
    has ``broad`` and ``total``, its bounding volumes and narrow phase run as one compiled call,
    untimed inside; run in the same compiled call as the sub-step's stages
    (``response.substep.run_detected``, most steps) only ``total``, that call's: detection and
    the stages together.
    """

    bodies: int = 0
    candidate_pairs: int = 0
    rejected_by_bounding_volume: int = 0
    settled_by_vertex: int = 0
    needed_edge_face: int = 0
    edge_face_hits: int | None = 0
    colliding_pairs: int = 0
    contacts: int = 0
    unsupported_pairs: int = 0
    bounding_volume: str = "auto"
    margin: float = 0.0
    seconds: dict = field(default_factory=dict)


class _Bodies:
    """Shape data of ``N`` bodies: the geometry table (``geometry.GeomTable``, one row per distinct
    shape object) and per-body arrays gathered from it; built once per shape list."""

    def __init__(self, shapes):
        self.n = len(shapes)
        self.geom = GeomTable(shapes)
        self.shape_of = self.geom.shape_of
        sf = self.geom.sf[self.shape_of]
        self.rank = self.geom.si[self.shape_of, SI_RANK]
        self.is_plane = self.rank == 0
        self.planes = np.flatnonzero(self.is_plane)
        self.finite = np.flatnonzero(~self.is_plane)
        # contiguous copies of the table's columns: the kernels that read them take C-ordered
        # arrays whatever the table's width (one compiled signature, not one per layout)
        cc = np.ascontiguousarray
        self.aabb_c, self.aabb_h = cc(sf[:, SF_BOX:SF_BOX + 3]), cc(sf[:, SF_BOX + 3:SF_BOX + 6])
        self.plane_n, self.plane_d = cc(sf[:, SF_PLANE:SF_PLANE + 3]), cc(sf[:, SF_PLANE + 3])
        self.pair_cache = broadphase.PairCache()   # broad-phase pairs carried across steps
        self.shapes = shapes
        self._narrow_args = None   # the narrow phase's fixed leading arguments (narrow_args)

    def narrow_args(self):
        """``pair_kernels.pair_contacts``' arguments that stay with the shapes: the type-pair
        table, the geometry arrays, the meshes' trees, ``shape_of`` and ``rank`` (built on first use)."""
        if self._narrow_args is None:
            g = self.geom
            self._narrow_args = (pair_kernels.which_table(), *g.arrays(), pair_kernels.trees(g), self.shape_of,
                                 self.rank)
        return self._narrow_args

    def volumes(self):
        """Slabs and hull planes per body (``bounding_volume`` slabs / hull only), built on first use."""
        if hasattr(self, "slab_n"):
            return
        bs = [bounding.bounds(s) if s.type != "plane" else None for s in self.shapes]
        n = self.n
        k = max([len(b.slab_n) for b in bs if b is not None] or [1])
        self.slab_n = np.tile(bounding.DEFAULT_SLAB_NORMALS[:1], (n, k, 1))
        self.slab_lo, self.slab_hi = np.full((n, k), -np.inf), np.full((n, k), np.inf)
        p = max([len(b.hull_n) for b in bs if b is not None] or [1])
        self.hull_n, self.hull_d = np.zeros((n, max(p, 1), 3)), np.full((n, max(p, 1)), np.inf)
        for i, b in enumerate(bs):
            if b is None:
                continue
            for arr, val in ((self.slab_n, b.slab_n), (self.slab_lo, b.slab_lo), (self.slab_hi, b.slab_hi)):
                pad_row(arr, i, val)
            if len(b.hull_n):
                pad_row(self.hull_n, i, b.hull_n)
                pad_row(self.hull_d, i, b.hull_d)


def pad_row(table, s, items):
    """``table[s]`` = ``items`` followed by copies of its first item (padding that repeats a real
    slab or plane never changes a min/max over the row)."""
    table[s, :len(items)] = items
    table[s, len(items):] = items[0]


def _bodies_of(world):
    """The world's shape arrays, built once and kept on the world itself (so they go with it),
    rebuilt when bodies are added (the shape list only grows)."""
    shapes = world.shapes
    n, last = len(shapes), shapes[-1] if shapes else None
    hit = world._derived.get("bodies")   # read every detection: identity checks, no closure
    if hit is None or hit[0] is not last or hit[1] != n:
        hit = world._derived["bodies"] = (last, n, _Bodies(shapes))
    return hit[2]


def _bv_keep(bodies, bv, a, b, pos, R, margin):
    """``(K,)`` bool: the pairs' bounding volumes overlap (within margin). ``auto`` = bounding
    sphere then OBB (compiled, one pass); ``aabb`` is the broad phase itself."""
    keep = np.ones(len(a), bool)
    if bv in COMPILED_VOLUMES:
        bounding.bv_filter(bv != "obb", bv != "sphere", a, b, bodies.shape_of, bodies.geom.sf, pos, R, margin, keep)
        return keep
    finite = ~bodies.is_plane[b] & ~((bodies.rank[a] == 1) & (bodies.rank[b] == 1))
    fi = np.flatnonzero(finite)
    if fi.size == 0 or bv == "aabb":
        return keep
    bodies.volumes()
    ia, ib = a[fi], b[fi]
    if bv == "slabs":
        ca = pos[ia] + np.einsum("nij,nj->ni", R[ia], bodies.aabb_c[ia])
        cb = pos[ib] + np.einsum("nij,nj->ni", R[ib], bodies.aabb_c[ib])
        ok = bounding.slab_overlap(bodies.slab_n[ia], bodies.slab_lo[ia], bodies.slab_hi[ia], pos[ia], R[ia],
                                   cb, R[ib], bodies.aabb_h[ib], margin)
        ok &= bounding.slab_overlap(bodies.slab_n[ib], bodies.slab_lo[ib], bodies.slab_hi[ib], pos[ib], R[ib],
                                    ca, R[ia], bodies.aabb_h[ia], margin)
    else:
        ok = _hull_overlap(bodies, ia, ib, pos, R, margin) & _hull_overlap(bodies, ib, ia, pos, R, margin)
    keep[fi] = ok
    return keep


def _hull_overlap(bodies, ia, ib, pos, R, margin):
    """Face planes of A's convex hull against B's bounding sphere (B a sphere) or OBB corners."""
    ok = np.ones(len(ia), bool)
    hp = np.flatnonzero(bodies.rank[ia] >= 2)
    if hp.size == 0:
        return ok
    a, b = ia[hp], ib[hp]
    hn, hd = bodies.hull_n[a], bodies.hull_d[a]
    nw = np.einsum("nij,npj->npi", R[a], hn)
    dw = hd + np.einsum("npi,ni->np", nw, pos[a])
    cb = pos[b] + np.einsum("nij,nj->ni", R[b], bodies.aabb_c[b])
    ext = np.einsum("npj,nj->np", np.abs(np.einsum("npi,nij->npj", nw, R[b])), bodies.aabb_h[b])
    low = np.einsum("npi,ni->np", nw, cb) - ext
    ok[hp] = np.all(low <= dw + margin, axis=1)
    return ok


_NO_REACH = np.zeros((2, 0))
#: the bounding volumes whose filter runs compiled with the narrow phase (``pair_kernels.kept_contacts``)
COMPILED_VOLUMES = ("auto", "sphere", "obb")
_NO_STAGES = {"bounding": 0.0, "narrow": 0.0}


def _detect(bodies, pos, quat, ia, ib, margin, bv, stats, t0, timings, R=None, reach=None, floor=0.0, timed=True,
            census=True, plane_margin=None):
    """Stages 2 and 3 for the pairs ``ia, ib (K,)``: ``(Contacts, stats)``; with ``reach (2,N)``
    each pair's narrow phase takes ``min(margin, floor + reach[0, a] + reach[0, b])``, a pair with a
    plane ``min(plane_margin, floor + reach[1, a] + reach[1, b])`` (``detect_world``).
    ``timed``: the two stages' seconds in ``stats.seconds`` (else the total only); ``census``: the
    edge–face crossings counted (``stats.edge_face_hits``, else None)."""
    if R is None:
        R = np.empty((len(quat), 3, 3))
        rotations(np.ascontiguousarray(quat, float), R)
    t1 = time.perf_counter()
    if len(ia) == 0:
        # no candidate pair (fewer than two bodies, or none near another): no kernel to run, and an
        # empty world's geometry table has no rows to type the kernels' arguments by
        stats.edge_face_hits = 0 if census else None
        stats.seconds = dict(timings, **(_NO_STAGES if timed else {}), total=time.perf_counter() - t0)
        return Contacts.empty(), stats
    ia, ib = np.ascontiguousarray(ia, np.int64), np.ascontiguousarray(ib, np.int64)
    counters = np.zeros(3 if census else 2, np.int64)
    reach = _NO_REACH if reach is None else reach
    plane_margin = margin if plane_margin is None else plane_margin
    if bv in COMPILED_VOLUMES:   # compiled: canonical order (A of the higher rank), filter, narrow phase
        seconds = np.zeros(2)
        rows_i, rows_f, body_a, body_b, normal, pairs, unsupported, kept = pair_kernels.kept_contacts(
            *bodies.narrow_args(), ia, ib, bv != "obb", bv != "sphere", pos, R, margin, reach, float(floor),
            float(plane_margin), counters, timed, seconds)
        if timed:
            timings["bounding"], timings["narrow"] = seconds.tolist()
    else:
        swap = bodies.rank[ia] < bodies.rank[ib]
        a, b = np.where(swap, ib, ia), np.where(swap, ia, ib)
        kk = np.flatnonzero(_bv_keep(bodies, bv, a, b, pos, R, margin))
        a, b, kept = a[kk], b[kk], len(kk)
        t2 = time.perf_counter()
        rows_i, rows_f, body_a, body_b, normal, pairs, unsupported = pair_kernels.pair_contacts(
            *bodies.narrow_args(), ia, ib, swap, kk, a, b, pos, R, margin, reach, float(floor), float(plane_margin),
            counters)
        timings["bounding"], timings["narrow"] = t2 - t1, time.perf_counter() - t2
    stats.rejected_by_bounding_volume = len(ia) - kept
    k = len(body_a)
    c = contacts_of_rows(rows_i, rows_f, body_a, body_b, normal)
    counts = counters.tolist()
    stats.settled_by_vertex, stats.needed_edge_face = counts[0], counts[1]
    stats.edge_face_hits = counts[2] if census else None
    stats.unsupported_pairs = unsupported
    stats.colliding_pairs = pairs
    stats.contacts = k
    timings["total"] = time.perf_counter() - t0
    stats.seconds = timings
    return c, stats


def contacts_of_rows(rows_i, rows_f, body_a, body_b, normal):
    """The narrow phase's rows (``pair_kernels.pair_contacts``' ``rows_i (K,3)``, ``rows_f (K,7)``
    and columns ``body_a, body_b (K,)``, ``normal (K,3)``) as ``Contacts``, the response's columns
    zero (the step fills them)."""
    k = len(body_a)
    vec, num = np.zeros((2, k, 3)), np.zeros((2, k))
    # positional, in ``COLUMNS`` order: body_a, body_b, point, normal, depth, impulse, normal_impulse,
    # friction_impulse, relative_normal_velocity, feature, feature_id
    return Contacts(body_a, body_b, rows_f[:, 0:3], normal, rows_f[:, 6], vec[0], num[0], vec[1], num[1],
                    rows_i[:, 1], rows_i[:, 2])


def disabled_keys(world):
    """``world.disabled_pairs`` as sorted keys ``min·N + max (E,)`` of body indices (cached until a
    body is added or removed, or the pairs change)."""
    def build():
        idx = world._index
        k = [min(idx[a], idx[b]) * len(world) + max(idx[a], idx[b]) for a, b in world.disabled_pairs
             if a in idx and b in idx]
        return np.unique(np.array(k, np.int64))

    return derived(world, "disabled_keys", (world.kind, world.disabled_pairs), build,
                   key=(len(world), len(world.disabled_pairs)))


def detect_world(world, margin=None, R=None, reach=None, floor=0.0, timed=True, horizon=0.0, census=True,
                 plane_margin=None):
    """All contacts of ``world``'s current state: ``(Contacts, DetectionStats)``.

    ``margin`` (m) overrides ``world.settings.contact_margin``: pairs closer than it are reported
    with ``depth = -separation`` (negative). ``body_a < body_b`` in every row; ``normal (K, 3)``
    points from ``body_b`` to ``body_a``. ``R (N, 3, 3)``: the bodies' rotation matrices, when the
    caller has them already (``vec3.rotations`` of ``world.s.quat``; the step shares them).
    ``reach (2,N)`` (m, the step's speculative contacts: ``prepare.speculative_reach``) narrows each
    pair's margin to ``min(margin, floor + reach[0, a] + reach[0, b])`` (capped reaches), a pair
    with a plane to ``min(plane_margin, floor + reach[1, a] + reach[1, b])`` (the bodies' whole
    reach); ``margin`` still finds the pairs, ``plane_margin`` (m, default ``margin``) the planes'.
    ``timed``: the seconds of each stage in the stats (the step's detection keeps the broad phase's
    and the total: its bounding volumes and narrow phase run as one compiled call, untimed inside).
    ``horizon`` (s): when the broad phase's pair cache is rebuilt, its fat boxes also cover each
    body's displacement over this time at its current velocity (the stepper's few steps ahead);
    the pairs found are the same whatever it is, only how often the cache is rebuilt changes.
    ``census``: count the edge–face crossings (``DetectionStats.edge_face_hits``; a step's
    detection does not: for polyhedra the test only counts, and costs a third of a resting box
    pair's narrow phase).
    """
    t0 = time.perf_counter()
    margin = float(world.settings.contact_margin if margin is None else margin)
    if not math.isfinite(margin) or margin < 0:
        raise ContactSimError(f"detect_world: margin must be a finite number >= 0, got {margin!r}")
    bv = world.settings.bounding_volume
    stats = DetectionStats(bodies=len(world.shapes), bounding_volume=bv, margin=margin)
    bodies = _bodies_of(world)
    timings = {"prepare": time.perf_counter() - t0}   # shape preparation: the first detection only
    pos, quat = world.s.pos, world.s.quat
    if bodies.n < 2:
        ia = ib = np.zeros(0, np.int64)
    else:
        if R is None:
            R = np.empty((bodies.n, 3, 3))
            rotations(quat, R)
        ia, ib = _world_pairs(world, bodies, pos, R, margin, horizon, plane_margin)
    timings["broad"] = time.perf_counter() - t0 - timings["prepare"]
    stats.candidate_pairs = len(ia)
    return _detect(bodies, pos, quat, ia, ib, margin, bv, stats, t0, timings, R, reach, floor, timed, census,
                   plane_margin)


def _world_pairs(world, bodies, pos, R, margin, horizon=0.0, plane_margin=None):
    """The broad phase of ``detect_world``: pairs ``(ia (K,), ib (K,))``, ``ia < ib``, sorted, whose
    world boxes overlap within ``margin`` (planes: whose half-space reaches the box within
    ``plane_margin``, default ``margin``), without the
    pairs that never collide (both static, group/mask, ``world.disabled_pairs``). One compiled pass
    (``broadphase.world_pairs``) while the pair cache holds; a rebuild of the cache first otherwise,
    its fat boxes stretched by each body's velocity × ``horizon`` (s)."""
    cache = bodies.pair_cache
    disabled = disabled_keys(world) if world.disabled_pairs else _NO_KEYS
    plane_margin = margin if plane_margin is None else plane_margin
    if cache.fat_c is not None:
        ok, ia, ib = _cached_pairs(world, bodies, pos, R, margin, plane_margin, disabled)
        if ok:
            cache.reuses += 1
            return ia, ib
    rebuild_pair_cache(world, bodies, pos, R, margin, horizon)
    # the fat boxes hold the boxes they were built from
    ok, ia, ib = _cached_pairs(world, bodies, pos, R, margin, plane_margin, disabled)
    assert ok
    return ia, ib


def rebuild_pair_cache(world, bodies, pos, R, margin, horizon):
    """The broad phase's pair cache built anew from the finite bodies' world boxes at ``pos (N,3)``,
    ``R (N,3,3)`` for pairs within ``margin`` (m), the fat boxes stretched by each body's velocity ×
    ``horizon`` (s; none at 0); with ``args``, the cache as the flight's kernel takes it
    (``PairCache``)."""
    fin = bodies.finite
    c, h = np.empty((len(fin), 3)), np.empty((len(fin), 3))
    broadphase.world_boxes(pos, R, fin, bodies.aabb_c, bodies.aabb_h, c, h)
    cache = bodies.pair_cache
    cache.rebuild(c, h, margin, world.s.vel[fin] if horizon else None, horizon)
    n_keys = len(cache.i) + len(bodies.planes) * len(fin)
    cache.args = (cache.fat_c, cache.fat_h, cache.i, cache.j, cache.margin, np.empty(max(n_keys, 64), np.int64))


def _cached_pairs(world, bodies, pos, R, margin, plane_margin, disabled):
    """``broadphase.world_pairs`` on the pair cache's fat boxes: ``(ok, ia, ib)``, ``ok`` False when
    a body left its fat box (the cache is then rebuilt)."""
    cache = bodies.pair_cache
    return broadphase.world_pairs(pos, R, bodies.finite, bodies.aabb_c, bodies.aabb_h, bodies.planes, bodies.plane_n,
                                  bodies.plane_d, cache.fat_c, cache.fat_h, cache.i, cache.j, cache.margin, margin,
                                  float(plane_margin), world.kind, world.group, world.mask, disabled)


_NO_KEYS = np.zeros(0, np.int64)


def _check_query(call, settings, margin, bounding_volume):
    """Settings, margin and bounding volume of a stateless query. With ``settings`` (a
    ``Settings`` or a mapping) its world bounds apply to positions, shape sizes and the margin, by
    the rules of a world; without, only what any world would refuse (non-finite values, lengths
    beyond ``LENGTH_LIMIT``), so internal callers (time-of-impact searches) pay no more."""
    st = None if settings is None else Nested(Settings).check(settings, f"{call}: settings")
    rule = Settings.rule("contact_margin") if st is not None else DISTANCE
    margin = rule.check(margin, f"{call}: margin", st)
    bounding_volume = Settings.rule("bounding_volume").check(bounding_volume, f"{call}: bounding_volume")
    return st, float(margin), bounding_volume


def _check_shape(shape, what, settings):
    if not isinstance(shape, Shape) or shape.type not in RANK:
        raise ContactSimError(f"{what}: must be a contact_sim shape, got {type(shape).__name__}")
    if settings is not None:
        shape.check_fits(settings, what)


def _check_pose(pose, what, settings):
    """``(position (3,), unit orientation (4,))`` from a pose; any non-zero quaternion is normalised."""
    try:
        p, q = pose
    except (TypeError, ValueError):
        raise ContactSimError(f"{what}: must be (position (3,), orientation (4,) x,y,z,w), got {pose!r}") from None
    rule = POSITION if settings is not None else COORDINATES
    return rule.check(p, f"{what}.position", settings), ANY_ORIENTATION.check(q, f"{what}.orientation", settings)


def collide(shape_a, pose_a, shape_b, pose_b, margin=0.0, bounding_volume="auto", stats=False, settings=None):
    """Contacts between two shapes (``Contacts`` with ``body_a = 0``, ``body_b = 1``).

    ``pose_* = (position (3,), orientation (4,) x,y,z,w)`` of the shape frame. ``normal (K, 3)``
    points from B to A; ``depth (K,)`` > 0 penetrating, ``-separation`` within ``margin``.
    Stateless; runs the same bounding-volume and kernel stages as ``detect_world``. With
    ``stats=True`` returns ``(Contacts, DetectionStats)``. Arguments are checked (finite, lengths
    within ``constants.LENGTH_LIMIT``); with ``settings`` (a ``Settings`` or a mapping) also against
    its world bounds (positions, shape sizes, margin), as a world would check them.
    """
    # the fast path (``single``) for plainly valid input; a margin that is plainly one is a float or
    # an int (not a bool, not a numpy number) within the limit
    if (settings is None and stats is False and bounding_volume == "auto" and type(margin) in single.NUMBER
            and 0 <= margin <= LENGTH_LIMIT):
        bodies = _cached_pair(shape_a, shape_b)   # (cached shapes were checked)
        if bodies is None and (isinstance(shape_a, Shape) and isinstance(shape_b, Shape) and shape_a.type in RANK
                               and shape_b.type in RANK):
            bodies = _bodies_cached((shape_a, shape_b))
        if bodies is not None:
            plan = bodies.__dict__.get("plan") or bodies.__dict__.setdefault("plan", single.PairPlan(bodies))
            c = single.collide_fast(plan, pose_a, pose_b, margin)
            if c is not None:
                return c
    t0 = time.perf_counter()   # (the stats' total: the fast path keeps none)
    st, margin, bounding_volume = _check_query("collide", settings, margin, bounding_volume)
    _check_shape(shape_a, "collide: shape_a", st)
    _check_shape(shape_b, "collide: shape_b", st)
    pa, qa = _check_pose(pose_a, "collide: pose_a", st)
    pb, qb = _check_pose(pose_b, "collide: pose_b", st)
    stats = Flag().check(stats, "collide: stats")
    bodies = _bodies_cached((shape_a, shape_b))
    st = DetectionStats(bodies=2, candidate_pairs=1, bounding_volume=bounding_volume, margin=margin)
    c, st = _detect(bodies, np.array([pa, pb]), np.array([qa, qb]), np.array([0]),
                    np.array([1]), margin, bounding_volume, st, t0, {"broad": 0.0})
    return (c, st) if stats else c


_PAIR_CACHE = {}


def _cached_pair(shape_a, shape_b):
    """The ``_Bodies`` of these two very shape objects when ``_bodies_cached`` holds them, else None."""
    hit = _PAIR_CACHE.get((id(shape_a), id(shape_b)))
    return hit[1] if hit is not None and hit[0][0] is shape_a and hit[0][1] is shape_b else None


def _bodies_cached(shapes):
    b = _cached_pair(*shapes)
    if b is not None:
        return b
    if len(_PAIR_CACHE) > 256:
        _PAIR_CACHE.clear()
    b = _Bodies(list(shapes))
    _PAIR_CACHE[id(shapes[0]), id(shapes[1])] = (shapes, b)
    return b


def collide_pairs(shapes, positions, orientations, pairs, margin=0.0, bounding_volume="auto", settings=None):
    """Contacts of many given pairs at once (no broad phase): ``(Contacts, DetectionStats)``.

    ``shapes`` list of N shapes (repeat the same object for identical bodies: its geometry is
    prepared once), ``positions (N, 3)``, ``orientations (N, 4)`` x,y,z,w (any non-zero length),
    ``pairs (K, 2)`` int. ``body_a``/``body_b`` of the result index ``shapes``. Same stages and
    kernels as ``collide``, and the same checks (world bounds only with ``settings``).
    """
    t0 = time.perf_counter()
    st, margin, bounding_volume = _check_query("collide_pairs", settings, margin, bounding_volume)
    if isinstance(shapes, Shape) or not isinstance(shapes, (list, tuple)):
        raise ContactSimError(f"collide_pairs: shapes must be a list of contact_sim shapes, got {type(shapes).__name__}")
    for i, s in enumerate(shapes):
        _check_shape(s, f"collide_pairs: shapes[{i}]", st)
    n = len(shapes)
    lengths = [len(v) if isinstance(v, (list, tuple)) or (isinstance(v, np.ndarray) and v.ndim) else None
               for v in (positions, orientations)]
    if None not in lengths and lengths != [n, n]:
        raise ContactSimError(f"collide_pairs: {n} shapes but {lengths[0]} positions and {lengths[1]} orientations")
    pos = (POSITIONS if st is not None else POINTS).check(positions, "collide_pairs: positions", st, count=n,
                                                          what="positions")
    q = ANY_ORIENTATION.check_rows(orientations, "collide_pairs: orientations", st, count=n)
    pairs = _check_pairs(pairs, n)
    bodies = _Bodies(list(shapes))
    stats = DetectionStats(bodies=n, candidate_pairs=len(pairs), bounding_volume=bounding_volume, margin=margin)
    return _detect(bodies, pos, q, pairs[:, 0], pairs[:, 1], margin, bounding_volume, stats, t0,
                   {"broad": 0.0})


def _check_pairs(pairs, n):
    """``(K, 2)`` int indices into ``n`` shapes, no pair of a shape with itself."""
    what = "collide_pairs: pairs"
    p = Rows(2).check(pairs, what, what="pairs")
    if not np.all(p == np.floor(p)):
        i = int(np.flatnonzero(np.any(p != np.floor(p), axis=1))[0])
        raise ContactSimError(f"{what}[{i}]: indices must be whole numbers, got {p[i].tolist()}")
    bad = np.flatnonzero(np.any((p < 0) | (p >= n), axis=1))
    if bad.size:
        i = int(bad[0])
        raise ContactSimError(f"{what}[{i}]: indices must be in [0, {n - 1}], got {show(p[i])}")
    same = np.flatnonzero(p[:, 0] == p[:, 1])
    if same.size:
        i = int(same[0])
        raise ContactSimError(f"{what}[{i}]: a shape cannot be paired with itself, got {show(p[i])}")
    return p.astype(np.int64)
