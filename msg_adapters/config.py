"""The node's parameters: declarations, validation, and the world they describe.

No node here: ``validate_config`` checks a dict of raw parameter values and ``build_world`` loads
the scene they name, so both are usable (and testable) without a running node. Shipped scenes are
found in the source tree when the package runs from it, else through the ament index (a colcon
install, with or without ``--symlink-install``), else under the Python prefix (``pip install``).
"""
import copy
import math
import os
from dataclasses import dataclass

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.parameter import Parameter

import contact_sim
from contact_sim.kinds import KINEMATIC
from contact_sim.scene import source_scenes_dir
from contact_sim.settings import parse_settings
from contact_sim.validate import Flag, Number, Rule

PACKAGE = "contact_sim"
MODEL_STRING = {  # parameter -> engine setting; "" keeps the scene's value
    "model.toi": "toi", "model.response": "response", "model.friction": "friction", "model.resting": "resting",
}
TRISTATE = {"true": True, "false": False, "auto": "auto"}


class ConfigError(ValueError):
    """A parameter value that cannot be used; the message names the parameter and the reason."""


class Text(Rule):
    """A string (``nonempty``: with something besides blanks)."""

    def __init__(self, nonempty=False, what="a string"):
        self.nonempty, self.what = nonempty, what

    def check(self, value, path, ctx=None):
        if not isinstance(value, str) or (self.nonempty and not value.strip()):
            raise contact_sim.ContactSimError(f"{path}: must be {self.what}, got {value!r}")
        return value


class Names(Rule):
    """A list of non-empty strings (unset: empty), unique when ``unique``."""

    def __init__(self, unique=False, what="a list of non-empty strings"):
        self.unique, self.what = unique, what

    def check(self, value, path, ctx=None):
        v = [] if value is None else list(value)
        if not all(isinstance(x, str) and x for x in v):
            raise contact_sim.ContactSimError(f"{path}: must be {self.what}, got {v!r}")
        if self.unique and len(set(v)) != len(v):
            raise contact_sim.ContactSimError(f"{path}: names must be unique, got {v!r}")
        return v


class Pairs(Names):
    """A list of ``'a:b'`` pairs of non-empty names, returned as ``[a, b]`` lists."""

    def check(self, value, path, ctx=None):
        v = super().check(value, path, ctx)
        pairs = [x.split(":") for x in v]
        bad = [x for x, parts in zip(v, pairs) if len(parts) != 2 or not all(parts)]
        if bad:
            raise contact_sim.ContactSimError(f"{path}: each pair is 'a:b' (a link or a body on each side), "
                                              f"got {bad[0]!r}")
        return pairs


class BasePose(Rule):
    """Unset or empty (None), or ``[x, y, z, qx, qy, qz, qw]`` finite with a unit quaternion (within
    1e-3), returned as ``(position, quaternion)``."""

    def check(self, value, path, ctx=None):
        pose = [] if value is None else list(value)
        if not pose:
            return None
        if (len(pose) != 7 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                                      for x in pose) or abs(np.linalg.norm(pose[3:]) - 1.0) > 1e-3):
            raise contact_sim.ContactSimError(f"{path}: must be [x, y, z, qx, qy, qz, qw] (finite, a unit "
                                              f"quaternion), got {pose!r}")
        return pose[:3], pose[3:]


@dataclass(frozen=True)
class Param:
    """One node parameter: its default (a ``Parameter.Type`` for one declared by type only, unset by
    default), the rule every value is checked by (``contact_sim.validate``'s rules, as the engine's
    settings are), its description, and whether it is read-only (set at start-up only). Its ROS
    descriptor (type, ranges, constraints) is derived from the rule (``descriptor``)."""

    default: object
    rule: Rule
    description: str
    read_only: bool = False
    constraints: str = ""

    def descriptor(self):
        desc = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                   additional_constraints=self.constraints)
        r = self.rule
        if isinstance(self.default, Parameter.Type):
            desc.type = {Parameter.Type.STRING_ARRAY: ParameterType.PARAMETER_STRING_ARRAY,
                         Parameter.Type.DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY}[self.default]
        elif isinstance(r, Number) and r.integer:
            if r.ge is not None and r.le is not None:
                desc.integer_range = [IntegerRange(from_value=int(r.ge), to_value=int(r.le), step=1)]
        elif isinstance(r, Number):
            desc.dynamic_typing = True   # an integer is accepted; the rule checks the type and range
            if r.ge is not None and r.le is not None:
                desc.floating_point_range = [FloatingPointRange(from_value=float(r.ge), to_value=float(r.le),
                                                                step=0.0)]
                desc.additional_constraints = self.constraints or f"{r.ge:g} <= value <= {r.le:g}"
        return desc


