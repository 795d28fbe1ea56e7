"""Driving bodies from outside: kinematic poses (velocities from successive stamped poses) and
state overwrites, each checked in full before anything changes (``World`` inherits these)."""
import numpy as np

from . import free_motion, quat
from .errors import BoundsError, ContactSimError
from .kinds import KINDS, KINEMATIC, STATIC
from .validate import (ANGULAR_VELOCITIES, ANGULAR_VELOCITY, ORIENTATION, POSITION, POSITIONS, STAMP, VELOCITIES,
                       VELOCITY, show)

def _length(value):
    """``len(value)`` of a list, tuple or array with at least one dimension, else None."""
    if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim > 0):
        return len(value)
    return None


def _rows(check, value, m, path, row_path, settings, row_rule):
    """``check`` an ``(m, n)`` batch; when it is refused and the batch has ``m`` rows, name the
    first bad row by checking the rows one by one with ``row_rule``."""
    try:
        return check(value, path, settings, count=m, row_path=row_path)
    except ContactSimError:
        if _length(value) == m:
            for i in range(m):
                row_rule.check(value[i], row_path(i), settings)
        raise


class BodyInput:
    """``set_pose(s)``, ``drive_poses``, ``restart_pose_history``, ``set_state(s)`` of ``World``."""

    def set_pose(self, name, position, orientation, stamp=None, place=True):
        """Pose a kinematic body (``position (3,)`` origin, ``orientation (4,)`` x,y,z,w) at time
        ``stamp`` (s; default the world time). From the second pose on its linear and angular
        velocity are the finite differences of successive poses over their stamps, so responses
        see how fast it really moves. The body is placed at once, and the next step carries it on
        at that velocity: a trajectory ``p(t)`` is followed by giving ``p(t)`` stamped ``t`` (the
        world's time) before each step. Stamps must increase. Bad input changes nothing; a position
        beyond ``settings.max_position`` or a pose implying a speed beyond ``max_speed`` /
        ``max_angular_speed`` raises ``BoundsError``.

        With ``place=False`` the pose and its velocity are only recorded (the body goes on as it
        was, except at a first pose, which places it: there is nothing to drive it from), for
        ``drive_poses`` to move the body there without a jump."""
        self._set_poses([name], [position], [orientation], stamp, single=True, place=place)

    def set_poses(self, names, positions, orientations, stamp=None, place=True):
        """``set_pose`` for several kinematic bodies at one ``stamp``, vectorised: ``names (M,)``,
        ``positions (M, 3)``, ``orientations (M, 4)``. The whole batch is checked before anything
        changes, so a bad row leaves every body as it was; errors name the body and the reason.
        An empty batch changes nothing."""
        self._set_poses(names, positions, orientations, stamp, single=False, place=place)

    def _set_poses(self, names, positions, orientations, stamp, single, place=True):
        st = self.settings
        call = "set_pose" if single else "set_poses"
        if isinstance(names, (str, bytes)) or not hasattr(names, "__iter__"):
            raise ContactSimError(f"set_poses.names: must be a list of body names, got {show(names)}")
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
        lengths = [_length(positions), _length(orientations)]
        if None not in lengths and lengths != [m, m]:
            raise ContactSimError(f"set_poses: {m} names but {lengths[0]} positions and {lengths[1]} orientations")
        pos = _rows(POSITIONS.check, positions, m, f"{call}.positions", lambda i: f"{where(i)}.position", st,
                    POSITION)
        q = _rows(ORIENTATION.check_rows, orientations, m, f"{call}.orientations",
                  lambda i: f"{where(i)}.orientation", st, ORIENTATION)
        t = self.time if stamp is None else STAMP.check(stamp, f"{where(0) if single else 'set_poses'}.stamp")
        s = self.s
        posed = s.posed[idx]
        bad = np.flatnonzero(posed & (t - s.stamp[idx] <= 0))
        if bad.size:
            i = bad[0]
            raise ContactSimError(f"{where(i)}.stamp: must be after the previous pose ({s.stamp[idx[i]]!r}), got {t!r}")
        com_world = pos + quat.rotate(q, self.com_local[idx])
        j, ij = np.flatnonzero(posed), idx[posed]
        if j.size:
            # velocities: finite differences from the previous *pose* (between poses the body moved on
            # at its velocity; a difference from there would halve the velocity of a steadily driven
            # body every other pose), over the stamps, within the world's speed bounds
            dt = (t - s.stamp[ij])[:, None]
            q_prev = s.pose_quat[ij]
            qj = np.where(np.sum(q[j] * q_prev, axis=1, keepdims=True) < 0, -q[j], q[j])  # shorter way round
            q[j] = qj
            turn = quat.to_rotvec(quat.mul(qj, quat.conj(q_prev)))
            move = com_world[j] - s.pose_pos[ij]
            for d, bound, unit in ((move, "max_speed", "m/s"), (turn, "max_angular_speed", "rad/s")):
                # compared before dividing: stamps a hair apart would overflow the quotient
                over = np.linalg.norm(d, axis=1) > getattr(st, bound) * dt[:, 0]
                if over.any():
                    k = int(np.argmax(over))
                    speed = float(np.linalg.norm(d[k])) / float(dt[k, 0])
                    raise BoundsError(f"{where(j[k])}: moving since the previous pose {float(dt[k, 0]):.6g} s ago "
                                      f"implies {speed:.6g} {unit}, above {bound} ({getattr(st, bound):g} {unit})")
            omega = turn / dt
            vel = move / dt
        # ---- commit (nothing below can fail)
        placed = slice(None) if place else ~posed   # a first pose is always placed
        if j.size:
            if place:
                s.omega[ij] = omega
                s.vel[ij] = vel
            s.pose_vel[ij], s.pose_omega[ij], s.pose_gap[ij] = vel, omega, dt[:, 0]
        first = idx[~posed]
        s.pose_vel[first], s.pose_omega[first], s.pose_gap[first] = 0.0, 0.0, 0.0
        s.pos[idx[placed]] = com_world[placed]
        s.quat[idx[placed]] = q[placed]
        s.pose_pos[idx] = com_world
        s.pose_quat[idx] = q
        s.stamp[idx] = t
        s.posed[idx] = True

    def drive_poses(self, names, until, period, at_rest=False):
        """Drive the named kinematic bodies over the next ``period`` (s) to their last pose carried
        on at its velocity (``set_poses``' finite differences) to time ``until`` (s, the poses'
        stamps' clock), never back and at most its last two poses' interval plus ``period`` past its
        stamp: each body keeps its place and gets the linear and angular velocity that take its
        centre of mass and orientation there in ``period``, so the steps over ``period`` carry it
        there smoothly. A caller that steps late or receives poses in bunches (the ROS node) moves
        the bodies as far as its clock moved, never by a jump, which contacts (velocity-level)
        would not see: a part held between two pose-driven pads would be left behind by it.
        ``at_rest``: place the bodies there at rest instead (paused, or a drive beyond the bounds).

        A body with no pose given (or whose pose history was restarted) is left as it is; the pose
        record is kept (the next pose differences from the last). ``BoundsError`` (nothing
        changed) when the goal is beyond ``settings.max_position`` or the drive beyond
        ``max_speed`` / ``max_angular_speed``."""
        names = [names] if isinstance(names, str) else list(names)
        idx = np.array([self.index(n) for n in names], np.int64)
        bad = np.flatnonzero(self.kind[idx] != KINEMATIC)
        if bad.size:
            i = bad[0]
            raise ContactSimError(f"drive_poses({names[i]!r}): only kinematic bodies are driven by poses; "
                                  f"{names[i]!r} is {KINDS[self.kind[idx[i]]]}")
        until = STAMP.check(until, "drive_poses.until")
        period = float(STAMP.check(period, "drive_poses.period"))
        if not period > 0.0:
            raise ContactSimError(f"drive_poses.period: must be > 0 s, got {period!r}")
        s, st = self.s, self.settings
        on = np.flatnonzero(s.posed[idx])
        i = idx[on]
        if not i.size:
            return
        out = np.empty((i.size, 13))
        code, row = free_motion.pose_drive(i, float(until), period, bool(at_rest), s.pose_pos, s.pose_quat, s.pose_vel,
                                           s.pose_omega, s.stamp, s.pose_gap, s.pos, s.quat, float(st.max_position),
                                           float(st.max_speed), float(st.max_angular_speed), out)
        if code != free_motion.DRIVE_OK:
            name = names[on[row]]
            if code == free_motion.DRIVE_POSITION:
                raise BoundsError(f"drive_poses({name!r}): its pose carried on to {until:.9g} s is beyond max_position "
                                  f"({st.max_position:g} m)")
            bound, unit = ("max_speed", "m/s") if code == free_motion.DRIVE_SPEED else ("max_angular_speed", "rad/s")
            part = slice(7, 10) if code == free_motion.DRIVE_SPEED else slice(10, 13)
            speed = float(np.linalg.norm(out[row, part]))
            raise BoundsError(f"drive_poses({name!r}): reaching its pose carried on to {until:.9g} s in {period:.6g} s "
                              f"takes {speed:.6g} {unit}, above {bound} ({getattr(st, bound):g} {unit})")
        if at_rest:
            s.pos[i], s.quat[i] = out[:, 0:3], out[:, 3:7]
        s.vel[i], s.omega[i] = out[:, 7:10], out[:, 10:13]

    def restart_pose_history(self, names=None):
        """The next pose of each named kinematic body (every body when ``names`` is None) is taken
        as a first pose: it places the body and keeps its velocity, no finite difference across the
        gap (after a clock jump, or when a body was driven another way meanwhile)."""
        idx = np.arange(len(self)) if names is None else np.array([self.index(n) for n in names], np.int64)
        self.s.posed[idx] = False

    def set_state(self, name, position=None, orientation=None, velocity=None, angular_velocity=None):
        """Overwrite any part of a non-static body's state (teleport, set a velocity). Checked first,
        world bounds included; ``None`` keeps that part."""
        as_rows = [None if v is None else [v] for v in (position, orientation, velocity, angular_velocity)]
        self._set_states([name], *as_rows, label="set_state")

    def set_states(self, names, positions=None, orientations=None, velocities=None, angular_velocities=None):
        """``set_state`` for several non-static bodies at once, all or nothing: ``names (M,)`` and,
        each optional (None leaves that part unchanged), ``positions (M, 3)`` body-frame origins,
        ``orientations (M, 4)`` x,y,z,w, ``velocities (M, 3)`` of the centres of mass and
        ``angular_velocities (M, 3)``, world frame. A kinematic body given a velocity moves at it
        until the next pose or state; errors name the body and the reason."""
        self._set_states(names, positions, orientations, velocities, angular_velocities, label="set_states")

    def _set_states(self, names, positions, orientations, velocities, angular_velocities, label):
        names = [names] if isinstance(names, str) else list(names)
        m = len(names)
        idx = np.array([self.index(n) for n in names], np.int64)
        if len(set(idx.tolist())) != m:
            raise ContactSimError(f"{label}: a body is named twice in {names!r}")
        for i in np.flatnonzero(self.kind[idx] == STATIC):
            raise ContactSimError(f"{label}({names[i]!r}): {names[i]!r} is static and never moves")
        st = self.settings
        parts = {}
        for key, value, batch, rule in (
                ("position", positions, POSITIONS.check, POSITION),
                ("orientation", orientations, ORIENTATION.check_rows, ORIENTATION),
                ("velocity", velocities, VELOCITIES.check, VELOCITY),
                ("angular_velocity", angular_velocities, ANGULAR_VELOCITIES.check, ANGULAR_VELOCITY)):
            if value is None:
                continue
            n = _length(value)
            if n is None:
                raise ContactSimError(f"{label}.{key}: must be one row per body, got {value!r}")
            if n != m:
                raise ContactSimError(f"{label}.{key}: {n} rows for {m} bodies")
            # the batch at once; refused, the first bad row is named as one row at a time names it
            parts[key] = _rows(batch, value, m, f"{label}.{key}", lambda i, key=key: f"{label}({names[i]!r}).{key}",
                               st, rule).reshape(m, -1)
        om = parts.get("angular_velocity")
        if om is not None:
            for i in np.flatnonzero(self.particle[idx] & om.any(axis=1)):
                raise ContactSimError(f"{label}({names[i]!r}).angular_velocity: a particle does not rotate")
        # ---- commit (nothing below can fail)
        s = self.s
        com = self.com_local[idx]
        offset = com.any()   # a centre of mass off the body's origin (else the origin is the centre)
        origin = parts.get("position")
        if origin is None:
            origin = s.pos[idx] - quat.rotate(s.quat[idx], com) if offset else s.pos[idx]
        if "orientation" in parts:
            s.quat[idx] = parts["orientation"]
        s.pos[idx] = origin + quat.rotate(s.quat[idx], com) if offset else origin
        if "velocity" in parts:
            s.vel[idx] = parts["velocity"]
        if om is not None:
            s.omega[idx] = om
        s.posed[idx] = False   # a kinematic body set from outside: its pose history starts again
