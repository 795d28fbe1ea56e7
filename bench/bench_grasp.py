"""Grasp, lift and shake: contact_sim beside MuJoCo and pybullet, one process, engines taking turns.

The same two-finger grasp in three engines. A 5 cm cube of 0.2 kg (or a standing cylinder, radius
2.5 cm, height 5 cm, 0.2 kg) rests on the floor z = 0; μ = 1 on every surface, gravity −9.81 z,
dt = 1/240 s in every engine. Two finger boxes (2 cm thick in x, 4 cm × 4 cm faces, centred at the
object's mid-height) start 1 cm clear of the object's ±x faces. The commanded schedule (the "hand"
is the midpoint of the fingers; t in s):

* 0–1 s, close: each finger moves linearly from 1 cm clear to ``over`` past the face on its side
  (a position command: the engines decide how far the finger really goes);
* 1–3 s, lift: the hand rises linearly by 10 cm (constant 5 cm/s; speed jumps at 1 s and 3 s);
* 3–5 s, shake: the hand's y = 0.05 sin(2π·2 Hz·(t − 3)) m (±5 cm along y, across the grip axis,
  so friction carries the shake; the speed jumps from 0 to 0.63 m/s at 3 s), z held.

Reported per engine, object and ``over`` (0.5, 1, 5 mm; the cylinder at 1 mm), from positions read
back from each engine after every step (contact_sim: ``World.poses``; MuJoCo: ``data.xpos``;
pybullet: the object's base position and the finger links' frames), never from the commands:

* ``held``: the object's centre is above z = 5 cm at the end (5 s);
* ``slip_mm``: the largest change of the object's height relative to the fingers' mean height from
  the end of closing (1 s) to the end;
* ``faster_m_s``: the largest |v_object| − max(|v_left|, |v_right|) over the run, velocities as
  finite differences of the positions after successive steps (the same for every engine);
* ``depth_mm``: the largest finger–object penetration in the engine's contact report;
* ``grip_N``: the mean over the lift (1–3 s, after closing) of the normal force one finger applies
  (the two fingers averaged), from the engine's contact report (contact_sim: normal impulse ÷ dt;
  MuJoCo: ``mj_contactForce``; pybullet: ``normalForce``); ``grip_shake_N`` the same over 3–5 s;
* ``shake_mm``: the shake amplitude the fingers really made (largest |y| of their midpoint over
  3–5 s), since the peers' hands follow the command through their controllers;
* ``step_ms``: median time of one step: the command and the step (contact_sim: ``set_poses`` +
  ``step``; MuJoCo: setting ``ctrl`` + ``mj_step``; pybullet: ``setJointMotorControlArray`` +
  ``stepSimulation``), over every step of every round; ``command_ms`` the median of the command
  alone; ``ratio``: the engine's median step time ÷ contact_sim's in the same round, the median
  over rounds (below 1: faster than contact_sim). The engines step in turns (chunks of 24 steps,
  the order rotated each chunk) because this machine's absolute speed drifts 2× over minutes; only
  the command and step calls are timed (not the measuring).

Each engine on its own terms (defaults unless the scenario needs a value; all printed):

* contact_sim: ``Settings(dt=1/240)``, its defaults (compliant contacts with the kinematic
  fingers: ``kinematic_stiffness`` 1e5 N/m, critically damped, so the grip force per finger is
  about 1e5 × over), material μ = 1, e = 0. The fingers are
  kinematic bodies posed every step by ``set_poses`` at the step's end time. (Read back after the
  step, on this tree, such a body is one step's motion beyond that pose — the pose plus its
  velocity × dt — so the fingers lead the schedule by a step; the measures use the read-back
  positions, as for the peers.)
* MuJoCo: default Euler integrator, Newton solver, pyramidal cone, default solref/solimp; geom
  friction "1 0.005 0.0001" (MuJoCo's default, μ = 1). The hand is a 1 kg body on three slide joints
  (x, y, z), each with a position actuator kp = 1e5 N/m and joint damping 2√(kp·m) (joint damping:
  integrated implicitly by the Euler integrator); the fingers (0.1 kg each) are on slide joints
  along x relative to the hand, each with a position actuator kp = 1e5 N/m (the same stiffness as
  contact_sim's, so a command ``over`` past the face asks for kp × over, as in contact_sim),
  forcerange ±100 N (the menagerie Panda's finger limit), joint damping 2√(kp·m).
* pybullet: default solver (50 iterations), ``DIRECT``; every body's lateralFriction 1 (product rule:
  1). The gripper is one multibody with a fixed base: prismatic x, y, z links (0.1, 0.1, 1 kg, no
  collision shape), then two finger links (0.1 kg) on prismatic joints along x. Every joint under
  ``POSITION_CONTROL`` (pybullet's default position and velocity gains) with the schedule's target
  positions and velocities (finite differences of the schedule): force limit 100 N on the fingers,
  1000 N on the hand's joints.

Run (from the repository root)::

    PYTHONPATH=. .venv/bin/python bench/bench_grasp.py [--quick] [--rounds N] [--overs 0.5,1,5]
                                                      [--engines contact_sim,mujoco,pybullet]
                                                      [--no-cylinder] [--out DIR]
                                                      [--mujoco-option 'cone="elliptic" impratio="10"']

Prints a table and writes ``grasp.csv`` and ``grasp.png`` (object height and the fingers' mean
height against time, a panel per engine and case) to bench/results/ (``--quick``: one over
(1 mm), one round, no cylinder, ``grasp_quick.*``). An engine that is not installed is left out with a note.
``--mujoco-option`` adds attributes to MuJoCo's ``<option>`` (not its defaults: a variant to try,
e.g. the elliptic cone with a high ``impratio`` that MuJoCo's documentation suggests against slip);
the printed header and the CSV's ``settings`` column say so.
"""
import argparse
import csv
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

