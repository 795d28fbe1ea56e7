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

from .. import dynamics, quat
from ..scene import load_scene
from ..settings import combine
from .references import (bouncing_height, head_on, incline_acceleration, penalty_rest_depth, rod_impact,
                         sliding_stop_distance)
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
    predicate's value (1 or 0) and ``cost``: wall seconds of the steps (and the drive's poses) per
    simulated second — the recorders' own work between steps is not timed, so a figure recorded
    does not change the cost measured (``bench/bench_accuracy.py`` timed only the steps too)."""
    dt = world.settings.dt
    n = max(1, int(round(duration / dt)))
    motion = make_drive(drive, world, scene)
    recorders = [RECORDERS[name](world, scene, opts) for name, opts in study.records if name in RECORDERS]
    success = study.success
    at_step = min(n, max(1, int(math.ceil(success["at"] / dt - 1e-9)))) if success else -1
    ok = None
    wall = 0.0
    for k in range(1, n + 1):
        t0 = time.perf_counter()
        if motion is not None:     # posed for the step's start; the step moves them on at the poses' velocity
            motion(world, (k - 1) * dt)
        world.step(dt)
        wall += time.perf_counter() - t0
        for r in recorders:
            r.step(world, dt)
        if k == at_step:
            ok = holds(world, success["terms"])
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


# ---------------------------------------------------------------------------- reference recorders
# Each compares a run with a closed form of ``references.py`` and records ``error``: the relative
# error bench/bench_accuracy.py reports for its scene (unitless, so one threshold reads the same in
# every scene). The scene's parameters are read from the world the run built (its grid cell's
# values applied); ``spec.py`` checks a reference's bodies and ground when the study is loaded, and
# a recorder raises ``ValueError`` (the run's ``exception``) where its closed form does not apply.
def _coefficient(world, a, b, field):
    """Material coefficient ``field`` (restitution, friction) of the contact between bodies ``a``
    and ``b``: their materials' combined by ``settings.combine``, as the step combines them."""
    x = getattr(world.materials[world.body(a).material], field)
    y = getattr(world.materials[world.body(b).material], field)
    return float(combine(x, y, world.settings.combine))


def _ground(world, scene):
    """The ground of a reference scene — the first static plane the scene declares — as its name,
    world-frame unit normal ``(3,)`` (out of the solid) and offset (m): the surface is
    ``{x : normal·x = offset}``."""
    name = next(b["name"] for b in scene["bodies"] if isinstance(b, dict) and b.get("kind") == "static"
                and (b.get("shape") or {}).get("type") == "plane")
    g = world.body(name)
    n = quat.rotate(g.orientation, g.shape.normal)
    return name, n, float(g.shape.offset + n @ g.position)


def _spin(body):
    """Spin angular momentum ``R I Rᵀ ω (3,)`` (kg m²/s) of a ``Body`` about its centre of mass."""
    r = quat.to_matrix(body.orientation)
    return r @ body.inertia @ r.T @ body.angular_velocity


class BouncingBallError:
    """``error``: the largest ``|z − z_exact(t)|`` over every step, divided by the drop height —
    a ball (``body``) dropped from rest onto the scene's ground plane with the restitution of its
    material and the plane's (combined by ``settings.combine``), against the closed-form flights
    of ``bouncing_height`` (``bench/bench_accuracy.py``'s bouncing-ball measure)."""

    def __init__(self, world, scene, opts):
        self.body = opts["body"]
        ground, _n, _off = _ground(world, scene)
        e = _coefficient(world, self.body, ground, "restitution")
        ball = world.body(self.body)
        self.h0, self.radius, self.e = float(ball.position[2]), float(ball.shape.radius), e
        self.g = -float(world.gravity[2])
        self.t, self.z = [], []

    def step(self, world, dt):
        self.t.append(world.time)
        self.z.append(world.body(self.body).position[2])

    def finish(self, world):
        exact = bouncing_height(np.array(self.t), self.h0, self.radius, self.e, self.g)
        return {"error": float(np.max(np.abs(np.array(self.z) - exact)) / self.h0)}


