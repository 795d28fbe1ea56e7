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

from . import pgs
from ..constants import DIRECT_FIRST, DIRECT_ISLAND_MAX, DIRECT_MAX_CONTACTS
from .direct import delassus, solve_direct, solve_exact
from .rows import _TINY, Rows, SolveResult, apply, build_rows, row_velocity

__all__ = ["Rows", "SolveResult", "apply", "build_rows", "delassus", "row_velocity", "solve", "solve_auto",
           "solve_direct", "solve_jacobi", "solve_soft"]



def solve(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, iterations=20, tolerance=1e-9, warm=None,
          compliance=None):
    """Projected Gauss–Seidel, sequential over the contacts in a compiled loop (``pgs.sweeps``),
    updating ``vel, omega (N,3)`` in place.

    Normal row: ``n·v_rel ≥ target_n`` with a non-negative impulse (complementarity: zero impulse
    where the row is satisfied, i.e. separating).
    Friction rows (when ``mu_s``/``mu_d (K,)`` are given): tangential relative velocity driven to
    zero by a 2-D impulse kept in the cone: if the sticking impulse is within ``mu_s·λn`` it is
    taken, otherwise the impulse on the kinetic disc ``mu_d·λn`` nearest to it in the contact's
    metric (kinetic friction, maximal dissipation). ``warm (K,3)`` starting impulses (applied
    first). ``compliance (K,)`` softens the normal rows to ``n·v_rel + compliance·λn ≥ target_n``
    (the implicit spring–damper of the penalty response). Sweeps stop when no impulse changed by
    more than ``tolerance`` (N·s) or after ``iterations``. Returns ``SolveResult``.
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
    it, residual = pgs.sweeps(c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), c(rows.dirs), c(rows.ang_a),
                              c(rows.ang_b), c(rows.iang_a), c(rows.iang_b), c(rows.ima, dtype=float),
                              c(rows.imb, dtype=float), c(rows.K), c(target_n, dtype=float), comp, mus, mud,
                              friction, lam, v, w, int(iterations), float(tolerance))
    if v is not vel:
        vel[...] = v
    if w is not omega:
        omega[...] = w
    return SolveResult(lam, int(it), float(residual))


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
        residual = float(np.abs(delta).max())
        if residual <= tolerance:
            break
    return SolveResult(lam, it, residual)


def solve_auto(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, iterations=20, tolerance=1e-9, warm=None,
               method="auto", direct_max=None, compliance=None):
    """Contact impulses by the best method for the size: ``direct`` (active set, exact) up to
    ``direct_max`` contacts (default ``DIRECT_MAX_CONTACTS``; ``settings.direct_max_contacts``),
    finished by Gauss–Seidel when friction slides; ``jacobi``
    (mass splitting) or ``gs`` (compiled sequential Gauss–Seidel) above. Same result type as ``solve``.
    ``compliance (K,)`` (or None: rigid) regularises the normal rows, ``n·v + compliance·λn ≥
    target_n`` (compliant contact: ``response.compliance``), in every method; ``jacobi`` has no such
    row and gives compliant rows to ``gs``.

    Contacts between two bodies that cannot move (a kinematic robot link pressed into a static
    floor) are reported by detection but carry no impulse: nothing can respond, and their rows
    have no effective mass (``K = 0``), which no solver may divide by."""
    k = len(rows.a)
    if compliance is not None and not np.any(compliance):
        compliance = None
    live = rows.movable[rows.a] | rows.movable[rows.b]
    if not live.all():
        lam = np.zeros((k, 3))
        li = np.flatnonzero(live)
        if li.size:
            res = solve_auto(rows.select(li), vel, omega, target_n=target_n[li],
                             mu_s=None if mu_s is None else mu_s[li], mu_d=None if mu_d is None else mu_d[li],
                             iterations=iterations, tolerance=tolerance, warm=None if warm is None else warm[li],
                             method=method, direct_max=direct_max,
                             compliance=None if compliance is None else compliance[li])
            lam[li] = res.impulse
            return SolveResult(lam, res.iterations, res.residual)
        return SolveResult(lam, 0, 0.0)
    if method == "auto":
        limit = DIRECT_MAX_CONTACTS if direct_max is None else direct_max
        if DIRECT_FIRST < k <= limit and _largest_island(rows) > DIRECT_ISLAND_MAX:
            # Gauss–Seidel first, the active set only when it does not converge: one large island
            # (a pyramid of 55 boxes, 400 contacts) costs tens of ms to factorise and Gauss–Seidel
            # warm-started usually converges; many small islands (a resting floor) take the compiled
            # dense kernel, as fast as Gauss–Seidel and exact
            v0, w0 = vel.copy(), omega.copy()
            res = solve_auto(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, iterations=iterations,
                             tolerance=tolerance, warm=warm, method="gs", compliance=compliance)
            if res.residual <= tolerance:
                return res
            vel[...] = v0
            omega[...] = w0
        method = "direct" if k <= limit else "gs"
    if method == "direct":
        # islands are independent: the solved ones keep their exact impulses (applied), Gauss–Seidel
        # finishes the others (sliding friction, an inconsistent set) from the start the active set left
        lam, solved, residual = solve_exact(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, warm=warm,
                                            apply_solved=True, compliance=compliance)
        if solved.all():
            return SolveResult(lam, 1, residual)
        ui = np.flatnonzero(~solved)
        res = solve(rows.select(ui), vel, omega, target_n=target_n[ui], mu_s=None if mu_s is None else mu_s[ui],
                    mu_d=None if mu_d is None else mu_d[ui], iterations=iterations, tolerance=tolerance,
                    warm=lam[ui], compliance=None if compliance is None else compliance[ui])
        lam[ui] = res.impulse
        return SolveResult(lam, res.iterations, max(res.residual, residual))
    if method == "gs":
        # islands of one contact (a body touching only static geometry) exactly, by the island kernel;
        # Gauss–Seidel for the coupled rest and for a single contact that slides
        lam, solved, _ = solve_exact(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, warm=warm,
                                     apply_solved=True, island_max=1, sparse=False, compliance=compliance)
        if solved.all():
            return SolveResult(lam, 1, 0.0)
        rest = np.flatnonzero(~solved)
        res = solve(rows.select(rest), vel, omega, target_n=target_n[rest],
                    mu_s=None if mu_s is None else mu_s[rest], mu_d=None if mu_d is None else mu_d[rest],
                    iterations=iterations, tolerance=tolerance, warm=None if warm is None else warm[rest],
                    compliance=None if compliance is None else compliance[rest])
        lam[rest] = res.impulse
        return SolveResult(lam, res.iterations, res.residual)
    if method == "jacobi" and compliance is None:
        return solve_jacobi(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, iterations=iterations,
                            tolerance=tolerance, warm=warm)
    return solve(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, iterations=iterations,
                 tolerance=tolerance, warm=warm, compliance=compliance)


def _largest_island(rows):
    """Contacts in the largest island of ``rows`` (contacts linked through movable bodies)."""
    start = rows.islands()[1]
    return int(np.diff(start).max()) if len(start) > 1 else 0


def solve_soft(rows, vel, omega, *, target_n, compliance, iterations=20, tolerance=1e-9, direct_max=None):
    """Frictionless contacts with compliant normal rows, updating ``vel, omega (N,3)`` in place:
    ``n·v_rel + compliance·λn ≥ target_n ⟂ λn ≥ 0`` (``compliance, target_n (K,)``). This is the
    implicit (backward Euler) spring–damper of the penalty response, stable at any stiffness.
    Exact active set on ``A + diag(compliance)`` up to ``direct_max`` contacts, compiled
    Gauss–Seidel above (the compliance only improves its conditioning)."""
    k = len(rows.a)
    live = rows.movable[rows.a] | rows.movable[rows.b]
    if not live.all():   # no movable body: no impulse (see solve_auto)
        lam = np.zeros((k, 3))
        li = np.flatnonzero(live)
        if li.size:
            res = solve_soft(rows.select(li), vel, omega, target_n=target_n[li], compliance=compliance[li],
                             iterations=iterations, tolerance=tolerance, direct_max=direct_max)
            lam[li] = res.impulse
            return SolveResult(lam, res.iterations, res.residual)
        return SolveResult(lam, 0, 0.0)
    if 0 < k <= (DIRECT_MAX_CONTACTS if direct_max is None else direct_max):
        res, ok = solve_direct(rows, vel, omega, target_n=target_n, compliance=compliance)
        if ok:
            return res
    return solve(rows, vel, omega, target_n=target_n, iterations=iterations, tolerance=tolerance,
                 compliance=compliance)
