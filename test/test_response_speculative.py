"""Speculative contacts (next_step) and the per-step contact records of ``World.contacts``."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim import quat

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT

G, R = 9.81, 0.1


def _ball_scene(e, drop, dt, toi="next_step", friction=0.0, spheres=1):
    bodies = [{"name": "ground", "kind": "static", "shape": {"type": "plane", "normal": [0, 0, 1], "offset": 0.0},
               "material": "m"}]
    for i in range(spheres):
        bodies.append({"name": f"ball{i}", "shape": {"type": "sphere", "radius": R}, "mass": 1.0,
                       "position": [0.5 * i, 0.0, R + drop], "material": "m"})
    return cs.load_scene({"gravity": [0, 0, -G], "settings": {"dt": dt, "toi": toi, "response": "impulse"},
                          "materials": {"m": {"restitution": e, "friction": friction}}, "bodies": bodies})


def _penetration_of_landing(dt, steps, speculative=True):
    world = _ball_scene(0.0, 0.1, dt)            # lands at sqrt(2 g 0.1) = 1.4 m/s
    world.settings.speculative = speculative
    worst = 0.0
    for _ in range(steps):
        world.step()
        worst = max(worst, R - world.body("ball0").position[2])
    return world, worst


def test_landing_at_speed_does_not_penetrate_with_speculative_contacts():
    dt = 1 / 240
    world, worst = _penetration_of_landing(dt, 120)
    u = np.sqrt(2 * G * 0.1)
    print(f"speculative: worst penetration {worst:.3g} m (travel per step {u * dt:.3g} m)")
    assert worst < 1e-6
    assert abs(world.body("ball0").velocity[2]) < 1e-6       # at rest, no bounce (e = 0)
    assert abs(world.body("ball0").position[2] - R) < 1e-6


def test_without_speculative_contacts_the_same_landing_penetrates():
    """The comparison that makes the test above meaningful: the old next_step overlaps by ~u·dt/2."""
    dt = 1 / 240
    _, worst = _penetration_of_landing(dt, 120, speculative=False)
    assert worst > 1e-4


@pytest.mark.parametrize("e", [0.5, 0.8, 1.0])
def test_restitution_applies_when_a_speculative_contact_closes(e):
    """The ball is slowed to arrive exactly touching; the next step it rebounds with e × the speed it
    arrived with before the speculative impulse (to within gravity over two steps)."""
    dt = 1 / 60
    world = _ball_scene(e, 0.9, dt)
    v_prev, z_min, rebound = 0.0, np.inf, None
    for _ in range(60):
        world.step()
        v = world.body("ball0").velocity[2]
        z_min = min(z_min, world.body("ball0").position[2])
        if v_prev < 0 < v:
            rebound = v
            break
        v_prev = v
    u = np.sqrt(2 * G * 0.9)
    assert rebound is not None
    assert z_min > R - 1e-9                                 # never overlapped
    assert abs(rebound - e * u) < 2 * G * dt + 1e-9, (rebound, e * u)


def test_speculative_contacts_never_start_a_pair_moving_apart():
    """A speculative contact may only slow an approach: a ball resting 1 mm above the ground (held
    there by nothing but an initial upward velocity) follows free flight exactly."""
    world = _ball_scene(0.0, 0.001, 1 / 240)
    world.set_state("ball0", velocity=[0.0, 0.0, 0.5])
    z0 = world.body("ball0").position[2]
    world.step()
    t = 1 / 240
    assert abs(world.body("ball0").position[2] - (z0 + 0.5 * t - 0.5 * G * t * t)) < 1e-12
    assert abs(world.body("ball0").velocity[2] - (0.5 - G * t)) < 1e-12


def test_contacts_one_row_per_point_with_the_total_impulse_of_the_step():
    """Fractional time of impact splits the step at the impact; ``world.contacts`` still has one
    row for the ball–ground contact, whose impulse is the ball's whole momentum change minus gravity's."""
    world = _ball_scene(0.8, 0.9, 1 / 60, toi="fractional")
    m = 1.0
    seen = 0
    for _ in range(40):
        v0 = world.body("ball0").velocity.copy()
        world.step()
        v1 = world.body("ball0").velocity
        c = world.contacts
        pairs = set(zip(c.body_a.tolist(), c.body_b.tolist()))
        assert len(pairs) == len(c)                              # one row per contact point
        if len(c) and np.any(c.impulse != 0):
            seen += 1
            sign = 1.0 if c.body_a[0] == world.index("ball0") else -1.0
            expected = m * (v1 - v0) - m * np.array([0, 0, -G]) * world.settings.dt
            assert np.allclose(sign * c.impulse[0], expected, rtol=0, atol=1e-9)
            assert np.allclose(c.impulse[0], c.normal_impulse[0] * c.normal[0] + c.friction_impulse[0], atol=1e-15)
    assert seen >= 1


def test_resting_contact_rows_carry_the_weight():
    """Balls resting on the ground: one row each, normal impulse m g dt per step (no double count
    across the sub-steps of a step), depth within the contact margin."""
    dt = 1 / 240
    world = _ball_scene(0.0, 0.0, dt, spheres=3)
    for _ in range(10):
        world.step()
    c = world.contacts
    assert len(c) == 3
    assert np.allclose(c.normal_impulse, 1.0 * G * dt, rtol=1e-9)
    assert np.all(np.abs(c.depth) <= world.settings.contact_margin)


def test_head_on_spheres_meet_without_overlap_and_keep_momentum():
    """Two free spheres (no gravity, e = 0) closing at 4 m/s with next_step: they arrive touching
    (no overlap beyond round-off), stop together, and momentum is conserved to round-off."""
    bodies = [{"name": n, "shape": {"type": "sphere", "radius": R}, "mass": m, "position": [x, 0, 0],
               "velocity": [v, 0, 0], "material": "m"}
              for n, m, x, v in (("a", 1.0, -0.25, 2.0), ("b", 3.0, 0.25, -2.0))]
    world = cs.load_scene({"gravity": [0, 0, 0], "settings": {"dt": 1 / 60, "toi": "next_step", "response": "impulse"},
                           "materials": {"m": {"restitution": 0.0, "friction": 0.0}}, "bodies": bodies})
    p0 = 1.0 * 2.0 + 3.0 * -2.0
    worst = 0.0
    for _ in range(20):
        world.step()
        gap = world.body("b").position[0] - world.body("a").position[0] - 2 * R
        worst = max(worst, -gap)
        p = 1.0 * world.body("a").velocity[0] + 3.0 * world.body("b").velocity[0]
        assert abs(p - p0) < 1e-12
    assert worst < 1e-12
    assert abs(world.body("a").velocity[0] - p0 / 4.0) < 1e-12     # e = 0: common velocity
    assert abs(world.body("b").velocity[0] - p0 / 4.0) < 1e-12


def test_describe_names_speculative_contacts():
    world = _ball_scene(0.0, 0.1, 1 / 240)
    assert any("speculative contacts on" in line for line in world.describe().splitlines())


def _hull_beside_a_fast_ball():
    """A hull resting on four bottom corners, with one more vertex 1 cm up sticking out past them,
    and a ball rolling at 5 m/s far away: the ball alone sets the step's speculative margin."""
    w = cs.World(settings=cs.Settings(dt=0.01))
    w.add_body("ground", cs.Plane(), kind="static")
    corners = [[0.1, 0.1, 0.0], [0.1, -0.1, 0.0], [-0.1, 0.1, 0.0], [-0.1, -0.1, 0.0]]
    w.add_body("hull", cs.Convex(np.array(corners + [[0.25, 0.0, 0.01], [0.0, 0.0, 0.12]])), mass=1.0)
    w.add_body("ball", cs.Sphere(R), mass=1.0, position=(3.0, 0.0, R), velocity=(5.0, 0.0, 0.0))
    return w, np.array(corners)


