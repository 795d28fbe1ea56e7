"""The study file: its model, its validation, and the expansion of its grid and perturbations.

A study is many independent runs of one scene: a **grid** of parameter values (their Cartesian
product, one *cell* per combination) times ``replicates`` runs per cell, each run drawing its
**perturbations** from a random generator seeded by ``(seed, cell, replicate)`` alone, so a run's
result depends only on the study, its cell and its replicate index — never on where or in which
order it ran. Parameters are addressed by paths into the scene (``settings.dt``,
``settings.penalty.stiffness``, ``materials.pad.friction``, ``bodies.cube.position[2]``,
``bodies.ball.shape.radius``, ``gravity[2]``), into the study itself (``duration``,
``drive.overlap``, ``perturb.pose_noise.std``), or ``settings`` alone (a mapping merged into the
scene's settings: one value of a *model* axis). Every error names its place in the study file and
the reason, as scene files do (``StudyError``).
"""
import copy
import hashlib
import json
import math
import numbers
import os
import re

import numpy as np

from ..errors import ContactSimError, StudyError
from ..kinds import DYNAMIC
from ..scene import BODY_KEYS, SHAPE_KEYS, load_scene, resolve_scene, scenes_dir
from ..settings import Material, Penalty, Settings

TOP_KEYS = {"name", "description", "scene", "set", "duration", "seed", "replicates", "grid", "perturb", "drive", "record",
            "success", "summary", "plot"}
#: the figures a run can record (``record:``), each a name or ``{name: options}``
RECORDS = ("final_pose", "max_penetration", "energy_drift", "contacts", "wall_time", "reference")
#: named exact answers a run is compared with (``record: [{reference: {type: NAME, ...}}]``, closed
#: forms in ``references.py``, recorders in ``runner.py``): their options (default; None: required),
#: the role of their body, the shape it must have, and whether they need a static ground plane
#: (else: gravity 0). Each records ``error``, relative (bench/bench_accuracy.py's measure).
REFERENCES = {
    "bouncing_ball": {"options": {"body": "ball"}, "role": "the ball (a dynamic sphere)", "shape": "sphere",
                      "ground": True},
    "two_spheres": {"options": {"bodies": None}, "role": "the two spheres (dynamic spheres)", "shape": "sphere",
                    "ground": False},
    "rod_impact": {"options": {"body": None, "after": 0.03}, "role": "the rod (a dynamic box)", "shape": "box",
                   "ground": True},
    "sliding_block": {"options": {"body": None}, "role": "the sliding block (a dynamic box)", "shape": "box",
                      "ground": True},
    "incline": {"options": {"body": None}, "role": "the block (a dynamic box)", "shape": "box", "ground": True},
    "penalty_rest": {"options": {"body": None}, "role": "the ball (a dynamic sphere)", "shape": "sphere",
                     "ground": True},
}
#: named distributions of ``perturb:`` and their parameters (defaults; None: required)
DISTRIBUTIONS = {"normal": {"mean": 0.0, "std": None}, "uniform": {"low": None, "high": None}}
#: named motions of the kinematic bodies (``drive:``) and their parameters (defaults; None: required)
DRIVES = {
    "grip": {"pads": None, "axis": 0, "half_width": None, "overlap": None, "close_time": 0.5, "lift": 0.1,
             "lift_time": 1.0},
    "keyframes": {"bodies": None},
}
VECTOR_LEN = {"position": 3, "orientation": 4, "velocity": 3, "angular_velocity": 3}
VECTOR_DEFAULT = {"position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0, 1.0], "velocity": [0.0, 0.0, 0.0],
                  "angular_velocity": [0.0, 0.0, 0.0]}
SUCCESS_FIELDS = ("x", "y", "z", "vx", "vy", "vz", "speed")
SUCCESS_OPS = (">=", "<=", ">", "<")
PLOT_TYPES = ("work_precision", "heatmap")
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")
_SEGMENT = re.compile(r"^([A-Za-z_][\w\-]*)(?:\[(\d+)\])?$")
_FRACTION = re.compile(r"^\s*(-?\d+(?:\.\d*)?)\s*/\s*(\d+(?:\.\d*)?)\s*$")


def studies_dir():
    """Folder of the shipped studies: ``config/studies`` beside ``config/scenes`` (source tree or
    ``share/contact_sim/config`` of an install)."""
    return os.path.join(os.path.dirname(scenes_dir()), "studies")


def list_studies():
    """The names of the shipped studies (``list[str]``, sorted; ``resolve_study`` takes each)."""
    d = studies_dir()
    return sorted(f[:-5] for f in os.listdir(d) if f.endswith(".yaml")) if os.path.isdir(d) else []


