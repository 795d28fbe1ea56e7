"""The command line: run a scene, per-second summary, trajectory and plot files, clear errors."""
import subprocess
import sys

import numpy as np
import pytest

from contact_sim.cli import main

FREE_FALL = """
gravity: [0, 0, -9.81]
settings: {dt: 0.01}
bodies:
  - {name: ball, shape: {type: sphere, radius: 0.1}, mass: 1.0, position: [0, 0, 100]}
  - {name: cube, shape: {type: box, size: [0.2, 0.2, 0.2]}, mass: 2.0, position: [1, 0, 100], velocity: [1, 0, 0]}
"""


@pytest.fixture
def free_fall(tmp_path):
    p = tmp_path / "fall.yaml"
    p.write_text(FREE_FALL)
    return str(p)


def test_run_prints_per_second_summary(free_fall, capsys):
    assert main(["run", free_fall, "--duration", "2", "--no-progress"]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line.strip() and line.split()[0] in ("1.000", "2.000")]
    assert len(rows) == 2
    t, bodies, contacts, pen, energy = rows[1]
    assert bodies == "2" and contacts == "0"
    e0 = 1 * 9.81 * 100 + 2 * 9.81 * 100 + 0.5 * 2 * 1
    assert float(energy) == pytest.approx(e0, rel=1e-9)  # free fall conserves energy exactly


def test_trajectory_csv_npz_and_plot(free_fall, tmp_path, capsys):
    csv, npz, png = tmp_path / "t.csv", tmp_path / "t.npz", tmp_path / "p.png"
    assert main(["run", free_fall, "--duration", "0.5", "--trajectory", str(csv), "--plot", str(png),
                 "--no-progress"]) == 0
    assert main(["run", free_fall, "--duration", "0.5", "--trajectory", str(npz), "--no-progress"]) == 0
    rows = np.genfromtxt(csv, delimiter=",", names=True, dtype=None, encoding=None)
    assert len(rows) == 2 * 51
    last = rows[-1]
    assert last["body"] == "cube"
    assert last["z"] == pytest.approx(100 - 0.5 * 9.81 * 0.25, abs=1e-9)
    assert last["x"] == pytest.approx(1.5, abs=1e-12)
    data = np.load(npz)
    assert data["position"].shape == (51, 2, 3) and list(data["body_names"]) == ["ball", "cube"]
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"


def test_errors_are_clear_and_exit_nonzero(tmp_path, capsys):
    assert main(["run", str(tmp_path / "missing.yaml"), "--no-progress"]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("bodies:\n  - {name: b, shape: {type: sphere, radius: -1}}\n")
    assert main(["run", str(bad), "--no-progress"]) == 2
    assert "bodies[0].shape.radius: must be > 0" in capsys.readouterr().err
    assert main(["run", str(bad), "--dt", "0"]) == 2


def test_scenes_and_describe(capsys):
    assert main(["scenes"]) == 0
    assert "default" in capsys.readouterr().out.split()
    assert main(["describe", "default"]) == 0
    assert "bodies" in capsys.readouterr().out


def test_python_dash_m_runs_default_scene(repo):
    out = subprocess.run([sys.executable, "-m", "contact_sim", "run", "--duration", "0.5", "--no-progress"],
                         capture_output=True, text=True, cwd=repo, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "scene config/scenes/default.yaml" in out.stdout or "default.yaml" in out.stdout
    assert "steps of" in out.stdout
