"""Tunnelling: a 1 cm sphere at 100 m/s toward a 1 cm wall, dt 1/60."""
import os
import warnings

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import stepper
from contact_sim.response import TunnellingWarning

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")
WALL_FRONT = 0.5 - 0.005


def _run(toi):
    world = cs.load_scene(os.path.join(SCENES, "tunnelling.yaml"))
    world.settings.toi = toi
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        xs = []
        for _ in range(6):
            world.step()
            xs.append(world.body("bullet").position[0])
    return world, np.array(xs), caught


@pytest.mark.parametrize("toi", ["swept", "fractional"])
def test_stopped_with_swept_or_fractional(toi):
    world, xs, caught = _run(toi)
    assert xs.max() <= WALL_FRONT - 0.005 + 1e-9      # never got past the wall's front face
    assert world.body("bullet").velocity[0] < 0        # bounced back
    assert abs(world.body("bullet").velocity[0] + 0.5 * 100.0) < 1.0   # restitution 0.5
    assert not [w for w in caught if issubclass(w.category, TunnellingWarning)]


def test_passes_with_next_step_and_preflight_warned():
    world, xs, caught = _run("next_step")
    assert xs[-1] > 0.5 + 0.005                        # went straight through
    tw = [w for w in caught if issubclass(w.category, TunnellingWarning)]
    assert tw and "bullet" in str(tw[0].message)
    assert any("bullet" in line and "pass through" in line for line in stepper.describe_models(world))


def test_auto_picks_swept():
    world = cs.load_scene(os.path.join(SCENES, "tunnelling.yaml"))
    world.settings.toi = "auto"
    lines = stepper.describe_models(world)
    assert any(line.startswith("time of impact swept") for line in lines), lines


def test_cached_model_choice_follows_settings_bodies_and_speed():
    from contact_sim.response import models

    world = cs.World()
    world.add_body("ground", cs.Plane((0, 0, 1), 0.0), kind="static")
    world.add_body("ball", cs.Sphere(0.1), mass=1.0, position=(0, 0, 1))
    m1 = models.choose(world, 0.01)
    assert models.choose(world, 0.01) is m1                 # nothing changed: cached
    assert m1.toi == "fractional"
    world.settings.toi = "next_step"                        # a setting edited in place
    assert models.choose(world, 0.01).toi == "next_step"
    world.settings.toi = "auto"
    for i in range(5):                                      # more dynamic bodies: next_step
        world.add_body(f"b{i}", cs.Sphere(0.1), mass=1.0, position=(i, 0, 1))
    assert models.choose(world, 0.01).toi == "next_step"
    world.s.vel[1] = (0.0, 0.0, -100.0)                     # thin and fast this step: its own search
    fast = models.choose(world, 0.01)                       # (5 dynamic bodies: next_step for the rest)
    assert fast.toi == "next_step" and fast.continuous == (1,)
    world.s.vel[1] = 0.0                                    # and back
    assert models.choose(world, 0.01).toi == "next_step"
    world.settings.friction = False
    assert models.choose(world, 0.01).friction is False
