"""Body kinds: their names and the codes ``World.kind (N,)`` stores (compare with these names,
never with raw numbers)."""
from typing import NamedTuple

import numpy as np

KINDS = ("static", "kinematic", "dynamic")
STATIC, KINEMATIC, DYNAMIC = 0, 1, 2


class BodyMasks(NamedTuple):
    """Per-body facts every step reads (``World.body_masks``): ``(N,)`` bool masks, ``gravity`` and
    ``any_kinematic``."""
    dynamic: np.ndarray
    rotating: np.ndarray      # dynamic rigid bodies (not particles)
    kinematic: np.ndarray
    moving: np.ndarray        # not static
    gravity: np.ndarray       # (N, 3): the world's gravity on dynamic bodies, 0 on the others
    any_kinematic: bool       # a kinematic body exists (else the kinematic energy checks are skipped)


def body_masks(kind, particle, gravity):
    """``BodyMasks`` of ``kind (N,) int8``, ``particle (N,) bool`` and ``gravity (3,)``. They are
    cached and shared by every step until the bodies or gravity change: never write into them.
    (Not flagged read-only: compiled kernels type read-only arrays apart, and a kernel handed both
    kinds would compile twice.)"""
    dynamic = kind == DYNAMIC
    return BodyMasks(dynamic=dynamic, rotating=dynamic & ~particle, kinematic=kind == KINEMATIC, moving=kind != STATIC,
                     gravity=np.where(dynamic[:, None], gravity, 0.0), any_kinematic=bool((kind == KINEMATIC).any()))
