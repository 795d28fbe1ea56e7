"""The input contract, in one place.

Every public entry point — the ``Settings``, ``Material`` and shape constructors, ``World``,
``add_body``, ``set_pose(s)``, ``set_state``, ``step``, ``collide``, ``collide_pairs`` and
``load_scene`` — checks its arguments with the rules below before anything changes, so scene
files and code obey the same rules and every refusal is a ``ContactSimError`` whose message
starts with the argument (or scene path) and gives the reason.

A rule is declared once per field or argument: ``Number`` (type, range, finiteness, whole
numbers), ``Choice``, ``Tristate``, ``Flag``, ``BitMask``, ``Nested`` (an object of declared
fields), ``Vector`` and ``Rows`` (arrays of a shape, finite, within a bound) and ``Quaternion``.
A bound is either a number or the *name of another field* (``le="max_step"``), read from the
settings in force. Settings declared with ``world_bound=True`` (``max_position``, ``max_speed``,
...) are the **world bounds**: a finite value beyond one raises ``BoundsError`` (a
``ContactSimError``), so callers such as the ROS node can count it apart.

``Declared`` turns a dataclass whose fields are made with ``declare(default, rule)`` into one
that checks every assignment (in the constructor and afterwards) and refuses unknown names;
``build`` makes one from a mapping (a scene's ``settings:``), errors naming the scene path.
"""
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from .errors import BoundsError, ContactSimError
from .constants import LENGTH_LIMIT, STAMP_LIMIT

_SYMBOL = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}


def show(value):
    """A short text of ``value`` for an error message."""
    if isinstance(value, np.ndarray):
        return repr(value.tolist()) if value.size <= 12 else f"an array of shape {value.shape}"
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _num(x, unit=""):
    x = float(x)
    text = f"{x:g}" if not x.is_integer() or abs(x) >= 1e6 else str(int(x))
    return f"{text} {unit}".rstrip() if unit else text


def _resolve(bound, ctx):
    """The value of a bound (a number, a setting's name, or ``callable(settings) -> (value,
    label)``), or None when there is none or no settings to read it from (a constructor still
    filling its fields)."""
    if bound is None or isinstance(bound, (int, float)):
        return bound
    if ctx is None:
        return None
    return getattr(ctx, bound) if isinstance(bound, str) else bound(ctx)[0]


def _label(bound, ctx, unit):
    """``(text, is_world_bound)`` of a bound, for an error message."""
    if isinstance(bound, str):
        return f"{bound} ({_num(getattr(ctx, bound), unit)})", isinstance(ctx, Declared) and bound in ctx.world_bounds()
    if callable(bound):
        return bound(ctx)[1], True
    return _num(bound, unit if bound else ""), False


def _refuse(path, relation, bound, ctx, unit, got):
    label, world = _label(bound, ctx, unit)
    sep = "" if relation.endswith("±") else " "
    raise (BoundsError if world else ContactSimError)(f"{path}: {relation}{sep}{label}{got}")


class Rule:
    """Base of the rules: ``check(value, path, ctx=None)`` returns the normalised value or raises
    ``ContactSimError`` naming ``path``; ``ctx`` is the settings that world bounds are read from."""

    refs = frozenset()   # names of the settings this rule's bounds read

    def check(self, value, path, ctx=None):
        raise NotImplementedError


@dataclass(frozen=True)
class Number(Rule):
    """A finite real number (booleans refused) within ``gt``/``ge``/``lt``/``le`` and ``|x| <=
    bound``; ``integer`` wants a whole number (returned as ``int``); ``optional`` accepts None."""

    gt: object = None
    ge: object = None
    lt: object = None
    le: object = None
    bound: object = None
    integer: bool = False
    optional: bool = False
    unit: str = ""

    @property
    def refs(self):
        return frozenset(b for b in (self.gt, self.ge, self.lt, self.le, self.bound) if isinstance(b, str))

    def range_text(self, ctx=None):
        parts = []
        for op in ("gt", "ge", "lt", "le"):
            b = getattr(self, op)
            if _resolve(b, ctx) is not None:
                parts.append(f"{_SYMBOL[op]} {_label(b, ctx, self.unit)[0]}")
        if _resolve(self.bound, ctx) is not None:
            parts.append(f"within ±{_label(self.bound, ctx, self.unit)[0]}")
        return " and ".join(parts)

    def check(self, value, path, ctx=None):
        if value is None and self.optional:
            return None
        kind = "whole number" if self.integer else "number"
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise ContactSimError(f"{path}: must be a {kind}, got {show(value)}")
        try:
            x = float(value)
        except OverflowError:   # a Python int beyond float
            x = math.inf
        if not math.isfinite(x):
            rng = self.range_text(ctx)
            raise ContactSimError(f"{path}: must be a finite {kind}{' ' + rng if rng else ''}, got {show(value)}")
        if self.integer:
            if not x.is_integer():
                raise ContactSimError(f"{path}: must be a whole number, got {show(value)}")
            x = int(value) if isinstance(value, numbers.Integral) else int(x)
        for op in ("gt", "ge", "lt", "le"):
            b = _resolve(getattr(self, op), ctx)
            if b is None:
                continue
            if not (x > b if op == "gt" else x >= b if op == "ge" else x < b if op == "lt" else x <= b):
                _refuse(path, f"must be {_SYMBOL[op]}", getattr(self, op), ctx, self.unit, f", got {show(value)}")
        b = _resolve(self.bound, ctx)
        if b is not None and abs(x) > b:
            _refuse(path, "must be within ±", self.bound, ctx, self.unit, f", got {show(value)}")
        return x


