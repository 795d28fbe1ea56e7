"""The world: bodies as a structure of arrays, and stepping.

Internally a body's position is its centre of mass and its collision geometry is stored
relative to it; ``World.body()`` and ``World.set_pose()`` speak of the body frame the user
gave (for primitives the two coincide).
"""
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from . import collision, dynamics, free_motion, quat, stepper
from .contacts import Contacts
from .errors import ContactSimError, EngineError
from .kinds import DYNAMIC, KINDS, body_masks
from .response.cache import ContactCache
from .settings import DEFAULT_MATERIAL, Material, Settings
from .stats import StepStats
from .shapes import Plane, Shape
from .validate import ANGULAR_VELOCITY, DENSITY, GRAVITY, GROUP, MASS, ORIENTATION, POSITION, VELOCITY, Choice, Nested, show
from .world_input import BodyInput
from .constants import DEFAULT_DENSITY, ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS

# Per-body attributes of a World, rows in body order (arrays) or items (lists). remove_bodies and the
# rollback of add_bodies treat them together: a new per-body attribute belongs here (an engine test
# fails when an array with a row per body is missing from this list).
BODY_ARRAYS = ("kind", "particle", "mass", "inv_mass", "inertia_body", "inv_inertia_body", "com_local",
               "restitution", "friction", "static_friction", "stiffness", "damping_ratio", "group", "mask")
BODY_LISTS = ("_names", "shapes", "user_shapes", "material_names")
MODELS = ("rigid", "particle")
_KIND, _MODEL = Choice(KINDS), Choice(MODELS)
ALL_GROUPS = 0xFFFFFFFF
_NO_BODIES = np.zeros(0, np.int64)   # _nonfinite_bodies' usual answer (read only: its size)


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


@dataclass(frozen=True)
class Snapshot:
    """A world's state at ``World.snapshot()``, for ``World.restore``: what a step and the state
    inputs (poses, velocities, joint positions) change, and nothing the scene fixes.

    ``state``: the bodies' ``_State`` (motion and the poses given); ``time`` (s); ``contact_cache``:
    what a step carries to the next (warm starts, the preflight record); the last step's outputs
    ``contacts``, ``last_solve``, ``last_detection``; ``robots``: per robot its model and joint
    record ``(model, q, qd, t, before)``; ``bodies``: the body set it belongs to (the world's
    ``kind`` array, replaced whenever a body is added or removed)."""

    state: "_State"
    time: float
    contact_cache: ContactCache
    contacts: Contacts
    last_solve: StepStats
    last_detection: object
    robots: tuple
    bodies: np.ndarray


class _State:
    """Per-body state arrays (a row per body): the motion a step advances and the poses given to
    kinematic bodies; copied whole by ``World.snapshot``, ``reset`` and input refused atomically."""

    NAMES = ("pos", "vel", "quat", "omega", "principal_q", "principal_moments", "stamp", "posed", "pose_pos",
             "pose_quat", "pose_vel", "pose_omega", "pose_gap", "stepped")

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
        self.pose_vel = np.zeros((0, 3))      # the last pose's velocity and angular velocity (the finite
        self.pose_omega = np.zeros((0, 3))    # differences from the pose before; 0 after a first pose) and
        self.pose_gap = np.zeros(0)           # the interval of those two poses' stamps (s; 0 after a first pose)
        self.stepped = np.zeros((0, 7))       # centre and orientation where the last step left each body: a
        #                                       pose given since moved a kinematic body at once (energy.pose_work)

    #: the arrays a step writes; the others change only when poses are given or bodies added
    MOTION = ("pos", "vel", "quat", "omega", "stepped")

    def copy(self):
        c = _State.__new__(_State)   # not __init__: its empty arrays would be replaced at once
        c.__dict__ = {n: getattr(self, n).copy() for n in self.NAMES}
        return c

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


