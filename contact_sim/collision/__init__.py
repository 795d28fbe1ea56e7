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
3. narrow phase: one batch kernel per shape-type pair (``narrow.py``), polyhedra in the
   lecture's order (vertex inside → edge–face) with the separating axis test for depth/normal.

Margin semantics: a pair whose separation is ≤ ``margin`` is reported, with ``depth =
-separation`` (negative when apart). The separation is the true distance for pairs with a
sphere or a plane and the separating-axis separation for two polyhedra (≤ the true distance,
exact at 0), so depth is continuous in the poses and exactly 0 when touching.
"""
import time
from dataclasses import dataclass, field

import numpy as np

from .. import quat as Q
from ..contacts import Contacts
from ..errors import ContactSimError
from ..memo import derived
from ..settings import Settings
from ..shapes import Shape
from ..validate import (ANY_ORIENTATION, COORDINATES, DISTANCE, POINTS, POSITION, POSITIONS, Flag, Nested, Rows,
                        show)
from . import bounding, broadphase, narrow
from .geometry import PolyTable, pad_row, poly_geom

__all__ = ["collide", "collide_pairs", "detect_world", "DetectionStats", "RANK"]

# shape type -> rank; kernels take A with the higher rank (so a plane or sphere is always B)
RANK = {"plane": 0, "sphere": 1, "box": 2, "convex": 3, "mesh": 4}
_POLY = (2, 3, 4)


@dataclass
class DetectionStats:
    """Counts and timings of one detection.

    ``candidate_pairs``: pairs after the broad phase (and group/mask/static filters);
    ``rejected_by_bounding_volume``: of those, rejected by the bounding volumes;
    ``settled_by_vertex``: polyhedron pairs where a vertex of one is inside the other;
    ``needed_edge_face``: polyhedron pairs that got past the bounding volumes and the face-axis
    test with no vertex inside, so the edge–face test ran (``edge_face_hits`` of them crossed);
    ``colliding_pairs``, ``contacts``: what was reported; ``unsupported_pairs``: mesh–mesh
    pairs, skipped; ``seconds``: per stage (``broad``, ``bounding``, ``narrow``, ``total``).
    """

    bodies: int = 0
    candidate_pairs: int = 0
    rejected_by_bounding_volume: int = 0
    settled_by_vertex: int = 0
    needed_edge_face: int = 0
    edge_face_hits: int = 0
    colliding_pairs: int = 0
    contacts: int = 0
    unsupported_pairs: int = 0
    bounding_volume: str = "auto"
    margin: float = 0.0
    seconds: dict = field(default_factory=dict)


class _Bodies:
    """Shape data of ``N`` bodies as arrays (built once per shape list)."""

    def __init__(self, shapes):
        n = len(shapes)
        self.n = n
        self.rank = np.array([RANK[s.type] for s in shapes], np.int64)
        self.pair_cache = broadphase.PairCache()   # broad-phase pairs carried across steps
        self.plane_n = np.zeros((n, 3))
        self.plane_d = np.zeros(n)
        self.radius = np.zeros(n)
        self.half = np.zeros((n, 3))
        self.closed = np.zeros(n, bool)
        self.row = np.zeros(n, np.int64)
        self.tables = {}
        self.bv_c = np.zeros((n, 3))
        self.bv_r = np.zeros(n)
        self.aabb_c = np.zeros((n, 3))
        self.aabb_h = np.zeros((n, 3))
        for code in _POLY:
            idx = [i for i, s in enumerate(shapes) if RANK[s.type] == code]
            if idx:
                self.tables[code] = PolyTable([poly_geom(shapes[i]) for i in idx])
                self.row[idx] = np.arange(len(idx))
        slabs = []
        for i, s in enumerate(shapes):
            if s.type == "plane":
                self.plane_n[i], self.plane_d[i] = s.normal, s.offset
                slabs.append(None)
                continue
            if s.type == "sphere":
                self.radius[i] = s.radius
            if s.type == "box":
                self.half[i] = s.half
            if s.type == "mesh":
                self.closed[i] = s.watertight
            b = bounding.bounds(s)
            self.bv_c[i], self.bv_r[i] = b.sphere_c, b.sphere_r
            self.aabb_c[i], self.aabb_h[i] = 0.5 * (b.lo + b.hi), 0.5 * (b.hi - b.lo)
            slabs.append(b)
        k = max([len(b.slab_n) for b in slabs if b is not None] or [1])
        self.slab_n = np.tile(bounding.DEFAULT_SLAB_NORMALS[:1], (n, k, 1))
        self.slab_lo = np.full((n, k), -np.inf)
        self.slab_hi = np.full((n, k), np.inf)
        for i, b in enumerate(slabs):
            if b is not None:
                m = len(b.slab_n)
                self.slab_n[i, :m], self.slab_lo[i, :m], self.slab_hi[i, :m] = b.slab_n, b.slab_lo, b.slab_hi
                self.slab_n[i, m:], self.slab_lo[i, m:], self.slab_hi[i, m:] = b.slab_n[0], b.slab_lo[0], b.slab_hi[0]
        self.is_plane = self.rank == 0


def _bodies_of(world):
    """The world's shape arrays, built once and kept on the world itself (so they go with it),
    rebuilt when bodies are added (the shape list only grows)."""
    shapes = world.shapes
    return derived(world, "bodies", (shapes[-1] if shapes else None,), lambda: _Bodies(shapes), key=len(shapes))


def _bv_reject(bodies, bv, ia, ib, pos, R, margin):
    """``(K,)`` bool: the pair's bounding volumes overlap (within margin)."""
    ok = np.ones(len(ia), bool)
    if bv in ("auto", "sphere"):
        ca = pos[ia] + np.einsum("nij,nj->ni", R[ia], bodies.bv_c[ia])
        cb = pos[ib] + np.einsum("nij,nj->ni", R[ib], bodies.bv_c[ib])
        ok &= bounding.sphere_overlap(ca, bodies.bv_r[ia], cb, bodies.bv_r[ib], margin)
    if bv in ("auto", "obb") and ok.any():
        k = np.flatnonzero(ok)
        a, b = ia[k], ib[k]
        ca = pos[a] + np.einsum("nij,nj->ni", R[a], bodies.aabb_c[a])
        cb = pos[b] + np.einsum("nij,nj->ni", R[b], bodies.aabb_c[b])
        ok[k] = bounding.obb_overlap(ca, R[a], bodies.aabb_h[a], cb, R[b], bodies.aabb_h[b], margin)
    if bv == "slabs":
        ca = pos[ia] + np.einsum("nij,nj->ni", R[ia], bodies.aabb_c[ia])
        cb = pos[ib] + np.einsum("nij,nj->ni", R[ib], bodies.aabb_c[ib])
        ok &= bounding.slab_overlap(bodies.slab_n[ia], bodies.slab_lo[ia], bodies.slab_hi[ia], pos[ia], R[ia],
                                    cb, R[ib], bodies.aabb_h[ib], margin)
        ok &= bounding.slab_overlap(bodies.slab_n[ib], bodies.slab_lo[ib], bodies.slab_hi[ib], pos[ib], R[ib],
                                    ca, R[ia], bodies.aabb_h[ia], margin)
    if bv == "hull":
        ok &= _hull_overlap(bodies, ia, ib, pos, R, margin) & _hull_overlap(bodies, ib, ia, pos, R, margin)
    return ok


