"""Compliant contact (``response.compliance``): a contact with a stiffness is a spring and damper
row of the resting solve, so a body squeezed where it cannot yield has one bounded answer.

Each test checks a formula: the spring's force ``k·d`` per contact point at rest, the impulse
``dt·k·d`` a held contact reports, the damper's ``c = 2ζ√(k m)``, the rebound of an undamped spring.
"""
import numpy as np
import pytest

import contact_sim as cs

DT = 1 / 240


def _pusher_world(k, method="auto", toi="auto", zeta=1.0, pad_stiffness=True):
    """A 10 cm box (1 kg) on a floor against a static wall (x < 0), a kinematic pusher 1 cm from
    its other face; the pusher's material is compliant (``k`` N/m), the floor, wall and box rigid."""
    st = cs.Settings(dt=DT, solver_method=method, toi=toi)
    pad = dict(stiffness=k, damping_ratio=zeta) if pad_stiffness else {}
    w = cs.World(settings=st, materials={"default": cs.Material(friction=0.5, restitution=0.0),
                                         "pad": cs.Material(friction=0.5, restitution=0.0, **pad)})
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("wall", cs.Box([0.2, 1.0, 1.0]), kind="static", position=[-0.1, 0, 0.5])
    w.add_body("box", cs.Box([0.1] * 3), mass=1.0, position=[0.05, 0, 0.05])
    w.add_body("pusher", cs.Box([0.1, 0.06, 0.06]), kind="kinematic", position=[0.16, 0, 0.05], material="pad")
    return w


def _press(w, past, t_press=0.5, t_hold=0.5):
    """Drive the pusher from 1 cm away to ``past`` beyond touching over ``t_press``, hold it;
    returns the box's largest speed beyond the pusher's."""
    x0, x1 = 0.16, 0.15 - past
    worst = 0.0
    n = int(round((t_press + t_hold) / DT))
    for i in range(n):
        t = (i + 1) * DT
        x = x0 + (x1 - x0) * min(t / t_press, 1.0)
        w.set_pose("pusher", [x, 0, 0.05], [0, 0, 0, 1], t)
        w.step()
        worst = max(worst, np.linalg.norm(w.body("box").velocity) - np.linalg.norm(w.body("pusher").velocity))
    return worst


@pytest.mark.parametrize("method", ["auto", "gs"])
def test_a_box_pressed_into_a_wall_by_a_compliant_pusher_feels_the_springs_force(method):
    """1 cm past touching, held: the pusher's face pushes with ``k·d`` (d = 1 cm; its four points
    share the pair's stiffness), the box stays where the wall holds it (not squeezed out), and it
    never moves faster than the pusher."""
    k = 1e4
    w = _pusher_world(k, method)
    faster = _press(w, 0.01)
    box = w.body("box")
    np.testing.assert_allclose(box.position, [0.05, 0, 0.05], atol=1e-9)
    assert np.linalg.norm(box.velocity) < 1e-9
    assert faster <= 1e-6   # round-off of two speeds (m/s)
    c = w.contacts
    pad = (c.body_a == w.index("pusher")) | (c.body_b == w.index("pusher"))
    assert pad.sum() == 4
    # the box's own overlaps are round-off the resting solve holds (a body a spring holds gets no
    # position correction: correction.penetrating), as its position's
    np.testing.assert_allclose(c.depth[pad], 0.01, atol=1e-9)
    # the reported impulse is the spring's force over the step: dt·(k/4)·d per point, 100 N in all
    np.testing.assert_allclose(c.normal_impulse[pad], DT * k / 4 * 0.01, rtol=1e-6)
    # the box at rest: every contact's impulse on it (pusher, wall, floor) sums to its weight's
    on_box = np.where((c.body_a == w.index("box"))[:, None], c.impulse, -c.impulse)
    np.testing.assert_allclose(on_box.sum(axis=0), [0, 0, 9.81 * DT], atol=1e-9)