DT = 1.0 / 240.0
T_CLOSE, T_LIFT, T_SHAKE = 1.0, 2.0, 2.0
T_END = T_CLOSE + T_LIFT + T_SHAKE
N_STEPS = int(round(T_END / DT))
HALF = 0.025            # object's half width (m): cube half edge, cylinder radius
FINGER = (0.02, 0.04, 0.04)   # finger box (m): thickness along x, face 4 cm × 4 cm
CLEAR = 0.01            # start 1 cm clear of the faces
LIFT = 0.10             # m
SHAKE_AMP, SHAKE_HZ = 0.05, 2.0
MASS = 0.2              # kg
MU = 1.0
K_FINGER = 1e5          # N/m: MuJoCo's finger kp, contact_sim's default kinematic_stiffness
FINGER_FORCE = 100.0    # N: MuJoCo finger forcerange, pybullet finger force limit
ARM_FORCE = 1000.0      # N: pybullet hand-joint force limit
HAND_MASS, FINGER_MASS = 1.0, 0.1   # kg (MuJoCo, pybullet)
CHUNK = 24


def schedule(t, over):
    """The commanded hand at time ``t`` (s) for a squeeze ``over`` (m) past the faces: returns
    (hand position (3,) m, finger offset m): the fingers' centres are at hand ± (offset, 0, 0)."""
    s_close = min(t / T_CLOSE, 1.0)
    offset = HALF + FINGER[0] / 2 + CLEAR - (CLEAR + over) * s_close
    z = HALF + LIFT * min(max(t - T_CLOSE, 0.0) / T_LIFT, 1.0)
    ts = t - T_CLOSE - T_LIFT
    y = SHAKE_AMP * math.sin(2 * math.pi * SHAKE_HZ * ts) if ts > 0 else 0.0
    return np.array([0.0, y, z]), offset


def finger_targets(t, over):
    """Left and right finger centres (m) commanded at time ``t``."""
    hand, off = schedule(t, over)
    return hand - [off, 0, 0], hand + [off, 0, 0]