def _hull_overlap(bodies, ia, ib, pos, R, margin):
    """Face planes of A's convex hull against B's bounding sphere (B a sphere) or OBB corners."""
    ok = np.ones(len(ia), bool)
    hp = np.flatnonzero(np.isin(bodies.rank[ia], _POLY))
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


def _prepare_hulls(bodies, shapes):
    if hasattr(bodies, "hull_n"):
        return
    bs = [bounding.bounds(s) if s.type != "plane" else None for s in shapes]
    p = max([len(b.hull_n) for b in bs if b is not None] or [1])
    p = max(p, 1)
    bodies.hull_n = np.zeros((bodies.n, p, 3))
    bodies.hull_d = np.full((bodies.n, p), np.inf)
    for i, b in enumerate(bs):
        if b is not None and len(b.hull_n):
            pad_row(bodies.hull_n, i, b.hull_n)
            pad_row(bodies.hull_d, i, b.hull_d)


def _narrow(bodies, pos, R, a, b, margin, counters):
    """Contacts of pairs ``a, b (K,)`` already ordered so that ``rank[a] >= rank[b]``;
    returns kernel outputs with ``pair`` indexing ``a``."""
    out = []
    key = bodies.rank[a] * 5 + bodies.rank[b]
    unsupported = 0
    present = np.flatnonzero(np.bincount(key, minlength=25)) if len(key) else []
    for k in present:   # loop over the few shape-type pairs present
        # one type pair (the usual case): the whole batch, no gather
        sel = None if len(present) == 1 else np.flatnonzero(key == k)
        ta, tb = divmod(int(k), 5)
        A, B = (a, b) if len(present) == 1 else (a[sel], b[sel])
        pa, pb, Ra, Rb = pos[A], pos[B], R[A], R[B]
        if tb == 0:
            if ta == 0:
                continue
            nw = np.einsum("nij,nj->ni", Rb, bodies.plane_n[B])
            dw = bodies.plane_d[B] + np.einsum("ni,ni->n", nw, pb)
            if ta == 1:
                res = narrow.sphere_plane(pa, bodies.radius[A], nw, dw, margin)
            else:
                res = narrow.poly_plane(bodies.tables[ta], bodies.row[A], pa, Ra, nw, dw, margin)
        elif tb == 1:
            if ta == 1:
                res = narrow.sphere_sphere(pa, bodies.radius[A], pb, bodies.radius[B], margin)
            elif ta == 2:
                res = narrow.box_sphere(pa, Ra, bodies.half[A], pb, bodies.radius[B], margin)
            elif ta == 3:
                res = narrow.poly_sphere(bodies.tables[3], bodies.row[A], pa, Ra, pb, bodies.radius[B], margin)
            else:
                res = narrow.mesh_sphere(bodies.tables[4], bodies.row[A], pa, Ra, pb, bodies.radius[B], margin,
                                         bodies.closed[A])
        elif ta == 4:
            if tb == 4:
                unsupported += len(A)
                continue
            res = narrow.mesh_poly(bodies.tables[4], bodies.row[A], pa, Ra, bodies.closed[A],
                                   bodies.tables[tb], bodies.row[B], pb, Rb, margin, counters)
        else:
            res = narrow.poly_poly(bodies.tables[ta], bodies.row[A], pa, Ra, bodies.tables[tb], bodies.row[B],
                                   pb, Rb, margin, counters)
        pi, pt, nrm, dep, ft = res
        out.append((pi if sel is None else sel[pi], pt, nrm, dep, ft))
    if not out:
        return (np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)), \
            unsupported
    if len(out) == 1:
        return out[0], unsupported
    return tuple(np.concatenate(p) for p in zip(*out)), unsupported


