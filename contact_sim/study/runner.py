"""One run of a study: its scene (the base scene, its grid cell's values, its perturbations drawn
from its own seed), the kinematic bodies' drive, the stepping, and the figures it records.

``run_one(study, cell, replicate)`` is a plain function of its arguments — what the process pool
and Ray call in their workers, and what ``--workers 1`` calls in the driver — so a run's row is
the same wherever it ran (except ``wall_time`` and ``cost``, which measure the machine).
"""
import copy
import math
import time
import warnings

import numpy as np

from ..scene import load_scene
from ..settings import Material, combine
from .spec import POSE_COLUMNS, figure_columns, get_path, parse_path, run_id, run_seed, set_path

#: the columns that measure the machine, not the physics (left out when rows are compared)
TIMING_COLUMNS = ("wall_time", "cost")


def columns(study):
    """Every column of ``runs.csv`` for ``study``: ids and seed, the grid cell's values, the
    perturbations' draws (``drawn:PATH``), the figures, timing, the exception text (empty when the
    run finished), the warnings it raised (distinct messages), the code version and the study's
    fingerprint."""
    drawn = [f"drawn:{p}" for q in study.perturb.values() for p in q["paths"]]
    return (["run_id", "cell", "replicate", "seed"] + [a[0] for a in study.axes] + drawn + figure_columns(study)
            + ["wall_time", "cost", "exception", "warnings", "code_version", "study"])


def run_scene(study, cell, rng, row=None):
    """The scene dict of a run (a copy of the base scene with the cell's values set and the
    perturbations drawn from ``rng`` in declaration order), its duration (s) and its drive.
    The draws are written to ``row`` (``drawn:PATH``) when given."""
    scene = copy.deepcopy(study.scene)
    duration, drive, perturb = study.duration, copy.deepcopy(study.drive), copy.deepcopy(study.perturb)
    for path, _label, value in study.cell_params(cell):
        toks = parse_path(path, path)
        head = toks[0][0]
        if head == "duration":
            duration = float(value)
        elif head == "drive":
            drive[toks[1][0]] = value
        elif head == "perturb":
            perturb[toks[1][0]][toks[2][0]] = float(value)
        else:
            set_path(scene, toks, value, path)
    for q in perturb.values():
        for p in q["paths"]:
            if q["distribution"] == "normal":
                x = float(rng.normal(q["mean"], q["std"]))
            else:
                x = float(rng.uniform(q["low"], q["high"]))
            toks = parse_path(p, p)
            set_path(scene, toks, float(get_path(scene, toks)) + x if q["mode"] == "add" else x, p)
            if row is not None:
                row[f"drawn:{p}"] = x
    return scene, duration, drive


def run_one(study, cell, rep, code_version=""):
    """Run replicate ``rep`` of grid cell ``cell`` of ``study``; returns its row (a dict keyed by
    ``columns(study)``). A run that raises is returned with its ``exception`` text and no figures.
    Warnings are caught and recorded (``warnings``), never raised, whatever the interpreter's
    warning filters: a run's row does not depend on where it ran."""
    rng, seed = run_seed(study.seed, cell, rep)
    row = dict.fromkeys(columns(study))
    row.update(run_id=run_id(cell, rep), cell=cell, replicate=rep, seed=seed, code_version=code_version,
               study=study.fingerprint, exception="", warnings="")
    for path, label, _value in study.cell_params(cell):
        row[path] = label
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            scene, duration, drive = run_scene(study, cell, rng, row)
            world = load_scene(scene, base_dir=study.base_dir)
            row.update(simulate(world, scene, study, duration, drive))
        except Exception as exc:   # a run that raises is recorded with its exception; the study goes on
            row["exception"] = f"{type(exc).__name__}: {exc}".replace("\n", " ")
    row["wall_time"] = time.perf_counter() - t0
    row["warnings"] = " | ".join(dict.fromkeys(f"{w.category.__name__}: {w.message}".replace("\n", " ")
                                               for w in caught))
    return row