def test_the_same_press_under_exact_times_of_impact():
    """The sub-step's split exit (fractional time of impact) gives the whole exit's answer."""
    k = 1e4
    w = _pusher_world(k, toi="fractional")
    _press(w, 0.01)
    c = w.contacts
    pad = (c.body_a == w.index("pusher")) | (c.body_b == w.index("pusher"))
    np.testing.assert_allclose(w.body("box").position, [0.05, 0, 0.05], atol=1e-9)
    np.testing.assert_allclose(c.normal_impulse[pad], DT * k / 4 * 0.01, rtol=1e-6)


def test_a_rigid_pusher_squeezes_the_box_out_a_compliant_one_does_not():
    """The failure compliance removes: with a rigid pusher 1 cm past touching there is no rigid
    answer, and the box leaves the line between pusher and wall (or the overlap stays unresolved)."""
    rigid = _pusher_world(1e4, pad_stiffness=False)
    _press(rigid, 0.01)
    soft = _pusher_world(1e4)
    _press(soft, 0.01)
    assert np.linalg.norm(soft.body("box").position - [0.05, 0, 0.05]) < 1e-9
    moved = np.linalg.norm(rigid.body("box").position - [0.05, 0, 0.05])
    assert moved > 1e-3 or rigid.last_solve.max_penetration > 5e-3


def _grasp(over, shape="box", k=1e5, dt=DT, shake=True):
    """Two kinematic finger pads close on a 5 cm, 0.2 kg part on the floor over 1 s to ``over``
    past its width on each side, lift it 10 cm over 2 s, shake it ±5 cm at 2 Hz for 2 s and hold
    0.5 s. Returns ``(slip, lag, faster, part z - pad z at the end)``: the change of the part's
    height relative to the pads from before the lift to the end (m), the largest transient offset,
    and the part's largest speed beyond the pads'."""
    st = cs.Settings(dt=dt)
    w = cs.World(settings=st, materials={"default": cs.Material(friction=1.0, restitution=0.0),
                                         "pad": cs.Material(friction=1.0, restitution=0.0, stiffness=k)})
    w.add_body("floor", cs.Plane(), kind="static")
    part = cs.Box([0.05] * 3) if shape == "box" else cs.Cylinder(0.025, 0.05)
    w.add_body("part", part, mass=0.2, position=[0, 0, 0.025])
    x_open, x_shut = 0.025 + 0.01 + 0.01, 0.025 + 0.01 - over
    for s in (-1, 1):
        w.add_body(f"pad{s}", cs.Box([0.02, 0.04, 0.04]), kind="kinematic", position=[s * x_open, 0, 0.025],
                   material="pad")

    def pads(t):
        if t < 1.0:
            return x_open + (x_shut - x_open) * t, 0.025
        if t < 3.0:
            return x_shut, 0.025 + 0.1 * (t - 1.0) / 2.0
        if t < 5.0 and shake:
            return x_shut, 0.125 + 0.05 * np.sin(2 * np.pi * 2.0 * (t - 3.0))
        return x_shut, 0.125

    n = int(round((5.5 if shake else 3.5) / dt))
    lag = faster = 0.0
    rel0 = None
    for i in range(n):
        t = (i + 1) * dt
        x, z = pads(t)
        for s in (-1, 1):
            w.set_pose(f"pad{s}", [s * x, 0, z], [0, 0, 0, 1], t)
        w.step()
        p, pad = w.body("part"), w.body("pad1")
        rel = p.position[2] - pad.position[2]
        if t <= 1.0 + 1e-12:
            rel0 = rel
        else:
            lag = max(lag, abs(rel - rel0))
        faster = max(faster, np.linalg.norm(p.velocity - pad.velocity))
        assert np.all(np.isfinite(p.position))
    p, pad = w.body("part"), w.body("pad1")
    return abs(p.position[2] - pad.position[2] - rel0), lag, faster, p.position


@pytest.mark.parametrize("over", [0.5e-3, 1e-3, 5e-3])
def test_kinematic_pads_lift_and_shake_a_cube_without_slip(over):
    slip, lag, faster, end = _grasp(over)
    assert end[2] > 0.1                 # lifted 10 cm and held through the shake
    assert slip <= 1e-3, slip
    # the part follows the pads a step and a half behind: at most 1.5·dt × their top speed (0.63 m/s)
    assert lag <= 1.5 * DT * 0.63 + 1e-4, lag
    assert faster <= 0.1, faster
    assert abs(end[0]) < 1e-3 and abs(end[1]) < 1e-3   # not squeezed out sideways


