"""The world: bodies as a structure of arrays, and stepping.

Internally a body's position is its centre of mass and its collision geometry is stored
relative to it; ``World.body()`` and ``World.set_pose()`` speak of the body frame the user
gave (for primitives the two coincide).
"""
from dataclasses import dataclass

import numpy as np

from . import dynamics, quat
from .contacts import Contacts
from .errors import ContactSimError
from .settings import DEFAULT_MATERIAL, Material, Settings
from .shapes import Plane, Shape
from .validate import positive as _positive
from .validate import unit_quaternion as _unit_quaternion
from .validate import vector as _vector

KINDS = ("static", "kinematic", "dynamic")
# Per-body attributes of a World, rows in body order (arrays) or items (lists). remove_bodies and the
# rollback of add_bodies treat them together: a new per-body attribute belongs here (an engine test
# fails when an array with a row per body is missing from this list).
BODY_ARRAYS = ("kind", "particle", "mass", "inv_mass", "inertia_body", "inv_inertia_body", "com_local",
               "restitution", "friction", "static_friction", "group", "mask")
BODY_LISTS = ("_names", "shapes", "user_shapes", "material_names")
MODELS = ("rigid", "particle")
STATIC, KINEMATIC, DYNAMIC = 0, 1, 2
DEFAULT_DENSITY = 1000.0  # kg/m³ (water), when neither mass nor density is given
ALL_GROUPS = 0xFFFFFFFF


@dataclass(frozen=True)
class Body:
    """A snapshot of one body (copies, world frame). ``velocity`` is that of the centre of mass."""

    name: str
    index: int
    kind: str
    model: str
    shape: Shape
    mass: float
    inertia: np.ndarray          # (3, 3) body frame, about the centre of mass
    center_of_mass: np.ndarray   # (3,) body frame
    position: np.ndarray         # (3,) body-frame origin in the world
    orientation: np.ndarray      # (4,) x, y, z, w
    velocity: np.ndarray         # (3,)
    angular_velocity: np.ndarray  # (3,)
    material: str


class _State:
    """Per-body motion arrays; copied whole for reset and for refusing bad input atomically."""

    NAMES = ("pos", "vel", "quat", "omega", "principal_q", "principal_moments", "stamp", "posed", "pose_pos",
             "pose_quat")

    def __init__(self):
        self.pos = np.zeros((0, 3))
        self.vel = np.zeros((0, 3))
        self.quat = np.zeros((0, 4))
        self.omega = np.zeros((0, 3))
        self.principal_q = np.zeros((0, 4))
        self.principal_moments = np.zeros((0, 3))
        self.stamp = np.zeros(0)              # time of the last pose given (kinematic bodies)
        self.posed = np.zeros(0, bool)        # has a pose been given yet
        self.pose_pos = np.zeros((0, 3))      # centre of mass and orientation at that last pose: the
        self.pose_quat = np.zeros((0, 4))     # finite differences start there, not where the body drifted to

    def copy(self):
        return self.take(slice(None))

    def take(self, rows):
        """A new state with the bodies ``rows`` (mask, indices or slice), arrays copied."""
        c = _State()
        for n in self.NAMES:
            setattr(c, n, getattr(self, n)[rows].copy())
        return c

    def concat(self, other):
        """A new state: these bodies, then those of ``other``."""
        c = _State()
        for n in self.NAMES:
            setattr(c, n, np.concatenate([getattr(self, n), getattr(other, n)]))
        return c


