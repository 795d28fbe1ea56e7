"""Broad phase: world AABBs and a vectorised sweep-and-prune; planes tested against AABBs directly."""
import numpy as np


def world_aabbs(pos, R, centre_local, half_local):
    """World AABB ``(centre (N, 3), half (N, 3))`` of object boxes carried by the poses."""
    c = pos + np.einsum("nij,nj->ni", R, centre_local)
    h = np.einsum("nij,nj->ni", np.abs(R), half_local)
    return c, h


def sweep_and_prune(c, h, margin):
    """Pairs ``(i (K,), j (K,))``, ``i < j``, of boxes (centres, half sizes ``(N, 3)``) overlapping
    within ``margin``. Sort the lower bounds along the axis of largest spread; each box's partners
    are the boxes whose lower bound falls within its interval (``searchsorted``), then the other
    two axes filter. O(N log N + pairs on the sweep axis), no Python loop over boxes."""
    n = len(c)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ax = int(np.argmax(c.var(axis=0)))
    lo = c[:, ax] - h[:, ax]
    hi = c[:, ax] + h[:, ax] + margin
    order = np.argsort(lo, kind="stable")
    lo_s, hi_s = lo[order], hi[order]
    end = np.searchsorted(lo_s, hi_s, side="right")
    start = np.arange(n) + 1
    counts = np.maximum(end - start, 0)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i_s = np.repeat(np.arange(n), counts)
    offs = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    j_s = i_s + 1 + offs
    i, j = order[i_s], order[j_s]
    d = np.abs(c[i] - c[j]) <= h[i] + h[j] + margin
    keep = d.all(axis=1)
    i, j = i[keep], j[keep]
    return np.minimum(i, j), np.maximum(i, j)


def plane_pairs(plane_idx, plane_n, plane_d, finite_idx, c, h, margin):
    """Pairs ``(plane body (K,), finite body (K,))`` whose AABB reaches within ``margin`` of the
    half-space (world plane normals ``(Np, 3)``, offsets ``(Np,)``; finite AABBs ``c, h (Nf, 3)``)."""
    if len(plane_idx) == 0 or len(finite_idx) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    low = plane_n @ c.T - np.abs(plane_n) @ h.T          # (Np, Nf) lowest point of each box
    p, f = np.nonzero(low <= plane_d[:, None] + margin)
    return plane_idx[p], finite_idx[f]