class TwoSpheresError:
    """``error``: the largest distance of either sphere's centre (``bodies``: two spheres moving
    head-on, along the line of their centres, no gravity) from its closed-form position
    (``head_on``: one collision, restitution of their materials combined) over every step, divided
    by the initial distance of the centres (bench_accuracy's two-spheres measure). A centre's
    distance counts both its error along the line and any drift off it."""

    def __init__(self, world, scene, opts):
        self.names = list(opts["bodies"])
        a, b = (world.body(n) for n in self.names)
        line = b.position - a.position
        self.d = line / np.linalg.norm(line)
        for body in (a, b):
            off = body.velocity - (body.velocity @ self.d) * self.d
            if np.linalg.norm(off) > 1e-12 * max(np.linalg.norm(body.velocity), 1.0):
                raise ValueError(f"two_spheres reference: {body.name!r} moves off the line of the centres "
                                 "(the closed form is a head-on collision)")
        x1, x2, v1, v2 = a.position @ self.d, b.position @ self.d, a.velocity @ self.d, b.velocity @ self.d
        if v1 <= v2:
            raise ValueError("two_spheres reference: the spheres do not approach each other")
        e = _coefficient(world, a.name, b.name, "restitution")
        self.args = (x1, x2, v1, v2, a.mass, b.mass, float(a.shape.radius), float(b.shape.radius), e)
        self.p0 = (a.position.copy(), b.position.copy())
        self.t, self.p = [], ([], [])

    def step(self, world, dt):
        self.t.append(world.time)
        for name, out in zip(self.names, self.p):
            out.append(world.body(name).position)

    def finish(self, world):
        exact = head_on(np.array(self.t), *self.args)[:2]
        worst = 0.0
        for p, p0, s in zip(self.p, self.p0, exact):
            p = np.array(p)
            moved = p - p0
            off = moved - np.outer(moved @ self.d, self.d)       # drift off the line (0 when on it)
            worst = max(worst, float(np.max(np.hypot(p @ self.d - s, np.linalg.norm(off, axis=1)))))
        return {"error": worst / (self.args[1] - self.args[0])}


class RodImpactError:
    """``error``: the larger relative error of the linear velocity and of the spin angular momentum
    of ``body`` (a box falling without spin onto the ground ``z = 0``, gravity along −z, hitting it
    with one corner) against their values just after the impact (``rod_impact``: the lecture's
    impulse formula), taken at the first step at or after ``after`` s past the exact time of
    impact (bench_accuracy's rod measure: 30 ms, before the far end lands) with gravity since
    the impact removed from the velocity. The run must last that long."""

    def __init__(self, world, scene, opts):
        self.name, self.after = opts["body"], float(opts["after"])
        ground, n, offset = _ground(world, scene)
        g = np.asarray(world.gravity, float)
        if not (np.array_equal(n, [0.0, 0.0, 1.0]) and offset == 0.0 and g[0] == g[1] == 0.0 and g[2] < 0):
            raise ValueError("rod_impact reference: the closed form takes the ground z = 0 (normal +z) and gravity "
                             "along -z")
        rod = world.body(self.name)
        if np.any(rod.angular_velocity != 0):
            raise ValueError(f"rod_impact reference: {self.name!r} spins before the impact (the closed form "
                             "takes a body falling without spin)")
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * rod.shape.half
        q = rod.orientation
        com = rod.position + quat.rotate(q, rod.center_of_mass)
        inv_i = dynamics.world_inverse_inertia(q[None], np.linalg.inv(rod.inertia)[None])[0]
        e = _coefficient(world, self.name, ground, "restitution")
        self.tc, self.v_plus, self.l_plus = rod_impact(rod.position + quat.rotate(q, corners), com, rod.velocity,
                                                       rod.mass, inv_i, e, -g[2])
        self.gravity = g
        self.at_step = int(np.ceil((self.tc + self.after) / world.settings.dt))
        self.steps, self.error = 0, None

    def step(self, world, dt):
        self.steps += 1
        if self.steps == self.at_step:
            rod = world.body(self.name)
            v = rod.velocity - self.gravity * (world.time - self.tc)
            self.error = max(np.linalg.norm(v - self.v_plus) / np.linalg.norm(self.v_plus),
                             np.linalg.norm(_spin(rod) - self.l_plus) / np.linalg.norm(self.l_plus))

    def finish(self, world):
        if self.error is None:
            raise ValueError(f"the run ended at t = {world.time:.3g} s, before the impact + {self.after:g} s "
                             f"(t = {self.tc + self.after:.3g} s) where the rod_impact reference measures: "
                             "lengthen the study's duration")
        return {"error": float(self.error)}