def _detect(bodies, shapes, pos, quat, ia, ib, margin, bv, stats, t0, timings, R=None):
    R = Q.to_matrix(quat) if R is None else R
    # canonical order: A has the higher rank; remember to flip normals back
    swap = bodies.rank[ia] < bodies.rank[ib]
    a = np.where(swap, ib, ia)
    b = np.where(swap, ia, ib)
    t1 = time.perf_counter()
    # sphere–sphere pairs skip the bounding volumes: the sphere is its own bounding sphere and the
    # narrow kernel is the same distance test (an OBB test on top only costs time)
    finite = ~bodies.is_plane[b] & ~((bodies.rank[a] == 1) & (bodies.rank[b] == 1))
    if bv == "hull":
        _prepare_hulls(bodies, shapes)
    keep = np.ones(len(a), bool)
    fi = np.flatnonzero(finite)
    if fi.size:
        keep[fi] = _bv_reject(bodies, bv, a[fi], b[fi], pos, R, margin)
    stats.rejected_by_bounding_volume = int((~keep).sum())
    t2 = time.perf_counter()
    timings["bounding"] = t2 - t1
    kk = np.flatnonzero(keep)
    counters = narrow.Counters()
    (pi, pt, nrm, dep, ft), unsupported = _narrow(bodies, pos, R, a[kk], b[kk], margin, counters)
    pair = kk[pi]
    flip = swap[pair]
    nrm = np.where(flip[:, None], -nrm, nrm)
    t3 = time.perf_counter()
    timings["narrow"] = t3 - t2
    k = len(dep)
    c = Contacts(body_a=ia[pair].astype(np.int64), body_b=ib[pair].astype(np.int64), point=pt, normal=nrm,
                 depth=dep, impulse=np.zeros((k, 3)), normal_impulse=np.zeros(k),
                 friction_impulse=np.zeros((k, 3)), relative_normal_velocity=np.zeros(k),
                 feature=ft.astype(np.int64))
    stats.settled_by_vertex = counters.vertex
    stats.needed_edge_face = counters.edge_face
    stats.edge_face_hits = counters.edge_hits
    stats.unsupported_pairs = unsupported
    hit = np.zeros(len(ia), bool)
    hit[pair] = True
    stats.colliding_pairs = int(np.count_nonzero(hit))
    stats.contacts = k
    timings["total"] = time.perf_counter() - t0
    stats.seconds = timings
    return c, stats


