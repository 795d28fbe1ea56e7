"""Response benchmark: contact_sim beside pybullet and MuJoCo, one process, engines taking turns.

The machine (2 cores, shared) drifts by 2× in absolute speed, so every row builds the same scene
in each engine and steps them in alternation — short chunks of the same simulated interval, the
order rotated every round — and reports RATIOS (contact_sim's time ÷ the peer's). Only the step
calls are timed. Penetration, escapes and drift are computed in numpy from each engine's final
poses, the same way for all (``response_engines.max_penetration``), never from an engine's own
contact report.

    .venv/bin/python bench/bench_response.py [--quick] [--rows pile,stack,resting,rotation]
                                             [--seconds S] [--out DIR] [--variants gs:20 ...]

Prints a table, writes ``response_peers.csv`` and ``response_peers.png`` (bar chart of the
ratios) to bench/results/ (``--quick``: ``response_peers_quick.*``; ``--out`` another folder).
``make bench`` runs it; ``bench/report.py`` puts the table in docs/benchmarks.md.

The scenes (issue 12), exactly:

1. ``pile_1000``, the jittered sphere pile: 1000 spheres, radius 0.05 m, mass 0.1 kg, start on a
   10×10×10 grid of 0.12 m spacing centred on x = y = 0, lowest layer's centres at z = 0.5 m,
   each coordinate jittered by U(−0.01, 0.01) m (``numpy.random.default_rng(0)``, one
   ``uniform(size=(1000, 3))`` call, grid order x, y, z). Ground: the plane z = 0. Four static
   boxes 0.1 m thick and 2 m high (z 0 to 2) whose inner faces are at x = ±0.7 and y = ±0.7
   (a 1.4 × 1.4 m area centred on the grid; the x walls 1.6 m long, the y walls 1.4 m).
   μ 0.5, e 0, gravity −9.81 z, dt 1/240, 2 s (480 steps), chunks of 12 steps. Reported: wall s
   per simulated s, final maximum penetration (deepest sphere–sphere, sphere–ground or
   sphere–wall overlap at the final poses) and spheres escaped (centre outside |x|, |y| ≤ 0.7 or
   below z = 0).
2. ``stack_10``: ten 0.2 m cubes of 1 kg stacked exactly touching (centres at z = 0.1 + 0.2 i) on
   the plane z = 0, μ 0.6, e 0, dt 1/240, 5 s (1200 steps), chunks of 24, median of 3 repeats.
   Reported: wall s per simulated s, top box drift (distance of its final centre from its start)
   and final maximum penetration (box–box by the 15-axis separating-axis overlap, box–ground by
   the lowest corner).
3. ``resting_10`` and ``resting_100``: 10 (100) bodies on the plane z = 0, alternately spheres
   (r 0.1 m) and boxes (0.2 m cubes), 1 kg each, on a square grid 0.5 m apart (4×4 and 10×10
   cells, row-major), resting at z = 0.1; μ 0.5, e 0, dt 0.01. Settled for 1 s (untimed), then
   200 rounds of 10 steps per engine, taking turns (the order rotated each round), each step
   timed: median step time. The ratio to a peer is the median over rounds of the two engines'
   median step times within the round, which cancels this shared machine's drift (2× over
   minutes) better than the ratio of the whole run's medians (``ratio_of_medians`` in the CSV).
   For contact_sim also the split: detection (``world.last_detection.seconds["total"]``) and the
   rest of the step (the median of step − detection).
4. ``rotation``: a 1 × 0.05 × 0.05 m rod of 1 kg spinning end over end (ω = 7 rad/s about the
   world y axis, a transverse principal axis) in free flight, no gravity, dt 1/60; and a 0.2 m
   cube of 1 kg with the same spin. contact_sim only: 40 rounds of 10 steps each, median step
   time, ratio rod ÷ cube (target ≤ 1).

Each engine runs on its own terms (see ``response_engines``): contact_sim with its defaults (only
dt set; its ``auto`` models), pybullet with its defaults (50 iterations) but damping 0 and
restitution threshold 0, with √μ and √e per body (product rule), MuJoCo with its defaults
(Newton, 100 iterations, pyramidal cone, soft contacts, no restitution) and friction μ per geom
(max rule). The settings each ran with are printed and written to the CSV.

``--quick`` (smoke test, ~10 s): a 4×4×4 pile for 0.4 s, the stack for 0.25 s, 2 rounds of
resting and rotation steps after 0.1 s of settling — it checks the machinery, not the speed.
"""
import argparse
import csv
import importlib.metadata
import math
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

