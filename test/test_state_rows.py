"""msg_adapters.state_rows: the node's per-body rows in one compiled pass, against the numpy
formulas they replace (bit for bit) and against the wrench's definition."""
import numpy as np
import pytest

import contact_sim as cs
from contact_sim.vec import cross
from msg_adapters.state_rows import blocks, state_rows

pytestmark = pytest.mark.exact


def _pile(offset_hull):
    """A ground, a hull whose centre of mass is off its origin (or a box instead), a box and two spheres,
    spinning, dropped until they touch."""
    world = cs.World()
    world.add_body("ground", cs.Plane(), kind="static")
    rng = np.random.default_rng(3)
    shape = cs.Convex(rng.normal(size=(16, 3)) * 0.1 + [0.25, -0.1, 0.05]) if offset_hull else cs.Box((0.1, 0.1, 0.1))
    world.add_body("hull", shape, density=800.0, position=(0.0, 0.0, 0.3),
                   orientation=(0.1, 0.2, 0.3, 0.927), angular_velocity=(1.0, -2.0, 0.5))
    world.add_body("box", cs.Box((0.1, 0.2, 0.1)), density=500.0, position=(0.6, 0.0, 0.12),
                   angular_velocity=(0.0, 0.0, 3.0), velocity=(0.2, 0.0, 0.0))
    world.add_body("ball", cs.Sphere(0.1), density=1000.0, position=(-0.5, 0.0, 0.1), velocity=(0.0, 0.3, -0.1))
    world.add_body("ball2", cs.Sphere(0.05), density=1000.0, position=(-0.5, 0.0, 0.25))
    for _ in range(40):
        world.step(0.005)
        if len(world.contacts) >= 4:
            break
    return world


@pytest.mark.parametrize("offset_hull", [True, False])
def test_state_rows_are_the_numpy_formulas_bit_for_bit(offset_hull):
    world = _pile(offset_hull)
    assert bool(world.com_local.any()) == offset_hull
    contacts = world.contacts
    assert len(contacts) >= 4 and np.abs(contacts.impulse).max() > 0
    n, duration = len(world), 0.005
    poses, twists, wrenches = blocks(state_rows(world, contacts, duration), n)
    p, q = world.poses()
    v, w = world.velocities()
    np.testing.assert_array_equal(poses[:, :3], p)
    np.testing.assert_array_equal(poses[:, 3:], q)
    np.testing.assert_array_equal(twists[:, :3], v + cross(w, p - world.s.pos))
    np.testing.assert_array_equal(twists[:, 3:], w)
    cv = pytest.importorskip("msg_adapters.conversions")   # the numpy version it replaced (ROS messages)
    force, torque = cv.contact_wrenches(contacts, p, duration)
    np.testing.assert_array_equal(wrenches[:, :3], force)
    np.testing.assert_array_equal(wrenches[:, 3:], torque)


def test_wrench_is_the_sum_of_impulses_over_the_duration_with_torque_about_the_origin():
    """Two contacts between bodies 0 and 1 with chosen impulses: the force on A is their sum over
    the duration, on B its negative; the torque is (point - origin) x force for each."""
    world = cs.World()
    world.add_body("a", cs.Sphere(0.5), position=(1.0, 2.0, 3.0))
    world.add_body("b", cs.Sphere(0.5), position=(1.0, 2.0, 4.0))
    world.add_body("c", cs.Sphere(0.5), position=(5.0, 0.0, 0.0))
    contacts = cs.Contacts(body_a=np.array([0, 0]), body_b=np.array([1, 1]),
                           point=np.array([[1.0, 2.0, 3.5], [1.5, 2.0, 3.5]]), normal=np.tile([0.0, 0.0, 1.0], (2, 1)),
                           depth=np.zeros(2), impulse=np.array([[0.0, 0.0, -2.0], [0.5, 0.0, -1.0]]),
                           normal_impulse=np.array([2.0, 1.0]), friction_impulse=np.zeros((2, 3)),
                           relative_normal_velocity=np.zeros(2), feature=np.zeros(2, np.int64),
                           feature_id=np.zeros(2, np.int64))
    _, _, wrenches = blocks(state_rows(world, contacts, 0.5), 3)
    fa = np.array([0.5, 0.0, -3.0]) / 0.5
    ta = (np.cross([0.0, 0.0, 0.5], [0.0, 0.0, -2.0]) + np.cross([0.5, 0.0, 0.5], [0.5, 0.0, -1.0])) / 0.5
    tb = -(np.cross([0.0, 0.0, -0.5], [0.0, 0.0, -2.0]) + np.cross([0.5, 0.0, -0.5], [0.5, 0.0, -1.0])) / 0.5
    np.testing.assert_allclose(wrenches[0], np.r_[fa, ta], rtol=0, atol=1e-15)
    np.testing.assert_allclose(wrenches[1], np.r_[-fa, tb], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(wrenches[2], 0.0)


def test_no_contacts_give_zero_wrenches_and_an_empty_world_no_rows():
    world = _pile(True)
    _, _, wrenches = blocks(state_rows(world, None), len(world))
    np.testing.assert_array_equal(wrenches, 0.0)
    assert state_rows(cs.World(), None).shape == (0,)