def detect_world(world, margin=None):
    """All contacts of ``world``'s current state: ``(Contacts, DetectionStats)``.

    ``margin`` (m) overrides ``world.settings.contact_margin``: pairs closer than it are reported
    with ``depth = -separation`` (negative). ``body_a < body_b`` in every row; ``normal (K, 3)``
    points from ``body_b`` to ``body_a``.
    """
    t0 = time.perf_counter()
    margin = float(world.settings.contact_margin if margin is None else margin)
    if not np.isfinite(margin) or margin < 0:
        raise ContactSimError(f"detect_world: margin must be a finite number >= 0, got {margin!r}")
    bv = world.settings.bounding_volume
    stats = DetectionStats(bodies=len(world.shapes), bounding_volume=bv, margin=margin)
    bodies = _bodies_of(world)
    pos, quat = world.s.pos, world.s.quat
    timings = {}
    R = None
    if bodies.n < 2:
        ia = ib = np.zeros(0, np.int64)
    else:
        R = Q.to_matrix(quat)
        fin = np.flatnonzero(~bodies.is_plane)
        c, h = broadphase.world_aabbs(pos[fin], R[fin], bodies.aabb_c[fin], bodies.aabb_h[fin])
        i, j = bodies.pair_cache.pairs(c, h, margin)
        i, j = fin[i], fin[j]
        pl = np.flatnonzero(bodies.is_plane)
        if pl.size:
            nw = np.einsum("nij,nj->ni", R[pl], bodies.plane_n[pl])
            dw = bodies.plane_d[pl] + np.einsum("ni,ni->n", nw, pos[pl])
            p, f = broadphase.plane_pairs(pl, nw, dw, fin, c, h, margin)
            i, j = np.concatenate([i, np.minimum(p, f)]), np.concatenate([j, np.maximum(p, f)])
        kind, group, mask = world.kind, world.group, world.mask
        keep = ~((kind[i] == 0) & (kind[j] == 0))
        keep &= ((group[i] & mask[j]) != 0) & ((group[j] & mask[i]) != 0)
        order = np.lexsort((j[keep], i[keep]))
        ia, ib = i[keep][order], j[keep][order]
    timings["broad"] = time.perf_counter() - t0
    stats.candidate_pairs = len(ia)
    return _detect(bodies, world.shapes, pos, quat, ia, ib, margin, bv, stats, t0, timings, R)


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
    within ``validate.LENGTH_LIMIT``); with ``settings`` (a ``Settings`` or a mapping) also against
    its world bounds (positions, shape sizes, margin), as a world would check them.
    """
    t0 = time.perf_counter()
    st, margin, bounding_volume = _check_query("collide", settings, margin, bounding_volume)
    _check_shape(shape_a, "collide: shape_a", st)
    _check_shape(shape_b, "collide: shape_b", st)
    pa, qa = _check_pose(pose_a, "collide: pose_a", st)
    pb, qb = _check_pose(pose_b, "collide: pose_b", st)
    stats = Flag().check(stats, "collide: stats")
    if shape_a.type == "mesh" and shape_b.type == "mesh":
        raise ContactSimError("collide: mesh-mesh pairs are not supported; make one of them convex")
    bodies = _bodies_cached((shape_a, shape_b))
    st = DetectionStats(bodies=2, candidate_pairs=1, bounding_volume=bounding_volume, margin=margin)
    c, st = _detect(bodies, [shape_a, shape_b], np.array([pa, pb]), np.array([qa, qb]), np.array([0]),
                    np.array([1]), margin, bounding_volume, st, t0, {"broad": 0.0})
    return (c, st) if stats else c


_PAIR_CACHE = {}


def _bodies_cached(shapes):
    key = (id(shapes[0]), id(shapes[1]))
    hit = _PAIR_CACHE.get(key)
    if hit is not None and hit[0][0] is shapes[0] and hit[0][1] is shapes[1]:
        return hit[1]
    if len(_PAIR_CACHE) > 256:
        _PAIR_CACHE.clear()
    b = _Bodies(list(shapes))
    _PAIR_CACHE[key] = (shapes, b)
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
    return _detect(bodies, list(shapes), pos, q, pairs[:, 0], pairs[:, 1], margin, bounding_volume, stats, t0,
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
