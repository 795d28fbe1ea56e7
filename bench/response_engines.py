"""One scene description, three engines: the adapters behind ``bench_response.py``.

A ``Scene`` is plain data (bodies with shape, mass, pose, velocity; gravity, dt, one material).
Each adapter builds that same scene in its engine — contact_sim, pybullet, MuJoCo — and exposes
the same four calls: ``step()`` (one step, the only thing that is timed), ``poses()`` of the
dynamic bodies in scene order, ``settings()`` (the solver settings it ran with, for the report)
and ``close()``. Everything measured about the result (penetration, escapes, drift) is computed
here in numpy from the final poses, the same way for every engine, so that no engine's own
contact report is trusted.

How each engine gets the scene's one material (friction μ, restitution e) for every pair:
  * contact_sim: one material; two equal coefficients combine to themselves under every rule.
  * pybullet multiplies the two bodies' coefficients (Bullet's product rule), so every body gets
    √μ and √e: every pair — sphere–sphere as well as sphere–wall — then has exactly μ and e.
    Linear/angular damping 0 (its default is 0.04), rolling/spinning friction 0, restitution
    velocity threshold 0, otherwise its defaults (50 solver iterations, split impulse, ERP).
    Every body, the ground and walls too, is made with ``useMaximalCoordinates=True``: a
    btRigidBody solved by Bullet's rigid-body solver, its fastest way for free rigid bodies
    (``createMultiBody``'s default makes each a Featherstone multibody). Measured by
    ``bench/response_protocol.py`` (seconds 1–10 of fresh builds), ms a step, multibody / maximal
    dynamic bodies only / maximal every body: resting_10 0.0256 / 0.0206 / 0.0141, resting_100
    0.255 / 0.205 / 0.141, stack_10 0.124 / 0.086 / 0.082, spheres_10 0.0108 / 0.0093 / 0.0067,
    ball_1 0.0013 / 0.0014 / 0.0015 (the one ball: no gain, within the noise). The physics: the
    same coefficients and combination rules; with e 0 nearly the same results (pybullet alone, multibody → maximal every body): resting penetration
    0.0125 → 0.0126 mm (resting_100 0.0164 → 0.0126), the stack after 5 s 0.62 → 0.55 mm and top
    drift 6.3 → 5.6 mm, the pile after 2 s 0.65 → 1.02 mm deepest overlap, none escaped. Restitution is
    handled differently once no multibody takes part: any contact with a multibody goes through
    the multibody solver (with only the dynamic bodies maximal the ball bounces exactly as
    before), the rigid-body solver subtracts a speculative contact's remaining gap ÷ dt from the
    bounce velocity, so a bounce detected before touching loses height (at 2.0 mm gap: 0.9 × 3.988 − 0.0020 × 240
    = 3.11 m/s, measured 3.107): the e 0.9 ball's apexes
    are 0.921, 0.601, 0.345 m (exact 0.829, 0.690, 0.590; with the multibody ground 0.936,
    0.801, 0.732, the first overshoot from Baumgarte pushing out a 12 mm penetration). The bodies
    do not sleep (their velocities stay non-zero at rest).
  * MuJoCo takes the element-wise maximum of the two geoms' friction when their priorities are
    equal (the default), so every geom gets sliding friction μ (torsional and rolling left at
    their defaults 0.005 and 0.0001; they act only with condim > 3, and the default condim is 3).
    MuJoCo has no restitution coefficient: its contacts are soft (default solref 0.02 s, damping
    ratio 1, critically damped), which does not bounce — the closest it has to e = 0.
"""
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree


# ---------------------------------------------------------------------------- the scene as data
@dataclass
class Body:
    """``shape`` is ``plane`` (the ground z = 0, static only), ``sphere`` (``size`` = radius) or
    ``box`` (``size`` = full edge lengths, like URDF/SDF). ``mass`` 0 means static."""

    name: str
    shape: str
    size: object
    mass: float = 0.0
    position: tuple = (0.0, 0.0, 0.0)
    orientation: tuple = (0.0, 0.0, 0.0, 1.0)          # x, y, z, w
    velocity: tuple = (0.0, 0.0, 0.0)
    angular_velocity: tuple = (0.0, 0.0, 0.0)          # world frame

    @property
    def static(self):
        return self.mass == 0.0


