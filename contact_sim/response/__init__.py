"""Collision response and time of impact (issue 4).

* ``solver``  — contact rows, graph colouring, projected Gauss–Seidel impulses (pure functions of
  body arrays and contact arrays);
* ``toi``     — time of impact: closed forms, bracket + Brent, swept test;
* ``models``  — ``auto`` model choice, ``describe`` and preflight warnings;
* ``kinematic`` — the kinematic response ``v − (1+k)(N·v)N``; ``swept`` — swept-volume time of impact;
  ``penalty_friction`` — regularised Coulomb friction of the penalty response.

The step pipeline that uses them is ``contact_sim.stepper``.
"""
from .models import (ContactModelWarning, MassRatioWarning, PenaltyFrictionWarning, PenaltyStiffnessWarning,
                     TunnellingWarning,
                     choose, describe, preflight)
from .solver import build_rows, color_contacts, row_velocity, solve

__all__ = ["ContactModelWarning", "MassRatioWarning", "PenaltyFrictionWarning", "PenaltyStiffnessWarning",
           "TunnellingWarning",
           "build_rows", "choose", "color_contacts", "describe", "preflight", "row_velocity", "solve"]
