"""Why bench_response timed pybullet's resting_10 slower than a plain ``stepSimulation`` loop.

    PYTHONPATH=. .venv/bin/python bench/response_protocol.py [--scene resting_10] [--steps 2000] [--repeats 5]

Times the same pybullet scene (``bench_response``'s resting_10 after 1 s of settling) under each
protocol in turn, the protocols taking turns ``--repeats`` times (median reported), and prints the
per-step time of each, in ms:

  * ``loop``: a plain ``for _ in range(n): p.stepSimulation(physicsClientId=cid)``, timed as a whole;
  * the same with the dynamic bodies made with ``useMaximalCoordinates=True``, and with the
    ground too (bench_response's pybullet now);
  * ``per-step timer``: the old protocol's measurement alone, every step wrapped in its own
    ``perf_counter`` pair and the engine's ``after_step`` between steps, the median step;
  * ``old protocol``: that, in blocks of 10 steps, taking turns with contact_sim (resting_10 too),
    the order rotated each round — what bench_response did before (the old protocol);
  * ``turns of B``: the new protocol: turns of B steps with contact_sim, each block timed as a
    whole (one ``perf_counter`` pair around the plain loop), per-step = block time / B, median of
    the blocks.

Also the cost of one ``perf_counter`` pair; and on each scene of ``--configs`` pybullet's three
ways of making the bodies (``createMultiBody`` as before; ``useMaximalCoordinates=True`` for the
dynamic bodies; for the ground too), fresh builds stepped 10 s in plain-loop blocks taking
turns, three times: the median per-step time in each second, and over seconds 1–10. Writes
``bench/results/response_protocol.csv``.
"""
import argparse
import csv
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import bench_response as br  # noqa: E402
import response_engines as re_  # noqa: E402


def loop_time(e, n):
    step, cid = e.p.stepSimulation, e.cid
    t0 = time.perf_counter()
    for _ in range(n):
        step(physicsClientId=cid)
    return (time.perf_counter() - t0) / n


def per_step_median(e, n):
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        e.step()
        ts.append(time.perf_counter() - t0)
        e.after_step()
    return float(np.median(ts))


def old_protocol(pb, cs, rounds, block=10):
    """bench_response's old protocol: blocks of 10 per-step-timed steps, engines taking turns."""
    times = {id(pb): [], id(cs): []}
    for r in range(rounds):
        for e in br.rotated([cs, pb], r):
            for _ in range(block):
                t0 = time.perf_counter()
                e.step()
                times[id(e)].append(time.perf_counter() - t0)
                e.after_step()
    return float(np.median(times[id(pb)])), float(np.median(times[id(cs)]))


def blocks(pb, cs, rounds, block):
    """The new protocol: each turn one block of ``block`` steps timed as a whole."""
    times = {id(pb): [], id(cs): []}
    for r in range(rounds):
        for e in br.rotated([cs, pb], r):
            times[id(e)].append(e.run_block(block) / block)
    return float(np.median(times[id(pb)])), float(np.median(times[id(cs)]))


CONFIGS = {"multibody (old adapter)": dict(maximal=False, maximal_static=False),
           "maximal coordinates, dynamic bodies": dict(maximal=True, maximal_static=False),
           "maximal coordinates, ground too": dict(maximal=True, maximal_static=True)}


