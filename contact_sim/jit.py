"""Compiled kernels: ``njit`` is numba's ``@njit(cache=True)``, or the identity without numba.

The engine's hot loops (narrow-phase kernels, the contact solver, free motion, time-of-impact
searches) are plain Python functions over arrays, written as loops the way Box2D's C reads, and
decorated with ``@njit``. numba compiles them to machine code on first use and caches the result
beside the source (``__pycache__``), so later processes load them in milliseconds. Without numba
(or with ``NUMBA_DISABLE_JIT=1``, which CI uses to run the exact-answer tests through the Python
path) the same functions run as Python: correct, and slow; a one-line notice says so.

Rules for a kernel: arrays and scalars in, arrays out (preallocated by the caller where the size is
known); no Python objects, no dicts, no exceptions for control flow; ``float64`` and ``int64``
arrays; deterministic (no parallel reductions), so the same inputs give bit-identical results.

Reference counts: compiled code counts the references to every array it holds (an argument handed
on to another kernel, a view such as ``vecs[0]``, a tuple of arrays unpacked) with atomic
operations, ~10–20 ns each on this machine, which numba's pruning removes only from simple code.
A kernel that allocates nothing and returns no array is compiled without them,
``@njit(_nrt=False)`` (numba's option: its arrays are borrowed from the caller, which holds them
for the call; numba refuses to compile such a kernel if it allocates or returns a view). The
island solves are (``response.active_set``): a resting box's island took 1.65 µs with them, 1.06
without, its first half-microsecond spent before any arithmetic.
"""
import os
import sys

try:
    import numba as _numba
except ImportError:   # the engine still imports and runs, as plain Python
    _numba = None
    if not os.environ.get("CONTACT_SIM_QUIET_NO_NUMBA"):
        print("contact_sim: numba is not installed; kernels run as plain Python (correct but slow)",
              file=sys.stderr)

#: True when kernels are compiled (numba present and ``NUMBA_DISABLE_JIT`` not set)
COMPILED = _numba is not None and os.environ.get("NUMBA_DISABLE_JIT", "0") in ("", "0")


def njit(func=None, **options):
    """``numba.njit`` with ``cache=True`` (and never ``fastmath``: IEEE results, bit-identical runs);
    the identity decorator without numba. Use as ``@njit`` or ``@njit(**options)``."""
    if _numba is None:
        return func if func is not None else (lambda f: f)
    options.setdefault("cache", True)
    decorate = _numba.njit(**options)
    return decorate(func) if func is not None else decorate


class _PlainObjmode:
    """``objmode`` without numba: the block already runs as Python (``objmode(x="float64")`` and
    bare ``objmode`` both work as context managers)."""

    def __call__(self, *args, **types):
        return self

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


#: numba's ``objmode``: a block inside a kernel that runs as Python (for the few calls a kernel
#: hands to SciPy, e.g. the sparse active set of an island too large for the dense one); the
#: block's outputs are declared with their numba types, ``with objmode(ok="boolean"):``
objmode = _numba.objmode if _numba is not None else _PlainObjmode()
