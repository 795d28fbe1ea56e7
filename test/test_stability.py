"""Long-run stability scenes (issue 10): ten simulated seconds each, under default settings, with
maximum penetration, drift, energy and wall time reported (``HARD`` lines, collected by
``make bench`` into docs/benchmarks.md) and the physical bounds asserted: nothing explodes, stacks stand,
piles settle, no body ever moves faster than a fall from the highest start (plus what a kinematic
paddle gives it), and the total energy never exceeds its start by more than the potential energy
position correction adds when it separates overlaps.
"""
import os
import time
import warnings

import numpy as np
import pytest
import trimesh

import contact_sim as cs
from contact_sim.response import ContactModelWarning, compliance
from scenegen import flat_tile_mesh

pytestmark = pytest.mark.stability
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
G = 9.81


class Run:
    """Steps a world for ``seconds`` and keeps the figures the issue asks for."""

    def __init__(self, world, seconds, dt=None):
        self.w = world
        dyn = world.kind == 2
        self.dyn = np.flatnonzero(dyn)
        self.p0 = world.s.pos.copy()
        self.e0 = world.energy()
        self.max_pen = self.max_speed = 0.0
        self.max_energy = self.e0
        self.allowance = 0.0
        # compliant contacts (a spring's force integrated over the step): its declared error bounds too
        self.springs = bool(compliance.possible(world))
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactModelWarning)   # mass ratios etc.: advice
            for _ in range(int(round(seconds / (dt or world.settings.dt)))):
                world.step(dt)
                s = world.s
                assert all(np.isfinite(a).all() for a in (s.pos, s.vel, s.quat, s.omega))
                ls = world.last_solve
                self.allowance += max(ls["correction_energy"], 0.0) + max(ls["kinematic_work"], 0.0) \
                    + max(ls["pose_work"], 0.0)
                if self.springs:   # the step's own bounds on what the springs' force may add
                    self.allowance += ls["rest_work_bound"] + ls["kick_error_bound"] + max(ls["rotation_drift"], 0.0)
                self.max_pen = max(self.max_pen, ls["max_penetration"])
                self.max_speed = max(self.max_speed, float(np.linalg.norm(s.vel[self.dyn], axis=1).max()))
                self.max_energy = max(self.max_energy, world.energy() - self.allowance)
        self.wall = time.perf_counter() - t
        self.seconds = seconds

    def drift(self):
        return float(np.linalg.norm(self.w.s.pos[self.dyn] - self.p0[self.dyn], axis=1).max())

    def report(self, name):
        print(f"HARD {name}, {self.seconds:g} s: max penetration {self.max_pen * 1e3:.3g} mm, max drift "
              f"{self.drift() * 1e3:.3g} mm, energy {self.e0:.6g} → {self.w.energy():.6g} J (peak above start, "
              f"correction deducted: {self.max_energy - self.e0:.3g} J), max speed {self.max_speed:.3g} m/s, "
              f"wall {self.wall:.1f} s")
        return self


def _ground(dt=1 / 60, **settings):
    w = cs.World(settings=cs.Settings(dt=dt, **settings), materials={"wood": cs.Material(restitution=0.0, friction=0.6)})
    w.add_body("ground", cs.Plane(), kind="static", material="wood")
    return w


def _walls(w, half):
    for name, n in (("wall_x0", [1, 0, 0]), ("wall_x1", [-1, 0, 0]), ("wall_y0", [0, 1, 0]), ("wall_y1", [0, -1, 0])):
        w.add_body(name, cs.Plane(n, -half), kind="static", material="wood")


@pytest.mark.parametrize("n", [20, 40])
def test_tall_stack_stands_for_ten_seconds(n):
    w = _ground()
    for i in range(n):
        w.add_body(f"box{i}", cs.Box([0.2] * 3), mass=1.0, position=[0, 0, 0.1 + 0.2 * i], material="wood")
    r = Run(w, 10.0).report(f"{n}-box stack")
    assert r.drift() < 1e-3 and r.max_pen < 1e-3 and r.max_speed < 1e-2
    assert r.max_energy <= r.e0 + 1e-9 * abs(r.e0)


