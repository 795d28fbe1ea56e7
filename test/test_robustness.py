"""Scenes users make (issue 10): each was reproduced on the engine before its fix.

Every assertion is a physical expectation with its own tolerance: finite state, no energy
created, resting bodies at rest, exact normals and depths.
"""
import warnings

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

import contact_sim as cs
from contact_sim.response import PenaltyStiffnessWarning
from scenegen import flat_tile_mesh

G = 9.81


def _finite(world):
    s = world.s
    return all(np.isfinite(a).all() for a in (s.pos, s.vel, s.quat, s.omega))


def excess_energy(world, dt=None):
    """Step ``world`` and return how much its energy grew beyond what the step may add: the
    potential energy of position correction, the work of kinematic bodies, and the bounded
    oscillation of a tumbling body's rotational energy under the splitting integrator (each
    measured by the step, ``last_solve``)."""
    e = world.energy()
    world.step(dt)
    ls = world.last_solve
    return world.energy() - e - ls["correction_energy"] - ls["kinematic_work"] - ls["rotation_drift"]


def _ground_world(dt=0.01, **settings):
    w = cs.World(settings=cs.Settings(dt=dt, **settings))
    w.add_body("ground", cs.Plane(), kind="static")
    return w


# ---------------------------------------------------------------- infinite-mass pairs
@pytest.mark.parametrize("floor", ["static plane", "static box", "kinematic box"])
def test_kinematic_body_pressed_into_static_geometry_stays_finite(floor):
    """A robot link (kinematic) posed 5 cm into the floor: nothing can respond to that contact, so
    it carries no impulse; it is still reported, and the rest of the world goes on normally."""
    w = cs.World()
    if floor == "static plane":
        w.add_body("floor", cs.Plane(), kind="static")
    else:
        w.add_body("floor", cs.Box([2, 2, 0.2]), kind=floor.split()[0], position=[0, 0, -0.1])
    w.add_body("link", cs.Box([0.4, 0.4, 0.1]), kind="kinematic", position=[0, 0, 0.5])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[1, 0, 0.3])
    w.set_pose("link", [0, 0, 0.0], [0, 0, 0, 1], 0.0)           # 5 cm into the floor
    for _ in range(100):
        w.step(0.01)
        assert _finite(w)
    names = w.body_names
    pairs = {tuple(sorted((names[a], names[b]))) for a, b in zip(w.contacts.body_a, w.contacts.body_b)}
    assert ("floor", "link") in pairs                                # reported ...
    inert = [i for i, (a, b) in enumerate(zip(w.contacts.body_a, w.contacts.body_b))
             if {names[a], names[b]} == {"floor", "link"}]
    assert np.all(w.contacts.impulse[inert] == 0)                    # ... with no impulse
    # the ball rests on the floor; a kinematic floor is compliant by default: it sinks m g / k
    sink = 9.81 / w.settings.kinematic_stiffness if floor == "kinematic box" else 0.0
    assert abs(w.body("ball").position[2] - (0.1 - sink)) < 1e-9
    assert np.all(w.body("floor").position == ([0, 0, 0] if floor == "static plane" else [0, 0, -0.1]))


# ---------------------------------------------------------------- the friction solve
@pytest.mark.parametrize("n", [13, 20])
def test_tall_stack_of_cubes_holds(n):
    """A stack of n identical cubes on a plane (exploded on its 4th step at 13 cubes: the active set
    grew one layer per round and ran out of rounds; Gauss–Seidel was then warm-started from the
    unfinished answer)."""
    w = _ground_world()
    for i in range(n):
        w.add_body(f"b{i}", cs.Box([0.2] * 3), mass=1.0, position=[0, 0, 0.1 + 0.2 * i])
    e0 = w.energy()
    p0 = w.s.pos.copy()
    for _ in range(100):
        w.step()
        assert w.energy() <= e0 + 1e-9 * abs(e0)
    assert np.abs(w.s.pos - p0).max() < 1e-9
    assert np.abs(w.s.vel).max() < 1e-9


def test_sphere_wedged_between_ground_wall_and_sphere_keeps_its_energy():
    w = _ground_world()
    w.add_body("wall", cs.Plane([1, 0, 0], 0.0), kind="static")
    w.add_body("small", cs.Sphere(0.093), density=1000, position=[0.093, 0, 0.093])
    w.add_body("big", cs.Sphere(0.14), density=1000, position=[0.093 * 2 + 0.14, 0, 0.14])
    e0 = w.energy()
    for _ in range(200):
        w.step()
        assert _finite(w) and w.energy() <= e0 + 1e-9 * abs(e0)


