"""Swept-volume time of impact (the lecture's method, ``settings.toi = swept``).

Over the rest of a step ``[0, T]`` a body that only translates sweeps out a volume: a sphere a
capsule, a polyhedron the hull of its vertices at both ends of the translation. If part of another
body is inside that volume, it was hit. For a pair that both move, the volume is the one swept
relative to the other body (relative motion), so a pair counts as one moving body against one at
rest.

The test is done with separating planes, as the convex narrow phase does: along a direction ``n``
the swept volume's extent is the union of the moving body's extents along the path, and the pair
can only touch while the two extents overlap along *every* direction at once. The directions are
the face normals of both shapes (a mesh: those of its convex hull, which contains it; a plane: its
normal alone). The centres move by ``x + v τ + a τ²/2`` (gravity and the resting force included, as
the stepper integrates them), so along a fixed direction the gap between the two extents is a
quadratic in ``τ`` and the time it first closes is a root in closed form (no distance
evaluations, no root search). Then:

* a direction along which the extents never overlap in ``[0, T]`` is a plane that separates the
  whole swept volume from the other body: **no hit** (exact);
* otherwise the pair cannot touch before the **latest of the first-overlap times** over the
  directions (each one must overlap at the instant of contact): that time is returned, **never
  later than the true time of impact**, and exactly it when the last direction to close is the
  contact's normal (a body meeting a face or a plane). When it is earlier (the bodies pass close by
  an edge that no face direction separates) the stepper advances to it, finds no contact, and the
  next search for that pair, now overlapping along every direction, goes to the root search;
* pairs where the sweep cannot decide return ``nan`` and the caller uses ``toi.pair_toi``
  (``fractional``'s conservative advancement): a body that **rotates** during the step (its swept
  volume is no hull of its two end positions: rotation is outside the method, as the lecture says;
  a spin that moves no point farther than the touching tolerance over the step counts as none),
  pairs already overlapping along every direction at the start, and a plane that spins.

Sphere–plane and sphere–sphere pairs keep their closed forms (the capsule's exact root).
``COUNTS`` counts the sweeps done (``sweeps``) next to ``toi``'s distance evaluations, for tests and
benchmarks.
"""
import numpy as np

from .. import quat
from ..shapes import Plane, Sphere
from ..constants import TOI_TOLERANCE
from .bounds import _extents, _first_quadratic_root, max_spin

COUNTS = {"sweeps": 0}


def _axes_and_support(world, k, q):
    """World directions ``(A, 3)`` a body contributes (its face normals; none for a sphere) and its
    vertices ``(V, 3)`` relative to its centre (``None`` for a sphere), at orientation ``q``."""
    sh = world.shapes[k]
    if isinstance(sh, Sphere):
        return np.zeros((0, 3)), None
    if sh.convex:
        normals = sh.plane_normals
    else:
        from ..collision import bounding
        normals = bounding.bounds(sh).hull_n
    R = quat.to_matrix(q)
    return normals @ R.T, sh.vertices @ R.T


def _extent(sh, verts, axes):
    """Lowest and highest ``(A,)`` projection of a body on ``axes`` relative to its centre."""
    if verts is None:
        r = sh.radius
        z = np.zeros(len(axes))
        return z - r, z + r
    p = verts @ axes.T
    return p.min(axis=0), p.max(axis=0)


def _first_entry(c0, c1, c2, T, tol):
    """First ``τ`` in ``[0, T]`` with ``c0 + c1 τ + c2 τ² ≤ 0`` per row (``0`` where already so),
    ``inf`` where never. A gap within ``tol`` of touching that only opens over the interval (a pair
    leaving a contact: ``c1 ≥ 0`` and ``c1 + 2 c2 T ≥ 0``) never closes: ``inf``."""
    out = np.zeros(len(c0))
    apart = c0 > 0
    if apart.any():
        out[apart] = _first_quadratic_root(c0[apart], c1[apart], c2[apart], T)
    leaving = ~apart & (c0 >= -tol) & (c1 >= 0) & (c1 + 2 * c2 * T >= 0)
    out[leaving] = np.inf
    return out


