"""The input contract, table-driven (issue #11): NaN, ±inf, 1e300, 0, negative, wrong type, wrong
shape and empty thrown at every argument of every public call. Each value is either refused —
``ContactSimError`` whose message names the argument, the world bit-identical afterwards — or
(listed per argument) accepted, leaving a finite world. No call may hang (pytest-timeout)."""
import copy
import math
import warnings
from dataclasses import dataclass, field, is_dataclass

import numpy as np
import pytest

import contact_sim as cs
from contact_sim.collision import collide_pairs
from contact_sim.response.models import ContactModelWarning
from contact_sim.settings import Penalty
from contact_sim.shapes import Shape
from contact_sim.validate import Declared, Flag, Tristate

pytestmark = pytest.mark.timeout(20)

NAN, INF = float("nan"), float("inf")
I = (0.0, 0.0, 0.0, 1.0)
TET = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def _make_world(ground=True):
    w = cs.World(materials={"rubber": cs.Material(restitution=0.8, friction=0.3)})
    if ground:
        w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 0.1], velocity=[0.5, 0, 0], material="rubber")
    w.add_body("paddle", cs.Box([0.4, 0.4, 0.05]), kind="kinematic", position=[1, 0, 0.5])
    w.add_body("rock", cs.Convex(TET), density=500.0, position=[-1, 0, 0], angular_velocity=[0, 0, 1])
    w.mark_initial()
    w.set_pose("paddle", [1, 0, 0.5], I, stamp=0.0)
    w.step()
    assert len(w.contacts) or not ground   # contacts, warm-start data, caches: all must survive a refusal
    return w


_TEMPLATE = _make_world()


def snapshot(obj):
    """Everything reachable from ``obj`` as comparable values: arrays by dtype, shape and bytes
    (bit-identical, NaN included), floats by repr, other objects (shapes, caches) by identity."""
    if isinstance(obj, np.ndarray):
        return ("array", obj.dtype.str, obj.shape, obj.tobytes())
    if isinstance(obj, np.generic):
        return ("scalar", obj.dtype.str, obj.tobytes())
    if isinstance(obj, float):
        return ("float", repr(obj))
    if obj is None or isinstance(obj, (bool, int, str)):
        return obj
    if isinstance(obj, (list, tuple)):
        return (type(obj).__name__, tuple(snapshot(x) for x in obj))
    if isinstance(obj, dict):
        return ("dict", tuple((repr(k), snapshot(v)) for k, v in obj.items()))
    if isinstance(obj, Declared):
        return (type(obj).__name__, snapshot(obj.as_dict()))
    if isinstance(obj, Shape):
        return ("shape", id(obj))
    if is_dataclass(obj) or type(obj).__name__ == "_State":
        return (type(obj).__name__, snapshot(vars(obj)))
    return ("object", type(obj).__name__, id(obj))


def finite_state(w):
    s = w.s
    return all(np.isfinite(a).all() for a in (s.pos, s.vel, s.quat, s.omega)) and math.isfinite(w.energy())


# ---------------------------------------------------------------------------- junk
def scalar_junk():
    return {"nan": NAN, "inf": INF, "-inf": -INF, "1e300": 1e300, "0": 0, "negative": -1.0, "wrong type": "x",
            "None": None, "bool": True, "wrong shape": [1.0], "empty": []}


def vector_junk(good):
    good = list(map(float, good))

    def at0(x):
        return [x] + good[1:]

    return {"nan": at0(NAN), "inf": at0(INF), "-inf": at0(-INF), "1e300": at0(1e300), "0": [0.0] * len(good),
            "negative": [-x for x in good], "wrong type": "x", "None": None, "bool": [True] + good[1:],
            "wrong shape": good[:-1], "nested": [good], "empty": []}


