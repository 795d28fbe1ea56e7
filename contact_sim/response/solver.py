"""Contact impulse solver: a pure function of body arrays and contact arrays.

Rows are built by a kernel; the exact active-set solve (up to ``DIRECT_MAX_CONTACTS`` contacts)
runs island by island in a compiled kernel, dense per island (``direct``, ``active_set``), sparse
for islands too large for it; projected Gauss–Seidel, for larger systems and to finish an island
whose friction slides, is a compiled sequential loop over the contacts (``pgs.sweeps``):
sequential, so each contact sees every impulse before it (a graph-coloured, vectorised sweep
converges slower and costs more per sweep in numpy).

Notation (shapes): ``N`` bodies, ``K`` contacts. Body arrays: ``vel (N,3)``, ``omega (N,3)``,
``inv_mass (N,)``, ``inv_inertia (N,3,3)`` world frame (zero for particles/static/kinematic).
Contact arrays: ``a, b (K,) int``, ``point (K,3)``, ``normal (K,3)`` unit from B to A.

Three uses of the same machinery:

* ``impact``: instantaneous impulses with restitution (the lecture's
  ``j = -(1+e) v_rel / (1/M_A + 1/M_B + n·(I_A⁻¹(r_A×n)×r_A + I_B⁻¹(r_B×n)×r_B))``, generalised to
  many simultaneous contacts with Coulomb friction; one contact converges in one iteration to the
  formula exactly).
* ``resting``: the contact impulse that acts as a constant force over the rest of the step
  (held against gravity): the normal and friction constraints are on the velocity at the *end* of
  the interval (never approaching; sticking means stopped).
* ``position``: split-impulse pseudo-velocities that push penetrating bodies apart; they move
  positions only and are thrown away, so no energy is added.
"""
import numpy as np

from ..jit import njit, objmode
from ..settings import SOLVER_METHODS
from . import pgs
from .active_set import SOLVED, TOO_LARGE, islands, solve_islands
from ..constants import (DIRECT_CONSISTENCY, DIRECT_FIRST, DIRECT_ISLAND_MAX, DIRECT_MAX_CONTACTS, DIRECT_MAX_ROUNDS,
                         DIRECT_REGULARISATION, PGS_STALL_SWEEPS)
from .direct import _active_set, delassus, solve_direct, solve_exact
from .pgs import apply_ids, sweeps
from .rows import _TINY, Rows, SolveResult, apply, body_mass, build_rows, row_velocity

__all__ = ["Rows", "SolveResult", "apply", "build_rows", "delassus", "row_velocity", "solve", "solve_auto",
           "solve_direct", "solve_jacobi", "solve_rows"]



def solve(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, iterations=20, tolerance=1e-9, warm=None,
          compliance=None, stall=PGS_STALL_SWEEPS):
    """Projected Gauss–Seidel, sequential over the contacts in a compiled loop (``pgs.sweeps``),
    updating ``vel, omega (N,3)`` in place.

    Normal row: ``n·v_rel ≥ target_n`` with a non-negative impulse (complementarity: zero impulse
    where the row is satisfied, i.e. separating).
    Friction rows (when ``mu_s``/``mu_d (K,)`` are given): tangential relative velocity driven to
    zero by a 2-D impulse kept in the cone: if the sticking impulse is within ``mu_s·λn`` it is
    taken, otherwise the impulse on the kinetic disc ``mu_d·λn`` nearest to it in the contact's
    metric (kinetic friction, maximal dissipation). ``warm (K,3)`` starting impulses (applied
    first). ``compliance (K,)`` softens the normal rows to ``n·v_rel + compliance·λn ≥ target_n``
    (the implicit spring–damper of the penalty response). Sweeps stop when no contact's velocity
    changed by more than ``tolerance`` (m/s), after ``iterations``, or after ``stall`` sweeps in a
    row without a new smallest change (0: never; ``pgs.sweeps``). Returns ``SolveResult``.
    """
    k = len(rows.a)
    lam = np.zeros((k, 3)) if warm is None else np.array(warm, dtype=float)
    if k == 0:
        return SolveResult(lam, 0, 0.0)
    if warm is not None and np.any(warm):
        apply(rows, vel, omega, lam)
    friction = mu_s is not None and bool(np.any(mu_s > 0))
    zeros = np.zeros(k)
    comp = zeros if compliance is None else np.ascontiguousarray(compliance, dtype=float)
    mus = np.ascontiguousarray(mu_s, dtype=float) if friction else zeros
    mud = np.ascontiguousarray(mu_d, dtype=float) if friction else zeros
    # the kernel writes the velocity arrays in place: contiguous float64 views of the caller's
    v = vel if vel.flags.c_contiguous and vel.dtype == np.float64 else np.ascontiguousarray(vel, dtype=float)
    w = omega if omega.flags.c_contiguous and omega.dtype == np.float64 else np.ascontiguousarray(omega, dtype=float)
    c = np.ascontiguousarray
    it, residual, stopped = pgs.sweeps(c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), c(rows.dirs),
                                       c(rows.ang_a), c(rows.ang_b), c(rows.iang_a), c(rows.iang_b),
                                       c(rows.ima, dtype=float), c(rows.imb, dtype=float), c(rows.K),
                                       c(target_n, dtype=float), comp, mus, mud, friction, lam, v, w, int(iterations),
                                       float(tolerance), int(stall))
    if v is not vel:
        vel[...] = v
    if w is not omega:
        omega[...] = w
    return SolveResult(lam, int(it), float(residual), bool(stopped))


