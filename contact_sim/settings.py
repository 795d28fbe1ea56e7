"""World settings and materials: each field declared once, with its rule.

A field is one ``declare(default, rule, doc)`` line in ``Settings`` (or ``Material``,
``Penalty``); that rule checks it in the constructor, on every later assignment
(``world.settings.dt = x``), and in scene files (``parse_settings`` / ``parse_material`` build
from the same table), so code and scenes obey the same rules. Adding a setting is one line.
Bounds may name another setting (``le="max_step"``): the world bounds below are read that way.
"""
import math
from dataclasses import dataclass

import numpy as np

from .constants import LENGTH_LIMIT
from .jit import njit
from .validate import Choice, Declared, Flag, Nested, Number, Tristate, build, declare

TOI_MODES = ("auto", "next_step", "fractional", "swept")
RESPONSES = ("auto", "kinematic", "penalty", "impulse")
BOUNDING_VOLUMES = ("auto", "sphere", "aabb", "obb", "slabs", "hull")
COMBINE_RULES = ("average", "min", "max", "multiply", "geometric")
SOLVER_METHODS = ("auto", "direct", "gs", "jacobi")
#: upper bound of the numerical knobs whose exact size does not matter beyond a point: it only
#: keeps their products finite (a stiffness times a step, a ratio of masses)
_HUGE = 1e15


@dataclass(eq=True)
class Penalty(Declared):
    """Spring and damper of the penalty response."""

    LABEL = "settings.penalty"

    stiffness: float = declare(1.0e5, Number(gt=0, le=_HUGE, unit="N/m"), "N/m")
    damping: float = declare(1.0e2, Number(ge=0, le=_HUGE, unit="N·s/m"), "N·s/m")
    friction_velocity: float = declare(1.0e-4, Number(gt=0, le=_HUGE, unit="m/s"),
                                       "m/s: regularised Coulomb friction is viscous below this sliding speed")


@dataclass(eq=True)
class Settings(Declared):
    """Model choices and world bounds of a world. ``auto`` lets the engine pick the cheapest
    adequate model. Every field is checked when set (``ContactSimError`` naming it)."""

    LABEL = "settings"

    dt: float = declare(1.0 / 60.0, Number(gt=0, le="max_step", unit="s"), "s: default step size")
    toi: str = declare("auto", Choice(TOI_MODES), "time of impact: next_step | fractional | swept | auto")
    response: str = declare("auto", Choice(RESPONSES), "kinematic | penalty | impulse | auto")
    friction: object = declare("auto", Tristate(), "true | false | auto")
    resting: object = declare("auto", Tristate(), "resting-contact solver: true | false | auto")
    solver_iterations: int = declare(100, Number(ge=1, le=100_000, integer=True))
    solver_tolerance: float = declare(1e-9, Number(ge=0, le="max_speed", unit="m/s"),
                                      "m/s: residual at which the solver stops")
    solver_method: str = declare("auto", Choice(SOLVER_METHODS),
                                 "auto (exact active set up to direct_max_contacts, compiled Gauss–Seidel above) | "
                                 "direct | gs | jacobi (mass splitting)")
    direct_max_contacts: int = declare(500, Number(ge=0, le=100_000, integer=True),
                                       "the exact active-set solve up to this many contacts (stacks, pyramids), "
                                       "Gauss–Seidel above")
    speculative: bool = declare(True, Flag(), "next_step: speculative contacts (pairs closing within the step "
                                "are stopped exactly at touching)")
    split_slop: float = declare(1e-7, Number(ge=0, le="max_size", unit="m"),
                                "m: penetrations up to this are left to the resting solve (round-off of resting "
                                "contacts; correcting them costs a whole solve per step), and the position "
                                "correction's solve stops once a sweep moves no contact by more than this")
    max_impacts_per_step: int = declare(128, Number(ge=1, le=10_000, integer=True),
                                        "exact times of impact (fractional, swept; next_step's fast bodies): "
                                        "events handled per step, in time order, the rest of the step then "
                                        "taken without a search (a light body chattering between a wall and "
                                        "one 1000 times heavier takes about pi*sqrt(1000) = 99)")
    contact_margin: float = declare(1e-4, Number(ge=0, le="max_size", unit="m"),
                                    "m: closer than this counts as touching")
    bounding_volume: str = declare("auto", Choice(BOUNDING_VOLUMES), "sphere | aabb | obb | slabs | hull | auto")
    combine: str = declare("average", Choice(COMBINE_RULES), "how two materials' coefficients combine")
    quaternion_tolerance: float = declare(1e-3, Number(gt=0, le=1),
                                          "|‖q‖ − 1| accepted (and normalised) in given poses")
    split_beta: float = declare(0.5, Number(ge=0, le=1), "fraction of a penetration removed per step")
    split_max_speed: float = declare(3.0, Number(gt=0, le="max_speed", unit="m/s"),
                                     "m/s: fastest the position correction moves a body beyond what its own "
                                     "overlap needs (split_beta of it a step); Box2D's maximum push-out speed")
    mass_ratio_limit: float = declare(100.0, Number(ge=1, le=_HUGE),
                                      "preflight warning above this mass ratio between touching bodies")
    penalty: Penalty = declare(Penalty, Nested(Penalty), "spring and damper of the penalty response")
    kinematic_stiffness: float = declare(1.0e5, Number(ge=0, le=_HUGE, unit="N/m"),
                                         "N/m: stiffness of a contact with a kinematic body whose materials give "
                                         "none (compliant contact: a robot's fingers hold what they squeeze, 1 mm "
                                         "deep with 100 N; a 1 kg part resting on one sinks 0.1 mm); 0: rigid")
    # world bounds: finite inputs beyond them are refused by name (BoundsError)
    max_position: float = declare(1e4, Number(gt=0, le=LENGTH_LIMIT, unit="m"),
                                  "m: every coordinate of a body origin or pose within ±this", world_bound=True)
    max_speed: float = declare(1e4, Number(gt=0, le=LENGTH_LIMIT, unit="m/s"),
                               "m/s: linear speed given to a body or implied by successive poses", world_bound=True)
    max_angular_speed: float = declare(1e4, Number(gt=0, le=LENGTH_LIMIT, unit="rad/s"),
                                       "rad/s: the same for angular speed", world_bound=True)
    max_step: float = declare(1.0, Number(gt=0, le=1e6, unit="s"),
                              "s: largest step size (settings.dt, step(dt))", world_bound=True)
    min_size: float = declare(1e-6, Number(ge=1e-12, le="max_size", unit="m"),
                              "m: length tolerance: the thinnest a shape may be", world_bound=True)
    max_size: float = declare(1e4, Number(gt=0, le=LENGTH_LIMIT, unit="m"),
                              "m: farthest a shape may reach from its origin; largest contact margin",
                              world_bound=True)
    min_mass: float = declare(1e-9, Number(ge=1e-30, le="max_mass", unit="kg"),
                              "kg: lightest dynamic body", world_bound=True)
    max_mass: float = declare(1e9, Number(gt=0, le=1e30, unit="kg"), "kg: heaviest dynamic body", world_bound=True)