def resolve_study(name_or_path):
    """A study file path from a path, or the name of a shipped study (``grasp``) in ``config/studies``."""
    if os.path.isfile(name_or_path):
        return name_or_path
    shipped = os.path.join(studies_dir(), name_or_path if name_or_path.endswith(".yaml") else name_or_path + ".yaml")
    if os.path.isfile(shipped):
        return shipped
    raise StudyError("", f"study {name_or_path!r}: no such file, and no shipped study of that name "
                         f"(shipped: {', '.join(list_studies()) or 'none'})")


def parse_path(text, where):
    """``"bodies.cube.position[2]"`` → ``[("bodies", None), ("cube", None), ("position", 2)]``."""
    if not isinstance(text, str) or not text:
        raise StudyError(where, f"a parameter path is a text such as settings.dt, got {text!r}")
    out = []
    for part in text.split("."):
        m = _SEGMENT.match(part)
        if not m:
            raise StudyError(where, f"{part!r} is not a path segment (name or name[index])")
        out.append((m.group(1), None if m.group(2) is None else int(m.group(2))))
    return out


def _number(value, where, what="a number"):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise StudyError(where, f"must be {what}, got {value!r}")
    return float(value)


def _fraction(value):
    """``"1/240"`` → ``1/240`` as a float (grid values may be written so); anything else unchanged."""
    if isinstance(value, str):
        m = _FRACTION.match(value)
        if m and float(m.group(2)) != 0:
            return float(m.group(1)) / float(m.group(2))
    return value


