"""Time of impact: the first time in ``(0, T]`` at which a pair that is apart now touches.

Motion over the interval is the one the stepper will integrate: centres ``x + v τ + a τ²/2``
(``a`` gravity plus the constant resting-contact force, per body ``(N,3)``), orientations by the
torque-free rotation of ``dynamics.rotate_free``. Roots:

* sphere–plane: the signed distance is a quadratic in τ, solved in closed form (stable formula);
* sphere–sphere with equal accelerations: ``|Δx + Δv τ|² = R²``, a quadratic, closed form;
* everything else: conservative advancement (Mirtich; the method of Bullet's and Box2D's time of
  impact): from a separation ``d`` the pair cannot touch sooner than ``d / w``, with ``w`` a bound
  on how fast any two points of the bodies close (relative speed, acceleration over the interval,
  spin × extent), so time advances by that much until the separation is below ``TOI_TOLERANCE`` ×
  the smaller body's size: never later than the true contact. Bounded: after ``MAX_ADVANCES``
  evaluations (a loose bound: a fast spin about the normal) the rest of the interval is sampled at
  most ``MAX_SAMPLES`` times and the first sign change refined by Brent's method, so a fast-spinning
  body costs a bounded amount per step instead of thousands of samples.

``toi = swept`` puts the lecture's swept-volume test (``response.swept``) before that search for
pairs that only translate during the step: closed-form roots along separating directions, a
conservative time of impact, no distance evaluations.

Candidate pairs come from the broad phase over the boxes bounding each body's path (O(N log N)):
a fast body among thousands at rest is tested against its neighbours along its path, not
against every body of the world.
"""
import numpy as np
from scipy.optimize import brentq

from .. import dynamics, quat
from ..kinds import DYNAMIC, KINEMATIC
from ..memo import derived
from ..shapes import Box, Plane, Polyhedron, Sphere
from .swept import mark_swept, swept_toi  # noqa: F401 (mark_swept: the stepper marks the sweep's contacts)

XTOL = 1e-15
TOI_TOLERANCE = 1e-9   # × the smaller body's size: a pair this close counts as touching at its impact time
MAX_ADVANCES = 16      # conservative-advancement evaluations per pair and search, then bounded sampling
MAX_SAMPLES = 32       # samples of the rest of the interval when advancement is slow (its bound is loose)


def plane_world(shape, pos, q):
    """World normal ``(3,)`` and offset of a plane shape posed at centre ``pos``, orientation ``q``."""
    n = quat.rotate(q, shape.normal)
    return n, shape.offset + float(n @ pos)


def _first_quadratic_root(c0, c1, c2, T):
    """Smallest τ in (0, T] with ``c0 + c1 τ + c2 τ² = 0`` crossing downward, for ``c0 > 0``;
    ``inf`` when there is none. Arrays ``(P,)``; stable (no cancellation) formula."""
    c0, c1, c2 = np.broadcast_arrays(np.asarray(c0, float), np.asarray(c1, float), np.asarray(c2, float))
    out = np.full(c0.shape, np.inf)
    disc = c1 * c1 - 4 * c2 * c0
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    qq = -0.5 * (c1 + np.where(c1 >= 0, sq, -sq))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(c2 != 0, qq / c2, np.inf)
        r2 = np.where(qq != 0, c0 / qq, np.inf)
    r1 = np.where(np.isfinite(r1), r1, np.inf)
    r2 = np.where(np.isfinite(r2), r2, np.inf)
    lo = np.minimum(np.where(r1 > 0, r1, np.inf), np.where(r2 > 0, r2, np.inf))
    hit = ok & (c0 > 0) & (lo <= T)
    out[hit] = lo[hit]
    return out