@dataclass(eq=True)
class Material(Declared):
    """Contact coefficients of a material; ``static_friction`` defaults to ``friction``. Checked
    like ``Settings``; a later assignment that would put ``friction`` above ``static_friction`` is
    refused (set ``static_friction`` first)."""

    LABEL = "material"

    restitution: float = declare(0.5, Number(ge=0, le=1), "0 (no bounce) to 1 (elastic)")
    friction: float = declare(0.5, Number(ge=0, le=100), "Coulomb coefficient while sliding")
    static_friction: float = declare(None, Number(ge="friction", le=100, optional=True),
                                     "coefficient at rest, >= friction (default: friction)")
    stiffness: float = declare(None, Number(gt=0, le=_HUGE, optional=True, unit="N/m"),
                               "N/m: compliant contact, force = stiffness × overlap (+ damping); none: rigid")
    damping_ratio: float = declare(1.0, Number(ge=0, le=_HUGE),
                                   "a compliant contact's damping as a fraction of critical (1: critical)")

    def _complete(self):
        if self.__dict__.get("static_friction") is None:
            object.__setattr__(self, "static_friction", self.friction)


DEFAULT_MATERIAL = "default"


def parse_settings(d, path="settings"):
    """Validated ``Settings`` from a mapping (scene ``settings:``); unknown keys are refused."""
    return build(Settings, d, path)


def parse_material(d, path):
    """Validated ``Material`` from a mapping (scene ``materials.<name>:``)."""
    return build(Material, d, path)


def combine(a, b, rule):
    """Combine two materials' coefficients ``(K,)`` elementwise by ``rule`` (average, min, max,
    multiply, geometric): ``combine_pair`` on each pair, the kernel the step uses. Two equal
    coefficients always give exactly that value — under ``multiply`` too, where Bullet would square
    them — so a material meeting itself behaves as its own coefficients say."""
    if rule not in COMBINE_RULES:
        raise ValueError(f"unknown combine rule {rule!r}")
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    out = np.empty(a.shape)
    _combine_rows(np.ascontiguousarray(a).reshape(-1), np.ascontiguousarray(b).reshape(-1), COMBINE_RULES.index(rule),
                  out.reshape(-1))
    return out


@njit
def combine_pair(x, y, rule):
    """``x`` and ``y`` combined by ``COMBINE_RULES[rule]``: ``(x + y)/2``, ``min``, ``max``,
    ``x·y`` or ``√(x·y)``; ``x`` itself when the two are equal."""
    if x == y:
        return x
    if rule == 0:
        return 0.5 * (x + y)
    if rule == 1:
        return x if x <= y else y
    if rule == 2:
        return x if x >= y else y
    if rule == 3:
        return x * y
    return math.sqrt(x * y)


@njit
def _combine_rows(a, b, rule, out):
    for i in range(a.shape[0]):
        out[i] = combine_pair(a[i], b[i], rule)