class Study:
    """A validated study (``load_study``): the base scene as a dict, the grid axes, perturbations,
    drive, figures to record, success predicate, summary and plot options. Picklable (sent to the
    process pool's and Ray's workers as it is)."""

    def __init__(self, data, where_dir=None, name=None):
        if not isinstance(data, dict):
            raise StudyError("study", f"must be a mapping, got {type(data).__name__}")
        unknown = set(data) - TOP_KEYS
        if unknown:
            raise StudyError(f"study.{sorted(unknown)[0]}", f"unknown key (known: {', '.join(sorted(TOP_KEYS))})")
        self.source = copy.deepcopy(data)
        self.where_dir = where_dir or os.getcwd()
        self.name = str(data.get("name") or name or "study")
        self.description = str(data.get("description") or "")
        self.scene, self.base_dir = self._scene(data.get("scene"))
        try:
            world = load_scene(copy.deepcopy(self.scene), base_dir=self.base_dir)
        except ContactSimError as exc:
            raise StudyError("study.scene", str(exc)) from None
        self.body_names = list(world.body_names)
        self.dynamic = [n for n, k in zip(world.body_names, world.kind) if int(k) == DYNAMIC]
        self._set(data.get("set"))
        self.duration = _number(data.get("duration", 1.0), "study.duration")
        if self.duration <= 0:
            raise StudyError("study.duration", f"must be > 0 (simulated seconds), got {self.duration!r}")
        seed = data.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise StudyError("study.seed", f"must be a whole number >= 0, got {seed!r}")
        self.seed = int(seed)
        reps = data.get("replicates", 1)
        if isinstance(reps, bool) or not isinstance(reps, numbers.Integral) or reps < 1:
            raise StudyError("study.replicates", f"must be a whole number >= 1, got {reps!r}")
        self.replicates = int(reps)
        self.drive = self._drive(data.get("drive"))
        self.perturb = self._perturb(data.get("perturb"))
        self.records = self._records(data.get("record", ["max_penetration", "energy_drift", "contacts"]))
        self.success = self._success(data.get("success"))
        self.summary = self._summary(data.get("summary"))
        self.axes = self._grid(data.get("grid"))
        self.plot = self._plot(data.get("plot"))
        self.fingerprint = hashlib.sha256(json.dumps(
            [self.source, self.scene], sort_keys=True, default=repr).encode()).hexdigest()[:16]

    # ------------------------------------------------------------------ sections
    def _scene(self, scene):
        if scene is None:
            raise StudyError("study.scene", "required: a scene file, a shipped scene's name or a scene mapping")
        if isinstance(scene, dict):
            return copy.deepcopy(scene), self.where_dir
        if not isinstance(scene, str):
            raise StudyError("study.scene", f"must be a file, a shipped scene's name or a mapping, got {scene!r}")
        local = scene if os.path.isabs(scene) else os.path.join(self.where_dir, scene)
        try:
            path = local if os.path.isfile(local) else resolve_scene(scene)
        except ContactSimError as exc:
            raise StudyError("study.scene", str(exc)) from None
        import yaml

        try:
            with open(path) as fh:
                d = yaml.safe_load(fh) or {}
        except yaml.YAMLError as exc:
            raise StudyError("study.scene", f"{path}: not valid YAML: {exc}") from None
        return d, os.path.dirname(os.path.abspath(path))

    def _set(self, d):
        """``set:`` — scene paths given one value for every run, applied to the base scene."""
        if d is None:
            return
        if not isinstance(d, dict):
            raise StudyError("study.set", f"must be a mapping of scene path → value, got {d!r}")
        for path, value in d.items():
            where = f"study.set[{path!r}]"
            toks = parse_path(path, where)
            if toks[0][0] not in ("settings", "materials", "bodies", "gravity"):
                raise StudyError(where, f"{path!r}: set: changes the scene (settings, materials, bodies, gravity); "
                                        "give the study's own keys directly")
            check_path(self, toks, path, where)
            scene = copy.deepcopy(self.scene)
            try:
                set_path(scene, toks, _fraction(value), path)
                load_scene(copy.deepcopy(scene), base_dir=self.base_dir)
            except ContactSimError as exc:
                raise StudyError(where, f"{value!r}: {exc}") from None
            self.scene = scene

    def _drive(self, d):
        if d is None:
            return None
        where = "study.drive"
        if not isinstance(d, dict) or d.get("type") not in DRIVES:
            raise StudyError(f"{where}.type", f"required: one of {', '.join(DRIVES)}; got "
                                              f"{d.get('type') if isinstance(d, dict) else d!r}")
        spec = DRIVES[d["type"]]
        unknown = set(d) - set(spec) - {"type"}
        if unknown:
            raise StudyError(f"{where}.{sorted(unknown)[0]}", f"unknown key of a {d['type']} drive "
                                                              f"(known: {', '.join(sorted(spec))})")
        out = {"type": d["type"]}
        for k, default in spec.items():
            if k not in d and default is None:
                raise StudyError(f"{where}.{k}", "required")
            out[k] = copy.deepcopy(d.get(k, default))
        check_drive(out, self, where)
        return out

    def _perturb(self, d):
        if d is None:
            return {}
        if not isinstance(d, dict):
            raise StudyError("study.perturb", f"must be a mapping of name → perturbation, got {d!r}")
        out = {}
        for name, p in d.items():
            where = f"study.perturb.{name}"
            if not isinstance(p, dict):
                raise StudyError(where, f"must be a mapping {{paths, distribution, ...}}, got {p!r}")
            dist = p.get("distribution")
            if dist not in DISTRIBUTIONS:
                raise StudyError(f"{where}.distribution", f"unknown distribution {dist!r} "
                                                          f"(known: {', '.join(DISTRIBUTIONS)})")
            params = DISTRIBUTIONS[dist]
            unknown = set(p) - set(params) - {"paths", "distribution", "mode"}
            if unknown:
                raise StudyError(f"{where}.{sorted(unknown)[0]}", f"unknown key of a {dist} perturbation "
                                                                  f"(known: paths, distribution, mode, "
                                                                  f"{', '.join(params)})")
            paths = p.get("paths")
            if isinstance(paths, str):
                paths = [paths]
            if not isinstance(paths, list) or not paths:
                raise StudyError(f"{where}.paths", f"required: a list of parameter paths, got {paths!r}")
            mode = p.get("mode", "add")
            if mode not in ("add", "set"):
                raise StudyError(f"{where}.mode", f"must be add (offset the value) or set, got {mode!r}")
            q = {"paths": list(paths), "distribution": dist, "mode": mode}
            for k, default in params.items():
                if k not in p and default is None:
                    raise StudyError(f"{where}.{k}", f"required by the {dist} distribution")
                q[k] = _number(p.get(k, default), f"{where}.{k}")
            check_distribution(q, where)
            for i, path in enumerate(q["paths"]):
                w = f"{where}.paths[{i}]"
                toks = parse_path(path, w)
                if toks[0][0] not in ("settings", "materials", "bodies", "gravity"):
                    raise StudyError(w, f"{path!r}: a perturbation changes the scene (settings, materials, bodies, "
                                        "gravity)")
                check_path(self, toks, path, w)
                if not isinstance(self._current(path), numbers.Real):
                    raise StudyError(w, f"{path!r} is not a number in the scene")
            out[str(name)] = q
        return out

    def _records(self, items):
        if not isinstance(items, list):
            raise StudyError("study.record", f"must be a list of figures ({', '.join(RECORDS)}), got {items!r}")
        out = []
        for i, item in enumerate(items):
            where = f"study.record[{i}]"
            name, opts = (item, None) if isinstance(item, str) else (
                next(iter(item.items())) if isinstance(item, dict) and len(item) == 1 else (None, None))
            if name not in RECORDS:
                raise StudyError(where, f"unknown figure {item!r} (known: {', '.join(RECORDS)})")
            if name == "final_pose":
                bodies = self.dynamic if opts is None else opts.get("bodies") if isinstance(opts, dict) else None
                if not isinstance(bodies, list) or any(b not in self.body_names for b in bodies):
                    raise StudyError(where, f"final_pose takes {{bodies: [names of the scene's bodies]}}, got {opts!r}")
                out.append(("final_pose", {"bodies": list(bodies)}))
            elif name == "reference":
                if any(n == "reference" for n, _ in out):
                    raise StudyError(where, "one reference per study (its figure is error)")
                out.append(("reference", self._reference(opts, where)))
            else:
                out.append((name, {}))
        return out

    def _reference(self, opts, where):
        """``{reference: NAME}`` or ``{reference: {type: NAME, body: BODY, ...}}``: an exact answer
        of ``REFERENCES``, its options (defaults filled in) and its bodies checked against the
        base scene — each a dynamic body of the shape the closed form takes — and the ground or
        gravity it needs."""
        opts = {"type": opts} if isinstance(opts, str) else opts
        if not isinstance(opts, dict):
            raise StudyError(where, f"reference takes {{type: NAME, ...}} or NAME (NAME one of "
                                    f"{', '.join(REFERENCES)}), got {opts!r}")
        kind = opts.get("type")
        if kind not in REFERENCES:
            raise StudyError(f"{where}.type", f"unknown exact answer {kind!r} (known: {', '.join(REFERENCES)})")
        spec = REFERENCES[kind]
        unknown = set(opts) - set(spec["options"]) - {"type"}
        if unknown:
            raise StudyError(f"{where}.{sorted(unknown)[0]}", f"unknown key of a {kind} reference "
                                                              f"(known: {', '.join(sorted(spec['options']))})")
        out = {"type": kind}
        for key, default in spec["options"].items():
            if key not in opts and default is None:
                raise StudyError(f"{where}.{key}", f"required: {spec['role']}")
            out[key] = copy.deepcopy(opts.get(key, default))
        declared = {b.get("name"): b for b in self.scene.get("bodies") or [] if isinstance(b, dict)}

        def check_body(name, at):
            if name not in self.body_names:
                raise StudyError(at, f"no body {name!r} in the scene ({', '.join(map(str, self.body_names))})")
            b = declared.get(name)
            if b is None:
                raise StudyError(at, f"{name!r} is a robot's link; a {kind} reference measures a body the scene "
                                     "declares")
            if b.get("kind", "dynamic") != "dynamic":
                raise StudyError(at, f"{name!r} is {b.get('kind')}; a {kind} reference measures a dynamic "
                                     f"{spec['shape']}")
            shape = (b.get("shape") or {}).get("type")
            if shape != spec["shape"]:
                raise StudyError(at, f"{name!r} is a {shape}; a {kind} reference measures a dynamic {spec['shape']}")

        if "bodies" in out:
            names = out["bodies"]
            if not isinstance(names, list) or len(names) != 2 or names[0] == names[1] or \
                    not all(isinstance(n, str) for n in names):
                raise StudyError(f"{where}.bodies", f"must name two different dynamic {spec['shape']}s of the scene, "
                                                    f"got {names!r}")
            for n in names:
                check_body(n, f"{where}.bodies")
        else:
            check_body(out["body"], f"{where}.body")
        if "after" in out and _number(out["after"], f"{where}.after") <= 0:
            raise StudyError(f"{where}.after", f"must be > 0 (seconds after the exact impact), got {out['after']!r}")
        if spec["ground"] and not any(b.get("kind") == "static" and (b.get("shape") or {}).get("type") == "plane"
                                      for b in declared.values()):
            raise StudyError(where, f"a {kind} reference needs a static plane in the scene (the ground)")
        if not spec["ground"] and any(float(x) != 0 for x in self.scene.get("gravity", [0.0, 0.0, -9.81])):
            raise StudyError(where, f"a {kind} reference needs gravity 0 (its closed form has no force but the "
                                    "collision)")
        return out

    def _success(self, s):
        if s is None:
            return None
        where = "study.success"
        if isinstance(s, str):
            s = {"when": s}
        if not isinstance(s, dict) or "when" not in s or set(s) - {"when", "at"}:
            raise StudyError(where, f"must be a predicate text or {{when: text, at: seconds}}, got {s!r}")
        at = _number(s.get("at", self.duration), f"{where}.at")
        if not 0 < at <= self.duration:
            raise StudyError(f"{where}.at", f"must be in (0, duration = {self.duration}], got {at!r}")
        terms = []
        for term in str(s["when"]).split(" and "):
            m = re.match(r"^\s*([\w\-]+)\.(\w+)\s*(>=|<=|>|<)\s*(\S+)\s*$", term)
            if not m:
                raise StudyError(f"{where}.when", f"{term.strip()!r}: write BODY.FIELD OP NUMBER "
                                                  f"(FIELD one of {', '.join(SUCCESS_FIELDS)}; OP one of "
                                                  f"{', '.join(SUCCESS_OPS)}), joined by ' and '")
            body, fld, op, num = m.groups()
            if body not in self.body_names:
                raise StudyError(f"{where}.when", f"{term.strip()!r}: no body {body!r} in the scene")
            if fld not in SUCCESS_FIELDS:
                raise StudyError(f"{where}.when", f"{term.strip()!r}: unknown field {fld!r} "
                                                  f"(known: {', '.join(SUCCESS_FIELDS)})")
            try:
                value = float(num)
            except ValueError:
                raise StudyError(f"{where}.when", f"{term.strip()!r}: {num!r} is not a number") from None
            terms.append((body, fld, op, value))
        return {"when": str(s["when"]), "at": at, "terms": terms}

    def _summary(self, s):
        s = {} if s is None else s
        if not isinstance(s, dict) or set(s) - {"quantiles", "show"}:
            raise StudyError("study.summary", f"takes {{quantiles: [..], show: [figures]}}, got {s!r}")
        q = s.get("quantiles", [0.05, 0.5, 0.95])
        if not isinstance(q, list) or not all(isinstance(x, numbers.Real) and 0 <= x <= 1 for x in q):
            raise StudyError("study.summary.quantiles", f"must be a list of numbers in [0, 1], got {q!r}")
        show = s.get("show")
        if show is not None and (not isinstance(show, list) or not all(isinstance(x, str) for x in show)):
            raise StudyError("study.summary.show", f"must be a list of figure names, got {show!r}")
        return {"quantiles": [float(x) for x in q], "show": show}

    def _grid(self, g):
        g = {} if g is None else g
        if not isinstance(g, dict):
            raise StudyError("study.grid", f"must be a mapping of parameter path → values, got {g!r}")
        axes = []
        for path, values in g.items():
            where = f"study.grid[{path!r}]"
            toks = parse_path(path, where)
            check_path(self, toks, path, where)
            if isinstance(values, dict):
                labels, vals = [str(k) for k in values], [_fraction(v) for v in values.values()]
            elif isinstance(values, list):
                vals = [_fraction(v) for v in values]
                labels = [v if isinstance(v, (numbers.Real, str, bool)) else json.dumps(v, sort_keys=True)
                          for v in vals]
            else:
                raise StudyError(where, f"must be a list of values or a mapping label → value, got {values!r}")
            if not vals:
                raise StudyError(where, "must give at least one value")
            if len(set(map(str, labels))) != len(labels):
                raise StudyError(where, "values repeat")
            for k, v in enumerate(vals):
                self._check_value(path, toks, v, f"{where}[{k}]")
            axes.append((path, labels, vals))
        return axes

    def _plot(self, p):
        if p is None:       # two swept axes: a heat-map of the success rate (or the first figure's mean)
            if len(self.axes) != 2:
                return None
            figures = [f for f in figure_columns(self) if f != "success"] + ["cost"]
            return {"type": "heatmap", "x": self.axes[0][0], "y": self.axes[1][0],
                    "value": "success_rate" if self.success is not None else f"{figures[0]}_mean"}
        if p is False:
            return None
        where = "study.plot"
        if not isinstance(p, dict) or p.get("type") not in PLOT_TYPES:
            raise StudyError(f"{where}.type", f"must be one of {', '.join(PLOT_TYPES)}, got {p!r}")
        keys = {"work_precision": {"series", "points", "x", "y"}, "heatmap": {"x", "y", "value"}}[p["type"]]
        unknown = set(p) - keys - {"type"}
        missing = keys - set(p)
        if unknown or missing:
            raise StudyError(where, f"a {p['type']} plot takes {', '.join(sorted(keys))}")
        grid = [a[0] for a in self.axes]
        for k in ("series", "points") if p["type"] == "work_precision" else ("x", "y"):
            if p[k] not in grid:
                raise StudyError(f"{where}.{k}", f"{p[k]!r} is not a grid axis (axes: {', '.join(grid) or 'none'})")
        figures = [f for f in figure_columns(self) if f != "success"] + ["cost"]
        if p["type"] == "work_precision":
            for k in ("x", "y"):
                if p[k] not in figures:
                    raise StudyError(f"{where}.{k}", f"{p[k]!r} is not a recorded figure (figures: {', '.join(figures)})")
        else:
            values = ["success_rate"] * (self.success is not None) + [f"{f}_mean" for f in figures]
            if p["value"] not in values:
                raise StudyError(f"{where}.value", f"{p['value']!r} is not a summary column (one of {', '.join(values)})")
        return dict(p)

    # ------------------------------------------------------------------ values
    def _current(self, path):
        """The value at a scene path in the base scene (defaults filled in)."""
        d = copy.deepcopy(self.scene)
        return get_path(d, parse_path(path, path))

    def _check_value(self, path, toks, value, where):
        """A grid value for ``path`` is checked by building the base scene with it (settings,
        materials, bodies: the scene's own rules and messages) or by the drive's or
        perturbation's rules."""
        head = toks[0][0]
        if head == "duration":
            if _number(value, where) <= 0:
                raise StudyError(where, f"must be > 0 (simulated seconds), got {value!r}")
            return
        if head == "drive":
            d = dict(self.drive)
            d[toks[1][0]] = value
            check_drive(d, self, where)
            return
        if head == "perturb":
            q = dict(self.perturb[toks[1][0]])
            q[toks[2][0]] = _number(value, where)
            check_distribution(q, where)
            return
        scene = copy.deepcopy(self.scene)
        try:
            set_path(scene, toks, value, path)
            load_scene(scene, base_dir=self.base_dir)
        except ContactSimError as exc:
            raise StudyError(where, f"{value!r}: {exc}") from None

    # ------------------------------------------------------------------ expansion
    @property
    def cells(self):
        """Number of grid cells (the product of the axes' lengths; 1 without a grid)."""
        return int(np.prod([len(a[1]) for a in self.axes])) if self.axes else 1

    def cell_params(self, cell):
        """``[(path, label, value)]`` of grid cell ``cell`` (row-major: the last axis varies fastest)."""
        out = []
        for path, labels, vals in reversed(self.axes):
            cell, k = divmod(cell, len(vals))
            out.append((path, labels[k], vals[k]))
        return out[::-1]

    def runs(self):
        """Every run of the study in order, as ``(run_id, cell, replicate)``; ids are ``"cell-replicate"``."""
        for cell in range(self.cells):
            for rep in range(self.replicates):
                yield run_id(cell, rep), cell, rep

    def __len__(self):
        return self.cells * self.replicates