@dataclass(frozen=True)
class Choice(Rule):
    """One of ``options`` (strings)."""

    options: tuple

    def check(self, value, path, ctx=None):
        if isinstance(value, str) and value in self.options:
            return value
        raise ContactSimError(f"{path}: must be one of {', '.join(self.options)}; got {show(value)}")


@dataclass(frozen=True)
class Tristate(Rule):
    """``True``, ``False`` or ``"auto"``."""

    def check(self, value, path, ctx=None):
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        if isinstance(value, str) and value == "auto":
            return value
        raise ContactSimError(f"{path}: must be true, false or auto; got {show(value)}")


@dataclass(frozen=True)
class Flag(Rule):
    """``True`` or ``False``."""

    def check(self, value, path, ctx=None):
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        raise ContactSimError(f"{path}: must be true or false, got {show(value)}")


@dataclass(frozen=True)
class BitMask(Rule):
    """A 32-bit collision group or mask."""

    def check(self, value, path, ctx=None):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or not 0 <= value <= 0xFFFFFFFF:
            raise ContactSimError(f"{path}: must be an integer bit mask in [0, 2^32), got {show(value)}")
        return int(value)


@dataclass(frozen=True)
class Nested(Rule):
    """An instance of the ``Declared`` class ``cls``, or a mapping of its fields."""

    cls: type

    def check(self, value, path, ctx=None):
        if isinstance(value, self.cls):
            return value
        if isinstance(value, Mapping):
            return build(self.cls, value, path)
        raise ContactSimError(f"{path}: must be a {self.cls.__name__} or a mapping of its fields, "
                              f"got {type(value).__name__}")


# ---------------------------------------------------------------------------- arrays
def _has_bool(value):
    """A boolean anywhere in nested lists/tuples (numpy would read it as 0 or 1)."""
    if not isinstance(value, (list, tuple)):
        return isinstance(value, (bool, np.bool_))
    stack = [value]
    while stack:
        for x in stack.pop():
            t = type(x)
            if t is bool or t is np.bool_:
                return True
            if t is list or t is tuple:
                stack.append(x)
    return False


def numbers_array(value, path, expect):
    """``value`` as a new float array; refuses what is not plainly numbers (booleans, strings,
    None, ragged nesting, complex) with ``expect`` saying what was wanted."""
    if type(value) is np.ndarray and value.dtype.kind == "f":   # the common case, at once
        return value.astype(float)
    try:
        a = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError):   # ragged nesting
        raise ContactSimError(f"{path}: must be {expect}, got {show(value)}") from None
    if a.dtype.kind not in "iuf" or _has_bool(value):
        raise ContactSimError(f"{path}: must be {expect}, got {show(value)}")
    return a.astype(float)


def _norms(a):
    """Row lengths of ``a (M, n)``, without overflow in the squares of entries beyond 1e150."""
    if not a.size or np.abs(a).max() < 1e150:
        return np.linalg.norm(a, axis=1)
    big = np.abs(a).max(axis=1)
    scale = np.where(big > 0, big, 1.0)[:, None]
    return big * np.linalg.norm(a / scale, axis=1)


