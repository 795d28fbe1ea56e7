"""What the node publishes: contacts, body states, body names, markers, /clock and /diagnostics.

A mixin of ``ContactSimNode`` (it reads the node's world, configuration and counters). Every output
of one tick carries one stamp: the world's time after the step, on the node's clock (see
``ContactSimNode._tick_work``). The per-tick topics are written as CDR bytes or through one numpy
structured array, never as a Python object per body or contact.
"""
import collections
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import MultiDOFJointState, PointCloud2
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

import contact_sim

from .cdr_out import marker_array_cdr, point_fields_cdr, pointcloud2_cdr
from .robot_input import JOINT_STATE_REASONS, robot_exclusions
from .conversions import (CONTACT_DTYPE, contact_marker_specs, contacts_to_array, diagnostic_array, make_header,
                          multidof_rows_cdr, names_cdr, ns_to_stamp, point_fields, posearray_rows_cdr)
from .state_rows import blocks, state_rows

POSE_REJECT_REASONS = ("malformed", "length", "nonfinite", "zero_quaternion", "non_unit_quaternion", "stamp",
                       "frame_id", "out_of_bounds", "engine")
MAX_REASONS = 20   # distinct refusal texts per category in one /diagnostics report (the rest counted)
#: counters whose growth since the last /diagnostics message makes it a WARN
WARN_COUNTERS = ("rejected_poses", "rejected_parameters", "overruns", "poses_dropped", "rejected_body_states",
                 "rejected_spawns", "rejected_deletes", "clock_jumps_back", "rejected_robot_descriptions",
                 "rejected_joint_states", "joint_states_unknown_joints", "unconverged_steps", "robot_jumps",
                 "pose_jumps")


_CONTACT_FIELDS_CDR = point_fields_cdr(point_fields(CONTACT_DTYPE))   # the contacts' layout, once


def diag_name(node_name):
    """The status name, as diagnostic_updater names a task: ``<node name>: world``."""
    return f"{node_name}: world"