def test_pyramid_of_fifty_five_boxes_stands():
    w = _ground()
    k = 0
    for layer in range(10):                              # 10 + 9 + ... + 1 = 55 boxes, 1 cm apart
        for i in range(10 - layer):
            x = (i - (9 - layer) / 2) * 0.21
            w.add_body(f"box{k}", cs.Box([0.2] * 3), mass=1.0, position=[x, 0, 0.1 + 0.2 * layer], material="wood")
            k += 1
    assert k == 55
    r = Run(w, 10.0).report("pyramid of 55")
    assert r.drift() < 1e-3 and r.max_pen < 1e-3 and r.max_speed < 1e-2


def _spring_release_speed(w):
    """The largest ``√(2E/m)`` (m/s) over the dynamic bodies of ``w``: ``E`` the energy (J) its
    compliant contacts store now, ``½ k d²`` per point (``World.contact_energy``'s terms)."""
    from contact_sim.collision import detect_world
    from contact_sim.response import models, prepare

    c, _ = detect_world(w, margin=w.settings.contact_margin)
    k, _ = prepare.stiffnesses(w, c, models.choose(w))
    e = 0.5 * k * np.maximum(c.depth, 0.0) ** 2
    per = np.zeros(len(w))
    np.add.at(per, c.body_a, e)
    np.add.at(per, c.body_b, e)
    dyn = w.kind == 2
    return float(np.sqrt(2.0 * per[dyn] / w.mass[dyn]).max()) if dyn.any() else 0.0


def _pile(w, n, half, rng, top):
    shapes = [lambda: cs.Box(rng.uniform(0.06, 0.16, 3)), lambda: cs.Sphere(rng.uniform(0.03, 0.08)),
              lambda: cs.Convex(rng.normal(size=(12, 3)) * 0.04)]
    for i in range(n):
        q = rng.normal(size=4)
        w.add_body(f"b{i}", shapes[i % 3](), density=float(rng.uniform(300, 3000)),
                   position=[rng.uniform(-half + 0.1, half - 0.1), rng.uniform(-half + 0.1, half - 0.1),
                             rng.uniform(0.2, top)], orientation=(q / np.linalg.norm(q)).tolist(), material="wood")


def test_two_hundred_body_pile_in_a_box_of_walls_settles():
    rng = np.random.default_rng(0)
    w = _ground()
    _walls(w, 0.6)
    _pile(w, 200, 0.6, rng, 2.5)
    r = Run(w, 10.0).report("200-body mixed pile")
    assert r.max_speed < np.sqrt(2 * G * 2.6) + 0.5        # nothing faster than a fall from the top
    assert r.max_energy <= r.e0 + 1e-6 * abs(r.e0)
    assert np.linalg.norm(w.s.vel[r.dyn], axis=1).max() < 0.2   # settled after ten seconds


def test_jammed_overlapping_boxes_separate_without_exploding():
    rng = np.random.default_rng(1)
    w = _ground()
    for i in range(10):
        w.add_body(f"box{i}", cs.Box([0.2] * 3), mass=1.0, position=(rng.uniform(-0.05, 0.05, 3) + [0, 0, 0.1]).tolist(),
                   material="wood")
    r = Run(w, 10.0).report("10 jammed overlapping boxes")
    assert r.max_speed < 5.0 and r.max_energy <= r.e0 + 1e-6 * abs(r.e0)
    c = w.detect()
    assert c.depth.max() < 1e-3                            # separated
    assert np.linalg.norm(w.s.vel[r.dyn], axis=1).max() < 1e-2