def test_each_pair_takes_only_the_margin_its_bodies_can_close():
    """The speculative margin is the fastest pair's (2 v dt + g dt², capped); a pair's own margin is
    contact_margin + g dt² + what its two bodies can travel in dt. The hull at rest takes only its
    four touching corners into its manifold; with the ball's margin it took the vertex 1 cm up in
    place of a corner (reduce4 kept the widest four), which the look-ahead then dropped. With either
    margin the four corners are the manifold now: reduce4 puts the points that touch before those
    apart."""
    from contact_sim.collision import detect_world
    from contact_sim.response import prepare

    w, corners = _hull_beside_a_fast_ball()
    dt = 0.01
    margin, reach, floor, plane_margin = prepare.speculative_reach(w, dt)
    cap = prepare._margin_facts(w)[3]                   # a fraction of the thickest finite body
    assert margin == max(w.settings.contact_margin, min(2.0 * 5.0 * dt + G * dt * dt, cap))   # the ball's
    assert margin > 0.01                                # the 1 cm vertex is in it
    np.testing.assert_array_equal(reach, [[0.0, 0.0, 5.0 * dt]] * 2)
    assert floor == w.settings.contact_margin + G * dt * dt

    def hull_contacts(r):
        c, _ = detect_world(w, margin=margin, reach=r, floor=floor)
        m = (c.body_a == 1) | (c.body_b == 1)
        return c.point[m], c.depth[m]

    for r in (None, reach):                          # one margin for every pair, or each pair's own
        points, depth = hull_contacts(r)
        np.testing.assert_allclose(np.sort(points, axis=0), np.sort(corners, axis=0), atol=1e-12)
        np.testing.assert_allclose(depth, 0.0, atol=1e-12)



