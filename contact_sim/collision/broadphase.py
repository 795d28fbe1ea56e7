"""Broad phase: world AABBs, then candidate pairs by the cheapest exact method for the scene: all
pairs (few bodies), sweep-and-prune (few overlaps on the sweep axis), or a uniform hash grid
(crowded, grid-like 3-D scenes, where SAP degrades to N^(5/3)); planes are tested against AABBs
directly. Every method returns exactly the pairs whose AABBs overlap within the margin."""
import numpy as np

from ..jit import njit
from ..constants import BRUTE_MAX, SAP_BUDGET, FAT_FRACTION, FAT_STRETCH_MAX


def _filter(c, h, i, j, margin):
    """The pairs ``i, j (K,)`` whose boxes overlap within ``margin`` (compiled ``overlap_filter``)."""
    i, j = np.ascontiguousarray(i, np.int64), np.ascontiguousarray(j, np.int64)
    oi, oj = np.empty_like(i), np.empty_like(j)
    n = overlap_filter(c, h, i, j, margin, oi, oj)
    return oi[:n], oj[:n]


def candidate_pairs(c, h, margin):
    """Pairs ``(i (K,), j (K,))``, ``i < j``, of boxes (centres, half sizes ``(N, 3)``) overlapping
    within ``margin``, by the cheapest method for the layout (measured: ``bench/bench_detect.py``;
    all pairs, one compiled pass, ~1 µs at 10 boxes against ~60 µs for SAP and ~100 µs for the
    grid; SAP 2× faster than the grid on a 2-D layer of 500 spheres, 10× slower on a 3-D lattice of
    2000)."""
    n = len(c)
    if n <= BRUTE_MAX:
        return all_pairs(c, h, margin)
    out = sweep_and_prune(c, h, margin, budget=SAP_BUDGET * n + 64)
    return grid_pairs(c, h, margin) if out is None else out


class PairCache:
    """Candidate pairs carried across steps (temporal coherence, as Box2D's fat AABBs).

    The pairs are computed for *fat* boxes (each tight box grown by ``FAT_FRACTION`` of its size,
    and stretched along the displacement its body is expected to make, as Box2D v2's predictive
    AABBs: a falling ball keeps its cache for several steps instead of one) with twice the
    margin. While every tight box stays inside its fat box and the margin does not
    grow past the cached one, the cached pairs are a superset of the overlapping pairs, and one
    exact test on the tight boxes gives exactly what ``candidate_pairs`` would (a resting or slowly
    moving scene skips the sort/grid work); otherwise the cache is rebuilt from the current boxes.
    ``rebuilds``/``reuses`` count what happened. A world's cache (``collision.rebuild_pair_cache``)
    also holds ``args = (fat_c, fat_h, i, j, margin, keys)``: itself as a one-call kernel takes it
    (``stepper._flight``), with a keys workspace sized for it (``world_pairs``' sizes); None until
    it is built."""

    def __init__(self):
        self.fat_c = self.fat_h = None
        self.margin = -1.0
        self.i = self.j = None
        self.args = None
        self.rebuilds = 0
        self.reuses = 0

    def pairs(self, c, h, margin, vel=None, horizon=0.0):
        """Same contract as ``candidate_pairs`` for boxes ``c, h (N, 3)``, pairs sorted by ``(i, j)``;
        ``vel, horizon``: a rebuild's stretch (``rebuild``)."""
        if self.valid(c, h, margin):
            self.reuses += 1
        else:
            self.rebuild(c, h, margin, vel, horizon)
        oi, oj = np.empty_like(self.i), np.empty_like(self.j)
        n = overlap_filter(c, h, self.i, self.j, margin, oi, oj)
        return oi[:n], oj[:n]

    def valid(self, c, h, margin):
        """The cached pairs hold for boxes ``c, h (N, 3)`` within ``margin``."""
        return (self.fat_c is not None and len(self.fat_c) == len(c) and margin <= self.margin
                and inside_fat(c, h, self.fat_c, self.fat_h))

    def rebuild(self, c, h, margin, vel=None, horizon=0.0):
        """Fat boxes and their pairs from the boxes ``c, h (N, 3)``; with ``vel (N, 3)`` (m/s) each
        fat box also covers its box moved by ``vel × horizon`` (s) (``fat_boxes``)."""
        self.fat_c, self.fat_h = np.empty_like(c), np.empty_like(h)
        scale = fat_boxes(c, h, _NO_VEL if vel is None else vel, float(horizon), self.fat_c, self.fat_h)
        # twice the margin (a growing look-ahead keeps the cache a while), plus round-off slack
        # of the coordinates so that the superset argument holds in floating point
        self.margin = 2.0 * margin + 1e-9 * (1.0 + scale)
        i, j = candidate_pairs(self.fat_c, self.fat_h, self.margin)
        if len(c) > BRUTE_MAX:   # all pairs come in (i, j) order already
            order = np.lexsort((j, i))
            i, j = np.ascontiguousarray(i[order]), np.ascontiguousarray(j[order])
        self.i, self.j = i, j
        self.rebuilds += 1


