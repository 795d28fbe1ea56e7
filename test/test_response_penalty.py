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