def test_convex_hull_dropped_into_a_plane_corner_settles():
    rng = np.random.default_rng(0)
    w = _ground_world(toi="next_step")
    w.add_body("wall", cs.Plane([1, 0, 0], 0.0), kind="static")
    w.add_body("hull", cs.Convex(rng.normal(size=(20, 3)) * 0.1), density=1000, position=[0.35, 0, 0.4],
               velocity=[-1.5, 0, 0], angular_velocity=[1, 2, 3])
    e0 = w.energy()
    for _ in range(300):
        w.step()
        assert _finite(w) and w.energy() <= e0 + 1e-9 * abs(e0)
    assert np.linalg.norm(w.s.vel[2]) < 1e-3


# ---------------------------------------------------------------- meshes
def _mesh_floor(subdivide=0):
    m = trimesh.creation.box([2, 2, 0.2])
    for _ in range(subdivide):
        m = m.subdivide()
    return cs.TriMesh(m.vertices, m.faces)


@pytest.mark.parametrize("subdivide", [0, 2])
def test_box_touching_a_mesh_gets_the_face_normal(subdivide):
    mesh = _mesh_floor(subdivide)
    for xy in ([0.3, 0.2], [0.0, 0.0], [-0.61, 0.37]):
        c = cs.collide(mesh, ([0, 0, -0.1], [0, 0, 0, 1]), cs.Box([0.2] * 3), ([*xy, 0.1], [0, 0, 0, 1]),
                       margin=1e-4)
        assert len(c) >= 3
        np.testing.assert_allclose(c.normal, np.tile([0.0, 0.0, -1.0], (len(c), 1)), atol=1e-12)
        assert np.abs(c.depth).max() < 1e-12


@pytest.mark.parametrize("xy", [[0.0, 0.0], [0.3, 0.2], [0.55, -0.3]])
def test_cube_dropped_onto_a_mesh_comes_to_rest_without_gaining_energy(xy):
    w = cs.World(settings=cs.Settings(dt=1 / 60))
    w.add_body("floor", _mesh_floor(2), kind="static", position=[0, 0, -0.1])
    w.add_body("cube", cs.Box([0.2] * 3), mass=1.0, position=[xy[0], xy[1], 0.11])
    worst = max(excess_energy(w) for _ in range(120))
    assert worst <= 1e-9
    b = w.body("cube")
    assert abs(b.position[2] - 0.1) < 1e-6 and np.linalg.norm(b.velocity) < 1e-6
    np.testing.assert_allclose(b.position[:2], xy, atol=1e-6)


def test_flat_open_mesh_collides_as_a_one_sided_surface():
    tile = flat_tile_mesh(2.0, 4)
    c = cs.collide(tile, ([0, 0, 0], [0, 0, 0, 1]), cs.Sphere(0.1), ([0.3, 0.1, 0.05], [0, 0, 0, 1]))
    assert len(c) == 1
    np.testing.assert_allclose(c.depth, [0.05], rtol=1e-12)
    np.testing.assert_allclose(c.normal, [[0, 0, -1]], atol=1e-12)   # B (sphere) → A (tile): down
    c = cs.collide(tile, ([0, 0, 0], [0, 0, 0, 1]), cs.Box([0.2] * 3), ([0.3, 0.1, 0.09], [0, 0, 0, 1]))
    assert len(c) == 4
    np.testing.assert_allclose(c.depth, 0.01, rtol=1e-9)
    np.testing.assert_allclose(c.normal, np.tile([0, 0, -1.0], (4, 1)), atol=1e-12)


@pytest.mark.parametrize("shape", [cs.Sphere(0.1), cs.Box([0.2] * 3)])
def test_bodies_rest_on_a_flat_terrain_mesh(shape):
    w = cs.World(settings=cs.Settings(dt=1 / 60))
    w.add_body("terrain", flat_tile_mesh(2.0, 4), kind="static")
    w.add_body("body", shape, mass=1.0, position=[0.3, 0.1, 0.5])
    for _ in range(120):
        w.step()
        assert _finite(w)
    b = w.body("body")
    assert abs(b.position[2] - 0.1) < 1e-6 and np.linalg.norm(b.velocity) < 1e-6


