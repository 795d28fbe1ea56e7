"""The grasp benchmark's contact_sim scenario (``bench/bench_grasp.py``) meets its physics targets:
a 5 cm, 0.2 kg cube squeezed by kinematic fingers 0.5, 1 or 5 mm past its faces (a standing 5 cm
cylinder 1 mm) is lifted 10 cm and shaken ±5 cm at 2 Hz without dropping, slipping more than 1
mm, or ever moving faster than the fingers by more than 0.1 m/s. Only contact_sim runs here (the peers are the bench's business).
"""
import os
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "bench"))

import bench_grasp  # noqa: E402

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("shape, over_mm", [("cube", 0.5), ("cube", 1.0), ("cube", 5.0), ("cylinder", 1.0)])
def test_contact_sim_holds_the_part_through_lift_and_shake(shape, over_mm):
    r = bench_grasp.run_contact_sim(over_mm * 1e-3, shape)   # the defaults: kinematic_stiffness 1e5 N/m
    assert r["held"], r
    assert r["object_z_end_mm"] == pytest.approx(125.0, abs=1.0), r
    assert r["slip_mm"] <= 1.0, r
    assert r["faster_m_s"] <= 0.1, r
    # compliant contacts with the kinematic fingers: each pushes with about k × over
    assert r["grip_N"] == pytest.approx(1e5 * over_mm * 1e-3, rel=0.05), r


def test_a_quick_run_writes_its_table(tmp_path):
    """``main(["--quick"])`` with contact_sim alone writes one CSV row with every column and the chart."""
    import csv

    rows = bench_grasp.main(["--quick", "--engines", "contact_sim", "--out", str(tmp_path)])
    assert len(rows) == 1
    with open(tmp_path / "grasp_quick.csv", newline="") as fh:
        got = list(csv.DictReader(fh))
    assert len(got) == 1 and set(got[0]) == set(bench_grasp.FIELDS)
    assert got[0]["engine"] == "contact_sim" and got[0]["held"] == "True" and float(got[0]["step_ms"]) > 0
    assert (tmp_path / "grasp_quick.png").stat().st_size > 0