def test_kinematic_pads_lift_and_shake_a_cylinder_without_slip():
    slip, lag, faster, end = _grasp(1e-3, shape="cylinder")
    assert end[2] > 0.1
    assert slip <= 1e-3, slip
    assert faster <= 0.1, faster


def test_a_held_part_reports_the_springs_force_and_its_weight_in_friction():
    """Pads at rest holding the part in the air: each pad's points push with ``dt·(k/n)·d`` (their
    depth at rest, the pair's stiffness shared by its ``n`` points), and the friction impulses carry
    the weight, ``m g dt`` in all."""
    k = 1e5
    st = cs.Settings(dt=DT)
    w = cs.World(settings=st, materials={"default": cs.Material(friction=1.0, restitution=0.0),
                                         "pad": cs.Material(friction=1.0, restitution=0.0, stiffness=k)})
    w.add_body("part", cs.Box([0.05] * 3), mass=0.2, position=[0, 0, 0.5])
    for s in (-1, 1):
        w.add_body(f"pad{s}", cs.Box([0.02, 0.04, 0.04]), kind="kinematic", position=[s * 0.034, 0, 0.5],
                   material="pad")
    for _ in range(240):
        w.step()
    c = w.contacts
    assert len(c) == 8
    np.testing.assert_allclose(c.normal_impulse, DT * k / 4 * c.depth, rtol=1e-6)
    np.testing.assert_allclose(c.depth, 0.001, atol=1e-5)
    lift = np.sum(np.where(c.body_b == w.index("part"), -1.0, 1.0)[:, None] * c.impulse, axis=0)
    np.testing.assert_allclose(abs(lift[2]), 0.2 * 9.81 * DT, rtol=1e-6)
    assert np.linalg.norm(w.body("part").velocity) < 1e-9


def _drop(zeta, dt, k=1e4):
    """A 1 kg ball dropped from 0.1 m onto a compliant floor; returns its rebound height (m)."""
    w = cs.World(settings=cs.Settings(dt=dt),
                 materials={"default": cs.Material(restitution=0.0, friction=0.0, stiffness=k, damping_ratio=zeta)})
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("ball", cs.Sphere(0.05), mass=1.0, position=[0, 0, 0.15])
    top, down = 0.0, True
    for _ in range(int(round(0.6 / dt))):
        w.step()
        z, v = w.body("ball").position[2], w.body("ball").velocity[2]
        if down and v > 0:
            down = False
        if not down:
            top = max(top, z - 0.05)
    return top


def test_an_undamped_compliant_floor_returns_the_drop_height_as_the_step_shrinks():
    """ζ = 0: no damper, and the step's own loss (the spring on its end depth) is first order in
    ``ω dt``: a quarter of the step, about a quarter of the loss; 97 % of the height at ω dt = 0.026."""
    loss = [0.1 - _drop(0.0, dt) for dt in (1 / 960, 1 / 3840)]
    assert 0 < loss[1] < loss[0]
    assert 3.0 < loss[0] / loss[1] < 5.0, loss
    assert loss[1] < 0.004


def test_a_critically_damped_compliant_floor_takes_the_bounce():
    """ζ = 1: the damper takes the energy, the ball does not come back above a millimetre."""
    assert _drop(1.0, DT / 4) < 1e-3


def test_rigid_contacts_take_no_compliance_and_describe_says_which():
    w = cs.World(settings=cs.Settings(dt=DT))
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("box", cs.Box([0.1] * 3), mass=1.0, position=[0, 0, 0.05])
    assert any("contacts rigid" in line for line in w.describe().splitlines())
    w.settings.kinematic_stiffness = 2e4
    w.add_body("pad", cs.Box([0.1] * 3), kind="kinematic", position=[0, 0, 0.5])
    text = w.describe()
    assert "compliant contacts: contacts with a kinematic body 2e+04 N/m" in text, text


@pytest.mark.parametrize("field, value", [("stiffness", -1.0), ("stiffness", 0.0), ("damping_ratio", -0.5),
                                          ("stiffness", float("nan"))])
