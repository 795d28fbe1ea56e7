"""The contact cache carried between steps (``ContactCache``, owned by ``World.contact_cache``):
resting impulses (warm starts), matched from step to step by pair and by the contact point in
body A's frame; and the per-step contact records merged the same way."""
import math
from dataclasses import dataclass

import numpy as np

from ..contacts import Contacts
from ..jit import njit
from . import toi as toi_mod
from ..constants import MATCH_FRACTION


@dataclass
class ContactCache:
    """What the stepper keeps from one step for the next: the only state outside the bodies' that a
    step reads. ``World.reset`` empties it and ``World.remove_bodies`` renumbers it; it only speeds
    up the next step (warm starts) and decides when the preflight check reruns."""

    #: the last resting solve's contacts: ``(body_a (K,), body_b (K,), points in A's frame (K,3),
    #: impulses per unit of the step's time (K,4): normal, then the world tangential vector)``, int64 and float64
    #: C-order arrays (the sub-step's kernel takes them as they are); ``None`` before one
    warm: tuple = None
    #: the step length the preflight warnings were last checked for
    preflight_dt: float = None

    def reset(self):
        self.warm = None
        self.preflight_dt = None

    def copy(self):
        """A copy holding the same records (they are never edited in place: a step replaces them);
        ``dataclasses.replace`` costs five times as much, on every step's snapshot."""
        return ContactCache(self.warm, self.preflight_dt)

    def remap(self, new_index):
        """Keep the contacts of bodies left after a removal (``new_index (N_old,)`` old → new, −1
        removed), renumbered."""
        if self.warm is not None:
            a, b = self.warm[0], self.warm[1]
            keep = (new_index[a] >= 0) & (new_index[b] >= 0)
            c = np.ascontiguousarray
            self.warm = (c(new_index[a][keep], dtype=np.int64), c(new_index[b][keep], dtype=np.int64)) + tuple(
                c(x[keep], dtype=float) for x in self.warm[2:])


@njit(_nrt=False)
def local_points(a, point, pos, R, out):
    """Contact points ``point (K,3)`` of the contacts' A bodies ``a (K,)`` in A's frame (what
    identifies a contact across steps): ``out[k] = R[a[k]]ᵀ (point[k] − pos[a[k]])``, ``R (N,3,3)``
    the bodies' rotation matrices."""
    for k in range(a.shape[0]):
        i = a[k]
        dx, dy, dz = point[k, 0] - pos[i, 0], point[k, 1] - pos[i, 1], point[k, 2] - pos[i, 2]
        for x in range(3):
            out[k, x] = R[i, 0, x] * dx + R[i, 1, x] * dy + R[i, 2, x] * dz


def match(world, a0, b0, p0, a1, b1, p1):
    """For each new contact ``(a1, b1, p1 (K1,3))`` the index of the old contact ``(a0, b0, p0 (K0,3))``
    of the same pair whose point in A's frame is nearest, within ``MATCH_FRACTION`` of the smaller
    body's size; ``-1`` when none. Each old contact is claimed at most once, nearest claims first
    (``(K1,) int``)."""
    out = np.full(len(a1), -1, np.int64)
    if len(a0) == 0 or len(a1) == 0:
        return out
    c = np.ascontiguousarray
    _match(c(a0, dtype=np.int64), c(b0, dtype=np.int64), c(p0, dtype=float), c(a1, dtype=np.int64),
           c(b1, dtype=np.int64), c(p1, dtype=float), toi_mod._extents(world), MATCH_FRACTION, out)
    return out


@njit
def _match(a0, b0, p0, a1, b1, p1, ext, fraction, out):
    """``match``'s kernel: old and new contacts' bodies ``a0, b0 (K0,)``, ``a1, b1 (K1,)``; a match
    lies within ``fraction × min(ext[a1], ext[b1])`` (``ext (N,)`` the bodies' sizes); writes
    ``out (K1,)``. Each new contact's candidates are its pair's old contacts (a handful), found
    through a hash of the pairs (chained, a power of two of at least twice ``K0``
    buckets: linear in the contacts, whatever ``N``); its best is the nearest, ties to the lower
    index (a minimum, so the order of the chain does not matter). Each old contact goes to one new
    contact, the nearest claiming first: only when two new contacts pick the same old one is the
    claim order (by distance, ties to the lower index) needed, and sorted."""
    k0, k1 = a0.shape[0], a1.shape[0]
    size = 1
    while size < 2 * k0:
        size *= 2
    links = np.empty(size + k0, np.int64)   # one block: each bucket's first old contact, then each one's next
    head, nxt = links[:size], links[size:]
    head[:] = -1
    for j in range(k0 - 1, -1, -1):   # pushed from the last, so a chain lists its contacts in order
        h = _bucket(a0[j], b0[j], size)
        nxt[j] = head[h]
        head[h] = j
    best = np.full(k1, -1, np.int64)
    dist = np.full(k1, np.inf)
    for i in range(k1):
        reach = fraction * min(ext[a1[i]], ext[b1[i]])
        o = head[_bucket(a1[i], b1[i], size)]
        while o >= 0:
            if a0[o] == a1[i] and b0[o] == b1[i]:
                d = math.sqrt((p1[i, 0] - p0[o, 0]) ** 2 + (p1[i, 1] - p0[o, 1]) ** 2 + (p1[i, 2] - p0[o, 2]) ** 2)
                if d <= reach and (d < dist[i] or (d == dist[i] and o < best[i])):
                    dist[i] = d
                    best[i] = o
            o = nxt[o]
    claimed = np.zeros(k0, np.bool_)
    conflict = False
    for i in range(k1):
        o = best[i]
        if o >= 0:
            conflict = conflict or claimed[o]
            claimed[o] = True
            out[i] = o
    if not conflict:
        return
    claimed[:] = False
    for i in range(k1):
        out[i] = -1
    for i in np.argsort(dist, kind="mergesort"):   # the nearest pairings claim first
        o = best[i]
        if o >= 0 and not claimed[o]:
            claimed[o] = True
            out[i] = o