# ---------------------------------------------------------------------------------------- engines
class ContactSimGrasp:
    """contact_sim: kinematic fingers posed each step by ``set_poses`` at the step's end time."""

    name = "contact_sim"

    def __init__(self, over, shape="cube", kinematic_stiffness=None):
        import contact_sim as cs
        self.over = over
        st = cs.Settings(dt=DT) if kinematic_stiffness is None else \
            cs.Settings(dt=DT, kinematic_stiffness=kinematic_stiffness)
        kinematic_stiffness = st.kinematic_stiffness
        self.w = w = cs.World(settings=st,
                              materials={"default": cs.Material(friction=MU, restitution=0.0)})
        w.add_body("floor", cs.Plane(), kind="static")
        geom = cs.Box([2 * HALF] * 3) if shape == "cube" else cs.Cylinder(HALF, 2 * HALF)
        w.add_body("object", geom, mass=MASS, position=[0, 0, HALF])
        left, right = finger_targets(0.0, over)
        w.add_body("left", cs.Box(list(FINGER)), kind="kinematic", position=left)
        w.add_body("right", cs.Box(list(FINGER)), kind="kinematic", position=right)
        self.i_obj, self.i_left, self.i_right = w.index("object"), w.index("left"), w.index("right")
        self.settings = f"Settings(dt=1/240, kinematic_stiffness={kinematic_stiffness:g}), mu {MU}, e 0"

    def command(self, t):
        left, right = finger_targets(t, self.over)
        self.w.set_poses(["left", "right"], [left, right], [[0, 0, 0, 1]] * 2, t)

    def advance(self):
        self.w.step()

    def positions(self):
        pos, _ = self.w.poses()
        return pos[self.i_obj], pos[self.i_left], pos[self.i_right]

    def contacts(self):
        """(deepest finger–object penetration m, normal force of the left finger N, of the right)."""
        c = self.w.contacts
        depth, forces = 0.0, []
        for f in (self.i_left, self.i_right):
            sel = ((c.body_a == f) & (c.body_b == self.i_obj)) | ((c.body_b == f) & (c.body_a == self.i_obj))
            if sel.any():
                depth = max(depth, float(c.depth[sel].max()))
            forces.append(float(c.normal_impulse[sel].sum()) / DT)
        return depth, forces[0], forces[1]


MJCF = """
<mujoco model="grasp">
  <option timestep="{dt!r}" gravity="0 0 -9.81" {extra_option}/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="object" pos="0 0 {half!r}">
      <freejoint/>
      <geom name="object" {object_geom} mass="{mass}"/>
    </body>
    <body name="hand" pos="0 0 {half!r}">
      <joint name="hx" type="slide" axis="1 0 0" damping="{hand_damping!r}"/>
      <joint name="hy" type="slide" axis="0 1 0" damping="{hand_damping!r}"/>
      <joint name="hz" type="slide" axis="0 0 1" damping="{hand_damping!r}"/>
      <geom name="palm" type="box" size="0.02 0.02 0.01" pos="0 0 0.1" mass="{hand_mass}" contype="0" conaffinity="0"/>
      <body name="left" pos="{neg_off!r} 0 0">
        <joint name="fl" type="slide" axis="1 0 0" damping="{finger_damping!r}"/>
        <geom name="left" type="box" size="{fx!r} {fy!r} {fz!r}" mass="{finger_mass}"/>
      </body>
      <body name="right" pos="{off!r} 0 0">
        <joint name="fr" type="slide" axis="1 0 0" damping="{finger_damping!r}"/>
        <geom name="right" type="box" size="{fx!r} {fy!r} {fz!r}" mass="{finger_mass}"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="hx" joint="hx" kp="{hand_kp!r}"/>
    <position name="hy" joint="hy" kp="{hand_kp!r}"/>
    <position name="hz" joint="hz" kp="{hand_kp!r}"/>
    <position name="fl" joint="fl" kp="{finger_kp!r}" forcelimited="true" forcerange="-{fmax} {fmax}"/>
    <position name="fr" joint="fr" kp="{finger_kp!r}" forcelimited="true" forcerange="-{fmax} {fmax}"/>
  </actuator>
</mujoco>
"""