import response_engines as re_  # noqa: E402
from response_engines import ENGINES, Body, ContactSimEngine, Scene  # noqa: E402

FIELDS = ["scene", "engine", "bodies", "dt", "steps", "repeats", "wall_s_per_sim_s", "step_ms", "detect_ms",
          "rest_ms", "ratio", "ratio_meaning", "ratio_of_medians", "max_penetration_mm", "escaped", "top_drift_mm",
          "contacts_per_step", "solver_iterations", "load_1min", "settings"]
WALL_INNER = 0.7


# ---------------------------------------------------------------------------- scenes
def pile_scene(side=10, seed=0):
    """Row 1: the jittered sphere pile (``side``³ spheres; 10 in the issue)."""
    g = (np.arange(side) - (side - 1) / 2) * 0.12
    grid = np.array([[x, y, 0.5 + 0.12 * k] for x in g for y in g for k in range(side)])
    pos = grid + np.random.default_rng(seed).uniform(-0.01, 0.01, size=grid.shape)
    t, h, a = 0.1, 2.0, WALL_INNER
    c = a + t / 2
    bodies = [Body("ground", "plane", None),
              Body("wall_px", "box", (t, 2 * a + 2 * t, h), position=(c, 0, h / 2)),
              Body("wall_nx", "box", (t, 2 * a + 2 * t, h), position=(-c, 0, h / 2)),
              Body("wall_py", "box", (2 * a, t, h), position=(0, c, h / 2)),
              Body("wall_ny", "box", (2 * a, t, h), position=(0, -c, h / 2))]
    bodies += [Body(f"s{i}", "sphere", 0.05, mass=0.1, position=tuple(p)) for i, p in enumerate(pos)]
    return Scene(f"pile_{side ** 3}", bodies, dt=1 / 240, friction=0.5, restitution=0.0)


def stack_scene(n=10):
    """Row 2: ``n`` 0.2 m cubes of 1 kg exactly touching, μ 0.6."""
    bodies = [Body("ground", "plane", None)]
    bodies += [Body(f"box{i}", "box", (0.2, 0.2, 0.2), mass=1.0, position=(0, 0, 0.1 + 0.2 * i)) for i in range(n)]
    return Scene(f"stack_{n}", bodies, dt=1 / 240, friction=0.6, restitution=0.0)


def resting_scene(n):
    """Row 3: ``n`` bodies resting on the plane, alternately spheres r 0.1 and 0.2 m cubes, 0.5 m apart."""
    side = math.ceil(math.sqrt(n))
    bodies = [Body("ground", "plane", None)]
    for i in range(n):
        r, c = divmod(i, side)
        shape, size = ("sphere", 0.1) if i % 2 == 0 else ("box", (0.2, 0.2, 0.2))
        bodies.append(Body(f"b{i}", shape, size, mass=1.0, position=(0.5 * c, 0.5 * r, 0.1)))
    return Scene(f"resting_{n}", bodies, dt=0.01, friction=0.5, restitution=0.0)


def rotation_scene(size):
    """Row 4: one box of edge lengths ``size``, 1 kg, ω = 7 rad/s about y, no gravity, dt 1/60."""
    return Scene("rod" if size[0] != size[1] else "cube",
                 [Body("body", "box", size, mass=1.0, angular_velocity=(0.0, 7.0, 0.0))],
                 dt=1 / 60, gravity=(0.0, 0.0, 0.0), friction=0.5, restitution=0.0)


# ---------------------------------------------------------------------------- protocols
def rotated(items, k):
    k %= len(items)
    return items[k:] + items[:k]


def load():
    return round(os.getloadavg()[0], 2)


