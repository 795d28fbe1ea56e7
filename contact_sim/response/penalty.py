"""The penalty response's stage: a spring ``k·depth`` and damper ``−c·v_n`` along each contact
normal (never pulling), with regularised Coulomb friction, both integrated implicitly.

Normal: the force uses the depth and normal velocity at the *end* of the step, ``F = k·(d −
dt·v_n⁺) − c·v_n⁺``, which makes the impulse of each contact ``λ = dt·F`` the solution of ``v_n⁺ +
γλ = k·d/(dt·k + c)`` with compliance ``γ = 1/(dt·(dt·k + c))`` (the soft-constraint form of Catto's
soft step and ODE's CFM/ERP). Stable for every stiffness and step (the explicit spring exploded
above sqrt(k/m)·dt = 2, which the old defaults crossed for a 1 kg body at the default dt); rest is
still exactly k·depth = m g. The damper acts on a point inside; one apart meets the spring alone,
``λ = dt·k·max(depth at the end, 0)``, which is zero unless the point gets inside within the step.

Friction: ``F_t = −μ F_n v_t / max(|v_t|, v_r)``. Above the regularisation speed ``v_r``
(``settings.penalty.friction_velocity``) the force is Coulomb's, ``μ F_n`` against the sliding
direction; below it a damper of coefficient ``μ F_n / v_r`` (Karnopp's and ODE's regularised
friction). The damper is far too stiff for explicit integration (``μ g dt / v_r`` is ~200 for a
1e-4 m/s regulariser at dt 1/240), so it is integrated implicitly, as the normal spring is: the
force uses the tangential velocity at the *end* of the step, ``λ_t = −(μ λ_n / v_r) v_t⁺``
(impulses, ``λ_n`` the contact's normal impulse of the step), i.e. the soft constraint ``v_t⁺ + γ
λ_t = 0`` with compliance ``γ = v_r / (μ λ_n)``, with ``|λ_t| ≤ μ λ_n`` (the Coulomb cap). Solved by
projected Gauss–Seidel, a compiled loop over the contacts, on the velocities after the normal
impulses.

What it guarantees: a sliding body decelerates at ``μ g`` until ``|v_t| ≈ v_r`` (then stops
exponentially, with time constant ``v_r / (μ g)``), so its stopping distance is ``v0²/(2μg)`` to
within ``v_r`` and the step's first-order error; a body held by friction creeps at the speed where
the damper balances the pull: ``v_r · tan θ / μ`` on an incline of angle ``θ`` (the warning
``PenaltyFrictionWarning`` fires when ``v_r`` lets that reach ``models.FRICTION_CREEP_LIMIT``).
"""
import numpy as np

from ..jit import njit
from .pgs import soft_friction_sweeps
from .solver import SOFT, solve_rows


@njit
def penalty_stage(a, b, depth, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, mu, friction, stiffness, damping, v_reg,
                  dt, movable, inv_mass, inv_inertia, direct_max, iterations, tolerance, friction_tolerance, v_end,
                  w_end, lam):
    """The penalty impulses of a step of ``dt`` on ``K`` contacts (rows as ``rows.Rows``' arrays,
    ``depth (K,)``), from the end-of-step velocities without contact ``v_end, w_end (N,3)``, which
    it updates: the springs' normal rows (``solver.solve_rows``' ``SOFT`` method), then with
    ``friction`` the regularised Coulomb friction (``mu (K,)``, ``v_reg`` m/s) with the normal rows
    again, per contact (``pgs.soft_friction_sweeps``: friction solved after the normal impulses
    alone rocked a block on an incline into a slow walk), until a sweep changes no impulse by more
    than ``friction_tolerance`` × the largest one or after ``iterations`` sweeps (a fixed 12 left a
    light ball squeezed between the ground and a ball 866 times heavier with a quarter of its
    springs' forces: +612 J in a step; 20 converge there). Writes ``lam (K,3)`` (zeros in).
    Returns ``(sweeps, residual, friction sweeps, the normal rows' solve stopped unconverged)``."""
    k = a.shape[0]
    target, gamma = np.empty(k), np.empty(k)
    for c in range(k):
        damp = damping if depth[c] >= 0.0 else 0.0   # the damper acts on a point inside
        gamma[c] = 1.0 / (dt * (dt * stiffness + damp))
        target[c] = stiffness * depth[c] / (dt * stiffness + damp)
    zeros = np.zeros(k)
    it, residual, stopped = solve_rows(SOFT, a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, gamma,
                                       zeros, zeros, False, np.zeros((k, 3)), False, movable, inv_mass, inv_inertia,
                                       direct_max, iterations, tolerance, v_end, w_end, lam)
    sweeps = 0
    if friction and k and np.any(mu > 0.0):
        sweeps = soft_friction_sweeps(a, b, dirs, ang_a, ang_b, iang_a, iang_b, ima, imb, K, target, gamma, mu, v_reg,
                                      lam, v_end, w_end, iterations, friction_tolerance)
    return it, residual, sweeps, stopped
