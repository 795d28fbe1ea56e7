"""Response benchmark: contact_sim beside pybullet and MuJoCo, one process, engines taking turns.

The machine (2 cores, shared) drifts by 2× in absolute speed, so every row builds the same scene
in each engine and steps them in alternation and reports RATIOS (contact_sim's time ÷ the peer's).
Penetration, escapes, drift and bounce heights are computed in numpy from each engine's poses, the
same way for all (``response_engines.max_penetration``), never from an engine's own contact report.

    .venv/bin/python bench/bench_response.py [--quick] [--rows ball,spheres,resting,stack,pile,rotation]
                                             [--seconds S] [--peers pybullet,MuJoCo] [--pile-peers ...]
                                             [--out DIR] [--variants gs:20 ...] [--replot]

Prints a table, writes ``response_peers.csv`` and ``response_peers.png`` (bar chart of the
ratios) to bench/results/ (``--quick``: ``response_peers_quick.*``; ``--out`` another folder).
``make bench`` runs it; ``bench/report.py`` puts the table in docs/benchmarks.md.

The timing protocol, the same for every engine and row:

* Engines take turns, the order rotated every round; each turn is one BLOCK of steps, timed whole:
  one ``perf_counter`` pair around a plain Python loop over the engine's own step call, bound
  once (``world.step()``; ``stepSimulation(physicsClientId=cid)``; ``mj_step(m, d)``), nothing
  else in the loop (``response_engines.Engine.run_block``). Statistics (contact_sim's contact
  count, iterations, detection time) are read after the block, untimed, from its last step.
* ``step_ms`` is the p50 over blocks of the block's time per step; ``ratio`` the median over
  rounds of contact_sim's block time ÷ the peer's in the same round (timed within the same
  second, which cancels the machine's drift); ``ratio_of_medians`` the ratio of the two
  ``step_ms``; for the runs (ball, stack, pile) ``wall_s_per_sim_s`` and ``ratio_of_totals`` from
  the whole runs' block times.
* Blocks are 48–100 steps for the small scenes (12 for the pile, 24 for the stack — each a
  long block already), every engine's kernels and caches warmed before timing: contact_sim's
  kernels loaded (``contact_sim.warmup``), each run preceded by an untimed throwaway build and
  block, each resting scene settled 1 s untimed.
* Why (``bench/response_protocol.py``, ``bench/results/response_protocol.csv``): the old protocol
  timed every step alone in turns of 10 and reported pybullet's resting_10 at ~0.027–0.032 ms a
  step where plain loops took 0.013–0.023. The protocol was not the cause: a ``perf_counter``
  pair costs 0.09 µs; per-step timing and a plain loop gave 0.0269 and 0.0272 ms; in turns with
  contact_sim, blocks of 10, 100 and 500 steps gave 0.0147, 0.0150 and 0.0149 ms (the
  btRigidBody configuration; contact_sim 0.078–0.080 in all). The causes were pybullet's
  configuration and the window timed. ``createMultiBody``'s default makes every body a
  Featherstone multibody: 0.0272 ms, against 0.0221 with the dynamic bodies
  ``useMaximalCoordinates=True`` and 0.0148 with every body so (btRigidBodies, Bullet's
  rigid-body solver). And with a multibody in the scene the resting cost changes as the bodies
  settle: fresh builds of resting_10 step at 0.018–0.019 ms for the first 3 s and 0.026 from the
  fourth second on (resting_100 0.180 → 0.256), so a short plain loop on a fresh build timed the
  cheap phase and bench_response's window (after 1 s, 20 s long) the other; as btRigidBodies the
  step is flat at 0.014 ms. So pybullet now runs as btRigidBodies, the blocks are timed whole
  (the same overhead for every engine, none per step) and the resting window is unchanged.

The scenes, exactly:

1. ``ball_1``: one sphere, radius 0.1 m, 1 kg, dropped from rest with its centre at 1 m onto the
   plane z = 0, e 0.9 (0.9 keeps it bouncing through the run), μ
   0.5, dt 1/240, 4 s (960 steps), contact_sim with ``toi: next_step``; blocks of 48, median of 5
   fresh runs. Reported also: the first three bounce apexes (centre height) from a separate
   untimed run reading the pose every step (exact 0.829, 0.690, 0.590 m).
2. ``spheres_10``: 10 spheres r 0.1 m, 1 kg, on the plane z = 0 on resting_10's grid (4×4 cells
   0.5 m apart, row-major), resting at z = 0.1; μ 0.5, e 0, dt 0.01; protocol of row 4.
3. ``pile_1000``, the jittered sphere pile: 1000 spheres, radius 0.05 m, mass 0.1 kg, start on a
   10×10×10 grid of 0.12 m spacing centred on x = y = 0, lowest layer's centres at z = 0.5 m,
   each coordinate jittered by U(−0.01, 0.01) m (``numpy.random.default_rng(0)``, one
   ``uniform(size=(1000, 3))`` call, grid order x, y, z). Ground: the plane z = 0. Four static
   boxes 0.1 m thick and 2 m high (z 0 to 2) whose inner faces are at x = ±0.7 and y = ±0.7
   (a 1.4 × 1.4 m area centred on the grid; the x walls 1.6 m long, the y walls 1.4 m).
   μ 0.5, e 0, gravity −9.81 z, dt 1/240, 2 s (480 steps), blocks of 12 steps, one run. Reported:
   wall s per simulated s, final maximum penetration (deepest sphere–sphere, sphere–ground or
   sphere–wall overlap at the final poses) and spheres escaped (centre outside |x|, |y| ≤ 0.7 or
   below z = 0).
4. ``stack_10``: ten 0.2 m cubes of 1 kg stacked exactly touching (centres at z = 0.1 + 0.2 i) on
   the plane z = 0, μ 0.6, e 0, dt 1/240, 5 s (1200 steps), blocks of 24, 3 fresh runs.
   Reported: wall s per simulated s, top box drift (distance of its final centre from its start)
   and final maximum penetration (box–box by the 15-axis separating-axis overlap, box–ground by
   the lowest corner).
5. ``resting_10`` and ``resting_100``: 10 (100) bodies on the plane z = 0, alternately spheres
   (r 0.1 m) and boxes (0.2 m cubes), 1 kg each, on a square grid 0.5 m apart (4×4 and 10×10
   cells, row-major), resting at z = 0.1; μ 0.5, e 0, dt 0.01. Settled for 1 s (untimed), then
   60 rounds of one block of 100 steps per engine. For contact_sim also its detection run alone
   (``detect_ms``: the block's last state detected once more after the block, ``detect_seconds``,
   median). It is no share of the step: a step runs its detection inside the sub-step's compiled
   call, without the Python a detection alone pays (``bench/step_anatomy.py`` splits the step).
6. ``rotation``: a 1 × 0.05 × 0.05 m rod of 1 kg spinning end over end (ω = 7 rad/s about the
   world y axis, a transverse principal axis) in free flight, no gravity, dt 1/60; and a 0.2 m
   cube of 1 kg with the same spin. contact_sim only, the two taking turns: 40 rounds of blocks
   of 50 steps, ratio rod ÷ cube (target ≤ 1).

The step-time targets (contact_sim ÷ peer, p50 step, at most; the ``target`` column): ball_1 3×,
spheres_10 2×, resting_10 2× and resting_100 1× against pybullet; stack_10 2× against MuJoCo;
pile_1000 1× against pybullet.

Each engine runs on its own terms (see ``response_engines``): contact_sim with its defaults (only
dt set, and ``toi`` for the ball; its ``auto`` models), pybullet with every body a btRigidBody
(``useMaximalCoordinates=True``, its fastest way for free rigid bodies), otherwise its defaults
(50 iterations) but damping 0 and restitution threshold 0, with √μ and √e per body (product
rule), MuJoCo with its defaults (Newton, 100 iterations, pyramidal cone, soft contacts, no
restitution: its ball does not bounce) and friction μ per geom (max rule). The settings each ran
with are printed and written to the CSV.

``--quick`` (smoke test, ~15 s): the ball for 0.5 s, a 4×4×4 pile for 0.4 s, the stack for 0.25 s,
2 rounds of blocks of 5 resting and rotation steps after 0.1 s of settling — it checks the
machinery, not the speed.
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

def detect_seconds(world):
    """Seconds of one detection of ``world``'s state as a step detects it (no edge–face census,
    the stages untimed), run alone after the block: a step's detection shares its compiled call
    with the sub-step's stages, whose seconds are of both (``DetectionStats.seconds``)."""
    from contact_sim.collision import detect_world

    t = time.perf_counter()
    detect_world(world, timed=False, census=False)
    return time.perf_counter() - t


