"""Where a small step's time goes: Python between the compiled calls, the calls' boundary (numba
unboxing each argument and boxing each array handed back), and the compiled kernels themselves.

    python bench/step_anatomy.py [--scenes ball_1,spheres_10,resting_10,resting_100,stack_10]
                                 [--steps 400] [--out bench/results]

Part 1 measures the boundary's unit costs on this machine: a call, an array argument, a scalar
argument, an array handed back, an allocation inside compiled code. Part 2 takes each scene of
``bench_response`` (settled for 300 steps) and

1. times ``World.step`` over ``--steps`` steps, as the benchmarks do;
2. steps as many again with every compiled function that Python calls wrapped (each module's
   numba dispatchers, wherever a module imported them): each call's arguments are copied before it
   runs, so it can be replayed as it was;
3. replays every recorded call on fresh copies, timing the call alone: the compiled time per step,
   boundary included;
4. estimates the boundary from the calls' argument and result counts and part 1's unit costs; the
   rest of the compiled time is the kernels'.

Python glue = the step's time − the compiled calls' time; its largest parts by function come from
a cProfile run of as many steps, scaled to it (indicative: cProfile inflates small functions).
Replayed alone a call finds its data in the cache, so the glue also holds what the kernels lose to
a colder cache inside the step: an upper bound on the Python's share (on 100 bodies, 30–52 µs
against ~28 on ten, where the Python does the same few things a step). ``kernels ÷ peer``: the
step's kernels alone against the peer's whole step (``bench/results/response_peers.csv``, the last
peer run): the ratio a step with no Python and no boundary would have at today's kernels.

Prints a table and writes ``step_anatomy.csv`` into ``--out``. Times drift on this shared machine
(2×), so the split within a scene is what to read, not the absolute values.
"""
import argparse
import csv
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.dirname(HERE)]

import bench_response as br  # noqa: E402
from response_engines import ContactSimEngine  # noqa: E402

OUT = os.path.join(HERE, "results")
PEERS = os.path.join(HERE, "results", "response_peers.csv")
PEER_OF = {"ball_1": "pybullet", "spheres_10": "pybullet", "resting_10": "pybullet", "resting_100": "pybullet",
           "stack_10": "MuJoCo"}


# ---------------------------------------------------------------------------- part 1: unit costs
def _best(f, n=20000, rounds=5):
    """Best of ``rounds`` of ``n`` calls of ``f`` (s per call)."""
    best = np.inf
    for _ in range(rounds):
        t = time.perf_counter()
        for _ in range(n):
            f()
        best = min(best, (time.perf_counter() - t) / n)
    return best


def unit_costs():
    """The boundary's unit costs (s): ``call`` (no argument, a float back), ``array`` (each array
    argument), ``scalar`` (each float argument), ``returned`` (each new array handed back),
    ``alloc`` (one small ``np.empty`` inside compiled code)."""
    from numba import njit

    n = 20
    names = ", ".join(f"x{i}" for i in range(n))
    ns = {}
    exec(f"def many({names}):\n    return 0.0\n", ns)
    many = njit(ns["many"])

    @njit
    def none():
        return 0.0

    @njit
    def one(x):
        return 0.0

    @njit
    def back1(x):
        return np.empty(2)

    @njit
    def back5(x):
        return np.empty(2), np.empty(2), np.empty(2), np.empty(2), np.empty(2)

    @njit
    def allocs(m):
        s = 0.0
        for _ in range(m):
            s += np.empty(3)[0] * 0.0
        return s

    arrays, floats, x = [np.zeros(3) for _ in range(n)], [1.0] * n, np.zeros(3)
    for f, a in ((none, ()), (one, (x,)), (many, arrays), (many, floats), (back1, (x,)), (back5, (x,)), (allocs, (1,))):
        f(*a)
    call = _best(none)
    array = (_best(lambda: many(*arrays)) - _best(lambda: one(x))) / (n - 1)
    scalar = (_best(lambda: many(*floats)) - _best(lambda: one(1.0))) / (n - 1)
    returned = (_best(lambda: back5(x)) - _best(lambda: back1(x))) / 4
    alloc = _best(lambda: allocs(100000), n=3) / 100000
    return dict(call=call, array=array, scalar=scalar, returned=returned, alloc=alloc)


