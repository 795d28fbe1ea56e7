"""The swept-volume time of impact as its own mechanism (issue 14, part 1): the feature it emits,
its conservative time, and its cost beside fractional's root search (distance evaluations)."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat  # noqa: F401 (cs.quat)
from contact_sim.response import TunnellingWarning, swept, toi

pytestmark = pytest.mark.exact


_A = np.arange(6) * np.pi / 3
HEX_PRISM = np.array([[0.02 * np.cos(a), 0.02 * np.sin(a), z] for z in (-0.015, 0.015) for a in _A])


def plate_world(mode, shape, v=-60.0, g=-9.81):
    """A body falling fast onto a 1 cm static plate (a box, so no closed form applies): next_step
    steps straight through it in one step of 1/60 s."""
    w = cs.World(gravity=(0, 0, g), settings={"toi": mode, "dt": 1 / 60},
                 materials={"m": {"restitution": 0.5, "friction": 0.0}})
    w.add_body("plate", cs.Box([2.0, 2.0, 0.01]), kind="static", material="m")
    w.add_body("bullet", shape, mass=1.0, position=[0.1, -0.05, 0.6], velocity=[0, 0, v], material="m")
    return w


def run(mode, shape, steps=6, **kw):
    w = plate_world(mode, shape, **kw)
    evals0 = toi.COUNTS["distance_evaluations"]
    sweeps0 = swept.COUNTS["sweeps"]
    features = []
    zs = []
    for _ in range(steps):
        w.step()
        zs.append(w.body("bullet").position[2])
        features.extend(cs.FEATURES[f] for f in w.contacts.feature)
    return w, np.array(zs), toi.COUNTS["distance_evaluations"] - evals0, swept.COUNTS["sweeps"] - sweeps0, features


@pytest.mark.parametrize("shape", [cs.Sphere(0.02), cs.Box([0.04, 0.04, 0.04]),
                                   cs.Convex(HEX_PRISM)],
                         ids=["sphere", "box", "convex"])
def test_sweep_catches_what_next_step_misses_without_distance_evaluations(shape):
    with pytest.warns(TunnellingWarning):            # the preflight says so
        _, zs, _, _, _ = run("next_step", shape)
    assert zs.min() < -0.1                       # next_step: straight through the plate
    w, zs, evals, sweeps, features = run("swept", shape)
    assert zs.min() > 0.005 - 1e-6                # swept: stopped on the plate's top face (z = 0.005)
    assert w.body("bullet").velocity[2] > 0       # and bounced
    assert "swept" in features                   # the sweep's contacts say so
    assert sweeps >= 1 and evals == 0            # closed-form roots along separating directions only
    wf, zf, evals_f, sweeps_f, features_f = run("fractional", shape)
    assert zf.min() > 0.005 - 1e-6 and sweeps_f == 0 and "swept" not in features_f
    assert evals_f > evals                       # fractional: the root search evaluates distances
    # the same impact: the bodies leave the plate with the same velocity
    assert np.allclose(w.body("bullet").velocity, wf.body("bullet").velocity, rtol=0, atol=1e-9)


def test_swept_time_is_exact_on_a_face_and_never_late():
    # a box falling flat onto the plate under gravity: the gap along the plate's normal is the
    # quadratic h0 + v t + g t²/2 = 0, its root is the sweep's answer exactly
    w = plate_world("swept", cs.Box([0.04, 0.04, 0.04]), v=-40.0)
    m = toi.Motion(w, np.where((w.kind == 2)[:, None], w.gravity, 0.0), w.kind == 2)
    T = 1 / 60
    t = swept.swept_toi(w, m, 1, 0, T)
    h0, v, g = 0.6 - 0.02 - 0.005, -40.0, -9.81
    exact = (-v - np.sqrt(v * v - 2 * g * h0)) / g
    assert abs(t - exact) <= 1e-15 * 10
    # tilted 30° about x and moving sideways: a corner leads; the sweep is never later than the
    # true time (found by fractional's root search)
    w = plate_world("swept", cs.Box([0.04, 0.04, 0.04]), v=-40.0)
    w.set_state("bullet", orientation=[np.sin(np.pi / 12), 0, 0, np.cos(np.pi / 12)], velocity=[3.0, 1.0, -40.0])
    m = toi.Motion(w, np.where((w.kind == 2)[:, None], w.gravity, 0.0), w.kind == 2)
    ts = swept.swept_toi(w, m, 1, 0, T)
    tf = toi.pair_toi(w, m, 1, 0, T)      # conservative advancement: up to its tolerance early
    lowest = float((w.shapes[1].vertices @ cs.quat.to_matrix(w.s.quat[1]).T)[:, 2].min())
    h0 = 0.6 + lowest - 0.005
    exact = (-v - np.sqrt(v * v - 2 * g * h0)) / g      # the leading corner's own quadratic
    assert abs(ts - exact) <= 1e-14 and ts <= exact + 1e-15
    tol_time = toi.TOI_TOLERANCE * 0.02 / 40.0
    assert exact - tol_time * 2 <= tf <= exact + 1e-15


def test_sweep_misses_what_a_separating_plane_clears():
    # the body passes beside the plate: a side plane of the plate separates the whole sweep
    w = plate_world("swept", cs.Box([0.04, 0.04, 0.04]))
    w.set_state("bullet", position=[1.5, 0, 0.6])
    m = toi.Motion(w, np.where((w.kind == 2)[:, None], w.gravity, 0.0), w.kind == 2)
    assert swept.swept_toi(w, m, 1, 0, 1 / 60) == np.inf


def test_rotation_is_outside_the_method():
    w = plate_world("swept", cs.Box([0.04, 0.04, 0.04]))
    w.set_state("bullet", angular_velocity=[0, 0, 5.0])
    m = toi.Motion(w, np.where((w.kind == 2)[:, None], w.gravity, 0.0), w.kind == 2)
    assert np.isnan(swept.swept_toi(w, m, 1, 0, 1 / 60))     # the caller uses the root search
    # and the step still stops the spinning body on the plate (the fallback is fractional's search)
    for _ in range(6):
        w.step()
    assert w.body("bullet").position[2] > 0.0


def test_both_moving_relative_sweep():
    # two boxes flying at each other, 1 m apart, 50 m/s each: they meet within the first step
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "swept", "dt": 1 / 60})
    w.add_body("a", cs.Box([0.02] * 3), mass=1.0, position=[-0.5, 0, 0], velocity=[50.0, 0, 0])
    w.add_body("b", cs.Box([0.02] * 3), mass=1.0, position=[0.5, 0, 0], velocity=[-50.0, 0, 0])
    m = toi.Motion(w, np.zeros((2, 3)), w.kind == 2)
    t = swept.swept_toi(w, m, 0, 1, 1 / 60)
    assert abs(t - (1.0 - 0.02) / 100.0) <= 1e-15
    w.step()
    assert w.body("a").position[0] < w.body("b").position[0] and w.body("a").velocity[0] <= 0
