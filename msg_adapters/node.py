"""The ``contact_sim`` ROS 2 node: poses in, contacts and impulses out, on a timer.

Thin by design: parameters (``config``), a timer, subscriptions, publishers (``publishing``),
body control (``body_control``) and services. All physics is ``contact_sim.World``; all message
work is ``msg_adapters.conversions``.

Run: ``contact_sim_node --ros-args --params-file config/contact_sim.params.yaml`` or
``python -m msg_adapters --ros-args -p scene:=kinematic_paddle``.
"""
import collections
import gc
import math
import os
import time

import numpy as np
import rclpy
import rclpy.exceptions
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockChange, ClockType, JumpThreshold
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks, UnsupportedEventTypeError
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSPolicyKind, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import InvalidQosOverridesError, QoSOverridingOptions
from std_srvs.srv import SetBool, Trigger

import contact_sim

from .body_control import BodyControl
from .robot_input import RobotInput
from .config import (PARAMETERS, ConfigError, apply_model, build_world, resolve_tracked,  # noqa: F401
                     validate_config)
from .conversions import CdrError, PoseError, engine_reject_reason, parse_posearray_cdr, validate_poses
from .publishing import POSE_REJECT_REASONS, Outputs, diag_name  # noqa: F401 (POSE_REJECT_REASONS: for users)

NODE_NAME = "contact_sim"
DIAG_NAME = diag_name(NODE_NAME)   # the status name of a node with the default name


def qos_overrides():
    """Standard QoS parameter overrides (``qos_overrides./<topic>.subscription.<policy>``)."""
    return QoSOverridingOptions([QoSPolicyKind.HISTORY, QoSPolicyKind.DEPTH, QoSPolicyKind.RELIABILITY,
                                 QoSPolicyKind.DURABILITY])


