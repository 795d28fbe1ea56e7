"""The compiled time-of-impact search (``response.advancement``): its quaternion arithmetic is the
``quat`` module's, its poses are the integrator's, its distances and times are the formulas'."""
import numpy as np
import pytest
import trimesh

import contact_sim as cs
from contact_sim import dynamics, quat
from contact_sim.response import advancement, toi

pytestmark = pytest.mark.exact


def test_quaternion_helpers_are_the_quat_modules_arithmetic():
    # the search's scalar helpers (free_motion's rotation and rotation vector, its own product)
    from contact_sim.free_motion import _qrot, _rotvec_quat

    rng = np.random.default_rng(0)
    for _ in range(500):
        a, b = rng.normal(size=4), rng.normal(size=4)
        a /= np.linalg.norm(a)
        v = rng.normal(size=3)
        r = rng.normal(size=3) * 10.0 ** rng.uniform(-7, 1)   # both sides of the series' switch at 1e-4
        assert np.array_equal(_qrot(*a, *v), quat.rotate(a, v))
        assert np.array_equal(advancement.qmul(*a, *b), quat.mul(a, b))
        assert np.array_equal(_rotvec_quat(*r), quat.from_rotvec(r))


def _tumbling_world(toi_mode="fractional"):
    w = cs.World(gravity=(0, 0, -9.81), settings={"toi": toi_mode, "dt": 1 / 60})
    w.add_body("floor", cs.Plane((0, 0, 1), 0.0), kind="static")
    w.add_body("brick", cs.Box([0.4, 0.2, 0.1]), mass=2.0, position=[0, 0, 1.0], velocity=[1.0, 0, 0],
               angular_velocity=[3.0, 0.2, 5.0])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[1.0, 0, 1.0], velocity=[-1.0, 0, 0])
    w.add_body("paddle", cs.Box([0.1, 0.5, 0.5]), kind="kinematic", position=[0, 1.5, 1.0],
               angular_velocity=[0, 0, 2.0])
    return w


def test_poses_follow_the_integrators_motion():
    # the search's pose is the step's free motion: the torque-free rotation of a tumbling brick
    # (dynamics.rotate_free) and a kinematic body's constant spin, bit for bit
    w = _tumbling_world()
    acc = np.where((w.kind == 2)[:, None], w.gravity, 0.0)
    m = toi.Motion(w, acc, w.kind == 2)
    s = w.s
    for tau in (0.0, 1e-9, 0.004, 1 / 60, 0.3):
        p, q = m.pose(1, tau)
        q_ref, _ = dynamics.rotate_free(s.quat[1:2], s.omega[1:2], s.principal_q[1:2], s.principal_moments[1:2], tau)
        assert np.array_equal(q, q_ref[0])
        assert np.array_equal(p, s.pos[1] + s.vel[1] * tau + 0.5 * acc[1] * tau * tau)
        _, qk = m.pose(3, tau)
        assert np.array_equal(qk, quat.mul(quat.from_rotvec(s.omega[3] * tau), s.quat[3]))


def test_signed_distances_are_the_formulas():
    w = _tumbling_world()
    I = np.array([0.0, 0.0, 0.0, 1.0])
    tilt = np.array([np.sin(0.3), 0.0, 0.0, np.cos(0.3)])          # 0.6 rad about x
    # sphere over the plane: height − radius
    assert toi.signed_distance(w, 2, 0, np.array([0.3, -1.0, 0.47]), I, np.zeros(3), I) == pytest.approx(0.37, abs=1e-15)
    # brick over the plane, tilted: its lowest corner
    half = np.array([0.2, 0.1, 0.05])
    low = 0.8 - (half[1] * np.sin(0.6) + half[2] * np.cos(0.6))
    assert toi.signed_distance(w, 1, 0, np.array([0, 0, 0.8]), tilt, np.zeros(3), I) == pytest.approx(low, abs=1e-15)
    # ball beside the brick's face, then off its corner edge (the brick in its own frame)
    assert toi.signed_distance(w, 2, 1, np.array([0.5, 0.0, 0.0]), I, np.zeros(3), I) == pytest.approx(0.2, abs=1e-15)
    corner = np.array([0.2 + 0.3, 0.1 + 0.4, 0.0])
    assert toi.signed_distance(w, 1, 2, np.zeros(3), I, corner, I) == pytest.approx(0.5 - 0.1, abs=1e-15)
    # two boxes (the narrow phase): brick and paddle 0.35 m apart along y, faces parallel
    gap = toi.signed_distance(w, 1, 3, np.zeros(3), I, np.array([0.0, 0.1 + 0.25 + 0.35, 0.0]), I)
    assert gap == pytest.approx(0.35, abs=1e-12)


