"""Graph colouring of contacts for the coloured Gauss–Seidel sweep, and the batched single-contact
path of the direct solver."""
import numpy as np
import pytest

from contact_sim.response import solver


def _check_valid(a, b, movable, colors):
    assert sorted(np.concatenate(colors).tolist()) == list(range(len(a)))
    for c in colors:
        bodies = np.concatenate([a[c][movable[a[c]]], b[c][movable[b[c]]]])
        assert len(np.unique(bodies)) == len(bodies)     # no movable body twice in a colour


def test_columns_get_few_colours():
    """100 columns of 10 spheres on the ground: every link shares a body with its neighbours, so
    two colours would do; the colouring stays at most three (not one per link)."""
    cols, height = 100, 10
    a, b = [], []
    n = 1 + cols * height           # body 0 the ground (static)
    for c in range(cols):
        base = 1 + c * height
        a.append(base), b.append(0)
        for k in range(height - 1):
            a.append(base + k + 1), b.append(base + k)
    a, b = np.array(a), np.array(b)
    movable = np.ones(n, bool)
    movable[0] = False
    colors = solver.color_contacts(a, b, movable)
    _check_valid(a, b, movable, colors)
    assert len(colors) <= 3


def test_random_graph_colouring_is_valid_and_maximal():
    rng = np.random.default_rng(3)
    n, k = 200, 1500
    a, b = rng.integers(0, n, k), rng.integers(0, n, k)
    b = np.where(a == b, (b + 1) % n, b)
    movable = rng.random(n) > 0.1
    colors = solver.color_contacts(a, b, movable)
    _check_valid(a, b, movable, colors)
    # maximal: every contact of a later colour conflicts with some contact of each earlier colour
    for i, c in enumerate(colors[:-1]):
        used = np.zeros(n, bool)
        used[a[c][movable[a[c]]]] = True
        used[b[c][movable[b[c]]]] = True
        later = np.concatenate(colors[i + 1:])
        assert np.all((movable[a[later]] & used[a[later]]) | (movable[b[later]] & used[b[later]]))


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