_NO_VEL = np.zeros((0, 3))


@njit
def fat_boxes(c, h, vel, horizon, fat_c, fat_h):
    """The fat boxes ``fat_c, fat_h (N, 3)`` of the boxes ``c, h (N, 3)``: each grown by
    ``FAT_FRACTION`` × its largest half size and, with ``vel (N, 3)`` (m/s; empty: none),
    stretched to cover the box moved by ``d = vel × horizon`` (m) as well (centre moved by d/2,
    half sizes grown by |d|/2), each component of ``d`` capped at ``FAT_STRETCH_MAX`` × the
    largest half size so that a fast body's fat box cannot take in the whole scene. Returns the
    coordinates' scale (the largest |fat centre| + the largest fat half size, m)."""
    big_c, big_h = 0.0, 0.0
    for m in range(c.shape[0]):
        hm = max(h[m, 0], h[m, 1], h[m, 2])
        cap = FAT_STRETCH_MAX * hm
        for i in range(3):
            d = 0.0
            if vel.shape[0]:
                d = min(max(vel[m, i] * horizon, -cap), cap)
            fat_c[m, i] = c[m, i] + 0.5 * d
            # never less than ``inside_fat`` computes for the box itself (round-off of the move)
            fat_h[m, i] = max(h[m, i] + FAT_FRACTION * hm + 0.5 * abs(d), abs(c[m, i] - fat_c[m, i]) + h[m, i])
            big_c, big_h = max(big_c, abs(fat_c[m, i])), max(big_h, fat_h[m, i])
    return big_c + big_h


