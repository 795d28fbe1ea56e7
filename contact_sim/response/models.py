"""Which response / time-of-impact / friction / resting model a world uses, and why.

``choose(world, dt)`` resolves every ``auto`` setting from the scene itself (cheapest adequate
model); ``describe(world)`` turns the choice into sentences; ``preflight(world)`` returns the
warnings users of other engines ask for (mass ratio, thin-and-fast, stiff penalty).
"""
import math
import warnings
from dataclasses import dataclass, field
from operator import is_

import numpy as np

from .. import validate
from ..jit import njit
from ..kinds import DYNAMIC, KINEMATIC
from ..memo import derived
from ..shapes import Sphere
from ..constants import PENALTY_OMEGA_DT_LIMIT, FRACTIONAL_AUTO_MAX_BODIES, FRICTION_CREEP_LIMIT


class ContactModelWarning(UserWarning):
    """A preflight warning about the chosen contact models (mass ratio, tunnelling, stiffness)."""


class PenaltyStiffnessWarning(ContactModelWarning):
    """Penalty stiffness too high for the step size to resolve the spring's oscillation (stable, as
    the spring is integrated implicitly, but its elastic bounce is damped away)."""


class PenaltyFrictionWarning(ContactModelWarning):
    """Penalty friction's regularisation speed lets a body that friction should hold creep: up to
    ``settings.penalty.friction_velocity`` at the friction angle (the regularised damper is
    integrated implicitly, so it is stable at any step; the price of a large regulariser is creep)."""


class TunnellingWarning(ContactModelWarning):
    """A body moves more than the thinnest size it can meet in one step without swept detection."""


class MassRatioWarning(ContactModelWarning):
    """Mass ratio between two bodies that can touch is above ``settings.mass_ratio_limit``."""


@dataclass
class Models:
    response: str
    toi: str
    friction: bool
    resting: bool
    rotation: bool
    reasons: list = field(default_factory=list)
    continuous: tuple = ()   # next_step with a time-of-impact search for these bodies only (the fast ones)


def _can_touch(world):
    """Boolean ``(N,N)`` matrix of body pairs that can touch (masks agree, one is dynamic)."""
    g, m = world.group, world.mask
    ok = ((g[:, None] & m[None, :]) != 0) & ((g[None, :] & m[:, None]) != 0)
    dyn = world.kind == DYNAMIC
    ok &= dyn[:, None] | dyn[None, :]
    np.fill_diagonal(ok, False)
    return ok


def _shape_info(world):
    """Per-world shape facts cached across steps (rebuilt when bodies are added: the shape list only
    grows, or kinds change): ``(thinnest (N,), dynamic bodies all spheres, thinnest finite size,
    limit (N,))`` with ``limit`` the thinnest size each body can meet (its own or the thinnest
    finite body's, whichever is smaller)."""
    return derived(world, "shape_info", _body_deps(world), lambda: _build_shape_info(world),
                   key=world.kind.tobytes())


def _body_deps(world):
    """What says the bodies changed: the last shape and the kind array (replaced by ``add_body``)."""
    return (world.shapes[-1] if len(world) else None, world.kind)


def _build_shape_info(world):
    n = len(world)
    thin = np.array([sh.thinnest() for sh in world.shapes]) if n else np.zeros(0)
    dyn = world.kind == DYNAMIC
    spheres = all(isinstance(world.shapes[i], Sphere) for i in np.flatnonzero(dyn))
    finite = np.isfinite(thin)
    thinnest = float(thin[finite].min()) if finite.any() else np.inf
    return thin, spheres, thinnest, np.minimum(thin, thinnest)


def body_thinness(world):
    """Each body's thinnest size ``(N,)`` (m; ``inf`` for a plane)."""
    return _shape_info(world)[0]


def step_travel(world, dt):
    """Distance ``(N,)`` each body can travel in one step at its current speed under gravity."""
    v = world.s.vel
    g = world.gravity_norm()
    return np.sqrt(np.einsum("ij,ij->i", v, v)) * dt + np.where(world.kind == DYNAMIC, 0.5 * g * dt * dt, 0.0)