def rows_junk(good):
    good = np.array(good, float)

    def last(x):
        a = good.copy()
        a[-1, 0] = x
        return a.tolist()

    return {"nan": last(NAN), "inf": last(INF), "-inf": last(-INF), "1e300": last(1e300),
            "0": np.zeros_like(good).tolist(), "negative": (-good).tolist(), "wrong type": "x", "None": None,
            "bool": [[True] + r[1:] for r in good.tolist()], "wrong shape": good[:, :-1].tolist(),
            "flat": good.ravel().tolist(), "empty": []}


@dataclass
class Arg:
    """One argument of one public call: ``run(world, value)`` makes the call with ``value`` there;
    ``ok`` are the junk kinds that are valid input for it; ``names``: one must be in the message."""

    call: str
    junk: dict
    run: object
    names: tuple
    ok: frozenset = field(default_factory=frozenset)
    world: bool = True     # the call acts on a world (checked bit-identical after a refusal)


def _ok(*kinds):
    return frozenset(kinds)


ZERO_OK_SETTINGS = {"solver_tolerance", "contact_margin", "split_beta", "split_slop", "direct_max_contacts",
                    "kinematic_stiffness"}


def _shape_then_add(make, kind="dynamic"):
    """Build a shape with the value; when built, add it to a world (sizes are world-relative)."""
    def run(w, v):
        w.add_body("new", make(v), kind=kind)
    return run