def test_search_finds_the_closing_time_of_translating_polyhedra():
    # a hull and a box closing at 4 m/s across a 0.3 m gap, no rotation, no gravity: contact at
    # 0.075 s, found no later and within the tolerance × the smaller size
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "fractional", "dt": 1 / 60})
    hull = cs.Convex(np.array([[0.1, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, -0.1, 0], [0, 0, 0.1], [0, 0, -0.1]]))
    w.add_body("hull", hull, mass=1.0, position=[0.0, 0.0, 0.0], velocity=[2.0, 0, 0])
    w.add_body("box", cs.Box([0.2, 0.2, 0.2]), mass=1.0, position=[0.5, 0.0, 0.0], velocity=[-2.0, 0, 0])
    m = toi.Motion(w, np.zeros((2, 3)), w.kind == 2)
    n0 = toi.COUNTS["distance_evaluations"]
    t = toi.pair_toi(w, m, 0, 1, 0.2)
    assert toi.COUNTS["distance_evaluations"] > n0
    assert 0.075 - toi.TOI_TOLERANCE * 0.1 / 4.0 - 1e-15 <= t <= 0.075 + 1e-15
    assert toi.pair_toi(w, m, 0, 1, 0.07) == np.inf          # not within a shorter interval


def test_search_refines_a_spinning_approach_to_the_touching_instant():
    # the brick tumbles while falling: the time returned is where the distance crosses zero (to
    # the tolerance), and nothing touches before it (sampled densely)
    w = _tumbling_world()
    w.set_state("brick", position=[0, 0, 0.35], velocity=[0, 0, -2.0])
    acc = np.where((w.kind == 2)[:, None], w.gravity, 0.0)
    m = toi.Motion(w, acc, w.kind == 2)
    t = toi.pair_toi(w, m, 1, 0, 0.2)
    assert 0 < t < 0.2

    def d(tau):
        p, q = m.pose(1, tau)
        return toi.signed_distance(w, 1, 0, p, q, np.zeros(3), np.array([0, 0, 0, 1.0]))

    tol = toi.TOI_TOLERANCE * np.linalg.norm(w.shapes[1].vertices, axis=1).max()
    assert abs(d(t)) <= tol + 1e-12
    assert min(d(x) for x in np.linspace(0, t, 400)[:-1]) > -1e-12