class Motion:
    """Body poses along the interval. ``pos, vel, acc (N,3)``, ``quat (N,4)``, ``omega (N,3)``."""

    def __init__(self, world, acc, rotating):
        s = world.s
        self.world = world
        self.pos, self.vel, self.acc = s.pos.copy(), s.vel.copy(), acc
        self.quat, self.omega = s.quat.copy(), s.omega.copy()
        self.rotating = rotating

    def pose(self, i, tau):
        """Centre ``(3,)`` and orientation ``(4,)`` of body ``i`` at ``tau``."""
        p = self.pos[i] + self.vel[i] * tau + 0.5 * self.acc[i] * tau * tau
        q = self.quat[i]
        if self.rotating[i] and np.any(self.omega[i]):
            s = self.world.s
            q, _ = dynamics.rotate_free(q[None], self.omega[i][None], s.principal_q[i][None],
                                        s.principal_moments[i][None], tau)
            q = q[0]
        elif self.world.kind[i] == KINEMATIC and np.any(self.omega[i]):
            q = quat.mul(quat.from_rotvec(self.omega[i] * tau), q)
        return p, q


def signed_distance(world, i, j, pi, qi, pj, qj):
    """Signed distance between bodies ``i`` and ``j`` at the given poses (negative: penetrating)."""
    si, sj = world.shapes[i], world.shapes[j]
    if isinstance(si, Plane) and not isinstance(sj, Plane):
        si, sj, pi, qi, pj, qj = sj, si, pj, qj, pi, qi
    if isinstance(sj, Plane):
        n, off = plane_world(sj, pj, qj)
        if isinstance(si, Sphere):
            return float(pi @ n - off - si.radius)
        if isinstance(si, Polyhedron):
            return float(np.min((pi + quat.rotate(qi, si.vertices)) @ n) - off)
    if isinstance(si, Sphere) and isinstance(sj, Sphere):
        return float(np.linalg.norm(pi - pj) - si.radius - sj.radius)
    if isinstance(si, Box) and isinstance(sj, Sphere):
        si, sj, pi, qi, pj, qj = sj, si, pj, qj, pi, qi
    if isinstance(si, Sphere) and isinstance(sj, Box):
        local = quat.rotate(quat.conj(qj), pi - pj)
        h = sj.half
        out = np.abs(local) - h
        outside = np.linalg.norm(np.maximum(out, 0.0))
        return float(outside + min(out.max(), 0.0) - si.radius)
    from ..collision import collide  # general pairs need the detection package

    big = 1e3
    c = collide(si, (pi, qi), sj, (pj, qj), margin=big)
    if len(c) == 0:
        return big
    return float(-np.max(c.depth))


def _extent(shape):
    if isinstance(shape, Sphere):
        return shape.radius
    if isinstance(shape, Polyhedron):
        return float(np.linalg.norm(shape.vertices, axis=1).max())
    return np.inf


