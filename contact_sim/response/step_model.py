"""What the scene fixes for a step, as one object the compiled step reads (MuJoCo's ``mjModel``).

The compiled calls of a step with contacts (``substep._detect_substep``, detection and the
sub-step in one call, and ``substep._substep``, the sub-step after detection in Python) read ~65
values that stay the same from step to step: the shapes' geometry and the narrow phase's tables,
the bodies' masses, inertias, materials and masks, the look-ahead's facts and the settings'
numbers. Handed one by one, each array costs the call its own wrapping for numba's reference
counts (~0.1 µs an array, ~6 µs a call for the ~50 of them, whatever the scene's size). A
``StepModel`` holds them in one compiled record (numba's ``StructRef``): built once per model
(``make``, ~10 µs) and handed as a single argument. The calls' other arguments are what stepping
changes: the bodies' motion, the rotation matrices, the broad phase's pair cache, the contact
cache's warm start, the time left, the contacts.

A ``StepModel`` holds the arrays themselves, not copies, so an edit in place (a material's
friction set into ``World.friction``) reaches the next step as it reached the kernels before;
``substep._step_model`` builds a new one whenever an array is replaced, a setting is assigned or
the models change.

Without numba (or with ``NUMBA_DISABLE_JIT=1``) ``StepModel`` is a named tuple with the same
fields, so the kernels read ``model.sf`` either way. Fields, in ``FIELDS`` order (``N`` bodies,
``M`` finite ones): the look-ahead's facts ``moving (N,) bool, caps (N,), cap, plane``
(``prepare._margin_facts``); the finite bodies and planes of the broad phase ``fin (M,), centre,
half (M,3), planes (P,), plane_n (P,3), plane_d (P,)``; the collision masks ``group, mask (N,)``;
the narrow phase's tables ``which … rank`` (``_Bodies.narrow_args``) and bounding volumes
``use_sphere, use_obb``; then what ``_substep`` reads (``substep._step_model``): ``g`` (m/s²) and
``kind``, the inertia, gravity, the materials, ``ext``, ``dt`` (s), ``exact_toi, particles,
resting``, and the solve's settings from ``margin`` to ``tolerance``.
"""
from collections import namedtuple

from ..jit import COMPILED, njit

FIELDS = ("moving", "caps", "cap", "plane", "fin", "centre", "half", "planes", "plane_n", "plane_d", "group", "mask",
          "which", "sf", "si", "verts", "gplanes", "faces", "loops", "edges", "tris", "bvh", "shape_of", "rank",
          "use_sphere", "use_obb",
          "g", "kind", "principal_q", "moments", "inertia_body", "inv_mass", "gravity", "gravity_rows", "dynamic",
          "rotating", "kinematic", "mass", "particle", "restitution", "friction", "static_friction", "may_soften",
          "stiffness", "damping_ratio", "k_kinematic", "rule", "kinetic", "ext", "dt", "exact_toi", "particles",
          "resting", "margin", "speculative", "toi_tolerance", "simultaneous", "gdt", "rebound_speed",
          "impact_speed", "split_slop", "split_beta", "split_max_speed", "method", "direct_max", "max_iterations",
          "tolerance")

if COMPILED:
    from numba.core import types
    from numba.experimental import structref

    @structref.register
    class StepModelType(types.StructRef):
        """numba's type of a ``StepModel``: its fields' types (literal values widened, so one
        compiled step serves every value of a setting)."""

        def preprocess_fields(self, fields):
            return tuple((name, types.unliteral(typ)) for name, typ in fields)

    class StepModel(structref.StructRefProxy):
        """What the scene fixes for a step (module docstring), as one compiled record."""

        def __reduce__(self):
            # a world's copy (``copy.deepcopy``) or pickle takes its derived tables along, but not
            # this record: made from the copied arrays before the copy's ``__setstate__`` makes
            # gravity read-only again, it would be another type to numba (a second compile of the
            # step, ~2 min). None in its place: the copy's first step makes its own
            return _absent, ()

    structref.define_proxy(StepModel, StepModelType, list(FIELDS))
else:
    StepModel = namedtuple("StepModel", FIELDS)
    StepModel.__doc__ = "What the scene fixes for a step (module docstring): the plain form, without numba."


@njit
def _make(*values):
    return StepModel(*values)


def make(values):
    """A ``StepModel`` of ``values`` (a tuple in ``FIELDS`` order)."""
    return _make(*values)


def _absent():
    """What a copied or unpickled world holds in place of its ``StepModel``."""
    return None
