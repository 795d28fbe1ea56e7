"""Free motion between contacts: exact ballistic flight, conservative torque-free rotation."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import contact_sim as cs
from contact_sim import quat

pytestmark = pytest.mark.exact   # quick exact-answer tests: CI runs them again without the JIT


def _free_world(gravity=(0.0, 0.0, -9.81)):
    return cs.World(gravity=gravity)


@pytest.mark.parametrize("dt", [1 / 60, 1 / 7, 0.5])
def test_ballistic_flight_exact_at_any_step(dt):
    g = np.array([0.3, -0.2, -9.81])
    w = _free_world(g)
    x0, v0 = np.array([0.1, 0.2, 5.0]), np.array([1.0, -2.0, 3.0])
    w.add_body("ball", cs.Sphere(0.1), mass=2.0, position=x0, velocity=v0)
    offset = np.array([0.0, 0.0, 10.0])  # far apart: the two never touch
    w.add_body("box", cs.Box([0.1, 0.2, 0.3]), mass=1.0, position=x0 + offset, velocity=v0, angular_velocity=[3, 1, 2])
    n = int(round(3.0 / dt))
    worst = 0.0
    for k in range(1, n + 1):
        w.step(dt)
        t = k * dt
        x = x0 + v0 * t + 0.5 * g * t * t
        v = v0 + g * t
        for name, shift in (("ball", 0.0), ("box", offset)):
            b = w.body(name)
            worst = max(worst, np.abs(b.position - shift - x).max() / np.abs(x).max(),
                        np.abs(b.velocity - v).max() / np.abs(v).max())
    assert worst <= 1e-12


def _euler_reference(inertia_diag, q0, omega0_world, t_end, t_eval):
    """Torque-free motion by Euler's equations + quaternion kinematics, integrated to 1e-12."""
    I = np.asarray(inertia_diag, float)
    wb0 = quat.rotate(quat.conj(q0), omega0_world)

    def rhs(t, y):
        wb, q = y[:3], y[3:]
        dw = np.array([(I[1] - I[2]) * wb[1] * wb[2] / I[0], (I[2] - I[0]) * wb[2] * wb[0] / I[1],
                       (I[0] - I[1]) * wb[0] * wb[1] / I[2]])
        dq = 0.5 * quat.mul(q, np.r_[wb, 0.0])
        return np.r_[dw, dq]

    sol = solve_ivp(rhs, (0, t_end), np.r_[wb0, q0], rtol=1e-12, atol=1e-13, method="DOP853", t_eval=t_eval)
    return quat.normalize(sol.y[3:].T)


def _angle_between(qa, qb):
    rel = quat.mul(quat.conj(qa), qb)  # arcsin of the vector part: full precision near zero
    return 2 * np.arcsin(np.linalg.norm(rel[..., :3], axis=-1).clip(max=1.0))


def _spinning(shape, omega, dt, seconds, q0=(0, 0, 0, 1)):
    w = _free_world((0.0, 0.0, 0.0))
    w.add_body("b", shape, mass=1.0, orientation=q0, angular_velocity=omega)
    L0 = w.angular_momentum()
    E0 = w.energy()
    qs, Ls, Es = [], [], []
    for _ in range(int(round(seconds / dt))):
        w.step(dt)
        qs.append(w.body("b").orientation)
        Ls.append(w.angular_momentum())
        Es.append(w.energy())
    return np.array(qs), np.array(Ls), np.array(Es), L0, E0, w


def test_free_rotation_conserves_angular_momentum_and_matches_euler_equations():
    shape = cs.Box([0.1, 0.4, 0.9])  # three distinct moments
    q0 = quat.normalize(np.array([0.1, 0.2, 0.3, 0.9]))
    omega = np.array([0.5, 3.0, 0.2])
    dt = 1 / 120
    qs, Ls, Es, L0, E0, w = _spinning(shape, omega, dt, 10.0, q0)
    assert np.abs(Ls - L0).max() <= 1e-9 * np.linalg.norm(L0)
    assert np.abs(np.linalg.norm(qs, axis=1) - 1).max() < 1e-14
    assert np.abs(Es - E0).max() / E0 < 1e-4  # symplectic: bounded, no drift
    # orientation against an independent high-accuracy solution (moments in the principal frame)
    inertia = w.body("b").inertia
    assert np.allclose(inertia, np.diag(np.diag(inertia)))  # box axes are principal axes
    t = dt * np.arange(1, len(qs) + 1)
    ref = _euler_reference(np.diag(inertia), q0, omega, t[-1], t)
    assert _angle_between(qs, ref).max() < 1e-4


def test_rotation_is_second_order_in_dt():
    # slow enough that one split sub-step is taken per step: the error then falls as dt²
    shape, q0, omega = cs.Box([0.1, 0.4, 0.9]), np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.2, 0.5, 0.1])
    errs = []
    for dt in (1 / 30, 1 / 60):
        qs, *_ , w = _spinning(shape, omega, dt, 4.0, q0)
        ref = _euler_reference(np.diag(w.body("b").inertia), q0, omega, 4.0, [4.0])
        errs.append(_angle_between(qs[-1], ref[0]))
    assert 3.5 < errs[0] / errs[1] < 4.5


