"""Contact constraint rows: per-contact geometry ``(K, ...)`` (directions ``n, t1, t2``, lever
arms, angular Jacobians and their images under the inverse inertia, effective inverse masses),
built by a kernel (``pgs.build_rows``), and the velocity algebra every solver shares."""
from dataclasses import dataclass

import numpy as np

from ..vec import cross
from . import active_set, pgs

_TINY = 1e-300


@dataclass
class Rows:
    """Per-contact constraint geometry ``(K, ...)`` shared by the solver phases."""

    a: np.ndarray
    b: np.ndarray
    n: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    # angular Jacobian rows (r×d) and their images under the inverse inertia, per direction
    ang_a: np.ndarray   # (K, 3 dirs, 3)
    ang_b: np.ndarray
    iang_a: np.ndarray
    iang_b: np.ndarray
    ima: np.ndarray     # (K,)
    imb: np.ndarray
    K: np.ndarray       # (K, 3, 3) effective inverse mass in the (n, t1, t2) basis
    dirs: np.ndarray    # (K, 3, 3) the directions n, t1, t2 as rows
    movable: np.ndarray  # (N,) bool: bodies whose velocity the solver changes
    # the bodies' inverse mass (N,) and world inverse inertia (N,3,3) the rows were built with: the
    # exact solve's body-space method needs the mass matrix itself (None: rows made without them)
    inv_mass: np.ndarray = None
    inv_inertia: np.ndarray = None

    def __len__(self):
        return len(self.a)

    def islands(self):
        """``(order (K,), start (I+1,))``: the contacts grouped by island (``active_set.islands``),
        computed once for these rows (the solver's method choice and the island solve share it)."""
        hit = self.__dict__.get("_islands")
        if hit is None:
            c = np.ascontiguousarray
            hit = self.__dict__["_islands"] = active_set.islands(
                c(self.a, dtype=np.int64), c(self.b, dtype=np.int64), c(self.movable, dtype=np.bool_), len(self.movable))
        return hit

    def select(self, idx):
        """Rows of the contacts ``idx`` (index array or boolean mask), without recomputation; ``self``
        when ``idx`` picks every row in order (the common case: 14 array copies saved; rows are never
        modified in place, only annotated with derived data that the same rows share)."""
        idx = np.asarray(idx)
        k = len(self.a)
        if (idx.all() if idx.dtype == bool else np.array_equal(idx, np.arange(k))) and len(idx) == k:
            return self
        f = ("a", "b", "n", "t1", "t2", "ra", "rb", "ang_a", "ang_b", "iang_a", "iang_b", "ima", "imb", "K", "dirs")
        return Rows(*[getattr(self, x)[idx] for x in f], self.movable, self.inv_mass, self.inv_inertia)


def build_rows(a, b, point, normal, pos, inv_mass, inv_inertia, vel=None, omega=None, movable=None, rel_vel=None,
               dynamic_levers=True):
    """Constraint rows for contacts. ``pos (N,3)`` centres of mass; ``vel/omega (N,3)`` (optional) or
    the contact points' relative velocity ``rel_vel (K,3)`` when already known pick the first
    tangent along the current sliding direction. ``dynamic_levers=False`` (the kinematic
    response) puts each movable body's contact at its centre: it acts as a particle. Returns ``Rows``."""
    if movable is None:
        movable = inv_mass > 0
    k = len(a)
    hint = rel_vel
    if hint is None and vel is not None and k:
        ra0 = point - pos[a]
        rb0 = point - pos[b]
        if not dynamic_levers:
            ra0 = np.where(movable[a][:, None], 0.0, ra0)
            rb0 = np.where(movable[b][:, None], 0.0, rb0)
        hint = (vel[a] + cross(omega[a], ra0)) - (vel[b] + cross(omega[b], rb0))
    if hint is None:
        hint = np.zeros((k, 3))
    c = np.ascontiguousarray
    # three blocks instead of twelve arrays (each field a contiguous slab of its block)
    t1, t2, ra, rb = np.empty((4, k, 3))
    ang_a, ang_b, iang_a, iang_b, K, d = np.empty((6, k, 3, 3))
    ima, imb = np.empty((2, k))
    pgs.build_rows(c(a, dtype=np.int64), c(b, dtype=np.int64), c(point, dtype=float), c(normal, dtype=float),
                   c(pos, dtype=float), c(inv_mass, dtype=float), c(inv_inertia, dtype=float), c(hint, dtype=float),
                   c(movable, dtype=np.bool_), bool(dynamic_levers), t1, t2, ra, rb, ang_a, ang_b, iang_a, iang_b,
                   ima, imb, K, d)
    return Rows(a, b, normal, t1, t2, ra, rb, ang_a, ang_b, iang_a, iang_b, ima, imb, K, d, movable,
                c(inv_mass, dtype=float), c(inv_inertia, dtype=float))


def row_velocity(rows, vel, omega, idx=slice(None)):
    """Relative velocity of the contact points of A and B ``(k,3)`` in the (n, t1, t2) basis."""
    a, b = rows.a[idx], rows.b[idx]
    d = rows.dirs[idx]
    va, vb = vel[a], vel[b]
    return (np.einsum("kdi,ki->kd", d, va - vb) + np.einsum("kdi,ki->kd", rows.ang_a[idx], omega[a])
            - np.einsum("kdi,ki->kd", rows.ang_b[idx], omega[b]))


def apply(rows, vel, omega, lam):
    """Apply impulses ``lam (k,3)`` (n, t1, t2 components, on A; −on B) to the velocity arrays in
    place, accumulating the contributions of contacts that share a body (``pgs.apply_ids``: one
    compiled pass in ``np.add.at``'s order, so the sums are bit for bit those of the numpy form
    ``vel[a] += ima·Σ_d λ_d d``, ``vel[b] −= imb·…``, ``ω[a] += Σ_d λ_d I⁻¹(r_a×d)``, ``ω[b] −= …``)."""
    c = np.ascontiguousarray
    v = vel if vel.flags.c_contiguous and vel.dtype == np.float64 else np.ascontiguousarray(vel, dtype=float)
    w = omega if omega.flags.c_contiguous and omega.dtype == np.float64 else np.ascontiguousarray(omega, dtype=float)
    pgs.apply_ids(np.arange(len(rows.a)), c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), c(rows.dirs),
                  c(rows.iang_a), c(rows.iang_b), c(rows.ima, dtype=float), c(rows.imb, dtype=float),
                  c(lam, dtype=float), v, w)
    if v is not vel:
        vel[...] = v
    if w is not omega:
        omega[...] = w


@dataclass
class SolveResult:
    impulse: np.ndarray     # (K,3) accumulated (normal, t1, t2) impulses on A
    iterations: int
    residual: float         # m/s: largest velocity change a row made in the last sweep (pgs.sweeps)
    unconverged: bool = False   # an iterative solve stopped above its tolerance (sweep limit, or stalled)



_NO_MASS, _NO_INERTIA = np.zeros(0), np.zeros((0, 3, 3))


def body_mass(rows):
    """``(inv_mass (N,), inv_inertia (N,3,3))`` of ``rows`` as the kernels take them (empty when the
    rows were made without them: the exact solve then keeps to its rows' method)."""
    if rows.inv_mass is None or rows.inv_inertia is None:
        return _NO_MASS, _NO_INERTIA
    c = np.ascontiguousarray
    return c(rows.inv_mass, dtype=float), c(rows.inv_inertia, dtype=float)