def run_interleaved(scene, names, steps, chunk, repeats, progress=True):
    """Step the scene in every engine for ``steps`` steps, in chunks of ``chunk`` steps, taking
    turns (order rotated each round); ``repeats`` fresh runs. Returns per engine the median wall
    seconds of the stepping and the engine object of the last run (for its final state)."""
    walls = {n: [] for n in names}
    last = {}
    for rep in range(repeats):
        engines = [ENGINES[n](scene) for n in names]
        wall = dict.fromkeys(names, 0.0)
        done, rnd, t_print = 0, 0, time.perf_counter()
        while done < steps:
            n = min(chunk, steps - done)
            for e in rotated(engines, rnd):
                wall[e.name] += e.run(n)
            done += n
            rnd += 1
            if progress and time.perf_counter() - t_print > 10:
                t_print = time.perf_counter()
                print(f"  {scene.name} repeat {rep + 1}/{repeats}: {done}/{steps} steps, "
                      + ", ".join(f"{k} {v:.1f} s" for k, v in wall.items()), file=sys.stderr, flush=True)
        for n in names:
            walls[n].append(wall[n])
        for e in last.values():
            e.close()
        last = {e.name: e for e in engines}
    return {n: float(np.median(walls[n])) for n in names}, last


def timed_steps(engines, settle, rounds, block):
    """Settle every engine ``settle`` steps (untimed), then ``rounds`` turns of ``block`` steps each,
    every step timed. Returns per engine the step times (s) and, for contact_sim, the detection
    seconds of the same steps."""
    for e in engines:
        e.run(settle)
    times = {id(e): [] for e in engines}
    detect = {id(e): [] for e in engines}
    for r in range(rounds):
        for e in rotated(engines, r):
            for _ in range(block):
                t0 = time.perf_counter()
                e.step()
                times[id(e)].append(time.perf_counter() - t0)
                if isinstance(e, ContactSimEngine):
                    detect[id(e)].append(e.world.last_detection.seconds.get("total", np.nan))
                e.after_step()
    return ({id(e): np.array(times[id(e)]) for e in engines},
            {id(e): np.array(detect[id(e)]) for e in engines})


def base_row(scene, engine, steps, repeats=1):
    return {"scene": scene.name, "engine": engine.name, "bodies": len(scene.bodies), "dt": scene.dt, "steps": steps,
            "repeats": repeats, "settings": engine.settings(), "load_1min": load()}


def cs_stats(e, row):
    if isinstance(e, ContactSimEngine):
        row["contacts_per_step"] = float(np.nanmean(e.contacts)) if e.contacts else ""
        row["solver_iterations"] = float(np.nanmean(e.iterations)) if e.iterations else ""


def add_ratios(rows, meaning="contact_sim ÷ {}"):
    """Ratio of contact_sim's time to each peer's, on the peer's row."""
    key = "wall_s_per_sim_s" if rows[0].get("wall_s_per_sim_s", "") != "" else "step_ms"
    cs = next(r for r in rows if r["engine"] == "contact_sim")
    for r in rows:
        if r is not cs:
            r["ratio"] = cs[key] / r[key]
            r["ratio_meaning"] = meaning.format(r["engine"])
    return rows


# ---------------------------------------------------------------------------- rows
def row_pile(names, side, seconds, chunk):
    scene = pile_scene(side)
    steps = int(round(seconds / scene.dt))
    wall, engines = run_interleaved(scene, names, steps, chunk, 1)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        out = (np.abs(pos[:, 0]) > WALL_INNER) | (np.abs(pos[:, 1]) > WALL_INNER) | (pos[:, 2] < 0)
        row = base_row(scene, e, steps)
        row.update(wall_s_per_sim_s=wall[n] / (steps * scene.dt),
                   max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q), escaped=int(out.sum()))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows)


def row_stack(names, seconds, chunk, repeats):
    scene = stack_scene()
    steps = int(round(seconds / scene.dt))
    wall, engines = run_interleaved(scene, names, steps, chunk, repeats)
    top0 = np.array(scene.dynamic[-1].position)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        row = base_row(scene, e, steps, repeats)
        row.update(wall_s_per_sim_s=wall[n] / (steps * scene.dt),
                   max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q),
                   top_drift_mm=1e3 * float(np.linalg.norm(pos[-1] - top0)))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows)


