"""Run-time body control with common interfaces: set states, spawn and delete bodies.

A mixin of ``ContactSimNode``. Three subscriptions in the node's private namespace:

- ``~/set_body_states`` (``sensor_msgs/MultiDOFJointState``): teleport and/or set the velocity of
  named non-static bodies (transforms: body origins; twist: velocity of the origin and angular
  velocity, world frame; an empty list leaves that part alone). A kinematic body given a twist
  moves at it until the next pose or state.
- ``~/spawn`` (``std_msgs/String``): a YAML list of bodies written as in a scene file.
- ``~/delete`` (``std_msgs/String``): body names, one per line.

Each request is applied whole or not at all (the engine checks it first), and its outcome is
visible: a warning naming the reason when refused, counters in /diagnostics, and the latched
``body_names`` republished when the body set changed.
"""
import os

import numpy as np
import yaml
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import MultiDOFJointState
from std_msgs.msg import String

import contact_sim
from contact_sim import quat
from contact_sim.scene import add_scene_bodies

from .conversions import PoseError, multidof_to_arrays, validate_poses


TOPICS = {"body_states": "~/set_body_states", "spawns": "~/spawn", "deletes": "~/delete"}


class BodyControl:
    """``~/set_body_states``, ``~/spawn`` and ``~/delete`` of ``ContactSimNode``."""

    def _create_body_control(self, overrides):
        # commands must arrive: reliable by default, overridable like the pose subscription
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.sub_set_states = self.create_subscription(MultiDOFJointState, "~/set_body_states", self._on_set_body_states,
                                                       qos, qos_overriding_options=overrides())
        self.sub_spawn = self.create_subscription(String, "~/spawn", self._on_spawn, qos,
                                                  qos_overriding_options=overrides())
        self.sub_delete = self.create_subscription(String, "~/delete", self._on_delete, qos,
                                                   qos_overriding_options=overrides())

    def _refuse(self, what, text):
        self.counts["rejected_" + what] += 1
        self._warn(what, f"{TOPICS[what]} refused: {text}; nothing changed")

    # ------------------------------------------------------------------ set states
    def _on_set_body_states(self, msg):
        try:
            names, p, q, v, w = multidof_to_arrays(msg)
            world = self.world
            idx = np.array([world.index(n) for n in names], np.int64)   # unknown names refused here
            if p is not None:
                p, q = validate_poses(p, q, len(names), world.settings.quaternion_tolerance, "set_body_states")
            if v is not None:
                bad = np.flatnonzero(~(np.isfinite(v).all(axis=1) & np.isfinite(w).all(axis=1)))
                if bad.size:
                    raise PoseError("nonfinite", f"set_body_states: twist of {names[bad[0]]!r} has NaN or infinite values")
                # the twist is that of the body origin; the engine takes the centre of mass's velocity
                orientation = world.s.quat[idx] if q is None else q
                v = v + np.cross(w, quat.rotate(orientation, world.com_local[idx]))
            world.set_states(names, positions=p, orientations=q, velocities=v, angular_velocities=w)
        except (PoseError, ValueError) as exc:   # ContactSimError is a ValueError
            return self._refuse("body_states", str(exc))
        except Exception as exc:                  # whatever else a message can provoke: refused, never a crash
            return self._refuse("body_states", f"{type(exc).__name__}: {exc}")
        # tracked bodies set from outside are no longer held at their last pose
        for j, n in enumerate(self.tracked):
            if n in names:
                self._posed[j] = False
        self.counts["body_states_set"] += 1

    # ------------------------------------------------------------------ spawn and delete
    def _on_spawn(self, msg):
        try:
            bodies = yaml.safe_load(msg.data)
        except yaml.YAMLError as exc:
            return self._refuse("spawns", f"not valid YAML: {exc}")
        except Exception as exc:   # e.g. nesting deep enough to exhaust the recursion limit
            return self._refuse("spawns", f"cannot read the YAML: {type(exc).__name__}: {exc}")
        if isinstance(bodies, dict):     # one body written as a mapping
            bodies = [bodies]
        base = os.path.dirname(os.path.abspath(self.scene_path))   # mesh files as in the scene
        try:
            idx = add_scene_bodies(self.world, bodies, base_dir=base, path="spawn")
        except contact_sim.ContactSimError as exc:
            return self._refuse("spawns", str(exc))
        except Exception as exc:   # a mesh file trimesh cannot read, ...: the world was restored by the engine
            return self._refuse("spawns", f"{type(exc).__name__}: {exc}")
        self.counts["spawned_bodies"] += len(idx)
        self._bodies_changed()
        names = [self.world.body_names[i] for i in idx]
        self.get_logger().info(f"spawned {len(idx)} bodies: {', '.join(names)}")

    def _on_delete(self, msg):
        names = [line.strip() for line in msg.data.splitlines() if line.strip()]
        if not names:
            return self._refuse("deletes", "no body names (one per line)")
        tracked = [n for n in names if n in self.tracked]
        if tracked:
            return self._refuse("deletes", f"{', '.join(map(repr, tracked))} driven by body_poses (tracked_bodies); "
                                           f"change tracked_bodies first")
        try:
            self.world.remove_bodies(names)
        except contact_sim.ContactSimError as exc:
            return self._refuse("deletes", str(exc))
        self.counts["deleted_bodies"] += len(names)
        self._bodies_changed()
        self._refreeze_heap()   # the deleted bodies' reference cycles (their meshes' caches) freed
        self.get_logger().info(f"deleted {len(names)} bodies: {', '.join(names)}")

    def _bodies_changed(self):
        """After spawn or delete: indices of the tracked bodies, the last contacts (the engine
        remapped them) and the latched names."""
        names = self.world.body_names
        self.tracked_idx = np.array([names.index(n) for n in self.tracked], np.int64)
        self.contacts = self.world.contacts
        self._publish_names()
