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
  body costs a bounded amount per step instead of thousands of samples. The search of a pair is
  one compiled call (``advancement``); ``COUNTS`` counts its distance evaluations.

``toi = swept`` puts the lecture's swept-volume test (``response.swept``) before that search for
pairs that only translate during the step: closed-form roots along separating directions, a
conservative time of impact, no distance evaluations.

Candidate pairs come from the broad phase over the boxes bounding each body's path (O(N log N)):
a fast body among thousands at rest is tested against its neighbours along its path, not
against every body of the world.
"""
import numpy as np

from .. import quat
from ..kinds import DYNAMIC
from ..memo import derived
from ..shapes import Box, Plane, Sphere
from . import advancement, compliance
from .bounds import _extent, _extents, _first_quadratic_root  # noqa: F401 (_extent: tests)
from .swept import swept_toi
from ..constants import MAX_ADVANCES, MAX_SAMPLES, MAX_SPLIT_ANGLE, MAX_SUBSTEPS, RTOL, TOI_DEEPEN, TOI_TOLERANCE, XTOL

_SPLIT = (MAX_SPLIT_ANGLE, float(MAX_SUBSTEPS))   # the free rotation's sub-step rule
COUNTS = {"distance_evaluations": 0}   # the searches' distance evaluations (for tests and benchmarks)


def plane_world(shape, pos, q):
    """World normal ``(3,)`` and offset of a plane shape posed at centre ``pos``, orientation ``q``."""
    n = quat.rotate(q, shape.normal)
    return n, shape.offset + float(n @ pos)


class Motion:
    """Body poses along the interval. ``pos, vel, acc (N,3)``, ``quat (N,4)``, ``omega (N,3)``."""

    def __init__(self, world, acc, rotating):
        s = world.s
        self.world = world
        self.pos, self.vel, self.acc = s.pos.copy(), s.vel.copy(), acc
        self.quat, self.omega = s.quat.copy(), s.omega.copy()
        self.rotating = rotating
        self._arrays = None

    def arrays(self):
        """``(motion, flags)`` as the compiled search reads them (``advancement``): ``(pos, vel, acc,
        quat, omega, principal_q, moments)`` and ``(N, 3)`` bool (rotating, kinematic, dynamic)."""
        if self._arrays is None:
            s, bm, c = self.world.s, self.world.body_masks(), np.ascontiguousarray
            self._arrays = ((c(self.pos, dtype=float), c(self.vel, dtype=float), c(self.acc, dtype=float),
                             c(self.quat, dtype=float), c(self.omega, dtype=float), c(s.principal_q, dtype=float),
                             c(s.principal_moments, dtype=float)),
                            np.stack([np.asarray(self.rotating, bool), bm.kinematic, bm.dynamic], axis=1))
        return self._arrays

    def pose(self, i, tau):
        """Centre ``(3,)`` and orientation ``(4,)`` of body ``i`` at ``tau`` (``advancement.pose``)."""
        motion, flags = self.arrays()
        p, q = np.empty((1, 3)), np.empty((1, 4))
        advancement.pose(i, float(tau), motion, flags, _SPLIT, p, q, 0)
        return p[0], q[0]


def signed_distance(world, i, j, pi, qi, pj, qj):
    """Signed distance between bodies ``i`` and ``j`` at the given poses (negative: penetrating):
    closed forms for a plane, two spheres, a sphere and a box, else the pair's narrow phase
    (``advancement.distance``)."""
    which, bvh = _pair_kernel(world, i, j)
    b = _geometry(world)
    code, facts, verts, vrange = _shape_facts(world)
    p = np.array([pi, pj], dtype=float)
    q = np.array([qi, qj], dtype=float)
    rows = advancement.pair_rows(int(i), int(j), b.shape_of, b.rank)
    return float(advancement.distance(which, b.geom.arrays(), bvh, rows, code, facts, verts, vrange,
                                      int(i), int(j), p, q, np.empty((2, 3, 3)), np.empty((4, 3), np.int64),
                                      np.empty((4, 7))))


def pair_toi(world, motion, i, j, T, in_contact=False):
    """First touching time of bodies ``i, j`` in ``(0, T]`` (``inf`` if none). A pair
    ``in_contact`` (touching now) has no first touch to find: its event is the first time it sinks
    ``TOI_DEEPEN`` × the thinner body's thinnest size deeper than now (another feature swinging in;
    the conservative search, never a closed form)."""
    si, sj = world.shapes[i], world.shapes[j]
    m = motion
    if not in_contact:   # closed forms
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
    # conservative advancement, compiled (advancement.search): the closing-speed bound is relative
    # centre speed, plus what the relative acceleration adds over the interval, plus each body's
    # largest spin over its torque-free motion (max_spin) times its extent
    which, bvh = _pair_kernel(world, i, j)
    if which < 0:
        return np.inf
    b = _geometry(world)
    code, facts, verts, vrange = _shape_facts(world)
    motion, flags = m.arrays()
    t, evals = advancement.search(which, b.geom.arrays(), bvh, b.shape_of, b.rank, code, facts, verts, vrange,
                                  motion, flags, _SPLIT, int(i), int(j), float(T), TOI_TOLERANCE, MAX_ADVANCES,
                                  MAX_SAMPLES, XTOL, RTOL, TOI_DEEPEN if in_contact else 0.0)
    COUNTS["distance_evaluations"] += evals
    return float(t)


def _geometry(world):
    from ..collision import _bodies_of   # the detection package's per-world shape tables

    return _bodies_of(world)


def _pair_kernel(world, i, j):
    """``(which, trees)``: the narrow-phase kernel of bodies ``i, j`` as ``collision.pair_kernels``
    numbers it (−1 for a pair no kernel takes: plane–plane), and the mesh trees it may need."""
    from ..collision import pair_kernels

    b = _geometry(world)
    ra, rb = int(b.rank[i]), int(b.rank[j])
    return pair_kernels.index(max(ra, rb), min(ra, rb)), pair_kernels.trees(b.geom)


def _shape_facts(world):
    """``(code (N,), facts (N, 10), verts (M, 3), vrange (N, 2))`` of ``advancement`` (cached)."""
    def build():
        n = len(world)
        code = np.empty(n, np.int64)
        facts = np.zeros((n, 10))
        vrange = np.zeros((n, 2), np.int64)
        verts = []
        start = 0
        facts[:, advancement.F_EXTENT] = _extents(world)
        for k, sh in enumerate(world.shapes):
            facts[k, advancement.F_THIN] = sh.thinnest()
            if isinstance(sh, Plane):
                code[k] = advancement.D_PLANE
                facts[k, 0:3], facts[k, advancement.F_OFFSET] = sh.normal, sh.offset
            elif isinstance(sh, Sphere):
                code[k] = advancement.D_SPHERE
                facts[k, advancement.F_RADIUS] = sh.radius
            else:   # every other shape is a polyhedron (boxes, hulls, cylinders, meshes)
                code[k] = advancement.D_BOX if isinstance(sh, Box) else advancement.D_POLY
                if isinstance(sh, Box):
                    facts[k, advancement.F_HALF:advancement.F_HALF + 3] = sh.half
                v = np.asarray(sh.vertices, float)
                verts.append(v)
                vrange[k] = start, len(v)
                start += len(v)
        verts = np.ascontiguousarray(np.concatenate(verts)) if verts else np.zeros((0, 3))
        return code, facts, verts, vrange

    return derived(world, "shape_facts", (), build, key=len(world))


def candidate_pairs(world, motion, T, exclude, swept=False, only=None):
    """Pairs ``(i, j)`` (two ``(P,) int`` arrays, ``i < j``) that may touch within ``T``: the
    spheres bounding their paths overlap, found by the broad phase over the boxes of those spheres
    (O(N log N)); planes against every path that reaches them. Pairs without a dynamic body, pairs
    whose collision groups exclude each other and pairs in ``exclude`` (keys ``min·N + max (E,)``:
    ``world.disabled_pairs``) are skipped, and so are pairs with no relative motion at all. With
    ``only`` (body indices), pairs without one of those bodies are skipped too."""
    from ..collision import broadphase

    n = len(world)
    m = motion
    motion_arrays, _ = m.arrays()
    pos, vel, acc, q, omega = motion_arrays[:5]
    mid, rad = np.empty((n, 3)), np.empty(n)
    advancement.path_spheres(pos, vel, acc, _extents(world), float(T), mid, rad)
    finite = np.flatnonzero(np.isfinite(rad))
    bi, bj = broadphase.candidate_pairs(mid[finite], np.repeat(rad[finite, None], 3, axis=1), 0.0)
    # the only bodies without a finite extent are planes (every other shape is a sphere or a polyhedron)
    code, facts = _shape_facts(world)[:2]
    planes = np.flatnonzero(code == advancement.D_PLANE) if finite.size else np.zeros(0, np.int64)
    only_mask = np.zeros(0, bool)
    if only is not None:
        only_mask = np.zeros(n, bool)
        only_mask[list(only)] = True
    size = len(bi) + finite.size * planes.size
    out_i, out_j = np.empty(size, np.int64), np.empty(size, np.int64)
    k = advancement.path_pairs(finite[bi], finite[bj], finite, planes, pos, q, vel, acc, omega, mid, rad, facts,
                               float(T), world.kind, DYNAMIC, world.group, world.mask, only_mask,
                               np.sort(np.asarray(exclude, np.int64)), out_i, out_j)
    return out_i[:k], out_j[:k]


def _closed_form_tois(world, motion, i, j, T):
    """First touching times ``(P,)`` in ``(0, T]`` of pairs ``(i, j)`` that have a closed form
    (sphere–plane with a non-spinning plane; sphere–sphere with equal accelerations), ``nan``
    for the pairs that need the sampled search. Vectorised over pairs."""
    m = motion
    shapes = world.shapes
    typ = _shape_facts(world)[0]
    plane, sphere = advancement.D_PLANE, advancement.D_SPHERE
    out = np.full(len(i), np.nan)
    is_plane_i, is_plane_j = typ[i] == plane, typ[j] == plane
    # sphere–plane
    sp = (is_plane_i & (typ[j] == sphere)) | (is_plane_j & (typ[i] == sphere))
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
    ss = (typ[i] == sphere) & (typ[j] == sphere) & np.all(m.acc[i] == m.acc[j], axis=1)
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


def earliest_event(world, motion, T, held, swept=False, only=None, soft=False):
    """``(τ, (i, j))`` of the first event in ``(0, T]`` or ``(inf, None)``: a pair apart touching,
    or a pair in contact (``held``: keys ``min·N + max (H,)``) sinking ``TOI_DEEPEN`` × its thinner
    body's thinnest size deeper than now (``pair_toi``'s ``in_contact``). The contacts of a pair in
    contact hold its touching features; another feature can swing in within the step (a spinning
    sliver wedged against a box turned its far corners 3 cm into it when such pairs were not
    searched). Sphere–plane and sphere–sphere pairs of a closed form have one feature, which their
    contact holds: in contact, they have no event; nor have compliant pairs (with ``soft``, the
    step's compliant contact: ``compliance.compliant_pairs``), whose depth is their springs'
    deflection (a finger squeezing a part).

    Closed-form pairs are solved together (vectorised); the pairs that need the sampled search
    (``pair_toi``: bracket + Brent, inherently one root at a time) are searched only up to the
    earliest closed-form time, nearest paths first. With ``swept`` the other pairs apart get the
    swept-volume test first (``response.swept``: closed-form roots along separating directions,
    for pairs that only translate), and the search only where it cannot decide;
    ``motion.swept_pair`` is then the pair when the event came from a sweep (else ``None``)."""
    motion.swept_pair = None
    from ..collision import disabled_keys

    never = disabled_keys(world) if world.disabled_pairs else np.zeros(0, np.int64)
    i, j = candidate_pairs(world, motion, T, never, swept, only)
    if len(i) == 0:
        return np.inf, None
    tau = _closed_form_tois(world, motion, i, j, T)
    in_contact = np.zeros(len(i), bool)
    if len(held):
        held = np.sort(held)
        keys = i * len(world) + j
        in_contact = held[np.minimum(np.searchsorted(held, keys), len(held) - 1)] == keys
        tau[in_contact & ~np.isnan(tau)] = np.inf
        if soft:
            tau[in_contact & compliance.compliant_pairs(world, i, j)] = np.inf
        # which pairs in contact can sink deeper within T: two convex shapes that only translate
        # cannot (the solve left their contact points at a normal speed and acceleration that do not
        # close, the resting force being in ``motion.acc``, and a translation moves every point as
        # those: their overlap along the contact normal, which bounds the depth, does not grow); a
        # spin moves each point of a surface at most its reach × the time (``spin_reach``) from
        # where the translation takes it, so the depth grows by at most the pair's summed reach × T.
        # A concave mesh can meet another of its own faces by translation alone: always searched
        code, facts = _shape_facts(world)[:2]
        reach = np.empty(len(world))
        advancement.spin_reach(*motion.arrays(), code, facts, reach)
        target = TOI_DEEPEN * np.minimum(facts[i, advancement.F_THIN], facts[j, advancement.F_THIN])
        convex = derived(world, "convex", (), lambda: np.array([sh.convex for sh in world.shapes], bool),
                         key=len(world))
        still = in_contact & convex[i] & convex[j] & ~((reach[i] + reach[j]) * T > target)
        tau[still] = np.inf
    best, pair = np.inf, None
    closed = np.isfinite(tau)
    if closed.any():
        k = int(np.argmin(np.where(closed, tau, np.inf)))
        best, pair = float(tau[k]), (int(i[k]), int(j[k]))
    for k in np.flatnonzero(np.isnan(tau)):   # general shapes: the sweep, else the scalar root search
        t = swept_toi(world, motion, int(i[k]), int(j[k]), min(T, best)) if swept and not in_contact[k] else np.nan
        by_sweep = not np.isnan(t)
        if not by_sweep:
            t = pair_toi(world, motion, int(i[k]), int(j[k]), min(T, best), bool(in_contact[k]))
        if t < best:
            best, pair = t, (int(i[k]), int(j[k]))
            motion.swept_pair = pair if by_sweep else None
    return best, pair
