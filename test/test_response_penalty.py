"""Penalty response: rest depth mg/k, and the stiffness warning naming the pair."""
import os
import warnings

import pytest

import contact_sim as cs
from contact_sim.response import PenaltyStiffnessWarning

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")


def test_penalty_rest_depth_is_mg_over_k():
    world = cs.load_scene(os.path.join(SCENES, "penalty_rest.yaml"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", PenaltyStiffnessWarning)   # this k is fine for this dt
        for _ in range(480):
            world.step()
    k = world.settings.penalty.stiffness
    expect = 1.0 * 9.81 / k
    depth = 0.1 - world.body("ball").position[2]
    print(f"penalty rest depth {depth * 1e3:.5f} mm, mg/k {expect * 1e3:.5f} mm")
    assert abs(depth / expect - 1) <= 0.01
    assert abs(world.contacts.normal_impulse.sum() / world.settings.dt - 9.81) <= 0.01 * 9.81


def test_penalty_too_stiff_warns_naming_the_pair():
    import yaml

    with open(os.path.join(SCENES, "penalty_rest.yaml")) as fh:
        data = yaml.safe_load(fh)
    data["settings"]["penalty"]["stiffness"] = 1e8
    world = cs.load_scene(data)
    with pytest.warns(PenaltyStiffnessWarning, match="'ball'.*'ground'|'ground'.*'ball'"):
        world.step()
    assert any("penalty stiffness" in line for line in cs.stepper.describe_models(world)) \
        if hasattr(cs, "stepper") else True


def _falling_ball(gap, speed, k=5000.0, c=100.0, friction=0.0, dt=0.01):
    """A 1 kg ball (radius 0.1) ``gap`` (m) above the ground moving down at ``speed``, no gravity."""
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(dt=dt, response="penalty", penalty={"stiffness": k, "damping": c}),
                 materials={"m": cs.Material(restitution=0.0, friction=friction)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=(0, 0, 0.1 + gap), velocity=(0, 0, -speed), material="m")
    return w


def test_a_point_that_gets_inside_within_the_step_meets_its_spring_in_that_step():
    """Speculative penalty contacts: a ball 2 mm above the ground at 1 m/s reaches 5.3 mm deep by
    the end of a 10 ms step. Its spring acts on that end depth (implicit, spring alone while the
    point was apart: no damper): m(u⁺ − u) = −dt k (dt u⁺ − gap), so u⁺ = (m u + dt k gap)/(m + k dt²),
    and the energy (kinetic + ½k depth²) does not grow. Seen only once inside, the first step in
    compressed the spring by 8 mm with nothing resisting: energy from no work."""
    m, k, dt, u, gap = 1.0, 5000.0, 0.01, 1.0, 0.002
    w = _falling_ball(gap, u, k=k, dt=dt)
    z0 = w.body("ball").position[2]
    w.step()
    up = (m * u + dt * k * gap) / (m + k * dt * dt)
    assert abs(w.body("ball").velocity[2] + up) <= 1e-12, (w.body("ball").velocity, up)
    assert abs(w.body("ball").position[2] - (z0 - dt * up)) <= 1e-12
    depth = dt * up - gap
    assert abs(w.contacts.normal_impulse.sum() - dt * k * depth) <= 1e-9
    assert 0.5 * m * up ** 2 + 0.5 * k * depth ** 2 <= 0.5 * m * u ** 2


def test_a_speculative_penalty_contact_that_does_not_close_is_no_contact():
    """8 mm above the ground at 0.5 m/s: 5 mm of travel in the step, no spring, no contact, and the
    ball moves ballistically (exactly 5 mm)."""
    w = _falling_ball(0.008, 0.5)
    w.step()
    assert len(w.contacts) == 0 and w.last_solve.contacts == 0
    assert abs(w.body("ball").position[2] - (0.108 - 0.005)) <= 1e-15
    assert w.body("ball").velocity[2] == -0.5


@pytest.mark.parametrize("mu", [2.2250738585e-313, 5e-324, 1e-300])
def test_penalty_friction_with_a_vanishing_coefficient_stays_finite(mu):
    """A denormal friction coefficient made the implicit friction damper's compliance v_reg/(μλn)
    overflow to inf, and inf/inf NaN impulses (a static wall's velocity among them): the step was
    refused as non-finite. Solved through the conductance μλn/v_reg it is finite; the friction
    impulse stays within μλn (here: nothing)."""
    import numpy as np

    w = _falling_ball(0.0, 0.0, friction=mu)
    w.gravity = (0, 0, -9.81)
    w.set_state("ball", velocity=(0.5, 0.2, -0.3))
    for _ in range(20):
        w.step()
        c = w.contacts
        assert np.all(np.linalg.norm(c.friction_impulse, axis=1) <= mu * c.normal_impulse + 1e-300)
    assert all(np.isfinite(a).all() for a in w.velocities()) and np.isfinite(w.poses()[0]).all()
    assert abs(w.body("ball").velocity[0] - 0.5) <= 1e-12   # no friction to slow it