# ---------------------------------------------------------------------------- part 2: a step
def _dispatchers():
    """``{(module, attribute): dispatcher}``: every numba dispatcher that an engine module holds
    as a global (its own kernels and those it imported)."""
    from numba.core.registry import CPUDispatcher

    out = {}
    for name, mod in list(sys.modules.items()):
        if not (name == "contact_sim" or name.startswith("contact_sim.")) or mod is None:
            continue
        for attr, value in vars(mod).items():
            if isinstance(value, CPUDispatcher):
                out[(mod, attr)] = value
    return out


def _copy(x):
    if isinstance(x, np.ndarray):
        return x.copy()
    if isinstance(x, tuple):
        return tuple(_copy(v) for v in x)
    return x


def _count(values):
    """``(arrays, scalars)`` among ``values``, tuples counted by their elements."""
    arrays = scalars = 0
    for v in values:
        if isinstance(v, np.ndarray):
            arrays += 1
        elif isinstance(v, tuple):
            a, s = _count(v)
            arrays, scalars = arrays + a, scalars + s
        else:
            scalars += 1
    return arrays, scalars


def anatomy(name, steps, units):
    """One scene's split: a dict of per-step microseconds and counts."""
    e = ContactSimEngine(br.SCENES[name]())
    w = e.world
    for _ in range(300):
        w.step()
    t = time.perf_counter()
    for _ in range(steps):
        w.step()
    step_s = (time.perf_counter() - t) / steps

    calls = []
    wrapped = _dispatchers()

    def wrap(d):
        def recorder(*args):
            calls.append((d, _copy(args)))
            return d(*args)
        return recorder

    try:
        for (mod, attr), d in wrapped.items():
            setattr(mod, attr, wrap(d))
        for _ in range(steps):
            w.step()
    finally:
        for (mod, attr), d in wrapped.items():
            setattr(mod, attr, d)

    compiled = boundary = 0.0
    n_args = n_back = 0
    for d, args in calls:
        a = _copy(args)
        t = time.perf_counter()
        out = d(*a)
        dt = time.perf_counter() - t
        a = _copy(args)   # best of two: the first may touch cold memory
        t = time.perf_counter()
        d(*a)
        compiled += min(dt, time.perf_counter() - t)
        arrays, scalars = _count(args)
        back, _ = _count(out if isinstance(out, tuple) else (out,))
        n_args += arrays + scalars
        n_back += back
        boundary += units["call"] + arrays * units["array"] + scalars * units["scalar"] + back * units["returned"]
    compiled, boundary = compiled / steps, boundary / steps
    compiled = min(compiled, step_s)
    glue = step_s - compiled
    return dict(scene=name, steps=steps, step_us=1e6 * step_s, glue_us=1e6 * glue, boundary_us=1e6 * boundary,
                kernels_us=1e6 * max(compiled - boundary, 0.0), calls_per_step=len(calls) / steps,
                args_per_step=n_args / steps, arrays_back_per_step=n_back / steps,
                glue_by_function=_glue_by_function(w, steps, set(wrapped.values()), glue))


_ENGINE = os.sep + "contact_sim" + os.sep


def _name(path, fn):
    """``module.function`` of an engine source file, the module dotted below the package."""
    mod = path.rsplit(_ENGINE, 1)[1][:-3].replace(os.sep, ".")
    return f"{mod[:-len('.__init__')] if mod.endswith('.__init__') else mod}.{fn}"


