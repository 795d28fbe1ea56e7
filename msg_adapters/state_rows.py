"""The per-body rows a tick publishes, computed in one compiled pass.

``body_states`` and ``body_multidof_states`` carry, per body, the origin's pose, the origin's
twist and the net contact wrench. Built with numpy that was a dozen small array calls and a
``bincount`` per tick (~80 us for 100 bodies at 1 kHz, a fifth of the node's tick); here it is one
loop over the bodies and one over the contacts, writing the rows in the order the CDR sequences
lay them out, so the publishers take byte slices of one buffer. The arithmetic is the numpy
code's, operation for operation (``World.poses``, ``v + w x (p - com)``,
``conversions.contact_wrenches``), so the published bits do not change; a test checks that.

No ROS here: it imports only numpy and ``contact_sim.jit`` (plain Python without numba).
"""
import numpy as np

from contact_sim.jit import njit

#: doubles per body in each block: pose (x y z qx qy qz qw), twist (v, w), wrench (force, torque)
POSE, TWIST, WRENCH = 7, 6, 6


@njit
def _rows(pos, quat, com_local, offset, vel, omega, a, b, point, impulse, duration, out):
    """Fill ``out (19 N,)``: poses ``(N,7)``, then twists ``(N,6)``, then wrenches ``(N,6)``."""
    n = pos.shape[0]
    tw, wr = POSE * n, (POSE + TWIST) * n
    for i in range(n):
        qx, qy, qz, qw = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        if offset:   # World.poses: pos - rotate(q, com_local), rotate as quat.rotate writes it
            vx, vy, vz = com_local[i, 0], com_local[i, 1], com_local[i, 2]
            tx, ty, tz = 2.0 * (qy * vz - qz * vy), 2.0 * (qz * vx - qx * vz), 2.0 * (qx * vy - qy * vx)
            px = px - (vx + qw * tx + (qy * tz - qz * ty))
            py = py - (vy + qw * ty + (qz * tx - qx * tz))
            pz = pz - (vz + qw * tz + (qx * ty - qy * tx))
        o = POSE * i
        out[o], out[o + 1], out[o + 2] = px, py, pz
        out[o + 3], out[o + 4], out[o + 5], out[o + 6] = qx, qy, qz, qw
        # the origin's velocity: v + w x (p - com)
        dx, dy, dz = px - pos[i, 0], py - pos[i, 1], pz - pos[i, 2]
        wx, wy, wz = omega[i, 0], omega[i, 1], omega[i, 2]
        o = tw + TWIST * i
        out[o] = vel[i, 0] + (wy * dz - wz * dy)
        out[o + 1] = vel[i, 1] + (wz * dx - wx * dz)
        out[o + 2] = vel[i, 2] + (wx * dy - wy * dx)
        out[o + 3], out[o + 4], out[o + 5] = wx, wy, wz
    # wrenches: each contact's (j, r x j) about A's origin added to A, about B's origin to a sum for
    # B subtracted at the end, in contact order: contact_wrenches' two bincounts, bit for bit
    k = a.shape[0]
    on_b = np.zeros((n, WRENCH))
    on_a = np.zeros((n, WRENCH))
    for c in range(k):
        j0, j1, j2 = impulse[c, 0] / duration, impulse[c, 1] / duration, impulse[c, 2] / duration
        for side in range(2):
            body = a[c] if side == 0 else b[c]
            acc = on_a if side == 0 else on_b
            o = POSE * body
            r0, r1, r2 = point[c, 0] - out[o], point[c, 1] - out[o + 1], point[c, 2] - out[o + 2]
            acc[body, 0] += j0
            acc[body, 1] += j1
            acc[body, 2] += j2
            acc[body, 3] += r1 * j2 - r2 * j1
            acc[body, 4] += r2 * j0 - r0 * j2
            acc[body, 5] += r0 * j1 - r1 * j0
    for i in range(n):
        for x in range(WRENCH):
            out[wr + WRENCH * i + x] = on_a[i, x] - on_b[i, x]


_NO_CONTACTS = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))


def state_rows(world, contacts=None, duration=1.0):
    """Every body's origin pose, origin twist and net contact wrench over ``duration`` seconds, as
    one float64 array ``(19 N,)``: poses ``(N, 7)`` (x y z qx qy qz qw), then twists ``(N, 6)``
    (linear, angular; world frame), then wrenches ``(N, 6)`` (force, torque about the origin;
    zero without ``contacts``), each block C-ordered. ``world.poses()``, the twist the node
    publishes and ``conversions.contact_wrenches``, the same bits."""
    s = world.s
    n = len(s.pos)
    out = np.empty((POSE + TWIST + WRENCH) * n)
    if contacts is None or not len(contacts):
        a, b, point, impulse = _NO_CONTACTS
    else:
        a, b, point, impulse = contacts.body_a, contacts.body_b, contacts.point, contacts.impulse
    com = world.com_local
    _rows(s.pos, s.quat, com, bool(com.any()), s.vel, s.omega, a, b, point, impulse, float(duration), out)
    return out


@njit
def contact_rows(point, normal, depth, impulse, normal_impulse, friction_impulse, relative_normal_velocity, body_a,
                 body_b, feature, xyz, f8, u4):
    """Fill one contact per row of the node's contact cloud: ``xyz (K,3) float32`` (the point for
    display; beyond float32's range inf, as numpy's cast), ``f8 (K,15)`` the float64 columns in
    ``conversions.CONTACT_FIELDS``' order, ``u4 (K,3) uint32`` body_a, body_b, feature. The three
    are strided views of one structured array (``conversions.contacts_to_array``): ten numpy
    assignments cost ~18 us for 100 contacts, this loop ~2."""
    for c in range(point.shape[0]):
        for x in range(3):
            xyz[c, x] = point[c, x]
            f8[c, x] = point[c, x]
            f8[c, 3 + x] = normal[c, x]
            f8[c, 7 + x] = impulse[c, x]
            f8[c, 11 + x] = friction_impulse[c, x]
        f8[c, 6] = depth[c]
        f8[c, 10] = normal_impulse[c]
        f8[c, 14] = relative_normal_velocity[c]
        u4[c, 0] = body_a[c]
        u4[c, 1] = body_b[c]
        u4[c, 2] = feature[c]


def blocks(rows, n):
    """``state_rows``' buffer as its three blocks ``(poses (N,7), twists (N,6), wrenches (N,6))``."""
    tw, wr = POSE * n, (POSE + TWIST) * n
    return rows[:tw].reshape(n, POSE), rows[tw:wr].reshape(n, TWIST), rows[wr:].reshape(n, WRENCH)


def warm_up():
    """Compile (or load from numba's cache) this module's kernels: ``python -m msg_adapters.state_rows``
    (``make venv`` and the colcon install run it beside ``contact_sim.warmup``)."""
    import contact_sim as cs

    world = cs.World()
    world.add_body("ground", cs.Plane(), kind="static")
    world.add_body("ball", cs.Sphere(0.1), position=(0.0, 0.0, 0.09))
    world.step()
    c = world.contacts
    state_rows(world, c, world.settings.dt)
    xyz, f8, u4 = np.zeros((len(c), 3), np.float32), np.zeros((len(c), 15)), np.zeros((len(c), 3), np.uint32)
    contact_rows(c.point, c.normal, c.depth, c.impulse, c.normal_impulse, c.friction_impulse,
                 c.relative_normal_velocity, c.body_a, c.body_b, c.feature, xyz, f8, u4)


if __name__ == "__main__":
    warm_up()