class World:
    """A rigid-body world. See the package docstring for the public contract."""

    def __init__(self, gravity=(0.0, 0.0, -9.81), settings=None, materials=None):
        self.gravity = _vector(gravity, 3, "gravity")
        self.settings = settings if settings is not None else Settings()
        self.materials = {DEFAULT_MATERIAL: Material()}
        self.materials.update(materials or {})
        self.time = 0.0
        self.contacts = Contacts.empty()
        self._names = []
        self._index = {}
        self.shapes = []          # per body, geometry relative to the centre of mass
        self.user_shapes = []     # per body, as given
        self.material_names = []
        self.s = _State()
        self.kind = np.zeros(0, np.int8)
        self.particle = np.zeros(0, bool)
        self.mass = np.zeros(0)
        self.inv_mass = np.zeros(0)
        self.inertia_body = np.zeros((0, 3, 3))
        self.inv_inertia_body = np.zeros((0, 3, 3))
        self.com_local = np.zeros((0, 3))
        self.restitution = np.zeros(0)
        self.friction = np.zeros(0)
        self.static_friction = np.zeros(0)
        self.group = np.zeros(0, np.uint32)
        self.mask = np.zeros(0, np.uint32)
        self._initial = None
        self.last_detection = None   # statistics of the last detection (collision.DetectionStats)

    # ------------------------------------------------------------------ bodies
    @property
    def body_names(self):
        """Body names in index order (what ``contacts.body_a`` / ``body_b`` index)."""
        return list(self._names)

    def __len__(self):
        return len(self._names)

    def index(self, name):
        """Index of a body by name; ``ContactSimError`` naming it when there is none."""
        try:
            return self._index[name]
        except (KeyError, TypeError):
            raise ContactSimError(f"unknown body {name!r} (bodies: {', '.join(self._names) or 'none'})") from None

    def add_body(self, name, shape, *, kind="dynamic", model="rigid", mass=None, density=None,
                 position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0), velocity=(0.0, 0.0, 0.0),
                 angular_velocity=(0.0, 0.0, 0.0), material=DEFAULT_MATERIAL, group=1, mask=ALL_GROUPS,
                 where=None):
        """Add a body and return its index. Everything is checked before the world changes.

        ``position (3,)`` is the body-frame origin, ``orientation (4,)`` x,y,z,w, velocities (3,)
        world frame (``velocity`` of the centre of mass). ``mass`` or ``density`` (kg/m³, default
        1000) sets mass and inertia of dynamic bodies; static and kinematic bodies have infinite
        mass. ``group``/``mask`` are collision bit masks: two bodies are tested only if each one's
        group intersects the other's mask. ``where`` prefixes error messages (the scene path).
        """
        w = where or f"body {name!r}"
        if not isinstance(name, str) or not name:
            raise ContactSimError(f"{w}.name: must be a non-empty string, got {name!r}")
        if name in self._index:
            raise ContactSimError(f"{w}.name: duplicate body name {name!r}")
        if not isinstance(shape, Shape):
            raise ContactSimError(f"{w}.shape: must be a contact_sim shape, got {type(shape).__name__}")
        if kind not in KINDS:
            raise ContactSimError(f"{w}.kind: must be one of {', '.join(KINDS)}; got {kind!r}")
        if model not in MODELS:
            raise ContactSimError(f"{w}.model: must be one of {', '.join(MODELS)}; got {model!r}")
        if material not in self.materials:
            raise ContactSimError(f"{w}.material: unknown material {material!r} "
                                  f"(materials: {', '.join(self.materials)})")
        tol = self.settings.quaternion_tolerance
        pos = _vector(position, 3, f"{w}.position")
        q = _unit_quaternion(orientation, f"{w}.orientation", tol)
        vel = _vector(velocity, 3, f"{w}.velocity")
        omega = _vector(angular_velocity, 3, f"{w}.angular_velocity")
        for label, value in (("group", group), ("mask", mask)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= ALL_GROUPS:
                raise ContactSimError(f"{w}.{label}: must be an integer bit mask in [0, 2^32), got {value!r}")
        if mass is not None and density is not None:
            raise ContactSimError(f"{w}: give mass or density, not both")

        com = np.zeros(3)
        inertia = np.zeros((3, 3))
        body_mass = np.inf
        if kind == "dynamic":
            if isinstance(shape, Plane):
                raise ContactSimError(f"{w}.shape: a plane is a half-space with no mass; make the body static or kinematic")
            if mass is not None:
                body_mass = _positive(mass, f"{w}.mass")
                try:
                    m1, com, i1 = shape.mass_properties(1.0)
                except ContactSimError as exc:
                    raise ContactSimError(f"{w}.shape: {exc}") from None
                inertia = i1 * (body_mass / m1)  # uniform density
            else:
                rho = DEFAULT_DENSITY if density is None else _positive(density, f"{w}.density")
                try:
                    body_mass, com, inertia = shape.mass_properties(rho)
                except ContactSimError as exc:
                    raise ContactSimError(f"{w}.shape: {exc}") from None
        elif mass is not None or density is not None:
            _positive(mass if mass is not None else density, f"{w}.{'mass' if mass is not None else 'density'}")
        # centre the geometry on the centre of mass (round-off-sized offsets are not worth a copy)
        scale = max(float(np.ptp(getattr(shape, "vertices", np.zeros((1, 3))), axis=0).max()), 1e-12)
        centered = shape.translated(-com) if np.abs(com).max() > 1e-12 * scale else shape
        if centered is shape:
            com = np.zeros(3)

        rotates = kind == "dynamic" and model == "rigid"
        if rotates:
            moments, pq = dynamics.principal_frame(inertia[None])
            moments, pq = moments[0], pq[0]
            inv_inertia = np.linalg.inv(inertia)
        else:
            moments, pq = np.full(3, np.inf), np.array([0.0, 0.0, 0.0, 1.0])
            inv_inertia = np.zeros((3, 3))
            if model == "particle" and np.any(omega != 0):
                raise ContactSimError(f"{w}.angular_velocity: a particle does not rotate; got {omega.tolist()}")
        if kind == "static" and (np.any(vel != 0) or np.any(omega != 0)):
            raise ContactSimError(f"{w}: a static body never moves; give it no velocity (or make it kinematic)")

        mat = self.materials[material]
        com_world = pos + quat.rotate(q, com)
        # ---- commit (nothing below can fail)
        idx = len(self._names)
        self._names.append(name)
        self._index[name] = idx
        self.shapes.append(centered)
        self.user_shapes.append(shape)
        self.material_names.append(material)
        s = self.s
        s.pos = np.vstack([s.pos, com_world])
        s.vel = np.vstack([s.vel, vel])
        s.quat = np.vstack([s.quat, q])
        s.omega = np.vstack([s.omega, omega])
        s.principal_q = np.vstack([s.principal_q, pq])
        s.principal_moments = np.vstack([s.principal_moments, moments])
        s.stamp = np.append(s.stamp, np.nan)
        s.posed = np.append(s.posed, False)
        s.pose_pos = np.vstack([s.pose_pos, com_world])
        s.pose_quat = np.vstack([s.pose_quat, q])
        self.kind = np.append(self.kind, np.int8(KINDS.index(kind)))
        self.particle = np.append(self.particle, model == "particle")
        self.mass = np.append(self.mass, body_mass)
        self.inv_mass = np.append(self.inv_mass, 0.0 if kind != "dynamic" else 1.0 / body_mass)
        self.inertia_body = np.concatenate([self.inertia_body, inertia[None]])
        self.inv_inertia_body = np.concatenate([self.inv_inertia_body, inv_inertia[None]])
        self.com_local = np.vstack([self.com_local, com])
        self.restitution = np.append(self.restitution, mat.restitution)
        self.friction = np.append(self.friction, mat.friction)
        self.static_friction = np.append(self.static_friction, mat.static_friction)
        self.group = np.append(self.group, np.uint32(group))
        self.mask = np.append(self.mask, np.uint32(mask))
        if self._initial is not None:   # reset() returns a body added later to the state it was added in
            self._initial = (self._initial[0].concat(s.take([idx])), self._initial[1])
        return idx

    def add_bodies(self, bodies):
        """Add several bodies at once and return their indices: ``bodies`` is a list of dicts of
        ``add_body`` arguments (``name``, ``shape`` and its keywords). All or nothing: when one is
        refused the world is exactly as before (same arrays, so its caches stay valid) and the error
        names that body."""
        saved = self._snapshot()
        try:
            out = []
            for i, b in enumerate(bodies):
                if not isinstance(b, dict) or "name" not in b or "shape" not in b:
                    raise ContactSimError(f"add_bodies[{i}]: must be a dict with name, shape and add_body keywords, "
                                          f"got {b!r}")
                kw = dict(b)
                try:
                    out.append(self.add_body(kw.pop("name"), kw.pop("shape"), **kw))
                except TypeError as exc:  # an unknown keyword
                    raise ContactSimError(f"add_bodies[{i}]: {exc}") from None
            return out
        except BaseException:
            self._restore(saved)
            raise

    def _snapshot(self):
        """The per-body data as it is now (add_body replaces arrays, never edits them in place)."""
        return ({n: getattr(self, n) for n in BODY_ARRAYS}, {n: list(getattr(self, n)) for n in BODY_LISTS},
                dict(self._index), {n: getattr(self.s, n) for n in _State.NAMES}, self._initial)

    def _restore(self, saved):
        arrays, lists, index, state, initial = saved
        for n, v in {**arrays, **lists}.items():
            setattr(self, n, v)
        for n, v in state.items():
            setattr(self.s, n, v)
        self._index, self._initial = index, initial

    def remove_bodies(self, names):
        """Remove the named bodies (of any kind) at once. The others keep their order and state;
        their indices close up, and ``body_names``, ``contacts``, the carried warm starts and the
        state ``reset()`` returns to follow. Refused as a whole (unknown or repeated name)."""
        names = [names] if isinstance(names, str) else list(names)
        idx = [self.index(n) for n in names]
        if len(set(idx)) != len(idx):
            raise ContactSimError(f"remove_bodies: a body is named twice in {names!r}")
        keep = np.ones(len(self), bool)
        keep[idx] = False
        new_index = np.where(keep, np.cumsum(keep) - 1, -1)
        # ---- commit (nothing below can fail)
        for n in BODY_ARRAYS:
            setattr(self, n, getattr(self, n)[keep])
        for n in BODY_LISTS:
            setattr(self, n, [x for x, k in zip(getattr(self, n), keep) if k])
        self._index = {n: i for i, n in enumerate(self._names)}
        self.s = self.s.take(keep)
        if self._initial is not None:
            self._initial = (self._initial[0].take(keep), self._initial[1])
        c = self.contacts
        c = c.select((new_index[c.body_a] >= 0) & (new_index[c.body_b] >= 0)) if len(c) else Contacts.empty()
        c.body_a, c.body_b = new_index[c.body_a], new_index[c.body_b]
        self.contacts = c
        for attr in ("_cs_warm", "_cs_spec"):   # what the stepper carries: (body_a, body_b, per-contact arrays...)
            setattr(self, attr, _remap_carried(getattr(self, attr, None), new_index))
        self.__dict__.pop("_cs_memo", None)       # every derived table is rebuilt for the new body set

    def body(self, name):
        """Snapshot (copies) of a body by name: position, orientation, velocities, mass, shape."""
        i = self.index(name)
        q = self.s.quat[i].copy()
        return Body(
            name=name, index=i, kind=KINDS[self.kind[i]], model="particle" if self.particle[i] else "rigid",
            shape=self.user_shapes[i], mass=float(self.mass[i]), inertia=self.inertia_body[i].copy(),
            center_of_mass=self.com_local[i].copy(),
            position=self.s.pos[i] - quat.rotate(q, self.com_local[i]), orientation=q,
            velocity=self.s.vel[i].copy(), angular_velocity=self.s.omega[i].copy(),
            material=self.material_names[i],
        )

    def poses(self):
        """Body-frame origins ``(N, 3)`` and orientations ``(N, 4)`` x,y,z,w of all bodies (copies)."""
        q = self.s.quat.copy()
        if not self.com_local.any():   # every origin is its centre of mass (spheres, boxes, ...)
            return self.s.pos.copy(), q
        return self.s.pos - quat.rotate(q, self.com_local), q

    def velocities(self):
        """Linear ``(N, 3)`` (of the centres of mass) and angular ``(N, 3)`` velocities (copies)."""
        return self.s.vel.copy(), self.s.omega.copy()

    # ------------------------------------------------------------------ driving bodies
    def set_pose(self, name, position, orientation, stamp=None):
        """Pose a kinematic body (``position (3,)`` origin, ``orientation (4,)`` x,y,z,w) at time
        ``stamp`` (s; default the world time). From the second pose on its linear and angular
        velocity are the finite differences of successive poses over their stamps, so responses
        see how fast it really moves. Stamps must increase. Bad input changes nothing."""
        self.set_poses([name], [position], [orientation], stamp)

    def set_poses(self, names, positions, orientations, stamp=None):
        """``set_pose`` for several kinematic bodies at one ``stamp``, vectorised: ``names (M,)``,
        ``positions (M, 3)``, ``orientations (M, 4)``. The whole batch is checked before anything
        changes, so a bad row leaves every body as it was; errors name the body and the reason."""
        names = list(names)
        m = len(names)
        idx = np.array([self.index(n) for n in names], dtype=np.int64)

        def where(i):
            return f"set_pose({names[i]!r})"

        if len(set(idx.tolist())) != m:
            raise ContactSimError(f"set_poses: a body is named twice in {names!r}")
        bad = np.flatnonzero(self.kind[idx] != KINEMATIC)
        if bad.size:
            i = bad[0]
            raise ContactSimError(f"{where(i)}: only kinematic bodies are posed from outside; {names[i]!r} is "
                                  f"{KINDS[self.kind[idx[i]]]} (use set_state for dynamic bodies)")
        try:
            pos = np.asarray(positions, dtype=float)
            q = np.asarray(orientations, dtype=float)
            ok = pos.shape == (m, 3) and q.shape == (m, 4) and bool(np.isfinite(pos).all() and np.isfinite(q).all())
        except (TypeError, ValueError):
            ok = False
        if not ok:  # the slow path only finds and names the first bad row
            if len(positions) != m or len(orientations) != m:
                raise ContactSimError(f"set_poses: {m} names but {len(positions)} positions and "
                                      f"{len(orientations)} orientations")
            for i in range(m):
                _vector(positions[i], 3, f"{where(i)}.position")
                _vector(orientations[i], 4, f"{where(i)}.orientation")
        norm = np.linalg.norm(q, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > self.settings.quaternion_tolerance)
        if bad.size:
            _unit_quaternion(q[bad[0]], f"{where(bad[0])}.orientation", self.settings.quaternion_tolerance)
        q = q / norm[:, None]
        t = self.time if stamp is None else stamp
        if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)) or not np.isfinite(t):
            raise ContactSimError(f"{where(0) if m == 1 else 'set_poses'}.stamp: must be a finite number of "
                                  f"seconds, got {stamp!r}")
        t = float(t)
        s = self.s
        posed = s.posed[idx]
        bad = np.flatnonzero(posed & (t - s.stamp[idx] <= 0))
        if bad.size:
            i = bad[0]
            raise ContactSimError(f"{where(i)}.stamp: must be after the previous pose ({s.stamp[idx[i]]!r}), got {t!r}")
        # ---- commit (nothing below can fail)
        com_world = pos + quat.rotate(q, self.com_local[idx])
        j, ij = np.flatnonzero(posed), idx[posed]
        if j.size:
            # from the previous *pose*: between poses the body moved on at its velocity, and a
            # difference from there would halve the velocity of a steadily driven body every other pose
            dt = (t - s.stamp[ij])[:, None]
            q_prev = s.pose_quat[ij]
            qj = np.where(np.sum(q[j] * q_prev, axis=1, keepdims=True) < 0, -q[j], q[j])  # shorter way round
            q[j] = qj
            s.omega[ij] = quat.to_rotvec(quat.mul(qj, quat.conj(q_prev))) / dt
            s.vel[ij] = (com_world[j] - s.pose_pos[ij]) / dt
        s.pos[idx] = com_world
        s.quat[idx] = q
        s.pose_pos[idx] = com_world
        s.pose_quat[idx] = q
        s.stamp[idx] = t
        s.posed[idx] = True

    def restart_pose_history(self, names=None):
        """The next pose of each named kinematic body (every body when ``names`` is None) is taken
        as a first pose: it places the body and keeps its velocity, no finite difference across the
        gap (after a clock jump, or when a body was driven another way meanwhile)."""
        idx = np.arange(len(self)) if names is None else np.array([self.index(n) for n in names], np.int64)
        self.s.posed[idx] = False

    def set_state(self, name, position=None, orientation=None, velocity=None, angular_velocity=None):
        """Overwrite any part of a non-static body's state (teleport, set a velocity). Checked first."""
        i = self.index(name)
        if self.kind[i] == STATIC:
            raise ContactSimError(f"set_state({name!r}): {name!r} is static and never moves")
        s = self.s
        q = s.quat[i] if orientation is None else _unit_quaternion(
            orientation, f"set_state({name!r}).orientation", self.settings.quaternion_tolerance)
        pos = None if position is None else _vector(position, 3, f"set_state({name!r}).position")
        vel = None if velocity is None else _vector(velocity, 3, f"set_state({name!r}).velocity")
        om = None if angular_velocity is None else _vector(angular_velocity, 3, f"set_state({name!r}).angular_velocity")
        if om is not None and self.particle[i] and np.any(om != 0):
            raise ContactSimError(f"set_state({name!r}).angular_velocity: a particle does not rotate")
        origin = s.pos[i] - quat.rotate(s.quat[i], self.com_local[i]) if pos is None else pos
        s.quat[i] = q
        s.pos[i] = origin + quat.rotate(q, self.com_local[i])
        if vel is not None:
            s.vel[i] = vel
        if om is not None:
            s.omega[i] = om
        s.posed[i] = False   # a kinematic body set from outside: its pose history starts again

    def set_states(self, names, positions=None, orientations=None, velocities=None, angular_velocities=None):
        """``set_state`` for several non-static bodies at once, all or nothing: ``names (M,)`` and,
        each optional (None leaves that part unchanged), ``positions (M, 3)`` body-frame origins,
        ``orientations (M, 4)`` x,y,z,w, ``velocities (M, 3)`` of the centres of mass and
        ``angular_velocities (M, 3)``, world frame. A kinematic body given a velocity moves at it
        until the next pose or state; errors name the body and the reason."""
        names = list(names)
        m = len(names)
        idx = np.array([self.index(n) for n in names], np.int64)
        if len(set(idx.tolist())) != m:
            raise ContactSimError(f"set_states: a body is named twice in {names!r}")
        for i in np.flatnonzero(self.kind[idx] == STATIC):
            raise ContactSimError(f"set_states({names[i]!r}): {names[i]!r} is static and never moves")
        tol = self.settings.quaternion_tolerance
        parts = {}
        for key, value, n in (("position", positions, 3), ("orientation", orientations, 4),
                              ("velocity", velocities, 3), ("angular_velocity", angular_velocities, 3)):
            if value is None:
                continue
            if len(value) != m:
                raise ContactSimError(f"set_states.{key}: {len(value)} rows for {m} bodies")
            check = (lambda v, w: _unit_quaternion(v, w, tol)) if n == 4 else (lambda v, w: _vector(v, n, w))
            parts[key] = np.array([check(value[i], f"set_states({names[i]!r}).{key}") for i in range(m)]).reshape(m, n)
        om = parts.get("angular_velocity")
        if om is not None:
            for i in np.flatnonzero(self.particle[idx] & om.any(axis=1)):
                raise ContactSimError(f"set_states({names[i]!r}).angular_velocity: a particle does not rotate")
        # ---- commit (nothing below can fail)
        s = self.s
        origin = parts.get("position")
        if origin is None:
            origin = s.pos[idx] - quat.rotate(s.quat[idx], self.com_local[idx])
        if "orientation" in parts:
            s.quat[idx] = parts["orientation"]
        s.pos[idx] = origin + quat.rotate(s.quat[idx], self.com_local[idx])
        if "velocity" in parts:
            s.vel[idx] = parts["velocity"]
        if om is not None:
            s.omega[idx] = om
        s.posed[idx] = False

    # ------------------------------------------------------------------ stepping
    def step(self, dt=None):
        """Advance the world by ``dt`` seconds (default ``settings.dt``); ``contacts`` then holds
        the contacts of this step with the impulses applied."""
        dt = self._check_dt(dt)
        from . import stepper  # the time-of-impact / response pipeline

        saved = (self.s.copy(), self.time, self.contacts, getattr(self, "_cs_warm", None))
        try:
            stepper.step(self, dt)
        except BaseException:
            self.s, self.time, self.contacts, self._cs_warm = saved
            raise
        bad = self._nonfinite_bodies()
        if bad.size:
            # the invariant guard: the engine never leaves a non-finite state behind; the step is
            # undone and the bodies are named, so a caller (the node) can keep its last good world
            self.s, self.time, self.contacts, self._cs_warm = saved
            names = ", ".join(repr(self._names[i]) for i in bad[:10]) + (" ..." if bad.size > 10 else "")
            raise ContactSimError(f"step: the state of {bad.size} bod{'y' if bad.size == 1 else 'ies'} ({names}) "
                                  f"would have become non-finite; the world is as it was before this step")

    def _nonfinite_bodies(self):
        """Indices ``(B,)`` of bodies with a non-finite position, velocity or orientation (one sum per
        array answers the usual all-finite case)."""
        s = self.s
        arrays = (s.pos, s.vel, s.quat, s.omega)
        if all(np.isfinite(a.sum()) for a in arrays):
            return np.zeros(0, np.int64)
        bad = np.zeros(len(self), bool)
        for a in arrays:
            bad |= ~np.isfinite(a).all(axis=1)
        return np.flatnonzero(bad)

    def detect(self):
        """All contacts of the current state, without stepping (``Contacts``); the statistics of
        this detection are in ``last_detection``."""
        from . import collision

        contacts, self.last_detection = collision.detect_world(self)
        return contacts

    def _check_dt(self, dt):
        if dt is None:
            return self.settings.dt
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)) or not np.isfinite(dt) or dt <= 0:
            raise ContactSimError(f"step: dt must be a finite number of seconds > 0, got {dt!r}")
        return float(dt)

    def _advance_free(self, dt):
        """Move every body as if nothing touched for ``dt``: dynamic bodies ballistically with
        torque-free rotation, kinematic bodies at their constant linear and angular velocity."""
        dynamic = self.kind == DYNAMIC
        dynamics.integrate_free(self.s, dt, self.gravity, dynamic, dynamic & ~self.particle)
        kin = np.flatnonzero((self.kind == KINEMATIC) & self.s.omega.any(axis=1))
        if kin.size:
            s = self.s
            turn = quat.from_rotvec(s.omega[kin] * dt)
            s.quat[kin] = quat.normalize(quat.mul(turn, s.quat[kin]))

    # ------------------------------------------------------------------ reporting
    def _spin(self, mask):
        """World-frame spin angular momentum ``I_w ω (M, 3)`` of the bodies selected by ``mask``."""
        r = quat.to_matrix(self.s.quat[mask])
        inertia_w = r @ self.inertia_body[mask] @ np.swapaxes(r, -1, -2)
        return np.einsum("ijk,ik->ij", inertia_w, self.s.omega[mask])

    def energy(self):
        """Kinetic (linear and rotational) plus gravitational potential energy (J) of the dynamic bodies."""
        d = self.kind == DYNAMIC
        s = self.s
        m = self.mass[d]
        lin = 0.5 * np.sum(m * np.einsum("ij,ij->i", s.vel[d], s.vel[d]))
        rigid = d & ~self.particle
        rot = 0.5 * np.sum(np.einsum("ij,ij->i", s.omega[rigid], self._spin(rigid)))
        pot = -np.sum(m * (s.pos[d] @ self.gravity))
        return float(lin + rot + pot)

    def angular_momentum(self):
        """Total angular momentum (3,) of the dynamic bodies about the world origin (spin of the
        rigid ones plus every body's orbital part)."""
        d = self.kind == DYNAMIC
        s = self.s
        orbital = np.cross(s.pos[d], self.mass[d][:, None] * s.vel[d]).sum(axis=0)
        return orbital + self._spin(d & ~self.particle).sum(axis=0)

    def describe(self):
        """A short human-readable account of the world: bodies, shapes, kinds and settings."""
        kinds = {k: int(np.sum(self.kind == i)) for i, k in enumerate(KINDS)}
        shapes = {}
        for sh in self.user_shapes:
            shapes[sh.type] = shapes.get(sh.type, 0) + 1
        lines = [
            f"{len(self)} bodies: " + ", ".join(f"{v} {k}" for k, v in kinds.items() if v),
            "shapes: " + ", ".join(f"{v} {k}" for k, v in sorted(shapes.items())),
            f"gravity {self.gravity.tolist()} m/s², dt {self.settings.dt:.6g} s",
        ]
        from . import stepper

        lines += stepper.describe_models(self)
        return "\n".join(lines)

    # ------------------------------------------------------------------ reset
    def mark_initial(self):
        """Remember the current state as the one ``reset()`` returns to."""
        self._initial = (self.s.copy(), self.time)

    def reset(self):
        """Return to the state saved by ``mark_initial()`` (done by ``load_scene``)."""
        if self._initial is None:
            raise ContactSimError("reset: no initial state was saved (call mark_initial first)")
        state, t = self._initial
        self.s = state.copy()
        self.time = t
        self.contacts = Contacts.empty()
        from . import stepper

        stepper.forget(self)


def _remap_carried(record, new_index):
    """A per-contact record the stepper carries between steps, ``(body_a, body_b, arrays...)`` with
    a row per contact, for the bodies left after a removal (``new_index`` old → new, -1 removed).
    Anything else is dropped (``None``): carried data only speeds up the next step."""
    try:
        a, b = record[0], record[1]
        keep = (new_index[a] >= 0) & (new_index[b] >= 0)
        return (new_index[a][keep], new_index[b][keep]) + tuple(x[keep] for x in record[2:])
    except Exception:
        return None