def _table():
    t = []
    # --- Settings, Penalty, Material: constructor and later assignment, every declared field
    for name, rule in cs.Settings.rules().items():
        ok = _ok("0") if name in ZERO_OK_SETTINGS else _ok("bool") if isinstance(rule, (Tristate, Flag)) else _ok()
        t.append(Arg(f"Settings({name}=)", scalar_junk(), lambda w, v, n=name: cs.Settings(**{n: v}),
                     (f"settings.{name}",), ok, world=False))
        t.append(Arg(f"world.settings.{name} =", scalar_junk(), lambda w, v, n=name: setattr(w.settings, n, v),
                     (f"settings.{name}",), ok))
    for name in Penalty.rules():
        t.append(Arg(f"Penalty({name}=)", scalar_junk(), lambda w, v, n=name: Penalty(**{n: v}),
                     (f"penalty.{name}",), _ok("0") if name == "damping" else _ok(), world=False))
    for name in cs.Material.rules():
        ok = {"restitution": _ok("0"), "friction": _ok("0"), "static_friction": _ok("None"), "stiffness": _ok("None"),
              "damping_ratio": _ok("0")}[name]
        t.append(Arg(f"Material({name}=)", scalar_junk(), lambda w, v, n=name: cs.Material(**{n: v}),
                     (f"material.{name}",), ok, world=False))
    # --- World
    t.append(Arg("World(gravity=)", vector_junk([0, 0, -9.81]), lambda w, v: cs.World(gravity=v), ("gravity",),
                 _ok("0", "negative"), world=False))
    t.append(Arg("World(settings=)", scalar_junk(), lambda w, v: cs.World(settings=v), ("settings",), _ok("None"),
                 world=False))
    t.append(Arg("World(materials=)", scalar_junk(), lambda w, v: cs.World(materials=v), ("materials",),
                 _ok("None"), world=False))
    t.append(Arg("World(materials={m: })", scalar_junk(), lambda w, v: cs.World(materials={"m": v}),
                 ("materials['m']",), world=False))
    # --- shapes: refused when built, or when added to a world (its size bounds)
    names = ("plane.normal",)
    # a normal is a direction: any non-zero finite vector, normalised (1e300 too)
    t.append(Arg("Plane(normal=)", vector_junk([0, 0, 1]), _shape_then_add(lambda v: cs.Plane(v), "static"), names,
                 _ok("negative", "1e300")))
    t.append(Arg("Plane(offset=)", scalar_junk(), _shape_then_add(lambda v: cs.Plane(offset=v), "static"),
                 ("plane.offset",), _ok("0", "negative")))
    t.append(Arg("Sphere(radius=)", scalar_junk(), _shape_then_add(cs.Sphere), ("sphere.radius",)))
    t.append(Arg("Box(size=)", vector_junk([1, 2, 3]), _shape_then_add(cs.Box), ("box.size",)))
    t.append(Arg("Convex(points=)", rows_junk(TET), _shape_then_add(cs.Convex), ("convex.points",),
                 _ok("negative")))
    t.append(Arg("TriMesh(vertices=)", rows_junk(TET), _shape_then_add(lambda v: cs.TriMesh(v, [[0, 1, 2]]), "static"),
                 ("mesh.vertices",), _ok("negative")))
    t.append(Arg("TriMesh(faces=)", rows_junk([[0, 1, 2], [0, 1, 3]]),
                 _shape_then_add(lambda v: cs.TriMesh(TET, v), "static"), ("mesh.faces",)))
    # --- add_body
    good = {"name": "new", "shape": cs.Sphere(0.1)}

    def add(key, **base):
        def run(w, v):
            kw = dict(good, **base)
            kw[key] = v
            w.add_body(kw.pop("name"), kw.pop("shape"), **kw)
        return run

    t.append(Arg("add_body(name=)", scalar_junk(), add("name"), (".name",), _ok("wrong type")))   # "x" is a name
    t.append(Arg("add_body(shape=)", scalar_junk(), add("shape"), ("shape",)))
    for key in ("kind", "model", "material"):
        t.append(Arg(f"add_body({key}=)", scalar_junk(), add(key), (f".{key}",)))
    t.append(Arg("add_body(mass=)", scalar_junk(), add("mass"), (".mass",), _ok("None")))
    t.append(Arg("add_body(density=)", scalar_junk(), add("density"), (".density",), _ok("None")))
    for key in ("group", "mask"):
        t.append(Arg(f"add_body({key}=)", scalar_junk(), add(key), (f".{key}",), _ok("0")))
    for key, g, ok in (("position", [0, 0, 2], _ok("0", "negative")), ("orientation", I, _ok("negative")),
                       ("velocity", [1, 0, 0], _ok("0", "negative")), ("angular_velocity", [0, 0, 1], _ok("0", "negative"))):
        t.append(Arg(f"add_body({key}=)", vector_junk(g), add(key), (f".{key}",), ok))
    # --- set_pose, set_poses, set_state (the paddle was posed at stamp 0; the world is at 1/60 s)
    pose = {"name": "paddle", "position": [1, 0, 0.6], "orientation": I, "stamp": 0.5}

    def set_pose(key):
        def run(w, v):
            kw = dict(pose, **{key: v})
            w.set_pose(kw["name"], kw["position"], kw["orientation"], kw["stamp"])
        return run

    t.append(Arg("set_pose(name=)", scalar_junk(), set_pose("name"), ("unknown body",)))
    t.append(Arg("set_pose(position=)", vector_junk(pose["position"]), set_pose("position"), (".position",),
                 _ok("0", "negative")))
    t.append(Arg("set_pose(orientation=)", vector_junk(I), set_pose("orientation"), (".orientation",), _ok("negative")))
    t.append(Arg("set_pose(stamp=)", scalar_junk(), set_pose("stamp"), (".stamp",), _ok("None")))
    batch = {"names": ["paddle"], "positions": [[1, 0, 0.6]], "orientations": [I], "stamp": 0.5}

    def set_poses(key):
        def run(w, v):
            kw = dict(batch, **{key: v})
            w.set_poses(kw["names"], kw["positions"], kw["orientations"], kw["stamp"])
        return run

    t.append(Arg("set_poses(names=)", scalar_junk(), set_poses("names"), ("names", "unknown body")))
    t.append(Arg("set_poses(positions=)", rows_junk(batch["positions"]), set_poses("positions"), ("position",),
                 _ok("0", "negative")))
    t.append(Arg("set_poses(orientations=)", rows_junk(batch["orientations"]), set_poses("orientations"),
                 ("orientation",), _ok("negative")))
    t.append(Arg("set_poses(stamp=)", scalar_junk(), set_poses("stamp"), (".stamp",), _ok("None")))
    t.append(Arg("set_state(name=)", scalar_junk(), lambda w, v: w.set_state(v, velocity=[0, 0, 0]),
                 ("unknown body",)))
    for key, g, ok in (("position", [0, 0, 2], _ok("0", "negative", "None")),
                       ("orientation", I, _ok("negative", "None")),
                       ("velocity", [1, 0, 0], _ok("0", "negative", "None")),
                       ("angular_velocity", [0, 0, 1], _ok("0", "negative", "None"))):
        t.append(Arg(f"set_state({key}=)", vector_junk(g), lambda w, v, k=key: w.set_state("rock", **{k: v}),
                     (f".{key}",), ok))
    # --- step
    t.append(Arg("step(dt=)", scalar_junk(), lambda w, v: w.step(v), ("dt",), _ok("None")))
    # --- collide, collide_pairs (stateless)
    col = {"shape_a": cs.Sphere(0.5), "pose_a": ((0, 0, 0.4), I), "shape_b": cs.Plane(), "pose_b": ((0, 0, 0), I),
           "margin": 0.0, "bounding_volume": "auto", "stats": False, "settings": None}

    def collide(key, part=None):
        def run(w, v):
            kw = dict(col)
            kw[key] = v if part is None else ((v, kw[key][1]) if part == 0 else (kw[key][0], v))
            cs.collide(**kw)
        return run

    for key in ("shape_a", "shape_b", "pose_a", "pose_b", "bounding_volume"):
        t.append(Arg(f"collide({key}=)", scalar_junk(), collide(key), (key,), world=False))
    t.append(Arg("collide(stats=)", scalar_junk(), collide("stats"), ("stats",), _ok("bool"), world=False))
    t.append(Arg("collide(margin=)", scalar_junk(), collide("margin"), ("margin",), _ok("0"), world=False))
    t.append(Arg("collide(settings=)", scalar_junk(), collide("settings"), ("settings",), _ok("None"), world=False))
    for key in ("pose_a", "pose_b"):
        t.append(Arg(f"collide({key}.position=)", vector_junk(col[key][0]), collide(key, 0), (f"{key}.position",),
                     _ok("0", "negative"), world=False))
        # collide normalises any non-zero quaternion (1e300 too)
        t.append(Arg(f"collide({key}.orientation=)", vector_junk(I), collide(key, 1), (f"{key}.orientation",),
                     _ok("negative", "1e300"), world=False))
    pairs = {"shapes": [cs.Sphere(0.5), cs.Box([1, 1, 1])], "positions": [[0, 0, 0], [0, 0, 0.9]],
             "orientations": [I, I], "pairs": [[1, 0]], "margin": 0.0, "bounding_volume": "auto", "settings": None}

    def many(key):
        def run(w, v):
            cs.collision.collide_pairs(**dict(pairs, **{key: v}))
        return run

    t.append(Arg("collide_pairs(shapes=)", scalar_junk(), many("shapes"), ("shapes",), world=False))
    t.append(Arg("collide_pairs(positions=)", rows_junk(pairs["positions"]), many("positions"), ("positions",),
                 _ok("0", "negative"), world=False))
    t.append(Arg("collide_pairs(orientations=)", rows_junk(pairs["orientations"]), many("orientations"),
                 ("orientations",), _ok("negative", "1e300"), world=False))
    t.append(Arg("collide_pairs(pairs=)", rows_junk(pairs["pairs"]), many("pairs"), ("pairs",), _ok("empty"),
                 world=False))
    t.append(Arg("collide_pairs(margin=)", scalar_junk(), many("margin"), ("margin",), _ok("0"), world=False))
    t.append(Arg("collide_pairs(bounding_volume=)", scalar_junk(), many("bounding_volume"), ("bounding_volume",),
                 world=False))
    return t