_OVERRIDE = "('' keeps the scene's)"
# name: Param. The rules are contact_sim.validate's (Number, Flag) and the few above; the model.*
# overrides are then checked by the engine's own settings rules (parse_settings).
DECLARED = {
    "scene": Param("default", Text(nonempty=True, what="a scene file or a shipped scene"), (
        "Scene file path, or the name of a shipped scene (config/scenes/<name>.yaml). Set at run time to load "
        "another scene; a scene that fails validation is refused.")),
    "rate_hz": Param(100.0, Number(ge=0.1, le=2000.0, unit="Hz"), (
        "Tick rate (Hz); every tick advances the world by exactly 1/rate_hz seconds."), read_only=True),
    "substeps": Param(1, Number(ge=1, le=1000, integer=True), "Engine steps per tick (each 1/(rate_hz*substeps) s)."),
    "frame_id": Param("world", Text(), ("Frame of every published pose, point and marker; incoming poses must be in "
                                        "it (or have an empty frame_id).")),
    "tracked_bodies": Param(Parameter.Type.STRING_ARRAY, Names(unique=True, what="a list of body names"), (
        "Kinematic bodies driven by body_poses: pose i drives tracked_bodies[i]. Unset or empty: all kinematic "
        "bodies of the scene, in scene order.")),
    "publish_markers": Param(True, Flag(), ("Publish contact_markers (MarkerArray) for RViz; turning it off (or "
                                            "stopping the node) sends a DELETEALL.")),
    "publish_clock": Param(False, Flag(), (
        "Publish /clock (rosgraph_msgs/Clock) from the world time and stamp every output with it; ticks then run on "
        "the steady clock. Not with use_sim_time."), read_only=True),
    "max_marker_arrows": Param(10, Number(ge=0, le=100000, integer=True), (
        "Arrows for at most this many of the largest impulses per tick (every impulse is also drawn as a line "
        "segment).")),
    "impulse_marker_scale": Param(1.0, Number(ge=0.0, le=1e6, unit="m/(N*s)"), "Impulse arrow length in m per N*s."),
    "pose_timeout": Param(0.5, Number(ge=0.001, le=3600.0, unit="s"), (
        "Seconds without a pose after which a tracked body holds its last pose and its velocity decays to zero.")),
    "velocity_decay": Param(0.1, Number(ge=0.0, le=3600.0, unit="s"),
                            "Time constant (s) of that decay; 0 stops the body at once."),
    "diagnostics_period": Param(1.0, Number(ge=0.0, le=3600.0, unit="s"),
                                "Seconds between /diagnostics messages; 0 publishes every tick."),
    "stats_window": Param(1000, Number(ge=1, le=1000000, integer=True), (
        "Number of most recent ticks over which the diagnostics' tick_time_ms_p50/p99/max are computed."),
        read_only=True),
    "thread_priority": Param(0, Number(ge=0, le=99, integer=True), (
        "SCHED_FIFO priority (1-99) of the thread that runs the ticks, set by the node's process before it spins "
        "(as ros2_control's controller manager runs its loop at 50); 0 keeps the normal scheduler. Needs "
        "CAP_SYS_NICE or an rtprio limit: refused, the node warns and runs at normal priority."), read_only=True),
    "model.toi": Param("", Text(), f"Override the scene's time-of-impact policy {_OVERRIDE}.",
                       constraints="'' | auto | next_step | fractional | swept"),
    "model.response": Param("", Text(), f"Override the scene's contact response {_OVERRIDE}.",
                            constraints="'' | auto | kinematic | penalty | impulse"),
    "model.friction": Param("", Text(), f"Override friction on/off {_OVERRIDE}.",
                            constraints="'' | auto | true | false"),
    "model.resting": Param("", Text(), f"Override the resting-contact solver on/off {_OVERRIDE}.",
                           constraints="'' | auto | true | false"),
    "model.solver_iterations": Param(0, Number(ge=0, le=100000, integer=True),
                                     "Override the solver iterations (0 keeps the scene's)."),
    "model.contact_margin": Param(-1.0, Number(unit="m"),
                                  "Override the contact margin in m (negative keeps the scene's).",
                                  constraints="negative, or the engine's contact_margin rule"),
    "robot_description_topic": Param("robot_description", Text(), (
        "Topic of the robot's URDF (std_msgs/String, transient local): its links become kinematic bodies, moved by "
        "joint_states_topic. Empty: no robot input."), read_only=True),
    "joint_states_topic": Param("joint_states", Text(), "Topic of the robot's sensor_msgs/JointState.",
                                read_only=True),
    "robot_description_semantic_topic": Param("robot_description_semantic", Text(), (
        "Topic of the robot's SRDF (std_msgs/String, transient local): its disable_collisions pairs are never "
        "tested. Empty: not read."), read_only=True),
    "robot_prefix": Param("", Text(), (
        "Prefix of the robot's body and joint names (the URDF's link and joint names after it)."), read_only=True),
    "robot_base_pose": Param(Parameter.Type.DOUBLE_ARRAY, BasePose(), (
        "Pose of the robot's root link in frame_id: [x, y, z, qx, qy, qz, qw] (m, quaternion). Unset or empty: the "
        "origin."), read_only=True),
    "robot_disable_collisions": Param(Parameter.Type.STRING_ARRAY, Pairs(), (
        "Pairs never tested for contact, each 'a:b': a robot link without robot_prefix, or a scene body by name "
        "(a robot's base on a table, a gripper's own fixture)."), read_only=True),
    "robot_exclude_touching": Param(True, Flag(), (
        "Never test the pairs in contact at the robot's initial configuration between two of its links, or a link "
        "and a static body (a robot standing on a floor; MoveIt's 'Default'); /diagnostics lists them."),
        read_only=True),
    "package_paths": Param(Parameter.Type.STRING_ARRAY, Names(), (
        "Folders holding the packages the robot's package:// mesh URIs name (besides $CONTACT_SIM_PACKAGE_PATH, "
        "$ROS_PACKAGE_PATH and the ament index)."), read_only=True),
}
#: name -> (default, ParameterDescriptor): what the node declares, derived from ``DECLARED``
PARAMETERS = {name: (p.default, p.descriptor()) for name, p in DECLARED.items()}