def swept_toi(world, motion, i, j, T):
    """First time ``τ`` in ``(0, T]`` at which the volume body ``i`` sweeps relative to body ``j``
    (or the reverse) can reach the other: conservative (never later than the true time of impact);
    ``inf`` when a separating plane clears the whole sweep; ``nan`` when the method does not apply
    (a rotating body, a spinning plane, a pair already overlapping along every direction)."""
    m = motion
    ext = _extents(world)
    tol = TOI_TOLERANCE * float(min(ext[i], ext[j]))
    for k in (i, j):
        # rotation during the step is outside the method; a spin that moves no point by more than
        # the touching tolerance over the step (round-off left by a flat landing) is none
        if np.any(m.omega[k]) and not (np.isfinite(ext[k]) and max_spin(m, k) * T * ext[k] <= tol):
            return np.nan
    COUNTS["sweeps"] += 1
    si, sj = world.shapes[i], world.shapes[j]
    dx = m.pos[i] - m.pos[j]
    dv = m.vel[i] - m.vel[j]
    da = 0.5 * (m.acc[i] - m.acc[j])
    if isinstance(si, Plane) or isinstance(sj, Plane):
        pl, ot, sgn = (i, j, -1.0) if isinstance(si, Plane) else (j, i, 1.0)
        n = quat.rotate(m.quat[pl], world.shapes[pl].normal)
        off = world.shapes[pl].offset + float(n @ m.pos[pl])
        axes, verts = _axes_and_support(world, ot, m.quat[ot])
        lo, _ = _extent(world.shapes[ot], None if verts is None else verts, n[None, :])
        # the gap of the body's lowest point above the plane: a quadratic in τ
        c0 = float(m.pos[ot] @ n + lo[0] - off)
        tau = _first_entry(np.array([c0]), np.array([sgn * float(dv @ n)]), np.array([sgn * float(da @ n)]), T,
                           tol)[0]
        return np.nan if tau == 0.0 else float(tau)
    ai, vi = _axes_and_support(world, i, m.quat[i])
    aj, vj = _axes_and_support(world, j, m.quat[j])
    axes = np.concatenate([ai, aj])
    if len(axes) == 0:
        return np.nan          # two spheres with different accelerations: their root search
    lo_i, hi_i = _extent(si, vi, axes)
    lo_j, hi_j = _extent(sj, vj, axes)
    # along n the extents overlap iff L ≤ r(τ) ≤ U, r = n·(x_i − x_j) a quadratic in τ
    r0, r1, r2 = axes @ dx, axes @ dv, axes @ da
    U, L = hi_j - lo_i, lo_j - hi_i
    above = _first_entry(r0 - U, r1, r2, T, tol)     # coming down to U
    below = _first_entry(L - r0, -r1, -r2, T, tol)   # coming up to L
    entry = np.maximum(above, below)                 # one of them is 0 (U ≥ L)
    tau = float(entry.max())
    if tau == 0.0:
        return np.nan          # overlapping along every direction already: the sweep cannot tell
    return tau


def mark_swept(contacts, pair):
    """Set the feature of the contacts of ``pair = (i, j)`` (either order) to ``swept``: the
    contacts the sweep found, detected at its time of impact. Returns ``contacts``."""
    if pair is None or len(contacts) == 0:
        return contacts
    from ..collision.manifold import F_SWEPT

    a, b = contacts.body_a, contacts.body_b
    hit = ((a == pair[0]) & (b == pair[1])) | ((a == pair[1]) & (b == pair[0]))
    if hit.any():
        contacts.feature = contacts.feature.copy()
        contacts.feature[hit] = F_SWEPT
    return contacts