@njit(_nrt=False)
def _bucket(a, b, size):
    """The hash bucket of the pair ``(a, b)`` among ``size`` (a power of two): each body's index
    times a large odd number, combined by exclusive or (no product overflows for fewer than 10¹¹
    bodies), so a body's pairs and neighbouring bodies spread over the buckets."""
    return ((a * 73856093) ^ (b * 19349663)) & (size - 1)


@njit
def warm_start(a0, b0, p0, a1, b1, p1, ext, fraction, values, t_left, dirs, mu, out):
    """The resting solve's warm start ``out (K,3)`` in the rows' (n, t1, t2) basis (``dirs
    (K,3,3)``): the previous step's resting impulses per unit of its time (the cache ``a0, b0 (K0,)``,
    ``p0 (K0,3)``, ``values (K0,4)``) of the contacts ``(a1, b1 (K,), p1 (K,3))`` that match one of
    them (same pair, nearest point: ``_match``, within ``fraction`` of the smaller body's extent
    ``ext (N,)``), times ``t_left``, projected on each contact's tangent plane and friction cone
    (``mu (K,)``, ``_project_warm``). Returns whether any warm impulse is non-zero."""
    k1 = a1.shape[0]
    hit = np.full(k1, -1, np.int64)
    _match(a0, b0, p0, a1, b1, p1, ext, fraction, hit)
    w = np.zeros((k1, 4))
    for i in range(k1):
        if hit[i] >= 0:
            for x in range(4):
                w[i, x] = values[hit[i], x] * t_left
    return _project_warm(w, dirs, mu, out)


def merge_records(world, records):
    """One row per contact point for the whole step: contacts of the sub-steps (``[(Contacts,
    local (k,3))]``) that are the same point (same pair, same place on A) are merged, keeping the
    latest geometry and the sum of the impulses."""
    if not records:
        return Contacts.empty()
    acc, loc = records[0]
    for c, local in records[1:]:
        hit = match(world, acc.body_a, acc.body_b, loc, c.body_a, c.body_b, local)
        ok = hit >= 0
        for name in ("normal_impulse", "friction_impulse", "impulse"):
            getattr(c, name)[ok] += getattr(acc, name)[hit[ok]]
        keep = np.ones(len(acc), bool)
        keep[hit[ok]] = False
        acc = Contacts.concat([acc.select(keep), c])
        loc = np.concatenate([loc[keep], local])
    return acc


def record(c, rows, lam, vn0):
    """Fill the impulse columns of contacts ``c`` from accumulated ``lam (K,3)`` (n, t1, t2)."""
    c.normal_impulse = lam[:, 0].copy()
    c.friction_impulse = lam[:, 1:2] * rows.t1 + lam[:, 2:3] * rows.t2
    c.impulse = c.normal_impulse[:, None] * c.normal + c.friction_impulse
    c.relative_normal_velocity = vn0.copy()
    return c


@njit(_nrt=False)
def warm_record(lam, dirs, out):
    """``out (K,4)``: impulses ``lam (K,3)`` in the rows' (n, t1, t2) basis (``dirs (K,3,3)``) as the
    normal impulse and the world tangential impulse vector (basis-free, so the next step's rows can
    take it whatever tangents they pick)."""
    for c in range(lam.shape[0]):
        out[c, 0] = lam[c, 0]
        for x in range(3):
            out[c, 1 + x] = lam[c, 1] * dirs[c, 1, x] + lam[c, 2] * dirs[c, 2, x]


@njit(_nrt=False)
def _project_warm(w, dirs, mu, out):
    """Warm impulses ``out (K,3)`` in the rows' basis (``dirs (K,3,3)``) from the ``warm_record``
    form ``w (K,4)``: the tangential vector projected on the contact's tangent plane, inside the
    cone (``mu (K,)``); returns whether any warm impulse is non-zero."""
    anything = False
    for c in range(w.shape[0]):
        for x in range(4):
            anything = anything or w[c, x] != 0.0
        n = max(w[c, 0], 0.0)
        t1 = w[c, 1] * dirs[c, 1, 0] + w[c, 2] * dirs[c, 1, 1] + w[c, 3] * dirs[c, 1, 2]
        t2 = w[c, 1] * dirs[c, 2, 0] + w[c, 2] * dirs[c, 2, 1] + w[c, 3] * dirs[c, 2, 2]
        mag = math.sqrt(t1 * t1 + t2 * t2)
        lim = mu[c] * n
        if mag > lim:
            scale = lim / max(mag, 1e-300)
            t1 *= scale
            t2 *= scale
        out[c, 0], out[c, 1], out[c, 2] = n, t1, t2
    return anything
