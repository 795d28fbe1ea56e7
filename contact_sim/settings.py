"""World settings and materials, validated once when a world or scene is built."""
from dataclasses import asdict, dataclass, field

import numpy as np

from .errors import SceneError

TOI_MODES = ("auto", "next_step", "fractional", "swept")
RESPONSES = ("auto", "kinematic", "penalty", "impulse")
BOUNDING_VOLUMES = ("auto", "sphere", "aabb", "obb", "slabs", "hull")
COMBINE_RULES = ("average", "min", "max", "multiply", "geometric")


@dataclass
class Penalty:
    stiffness: float = 1.0e5   # N/m
    damping: float = 1.0e2     # N·s/m


@dataclass
class Settings:
    """Model choices of a world. ``auto`` lets the engine pick the cheapest adequate model."""

    dt: float = 1.0 / 60.0
    toi: str = "auto"                 # next_step | fractional | swept | auto
    response: str = "auto"            # kinematic | penalty | impulse | auto
    friction: object = "auto"         # true | false | auto
    resting: object = "auto"          # resting-contact solver: true | false | auto
    solver_iterations: int = 20
    solver_tolerance: float = 1e-9
    max_impacts_per_step: int = 8
    contact_margin: float = 1e-4      # m: closer than this counts as touching
    bounding_volume: str = "auto"     # sphere | aabb | obb | slabs | hull | auto
    combine: str = "average"          # how two materials' coefficients combine
    quaternion_tolerance: float = 1e-3  # |‖q‖ − 1| accepted (and normalised) in given poses
    split_beta: float = 0.5           # fraction of a penetration removed per step (split impulse)
    mass_ratio_limit: float = 100.0   # preflight warning above this mass ratio between touching bodies
    penalty: Penalty = field(default_factory=Penalty)

    def as_dict(self):
        return asdict(self)


@dataclass
class Material:
    restitution: float = 0.5
    friction: float = 0.5
    static_friction: float = None  # defaults to ``friction``

    def __post_init__(self):
        if self.static_friction is None:
            self.static_friction = self.friction


DEFAULT_MATERIAL = "default"


def _number(value, path, lo=None, hi=None, lo_open=False, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(path, f"must be a number, got {value!r}")
    if integer and int(value) != value:
        raise SceneError(path, f"must be a whole number, got {value!r}")
    x = int(value) if integer else float(value)
    if not np.isfinite(x):
        raise SceneError(path, f"must be finite, got {value!r}")
    if lo is not None and (x <= lo if lo_open else x < lo):
        raise SceneError(path, f"must be {'>' if lo_open else '>='} {lo}, got {value!r}")
    if hi is not None and x > hi:
        raise SceneError(path, f"must be <= {hi}, got {value!r}")
    return x


def _choice(value, path, options):
    if value not in options:
        raise SceneError(path, f"must be one of {', '.join(map(str, options))}; got {value!r}")
    return value


def _tristate(value, path):
    if value in (True, False, "auto"):
        return value
    raise SceneError(path, f"must be true, false or auto; got {value!r}")


def check_keys(d, path, allowed):
    if not isinstance(d, dict):
        raise SceneError(path, f"must be a mapping, got {type(d).__name__}")
    unknown = sorted(set(d) - set(allowed))
    if unknown:
        where = f"{path}.{unknown[0]}" if path else str(unknown[0])
        raise SceneError(where, f"unknown key (allowed: {', '.join(sorted(allowed))})")


def parse_settings(d, path="settings"):
    """Validated ``Settings`` from a mapping (scene ``settings:``); unknown keys are refused."""
    d = {} if d is None else d
    s = Settings()
    check_keys(d, path, set(s.as_dict()))
    if "dt" in d:
        s.dt = _number(d["dt"], f"{path}.dt", lo=0, lo_open=True)
    if "toi" in d:
        s.toi = _choice(d["toi"], f"{path}.toi", TOI_MODES)
    if "response" in d:
        s.response = _choice(d["response"], f"{path}.response", RESPONSES)
    if "friction" in d:
        s.friction = _tristate(d["friction"], f"{path}.friction")
    if "resting" in d:
        s.resting = _tristate(d["resting"], f"{path}.resting")
    if "solver_iterations" in d:
        s.solver_iterations = _number(d["solver_iterations"], f"{path}.solver_iterations", lo=1, integer=True)
    if "solver_tolerance" in d:
        s.solver_tolerance = _number(d["solver_tolerance"], f"{path}.solver_tolerance", lo=0)
    if "max_impacts_per_step" in d:
        s.max_impacts_per_step = _number(d["max_impacts_per_step"], f"{path}.max_impacts_per_step", lo=1, integer=True)
    if "contact_margin" in d:
        s.contact_margin = _number(d["contact_margin"], f"{path}.contact_margin", lo=0)
    if "bounding_volume" in d:
        s.bounding_volume = _choice(d["bounding_volume"], f"{path}.bounding_volume", BOUNDING_VOLUMES)
    if "combine" in d:
        s.combine = _choice(d["combine"], f"{path}.combine", COMBINE_RULES)
    if "quaternion_tolerance" in d:
        s.quaternion_tolerance = _number(d["quaternion_tolerance"], f"{path}.quaternion_tolerance", lo=0, lo_open=True)
    if "split_beta" in d:
        s.split_beta = _number(d["split_beta"], f"{path}.split_beta", lo=0, hi=1)
    if "mass_ratio_limit" in d:
        s.mass_ratio_limit = _number(d["mass_ratio_limit"], f"{path}.mass_ratio_limit", lo=1)
    if "penalty" in d:
        p = d["penalty"]
        check_keys(p, f"{path}.penalty", {"stiffness", "damping"})
        if "stiffness" in p:
            s.penalty.stiffness = _number(p["stiffness"], f"{path}.penalty.stiffness", lo=0, lo_open=True)
        if "damping" in p:
            s.penalty.damping = _number(p["damping"], f"{path}.penalty.damping", lo=0)
    return s


def parse_material(d, path):
    check_keys(d, path, {"restitution", "friction", "static_friction"})
    m = Material()
    if "restitution" in d:
        m.restitution = _number(d["restitution"], f"{path}.restitution", lo=0, hi=1)
    if "friction" in d:
        m.friction = _number(d["friction"], f"{path}.friction", lo=0)
    m.static_friction = m.friction
    if "static_friction" in d:
        m.static_friction = _number(d["static_friction"], f"{path}.static_friction", lo=0)
        if m.static_friction < m.friction:
            raise SceneError(f"{path}.static_friction",
                             f"must be >= friction ({m.friction}), got {m.static_friction}")
    return m


def combine(a, b, rule):
    """Combine two materials' coefficients ``(K,)`` elementwise by ``rule`` (average, min, max,
    multiply, geometric). Two equal coefficients always give exactly that value — under
    ``multiply`` too, where Bullet would square them — so a material meeting itself behaves as
    its own coefficients say."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if rule == "average":
        out = 0.5 * (a + b)
    elif rule == "min":
        out = np.minimum(a, b)
    elif rule == "max":
        out = np.maximum(a, b)
    elif rule == "multiply":
        out = a * b
    elif rule == "geometric":
        out = np.sqrt(a * b)
    else:
        raise ValueError(f"unknown combine rule {rule!r}")
    return np.where(a == b, a, out)