# ---------------------------------------------------------------------------- shared row algebra
def _inv2(kt):
    """Inverses ``(K,2,2)`` of the tangential blocks ``kt (K,2,2)`` (zero where singular)."""
    det = kt[:, 0, 0] * kt[:, 1, 1] - kt[:, 0, 1] * kt[:, 1, 0]
    ok = det > 1e-300
    safe = np.where(ok, det, 1.0)
    out = np.empty_like(kt)
    out[:, 0, 0] = kt[:, 1, 1] / safe
    out[:, 1, 1] = kt[:, 0, 0] / safe
    out[:, 0, 1] = -kt[:, 0, 1] / safe
    out[:, 1, 0] = -kt[:, 1, 0] / safe
    out[~ok] = 0.0
    return out


def _project_row(old, rv, tn, inv_kn, kk, inv_kt, mus, mud):
    """One projected block update of contacts ``(k,)``: normal then friction (static/kinetic).

    ``old (k,3)`` accumulated impulses, ``rv (k,3)`` relative velocity (n, t1, t2), ``tn (k,)``
    normal target, ``kk (k,3,3)`` (possibly split) effective inverse mass, ``inv_kn (k,)`` and
    ``inv_kt (k,2,2)`` its inverted diagonal blocks (``inv_kt`` None: frictionless). Returns ``new (k,3)``."""
    new = old.copy()
    new[:, 0] = np.maximum(old[:, 0] + (tn - rv[:, 0]) * inv_kn, 0.0)
    if inv_kt is None:
        return new
    dn = new[:, 0] - old[:, 0]
    vt = rv[:, 1:] + kk[:, 1:, 0] * dn[:, None]
    trial = old[:, 1:] - (inv_kt @ vt[:, :, None])[:, :, 0]
    mag = np.sqrt(np.einsum("ki,ki->k", trial, trial))
    stick = mag <= mus * new[:, 0]
    new[:, 1:] = trial
    slide = np.flatnonzero(~stick)
    if slide.size:
        # sliding: the impulse on the kinetic disc |λt| ≤ mu_d·λn nearest to the sticking one in the
        # contact's own metric (Kt), which is where friction opposes the resulting sliding velocity
        # (Coulomb's maximal dissipation), and the contact's energy can only go down
        kt = kk[slide][:, 1:, 1:]
        free = vt[slide] - (kt @ old[slide, 1:, None])[:, :, 0]     # sliding velocity without own friction
        new[slide, 1:] = disc_projection(kt, free, mud[slide] * new[slide, 0])
    return new


def disc_projection(kt, vfree, radius):
    """Friction impulses ``(k,2)`` on the discs ``|λ| ≤ radius (k,)`` nearest, in the metric of the
    tangential blocks ``kt (k,2,2)``, to the sticking impulses ``−kt⁻¹ vfree`` (``vfree (k,2)`` the
    sliding velocities without this friction): ``pgs.disc`` for each contact (the Gauss–Seidel
    kernel's own projection, so both solvers slide alike)."""
    out = np.zeros((len(vfree), 2))
    c = np.ascontiguousarray
    pgs.disc_rows(c(kt, dtype=float), c(vfree, dtype=float), c(radius, dtype=float), out)
    return out