TABLE = _table()
CASES = [pytest.param(a, kind, id=f"{a.call}-{kind}") for a in TABLE for kind in a.junk]


@pytest.mark.parametrize("arg, kind", CASES)
def test_every_argument_refuses_junk_by_name_and_changes_nothing(arg, kind):
    world = copy.deepcopy(_TEMPLATE)
    before = snapshot(vars(world))
    value = copy.deepcopy(arg.junk[kind])
    if kind in arg.ok:
        arg.run(world, value)
        assert finite_state(world)
        return
    with pytest.raises(cs.ContactSimError) as info:
        arg.run(world, value)
    msg = str(info.value)
    assert any(n in msg for n in arg.names), (arg.call, kind, msg)
    if arg.world:
        assert snapshot(vars(world)) == before, (arg.call, kind, msg)


def test_the_table_covers_every_public_call_and_declared_field():
    calls = {a.call.split("(")[0].split(".")[0] for a in TABLE}
    assert {"Settings", "Penalty", "Material", "World", "Plane", "Sphere", "Box", "Convex", "TriMesh", "add_body",
            "set_pose", "set_poses", "set_state", "step", "collide", "collide_pairs", "world"} <= calls
    set_fields = {a.call for a in TABLE if a.call.startswith("Settings(")}
    assert set_fields == {f"Settings({n}=)" for n in cs.Settings.rules()}
    assert len(CASES) > 500