class MujocoGrasp:
    """MuJoCo: a hand on slide joints x, y, z and two fingers on slide joints along x, all under
    position actuators; ``ctrl`` set to the schedule's positions, then one ``mj_step``."""

    name = "MuJoCo"

    extra_option = ""   # MJCF <option> attributes beyond the defaults (main's --mujoco-option)

    def __init__(self, over, shape="cube", hand_kp=1e5, finger_kp=K_FINGER):
        import mujoco
        self.mj, self.over = mujoco, over
        self.off0 = schedule(0.0, over)[1]
        hand_total = HAND_MASS + 2 * FINGER_MASS
        object_geom = (f'type="box" size="{HALF!r} {HALF!r} {HALF!r}"' if shape == "cube"
                       else f'type="cylinder" size="{HALF!r} {HALF!r}"')
        xml = MJCF.format(dt=DT, extra_option=self.extra_option, half=HALF, object_geom=object_geom, mass=MASS,
                          hand_mass=HAND_MASS,
                          finger_mass=FINGER_MASS, hand_damping=2 * math.sqrt(hand_kp * hand_total),
                          finger_damping=2 * math.sqrt(finger_kp * FINGER_MASS), neg_off=-self.off0,
                          off=self.off0, fx=FINGER[0] / 2, fy=FINGER[1] / 2, fz=FINGER[2] / 2,
                          hand_kp=hand_kp, finger_kp=finger_kp, fmax=FINGER_FORCE)
        self.m = m = mujoco.MjModel.from_xml_string(xml)
        self.d = mujoco.MjData(m)
        mujoco.mj_forward(m, self.d)
        gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)  # noqa: E731
        bid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)  # noqa: E731
        self.g_obj, self.g_left, self.g_right = gid("object"), gid("left"), gid("right")
        self.b_obj, self.b_left, self.b_right = bid("object"), bid("left"), bid("right")
        self.f6 = np.zeros(6)
        self.settings = (f"{'option ' + self.extra_option + '; ' if self.extra_option else ''}"
                         f"Euler, Newton, default solref/solimp, friction 1 0.005 0.0001; hand {HAND_MASS} kg "
                         f"slide x/y/z position kp {hand_kp:g} damping 2sqrt(kp m); fingers {FINGER_MASS} kg "
                         f"slide x position kp {finger_kp:g} forcerange ±{FINGER_FORCE:g} N damping 2sqrt(kp m)")

    def ctrl(self, t):
        hand, off = schedule(t, self.over)
        start = np.array([0.0, 0.0, HALF])
        d = off - self.off0   # finger joint displacement: left moves +x by -d, right -x
        return np.array([hand[0] - start[0], hand[1] - start[1], hand[2] - start[2], -d, d])

    def command(self, t):
        self.d.ctrl[:] = self.ctrl(t)

    def advance(self):
        self.mj.mj_step(self.m, self.d)

    def positions(self):
        x = self.d.xpos
        return x[self.b_obj].copy(), x[self.b_left].copy(), x[self.b_right].copy()

    def contacts(self):
        d, depth, fl, fr = self.d, 0.0, 0.0, 0.0
        for i in range(d.ncon):
            c = d.contact[i]
            pair = {int(c.geom1), int(c.geom2)}
            if self.g_obj not in pair or not pair & {self.g_left, self.g_right}:
                continue
            depth = max(depth, -float(c.dist))
            self.mj.mj_contactForce(self.m, d, i, self.f6)
            if self.g_left in pair:
                fl += self.f6[0]
            else:
                fr += self.f6[0]
        return depth, fl, fr