# ---------------------------------------------------------------------------- Jacobi, mass splitting
def solve_jacobi(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, iterations=20, tolerance=1e-9, warm=None):
    """Projected Jacobi with mass splitting, updating ``vel, omega (N,3)`` in place.

    Every contact is updated in the same vectorised pass; a body touched by ``c`` contacts lends
    each of them ``1/c`` of its mass (``c`` × its inverse mass) and inverse inertia when the contact's impulse is
    computed (Tonge et al., mass splitting), which makes the simultaneous update convergent, while
    the impulses themselves act with the full inverse mass: the fixed point is the exact solution
    of the same complementarity problem that ``solve`` (Gauss–Seidel) solves. Same arguments and
    result as ``solve`` (end-velocity form, ``alpha_n = 1``)."""
    k = len(rows.a)
    lam = np.zeros((k, 3)) if warm is None else warm.copy()
    if k == 0:
        return SolveResult(lam, 0, 0.0)
    from scipy import sparse

    a, b = rows.a, rows.b
    n = len(vel)
    mov = rows.movable
    cnt = np.bincount(a[mov[a]], minlength=n) + np.bincount(b[mov[b]], minlength=n)
    sa = np.maximum(cnt[a], 1).astype(float)   # a copy of the body per contact: c × the inverse mass
    sb = np.maximum(cnt[b], 1).astype(float)
    d = rows.dirs
    ks = (rows.ima * sa + rows.imb * sb)[:, None, None] * np.eye(3) \
        + sa[:, None, None] * np.einsum("kdi,kei->kde", rows.ang_a, rows.iang_a) \
        + sb[:, None, None] * np.einsum("kdi,kei->kde", rows.ang_b, rows.iang_b)
    kn = ks[:, 0, 0]
    inv_kn = np.where(kn > 0, 1.0 / np.maximum(kn, _TINY), 0.0)
    friction = mu_s is not None and np.any(mu_s > 0)
    inv_kt = _inv2(ks[:, 1:, 1:]) if friction else None
    scat = sparse.csr_matrix((np.ones(2 * k), (np.concatenate([a, b]), np.arange(2 * k))), shape=(n, 2 * k))
    lin = np.concatenate([rows.ima[:, None, None] * d, -rows.imb[:, None, None] * d]).transpose(0, 2, 1)   # (2K,3,3)
    ang = np.concatenate([rows.iang_a, -rows.iang_b]).transpose(0, 2, 1)

    def push(delta):
        dd = np.concatenate([delta, delta])[:, :, None]
        vel[...] += scat @ (lin @ dd)[:, :, 0]
        omega[...] += scat @ (ang @ dd)[:, :, 0]

    if warm is not None and np.any(warm):
        push(lam)
    angab = np.concatenate([rows.ang_a, -rows.ang_b], axis=2)   # (K,3,6)
    it, residual = 0, 0.0
    for it in range(1, iterations + 1):
        rv = (d @ (vel[a] - vel[b])[:, :, None])[:, :, 0] \
            + (angab @ np.concatenate([omega[a], omega[b]], axis=1)[:, :, None])[:, :, 0]
        new = _project_row(lam, rv, target_n, inv_kn, ks, inv_kt, mu_s, mu_d)
        delta = new - lam
        lam = new
        push(delta)
        residual = float((np.abs(delta) * np.diagonal(ks, axis1=1, axis2=2)).max())   # m/s, as pgs.sweeps
        if residual <= tolerance:
            break
    return SolveResult(lam, it, residual, residual > tolerance)


