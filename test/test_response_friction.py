"""Coulomb friction and resting contact against closed forms: sliding block, incline."""
import math
import os

import numpy as np
import pytest

import contact_sim as cs

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")
G = 9.81


def _scene(name):
    import yaml

    with open(os.path.join(SCENES, name)) as fh:
        return yaml.safe_load(fh)


def test_sliding_block_stop_distance():
    world = cs.load_scene(os.path.join(SCENES, "sliding_block.yaml"))
    assert abs(world.settings.dt - 1 / 240) < 1e-15
    v0, mu = 2.0, 0.5
    x0 = world.body("block").position[0]
    for _ in range(240):
        world.step()
    b = world.body("block")
    d = b.position[0] - x0
    expect = v0 ** 2 / (2 * mu * G)
    print(f"stop distance {d:.6f} m, closed form {expect:.6f} m, error {100 * (d / expect - 1):.4f} %")
    assert abs(d / expect - 1) <= 0.005
    assert np.linalg.norm(b.velocity) < 1e-6                 # stopped, and stays stopped
    assert abs(b.position[2] - 0.1) < 1e-4                    # neither sank nor jumped
    assert world.last_solve["residual"] <= 1e-6


def _incline(theta_deg):
    data = _scene("incline.yaml")
    t = np.radians(theta_deg)
    n = [float(np.sin(t)), 0.0, float(np.cos(t))]
    data["bodies"][0]["shape"]["normal"] = n
    data["bodies"][1]["position"] = [0.1 * n[0], 0.0, 0.1 * n[2]]
    data["bodies"][1]["orientation"] = [0.0, float(np.sin(t / 2)), 0.0, float(np.cos(t / 2))]
    return cs.load_scene(data), np.array([np.cos(t), 0.0, -np.sin(t)])   # down-slope direction


def test_incline_below_friction_angle_stays():
    world, down = _incline(20.0)
    p0 = world.body("block").position.copy()
    for _ in range(480):   # 2 s
        world.step()
    drift = np.linalg.norm(world.body("block").position - p0)
    print(f"incline 20°: drift {drift * 1e3:.4g} mm in 2 s")
    assert drift < 1e-4


def test_incline_above_friction_angle_slides_with_closed_form_acceleration():
    theta, mu = 35.0, 0.5
    world, down = _incline(theta)
    a_expect = G * (np.sin(np.radians(theta)) - mu * np.cos(np.radians(theta)))
    p0 = world.body("block").position.copy()
    ts, ss = [], []
    for _ in range(240):   # 1 s
        world.step()
        ts.append(world.time)
        ss.append((world.body("block").position - p0) @ down)
    ts, ss = np.array(ts), np.array(ss)
    a_fit = np.polyfit(ts, ss, 2)[0] * 2
    v = world.body("block").velocity @ down
    print(f"incline 35°: a {a_fit:.5f} (fit), v/t {v / ts[-1]:.5f}, closed form {a_expect:.5f}")
    assert abs(a_fit / a_expect - 1) <= 0.01
    assert abs(v / ts[-1] / a_expect - 1) <= 0.01


def _stack(n=4, **settings):
    w = cs.World(settings=cs.Settings(toi="next_step", **settings), materials={"m": cs.Material(0.0, 0.6)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    for i in range(n):
        w.add_body(f"box{i}", cs.Box((0.2, 0.2, 0.2)), mass=1.0 + i, position=(0.01 * i, 0, 0.1 + 0.2 * i),
                   velocity=(0.3, 0, 0), material="m")
    return w


@pytest.mark.parametrize("method", ["auto", "gs"])
def test_a_step_whose_solve_stops_at_the_iteration_limit_says_so(method):
    """``last_solve.unconverged``: a solve stopped at ``solver_iterations`` with an impulse still
    changing by more than ``solver_tolerance``. A box sliding on the ground given two Gauss–Seidel
    sweeps cannot converge; with the defaults the same steps do."""
    short, full = _stack(1, solver_method=method, solver_iterations=2), _stack(1, solver_method=method)
    flags = []
    for _ in range(10):
        short.step()
        full.step()
        s = short.last_solve
        assert s.unconverged == (s.iterations >= 2 and s.residual > short.settings.solver_tolerance)
        flags.append(s.unconverged)
        assert not full.last_solve.unconverged, full.last_solve
    assert any(flags)


def test_the_resting_work_bound_holds_for_any_impulses():
    """``resting._work_bound``: ``½|λ|·|u_start|`` plus, where a solve stopped short, the positive part
    of ``λn (u_end,n − target)`` and of ``λt·u_end,t``; zero beyond the first term for a
    complementary answer."""
    from contact_sim.response.resting import _work_bound

    a, b = np.array([0]), np.array([1])               # A the sliding body, B static
    dirs = np.eye(3)[None].copy()                      # n = x, t1 = y, t2 = z; the contact at A's centre
    ang = np.zeros((1, 3, 3))
    vel0 = np.array([[0.0, 0.3, 0], [0.0, 0, 0]])      # A slides along t1 at 0.3 m/s
    zero = np.zeros((2, 3))
    target = np.array([-0.1])
    lam = np.array([[2.0, -0.5, 0.0]])
    base = 0.5 * np.linalg.norm(lam[0]) * 0.3
    # converged: the normal row at its target, the friction opposing the slide at the end
    end = np.array([[-0.1, 0.1, 0], [0.0, 0, 0]])
    assert _work_bound(a, b, dirs, ang, ang, vel0, zero, end, zero, target, lam) == pytest.approx(base, rel=1e-15)
    # stopped short: pushing (λn > 0) while 0.05 m/s above its target, friction along the slide
    end = np.array([[-0.05, -0.2, 0], [0.0, 0, 0]])
    got = _work_bound(a, b, dirs, ang, ang, vel0, zero, end, zero, target, lam)
    assert got == pytest.approx(base + 0.5 * (2.0 * 0.05 + 0.5 * 0.2), rel=1e-15)


@pytest.mark.parametrize("scale", [1e-162, 1e-100, 1.0, 1e100, 1e160])
def test_the_kinetic_disc_projection_is_the_same_at_any_magnitude(scale):
    """``pgs.disc`` is homogeneous: a sliding velocity and a disc radius both ``scale`` times larger
    give an impulse ``scale`` times larger. At 1e-162 m/s the Newton step squared the impulse to 0
    and divided 0 by 0 (a ZeroDivisionError from the compiled solver on valid input)."""
    from contact_sim.response.pgs import disc

    k = (0.5507439913131433, -0.07363547753712203, 0.5304387116145647)   # an anisotropic block
    f, r = np.array([3.6026297847417245, -5.765601996530567]), 2.756698587907222
    want = np.array(disc(*k, f[0], f[1], r, 12))
    got = np.array(disc(*k, f[0] * scale, f[1] * scale, r * scale, 12))
    assert np.isfinite(got).all() and math.hypot(*got) == pytest.approx(r * scale, rel=1e-12)
    np.testing.assert_allclose(got / scale, want, rtol=1e-12)