class PybulletGrasp:
    """pybullet: one fixed-base multibody, prismatic x, y, z (the hand) then two prismatic fingers
    along x, every joint under ``POSITION_CONTROL`` with a force limit."""

    name = "pybullet"

    def __init__(self, over, shape="cube"):
        import pybullet as p
        self.p, self.over = p, over
        self.cid = cid = p.connect(p.DIRECT)
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setTimeStep(DT, physicsClientId=cid)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self.floor = p.createMultiBody(0, plane, physicsClientId=cid)
        if shape == "cube":
            obj = p.createCollisionShape(p.GEOM_BOX, halfExtents=[HALF] * 3, physicsClientId=cid)
        else:
            obj = p.createCollisionShape(p.GEOM_CYLINDER, radius=HALF, height=2 * HALF, physicsClientId=cid)
        self.obj = p.createMultiBody(MASS, obj, basePosition=[0, 0, HALF], physicsClientId=cid)
        finger = p.createCollisionShape(p.GEOM_BOX, halfExtents=[v / 2 for v in FINGER], physicsClientId=cid)
        self.off0 = off0 = schedule(0.0, over)[1]
        x, y, z = [1, 0, 0], [0, 1, 0], [0, 0, 1]
        pj = p.JOINT_PRISMATIC
        # links: 0 slide x, 1 slide y, 2 slide z (the hand), 3 left finger, 4 right finger
        self.gripper = p.createMultiBody(
            0, -1, basePosition=[0, 0, HALF],
            linkMasses=[0.1, 0.1, HAND_MASS, FINGER_MASS, FINGER_MASS],
            linkCollisionShapeIndices=[-1, -1, -1, finger, finger],
            linkVisualShapeIndices=[-1] * 5,
            linkPositions=[[0, 0, 0], [0, 0, 0], [0, 0, 0], [-off0, 0, 0], [off0, 0, 0]],
            linkOrientations=[[0, 0, 0, 1]] * 5,
            linkInertialFramePositions=[[0, 0, 0]] * 5,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * 5,
            linkParentIndices=[0, 1, 2, 3, 3],
            linkJointTypes=[pj] * 5,
            linkJointAxis=[x, y, z, x, x],
            useMaximalCoordinates=False, physicsClientId=cid)
        for body, links in ((self.floor, [-1]), (self.obj, [-1]), (self.gripper, [-1, 0, 1, 2, 3, 4])):
            for link in links:
                p.changeDynamics(body, link, lateralFriction=MU, physicsClientId=cid)
        self.joints = list(range(5))
        self.forces = [ARM_FORCE] * 3 + [FINGER_FORCE] * 2
        # no default velocity motors left over: every joint is set below each step
        self.prev = self.targets(0.0)
        self.settings = (f"defaults (50 iterations); lateralFriction {MU}; hand 0.1/0.1/{HAND_MASS} kg prismatic "
                         f"x/y/z force {ARM_FORCE:g} N; fingers {FINGER_MASS} kg prismatic x force "
                         f"{FINGER_FORCE:g} N; POSITION_CONTROL with target velocities")

    def targets(self, t):
        hand, off = schedule(t, self.over)
        d = off - self.off0
        return np.array([hand[0], hand[1], hand[2] - HALF, -d, d])

    def command(self, t):
        p = self.p
        q = self.targets(t)
        v = (q - self.prev) / DT
        self.prev = q
        p.setJointMotorControlArray(self.gripper, self.joints, p.POSITION_CONTROL, targetPositions=q.tolist(),
                                    targetVelocities=v.tolist(), forces=self.forces, physicsClientId=self.cid)

    def advance(self):
        self.p.stepSimulation(physicsClientId=self.cid)

    def positions(self):
        p = self.p
        obj = np.array(p.getBasePositionAndOrientation(self.obj, physicsClientId=self.cid)[0])
        ls = p.getLinkStates(self.gripper, [3, 4], physicsClientId=self.cid)
        return obj, np.array(ls[0][4]), np.array(ls[1][4])

    def contacts(self):
        p, depth, f = self.p, 0.0, []
        for link in (3, 4):
            pts = p.getContactPoints(self.gripper, self.obj, linkIndexA=link, physicsClientId=self.cid)
            for c in pts:
                depth = max(depth, -c[8])
            f.append(sum(c[9] for c in pts))
        return depth, f[0], f[1]

    def close(self):
        self.p.disconnect(self.cid)


ENGINES = {"contact_sim": ContactSimGrasp, "mujoco": MujocoGrasp, "pybullet": PybulletGrasp}


