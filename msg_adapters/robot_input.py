"""A robot from ``robot_description``, moved by ``joint_states``: the inputs robot_state_publisher takes.

A mixin of ``ContactSimNode``:

- ``robot_description_topic`` (``std_msgs/String``, transient local, reliable; parameter, default
  ``robot_description``, empty disables): the URDF. When it arrives the robot's link bodies are
  added (``World.add_urdf``, bodies named by link with ``robot_prefix``); a new description replaces
  them, the other bodies keep their state. A description the engine refuses is counted and warned
  about, and the robot already there stays.
- ``joint_states_topic`` (``sensor_msgs/JointState``, best effort so reliable publishers match too;
  default ``joint_states``): positions of the robot's joints, applied with
  ``World.set_joint_positions`` at the message stamp (zero: time of receipt). Each joint keeps its
  own stamp, as robot_state_publisher does, so an arm driver and a gripper driver publishing at
  their own rates and times each move their own joints: a message is judged joint by joint, and
  only its joints stamped before their own previous one are left out (all of them:
  ``rejected_joint_state_out_of_order``). A joint's velocity is the finite difference of its own
  consecutive stamps. Joints the robot does not have are counted (``joint_states_unknown_joints``)
  and warned about, the known ones applied; mimic joints are accepted when they agree with the
  joints they follow (``..._invalid`` when not). A message older than ``pose_timeout`` on arrival
  (``..._stale``), malformed or refused by the engine (NaN, beyond the joint limits:
  ``..._invalid``) changes nothing and is counted and warned about, like a bad pose.
- ``robot_description_semantic_topic`` (``std_msgs/String``, transient local; default
  ``robot_description_semantic``, empty: not read): MoveIt's SRDF; its ``disable_collisions``
  pairs are never tested (the robot is rebuilt with them). An SRDF that does not fit the robot
  (an unknown link) is refused, counted and warned about.
- Each tick drives the links from the joint positions the last tick took them to, at the joint
  velocities that get them over the tick's period to the latest joint state carried on (at its
  joints' stamp velocities) to the tick's end (``_drive_robot``). Their displacement in the world
  is then what their velocities carry, whatever the timing: a tick the timer could not honour, or
  joint states bunched into one tick, moves the links as far as the clock moved, never by a jump.
  A jump slips a held part: its contacts follow the fingers' velocities, not their jumps
  (test_ros_grasp: a Panda's lifted cube ended 2.5 cm low in the hand with one tick in four late
  and one joint state in seven a tick late, when each joint state placed the links).
- After ``pose_timeout`` without joint states the links hold their last pose with zero velocity.
"""
import dataclasses

import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

import contact_sim

JOINT_STATE_REASONS = ("out_of_order", "stale", "invalid", "malformed", "no_robot")


def robot_exclusions(robot):
    """The pairs of ``robot`` never tested, by reason: ``"12 adjacent links; 2 touching at the initial
    configuration: floor–base, finger–upper"`` (the adjacent ones counted, the others named)."""
    why = {}
    for pair, reason in sorted(robot.exclusions.items()):
        why.setdefault(reason, []).append(pair)
    return "; ".join(f"{len(p)} {reason}" + ("" if reason == "adjacent links" else
                                             ": " + ", ".join(f"{a}–{b}" for a, b in p))
                     for reason, p in why.items()) or "none"