def _check_row_bounds(rule, a, row_path, ctx):
    """World bounds of the rows of ``a (M, n)``; errors name ``row_path(i)``."""
    box = _resolve(rule.bound, ctx)
    if box is not None:
        over = np.abs(a) > box
        if over.any():
            i = int(np.argmax(over.any(axis=1)))
            _refuse(row_path(i), "every coordinate must be within ±", rule.bound, ctx, rule.unit, f", got {a[i].tolist()}")
    ball = _resolve(rule.norm_bound, ctx)
    if ball is not None:
        norm = _norms(a)
        over = norm > ball
        if over.any():
            i = int(np.argmax(over))
            _refuse(row_path(i), f"magnitude {_num(norm[i], rule.unit)} is above", rule.norm_bound, ctx, rule.unit, "")


@dataclass(frozen=True)
class Vector(Rule):
    """``n`` finite numbers; ``bound``: every coordinate within ± it; ``norm_bound``: the length
    at most it (numbers, setting names, or ``callable(settings) -> (value, label)``)."""

    n: int
    bound: object = None
    norm_bound: object = None
    unit: str = ""

    @property
    def refs(self):
        return frozenset(b for b in (self.bound, self.norm_bound) if isinstance(b, str))

    def check(self, value, path, ctx=None):
        a = numbers_array(value, path, f"{self.n} numbers")
        if a.shape != (self.n,):
            raise ContactSimError(f"{path}: must be {self.n} numbers, got {show(value)}")
        box = _resolve(self.bound, ctx)
        top = float(np.abs(a).max())
        if not (top < math.inf and (box is None or top <= box)):   # one reduction on the common path; NaN fails
            if not np.isfinite(a).all():
                raise ContactSimError(f"{path}: must be finite, got {a.tolist()}")
            _check_row_bounds(self, a[None], lambda i: path, ctx)
        if self.norm_bound is not None:
            _check_row_bounds(self, a[None], lambda i: path, ctx)
        return a


_SQRT = {n: math.sqrt(n) * (1.0 + 1e-12) for n in range(1, 17)}   # sqrt(n), rounded up


@dataclass(frozen=True)
class Rows(Rule):
    """An ``(M, n)`` array of finite numbers, each row within the bounds of ``Vector``; errors name
    the row (``row_path(i)``, default ``path[i]``). ``count`` fixes M, ``min_rows`` bounds it."""

    n: int
    bound: object = None
    norm_bound: object = None
    unit: str = ""

    refs = Vector.refs

    def check(self, value, path, ctx=None, count=None, min_rows=0, row_path=None, what="rows"):
        row_path = row_path or (lambda i: f"{path}[{i}]")
        shape = f"({'M' if count is None else count}, {self.n})"
        a = numbers_array(value, path, f"an {shape} array")
        if a.size == 0 and a.ndim <= 2:
            a = a.reshape(0, self.n)
        if a.ndim != 2 or a.shape[1] != self.n:
            raise ContactSimError(f"{path}: must be an {shape} array, got shape {a.shape}")
        if count is not None and len(a) != count:
            raise ContactSimError(f"{path}: must be an {shape} array, got {len(a)} {what}")
        if len(a) < min_rows:
            raise ContactSimError(f"{path}: needs at least {min_rows} {what}, got {len(a)}")
        # the common case in one reduction: every coordinate finite and within ``bound``, and
        # ``sqrt(n)`` × the largest within ``norm_bound`` (no row's length can be more); NaN fails
        top = float(np.abs(a).max(initial=0.0))
        box, ball = _resolve(self.bound, ctx), _resolve(self.norm_bound, ctx)
        if top < math.inf and (box is None or top <= box) and (ball is None or top * _SQRT[self.n] <= ball):
            return a
        finite = np.isfinite(a)
        if not finite.all():
            i = int(np.argmin(finite.all(axis=1)))
            raise ContactSimError(f"{row_path(i)}: must be finite, got {a[i].tolist()}")
        _check_row_bounds(self, a, row_path, ctx)
        return a


