"""Impulse and kinematic responses against the lecture's formulas (exact-answer tests)."""
import os
import warnings

import numpy as np
import pytest

import contact_sim as cs
from contact_sim import dynamics, quat
from contact_sim.response import MassRatioWarning, solver
from scenegen import random_contacts

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "config", "scenes")


def combined(a, b, rule):
    """The combine rules by their formulas (the reference ``settings.combine`` must meet): the
    mean, min, max, product or geometric mean, and a coefficient itself where both are equal."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    out = {"average": (a + b) / 2, "min": np.minimum(a, b), "max": np.maximum(a, b), "multiply": a * b,
           "geometric": np.sqrt(a * b)}[rule]
    return np.where(a == b, a, out)


def _scene(name):
    import yaml

    with open(os.path.join(SCENES, name)) as fh:
        return yaml.safe_load(fh)


def _momentum(world):
    d = world.kind == 2
    return np.sum(world.mass[d][:, None] * world.s.vel[d], axis=0)


@pytest.mark.parametrize("e", [1.0, 0.0, 0.6])
def test_two_spheres_head_on(e):
    data = _scene("two_spheres.yaml")
    data["materials"]["elastic"]["restitution"] = e
    world = cs.load_scene(data)
    v1, v2 = 1.5, -0.5
    p0, L0 = _momentum(world), world.angular_momentum()
    for _ in range(30):
        world.step()
    a, b = world.body("left").velocity, world.body("right").velocity
    # closed form for equal masses: v1' = ((1-e) v1 + (1+e) v2)/2, v2' = ((1+e) v1 + (1-e) v2)/2
    ea = np.array([((1 - e) * v1 + (1 + e) * v2) / 2, 0, 0])
    eb = np.array([((1 + e) * v1 + (1 - e) * v2) / 2, 0, 0])
    assert np.abs(a - ea).max() <= 1e-12 and np.abs(b - eb).max() <= 1e-12, (a, b)
    assert np.abs(_momentum(world) - p0).max() <= 1e-12
    assert np.abs(world.angular_momentum() - L0).max() <= 1e-12
    if e == 1.0:   # exchange
        assert abs(a[0] - v2) <= 1e-12 and abs(b[0] - v1) <= 1e-12


def lecture_j(e, v_rel, n, inv_ma, inv_mb, inv_ia, inv_ib, ra, rb):
    """j = -(1+e) v_rel / (1/M_A + 1/M_B + n·((I_A⁻¹(r_A×n))×r_A + (I_B⁻¹(r_B×n))×r_B))."""
    den = inv_ma + inv_mb + n @ (np.cross(inv_ia @ np.cross(ra, n), ra) + np.cross(inv_ib @ np.cross(rb, n), rb))
    return -(1 + e) * v_rel / den


def test_rod_impact_matches_lecture_formula():
    world = cs.load_scene(os.path.join(SCENES, "rod_impact.yaml"))
    i = world.index("rod")
    m, e, g = world.mass[i], 0.5, 9.81
    q0, p0, v0 = world.s.quat[i].copy(), world.s.pos[i].copy(), world.s.vel[i].copy()
    verts = quat.rotate(q0, world.shapes[i].vertices)
    low = np.argmin(verts[:, 2])
    h0 = p0[2] + verts[low, 2]
    # falls without rotating until the lowest corner touches: h0 + v0z t - g t²/2 = 0
    tc = (v0[2] + np.sqrt(v0[2] ** 2 + 2 * g * h0)) / g
    pc = p0 + v0 * tc + 0.5 * np.array([0, 0, -g]) * tc * tc
    vc = v0 + np.array([0, 0, -g]) * tc
    ra = verts[low]
    n = np.array([0.0, 0.0, 1.0])
    inv_i = dynamics.world_inverse_inertia(q0[None], world.inv_inertia_body[i][None])[0]
    v_rel = n @ vc
    j = lecture_j(e, v_rel, n, 1 / m, 0.0, inv_i, np.zeros((3, 3)), ra, np.zeros(3))
    v_plus = vc + j * n / m
    w_plus = inv_i @ np.cross(ra, j * n)
    # sanity: the formula gives the desired separation velocity
    assert abs(n @ (v_plus + np.cross(w_plus, ra)) + e * v_rel) <= 1e-12
    dt = world.settings.dt
    steps = int(np.ceil(tc / dt))
    for _ in range(steps):
        world.step()
    c = world.contacts
    assert len(c) == 1 and world.last_solve["impacts"] == 1
    assert abs(c.normal_impulse[0] - j) <= 1e-9 * abs(j)
    assert abs(c.relative_normal_velocity[0] - v_rel) <= 1e-9 * abs(v_rel)
    # after the exact impact the centre of mass flies ballistically with v+
    t = world.time - tc
    expect = pc + v_plus * t + 0.5 * np.array([0, 0, -g]) * t * t
    assert np.abs(world.s.pos[i] - expect).max() <= 1e-9
    # after the impact the rod flies freely: v exact, world angular momentum conserved (torque-free)
    t_after = world.time - tc
    v_expect = v_plus + np.array([0, 0, -g]) * t_after
    assert np.abs(world.s.vel[i] - v_expect).max() <= 1e-9 * np.linalg.norm(v_expect)
    L_expect = np.linalg.inv(inv_i) @ w_plus
    L_now = np.linalg.inv(dynamics.world_inverse_inertia(world.s.quat[i][None], world.inv_inertia_body[i][None])[0]) @ world.s.omega[i]
    assert np.abs(L_now - L_expect).max() <= 1e-9 * np.linalg.norm(L_expect)


def _random_bodies(rng, n):
    inv_mass = 1 / rng.uniform(0.5, 3, n)
    inv_i_body = np.stack([np.diag(1 / rng.uniform(0.05, 0.5, 3)) for _ in range(n)])
    q = quat.normalize(rng.normal(size=(n, 4)))
    inv_i = dynamics.world_inverse_inertia(q, inv_i_body)
    return inv_mass, inv_i, np.linalg.inv(inv_i)


def test_single_contact_solver_is_the_lecture_j_and_conserves_momentum():
    rng = np.random.default_rng(4)
    for trial in range(20):
        inv_mass, inv_i, inertia = _random_bodies(rng, 2)
        pos = rng.normal(size=(2, 3))
        vel, omega = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        point = 0.5 * (pos[0] + pos[1]) + 0.1 * rng.normal(size=3)
        a, b = np.array([0]), np.array([1])
        rows = solver.build_rows(a, b, point[None], n[None], pos, inv_mass, inv_i)
        ra, rb = point - pos[0], point - pos[1]
        v_rel = n @ (vel[0] + np.cross(omega[0], ra) - vel[1] - np.cross(omega[1], rb))
        if v_rel >= 0:
            vel[0] -= 2 * v_rel * n + 0.5 * n
            v_rel = n @ (vel[0] + np.cross(omega[0], ra) - vel[1] - np.cross(omega[1], rb))
        e = rng.uniform(0, 1)
        j = lecture_j(e, v_rel, n, inv_mass[0], inv_mass[1], inv_i[0], inv_i[1], ra, rb)
        P0 = vel[0] / inv_mass[0] + vel[1] / inv_mass[1]
        L0 = sum(inertia[k] @ omega[k] + np.cross(pos[k], vel[k] / inv_mass[k]) for k in range(2))
        v, w = vel.copy(), omega.copy()
        res = solver.solve(rows, v, w, target_n=np.array([-e * v_rel]), iterations=5, tolerance=0.0)
        assert abs(res.impulse[0, 0] - j) <= 1e-12 * abs(j)
        assert np.allclose(v[0], vel[0] + j * n * inv_mass[0], rtol=0, atol=1e-12)
        assert np.allclose(w[1], omega[1] - inv_i[1] @ np.cross(rb, j * n), rtol=0, atol=1e-12)
        P1 = v[0] / inv_mass[0] + v[1] / inv_mass[1]
        L1 = sum(inertia[k] @ w[k] + np.cross(pos[k], v[k] / inv_mass[k]) for k in range(2))
        assert np.abs(P1 - P0).max() <= 1e-12 * max(1, np.abs(P0).max())
        assert np.abs(L1 - L0).max() <= 1e-12 * max(1, np.abs(L0).max())


def test_many_contacts_momentum_conserved():
    """Simultaneous contacts with friction among dynamic bodies: total momenta unchanged."""
    rng = np.random.default_rng(7)
    nb, k = 6, 15
    inv_mass, inv_i, inertia = _random_bodies(rng, nb)
    pos, vel, omega, a, b, n, point = random_contacts(rng, nb, k)
    rows = solver.build_rows(a, b, point, n, pos, inv_mass, inv_i, vel, omega)
    P0 = (vel / inv_mass[:, None]).sum(0)
    L0 = (np.einsum("kij,kj->ki", inertia, omega) + np.cross(pos, vel / inv_mass[:, None])).sum(0)
    mu = np.full(k, 0.7)
    res = solver.solve(rows, vel, omega, target_n=np.zeros(k), mu_s=mu, mu_d=0.5 * mu, iterations=50, tolerance=0)
    assert np.all(res.impulse[:, 0] >= 0)
    assert np.all(np.linalg.norm(res.impulse[:, 1:], axis=1) <= mu * res.impulse[:, 0] + 1e-12)
    P1 = (vel / inv_mass[:, None]).sum(0)
    L1 = (np.einsum("kij,kj->ki", inertia, omega) + np.cross(pos, vel / inv_mass[:, None])).sum(0)
    assert np.abs(P1 - P0).max() <= 1e-12 * max(1, np.abs(P0).max())
    assert np.abs(L1 - L0).max() <= 1e-12 * max(1, np.abs(L0).max())


def test_gauss_seidel_stops_a_falling_column_with_the_exact_impulses():
    """Five unit masses in a column on the ground, all falling at 1 m/s: the compiled sequential
    Gauss–Seidel (solver.solve) stops every one, and the contact under body k carries the momentum
    of the n − k bodies above it, λ = (n − k)·1 N·s, converged to round-off."""
    n = 5
    pos = np.array([[0.0, 0.0, 0.5 + i] for i in range(-1, n)])     # body 0 the ground's stand-in
    inv_mass = np.r_[0.0, np.ones(n)]
    inv_i = np.zeros((n + 1, 3, 3))
    vel = np.zeros((n + 1, 3))
    vel[1:, 2] = -1.0
    omega = np.zeros((n + 1, 3))
    a, b = np.arange(1, n + 1), np.arange(0, n)
    point = np.column_stack([np.zeros(n), np.zeros(n), np.arange(n) + 0.0])
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    rows = solver.build_rows(a, b, point, normal, pos, inv_mass, inv_i, vel, omega)
    res = solver.solve(rows, vel, omega, target_n=np.zeros(n), iterations=2000, tolerance=1e-15)
    np.testing.assert_allclose(res.impulse[:, 0], n - np.arange(n), rtol=0, atol=1e-12)
    np.testing.assert_allclose(vel[1:], 0.0, rtol=0, atol=1e-12)
    assert res.residual <= 1e-15 and res.iterations < 2000


@pytest.mark.parametrize("k", [1.0, 0.8])
def test_kinematic_response_rebound_exact(k):
    scene = {
        "gravity": [0, 0, 0],
        "settings": {"dt": 1 / 60, "toi": "fractional", "response": "kinematic"},
        "materials": {"m": {"restitution": k, "friction": 0.0}},
        "bodies": [
            {"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
            {"name": "p", "kind": "dynamic", "model": "particle", "shape": {"type": "sphere", "radius": 0.05},
             "mass": 1.0, "position": [0, 0, 0.5], "velocity": [1.25, -0.5, -3.0], "material": "m"},
        ],
    }
    world = cs.load_scene(scene)
    v0 = np.array([1.25, -0.5, -3.0])
    n = np.array([0, 0, 1.0])
    expect = v0 - (1 + k) * (n @ v0) * n        # v+ = v − (1+k)(N·v)N
    for _ in range(20):
        world.step()
    v = world.body("p").velocity
    assert np.abs(v - expect).max() <= 1e-12, v
    assert abs(np.linalg.norm(v) - np.linalg.norm(expect)) <= 1e-12
    # the rebound happened at the exact time: height now is exact
    tc = (0.5 - 0.05) / 3.0
    z = 0.05 + expect[2] * (world.time - tc)
    assert abs(world.body("p").position[2] - z) <= 1e-12
    from contact_sim import stepper

    assert "kinematic" in " ".join(stepper.describe_models(world))


def test_same_material_exact_coefficients():
    from contact_sim.settings import combine as _combine

    x = np.array([0.3, 0.7, 0.1])
    for rule in ("average", "min", "max", "multiply", "geometric"):
        assert np.array_equal(_combine(x, x.copy(), rule), x)


@pytest.mark.parametrize("rule", cs.settings.COMBINE_RULES)
def test_combine_meets_the_formula_of_each_rule(rule):
    """``settings.combine`` (the kernel the step's coefficients come from) against each rule's formula."""
    from contact_sim.settings import combine

    a = np.array([0.3, 0.7, 0.1, 0.0, 1.0, 0.25])
    b = np.array([0.6, 0.2, 0.1, 0.9, 0.5, 0.81])
    np.testing.assert_array_equal(combine(a, b, rule), combined(a, b, rule))
    with pytest.raises(ValueError, match="unknown combine rule 'mean'"):
        combine(a, b, "mean")


def test_world_inverse_inertia_skips_only_isotropic_bodies_and_follows_new_bodies():
    from contact_sim.response import models, prepare

    w = cs.World()
    w.add_body("ground", cs.Plane((0, 0, 1), 0.0), kind="static")
    w.add_body("ball", cs.Sphere(0.2), mass=1.0, position=(0, 0, 1), orientation=quat.normalize([0.3, 0.1, 0.2, 0.9]))
    w.add_body("plank", cs.Box((1.0, 0.2, 0.1)), mass=2.0, position=(2, 0, 1),
               orientation=quat.normalize([0.1, -0.4, 0.2, 0.8]))
    m = models.choose(w, 0.01)

    def check():
        R = quat.to_matrix(w.s.quat)
        ref = dynamics.world_inverse_inertia(w.s.quat, w.inv_inertia_body)
        np.testing.assert_allclose(prepare.inv_inertia(w, m, R), ref, rtol=0, atol=1e-15 * np.abs(ref).max())

    check()
    w.add_body("rod", cs.Box((0.05, 0.05, 0.8)), mass=1.0, position=(4, 0, 1),
               orientation=quat.normalize([0.5, 0.1, -0.2, 0.7]))
    check()
    assert prepare.inv_inertia(w, m, quat.to_matrix(w.s.quat)).shape == (4, 3, 3)


def test_per_contact_coefficients_with_one_material_and_after_a_second_one_is_added():
    from contact_sim.response import models, prepare

    w = cs.World(materials={"rubber": cs.Material(restitution=0.9, friction=0.8, static_friction=1.0)})
    w.add_body("ground", cs.Plane((0, 0, 1), 0.0), kind="static")
    w.add_body("a", cs.Sphere(0.1), mass=1.0, position=(0, 0, 0.1))
    c = w.detect()
    m = models.choose(w, 0.01)
    e, mu_s, mu_d = prepare.coefficients(w, c, m)
    mat = w.materials["default"]
    assert np.all(e == mat.restitution) and np.all(mu_d == mat.friction) and np.all(mu_s == mat.static_friction)
    w.add_body("b", cs.Sphere(0.1), mass=1.0, position=(1, 0, 0.1), material="rubber")
    c = w.detect()
    e, mu_s, mu_d = prepare.coefficients(w, c, models.choose(w, 0.01))
    rule = w.settings.combine
    np.testing.assert_array_equal(e, combined(w.restitution[c.body_a], w.restitution[c.body_b], rule))
    assert e[list(c.body_b).index(2)] == combined(np.array([0.5]), np.array([0.9]), rule)[0] == 0.7


def _spheres_at_a_wall(toi, gap_ab, gap_wall, v, masses=(1.0, 1.0)):
    """Two spheres (radius 0.1) on the x axis, no gravity, e = 1, no friction: A moving at ``v``
    towards B, B ``gap_wall`` (m) from a static wall at x = 0 and ``gap_ab`` from A."""
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(toi=toi, dt=0.01),
                 materials={"m": cs.Material(restitution=1.0, friction=0.0)})
    w.add_body("wall", cs.Plane((1, 0, 0), 0.0), kind="static", material="m")
    xb = 0.1 + gap_wall
    w.add_body("B", cs.Sphere(0.1), mass=masses[1], position=(xb, 0, 0), material="m")
    w.add_body("A", cs.Sphere(0.1), mass=masses[0], position=(xb + 0.2 + gap_ab, 0, 0), velocity=(-v, 0, 0),
               material="m")
    return w


@pytest.mark.parametrize("toi", ["next_step", "fractional"])
@pytest.mark.parametrize("mb", [1.0, 3.0])
def test_a_rebound_that_sends_a_body_into_a_wall_is_an_impact_of_its_own(toi, mb):
    """A hits B (touching, e = 1); B then closes a 50 µm gap to the wall within the same step. That
    second impact is a round of its own (``impact.next_round``) at the speed B has after the first,
    not a landing the resting stage absorbs: the kinetic energy is kept exactly, and for equal
    masses the sequence A→B, B→wall, B→A ends with A leaving at v and B at rest."""
    v = 1.0
    w = _spheres_at_a_wall(toi, 0.0, 5e-5, v, (1.0, mb))
    e0 = w.energy()
    w.step()
    assert abs(w.energy() - e0) <= 1e-12 * e0, w.energy() - e0
    if mb == 1.0:
        assert abs(w.body("A").velocity[0] - v) <= 1e-12 and abs(w.body("B").velocity[0]) <= 1e-12, w.velocities()
    # momentum is not conserved (the wall pushed), but the wall's impulse is on B alone and along x
    c = w.contacts
    wall = (c.body_a == 0) | (c.body_b == 0)
    assert wall.any() and np.all(c.normal_impulse[wall] > 0)


@pytest.mark.parametrize("ma, mb", [(1.0, 1.0), (0.2, 5.0), (5.0, 0.2)])
def test_a_body_held_against_a_wall_sends_an_impact_straight_back(ma, mb):
    """B touches a static wall; A hits B at v (e = 1). The compression presses B into the wall, and
    the wall holds B through the restitution too (a pressed touching contact that does not bounce
    keeps v_n ≥ 0), so A leaves at −e v whatever the masses, as from the wall itself, and B stays
    at rest: nothing pushes B into the wall for the resting stage to stop (which lost energy)."""
    v = 2.0
    w = _spheres_at_a_wall("next_step", 0.0, 0.0, v, (ma, mb))
    w.step()
    assert abs(w.body("A").velocity[0] - v) <= 1e-12 * v, w.body("A").velocity
    assert np.abs(w.body("B").velocity).max() <= 1e-12, w.body("B").velocity
    assert abs(w.energy() - 0.5 * ma * v * v) <= 1e-12 * ma * v * v


def test_a_touching_chain_takes_an_impact_together():
    """Three equal balls in a row, touching, no gravity, e = 1: the first arrives at v. Contacts of one
    instant take the impact together (the resting one is pressed in the compression and held in the
    restitution), so the chain answers as one stiff body: −v/3, 2v/3, 2v/3, energy and momentum
    exact, not Newton's cradle's 0, 0, v (a sequence of separate impacts; docs/limits.md)."""
    v = 1.5
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(toi="next_step", dt=0.01),
                 materials={"m": cs.Material(restitution=1.0, friction=0.0)})
    for i in range(3):
        w.add_body(f"b{i}", cs.Sphere(0.1), mass=1.0, position=(0.2 * i, 0, 0), velocity=(v if i == 0 else 0, 0, 0),
                   material="m")
    for _ in range(5):
        w.step()
    got = w.velocities()[0][:, 0]
    assert np.abs(got - [-v / 3, 2 * v / 3, 2 * v / 3]).max() <= 1e-12, got
    assert abs(w.energy() - 0.5 * v * v) <= 1e-12 and abs(_momentum(w)[0] - v) <= 1e-12


@pytest.mark.parametrize("ratio", [100.0, 1000.0])
def test_a_light_ball_between_a_wall_and_a_heavy_one_takes_all_its_impacts_in_the_step(ratio):
    """Galperin's billiard: a heavy ball (M = ratio·m) pushes a light one, drifting off the wall, back
    against it; e = 1, no gravity. The light ball bounces between the two about π√(M/m) times (31 at
    100, 99 at 1000) within the step, each an impact round of its own; the energy is kept exactly,
    and at the end every contact separates (none left to the resting stage, which stopped the
    sequence inelastically after 8 rounds)."""
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(toi="next_step", dt=0.01),
                 materials={"m": cs.Material(restitution=1.0, friction=0.0)})
    w.add_body("wall", cs.Plane((1, 0, 0), 0.0), kind="static", material="m")
    w.add_body("light", cs.Sphere(0.1), mass=1.0, position=(0.1, 0, 0), velocity=(0.01, 0, 0), material="m")
    w.add_body("heavy", cs.Sphere(0.1), mass=ratio, position=(0.3, 0, 0), velocity=(-1.0, 0, 0), material="m")
    e0 = w.energy()
    with warnings.catch_warnings():   # the preflight's advice above a ratio of 100, as it should
        warnings.simplefilter("ignore", MassRatioWarning)
        w.step()
    assert abs(w.energy() - e0) <= 1e-12 * e0
    v = w.velocities()[0][:, 0]
    assert 0.0 <= v[1] <= v[2], v          # both leave the wall, the heavy one no slower: nothing approaches


@pytest.mark.exact
@pytest.mark.parametrize("max_speed", [3.0, 100.0])
def test_position_correction_pushes_a_squeezed_body_out_at_most_at_split_max_speed(max_speed):
    """No gravity, dt 0.01. A ball 1 m deep in a static block comes out by ``split_beta`` = 0.5 of its
    own overlap (0.5 m) in a step, however fast that is. A ball 1 cm into each of two static walls
    that close like a wedge (normals (±cos φ, sin φ, 0), φ = 0.01 rad) has no separation but along
    the wedge: ``β d / sin φ`` = 0.5 m in the step, 50 times its overlap. That is kept up to
    ``split_max_speed`` (100 m/s: 1 m in the step) and cut to it below (3 m/s: 0.03 m); the block's
    1 m overlap no longer lets every body move 1 m (a body squeezed by a paddle in a pile went 2.4 m
    up in a step). The velocities are untouched."""
    from contact_sim import quat

    dt, r, d, phi = 0.01, 0.1, 0.01, 0.01
    w = cs.World(gravity=(0, 0, 0), settings=cs.Settings(dt=dt, split_max_speed=max_speed))
    for name, sign in (("wall_1", 1.0), ("wall_2", -1.0)):
        n = np.array([sign * np.cos(phi), np.sin(phi), 0.0])     # the face towards the ball
        w.add_body(name, cs.Box([0.1, 1.0, 1.0]), kind="static", position=-(r - d + 0.05) * n,
                   orientation=quat.from_rotvec([0.0, 0.0, sign * phi]))
    w.add_body("ball", cs.Sphere(r), mass=1.0)
    w.add_body("block", cs.Box([2.0, 2.0, 2.0]), kind="static", position=[0, 20, -2])
    w.add_body("deep", cs.Sphere(2.0), mass=1.0, position=[0, 20, 0])
    w.step()
    wedge = 0.5 * d / np.sin(phi)
    moved = np.linalg.norm(w.body("ball").position)
    assert abs(moved - min(wedge, max_speed * dt)) < 1e-12
    assert abs(w.body("ball").position[1] - moved) < 1e-12            # along the wedge
    np.testing.assert_allclose(w.body("deep").position, [0, 20, 0.5], rtol=0, atol=1e-12)
    for b in ("ball", "deep"):
        np.testing.assert_array_equal(w.body(b).velocity, [0.0, 0.0, 0.0])


def _correction_column(slop, m=0.1, n=12, d=2e-3, beta=0.5, dt=1 / 240):
    """``correction.plan`` by Gauss–Seidel on a column of ``n`` point masses of ``m`` kg, each ``d``
    into the one below, the lowest into static ground, the contacts listed top down (the order it
    converges slowest in: a sweep carries the push-out one contact down). Returns ``(a, b, vp, wp,
    pen)``: each contact's bodies (top one first), the pseudo-velocities and the contacts pushed."""
    from contact_sim.response import correction

    c = np.arange(n)[::-1]                              # contact c: body c+1 on body c, top first
    a, b = (c + 1).astype(np.int64), c.astype(np.int64)
    dynamic = np.ones(n + 1, bool)
    dynamic[0] = False                                  # the ground
    ima = np.full(n, 1 / m)
    imb = np.where(dynamic[b], 1 / m, 0.0)
    dirs = np.tile(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), (n, 1, 1))
    zero = np.zeros((n, 3, 3))
    K = np.zeros((n, 3, 3))
    for x in range(3):
        K[:, x, x] = ima + imb
    vp, wp = np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    inv_mass, inv_inertia = np.where(dynamic, 1 / m, 0.0), np.zeros((n + 1, 3, 3))   # point masses
    pen, _ = correction.plan(a, b, np.full(n, d), np.zeros(n), dirs, zero, zero, zero, zero, ima, imb, K,
                             np.zeros(0, bool), dynamic, inv_mass, inv_inertia, beta, slop, dt,
                             solver.SOLVER_METHODS.index("gs"), 0, 100_000, 0.0, vp, wp)
    return a, b, vp, wp, pen


