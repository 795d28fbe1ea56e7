"""Collision response and time of impact.

* ``rows``    — contact constraint rows and their velocity algebra;
* ``solver``  — the solve by size: ``direct`` (the exact active set) or projected Gauss–Seidel
  (``pgs``: the compiled sweeps and row set-up), pure functions of body and contact arrays;
* ``toi``     — time of impact: closed forms, bracket + Brent, swept test;
* ``models``  — ``auto`` model choice, ``describe`` and preflight warnings;
* ``kinematic`` — the kinematic response ``v − (1+k)(N·v)N``; ``swept`` — swept-volume time of impact;
  ``penalty`` — the penalty response's springs, dampers and regularised Coulomb friction.

``substep`` sequences the stages' kernels (``prepare``, ``impact``, ``resting``, ``correction``,
``penalty``) as one compiled call per sub-step; ``contact_sim.stepper`` runs detection, the time of
impact and the sub-steps.
"""
from .models import (ContactModelWarning, MassRatioWarning, PenaltyFrictionWarning, PenaltyStiffnessWarning,
                     TunnellingWarning,
                     choose, describe, preflight)
from .solver import build_rows, row_velocity, solve

__all__ = ["ContactModelWarning", "MassRatioWarning", "PenaltyFrictionWarning", "PenaltyStiffnessWarning",
           "TunnellingWarning", "build_rows", "choose", "describe", "preflight", "row_velocity", "solve"]