def solve_auto(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, iterations=20, tolerance=1e-9, warm=None,
               method="auto", direct_max=None, compliance=None):
    """Contact impulses by the best method for the size (``solve_rows``, the step's own solve):
    ``direct`` (active set, exact) up to ``direct_max`` contacts (default ``DIRECT_MAX_CONTACTS``;
    ``settings.direct_max_contacts``), finished by Gauss–Seidel when friction slides; ``jacobi``
    (mass splitting) or ``gs`` (compiled sequential Gauss–Seidel) above. Same result type as
    ``solve``; ``vel, omega (N,3)`` updated in place. ``compliance (K,)`` (or None: rigid)
    regularises the normal rows, ``n·v + compliance·λn ≥ target_n`` (compliant contact:
    ``response.compliance``)."""
    k = len(rows.a)
    c = np.ascontiguousarray
    zeros = np.zeros(k)
    lam = np.zeros((k, 3))
    v = vel if vel.flags.c_contiguous and vel.dtype == np.float64 else np.ascontiguousarray(vel, dtype=float)
    w = omega if omega.flags.c_contiguous and omega.dtype == np.float64 else np.ascontiguousarray(omega, dtype=float)
    kinetic = mu_s is not None
    it, residual, stopped = solve_rows(
        SOLVER_METHODS.index(method), c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), c(rows.dirs),
        c(rows.ang_a), c(rows.ang_b), c(rows.iang_a), c(rows.iang_b), c(rows.ima, dtype=float),
        c(rows.imb, dtype=float), c(rows.K), c(target_n, dtype=float),
        zeros if compliance is None else c(compliance, dtype=float), c(mu_s, dtype=float) if kinetic else zeros,
        c(mu_d, dtype=float) if kinetic else zeros, kinetic,
        np.zeros((k, 3)) if warm is None else c(warm, dtype=float), warm is not None,
        c(rows.movable, dtype=np.bool_), *body_mass(rows),
        DIRECT_MAX_CONTACTS if direct_max is None else int(direct_max), int(iterations), float(tolerance), v, w, lam)
    if v is not vel:
        vel[...] = v
    if w is not omega:
        omega[...] = w
    return SolveResult(lam, int(it), float(residual), bool(stopped))


#: ``settings.SOLVER_METHODS`` by index, as the kernels take them; ``SOFT``: the penalty response's
#: frictionless compliant rows (``solve_rows``)
AUTO, DIRECT, GS, JACOBI = (SOLVER_METHODS.index(x) for x in ("auto", "direct", "gs", "jacobi"))
SOFT = len(SOLVER_METHODS)


@njit
def solve_rows(method, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d, kinetic,
               warm, use_warm, movable, inv_mass, inv_inertia, direct_max, iterations, tolerance, vel, omega, lam):
    """The step's contact solve, every method (``method`` an index of ``settings.SOLVER_METHODS``),
    on the rows of ``K`` contacts (``rows.Rows``' arrays): ``n·v + compliance·λn ≥ target`` with
    ``λn ≥ 0`` and Coulomb friction when ``kinetic`` and some ``mu_s > 0``; ``warm (K,3)`` the
    starting impulses (read when ``use_warm``); ``movable (N,)`` the bodies the solve moves,
    ``inv_mass (N,)`` and ``inv_inertia (N,3,3)`` the inverse mass and world inverse inertia the
    rows were built with (the exact solve's body-space method reads them; empty: it declines).
    Writes the impulses into ``lam (K,3)`` (zeros in) and updates ``vel, omega (N,3)``. Returns
    ``(sweeps, residual, unconverged)``: ``unconverged`` when an iterative solve stopped with a
    velocity still changing by more than ``tolerance`` (m/s), at ``iterations`` sweeps or stalled
    (``pgs.sweeps``).

    ``auto``: the exact active set per island (``direct``) up to ``direct_max`` contacts,
    Gauss–Seidel above; a set of more than ``DIRECT_FIRST`` contacts with an island larger than
    ``DIRECT_ISLAND_MAX`` tries Gauss–Seidel first (a pyramid of 55 boxes, 400 contacts, costs tens
    of ms to factorise and Gauss–Seidel warm started usually converges) and the active set only
    when it does not. ``SOFT`` (the penalty response's normal rows, frictionless, ``compliance > 0``:
    the implicit spring–damper, stable at any stiffness): the exact active set on ``A +
    diag(compliance)`` up to ``direct_max`` contacts when every island solves, else Gauss–Seidel
    from zero (the compliance only improves its conditioning). Contacts between two bodies that
    cannot move (a kinematic link pressed into a static floor) carry no impulse: their rows have no
    effective mass (``K = 0``)."""
    k = a.shape[0]
    if k == 0:
        return 0, 0.0, False
    n_live = 0
    for c in range(k):
        n_live += movable[a[c]] or movable[b[c]]
    if n_live < k:
        if n_live == 0:
            return 0, 0.0, False
        li = np.empty(n_live, np.int64)
        j = 0
        for c in range(k):
            if movable[a[c]] or movable[b[c]]:
                li[j] = c
                j += 1
        lam_l = np.zeros((n_live, 3))
        it, residual, stopped = solve_rows(method, a[li], b[li], dirs[li], ang_a[li], ang_b[li], iang_a[li],
                                           iang_b[li], ima[li], imb[li], K[li], target[li], compliance[li], mu_s[li],
                                           mu_d[li], kinetic, warm[li], use_warm, movable, inv_mass, inv_inertia,
                                           direct_max, iterations, tolerance, vel, omega, lam_l)
        for j in range(n_live):
            for x in range(3):
                lam[li[j], x] = lam_l[j, x]
        return it, residual, stopped
    order, start = islands(a, b, movable, vel.shape[0])
    if method == SOFT:
        return _soft(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, movable,
                     inv_mass, inv_inertia, direct_max, iterations, tolerance, vel, omega, lam)
    if method == AUTO:
        if DIRECT_FIRST < k <= direct_max and _largest(start) > DIRECT_ISLAND_MAX:
            v0, w0 = vel.copy(), omega.copy()
            lam_g = np.zeros((k, 3))
            it, residual, stopped = _gauss_seidel(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb,
                                                  K, target, compliance, mu_s, mu_d, kinetic, warm, use_warm, movable,
                                                  iterations, tolerance, vel, omega, lam_g)
            if not stopped:
                lam[:] = lam_g
                return it, residual, False
            vel[:] = v0
            omega[:] = w0
        method = DIRECT if k <= direct_max else GS
    if method == DIRECT:
        return _direct(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s,
                       mu_d, kinetic, warm, use_warm, movable, inv_mass, inv_inertia, iterations, tolerance, vel, omega,
                       lam)
    if method == GS:
        return _gauss_seidel(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance,
                             mu_s, mu_d, kinetic, warm, use_warm, movable, iterations, tolerance, vel, omega, lam)
    rigid = True
    for c in range(k):
        rigid = rigid and compliance[c] == 0.0
    if method == JACOBI and rigid:   # mass splitting (numpy, SciPy's sparse scatter): solve_jacobi
        with objmode(it="int64", residual="float64"):
            it, residual = _jacobi_py(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, mu_s, mu_d,
                                      kinetic, warm, use_warm, movable, iterations, tolerance, vel, omega, lam)
        return it, residual, it >= iterations and residual > tolerance
    ids = np.arange(k)
    return _sweep_ids(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d,
                      kinetic, warm, use_warm, iterations, tolerance, vel, omega, lam)


