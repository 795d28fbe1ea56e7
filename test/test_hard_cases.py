"""Numerical-stability hard cases (issue 6). Run alone with ``pytest -m hard``.

Every assertion is a physical threshold from the issue: stacks and resting contact hold still,
mass ratios do not sink, deep overlaps separate without exploding, degenerate contact geometry
gives finite results and normals that do not flip, the same stack behaves the same at 1 mm and
100 m, thin and fast bodies do not tunnel with continuous time of impact, and elastic bouncing
keeps its energy.
"""
import os
import warnings

import numpy as np
import pytest
import yaml

import contact_sim as cs
from contact_sim.response import MassRatioWarning, TunnellingWarning

pytestmark = pytest.mark.hard

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")
G = 9.81


def _scene(name):
    with open(os.path.join(SCENES, name + ".yaml")) as fh:
        return yaml.safe_load(fh)


def _box(name, size, pos, mass=1.0, q=(0, 0, 0, 1), material="wood", kind="dynamic", **kw):
    d = {"name": name, "kind": kind, "shape": {"type": "box", "size": list(map(float, size))},
         "position": list(map(float, pos)), "orientation": list(map(float, q)), "material": material}
    if kind == "dynamic":
        d["mass"] = mass
    d.update(kw)
    return d


def _world(bodies, dt=1 / 60, friction=0.5, restitution=0.0, gravity=(0, 0, -G), **settings):
    st = {"dt": dt, "response": "impulse", "friction": friction > 0, "resting": True}
    st.update(settings)
    return cs.load_scene({"gravity": list(gravity), "settings": st,
                          "materials": {"wood": {"restitution": restitution, "friction": friction}},
                          "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"},
                                      "material": "wood"}] + bodies})


class Recorder:
    """Steps a world and keeps the worst figures: penetration (from a fresh detection after every
    step), largest body speed, and positions."""

    def __init__(self, world):
        self.w = world
        self.dyn = np.flatnonzero(world.kind == 2)
        self.p0 = world.s.pos.copy()
        self.max_pen = 0.0
        self.max_speed = 0.0
        self.speeds = []

    def run(self, seconds):
        w = self.w
        for _ in range(int(round(seconds / w.settings.dt))):
            w.step()
            assert np.all(np.isfinite(w.s.pos)) and np.all(np.isfinite(w.s.vel))
            c = w.detect()
            if len(c):
                self.max_pen = max(self.max_pen, float(c.depth.max()))
            sp = float(np.linalg.norm(w.s.vel[self.dyn], axis=1).max())
            self.speeds.append(sp)
            self.max_speed = max(self.max_speed, sp)
        return self

    def drift(self, name):
        i = self.w.index(name)
        return float(np.linalg.norm(self.w.s.pos[i] - self.p0[i]))

    def max_drift(self):
        return float(np.linalg.norm(self.w.s.pos[self.dyn] - self.p0[self.dyn], axis=1).max())


# ---------------------------------------------------------------------------- stacks and resting
def _stack(scale=1.0, n=10, dt=1 / 60):
    s = 0.2 * scale
    bodies = [_box(f"box{i}", [s, s, s], [0, 0, s / 2 + s * i]) for i in range(n)]
    return _world(bodies, dt=dt, gravity=(0, 0, -G * scale))


def test_stack_of_ten_boxes_holds_for_ten_seconds():
    rec = Recorder(_stack()).run(10.0)
    drift = rec.drift("box9")
    print(f"HARD 10-box stack, 10 s: top drift {drift * 1e3:.3g} mm, max penetration {rec.max_pen * 1e3:.3g} mm, "
          f"max speed {rec.max_speed:.3g} m/s")
    assert drift < 1e-3
    assert rec.max_pen < 1e-3
    assert rec.max_speed < 1e-2


def test_stack_scene_file_at_its_own_step_size():
    """The shipped scene (dt 1/240) for 1 s: same thresholds."""
    rec = Recorder(cs.load_scene(os.path.join(SCENES, "box_stack.yaml"))).run(1.0)
    assert rec.drift("box9") < 1e-3 and rec.max_pen < 1e-3 and rec.max_speed < 1e-2


