"""The node's parameters: declarations, validation, and the world they describe.

No node here: ``validate_config`` checks a dict of raw parameter values and ``build_world`` loads
the scene they name, so both are usable (and testable) without a running node. Shipped scenes are
found in the source tree when the package runs from it, else through the ament index (a colcon
install, with or without ``--symlink-install``), else under the Python prefix (``pip install``).
"""
import copy
import math
import os

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.parameter import Parameter

import contact_sim
from contact_sim.kinds import KINEMATIC
from contact_sim.scene import source_scenes_dir
from contact_sim.settings import parse_settings

PACKAGE = "contact_sim"
MODEL_STRING = {  # parameter -> engine setting; "" keeps the scene's value
    "model.toi": "toi", "model.response": "response", "model.friction": "friction", "model.resting": "resting",
}
TRISTATE = {"true": True, "false": False, "auto": "auto"}


class ConfigError(ValueError):
    """A parameter value that cannot be used; the message names the parameter and the reason."""


def _d(description, read_only=False, dynamic_typing=False, fp=None, ir=None, constraints="", ptype=None):
    desc = ParameterDescriptor(description=description, read_only=read_only, dynamic_typing=dynamic_typing,
                               additional_constraints=constraints)
    if ptype is not None:
        desc.type = ptype
    if fp is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=fp[0], to_value=fp[1], step=0.0)]
    if ir is not None:
        desc.integer_range = [IntegerRange(from_value=ir[0], to_value=ir[1], step=1)]
    return desc


