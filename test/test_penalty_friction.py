"""Penalty response with regularised Coulomb friction (issue 14, part 3): stopping distance
v0²/(2μg), holding on an incline below the friction angle, its setting and its preflight warning."""
import warnings

import numpy as np
import pytest

import contact_sim as cs
from contact_sim.response import PenaltyFrictionWarning, PenaltyStiffnessWarning

pytestmark = pytest.mark.exact

G = 9.81
DT = 1 / 240
K = 5.0e4           # sqrt(k/m)·dt = 0.93 for the 1 kg block: the preflight accepts it


def block_world(mu, slope_deg=0.0, v0=0.0, friction_velocity=None):
    """A 1 kg, 0.2 m cube on a static plane through the origin tilted by ``slope_deg`` about y;
    ``v0`` down the slope (along the plane)."""
    th = np.radians(slope_deg)
    n = np.array([np.sin(th), 0.0, np.cos(th)])           # plane normal, the slope descends along +x
    down = np.array([np.cos(th), 0.0, -np.sin(th)])
    pen = {"stiffness": K, "damping": 2 * 0.7 * np.sqrt(K)}
    if friction_velocity is not None:
        pen["friction_velocity"] = friction_velocity
    w = cs.World(gravity=(0, 0, -G), settings={"dt": DT, "response": "penalty", "friction": True, "penalty": pen},
                 materials={"m": {"restitution": 0.0, "friction": mu, "static_friction": mu}})
    w.add_body("ground", cs.Plane(n, 0.0), kind="static", material="m")
    q = [0.0, np.sin(th / 2), 0.0, np.cos(th / 2)]          # the cube's bottom face on the plane
    sink = 1.0 * G * np.cos(th) / K / 4 * 4                  # rest depth m g cosθ / k
    w.add_body("block", cs.Box([0.2, 0.2, 0.2]), mass=1.0, position=n * (0.1 - sink), orientation=q,
               velocity=down * v0, material="m")
    return w, down


def test_sliding_block_stops_at_v0_squared_over_2_mu_g():
    mu, v0 = 0.5, 4.0
    w, down = block_world(mu, v0=v0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PenaltyStiffnessWarning)
        warnings.simplefilter("error", PenaltyFrictionWarning)
        x0 = w.body("block").position.copy()
        for _ in range(int(1.5 / DT)):          # stops after v0/(μg) = 0.82 s
            w.step()
    travel = float((w.body("block").position - x0) @ down)
    expect = v0 * v0 / (2 * mu * G)
    assert abs(travel / expect - 1) <= 0.01, (travel, expect)
    assert np.linalg.norm(w.body("block").velocity) < 1e-3
    # the friction impulses oppose the motion and are at most μ × the normal ones
    c = w.contacts
    assert np.all(np.linalg.norm(c.friction_impulse, axis=1) <= mu * c.normal_impulse * (1 + 1e-9) + 1e-15)


def test_block_stays_on_an_incline_below_the_friction_angle():
    mu = 0.5
    slope = 20.0                                    # tan 20° = 0.36 < 0.5
    w, down = block_world(mu, slope_deg=slope)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PenaltyStiffnessWarning)
        warnings.simplefilter("error", PenaltyFrictionWarning)
        for _ in range(int(0.5 / DT)):              # settle onto the spring
            w.step()
        x0 = w.body("block").position.copy()
        for _ in range(int(2.0 / DT)):
            w.step()
    drift = np.linalg.norm(w.body("block").position - x0)
    assert drift < 1e-3, drift
    # the creep the regulariser allows: v_r tanθ/μ
    creep = 1e-4 * np.tan(np.radians(slope)) / mu
    assert abs(float(w.body("block").velocity @ down)) <= 2 * creep


def test_block_slides_above_the_friction_angle():
    mu, slope = 0.3, 30.0                           # tan 30° = 0.58 > 0.3: a = g (sinθ − μ cosθ)
    w, down = block_world(mu, slope_deg=slope)
    for _ in range(int(0.25 / DT)):
        w.step()
    v1 = float(w.body("block").velocity @ down)
    for _ in range(int(0.5 / DT)):
        w.step()
    v2 = float(w.body("block").velocity @ down)
    th = np.radians(slope)
    a = G * (np.sin(th) - mu * np.cos(th))
    assert abs((v2 - v1) / 0.5 / a - 1) <= 0.01


def test_friction_off_keeps_the_old_penalty_model():
    w, down = block_world(0.5, v0=2.0)
    w.settings.friction = False
    for _ in range(60):
        w.step()
    assert abs(float(w.body("block").velocity @ down) - 2.0) <= 1e-9


def test_friction_velocity_setting_is_checked_and_warned():
    with pytest.raises(cs.ContactSimError, match=r"settings\.penalty\.friction_velocity: must be > 0"):
        cs.Settings(penalty={"friction_velocity": 0.0})
    with pytest.raises(cs.ContactSimError, match=r"friction_velocity"):
        cs.Settings(penalty={"friction_velocity": float("nan")})
    w, _ = block_world(0.5, slope_deg=10.0, friction_velocity=0.01)
    with pytest.warns(PenaltyFrictionWarning, match="friction_velocity 0.01 m/s"):
        w.step()


def test_a_friction_solve_stopped_at_the_sweep_limit_is_reported_unconverged():
    """The penalty step's friction solve (Gauss–Seidel) runs to ``settings.solver_iterations`` and
    counts as unconverged when that stops it, as the other solves do: a box sliding on the ground
    (four coupled corner contacts) is unconverged after one sweep, converged with the default 100."""
    import contact_sim as cs

    def slide(iterations):
        w = cs.World(settings=cs.Settings(response="penalty", dt=0.002, solver_iterations=iterations),
                     materials={"m": cs.Material(friction=0.5)})
        w.add_body("ground", cs.Plane(), kind="static", material="m")
        w.add_body("box", cs.Box([0.2, 0.2, 0.2]), mass=1.0, position=[0, 0, 0.1 - 9.81 / w.settings.penalty.stiffness / 4],
                   velocity=[1.0, 0.0, 0.0], material="m")
        w.step()
        return w.last_solve["unconverged"]

    assert slide(1) is True
    assert slide(100) is False
