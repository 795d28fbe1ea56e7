"""Coulomb friction for the penalty response, regularised: ``F_t = −μ F_n v_t / max(|v_t|, v_r)``.

Above the regularisation speed ``v_r`` (``settings.penalty.friction_velocity``) the force is
Coulomb's, ``μ F_n`` against the sliding direction; below it a damper of coefficient ``μ F_n / v_r``
(Karnopp's and ODE's regularised friction). The damper is far too stiff for explicit integration
(``μ g dt / v_r`` is ~200 for a 1e-4 m/s regulariser at dt 1/240), so it is integrated implicitly,
as the normal spring is: the force uses the tangential velocity at the *end* of the step,
``λ_t = −(μ λ_n / v_r) v_t⁺`` (impulses, ``λ_n`` the contact's normal impulse of the step),
i.e. the soft constraint ``v_t⁺ + γ λ_t = 0`` with compliance ``γ = v_r / (μ λ_n)``, with
``|λ_t| ≤ μ λ_n`` (the Coulomb cap). Solved by projected Gauss–Seidel, a compiled loop over the
contacts, on the velocities after the normal impulses.

What it guarantees: a sliding body decelerates at ``μ g`` until ``|v_t| ≈ v_r`` (then stops
exponentially, with time constant ``v_r / (μ g)``), so its stopping distance is ``v0²/(2μg)`` to
within ``v_r`` and the step's first-order error; a body held by friction creeps at the speed where
the damper balances the pull: ``v_r · tan θ / μ`` on an incline of angle ``θ`` (the warning
``PenaltyFrictionWarning`` fires when ``v_r`` lets that reach ``models.FRICTION_CREEP_LIMIT``).
"""
import numpy as np

from . import pgs
from ..constants import PGS_TOLERANCE


def solve_with_friction(rows, vel, omega, lam, target_n, compliance_n, mu, v_reg, iterations,
                        tolerance=PGS_TOLERANCE):
    """Add the regularised Coulomb friction to a penalty solve, in place.

    ``lam (K, 3)`` the (normal, t1, t2) impulses on A of ``solver.solve_soft`` (normal only) and
    ``vel, omega (N, 3)`` the end-of-step velocities it left; ``target_n, compliance_n (K,)`` its
    soft normal rows (``n·v + γ_n λ_n ≥ target_n ⟂ λ_n ≥ 0``); ``mu (K,)`` friction coefficients,
    ``v_reg`` the regularisation speed (m/s). Projected Gauss–Seidel over the contacts in a compiled
    loop (``pgs.soft_friction_sweeps``), each contact's normal row then its friction, so that the turning the friction causes (its lever
    below the centre of mass) is answered by the springs in the same solve: friction solved after
    the normal impulses alone rocked a block on an incline into a slow walk. Stops when a sweep
    changes no impulse by more than ``tolerance`` × the largest one, or after ``iterations``
    sweeps (the step passes ``settings.solver_iterations``). Returns the sweeps done. A fixed 12
    sweeps left a light ball squeezed between the ground and a ball 866 times heavier (k dt²/m =
    54) with normal impulses a quarter of its springs' forces: the spring compressed by work no
    force did, +612 J in a step; 20 sweeps converge there."""
    k = len(rows.a)
    if k == 0 or not np.any(mu > 0):
        return 0
    c = np.ascontiguousarray
    v = vel if vel.flags.c_contiguous and vel.dtype == np.float64 else np.ascontiguousarray(vel, dtype=float)
    w = omega if omega.flags.c_contiguous and omega.dtype == np.float64 else np.ascontiguousarray(omega, dtype=float)
    out = c(lam, dtype=float)
    sweeps = pgs.soft_friction_sweeps(c(rows.a, dtype=np.int64), c(rows.b, dtype=np.int64), c(rows.dirs),
                                      c(rows.ang_a), c(rows.ang_b), c(rows.iang_a), c(rows.iang_b),
                                      c(rows.ima, dtype=float), c(rows.imb, dtype=float), c(rows.K),
                                      c(target_n, dtype=float), c(compliance_n, dtype=float), c(mu, dtype=float),
                                      float(v_reg), out, v, w, int(iterations), float(tolerance))
    if out is not lam:
        lam[...] = out
    if v is not vel:
        vel[...] = v
    if w is not omega:
        omega[...] = w
    return int(sweeps)
