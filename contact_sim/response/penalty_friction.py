"""Coulomb friction for the penalty response, regularised: ``F_t = −μ F_n v_t / max(|v_t|, v_r)``.

Above the regularisation speed ``v_r`` (``settings.penalty.friction_velocity``) the force is
Coulomb's, ``μ F_n`` against the sliding direction; below it a damper of coefficient ``μ F_n / v_r``
(Karnopp's and ODE's regularised friction). The damper is far too stiff for explicit integration
(``μ g dt / v_r`` is ~200 for a 1e-4 m/s regulariser at dt 1/240), so it is integrated implicitly,
as the normal spring is: the force uses the tangential velocity at the *end* of the step,
``λ_t = −(μ λ_n / v_r) v_t⁺`` (impulses, ``λ_n`` the contact's normal impulse of the step),
i.e. the soft constraint ``v_t⁺ + γ λ_t = 0`` with compliance ``γ = v_r / (μ λ_n)``, with
``|λ_t| ≤ μ λ_n`` (the Coulomb cap). Solved by projected Gauss–Seidel over the contacts' colours
(contacts of one colour share no moving body), on the velocities after the normal impulses.

What it guarantees: a sliding body decelerates at ``μ g`` until ``|v_t| ≈ v_r`` (then stops
exponentially, with time constant ``v_r / (μ g)``), so its stopping distance is ``v0²/(2μg)`` to
within ``v_r`` and the step's first-order error; a body held by friction creeps at the speed where
the damper balances the pull: ``v_r · tan θ / μ`` on an incline of angle ``θ`` (the warning
``PenaltyFrictionWarning`` fires when ``v_r`` lets that reach ``models.FRICTION_CREEP_LIMIT``).
"""
import numpy as np

from . import solver

PGS_SWEEPS = 12        # sweeps at most: the stick/slip projection converges slowly near the cap, and
PGS_TOLERANCE = 1e-6   # the stopping distance and hold are within 1e-3 of exact by then (tests)


def solve_with_friction(rows, vel, omega, lam, target_n, compliance_n, mu, v_reg, iterations=PGS_SWEEPS,
                        tolerance=PGS_TOLERANCE):
    """Add the regularised Coulomb friction to a penalty solve, in place.

    ``lam (K, 3)`` the (normal, t1, t2) impulses on A of ``solver.solve_soft`` (normal only) and
    ``vel, omega (N, 3)`` the end-of-step velocities it left; ``target_n, compliance_n (K,)`` its
    soft normal rows (``n·v + γ_n λ_n ≥ target_n ⟂ λ_n ≥ 0``); ``mu (K,)`` friction coefficients,
    ``v_reg`` the regularisation speed (m/s). Projected Gauss–Seidel over the contacts' colours,
    each contact's normal row then its friction, so that the turning the friction causes (its lever
    below the centre of mass) is answered by the springs in the same solve: friction solved after
    the normal impulses alone rocked a block on an incline into a slow walk. Stops when a sweep
    changes no impulse by more than ``tolerance`` × the largest one, or after ``iterations``
    sweeps. Returns the sweeps done."""
    k = len(rows.a)
    if k == 0 or not np.any(mu > 0):
        return 0
    K = rows.K
    eye = np.eye(2)
    colors = rows.colors
    sweeps = 0
    for sweeps in range(1, iterations + 1):
        change = 0.0
        for idx in colors:
            v = solver.row_velocity(rows, vel, omega, idx)
            old = lam[idx].copy()
            new = old.copy()
            # the soft normal row (as solve_soft)
            kn = K[idx, 0, 0] + compliance_n[idx]
            new[:, 0] = np.maximum(old[:, 0] + (target_n[idx] - v[:, 0] - compliance_n[idx] * old[:, 0]) / kn, 0.0)
            vt = v[:, 1:] + K[idx, 1:, 0:1][..., 0] * (new[:, 0] - old[:, 0])[:, None]   # after that change
            cap = mu[idx] * new[:, 0]
            live = cap > 0
            gamma = np.where(live, v_reg / np.where(live, cap, 1.0), 0.0)
            # the damper μλ_n/v_r, implicit: (K_tt + γ) Δλ = −(v_t + γ λ_t), then the Coulomb cap
            Ktt = K[idx, 1:, 1:]
            t = old[:, 1:] + np.linalg.solve(Ktt + gamma[:, None, None] * eye,
                                             -(vt + gamma[:, None] * old[:, 1:])[..., None])[..., 0]
            mag = np.sqrt(np.einsum("ij,ij->i", t, t))
            over = mag > cap
            if over.any():
                # sliding: the Coulomb force against the velocity the point would have without this
                # contact's friction (maximum dissipation; clipping the coupled 2-D solution instead
                # tilts it off the sliding direction when the body's inertia couples t1 and t2)
                free = vt[over] - np.einsum("kij,kj->ki", Ktt[over], old[over, 1:])
                fm = np.sqrt(np.einsum("ij,ij->i", free, free))
                safe = np.where(fm > 0, fm, 1.0)[:, None]
                dirn = np.where(fm[:, None] > 0, -free / safe, t[over] / np.maximum(mag[over], 1e-300)[:, None])
                t[over] = cap[over][:, None] * dirn
            t[~live] = 0.0
            new[:, 1:] = t
            lam[idx] = new
            d = new - old
            solver.apply(rows, vel, omega, d, idx, unique=True)
            change = max(change, float(np.abs(d).max()))
        if change <= tolerance * max(float(np.abs(lam).max()), 1e-300):
            break
    return sweeps