def validate_config(values):
    """Check raw parameter values (a dict name -> value) by each parameter's rule (``DECLARED``),
    then what relates parameters; return the normalised config or raise ``ConfigError`` naming the
    parameter. Scene loading and body names are checked separately."""
    cfg = dict(values)
    try:
        for name, p in DECLARED.items():
            cfg[name] = p.rule.check(cfg[name], f"parameter {name}")
    except contact_sim.ContactSimError as exc:
        raise ConfigError(str(exc)) from None
    if cfg["robot_description_topic"] and not cfg["joint_states_topic"]:
        raise ConfigError("parameter joint_states_topic: must name a topic when robot_description_topic is set")
    overrides = {}
    for pname, key in MODEL_STRING.items():
        v = cfg[pname].strip().lower()
        if v:
            overrides[key] = TRISTATE.get(v, v) if key in ("friction", "resting") else v
    if cfg["model.solver_iterations"]:
        overrides["solver_iterations"] = cfg["model.solver_iterations"]
    if cfg["model.contact_margin"] >= 0:
        overrides["contact_margin"] = cfg["model.contact_margin"]
    try:   # the engine's own rules for the settings they override
        checked = parse_settings(overrides)
    except contact_sim.ContactSimError as exc:
        raise ConfigError(f"parameter model.{str(exc).split('.', 1)[1] if '.' in str(exc) else exc}") from None
    cfg["model_overrides"] = {k: getattr(checked, k) for k in overrides}
    return cfg


def package_share():
    """The share folder of the installed ROS package (ament index), or None when it is not installed
    (no AMENT_PREFIX_PATH, or the package is not in it)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return get_package_share_directory(PACKAGE)
    except Exception:  # PackageNotFoundError, or no ament prefix path at all (a plain venv)
        return None


def scene_search():
    """Folders to look for shipped scenes in: the source tree's when running from it, else the
    installed package's share folder."""
    if source_scenes_dir() is not None:
        return []          # the engine's own default: config/scenes of this source tree
    share = package_share()
    return [os.path.join(share, "config", "scenes")] if share else []


def build_world(cfg):
    """Load the scene of ``cfg``, apply the model overrides, resolve the tracked bodies.
    Returns ``(world, scene_path, tracked_names, tracked_indices, scene_settings)``; raises ``ConfigError``."""
    try:
        path = contact_sim.resolve_scene(cfg["scene"], search=scene_search())
        world = contact_sim.load_scene(path)
    except contact_sim.ContactSimError as exc:
        raise ConfigError(f"parameter scene={cfg['scene']!r}: {exc}") from None
    scene_settings = copy.deepcopy(world.settings)
    apply_model(world, scene_settings, cfg)
    tracked, idx = resolve_tracked(world, cfg["tracked_bodies"], path)
    return world, path, tracked, idx, scene_settings


def resolve_tracked(world, requested, path):
    """Names and indices of the tracked bodies (all kinematic bodies when ``requested`` is empty)."""
    names = world.body_names
    links = {b for r in world.robots for b in r.bodies}    # robot links follow joint positions, not poses
    tracked = list(requested) or [n for n, k in zip(names, world.kind) if k == 1 and n not in links]
    for n in tracked:
        if n not in names:
            raise ConfigError(f"parameter tracked_bodies: unknown body {n!r} in scene {path} "
                              f"(bodies: {', '.join(names)})")
        if world.kind[names.index(n)] != KINEMATIC:
            raise ConfigError(f"parameter tracked_bodies: body {n!r} is not kinematic; only kinematic bodies "
                              f"are driven by poses")
    return tracked, np.array([names.index(n) for n in tracked], np.int64)


def apply_model(world, scene_settings, cfg):
    """The scene's model settings with the parameter overrides on top."""
    for key in list(MODEL_STRING.values()) + ["solver_iterations", "contact_margin"]:
        setattr(world.settings, key, cfg["model_overrides"].get(key, getattr(scene_settings, key)))