def thin_and_fast(world, dt):
    """Bodies ``[(name, travel, thinnest)]`` that move farther in a step than the thinnest finite
    body they could meet (themselves included)."""
    if len(world) == 0:
        return []
    limit = _shape_info(world)[3]
    if not _any_too_fast(world.s.vel, world.kind, limit, world.gravity_norm(), float(dt)):
        return []   # the usual step: one compiled pass, no arrays
    travel = step_travel(world, dt)
    bad = np.flatnonzero((world.kind == DYNAMIC) & (travel > limit))
    return [(world.body_names[i], float(travel[i]), float(limit[i])) for i in bad]


@njit(_nrt=False)
def _any_too_fast(vel, kind, limit, g, dt):
    """Whether a dynamic body's ``step_travel`` exceeds its ``limit (N,)``."""
    for i in range(vel.shape[0]):
        if kind[i] == DYNAMIC and math.sqrt(vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) * dt \
                + 0.5 * g * dt * dt > limit[i]:
            return True
    return False


def choose(world, dt=None):
    """Resolve the ``auto`` settings of ``world`` for a step of ``dt`` (default ``settings.dt``).

    The choice depends on the settings, the bodies (kinds, shapes, materials) and, for an ``auto``
    time of impact, on whether a body is thin-and-fast this step; it is cached on the world and
    recomputed when any of these changes (the velocity test runs every call). Treat the returned
    ``Models`` as read-only."""
    st = world.settings
    dt = st.dt if dt is None else dt
    models, limit = _kept_models(world, st, dt)
    if st.toi != "auto" or not _any_too_fast(world.s.vel, world.kind, limit, world.gravity_norm(), float(dt)):
        return models
    return _choose(world, dt, thin_and_fast(world, dt))   # this step's speeds decide (swept): not kept


def _kept_models(world, st, dt):
    """``(models, limit)``: the models when no body is thin-and-fast (``_choose``), and the limits
    ``(N,)`` (m) the velocity test reads. Kept on the world while the settings object is the same
    and no settings field was assigned since (``validate.edits``), ``dt`` is equal, the bodies are
    the same (the last shape, the kind array, equal kinds) and so are the material arrays; one
    check of those a step instead of reading every field the choice depends on."""
    kind = world.kind
    deps = (world.shapes[-1] if len(world) else None, kind, world.friction, world.restitution, world.particle,
            world.stiffness, world.damping_ratio)
    hit = world._derived.get("models")
    if (hit is not None and hit[0] is st and hit[1] == validate.edits and hit[2] == dt and all(map(is_, hit[3], deps))
            and hit[4] == kind.tobytes()):
        return hit[5]
    edits = validate.edits
    kept = (_choose(world, dt, []), _shape_info(world)[3] if len(world) else np.zeros(0))
    world._derived["models"] = (st, edits, dt, deps, kind.tobytes(), kept)
    return kept