@pytest.mark.parametrize("slop", [1e-7, 1e-5])
def test_the_correction_solve_stops_at_the_same_sweep_at_any_mass(slop):
    """The correction's stopping rule is a distance (``split_slop``, m): the same column with every
    mass 1024 times larger or smaller (a power of two: the same arithmetic, impulses scaled
    exactly) stops at the same sweep, so its pseudo-velocities (m/s, which no mass scales) are the
    same bit for bit. Gauss–Seidel measures a sweep's change as a speed (m/s: ``pgs.sweeps``); a
    tolerance converted to an impulse (``split_slop / (dt · K_nn)``, N·s) and compared with that
    speed stopped the heavy column 1024 times sooner and the light one later."""
    runs = [_correction_column(slop, m=0.1 * s) for s in (2.0 ** -10, 1.0, 2.0 ** 10)]
    for a, b, vp, wp, pen in runs:
        np.testing.assert_array_equal(vp, runs[1][2])
    a, b, vp = runs[1][:3]
    err = np.abs((vp[a, 2] - vp[b, 2]) / 240 - 0.5 * 2e-3)
    assert 0.0 < err.max() <= 2 * slop * (1 + 1e-9)     # stopped before converging, within the bound


@pytest.mark.parametrize("slop", [0.0, 1e-7, 1e-5])
def test_the_correction_solve_stops_once_a_sweep_moves_no_contact_by_more_than_split_slop(slop):
    """``correction.plan`` on a column of 12 point masses (0.1 kg), each 2 mm into the one below, the
    lowest 2 mm into static ground, by Gauss–Seidel with the contacts listed top down (the order
    it converges slowest in: a sweep carries the push-out one contact down). Converged, each
    contact's push-out is ``split_beta · d / dt`` exactly, so body ``i`` moves up at ``i β d/dt``.
    The solve stops at the first sweep whose largest change moves no contact by more than
    ``split_slop`` over the step (``δ · K_nn · dt`` for an impulse change ``δ``): the rows a
    contact shares a body with (two in a column) were updated by at most that after it, so every
    contact's push-out is within ``2 · split_slop`` of its target. With ``split_slop`` 0 it runs
    to ``tolerance`` (0 here: to a fixed point of the sweep, round-off)."""
    n, m, d, beta, dt = 12, 0.1, 2e-3, 0.5, 1 / 240
    a, b, vp, wp, pen = _correction_column(slop, m, n, d, beta, dt)
    assert len(pen) == n
    push = (vp[a, 2] - vp[b, 2]) * dt                  # each contact's push-out over the step (m)
    err = np.abs(push - beta * d)
    if slop == 0.0:
        np.testing.assert_allclose(vp[:, 2], np.arange(n + 1) * beta * d / dt, rtol=1e-12, atol=0)
    else:
        assert err.max() <= 2 * slop * (1 + 1e-9)
        assert err.max() > 0.0                          # stopped before converging
    np.testing.assert_array_equal(vp[:, :2], 0.0)
    np.testing.assert_array_equal(wp, 0.0)