def test_the_compiled_table_is_the_narrow_phase_table():
    """``pair_kernels.call`` branches on numbers: each type pair's number must reach the kernel
    ``COLLIDERS`` gives it. Every type pair's scene is detected through ``call`` (a detection) and
    by the table's own kernel called directly; the rows must be the same."""
    from contact_sim.collision import _bodies_of, pair_kernels
    from contact_sim.collision.geometry import RANK

    cube = trimesh.creation.box(extents=[0.5, 0.5, 0.5])
    tilt = np.array([0.1, 0.05, 0.0, 0.99]) / np.linalg.norm([0.1, 0.05, 0.0, 0.99])
    shapes = {"plane": cs.Plane(), "sphere": cs.Sphere(0.3), "box": cs.Box([0.5, 0.4, 0.6]),
              "convex": cs.Convex([[0, 0, 0], [0.6, 0, 0], [0, 0.6, 0], [0, 0, 0.6], [0.4, 0.4, 0.4]]),
              "cylinder": cs.Cylinder(0.25, 0.6),
              "mesh": cs.TriMesh(cube.vertices, cube.faces)}
    assert pair_kernels.KERNELS == tuple(dict.fromkeys(pair_kernels.COLLIDERS.values()))
    seen = set()
    for ta, ra in RANK.items():
        for tb, rb in RANK.items():
            if rb > ra:
                continue
            which = pair_kernels.index(ra, rb)
            if (ra, rb) == (0, 0):
                assert which == -1
                continue
            w = cs.World(gravity=[0, 0, 0])
            w.add_body("a", shapes[ta], kind="dynamic" if ta != "plane" else "static", mass=1.0,
                       position=[0.0, 0.0, 0.0], orientation=tilt)
            w.add_body("b", shapes[tb], kind="dynamic" if tb != "plane" else "static", mass=1.0,
                       position={"plane": [0, 0, 0], "convex": [-0.1, -0.1, 0.0]}.get(tb, [0.05, 0.02, 0.3]))
            if ta == tb == "plane":
                continue
            b = _bodies_of(w)
            pos, R = w.s.pos.copy(), np.array([quat.to_matrix(q) for q in w.s.quat])
            args = (*b.geom.arrays(), b.shape_of, np.array([0]), np.array([1]), pos, R, np.array([0.01]),
                    np.zeros(3, np.int64), np.empty((4, 3), np.int64), np.empty((4, 7)))
            got_i, got_f = np.empty((4, 3), np.int64), np.empty((4, 7))
            n_call = pair_kernels.call(which, *args[:-2], got_i, got_f, pair_kernels.trees(b.geom))
            kernel = pair_kernels.COLLIDERS[(ra, rb)]
            extra = tuple(pair_kernels.trees(b.geom)) if kernel is pair_kernels.KERNELS[pair_kernels.MESH_MESH] else ()
            n_direct = kernel(*args, *extra)
            assert n_call == n_direct and n_call > 0, (ta, tb)
            np.testing.assert_array_equal(got_i[:n_call], args[-2][:n_direct])
            np.testing.assert_array_equal(got_f[:n_call], args[-1][:n_direct])
            seen.add(kernel)
    assert seen == set(pair_kernels.KERNELS)   # every kernel reached through its number


@pytest.mark.parametrize("pair", ["box-box", "hull-sphere", "cylinder-box", "mesh-sphere", "mesh-hull", "mesh-mesh"])
def test_general_distances_are_collides(pair):
    # the search's distance for the pairs without a closed form is what collide() reports: minus
    # the deepest contact within a wide margin (every kernel the search can reach through the table)
    import trimesh

    rng = np.random.default_rng(4)
    tet = trimesh.creation.icosphere(subdivisions=1, radius=0.15)
    mesh = cs.TriMesh(tet.vertices, tet.faces)
    make = {"box": lambda: cs.Box([0.3, 0.2, 0.1]), "sphere": lambda: cs.Sphere(0.1),
            "hull": lambda: cs.Convex(rng.normal(size=(14, 3)) * 0.1), "cylinder": lambda: cs.Cylinder(0.1, 0.3),
            "mesh": lambda: mesh}
    a, b = pair.split("-")
    w = cs.World(gravity=(0, 0, 0))
    w.add_body("a", make[a](), mass=1.0)
    w.add_body("b", make[b](), mass=1.0, position=[0.5, 0, 0])
    for _ in range(20):
        qa, qb = rng.normal(size=4), rng.normal(size=4)
        qa, qb = qa / np.linalg.norm(qa), qb / np.linalg.norm(qb)
        pa, pb = rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.3
        got = toi.signed_distance(w, 0, 1, pa, qa, pb, qb)
        c = cs.collide(w.shapes[0], (pa, qa), w.shapes[1], (pb, qb), margin=advancement.WIDE)
        assert got == (-float(np.max(c.depth)) if len(c) else advancement.WIDE)