def row_resting(names, n_bodies, settle, rounds, block):
    scene = resting_scene(n_bodies)
    engines = [ENGINES[n](scene) for n in names]
    times, detect = timed_steps(engines, settle, rounds, block)
    rows = []
    for e in engines:
        t = times[id(e)]
        pos, q = e.poses()
        row = base_row(scene, e, len(t))
        row.update(step_ms=1e3 * float(np.median(t)), max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q))
        d = detect[id(e)]
        if d.size:
            row.update(detect_ms=1e3 * float(np.median(d)), rest_ms=1e3 * float(np.median(t - d)))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    rows = add_ratios(rows)
    # the ratio taken round by round: both engines' steps of a round were timed seconds apart
    cs = times[id(engines[0])].reshape(rounds, block)
    for e, row in zip(engines[1:], rows[1:]):
        peer = times[id(e)].reshape(rounds, block)
        row["ratio_of_medians"] = row["ratio"]
        row["ratio"] = float(np.median(np.median(cs, axis=1) / np.median(peer, axis=1)))
        row["ratio_meaning"] = f"contact_sim ÷ {e.name}, median over rounds of the round's step medians"
    return rows


def row_rotation(rounds, block):
    rod, cube = rotation_scene((1.0, 0.05, 0.05)), rotation_scene((0.2, 0.2, 0.2))
    engines = [ContactSimEngine(rod), ContactSimEngine(cube)]
    times, _ = timed_steps(engines, 0, rounds, block)
    rows = []
    for scene, e in zip((rod, cube), engines):
        row = base_row(scene, e, len(times[id(e)]))
        row.update(scene=f"rotation_{scene.name}", step_ms=1e3 * float(np.median(times[id(e)])))
        rows.append(row)
        e.close()
    rows[0].update(ratio=rows[0]["step_ms"] / rows[1]["step_ms"], ratio_meaning="rod ÷ cube (contact_sim)")
    return rows


def row_variant(spec, side, seconds, chunk):
    """contact_sim alone on the pile with the solver forced (``METHOD:ITERATIONS``, e.g. ``gs:20``,
    ``jacobi:20``): the speed/penetration trade-off, through ``settings.solver_method`` and
    ``settings.solver_iterations``."""
    method, iters = spec.split(":")[:2]
    scene = pile_scene(side)
    scene.contact_sim_settings = {"solver_iterations": int(iters), "solver_method": method}
    scene.name = f"{scene.name}_{method}{iters}"
    return _variant(scene, seconds, chunk)


def _variant(scene, seconds, chunk):
    steps = int(round(seconds / scene.dt))
    wall, engines = run_interleaved(scene, ["contact_sim"], steps, chunk, 1)
    e = engines["contact_sim"]
    pos, q = e.poses()
    out = (np.abs(pos[:, 0]) > WALL_INNER) | (np.abs(pos[:, 1]) > WALL_INNER) | (pos[:, 2] < 0)
    row = base_row(scene, e, steps)
    row.update(wall_s_per_sim_s=wall["contact_sim"] / (steps * scene.dt),
               max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q), escaped=int(out.sum()))
    cs_stats(e, row)
    return row


# ---------------------------------------------------------------------------- output
def fmt(x, spec):
    return "" if x in ("", None) or (isinstance(x, float) and np.isnan(x)) else format(x, spec)


def print_table(rows):
    head = (f"{'scene':<18} {'engine':<12} {'s/sim s':>8} {'step ms':>8} {'ratio':>8}  {'meaning':<22} "
            f"{'pen mm':>9} {'escaped':>7} {'drift mm':>9} {'detect ms':>9} {'rest ms':>8} {'contacts':>8} {'iters':>6}")
    print("\n" + head + "\n" + "-" * len(head))
    for r in rows:
        print(f"{r['scene']:<18} {r['engine']:<12} {fmt(r.get('wall_s_per_sim_s'), '8.3f'):>8} "
              f"{fmt(r.get('step_ms'), '8.3f'):>8} {fmt(r.get('ratio'), '8.2f'):>8}  {r.get('ratio_meaning', ''):<22} "
              f"{fmt(r.get('max_penetration_mm'), '9.3g'):>9} {fmt(r.get('escaped'), 'd'):>7} "
              f"{fmt(r.get('top_drift_mm'), '9.3g'):>9} {fmt(r.get('detect_ms'), '9.3f'):>9} "
              f"{fmt(r.get('rest_ms'), '8.3f'):>8} {fmt(r.get('contacts_per_step'), '8.0f'):>8} "
              f"{fmt(r.get('solver_iterations'), '6.1f'):>6}")
    print("\nsettings:")
    scenes = {}
    for r in rows:
        scenes.setdefault((r["engine"], r["settings"]), []).append(r["scene"])
    for (engine, st), sc in scenes.items():
        print(f"  {engine} ({', '.join(dict.fromkeys(sc))}): {st}")