def pair_toi(world, motion, i, j, T):
    """First touching time of bodies ``i, j`` in ``(0, T]`` (``inf`` if none)."""
    si, sj = world.shapes[i], world.shapes[j]
    m = motion
    # closed forms
    if isinstance(si, Plane) or isinstance(sj, Plane):
        pl, ot = (i, j) if isinstance(si, Plane) else (j, i)
        osh = world.shapes[ot]
        if isinstance(osh, Sphere) and not np.any(m.omega[pl]):
            n, off = plane_world(world.shapes[pl], m.pos[pl], m.quat[pl])
            c0 = m.pos[ot] @ n - off - osh.radius
            c1 = (m.vel[ot] - m.vel[pl]) @ n
            c2 = 0.5 * (m.acc[ot] - m.acc[pl]) @ n
            return float(_first_quadratic_root(c0, c1, c2, T))
    if isinstance(si, Sphere) and isinstance(sj, Sphere) and np.allclose(m.acc[i], m.acc[j], rtol=0, atol=0):
        dx = m.pos[i] - m.pos[j]
        dv = m.vel[i] - m.vel[j]
        R = si.radius + sj.radius
        # |dx|² - R² = (|dx| - R)(|dx| + R): compute c0 without cancellation
        c0 = (np.linalg.norm(dx) - R) * (np.linalg.norm(dx) + R)
        return float(_first_quadratic_root(c0, 2 * dx @ dv, dv @ dv, T))
    # conservative advancement
    def f(tau):
        pi, qi = m.pose(i, tau)
        pj, qj = m.pose(j, tau)
        return signed_distance(world, i, j, pi, qi, pj, qj)

    tol = TOI_TOLERANCE * min(_extent(si), _extent(sj))
    rate = _closing_bound(m, i, j, T, _extent(si), _extent(sj))
    if rate <= 0:
        return np.inf
    tau, d = 0.0, f(0.0)
    if d <= 0:
        return np.inf
    for _ in range(MAX_ADVANCES):
        if d <= tol:
            return tau
        nxt = tau + d / rate
        if nxt > T:
            return np.inf
        dn = f(nxt)
        if dn < 0:   # the bound was beaten by round-off: the root is between the two, find it exactly
            return float(brentq(f, tau, nxt, xtol=XTOL, rtol=4 * np.finfo(float).eps))
        tau, d = nxt, dn
    # the bound is far from the motion (a fast spin about the contact normal closes nothing): sample
    # the rest of the interval finely enough that neither body moves more than half the thinner one
    # between samples, at most MAX_SAMPLES times, and refine the first sign change exactly
    thin = min(si.thinnest(), sj.thinnest())
    n = int(np.clip(np.ceil(rate * (T - tau) / (0.5 * thin)), 1, MAX_SAMPLES))
    prev = tau
    for t in np.linspace(tau, T, n + 1)[1:]:
        ft = f(t)
        if ft <= tol:
            return float(brentq(f, prev, t, xtol=XTOL, rtol=4 * np.finfo(float).eps)) if ft < 0 else t
        prev = t
    return np.inf


def _closing_bound(m, i, j, T, ext_i, ext_j):
    """An upper bound (m/s) on how fast any point of body ``i`` can approach any point of body
    ``j`` during ``[0, T]``: relative centre speed, plus what the relative acceleration adds over the
    interval, plus each body's largest spin over its torque-free motion (``max_spin``) times its
    extent."""
    rel = float(np.linalg.norm(m.vel[i] - m.vel[j]) + np.linalg.norm(m.acc[i] - m.acc[j]) * T)
    for k, ext in ((i, ext_i), (j, ext_j)):
        if np.isfinite(ext) and np.any(m.omega[k]):
            rel += max_spin(m, k) * ext
    return rel


def max_spin(m, k):
    """The largest ``|ω|`` (rad/s) body ``k`` reaches in torque-free motion from its current spin:
    with ``pᵢ = Πᵢ²`` (principal-frame angular momentum), ``|ω|² = Σ pᵢ/Iᵢ²`` is largest at a vertex
    of ``{p ≥ 0: Σ pᵢ = |L|², Σ pᵢ/Iᵢ = 2E}`` (both conserved). A body spinning about a principal
    axis keeps its ``|ω|`` exactly (the set is that one point); the crude ``|ω|·I_max/I_min`` is only
    the fallback."""
    w = m.omega[k]
    s = m.world.s
    mom = s.principal_moments[k]
    if m.world.kind[k] != DYNAMIC or not np.all(np.isfinite(mom)) or mom.min() <= 0:
        return float(np.linalg.norm(w))            # kinematic: spins as told; particles do not spin
    qp = quat.mul(s.quat[k], s.principal_q[k])
    pi = mom * quat.rotate(quat.conj(qp), w)
    p = pi * pi
    l2, e2 = p.sum(), (p / mom).sum()
    best = (p / mom ** 2).sum()
    for z in range(3):   # vertices: one pᵢ = 0, the other two from the two conserved sums
        a, b = [x for x in range(3) if x != z]
        det = 1.0 / mom[b] - 1.0 / mom[a]
        if abs(det) <= 1e-12 / mom[a]:
            continue
        pb = (e2 - l2 / mom[a]) / det
        pa = l2 - pb
        if pa >= -1e-12 * l2 and pb >= -1e-12 * l2:
            best = max(best, max(pa, 0.0) / mom[a] ** 2 + max(pb, 0.0) / mom[b] ** 2)
    return float(np.sqrt(best))


