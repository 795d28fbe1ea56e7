"""Per-world derived data, kept on the world object across steps.

The world replaces (never edits in place) its per-body arrays when a body is added, so a value
derived from them stays valid while the very same array objects are there. ``derived`` holds them
and compares by identity (an ``id()`` alone could be reused by a later array); ``key`` adds
plain values compared by equality (settings, a step size). Everything lives in the object's own
declared dict ``_derived`` (``World._derived``), so it goes with the world.
"""
from operator import is_


def derived(obj, name, deps, build, key=None):
    """``build()``, cached on ``obj`` under ``name`` until one of ``deps`` (objects, compared by
    identity) is replaced or ``key`` (compared by equality) changes."""
    memo = obj._derived
    hit = memo.get(name)
    # a hit is the usual case, several times a step: ``map(is_)`` compares without a generator frame
    if (hit is None or hit[1] != key or len(hit[0]) != len(deps)
            or not all(map(is_, hit[0], deps))):
        hit = memo[name] = (tuple(deps), key, build())
    return hit[2]