def figure_columns(study):
    """The names of the figures a run of ``study`` records, in ``runs.csv`` order."""
    out = []
    for name, opts in study.records:
        if name == "final_pose":
            out += [f"{b}.{c}" for b in opts["bodies"] for c in POSE_COLUMNS]
        elif name == "max_penetration":
            out.append("max_penetration")
        elif name == "energy_drift":
            out += ["energy_drift", "max_energy_gain"]
        elif name == "contacts":
            out += ["contacts_max", "contacts_final", "max_contact_force", "final_contact_force"]
        elif name == "reference":
            out.append("error")
    if study.success is not None:
        out.append("success")
    return out


def run_id(cell, rep):
    """A run's id: ``"cell-replicate"`` (what ``runs.csv`` holds and a resume skips)."""
    return f"{cell}-{rep}"


def run_seed(seed, cell, rep):
    """The random generator of one run and its integer seed: ``numpy.random.SeedSequence([seed,
    cell, rep])``, so a run's draws depend on nothing but the study seed, its cell and replicate."""
    ss = np.random.SeedSequence([seed, cell, rep])
    return np.random.default_rng(ss), int(ss.generate_state(1, np.uint32)[0])


def check_path(study, toks, path, where):
    """Refuse a path that addresses nothing in the study's scene or the study, naming why."""
    head, idx = toks[0]
    if head == "duration" and len(toks) == 1 and idx is None:
        return
    if head == "gravity" and len(toks) == 1 and (idx is None or idx < 3):
        return
    if head == "settings":
        if len(toks) == 1 and idx is None:
            return
        name = toks[1][0]
        if name == "penalty" and len(toks) == 3 and toks[2][0] in Penalty.rules():
            return
        if len(toks) == 2 and name in Settings.rules() and name != "penalty" and toks[1][1] is None:
            return
        raise StudyError(where, f"{path!r}: unknown setting (settings.NAME with NAME one of "
                                f"{', '.join(sorted(Settings.rules()))}, or settings.penalty.NAME)")
    if head == "materials":
        mats = study.scene.get("materials") or {}
        if len(toks) != 3 or toks[1][0] not in mats or toks[2][0] not in Material.rules():
            raise StudyError(where, f"{path!r}: write materials.NAME.FIELD with NAME a material of the scene "
                                    f"({', '.join(mats) or 'none'}) and FIELD one of "
                                    f"{', '.join(Material.rules())}")
        return
    if head == "bodies":
        declared = [b.get("name") for b in study.scene.get("bodies") or [] if isinstance(b, dict)]
        if len(toks) < 3 or toks[1][0] not in declared:
            raise StudyError(where, f"{path!r}: write bodies.NAME.FIELD with NAME one of the scene's bodies "
                                    f"({', '.join(map(str, declared))}; a robot's links cannot be addressed)")
        field, i = toks[2]
        if field not in BODY_KEYS - {"name", "shape", "collision"} and field != "shape":
            raise StudyError(where, f"{path!r}: unknown body field {field!r} "
                                    f"(known: {', '.join(sorted(BODY_KEYS - {'name', 'collision'}))})")
        if field == "shape":
            body = _body(study.scene, toks[1][0])
            t = (body.get("shape") or {}).get("type")
            if len(toks) != 4 or toks[3][0] not in SHAPE_KEYS.get(t, ()) - {"type", "file"}:
                raise StudyError(where, f"{path!r}: write bodies.NAME.shape.KEY with KEY one of the {t} shape's "
                                        f"{', '.join(sorted(SHAPE_KEYS.get(t, set()) - {'type', 'file'}))}")
            return
        if len(toks) != 3:
            raise StudyError(where, f"{path!r}: nothing below bodies.NAME.{field}")
        if i is not None and (field not in VECTOR_LEN or i >= VECTOR_LEN[field]):
            raise StudyError(where, f"{path!r}: index [{i}] out of range for {field}")
        return
    if head == "drive":
        if study.drive is None:
            raise StudyError(where, f"{path!r}: the study has no drive")
        if len(toks) != 2 or toks[1][0] not in DRIVES[study.drive["type"]] or toks[1][0] in ("pads", "bodies"):
            raise StudyError(where, f"{path!r}: write drive.KEY with KEY a number of the "
                                    f"{study.drive['type']} drive")
        return
    if head == "perturb":
        if len(toks) != 3 or toks[1][0] not in study.perturb or \
                toks[2][0] not in DISTRIBUTIONS[study.perturb[toks[1][0]]["distribution"]]:
            raise StudyError(where, f"{path!r}: write perturb.NAME.PARAMETER with NAME a perturbation of the study "
                                    f"({', '.join(study.perturb) or 'none'}) and PARAMETER one of its distribution's")
        return
    raise StudyError(where, f"{path!r}: unknown parameter path (it starts with settings, materials, bodies, "
                            "gravity, duration, drive or perturb)")