def all_pairs(c, h, margin):
    """Same contract as ``sweep_and_prune``, by testing every pair (for a few boxes); the pairs in
    ``(i, j)`` order, contiguous."""
    n = len(c)
    oi, oj = np.empty(n * (n - 1) // 2, np.int64), np.empty(n * (n - 1) // 2, np.int64)
    k = _all_overlapping(c, h, margin, oi, oj)
    return oi[:k], oj[:k]


@njit(_nrt=False)
def _all_overlapping(c, h, margin, oi, oj):
    """Every pair ``a < b`` of the boxes ``c, h (N, 3)`` that overlaps within ``margin`` into
    ``oi, oj (≥ N(N-1)/2,)``, in ``(a, b)`` order; returns their count."""
    k = 0
    for a in range(c.shape[0]):
        for b in range(a + 1, c.shape[0]):
            if _overlap(c, h, a, b, margin):
                oi[k], oj[k] = a, b
                k += 1
    return k


def world_aabbs(pos, R, centre_local, half_local):
    """World AABB ``(centre (N, 3), half (N, 3))`` of object boxes carried by the poses."""
    c = pos + np.einsum("nij,nj->ni", R, centre_local)
    h = np.einsum("nij,nj->ni", np.abs(R), half_local)
    return c, h


def sweep_and_prune(c, h, margin, budget=None):
    """Pairs ``(i (K,), j (K,))``, ``i < j``, of boxes (centres, half sizes ``(N, 3)``) overlapping
    within ``margin``. Sort the lower bounds along the axis of widest extent; each box's partners
    are the boxes whose lower bound falls within its interval (``searchsorted``), then the other
    two axes filter. O(N log N + pairs on the sweep axis), no Python loop over boxes. ``None``
    when the sweep-axis candidates exceed ``budget`` (the caller then uses the grid)."""
    n = len(c)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ax = int(np.argmax(c.max(axis=0) - c.min(axis=0)))   # widest spread (np.var costs 10× more)
    lo = c[:, ax] - h[:, ax]
    hi = c[:, ax] + h[:, ax] + margin
    order = np.argsort(lo, kind="stable")
    lo_s, hi_s = lo[order], hi[order]
    end = np.searchsorted(lo_s, hi_s, side="right")
    start = np.arange(n) + 1
    counts = np.maximum(end - start, 0)
    total = int(counts.sum())
    if budget is not None and total > budget:
        return None
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i_s = np.repeat(np.arange(n), counts)
    offs = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    j_s = i_s + 1 + offs
    i, j = _filter(c, h, order[i_s], order[j_s], margin)
    return np.minimum(i, j), np.maximum(i, j)


# the 13 neighbour offsets of a cell that come "after" it, plus the cell itself (index 0)
_OFFS = np.array([(0, 0, 0)] + [(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)
                                 if (x, y, z) > (0, 0, 0)], np.int64)


def _key(cell):
    c = cell + (1 << 20)
    return (c[..., 0] << 42) | (c[..., 1] << 21) | c[..., 2]


def grid_pairs(c, h, margin):
    """Pairs ``(i (K,), j (K,))``, ``i < j``, of boxes (centres, half sizes ``(N, 3)``) overlapping
    within ``margin``: a uniform grid whose cell is the largest ordinary box (so overlapping boxes
    sit in the same or adjacent cells), cell keys sorted once and each of the 14 forward
    neighbour cells looked up with ``searchsorted``; boxes much larger than the median (a few at
    most) are swept against everything. O(N log N + candidates), no Python loop over boxes."""
    n = len(c)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ext = 2.0 * h.max(axis=1) + margin
    big = ext > 4.0 * np.partition(ext, n // 2)[n // 2]  # (upper) median; np.median costs ~0.2 ms here
    small = np.flatnonzero(~big)
    out_i, out_j = [], []
    if small.size > 1:
        size = float(ext[small].max())
        cell = np.floor(c[small] / size).astype(np.int64)
        keys = _key(cell)
        order = np.argsort(keys, kind="stable")
        ks = keys[order]
        m = len(ks)
        # the 14 forward neighbour cells of every box at once: one searchsorted over (m, 14) keys
        q = _key(cell[order][:, None, :] + _OFFS[None, :, :])
        lo = np.searchsorted(ks, q, side="left")
        hi = np.searchsorted(ks, q, side="right")
        lo[:, 0] = np.arange(m) + 1              # same cell: only later entries
        cnt = np.maximum(hi - lo, 0).ravel()
        tot = int(cnt.sum())
        if tot:
            a = np.repeat(np.repeat(np.arange(m), len(_OFFS)), cnt)
            b = np.repeat(lo.ravel(), cnt) + np.arange(tot) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            out_i.append(small[order[a]])
            out_j.append(small[order[b]])
    bigi = np.flatnonzero(big)
    if bigi.size:
        bi = np.repeat(bigi, n)
        bj = np.tile(np.arange(n), bigi.size)
        keep = (bj != bi) & ~(big[bj] & (bj < bi))    # big-big pairs once
        out_i.append(bi[keep])
        out_j.append(bj[keep])
    if not out_i:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i, j = _filter(c, h, np.concatenate(out_i), np.concatenate(out_j), margin)
    return np.minimum(i, j), np.maximum(i, j)


# ---------------------------------------------------------------- compiled warm path
@njit(_nrt=False)
def world_boxes(pos, R, idx, centre, half, c, h):
    """World AABBs ``c, h (M, 3)`` of bodies ``idx (M,)``: object boxes ``centre, half (N, 3)``
    carried by ``pos (N, 3)``, ``R (N, 3, 3)`` (as ``world_aabbs``, one pass)."""
    for m in range(idx.shape[0]):
        k = idx[m]
        for i in range(3):
            c[m, i] = pos[k, i] + R[k, i, 0] * centre[k, 0] + R[k, i, 1] * centre[k, 1] + R[k, i, 2] * centre[k, 2]
            h[m, i] = abs(R[k, i, 0]) * half[k, 0] + abs(R[k, i, 1]) * half[k, 1] + abs(R[k, i, 2]) * half[k, 2]


@njit(_nrt=False)
def inside_fat(c, h, fat_c, fat_h):
    """Every tight box ``c, h`` inside its fat box."""
    for m in range(c.shape[0]):
        for i in range(3):
            if not abs(c[m, i] - fat_c[m, i]) + h[m, i] <= fat_h[m, i]:
                return False
    return True


@njit(inline="always")
def _overlap(c, h, a, b, margin):
    """Boxes ``a`` and ``b`` of ``c, h (N, 3)`` overlap within ``margin`` on all three axes."""
    return (abs(c[a, 0] - c[b, 0]) <= h[a, 0] + h[b, 0] + margin and abs(c[a, 1] - c[b, 1]) <= h[a, 1] + h[b, 1] + margin
            and abs(c[a, 2] - c[b, 2]) <= h[a, 2] + h[b, 2] + margin)


@njit(_nrt=False)
def overlap_filter(c, h, i, j, margin, oi, oj):
    """The pairs ``i, j`` whose boxes overlap within ``margin`` into ``oi, oj``; returns their count
    (the one exact test every method ends with, so they all return the same pairs; order kept)."""
    n = 0
    for k in range(i.shape[0]):
        a, b = i[k], j[k]
        if _overlap(c, h, a, b, margin):
            oi[n], oj[n] = a, b
            n += 1
    return n


@njit
def world_pairs(pos, R, fin, centre, half, planes, plane_n, plane_d, fat_c, fat_h, ci, cj, fat_margin, margin,
                plane_margin, kind, group, mask, disabled):
    """The world's candidate pairs in one pass, while the pair cache holds: ``(ok, i (K,), j (K,))``.

    World boxes of the finite bodies ``fin (M,)`` (``world_boxes``); ``ok`` False (nothing else
    done) when one left its fat box or ``margin`` grew past the cache's ``fat_margin`` (the caller
    rebuilds the cache and calls again). Otherwise the cached pairs ``ci, cj`` (indices into
    ``fin``) that overlap within ``margin`` (``PairCache.pairs``' answer), and each plane of
    ``planes (P,)`` (object normal and offset ``plane_n (N, 3)``, ``plane_d (N,)``) with every
    finite box whose lowest point along the world normal reaches within ``plane_margin`` of the plane;
    sorted by ``(i, j)``, ``i < j`` body indices; without the pairs that may not touch
    (``may_touch``). One compiled pass (``cached_keys``, then the filter): a dozen numpy calls a step
    were most of a small world's detection."""
    m = fin.shape[0]
    nb = pos.shape[0]
    boxes = np.empty((2, m, 3))   # the world boxes' centres and half sizes, one block
    keys = np.empty(ci.shape[0] + planes.shape[0] * m, np.int64)
    n = cached_keys(pos, R, fin, centre, half, planes, plane_n, plane_d, fat_c, fat_h, ci, cj, fat_margin, margin,
                    plane_margin, boxes[0], boxes[1], keys)
    if n < 0:
        return False, np.zeros(0, np.int64), np.zeros(0, np.int64)
    keys = keys[:n]
    if planes.shape[0]:
        keys.sort()   # in place: the plane pairs among the cached ones
    pairs = np.empty((2, n), np.int64)   # the kept pairs' i and j, one block
    oi, oj = pairs[0], pairs[1]
    out = 0
    for k in range(n):
        if may_touch(keys[k], nb, kind, group, mask, disabled):
            oi[out], oj[out] = keys[k] // nb, keys[k] % nb
            out += 1
    return True, oi[:out], oj[:out]


@njit(_nrt=False)
def cached_keys(pos, R, fin, centre, half, planes, plane_n, plane_d, fat_c, fat_h, ci, cj, fat_margin, margin,
                plane_margin, c, h, keys):
    """``world_pairs``' pass before its filter, into workspace (arguments as there): the world boxes
    ``c, h (M,3)`` of the finite bodies, and the keys ``i·N + j`` of the candidate pairs into ``keys
    (≥ C + P·M,)``, unsorted (the cached pairs' in their order, then each plane's). Returns how many,
    −1 when a body left its fat box or ``margin`` grew past ``fat_margin`` (nothing else done)."""
    m = fin.shape[0]
    nb = pos.shape[0]
    world_boxes(pos, R, fin, centre, half, c, h)
    if fat_c.shape[0] != m or not margin <= fat_margin or not inside_fat(c, h, fat_c, fat_h):
        return -1
    n = 0
    for k in range(ci.shape[0]):
        a, b = ci[k], cj[k]
        if _overlap(c, h, a, b, margin):
            keys[n] = fin[a] * nb + fin[b]   # fin ascending and a < b: already i < j
            n += 1
    for q in range(planes.shape[0]):
        p = planes[q]
        # the plane's world normal (nx, ny, nz) and offset dw
        nx = R[p, 0, 0] * plane_n[p, 0] + R[p, 0, 1] * plane_n[p, 1] + R[p, 0, 2] * plane_n[p, 2]
        ny = R[p, 1, 0] * plane_n[p, 0] + R[p, 1, 1] * plane_n[p, 1] + R[p, 1, 2] * plane_n[p, 2]
        nz = R[p, 2, 0] * plane_n[p, 0] + R[p, 2, 1] * plane_n[p, 1] + R[p, 2, 2] * plane_n[p, 2]
        dw = plane_d[p] + (nx * pos[p, 0] + ny * pos[p, 1] + nz * pos[p, 2])
        for f in range(m):
            low = (nx * c[f, 0] + ny * c[f, 1] + nz * c[f, 2]) \
                - (abs(nx) * h[f, 0] + abs(ny) * h[f, 1] + abs(nz) * h[f, 2])
            if low <= dw + plane_margin:
                keys[n] = min(p, fin[f]) * nb + max(p, fin[f])
                n += 1
    return n


@njit
def may_touch(key, nb, kind, group, mask, disabled):
    """Whether the pair of ``key = i·nb + j`` may touch: not both static, each one's group in the
    other's mask, and not among the sorted keys ``disabled (D,)``."""
    a, b = key // nb, key % nb
    if not ((kind[a] != 0 or kind[b] != 0) and (group[a] & mask[b]) != 0 and (group[b] & mask[a]) != 0):
        return False
    if disabled.shape[0]:
        d = np.searchsorted(disabled, key)
        if d < disabled.shape[0] and disabled[d] == key:
            return False
    return True