# name: (default, descriptor). Doubles use dynamic_typing so that an integer is accepted; their
# type and range are then checked by ``validate_config`` (the ranges are also in the descriptor).
PARAMETERS = {
    "scene": ("default", _d("Scene file path, or the name of a shipped scene (config/scenes/<name>.yaml). "
                            "Set at run time to load another scene; a scene that fails validation is refused.")),
    "rate_hz": (100.0, _d("Tick rate (Hz); every tick advances the world by exactly 1/rate_hz seconds.",
                          read_only=True, dynamic_typing=True, fp=(0.1, 2000.0), constraints="0.1 <= rate_hz <= 2000")),
    "substeps": (1, _d("Engine steps per tick (each 1/(rate_hz*substeps) s).", ir=(1, 1000))),
    "frame_id": ("world", _d("Frame of every published pose, point and marker; incoming poses must be in it "
                             "(or have an empty frame_id).")),
    "tracked_bodies": (Parameter.Type.STRING_ARRAY, _d(
        "Kinematic bodies driven by body_poses: pose i drives tracked_bodies[i]. Unset or empty: all kinematic "
        "bodies of the scene, in scene order.", ptype=ParameterType.PARAMETER_STRING_ARRAY)),
    "publish_markers": (True, _d("Publish contact_markers (MarkerArray) for RViz; turning it off (or stopping the "
                                 "node) sends a DELETEALL.")),
    "publish_clock": (False, _d("Publish /clock (rosgraph_msgs/Clock) from the world time and stamp every output with "
                                "it; ticks then run on the steady clock. Not with use_sim_time.", read_only=True)),
    "max_marker_arrows": (10, _d("Arrows for at most this many of the largest impulses per tick (every impulse is "
                                 "also drawn as a line segment).", ir=(0, 100000))),
    "impulse_marker_scale": (1.0, _d("Impulse arrow length in m per N*s.", dynamic_typing=True, fp=(0.0, 1e6))),
    "pose_timeout": (0.5, _d("Seconds without a pose after which a tracked body holds its last pose and its "
                             "velocity decays to zero.", dynamic_typing=True, fp=(0.001, 3600.0))),
    "velocity_decay": (0.1, _d("Time constant (s) of that decay; 0 stops the body at once.",
                               dynamic_typing=True, fp=(0.0, 3600.0))),
    "diagnostics_period": (1.0, _d("Seconds between /diagnostics messages; 0 publishes every tick.",
                                   dynamic_typing=True, fp=(0.0, 3600.0))),
    "stats_window": (1000, _d("Number of most recent ticks over which the diagnostics' tick_time_ms_p50/p99/max "
                              "are computed.", read_only=True, ir=(1, 1000000))),
    "thread_priority": (0, _d("SCHED_FIFO priority (1-99) of the thread that runs the ticks, set by the node's process "
                              "before it spins (as ros2_control's controller manager runs its loop at 50); 0 keeps the "
                              "normal scheduler. Needs CAP_SYS_NICE or an rtprio limit: refused, the node warns and "
                              "runs at normal priority.", read_only=True, ir=(0, 99))),
    "model.toi": ("", _d("Override the scene's time-of-impact policy ('' keeps the scene's).",
                         constraints="'' | auto | next_step | fractional | swept")),
    "model.response": ("", _d("Override the scene's contact response ('' keeps the scene's).",
                              constraints="'' | auto | kinematic | penalty | impulse")),
    "model.friction": ("", _d("Override friction on/off ('' keeps the scene's).", constraints="'' | auto | true | false")),
    "model.resting": ("", _d("Override the resting-contact solver on/off ('' keeps the scene's).",
                             constraints="'' | auto | true | false")),
    "model.solver_iterations": (0, _d("Override the solver iterations (0 keeps the scene's).", ir=(0, 100000))),
    "model.contact_margin": (-1.0, _d("Override the contact margin in m (negative keeps the scene's).",
                                      dynamic_typing=True)),
    "robot_description_topic": ("robot_description", _d(
        "Topic of the robot's URDF (std_msgs/String, transient local): its links become kinematic bodies, moved by "
        "joint_states_topic. Empty: no robot input.", read_only=True)),
    "joint_states_topic": ("joint_states", _d("Topic of the robot's sensor_msgs/JointState.", read_only=True)),
    "robot_description_semantic_topic": ("robot_description_semantic", _d(
        "Topic of the robot's SRDF (std_msgs/String, transient local): its disable_collisions pairs are never "
        "tested. Empty: not read.", read_only=True)),
    "robot_prefix": ("", _d("Prefix of the robot's body and joint names (the URDF's link and joint names after it).",
                            read_only=True)),
    "robot_base_pose": (Parameter.Type.DOUBLE_ARRAY, _d(
        "Pose of the robot's root link in frame_id: [x, y, z, qx, qy, qz, qw] (m, quaternion). Unset or empty: the "
        "origin.", read_only=True, ptype=ParameterType.PARAMETER_DOUBLE_ARRAY)),
    "robot_disable_collisions": (Parameter.Type.STRING_ARRAY, _d(
        "Pairs never tested for contact, each 'a:b': a robot link without robot_prefix, or a scene body by name "
        "(a robot's base on a table, a gripper's own fixture).", read_only=True,
        ptype=ParameterType.PARAMETER_STRING_ARRAY)),
    "robot_exclude_touching": (True, _d(
        "Never test the pairs in contact at the robot's initial configuration between two of its links, or a link "
        "and a static body (a robot standing on a floor; MoveIt's 'Default'); /diagnostics lists them.",
        read_only=True)),
    "package_paths": (Parameter.Type.STRING_ARRAY, _d(
        "Folders holding the packages the robot's package:// mesh URIs name (besides $CONTACT_SIM_PACKAGE_PATH, "
        "$ROS_PACKAGE_PATH and the ament index).", read_only=True, ptype=ParameterType.PARAMETER_STRING_ARRAY)),
}
DOUBLES = {"rate_hz", "impulse_marker_scale", "pose_timeout", "velocity_decay", "diagnostics_period",
           "model.contact_margin"}