@dataclass(frozen=True)
class Quaternion(Rule):
    """A rotation x, y, z, w: finite, non-zero, its norm within ``tolerance`` (a number or a
    setting name) of 1; returned normalised."""

    tolerance: object = "quaternion_tolerance"

    def _unit(self, q, norm, path, ctx):
        tol = _resolve(self.tolerance, ctx)
        tol = math.inf if tol is None else tol
        if norm < 1e-12:
            raise ContactSimError(f"{path}: zero quaternion is not a rotation")
        if abs(norm - 1.0) > tol:
            raise ContactSimError(f"{path}: quaternion must be unit length (x, y, z, w), got norm {norm:.6g}")

    def check(self, value, path, ctx=None):
        q = _VECTOR4.check(value, path)
        big = float(np.abs(q).max())
        if big >= 1e150:   # as in check_rows: scaled first (or far from unit length)
            return self.check_rows(q[None], path, ctx, row_path=lambda i: path)[0]
        norm = float(np.linalg.norm(q))
        self._unit(q, norm, path, ctx)
        return q / norm

    def check_rows(self, value, path, ctx=None, count=None, row_path=None):
        """``(M, 4)`` quaternions, returned normalised; errors name ``row_path(i)``."""
        row_path = row_path or (lambda i: f"{path}[{i}]")
        q = _ROWS4.check(value, path, count=count, row_path=row_path, what="orientations")
        tol = _resolve(self.tolerance, ctx)
        tol = math.inf if tol is None else tol
        huge = np.abs(q).max(axis=1, initial=0.0) >= 1e150
        if huge.any():   # far from unit length; or, with any length accepted, scaled first
            if math.isfinite(tol):
                i = int(np.argmax(huge))
                self._unit(q[i], _norms(q[i:i + 1])[0], row_path(i), ctx)
            q[huge] /= np.abs(q[huge]).max(axis=1)[:, None]
        norm = np.linalg.norm(q, axis=1)
        bad = (norm < 1e-12) | (np.abs(norm - 1.0) > tol)
        if bad.any():
            i = int(np.argmax(bad))
            self._unit(q[i], norm[i], row_path(i), ctx)
        return q / norm[:, None]


_VECTOR4 = Vector(4)
_ROWS4 = Rows(4)


# ---------------------------------------------------------------------------- declared fields
def declare(default, rule, doc="", world_bound=False):
    """A dataclass field checked by ``rule``: the one declaration of a setting or material field.
    A class as ``default`` is a factory (a nested ``Declared`` object). ``world_bound``: values
    beyond this field (when a rule names it) raise ``BoundsError``."""
    meta = {"rule": rule, "doc": doc, "world_bound": world_bound}
    if isinstance(default, type):
        return field(default_factory=default, metadata=meta)
    return field(default=default, metadata=meta)


_RULES = {}          # Declared class -> {field: rule}
_WORLD_BOUNDS = {}   # Declared class -> names of its world-bound fields
#: how many field assignments any ``Declared`` object (settings, materials) has taken: a value
#: derived from a settings object stays true while this count and the object are the same (the
#: step's fixed arguments, ``response.substep``), one comparison instead of reading every field
edits = 0


class Declared:
    """Mixin for dataclasses made of ``declare``d fields: every assignment — in the constructor
    and later (``world.settings.dt = x``) — is checked by the field's rule, bounds naming other
    fields (``le="max_step"``) once every field is set, and unknown attribute names are refused.
    A refused assignment leaves the object as it was. ``LABEL`` starts the error messages."""

    LABEL = "object"

    @classmethod
    def rules(cls):
        """``{field name: rule}`` in declaration order."""
        r = _RULES.get(cls)
        if r is None:
            r = _RULES[cls] = {f.name: f.metadata["rule"] for f in fields(cls)}
        return r

    @classmethod
    def rule(cls, name):
        return cls.rules()[name]

    @classmethod
    def world_bounds(cls):
        """Names of the fields declared ``world_bound=True``."""
        b = _WORLD_BOUNDS.get(cls)
        if b is None:
            b = _WORLD_BOUNDS[cls] = frozenset(f.name for f in fields(cls) if f.metadata["world_bound"])
        return b

    def __setattr__(self, name, value):
        rules = self.rules()
        if name not in rules:
            raise ContactSimError(f"{self.LABEL}.{name}: unknown field (known: {', '.join(rules)})")
        ready = self.__dict__.get("_ready", False)
        value = rules[name].check(value, f"{self.LABEL}.{name}", self if ready else None)
        global edits
        edits += 1   # before the change: a refused one only costs a rebuild
        if not ready:   # the constructor: bounds between fields are checked in __post_init__
            object.__setattr__(self, name, value)
            return
        old = self.__dict__[name]
        object.__setattr__(self, name, value)
        try:
            self._check_links(changed=name)
            self._complete()
        except ContactSimError:
            object.__setattr__(self, name, old)
            raise

    def __post_init__(self):
        self._complete()
        self._check_links()
        object.__setattr__(self, "_ready", True)

    def _complete(self):
        """Fill fields whose default depends on another (``static_friction`` follows ``friction``)."""

    def _check_links(self, changed=None):
        for name, rule in self.rules().items():
            if not rule.refs or (changed is not None and changed not in rule.refs):
                continue
            try:
                rule.check(self.__dict__[name], f"{self.LABEL}.{name}", self)
            except ContactSimError as exc:
                if changed is None:
                    raise
                raise type(exc)(f"{self.LABEL}.{changed}: {show(self.__dict__[changed])} would leave {exc}") from None

    def as_dict(self):
        """Every field as plain values (nested objects as dicts)."""
        return {k: v.as_dict() if isinstance(v, Declared) else v for k, v in
                ((k, self.__dict__[k]) for k in self.rules())}