def test_bad_compliance_parameters_are_refused_by_name(field, value):
    with pytest.raises(cs.ContactSimError, match=field):
        cs.Material(**{field: value})


def test_bad_kinematic_stiffness_is_refused_by_name():
    with pytest.raises(cs.ContactSimError, match="kinematic_stiffness"):
        cs.Settings(kinematic_stiffness=-1.0)


def test_a_ball_squeezed_by_a_compliant_paddle_never_has_more_energy_than_the_paddle_gave():
    """The squeeze the rigid model caps (test_kinematic.squeeze_at_a_wall) with the default
    compliant paddle: a paddle at 0.5 m/s drives a ball into a box standing at a wall. The springs
    store what the paddle does as work and give it back when the ball escapes, so the ball may
    leave faster than a rigid push would make it, but the bodies' energy with the springs' (``World.energy``)
    never exceeds the start's plus the paddle's work so far and the steps' own error bounds (the
    resting force's first-order work, the position correction's potential energy)."""
    from test_kinematic import squeeze_at_a_wall

    w = squeeze_at_a_wall()
    w.settings.kinematic_stiffness = 1e5
    e0, work = w.energy(), 0.0
    for _ in range(150):
        w.step()
        ls = w.last_solve
        work += ls.kinematic_work + ls.pose_work + ls.rest_work_bound + max(ls.correction_energy, 0.0)
        assert w.energy() <= e0 + work + 1e-9 * (1 + abs(e0) + abs(work))
    assert work > 1.0                           # the paddle pushed (and drove on into the wall)
    assert np.all(np.isfinite(w.s.vel)) and np.all(np.isfinite(w.s.pos))


def test_a_ball_resting_on_a_compliant_kinematic_floor_sinks_by_its_weight():
    """``kinematic_stiffness`` k: a 1 kg ball at rest on a kinematic box sinks ``m g / k``, and the
    contact reports the weight's impulse ``m g dt``; the stored energy is ``½ k d²``."""
    k = 1e5
    w = cs.World(settings=cs.Settings(dt=0.01, kinematic_stiffness=k))
    w.add_body("floor", cs.Box([2, 2, 0.2]), kind="kinematic", position=[0, 0, -0.1])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 0.1])
    for _ in range(200):
        w.step()
    sink = 9.81 / k
    assert w.body("ball").position[2] == pytest.approx(0.1 - sink, abs=1e-9)
    np.testing.assert_allclose(w.contacts.normal_impulse.sum(), 9.81 * 0.01, rtol=1e-9)
    assert w.contact_energy() == pytest.approx(0.5 * k * sink ** 2, rel=1e-6)


def test_the_shipped_grasp_scene_lifts_its_cube():
    """``config/scenes/grasp.yaml`` as its description says: pads closed to ±0.034 m (1 mm past
    the cube's faces) over 0.5 s, then raised 10 cm over 1 s: the cube goes up with them, and each
    pad pushes with ``k·1 mm`` = 100 N."""
    w = cs.load_scene(cs.resolve_scene("grasp"))
    dt = w.settings.dt
    n_close, n_lift = int(round(0.5 / dt)), int(round(1.0 / dt))
    for i in range(n_close + n_lift + 60):
        t = (i + 1) * dt
        x = 0.045 - 0.011 * min(t / 0.5, 1.0)
        z = 0.025 + 0.1 * min(max(t - 0.5, 0.0) / 1.0, 1.0)
        w.set_poses(["pad_left", "pad_right"], [[-x, 0, z], [x, 0, z]], [[0, 0, 0, 1]] * 2, t)
        w.step()
    assert w.body("cube").position[2] == pytest.approx(0.125, abs=1e-3)
    c = w.contacts
    pad = c.body_a == w.index("pad_right")
    pad |= c.body_b == w.index("pad_right")
    np.testing.assert_allclose(c.normal_impulse[pad].sum() / dt, 1e5 * 1e-3, rtol=1e-3)