@dataclass
class Scene:
    name: str
    bodies: list
    dt: float
    gravity: tuple = (0.0, 0.0, -9.81)
    friction: float = 0.5
    restitution: float = 0.0
    contact_sim_settings: dict = field(default_factory=dict)   # beyond dt: empty = the engine's defaults

    @property
    def dynamic(self):
        return [b for b in self.bodies if not b.static]


def quat_matrix(q):
    """Rotation matrices ``(N, 3, 3)`` of unit quaternions ``(N, 4)`` x, y, z, w."""
    q = np.asarray(q, float).reshape(-1, 4)
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


# ---------------------------------------------------------------------------- adapters
class Engine:
    """Two loops. ``run_block(n)``, the benchmark's timed unit: ``n`` steps in a plain Python loop
    over the engine's own step call (``world.step``, ``stepSimulation``, ``mj_step``), bound once,
    one ``perf_counter`` pair around the whole block, nothing between the steps; returns its wall
    seconds. ``run(n)``: each step timed on its own with the statistics hook ``after_step`` between
    steps (not counted) — for untimed settling and for per-step statistics."""

    name = "engine"

    def run_block(self, n):
        raise NotImplementedError

    def run(self, n):
        total = 0.0
        for _ in range(n):
            t0 = time.perf_counter()
            self.step()
            total += time.perf_counter() - t0
            self.after_step()
        return total

    def after_step(self):
        """Hook for per-step statistics, outside the timed region."""


class ContactSimEngine(Engine):
    """contact_sim with its defaults unless the scene says otherwise (only ``dt`` is set)."""

    name = "contact_sim"

    def __init__(self, scene):
        import contact_sim as cs

        bodies = []
        for b in scene.bodies:
            if b.shape == "plane":
                shape = {"type": "plane", "normal": [0, 0, 1], "offset": 0.0}
            elif b.shape == "sphere":
                shape = {"type": "sphere", "radius": float(b.size)}
            else:
                shape = {"type": "box", "size": [float(s) for s in b.size]}
            d = {"name": b.name, "kind": "static" if b.static else "dynamic", "shape": shape, "material": "m"}
            if b.shape != "plane":
                d["position"] = [float(v) for v in b.position]
                d["orientation"] = [float(v) for v in b.orientation]
            if not b.static:
                d.update(mass=float(b.mass), velocity=[float(v) for v in b.velocity],
                         angular_velocity=[float(v) for v in b.angular_velocity])
            bodies.append(d)
        self.world = cs.load_scene({
            "gravity": [float(g) for g in scene.gravity],
            "settings": {"dt": scene.dt, **scene.contact_sim_settings},
            "materials": {"m": {"restitution": scene.restitution, "friction": scene.friction}},
            "bodies": bodies})
        self.dyn = np.array([self.world.index(b.name) for b in scene.dynamic], int)
        self.contacts, self.iterations = [], []

    def step(self):
        self.world.step()

    def run_block(self, n):
        step = self.world.step
        t0 = time.perf_counter()
        for _ in range(n):
            step()
        return time.perf_counter() - t0

    def after_step(self):
        st = self.world.last_solve
        get = st.get
        self.contacts.append(get("contacts", np.nan))
        self.iterations.append(get("iterations", np.nan))

    def poses(self):
        p, q = self.world.poses()
        return p[self.dyn], q[self.dyn]

    def settings(self):
        s = self.world.settings
        lines = [ln for ln in self.world.describe().splitlines()
                 if ln.startswith(("friction", "response", "time of impact", "speculative", "resting"))]
        return (f"defaults: solver_iterations {s.solver_iterations}, solver_tolerance {s.solver_tolerance:g} m/s, "
                f"contact_margin {s.contact_margin:g} m, split_beta {s.split_beta:g}; chose: "
                + "; ".join(ln.split(":")[0] for ln in lines))

    def close(self):
        self.world = None