def _glue_by_function(world, steps, dispatchers, glue, top=6):
    """The glue's largest parts by engine function: ``"name µs; ..."``. cProfile's own time of
    each Python function of the engine (numpy and builtins counted with their caller; the compiled
    calls left out), scaled so that they sum to ``glue`` (s a step): cProfile's cost per call
    inflates functions that are called often, so the split is indicative, not exact."""
    import cProfile
    import pstats

    compiled = {(d.py_func.__code__.co_filename, d.py_func.__code__.co_firstlineno) for d in dispatchers}
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(steps):
        world.step()
    prof.disable()
    own = {}
    for (path, line, fn), (_, _, tottime, _, callers) in pstats.Stats(prof).stats.items():
        if (path, line) in compiled:
            continue
        if _ENGINE in path:
            key = _name(path, fn)
        else:   # a builtin or numpy: its engine caller's
            mine = [c for c in callers if _ENGINE in c[0] and (c[0], c[1]) not in compiled]
            if not mine:
                continue
            key = _name(mine[0][0], mine[0][2])
        own[key] = own.get(key, 0.0) + tottime
    total = sum(own.values()) or 1.0
    parts = sorted(own.items(), key=lambda kv: -kv[1])[:top]
    return "; ".join(f"{k} {1e6 * glue * v / total:.1f}" for k, v in parts)


def peer_ms():
    """``{scene: (peer, step_ms)}`` from the last peer run."""
    out = {}
    if not os.path.exists(PEERS):
        return out
    with open(PEERS) as f:
        for row in csv.DictReader(f):
            if PEER_OF.get(row["scene"]) == row["engine"] and row["step_ms"]:
                out[row["scene"]] = (row["engine"], float(row["step_ms"]))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(PEER_OF))
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--out", default=OUT, help="directory for step_anatomy.csv (default: bench/results)")
    args = ap.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    unknown = [s for s in scenes if s not in br.SCENES]
    if unknown:
        ap.error(f"unknown scene(s) {', '.join(unknown)}; known: {', '.join(br.SCENES)}")
    from contact_sim.jit import COMPILED

    if not COMPILED:
        ap.error("the kernels are not compiled (numba missing or NUMBA_DISABLE_JIT set): there is no boundary "
                 "to measure and no compiled call to replay")
    units = unit_costs()
    print("boundary unit costs (ns): " + ", ".join(f"{k} {1e9 * v:.0f}" for k, v in units.items()))
    peers = peer_ms()
    rows = []
    head = (f"{'scene':12s} {'step us':>8s} {'glue':>13s} {'boundary':>13s} {'kernels':>13s} {'calls':>6s} "
            f"{'args':>6s} {'back':>5s} {'kernels÷peer':>13s}")
    print(head)
    for name in scenes:
        r = anatomy(name, args.steps, units)
        peer = peers.get(name)
        r["peer"], r["peer_step_us"] = (peer[0], 1e3 * peer[1]) if peer else ("", float("nan"))
        r["kernels_over_peer"] = r["kernels_us"] / r["peer_step_us"] if peer else float("nan")
        rows.append(r)
        pct = {k: 100 * r[k] / r["step_us"] for k in ("glue_us", "boundary_us", "kernels_us")}
        print(f"{name:12s} {r['step_us']:8.1f} {r['glue_us']:7.1f} ({pct['glue_us']:3.0f}%) "
              f"{r['boundary_us']:7.1f} ({pct['boundary_us']:3.0f}%) "
              f"{r['kernels_us']:7.1f} ({pct['kernels_us']:3.0f}%) "
              f"{r['calls_per_step']:6.1f} {r['args_per_step']:6.0f} {r['arrays_back_per_step']:5.1f} "
              f"{r['kernels_over_peer']:8.2f} {r['peer']}")
    print("glue by function (µs a step, cProfile's split scaled to the glue):")
    for r in rows:
        print(f"  {r['scene']}: {r['glue_by_function']}")
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "step_anatomy.csv")
    with open(path, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]) + [f"unit_{k}_ns" for k in units])
        wr.writeheader()
        for r in rows:
            wr.writerow({**r, **{f"unit_{k}_ns": 1e9 * v for k, v in units.items()}})
    print(f"wrote {path}")
    return rows


if __name__ == "__main__":
    main()