@njit
def _largest(start):
    """Contacts in the largest island (``start (I+1,)`` of ``active_set.islands``)."""
    m = 0
    for i in range(start.shape[0] - 1):
        m = max(m, start[i + 1] - start[i])
    return m


@njit
def _islands(max_island, a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance, mu_s,
             mu_d, kinetic, warm, use_warm, inv_mass, inv_inertia, vel, omega, lam):
    """The dense active set on every island of at most ``max_island`` contacts
    (``active_set.solve_islands``, with the bodies' ``inv_mass, inv_inertia``), the solved ones
    applied to ``vel, omega``; friction only when
    ``kinetic`` and some ``mu_s > 0``. Returns ``(friction, mu_s, mu_d as solved, residual, status
    (K,))``."""
    k = a.shape[0]
    friction = False
    if kinetic:
        for c in range(k):
            friction = friction or mu_s[c] > 0.0
    if friction:
        mus, mud = mu_s, mu_d
    else:
        mus = np.zeros(k)
        mud = mus
    status = np.empty(k, np.int64)
    residual = solve_islands(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance, mus,
                             mud, friction, warm, use_warm, max_island, DIRECT_REGULARISATION, DIRECT_CONSISTENCY,
                             DIRECT_MAX_ROUNDS, vel, omega, True, lam, status, inv_mass, inv_inertia)
    return friction, mus, mud, residual, status