def configs(scene, seconds, block, repeats):
    """pybullet's three ways of making the bodies, fresh builds stepped ``seconds`` from the start
    in plain-loop blocks of ``block`` taking turns, ``repeats`` times: per config the per-step
    times, an array (repeats, blocks)."""
    n_blocks = int(round(seconds / scene.dt)) // block
    t = {k: np.zeros((repeats, n_blocks)) for k in CONFIGS}
    for rep in range(repeats):
        es = {k: re_.PyBulletEngine(scene, **kw) for k, kw in CONFIGS.items()}
        for b in range(n_blocks):
            for k in br.rotated(list(es), b + rep):
                t[k][rep, b] = es[k].run_block(block) / block
        for e in es.values():
            e.close()
    return t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="resting_10", help="resting_10 | resting_100 | spheres_10")
    ap.add_argument("--steps", type=int, default=2000, help="timed steps per protocol and repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "response_protocol.csv"))
    ap.add_argument("--configs", default="ball_1,spheres_10,resting_10,resting_100,stack_10",
                    help="scenes on which to time pybullet's three body configurations ('' for none)")
    args = ap.parse_args(argv)
    scene = br.SCENES[args.scene]()
    n = args.steps
    warnings.simplefilter("ignore")

    def build(**kw):
        e = re_.PyBulletEngine(scene, **kw)
        e.run_block(100)          # settle 1 s at dt 0.01
        return e

    pb_multi = build(maximal=False, maximal_static=False)
    pb_max = build(maximal=True, maximal_static=False)
    pb_all = build(maximal=True, maximal_static=True)
    cs = re_.ContactSimEngine(scene)
    cs.run_block(100)
    t = time.perf_counter
    pair = []
    for _ in range(5):
        t0 = t()
        for _ in range(100000):
            t()
            t()
        pair.append((t() - t0) / 100000)
    res = {}

    def add(key, v):
        res.setdefault(key, []).append(v)

    for rep in range(args.repeats):
        add("loop, multibody (old adapter)", loop_time(pb_multi, n))
        add("loop, maximal coordinates (dynamic bodies)", loop_time(pb_max, n))
        add("loop, maximal coordinates (ground too)", loop_time(pb_all, n))
        add("per-step timer alone, multibody", per_step_median(pb_multi, n))
        add("per-step timer alone, maximal (dynamic bodies)", per_step_median(pb_max, n))
        add("per-step timer alone, maximal (ground too)", per_step_median(pb_all, n))
        add("contact_sim world.step loop alone", cs.run_block(n) / n)
        pb, c = old_protocol(pb_multi, cs, n // 10)
        add("old protocol (turns of 10, per-step timer), multibody", pb)
        add("  contact_sim in it", c)
        pb, c = old_protocol(pb_all, cs, n // 10)
        add("old protocol (turns of 10, per-step timer), maximal (ground too)", pb)
        add("  contact_sim in it (maximal peer)", c)
        for b in (10, 100, 500):
            pb, c = blocks(pb_all, cs, max(4, n // b), b)
            add(f"turns of {b}, block timed whole, maximal (ground too)", pb)
            add(f"  contact_sim in it (turns of {b})", c)
        print(f"repeat {rep + 1}/{args.repeats}", file=sys.stderr, flush=True)
    print(f"\n{scene.name}: pybullet per-step ms, median of {args.repeats} repeats of {n} steps "
          f"(load {br.load()}); perf_counter pair {1e6 * np.median(pair):.3f} µs")
    out = []
    for k, v in res.items():
        out.append({"scene": scene.name, "protocol": k, "step_ms": 1e3 * float(np.median(v)),
                    "min_ms": 1e3 * float(np.min(v)), "max_ms": 1e3 * float(np.max(v)), "repeats": len(v)})
        print(f"  {k:<58} {out[-1]['step_ms']:.4f}  ({out[-1]['min_ms']:.4f}–{out[-1]['max_ms']:.4f})")
    out.append({"scene": scene.name, "protocol": "perf_counter pair", "step_ms": 1e3 * float(np.median(pair)),
                "min_ms": 1e3 * min(pair), "max_ms": 1e3 * max(pair), "repeats": len(pair)})
    for name in filter(None, args.configs.split(",")):
        sc = br.SCENES[name]()
        per_s = int(round(1.0 / sc.dt))
        block = per_s // 2 if name != "stack_10" else per_s // 10
        t = configs(sc, 10.0, block, 3)
        print(f"\n{name}: pybullet per-step ms by configuration, fresh builds stepped 10 s in blocks of {block} "
              f"taking turns, median of 3; each second of the 10, then seconds 1-10 (bench_response's window)")
        for k, v in t.items():
            med = np.median(v, axis=0)                         # per block, over repeats
            secs = [1e3 * float(np.median(c)) for c in np.array_split(med, 10)]
            late = v[:, len(med) // 10:]
            out.append({"scene": name, "protocol": f"config: {k}", "step_ms": 1e3 * float(np.median(late)),
                        "min_ms": 1e3 * float(late.min()), "max_ms": 1e3 * float(late.max()), "repeats": v.shape[0],
                        "by_second_ms": " ".join(f"{x:.4f}" for x in secs)})
            print(f"  {k:<40} {out[-1]['step_ms']:.4f}   by second " + out[-1]["by_second_ms"])
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(out[-2]), restval="")
        w.writeheader()
        w.writerows(out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