FIELDS = ["scene", "engine", "bodies", "dt", "steps", "repeats", "block", "wall_s_per_sim_s", "step_ms", "detect_ms",
          "ratio", "ratio_meaning", "ratio_of_medians", "ratio_of_totals", "target", "max_penetration_mm",
          "escaped", "top_drift_mm", "apex_m", "contacts_per_step", "solver_iterations", "load_1min", "settings"]
# the step-time targets: contact_sim's p50 step time ÷ the peer's, at most
TARGETS = {("ball_1", "pybullet"): 3.0, ("spheres_10", "pybullet"): 2.0, ("resting_10", "pybullet"): 2.0,
           ("resting_100", "pybullet"): 1.0, ("stack_10", "MuJoCo"): 2.0, ("pile_1000", "pybullet"): 1.0}
WALL_INNER = 0.7


# ---------------------------------------------------------------------------- scenes
def pile_scene(side=10, seed=0):
    """Row 1: the jittered sphere pile (``side``³ spheres; side 10 in the table)."""
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


def resting_scene(n, shapes=("sphere", "box")):
    """Row 3: ``n`` bodies resting on the plane, alternately spheres r 0.1 and 0.2 m cubes, 0.5 m apart."""
    side = math.ceil(math.sqrt(n))
    bodies = [Body("ground", "plane", None)]
    for i in range(n):
        r, c = divmod(i, side)
        shape = shapes[i % len(shapes)]
        size = 0.1 if shape == "sphere" else (0.2, 0.2, 0.2)
        bodies.append(Body(f"b{i}", shape, size, mass=1.0, position=(0.5 * c, 0.5 * r, 0.1)))
    return Scene(f"resting_{n}", bodies, dt=0.01, friction=0.5, restitution=0.0)