def check_drive(d, study, where):
    """Refuse a drive whose bodies are not kinematic bodies of the scene or whose numbers are bad."""
    kinematic = {b.get("name") for b in study.scene.get("bodies") or [] if b.get("kind") == "kinematic"}
    if d["type"] == "grip":
        pads = d["pads"]
        if not isinstance(pads, list) or len(pads) != 2 or any(p not in kinematic for p in pads):
            raise StudyError(f"{where}.pads", f"must name two kinematic bodies of the scene "
                                              f"({', '.join(sorted(kinematic)) or 'none'}), got {pads!r}")
        if d["axis"] not in (0, 1):
            raise StudyError(f"{where}.axis", f"must be 0 (x) or 1 (y), got {d['axis']!r}")
        for k in ("half_width", "overlap", "close_time", "lift", "lift_time"):
            v = _number(d[k], f"{where}.{k}")
            if k in ("close_time", "lift_time", "half_width") and v <= 0:
                raise StudyError(f"{where}.{k}", f"must be > 0, got {v!r}")
        for p in pads:
            shape = _body(study.scene, p).get("shape") or {}
            if shape.get("type") != "box":
                raise StudyError(f"{where}.pads", f"{p!r}: a grip's pads are boxes")
    else:
        bodies = d["bodies"]
        if not isinstance(bodies, dict) or not bodies:
            raise StudyError(f"{where}.bodies", "must map kinematic body names to [[t, x, y, z], ...] keyframes")
        for name, keys in bodies.items():
            if name not in kinematic:
                raise StudyError(f"{where}.bodies.{name}", "not a kinematic body of the scene")
            arr = np.asarray(keys, float) if isinstance(keys, list) else None
            if arr is None or arr.ndim != 2 or arr.shape[1] != 4 or len(arr) < 1 or not np.all(np.isfinite(arr)) \
                    or np.any(np.diff(arr[:, 0]) <= 0):
                raise StudyError(f"{where}.bodies.{name}", "must be a list of [t, x, y, z] rows, times increasing")