class Outputs:
    """Publishers and the per-tick publication of ``ContactSimNode``."""

    def _create_publishers(self):
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_contacts = self.create_publisher(PointCloud2, "contacts", reliable)
        self.pub_states = self.create_publisher(PoseArray, "body_states", reliable)
        self.pub_multidof = self.create_publisher(MultiDOFJointState, "body_multidof_states", reliable)
        self.pub_names = self.create_publisher(String, "body_names", latched)
        self.pub_markers = self.create_publisher(MarkerArray, "contact_markers", reliable)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", reliable)
        # reliable matches reliable and best-effort /clock subscribers (rclpy's time source is best effort)
        self.pub_clock = (self.create_publisher(Clock, "/clock", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
                          if self.cfg["publish_clock"] else None)
        self._names_blob = (None, b"")
        self._last_diag = None
        self._diag_snapshot = collections.Counter()

    # ------------------------------------------------------------------ per tick
    def _publish_tick(self, contacts, stamp_ns, duration):
        """Everything a tick publishes, all stamped ``stamp_ns``; ``duration`` (s) is the time the
        contacts' impulses acted over (for the wrenches)."""
        frame = self.cfg["frame_id"]
        self._publish_clock(stamp_ns)
        # as CDR bytes (cdr_out): rclpy's conversion of the message objects cost more than the step
        self.pub_contacts.publish(pointcloud2_cdr(contacts_to_array(contacts), _CONTACT_FIELDS_CDR, frame, stamp_ns))
        self._publish_states(stamp_ns, contacts, duration)
        if self.cfg["publish_markers"]:
            specs = contact_marker_specs(contacts, self.cfg["impulse_marker_scale"], self.cfg["max_marker_arrows"])
            self.pub_markers.publish(marker_array_cdr(specs, frame, stamp_ns))

    def _publish_states(self, stamp_ns, contacts=None, duration=None):
        """``body_states`` (PoseArray, for RViz) and ``body_multidof_states`` (names, poses, twists of
        the body origins and the contact wrenches; zero wrenches when no step was taken), from one
        compiled pass over the bodies and contacts (``state_rows``)."""
        rows = state_rows(self.world, contacts, duration if contacts is not None else 1.0)
        poses, twists, wrenches = blocks(rows, len(self.world))
        frame = self.cfg["frame_id"]
        self.pub_states.publish(posearray_rows_cdr(poses, frame, stamp_ns))
        self.pub_multidof.publish(multidof_rows_cdr(self._names_cdr(), poses, twists, wrenches, frame, stamp_ns))

    def _names_cdr(self):
        names = tuple(self.world.body_names)
        if self._names_blob[0] != names:
            self._names_blob = (names, names_cdr(names))
        return self._names_blob[1]

    def _publish_names(self):
        self.pub_names.publish(String(data="\n".join(self.world.body_names)))

    def _publish_clock(self, stamp_ns):
        if self.pub_clock is not None:
            self.pub_clock.publish(Clock(clock=ns_to_stamp(stamp_ns)))

    def _delete_markers(self):
        """One DELETEALL, so RViz drops the markers (publish_markers turned off, or shutting down)."""
        header = make_header(self.cfg["frame_id"], self._now_ns())
        self.pub_markers.publish(MarkerArray(markers=[Marker(header=header, ns="contacts", action=Marker.DELETEALL)]))

    def close_outputs(self, timeout=0.3):
        """Before the node goes away (context still valid): clear the markers and give reliable
        subscribers up to ``timeout`` s to receive that."""
        self._delete_markers()
        if self.pub_markers.get_subscription_count():
            self.pub_markers.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))

    # ------------------------------------------------------------------ diagnostics
    def diagnostics_values(self):
        """The key/values of the node's /diagnostics status (a dict, in order)."""
        c = self.counts
        n = min(self._ticks_timed, len(self._tick_buf))
        times = self._tick_buf[:n] * 1e3 if n else np.zeros(1)
        cpu = self._tick_cpu_buf[:n] * 1e3 if n else np.zeros(1)
        p50, p99 = np.percentile(times, [50, 99])
        last = self._last_tick_time * 1e3 if n else 0.0
        contacts = getattr(self, "contacts", None)
        contacts = contact_sim.Contacts.empty() if contacts is None else contacts
        solve = self.world.last_solve   # a contact_sim.StepStats
        residual, iterations = solve.residual, solve.iterations
        try:
            residual = float(residual)
        except (TypeError, ValueError):
            residual = float("nan")
        values = {
            "scene": self.scene_path,
            "sim_time_s": float(self.world.time),
            "paused": self.paused,
            "bodies": len(self.world),
            "ticks": c["ticks"],
            "step_time_ms": self.step_time * 1e3,
            "tick_time_ms_last": float(last),
            "tick_time_ms_p50": float(p50),
            "tick_time_ms_p99": float(p99),
            "tick_time_ms_max": float(times.max()),
            "tick_cpu_ms_p99": float(np.percentile(cpu, 99)),
            "tick_cpu_ms_max": float(cpu.max()),
            "tick_overruns": c["overruns"],
            "tick_overruns_off_cpu": c["overruns_off_cpu"],
            "skipped_ticks": c["skipped_ticks"],
            "thread_priority": self._thread_priority,
            "contacts": len(contacts),
            "max_penetration_m": float(contacts.depth.max()) if len(contacts) else 0.0,
            "energy_J": float(self.world.energy()),
            "solver_residual": residual,
            "solver_iterations": iterations if isinstance(iterations, int) else -1,
            "unconverged_steps": c["unconverged_steps"],
            "poses_received": c["poses_received"],
            "poses_accepted": c["poses_accepted"],
            "poses_superseded": c["poses_superseded"],
            "poses_dropped": c["poses_dropped"],
            "pose_publishers": self._pose_publishers,
            "rejected_poses": c["rejected_poses"],
        }
        for r in POSE_REJECT_REASONS:
            values["rejected_pose_" + r] = c["rejected_pose_" + r]
        for key in ("rejected_parameters", "step_errors", "resets", "clock_jumps_back", "body_states_set",
                    "rejected_body_states", "spawned_bodies", "rejected_spawns", "deleted_bodies", "rejected_deletes",
                    "robot_descriptions", "robot_semantic_descriptions", "rejected_robot_descriptions", "joint_states_received", "joint_states_accepted",
                    "rejected_joint_states", "joint_states_unknown_joints", "unconverged_steps", "robot_jumps",
                    "pose_jumps"):
            values[key] = c[key]
        for r in JOINT_STATE_REASONS:
            values["rejected_joint_state_" + r] = c["rejected_joint_state_" + r]
        values["last_step_error"] = self._last_step_error
        robot = self._robot
        if robot is not None and robot in self.world.robots:
            values["robot_exclusions"] = robot_exclusions(robot)
        for key in sorted(self._last_reason):
            values["last_reason." + key] = self._last_reason[key]
        for key in sorted(self._reasons):   # every reason since the last report, each with its count
            texts = sorted(self._reasons[key].items(), key=lambda kv: -kv[1])
            shown = " | ".join(f"{n}× {t}" for t, n in texts[:MAX_REASONS])
            values["reasons." + key] = shown + (f" | and {len(texts) - MAX_REASONS} more distinct" if len(texts) >
                                                 MAX_REASONS else "")
        return values

    def _maybe_diagnostics(self, now_ns):
        """Publish /diagnostics when ``diagnostics_period`` has passed on the node's clock, or when
        that clock went backwards (sim time restarted). Under publish_clock the period is on the
        steady clock: the world time stands still while paused, the reports should not."""
        now = time.monotonic() if self.cfg["publish_clock"] else now_ns * 1e-9
        if self._last_diag is not None and 0.0 <= now - self._last_diag < self.cfg["diagnostics_period"]:
            return
        self._last_diag = now
        values = self.diagnostics_values()
        self._reasons = {}   # reported: the next report says what came after
        new = {k: self.counts[k] - self._diag_snapshot[k] for k in ("step_errors",) + WARN_COUNTERS}
        self._diag_snapshot = collections.Counter(self.counts)
        if new["step_errors"]:
            level = DiagnosticStatus.ERROR
            msg = (f"{new['step_errors']} engine step failures, the world kept its last good state; last: "
                   f"{self._last_step_error}")
        elif any(new[k] for k in WARN_COUNTERS):
            level = DiagnosticStatus.WARN
            msg = "; ".join(f"{k.replace('_', ' ')}: {new[k]}" for k in WARN_COUNTERS if new[k])
        else:
            level, msg = DiagnosticStatus.OK, "paused" if self.paused else "running"
        # frame_id empty (a status is about no frame); told apart from other nodes by the node's name
        self.pub_diag.publish(diagnostic_array(make_header("", now_ns), diag_name(self.get_name()),
                                               self.get_fully_qualified_name(), values, level, msg))
