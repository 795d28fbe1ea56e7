"""What bounds a body's motion over an interval, for the time-of-impact searches (``toi``) and the
swept-volume test (``swept``): each body's extent, the largest spin its torque-free motion
reaches, and the first root of a gap that is quadratic in time."""
import numpy as np

from ..memo import derived
from ..shapes import Polyhedron, Sphere
from . import advancement


def _first_quadratic_root(c0, c1, c2, T):
    """Smallest τ in (0, T] with ``c0 + c1 τ + c2 τ² = 0`` crossing downward, for ``c0 > 0``;
    ``inf`` when there is none. Arrays ``(P,)``; stable (no cancellation) formula."""
    c0, c1, c2 = np.broadcast_arrays(np.asarray(c0, float), np.asarray(c1, float), np.asarray(c2, float))
    out = np.full(c0.shape, np.inf)
    disc = c1 * c1 - 4 * c2 * c0
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    qq = -0.5 * (c1 + np.where(c1 >= 0, sq, -sq))
    with np.errstate(all="ignore"):   # non-finite quotients (a denormal qq) are dropped below
        r1 = np.where(c2 != 0, qq / c2, np.inf)
        r2 = np.where(qq != 0, c0 / qq, np.inf)
    r1 = np.where(np.isfinite(r1), r1, np.inf)
    r2 = np.where(np.isfinite(r2), r2, np.inf)
    lo = np.minimum(np.where(r1 > 0, r1, np.inf), np.where(r2 > 0, r2, np.inf))
    hit = ok & (c0 > 0) & (lo <= T)
    out[hit] = lo[hit]
    return out


def _extent(shape):
    if isinstance(shape, Sphere):
        return shape.radius
    if isinstance(shape, Polyhedron):
        return float(np.linalg.norm(shape.vertices, axis=1).max())
    return np.inf


def _extents(world):
    """Bounding radius per body ``(N,)`` (inf for planes), cached on the world."""
    return derived(world, "extents", (), lambda: np.array([_extent(sh) for sh in world.shapes]), key=len(world))


def max_spin(m, k):
    """The largest ``|ω|`` (rad/s) body ``k`` reaches in torque-free motion from its current spin:
    with ``pᵢ = Πᵢ²`` (principal-frame angular momentum), ``|ω|² = Σ pᵢ/Iᵢ²`` is largest at a vertex
    of ``{p ≥ 0: Σ pᵢ = |L|², Σ pᵢ/Iᵢ = 2E}`` (both conserved). A body spinning about a principal
    axis keeps its ``|ω|`` exactly (the set is that one point); kinematic bodies and particles spin
    as told (``advancement.max_spin``)."""
    motion, flags = m.arrays()
    return float(advancement.max_spin(int(k), motion, flags))