def check_distribution(q, where):
    """Refuse a distribution's parameters that draw nothing sensible (std < 0, low > high)."""
    if q["distribution"] == "normal" and q["std"] < 0:
        raise StudyError(f"{where}.std", f"must be >= 0, got {q['std']!r}")
    if q["distribution"] == "uniform" and q["low"] > q["high"]:
        raise StudyError(f"{where}.low", f"must be <= high ({q['high']!r}), got {q['low']!r}")


def _body(scene, name):
    for b in scene.get("bodies") or []:
        if isinstance(b, dict) and b.get("name") == name:
            return b
    raise StudyError("", f"no body {name!r} in the scene")


def _container(scene, toks, path):
    """The dict that holds the last segment of a scene path, and that segment's key."""
    head = toks[0][0]
    if head == "gravity":
        return scene, "gravity"
    if head == "settings":
        s = scene.setdefault("settings", {}) or {}
        scene["settings"] = s
        if len(toks) == 1:
            return scene, "settings"
        if toks[1][0] == "penalty" and len(toks) == 3:
            p = s.setdefault("penalty", {}) or {}
            s["penalty"] = p
            return p, toks[2][0]
        return s, toks[1][0]
    if head == "materials":
        m = scene["materials"][toks[1][0]]
        if m is None:
            m = scene["materials"][toks[1][0]] = {}
        return m, toks[2][0]
    if head == "bodies":
        b = _body(scene, toks[1][0])
        if toks[2][0] == "shape":
            return b["shape"], toks[3][0]
        return b, toks[2][0]
    raise StudyError(path, "not a scene path")


