"""The exact contact solve: an active-set method on the Delassus (contact coupling) matrix, island
by island: dense in the compiled kernel (``active_set``) up to ``DIRECT_ISLAND_MAX`` contacts an
island, sparse (SciPy's SuperLU) above."""
import numpy as np

from . import active_set
from .rows import _TINY, SolveResult, apply, body_mass, row_velocity
from ..constants import DIRECT_CONSISTENCY, DIRECT_ISLAND_MAX, DIRECT_MAX_ROUNDS, DIRECT_REGULARISATION


def _regularised_solve_sparse(sub, r, eps, refine=2):
    """``x`` with ``sub @ x = r`` for a sparse symmetric positive semi-definite ``sub (m,m)``
    (CSR/CSC): SuperLU of ``sub + eps·I`` followed by ``refine`` steps of iterative refinement
    (proximal point), which remove the shift's bias on the well-determined part (exact to rounding
    for full rank) and leave redundant directions at their least-norm value; dense least squares
    if the factorisation fails."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    m = sub.shape[0]
    try:
        f = splu((sub + eps * sparse.identity(m, format="csc")).tocsc(), permc_spec="MMD_AT_PLUS_A")
    except RuntimeError:
        return np.linalg.lstsq(sub.toarray(), r, rcond=None)[0]
    x = f.solve(r)
    for _ in range(refine):
        x += f.solve(r - sub @ x)
    return x


def delassus(rows):
    """Delassus matrix ``A = J M⁻¹ Jᵀ (3K,3K)`` as CSR, rows ordered (n, t1, t2) per contact:
    ``A @ λ.ravel()`` is the change of the contacts' relative velocities made by impulses ``λ (K,3)``.
    Built as a sparse product (12 non-zeros per row of ``J``); the islands the compiled kernel
    solves build their dense blocks themselves (``active_set._delassus``)."""
    from scipy import sparse

    k = len(rows.a)
    d = rows.dirs
    r = np.repeat(np.arange(3 * k), 12)
    cols_a = 6 * rows.a[:, None] + np.arange(6)                          # (K,6)
    cols_b = 6 * rows.b[:, None] + np.arange(6)
    cols = np.concatenate([np.broadcast_to(cols_a[:, None, :], (k, 3, 6)),
                           np.broadcast_to(cols_b[:, None, :], (k, 3, 6))], axis=2).ravel()
    jv = np.concatenate([d, rows.ang_a, -d, -rows.ang_b], axis=2).ravel()            # (K,3,12)
    wv = np.concatenate([rows.ima[:, None, None] * d, rows.iang_a, -rows.imb[:, None, None] * d,
                         -rows.iang_b], axis=2).ravel()
    n6 = 6 * (max(int(rows.a.max()), int(rows.b.max())) + 1) if k else 0
    J = sparse.csr_matrix((jv, (r, cols)), shape=(3 * k, n6))
    W = sparse.csr_matrix((wv, (r, cols)), shape=(3 * k, n6))
    return (J @ W.T).tocsr()


def _safest_start(A, rhs, *candidates):
    """The candidate impulses ``(K,3)`` (``None`` skipped; zero always a candidate) with the lowest
    contact objective ``f(λ) = ½ λ·Aλ − λ·rhs`` (``rhs`` = target − current row velocity): the
    quantity projected Gauss–Seidel descends, so its start decides where it can end. An unfinished
    active-set answer can be far worse than no impulse at all; warm-starting from it diverges."""
    k = len(rhs) // 3
    best, best_f = np.zeros((k, 3)), 0.0
    for lam in candidates:
        if lam is None or not np.all(np.isfinite(lam)):
            continue
        x = lam.ravel()
        f = 0.5 * float(x @ (A @ x)) - float(x @ rhs)
        if f < best_f:
            best, best_f = lam, f
    return best


def solve_exact(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, warm=None, compliance=None, apply_solved=False,
                island_max=None, sparse=True):
    """Exact contact impulses by the active-set method, island by island (``active_set``: compiled,
    dense per island; an island larger than ``DIRECT_ISLAND_MAX`` contacts, or whose factorisation
    fails, by the sparse ``_active_set`` below).

    Solves ``v_n + (Aλ)_n + compliance·λ_n ≥ target_n ⟂ λ_n ≥ 0`` with sticking friction
    (tangential velocity zero). Returns ``(lam (K,3), solved (K,) bool, residual)``: the impulses of
    the solved islands, and for the others (a sticking impulse outside the static cone, an
    inconsistent set, too many rounds) the start of lowest contact objective for Gauss–Seidel;
    ``residual`` is the largest row residual of the solved ones (m/s: how far a row's velocity
    misses its target). ``vel, omega (N,3)`` are
    left as they are, or with ``apply_solved`` get the solved islands' impulses. ``island_max``
    (default ``DIRECT_ISLAND_MAX``) bounds the islands the kernel takes; larger ones go through the
    sparse path, or with ``sparse`` false are left unsolved (zero impulse)."""
    k = len(rows.a)
    lam = np.zeros((k, 3))
    if k == 0:
        return lam, np.ones(0, bool), 0.0
    c = np.ascontiguousarray
    friction = mu_s is not None and bool(mu_s.max() > 0)
    zeros = np.zeros(k)
    mus = c(mu_s, dtype=float) if friction else zeros
    mud = c(mu_d, dtype=float) if friction else zeros
    comp = zeros if compliance is None else c(compliance, dtype=float)
    status = np.empty(k, np.int64)
    # the kernel reads (and with apply_solved writes) the velocity arrays: contiguous float64 views
    v = vel if vel.flags.c_contiguous and vel.dtype == np.float64 else np.ascontiguousarray(vel, dtype=float)
    w = omega if omega.flags.c_contiguous and omega.dtype == np.float64 else np.ascontiguousarray(omega, dtype=float)
    order, start = rows.islands()
    residual = active_set.solve_islands(
        c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), order, start, c(rows.dirs),
        c(rows.ang_a), c(rows.ang_b), c(rows.iang_a), c(rows.iang_b), c(rows.ima, dtype=float),
        c(rows.imb, dtype=float), c(target_n, dtype=float), comp, mus, mud, friction,
        zeros.reshape(k, 1) if warm is None else c(warm, dtype=float), warm is not None,
        DIRECT_ISLAND_MAX if island_max is None else island_max,
        DIRECT_REGULARISATION, DIRECT_CONSISTENCY, DIRECT_MAX_ROUNDS, v, w, apply_solved, lam, status,
        *body_mass(rows))
    if apply_solved:
        if v is not vel:
            vel[...] = v
        if w is not omega:
            omega[...] = w
    solved = status == active_set.SOLVED
    if solved.all():   # the usual case: every island solved in the kernel
        return lam, solved, residual
    big = np.flatnonzero(status == active_set.TOO_LARGE)
    if big.size and not sparse:
        lam[big] = 0.0
    elif big.size:
        sub = rows.select(big)
        A = None
        if compliance is not None:
            from scipy import sparse

            d = np.zeros(3 * big.size)
            d[0::3] = compliance[big]
            A = (delassus(sub) + sparse.diags(d)).tocsr()
        v0 = row_velocity(rows, vel, omega, big)
        lam_b, ok, res_b = _active_set(sub, v0, target_n[big], None if not friction else mu_s[big],
                                       None if not friction else mu_d[big], None if warm is None else warm[big], A)
        lam[big] = lam_b
        solved[big] = ok
        if ok:
            residual = max(residual, res_b)
            if apply_solved:
                apply(sub, vel, omega, lam_b)
    return lam, solved, residual


def solve_direct(rows, vel, omega, *, target_n, mu_s=None, mu_d=None, warm=None, compliance=None):
    """``solve_exact`` for the whole set: ``(SolveResult, converged)``, ``vel, omega`` updated only
    when every island is solved (otherwise the result holds Gauss–Seidel's start)."""
    k = len(rows.a)
    lam, solved, residual = solve_exact(rows, vel, omega, target_n=target_n, mu_s=mu_s, mu_d=mu_d, warm=warm,
                                        compliance=compliance)
    if not solved.all():
        return SolveResult(lam, DIRECT_MAX_ROUNDS, np.inf, True), False
    if k:
        apply(rows, vel, omega, lam)
    return SolveResult(lam, 1, residual), True


def _active_set(rows, v0, target_n, mu_s, mu_d, warm, A=None):
    """The active-set method on one sparse Delassus matrix ``A (3K,3K)`` (built from ``rows`` when
    not given), for islands too large for the compiled dense kernel. ``v0 (K,3)`` row velocities.
    Returns ``(lam (K,3), converged, residual)`` (Gauss–Seidel's start when not converged)."""
    k = len(rows.a)
    if A is None:
        A = delassus(rows)
    rhs = -v0.copy()
    rhs[:, 0] += target_n
    rhs = rhs.ravel()
    friction = mu_s is not None and np.any(mu_s > 0)
    # initial guess: every contact that is not separating is pushing (a resting stack starts
    # with all its layers active: guessing only the approaching ones adds one layer per round)
    act = v0[:, 0] <= target_n
    if warm is not None:
        act |= warm[:, 0] > 0
    diag = A.diagonal()
    eps = DIRECT_REGULARISATION * max(float(diag.max()), _TINY)
    tol = 1e-12 + 1e-9 * float(np.abs(rhs).max())
    lam = np.zeros((k, 3))
    converged = False
    for _ in range(DIRECT_MAX_ROUNDS + k // 4):
        sel = np.zeros((k, 3), bool)
        sel[:, 0] = act
        if friction:
            sel[:, 1:] = (act & (mu_s > 0))[:, None]
        S = np.flatnonzero(sel.ravel())
        x = np.zeros(3 * k)
        if S.size:
            x[S] = _regularised_solve_sparse(A[S][:, S], rhs[S], eps)
        lam = x.reshape(k, 3)
        ax = A @ x
        if S.size and np.abs(ax[S] - rhs[S]).max() > DIRECT_CONSISTENCY * (np.abs(rhs).max() + _TINY):
            # the active rows cannot all hold (e.g. more sticking points than the bodies have
            # freedoms, pulling different ways): the regularised solve answers with impulses of
            # size 1/eps. No active set containing them is right; Gauss–Seidel takes over
            break
        vn = v0[:, 0] + ax[0::3]
        neg = act & (lam[:, 0] < 0)
        viol = ~act & (vn < target_n - tol)
        if neg.any() or viol.any():
            act = (act & ~neg) | viol
            continue
        converged = True
        break
    lam[:, 0] = np.maximum(lam[:, 0], 0.0)
    if friction:
        mag = np.linalg.norm(lam[:, 1:], axis=1)
        out = mag > mu_s * lam[:, 0] * (1 + 1e-12) + 1e-300
        if out.any():
            converged = False
            lim = mu_d * lam[:, 0]
            lam[:, 1:] *= np.where(out, lim / np.maximum(mag, _TINY), 1.0)[:, None]
    else:
        lam[:, 1:] = 0.0
    if not converged:
        return _safest_start(A, rhs, lam, warm), False, np.inf
    resid = (A @ lam.ravel() - rhs).reshape(k, 3)
    resid[:, 0] = np.where(lam[:, 0] > 0, resid[:, 0], np.minimum(resid[:, 0], 0.0))
    if not friction:
        resid[:, 1:] = 0.0
    residual = float(np.max(np.abs(resid))) if k else 0.0
    return lam, True, residual