# ---------------------------------------------------------------------------- scene files, the same rules
SCENE = {"settings": {"dt": 0.01}, "materials": {"rubber": {"restitution": 0.5}},
         "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}},
                    {"name": "ball", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0,
                     "position": [0, 0, 1], "material": "rubber"}]}


@pytest.mark.parametrize("path, value, ok", [
    ("gravity", [0, 0, 1e300], False), ("gravity", "x", False),
    ("settings.dt", NAN, False), ("settings.dt", 1e300, False), ("settings.max_position", -1, False),
    ("settings.solver_iterations", 0, False), ("settings.toi", 0, False),
    ("materials.rubber.restitution", NAN, False), ("materials.rubber.friction", [0.5], False),
    ("bodies.1.mass", 1e300, False), ("bodies.1.mass", True, False), ("bodies.1.position", [1e300, 0, 0], False),
    ("bodies.1.velocity", [1e200, 0, 0], False), ("bodies.1.material", ["rubber"], False),
    ("bodies.1.shape.radius", 1e-100, False), ("bodies.1.shape.radius", [0.1], False),
    ("bodies.1.position", [-5, 0, 0], True), ("settings.contact_margin", 0, True),
])
def test_scene_values_follow_the_same_rules(path, value, ok):
    d = copy.deepcopy(SCENE)
    node, keys = d, path.split(".")
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    node[keys[-1]] = value
    if ok:
        assert finite_state(cs.load_scene(d))
        return
    where = path.replace(".1.", "[1].").replace("bodies.1", "bodies[1]")
    with pytest.raises(cs.SceneError) as info:
        cs.load_scene(d)
    assert str(info.value).startswith(where), str(info.value)


def test_collide_pairs_with_no_pairs_is_empty():
    c, st = collide_pairs([cs.Sphere(1.0)], [[0, 0, 0]], [I], [])
    assert len(c) == 0 and st.candidate_pairs == 0


# ---------------------------------------------------------------------------- random sequences of calls
# This checks the contract, not the physics. Two engine failures found by it, both on main before
# this work and reported apart from this issue, are kept out of the way: valid draws stay moderate
# (up to 50 m, m/s, kg; steps up to 30 ms) and the world uses next-step time of impact, since the
# fractional time-of-impact search can take minutes for some fast or spinning bodies; and the world
# has no static ground, since a kinematic body touching a static one turns the split-impulse solve
# NaN (World.step now refuses that step with EngineError and keeps the world as it was).
def _number(rng):
    """Mostly sane, sometimes junk: what a fuzzer (or a bad upstream) sends."""
    if rng.random() < 0.1:
        return [NAN, INF, -INF, 1e300, -1e300, 0.0, "x", None, True, [1.0]][rng.integers(10)]
    return float(rng.choice([-1, 1]) * 10.0 ** rng.uniform(-3, 1.7))


