"""Smoke test of the response benchmark (``bench/bench_response.py --quick``): the engines are
built from one scene description, stepped in turns, measured, and the CSV and chart written.
It checks the instrument, not the speed (speed is never a test here)."""
import csv
import math
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_quick_run_writes_every_row_for_every_engine(tmp_path):
    for module in ("pybullet", "mujoco"):
        pytest.importorskip(module, reason=f"{module} is not installed: the benchmark compares with it "
                                           f"(pip install '.[bench]', or make bench installs it)")
    proc = subprocess.run([sys.executable, os.path.join(REPO, "bench", "bench_response.py"), "--quick",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    with open(tmp_path / "response_peers_quick.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert (tmp_path / "response_peers_quick.png").stat().st_size > 0
    got = {(r["scene"], r["engine"]) for r in rows}
    for scene in ("ball_1", "spheres_10", "pile_64", "stack_10", "resting_10", "resting_100"):
        for engine in ("contact_sim", "pybullet", "MuJoCo"):
            assert (scene, engine) in got
    assert {("rotation_rod", "contact_sim"), ("rotation_cube", "contact_sim")} <= got
    for r in rows:
        assert float(r["step_ms"]) > 0 and int(r["block"]) > 0, r   # every row timed in blocks
        if r["scene"] in ("ball_1", "stack_10", "pile_64"):
            assert float(r["wall_s_per_sim_s"]) > 0, r
        if r["engine"] != "contact_sim" or r["scene"] == "rotation_rod":
            assert float(r["ratio"]) > 0 and r["ratio_meaning"], r
        if not r["scene"].startswith("rotation"):
            assert math.isfinite(float(r["max_penetration_mm"])), r
        assert r["settings"], r
    cs_rest = [r for r in rows if r["scene"] == "resting_10" and r["engine"] == "contact_sim"][0]
    assert 0 < float(cs_rest["detect_ms"]) and "rest_ms" not in cs_rest   # detection run alone: no share of the step
    pile = [r for r in rows if r["scene"] == "pile_64"]
    assert all(r["escaped"] != "" for r in pile)
    assert "contact_sim ÷ pybullet" in proc.stdout and "rod ÷ cube" in proc.stdout
    targets = {(r["scene"], r["engine"]): float(r["target"]) for r in rows if r["target"]}
    assert targets == {("ball_1", "pybullet"): 3.0, ("spheres_10", "pybullet"): 2.0, ("resting_10", "pybullet"): 2.0,
                       ("resting_100", "pybullet"): 1.0, ("stack_10", "MuJoCo"): 2.0}   # pile_1000's: not in --quick
    assert all(r["apex_m"] for r in rows if r["scene"] == "ball_1")
    assert "useMaximalCoordinates=True" in next(r["settings"] for r in rows if r["engine"] == "pybullet")


def test_default_scene_benchmark_writes_every_phase(tmp_path):
    """``bench/bench_default.py``: a short run writes one row per phase with positive times."""
    proc = subprocess.run([sys.executable, os.path.join(REPO, "bench", "bench_default.py"), "--seconds", "3.5",
                           "--repeats", "1", "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    with open(tmp_path / "default_scene.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["phase"].split(" (")[0] for r in rows] == ["falling and hitting", "bouncing, sliding", "resting",
                                                         "whole run"]
    for r in rows:
        p50, p99, mx = float(r["p50_ms"]), float(r["p99_ms"]), float(r["max_ms"])
        assert float(r["wall_s_per_sim_s"]) > 0 and 0 < p50 <= p99 <= mx, r


def test_step_anatomy_splits_a_step_into_glue_boundary_and_kernels(tmp_path):
    """``bench/step_anatomy.py`` on the ball and the stack: every part non-negative, the three
    summing to the step's time, the compiled calls found and replayed (a stack step reaches the
    narrow phase and the resting solve: some kernel time), the glue's six largest parts named by
    engine function, the CSV written."""
    proc = subprocess.run([sys.executable, os.path.join(REPO, "bench", "step_anatomy.py"), "--scenes",
                           "ball_1,stack_10", "--steps", "30", "--out", str(tmp_path)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    with open(tmp_path / "step_anatomy.csv", newline="") as fh:
        rows = {r["scene"]: r for r in csv.DictReader(fh)}
    assert set(rows) == {"ball_1", "stack_10"}
    for r in rows.values():
        parts = [float(r[k]) for k in ("glue_us", "boundary_us", "kernels_us")]
        assert min(parts) >= 0 and float(r["calls_per_step"]) >= 1, r
        assert sum(parts) == pytest.approx(float(r["step_us"]), rel=1e-9) or float(r["kernels_us"]) == 0, r
    assert float(rows["stack_10"]["kernels_us"]) > 0
    parts = rows["stack_10"]["glue_by_function"].split("; ")
    assert len(parts) == 6 and all(p.split(" ")[0].count(".") >= 1 and float(p.split(" ")[1]) >= 0 for p in parts)