class SlidingBlockError:
    """``error``: ``|d − v0²/(2 μ g)| / (v0²/(2 μ g))`` — the distance ``d`` (m) ``body`` slid along
    its launch velocity ``v0`` over level ground by the end of the run, against the stop distance
    under Coulomb friction ``μ`` (the block's and ground's dynamic friction, combined) with ``g``
    the gravity pressing it down (bench_accuracy's sliding-block measure). The run must last until
    the block stops (``v0/(μ g)`` s)."""

    def __init__(self, world, scene, opts):
        self.name = opts["body"]
        ground, n, _off = _ground(world, scene)
        g = np.asarray(world.gravity, float)
        g_n = -(g @ n)
        if g_n <= 0 or np.linalg.norm(g + g_n * n) > 1e-12 * np.linalg.norm(g):
            raise ValueError("sliding_block reference: the ground must be level (its normal against gravity)")
        block = world.body(self.name)
        v0 = block.velocity
        speed = float(np.linalg.norm(v0))
        if speed == 0 or abs(v0 @ n) > 1e-12 * speed:
            raise ValueError(f"sliding_block reference: {self.name!r} must be launched along the ground")
        mu = _coefficient(world, self.name, ground, "friction")
        self.along, self.p0 = v0 / speed, block.position.copy()
        self.expect = sliding_stop_distance(speed, mu, g_n)
        self.stops = speed / (mu * g_n)

    def step(self, world, dt):
        pass

    def finish(self, world):
        if world.time < self.stops:
            raise ValueError(f"the run ended at t = {world.time:.3g} s, before the block stops (v0/(μ g) = "
                             f"{self.stops:.3g} s): lengthen the study's duration")
        slid = (world.body(self.name).position - self.p0) @ self.along
        return {"error": float(abs(slid - self.expect) / self.expect)}


class InclineError:
    """``error``: ``|a − g (sin θ − μ cos θ)| / (g (sin θ − μ cos θ))`` — the acceleration
    ``a = 2 s / t²`` (m/s²) of ``body``, from the distance ``s`` it slid down the ground plane
    (incline θ: the angle of its normal from ``−gravity``) from rest in the run's ``t`` s, against
    the closed form with the dynamic friction ``μ`` of the block and the slope combined
    (bench_accuracy's incline measure). A block that sticks (``tan θ <= μ``) has no relative error:
    the run raises."""

    def __init__(self, world, scene, opts):
        self.name = opts["body"]
        ground, n, _off = _ground(world, scene)
        g = np.asarray(world.gravity, float)
        g_n = -(g @ n)
        tangential = g + g_n * n
        if g_n <= 0:
            raise ValueError("incline reference: gravity must press the block onto the slope")
        theta = float(np.arctan2(np.linalg.norm(tangential), g_n))
        mu = _coefficient(world, self.name, ground, "friction")
        if np.tan(theta) <= mu:
            raise ValueError(f"incline reference: the block sticks (tan θ = {np.tan(theta):.3g} <= μ = {mu:g}): its "
                             "acceleration is 0 and a relative error of it undefined")
        block = world.body(self.name)
        if np.any(block.velocity != 0) or np.any(block.angular_velocity != 0):
            raise ValueError(f"incline reference: {self.name!r} must start at rest (a = 2 s / t²)")
        self.down = tangential / np.linalg.norm(tangential)
        self.p0 = block.position.copy()
        self.expect = incline_acceleration(theta, mu, float(np.linalg.norm(g)))

    def step(self, world, dt):
        pass

    def finish(self, world):
        a = 2 * (world.body(self.name).position - self.p0) @ self.down / world.time ** 2
        return {"error": float(abs(a - self.expect) / self.expect)}


class PenaltyRestError:
    """``error``: ``|depth − m g / k| / (m g / k)`` — the penetration (m) of ``body`` (a sphere on
    the ground plane) at the end of the run against the rest depth of the penalty spring
    (``settings.penalty.stiffness`` k, N/m; ``g`` the gravity along the ground's normal)
    (bench_accuracy's penalty-rest measure)."""

    def __init__(self, world, scene, opts):
        self.name = opts["body"]
        _ground_name, self.n, self.offset = _ground(world, scene)
        ball = world.body(self.name)
        self.radius = float(ball.shape.radius)
        g_n = -(np.asarray(world.gravity, float) @ self.n)
        self.expect = penalty_rest_depth(ball.mass, g_n, world.settings.penalty.stiffness)

    def step(self, world, dt):
        pass

    def finish(self, world):
        depth = self.radius - (world.body(self.name).position @ self.n - self.offset)
        return {"error": float(abs(depth - self.expect) / self.expect)}


def reference(world, scene, opts):
    """The recorder of ``record: [{reference: {type: NAME, ...}}]``: ``REFERENCES[NAME]``."""
    return REFERENCES[opts["type"]](world, scene, opts)


#: the reference recorders by the name a study file gives (``spec.REFERENCES`` validates their options)
REFERENCES = {"bouncing_ball": BouncingBallError, "two_spheres": TwoSpheresError, "rod_impact": RodImpactError,
              "sliding_block": SlidingBlockError, "incline": InclineError, "penalty_rest": PenaltyRestError}
RECORDERS = {"max_penetration": MaxPenetration, "energy_drift": EnergyDrift, "contacts": ContactFigures,
             "final_pose": FinalPose, "reference": reference}