def ball_scene():
    """``ball_1``: one 0.1 m, 1 kg sphere dropped from rest at 1 m (centre height) onto the plane,
    e 0.9, μ 0.5, dt 1/240; contact_sim with ``toi: next_step``."""
    bodies = [Body("ground", "plane", None), Body("ball", "sphere", 0.1, mass=1.0, position=(0.0, 0.0, 1.0))]
    return Scene("ball_1", bodies, dt=1 / 240, friction=0.5, restitution=0.9,
                 contact_sim_settings={"toi": "next_step"})


def spheres_scene(n=10):
    """``spheres_10``: ``n`` spheres r 0.1 m, 1 kg, resting on the plane 0.5 m apart (resting's grid)."""
    scene = resting_scene(n, shapes=("sphere",))
    scene.name = f"spheres_{n}"
    return scene


def rotation_scene(size):
    """Row 4: one box of edge lengths ``size``, 1 kg, ω = 7 rad/s about y, no gravity, dt 1/60."""
    return Scene("rod" if size[0] != size[1] else "cube",
                 [Body("body", "box", size, mass=1.0, angular_velocity=(0.0, 7.0, 0.0))],
                 dt=1 / 60, gravity=(0.0, 0.0, 0.0), friction=0.5, restitution=0.0)


SCENES = {"ball_1": ball_scene, "spheres_10": spheres_scene, "resting_10": lambda: resting_scene(10),
          "resting_100": lambda: resting_scene(100), "stack_10": stack_scene, "pile_1000": pile_scene}