def test_a_turning_kinematic_plane_takes_the_whole_margin():
    """A plane has no extent to bound how fast its far points move: turning at 1 rad/s, its point
    under a ball 2 m from its origin rises at 2 m/s. Its reach is infinite, so its pairs take the
    step's whole margin and the ball 1 cm above it is a speculative contact that closes."""
    from contact_sim.collision import detect_world
    from contact_sim.response import prepare

    w = cs.World(settings=cs.Settings(dt=0.01))
    w.add_body("deck", cs.Plane(), kind="kinematic", angular_velocity=(0.0, 1.0, 0.0))
    w.add_body("ball", cs.Sphere(R), mass=1.0, position=(-2.0, 0.0, R + 0.01))
    w.add_body("runner", cs.Sphere(R), mass=1.0, position=(3.0, 0.0, 0.5), velocity=(3.0, 0.0, 0.0))
    margin, reach, floor, plane_margin = prepare.speculative_reach(w, 0.01)
    assert reach[0, 0] == np.inf and margin == prepare._margin_facts(w)[3] > 0.01   # the whole, capped margin
    assert plane_margin == max(margin, floor + 3.0 * 0.01)   # the runner's whole reach
    c, _ = detect_world(w, margin=margin, reach=reach, floor=floor, plane_margin=plane_margin)
    (row,) = np.flatnonzero((c.body_a == 0) | (c.body_b == 0))
    assert c.depth[row] == pytest.approx(-0.01, abs=1e-12)


def test_each_body_looks_ahead_as_far_as_its_own_size_allows():
    """A body's reach is capped by its own thinnest size, not the world's thinnest body: a 2 cm ball
    elsewhere kept a 12 cm box spinning at 19 rad/s to a 1 cm look-ahead, and its corners 1.7 cm up
    entered the ground unseen within the step."""
    from contact_sim.collision import detect_world
    from contact_sim.response import prepare

    w = cs.World(settings=cs.Settings(dt=1 / 60))
    w.add_body("ground", cs.Plane(), kind="static")
    w.add_body("box", cs.Box([0.2, 0.2, 0.12]), mass=1.0, position=(0.0, 0.0, 0.06 + 0.017),
               angular_velocity=(10.0, 0.0, 0.0))
    w.add_body("pebble", cs.Sphere(0.01), mass=0.01, position=(2.0, 0.0, 0.01))
    margin, reach, floor, plane_margin = prepare.speculative_reach(w, 1 / 60)
    ext = np.linalg.norm([0.1, 0.1, 0.06])
    assert reach[0, 1] == pytest.approx(min(10.0 * ext / 60, 0.5 * 0.12), rel=1e-12)
    assert reach[1, 1] == pytest.approx(10.0 * ext / 60, rel=1e-12)
    assert margin > 0.017 + 0.01
    c, _ = detect_world(w, margin=margin, reach=reach, floor=floor, plane_margin=plane_margin)
    box = c.body_b == 1
    assert box.sum() == 4 and np.allclose(c.depth[box], -0.017, atol=1e-12)