def test_candidate_pairs_follow_their_contract():
    # a double loop written from candidate_pairs' contract: path spheres whose boxes overlap (a
    # plane: the path reaches its half-space), a dynamic body in the pair, groups that collide,
    # relative motion, one of ``only``, not excluded
    rng = np.random.default_rng(5)
    w = cs.World(gravity=(0, 0, -9.81), settings={"toi": "fractional", "dt": 1 / 60})
    w.add_body("floor", cs.Plane((0, 0, 1), 0.0), kind="static")
    w.add_body("wall", cs.Plane((1, 0, 0), -1.0), kind="static")
    for k in range(30):
        kind = "static" if k % 7 == 3 else "dynamic"
        kw = dict(mass=1.0, velocity=rng.normal(size=3) * 3 * (k % 5 != 0),
                  angular_velocity=rng.normal(size=3) * 8 * (k % 3 != 0)) if kind == "dynamic" else {}
        shape = [cs.Sphere(0.1), cs.Box([0.3, 0.2, 0.1]), cs.Convex(rng.normal(size=(12, 3)) * 0.1)][k % 3]
        w.add_body(f"b{k}", shape, kind=kind, position=rng.uniform(-1.5, 1.5, 3) + [0, 0, 1.6],
                   group=1 if k % 4 else 2, mask=1 if k % 4 else 2 | 1, **kw)
    acc = np.where((w.kind == 2)[:, None], w.gravity, 0.0)
    m = toi.Motion(w, acc, w.kind == 2)
    n = len(w)
    T = 0.2
    ext = np.array([toi._extent(sh) for sh in w.shapes])
    mid = m.pos + 0.5 * m.vel * T + 0.125 * m.acc * T * T
    rad = ext + 0.5 * np.linalg.norm(m.vel * T + 0.5 * m.acc * T * T, axis=1) + 0.125 * np.linalg.norm(m.acc, axis=1) * T * T
    base_i, base_j = toi.candidate_pairs(w, m, T, np.zeros(0, np.int64))
    exclude = np.sort((base_i * n + base_j)[::7][:3])    # pairs that would be candidates: in contact
    assert len(exclude) == 3
    for only in (None, (4, 9)):
        want = set()
        for i in range(n):
            for j in range(i + 1, n):
                if np.isfinite(rad[i]) and np.isfinite(rad[j]):
                    near = np.all(np.abs(mid[i] - mid[j]) <= rad[i] + rad[j])
                else:
                    pl, o = (i, j) if not np.isfinite(rad[i]) else (j, i)
                    if not np.isfinite(rad[o]):
                        continue
                    sh = w.shapes[pl]
                    near = mid[o] @ sh.normal - sh.offset <= rad[o]
                dyn = w.kind[i] == 2 or w.kind[j] == 2
                groups = (w.group[i] & w.mask[j]) and (w.group[j] & w.mask[i])
                moves = np.any(m.vel[i] != m.vel[j]) or np.any(m.acc[i] != m.acc[j]) or np.any(m.omega[i]) or np.any(m.omega[j])
                chosen = only is None or i in only or j in only
                if near and dyn and groups and moves and chosen and i * n + j not in exclude:
                    want.add((i, j))
        got_i, got_j = toi.candidate_pairs(w, m, T, exclude, only=only)
        assert set(zip(got_i.tolist(), got_j.tolist())) == want and len(got_i) == len(want)
        assert len(want) > (2 if only else 20)


def _bar_on_plate(mode, spin, velocity=(0.0, 0.0, 0.0)):
    """A 0.4 × 0.02 × 0.02 m bar tilted 0.2 rad about y, its +x end's bottom edge 0.1 µm into a 1 cm
    static plate (top face z = 0), spinning about y (a principal axis: the spin stays constant)
    with no gravity, e = 1, no friction."""
    w = cs.World(gravity=(0, 0, 0), settings={"toi": mode, "dt": 1 / 60},
                 materials={"m": {"restitution": 1.0, "friction": 0.0}})
    w.add_body("plate", cs.Box([2.0, 2.0, 0.01]), kind="static", material="m", position=[0, 0, -0.005])
    th, L, t = 0.2, 0.4, 0.02
    cz = (L / 2) * np.sin(th) + (t / 2) * np.cos(th) - 1e-7
    w.add_body("bar", cs.Box([L, t, t]), mass=1.0, position=[0, 0, cz], orientation=[0, np.sin(th / 2), 0,
               np.cos(th / 2)], angular_velocity=[0, spin, 0], velocity=list(velocity), material="m")
    return w


