"""Compliant contact: a contact with a stiffness enters the resting solve as a regularised row.

A rigid contact has no answer where a body cannot yield: a cube squeezed between two kinematic
fingers, or between a kinematic pusher and a wall, overlaps by what the geometry fixes, and a rigid
solve (and the position correction after it) pushes the cube out sideways. A compliant contact
has one bounded answer: a spring of stiffness ``k`` (N/m) and a damper ``c`` (N·s/m) along the
normal, never pulling, the model of MuJoCo's soft constraints, Drake's compliant contact and Box2D
v3's soft step.

Over the resting interval ``T`` the step's velocity changes linearly (the kick–drift–kick of the
advance stage), so a contact that starts ``d`` deep (m, > 0 overlapping) with normal velocity
``v₀`` (m/s, > 0 separating) ends ``d − T (v₀ + v⁺)/2`` deep. The force on that end depth and
the end velocity ``v⁺``, ``F = k (d − T (v₀ + v⁺)/2) − c v⁺ ≥ 0``, over the interval is the
impulse ``λ = T F``; rearranged, the row of the solve (exact active set and Gauss–Seidel alike)::

    v⁺ + γ λ ≥ b  ⟂  λ ≥ 0,    γ = 1 / (T (T k/2 + c)),    b = T k (d − T v₀/2) / (T (T k/2 + c))

The damper takes energy out; ``c = 2 ζ √(k m)`` with ``m = 1/K_nn`` the contact's effective mass
along its normal and ``ζ`` the damping ratio (1: critical, no rebound), so one ``ζ`` means the
same for a finger on a 20 g part and on a 20 kg one.

A speculative contact (apart at the interval's start, ``d < 0``) meets no damper and half the
spring, ``F = (k/2)·(d − T (v₀ + v⁺)/2) ≥ 0`` (``γ = 4 / (T² k)``, ``b = 2d/T − v₀``: the rigid
speculative row, softened): the mean force of a spring that grows from nothing at touching. The
full spring over the whole interval would do more work than it stores (up to ``½ k d²`` for a
gap ``d``); this half never does, since ``−F (d − d_end) ≥ ½ k d_end²`` for ``d ≤ 0``. Inside (``d ≥ 0``) the spring's work on the end depth is the
energy it releases, ``½ k (d² − d_end²)``, less ``½ k (d − d_end)²`` (the step's loss); the damper
acts on the end velocity. A compliant contact takes no impact (no restitution: the damper decides its rebound) and no
position correction (its overlap is the spring's deflection, which the force needs).

Stiffness of a pair of bodies in contact: the two materials' ``stiffness`` as springs in series,
``k_a k_b / (k_a + k_b)`` (a rigid material adds no spring of its own: the other's alone); with
neither material compliant, ``settings.kinematic_stiffness`` for a contact with a kinematic body
(robot fingers and pads), rigid otherwise. The pair's points share it (``k / n`` each of ``n``
points): a pad pressed ``d`` into a face pushes with ``k·d`` whether the manifold holds one point
or four. The damping ratio is the materials' combined by ``settings.combine``. Each point's
``m`` and ``c`` are its own.

The step integrates the spring on its end depth (backward Euler in the force, as Drake's and
Box2D's soft contacts do): stable for any stiffness, and it damps what the step cannot resolve,
a loss of order ``ω T`` per contact (``ω = √(k/m)``): an undamped floor (``ζ = 0``) returns 61 % of
a drop's height at ``ω T = 0.4``, 88 % at 0.1, 97 % at 0.026, converging to all of it.
"""
import math

import numpy as np

from ..jit import njit
from ..kinds import KINEMATIC
from ..memo import derived
from ..settings import combine_pair