def _choose(world, dt, fast):
    st = world.settings
    dyn = world.kind == DYNAMIC
    reasons = []
    # friction
    if st.friction == "auto":
        friction = bool(np.any(world.friction[dyn] > 0)) if dyn.any() else False
        reasons.append(f"friction {'on' if friction else 'off'}: "
                       + ("a dynamic body's material has friction > 0" if friction else "no dynamic material has friction"))
    else:
        friction = bool(st.friction)
        reasons.append(f"friction {'on' if friction else 'off'}: set by the scene")
    # response
    if st.response == "auto":
        if dyn.any() and np.all(world.particle[dyn]):
            response = "kinematic"
            reasons.append("response kinematic: every dynamic body is a particle (no rotation, no inertia)")
        else:
            response = "impulse"
            reasons.append("response impulse: rigid bodies with rotation")
    else:
        response = st.response
        reasons.append(f"response {response}: set by the scene")
    # rotation work
    spheres_only = _shape_info(world)[1]
    rigid = dyn & ~world.particle
    rotation = bool(rigid.any()) and response != "kinematic" and not (spheres_only and not friction)
    if not rotation and rigid.any() and response != "kinematic":
        reasons.append("rotation skipped in responses: frictionless spheres (contact forces pass through the centre)")
    # time of impact
    continuous = ()
    if st.toi == "auto":
        # a few bodies: continuous time of impact for the whole world is cheap
        few = len(world) <= FRACTIONAL_AUTO_MAX_BODIES and dyn.sum() <= 4
        if fast and few:
            toi = "swept"
            reasons.append(f"time of impact swept: {fast[0][0]} moves {fast[0][1]:.3g} m per step, more than "
                           f"the thinnest size it can meet ({fast[0][2]:.3g} m)")
        elif fast:
            # the continuous test applies to the bodies that need it: the rest of a big world keeps
            # next_step (sub-stepping everything at every impact of one fast body cost seconds a step)
            toi = "next_step"
            continuous = tuple(world.index(name) for name, _, _ in fast)
            reasons.append(f"time of impact next_step, continuous for {len(fast)} bod{'y' if len(fast) == 1 else 'ies'} "
                           f"that move more than the thinnest size they can meet in a step ({fast[0][0]} moves "
                           f"{fast[0][1]:.3g} m, more than {fast[0][2]:.3g} m)")
        elif few and response != "penalty":
            toi = "fractional"
            reasons.append("time of impact fractional: a few bodies, exact impact times are cheap")
        else:
            toi = "next_step"
            reasons.append("time of impact next_step: no body moves more than the thinnest size in a step")
    else:
        toi = st.toi
        reasons.append(f"time of impact {toi}: set by the scene")
    if response == "penalty" and toi != "next_step":
        reasons.append("penalty forces act on penetration: time of impact is handled at the next step")
        toi = "next_step"
    if toi == "next_step" and response != "penalty":
        if st.speculative:
            reasons.append("speculative contacts on (next_step): pairs that can close within a step (look-ahead "
                           "2·speed·dt, at most half the thinnest body) are slowed to arrive exactly touching")
    # compliant contacts (response.compliance): rows of the resting solve
    soft_materials = int(np.count_nonzero(world.stiffness > 0))
    soft_kinematic = st.kinematic_stiffness > 0 and bool(np.any(world.kind == KINEMATIC))
    compliant = response == "impulse" and (soft_materials > 0 or soft_kinematic)
    # resting
    if st.resting == "auto":
        lone = int(dyn.sum()) == 1 and response != "penalty"
        bouncy = lone and np.all(world.restitution[dyn] >= 1.0)   # e < 1: it comes to rest in finite time
        lone_sphere = lone and spheres_only and not friction
        resting = (not (bouncy and lone_sphere) or compliant) and response != "penalty"
        reasons.append("resting-contact solver " + ("off: a lone elastic (e = 1) body never comes to rest, impacts suffice" if not resting and response != "penalty"
                                                    else "off: penalty forces hold bodies" if response == "penalty"
                                                    else "on: compliant contacts are rows of the resting solve" if compliant and bouncy and lone_sphere
                                                    else "on: bodies can rest on each other"))
    else:
        resting = bool(st.resting) and response != "penalty"
        reasons.append(f"resting-contact solver {'on' if resting else 'off'}: set by the scene")
    if compliant and resting:
        parts = []
        if soft_kinematic:
            parts.append(f"contacts with a kinematic body {st.kinematic_stiffness:.3g} N/m (settings.kinematic_stiffness)")
        if soft_materials:
            parts.append(f"{soft_materials} bod{'y' if soft_materials == 1 else 'ies'} of a compliant material "
                         f"(springs in series)")
        reasons.append("compliant contacts: " + ", ".join(parts) + " per touching pair (shared by its points), damping ratio "
                       + _ratios(world) + " (1: critical); the others rigid")
    elif compliant:
        reasons.append("compliant contacts off: they are rows of the resting solve, which the scene turned off")
    else:
        reasons.append("contacts rigid: no material has a stiffness" + (" and settings.kinematic_stiffness is 0"
                                                                       if np.any(world.kind == KINEMATIC) else ""))
    return Models(response, toi, friction, resting, rotation, reasons, continuous)