@njit
def _direct(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d,
            kinetic, warm, use_warm, movable, inv_mass, inv_inertia, iterations, tolerance, vel, omega, lam):
    """The active set island by island (``active_set.solve_islands``; an island larger than
    ``DIRECT_ISLAND_MAX`` or whose factorisation failed by the sparse ``direct._active_set``), the
    solved islands' impulses applied, Gauss–Seidel finishing the others (sliding friction, an
    inconsistent set) from the start the active set left. Returns ``(sweeps, residual, unconverged)``."""
    friction, mus, mud, residual, status = _islands(DIRECT_ISLAND_MAX, a, b, order, start, dirs, ang_a, ang_b, iang_a,
                                                    iang_b, ima, imb, target, compliance, mu_s, mu_d, kinetic, warm,
                                                    use_warm, inv_mass, inv_inertia, vel, omega, lam)
    ok, res_b, big = _sparse_islands(status, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target,
                                     compliance, mus, mud, friction, warm, use_warm, movable, vel, omega, lam)
    if ok and big.shape[0]:
        residual = max(residual, res_b)
        apply_ids(big, a, b, dirs, iang_a, iang_b, ima, imb, lam, vel, omega)
    unfinished = _where(status, SOLVED, False)
    if unfinished.shape[0] == 0:
        return 1, residual, False
    sweeps_, res, stopped = _sweep_ids(unfinished, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target,
                                       compliance, mu_s, mu_d, kinetic, lam, True, iterations, tolerance, vel, omega,
                                       lam)
    return sweeps_, max(res, residual), stopped


@njit
def _soft(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, movable, inv_mass,
          inv_inertia, direct_max, iterations, tolerance, vel, omega, lam):
    """``solve_rows``' ``SOFT`` method: the active set on every island (the sparse one for an island
    too large for the dense kernel), applied only when every island solved; otherwise Gauss–Seidel
    on all the rows from zero. Returns ``(sweeps, residual, unconverged)``."""
    k = a.shape[0]
    zeros = np.zeros(k)
    warm = np.zeros((k, 3))
    if k <= direct_max:
        status = np.empty(k, np.int64)
        lam_d = np.zeros((k, 3))
        residual = solve_islands(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance,
                                 zeros, zeros, False, warm, False, DIRECT_ISLAND_MAX, DIRECT_REGULARISATION,
                                 DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, vel, omega, False, lam_d, status, inv_mass,
                                 inv_inertia)
        ok, res_b, big = _sparse_islands(status, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target,
                                         compliance, zeros, zeros, False, warm, False, movable, vel, omega, lam_d)
        if ok and big.shape[0]:
            residual = max(residual, res_b)
        if np.all(status == SOLVED):
            apply_ids(np.arange(k), a, b, dirs, iang_a, iang_b, ima, imb, lam_d, vel, omega)
            lam[:] = lam_d
            return 1, residual, False
    return _sweep_ids(np.arange(k), a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, zeros,
                      zeros, False, warm, False, iterations, tolerance, vel, omega, lam)


@njit
def _sparse_islands(status, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d,
                    friction, warm, use_warm, movable, vel, omega, lam):
    """The islands ``solve_islands`` left ``TOO_LARGE`` (``status (K,)``), together by SciPy's sparse
    active set (``_sparse_py``, run as Python from the kernel) from the velocities the solved islands
    left: their impulses (the solve's, or Gauss–Seidel's start) into ``lam``'s rows, marked ``SOLVED``
    when it converged (the caller applies them). Returns ``(converged, residual, contacts (B,))``."""
    big = _where(status, TOO_LARGE, True)
    if big.shape[0] == 0:
        return True, 0.0, big
    lam_b = np.zeros((big.shape[0], 3))
    with objmode(ok="boolean", res_b="float64"):
        ok, res_b = _sparse_py(big, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s,
                               mu_d, friction, warm, use_warm, movable, vel, omega, lam_b)
    for j in range(big.shape[0]):
        for x in range(3):
            lam[big[j], x] = lam_b[j, x]
        if ok:
            status[big[j]] = SOLVED
    return ok, res_b, big


@njit
def _gauss_seidel(a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d,
                  kinetic, warm, use_warm, movable, iterations, tolerance, vel, omega, lam):
    """Islands of one contact (a body touching only static geometry) exactly, by the island
    kernel; Gauss–Seidel (``pgs.sweeps``) for the coupled rest and for a single contact that
    slides, from ``warm``. Returns ``(sweeps, residual, unconverged)``."""
    status = _islands(1, a, b, order, start, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, target, compliance, mu_s,
                      mu_d, kinetic, warm, use_warm, np.zeros(0), np.zeros((0, 3, 3)), vel, omega, lam)[4]
    rest = _where(status, SOLVED, False)
    if rest.shape[0] == 0:
        return 1, 0.0, False
    for j in range(rest.shape[0]):
        for x in range(3):
            lam[rest[j], x] = 0.0
    return _sweep_ids(rest, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d,
                      kinetic, warm, use_warm, iterations, tolerance, vel, omega, lam)