def _sink(quat_a, omega_a, point, normal, t, moments=(1.0, 1.0, 1.0), dw_a=(0.0, 0.0, 0.0), slop=1e-7):
    """``correction.drift_sink`` of one resting contact at ``point`` between dynamic body 0 (A:
    centred at the origin, orientation ``quat_a``, spin ``omega_a``, the resting force's spin
    change ``dw_a``, principal ``moments``) and static body 1 (B). Returns ``(sink, deepest)``."""
    from contact_sim.response import correction

    f = lambda *rows: np.array(rows, dtype=float)   # noqa: E731
    sink = np.zeros(1)
    deepest = correction.drift_sink(
        np.array([0]), np.array([1]), f(point), f(normal), np.zeros(1), np.array([True]), f([0, 0, 0], [0, 0, 0]),
        f(quat_a, [0, 0, 0, 1]), f(omega_a, [0, 0, 0]), f(dw_a, [0, 0, 0]), f([0, 0, 0, 1], [0, 0, 0, 1]),
        f(moments, [1, 1, 1]), np.array([True, False]), np.array([True, False]), np.array([1.0, np.inf]), t, slop,
        sink)
    return sink[0], deepest


@pytest.mark.parametrize("w", [3.0, -3.0, 0.5])
def test_the_drift_sink_is_the_turns_curve_beyond_its_first_order(w):
    """A cube (equal moments: the drift turns it at constant ω) turning about +y at ``w`` rad/s
    for ``t``, ``θ = w t``. A point ``r = (½, 0, ½)`` above its centre, on the side of a contact
    whose normal is +z (from B to the cube A), goes to ``z' = −½ sin θ + ½ cos θ``; its first-order
    motion is ``−½ θ``, so it curves ``½ (1 − cos θ) − ½ (θ − sin θ)`` deeper than the rows see,
    whichever way it turns (an even term and an odd one). A point below the centre, ``(½, 0, −½)``,
    curves up, toward the axis: a convex body turning at constant ω about its centre never curves
    into a plane it rests on, and nothing is counted. The resting force's half-kick ``dw/2`` is
    part of the turn: ``dw = −2ω`` leaves no turn and no curve."""
    t = 1 / 60
    th = w * t
    s, deepest = _sink([0, 0, 0, 1], [0, w, 0], [0.5, 0, 0.5], [0, 0, 1], t)
    assert s == pytest.approx(0.5 * (1 - np.cos(th)) - 0.5 * (th - np.sin(th)), rel=1e-9)
    assert deepest == s
    s, _ = _sink([0, 0, 0, 1], [0, w, 0], [0.5, 0, -0.5], [0, 0, 1], t)
    assert s == 0.0
    s, _ = _sink([0, 0, 0, 1], [0, w, 0], [0.5, 0, 0.5], [0, 0, 1], t, dw_a=[0, -2 * w, 0])
    assert s == 0.0