def _extents(world):
    """Bounding radius per body ``(N,)`` (inf for planes), cached on the world."""
    return derived(world, "extents", (), lambda: np.array([_extent(sh) for sh in world.shapes]), key=len(world))


def candidate_pairs(world, motion, T, exclude, swept=False, only=None):
    """Pairs ``(i, j)`` (two ``(P,) int`` arrays, ``i < j``) that may touch within ``T``: the
    spheres bounding their paths overlap, found by the broad phase over the boxes of those spheres
    (O(N log N)); planes against every path that reaches them. Pairs without a dynamic body, pairs
    whose collision groups exclude each other and pairs in ``exclude`` (keys ``min·N + max (E,)``,
    those already in contact) are skipped, and so are pairs with no relative motion at all. With
    ``only`` (body indices), pairs without one of those bodies are skipped too."""
    from ..collision import broadphase

    n = len(world)
    kind = world.kind
    ext = _extents(world)
    m = motion
    mid = m.pos + 0.5 * m.vel * T + 0.125 * m.acc * T * T
    half_path = 0.5 * np.linalg.norm(m.vel * T + 0.5 * m.acc * T * T, axis=1) + 0.125 * np.linalg.norm(m.acc, axis=1) * T * T
    rad = ext + half_path
    finite = np.flatnonzero(np.isfinite(rad))
    i, j = broadphase.candidate_pairs(mid[finite], np.repeat(rad[finite, None], 3, axis=1), 0.0)
    i, j = finite[i], finite[j]
    planes = np.flatnonzero(~np.isfinite(rad))
    if planes.size and finite.size:
        typ = _types(world)
        pl = planes[typ[planes] == 0]
        if pl.size:
            nw = quat.rotate(m.quat[pl], np.array([world.shapes[x].normal for x in pl]))
            off = np.array([world.shapes[x].offset for x in pl]) + np.einsum("ij,ij->i", nw, m.pos[pl])
            # a plane moves (kinematic): widen by its own path
            reach = rad[finite][None, :] + (np.linalg.norm(m.vel[pl], axis=1) * T)[:, None]
            p, f = np.nonzero(mid[finite] @ nw.T - off[None, :] <= reach.T)   # (finite, plane) pairs
            pi, fi = pl[f], finite[p]
            i, j = np.concatenate([i, np.minimum(pi, fi)]), np.concatenate([j, np.maximum(pi, fi)])
        other = planes[typ[planes] != 0]   # unbounded meshes (none today): every finite body
        if other.size:
            oi, fi = np.repeat(other, finite.size), np.tile(finite, other.size)
            i, j = np.concatenate([i, np.minimum(oi, fi)]), np.concatenate([j, np.maximum(oi, fi)])
    ok = (kind[i] == DYNAMIC) | (kind[j] == DYNAMIC)
    g, mk = world.group, world.mask
    ok &= ((g[i] & mk[j]) != 0) & ((g[j] & mk[i]) != 0)
    # no relative motion: a pair apart now stays apart
    still = ~(np.any(m.vel[i] != m.vel[j], axis=1) | np.any(m.acc[i] != m.acc[j], axis=1)
              | np.any(m.omega[i] != 0, axis=1) | np.any(m.omega[j] != 0, axis=1))
    ok &= ~still
    if only is not None:
        sel = np.zeros(n, bool)
        sel[list(only)] = True
        ok &= sel[i] | sel[j]
    i, j = i[ok], j[ok]
    if len(exclude):
        keep = ~np.isin(i * n + j, exclude)
        i, j = i[keep], j[keep]
    return i, j