# ---------------------------------------------------------------- scale ratio
def _sat_depth(shape_a, pos_a, R_a, shape_b):
    """Penetration depth by brute force over every separating axis candidate of two convex bodies
    (face normals of both, every edge of A crossed with B's box axes): B is an axis-aligned box."""
    va = shape_a.vertices @ R_a.T + pos_a
    dirs = list(np.eye(3)) + list(shape_a.plane_normals @ R_a.T)
    ea = (shape_a.vertices[shape_a.edges[:, 1]] - shape_a.vertices[shape_a.edges[:, 0]]) @ R_a.T
    dirs += [np.cross(e, ax) for e in ea for ax in np.eye(3)]
    best = np.inf
    for d in dirs:
        n = np.linalg.norm(d)
        if n < 1e-12 * np.abs(ea).max():
            continue
        d = d / n
        a, b = va @ d, shape_b.vertices @ d
        best = min(best, a.max() - b.min(), b.max() - a.min())
    return best


@pytest.mark.parametrize("kind", ["box", "hull"])
def test_millimetre_body_against_kilometre_box_gets_the_exact_depth(kind):
    """Tolerances are relative to the smaller body: 1e-9 of a kilometre would be a micrometre,
    a third of these penetrations."""
    rng = np.random.default_rng(7)
    big = cs.Box([1e3] * 3)
    checked = 0
    for _ in range(60):
        small = cs.Box([1e-3] * 3) if kind == "box" else cs.Convex(rng.normal(size=(10, 3)) * 5e-4)
        q = Rotation.random(random_state=int(rng.integers(1 << 30))).as_quat()
        pos = np.array([500 - rng.uniform(-5e-4, 5e-4), rng.uniform(-1, 1), 500 - rng.uniform(-5e-4, 5e-4)])
        exact = _sat_depth(small, pos, Rotation.from_quat(q).as_matrix(), big)
        c = cs.collide(small, (pos, q), big, ([0, 0, 0], [0, 0, 0, 1]))
        if exact <= 1e-9:
            continue
        checked += 1
        assert len(c) and abs(c.depth.max() - exact) <= 1e-7 * exact
    assert checked > 20


def test_no_warnings_on_the_repro_scenes():
    """The repro scenes above step without runtime warnings (an invalid value in a matmul was the
    first sign of the NaN world)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        test_kinematic_body_pressed_into_static_geometry_stays_finite("static plane")


# ---------------------------------------------------------------- the invariant guard
def test_a_step_that_would_leave_a_non_finite_state_is_undone_and_names_the_bodies(monkeypatch):
    from contact_sim import stepper

    w = _ground_world()
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 0.5])
    w.add_body("crate", cs.Box([0.2] * 3), mass=1.0, position=[1, 0, 0.1])
    w.step()
    before = w.s.copy(), w.time, w.contacts
    real = stepper.step

    def broken(world, dt, m=None):
        real(world, dt, m)
        world.s.vel[world.index("crate"), 2] = np.nan      # what a numerical failure would leave

    monkeypatch.setattr(stepper, "step", broken)
    with pytest.raises(cs.ContactSimError, match=r"1 body \('crate'\).*non-finite.*as it was before"):
        w.step()
    for name in before[0].NAMES:
        np.testing.assert_array_equal(getattr(w.s, name), getattr(before[0], name))
    assert w.time == before[1] and w.contacts is before[2]
    monkeypatch.setattr(stepper, "step", real)
    w.step()                                                  # and the world goes on
    assert _finite(w)


@pytest.mark.parametrize("response, toi", [("impulse", "next_step"), ("impulse", "fractional"), ("penalty", "auto")])
def test_a_step_writes_only_the_motion_arrays_its_undo_copies(response, toi):
    """A step (impacts, resting, a kinematic body driven by poses, a tumbling body) writes the
    ``_State.MOTION`` arrays and never the poses given (``stamp``, ``posed``, ``pose_pos``,
    ``pose_quat``, the principal frames): those are the inputs' alone."""
    w = _ground_world()
    w.settings = cs.Settings(response=response, toi=toi)
    w.add_body("paddle", cs.Box([0.05, 0.4, 0.3]), kind="kinematic", position=[-0.3, 0, 0.15])
    w.add_body("crate", cs.Box([0.3, 0.2, 0.1]), mass=1.0, position=[0, 0, 0.3], angular_velocity=[1, 5, 0.3])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0.4, 0, 0.5], velocity=[-1, 0, 0])
    moved = set()
    for i in range(120):
        w.set_pose("paddle", [-0.3 + 0.004 * i, 0, 0.15], [0, 0, 0, 1], stamp=w.time)
        before = {n: getattr(w.s, n).copy() for n in w.s.NAMES}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PenaltyStiffnessWarning)   # the default spring at this dt
            w.step()
        for n in w.s.NAMES:
            if not np.array_equal(getattr(w.s, n), before[n], equal_nan=True):
                moved.add(n)
    assert moved == set(w.s.MOTION)   # not vacuous: the step did move every motion array