def _ratios(world):
    """The damping ratios of the world's materials, as text."""
    z = np.unique(world.damping_ratio)
    return ", ".join(f"{v:.3g}" for v in z[:4]) + (" ..." if len(z) > 4 else "")


def describe(world):
    """Sentences (``list[str]``) saying which models the world uses and why, plus the preflight
    warnings."""
    m = choose(world)
    return m.reasons + [f"warning: {w}" for _, w in preflight(world, m)]


def _effective_masses(world):
    """Lightest effective mass of a pair that can touch ``(m_eff, i, j)``."""
    touch = _can_touch(world)
    if not touch.any():
        return None
    m = np.where(world.kind == DYNAMIC, world.mass, np.inf)
    inv = np.where(np.isfinite(m), 1.0 / m, 0.0)
    meff = 1.0 / np.maximum(inv[:, None] + inv[None, :], 1e-300)
    meff = np.where(touch, meff, np.inf)
    k = np.argmin(meff)
    i, j = np.unravel_index(k, meff.shape)
    return float(meff[i, j]), int(i), int(j)


def preflight(world, models=None, dt=None):
    """Warnings ``[(category, message)]`` about the scene and its models."""
    m = choose(world, dt) if models is None else models
    dt = world.settings.dt if dt is None else dt
    out = []
    names = world.body_names
    if len(world) and len(world) <= 2000:
        touch = _can_touch(world)
        dyn2 = touch & (world.kind == DYNAMIC)[:, None] & (world.kind == DYNAMIC)[None, :]
        if dyn2.any():
            mass = world.mass
            ratio = np.divide(mass[:, None], mass[None, :], out=np.zeros(dyn2.shape), where=dyn2)
            k = np.argmax(ratio)
            i, j = np.unravel_index(k, ratio.shape)
            limit = world.settings.mass_ratio_limit
            if ratio[i, j] > limit:
                out.append((MassRatioWarning,
                            f"mass ratio {ratio[i, j]:.3g} between {names[i]!r} and {names[j]!r} (above "
                            f"{limit:g}): iterative contact solvers converge slowly"))
    if m.toi == "next_step":   # fractional and swept are continuous (see response.toi): nothing passes
        for name, travel, thin in thin_and_fast(world, dt):
            if world.index(name) in m.continuous:   # auto gave it its own time-of-impact search
                continue
            out.append((TunnellingWarning,
                        f"{name!r} moves {travel:.3g} m per step, more than the thinnest size it can meet "
                        f"({thin:.3g} m), without swept or fractional time of impact (toi {m.toi}): it can pass through"))
    if m.response == "penalty":
        em = _effective_masses(world)
        if em is not None:
            meff, i, j = em
            omega_dt = np.sqrt(world.settings.penalty.stiffness / meff) * dt
            if omega_dt > PENALTY_OMEGA_DT_LIMIT:
                out.append((PenaltyStiffnessWarning,
                            f"penalty stiffness {world.settings.penalty.stiffness:g} N/m is too high for dt "
                            f"{dt:.4g} s between {names[i]!r} and {names[j]!r}: sqrt(k/m)·dt = {omega_dt:.3g} "
                            f"(resolved below {PENALTY_OMEGA_DT_LIMIT:g}); the spring is integrated implicitly, "
                            f"so it stays stable, but its bounce is damped away: lower k or dt for an elastic "
                            f"contact"))
        vr = world.settings.penalty.friction_velocity
        if m.friction and vr > FRICTION_CREEP_LIMIT:
            out.append((PenaltyFrictionWarning,
                        f"penalty friction_velocity {vr:g} m/s is above {FRICTION_CREEP_LIMIT:g} m/s: bodies that "
                        f"friction holds creep at up to friction_velocity·tan(slope)/mu (that speed at the friction "
                        f"angle); lower it (the regularised friction is implicit, so any value is stable)"))
    return out


def warn_preflight(world, models=None, dt=None):
    """Issue the preflight warnings with ``warnings.warn`` (categories above)."""
    for cat, msg in preflight(world, models, dt):
        warnings.warn(msg, cat, stacklevel=3)