def validate_config(values):
    """Check raw parameter values (a dict name -> value); return the normalised config or raise
    ``ConfigError`` naming the parameter. Scene loading and body names are checked separately."""
    cfg = dict(values)
    for name in DOUBLES:
        v = cfg[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"parameter {name}: must be a number, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise ConfigError(f"parameter {name}: must be finite, got {v!r}")
        fp = PARAMETERS[name][1].floating_point_range
        if fp and not fp[0].from_value <= v <= fp[0].to_value:
            raise ConfigError(f"parameter {name}: must be in [{fp[0].from_value:g}, {fp[0].to_value:g}], got {v:g}")
        cfg[name] = v
    for name in ("substeps", "max_marker_arrows", "model.solver_iterations", "stats_window", "thread_priority"):
        v = cfg[name]
        ir = PARAMETERS[name][1].integer_range[0]
        if isinstance(v, bool) or not isinstance(v, int) or not ir.from_value <= v <= ir.to_value:
            raise ConfigError(f"parameter {name}: must be an integer in [{ir.from_value}, {ir.to_value}], got {v!r}")
    for name in ("scene", "frame_id", "robot_description_topic", "joint_states_topic", "robot_prefix",
                 "robot_description_semantic_topic") + \
            tuple(MODEL_STRING):
        if not isinstance(cfg[name], str):
            raise ConfigError(f"parameter {name}: must be a string, got {cfg[name]!r}")
    if cfg["robot_description_topic"] and not cfg["joint_states_topic"]:
        raise ConfigError("parameter joint_states_topic: must name a topic when robot_description_topic is set")
    if not cfg["scene"].strip():
        raise ConfigError("parameter scene: must name a scene file or a shipped scene, got ''")
    for name in ("publish_markers", "publish_clock"):
        if not isinstance(cfg[name], bool):
            raise ConfigError(f"parameter {name}: must be true or false, got {cfg[name]!r}")
    tb = cfg["tracked_bodies"]
    tb = [] if tb is None else list(tb)
    if not all(isinstance(n, str) and n for n in tb):
        raise ConfigError(f"parameter tracked_bodies: must be a list of body names, got {tb!r}")
    if len(set(tb)) != len(tb):
        raise ConfigError(f"parameter tracked_bodies: names must be unique, got {tb!r}")
    cfg["tracked_bodies"] = tb
    for name in ("package_paths", "robot_disable_collisions"):
        v = [] if cfg[name] is None else list(cfg[name])
        if not all(isinstance(x, str) and x for x in v):
            raise ConfigError(f"parameter {name}: must be a list of non-empty strings, got {v!r}")
        cfg[name] = v
    pairs = [p.split(":") for p in cfg["robot_disable_collisions"]]
    bad = [p for p, parts in zip(cfg["robot_disable_collisions"], pairs) if len(parts) != 2 or not all(parts)]
    if bad:
        raise ConfigError(f"parameter robot_disable_collisions: each pair is 'a:b' (a link or a body on each side), "
                          f"got {bad[0]!r}")
    cfg["robot_disable_collisions"] = pairs
    pose = [] if cfg["robot_base_pose"] is None else list(cfg["robot_base_pose"])
    if pose and (len(pose) != 7 or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in pose)
                 or abs(np.linalg.norm(pose[3:]) - 1.0) > 1e-3):
        raise ConfigError(f"parameter robot_base_pose: must be [x, y, z, qx, qy, qz, qw] (finite, a unit "
                          f"quaternion), got {pose!r}")
    cfg["robot_base_pose"] = (pose[:3], pose[3:]) if pose else None
    if not isinstance(cfg["robot_exclude_touching"], bool):
        raise ConfigError(f"parameter robot_exclude_touching: must be true or false, "
                          f"got {cfg['robot_exclude_touching']!r}")
    overrides = {}
    for pname, key in MODEL_STRING.items():
        v = cfg[pname].strip().lower()
        if v:
            overrides[key] = TRISTATE.get(v, v) if key in ("friction", "resting") else v
    if cfg["model.solver_iterations"]:
        overrides["solver_iterations"] = cfg["model.solver_iterations"]
    if cfg["model.contact_margin"] >= 0:
        overrides["contact_margin"] = cfg["model.contact_margin"]
    try:
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