@pytest.mark.parametrize("mode", ["fractional", "swept"])
def test_a_pair_in_contact_is_searched_for_another_corner_swinging_in(mode):
    # the bar's touching end lifts (ω_y = −40 rad/s) and its other end swings down 0.67 rad within
    # the step: the pair is in contact, so its event is the instant it is TOI_DEEPEN × the thinner
    # body's thinnest size (the plate's 1 cm: 1 mm) deeper than now, where it takes its impact.
    # Unsearched, that end went 4.9 cm into the plate within the step.
    from contact_sim.constants import TOI_DEEPEN, TOI_TOLERANCE

    w = _bar_on_plate(mode, -40.0)
    e0 = w.energy()
    w.step()
    assert w.last_solve["impacts"] == 1
    target = 1e-7 + TOI_DEEPEN * 0.01
    tol = TOI_TOLERANCE * np.linalg.norm([0.2, 0.01, 0.01])          # the search's, × the smaller extent
    assert target - tol <= w.contacts.depth.max() <= target         # the instant it is reached, never late
    assert abs(w.energy() - e0) <= 1e-12 * e0                       # e = 1: the impact keeps the energy
    assert w.s.omega[1, 1] > 0                                      # and the bar rebounds
    for _ in range(3):                                              # and flies off the plate
        w.step()
        assert w.last_solve["max_penetration"] <= 0


def test_a_pair_in_contact_that_only_translates_costs_no_search():
    # convex shapes that only translate keep their contacts' depth (the solve left them not
    # closing): no distance is evaluated for the pair in contact
    w = _bar_on_plate("fractional", 0.0, velocity=(0.5, 0.2, 0.0))   # sliding along the plate
    n0 = toi.COUNTS["distance_evaluations"]
    for _ in range(5):
        w.step()
        assert w.last_solve["impacts"] == 0
    assert toi.COUNTS["distance_evaluations"] == n0


def test_disabled_pairs_have_no_time_of_impact():
    # a pair never tested for contact has no event to split the step at
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "fractional", "dt": 1 / 60})
    w.add_body("a", cs.Box([0.1, 0.1, 0.1]), mass=1.0, position=[0, 0, 0], velocity=[12.0, 0, 0])
    w.add_body("b", cs.Box([0.1, 0.1, 0.1]), mass=1.0, position=[0.2, 0, 0])
    w.disable_collisions([("a", "b")])
    w.step()
    assert w.last_solve["impacts"] == 0 and len(w.contacts) == 0
    assert w.body("a").position[0] == 12.0 / 60                    # through b, as if it were not there


def test_a_compliant_squeeze_is_no_event():
    # two kinematic jaws closing on a cube and turning (a compliant contact: the default
    # kinematic_stiffness): the contacts' depth is their springs' deflection, which grows as the
    # jaws squeeze; no time of impact splits the step for it (it split every step while the pairs
    # in contact were searched regardless)
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "fractional", "dt": 1 / 60})
    w.add_body("cube", cs.Box([0.1, 0.1, 0.1]), mass=0.5)
    for name, side in (("left", -1.0), ("right", 1.0)):
        w.add_body(name, cs.Box([0.02, 0.1, 0.1]), kind="kinematic", position=[side * 0.059, 0, 0],
                   velocity=[-side * 0.05, 0, 0], angular_velocity=[0, -side * 2.0, 0])
    assert w.settings.kinematic_stiffness > 0
    for _ in range(30):
        w.step()
        assert w.last_solve["impacts"] == 0
    assert w.last_solve["max_penetration"] > 0.01                  # squeezed: the springs deflect


def test_a_spinning_ball_in_contact_costs_no_search():
    # a sphere's spin moves no point of its surface off it: a ball spinning on a plate (a
    # sphere–box pair, which has no closed form) keeps its depth, and is not searched
    w = cs.World(gravity=(0, 0, 0), settings={"toi": "fractional", "dt": 1 / 60})
    w.add_body("plate", cs.Box([2.0, 2.0, 0.01]), kind="static", position=[0, 0, -0.005])
    w.add_body("ball", cs.Sphere(0.05), mass=1.0, position=[0, 0, 0.05 - 1e-7], angular_velocity=[0, 0, 100.0])
    n0 = toi.COUNTS["distance_evaluations"]
    for _ in range(5):
        w.step()
        assert w.last_solve["impacts"] == 0 and len(w.contacts) == 1
    assert toi.COUNTS["distance_evaluations"] == n0
