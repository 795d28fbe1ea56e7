"""Time of impact against closed forms: the bouncing ball (fractional exact, next_step error reported)."""
import os

import numpy as np
import pytest

import contact_sim as cs

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")
G, R, H0, E = 9.81, 0.1, 1.0, 0.8


def closed_form_height(t):
    """Centre height (m) of a ball dropped from H0 bouncing with restitution E on z=0 (radius R)."""
    t = np.asarray(t, float)
    fall = H0 - R
    t1 = np.sqrt(2 * fall / G)
    u = G * t1                      # impact speed
    z = np.empty_like(t)
    first = t <= t1
    z[first] = H0 - 0.5 * G * t[first] ** 2
    tb, ub = t1, E * u              # time of the last bounce and speed after it
    rest = ~first
    tt = t[rest]
    out = np.empty_like(tt)
    todo = np.ones(tt.shape, bool)
    for _ in range(200):
        flight = 2 * ub / G
        here = todo & (tt <= tb + flight)
        s = tt[here] - tb
        out[here] = R + ub * s - 0.5 * G * s * s
        todo &= ~here
        if not todo.any():
            break
        tb, ub = tb + flight, E * ub
    z[rest] = out
    return z


def run(toi, seconds=3.0):
    world = cs.load_scene(os.path.join(SCENES, "bouncing_ball.yaml"))
    world.settings.toi = toi
    dt = world.settings.dt
    n = int(round(seconds / dt))
    t, z = np.empty(n), np.empty(n)
    for i in range(n):
        world.step()
        t[i], z[i] = world.time, world.body("ball").position[2]
    return t, z, world


def test_fractional_height_exact_everywhere():
    t, z, world = run("fractional")
    err = np.abs(z - closed_form_height(t))
    assert err.max() <= 1e-9, err.max()
    assert np.sum(np.diff(np.sign(np.diff(z))) > 0) >= 5   # it really bounced (several minima)


def test_next_step_error_reported_and_of_order_dt():
    t, z, world = run("next_step")
    err = np.abs(z - closed_form_height(t))
    dt = world.settings.dt
    u = np.sqrt(2 * G * (H0 - R))
    print(f"next_step max height error {err.max():.4g} m (dt {dt:.4g} s, impact speed × dt = {u * dt:.4g} m)")
    # error of order dt: not exact, but bounded by a few impact-speed × dt
    assert 1e-6 < err.max() < 5 * u * dt


def test_quadratic_root_precision():
    from contact_sim.response.toi import _first_quadratic_root

    # (τ - 1e-3)(τ - 2): root 1e-3 with c0 tiny relative to c1 (cancellation-prone)
    tau = _first_quadratic_root(2e-3, -(2 + 1e-3), 1.0, 1.0)
    assert abs(tau - 1e-3) <= 1e-18
    assert np.isinf(_first_quadratic_root(1.0, 1.0, 1.0, 1.0))   # never reaches zero