def get_path(scene, toks):
    """The value at a scene path (defaults of vectors and gravity filled in)."""
    box, key = _container(scene, toks, "")
    idx = toks[-1][1]
    default = [0.0, 0.0, -9.81] if toks[0][0] == "gravity" else VECTOR_DEFAULT.get(key)
    value = box.get(key, default)
    return value if idx is None else value[idx]


def set_path(scene, toks, value, path):
    """Set a scene path in the scene dict ``scene`` (in place). ``settings`` alone merges a mapping
    into the settings; an index sets one component of a vector (defaults filled in)."""
    box, key = _container(scene, toks, path)
    idx = toks[-1][1]
    if toks[0][0] == "settings" and len(toks) == 1:
        if not isinstance(value, dict):
            raise StudyError(path, f"a value of the settings axis is a mapping of settings, got {value!r}")
        merged = dict(box.get("settings") or {})
        for k, v in value.items():
            if k == "penalty" and isinstance(v, dict):
                merged["penalty"] = {**(merged.get("penalty") or {}), **v}
            else:
                merged[k] = v
        box["settings"] = merged
        return
    if idx is None:
        box[key] = copy.deepcopy(value)
        return
    default = [0.0, 0.0, -9.81] if toks[0][0] == "gravity" else VECTOR_DEFAULT[key]
    vec = list(box.get(key, default))
    vec[idx] = value
    box[key] = vec


def load_study(source, name=None):
    """A validated ``Study`` from a study file path, a shipped study's name (``config/studies``) or
    a dict of the same content. Raises ``StudyError`` naming the place (``study.grid['settings.dt']``)
    and the reason."""
    if isinstance(source, Study):
        return source
    if isinstance(source, dict):
        return Study(source, name=name)
    import yaml

    path = resolve_study(os.fspath(source))
    try:
        with open(path) as fh:
            data = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        raise StudyError("study", f"{path}: not valid YAML: {exc}") from None
    return Study(data, where_dir=os.path.dirname(os.path.abspath(path)),
                 name=name or os.path.splitext(os.path.basename(path))[0])


__all__ = ["Study", "StudyError", "load_study", "list_studies", "resolve_study", "run_seed", "run_id",
           "set_path", "get_path", "parse_path"]