def write_csv(rows, path):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in FIELDS})


def plot(rows, path):
    """Bar chart of the ratios on a log scale; 1 (parity) drawn as a line."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not importable: no chart")
        return None
    rr = [r for r in rows if r.get("ratio", "") != ""]
    if not rr:
        return None
    colour = {"pybullet": "tab:orange", "MuJoCo": "tab:green", "contact_sim": "tab:blue"}
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(rr) + 2), 4.5))
    x = np.arange(len(rr))
    vals = [r["ratio"] for r in rr]
    ax.bar(x, vals, color=[colour.get(r["engine"], "grey") for r in rr])
    for xi, v in zip(x, vals):
        ax.annotate(f"{v:.3g}×", (xi, v), ha="center", va="bottom", fontsize=8)
    ax.axhline(1.0, color="black", linewidth=0.8)
    ax.set_yscale("log")
    ax.set_xticks(x, [f"{r['scene']}\n{r['ratio_meaning']}" for r in rr], fontsize=7, rotation=30, ha="right")
    ax.set_ylabel("time ratio (> 1: contact_sim slower)")
    ax.set_title("contact_sim against its peers, one process, engines taking turns", fontsize=9)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def versions():
    out = []
    for pkg in ("numpy", "numba", "pybullet", "mujoco"):
        try:
            out.append(f"{pkg} {importlib.metadata.version(pkg)}")
        except importlib.metadata.PackageNotFoundError:
            out.append(f"{pkg} absent")
    return ", ".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a short smoke run (small pile, short runs, few repeats)")
    ap.add_argument("--rows", default="pile,stack,resting,rotation", help="comma-separated subset")
    ap.add_argument("--seconds", type=float, default=None,
                    help="simulated seconds of the pile and the stack (default 2 and 5, as specified)")
    ap.add_argument("--out", default=os.path.join(HERE, "results"), help="folder for the CSV and PNG")
    ap.add_argument("--variants", nargs="*", default=[], metavar="METHOD:ITERATIONS",
                    help="extra contact_sim-only runs of the pile with the solver forced, e.g. gs:10 jacobi:20")
    ap.add_argument("--peers", default=None,
                    help="comma-separated subset of the peers (pybullet, MuJoCo); default every one installed "
                         "(MuJoCo's dense Newton solve takes ~15 minutes on the 1000-sphere pile)")
    args = ap.parse_args(argv)
    q = args.quick
    side = 4 if q else 10
    pile_s, stack_s = (0.4, 0.25) if q else (2.0, 5.0)
    if args.seconds is not None:
        pile_s = stack_s = args.seconds
    settle, rounds, block = (10, 2, 5) if q else (100, 40, 10)
    rest_rounds = 2 if q else 200   # a resting step is ~0.1 ms: many rounds for a steady ratio
    peers, missing = re_.available_peers()
    for name, why in missing.items():
        print(f"{name} left out: {why}")
    if args.peers is not None:
        keep = {p.strip().lower() for p in args.peers.split(",") if p.strip()}
        peers = [p for p in peers if p.lower() in keep]
    names = ["contact_sim"] + peers
    print(f"engines: {', '.join(names)} ({versions()}); load average {load()}", flush=True)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # preflight warnings of the engine are not the benchmark's business
        wanted = args.rows.split(",")
        unknown = set(wanted) - {"pile", "stack", "resting", "rotation"}
        if unknown:
            ap.error(f"--rows: unknown {sorted(unknown)}")
        if "pile" in wanted:
            rows += row_pile(names, side, pile_s, 12)
        if "stack" in wanted:
            rows += row_stack(names, stack_s, 24, 1 if q else 3)
        if "resting" in wanted:
            rows += row_resting(names, 10, settle, rest_rounds, block)
            rows += row_resting(names, 100, settle, rest_rounds, block)
        if "rotation" in wanted:
            rows += row_rotation(rounds, block)
        for v in args.variants:
            rows.append(row_variant(v, side, pile_s, 12))
    print_table(rows)
    os.makedirs(args.out, exist_ok=True)
    stem = os.path.join(args.out, "response_peers" + ("_quick" if q else ""))
    write_csv(rows, stem + ".csv")
    png = plot(rows, stem + ".png")
    print(f"wrote {stem}.csv" + (f" and {png}" if png else "") + f"; load average {load()}")
    return rows


if __name__ == "__main__":
    main()