def test_pyramid_of_fifteen_boxes_stands():
    world = cs.load_scene(_scene("pyramid"))
    assert int(np.sum(world.kind == 2)) == 15
    rec = Recorder(world).run(10.0)
    print(f"HARD pyramid: max drift {rec.max_drift() * 1e3:.3g} mm, penetration {rec.max_pen * 1e3:.3g} mm, "
          f"max speed {rec.max_speed:.3g} m/s")
    assert rec.max_drift() < 1e-3          # no box moved a millimetre: no collapse
    assert rec.max_pen < 1e-3
    assert rec.max_speed < 1e-2


def test_box_on_plank_on_spheres_stands():
    world = cs.load_scene(_scene("plank_on_spheres"))
    rec = Recorder(world).run(10.0)
    print(f"HARD plank on spheres: max drift {rec.max_drift() * 1e3:.3g} mm, penetration {rec.max_pen * 1e3:.3g} mm")
    box, plank = world.body("box").position, world.body("plank").position
    assert abs(box[2] - 0.35) < 1e-3 and abs(plank[2] - 0.225) < 1e-3     # nothing fell or sank
    assert np.linalg.norm(box[:2] - plank[:2]) < 1e-3                      # the box stayed on the plank
    assert rec.max_drift() < 1e-3
    assert rec.max_pen < 1e-3


@pytest.mark.parametrize("ratio", [100.0, 1000.0])
def test_heavy_box_on_light_box(ratio):
    data = _scene("mass_ratio")
    data["bodies"][2]["mass"] = ratio
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        world = cs.load_scene(data)
        rec = Recorder(world).run(3.0)
    warned = [w for w in caught if issubclass(w.category, MassRatioWarning) and "heavy" in str(w.message)]
    assert bool(warned) == (ratio > world.settings.mass_ratio_limit)   # the preflight says so above the limit ...
    print(f"HARD mass ratio {ratio:g}: penetration {rec.max_pen * 1e3:.3g} mm, drift {rec.max_drift() * 1e3:.3g} mm")
    assert rec.max_pen < 1e-3                               # ... and it still holds
    assert rec.max_drift() < 1e-3
    assert abs(world.body("light").position[2] - 0.1) < 1e-3
    assert abs(world.body("heavy").position[2] - 0.3) < 1e-3


def test_deep_initial_overlap_separates_without_exploding():
    world = cs.load_scene(_scene("deep_overlap"))
    dyn = np.flatnonzero(world.kind == 2)
    m = world.mass[dyn]

    def kinetic():
        v, w = world.s.vel[dyn], world.s.omega[dyn]
        rot = 0.5 * np.sum(np.einsum("ij,ijk,ik->i", w, world.inertia_body[dyn], w))   # cubes: isotropic
        return 0.5 * np.sum(m * np.einsum("ij,ij->i", v, v)) + rot

    k0 = kinetic()
    z_top = world.s.pos[dyn, 2].copy()
    worst_speed, worst_excess = 0.0, -np.inf
    for _ in range(180):   # 3 s
        world.step()
        assert np.all(np.isfinite(world.s.pos))
        z = world.s.pos[dyn, 2]
        z_top = np.maximum(z_top, z)
        # the most work gravity can have done: every body falling from the highest point it reached
        work = float(np.sum(m * G * (z_top - z)))
        worst_excess = max(worst_excess, kinetic() - (k0 + work))
        worst_speed = max(worst_speed, float(np.linalg.norm(world.s.vel[dyn], axis=1).max()))
    c = world.detect()
    print(f"HARD deep overlap: max speed {worst_speed:.3g} m/s, final penetration {c.depth.max() * 1e3:.3g} mm, "
          f"kinetic energy minus (initial + gravity work) at most {worst_excess:.3g} J")
    assert c.depth.max() < 1e-3                                          # separated
    assert world.body("upper").position[2] > world.body("lower").position[2] + 0.199
    assert worst_speed < 2.0
    assert worst_excess <= 1e-9


