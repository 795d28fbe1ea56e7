"""The batched single-contact path of the direct solver."""
import numpy as np
import pytest

from contact_sim.response import solver


@pytest.mark.parametrize("spin, converged", [(0.01, True), (1.0, False)])
def test_single_contacts_batched_equal_the_active_set_answer(spin, converged):
    """Spheres each touching only the ground (independent contacts): the batched 3×3 path gives the
    active-set solver's impulses to round-off, separating contacts get none, sliding ones (outside
    the static cone) are left to the general path and still come out the same."""

    rng = np.random.default_rng(5)
    k = 60                                             # > DIRECT_DENSE_MAX: the split path runs
    n = k + 1
    pos = np.zeros((n, 3))
    pos[1:, :2] = rng.uniform(-5, 5, (k, 2))
    pos[1:, 2] = 0.1
    inv_mass = np.r_[0.0, np.full(k, 2.0)]
    inertia_inv = np.zeros((n, 3, 3))
    inertia_inv[1:] = np.eye(3) / (0.4 * 0.5 * 0.01)
    vel = np.zeros((n, 3))
    vel[1:] = rng.normal(0, 0.5, (k, 3))
    vel[1:, :2] *= spin                                # slow tangential motion: every contact sticks
    omega = np.zeros((n, 3))
    omega[1:] = rng.normal(0, 2.0, (k, 3)) * spin
    a = np.arange(1, n)
    b = np.zeros(k, np.int64)
    normal = np.tile([0.0, 0.0, 1.0], (k, 1))
    point = pos[1:] - 0.1 * normal
    rows = solver.build_rows(a, b, point, normal, pos, inv_mass, inertia_inv, vel, omega)
    mu = np.full(k, 0.5)
    target = np.zeros(k)
    out = []
    for split in (True, False):
        v, w = vel.copy(), omega.copy()
        res, ok = solver.solve_direct(rows, v, w, target_n=target, mu_s=mu, mu_d=mu, _split=split)
        out.append((res.impulse, ok, v, w))
    (l1, ok1, v1, w1), (l2, ok2, v2, w2) = out
    assert ok1 == ok2 == converged
    assert np.allclose(l1, l2, rtol=0, atol=1e-12)
    if ok1:
        assert np.allclose(v1, v2, atol=1e-12) and np.allclose(w1, w2, atol=1e-12)
    separating = solver.row_velocity(rows, vel, omega)[:, 0] >= 0
    assert separating.any() and np.all(l1[separating] == 0)
