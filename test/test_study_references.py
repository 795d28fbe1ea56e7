"""The accuracy studies' exact answers (``record: [{reference: ...}]``): for each scene of
``bench/bench_accuracy.py``, a run at a fine step reaches the error the benchmark reports, the
recorder's ``error`` equals the same measure computed here, independently, from the stepped state
(formulas written out below, not taken from ``contact_sim.study.references``), a study file naming
a reference badly is refused with the place and the reason, and the shipped ``accuracy_<scene>``
studies hold the benchmark's grid of models and step sizes."""
import copy
import csv
import math
import os
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import yaml

import contact_sim as cs
from contact_sim import quat
from contact_sim.study import load_study, run_one

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
G = 9.81
DTS = [1 / 30, 1 / 60, 1 / 120, 1 / 240, 1 / 500, 1 / 1000, 1 / 2000]
SCENES = ("bouncing_ball", "two_spheres", "rod_impact", "sliding_block", "incline", "penalty_rest")


def scene_dict(name):
    with open(cs.resolve_scene(name)) as fh:
        return yaml.safe_load(fh)


def study(scene, reference, duration, **settings):
    """A one-run study of ``scene`` (a shipped scene's name or a mapping) with ``settings`` set,
    recording ``reference`` (the options of ``{reference: ...}``)."""
    flat = {}
    for k, v in settings.items():
        flat.update({f"settings.{k}.{kk}": vv for kk, vv in v.items()} if isinstance(v, dict) else {f"settings.{k}": v})
    return {"scene": scene, "duration": duration, "set": flat, "record": [{"reference": reference}]}


