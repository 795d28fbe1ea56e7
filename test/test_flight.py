"""The free-flight step (``stepper.flight``): where the step before found no candidate pair, the
broad phase and the advance run as one compiled call. It must leave exactly what the whole pipeline
leaves (state, contacts, statistics, contact cache, time) and decline, with the world unchanged,
whatever it does not cover."""
import dataclasses

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import stepper
from contact_sim.response import models

from test_substep import _same_step


def _ball(**settings):
    """A ball dropped from 1 m onto a plane (e = 0.8): flight, bounces, flight."""
    w = cs.World(settings=cs.Settings(**{"toi": "next_step", "dt": 1 / 240, **settings}),
                 materials={"m": cs.Material(restitution=0.8, friction=0.3)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, material="m", position=(0, 0, 1.0))
    return w


def _tumbling():
    """A box thrown up spinning about an axis between its principal ones (its free rotation
    splits, so a flight step's drift is not zero), a ball beside it, a kinematic paddle gliding past
    above them both, a disabled pair; all of it lands on the ground."""
    w = cs.World(settings=cs.Settings(toi="next_step", dt=0.005),
                 materials={"m": cs.Material(restitution=0.3, friction=0.5)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("box", cs.Box((0.3, 0.2, 0.1)), mass=2.0, material="m", position=(0, 0, 0.5),
               velocity=(0.1, 0, 2.0), angular_velocity=(3.0, 7.0, 1.0))
    w.add_body("ball", cs.Sphere(0.05), mass=0.3, material="m", position=(1.0, 0, 0.3), velocity=(0, 0.2, 1.0))
    w.add_body("paddle", cs.Box((0.2, 0.2, 0.02)), kind="kinematic", material="m", position=(-2.0, 0, 3.0),
               velocity=(0.5, 0, 0))
    w.disabled_pairs = [("box", "ball")]
    return w


def _alone():
    """One body and nothing else: no pair to look for."""
    w = cs.World(settings=cs.Settings(toi="next_step", dt=0.01))
    w.add_body("box", cs.Box((0.3, 0.2, 0.1)), mass=1.0, velocity=(1, 0, 3), angular_velocity=(2.0, 5.0, 0.5))
    return w


def _detection(w):
    d = dataclasses.asdict(w.last_detection)
    d.pop("seconds")
    return d


def step_diff(wa, wb):
    """What differs between two worlds after a step: ``_same_step``'s (state, contacts, statistics,
    contact cache), where the step left the bodies, the time, the detection's statistics (all but
    their seconds)."""
    diff = _same_step(wa, wb)
    diff += ["stepped"] if not np.array_equal(wa.s.stepped, wb.s.stepped) else []
    diff += ["time"] if wa.time != wb.time else []
    diff += ["last_detection"] if _detection(wa) != _detection(wb) else []
    return diff


def _both_ways(make, steps, monkeypatch, edits=None):
    """Step a scene with the flight and a copy through the whole pipeline only, comparing every
    step (``edits``: step → a change made to both worlds before it); returns the flown world and
    how many steps the flight took."""
    wa, wb = make(), make()
    real = stepper.flight
    flown = 0

    def counted(w, dt):
        nonlocal flown
        m = real(w, dt)
        flown += m is None
        return m

    for i in range(steps):
        for w, flight in ((wa, counted), (wb, lambda w, dt: models.choose(w, dt))):
            monkeypatch.setattr(stepper, "flight", flight)
            if edits and i in edits:
                edits[i](w)
            w.step()
        diff = step_diff(wa, wb)
        assert not diff, f"step {i}: {diff}"
    return wa, flown


@pytest.mark.exact
def test_a_bouncing_ball_flies_bit_for_bit_as_the_pipeline_steps_it(monkeypatch):
    w, flown = _both_ways(_ball, 480, monkeypatch)
    # not vacuous: most steps are flight, some are bounces through the pipeline, and the pair
    # cache was rebuilt inside flights
    assert 300 < flown < 480
    assert w.s.vel[1, 2] != 0.0 and w.time == pytest.approx(2.0)


@pytest.mark.exact
@pytest.mark.parametrize("speculative", [True, False])
def test_tumbling_bodies_a_kinematic_paddle_and_a_disabled_pair_fly_bit_for_bit(speculative, monkeypatch):
    def make():
        w = _tumbling()
        w.settings.speculative = speculative
        return w

    w, flown = _both_ways(make, 200, monkeypatch)
    assert flown > 50
    assert w.last_solve.contacts > 0 or w.s.pos[1, 2] < 0.3   # the box came down


@pytest.mark.exact
def test_a_lone_body_flies_bit_for_bit_and_its_drift_is_reported(monkeypatch):
    w, flown = _both_ways(_alone, 50, monkeypatch)
    assert flown == 49   # all but the first step of the dt (its preflight warnings)
    assert w.last_solve.rotation_drift != 0.0


@pytest.mark.exact
def test_what_the_flight_keeps_is_renewed_when_the_scene_changes_between_steps(monkeypatch):
    """The flight keeps what the scene fixes (``stepper._plan``): gravity, a settings field, a
    step of another ``dt``, a body added, a pair disabled and the look-ahead switched off between
    steps are each seen at the next step, which stays bit for bit the pipeline's."""
    edits = {20: lambda w: setattr(w, "gravity", (0.5, 0.0, -3.0)),
             40: lambda w: setattr(w.settings, "contact_margin", 0.01),
             60: lambda w: w.step(1 / 500),
             80: lambda w: w.add_body("late", cs.Sphere(0.05), mass=0.5, position=(2.0, 0, 2.0), velocity=(0, 0, 1.0)),
             100: lambda w: w.disable_collisions([("late", "ball")]),
             120: lambda w: setattr(w.settings, "speculative", False)}
    wa, flown = _both_ways(_ball, 140, monkeypatch, edits)
    assert flown > 100 and len(wa) == 3 and wa.s.vel[1, 0] > 0.0   # flights under the new gravity too


@pytest.mark.exact
@pytest.mark.parametrize("settings", [{"toi": "fractional"}, {"toi": "swept"}, {"response": "penalty", "dt": 1e-3}])
def test_the_flight_declines_what_it_does_not_cover_and_leaves_the_world_unchanged(settings):
    w = _ball(**settings)
    w.set_state("ball", position=(0, 0, 5.0))
    w.step()
    w.step()
    before = w.snapshot()
    assert stepper.flight(w, w.settings.dt) is not None
    after = w.snapshot()
    assert w.time == before.time
    for f in ("pos", "vel", "quat", "omega", "stepped"):
        assert np.array_equal(getattr(before.state, f), getattr(after.state, f))


@pytest.mark.exact
def test_a_motion_that_would_not_be_finite_is_declined_with_the_state_untouched():
    """The kernel itself: a speed whose displacement overflows is handed back to the pipeline (which
    names the body), the state arrays as they were."""
    pos, vel = np.array([[0.0, 0.0, 1e308]]), np.array([[0.0, 0.0, 1e308]])
    quat, omega, stepped = np.array([[0.0, 0.0, 0.0, 1.0]]), np.zeros((1, 3)), np.zeros((1, 7))
    state = [a.copy() for a in (pos, vel, quat, omega, stepped)]
    yes = np.ones(1, bool)
    with np.errstate(over="ignore", invalid="ignore"):   # numpy's scalars warn where the kernel runs as Python
        fixed = stepper.pack(quat.copy(), np.ones((1, 3)), np.eye(3)[None], np.array([0.0, 0.0, -9.81]), yes, yes,
                             ~yes, False, np.ones(1), yes, np.ones(1), 1.0, False, 0.0, 0.0, False,
                             np.zeros(0, np.int64), np.zeros((1, 3)), np.ones((1, 3)), np.zeros(0, np.int64),
                             np.zeros((1, 3)), np.zeros(1), np.ones(1, np.uint32), np.ones(1, np.uint32),
                             np.zeros(0, np.int64), 10.0)
        status, _, _ = stepper._flight(pos, vel, quat, omega, stepped, *fixed, np.full(1, 2, np.int8), np.zeros((0, 3)),
                                       np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64), 0.0,
                                       np.empty(1, np.int64))
    assert status == stepper.DECLINED
    for a, b in zip(state, (pos, vel, quat, omega, stepped)):
        assert np.array_equal(a, b)