def simulate(world, scene, study, duration, drive):
    """Step ``world`` for ``duration`` s at its ``settings.dt`` (at least one step), driving its
    kinematic bodies by ``drive`` before each step; returns the recorded figures, the success
    predicate's value (1 or 0) and ``cost`` (wall seconds of stepping per simulated second)."""
    dt = world.settings.dt
    n = max(1, int(round(duration / dt)))
    motion = make_drive(drive, world, scene)
    recorders = [RECORDERS[name](world, scene, opts) for name, opts in study.records if name in RECORDERS]
    success = study.success
    at_step = min(n, max(1, int(math.ceil(success["at"] / dt - 1e-9)))) if success else -1
    ok = None
    t0 = time.perf_counter()
    for k in range(1, n + 1):
        if motion is not None:     # posed for the step's start; the step moves them on at the poses' velocity
            motion(world, (k - 1) * dt)
        world.step(dt)
        for r in recorders:
            r.step(world, dt)
        if k == at_step:
            ok = holds(world, success["terms"])
    wall = time.perf_counter() - t0
    out = {}
    for r in recorders:
        out.update(r.finish(world))
    if success:
        out["success"] = int(ok)
    out["cost"] = wall / (n * dt)
    return out


def holds(world, terms):
    """Whether every ``(body, field, op, value)`` term of a success predicate holds now."""
    for body, fld, op, value in terms:
        b = world.body(body)
        x = {"x": b.position[0], "y": b.position[1], "z": b.position[2], "vx": b.velocity[0], "vy": b.velocity[1],
             "vz": b.velocity[2], "speed": np.linalg.norm(b.velocity)}[fld]
        if not {">": x > value, ">=": x >= value, "<": x < value, "<=": x <= value}[op]:
            return False
    return True


# ---------------------------------------------------------------------------- drives
def make_drive(drive, world, scene):
    """``motion(world, t)`` posing the kinematic bodies at time ``t`` (s), or None without a drive.
    ``simulate`` poses them at the start of each step (stamp ``t`` = the world's time); the step
    moves them on at the finite difference of the last two poses, so after each step a body on a
    straight stretch of its path is where the drive puts it at the world's new time (at a corner,
    one step late).

    ``grip``: two box pads close along ``axis`` from their initial positions over ``close_time``
    until each is ``overlap`` (m) past the faces of an object ``half_width`` (m) either side of the
    pads' midpoint, then both rise ``lift`` (m, against gravity) over ``lift_time`` and hold.
    ``keyframes``: each named body's origin moves linearly between ``[t, x, y, z]`` rows (held
    before the first and after the last)."""
    if drive is None:
        return None
    if drive["type"] == "keyframes":
        names = list(drive["bodies"])
        keys = [np.asarray(drive["bodies"][n], float) for n in names]
        q = [world.body(n).orientation for n in names]

        def keyframes(w, t):
            pos = [[np.interp(t, k[:, 0], k[:, j]) for j in (1, 2, 3)] for k in keys]
            w.set_poses(names, pos, q, t)

        return keyframes
    pads, axis = list(drive["pads"]), int(drive["axis"])
    p0 = np.array([world.body(p).position for p in pads])
    q0 = np.array([world.body(p).orientation for p in pads])
    centre = p0[:, axis].mean()
    side = np.sign(p0[:, axis] - centre)
    half_pad = np.array([0.5 * next(b for b in scene["bodies"] if b["name"] == p)["shape"]["size"][axis]
                         for p in pads])
    target = centre + side * (float(drive["half_width"]) + half_pad - float(drive["overlap"]))
    g = np.asarray(world.gravity, float)
    up = -g / np.linalg.norm(g) if np.any(g) else np.array([0.0, 0.0, 1.0])
    close_time, lift, lift_time = float(drive["close_time"]), float(drive["lift"]), float(drive["lift_time"])

    def grip(w, t):
        pos = p0.copy()
        pos[:, axis] += (target - p0[:, axis]) * min(t / close_time, 1.0)
        pos += up * (lift * min(max(t - close_time, 0.0) / lift_time, 1.0))
        w.set_poses(pads, pos, q0, t)

    return grip


# ---------------------------------------------------------------------------- recorders
class MaxPenetration:
    """``max_penetration`` (m): the deepest contact of any step."""

    def __init__(self, world, scene, opts):
        self.deepest = 0.0

    def step(self, world, dt):
        c = world.contacts
        if len(c):
            self.deepest = max(self.deepest, float(c.depth.max()))

    def finish(self, world):
        return {"max_penetration": self.deepest}