def test_resting_box_does_not_jitter_for_a_minute():
    world = _world([_box("box", [0.2, 0.2, 0.2], [0, 0, 0.1 + 1e-3])])   # dropped from 1 mm
    rec = Recorder(world).run(60.0)
    late = np.array(rec.speeds[int(round(1.0 / world.settings.dt)):])
    om = float(np.linalg.norm(world.s.omega[1]))
    print(f"HARD resting box: speed after 1 s at most {late.max():.3g} m/s, final angular speed {om:.3g} rad/s")
    assert late.max() < 1e-4
    assert om * 0.1 < 1e-4


# ---------------------------------------------------------------------------- degenerate geometry
def _normals_stable(world, seconds):
    """Steps ``world``; per pair, the mean contact normal of consecutive steps must not flip
    (cosine > 0.5). Returns the smallest cosine seen (1 when no pair persisted)."""
    prev = {}
    worst = 1.0
    for _ in range(int(round(seconds / world.settings.dt))):
        world.step()
        c = world.contacts
        assert np.all(np.isfinite(world.s.pos)) and np.all(np.isfinite(world.s.vel))
        assert np.all(np.isfinite(c.normal)) and np.all(np.isfinite(c.impulse)) and np.all(np.isfinite(c.depth))
        cur = {}
        for key in set(zip(c.body_a.tolist(), c.body_b.tolist())):
            sel = (c.body_a == key[0]) & (c.body_b == key[1])
            n = c.normal[sel].mean(axis=0)
            cur[key] = n / np.linalg.norm(n)
        for key, n in cur.items():
            if key in prev:
                worst = min(worst, float(n @ prev[key]))
        prev = cur
    return worst


S45 = np.sin(np.pi / 8), np.cos(np.pi / 8)   # half-angle of 45°


@pytest.mark.parametrize("case", ["parallel_edges", "coplanar_faces", "vertex_on_face", "sphere_tangent"])
def test_degenerate_contact_geometry(case):
    if case == "parallel_edges":       # an edge of the upper box exactly on an edge of the lower one
        h = 0.1 * np.sqrt(2)
        q = [S45[0], 0, 0, S45[1]]     # 45° about x: edges along x point down and up
        bodies = [_box("lower", [0.2, 0.2, 0.2], [0, 0, h], q=q, kind="static"),
                  _box("upper", [0.2, 0.2, 0.2], [0, 0, 3 * h], q=q)]
    elif case == "coplanar_faces":     # two boxes side by side, faces flush, on the ground
        bodies = [_box("left", [0.2, 0.2, 0.2], [-0.1, 0, 0.1]), _box("right", [0.2, 0.2, 0.2], [0.1, 0, 0.1])]
    elif case == "vertex_on_face":     # a cube standing on one vertex, exactly on the top face of another
        axis = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
        ang = np.arccos(1 / np.sqrt(3))          # body diagonal (1,1,1) to vertical
        q = list(axis * np.sin(ang / 2)) + [np.cos(ang / 2)]
        bodies = [_box("base", [0.4, 0.4, 0.2], [0, 0, 0.1], kind="static"),
                  _box("tip", [0.2, 0.2, 0.2], [0, 0, 0.2 + 0.1 * np.sqrt(3)], q=q)]
    else:                              # a ball exactly tangent to a box's top face
        bodies = [_box("base", [0.4, 0.4, 0.2], [0, 0, 0.1], kind="static"),
                  {"name": "ball", "shape": {"type": "sphere", "radius": 0.1}, "mass": 1.0,
                   "position": [0, 0, 0.3], "material": "wood"}]
    world = _world(bodies, dt=1 / 240)
    c0 = world.detect()
    assert len(c0) and np.all(np.abs(c0.depth) < 1e-9)          # really exactly touching
    worst = _normals_stable(world, 0.5)
    print(f"HARD {case}: smallest cosine between consecutive normals {worst:.6f}")
    assert worst > 0.5
    if case in ("coplanar_faces", "sphere_tangent"):            # these are at rest: nothing moves
        assert np.linalg.norm(world.s.vel[world.kind == 2], axis=1).max() < 1e-6