# ---------------------------------------------------------------------------- protocols
def rotated(items, k):
    k %= len(items)
    return items[k:] + items[:k]


def load():
    return round(os.getloadavg()[0], 2)


class Turns:
    """Block times of engines stepped in turns: ``per_step[name]`` (seconds per step of each block,
    rounds aligned across engines), ``total[name]`` (wall seconds of all blocks of each repeat)."""

    def __init__(self, names):
        self.per_step = {n: [] for n in names}
        self.total = {n: [] for n in names}
        self.detect = {n: [] for n in names}


def take_turns(engines, steps, block, turns, progress_label=None):
    """Step ``engines`` ``steps`` steps each, in turns of one block of ``block`` steps per engine
    (the order rotated every round), each block timed whole by the engine's ``run_block`` (a
    plain loop over its step call). Appends to ``turns``; after each block, untimed, the engine's
    ``after_step`` reads its statistics of the block's last step."""
    wall = dict.fromkeys((e.name for e in engines), 0.0)
    done, rnd, t_print = 0, 0, time.perf_counter()
    while done < steps:
        n = min(block, steps - done)
        for e in rotated(engines, rnd):
            t = e.run_block(n)
            wall[e.name] += t
            turns.per_step[e.name].append(t / n)
            e.after_step()
            if isinstance(e, ContactSimEngine):
                turns.detect[e.name].append(detect_seconds(e.world))
        done += n
        rnd += 1
        if progress_label and time.perf_counter() - t_print > 10:
            t_print = time.perf_counter()
            print(f"  {progress_label}: {done}/{steps} steps, " + ", ".join(f"{k} {v:.1f} s" for k, v in wall.items()),
                  file=sys.stderr, flush=True)
    for k, v in wall.items():
        turns.total[k].append(v)
    return turns


def run_fresh(scene, names, steps, block, repeats):
    """The runs (ball, stack, pile): ``repeats`` fresh builds of the scene, each stepped ``steps``
    steps from its start in turns of ``block``. Returns the ``Turns`` and the last run's engines."""
    turns, last = Turns(names), {}
    for n in names:   # untimed: a throwaway build and block, so that no repeat pays first-use costs
        ENGINES[n](scene).run_block(block)
    for rep in range(repeats):
        engines = [ENGINES[n](scene) for n in names]
        take_turns(engines, steps, block, turns, f"{scene.name} repeat {rep + 1}/{repeats}")
        for e in last.values():
            e.close()
        last = {e.name: e for e in engines}
    return turns, last


def run_steady(scene, names, settle, rounds, block):
    """The resting scenes: one build, ``settle`` steps untimed, then ``rounds`` turns of ``block``."""
    engines = [ENGINES[n](scene) for n in names]
    for e in engines:
        e.run_block(settle)
    turns = take_turns(engines, rounds * block, block, Turns(names), scene.name)
    return turns, {e.name: e for e in engines}


def base_row(scene, engine, steps, repeats=1, block=None):
    return {"scene": scene.name, "engine": engine.name, "bodies": len(scene.bodies), "dt": scene.dt, "steps": steps,
            "repeats": repeats, "block": block, "settings": engine.settings(), "load_1min": load()}


def cs_stats(e, row):
    if isinstance(e, ContactSimEngine):
        row["contacts_per_step"] = float(np.nanmean(e.contacts)) if e.contacts else ""
        row["solver_iterations"] = float(np.nanmean(e.iterations)) if e.iterations else ""