@pytest.mark.parametrize("support", ["concave mesh", "flat terrain mesh"])
def test_box_rests_on_a_mesh_for_ten_seconds(support):
    w = cs.World(settings=cs.Settings(dt=1 / 60), materials={"wood": cs.Material(restitution=0.0, friction=0.6)})
    if support == "concave mesh":
        m = trimesh.load(os.path.join(REPO, "config", "meshes", "l_step.obj"), force="mesh", process=False)
        w.add_body("support", cs.TriMesh(m.vertices, m.faces), kind="static", material="wood")
        top = 0.5                                         # the L-step's lower tread: x in [0, 1], z = 0.5
        xy = [0.55, 0.0]
    else:
        w.add_body("support", flat_tile_mesh(2.0, 4), kind="static", material="wood")
        top, xy = 0.0, [0.3, 0.1]
    w.add_body("box", cs.Box([0.2] * 3), mass=1.0, position=[xy[0], xy[1], top + 0.1], material="wood")
    r = Run(w, 10.0).report(f"box on a {support}")
    assert r.drift() < 1e-6 and r.max_pen < 1e-3 and r.max_speed < 1e-3


@pytest.mark.parametrize("stiffness", [0.0, 1e5], ids=["rigid", "compliant"])
@pytest.mark.parametrize("seed", [2, 3, 4, 5, 6, 7, 8, 9])
def test_kinematic_paddle_sweeps_through_a_pile(seed, stiffness):
    # rigid kinematic contacts (kinematic_stiffness 0): seeds 3-5 threw bodies out at 41-180 m/s
    # before the push cap (energy.push_cap_kernel), and seed 6 threw one 2.7 m up before the correction
    # cap (correction.plan): a body squeezed between the paddle and a wall, or a chain ending at
    # one, has no impulse that holds every contact, and Gauss-Seidel's impulses grew with every
    # sweep. Compliant ones (the default): the same energy bound, the paddle's work counted where its
    # poses compress the springs at once too (energy.pose_work: 5.9 J above it without), and the
    # speed bound plus what the springs hold (below)
    rng = np.random.default_rng(seed)
    w = _ground()
    w.settings.kinematic_stiffness = stiffness
    _walls(w, 0.6)
    _pile(w, 40, 0.6, rng, 1.0)
    w.add_body("paddle", cs.Box([0.05, 1.0, 0.3]), kind="kinematic", position=[-0.5, 0, 0.15], material="wood")
    dt = w.settings.dt
    speed = 0.5                                           # m/s, across and back, twice


    t = [0.0]

    def drive(world):
        t[0] += dt
        x = -0.5 + speed * ((t[0] % 4.0) if (t[0] % 4.0) < 2.0 else 4.0 - (t[0] % 4.0))
        world.set_pose("paddle", [x, 0, 0.15], [0, 0, 0, 1], t[0])

    real_step = w.step
    release = [0.0]   # compliant: the fastest the springs a body is held in can throw it, √(2E/m)

    def stepped(dt_=None):
        drive(w)
        real_step(dt_)
        if stiffness:
            release[0] = max(release[0], _spring_release_speed(w))

    w.step = stepped
    kind = "rigid" if stiffness == 0 else f"compliant {stiffness:g} N/m"
    r = Run(w, 10.0).report(f"kinematic paddle ({kind}) through a 40-body pile (seed {seed})")
    # nothing faster than a fall from the top and a push (2u), plus, where the paddle is compliant,
    # what its springs hold: a body jammed against a wall compresses the paddle's spring by up to
    # 13 cm (the gap the paddle leaves is narrower than the body), and that spring gives back up to
    # ½kd² when the jam slips: a spring obeys its law, the push cap is the rigid contacts' answer to
    # a squeeze (response.resting). Its cap once came from the paddle's contact with the floor,
    # counted as a push (energy.push_speed): it held the springs of a still link to nothing. The
    # energy bound below is the tight one
    if stiffness:
        print(f"  springs' release speed at most {release[0]:.3g} m/s")
    assert r.max_speed < np.sqrt(2 * G * 1.1) + 2 * speed + 0.5 + release[0]
    assert r.max_energy <= r.e0 + 1e-6 * abs(r.e0)
