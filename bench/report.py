"""Rewrite the "Measured results" block of docs/benchmarks.md from the benchmark results in bench/results/.

    python bench/report.py        # after `make bench`; also prints the block

The block sits between the markers ``<!-- results:begin -->`` and ``<!-- results:end -->``; every
number in it comes from a CSV written by a benchmark, with the machine load at the time noted by
the benchmark run itself (2 cores here, shared with whatever else runs).
"""
import csv
import os
import platform
import re

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results")
# the documentation page that holds the block; charts are linked from it as ../bench/results/NAME.png
# (the docs site serves them through docs/hooks/mkdocs_hooks.py)
PAGE = os.path.join(os.path.dirname(HERE), "docs", "benchmarks.md")
CHARTS = "../bench/results/"
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"


def rows(name):
    path = os.path.join(RESULTS, name)
    if not os.path.isfile(path):
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def write_rows(path, table):
    """Write ``table`` (dicts with the same keys, in column order) as CSV at ``path``, making its
    folder: the benchmarks' writer, beside ``rows``, the reader. Returns ``path``."""
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    return path


def table(columns, cells):
    """A markdown table: the header ``columns`` and one row per list of cell strings in ``cells``."""
    return (["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
            + ["| " + " | ".join(row) + " |" for row in cells])


def f(x, fmt):
    try:
        return format(float(x), fmt)
    except (TypeError, ValueError):
        return "–"


def detection():
    r = rows("detect.csv")
    if not r:
        return []
    out = ["### Detection (`bench/bench_detect.py`)", "",
           "500 mixed bodies (a third each spheres, boxes, 32-point hulls), one process, engines taking turns on the "
           "same poses; warm = the query repeated (median), cold = the first query after building the world "
           "(contact_sim: after `load_scene`, shape preparation included; median of 5 fresh builds). FCL = python-fcl's dynamic AABB tree on "
           "primitives, every colliding pair.", ""]
    out += table(["scene", "touching pairs", "contact_sim warm ms", "MuJoCo", "FCL", "FCL + contacts", "pybullet",
                  "trimesh (FCL meshes)", "contact_sim cold ms", "ours / FCL warm, taking turns",
                  "ours / MuJoCo", "ours / pybullet"],
                 [[x["scene"], x["touching_pairs"], f(x["ours_warm_ms"], ".3f"), f(x.get("mujoco_warm_ms"), ".3f"),
                   f(x.get("fcl_warm_ms"), ".3f"), f(x.get("fcl+contacts_warm_ms"), ".3f"),
                   f(x.get("pybullet_warm_ms"), ".3f"), f(x.get("trimesh_warm_ms"), ".3f"), f(x["ours_cold_ms"], ".1f"),
                   f(x.get("ours_over_fcl_warm"), ".2f"), f(x.get("ours_over_mujoco_warm"), ".2f"),
                   f(x.get("ours_over_pybullet_warm"), ".2f")] for x in r])
    s = rows("detect_scale.csv")
    if s:
        out += ["", f"Scale (the 6 m scene's density), warm ms; fitted exponent t ∝ n^k: contact_sim "
                    f"{f(s[0].get('fitted_exponent'), '.2f')}, FCL {f(s[0].get('fcl_fitted_exponent'), '.2f')}.", ""]
        out += table(["bodies", "touching pairs", "contact_sim ms", "FCL ms", "ours / FCL, taking turns"],
                     [[x["bodies"], x["touching_pairs"], f(x["ours_warm_ms"], ".3f"), f(x["fcl_warm_ms"], ".3f"),
                       f(x["ours_over_fcl"], ".2f")] for x in s])
    return out + [""]


def response():
    r = rows("response_peers.csv")
    if not r:
        return []
    out = ["### Contact response against pybullet and MuJoCo (`bench/bench_response.py`)", "",
           "Each scene built from one description in every engine, stepped in one process with the engines "
           "taking turns, order rotated each round; each turn one block of steps timed whole (a plain loop over "
           "the engine's own step call: `world.step`, `stepSimulation`, `mj_step`), the same overhead for every "
           "engine. Step ms = the p50 over blocks of the time per step; ratio = the median over rounds of "
           "contact_sim's block time ÷ the peer's in the same round (> 1: contact_sim slower). pybullet runs "
           "every body as a btRigidBody (`useMaximalCoordinates=True`), its fastest configuration for free rigid "
           "bodies (why, and what it changes: the docstrings of `bench/bench_response.py` and "
           "`bench/response_engines.py`, the numbers in `bench/results/response_protocol.csv`). Penetration, "
           "escapes, drift and bounce apexes are computed from each engine's poses in numpy, the same way for all. "
           "Scene specifications: the docstring of `bench/bench_response.py`.", ""]
    targets = [x for x in r if x.get("target")]
    if targets:
        out += ["The step-time targets (contact_sim ÷ peer, p50 step time; why the missed ones are missed: [known limits](limits.md)):", ""]
        cs = {x["scene"]: x for x in r if x["engine"] == "contact_sim"}
        out += table(["scene", "peer", "contact_sim ms", "peer ms", "ratio", "target", ""],
                     [[x["scene"], x["engine"], f(cs[x["scene"]]["step_ms"], ".3g"), f(x["step_ms"], ".3g"),
                       f(x["ratio"], ".3g"), f"≤ {f(x['target'], 'g')}",
                       "met" if float(x["ratio"]) <= float(x["target"]) else "missed"] for x in targets])
        out += [""]
    cells = []
    for x in r:
        ratio = f"{f(x['ratio'], '.3g')} ({x['ratio_meaning']})" if x.get("ratio") else ""
        split = f(x["detect_ms"], ".3f") if x.get("detect_ms") else ""
        cells.append([x["scene"], x["engine"], f(x["step_ms"], ".3g"), ratio, f(x["wall_s_per_sim_s"], ".3g"),
                      f(x.get("ratio_of_totals"), ".3g"), f(x["max_penetration_mm"], ".3g"), x["escaped"] or "–",
                      f(x["top_drift_mm"], ".3g"), x.get("apex_m") or "–", split or "–"])
    out += table(["scene", "engine", "step ms (p50)", "ratio", "wall s per simulated s", "ratio of totals",
                  "final max penetration mm", "escaped", "top drift mm", "bounce apexes m",
                  "contact_sim detection run alone ms"], cells)
    out += ["", "Settings each engine ran with:", ""]
    scenes = {}
    for x in r:   # one line per engine and settings, naming the scenes that ran with them
        scenes.setdefault((x["engine"], x["settings"]), []).append(x["scene"])
    out += [f"- {e} ({', '.join(dict.fromkeys(sc))}): {st}" for (e, st), sc in scenes.items()]
    if os.path.isfile(os.path.join(RESULTS, "response_peers.png")):
        out += ["", f"![response ratios]({CHARTS}response_peers.png)"]
    return out + [""] + anatomy() + response_protocol()


def anatomy():
    """Where a step's time goes, from ``bench/step_anatomy.py``'s CSV."""
    r = rows("step_anatomy.csv")
    if not r:
        return []
    unit = {k: r[0][f"unit_{k}_ns"] for k in ("call", "array", "scalar", "returned", "alloc")}

    def share(x, part):
        return f"{f(x[part], '.1f')} ({f(100 * float(x[part]) / float(x['step_us']), '.0f')} %)"

    out = ["#### Where a step's time goes (`bench/step_anatomy.py`)", "",
           "The response scenes' step split three ways: the Python between the compiled calls (glue), the calls' "
           "boundary (numba unboxing each argument and boxing each array handed back, from the unit costs measured "
           "first), and the compiled kernels. `World.step` is timed, then stepped again with every compiled "
           "function Python calls recording its arguments, and each call is replayed alone (µs a step over "
           f"{r[0].get('steps', '?')} steps after 300 to settle):", ""]
    out += table(["scene", "step", "glue", "boundary", "kernels", "calls / arguments / arrays back a step",
                  "kernels ÷ the peer's step"],
                 [[x["scene"], f(x["step_us"], ".1f"), share(x, "glue_us"), share(x, "boundary_us"),
                   share(x, "kernels_us"), f"{f(x['calls_per_step'], '.1f')} / {f(x['args_per_step'], '.0f')} / "
                   f"{f(x['arrays_back_per_step'], '.1f')}", f"{f(x['kernels_over_peer'], '.2f')} ({x['peer']})"]
                  for x in r])
    out += ["", f"Unit costs on this machine: a call {f(unit['call'], '.0f')} ns, an array argument "
                f"{f(unit['array'], '.0f')}, a scalar {f(unit['scalar'], '.0f')}, an array handed back "
                f"{f(unit['returned'], '.0f')} (numba finds the array's Python type through a pickle, per array), an "
                f"allocation inside compiled code {f(unit['alloc'], '.0f')}. The last column is the step's kernels "
                "alone against the peer's whole step (its last run in `response_peers.csv`): what a step with no "
                "Python around its kernels and no boundary would reach with today's kernels. A call replayed alone "
                "finds its data in the cache: the glue also holds what the kernels lose to a colder cache inside the "
                "step, an upper bound on the Python's share.", ""]
    if all(x.get("glue_by_function") for x in r):
        out += ["The glue's largest parts by engine function (µs a step; a cProfile run's split scaled to the glue, "
                "indicative: cProfile inflates functions called often):", ""]
        out += [f"- {x['scene']}: {x['glue_by_function']}" for x in r] + [""]
    return out


def response_protocol():
    """Why pybullet timed slower in the old protocol, from ``bench/response_protocol.py``'s CSV."""
    r = rows("response_protocol.csv")
    if not r:
        return []
    out = ["#### Why blocks timed whole and pybullet as btRigidBodies (`bench/response_protocol.py`)", "",
           "The earlier protocol (every step timed alone, turns of 10 steps) reported pybullet's resting_10 at "
           "~0.03 ms a step where plain `stepSimulation` loops took 0.013–0.023. The protocol was not the cause: "
           "timed alone, per step or as a loop, or in turns of 10, 100 or 500 steps, pybullet's step costs the "
           "same (resting_10 after 1 s of settling, median of 5 repeats of 2000 steps):", ""]
    proto = [x for x in r if not x["protocol"].startswith("config:")]
    out += table(["measured (pybullet unless named)", "ms a step"],
                 [[x["protocol"].strip(), f(x["step_ms"], ".4f") if x["protocol"] != "perf_counter pair"
                   else f"{f(1e3 * float(x['step_ms']), '.3f')} µs"] for x in proto])
    cfg = [x for x in r if x["protocol"].startswith("config:")]
    if cfg:
        names = list(dict.fromkeys(x["protocol"][len("config: "):] for x in cfg))
        by = {(x["scene"], x["protocol"][len("config: "):]): x for x in cfg}
        out += ["", "The causes: pybullet's configuration (`createMultiBody`'s default makes every body a "
                    "Featherstone multibody; `useMaximalCoordinates=True` makes a btRigidBody), and the window: with a "
                    "multibody in the scene the resting step grows after ~3 s of rest, so a short loop on a fresh "
                    "build timed the cheap phase. Fresh builds stepped 10 s in blocks taking turns, median of 3; ms a "
                    "step over seconds 1–10, then each second from the build:", ""]
        out += table(["scene"] + names + [f"{n}, by second" for n in names[:1]],
                     [[sc] + [f(by[sc, n]["step_ms"], ".4f") for n in names] + [by[sc, names[0]].get("by_second_ms", "")]
                      for sc in dict.fromkeys(x["scene"] for x in cfg)])
    return out + [""]


def accuracy():
    path = os.path.join(RESULTS, "accuracy_summary.md")
    if not os.path.isfile(path):
        return []
    with open(path) as fh:
        table = fh.read().strip()
    charts = sorted(p for p in os.listdir(RESULTS) if p.startswith("accuracy_") and p.endswith(".png"))
    out = ["### Speed against error (`bench/bench_accuracy.py`)", "",
           "Relative error against the exact answer, cost in wall seconds per simulated second, step sizes "
           "1/30 to 1/2000 s. The cheapest run within each error level:", "", table, ""]
    out += [f"![{c[9:-4]}]({CHARTS}{c})" for c in charts]
    return out + [""]


def mesh_mesh():
    r = rows("mesh_mesh.csv")
    if not r:
        return []
    out = ["### Mesh–mesh (`bench/bench_mesh_mesh.py`)", "",
           "Two tori at 100 random poses within 2.4 m of each other (about 60 % intersect), median time of one `cs.collide` "
           "(contacts: points, normals, depths) with the per-mesh AABB tree and without it (one leaf holding "
           "every triangle), and python-fcl's BVH yes/no beside it; the verdicts agree.", ""]
    out += table(["triangles per mesh", "tree (ms)", "no tree (ms)", "python-fcl verdict (ms)"],
                 [[x["triangles"], f(x["tree_ms"], ".3f"), f(x["no_tree_ms"], ".3f"), f(x["fcl_ms"], ".3f")]
                  for x in r])
    return out + [""]


def single_pair():
    r = rows("collide.csv")
    if not r:
        return []
    out = ["### One pair, the stateless query (`bench/bench_collide.py`)", "",
           "`cs.collide` called in a loop (the pose given three ways), python-fcl's `collide` asking for up to "
           "4 contacts beside it, µs per call (median of rounds):", ""]
    out += table(["pair", "call", "µs per call", "contacts"],
                 [[x["pair"], x["call"], f(x["us_per_call"], ".2f"), x["contacts"]] for x in r])
    return out + [""]


def default_scene():
    r = rows("default_scene.csv")
    if not r:
        return []
    x0 = r[0]
    out = ["### The default scene (`bench/bench_default.py`)", "",
           f"The shipped scene (`config/scenes/default.yaml`, dt {x0['dt']} s) stepped from a fresh load for "
           f"{x0['seconds']} simulated s, kernels loaded beforehand; medians of {x0['repeats']} repeats. "
           "Target: ≤ 0.1 wall s per simulated s over the run, step p99 < 1 ms.", ""]
    out += table(["phase", "wall s per simulated s", "step p50 ms", "step p99 ms", "step max ms"],
                 [[x["phase"], f(x["wall_s_per_sim_s"], ".3f"), f(x["p50_ms"], ".3f"), f(x["p99_ms"], ".3f"),
                   f(x["max_ms"], ".2f")] for x in r])
    return out + [""]


def robot():
    r = rows("robot.csv")
    if not r:
        return []
    x0 = r[0]
    out = ["### Robot arm among static objects (`bench/bench_robot.py`)", "",
           f"A {x0['links']}-link arm of about {x0['triangles_per_link']}-triangle convex mesh links sweeping through "
           f"{x0['objects']} static boxes, spheres and cylinders at 100 Hz: each tick sets the joints, then steps "
           "the world (tick) or only detects (query); python-fcl checks the same poses as MoveIt does (BVH links, "
           "primitive objects, contact data):", ""]
    out += table(["measurement", "p50 ms", "p99 ms", "colliding pairs per tick"],
                 [[x["measurement"], f(x["p50_ms"], ".3f"), f(x["p99_ms"], ".3f"), x["colliding_pairs_per_tick"]]
                  for x in r])
    return out + [""]


def panda():
    r = rows("panda.csv")
    if not r:
        return []
    x0 = r[0]
    out = ["### A robot cell at 1 kHz (`bench/bench_panda.py`)", "",
           f"pybullet_data's Franka Panda (no package path; its collision meshes are their hulls but link6's) on a "
           f"floor beside a table with {x0['objects']} objects, its joints on sinusoids, 1 ms steps, "
           f"{x0['ticks']} ticks per measurement, the engines taking turns: the tick sets the joints (each its own "
           "stamp) and steps (what the node does per tick, without the messages), the query only detects; "
           "python-fcl checks the same link poses as MoveIt does. Contact rows from the base or between two "
           f"links over every tick: {x0['base_or_self_rows']} (excluded: touching at the initial configuration).", ""]
    out += table(["measurement", "p50 ms", "p99 ms", "max ms", "× python-fcl (median of rounds)"],
                 [[x["measurement"], f(x["p50_ms"], ".3f"), f(x["p99_ms"], ".3f"), f(x["max_ms"], ".2f"),
                   f(x["ratio_to_fcl"], ".2f")] for x in r])
    return out + [""]


def node_panda():
    r = rows("node_panda.csv")
    if not r:
        return []
    out = ["### The Panda cell through the node at 1 kHz (`bench/bench_node.py --panda`)", "",
           "`bench_panda`'s cell with the node in its own process: the scene file holds the floor, the table and "
           "the objects; the Panda arrives on `robot_description` as robot_state_publisher sends it (its meshes "
           "through the `package_paths` parameter) and its joints on `joint_states` at 1 kHz; one 1 ms step a tick. "
           "Tick statistics as below (the node's own, from `/diagnostics`), after a 2 s warm-up; joint states sent "
           "by the bench and received, accepted and refused by the node in the window (the node records each as it "
           "arrives, and each tick poses the links, driving them to the newest: that posing, ~0.06 ms for the Panda, "
           "is in the tick's time; before the drive each joint state's callback posed them, ~0.2 ms a message "
           "outside the tick).", "",
           "| round | scheduler | p50 ms | p99 ms | max ms | overruns (off-CPU) in ticks | contact rows | joint states "
           "sent, received, accepted, refused | platform probe p99, overruns |",
           "|---|---|---|---|---|---|---|---|---|"]
    for x, probe in zip(r[::2], r[1::2]):
        prio = int(x.get("thread_priority") or 0)
        out.append(f"| {x['round']} | {'SCHED_FIFO ' + str(prio) if prio else 'normal'} | {f(x['p50_ms'], '.3f')} | "
                   f"{f(x['p99_ms'], '.3f')} | {f(x['max_ms'], '.2f')} | {x['overruns']} ({x['overruns_off_cpu']}) "
                   f"in {x['ticks']} | {x['contacts']} | {x['sent']}, {x['received']}, {x['accepted']}, "
                   f"{x['refused']} | {f(probe['p99_ms'], '.3f')}, {probe['overruns']} |")
    return out + [""]


def node():
    r = rows("node.csv")
    if not r:
        return []
    out = ["### ROS node (`bench/bench_node.py`, node in its own process)", "",
           "Tick time is the node's own measure (timer callback to the last publication), p50/p99/max over "
           "its last `stats_window` ticks (the measured window, after a 1 s warm-up), as reported in "
           "`/diagnostics`; overruns count the ticks longer than the period from the window's start to the "
           "diagnostics that close it (in brackets: those before it, start-up and warm-up), skipped the "
           "periods whose tick the timer never started (the executor late). CPU is the tick thread's own CPU "
           "time in the same ticks (`time.thread_time`); an overrun is off-CPU when that time fitted the "
           "period: the thread was descheduled or blocked for the rest. The platform probe "
           "(`bench/platform_probe.py`, its own process, like the node) repeats a constant piece of pure-Python "
           "work as long as the 1 kHz tick's p50, at the same rate and scheduler, timed the same way: its "
           "overruns are the machine's (interrupts, whose time this kernel charges to the running thread as CPU "
           "time, and the hypervisor), not the code's.", "",
           "| measurement | bodies | rate Hz | p50 | p99 | max | CPU p99, max | ticks: measured, counted; overruns, off-CPU (before); skipped | sent | received | dropped |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for x in r:
        if (x.get("round") or "1") != "1":   # later rounds of the 1 kHz cases: summed below the table
            continue
        if x["test"] in ("tick_time", "tick_default", "platform_probe"):
            what = {"tick_time": "tick time (ms)", "tick_default": "tick time (ms), default scene, node defaults",
                    "platform_probe": "platform probe: constant work of the tick above's p50 (ms)"}[x["test"]]
            if int(x.get("thread_priority") or 0):
                what += f", `thread_priority: {x['thread_priority']}` (SCHED_FIFO)"
            out.append(f"| {what} | {x['bodies']} | {x['rate_hz']} | {f(x['p50_ms'], '.2f')} | "
                       f"{f(x['p99_ms'], '.2f')} | {f(x['max_ms'], '.2f')} | "
                       f"{f(x.get('cpu_p99_ms', ''), '.2f')}, {f(x.get('cpu_max_ms', ''), '.2f')} | "
                       f"{x['samples']}, {x.get('ticks', '')}; {x['overruns']}, {x.get('overruns_off_cpu', '')} "
                       f"({x.get('overruns_startup', '')}); {x['skipped_ticks']} | | | |")
        else:
            out.append(f"| pose → contacts latency (ms), {x['test']} | {x['bodies']} | {x['rate_hz']} | "
                       f"{f(x['latency_p50_ms'], '.1f')} | {f(x['latency_p99_ms'], '.1f')} | | | | {x['sent']} | "
                       f"{x['received']} | {x['dropped']} |")
    out += rounds_summary([x for x in r if x.get("round")])
    out += ["", "A tick at 100 Hz runs about twice as slow as the same tick repeated back to back, on this "
                "shared machine, whether the 9 ms between ticks sleeps or busy-waits (`bench/node_tick_gap.py`: "
                "the engine step and the publications both slow down): the tick's code and data are evicted between "
                "ticks, not waiting on the executor or an idle CPU."]
    return out + [""]


def rounds_summary(r):
    """One line per scheduler: the 1 kHz node's and the platform probe's overruns summed over the
    rounds of ``bench_node.py --rounds``."""
    if not r:
        return []
    n_rounds = len({x["round"] for x in r})
    seconds = int(r[0]["samples"]) / float(r[0]["rate_hz"])   # the window bench_node was run with
    out = ["", f"Over {n_rounds} rounds of the 1 kHz cases (node and probe taking turns, {seconds:g} s each):", ""]
    for prio in sorted({int(x["thread_priority"] or 0) for x in r}):
        sched = f"SCHED_FIFO {prio}" if prio else "normal scheduler"

        def total(test):
            sel = [x for x in r if x["test"] == test and int(x["thread_priority"] or 0) == prio]
            return (sum(int(x["overruns"]) for x in sel), sum(int(x["ticks"]) for x in sel),
                    max(float(x["max_ms"]) for x in sel))
        node, probe = total("tick_time"), total("platform_probe")
        out.append(f"- {sched}: node {node[0]} overruns in {node[1]} ticks (max {node[2]:.2f} ms); platform probe "
                   f"{probe[0]} in {probe[1]} (max {probe[2]:.2f} ms)")
    return out


def hard_cases():
    path = os.path.join(RESULTS, "hard_cases.txt")
    if not os.path.isfile(path):
        return []
    with open(path) as fh:
        lines = [ln.strip() for ln in fh if ln.strip()]
    out = ["### Hard cases and stability scenes (`make test ARGS=\"-m hard -s\"`, `make stability`; each a test with its thresholds)", ""]
    out += table(["case", "measured"], [ln.partition(": ")[::2] for ln in lines])   # (case, value)
    return out + [""]


def block():
    head = [BEGIN, f"Measured on this project's machine ({platform.machine()}, 2 cores, shared), "
                   "regenerated by `make bench` and `python bench/report.py`.", ""]
    return "\n".join(head + hard_cases() + accuracy() + response() + default_scene() + detection() + single_pair()
                     + mesh_mesh() + robot() + panda() + node_panda() + node() + [END])


def main():
    text = block()
    with open(PAGE) as fh:
        page = fh.read()
    if BEGIN in page:
        page = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), lambda _: text, page, flags=re.S)
    else:
        page = page.rstrip("\n") + "\n\n## Measured results\n\n" + text + "\n"
    with open(PAGE, "w") as fh:
        fh.write(page)
    print(text)


if __name__ == "__main__":
    main()
