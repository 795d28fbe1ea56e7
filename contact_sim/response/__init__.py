"""Collision response and time of impact (issue 4).

* ``solver``  — contact rows, the exact active-set solve and projected Gauss–Seidel (pure functions
  of body arrays and contact arrays); ``pgs`` — the compiled Gauss–Seidel sweeps;
* ``toi``     — time of impact: closed forms, bracket + Brent, swept test;
* ``models``  — ``auto`` model choice, ``describe`` and preflight warnings.

The step pipeline that uses them is ``contact_sim.stepper``.
"""
from .models import (ContactModelWarning, MassRatioWarning, PenaltyStiffnessWarning, TunnellingWarning,
                     choose, describe, preflight)
from .solver import build_rows, row_velocity, solve

__all__ = ["ContactModelWarning", "MassRatioWarning", "PenaltyStiffnessWarning", "TunnellingWarning",
           "build_rows", "choose", "describe", "preflight", "row_velocity", "solve"]