def _closed_form_tois(world, motion, i, j, T):
    """First touching times ``(P,)`` in ``(0, T]`` of pairs ``(i, j)`` that have a closed form
    (sphere–plane with a non-spinning plane; sphere–sphere with equal accelerations), ``nan``
    for the pairs that need the sampled search. Vectorised over pairs."""
    m = motion
    shapes = world.shapes
    typ = _types(world)
    out = np.full(len(i), np.nan)
    is_plane_i, is_plane_j = typ[i] == 0, typ[j] == 0
    # sphere–plane
    sp = (is_plane_i & (typ[j] == 1)) | (is_plane_j & (typ[i] == 1))
    pl = np.where(is_plane_i, i, j)
    ot = np.where(is_plane_i, j, i)
    sp &= ~np.any(m.omega[pl] != 0, axis=1)
    if sp.any():
        k = np.flatnonzero(sp)
        P, O = pl[k], ot[k]
        normals = np.array([shapes[x].normal for x in P])
        offsets = np.array([shapes[x].offset for x in P])
        nw = quat.rotate(m.quat[P], normals)
        off = offsets + np.einsum("ij,ij->i", nw, m.pos[P])
        r = np.array([shapes[x].radius for x in O])
        c0 = np.einsum("ij,ij->i", m.pos[O], nw) - off - r
        c1 = np.einsum("ij,ij->i", m.vel[O] - m.vel[P], nw)
        c2 = 0.5 * np.einsum("ij,ij->i", m.acc[O] - m.acc[P], nw)
        out[k] = _first_quadratic_root(c0, c1, c2, T)
    # sphere–sphere with equal accelerations
    ss = (typ[i] == 1) & (typ[j] == 1) & np.all(m.acc[i] == m.acc[j], axis=1)
    if ss.any():
        k = np.flatnonzero(ss)
        I, J = i[k], j[k]
        dx = m.pos[I] - m.pos[J]
        dv = m.vel[I] - m.vel[J]
        R = np.array([shapes[x].radius for x in I]) + np.array([shapes[x].radius for x in J])
        d = np.linalg.norm(dx, axis=1)
        # |dx|² - R² = (|dx| - R)(|dx| + R): c0 without cancellation
        out[k] = _first_quadratic_root((d - R) * (d + R), 2 * np.einsum("ij,ij->i", dx, dv),
                                       np.einsum("ij,ij->i", dv, dv), T)
    return out


def _types(world):
    """Shape type code per body ``(N,)``: 0 plane, 1 sphere, 2 other (cached on the world)."""
    return derived(world, "shape_types", (), lambda: np.array(
        [0 if isinstance(sh, Plane) else 1 if isinstance(sh, Sphere) else 2 for sh in world.shapes], np.int64),
        key=len(world))


def earliest_event(world, motion, T, exclude, swept=False, only=None):
    """``(τ, (i, j))`` of the first touching event in ``(0, T]`` or ``(inf, None)``.

    Closed-form pairs are solved together (vectorised); the pairs that need the sampled search
    (``pair_toi``: bracket + Brent, inherently one root at a time) are searched only up to the
    earliest closed-form time, nearest paths first. With ``swept`` the other pairs get the
    swept-volume test first (``response.swept``: closed-form roots along separating directions,
    for pairs that only translate), and the search only where it cannot decide;
    ``motion.swept_pair`` is then the pair when the event came from a sweep (else ``None``)."""
    motion.swept_pair = None
    i, j = candidate_pairs(world, motion, T, exclude, swept, only)
    if len(i) == 0:
        return np.inf, None
    tau = _closed_form_tois(world, motion, i, j, T)
    best, pair = np.inf, None
    closed = np.isfinite(tau)
    if closed.any():
        k = int(np.argmin(np.where(closed, tau, np.inf)))
        best, pair = float(tau[k]), (int(i[k]), int(j[k]))
    for k in np.flatnonzero(np.isnan(tau)):   # general shapes: the sweep, else the scalar root search
        t = swept_toi(world, motion, int(i[k]), int(j[k]), min(T, best)) if swept else np.nan
        by_sweep = not np.isnan(t)
        if not by_sweep:
            t = pair_toi(world, motion, int(i[k]), int(j[k]), min(T, best))
        if t < best:
            best, pair = t, (int(i[k]), int(j[k]))
            motion.swept_pair = pair if by_sweep else None
    return best, pair