def _step(rng):
    dt = _number(rng)
    return dt * 1e-3 if isinstance(dt, float) else dt


def _size(rng):
    return _number(rng) if rng.random() < 0.2 else float(rng.uniform(0.05, 2.0))


def _vec(rng, n=3, draw=None):
    if rng.random() < 0.05:
        return [[], "x", None, [1.0] * (n - 1)][rng.integers(4)]
    return [(draw or _number)(rng) if rng.random() < 0.3 else float(rng.uniform(-2, 2)) for _ in range(n)]


def _free_world():
    """The table's world without its ground and with next-step time of impact (see above)."""
    w = _make_world(ground=False)
    w.settings.toi = "next_step"
    return w


_FREE = _free_world()


def random_calls(seed, n=60, trace=None, world=None):
    """Valid and invalid calls interleaved on one world; checks the contract after each and
    returns the counts ``(accepted, refused)``. ``trace`` (a list) gets each call; ``world`` (a
    list) the world (to replay a failure)."""
    rng = np.random.default_rng(seed)
    w = copy.deepcopy(_FREE)
    if world is not None:
        world.append(w)
    fields = list(cs.Settings.rules())
    stamp = [0.0]

    def add():
        make, size = (cs.Sphere, _size(rng)) if rng.random() < 0.5 else (cs.Box, [_size(rng) for _ in range(3)])
        kw = {"mass": _number(rng) if rng.random() < 0.5 else None, "position": _vec(rng), "velocity": _vec(rng),
              "angular_velocity": _vec(rng)}
        return "add_body", (f"b{rng.integers(1 << 30)}", make, size), kw

    def pose():
        stamp[0] += float(rng.choice([0.01, 1e-9, -1.0, 0.5]))
        return "set_pose", ("paddle", _vec(rng), I if rng.random() < 0.8 else _vec(rng, 4), stamp[0]), {}

    ops = [add, pose,
           lambda: ("set_state", ("ball",), {"position": _vec(rng) if rng.random() < 0.5 else None,
                                             "velocity": _vec(rng)}),
           lambda: ("set_state", ("rock",), {"angular_velocity": _vec(rng), "orientation": _vec(rng, 4)}),
           lambda: ("step", (None if rng.random() < 0.5 else _step(rng),), {}),
           lambda: ("settings", (fields[rng.integers(len(fields))], _number(rng)), {}),
           lambda: ("settings", ("dt", float(10.0 ** rng.uniform(-4, -1.5))), {})]
    accepted = refused = 0
    for _ in range(n):
        name, args, kw = ops[rng.integers(len(ops))]()
        call = ((lambda *a: setattr(w.settings, *a)) if name == "settings" else
                (lambda n, make, size, **k: w.add_body(n, make(size), **k)) if name == "add_body" else
                getattr(w, name))
        before = snapshot(vars(w))
        if trace is not None:
            trace.append((name, args, kw))
        try:
            with warnings.catch_warnings():   # preflight advice (mass ratio, tunnelling) is not refusal
                warnings.simplefilter("ignore", ContactModelWarning)
                call(*args, **kw)
        except cs.ContactSimError:
            refused += 1
            assert snapshot(vars(w)) == before
        else:
            accepted += 1
            assert finite_state(w)
    return accepted, refused


@pytest.mark.parametrize("seed", range(6))
def test_random_sequences_of_calls_keep_the_contract(seed):
    """An accepted call leaves the world finite, a refused one leaves it bit-identical, and
    nothing raises anything but ContactSimError, whatever came before."""
    accepted, refused = random_calls(seed)
    assert accepted > 5 and refused > 5
