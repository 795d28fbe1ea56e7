"""The lecture's kinematic collision response: ``v ← v − (1 + k)(N·v)N``.

Negate the velocity's component along the contact normal ``N``, scaled by the damping factor ``k``
(``k = 1``: no energy lost; ``k = 0``: the normal component is removed). No forces, no rotation:
a body under the kinematic response is a particle and ``v`` is the velocity of its centre (the
stepper's ``_relative_velocity`` leaves a dynamic body's spin out).

``kinematic_response`` is the formula, vectorised; ``kinematic_impacts`` is what the stepper calls
for the impacts of a step under ``response: kinematic``: the formula applied to each touching,
approaching contact's relative velocity, fastest approach first, the change shared between the two
bodies in proportion to their inverse masses (all of it to the dynamic one against a static or
kinematic body, where it is the lecture's formula exactly). A contact that the earlier ones have
already turned away is not approaching any more and is left alone, so a particle landing on two
corners is reflected once.
"""
import numpy as np

from ..jit import njit


@njit
def reflect_row(V, i, N, j, k, out, o):
    """``out[o] = V[i] − (1 + k)(N[j]·V[i]) N[j]`` for rows of ``(n, 3)`` arrays (one contact)."""
    s = (1.0 + k) * (N[j, 0] * V[i, 0] + N[j, 1] * V[i, 1] + N[j, 2] * V[i, 2])
    for c in range(3):
        out[o, c] = V[i, c] - s * N[j, c]


@njit
def _response_rows(V, N, k, out):
    for i in range(V.shape[0]):
        reflect_row(V, i, N, i, k[i], out, i)
    return out


def kinematic_response(v, n, k):
    """The kinematic response ``v − (1 + k)(N·v)N``.

    ``v (..., 3)`` velocities (relative velocity of the contact, A's minus B's), ``n (..., 3)`` unit
    normals (B to A), ``k`` the damping factor, a number or ``(...)`` per row. Returns ``(..., 3)``.
    Applied as it stands (whether ``v`` approaches, ``N·v < 0``, is the caller's test)."""
    v = np.asarray(v, float)
    n = np.asarray(n, float)
    shape = np.broadcast_shapes(v.shape, n.shape)
    V = np.ascontiguousarray(np.broadcast_to(v, shape)).reshape(-1, 3)
    N = np.ascontiguousarray(np.broadcast_to(n, shape)).reshape(-1, 3)
    K = np.ascontiguousarray(np.broadcast_to(np.asarray(k, float), shape[:-1])).reshape(-1)
    return _response_rows(V, N, K, np.empty_like(V)).reshape(shape)


@njit
def _impacts(vel, inv_mass, a, b, normal, extra, k, order, lam):
    """Sequential kinematic impacts (see the module docstring); ``lam (K,)`` normal impulses on A."""
    vr, vo = np.empty((1, 3)), np.empty((1, 3))
    for q in range(order.shape[0]):
        i = order[q]
        ia, ib = a[i], b[i]
        w = inv_mass[ia] + inv_mass[ib]
        if w <= 0.0:
            continue
        for c in range(3):
            vr[0, c] = vel[ia, c] - vel[ib, c] + extra[i, c]
        vn = normal[i, 0] * vr[0, 0] + normal[i, 1] * vr[0, 1] + normal[i, 2] * vr[0, 2]
        if not vn < 0.0:
            continue
        reflect_row(vr, 0, normal, i, k[i], vo, 0)
        fa, fb = inv_mass[ia] / w, inv_mass[ib] / w
        for c in range(3):
            dv = vo[0, c] - vr[0, c]
            vel[ia, c] += fa * dv
            vel[ib, c] -= fb * dv
        lam[i] = -(1.0 + k[i]) * vn / w


@njit
def kinematic_impacts(vel, inv_mass, a, b, normal, rel_vel, k, which, lam):
    """Apply the kinematic response to the contacts ``which (K,) bool`` in place on ``vel (N, 3)``,
    fastest approach first (the impact stage's kernel, ``impact.impact_stage``, calls it).

    ``inv_mass (N,)`` zero for bodies that do not move; ``a, b (K,)`` the contacts' bodies,
    ``normal (K, 3)`` B to A, ``rel_vel (K, 3)`` the contacts' relative velocities before the impact
    (what they hold beyond ``vel[a] − vel[b]``, a driven body's spin, is kept), ``k (K,)`` damping
    factors. Writes the normal impulses on A (B gets their negative) into ``lam (K,)``, 0 where none
    acted."""
    n_k = a.shape[0]
    extra = np.empty((n_k, 3))
    for c in range(n_k):
        lam[c] = 0.0
        for x in range(3):
            extra[c, x] = rel_vel[c, x] - (vel[a[c], x] - vel[b[c], x])
    idx = np.flatnonzero(which)
    if idx.shape[0] == 0:
        return
    vn = np.empty(idx.shape[0])
    for j in range(idx.shape[0]):
        c = idx[j]
        vn[j] = normal[c, 0] * rel_vel[c, 0] + normal[c, 1] * rel_vel[c, 1] + normal[c, 2] * rel_vel[c, 2]
    order = idx[np.argsort(vn, kind="mergesort")]      # fastest approach first
    _impacts(vel, inv_mass, a, b, normal, extra, k, order, lam)