class RobotInput:
    """``robot_description`` and ``joint_states`` of ``ContactSimNode``."""

    def _create_robot_input(self, overrides):
        self._robot_urdf = None          # the last accepted description (re-added when the scene changes)
        self._robot = None               # its RobotModel in the world
        self._robot_srdf = None          # the last accepted semantic description
        self._js_t0_ns = None
        self._js_last_rx = -np.inf
        self._robot_held = True
        self._drive_from = None          # joint positions the links start the next tick from (None: the latest)
        self._drive_moving = False       # the links were given a velocity by the last drive
        self._js_since_drive = False     # a joint state was applied since the last drive
        self.sub_description = self.sub_joint_states = None
        topic = self.cfg["robot_description_topic"]
        if not topic:
            return
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.sub_description = self.create_subscription(String, topic, self._on_robot_description, latched,
                                                        qos_overriding_options=overrides())
        self.sub_semantic = None
        if self.cfg["robot_description_semantic_topic"]:
            self.sub_semantic = self.create_subscription(String, self.cfg["robot_description_semantic_topic"],
                                                         self._on_robot_semantic, latched,
                                                         qos_overriding_options=overrides())
        self.sub_joint_states = self.create_subscription(
            JointState, self.cfg["joint_states_topic"], self._on_joint_states,
            QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST),
            qos_overriding_options=overrides())

    # ------------------------------------------------------------------ the description
    def _on_robot_description(self, msg):
        try:
            self._install_robot(msg.data)
        except contact_sim.ContactSimError as exc:
            self.counts["rejected_robot_descriptions"] += 1
            self._warn("robot_description", f"{self.cfg['robot_description_topic']} refused: {exc}; "
                                            f"{'the robot is unchanged' if self._robot else 'no robot'}")
            return
        except Exception as exc:   # whatever a document can provoke: refused, never a crash
            self.counts["rejected_robot_descriptions"] += 1
            self._warn("robot_description", f"{self.cfg['robot_description_topic']} refused: "
                                            f"{type(exc).__name__}: {exc}")
            return
        self.counts["robot_descriptions"] += 1
        self._bodies_changed()
        self._log_robot()

    def _on_robot_semantic(self, msg):
        if self._robot_urdf is not None:     # the robot again, with these pairs (refused: unchanged)
            try:
                self._install_robot(self._robot_urdf, msg.data, strict=True)
            except Exception as exc:
                self.counts["rejected_robot_descriptions"] += 1
                self._warn("robot_description_semantic", f"{self.cfg['robot_description_semantic_topic']} refused: "
                                                         f"{exc}; the robot is unchanged")
                return
            self._bodies_changed()
            self._log_robot()
        self._robot_srdf = msg.data
        self.counts["robot_semantic_descriptions"] += 1

    def _log_robot(self):
        self.get_logger().info(f"robot {self._robot.name!r}: {len(self._robot.bodies)} link bodies "
                               f"({', '.join(self._robot.bodies)}); {len(self.world.disabled_pairs)} body pairs "
                               f"never tested: {robot_exclusions(self._robot)}")

    def _install_robot(self, urdf, srdf=None, strict=False, refreeze=True):
        """Replace the robot (if any) by the one ``urdf`` describes (with the SRDF's allowed
        collisions: ``srdf``, else the last accepted one); all or nothing. ``strict``: an SRDF that
        does not fit refuses the whole request. ``refreeze``: refreeze the heap after (a scene
        reload does it once for the scene and the robot)."""
        world = self.world
        srdf = self._robot_srdf if srdf is None else srdf
        prefix = self.cfg["robot_prefix"]
        # a description the engine refuses on its own is refused before the old robot goes; an SRDF
        # that does not fit a new robot is dropped (the robot comes without it), not the robot
        place = dict(base_pose=self.cfg["robot_base_pose"], package_paths=self.cfg["package_paths"] or None)

        def trial():   # the world's gravity and settings (a bound such as max_speed / max_step checks gravity)
            return contact_sim.World(world.gravity, settings=world.settings)

        try:
            trial().add_urdf(urdf, prefix=prefix, srdf=srdf, exclude_touching=False, **place)
        except contact_sim.ContactSimError as exc:
            if strict or srdf is None or ".srdf" not in str(exc):
                raise
            self._warn("robot_description_semantic", f"the SRDF does not fit this robot ({exc}); ignored")
            srdf = self._robot_srdf = None
            trial().add_urdf(urdf, prefix=prefix, exclude_touching=False, **place)
        # the contact cache too: what the stepper carries between steps (renumbered by the removal)
        saved = (world._save_bodies(), world.robots, world.disabled_pairs, world.contacts,
                 dataclasses.replace(world.contact_cache))
        try:
            if self._robot is not None and self._robot in world.robots:
                world.remove_bodies(self._robot.bodies)
            world.add_urdf(urdf, prefix=prefix, srdf=srdf, disable_collisions=self.cfg["robot_disable_collisions"],
                           exclude_touching=self.cfg["robot_exclude_touching"], **place)
        except BaseException:   # e.g. a link named like a scene body
            world._restore_bodies(saved[0])
            world.robots, world.disabled_pairs, world.contacts = saved[1:4]
            world.contact_cache = saved[4]
            world._derived = {}
            raise
        self._robot = world.robots[-1]
        self._robot_urdf = urdf
        self._js_t0_ns = None     # a new robot: its first joint state places it
        self._robot_held = True
        self._drive_from = None
        if refreeze:
            self._refreeze_heap()     # the new links' meshes out of the collector's reach, the old ones freed

    def _reinstall_robot(self):
        """After a new scene: the robot of the last description into the new world."""
        self._robot = None
        if self._robot_urdf is None:
            return
        try:
            self._install_robot(self._robot_urdf, refreeze=False)
        except Exception as exc:
            self.counts["rejected_robot_descriptions"] += 1
            self._warn("robot_description", f"robot_description does not fit the new scene: {exc}")

    # ------------------------------------------------------------------ joint states
    def _reject_joint_state(self, reason, text):
        self.counts["rejected_joint_states"] += 1
        self.counts["rejected_joint_state_" + reason] += 1
        self._warn("joint_state_" + reason, f"{self.cfg['joint_states_topic']} rejected ({reason}): {text}; "
                                            f"the robot keeps its last good pose")

    def _on_joint_states(self, msg):
        self.counts["joint_states_received"] += 1
        robot = self._robot
        if robot is None or robot not in self.world.robots:
            return self._reject_joint_state("no_robot", f"no robot yet (waiting for "
                                                        f"{self.cfg['robot_description_topic']})")
        names, pos = list(msg.name), np.asarray(msg.position, float)
        if len(names) != len(pos):
            return self._reject_joint_state("malformed", f"{len(names)} names but {len(pos)} positions")
        movable = {j["name"]: j for j in robot.joints if j["type"] in ("revolute", "continuous", "prismatic")}
        unknown = [n for n in names if n not in movable]
        if unknown:
            self.counts["joint_states_unknown_joints"] += len(unknown)
            self._warn("joint_state_unknown", f"{self.cfg['joint_states_topic']}: unknown joints "
                                              f"{', '.join(map(repr, unknown[:5]))}{' ...' if len(unknown) > 5 else ''}"
                                              f" ignored (robot {robot.name!r})")
        now_ns = self._now_ns()
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec or now_ns
        t = (stamp_ns - (stamp_ns if self._js_t0_ns is None else self._js_t0_ns)) * 1e-9
        # joint by joint: a joint stamped before its own last stamp is left out (another publisher's
        # newer message moved it), and a mimic joint whose leader is left out with it
        late = {n for n in names if n in movable and movable[n]["mimic"] is None
                and robot.t.get(n) is not None and t < robot.t[n]}
        keep = [i for i, n in enumerate(names) if n in movable and n not in late
                and (movable[n]["mimic"] is None or movable[n]["mimic"][0] not in late)]
        if late and not any(movable[names[i]]["mimic"] is None for i in keep):
            n = min(late)
            return self._reject_joint_state("out_of_order", f"stamp {stamp_ns * 1e-9:.9f} s is before joint {n!r}'s "
                                                            f"previous one ({robot.t[n] + self._js_t0_ns * 1e-9:.9f} s)")
        if (now_ns - stamp_ns) * 1e-9 > self.cfg["pose_timeout"]:
            return self._reject_joint_state("stale", f"stamp {stamp_ns * 1e-9:.9f} s is older than pose_timeout "
                                                     f"({self.cfg['pose_timeout']:g} s) at {now_ns * 1e-9:.9f} s")
        if not keep:
            return
        if self._js_t0_ns is None:
            self._js_t0_ns = stamp_ns
        try:
            # the links are posed by the tick's drive; paused, by each joint state (nothing steps)
            self.world.set_joint_positions([names[i] for i in keep], pos[keep], t, place=self.paused)
        except contact_sim.ContactSimError as exc:
            return self._reject_joint_state("invalid", str(exc))
        self._js_last_rx = now_ns * 1e-9
        self._robot_held = False
        self._js_since_drive = True
        self.counts["joint_states_accepted"] += 1

    def _reset_joint_times(self):
        """Forget joint-state stamps (a reset, a clock jump): the next one places the links afresh."""
        self._js_t0_ns = None
        self._drive_from = None
        if self._robot is not None and self._robot in self.world.robots:
            self._robot.restart_stamps()

    def _hold_robot(self, now_s):
        """No joint states for pose_timeout: the links stay at the last forward kinematics, at rest
        (a kinematic body keeps moving at its velocity otherwise)."""
        robot = self._robot
        if self._robot_held or robot is None or robot not in self.world.robots:
            return
        if now_s - self._js_last_rx <= self.cfg["pose_timeout"]:
            return
        try:
            self.world.pose_robot(robot, robot.q, {n: 0.0 for n in robot.q})
        except contact_sim.ContactSimError as exc:   # beyond the world's bounds: they stay where they are
            self._warn("robot_jump", f"the links cannot hold at the last joint state ({exc})")
        robot.restart_stamps()   # at rest: the next joint state places the links, no difference across the gap
        self._drive_from = None
        self._drive_moving = False
        self._robot_held = True

    def _drive_robot(self, now_ns):
        """Before a tick's steps: pose the links at the joint positions the last tick drove them to
        (``start``; the goal itself when there is none: a new robot, a reset, after holding, paused
        or resumed) with the joint velocities ``(goal - start) / period`` that carry them to
        ``goal`` over the tick. The goal is each joint's latest position carried on at its velocity
        (the finite difference of its stamps) to the end of this tick on the node's clock
        (``now_ns`` + period), at most its last stamps' interval and a period beyond its stamp,
        within the joint's limits: a publisher slower than the ticks moves the links smoothly
        between its messages, and a tick that comes late carries them as far as the clock moved.
        Returns the goal, the next start once the steps succeed (``_drove``); None when nothing
        moves the links."""
        robot = self._robot
        if robot is None or robot not in self.world.robots:
            return None
        moving = any(robot.qd.values())
        if not (moving or self._drive_moving or self._js_since_drive):
            return None
        self._js_since_drive = False
        goal = dict(robot.q)
        if moving:
            t_end = (now_ns - self._js_t0_ns) * 1e-9 + self.period
            for n, qd in robot.qd.items():
                if qd:
                    # carried on to the tick's end, but never back (a stamp ahead of the node's clock
                    # is taken as it is) and never further than the joint's own last interval and a
                    # period beyond its stamp: joint states that reach a busy node late are not
                    # carried past where the robot stopped (and then back in one tick)
                    last = robot.t[n]
                    ahead = min(max(t_end - last, 0.0), last - robot.before[n][1] + self.period)
                    lo, hi = robot.by_name[n]["limits"]
                    goal[n] = min(max(goal[n] + qd * ahead, lo), hi)
        start = self._drive_from
        if start is None or start.keys() != goal.keys() or self.paused:   # paused: ~/step's time is not the clock's
            start = goal
        qd = {n: (goal[n] - start[n]) / self.period for n in goal}
        try:
            self.world.pose_robot(robot, start, qd)
        except contact_sim.ContactSimError as exc:   # faster than the world's bounds (settings.max_*)
            self.counts["robot_jumps"] += 1
            start = goal
            try:
                self.world.pose_robot(robot, start, {n: 0.0 for n in goal})
            except contact_sim.ContactSimError as again:   # the goal itself beyond them: the links stay
                self._warn("robot_jump", f"the links cannot move to the latest joint state ({again}); they stay "
                                         f"where they are")
                return None
            self._warn("robot_jump", f"the links cannot move to the latest joint state in one tick ({exc}); "
                                     f"they are placed there at rest")
        self._drive_moving = start != goal
        return goal

    def _drove(self, goal):
        """The tick's steps took the links to ``goal``: the next tick starts there."""
        if goal is not None:
            self._drive_from = goal