def check_keys(d, path, allowed):
    """``d`` must be a mapping whose keys are all in ``allowed``."""
    if not isinstance(d, Mapping):
        raise ContactSimError(f"{path}: must be a mapping, got {type(d).__name__}")
    unknown = sorted(set(map(str, d)) - set(allowed))
    if unknown:
        where = f"{path}.{unknown[0]}" if path else str(unknown[0])
        raise ContactSimError(f"{where}: unknown key (allowed: {', '.join(sorted(allowed))})")


def build(cls, d, path):
    """A ``cls`` (a ``Declared`` dataclass) from a mapping of its fields; errors name
    ``path.key``; unknown keys are refused."""
    d = {} if d is None else d
    check_keys(d, path, cls.rules())
    values = {k: rule.check(d[k], f"{path}.{k}") for k, rule in cls.rules().items() if k in d}
    try:
        return cls(**values)
    except ContactSimError as exc:   # a bound between fields: say it with the scene path
        text = str(exc)
        if text.startswith(cls.LABEL + "."):
            raise type(exc)(path + text[len(cls.LABEL):]) from None
        raise


# ---------------------------------------------------------------------------- arguments of the public calls
def _gravity_bound(s):
    return s.max_speed / s.max_step, f"max_speed / max_step ({_num(s.max_speed / s.max_step, 'm/s²')})"


#: the arguments of bodies and poses, declared once (world bounds read from the world's settings)
POSITION = Vector(3, bound="max_position", unit="m")
POSITIONS = Rows(3, bound="max_position", unit="m")
VELOCITY = Vector(3, norm_bound="max_speed", unit="m/s")
VELOCITIES = Rows(3, norm_bound="max_speed", unit="m/s")
ANGULAR_VELOCITY = Vector(3, norm_bound="max_angular_speed", unit="rad/s")
ANGULAR_VELOCITIES = Rows(3, norm_bound="max_angular_speed", unit="rad/s")
ORIENTATION = Quaternion("quaternion_tolerance")
ANY_ORIENTATION = Quaternion(math.inf)   # collide: any non-zero quaternion is normalised
GRAVITY = Vector(3, norm_bound=_gravity_bound, unit="m/s²")
MASS = Number(gt=0, ge="min_mass", le="max_mass", unit="kg")
DENSITY = Number(gt=0, unit="kg/m³")
STAMP = Number(bound=STAMP_LIMIT, unit="s")
GROUP = BitMask()
#: shapes: lengths when built (no world yet), and their size within a world's bounds
LENGTH = Number(gt=0, le=LENGTH_LIMIT, unit="m")
OFFSET = Number(bound=LENGTH_LIMIT, unit="m")
SCALE = Number(gt=0, le=LENGTH_LIMIT)
POINTS = Rows(3, bound=LENGTH_LIMIT, unit="m")
COORDINATES = Vector(3, bound=LENGTH_LIMIT, unit="m")   # a point when no world bounds apply
DISTANCE = Number(ge=0, le=LENGTH_LIMIT, unit="m")
THINNEST = Number(ge="min_size", unit="m")
REACH = Number(le="max_size", unit="m")
PLANE_OFFSET = Number(bound="max_position", unit="m")


def vector(value, n, what, ctx=None):
    """``value`` as a finite ``(n,)`` float array, or ``ContactSimError`` naming ``what``."""
    return Vector(n).check(value, what, ctx)


def positive(value, what):
    """``value`` as a finite float > 0 (booleans refused), or ``ContactSimError`` naming ``what``."""
    return Number(gt=0).check(value, what)


def unit_quaternion(value, what, tolerance):
    """``value`` (x, y, z, w) normalised; refused when not finite, zero, or when its norm differs
    from 1 by more than ``tolerance``."""
    return Quaternion(tolerance).check(value, what)