@njit
def stiffness_rows(a, b, depth, touch, stiffness, damping_ratio, kinematic, k_kinematic, rule, k_out, zeta_out):
    """Per contact ``a, b (K,)``: writes the stiffness ``k_out (K,)`` of each point (N/m, 0 rigid: the
    pair's stiffness shared by its points, so a face held at four points feels ``k`` × their mean
    depth, as one point would, and a manifold that gains or loses points does not jump; the points
    sharing it are those touching, ``depth (K,) ≥ −touch`` (the contact margin, m), and a speculative
    point apart takes a touching one's share) and damping ratio ``zeta_out (K,)`` from the bodies'
    ``stiffness, damping_ratio (N,)`` (0 stiffness: rigid material), ``kinematic (N,) bool`` and
    ``k_kinematic`` (``settings.kinematic_stiffness``), ``rule`` the index of ``settings.combine``.
    Returns how many contacts are compliant."""
    n_soft = 0
    k_pair = a.shape[0]
    # the points of each pair share its stiffness: how many the pair has (pairs by key a·N + b)
    key = np.empty(k_pair, np.int64)
    nb = stiffness.shape[0]
    for c in range(k_pair):
        key[c] = a[c] * nb + b[c]
    order = np.argsort(key, kind="mergesort")
    points = np.empty(k_pair, np.int64)
    i = 0
    while i < k_pair:
        j = i
        while j < k_pair and key[order[j]] == key[order[i]]:
            j += 1
        n = 0
        for r in range(i, j):
            n += depth[order[r]] >= -touch
        for r in range(i, j):
            points[order[r]] = max(n, 1)
        i = j
    for c in range(k_pair):
        ka, kb = stiffness[a[c]], stiffness[b[c]]
        if ka > 0.0 and kb > 0.0:
            k = ka * kb / (ka + kb)
        elif ka > 0.0:
            k = ka
        elif kb > 0.0:
            k = kb
        elif kinematic[a[c]] or kinematic[b[c]]:
            k = k_kinematic
        else:
            k = 0.0
        k_out[c] = k / points[c]
        zeta_out[c] = combine_pair(damping_ratio[a[c]], damping_ratio[b[c]], rule)
        n_soft += k > 0.0
    return n_soft


@njit(_nrt=False)
def soft_rows(ids, K, depth, vn, stiffness, zeta, T, target, compliance):
    """The compliant rows of the resting solve over an interval ``T`` (s): for row ``j`` of contact
    ``ids[j]`` with ``stiffness > 0``, writes its ``compliance[j] = γ`` and ``target[j] = b`` (module
    docstring) from the contact's effective mass ``1/K[c, 0, 0]``, ``depth`` (m) and normal velocity
    ``vn`` (m/s) at the interval's start; a rigid row's target is left as it is, its compliance 0."""
    for j in range(ids.shape[0]):
        c = ids[j]
        k = stiffness[c]
        knn = K[c, 0, 0]
        if k > 0.0 and knn > 0.0 and depth[c] >= 0.0:
            h = T * (0.5 * T * k + 2.0 * zeta[c] * math.sqrt(k / knn))
            compliance[j] = 1.0 / h
            target[j] = T * k * (depth[c] - 0.5 * T * vn[c]) / h
        elif k > 0.0 and knn > 0.0:   # apart: the mean of a spring that grows from 0 at touching
            compliance[j] = 4.0 / (T * T * k)
            target[j] = 2.0 * depth[c] / T - vn[c]
        else:
            compliance[j] = 0.0


def stored_energy(stiffness, depth):
    """Potential energy (J) of compliant contacts of ``stiffness (K,)`` (N/m per point, 0 rigid) at
    ``depth (K,)`` (m, > 0 overlapping): ``½ Σ k d²`` over the overlapping ones."""
    d = np.maximum(depth, 0.0)
    return float(0.5 * np.sum(stiffness * d * d))


def compliant_pairs(world, i, j):
    """``(P,) bool``: whether the contacts of the body pairs ``i, j (P,)`` are compliant when the
    step softens any (``possible``, the impulse response with resting contact): ``stiffness_rows``'
    rule, a material with a stiffness or, with ``settings.kinematic_stiffness``, a kinematic body."""
    soft = world.stiffness > 0
    kin = world.kind == KINEMATIC
    return soft[i] | soft[j] | ((kin[i] | kin[j]) & (world.settings.kinematic_stiffness > 0))


def possible(world):
    """Whether any contact of ``world`` can be compliant: a material with a stiffness, or
    ``settings.kinematic_stiffness`` with a kinematic body (else the step skips the stiffness rows).
    What the bodies decide is kept on the world while their arrays are the same."""
    soft_material, any_kinematic = derived(world, "compliant", (world.stiffness, world.kind), lambda: (
        bool(np.any(world.stiffness > 0)), bool(np.any(world.kind == KINEMATIC))))
    return soft_material or (any_kinematic and world.settings.kinematic_stiffness > 0)