@njit
def _where(status, value, equal):
    """The contacts whose ``status (K,)`` is ``value`` (``equal``) or is not, ascending
    (``np.flatnonzero`` without the temporary mask); an empty view of ``status`` when there is none."""
    m = 0
    for c in range(status.shape[0]):
        m += (status[c] == value) == equal
    if m == 0:
        return status[:0]
    out = np.empty(m, np.int64)
    j = 0
    for c in range(status.shape[0]):
        if (status[c] == value) == equal:
            out[j] = c
            j += 1
    return out


@njit
def _sweep_ids(ids, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d, kinetic,
               warm, use_warm, iterations, tolerance, vel, omega, lam):
    """Gauss–Seidel (``solve``: the warm impulses applied, then ``pgs.sweeps``) on the contacts
    ``ids (U,)`` from ``warm[ids]`` (zero unless ``use_warm``); writes their impulses into ``lam``.
    Returns ``(sweeps, residual, unconverged)``."""
    u = ids.shape[0]
    ua, ub = a[ids], b[ids]
    udirs, uang_a, uang_b, uiang_a, uiang_b, uK = dirs[ids], ang_a[ids], ang_b[ids], iang_a[ids], iang_b[ids], K[ids]
    uima, uimb = ima[ids], imb[ids]
    ulam = warm[ids] if use_warm else np.zeros((u, 3))
    friction = kinetic and np.any(mu_s[ids] > 0.0)
    zeros = np.zeros(u)
    if use_warm and np.any(ulam != 0.0):
        apply_ids(np.arange(u), ua, ub, udirs, uiang_a, uiang_b, uima, uimb, ulam, vel, omega)
    it, residual, stopped = sweeps(ua, ub, udirs, uang_a, uang_b, uiang_a, uiang_b, uima, uimb, uK, target[ids],
                                   compliance[ids], mu_s[ids] if friction else zeros, mu_d[ids] if friction else zeros,
                                   friction, ulam, vel, omega, iterations, tolerance, PGS_STALL_SWEEPS)
    for i in range(u):
        for x in range(3):
            lam[ids[i], x] = ulam[i, x]
    return it, residual, stopped


def _rows_of(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, movable):
    """A ``Rows`` over the kernel's arrays, for the solves that run as Python (the lever arms
    ``ra, rb`` are not carried: no solver reads them)."""
    return Rows(a, b, dirs[:, 0], dirs[:, 1], dirs[:, 2], None, None, ang_a, ang_b, iang_a, iang_b, ima, imb, K, dirs,
                movable)


def _sparse_py(big, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, compliance, mu_s, mu_d, friction,
               warm, use_warm, movable, vel, omega, lam_b):
    """``solve_rows``' Python block: the sparse active set (``direct._active_set``, SciPy) on the
    contacts ``big`` together, from the velocities the solved islands left; writes ``lam_b``
    (their impulses, or Gauss–Seidel's start) and returns ``(converged, residual)``."""
    from scipy import sparse

    sub = _rows_of(a[big], b[big], dirs[big], ang_a[big], ang_b[big], iang_a[big], iang_b[big], ima[big], imb[big],
                   K[big], movable)
    A = None
    if np.any(compliance[big]):
        d = np.zeros(3 * big.size)
        d[0::3] = compliance[big]
        A = (delassus(sub) + sparse.diags(d)).tocsr()
    v0 = row_velocity(sub, vel, omega)
    lam, ok, residual = _active_set(sub, v0, target[big], mu_s[big] if friction else None,
                                    mu_d[big] if friction else None, warm[big] if use_warm else None, A)
    lam_b[...] = lam
    return bool(ok), float(residual)


def _jacobi_py(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, mu_s, mu_d, kinetic, warm, use_warm,
               movable, iterations, tolerance, vel, omega, lam):
    """``solve_rows``' Python block for ``jacobi``: ``solve_jacobi`` on the kernel's arrays,
    writing ``lam`` and ``vel, omega`` in place; returns ``(sweeps, residual)``."""
    rows = _rows_of(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, movable)
    friction = kinetic and bool(np.any(mu_s > 0))
    res = solve_jacobi(rows, vel, omega, target_n=target, mu_s=mu_s if friction else None,
                       mu_d=mu_d if friction else None, iterations=iterations, tolerance=tolerance,
                       warm=warm.copy() if use_warm else None)
    lam[...] = res.impulse
    return int(res.iterations), float(res.residual)