def _panda_grasp(k):
    """pybullet_data's Franka Panda, hand pointing down over a 4 cm, 0.1 kg cube on a pedestal,
    driven by ``set_joint_positions`` at 240 Hz: the fingers close over 1 s to 1 mm past the
    cube's faces, then joints 4 and 6 lift the hand 10 cm (and 6 cm outwards) over 2 s, then it
    holds 0.5 s. Returns the world and the largest change of the cube's height relative to the
    left finger (m)."""
    from conftest import PANDA_URDF

    w = cs.World(settings=cs.Settings(dt=DT, kinematic_stiffness=k),
                 materials={"default": cs.Material(friction=1.0, restitution=0.0)})
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("pedestal", cs.Box([0.1, 0.1, 0.125]), kind="static", position=[0.556, 0, 0.0625])
    w.add_body("cube", cs.Box([0.04] * 3), mass=0.1, position=[0.556, 0, 0.145])
    w.add_urdf(PANDA_URDF)
    q0 = {"panda_joint1": 0.0, "panda_joint2": 0.3, "panda_joint3": 0.0, "panda_joint4": -2.2, "panda_joint5": 0.0,
          "panda_joint6": 2.5, "panda_joint7": 0.785, "panda_finger_joint1": 0.04}

    def q_at(t):
        q = dict(q0)
        q["panda_finger_joint1"] = 0.04 - 0.021 * min(t / 1.0, 1.0)
        s = min(max(t - 1.0, 0.0) / 2.0, 1.0)
        q["panda_joint4"], q["panda_joint6"] = -2.2 + 0.3 * s, 2.5 - 0.3 * s
        return q

    q = q_at(0.0)
    w.set_joint_positions(list(q), list(q.values()), 0.0)
    rel0, slip = None, 0.0
    for i in range(int(round(3.5 / DT))):
        t = (i + 1) * DT
        q = q_at(t)
        w.set_joint_positions(list(q), list(q.values()), t)
        w.step()
        rel = w.body("cube").position[2] - w.body("panda_leftfinger").position[2]
        if t <= 1.0 + 1e-12:
            rel0 = rel
        else:
            slip = max(slip, abs(rel - rel0))
    return w, slip


def test_the_panda_closes_its_fingers_on_a_cube_and_carries_it():
    """Compliant finger contacts (``kinematic_stiffness`` 1e5 N/m): the cube rises with the hand
    (10 cm up, 6 cm out) within 1 mm of where the fingers took it, and each finger pushes with the
    spring's force, ``k`` × its points' mean depth (about 108 N for a 1 mm squeeze of the
    finger meshes). Rigid fingers (0) leave it on the pedestal."""
    w, slip = _panda_grasp(1e5)
    cube = w.body("cube").position
    assert cube[2] > 0.145 + 0.095 and cube[0] > 0.556 + 0.05
    assert slip <= 1e-3, slip
    c = w.contacts
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        f = w.index(finger)
        m = (c.body_a == f) | (c.body_b == f)
        assert m.sum() >= 1
        np.testing.assert_allclose(c.normal_impulse[m].sum() / DT, 1e5 * c.depth[m].mean(), rtol=1e-6)
    rigid, _ = _panda_grasp(0.0)
    assert rigid.body("cube").position[2] < 0.15


@pytest.mark.parametrize("base_z, ball", [(0.18, [0, 0, 0.05]), (0.1, [0.25, 0, 0.05])], ids=["under", "beside"])
def test_a_ball_born_in_the_ground_and_a_compliant_base_is_not_pushed_into_the_spring(base_z, ball):
    """A ball placed 5 cm into a static floor and 5 cm into a still kinematic base (compliant by
    default), under it or beside it. Position correction would push it out of the floor and, with
    the base's spring holding it, into the base (under it, it gained 1 kJ in three steps that way);
    a body a compliant contact holds gets no correction (``correction.penetrating``). With nothing
    moving, the bodies' energy with the springs' (``World.energy``) never grows beyond the steps'
    own bounds."""
    w = cs.World(settings=cs.Settings(dt=DT))
    assert w.settings.kinematic_stiffness == 1e5
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("base", cs.Box([0.4, 0.2, 0.2]), kind="kinematic", position=[0, 0, base_z])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=ball)
    e0, bound = w.energy(), 0.0
    for _ in range(240):
        w.step()
        ls = w.last_solve
        bound += ls.kinematic_work + ls.pose_work + ls.rest_work_bound + max(ls.correction_energy, 0.0)
        assert w.energy() <= e0 + bound + 1e-9 * (1 + abs(e0) + abs(bound))
    assert np.all(np.isfinite(w.s.pos)) and np.all(np.isfinite(w.s.vel))


