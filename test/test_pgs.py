"""Projected Gauss–Seidel's stopping rules (``pgs.sweeps``): the tolerance, the sweep limit, and the
stall rule, which stops sweeps that no longer make progress (friction's cycle) and leaves every
converging solve as it was, bit for bit.

Not in the ``exact`` set: the cycle is shown sweep by sweep (a solve per sweep count), too slow
without the JIT."""
import numpy as np
import pytest

from contact_sim import dynamics, quat
from contact_sim.constants import PGS_STALL_SWEEPS
from contact_sim.response import solver
from scenegen import random_contacts

LIMIT = 400


def _problem(seed, nb=20, k=60, scale=1.0):
    """Random bodies (masses 0.3-2 kg, inertias 0.05-0.5 kg m², random orientations; both times
    ``scale``) and ``k`` random contacts between them with random normals, every body moving: a
    coupled system Gauss–Seidel has to iterate on."""
    rng = np.random.default_rng(seed)
    inv_mass = 1 / rng.uniform(0.5, 3, nb) / scale
    inv_i_body = np.stack([np.diag(1 / rng.uniform(0.05, 0.5, 3)) for _ in range(nb)]) / scale
    inv_i = dynamics.world_inverse_inertia(quat.normalize(rng.normal(size=(nb, 4))), inv_i_body)
    pos, vel, omega, a, b, normal, point = random_contacts(rng, nb, k)
    rows = solver.build_rows(a, b, point, normal, pos, inv_mass, inv_i, vel, omega)
    return rows, vel, omega


def _solve(problem, friction, **kw):
    rows, vel, omega = problem
    k = len(rows.a)
    mu = np.full(k, 0.7) if friction else None
    return solver.solve(rows, vel.copy(), omega.copy(), target_n=np.zeros(k), mu_s=mu,
                        mu_d=None if mu is None else 0.5 * mu, **kw)


@pytest.mark.parametrize("seed", [0, 5, 9])
def test_sweeps_that_cycle_stop_and_say_so(seed):
    """With friction (static 0.7, kinetic 0.35) these systems do not converge: the largest velocity
    change of a sweep wanders (seed 0), repeats with a period of 12 sweeps (seed 9), or falls
    geometrically until a contact switches between sticking and sliding and throws it back up
    (seed 5). The stall rule stops after ``PGS_STALL_SWEEPS`` sweeps without a new smallest change,
    reports the solve unconverged, and gives up little: no sweep up to ``LIMIT`` gets below half
    the smallest change it had seen (seed 5's best over 400 sweeps, 7.2e-3 m/s, against 9.4e-3)."""
    p = _problem(seed)
    res = _solve(p, True, iterations=LIMIT, tolerance=1e-12)
    assert PGS_STALL_SWEEPS < res.iterations < LIMIT and res.unconverged and res.residual > 1e-12
    # the residual after exactly n sweeps, for every n (each a solve from the start: same arithmetic)
    per_sweep = np.array([_solve(p, True, iterations=n, tolerance=1e-12, stall=0).residual
                          for n in range(1, LIMIT + 1)])
    assert per_sweep[res.iterations - 1] == res.residual   # the rule only stops: the same sweeps
    assert per_sweep[res.iterations:].min() >= 0.5 * per_sweep[:res.iterations].min()
    # the rule's count: the last new smallest change came PGS_STALL_SWEEPS sweeps before it stopped
    seen = np.minimum.accumulate(per_sweep[:res.iterations])
    last_new = np.flatnonzero(np.r_[True, seen[1:] < seen[:-1]])[-1]
    assert res.iterations - 1 - last_new == PGS_STALL_SWEEPS
    full = _solve(p, True, iterations=LIMIT, tolerance=1e-12, stall=0)
    assert full.iterations == LIMIT and full.unconverged


@pytest.mark.parametrize("seed", range(6))
def test_converging_sweeps_are_untouched_by_the_stall_rule(seed):
    """Without friction Gauss–Seidel converges (the systems above, frictionless: a convex
    problem): with the stall rule and without it the same sweeps, the same impulses bit for bit,
    down to the tolerance. (A frictional solve that converges, a box sliding on the ground under
    ``solver_method="gs"``: test_response_friction.)"""
    p = _problem(seed)
    ruled = _solve(p, False, iterations=3000, tolerance=1e-12)
    free = _solve(p, False, iterations=3000, tolerance=1e-12, stall=0)
    assert not ruled.unconverged and ruled.residual <= 1e-12
    assert ruled.iterations == free.iterations
    assert np.array_equal(ruled.impulse, free.impulse)


def test_the_step_solve_reports_a_stalled_solve_unconverged():
    """``solve_auto`` (the step's ``solve_rows``) with Gauss–Seidel: a cycling solve stops before
    its sweep limit and says unconverged; a converging one reaches its tolerance."""
    rows, vel, omega = _problem(0)
    k = len(rows.a)
    mu = np.full(k, 0.7)
    res = solver.solve_auto(rows, vel.copy(), omega.copy(), target_n=np.zeros(k), mu_s=mu, mu_d=0.5 * mu,
                            iterations=LIMIT, tolerance=1e-12, method="gs")
    assert res.iterations < LIMIT and res.unconverged
    res = solver.solve_auto(rows, vel.copy(), omega.copy(), target_n=np.zeros(k), iterations=LIMIT,
                            tolerance=1e-12, method="gs")
    assert res.residual <= 1e-12 and not res.unconverged


@pytest.mark.parametrize("friction", [False, True])
def test_the_tolerance_is_a_speed(friction):
    """``tolerance`` is in m/s: a sweep's largest change is the velocity a row changed at its own
    contact (its impulse change times its effective inverse mass), so the same system with every
    mass and inertia 1024 times larger or smaller (a power of two: the same arithmetic, impulses
    scaled exactly) stops at the same sweep with the same residual, bit for bit. Measured in
    impulse (N·s), as it was, the heavy system would stop 1024 times later in the residual's scale
    and the light one sooner."""
    scales = (2.0 ** -10, 1.0, 2.0 ** 10)
    runs = [_solve(_problem(3, scale=s), friction, iterations=3000, tolerance=1e-7) for s in scales]
    for r, s in zip(runs, scales):
        assert r.iterations == runs[1].iterations and r.residual == runs[1].residual
        assert np.array_equal(r.impulse, runs[1].impulse * s)
    assert runs[1].iterations > 5 and (friction or (runs[1].residual <= 1e-7 and not runs[1].unconverged))
