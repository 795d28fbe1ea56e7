"""Determinism across processes (issue 12): the same scene and inputs give bit-identical states in
two separate interpreter processes (compiled kernels loaded from the cache or compiled afresh, the
broad phase's hashing, the contact order, the Gauss–Seidel sweep order), not only within one run."""
import hashlib
import os
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SCRIPT = r"""
import hashlib, warnings
import numpy as np
import contact_sim as cs
warnings.simplefilter("ignore")
rng = np.random.default_rng(7)
w = cs.World(materials={"m": cs.Material(restitution=0.2, friction=0.6)})
w.add_body("ground", cs.Plane(), kind="static", material="m")
for name, n in (("x0", [1, 0, 0]), ("x1", [-1, 0, 0]), ("y0", [0, 1, 0]), ("y1", [0, -1, 0])):
    w.add_body(name, cs.Plane(n, -0.5), kind="static", material="m")
for i in range(90):   # enough contacts for the compiled Gauss-Seidel path (above 200)
    shape = [cs.Sphere(0.05), cs.Box([0.08, 0.1, 0.06]), cs.Convex(rng.normal(size=(10, 3)) * 0.04)][i % 3]
    q = rng.normal(size=4)
    w.add_body(f"b{i}", shape, mass=float(rng.uniform(0.1, 1.0)), material="m",
               position=[rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(0.05, 0.6)],
               orientation=(q / np.linalg.norm(q)).tolist(), angular_velocity=rng.normal(size=3).tolist())
for _ in range(90):
    w.step()
s = w.s
h = hashlib.sha256()
for a in (s.pos, s.vel, s.quat, s.omega, w.contacts.normal_impulse):
    h.update(np.ascontiguousarray(a).tobytes())
print(h.hexdigest(), len(w.contacts), w.last_solve["contacts"])
"""


def _run():
    env = {k: v for k, v in os.environ.items() if k != "PYTHONHASHSEED"}   # string hashing differs per process
    proc = subprocess.run([sys.executable, "-c", SCRIPT], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout.split()


def test_two_processes_give_bit_identical_states():
    first, second = _run(), _run()
    assert int(first[1]) > 0                       # the bodies touch: the solver ran
    assert first == second
    assert len(first[0]) == len(hashlib.sha256().hexdigest())