class PyBulletEngine(Engine):
    name = "pybullet"

    def __init__(self, scene, maximal=True, maximal_static=True):
        """``maximal``/``maximal_static``: ``useMaximalCoordinates`` of the dynamic/static bodies
        (both True: every body a btRigidBody, the fastest; see the module's docstring)."""
        import pybullet as p

        self.p = p
        self.maximal, self.maximal_static = maximal, maximal_static
        self.cid = cid = p.connect(p.DIRECT)
        p.setGravity(*scene.gravity, physicsClientId=cid)
        p.setTimeStep(scene.dt, physicsClientId=cid)
        p.setPhysicsEngineParameter(restitutionVelocityThreshold=0.0, physicsClientId=cid)
        mu, e = float(np.sqrt(scene.friction)), float(np.sqrt(scene.restitution))   # product rule → μ, e per pair
        shapes, self.ids = {}, []
        for b in scene.bodies:
            key = (b.shape, np.asarray(b.size, float).tobytes())
            if key not in shapes:
                if b.shape == "plane":
                    shapes[key] = p.createCollisionShape(p.GEOM_PLANE, planeNormal=[0, 0, 1], physicsClientId=cid)
                elif b.shape == "sphere":
                    shapes[key] = p.createCollisionShape(p.GEOM_SPHERE, radius=float(b.size), physicsClientId=cid)
                else:
                    shapes[key] = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.5 * float(s) for s in b.size],
                                                         physicsClientId=cid)
            bid = p.createMultiBody(float(b.mass), shapes[key], basePosition=list(b.position),
                                    baseOrientation=list(b.orientation),
                                    useMaximalCoordinates=maximal_static if b.static else maximal,
                                    physicsClientId=cid)
            p.changeDynamics(bid, -1, lateralFriction=mu, restitution=e, linearDamping=0.0, angularDamping=0.0,
                             rollingFriction=0.0, spinningFriction=0.0, physicsClientId=cid)
            if not b.static:
                p.resetBaseVelocity(bid, list(b.velocity), list(b.angular_velocity), physicsClientId=cid)
                self.ids.append(bid)

    def step(self):
        self.p.stepSimulation(physicsClientId=self.cid)

    def run_block(self, n):
        step, cid = self.p.stepSimulation, self.cid
        t0 = time.perf_counter()
        for _ in range(n):
            step(physicsClientId=cid)
        return time.perf_counter() - t0

    def poses(self):
        st = [self.p.getBasePositionAndOrientation(i, physicsClientId=self.cid) for i in self.ids]
        return np.array([s[0] for s in st], float).reshape(-1, 3), np.array([s[1] for s in st], float).reshape(-1, 4)

    def settings(self):
        par = self.p.getPhysicsEngineParameters(physicsClientId=self.cid)
        how = {(True, True): "every body useMaximalCoordinates=True (btRigidBody; the ground too)",
               (True, False): "dynamic bodies useMaximalCoordinates=True, the ground a multibody",
               (False, False): "every body a multibody (useMaximalCoordinates=False)",
               (False, True): "dynamic bodies multibodies, the ground useMaximalCoordinates=True"}
        return (f"{how[self.maximal, self.maximal_static]}; numSolverIterations {par['numSolverIterations']}, "
                f"numSubSteps {par['numSubSteps']}, damping 0, restitutionVelocityThreshold 0, "
                f"friction/restitution √ per body (product rule)")

    def close(self):
        self.p.disconnect(physicsClientId=self.cid)