# ---------------------------------------------------------------------------- scale
@pytest.mark.parametrize("scale", [0.005, 500.0])   # 1 mm and 100 m boxes (reference 20 cm)
def test_stack_same_at_every_scale(scale):
    """Lengths × s, gravity × s, same step: the motion is the reference motion scaled by s, so the
    relative drift and penetration must meet the reference thresholds (1 mm / 20 cm)."""
    runs = {}
    for s in (1.0, scale):
        rec = Recorder(_stack(scale=s)).run(2.0)
        runs[s] = (rec.drift("box9") / (0.2 * s), rec.max_pen / (0.2 * s), rec.max_speed / s)
    print(f"HARD scale {scale:g}: relative drift/penetration/speed {runs[scale]}, reference {runs[1.0]}")
    for s, (drift, pen, speed) in runs.items():
        assert drift < 5e-3 and pen < 5e-3 and speed < 5e-2
    assert abs(runs[scale][0] - runs[1.0][0]) < 1e-4 and abs(runs[scale][1] - runs[1.0][1]) < 1e-4


# ---------------------------------------------------------------------------- fast and thin
@pytest.mark.parametrize("toi", ["swept", "fractional"])
def test_fast_small_sphere_does_not_pass_thin_wall(toi):
    world = cs.load_scene(os.path.join(SCENES, "tunnelling.yaml"))
    world.settings.toi = toi
    back = 0.5 + 0.005
    xs = []
    for _ in range(12):
        world.step()
        xs.append(world.body("bullet").position[0])
    assert max(xs) + 0.005 <= 0.5 - 0.005 + 1e-9     # the sphere's front never got past the wall's front
    assert max(xs) < back
    assert world.body("bullet").velocity[0] < 0


def _plate(toi):
    data = _scene("thin_plate")
    data["settings"]["toi"] = toi
    world = cs.load_scene(data)
    low = []
    for _ in range(30):
        world.step()
        verts = world.body("plate").position + cs.quat.rotate(world.body("plate").orientation,
                                                                world.shapes[1].vertices)
        low.append(verts[:, 2].min())
    return world, np.array(low)


@pytest.mark.parametrize("toi", ["fractional", "swept"])
def test_thin_plate_edge_first_does_not_tunnel(toi):
    world, low = _plate(toi)
    print(f"HARD thin plate ({toi}): lowest point {low.min() * 1e3:.4g} mm (slab top at 5 mm)")
    assert low.min() > 0.005 - 1e-3          # never through the slab's top face (1 mm tolerance)
    assert world.body("plate").velocity[2] > -20.0 * 0.5   # it was stopped


def test_thin_plate_tunnels_without_continuous_detection():
    """The same scene with next_step passes through (what the continuous options prevent), and the
    preflight warned."""
    with pytest.warns(TunnellingWarning, match="plate"):
        world, low = _plate("next_step")
    assert low.min() < -0.005


# ---------------------------------------------------------------------------- long-run energy
def _ball(e):
    data = _scene("bouncing_ball")
    data["materials"]["rubber"]["restitution"] = e
    return cs.load_scene(data)


def test_elastic_bouncing_keeps_energy_for_a_minute():
    world = _ball(1.0)
    e0 = world.energy()
    worst = 0.0
    bounces = 0
    prev_vz = 0.0
    for _ in range(3600):   # 60 s
        world.step()
        worst = max(worst, abs(world.energy() - e0) / abs(e0))
        vz = world.body("ball").velocity[2]
        bounces += prev_vz < 0 < vz
        prev_vz = vz
    print(f"HARD e = 1, 60 s, {bounces} bounces: largest relative energy change {worst:.3g}")
    assert bounces >= 60
    assert worst < 1e-9


def test_inelastic_bouncing_never_gains_energy():
    world = _ball(0.8)
    e_prev = world.energy()
    scale = abs(e_prev)
    worst = -np.inf
    for _ in range(3600):   # 60 s: bouncing, then resting
        world.step()
        e = world.energy()
        worst = max(worst, e - e_prev)
        e_prev = e
    print(f"HARD e = 0.8, 60 s: largest energy increase in a step {worst:.3g} J (of {scale:.3g} J)")
    assert worst <= 1e-12 * scale