# ---------------------------------------------------------------- penalty defaults
@pytest.mark.parametrize("shape, points", [(cs.Box([0.2] * 3), 4), (cs.Sphere(0.1), 1)])
def test_penalty_defaults_rest_stably_at_mg_over_k(shape, points):
    """Default stiffness and damping, default dt: the spring is integrated implicitly, so it is
    stable (the explicit one sent a resting cube to z = 984 m) and still rests at k·depth = m g per
    contact point."""
    w = cs.World(settings=cs.Settings(response="penalty"))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("b", shape, mass=1.0, position=[0, 0, 0.1])
    e0 = w.energy()
    with warnings.catch_warnings():
        # the stiffness warning says the spring's oscillation is not resolved at this dt (so it rests
        # without bouncing); it is no longer a sign of instability
        warnings.simplefilter("ignore", PenaltyStiffnessWarning)
        for _ in range(300):
            w.step()
            assert w.energy() <= e0 + 1e-12 and w.s.pos[1, 2] <= 0.1
    k = w.settings.penalty.stiffness
    np.testing.assert_allclose(0.1 - w.s.pos[1, 2], G / (points * k), rtol=1e-9)
    np.testing.assert_allclose(w.contacts.normal_impulse.sum(), G * w.settings.dt, rtol=1e-9)


def test_penalty_is_stable_at_any_stiffness():
    w = cs.World(settings=cs.Settings(response="penalty", penalty={"stiffness": 1e12, "damping": 0.0}))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("b", cs.Box([0.2] * 3), mass=1.0, position=[0, 0, 0.15], velocity=[0, 0, -2.0])
    e0 = w.energy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")       # the stiffness warning: not resolved, still stable
        for _ in range(300):
            w.step()
            assert w.energy() <= e0 + 1e-9
    assert abs(w.s.pos[1, 2] - 0.1) < 1e-6 and np.linalg.norm(w.s.vel[1]) < 1e-6


# ---------------------------------------------------------------- kinematic response
def test_kinematic_response_of_a_spinning_box_never_gains_energy():
    """The lecture's v ← v − (1+k)(N·v)N acts on the centre's velocity: spin is neither seen nor
    changed (counting the contact point's spin velocity took 202.6 J to 1200 J)."""
    w = cs.World(settings=cs.Settings(dt=1 / 120, response="kinematic"),
                 materials={"m": cs.Material(restitution=1.0, friction=0.0)})
    w.add_body("ground", cs.Plane(), kind="static", material="m")
    w.add_body("box", cs.Box([0.4, 0.2, 0.1]), mass=1.0, position=[0, 0, 1.0], angular_velocity=[3, 7, 5],
               material="m")
    worst = max(excess_energy(w) for _ in range(600))
    assert worst <= 1e-9
    assert w.last_solve["response"] == "kinematic"