def timing(turns, name, row, sim_seconds=None):
    """The row's times from its blocks: ``step_ms`` the median block's time per step (p50),
    ``wall_s_per_sim_s`` the whole run's (runs only), contact_sim's detection run alone."""
    t = np.array(turns.per_step[name])
    row["step_ms"] = 1e3 * float(np.median(t))
    if sim_seconds:
        row["wall_s_per_sim_s"] = float(np.median(turns.total[name])) / sim_seconds
    d = np.array(turns.detect[name])
    if d.size and np.isfinite(d).any():
        row["detect_ms"] = 1e3 * float(np.nanmedian(d))


def add_ratios(rows, turns):
    """On each peer's row: ``ratio`` = the median over rounds of contact_sim's block time ÷ the
    peer's block time in the same round (both timed within the same second, which cancels the
    machine's drift); ``ratio_of_medians`` = the ratio of the two ``step_ms``; ``ratio_of_totals``
    = the ratio of the whole runs' wall times (runs only)."""
    cs = next(r for r in rows if r["engine"] == "contact_sim")
    a = np.array(turns.per_step["contact_sim"])
    for r in rows:
        if r is cs:
            continue
        b = np.array(turns.per_step[r["engine"]])
        r["ratio"] = float(np.median(a / b))
        r["ratio_meaning"] = f"contact_sim ÷ {r['engine']}"
        r["ratio_of_medians"] = cs["step_ms"] / r["step_ms"]
        if r.get("wall_s_per_sim_s", "") != "":
            r["ratio_of_totals"] = cs["wall_s_per_sim_s"] / r["wall_s_per_sim_s"]
    return rows


# ---------------------------------------------------------------------------- rows
def ball_apexes(name, scene, steps):
    """The ball's centre heights at the tops of its bounces, from a separate untimed run reading
    its pose every step (exact for e 0.9 from 1 m: 0.1 + 0.9 e^2k, i.e. 0.829, 0.690, 0.590)."""
    e = ENGINES[name](scene)
    z = []
    for _ in range(steps):
        e.step()
        z.append(e.poses()[0][0, 2])
    e.close()
    return [z[i] for i in range(1, len(z) - 1) if z[i - 1] < z[i] >= z[i + 1] and z[i] > 0.101]


def row_ball(names, seconds, block, repeats):
    scene = ball_scene()
    steps = int(round(seconds / scene.dt))
    turns, engines = run_fresh(scene, names, steps, block, repeats)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        row = base_row(scene, e, steps, repeats, block)
        timing(turns, n, row, steps * scene.dt)
        row.update(max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q),
                   apex_m=" / ".join(f"{h:.3f}" for h in ball_apexes(n, scene, steps)[:3]) or "no bounce")
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows, turns)


def row_pile(names, side, seconds, block):
    scene = pile_scene(side)
    steps = int(round(seconds / scene.dt))
    turns, engines = run_fresh(scene, names, steps, block, 1)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        out = (np.abs(pos[:, 0]) > WALL_INNER) | (np.abs(pos[:, 1]) > WALL_INNER) | (pos[:, 2] < 0)
        row = base_row(scene, e, steps, 1, block)
        timing(turns, n, row, steps * scene.dt)
        row.update(max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q), escaped=int(out.sum()))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows, turns)


def row_stack(names, seconds, block, repeats):
    scene = stack_scene()
    steps = int(round(seconds / scene.dt))
    turns, engines = run_fresh(scene, names, steps, block, repeats)
    top0 = np.array(scene.dynamic[-1].position)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        row = base_row(scene, e, steps, repeats, block)
        timing(turns, n, row, steps * scene.dt)
        row.update(max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q),
                   top_drift_mm=1e3 * float(np.linalg.norm(pos[-1] - top0)))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows, turns)


def row_resting(names, scene, settle, rounds, block):
    turns, engines = run_steady(scene, names, settle, rounds, block)
    rows = []
    for n in names:
        e = engines[n]
        pos, q = e.poses()
        row = base_row(scene, e, rounds * block, 1, block)
        timing(turns, n, row)
        row.update(max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q))
        cs_stats(e, row)
        rows.append(row)
        e.close()
    return add_ratios(rows, turns)