@pytest.mark.parametrize("dt", [1 / 60, 1 / 240])
def test_a_body_spun_flat_about_an_axis_that_is_not_principal_rests_on_the_floor(dt):
    """A skewed pyramid (its apex over a corner of its square base: no principal axis is vertical)
    spun at 2 rad/s about the vertical, flat on a frictionless floor: free motion would precess
    it, the floor keeps it flat. The velocity rows see neither the drift's curve nor the lag it
    leaves, and with the correction taking ``split_beta`` of an overlap a step it rested 1.34e-4 m
    deep at dt 1/60, beyond the contact margin (1e-4). Counted in the correction
    (``correction.drift_sink``), it rests within ``split_slop`` of the floor."""
    w = cs.World(settings=cs.Settings(dt=dt), materials={"m": cs.Material(restitution=0.0, friction=0.0)})
    w.add_body("ground", cs.Plane([0, 0, 1], 0.0), kind="static", material="m")
    w.add_body("p", cs.Convex([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.9, 0.9, 1.0]]), mass=1.0,
               position=[0, 0, 0], material="m", angular_velocity=[0, 0, 2.0])
    for _ in range(int(round(1.5 / dt))):
        w.step()
    c = w.detect()
    assert abs(w.body("p").angular_velocity[2] - 2.0) < 3e-3      # still spinning flat
    assert 0.0 <= c.depth.max() <= w.settings.split_slop