class World(BodyInput):
    """A rigid-body world. See the package docstring for the public contract.

    Every public method checks its arguments before it changes anything (``contact_sim.validate``;
    world bounds from ``settings``): a refused call raises ``ContactSimError`` naming the argument
    and leaves the world bit-identical. ``settings`` and ``gravity`` are checked when assigned too.
    """

    def __init__(self, gravity=(0.0, 0.0, -9.81), settings=None, materials=None):
        """``gravity (3,)`` m/s²; ``settings``: a ``Settings`` or a mapping of its fields;
        ``materials``: a mapping of name → ``Material`` (or a mapping of its fields)."""
        self.settings = Settings() if settings is None else settings
        self.gravity = gravity
        if materials is not None and not isinstance(materials, Mapping):
            raise ContactSimError(f"materials: must be a mapping of name → Material, got {type(materials).__name__}")
        self.materials = {DEFAULT_MATERIAL: Material()}
        for key, mat in (materials or {}).items():
            if not isinstance(key, str) or not key:
                raise ContactSimError(f"materials: names must be non-empty strings, got {show(key)}")
            self.materials[key] = Nested(Material).check(mat, f"materials[{key!r}]")
        self.time = 0.0
        self.contacts = Contacts.empty()
        self.contact_cache = ContactCache()   # what a step keeps for the next (warm starts)
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
        self.stiffness = np.zeros(0)       # N/m of the body's material, 0: rigid
        self.damping_ratio = np.zeros(0)
        self.group = np.zeros(0, np.uint32)
        self.mask = np.zeros(0, np.uint32)
        self._initial = None
        self._last_detection = None   # last_detection's value, or a step's fields for it
        self._last_solve = StepStats()  # last_solve's value, or a step's fields for it
        # tables derived from the model, rebuilt when what they derive from is replaced (``memo``)
        self._derived = {}
        self._body_masks = None
        # robots from URDF (contact_sim.robot.RobotModel): kinematic trees whose links are bodies here
        self.robots = []
        # body-name pairs (sorted tuples) never tested for contact (adjacent robot links, ...);
        # configuration, not state: reset() keeps them, removing a body drops its pairs
        self.disabled_pairs = set()

    @property
    def settings(self):
        """The world's ``Settings`` (model choices and world bounds); each field is checked when set."""
        return self._settings

    @settings.setter
    def settings(self, value):
        self._settings = Nested(Settings).check(value, "settings")

    @property
    def gravity(self):
        """Gravity ``(3,)`` m/s², at most ``settings.max_speed / settings.max_step`` long."""
        return self._gravity

    @gravity.setter
    def gravity(self, value):
        g = GRAVITY.check(value, "gravity", self._settings).copy()
        # read-only: gravity changes only through this setter (checked), so its norm and the
        # per-body rows derived from it (``body_masks``) stay true
        g.flags.writeable = False
        self._gravity = g
        self._gravity_norm = math.sqrt(float(g @ g))

    def __setstate__(self, state):
        """A copy (``copy.deepcopy``) or an unpickled world: copying an array makes it writable,
        and a writable array is another type to numba, so every kernel reading gravity would
        compile a second version (~25 s at the copy's first step). Read-only again, as the setter
        leaves it."""
        self.__dict__.update(state)
        self._gravity.flags.writeable = False

    @property
    def last_solve(self):
        """Statistics of the last step (``StepStats``; zeros before the first step)."""
        v = self._last_solve
        if v.__class__ is tuple:   # a step's fields (``stepper``): made a StepStats when first read
            v = self._last_solve = StepStats(*v)
        return v

    @last_solve.setter
    def last_solve(self, value):
        self._last_solve = value

    @property
    def last_detection(self):
        """Statistics of the last detection (``collision.DetectionStats``; None before the first)."""
        v = self._last_detection
        if v.__class__ is tuple:   # a step's fields: made a DetectionStats when first read
            v = self._last_detection = collision.DetectionStats(*v)
        return v

    @last_detection.setter
    def last_detection(self, value):
        self._last_detection = value

    def gravity_norm(self):
        """``|gravity|`` (m/s²; ``np.linalg.norm``'s value, kept from the last assignment)."""
        return self._gravity_norm

    def body_masks(self):
        """``kinds.BodyMasks`` of the current bodies and gravity, cached until a body is added or
        removed, a kind changes or gravity is assigned: what every step reads (never write into them)."""
        hit = self._body_masks   # read several times a step: identity checks only
        if hit is None or hit[0] is not self.kind or hit[1] is not self.particle or hit[2] is not self._gravity:
            hit = self._body_masks = (self.kind, self.particle, self._gravity,
                                      body_masks(self.kind, self.particle, self._gravity))
        return hit[3]

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
        st = self.settings
        if not isinstance(name, str) or not name:
            raise ContactSimError(f"{w}.name: must be a non-empty string, got {show(name)}")
        if name in self._index:
            raise ContactSimError(f"{w}.name: duplicate body name {name!r}")
        if not isinstance(shape, Shape):
            raise ContactSimError(f"{w}.shape: must be a contact_sim shape, got {type(shape).__name__}")
        _KIND.check(kind, f"{w}.kind")
        _MODEL.check(model, f"{w}.model")
        if not isinstance(material, str) or material not in self.materials:
            raise ContactSimError(f"{w}.material: unknown material {show(material)} "
                                  f"(materials: {', '.join(self.materials)})")
        if not isinstance(self.materials[material], Material):   # world.materials is a plain dict
            raise ContactSimError(f"{w}.material: world.materials[{material!r}] is not a Material, got "
                                  f"{type(self.materials[material]).__name__}")
        pos = POSITION.check(position, f"{w}.position", st)
        q = ORIENTATION.check(orientation, f"{w}.orientation", st)
        vel = VELOCITY.check(velocity, f"{w}.velocity", st)
        omega = ANGULAR_VELOCITY.check(angular_velocity, f"{w}.angular_velocity", st)
        group = GROUP.check(group, f"{w}.group")
        mask = GROUP.check(mask, f"{w}.mask")
        if mass is not None and density is not None:
            raise ContactSimError(f"{w}: give mass or density, not both")
        shape.check_fits(st, f"{w}.shape")

        com = np.zeros(3)
        inertia = np.zeros((3, 3))
        body_mass = np.inf
        if kind == "dynamic":
            if isinstance(shape, Plane):
                raise ContactSimError(f"{w}.shape: a plane is a half-space with no mass; make the body static or kinematic")
            if mass is not None:
                body_mass = MASS.check(mass, f"{w}.mass", st)
                try:
                    m1, com, i1 = shape.mass_properties(1.0)
                except ContactSimError as exc:
                    raise ContactSimError(f"{w}.shape: {exc}") from None
                inertia = i1 * (body_mass / m1)  # uniform density
            else:
                rho = DEFAULT_DENSITY if density is None else DENSITY.check(density, f"{w}.density")
                try:
                    body_mass, com, inertia = shape.mass_properties(rho)
                except ContactSimError as exc:
                    raise ContactSimError(f"{w}.shape: {exc}") from None
                MASS.check(body_mass, f"{w}.{'density' if density is not None else 'shape'} "
                                      f"(a mass of {body_mass:.3g} kg at {rho:g} kg/m³)", st)
        elif mass is not None or density is not None:
            DENSITY.check(mass if mass is not None else density, f"{w}.{'mass' if mass is not None else 'density'}")
        # centre the geometry on the centre of mass (round-off-sized offsets are not worth a copy)
        scale = max(float(np.ptp(getattr(shape, "vertices", np.zeros((1, 3))), axis=0).max()), 1e-12)
        centered = shape.translated(-com) if np.abs(com).max() > 1e-12 * scale else shape
        if centered is shape:
            com = np.zeros(3)

        rotates = kind == "dynamic" and model == "rigid"
        if rotates:
            if not np.all(np.isfinite(inertia)):
                raise ContactSimError(f"{w}.shape: its inertia is not finite ({inertia.tolist()})")
            moments, pq = dynamics.principal_frame(inertia[None])
            moments, pq = moments[0], pq[0]
            with np.errstate(all="ignore"):
                inv_inertia = np.linalg.inv(inertia) if np.all(moments > 0) else np.full((3, 3), np.nan)
            if not np.all(np.isfinite(inv_inertia)):
                raise ContactSimError(f"{w}.shape: its inertia (principal moments {moments.tolist()} kg·m²) cannot "
                                      f"be inverted: the body is too thin or too light to rotate (model: particle?)")
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
        s.pose_vel = np.vstack([s.pose_vel, np.zeros(3)])
        s.pose_omega = np.vstack([s.pose_omega, np.zeros(3)])
        s.pose_gap = np.append(s.pose_gap, 0.0)
        s.stepped = np.vstack([s.stepped, np.concatenate([com_world, q])])
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
        self.stiffness = np.append(self.stiffness, 0.0 if mat.stiffness is None else mat.stiffness)
        self.damping_ratio = np.append(self.damping_ratio, mat.damping_ratio)
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
        saved = self._save_bodies()
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
            self._restore_bodies(saved)
            raise

    def _save_bodies(self):
        """The per-body data as it is now (add_body replaces arrays, never edits them in place), for
        ``_restore_bodies`` to undo an edit of the body set that failed part-way."""
        return ({n: getattr(self, n) for n in BODY_ARRAYS}, {n: list(getattr(self, n)) for n in BODY_LISTS},
                dict(self._index), {n: getattr(self.s, n) for n in _State.NAMES}, self._initial)

    def _restore_bodies(self, saved):
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
        self.contact_cache.remap(new_index)
        self._derived = {}       # every derived table is rebuilt for the new body set
        gone = set(names)
        self.disabled_pairs = {p for p in self.disabled_pairs if not (p[0] in gone or p[1] in gone)}
        # a robot missing a link body can no longer be posed as a whole: it is dropped (its other
        # link bodies stay, as plain kinematic bodies)
        self.robots = [r for r in self.robots if not gone.intersection(r.bodies)]

    # ------------------------------------------------------------------ robots and allowed collisions
    def add_urdf(self, urdf, prefix="", base_pose=None, joint_positions=None, package_paths=None,
                 convex_meshes=False, material=None, srdf=None, disable_collisions=None, exclude_touching=True):
        """Add a robot from a URDF (a file path, or the XML text) and return its body names.

        One kinematic body per ``<collision>`` element, named by its link with ``prefix`` prepended
        (the second and later elements of a link: ``link#1``, ``link#2``, ...), each with its
        element's frame (link pose ∘ ``origin``). Shapes: box, sphere, cylinder (``cs.Cylinder``),
        mesh (with ``scale``; STL, OBJ, DAE through trimesh; a convex mesh, or any when
        ``convex_meshes``, becomes its ``Convex`` hull, others a ``TriMesh``). Mesh URIs:
        ``package://`` (``package_paths``: a mapping package → folder or a list of folders holding
        packages; ``$CONTACT_SIM_PACKAGE_PATH``; the ament index; then the URDF file's folder, as
        pybullet and yourdfpy look there), ``file://``, relative to the URDF file. ``base_pose``:
        ``(position (3,), orientation (4,))`` of the root link (default the origin);
        ``joint_positions``: a mapping joint → position (others 0, or their nearest limit).
        Never tested for contact (``disabled_pairs``; each robot's ``exclusions`` says why): links
        joined by a joint, the pairs an ``srdf`` (MoveIt's semantic description: a path or the XML
        text) lists in its ``disable_collisions``, the pairs ``disable_collisions`` gives (``[[a, b],
        ...]``, each name a link without the prefix, or a body of the world), and with
        ``exclude_touching`` (default) the pairs in contact at the initial configuration between two
        links or a link and a static body (a robot standing on a floor; MoveIt's "Default"). All or
        nothing: a refused robot (an error naming the link, joint or URI) leaves the world unchanged."""
        from . import robot

        return robot.add_urdf(self, urdf, prefix, base_pose, joint_positions, package_paths, convex_meshes,
                              material, srdf=srdf, disable_collisions=disable_collisions,
                              exclude_touching=exclude_touching)

    def set_joint_positions(self, names, positions, stamp=None, place=True):
        """Move robots: ``names (M,)`` joints (with their robot's prefix), ``positions (M,)`` (rad or m)
        at ``stamp`` (s; default the world time). Each joint keeps its own stamp (as
        robot_state_publisher does): its velocity is the finite difference of its consecutive
        positions over their stamps, and a later position at the same stamp replaces the last. Forward
        kinematics (revolute, continuous, prismatic, fixed, mimic) poses every body of each robot
        concerned, and the joint velocities give the bodies' velocities, all at once. A mimic joint's
        position that agrees with its leader's (within 1e-9) is accepted and ignored. Refused by name,
        world unchanged: an unknown joint, a mimic joint that disagrees with its leader, a repeated
        name, a non-finite value, a position beyond its limits by more than 1e-9, a stamp before the
        joint's previous one, a body speed beyond the world's bounds. ``place=False`` only records
        the joints' positions, stamps and velocities (``joint_positions``, the robot's ``q``,
        ``qd``), checked as above but for the body speeds, and leaves the bodies where they are: for
        a caller that poses them itself (the ROS node drives them once a tick)."""
        from . import robot

        robot.set_joint_positions(self, names, positions, stamp, place)

    def pose_robot(self, robot, positions, velocities):
        """Pose the links of ``robot`` (a ``RobotModel`` of ``robots``) at the joint positions
        ``positions`` moving at the joint velocities ``velocities`` (mappings over every movable
        joint that is not a mimic, rad or m, rad/s or m/s): forward kinematics and the links'
        velocities in one pass, as ``set_joint_positions`` poses them, but from the given velocities
        and leaving the joints' record (``joint_positions``, stamps) as it is. For a caller that
        drives the links between the joint states it records (the ROS node, once a tick). Refused,
        world unchanged: a robot not in this world, a link beyond ``settings.max_position`` or
        faster than ``max_speed`` / ``max_angular_speed`` (``BoundsError``)."""
        from . import robot as robot_mod

        robot_mod.pose_robot(self, robot, positions, velocities)

    def joint_positions(self):
        """Every robot's movable joint positions ``{name: position}`` (mimic joints excluded)."""
        return {n: x for r in self.robots for n, x in r.q.items()}

    def disable_collisions(self, pairs):
        """Never test the body pairs ``pairs`` (``[(name_a, name_b), ...]``) for contact; all or nothing."""
        new = set()
        for k, pair in enumerate(pairs):
            if isinstance(pair, (str, bytes)) or len(pair) != 2:
                raise ContactSimError(f"disable_collisions[{k}]: must be a pair of body names, got {show(pair)}")
            a, b = (self._names[self.index(n)] for n in pair)
            if a == b:
                raise ContactSimError(f"disable_collisions[{k}]: a body with itself ({a!r})")
            new.add((min(a, b), max(a, b)))
        self.disabled_pairs = self.disabled_pairs | new

    def remove_robot(self, name):
        """Remove a robot (its name: the prefix + the URDF's robot name) and all its bodies."""
        for r in self.robots:
            if r.name == name:
                self.remove_bodies(r.bodies)
                return
        raise ContactSimError(f"unknown robot {name!r} (robots: {', '.join(r.name for r in self.robots) or 'none'})")

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

    # ------------------------------------------------------------------ stepping
    def step(self, dt=None):
        """Advance the world by ``dt`` seconds (default ``settings.dt``); ``contacts`` then holds
        the contacts of this step with the impulses applied.

        A step is all or nothing: if the engine raises inside it, or leaves a body's state
        non-finite (``EngineError``: an engine failure on valid input, to be reported), the world
        is put back as it was before the step and the error raised."""
        dt = self._check_dt(dt)
        m = stepper.flight(self, dt)   # nothing near anything: one compiled call, all or nothing itself
        if m is None:
            return
        saved = self._step_snapshot()
        try:
            stepper.step(self, dt, m)
        except ContactSimError as exc:
            # every input was checked before the step: a refusal from inside it is the engine's own
            # failure (an internal query handed a bad value), not the caller's bad input
            self._undo_step(saved)
            if isinstance(exc, EngineError):
                raise
            raise EngineError(f"step: an internal query failed ({exc}); the world is as it was before this "
                              f"step (a failure on valid input, please report it)") from exc
        except BaseException:
            self._undo_step(saved)
            raise
        bad = self._nonfinite_bodies()
        if bad.size:
            # the invariant guard: the engine never leaves a non-finite state behind; the step is
            # undone and the bodies are named, so a caller (the node) can keep its last good world
            self._undo_step(saved)
            names = ", ".join(repr(self._names[i]) for i in bad[:10]) + (" ..." if bad.size > 10 else "")
            raise EngineError(f"step: the state of {bad.size} bod{'y' if bad.size == 1 else 'ies'} ({names}) "
                              f"would have become non-finite (a failure on valid input, please report it); "
                              f"the world is as it was before this step")

    def snapshot(self):
        """What stepping and the state inputs change, as it is now (``Snapshot``, copies):
        ``restore`` puts it back. The node takes one around a tick's sub-steps (``step`` keeps
        only what a step changes: ``_step_snapshot``). The model (bodies, shapes, materials,
        settings) is not in it."""
        return Snapshot(self.s.copy(), self.time, self.contact_cache.copy(), self.contacts, self.last_solve,
                        self.last_detection, tuple((r, dict(r.q), dict(r.qd), dict(r.t), dict(r.before))
                                                   for r in self.robots), self.kind)

    def restore(self, snapshot):
        """The state ``snapshot`` (from ``snapshot()`` on this world) holds, back in place; refused
        (``ContactSimError``, the world unchanged) when bodies were added or removed since."""
        if not isinstance(snapshot, Snapshot):
            raise ContactSimError(f"restore: snapshot must be a World.snapshot(), got {type(snapshot).__name__}")
        if snapshot.bodies is not self.kind or any(r not in self.robots for r, *_ in snapshot.robots):
            raise ContactSimError(f"restore: the snapshot is of other bodies ({len(snapshot.bodies)} then, "
                                  f"{len(self)} now): bodies or robots were added or removed since")
        self.s = snapshot.state.copy()
        self.time = snapshot.time
        self.contact_cache = snapshot.contact_cache.copy()
        self.contacts, self.last_solve, self.last_detection = snapshot.contacts, snapshot.last_solve, \
            snapshot.last_detection
        for r, q, qd, t, before in snapshot.robots:
            r.q, r.qd, r.t, r.before = dict(q), dict(qd), dict(t), dict(before)

    def _step_snapshot(self):
        """What a step can change, for ``_undo_step``: ``snapshot``'s cheaper form for ``step``'s own
        undo. A step writes only the motion arrays of the state (``_State.MOTION``, in place), so it
        copies those and keeps the state object with its other arrays as they are; the contact
        cache's fields (a step assigns new records, never edits them), the time and the last step's
        outputs are kept by reference. Robots' joint records are not in it: a step never changes them."""
        s, cache = self.s, self.contact_cache
        # in ``_State.MOTION``'s order, named one by one (a loop over the names costs a third of it)
        return (s, (s.pos.copy(), s.vel.copy(), s.quat.copy(), s.omega.copy(), s.stepped.copy()), self.time,
                cache.warm, cache.preflight_dt, self.contacts, self._last_solve, self._last_detection)

    def _undo_step(self, saved):
        """Put back what ``_step_snapshot`` saved (the world as it was before the step)."""
        s, motion, self.time, warm, preflight_dt, self.contacts, self._last_solve, self._last_detection = saved
        for n, a in zip(_State.MOTION, motion):
            setattr(s, n, a)
        self.s = s
        self.contact_cache.warm, self.contact_cache.preflight_dt = warm, preflight_dt

    def _nonfinite_bodies(self):
        """Indices ``(B,)`` of bodies with a non-finite position, velocity or orientation (one sum per
        array answers the usual all-finite case)."""
        s = self.s
        if free_motion.all_finite(s.pos, s.vel, s.quat, s.omega):
            return _NO_BODIES
        bad = np.zeros(len(self), bool)
        for a in (s.pos, s.vel, s.quat, s.omega):
            bad |= ~np.isfinite(a).all(axis=1)
        return np.flatnonzero(bad)

    def detect(self):
        """All contacts of the current state, without stepping (``Contacts``); the statistics of
        this detection are in ``last_detection``."""
        contacts, self.last_detection = collision.detect_world(self)
        return contacts

    def _check_dt(self, dt):
        """``dt`` by the rule of ``settings.dt`` (> 0, at most ``settings.max_step``)."""
        if dt is None:
            return self.settings.dt
        if type(dt) is float and 0.0 < dt <= self.settings.max_step:   # the rule's answer, without its ~8 us
            return dt
        return float(Settings.rule("dt").check(dt, "step.dt", self.settings))

    def _advance_free(self, dt, half_dv=None, half_dw=None):
        """Move every body as if nothing touched for ``dt``: dynamic bodies ballistically with
        torque-free rotation, kinematic bodies at their constant linear and angular velocity
        (``free_motion.advance``); with ``half_dv, half_dw (N,3)`` between two half-kicks of a
        constant contact force. Returns the rotational energy change (J) of the splitting for
        tumbling bodies (see ``dynamics``), and with the kicks also their
        first-order error bound (J): ``(drift, kick_error)``."""
        s = self.s
        bm = self.body_masks()
        kick = half_dv is not None
        z = np.zeros((0, 3))
        c = np.ascontiguousarray
        drift, kick_error = free_motion.advance(
            s.pos, s.vel, s.quat, s.omega, c(s.principal_q), c(s.principal_moments), c(self.inertia_body),
            self._gravity, bm.dynamic, bm.rotating, bm.kinematic,
            c(half_dv, dtype=float) if kick else z, c(half_dw, dtype=float) if kick else z, kick, float(dt),
            ISOTROPIC_TOLERANCE, MAX_SPLIT_ANGLE, MAX_SUBSTEPS)
        return (drift, kick_error) if kick else drift

    # ------------------------------------------------------------------ reporting
    def _spin(self, mask):
        """World-frame spin angular momentum ``I_w ω (M, 3)`` of the bodies selected by ``mask``."""
        r = quat.to_matrix(self.s.quat[mask])
        inertia_w = r @ self.inertia_body[mask] @ np.swapaxes(r, -1, -2)
        return np.einsum("ijk,ik->ij", inertia_w, self.s.omega[mask])

    def energy(self):
        """Kinetic (linear and rotational) plus gravitational potential energy (J) of the dynamic
        bodies, plus the energy stored in compliant contacts (``contact_energy``)."""
        d = self.kind == DYNAMIC
        s = self.s
        m = self.mass[d]
        lin = 0.5 * np.sum(m * np.einsum("ij,ij->i", s.vel[d], s.vel[d]))
        rigid = d & ~self.particle
        rot = 0.5 * np.sum(np.einsum("ij,ij->i", s.omega[rigid], self._spin(rigid)))
        pot = -np.sum(m * (s.pos[d] @ self.gravity))
        return float(lin + rot + pot) + self.contact_energy()

    def contact_energy(self):
        """Potential energy (J) stored in the compliant contacts of the current state: ``½ Σ k d²``
        over the touching contacts (within ``settings.contact_margin``) with a stiffness, each
        point's ``k`` as the step gives it (``response.compliance``). 0, with no detection, when no
        contact can be compliant."""
        from .response import compliance, models, prepare

        st = self.settings
        if not compliance.possible(self):
            return 0.0
        m = models.choose(self)
        if m.response != "impulse" or not m.resting:
            return 0.0
        from .collision import detect_world

        c, _ = detect_world(self, margin=st.contact_margin)
        k, _ = prepare.stiffnesses(self, c, m)
        dyn = self.kind == DYNAMIC   # two bodies that cannot move store nothing (no force acts)
        k = np.where(dyn[c.body_a] | dyn[c.body_b], k, 0.0)
        return compliance.stored_energy(k, c.depth)

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
        for r in self.robots:
            lines.append(f"robot {r.name}: {len(r.bodies)} link bodies, {len(r.q)} joints")
            why = {}
            for pair, reason in sorted(r.exclusions.items()):
                why.setdefault(reason, []).append(pair)
            for reason, pairs in why.items():
                shown = ", ".join(f"{a}–{b}" for a, b in pairs[:8]) + (" ..." if len(pairs) > 8 else "")
                lines.append(f"  {len(pairs)} pairs never tested ({reason}): {shown}")
        if self.disabled_pairs:
            lines.append(f"{len(self.disabled_pairs)} body pairs never tested (adjacent links, disable_collisions)")
        lines += stepper.describe_models(self)
        return "\n".join(lines)

    # ------------------------------------------------------------------ reset
    def mark_initial(self):
        """Remember the current state as the one ``reset()`` returns to."""
        self._initial = (self.s.copy(), self.time)
        for r in self.robots:
            r.q_initial = dict(r.q)

    def reset(self):
        """Return to the state saved by ``mark_initial()`` (done by ``load_scene``)."""
        if self._initial is None:
            raise ContactSimError("reset: no initial state was saved (call mark_initial first)")
        state, t = self._initial
        self.s = state.copy()
        self.time = t
        self.contacts = Contacts.empty()
        for r in self.robots:
            r.reset()
        self.contact_cache.reset()