# --------------------------------------------------------------------------------------- measures
class Recorder:
    """Measures one run step by step (outside the timed calls); ``result()`` gives the row."""

    def __init__(self, engine):
        self.e = engine
        obj, left, right = engine.positions()
        self.prev = (obj, left, right)
        self.t, self.obj_z, self.hand_z, self.hand_y = [], [], [], []
        self.faster, self.depth, self.rel0, self.slip = -np.inf, 0.0, None, 0.0
        self.grip_lift, self.grip_shake, self.step_s, self.command_s = [], [], [], []

    def record(self, t):
        obj, left, right = self.e.positions()
        v = [(a - b) / DT for a, b in zip((obj, left, right), self.prev)]
        self.prev = (obj, left, right)
        self.faster = max(self.faster, float(np.linalg.norm(v[0]) - max(np.linalg.norm(v[1]), np.linalg.norm(v[2]))))
        depth, fl, fr = self.e.contacts()
        self.depth = max(self.depth, depth)
        hz = 0.5 * (left[2] + right[2])
        rel = obj[2] - hz
        if t <= T_CLOSE + 1e-9:
            self.rel0 = rel
        else:
            self.slip = max(self.slip, abs(rel - self.rel0))
            (self.grip_lift if t <= T_CLOSE + T_LIFT + 1e-9 else self.grip_shake).append(0.5 * (fl + fr))
        self.t.append(t)
        self.obj_z.append(float(obj[2]))
        self.hand_z.append(float(hz))
        self.hand_y.append(float(0.5 * (left[1] + right[1])))

    def result(self):
        t = np.array(self.t)
        shake = t > T_CLOSE + T_LIFT
        return {
            "held": bool(self.obj_z[-1] > 0.05),
            "object_z_end_mm": 1e3 * self.obj_z[-1],
            "slip_mm": 1e3 * self.slip,
            "faster_m_s": self.faster,
            "depth_mm": 1e3 * self.depth,
            "grip_N": float(np.mean(self.grip_lift)),
            "grip_shake_N": float(np.mean(self.grip_shake)),
            "shake_mm": 1e3 * float(np.abs(np.array(self.hand_y)[shake]).max()),
        }


def run_contact_sim(over, shape="cube", kinematic_stiffness=None):
    """The scenario in contact_sim alone (the test's entry): returns ``Recorder.result()``."""
    e = ContactSimGrasp(over, shape, kinematic_stiffness)
    rec = Recorder(e)
    for i in range(N_STEPS):
        t = (i + 1) * DT
        e.command(t)
        e.advance()
        rec.record(t)
    return rec.result()


def run_round(names, over, shape, rotate):
    """Build every engine, step them in turns (chunks of ``CHUNK`` steps, order rotated each chunk),
    timing only the step calls. Returns {name: Recorder}."""
    engines = [ENGINES[n](over, shape) for n in names]
    recs = [Recorder(e) for e in engines]
    for k, start in enumerate(range(0, N_STEPS, CHUNK)):
        r = (k + rotate) % len(engines)
        for j in list(range(r, len(engines))) + list(range(r)):
            e, rec = engines[j], recs[j]
            for i in range(start, min(start + CHUNK, N_STEPS)):
                t = (i + 1) * DT
                t0 = time.perf_counter()
                e.command(t)
                t1 = time.perf_counter()
                e.advance()
                t2 = time.perf_counter()
                rec.step_s.append(t2 - t0)
                rec.command_s.append(t1 - t0)
                rec.record(t)
    for e in engines:
        if hasattr(e, "close"):
            e.close()
    return {n: rec for n, rec in zip(names, recs)}


