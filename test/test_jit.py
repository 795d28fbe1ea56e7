"""The compiled-kernel shim: the engine imports and runs without numba, with a notice."""
import subprocess
import sys

import numpy as np

import contact_sim as cs
from contact_sim import jit

SNIPPET = """
import sys
sys.modules["numba"] = None          # numba absent: `import numba` raises ImportError
import contact_sim as cs
from contact_sim import jit
assert not jit.COMPILED
w = cs.load_scene(cs.default_scene_path())
for _ in range(20):
    w.step()
print(repr(w.s.pos.tolist()))
"""


def test_engine_runs_without_numba_and_says_so():
    out = subprocess.run([sys.executable, "-c", SNIPPET], capture_output=True, text=True, timeout=240)
    assert out.returncode == 0, out.stderr
    assert "numba is not installed" in out.stderr and "plain Python" in out.stderr
    w = cs.load_scene(cs.default_scene_path())
    for _ in range(20):
        w.step()
    # the same physics either way (kernels are the same Python source)
    np.testing.assert_allclose(np.array(eval(out.stdout)), w.s.pos, rtol=0, atol=1e-9)


def test_njit_is_numba_with_cache_or_the_identity():
    @jit.njit
    def add(a, b):
        return a + b

    @jit.njit(nogil=True)
    def mul(a, b):
        return a * b

    assert add(2, 3) == 5 and mul(2, 3) == 6
    if jit.COMPILED:
        assert add.__class__.__name__ == "CPUDispatcher" and add._cache.__class__.__name__ != "NullCache"


def test_a_deep_copied_world_steps_with_the_kernels_already_compiled():
    """Copying an array makes it writable, and a writable array is another type to numba: every
    kernel reading the world's gravity would compile a second version (~25 s at the first step of
    a copy). A copied or unpickled world has it read-only again, so its step reuses the compiled
    versions (where numba compiles, the signature count shows it)."""
    import copy
    import pickle

    from contact_sim.response import substep

    w = cs.World(settings=cs.Settings(toi="next_step"))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("box", cs.Box((0.4, 0.4, 0.2)), mass=1.0, position=(0, 0, 0.1))
    w.step(0.01)
    twin = copy.deepcopy(w)
    assert not twin.gravity.flags.writeable and not pickle.loads(pickle.dumps(w)).gravity.flags.writeable
    versions = len(getattr(substep._substep, "signatures", ()))
    twin.step(0.01)
    assert not twin.gravity.flags.writeable
    assert len(getattr(substep._substep, "signatures", ())) == versions
    assert np.array_equal(twin.s.pos, (w.step(0.01), w.s.pos)[1])
