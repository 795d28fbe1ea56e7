"""Closed-form answers of the accuracy studies' reference scenes (independent of the engine).

Each function takes a scene's parameters (SI units: m, s, kg, m/s²) and returns the exact quantity
a ``reference`` recorder (``runner.py``) compares the simulation with. They are written once, here:
``bench/exact.py`` takes them from this module.
"""
import numpy as np


def bouncing_height(t, h0, radius, e, g):
    """Centre height ``(T,)`` at times ``t (T,)`` (s) of a ball dropped from rest at centre height
    ``h0`` (m) onto ``z = 0``, bouncing with restitution ``e`` under gravity ``g`` (m/s²), each
    flight in closed form; at rest on the ground once the bounces' speed is below 1e-12 m/s."""
    t = np.asarray(t, float)
    z = np.empty_like(t)
    t1 = np.sqrt(2 * (h0 - radius) / g)
    first = t <= t1
    z[first] = h0 - 0.5 * g * t[first] ** 2
    tb, ub = t1, e * g * t1
    todo = ~first
    while todo.any() and ub > 1e-12:
        flight = 2 * ub / g
        here = todo & (t <= tb + flight)
        s = t[here] - tb
        z[here] = radius + ub * s - 0.5 * g * s * s
        todo &= ~here
        tb, ub = tb + flight, e * ub
    z[todo] = radius
    return z


def head_on(t, x1, x2, v1, v2, m1, m2, r1, r2, e):
    """Positions ``(T,), (T,)`` (m, along the line) at times ``t (T,)`` of two spheres on a line,
    centres ``x1 < x2``, velocities ``v1 > v2`` (approaching), masses ``m1, m2``, radii ``r1, r2``,
    colliding once with restitution ``e`` (momentum kept, separation speed ``e`` × approach speed)
    and no other force; and the time of the collision ``t_c`` (s)."""
    t = np.asarray(t, float)
    tc = ((x2 - x1) - (r1 + r2)) / (v1 - v2)
    u1 = (m1 * v1 + m2 * v2 - m2 * e * (v1 - v2)) / (m1 + m2)
    u2 = (m1 * v1 + m2 * v2 + m1 * e * (v1 - v2)) / (m1 + m2)
    before = t <= tc
    p1 = np.where(before, x1 + v1 * t, x1 + v1 * tc + u1 * (t - tc))
    p2 = np.where(before, x2 + v2 * t, x2 + v2 * tc + u2 * (t - tc))
    return p1, p2, tc


def rod_impact(corners_world, com, velocity, mass, inv_inertia_world, e, g):
    """A non-rotating body (corners ``(K, 3)`` and centre of mass ``com (3,)`` in the world, m)
    falling with ``velocity (3,)`` (m/s) under gravity ``g`` along −z hits ``z = 0`` with its lowest
    corner. Returns ``(t_c, v_plus (3,), L_plus (3,))``: time of impact (s), and linear velocity
    (m/s) and angular momentum about the centre of mass (kg m²/s) just after it, by the lecture's
    impulse formula ``j = −(1+e) v_rel / (1/M + n·(I⁻¹(r×n))×r)`` with the ground as infinite mass
    (``inv_inertia_world (3, 3)``: the body's world-frame inverse inertia)."""
    z0 = corners_world[:, 2].min()
    k = np.argmin(corners_world[:, 2])
    vz = velocity[2]
    tc = (vz + np.sqrt(vz * vz + 2 * g * z0)) / g
    v_minus = velocity + np.array([0, 0, -g * tc])
    n = np.array([0.0, 0.0, 1.0])
    r = corners_world[k] - com
    v_rel = v_minus @ n
    j = -(1 + e) * v_rel / (1 / mass + n @ np.cross(inv_inertia_world @ np.cross(r, n), r))
    return tc, v_minus + j * n / mass, np.cross(r, j * n)


def sliding_stop_distance(v0, mu, g):
    """Distance ``v0²/(2 μ g)`` (m) a block launched at ``v0`` (m/s) slides on level ground before
    Coulomb friction ``μ`` stops it."""
    return v0 * v0 / (2 * mu * g)


def incline_acceleration(theta, mu, g):
    """Acceleration ``g (sin θ − μ cos θ)`` (m/s²) of a block sliding down an incline of angle
    ``theta`` (rad) with Coulomb friction ``μ`` (0 if it sticks: ``tan θ <= μ``)."""
    return max(g * (np.sin(theta) - mu * np.cos(theta)), 0.0)


def penalty_rest_depth(mass, g, stiffness):
    """Rest penetration ``m g / k`` (m) of a body of ``mass`` (kg) held by a penalty spring of
    ``stiffness`` (N/m) against gravity ``g`` (m/s², the component along the contact normal)."""
    return mass * g / stiffness


def damping_for_restitution(e, k, m):
    """Damping ``2 ζ √(k m)`` (N s/m) of a linear spring–damper (stiffness ``k`` N/m, mass ``m``
    kg) whose bounce has restitution ``e``: ζ from ``e = exp(−ζπ/√(1−ζ²))`` (the accuracy study's
    penalty model of the bouncing ball, e 0.8)."""
    a = -np.log(e) / np.pi
    zeta = a / np.sqrt(1 + a * a)
    return 2 * zeta * np.sqrt(k * m)