def row_rotation(rounds, block):
    rod, cube = rotation_scene((1.0, 0.05, 0.05)), rotation_scene((0.2, 0.2, 0.2))
    engines = [ContactSimEngine(rod), ContactSimEngine(cube)]
    engines[1].name = "contact_sim cube"
    turns = take_turns(engines, rounds * block, block, Turns([e.name for e in engines]))
    rows = []
    for scene, e in zip((rod, cube), engines):
        row = base_row(scene, e, rounds * block, 1, block)
        timing(turns, e.name, row)
        row.update(scene=f"rotation_{scene.name}", engine="contact_sim")
        rows.append(row)
        e.close()
    a, b = (np.array(turns.per_step[e.name]) for e in engines)
    rows[0].update(ratio=float(np.median(a / b)), ratio_of_medians=rows[0]["step_ms"] / rows[1]["step_ms"],
                   ratio_meaning="rod ÷ cube (contact_sim)")
    return rows


def row_variant(spec, side, seconds, block):
    """contact_sim alone on the pile with the solver forced (``METHOD:ITERATIONS``, e.g. ``gs:20``,
    ``jacobi:20``): the speed/penetration trade-off, through ``settings.solver_method`` and
    ``settings.solver_iterations``."""
    method, iters = spec.split(":")[:2]
    scene = pile_scene(side)
    scene.contact_sim_settings = {"solver_iterations": int(iters), "solver_method": method}
    scene.name = f"{scene.name}_{method}{iters}"
    steps = int(round(seconds / scene.dt))
    turns, engines = run_fresh(scene, ["contact_sim"], steps, block, 1)
    e = engines["contact_sim"]
    pos, q = e.poses()
    out = (np.abs(pos[:, 0]) > WALL_INNER) | (np.abs(pos[:, 1]) > WALL_INNER) | (pos[:, 2] < 0)
    row = base_row(scene, e, steps, 1, block)
    timing(turns, "contact_sim", row, steps * scene.dt)
    row.update(max_penetration_mm=1e3 * re_.max_penetration(scene, pos, q), escaped=int(out.sum()))
    cs_stats(e, row)
    return row


# ---------------------------------------------------------------------------- output
def fmt(x, spec):
    return "" if x in ("", None) or (isinstance(x, float) and np.isnan(x)) else format(x, spec)