def mjcf(scene):
    """The scene as an MJCF string: free-joint bodies with one geom each (``mass`` on the geom, so
    MuJoCo computes the same uniform-density inertia), static geoms in the world body, the ground a
    plane. Every option not written here is MuJoCo's default."""
    def num(*v):   # plain floats: repr of a numpy scalar is not MJCF
        return " ".join(repr(float(x)) for x in v)

    mu = f'friction="{num(scene.friction)} 0.005 0.0001"'

    def q(b):   # MuJoCo quaternions are w, x, y, z
        x, y, z, w = b.orientation
        return f'quat="{num(w, x, y, z)}"'

    def geom(b):
        if b.shape == "plane":
            return f'<geom name="{b.name}" type="plane" size="0 0 1" {mu}/>'
        size = num(b.size) if b.shape == "sphere" else num(*(0.5 * float(s) for s in b.size))
        mass = f' mass="{num(b.mass)}"' if not b.static else ""
        where = "" if not b.static else f' pos="{num(*b.position)}" {q(b)}'
        return f'<geom name="{b.name}" type="{b.shape}" size="{size}"{mass}{where} {mu}/>'

    out = [f'<mujoco model="{scene.name}">',
           '<option timestep="{}" gravity="{}"/>'.format(num(scene.dt), num(*scene.gravity)),
           "<worldbody>"]
    for b in scene.bodies:
        if b.static:
            out.append(geom(b))
        else:
            out.append(f'<body name="{b.name}" pos="{num(*b.position)}" {q(b)}><freejoint/>{geom(b)}</body>')
    return "\n".join(out + ["</worldbody>", "</mujoco>"])


class MuJoCoEngine(Engine):
    name = "MuJoCo"

    def __init__(self, scene):
        import mujoco

        self.mj = mujoco
        self.m = mujoco.MjModel.from_xml_string(mjcf(scene))
        self.d = mujoco.MjData(self.m)
        dyn = scene.dynamic
        self.adr = np.array([self.m.jnt_qposadr[self.m.body(b.name).jntadr[0]] for b in dyn], int)
        vadr = np.array([self.m.jnt_dofadr[self.m.body(b.name).jntadr[0]] for b in dyn], int)
        for b, a, v in zip(dyn, self.adr, vadr):
            # free joint: linear velocity in the world frame, angular velocity in the body frame
            R = quat_matrix(b.orientation)[0]
            self.d.qvel[v:v + 3] = b.velocity
            self.d.qvel[v + 3:v + 6] = R.T @ np.asarray(b.angular_velocity, float)
        mujoco.mj_forward(self.m, self.d)

    def step(self):
        self.mj.mj_step(self.m, self.d)

    def run_block(self, n):
        step, m, d = self.mj.mj_step, self.m, self.d
        t0 = time.perf_counter()
        for _ in range(n):
            step(m, d)
        return time.perf_counter() - t0

    def poses(self):
        qp = self.d.qpos
        pos = np.stack([qp[a:a + 3] for a in self.adr]).reshape(-1, 3).copy()
        wxyz = np.stack([qp[a + 3:a + 7] for a in self.adr]).reshape(-1, 4)
        return pos, np.concatenate([wxyz[:, 1:], wxyz[:, :1]], axis=1)

    def settings(self):
        o, mj = self.m.opt, self.mj

        def enum(kind, value):   # mjINT_EULER -> EULER
            return kind(value).name.split("_", 1)[1]

        return (f"MuJoCo {mj.__version__} defaults: integrator {enum(mj.mjtIntegrator, o.integrator)}, "
                f"solver {enum(mj.mjtSolver, o.solver)}, iterations {o.iterations}, tolerance {o.tolerance:g}, "
                f"ls_iterations {o.ls_iterations}, cone {enum(mj.mjtCone, o.cone)}, impratio {o.impratio:g}, "
                f"noslip_iterations {o.noslip_iterations}, solref 0.02 1, condim 3, friction max-combined, "
                f"no restitution (soft contacts)")

    def close(self):
        self.m = self.d = None


ENGINES = {"contact_sim": ContactSimEngine, "pybullet": PyBulletEngine, "MuJoCo": MuJoCoEngine}


def available_peers():
    """Peer engine names whose Python package imports here, and the reasons for the others."""
    ok, missing = [], {}
    for name, module in (("pybullet", "pybullet"), ("MuJoCo", "mujoco")):
        try:
            __import__(module)
            ok.append(name)
        except ImportError as exc:
            missing[name] = f"{module} not importable ({exc}); pip install {module}"
    return ok, missing