@pytest.mark.parametrize("toi", ["fractional", "swept"])
def test_an_impact_does_not_drive_a_resting_bodys_corners_apart_by_nanometres_into_the_floor(toi):
    """A plate on the ground, two corners touching and two 10 nm above it (tilted by round-off), is
    hit from above at its centre. Exact times of impact search only the pairs apart, and this pair
    touches: its two raised corners are the impact's too (held as speculative contacts: the gap
    may close, never more), so the plate, backed by the floor at all four corners, does not turn
    about its touching edge. Left to the resting stage, the raised edge went down at the speed the
    impact gave it and stopped only at the end of the step: half that speed × dt into the floor
    (0.29 mm in a fresh random draw, the 1 m/s hit here ~1 mm)."""
    tilt = 1e-8                                         # rad about x: the +y edge 10 nm up
    s, c = np.sin(tilt), np.cos(tilt)
    zc = 0.5 * s + 0.05 * c                             # the -y corners exactly on the floor
    plate_top = zc + 0.05 * c
    q = [np.sin(tilt / 2), 0.0, 0.0, np.cos(tilt / 2)]  # (x, y, z, w)
    world = cs.load_scene({
        "gravity": [0, 0, -G], "settings": {"dt": 1 / 120, "toi": toi, "response": "impulse"},
        "materials": {"m": {"restitution": 0.0, "friction": 0.5}},
        "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
                   {"name": "plate", "shape": {"type": "box", "size": [1.0, 1.0, 0.1]}, "mass": 1.0,
                    "position": [0.0, 0.0, zc], "orientation": q, "material": "m"},
                   {"name": "ball", "shape": {"type": "sphere", "radius": 0.05}, "mass": 1.0,
                    "position": [0.0, 0.0, plate_top + 0.05], "velocity": [0.0, 0.0, -1.0], "material": "m"}]})
    world.step()
    corners = np.array([[x, y, -0.05] for x in (-0.5, 0.5) for y in (-0.5, 0.5)])
    plate = world.body("plate")
    low = (plate.position + quat.rotate(plate.orientation[None], corners))[:, 2].min()
    print(f"{toi}: lowest corner {low:.3g} m after the hit")
    assert low > -1e-9
    # stopped on the plate (e = 0), which settles its raised edge over the step: the edge ends at
    # 2·gap/dt at most (the resting stage closes the gap exactly), the centre at half that
    assert abs(world.body("ball").velocity[2]) <= 1e-8 * 120 * (1 + 1e-6)



@pytest.mark.parametrize("response", ["impulse", "penalty"])
def test_a_box_falling_farther_than_half_its_thickness_in_a_step_sees_the_floor(response):
    """A 1 cm thick box falling at 1.8 m/s (7.5 mm a step at 240 Hz), its face 6 mm above the floor.
    A body's look-ahead against another finite body stops at half its own thinnest size (5 mm:
    beyond, ``swept``'s job and the preflight's warning; a longer one would stop bodies on the
    features of things they only pass by), but a plane is a half-space that nothing passes by: the
    pair's look-ahead is how far the box's points move in the step. So the floor is a speculative
    contact of this step, and the box arrives touching it (exactly, to round-off: the impulse
    closes the gap over the step under gravity) instead of 1.5 mm inside; under ``penalty`` the
    corners' springs act in this step on the depth they reach."""
    gap, v, dt = 0.006, 1.8, 1 / 240
    world = cs.load_scene({
        "gravity": [0, 0, -G], "settings": {"dt": dt, "toi": "next_step", "response": response,
                                            "penalty": {"stiffness": 2e4}},
        "materials": {"m": {"restitution": 0.0, "friction": 0.5}},
        "bodies": [{"name": "ground", "kind": "static", "shape": {"type": "plane"}, "material": "m"},
                   {"name": "box", "shape": {"type": "box", "size": [0.04, 0.02, 0.01]}, "mass": 1.0,
                    "position": [0.0, 0.0, 0.005 + gap], "velocity": [0.0, 0.0, -v], "material": "m"}]})
    assert v * dt > 0.005 + 1e-4 + G * dt * dt   # beyond the capped look-ahead (half the thickness + floor)
    world.step()
    low = world.body("box").position[2] - 0.005
    print(f"{response}: bottom face at {low:.3g} m after the step")
    if response == "impulse":
        assert abs(low) <= 1e-15
    else:
        # each corner's spring acts on the depth it reaches, k·(−gap − dt·u) with u the end velocity
        # (implicit, no damper apart): u = (−v − g dt − 4 dt k gap / m) / (1 + 4 dt² k / m) for the
        # four corners, and the face ends at gap + dt·u (0.70 mm in; unseen, 1.5 mm with no force)
        k = 2e4
        u = (-v - G * dt - 4 * dt * k * gap) / (1 + 4 * dt * dt * k)
        assert low == pytest.approx(gap + dt * u, rel=1e-12, abs=1e-15)