def print_table(rows):
    head = (f"{'scene':<18} {'engine':<12} {'s/sim s':>8} {'step ms':>8} {'ratio':>8}  {'meaning':<22} "
            f"{'pen mm':>9} {'escaped':>7} {'drift mm':>9} {'detect ms':>9} {'contacts':>8} {'iters':>6}")
    print("\n" + head + "\n" + "-" * len(head))
    for r in rows:
        print(f"{r['scene']:<18} {r['engine']:<12} {fmt(r.get('wall_s_per_sim_s'), '8.3f'):>8} "
              f"{fmt(r.get('step_ms'), '8.3f'):>8} {fmt(r.get('ratio'), '8.2f'):>8}  {r.get('ratio_meaning', ''):<22} "
              f"{fmt(r.get('max_penetration_mm'), '9.3g'):>9} {fmt(r.get('escaped'), 'd'):>7} "
              f"{fmt(r.get('top_drift_mm'), '9.3g'):>9} {fmt(r.get('detect_ms'), '9.3f'):>9} "
              f"{fmt(r.get('contacts_per_step'), '8.0f'):>8} "
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
    tx = [(xi, r["target"]) for xi, r in zip(x, rr) if r.get("target", "") != ""]
    if tx:   # the step-time targets: a red dash on the bar
        ax.scatter([t[0] for t in tx], [t[1] for t in tx], marker="_", s=400, color="red", zorder=3,
                   label="target (at most)")
        ax.legend(fontsize=7, loc="upper right")
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


ROWS = ("ball", "spheres", "resting", "stack", "pile", "rotation")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a short smoke run (small pile, short runs, few repeats)")
    ap.add_argument("--rows", default=",".join(ROWS), help=f"comma-separated subset of {', '.join(ROWS)}")
    ap.add_argument("--seconds", type=float, default=None,
                    help="simulated seconds of the pile and the stack (default 2 and 5, as specified)")
    ap.add_argument("--pile-peers", default=None,
                    help="peers on the pile (default: the same as --peers); MuJoCo's dense Newton solve takes "
                         "~5 minutes of the run there")
    ap.add_argument("--out", default=os.path.join(HERE, "results"), help="folder for the CSV and PNG")
    ap.add_argument("--variants", nargs="*", default=[], metavar="METHOD:ITERATIONS",
                    help="extra contact_sim-only runs of the pile with the solver forced, e.g. gs:10 jacobi:20")
    ap.add_argument("--peers", default=None,
                    help="comma-separated subset of the peers (pybullet, MuJoCo); default every one installed")
    ap.add_argument("--replot", action="store_true", help="only redraw the PNG from the CSV already in --out")
    args = ap.parse_args(argv)
    q = args.quick
    stem = os.path.join(args.out, "response_peers" + ("_quick" if q else ""))
    if args.replot:
        with open(stem + ".csv", newline="") as fh:
            rows = [{k: (float(v) if k in ("ratio", "target") and v else v) for k, v in r.items()}
                    for r in csv.DictReader(fh)]
        print(f"wrote {plot(rows, stem + '.png')}")
        return rows
    side = 4 if q else 10
    pile_s, stack_s = (0.4, 0.25) if q else (2.0, 5.0)
    if args.seconds is not None:
        pile_s = stack_s = args.seconds
    # (seconds, block, repeats) of the ball; (settle, rounds, block) of the resting scenes and the rotation
    ball = (0.5, 12, 1) if q else (4.0, 48, 5)
    rest = (10, 2, 5) if q else (100, 60, 100)
    rot = (0, 2, 5) if q else (0, 40, 50)
    peers, missing = re_.available_peers()
    for name, why in missing.items():
        print(f"{name} left out: {why}")

    def pick(spec):
        if spec is None:
            return peers
        keep = {p.strip().lower() for p in spec.split(",") if p.strip()}
        return [p for p in peers if p.lower() in keep]

    names = ["contact_sim"] + pick(args.peers)
    pile_names = ["contact_sim"] + [p for p in pick(args.pile_peers) if p in names]
    print(f"engines: {', '.join(names)} ({versions()}); load average {load()}", flush=True)
    from contact_sim.warmup import warm_up

    print(f"contact_sim kernels loaded in {warm_up():.1f} s (untimed)", flush=True)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # preflight warnings of the engine are not the benchmark's business
        wanted = args.rows.split(",")
        unknown = set(wanted) - set(ROWS)
        if unknown:
            ap.error(f"--rows: unknown {sorted(unknown)}")
        if "ball" in wanted:
            rows += row_ball(names, *ball)
        if "spheres" in wanted:
            rows += row_resting(names, spheres_scene(10), *rest)
        if "resting" in wanted:
            rows += row_resting(names, resting_scene(10), *rest)
            rows += row_resting(names, resting_scene(100), *rest)
        if "stack" in wanted:
            rows += row_stack(names, stack_s, 24, 1 if q else 3)
        if "pile" in wanted:
            rows += row_pile(pile_names, side, pile_s, 12)
        if "rotation" in wanted:
            rows += row_rotation(*rot[1:])
        for v in args.variants:
            rows.append(row_variant(v, side, pile_s, 12))
    for r in rows:
        if (r["scene"], r["engine"]) in TARGETS:
            r["target"] = TARGETS[r["scene"], r["engine"]]
    print_table(rows)
    os.makedirs(args.out, exist_ok=True)
    write_csv(rows, stem + ".csv")
    png = plot(rows, stem + ".png")
    print(f"wrote {stem}.csv" + (f" and {png}" if png else "") + f"; load average {load()}")
    return rows


if __name__ == "__main__":
    main()