class ContactSimNode(Outputs, BodyControl, RobotInput, Node):
    """See the module docstring and docs/ros.md (every topic, service and parameter)."""

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
        if self.cfg["publish_clock"] and self.get_parameter("use_sim_time").value:
            raise ConfigError("parameters publish_clock and use_sim_time: the node cannot follow the /clock it "
                              "publishes; set one of them")
        self._install_world(*build_world(self.cfg))
        self.period = 1.0 / self.cfg["rate_hz"]

        self.paused = False
        self._heap_frozen = False      # gc.freeze'd by the process's owner (freeze_heap)
        self._thread_priority = 0      # SCHED_FIFO priority of the spinning thread (set_thread_priority)
        self.counts = collections.Counter()
        # tick times (s) of the last stats_window ticks: a ring buffer (no per-publish list conversion)
        self._tick_buf = np.zeros(self.cfg["stats_window"])
        # and the tick thread's CPU time (s) in each: wall time beyond it is time the thread did not
        # run (descheduled by the OS, or blocked), which tells a slow tick from a preempted one
        self._tick_cpu_buf = np.zeros(self.cfg["stats_window"])
        self._ticks_timed = 0
        self._last_tick_time = 0.0
        self.step_time = 0.0
        self._last_tick_start = None
        self._last_step_error = ""
        self._warned = {}
        # why things were refused or warned about, per warning category: the last text ever, and every
        # text (with its count) since the last /diagnostics report, so that none is lost to throttling
        self._last_reason = {}
        self._reasons = {}
        self._last_seq = None          # publication sequence number of the last pose (drop counting)
        self._pose_publishers = 0

        self._create_publishers()
        # best effort matches reliable and best-effort publishers (drivers, mocap bridges); raw bytes
        # parsed with numpy keep up at 1 kHz; the message info carries the sequence numbers
        try:
            self.sub_poses = self._create_pose_subscription()
            self._create_body_control(qos_overrides)
            self._create_robot_input(qos_overrides)
        except (InvalidQosOverridesError, rclpy.exceptions.ParameterException, ValueError, KeyError,
                TypeError, RuntimeError) as exc:   # rclpy raises RuntimeError for an unknown policy value
            raise ConfigError(f"QoS override: {exc}") from None
        self.srv_reset = self.create_service(Trigger, "~/reset", self._on_reset)
        self.srv_pause = self.create_service(SetBool, "~/pause", self._on_pause)
        self.srv_step = self.create_service(Trigger, "~/step", self._on_step)
        self.add_pre_set_parameters_callback(self._pre_set_parameters)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if not self.cfg["publish_clock"]:   # our own /clock goes back only on a reset, handled there
            self._jump_handle = self.get_clock().create_jump_callback(
                JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1), on_clock_change=True),
                post_callback=self._on_time_jump)
        self._publish_names()
        self._publish_clock(self._now_ns())
        # publishing /clock from the world time, the ticks cannot wait on a clock: the steady one drives them
        clock = Clock(clock_type=ClockType.STEADY_TIME) if self.cfg["publish_clock"] else None
        self.timer = self.create_timer(self.period, self._on_timer, clock=clock)
        self.get_logger().info(
            f"scene {self.scene_path}: {self.world.describe().splitlines()[0]}; tracking "
            f"{', '.join(self.tracked) or 'no bodies'}; {self.cfg['rate_hz']:g} Hz x {self.cfg['substeps']} substeps")

    def freeze_heap(self):
        """Move every object alive now (the modules, the kernels, the world) out of the cyclic
        garbage collector's reach (``gc.freeze``), after one last collection: a full collection of
        the node's ~150,000 objects takes 30-40 ms, thirty ticks at 1 kHz, and with them frozen it
        scans only what the ticks make (0.003 ms). The process's owner calls it once the node is
        built (``launch.main``); a scene reload, a new robot and a body deletion refreeze (one
        full collection, 30-40 ms, each), so what they replaced is freed, reference cycles too."""
        gc.collect()
        gc.freeze()
        self._heap_frozen = True

    def set_thread_priority(self):
        """Run the calling thread (the one that will spin the node and so run its ticks) under
        SCHED_FIFO at the ``thread_priority`` parameter, as ros2_control's controller manager runs
        its 1 kHz loop: ticks then preempt the machine's ordinary processes instead of waiting for
        their time slice. The process's owner calls it (``launch.main``); threads already running
        (the middleware's) keep their scheduling. Refused (no CAP_SYS_NICE or rtprio limit, or no
        such call on this system): a warning, and the thread keeps the normal scheduler.
        Returns the priority in effect (0: normal scheduler), also in the diagnostics."""
        prio = self.cfg["thread_priority"]
        if prio:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
                self._thread_priority = prio
            except (OSError, AttributeError) as exc:
                self.get_logger().warning(f"parameter thread_priority: SCHED_FIFO priority {prio} refused "
                                          f"({exc}); ticks run under the normal scheduler")
        return self._thread_priority

    def _refreeze_heap(self):
        if self._heap_frozen:
            gc.unfreeze()
            self.freeze_heap()

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
        self.contacts = contact_sim.Contacts.empty()
        self._reset_tracking()

    def _reset_tracking(self):
        n = len(self.tracked)
        self._last_rx = np.full(n, -np.inf)         # node-clock seconds of the last accepted pose
        self._held_pos = np.zeros((n, 3))
        self._held_quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        self._posed = np.zeros(n, bool)             # driven by poses (and held after pose_timeout)
        self._reset_pose_times()
        self.world.contacts = contact_sim.Contacts.empty()

    def _reset_pose_times(self):
        """Forget the pose stamps: the next pose is a first pose (stamps start again)."""
        self._t0_ns = None
        self._last_pose_stamp_ns = None
        self._pending = None                        # latest zero-stamp pose not yet applied (p, q)
        self.world.restart_pose_history(self.tracked)
        self._last_rx[:] = np.where(self._posed, self._now_ns() * 1e-9, -np.inf)
        if hasattr(self, "_robot"):      # (not yet during set-up)
            self._reset_joint_times()

    # ------------------------------------------------------------------ helpers
    def _now_ns(self):
        """The node's time: the world time under publish_clock, else the node clock (sim time with
        use_sim_time)."""
        if self.cfg["publish_clock"]:
            return int(round(self.world.time * 1e9))
        return self.get_clock().now().nanoseconds

    def _warn(self, key, text, period=1.0):
        """A warning at most once per ``period`` per ``key``; says how many were suppressed. Every text
        is kept for /diagnostics (``_last_reason``, ``_reasons``), throttled or not."""
        self._last_reason[key] = text
        window = self._reasons.setdefault(key, {})
        window[text] = window.get(text, 0) + 1
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

    def _on_time_jump(self, jump):
        """The node clock went backwards (sim time restarted, a bag looped) or switched source: the
        pose stamp history no longer applies. Called by rclpy; must not raise."""
        try:
            back = jump.delta.nanoseconds < 0
            if not back and jump.clock_change not in (ClockChange.ROS_TIME_ACTIVATED, ClockChange.ROS_TIME_DEACTIVATED):
                return
            if back:
                self.counts["clock_jumps_back"] += 1
            self._reset_pose_times()
            self.get_logger().warning(f"clock {'jumped back by ' if back else 'changed source, '}"
                                      f"{-jump.delta.nanoseconds * 1e-9:.9g} s: pose stamp history reset (the next "
                                      f"pose places the tracked bodies without a velocity from the gap)")
        except Exception as exc:
            self._warn("jump", f"handling a clock jump failed: {type(exc).__name__}: {exc}")

    # ------------------------------------------------------------------ input
    def _on_poses(self, data, info):
        """Raw-subscription callback; also drains whatever else is queued, so a burst of poses costs
        one executor round trip instead of one per message (rclpy takes one message per wait)."""
        self._handle_pose(data, info)
        sub = self.sub_poses
        try:
            for _ in range(10000):
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                self._handle_pose(*taken)
        except Exception as exc:  # internal rclpy API changed or handle gone: one message per callback
            self._warn("drain", f"cannot drain body_poses ({type(exc).__name__}: {exc}); taking one per callback")

    def _create_pose_subscription(self):
        """The ``body_poses`` subscription. The publishers' count, for drop counting, comes from the
        middleware's matched events (asking for it every tick, ``count_publishers``, cost ~15 us of a
        1 kHz tick); a middleware without them gets the count asked for every tick instead."""
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST)
        self._poll_publishers = False
        try:
            return self.create_subscription(
                PoseArray, "body_poses", self._on_poses, qos, raw=True, qos_overriding_options=qos_overrides(),
                event_callbacks=SubscriptionEventCallbacks(matched=self._on_pose_publishers_matched))
        except UnsupportedEventTypeError:
            self._poll_publishers = True
            return self.create_subscription(PoseArray, "body_poses", self._on_poses, qos, raw=True,
                                            qos_overriding_options=qos_overrides())

    def _on_pose_publishers_matched(self, info):
        """A publisher of body_poses came or went (``QoSSubscriptionMatchedInfo``)."""
        self._pose_publishers = info.current_count

    def _count_drops(self, info):
        """Poses lost before they reached us (queue overflow, best effort): gaps in the publisher's
        sequence numbers. Counted only with one publisher (rclpy gives no publisher id, and the
        sequences of two would interleave); a restarted publisher starts a new sequence."""
        seq = info.get("publication_sequence_number") if isinstance(info, dict) else None
        if not seq or self._pose_publishers != 1:
            self._last_seq = None
            return
        if self._last_seq is not None and seq > self._last_seq + 1:
            self.counts["poses_dropped"] += seq - self._last_seq - 1
        self._last_seq = seq

    def _handle_pose(self, data, info=None):
        self.counts["poses_received"] += 1
        self._count_drops(info)
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
        zero = stamp_ns == 0
        if zero:      # "time of receipt"
            stamp_ns = now_ns
        if self._last_pose_stamp_ns is not None and stamp_ns <= self._last_pose_stamp_ns:
            if zero:  # several in one clock tick (sim time): the latest counts, applied when the clock moves
                if self._pending is not None:
                    self.counts["poses_superseded"] += 1
                self._pending = (p, q)
                return
            return self._reject_pose("stamp", f"stamp {stamp_ns * 1e-9:.9f} s is not after the previous pose's "
                                              f"{self._last_pose_stamp_ns * 1e-9:.9f} s")
        if self._pending is not None:
            self.counts["poses_superseded"] += 1
            self._pending = None
        self._apply_pose(p, q, stamp_ns, now_ns)

    def _apply_pose(self, p, q, stamp_ns, now_ns):
        if self._t0_ns is None:
            self._t0_ns = stamp_ns
        t = (stamp_ns - self._t0_ns) * 1e-9
        try:  # checked as a whole by the engine: a refused batch changes nothing
            # recorded; each tick drives the bodies there (_drive_poses), paused they are placed at once
            self.world.set_poses(self.tracked, p, q, t, place=self.paused)
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
        markers_off = self.cfg["publish_markers"] and not cfg["publish_markers"]
        self.cfg = cfg
        if new_world is None and "tracked_bodies" in changed:
            self.tracked, self.tracked_idx = tracked, idx
            self._reset_tracking()
        if new_world is not None:
            self._install_world(*new_world)
            self._reinstall_robot()
            self._publish_names()
            self._refreeze_heap()
            self.get_logger().info(f"loaded scene {self.scene_path}; tracking {', '.join(self.tracked) or 'nothing'}")
        apply_model(self.world, self.scene_settings, cfg)
        if markers_off:     # RViz keeps the last markers until told otherwise
            self._delete_markers()
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ services
    def _on_reset(self, request, response):
        self.world.reset()
        self._reset_tracking()
        self.contacts = contact_sim.Contacts.empty()
        self.counts["resets"] += 1
        now_ns = self._now_ns()
        self._publish_clock(now_ns)
        self._publish_states(now_ns)
        response.success = True
        response.message = (f"reset to the initial state of {self.scene_path} (spawned bodies to where they were "
                            f"spawned)")
        return response

    def _on_pause(self, request, response):
        self.paused = bool(request.data)
        self._drive_from = None   # paused or resumed, the world's time left the clock's: the robot's next drive places it
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def _on_step(self, request, response):
        if not self.paused:
            response.success = False
            response.message = "not paused: the world steps on its timer; call ~/pause with data=true first"
            return response
        ok = self._tick_work(time.perf_counter(), time.thread_time())
        response.success = ok
        response.message = (f"stepped to t = {self.world.time:.6f} s" if ok
                            else f"step failed, state kept: {self._last_step_error}")
        return response

    # ------------------------------------------------------------------ the tick
    def _on_timer(self):
        start, cpu_start = time.perf_counter(), time.thread_time()
        if self._last_tick_start is not None:
            behind = int((start - self._last_tick_start) / self.period + 0.5) - 1
            if behind > 0:  # ticks the timer could not honour: counted, never caught up
                self.counts["skipped_ticks"] += behind
        self._last_tick_start = start
        if self._poll_publishers:
            self._pose_publishers = self.count_publishers(self.sub_poses.topic_name)
        if self.paused:
            now_ns = self._now_ns()
            self._publish_clock(now_ns)
            self._publish_states(now_ns)
            self._maybe_diagnostics(now_ns)
            return
        self._tick_work(start, cpu_start)

    def _hold_timed_out(self, now_s):
        """Tracked bodies without a pose for pose_timeout: back to the last pose, velocity decays."""
        if not len(self.tracked):
            return
        stale = np.flatnonzero(self._posed & (now_s - self._last_rx > self.cfg["pose_timeout"]))
        if not stale.size:
            return
        tau = self.cfg["velocity_decay"]
        f = math.exp(-self.period / tau) if tau > 0 else 0.0
        s = self.world.s
        i = self.tracked_idx[stale]
        v, w = s.vel[i] * f, s.omega[i] * f
        small = (np.abs(v).max(axis=1) < 1e-9) & (np.abs(w).max(axis=1) < 1e-9)
        v[small], w[small] = 0.0, 0.0
        self.world.set_states([self.tracked[j] for j in stale], positions=self._held_pos[stale],
                              orientations=self._held_quat[stale], velocities=v, angular_velocities=w)

    def _drive_poses(self, now_ns):
        """Before a tick's steps: the tracked bodies with a live pose (not held after
        ``pose_timeout``) get the velocities that carry them, over the tick's period, from where
        they are to their latest pose carried on at its stamp velocity to the tick's end
        (``World.drive_poses``: never further than its last stamps' interval and a period past its
        stamp). A tick the timer could not honour, or poses bunched into one tick, move them as
        far as the clock moved, never by a jump (a jump slips a part held between pose-driven
        pads: its contacts follow the pads' velocities, not their jumps). Paused (``~/step``'s time
        is not the clock's) they are placed there at rest; a drive faster than the world's bounds
        places them there at rest too, counted (``pose_jumps``)."""
        if not self._posed.any() or self._t0_ns is None:
            return
        names = [n for n, on in zip(self.tracked, self._posed) if on]
        until = (now_ns - self._t0_ns) * 1e-9 + self.period
        try:
            self.world.drive_poses(names, until, self.period, at_rest=self.paused)
            return
        except contact_sim.ContactSimError as exc:   # faster than the world's bounds (settings.max_*)
            self.counts["pose_jumps"] += 1
            why = exc
        try:
            self.world.drive_poses(names, until, self.period, at_rest=True)
        except contact_sim.ContactSimError as again:   # the goal itself beyond them: the bodies stop
            reason, n = str(again), len(names)   # where they are (their pose history restarts: the next
            try:                                 # pose places them)
                self.world.set_states(names, velocities=np.zeros((n, 3)), angular_velocities=np.zeros((n, 3)))
            except contact_sim.ContactSimError as exc:   # (tracked bodies are kinematic: not expected)
                reason += f"; stopping them failed too: {exc}"
            self._warn("pose_jump", f"the tracked bodies cannot move to the latest pose ({reason}); they stop "
                                    f"where they are")
            return
        self._warn("pose_jump", f"the tracked bodies cannot move to the latest pose in one tick ({why}); they are "
                                f"placed there at rest")

    def _tick_work(self, start, cpu_start):
        """One fixed step (substeps engine steps) and the publications. False if the engine failed."""
        world = self.world
        now_ns = self._now_ns()
        if self._pending is not None and now_ns > self._last_pose_stamp_ns:
            p, q = self._pending
            self._pending = None
            self._apply_pose(p, q, now_ns, now_ns)
        self._hold_timed_out(now_ns * 1e-9)
        self._drive_poses(now_ns)
        self._hold_robot(now_ns * 1e-9)
        goal = self._drive_robot(now_ns)
        substeps = self.cfg["substeps"]
        saved = world.snapshot()   # every sub-step or none: a failure puts the world back as it was
        dt = self.period / substeps
        parts = []
        t0 = time.perf_counter()
        try:
            for _ in range(substeps):
                world.step(dt)
                parts.append(world.contacts)
                if world.last_solve.unconverged:   # a solve stopped unconverged: limit or stall (diagnostics)
                    self.counts["unconverged_steps"] += 1
        except Exception as exc:  # an engine failure (ContactSimError from its guard, or a bug) must not take the node down
            world.restore(saved)   # the bodies, time, contact cache (warm starts) and joint records
            world.contacts = self.contacts
            self.counts["step_errors"] += 1
            self._last_step_error = f"{type(exc).__name__}: {exc}"
            self._warn("step", f"world.step failed, the world keeps its last good state: {self._last_step_error}")
            self._maybe_diagnostics(now_ns)
            return False
        self.step_time = time.perf_counter() - t0
        self._drove(goal)
        contacts = parts[0] if len(parts) == 1 else contact_sim.Contacts.concat(parts)
        self.contacts = contacts
        self.counts["ticks"] += 1
        stamp_ns = self._now_ns()   # one stamp for the whole tick: the world's time after the step
        self._publish_tick(contacts, stamp_ns, self.period)
        # the CPU clock read inside the wall clock's interval at both ends (it starts after ``start``,
        # and is read first here), so a tick's CPU time never counts time its wall time does not
        cpu = time.thread_time() - cpu_start
        elapsed = time.perf_counter() - start
        slot = self._ticks_timed % len(self._tick_buf)
        self._tick_buf[slot], self._tick_cpu_buf[slot] = elapsed, cpu
        self._ticks_timed += 1
        self._last_tick_time = elapsed
        if elapsed > self.period:
            self.counts["overruns"] += 1
            off_cpu = cpu <= self.period   # the work fitted: the overrun is time the thread did not run
            self.counts["overruns_off_cpu"] += off_cpu
            # where the time went, for whoever watches the log (as ros2_control warns of its overruns)
            self._warn("overrun", f"tick overran its {self.period * 1e3:.3g} ms period: {elapsed * 1e3:.3g} ms, "
                                  f"{cpu * 1e3:.3g} ms of it on the tick thread's CPU (engine step "
                                  f"{self.step_time * 1e3:.3g} ms)"
                                  + ("; the rest descheduled or blocked" if off_cpu else ""))
        self._maybe_diagnostics(stamp_ns)
        return True

    def body_poses(self):
        """Body-frame origins (N, 3) and orientations (N, 4) of all bodies, vectorised."""
        return self.world.poses()
