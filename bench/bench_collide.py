"""The stateless one-pair query in a loop: ``cs.collide`` per pair, beside python-fcl's ``collide``.

Usage: ``python bench/bench_collide.py [--calls 2000] [--rounds 5]``

Pairs: sphere–box, box–box, and two hulls of 32 random points (seeded), overlapping, one pose each
(the second body turned about a skew axis). Poses are given as a user writing a loop would: a
tuple of Python numbers, a tuple of numpy scalars (``tuple(array)``), and numpy arrays. Each row is
the median over rounds of the mean time per call; contact_sim and FCL take turns per round.
Prints a table and writes ``bench/results/collide.csv``.
"""
import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import contact_sim as cs  # noqa: E402
from report import write_rows  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def pairs():
    rng = np.random.default_rng(0)
    return {"sphere-box": (cs.Sphere(0.1), cs.Box((0.2, 0.2, 0.2)), 0.19),
            "box-box": (cs.Box((0.2, 0.2, 0.2)), cs.Box((0.2, 0.2, 0.2)), 0.22),
            "hull-hull (32 points)": (cs.Convex(rng.normal(size=(32, 3)) * 0.1),
                                      cs.Convex(rng.normal(size=(32, 3)) * 0.1), 0.2)}


def per_call(fn, calls):
    fn()
    t = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t) / calls * 1e6


def fcl_query(a, b, d, q):
    import fcl

    def geom(s):
        if isinstance(s, cs.Sphere):
            return fcl.Sphere(s.radius)
        if isinstance(s, cs.Box):
            return fcl.Box(*s.size)
        m = fcl.Convex(s.vertices, len(s.faces), np.hstack([np.full((len(s.faces), 1), 3), s.faces]).ravel())
        return m

    oa = fcl.CollisionObject(geom(a), fcl.Transform())
    ob = fcl.CollisionObject(geom(b), fcl.Transform(np.array([q[3], q[0], q[1], q[2]]), np.array([0.0, 0.0, d])))
    req = fcl.CollisionRequest(num_max_contacts=4, enable_contact=True)
    return lambda: fcl.collide(oa, ob, req, fcl.CollisionResult())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    q = np.array([0.1, 0.2, 0.3, 0.9])
    q = q / np.linalg.norm(q)
    I = (0.0, 0.0, 0.0, 1.0)
    rows = []
    for name, (a, b, d) in pairs().items():
        forms = {"tuple of floats": ((0.0, 0.0, d), tuple(float(x) for x in q)),
                 "tuple of numpy scalars": ((0.0, 0.0, d), tuple(q)),
                 "numpy arrays": (np.array([0.0, 0.0, d]), q)}
        fns = {form: (lambda pose=pose: cs.collide(a, ((0.0, 0.0, 0.0), I), b, pose)) for form, pose in forms.items()}
        try:
            fns["python-fcl collide (4 contacts)"] = fcl_query(a, b, d, q)
        except ImportError:
            pass
        times = {k: [] for k in fns}
        for _ in range(args.rounds):
            for k, fn in fns.items():
                times[k].append(per_call(fn, args.calls))
        contacts = len(cs.collide(a, ((0.0, 0.0, 0.0), I), b, forms["numpy arrays"]))
        for k, t in times.items():
            rows.append({"pair": name, "call": k, "us_per_call": f"{statistics.median(t):.2f}",
                         "contacts": contacts if not k.startswith("python-fcl") else ""})
    print(f"{'pair':<24} {'call':<34} {'µs per call':>12} {'contacts':>9}")
    for r in rows:
        print(f"{r['pair']:<24} {r['call']:<34} {r['us_per_call']:>12} {r['contacts']!s:>9}")
    print(f"wrote {write_rows(os.path.join(HERE, 'results', 'collide.csv'), rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