# ---------------------------------------------------------------- time of impact: bounded cost
def test_one_fast_sphere_among_thousands_tests_only_its_neighbours():
    from contact_sim.response import toi

    w = _ground_world(dt=1 / 60)
    side = 40
    for i in range(side * side):
        w.add_body(f"s{i}", cs.Sphere(0.05), mass=0.1, position=[0.12 * (i % side), 0.12 * (i // side), 0.05])
    w.add_body("fast", cs.Sphere(0.05), mass=0.1, position=[-1, 2.4, 0.3], velocity=[30, 0, 0])
    w.step()
    m = toi.Motion(w, np.where((w.kind == 2)[:, None], w.gravity, 0.0), w.kind == 2)
    i, j = toi.candidate_pairs(w, m, w.settings.dt, np.zeros(0, np.int64))
    finite = (i != 0) & (j != 0)          # the ground pairs are the resting contacts (excluded by the stepper)
    assert 0 < finite.sum() <= 8 and np.all((i[finite] == w.index("fast")) | (j[finite] == w.index("fast")))
    # a big world keeps next_step; only the fast body's pairs get a time-of-impact search
    from contact_sim.response import choose

    assert w.last_solve["toi"] == "next_step" and choose(w).continuous == (w.index("fast"),)


def test_time_of_impact_search_is_bounded_for_a_fast_spinner(monkeypatch):
    from contact_sim.response import toi

    searches = []
    real_pair = toi.pair_toi

    def counted(*a, **k):
        n = toi.COUNTS["distance_evaluations"]
        out = real_pair(*a, **k)
        searches.append(toi.COUNTS["distance_evaluations"] - n)
        return out

    monkeypatch.setattr(toi, "pair_toi", counted)
    w = _ground_world(dt=1 / 60, toi="fractional")
    w.add_body("spinner", cs.Box([0.4, 0.1, 0.05]), mass=1, position=[0, 0, 0.5], angular_velocity=[0, 0, 1000])
    w.add_body("other", cs.Box([0.2] * 3), mass=1, position=[0.5, 0, 0.1])
    for _ in range(40):
        w.step()
        assert _finite(w)
    assert searches and max(searches) <= toi.MAX_ADVANCES + toi.MAX_SAMPLES + 60   # + Brent's refinement


# ---------------------------------------------------------------- free rotation: sub-steps only where needed
@pytest.mark.parametrize("shape, omega", [(cs.Box([1.0, 0.05, 0.05]), [0, 7.0, 0]),       # rod end over end
                                          (cs.Box([0.4, 0.1, 0.05]), [0, 0, 1000.0])])  # about a principal axis
def test_a_spin_with_no_split_term_takes_one_exact_sub_step(shape, omega, monkeypatch):
    from contact_sim import quat

    turns = []
    real = quat.axis_rotation
    monkeypatch.setattr(quat, "axis_rotation", lambda *a: turns.append(1) or real(*a))
    w = cs.World(gravity=[0, 0, 0], settings=cs.Settings(dt=1 / 60))
    w.add_body("b", shape, mass=1.0, angular_velocity=omega)
    n = 60
    for _ in range(n):
        w.step()
    assert len(turns) <= 3 * n                                        # one sub-step (three split turns) per step
    angle = np.linalg.norm(omega) * n / 60
    axis = np.array(omega) / np.linalg.norm(omega)
    exact = np.concatenate([axis * np.sin(angle / 2), [np.cos(angle / 2)]])
    q = w.body("b").orientation
    assert min(np.abs(q - exact).max(), np.abs(q + exact).max()) < 1e-9 * max(1.0, angle)


def test_an_empty_world_steps_and_detects_nothing():
    """No bodies yet (a node's world before its scene, a script adding bodies later): a step only
    advances time and detection finds nothing. Its geometry table has no rows, which once reached
    the narrow phase's kernels and failed there with numba's typing error."""
    w = cs.World()
    w.step(0.01)
    assert w.time == 0.01 and len(w.contacts) == 0
    assert len(w.detect()) == 0 and w.last_detection.candidate_pairs == 0
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=(0, 0, 1.0))
    w.step(0.01)   # one body: no pair either
    assert w.s.pos[0, 2] == pytest.approx(1.0 - 0.5 * 9.81 * 0.01 ** 2, rel=1e-15)


@pytest.mark.parametrize("margin", [0.0, 0.1, 1.0])
def test_a_body_wholly_behind_an_open_mesh_has_no_contact_with_it_whatever_the_margin(margin):
    """An open mesh acts on a body that straddles it; one entirely behind it has gone through. The
    broad phase pairs such a body with the surface only within the margin, so a contact there came
    and went with the margin: a box resting on the ground 0.4 m under a terrain tile was pushed up
    through the tile when a fast body elsewhere widened the step's speculative margin."""
    w = cs.World()
    w.add_body("tile", flat_tile_mesh(2.0, 4), kind="static", position=[0, 0, 0.5])
    w.add_body("box", cs.Box([0.2] * 3), mass=1.0, position=[0.3, 0.1, 0.1])          # 0.3 m under it
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[-0.5, 0.2, 0.3])           # its top 0.1 m under
    w.add_body("hull", cs.Convex(cs.Box([0.2] * 3).vertices), mass=1.0, position=[0.7, -0.4, 0.42])   # straddles
    w.add_body("rock", cs.TriMesh(*_cube_mesh(0.2)), mass=1.0, position=[-0.7, -0.4, 0.1])   # a closed mesh under it
    c, _ = cs.collision.detect_world(w, margin=margin)
    tile = w.index("tile")
    hit = {w.body_names[b] for a, b in zip(c.body_a, c.body_b) if a == tile}
    assert hit == {"hull"}, hit
    # the hull's lower face is 0.18 m behind the tile, its upper one 0.02 m in front: pushed back up
    assert np.allclose(c.depth[(c.body_a == tile) & (c.body_b == w.index("hull"))], 0.18, rtol=1e-9)


def _cube_mesh(edge):
    m = trimesh.creation.box([edge] * 3)
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def test_a_tilted_box_keeps_a_spring_at_every_corner_below_a_plane():
    """Four corners below the ground (a box on an edge, tipped): every one is a contact with its own
    depth. The manifold's reduction kept three of four (its rule picks the farthest and the widest
    triangle, and the fourth lay on their side); and of four corners inside and one apart within the
    margin it kept the apart one, dropping a corner 15 cm deep."""
    from contact_sim import quat

    box = cs.Box([0.4, 0.3, 0.06])
    q = quat.mul(quat.from_rotvec(np.array([0.0, 0.4, 0.0])), quat.from_rotvec(np.array([0.2, 0.0, 0.0])))
    corners = quat.rotate(np.tile(q, (8, 1)), box.vertices)
    for z0, margin in ((-corners[:, 2].min() - 0.15, 0.0), (-corners[:, 2].min() - 0.15, 0.1)):
        z = corners[:, 2] + z0
        c = cs.collide(box, ([0, 0, z0], q), cs.Plane(), ([0, 0, 0], [0, 0, 0, 1]), margin=margin)
        below = np.sort(-z[z < 0])
        assert len(below) == 4
        inside = np.sort(c.depth[c.depth > 0])
        np.testing.assert_allclose(inside, below, rtol=1e-12)


@pytest.mark.exact
@pytest.mark.parametrize("rotvec,dz", [
    ([0.0, 0.0, 0.0], 0.0),
    ([9.241339611395419e-10, -7.213379353501637e-10, -3.2936298844841966e-10], 2.256678568755003e-11),
    ([-1.928110643745686e-09, 2.1316318692059466e-09, 6.769134230337094e-10], -1.1370520580323492e-10),
    ([-1.1373226653371652e-09, 1.03987982277632e-09, 1.7431974752359069e-10], -6.818466031655257e-11),
    ([3e-9, 0.0, 0.0], 0.0),
    ([1e-7, -2e-7, 0.0], 1e-9),
])
def test_a_box_resting_half_over_another_keeps_the_corners_of_its_patch(rotvec, dz):
    """A box resting on a box of a pyramid's layer below, offset by 0.105 m: the patch is the
    0.095 m × 0.2 m overlap, and its four corners are the manifold at any tilt of round-off size.
    Tilted by ~1e-9 rad, some corners are inside by more than the touching tolerance and others
    outside by as much, and a corner is found twice (an incident vertex and an edge crossing, 2e-10 m
    apart): the reduction kept the deep ones and then a copy of one in place of the fourth corner,
    and a ten-layer pyramid of 55 boxes drifted 0.23 m in 10 s."""
    from contact_sim import quat

    q = quat.from_rotvec(np.array(rotvec))
    c = cs.collide(cs.Box([0.2] * 3), ([0.105, 0, 0.2 + dz], q), cs.Box([0.2] * 3), ([0, 0, 0], [0, 0, 0, 1]),
                   margin=2e-3)
    assert len(c.depth) == 4
    got = sorted(map(tuple, np.round(c.point[:, :2], 6)))
    assert got == [(0.005, -0.1), (0.005, 0.1), (0.1, -0.1), (0.1, 0.1)]
    assert np.abs(c.depth).max() < 1e-6 * 0.2


# ---------------------------------------------------------------- beside an open mesh's rim
_TILE_POSE = ([0, 0, 0], [0, 0, 0, 1])   # flat_tile_mesh(2.0): the square |x|, |y| <= 2 in z = 0, facing +z


@pytest.mark.parametrize("centre, rim", [([2.25, 0.3, -0.03], [2.0, 0.3, 0.0]),      # beyond an edge
                                         ([2.2, 2.1, -0.03], [2.0, 2.0, 0.0])])      # beyond a corner
def test_a_sphere_beside_an_open_meshs_rim_touches_the_rim_not_the_back(centre, rim):
    """A point below a flat open mesh's plane but outside its footprint is beside the sheet, not
    behind it: its nearest point is on the rim, and its distance to the sheet is its distance to the
    rim. Taken as behind, a sphere 0.25 m beyond the rim and 3 cm below its plane was reported
    0.55 m deep and pushed the wrong way (through the tile)."""
    r = 0.3
    c = cs.collide(flat_tile_mesh(2.0, 4), _TILE_POSE, cs.Sphere(r), (centre, [0, 0, 0, 1]))
    gap = np.subtract(centre, rim)
    dist = np.linalg.norm(gap)
    assert len(c) == 1
    np.testing.assert_allclose(c.depth, [r - dist], rtol=1e-12)
    np.testing.assert_allclose(c.normal, [-gap / dist], atol=1e-12)   # B (sphere) → A (tile): towards the rim


@pytest.mark.parametrize("body", ["box", "hull", "closed mesh"])
def test_a_body_beside_an_open_meshs_rim_is_apart_whatever_the_margin(body):
    """A cube 5 cm beyond the rim of a flat open mesh, straddling its plane, does not touch it: no
    contact at margin 0, and within a wide margin only separations of at least the 5 cm gap. Its
    lower corners are below the plane; taken as behind the sheet they were 0.11 m deep, a contact
    that came and went with the margin (fresh draws, seed 20261212: a penalty spring on it gave a
    box 8.5 kJ in one step)."""
    shape = {"box": cs.Box([0.2] * 3), "hull": cs.Convex(cs.Box([0.2] * 3).vertices),
             "closed mesh": cs.TriMesh(*_cube_mesh(0.2))}[body]
    tile = flat_tile_mesh(2.0, 4)
    pose = ([2.15, 0.3, 0.0], [0, 0, 0, 1])   # x from 2.05 to 2.25, z from -0.1 to 0.1
    assert len(cs.collide(tile, _TILE_POSE, shape, pose)) == 0
    c = cs.collide(tile, _TILE_POSE, shape, pose, margin=0.2)
    assert len(c) and c.depth.max() <= -0.05 + 1e-12, c.depth


@pytest.mark.parametrize("body", ["box", "hull", "closed mesh"])
@pytest.mark.parametrize("margin", [0.0, 0.05, 0.3])
def test_a_body_under_an_open_meshs_rim_has_gone_through_whatever_the_margin(body, margin):
    """A cube wholly below a flat open mesh's plane, half under the sheet and half beyond its rim,
    has gone through the sheet: no contact, at any margin. Its corners under the sheet are behind it,
    those beyond the rim beside it, none in front. Counting the corners beside the rim as in front,
    the cube was 0.2 m deep and was pushed up through the tile (fresh draws, seed 20261205: a penalty
    spring on a box under a terrain's rim gave it 36 J in one step)."""
    shape = {"box": cs.Box([0.2] * 3), "hull": cs.Convex(cs.Box([0.2] * 3).vertices),
             "closed mesh": cs.TriMesh(*_cube_mesh(0.2))}[body]
    pose = ([2.0, 0.3, -0.15], [0, 0, 0, 1])   # x from 1.9 to 2.1 across the rim at 2, z from -0.25 to -0.05
    assert len(cs.collide(flat_tile_mesh(2.0, 4), _TILE_POSE, shape, pose, margin=margin)) == 0


@pytest.mark.parametrize("body", ["box", "hull", "closed mesh"])
def test_a_body_across_an_open_meshs_rim_and_plane_is_pushed_out(body):
    """The same cube raised to straddle the plane (z from -0.05 to 0.15) has a corner in front of the
    sheet: not gone through; its corners under the sheet are 5 cm deep, pushed up along +z."""
    shape = {"box": cs.Box([0.2] * 3), "hull": cs.Convex(cs.Box([0.2] * 3).vertices),
             "closed mesh": cs.TriMesh(*_cube_mesh(0.2))}[body]
    c = cs.collide(flat_tile_mesh(2.0, 4), _TILE_POSE, shape, ([2.0, 0.3, 0.05], [0, 0, 0, 1]))
    assert len(c)
    np.testing.assert_allclose(c.depth.max(), 0.05, rtol=1e-12)
    deep = c.depth > 0.05 - 1e-12
    np.testing.assert_allclose(c.normal[deep], np.tile([0, 0, -1.0], (deep.sum(), 1)), atol=1e-12)
