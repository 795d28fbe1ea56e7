"""Closed-form answers for the reference scenes of the accuracy study (independent of the engine).

Each function takes the scene's parameters and returns the exact quantity the study compares with.
"""
import numpy as np

from contact_sim.study.runner import bouncing_height  # noqa: F401  (a closed form; the accuracy study's too)


def head_on(t, x1, x2, v1, v2, m1, m2, r1, r2, e):
    """Positions ``(T,), (T,)`` of two spheres on a line colliding once with restitution ``e``."""
    t = np.asarray(t, float)
    tc = ((x2 - x1) - (r1 + r2)) / (v1 - v2)
    u1 = (m1 * v1 + m2 * v2 - m2 * e * (v1 - v2)) / (m1 + m2)
    u2 = (m1 * v1 + m2 * v2 + m1 * e * (v1 - v2)) / (m1 + m2)
    before = t <= tc
    p1 = np.where(before, x1 + v1 * t, x1 + v1 * tc + u1 * (t - tc))
    p2 = np.where(before, x2 + v2 * t, x2 + v2 * tc + u2 * (t - tc))
    return p1, p2, tc


def rod_impact(corners_world, com, velocity, mass, inv_inertia_world, e, g):
    """A non-rotating body falling with ``velocity (3,)`` hits ``z = 0`` with its lowest corner.

    Returns ``(t_c, v_plus (3,), L_plus (3,))``: time of impact, and linear velocity and angular
    momentum (about the centre of mass) just after it, by the lecture's impulse formula
    ``j = −(1+e) v_rel / (1/M + n·(I⁻¹(r×n))×r)`` with the ground as infinite mass.
    """
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
    """Distance ``v0²/(2 μ g)`` a block slides on level ground before Coulomb friction stops it."""
    return v0 * v0 / (2 * mu * g)


def incline_acceleration(theta, mu, g):
    """Acceleration ``g (sin θ − μ cos θ)`` of a block sliding down an incline (0 if it sticks)."""
    return max(g * (np.sin(theta) - mu * np.cos(theta)), 0.0)


def penalty_rest_depth(mass, g, stiffness):
    """Rest penetration ``m g / k`` of a body held by a penalty spring."""
    return mass * g / stiffness