FIELDS = ["object", "over_mm", "engine", "held", "object_z_end_mm", "slip_mm", "faster_m_s", "depth_mm", "grip_N",
          "grip_shake_N", "shake_mm", "step_ms", "command_ms", "ratio", "rounds", "settings"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one over (1 mm), one round, no cylinder")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--overs", default="0.5,1,5", help="mm, comma separated")
    ap.add_argument("--engines", default="contact_sim,mujoco,pybullet")
    ap.add_argument("--no-cylinder", action="store_true")
    ap.add_argument("--mujoco-option", default="",
                    help='extra MJCF <option> attributes for MuJoCo, e.g. \'cone="elliptic" impratio="10"\'')
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    a = ap.parse_args(argv)
    MujocoGrasp.extra_option = a.mujoco_option
    overs = [1.0] if a.quick else [float(v) for v in a.overs.split(",")]
    rounds = 1 if a.quick else a.rounds
    names = []
    for n in a.engines.split(","):
        if n != "contact_sim":
            try:
                __import__(n)
            except ImportError:
                print(f"# {n} is not installed: left out")
                continue
        names.append(n)
    cases = [("cube", o) for o in overs]
    if not (a.quick or a.no_cylinder):
        cases.append(("cylinder", 1.0))
    # warm up the compiled kernels outside the timed rounds
    warm = ContactSimGrasp(1e-3)
    for i in range(24):
        warm.command((i + 1) * DT)
        warm.advance()

    print(f"# grasp, lift 10 cm, shake ±5 cm along y at 2 Hz; dt 1/240; mu {MU}; object {MASS} kg; "
          f"{rounds} round(s), engines in turns, chunks of {CHUNK} steps")
    settings = {}
    rows, traces = [], {}
    for shape, over in cases:
        per = {n: [] for n in names}
        for r in range(rounds):
            recs = run_round(names, over * 1e-3, shape, r)
            for n in names:
                per[n].append(recs[n])
        ratio = {}
        for n in names:
            rs = [np.median(per[n][r].step_s) / np.median(per["contact_sim"][r].step_s) for r in range(rounds)] \
                if "contact_sim" in names else [float("nan")]
            ratio[n] = float(np.median(rs))
        for n in names:
            rec0 = per[n][0]
            eng_settings = rec0.e.settings
            settings[n] = eng_settings
            row = {"object": shape, "over_mm": over, "engine": rec0.e.name, **rec0.result(),
                   "step_ms": 1e3 * float(np.median(np.concatenate([rec.step_s for rec in per[n]]))),
                   "command_ms": 1e3 * float(np.median(np.concatenate([rec.command_s for rec in per[n]]))),
                   "ratio": ratio[n], "rounds": rounds, "settings": eng_settings}
            rows.append(row)
            traces[(shape, over, rec0.e.name)] = (np.array(rec0.t), np.array(rec0.obj_z), np.array(rec0.hand_z))
    for n in names:
        print(f"# {ENGINES[n].name}: {settings[n]}")
    head = (f"{'object':8s} {'over':>5s} {'engine':11s} {'held':>4s} {'z_end':>6s} {'slip':>6s} {'faster':>7s} "
            f"{'depth':>6s} {'grip':>6s} {'gripS':>6s} {'shake':>6s} {'step':>7s} {'cmd':>6s} {'ratio':>6s}")
    print(head)
    print(f"{'':8s} {'mm':>5s} {'':11s} {'':>4s} {'mm':>6s} {'mm':>6s} {'m/s':>7s} {'mm':>6s} {'N':>6s} {'N':>6s} "
          f"{'mm':>6s} {'ms':>7s} {'ms':>6s} {'÷cs':>6s}")
    for r in rows:
        print(f"{r['object']:8s} {r['over_mm']:5.1f} {r['engine']:11s} {'yes' if r['held'] else 'NO':>4s} "
              f"{r['object_z_end_mm']:6.1f} {r['slip_mm']:6.2f} {r['faster_m_s']:7.3f} {r['depth_mm']:6.2f} "
              f"{r['grip_N']:6.1f} {r['grip_shake_N']:6.1f} {r['shake_mm']:6.1f} {r['step_ms']:7.3f} "
              f"{r['command_ms']:6.3f} {r['ratio']:6.3f}")
    for n in names:
        if n != "contact_sim":
            rs = [r["ratio"] for r in rows if r["engine"] == ENGINES[n].name]
            print(f"# step time contact_sim ÷ {ENGINES[n].name}: {1 / np.median(rs):.1f}× (median over the rows; "
                  f"each row's ratio is the median over rounds of the within-round ratio of medians)")
    os.makedirs(a.out, exist_ok=True)
    stem = "grasp_quick" if a.quick else "grasp"
    with open(os.path.join(a.out, stem + ".csv"), "w", newline="") as fh:
        wr = csv.DictWriter(fh, FIELDS)
        wr.writeheader()
        for r in rows:
            wr.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("# matplotlib is not installed: no chart")
        return rows
    labels = [ENGINES[n].name for n in names]
    fig, axes = plt.subplots(len(cases), len(labels), figsize=(4.2 * len(labels), 2.6 * len(cases)), sharex=True,
                             sharey=True, squeeze=False)
    for i, (shape, over) in enumerate(cases):
        for j, name in enumerate(labels):
            t, oz, hz = traces[(shape, over, name)]
            ax = axes[i][j]
            ax.plot(t, 1e3 * oz, label=f"{shape} centre z")
            ax.plot(t, 1e3 * hz, "--", label="fingers' mean z")
            ax.set_title(f"{name}: {shape}, over {over:g} mm", fontsize=9)
            ax.grid(alpha=0.3)
        axes[i][0].set_ylabel("height (mm)")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, stem + ".png"), dpi=90)
    return rows


if __name__ == "__main__":
    main()