# ---------------------------------------------------------------------------- measures from poses
def box_sdf(points, centre, R, half):
    """Signed distance of ``points (N, 3)`` to a box (negative inside)."""
    local = (np.asarray(points, float) - centre) @ R          # R's columns are the box axes
    q = np.abs(local) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def box_box_depth(pa, Ra, ha, pb, Rb, hb):
    """Penetration depth of two boxes (0 when apart): the smallest overlap of their projections
    over the 15 separating axes (3 + 3 face normals, 9 edge cross products), which is the minimum
    translation that separates two convex boxes."""
    axes = [Ra[:, i] for i in range(3)] + [Rb[:, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            c = np.cross(Ra[:, i], Rb[:, j])
            n = np.linalg.norm(c)
            if n > 1e-9:                                      # parallel edges add no new axis
                axes.append(c / n)
    L = np.array(axes)
    ra = np.abs(L @ Ra) @ ha
    rb = np.abs(L @ Rb) @ hb
    overlap = ra + rb - np.abs(L @ (np.asarray(pb) - pa))
    return max(0.0, float(overlap.min()))


def max_penetration(scene, pos, quat_xyzw):
    """Deepest overlap (m) of any pair at the given dynamic-body poses: sphere–sphere, sphere–box,
    box–box, and each against the ground plane z = 0 and the static boxes (walls)."""
    dyn = scene.dynamic
    R = quat_matrix(quat_xyzw)
    is_sphere = np.array([b.shape == "sphere" for b in dyn])
    size = [np.full(3, float(b.size)) if b.shape == "sphere" else 0.5 * np.asarray(b.size, float) for b in dyn]
    half = np.array(size).reshape(-1, 3)
    bound = np.where(is_sphere, half[:, 0], np.linalg.norm(half, axis=1))
    deepest = 0.0
    # against the ground: a sphere's centre height, a box's lowest corner
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    if any(b.shape == "plane" for b in scene.bodies):
        box_low = pos[:, 2] + np.einsum("kj,nj,nj->nk", corners, half, R[:, 2, :]).min(axis=1)
        low = np.where(is_sphere, pos[:, 2] - half[:, 0], box_low)
        deepest = max(deepest, float(np.max(-low, initial=0.0)))
    # against static boxes
    for w in (b for b in scene.bodies if b.static and b.shape == "box"):
        wc, wR, wh = np.asarray(w.position, float), quat_matrix(w.orientation)[0], 0.5 * np.asarray(w.size, float)
        if is_sphere.any():
            d = half[is_sphere, 0] - box_sdf(pos[is_sphere], wc, wR, wh)
            deepest = max(deepest, float(np.max(d, initial=0.0)))
        for i in np.flatnonzero(~is_sphere):
            deepest = max(deepest, box_box_depth(pos[i], R[i], half[i], wc, wR, wh))
    # dynamic pairs, found by bounding spheres
    if len(dyn) > 1:
        pairs = cKDTree(pos).query_pairs(2.0 * float(bound.max()), output_type="ndarray")
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            dist = np.linalg.norm(pos[i] - pos[j], axis=1)
            keep = dist < bound[i] + bound[j]
            i, j, dist = i[keep], j[keep], dist[keep]
            ss = is_sphere[i] & is_sphere[j]
            if ss.any():
                deepest = max(deepest, float(np.max(half[i[ss], 0] + half[j[ss], 0] - dist[ss])))
            for a, b in zip(i[~ss], j[~ss]):
                if is_sphere[a] or is_sphere[b]:
                    s, x = (a, b) if is_sphere[a] else (b, a)
                    d = half[s, 0] - box_sdf(pos[s][None], pos[x], R[x], half[x])[0]
                else:
                    d = box_box_depth(pos[a], R[a], half[a], pos[b], R[b], half[b])
                deepest = max(deepest, float(d))
    return deepest