def test_a_pose_that_presses_a_compliant_floor_counts_its_springs_work():
    """A 1 kg ball at rest on a compliant kinematic floor (``kinematic_stiffness`` k, sunk ``m g /
    k``); the floor is posed 1 mm up at once: its spring goes from ``d₀ = m g / k`` to ``d₀ + 1
    mm`` before the step, work the floor did (``energy.pose_work``, ``StepStats.pose_work``): exactly
    ``½ k ((d₀ + 1 mm)² − d₀²)``; the bodies' energy with the springs' never grows by more than the
    floor's reported work, up and down (it grew 31 mJ with none reported before)."""
    k = 1e5
    w = cs.World(settings=cs.Settings(dt=0.01, kinematic_stiffness=k))
    w.add_body("floor", cs.Box([2, 2, 0.2]), kind="kinematic", position=[0, 0, -0.1])
    w.add_body("ball", cs.Sphere(0.1), mass=1.0, position=[0, 0, 0.1])
    for _ in range(200):
        w.step()
    d0, z = 9.81 / k, -0.1
    for i in range(10):
        e0 = w.energy()
        z += 0.001 if i < 5 else -0.001
        w.set_pose("floor", [0, 0, z], [0, 0, 0, 1], w.time + 0.01)
        w.step()
        ls = w.last_solve
        if i == 0:   # the spring's own work; the step's impulses then move nothing kinematic yet
            assert ls.pose_work == pytest.approx(0.5 * k * ((d0 + 1e-3) ** 2 - d0 ** 2), rel=1e-9)
        assert w.energy() - e0 <= ls.kinematic_work + ls.pose_work + ls.rest_work_bound + 1e-12


@pytest.mark.parametrize("on_ground", [False, True])
def test_a_kinematic_spring_pushes_a_ball_the_same_whether_or_not_it_touches_the_ground(on_ground):
    """A 1 kg ball at rest on the floor (no gravity), 5 cm inside a still kinematic sphere level
    with it (the contact compliant by ``settings.kinematic_stiffness`` k, damping ratio ζ = 1): the
    spring's row is along x and the floor's takes nothing, so the step's impulse is the soft row's
    exact answer ``λ = T k d m / (h + m)``, ``h = T (T k/2 + 2ζ√(k m))``. Whether the sphere's own
    overlap with the floor is a contact (``on_ground``) or not (the pair disabled) changes nothing:
    it pushes no dynamic body (``energy.push_speed``). Counted as a push at rest, it made the push
    cap hold every body of the solve to its start speed: the ball stayed inside a spring that did
    not push (fresh draws, seed 20261209:
    test/cases/call_sequences_balls_born_deep_in_a_compliant_kinematic_sphere.yaml)."""
    k, m, d = 1e5, 1.0, 0.05
    w = cs.World(gravity=(0.0, 0.0, 0.0), settings=cs.Settings(dt=DT, kinematic_stiffness=k))
    w.add_body("floor", cs.Plane(), kind="static")
    w.add_body("pad", cs.Sphere(0.5), kind="kinematic", position=[0.0, 0.0, 0.1])
    w.add_body("ball", cs.Sphere(0.1), mass=m, position=[0.6 - d, 0.0, 0.1])
    if not on_ground:
        w.disable_collisions([("floor", "pad")])
    w.step()
    c = w.contacts
    pad = (c.body_a == w.index("pad")) & (c.body_b == w.index("ball")) | (c.body_a == w.index("ball")) & (
        c.body_b == w.index("pad"))
    assert pad.sum() == 1 and len(c) == (3 if on_ground else 2)   # and the ball on the floor
    h = DT * (0.5 * DT * k + 2.0 * np.sqrt(k * m))
    lam = DT * k * d * m / (h + m)
    np.testing.assert_allclose(c.normal_impulse[pad], [lam], rtol=1e-12)
    np.testing.assert_allclose(w.body("ball").velocity, [lam / m, 0.0, 0.0], rtol=1e-12, atol=1e-15)