def stepped(scene, steps, each=None, **settings):
    """The world of ``scene`` (a dict) with ``settings`` merged, stepped ``steps`` times at its
    ``dt``, calling ``each(world)`` after every step (what the recorder sees, computed here)."""
    d = copy.deepcopy(scene)
    d["settings"] = {**(d.get("settings") or {}), **settings}
    w = cs.load_scene(d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # next-step detection's tunnelling preflight warns; expected here
        for _ in range(steps):
            w.step()
            if each is not None:
                each(w)
    return w


def cell(s, *labels):
    """The grid cell of study ``s`` whose axes' values (labels) are ``labels``."""
    hits = [k for k in range(s.cells) if [p[1] for p in s.cell_params(k)] == list(labels)]
    assert len(hits) == 1, labels
    return hits[0]


def shipped_error(scene, model, dt):
    s = load_study(f"accuracy_{scene}")
    row = run_one(s, cell(s, model, dt), 0)
    assert row["exception"] == "", row["exception"]
    return row["error"]


# ---------------------------------------------------------------------------- two spheres head-on
def head_on_positions(t, x1, x2, v1, v2, m1, m2, r1, r2, e):
    """Centres of two spheres on a line, one collision: momentum kept, separation speed e × approach."""
    tc = (x2 - x1 - r1 - r2) / (v1 - v2)
    p = m1 * v1 + m2 * v2
    u1, u2 = (p - m2 * e * (v1 - v2)) / (m1 + m2), (p + m1 * e * (v1 - v2)) / (m1 + m2)
    assert m1 * u1 + m2 * u2 == pytest.approx(p, rel=1e-14) and u2 - u1 == pytest.approx(e * (v1 - v2), rel=1e-14)
    t = np.asarray(t)
    return (np.where(t <= tc, x1 + v1 * t, x1 + v1 * tc + u1 * (t - tc)),
            np.where(t <= tc, x2 + v2 * t, x2 + v2 * tc + u2 * (t - tc)))


def test_two_spheres_error_is_the_position_error_over_the_run():
    """e 0.6, a 3 kg right sphere 1.03 m from the left (collision at 0.415 s, between steps),
    next-step detection at 1/30 s: the collision is found late, so the error is large, and the
    recorder's must equal the one computed here."""
    d = scene_dict("two_spheres")
    d["materials"]["elastic"]["restitution"] = 0.6
    d["bodies"][1]["mass"] = 3.0
    d["bodies"][1]["position"] = [0.53, 0, 0]
    settings = {"dt": 1 / 30, "response": "impulse", "toi": "next_step"}
    row = run_one(load_study(study(d, {"type": "two_spheres", "bodies": ["left", "right"]}, 1.0, **settings)), 0, 0)
    ts, a, b = [], [], []
    w = stepped(d, 30, lambda w: (ts.append(w.time), a.append(w.body("left").position.copy()),
                                  b.append(w.body("right").position.copy())), **settings)
    a, b = np.array(a), np.array(b)
    assert np.all(a[:, 1:] == 0) and np.all(b[:, 1:] == 0)      # on the x axis throughout
    x1, x2 = head_on_positions(ts, -0.5, 0.53, 1.5, -0.5, 1.0, 3.0, 0.1, 0.1, 0.6)
    expect = max(np.abs(a[:, 0] - x1).max(), np.abs(b[:, 0] - x2).max()) / 1.03
    assert w.time == pytest.approx(1.0, abs=1e-12) and expect > 1e-3
    assert row["exception"] == "" and row["error"] == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("model", ["impulse + fractional", "impulse + swept", "kinematic + fractional"])
def test_two_spheres_at_a_fine_step_is_exact(model):
    """Exact times of impact: the positions are the closed form's to rounding (bench: < 2e-13)."""
    assert shipped_error("two_spheres", model, 1 / 2000) < 1e-12


# ---------------------------------------------------------------------------- rod impact
def rod_after_impact(d):
    """Exact impact time, and linear velocity and spin angular momentum just after it, of the
    shipped rod (no spin, falling onto z = 0 at its lowest corner): impulse j n with
    j = −(1+e) v_n / (1/m + n·((I⁻¹(r×n))×r)), I⁻¹ of the box in the world frame."""
    rod = d["bodies"][1]
    q = np.array(rod["orientation"], float)
    q /= np.linalg.norm(q)
    R = quat.to_matrix(q[None])[0]
    a, b, c = rod["shape"]["size"]
    m, e = rod["mass"], d["materials"]["steel"]["restitution"]
    inertia = m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    corners = np.array([[x * a, y * b, z * c] for x in (-.5, .5) for y in (-.5, .5) for z in (-.5, .5)]) @ R.T
    r = corners[np.argmin(corners[:, 2])]
    z0 = rod["position"][2] + r[2]
    v = np.array(rod["velocity"], float)
    tc = (v[2] + math.sqrt(v[2] ** 2 + 2 * G * z0)) / G      # z0 + vz t − g t²/2 = 0
    v_minus = v - np.array([0, 0, G * tc])
    n = np.array([0.0, 0.0, 1.0])
    inv_i = R @ np.linalg.inv(inertia) @ R.T
    j = -(1 + e) * (v_minus @ n) / (1 / m + n @ np.cross(inv_i @ np.cross(r, n), r))
    return tc, v_minus + j * n / m, np.cross(r, j * n)


def test_rod_impact_error_is_the_momentum_error_30_ms_after_the_impact():
    """Next-step detection at 1/30 s (far off): the recorder takes the state of the first step at
    or after t_c + 30 ms — here the second and last — gravity since the impact removed."""
    d = scene_dict("rod_impact")
    tc, v_plus, l_plus = rod_after_impact(d)
    steps = math.ceil((tc + 0.03) * 30)
    assert steps == 2
    settings = {"dt": 1 / 30, "response": "impulse", "toi": "next_step"}
    row = run_one(load_study(study("rod_impact", {"type": "rod_impact", "body": "rod"}, 2 / 30, **settings)), 0, 0)
    w = stepped(d, steps, **settings)
    rod = w.body("rod")
    v = rod.velocity - np.array([0, 0, -G]) * (w.time - tc)
    spin = w.angular_momentum() - np.cross(rod.position, rod.mass * rod.velocity)
    expect = max(np.linalg.norm(v - v_plus) / np.linalg.norm(v_plus),
                 np.linalg.norm(spin - l_plus) / np.linalg.norm(l_plus))
    assert expect > 0.1
    assert row["exception"] == "" and row["error"] == pytest.approx(expect, rel=1e-9)


def test_rod_impact_run_ending_before_the_measure_is_an_error_not_a_figure():
    row = run_one(load_study(study("rod_impact", {"type": "rod_impact", "body": "rod"}, 1 / 60, dt=1 / 60)), 0, 0)
    assert "ended at t = 0.0167 s, before the impact + 0.03 s" in row["exception"] and row["error"] is None


@pytest.mark.parametrize("model, dt, bound", [("impulse + swept", 1 / 2000, 1e-12),
                                              ("impulse + fractional", 1 / 60, 1e-9)])
def test_rod_impact_at_exact_times_of_impact_is_the_lecture_formula(model, dt, bound):
    """Bench: swept 1e-14, fractional 3e-10 (its contact point's time found by a root search)."""
    assert shipped_error("rod_impact", model, dt) < bound


# ---------------------------------------------------------------------------- sliding block
def test_sliding_block_error_is_the_stop_distance_error():
    settings = {"dt": 1 / 30, "solver_iterations": 4}
    row = run_one(load_study(study("sliding_block", {"type": "sliding_block", "body": "block"}, 1.0, **settings)), 0, 0)
    w = stepped(scene_dict("sliding_block"), 30, **settings)
    expect_distance = 2.0 ** 2 / (2 * 0.5 * G)
    expect = abs((w.body("block").position[0] - 0.0) - expect_distance) / expect_distance
    assert expect > 1e-4
    assert row["exception"] == "" and row["error"] == pytest.approx(expect, rel=1e-12)


def test_sliding_block_run_ending_before_the_block_stops_is_an_error():
    row = run_one(load_study(study("sliding_block", {"type": "sliding_block", "body": "block"}, 0.3)), 0, 0)
    assert "ended at t = 0.3 s, before the block stops (v0/(μ g) = 0.408 s)" in row["exception"]


def test_sliding_block_at_a_fine_step_is_within_1e_6():
    assert shipped_error("sliding_block", "impulse, 20 iterations", 1 / 2000) < 1e-6


# ---------------------------------------------------------------------------- incline
THETA = np.radians(35.0)


def test_incline_study_scene_is_a_35_degree_slope_with_the_block_on_it():
    s = load_study("accuracy_incline")
    slope, block = s.scene["bodies"]
    assert np.allclose(slope["shape"]["normal"], [np.sin(THETA), 0, np.cos(THETA)], atol=1e-15)
    assert np.allclose(block["position"], 0.1 * np.array([np.sin(THETA), 0, np.cos(THETA)]), atol=1e-15)
    assert np.allclose(block["orientation"], [0, np.sin(THETA / 2), 0, np.cos(THETA / 2)], atol=1e-15)
    assert s.scene["materials"]["wood"] == {"restitution": 0.0, "friction": 0.5}


def test_incline_error_is_the_acceleration_error():
    s = load_study("accuracy_incline")
    settings = {"dt": 1 / 30, "response": "penalty", "toi": "next_step", "friction": True,
                "penalty": {"stiffness": 5e4, "damping": 2 * 0.7 * math.sqrt(5e4)}}
    row = run_one(load_study(study(copy.deepcopy(s.scene), {"type": "incline", "body": "block"}, 0.5, **settings)),
                  0, 0)
    w = stepped(s.scene, 15, **settings)
    down = np.array([np.cos(THETA), 0, -np.sin(THETA)])
    a = 2 * (w.body("block").position - 0.1 * np.array([np.sin(THETA), 0, np.cos(THETA)])) @ down / w.time ** 2
    expect_a = G * (np.sin(THETA) - 0.5 * np.cos(THETA))
    expect = abs(a - expect_a) / expect_a
    assert expect > 1e-3
    assert row["exception"] == "" and row["error"] == pytest.approx(expect, rel=1e-9)


def test_incline_where_the_block_sticks_is_refused_at_the_run():
    """The shipped incline scene (20°, μ 0.5) holds the block: its acceleration is 0 and a
    relative error of it is undefined — the run says so rather than recording inf."""
    row = run_one(load_study(study("incline", {"type": "incline", "body": "block"}, 0.1)), 0, 0)
    assert "the block sticks (tan θ = 0.364 <= μ = 0.5)" in row["exception"]


@pytest.mark.parametrize("dt", [1 / 30, 1 / 2000])
def test_incline_sliding_at_any_step_is_within_1e_6(dt):
    """Bench: 20 iterations, 8e-10 at 1/30 s, 5e-12 at 1/2000 s."""
    assert shipped_error("incline", "impulse, 20 iterations", dt) < 1e-6


# ---------------------------------------------------------------------------- penalty rest
def test_penalty_rest_error_is_the_depth_error():
    """0.05 s: the spring (ζ 0.25, 16 Hz) still rings, so the depth is off mg/k by a measurable amount."""
    row = run_one(load_study(study("penalty_rest", {"type": "penalty_rest", "body": "ball"}, 0.05, dt=1 / 240)), 0, 0)
    w = stepped(scene_dict("penalty_rest"), 12, dt=1 / 240)
    expect_depth = 1.0 * G / 1e4
    expect = abs((0.1 - w.body("ball").position[2]) - expect_depth) / expect_depth
    assert expect > 1e-4
    assert row["exception"] == "" and row["error"] == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("model, dt", [("penalty k 1e+06", 1 / 30), ("penalty k 10000", 1 / 2000)])
def test_penalty_rest_settles_at_mg_over_k(model, dt):
    """Bench: 1e-13 and 1e-14 after 2 s (the damped spring settled)."""
    assert shipped_error("penalty_rest", model, dt) < 1e-9


# ---------------------------------------------------------------------------- bouncing ball
def test_bouncing_ball_at_a_fine_step_is_exact():
    assert shipped_error("bouncing_ball", "impulse + swept", 1 / 2000) < 1e-12


# ---------------------------------------------------------------------------- the study file
BALL_SCENE = {
    "gravity": [0, 0, -9.81],
    "materials": {"m": {"restitution": 0.5, "friction": 0.5}},
    "bodies": [
        {"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
        {"name": "ball", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0, "position": [0, 0, 0.5],
         "material": "m"},
        {"name": "cube", "shape": {"type": "box", "size": [0.2, 0.2, 0.2]}, "mass": 1.0, "position": [1, 0, 0.1],
         "material": "m"},
    ],
}
FLOATING = {"gravity": [0, 0, 0], "materials": BALL_SCENE["materials"], "bodies": BALL_SCENE["bodies"][1:]}


@pytest.mark.parametrize("scene, ref, message", [
    (BALL_SCENE, {"type": "bouncing_cube", "body": "ball"},
     "study.record[0].type: unknown exact answer 'bouncing_cube' (known: bouncing_ball, two_spheres, rod_impact, "
     "sliding_block, incline, penalty_rest)"),
    (BALL_SCENE, "nothing", "study.record[0].type: unknown exact answer 'nothing'"),
    (BALL_SCENE, ["sliding_block"], "study.record[0]: reference takes {type: NAME, ...} or NAME"),
    (BALL_SCENE, {"type": "sliding_block"}, "study.record[0].body: required: the sliding block (a dynamic box)"),
    (BALL_SCENE, {"type": "rod_impact"}, "study.record[0].body: required: the rod (a dynamic box)"),
    (BALL_SCENE, {"type": "incline"}, "study.record[0].body: required: the block (a dynamic box)"),
    (BALL_SCENE, {"type": "penalty_rest"}, "study.record[0].body: required: the ball (a dynamic sphere)"),
    (BALL_SCENE, {"type": "two_spheres"}, "study.record[0].bodies: required: the two spheres (dynamic spheres)"),
    (BALL_SCENE, {"type": "sliding_block", "body": "crate"},
     "study.record[0].body: no body 'crate' in the scene (ground, ball, cube)"),
    (BALL_SCENE, {"type": "bouncing_ball", "body": "crate"}, "study.record[0].body: no body 'crate' in the scene"),
    (BALL_SCENE, {"type": "penalty_rest", "body": "cube"},
     "study.record[0].body: 'cube' is a box; a penalty_rest reference measures a dynamic sphere"),
    (BALL_SCENE, {"type": "sliding_block", "body": "ground"},
     "study.record[0].body: 'ground' is static; a sliding_block reference measures a dynamic box"),
    (BALL_SCENE, {"type": "sliding_block", "body": "cube", "mu": 0.5},
     "study.record[0].mu: unknown key of a sliding_block reference (known: body)"),
    (BALL_SCENE, {"type": "rod_impact", "body": "cube", "after": 0},
     "study.record[0].after: must be > 0 (seconds after the exact impact), got 0"),
    (BALL_SCENE, {"type": "two_spheres", "bodies": ["ball", "ball"]},
     "study.record[0].bodies: must name two different dynamic spheres of the scene, got ['ball', 'ball']"),
    (BALL_SCENE, {"type": "two_spheres", "bodies": ["ball", "cube"]},
     "study.record[0].bodies: 'cube' is a box; a two_spheres reference measures a dynamic sphere"),
    (FLOATING, {"type": "sliding_block", "body": "cube"},
     "study.record[0]: a sliding_block reference needs a static plane in the scene (the ground)"),
])
def test_bad_references_are_refused_with_the_place_and_the_reason(scene, ref, message):
    with pytest.raises(cs.StudyError) as exc:
        load_study({"scene": copy.deepcopy(scene), "record": [{"reference": ref}]})
    assert message in str(exc.value)


def test_two_spheres_needs_no_gravity_and_one_reference_per_study():
    scene = copy.deepcopy(FLOATING)
    scene["bodies"].append({"name": "other", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0,
                            "position": [2, 0, 0]})
    ok = load_study({"scene": scene, "record": [{"reference": {"type": "two_spheres", "bodies": ["ball", "other"]}}]})
    assert ok.records == [("reference", {"type": "two_spheres", "bodies": ["ball", "other"]})]
    scene["gravity"] = [0, 0, -9.81]
    with pytest.raises(cs.StudyError, match=r"study.record\[0\]: a two_spheres reference needs gravity 0"):
        load_study({"scene": scene, "record": [{"reference": {"type": "two_spheres", "bodies": ["ball", "other"]}}]})
    with pytest.raises(cs.StudyError, match=r"study.record\[1\]: one reference per study \(its figure is error\)"):
        load_study({"scene": copy.deepcopy(BALL_SCENE), "record": [{"reference": "bouncing_ball"},
                                                                  {"reference": "bouncing_ball"}]})


def test_the_bouncing_ball_keeps_its_default_body_and_the_rod_its_default_delay():
    s = load_study({"scene": copy.deepcopy(BALL_SCENE), "record": [{"reference": "bouncing_ball"}]})
    assert s.records == [("reference", {"type": "bouncing_ball", "body": "ball"})]
    s = load_study({"scene": copy.deepcopy(BALL_SCENE), "record": [{"reference": {"type": "rod_impact", "body": "cube"}}]})
    assert s.records == [("reference", {"type": "rod_impact", "body": "cube", "after": 0.03})]


# ---------------------------------------------------------------------------- the shipped studies
def damping_for_restitution(e, k, m):
    """c = 2 ζ √(k m) of a linear spring–damper whose bounce has restitution e = exp(−ζπ/√(1−ζ²))."""
    a = -math.log(e) / math.pi
    zeta = a / math.sqrt(1 + a * a)
    return 2 * zeta * math.sqrt(k * m)


IMPULSE_TOI = {f"impulse + {t}": {"response": "impulse", "toi": t} for t in ("fractional", "swept", "next_step")}
KINEMATIC_TOI = {f"kinematic + {t}": {"response": "kinematic", "toi": t} for t in ("fractional", "next_step")}
SOLVERS = {**{f"impulse, {n} iterations": {"response": "impulse", "toi": "next_step", "solver_iterations": n}
              for n in (4, 20)},
           "penalty + friction (k 5e4)": {"response": "penalty", "toi": "next_step", "friction": True,
                                          "penalty": {"stiffness": 5e4, "damping": 2 * 0.7 * math.sqrt(5e4)}}}
MODELS = {   # bench_accuracy's models before it read them from the studies
    "bouncing_ball": {**IMPULSE_TOI, **KINEMATIC_TOI, "penalty (k 1e5, ζ for e 0.8)": {
        "response": "penalty", "toi": "next_step", "penalty": {"stiffness": 1e5,
                                                               "damping": damping_for_restitution(0.8, 1e5, 1.0)}}},
    "two_spheres": {**IMPULSE_TOI, **KINEMATIC_TOI},
    "rod_impact": IMPULSE_TOI,
    "sliding_block": SOLVERS,
    "incline": SOLVERS,
    "penalty_rest": {f"penalty k {k:g}": {"response": "penalty", "penalty": {"stiffness": k,
                                                                              "damping": 2 * 0.25 * math.sqrt(k)}}
                     for k in (1e4, 1e6)},
}
REFERENCE = {"bouncing_ball": {"type": "bouncing_ball", "body": "ball"},
             "two_spheres": {"type": "two_spheres", "bodies": ["left", "right"]},
             "rod_impact": {"type": "rod_impact", "body": "rod", "after": 0.03},
             "sliding_block": {"type": "sliding_block", "body": "block"},
             "incline": {"type": "incline", "body": "block"},
             "penalty_rest": {"type": "penalty_rest", "body": "ball"}}
DURATION = {"bouncing_ball": 3.0, "two_spheres": 1.0, "sliding_block": 1.0, "incline": 1.0, "penalty_rest": 2.0}


@pytest.mark.parametrize("scene", SCENES)
def test_shipped_accuracy_studies_hold_the_benchmarks_grid(scene):
    s = load_study(f"accuracy_{scene}")
    (model_axis, labels, values), (dt_axis, _, dts) = s.axes
    assert (model_axis, dt_axis) == ("settings", "settings.dt")
    assert dict(zip(labels, values)) == MODELS[scene] and dts == DTS
    assert ("reference", REFERENCE[scene]) in s.records
    if scene == "rod_impact":     # every step size reaches t_c + 30 ms (≈ 0.047 s) before the far end lands (0.136 s)
        assert 2 / 30 <= s.duration < 0.13
    else:
        assert s.duration == DURATION[scene]
    assert s.plot == {"type": "work_precision", "series": "settings", "points": "settings.dt", "x": "cost",
                      "y": "error"}


def test_cost_is_stepping_time_per_simulated_second():
    s = load_study(study("sliding_block", {"type": "sliding_block", "body": "block"}, 1.0, dt=1 / 120))
    row = run_one(s, 0, 0)
    assert 0 < row["cost"] * 1.0 < row["wall_time"]


# ---------------------------------------------------------------------------- the benchmark
@pytest.mark.slow
def test_bench_accuracy_quick_writes_every_scene_from_the_studies(tmp_path):
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, os.path.join(REPO, "bench", "bench_accuracy.py"), "--quick",
                          "--no-pybullet", "--out", str(tmp_path)], cwd=REPO, capture_output=True, text=True,
                         timeout=300, env={**os.environ, "PYTHONPATH": REPO})
    assert out.returncode == 0, out.stderr[-2000:]
    with open(tmp_path / "accuracy.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["scene", "method", "dt", "error", "cost"]
    quick = [1 / 30, 1 / 120, 1 / 500]
    for scene in SCENES:
        mine = [r for r in rows if r["scene"] == scene]
        assert sorted((r["method"], float(r["dt"])) for r in mine) == sorted(
            (m, dt) for m in MODELS[scene] for dt in quick)
        assert all(float(r["cost"]) > 0 and math.isfinite(float(r["error"])) for r in mine)
        assert (tmp_path / f"accuracy_{scene}.png").read_bytes()[:4] == b"\x89PNG"
    best = {s: min(float(r["error"]) for r in rows if r["scene"] == s) for s in SCENES}
    assert best["bouncing_ball"] < 1e-12 and best["two_spheres"] < 1e-12 and best["rod_impact"] < 1e-12
    assert best["incline"] < 1e-6 and best["penalty_rest"] < 1e-9 and best["sliding_block"] < 1e-4
    summary = (tmp_path / "accuracy_summary.md").read_text()
    assert summary.startswith("| scene | error measured | cheapest within 1e-3 | cheapest within 1e-6 |")
    assert all(f"| {s} |" in summary for s in SCENES)
    print(f"bench_accuracy --quick: {time.perf_counter() - t0:.1f} s")