def test_axisymmetric_and_isotropic_rotation_is_exact():
    # two equal moments: the splitting term vanishes and the free precession is reproduced exactly
    q0 = quat.normalize(np.array([0.3, -0.1, 0.2, 0.9]))
    omega = np.array([2.0, -1.0, 4.0])
    for shape in (cs.Box([0.2, 0.2, 0.6]), cs.Sphere(0.3), cs.Box([0.5, 0.5, 0.5])):
        qs, Ls, Es, L0, E0, w = _spinning(shape, omega, 1 / 30, 3.0, q0)
        inertia = w.body("b").inertia
        t = (1 / 30) * np.arange(1, len(qs) + 1)
        ref = _euler_reference(np.diag(inertia), q0, omega, t[-1], t)
        assert _angle_between(qs, ref).max() < 1e-9, shape
        assert np.abs(Es - E0).max() <= 1e-12 * E0


def test_isotropic_spin_is_the_closed_form_turn_and_a_still_body_keeps_its_orientation_bitwise():
    # sphere: q(t) = exp(ω t) ⊗ q0 and ω constant (bitwise); a body with ω = 0 never changes its quaternion
    w = _free_world(gravity=(0.0, 0.0, 0.0))
    q0 = quat.normalize(np.array([0.3, -0.1, 0.2, 0.9]))
    omega = np.array([2.0, -1.0, 4.0])
    w.add_body("spin", cs.Sphere(0.3), mass=2.0, orientation=q0, angular_velocity=omega)
    w.add_body("still", cs.Box([0.2, 0.4, 0.6]), mass=1.0, position=[5.0, 0.0, 0.0], orientation=q0)
    still0 = w.body("still").orientation.copy()
    for _ in range(90):
        w.step(1 / 30)
    spin, still = w.body("spin"), w.body("still")
    assert np.array_equal(spin.angular_velocity, omega)
    ref = quat.mul(quat.from_rotvec(omega * 3.0), q0)
    assert _angle_between(spin.orientation[None], ref[None]).max() < 1e-12
    assert np.array_equal(still.orientation, still0)


def test_fast_spin_stays_accurate():
    omega = np.array([30.0, 70.0, -50.0])  # ~90 rad/s at dt = 1/60: 1.5 rad per step
    q0 = np.array([0.0, 0.0, 0.0, 1.0])
    qs, Ls, Es, L0, E0, w = _spinning(cs.Box([0.1, 0.4, 0.9]), omega, 1 / 60, 1.0)
    assert np.all(np.isfinite(qs))
    assert np.abs(np.linalg.norm(qs, axis=1) - 1).max() < 1e-14
    assert np.abs(Ls - L0).max() <= 1e-9 * np.linalg.norm(L0)
    assert np.abs(Es - E0).max() / E0 < 2e-4
    t = (1 / 60) * np.arange(1, len(qs) + 1)
    ref = _euler_reference(np.diag(w.body("b").inertia), q0, omega, t[-1], t)
    assert _angle_between(qs, ref).max() < 1e-2


def test_very_fast_spin_does_not_blow_up():
    omega = np.array([300.0, 700.0, -500.0])  # ~900 rad/s at dt = 1/60: 15 rad per step
    qs, Ls, Es, L0, E0, _ = _spinning(cs.Box([0.1, 0.4, 0.9]), omega, 1 / 60, 1.0)
    assert np.all(np.isfinite(qs))
    assert np.abs(np.linalg.norm(qs, axis=1) - 1).max() < 1e-14
    assert np.abs(Ls - L0).max() <= 1e-9 * np.linalg.norm(L0)
    assert np.abs(Es - E0).max() / E0 < 2e-3  # sub-step cap reached: still bounded


def test_off_centre_convex_rotates_about_its_centre_of_mass():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], float) + [5, 0, 0]
    w = _free_world((0, 0, 0))
    w.add_body("t", cs.Convex(pts), mass=1.0, angular_velocity=[0, 0, 1.0])
    com0 = w.s.pos[0].copy()
    for _ in range(100):
        w.step(0.01)
    assert np.allclose(w.s.pos[0], com0, atol=1e-14)  # the centre of mass stays put
    b = w.body("t")
    assert np.allclose(b.position + quat.rotate(b.orientation, b.center_of_mass), com0, atol=1e-12)
    assert np.allclose(b.center_of_mass, [5.25, 0.5, 0.75], atol=1e-12)  # tetrahedron centroid


def test_particles_do_not_rotate():
    w = _free_world()
    w.add_body("p", cs.Box([1, 1, 1]), model="particle", mass=1.0, orientation=[0, 0, 0.6, 0.8])
    w.step(0.1)
    assert np.array_equal(w.body("p").orientation, [0, 0, 0.6, 0.8])
    with pytest.raises(cs.ContactSimError, match="particle does not rotate"):
        w.add_body("q", cs.Sphere(1), model="particle", angular_velocity=[1, 0, 0])


def test_static_bodies_never_move_and_energy_counts_dynamic_only():
    w = _free_world()
    w.add_body("g", cs.Plane(), kind="static")
    w.add_body("b", cs.Sphere(0.5), mass=2.0, position=[0, 0, 3], velocity=[1, 0, 0])
    e0 = w.energy()
    assert e0 == pytest.approx(0.5 * 2 * 1 + 2 * 9.81 * 3, rel=1e-15)
    for _ in range(30):
        w.step(1 / 60)
    assert np.array_equal(w.body("g").position, [0, 0, 0])
    assert w.energy() == pytest.approx(e0, rel=1e-12)


def test_step_refuses_bad_dt_and_leaves_state():
    w = _free_world()
    w.add_body("b", cs.Sphere(0.5), mass=1.0)
    for bad in (0, -1e-3, float("nan"), float("inf"), "x", True):
        with pytest.raises(cs.ContactSimError, match="dt"):
            w.step(bad)
    assert w.time == 0.0 and np.array_equal(w.body("b").position, [0, 0, 0])
