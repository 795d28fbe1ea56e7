"""The ``contact_sim`` ROS 2 node: poses in, contacts and impulses out, on a timer.

Thin by design: parameters, a timer, one subscription, publishers and services. All physics is
``contact_sim.World``; all message work is ``msg_adapters.conversions``.

Run: ``contact_sim_node --ros-args --params-file config/contact_sim.params.yaml`` or
``python -m msg_adapters --ros-args -p scene:=kinematic_paddle``.
"""
import collections
import copy
import math
import sys
import time

import numpy as np
import rclpy
import rclpy.exceptions
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType,
                                SetParametersResult)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

import contact_sim
from contact_sim.settings import parse_settings

from .conversions import (CdrError, PoseError, contact_markers, contacts_to_pointcloud2, diagnostic_array,
                          engine_reject_reason, make_header, parse_posearray_cdr, posearray_cdr, validate_poses)

NODE_NAME = "contact_sim"
DIAG_NAME = "contact_sim: world"
POSE_REJECT_REASONS = ("malformed", "length", "nonfinite", "zero_quaternion", "non_unit_quaternion", "stamp",
                       "frame_id", "out_of_bounds", "engine")
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
    "publish_markers": (True, _d("Publish contact_markers (MarkerArray) for RViz.")),
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
    for name in ("substeps", "max_marker_arrows", "model.solver_iterations", "stats_window"):
        v = cfg[name]
        ir = PARAMETERS[name][1].integer_range[0]
        if isinstance(v, bool) or not isinstance(v, int) or not ir.from_value <= v <= ir.to_value:
            raise ConfigError(f"parameter {name}: must be an integer in [{ir.from_value}, {ir.to_value}], got {v!r}")
    for name in ("scene", "frame_id") + tuple(MODEL_STRING):
        if not isinstance(cfg[name], str):
            raise ConfigError(f"parameter {name}: must be a string, got {cfg[name]!r}")
    if not cfg["scene"].strip():
        raise ConfigError("parameter scene: must name a scene file or a shipped scene, got ''")
    if not isinstance(cfg["publish_markers"], bool):
        raise ConfigError(f"parameter publish_markers: must be true or false, got {cfg['publish_markers']!r}")
    tb = cfg["tracked_bodies"]
    tb = [] if tb is None else list(tb)
    if not all(isinstance(n, str) and n for n in tb):
        raise ConfigError(f"parameter tracked_bodies: must be a list of body names, got {tb!r}")
    if len(set(tb)) != len(tb):
        raise ConfigError(f"parameter tracked_bodies: names must be unique, got {tb!r}")
    cfg["tracked_bodies"] = tb
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


def build_world(cfg):
    """Load the scene of ``cfg``, apply the model overrides, resolve the tracked bodies.
    Returns ``(world, scene_path, tracked_names, tracked_indices, scene_settings)``; raises ``ConfigError``."""
    try:
        path = contact_sim.resolve_scene(cfg["scene"])
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
    tracked = list(requested) or [n for n, k in zip(names, world.kind) if k == 1]
    for n in tracked:
        if n not in names:
            raise ConfigError(f"parameter tracked_bodies: unknown body {n!r} in scene {path} "
                              f"(bodies: {', '.join(names)})")
        if world.kind[names.index(n)] != 1:
            raise ConfigError(f"parameter tracked_bodies: body {n!r} is not kinematic; only kinematic bodies "
                              f"are driven by poses")
    return tracked, np.array([names.index(n) for n in tracked], np.int64)


def apply_model(world, scene_settings, cfg):
    """The scene's model settings with the parameter overrides on top."""
    for key in list(MODEL_STRING.values()) + ["solver_iterations", "contact_margin"]:
        setattr(world.settings, key, cfg["model_overrides"].get(key, getattr(scene_settings, key)))