class EnergyDrift:
    """``energy_drift`` (J): kinetic + potential energy at the end minus at the start;
    ``max_energy_gain`` (J): the largest rise above the start at any step (> 0 is energy made)."""

    def __init__(self, world, scene, opts):
        self.e0 = float(world.energy())
        self.gain = 0.0

    def step(self, world, dt):
        self.gain = max(self.gain, float(world.energy()) - self.e0)

    def finish(self, world):
        return {"energy_drift": float(world.energy()) - self.e0, "max_energy_gain": self.gain}


class ContactFigures:
    """``contacts_max`` / ``contacts_final``: the most contacts of any step and at the last;
    ``max_contact_force`` / ``final_contact_force`` (N): the total normal force (normal impulses
    ÷ dt) of the step where it was largest, and of the last step."""

    def __init__(self, world, scene, opts):
        self.most, self.force, self.last = 0, 0.0, 0.0

    def step(self, world, dt):
        c = world.contacts
        self.most = max(self.most, len(c))
        self.last = float(np.abs(c.normal_impulse).sum()) / dt if len(c) else 0.0
        self.force = max(self.force, self.last)

    def finish(self, world):
        return {"contacts_max": self.most, "contacts_final": len(world.contacts), "max_contact_force": self.force,
                "final_contact_force": self.last}


class FinalPose:
    """``BODY.x .y .z`` (m) and ``BODY.qx .qy .qz .qw`` of each named body at the end."""

    def __init__(self, world, scene, opts):
        self.bodies = opts["bodies"]

    def step(self, world, dt):
        pass

    def finish(self, world):
        out = {}
        for name in self.bodies:
            b = world.body(name)
            out.update({f"{name}.{c}": float(v) for c, v in zip(POSE_COLUMNS, np.concatenate([b.position,
                                                                                               b.orientation]))})
        return out


class BouncingBallError:
    """``error``: the largest ``|z − z_exact(t)|`` over every step, divided by the drop height —
    a ball (``body``) dropped from rest onto the scene's ground plane with the restitution of its
    material and the plane's (combined by ``settings.combine``), against the closed-form flights
    of ``bouncing_height`` (``bench/bench_accuracy.py``'s bouncing-ball measure)."""

    def __init__(self, world, scene, opts):
        self.body = opts["body"]
        spec = next(b for b in scene["bodies"] if b["name"] == self.body)
        ground = next(b for b in scene["bodies"] if (b.get("shape") or {}).get("type") == "plane")
        mats = scene.get("materials") or {}

        def restitution(b):
            m = mats.get(b.get("material")) or {}
            return float(m.get("restitution", Material().restitution))

        e = float(combine(restitution(spec), restitution(ground), world.settings.combine))
        self.h0, self.radius, self.e = float(world.body(self.body).position[2]), float(spec["shape"]["radius"]), e
        self.g = -float(world.gravity[2])
        self.t, self.z = [], []

    def step(self, world, dt):
        self.t.append(world.time)
        self.z.append(world.body(self.body).position[2])

    def finish(self, world):
        exact = bouncing_height(np.array(self.t), self.h0, self.radius, self.e, self.g)
        return {"error": float(np.max(np.abs(np.array(self.z) - exact)) / self.h0)}


def bouncing_height(t, h0, radius, e, g):
    """Centre height ``(T,)`` at times ``t (T,)`` (s) of a ball dropped from rest at centre height
    ``h0`` (m) onto ``z = 0``, bouncing with restitution ``e`` under gravity ``g`` (m/s²), each
    flight in closed form (``bench/exact.py`` takes it from here)."""
    t = np.asarray(t, float)
    z = np.empty_like(t)
    t1 = np.sqrt(2 * (h0 - radius) / g)
    first = t <= t1
    z[first] = h0 - 0.5 * g * t[first] ** 2
    tb, ub = t1, e * g * t1
    todo = ~first
    while todo.any() and ub > 1e-12:
        flight = 2 * ub / g
        here = todo & (t <= tb + flight)
        s = t[here] - tb
        z[here] = radius + ub * s - 0.5 * g * s * s
        todo &= ~here
        tb, ub = tb + flight, e * ub
    z[todo] = radius
    return z


RECORDERS = {"max_penetration": MaxPenetration, "energy_drift": EnergyDrift, "contacts": ContactFigures,
             "final_pose": FinalPose, "reference": BouncingBallError}