class ContactSimNode(Node):
    """See the module docstring and the README section "ROS interface"."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        try:
            self._setup()
        except Exception:
            self.destroy_node()
            raise

    # ------------------------------------------------------------------ set-up
    def _setup(self):
        for name, (default, desc) in PARAMETERS.items():
            try:
                self.declare_parameter(name, default, desc)
            except rclpy.exceptions.ParameterException as exc:  # wrong type or out of range at start-up
                raise ConfigError(f"parameter {name}: {exc}") from None
        self.cfg = validate_config(self._raw_params())
        self._install_world(*build_world(self.cfg))
        self.period = 1.0 / self.cfg["rate_hz"]

        self.paused = False
        self.counts = collections.Counter()
        # tick times (s) of the last stats_window ticks: a ring buffer (no per-publish list conversion)
        self._tick_buf = np.zeros(self.cfg["stats_window"])
        self._ticks_timed = 0
        self.step_time = 0.0
        self._last_tick_start = None
        self._last_diag = -math.inf
        self._warned = {}
        self._diag_snapshot = collections.Counter()

        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_contacts = self.create_publisher(PointCloud2, "contacts", reliable)
        self.pub_states = self.create_publisher(PoseArray, "body_states", reliable)
        self.pub_names = self.create_publisher(String, "body_names", latched)
        self.pub_markers = self.create_publisher(MarkerArray, "contact_markers", reliable)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", reliable)
        self.sub_poses = self.create_subscription(
            PoseArray, "body_poses", self._on_poses,
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST), raw=True)
        self.srv_reset = self.create_service(Trigger, "~/reset", self._on_reset)
        self.srv_pause = self.create_service(SetBool, "~/pause", self._on_pause)
        self.srv_step = self.create_service(Trigger, "~/step", self._on_step)
        self.add_pre_set_parameters_callback(self._pre_set_parameters)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._publish_names()
        self.timer = self.create_timer(self.period, self._on_timer)
        self.get_logger().info(
            f"scene {self.scene_path}: {self.world.describe().splitlines()[0]}; tracking "
            f"{', '.join(self.tracked) or 'no bodies'}; {self.cfg['rate_hz']:g} Hz x {self.cfg['substeps']} substeps")

    def _raw_params(self):
        out = {}
        for name in PARAMETERS:
            try:
                out[name] = self.get_parameter(name).value
            except rclpy.exceptions.ParameterUninitializedException:
                out[name] = None
        return out

    def _install_world(self, world, path, tracked, tracked_idx, scene_settings):
        self.world, self.scene_path, self.tracked, self.tracked_idx = world, path, tracked, tracked_idx
        self.scene_settings = scene_settings
        self._reset_tracking()

    def _reset_tracking(self):
        n = len(self.tracked)
        self._t0_ns = None
        self._last_pose_stamp_ns = None
        self._last_rx = np.full(n, -np.inf)         # node-clock seconds of the last accepted pose
        self._held_pos = np.zeros((n, 3))
        self._held_quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        self._posed = np.zeros(n, bool)
        self.world.contacts = contact_sim.Contacts.empty()

    # ------------------------------------------------------------------ helpers
    def _now_ns(self):
        return self.get_clock().now().nanoseconds

    def _warn(self, key, text, period=1.0):
        """A warning at most once per ``period`` per ``key``; says how many were suppressed."""
        now = time.monotonic()
        last, suppressed = self._warned.get(key, (-math.inf, 0))
        if now - last >= period:
            extra = f" ({suppressed} more like this suppressed)" if suppressed else ""
            self.get_logger().warning(text + extra)
            self._warned[key] = (now, 0)
        else:
            self._warned[key] = (last, suppressed + 1)

    def _reject_pose(self, reason, text):
        self.counts["rejected_poses"] += 1
        self.counts["rejected_pose_" + reason] += 1
        self._warn("pose_" + reason, f"body_poses rejected ({reason}): {text}; the world keeps its last good state")

    # ------------------------------------------------------------------ input
    def _on_poses(self, data):
        """Raw-subscription callback; also drains whatever else is queued, so a burst of poses costs
        one executor round trip instead of one per message (rclpy takes one message per wait)."""
        self._handle_pose(data)
        sub = self.sub_poses
        try:
            for _ in range(10000):
                with sub.handle:
                    info = sub.handle.take_message(sub.msg_type, sub.raw)
                if info is None:
                    break
                self._handle_pose(info[0])
        except Exception as exc:  # internal rclpy API changed or handle gone: one message per callback
            self._warn("drain", f"cannot drain body_poses ({type(exc).__name__}: {exc}); taking one per callback")

    def _handle_pose(self, data):
        self.counts["poses_received"] += 1
        try:
            stamp_ns, frame_id, p, q = parse_posearray_cdr(data)
        except CdrError as exc:
            return self._reject_pose("malformed", str(exc))
        if frame_id and frame_id != self.cfg["frame_id"]:
            return self._reject_pose("frame_id", f"frame_id {frame_id!r}, expected {self.cfg['frame_id']!r}")
        try:
            p, q = validate_poses(p, q, len(self.tracked), self.world.settings.quaternion_tolerance, "body_poses")
        except PoseError as exc:
            return self._reject_pose(exc.reason, str(exc))
        now_ns = self._now_ns()
        if stamp_ns == 0:
            stamp_ns = now_ns
        if self._last_pose_stamp_ns is not None and stamp_ns <= self._last_pose_stamp_ns:
            return self._reject_pose("stamp", f"stamp {stamp_ns * 1e-9:.9f} s is not after the previous pose's "
                                              f"{self._last_pose_stamp_ns * 1e-9:.9f} s")
        if self._t0_ns is None:
            self._t0_ns = stamp_ns
        t = (stamp_ns - self._t0_ns) * 1e-9
        try:  # checked as a whole by the engine: a refused batch changes nothing
            self.world.set_poses(self.tracked, p, q, t)
        except contact_sim.ContactSimError as exc:   # out_of_bounds: beyond a world bound (settings.max_*)
            return self._reject_pose(engine_reject_reason(exc), str(exc))
        self._last_pose_stamp_ns = stamp_ns
        self._last_rx[:] = now_ns * 1e-9
        self._held_pos, self._held_quat = p, q
        self._posed[:] = True
        self.counts["poses_accepted"] += 1

    def _candidate(self, params):
        values = self._raw_params()
        for prm in params:
            values[prm.name] = prm.value
        return values

    def _reject_parameters(self, params, exc):
        self.counts["rejected_parameters"] += 1
        self._warn("param:" + ",".join(sorted(p.name for p in params)),
                   f"parameter change rejected: {exc}; keeping the current configuration")

    def _pre_set_parameters(self, params):
        """Runs before rclpy checks types, ranges and read-only flags: counts and names every bad
        value (rclpy or ``_on_set_parameters`` then refuses it)."""
        try:
            validate_config(self._candidate(params))
        except ConfigError as exc:
            self._reject_parameters(params, exc)
            return params
        for prm in params:
            if PARAMETERS.get(prm.name, (None, ParameterDescriptor()))[1].read_only:
                self._reject_parameters(params, f"parameter {prm.name} is read-only (set it at start-up)")
                break
        return params

    def _on_set_parameters(self, params):
        try:
            cfg = validate_config(self._candidate(params))  # refused and counted already in the pre-set step
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        new_world = None
        changed = {p.name for p in params}
        try:
            if "scene" in changed:
                new_world = build_world(cfg)
            elif "tracked_bodies" in changed:  # same world, other bodies: no reload
                tracked, idx = resolve_tracked(self.world, cfg["tracked_bodies"], self.scene_path)
        except ConfigError as exc:
            self._reject_parameters(params, exc)
            return SetParametersResult(successful=False, reason=str(exc))
        self.cfg = cfg
        if new_world is None and "tracked_bodies" in changed:
            self.tracked, self.tracked_idx = tracked, idx
            self._reset_tracking()
        if new_world is not None:
            self._install_world(*new_world)
            self._publish_names()
            self.get_logger().info(f"loaded scene {self.scene_path}; tracking {', '.join(self.tracked) or 'nothing'}")
        apply_model(self.world, self.scene_settings, cfg)
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ services
    def _on_reset(self, request, response):
        self.world.reset()
        self._reset_tracking()
        self.counts["resets"] += 1
        self._publish_states(self._now_ns())
        response.success = True
        response.message = f"reset to the initial state of {self.scene_path}"
        return response

    def _on_pause(self, request, response):
        self.paused = bool(request.data)
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def _on_step(self, request, response):
        if not self.paused:
            response.success = False
            response.message = "not paused: the world steps on its timer; call ~/pause with data=true first"
            return response
        ok = self._tick_work(time.perf_counter())
        response.success = ok
        response.message = f"stepped to t = {self.world.time:.6f} s" if ok else "step failed; state kept (see log)"
        return response

    # ------------------------------------------------------------------ the tick
    def _on_timer(self):
        start = time.perf_counter()
        if self._last_tick_start is not None:
            behind = int((start - self._last_tick_start) / self.period + 0.5) - 1
            if behind > 0:  # ticks the timer could not honour: counted, never caught up
                self.counts["skipped_ticks"] += behind
        self._last_tick_start = start
        if self.paused:
            now_ns = self._now_ns()
            self._publish_states(now_ns)
            self._maybe_diagnostics(now_ns)
            return
        self._tick_work(start)

    def _hold_timed_out(self, now_s):
        """Tracked bodies without a pose for pose_timeout: back to the last pose, velocity decays."""
        if not len(self.tracked):
            return
        stale = self._posed & (now_s - self._last_rx > self.cfg["pose_timeout"])
        if not stale.any():
            return
        tau = self.cfg["velocity_decay"]
        f = math.exp(-self.period / tau) if tau > 0 else 0.0
        s = self.world.s
        for j in np.flatnonzero(stale):
            i = self.tracked_idx[j]
            v, w = s.vel[i] * f, s.omega[i] * f
            if np.abs(v).max() < 1e-9 and np.abs(w).max() < 1e-9:
                v, w = np.zeros(3), np.zeros(3)
            self.world.set_state(self.tracked[j], position=self._held_pos[j], orientation=self._held_quat[j],
                                 velocity=v, angular_velocity=w)

    def _tick_work(self, start):
        """One fixed step (substeps engine steps) and the publications. False if the engine failed."""
        world = self.world
        now_ns = self._now_ns()
        self._hold_timed_out(now_ns * 1e-9)
        saved, t_saved = world.s.copy(), world.time
        dt = self.period / self.cfg["substeps"]
        parts = []
        t0 = time.perf_counter()
        try:
            for _ in range(self.cfg["substeps"]):
                world.step(dt)
                parts.append(world.contacts)
        except Exception as exc:  # an engine failure must not take the node down
            world.s, world.time = saved, t_saved
            world.contacts = contact_sim.Contacts.empty()
            self.counts["step_errors"] += 1
            self._warn("step", f"world.step failed, state restored: {type(exc).__name__}: {exc}")
            return False
        self.step_time = time.perf_counter() - t0
        contacts = parts[0] if len(parts) == 1 else contact_sim.Contacts.concat(parts)
        self.contacts = contacts
        self.counts["ticks"] += 1
        header = make_header(self.cfg["frame_id"], self._now_ns())
        self.pub_contacts.publish(contacts_to_pointcloud2(contacts, header))
        self._publish_states(now_ns)
        if self.cfg["publish_markers"]:
            self.pub_markers.publish(contact_markers(contacts, header, self.cfg["impulse_marker_scale"],
                                                     self.cfg["max_marker_arrows"]))
        elapsed = time.perf_counter() - start
        self._tick_buf[self._ticks_timed % len(self._tick_buf)] = elapsed
        self._ticks_timed += 1
        self._last_tick_time = elapsed
        if elapsed > self.period:
            self.counts["overruns"] += 1
        self._maybe_diagnostics(now_ns)
        return True

    # ------------------------------------------------------------------ output
    def body_poses(self):
        """Body-frame origins (N, 3) and orientations (N, 4) of all bodies, vectorised."""
        return self.world.poses()

    def _publish_states(self, now_ns):
        p, q = self.body_poses()
        self.pub_states.publish(posearray_cdr(p, q, self.cfg["frame_id"], now_ns))

    def _publish_names(self):
        self.pub_names.publish(String(data="\n".join(self.world.body_names)))

    def diagnostics_values(self):
        c = self.counts
        n = min(self._ticks_timed, len(self._tick_buf))
        times = self._tick_buf[:n] * 1e3 if n else np.zeros(1)
        p50, p99 = np.percentile(times, [50, 99])
        last = self._last_tick_time * 1e3 if n else 0.0
        contacts = getattr(self, "contacts", None)
        contacts = contact_sim.Contacts.empty() if contacts is None else contacts
        solve = getattr(self.world, "last_solve", None)  # a dict (stepper) or an object; may not exist
        residual = solve.get("residual") if isinstance(solve, dict) else getattr(solve, "residual", None)
        iterations = solve.get("iterations") if isinstance(solve, dict) else getattr(solve, "iterations", None)
        try:
            residual = float(residual)
        except (TypeError, ValueError):
            residual = float("nan")
        values = {
            "scene": self.scene_path,
            "sim_time_s": float(self.world.time),
            "paused": self.paused,
            "ticks": c["ticks"],
            "step_time_ms": self.step_time * 1e3,
            "tick_time_ms_last": float(last),
            "tick_time_ms_p50": float(p50),
            "tick_time_ms_p99": float(p99),
            "tick_time_ms_max": float(times.max()),
            "tick_overruns": c["overruns"],
            "skipped_ticks": c["skipped_ticks"],
            "contacts": len(contacts),
            "max_penetration_m": float(contacts.depth.max()) if len(contacts) else 0.0,
            "energy_J": float(self.world.energy()),
            "solver_residual": residual,
            "solver_iterations": iterations if isinstance(iterations, int) else -1,
            "poses_received": c["poses_received"],
            "poses_accepted": c["poses_accepted"],
            "rejected_poses": c["rejected_poses"],
        }
        for r in POSE_REJECT_REASONS:
            values["rejected_pose_" + r] = c["rejected_pose_" + r]
        values["rejected_parameters"] = c["rejected_parameters"]
        values["step_errors"] = c["step_errors"]
        values["resets"] = c["resets"]
        return values

    def _maybe_diagnostics(self, now_ns):
        if now_ns * 1e-9 - self._last_diag < self.cfg["diagnostics_period"]:
            return
        self._last_diag = now_ns * 1e-9
        values = self.diagnostics_values()
        new = {k: self.counts[k] - self._diag_snapshot[k]
               for k in ("step_errors", "rejected_poses", "rejected_parameters", "overruns")}
        self._diag_snapshot = collections.Counter(self.counts)
        if new["step_errors"]:
            level, msg = DiagnosticStatus.ERROR, f"{new['step_errors']} engine step failures"
        elif new["rejected_poses"] or new["rejected_parameters"] or new["overruns"]:
            level = DiagnosticStatus.WARN
            msg = (f"rejected {new['rejected_poses']} pose messages and {new['rejected_parameters']} parameter "
                   f"changes; {new['overruns']} tick overruns")
        else:
            level, msg = DiagnosticStatus.OK, "paused" if self.paused else "running"
        self.pub_diag.publish(diagnostic_array(make_header(self.cfg["frame_id"], now_ns), DIAG_NAME,
                                               self.get_fully_qualified_name(), values, level, msg))


def main(args=None):
    """Console script ``contact_sim_node``: 0 on SIGINT/SIGTERM, 2 when the configuration is bad."""
    rclpy.init(args=args)
    try:
        node = ContactSimNode()
    except (ConfigError, contact_sim.ContactSimError) as exc:
        print(f"contact_sim_node: cannot start: {exc}", file=sys.stderr, flush=True)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
