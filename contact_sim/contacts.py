"""Contacts as a structure of arrays (one row per contact point)."""
from dataclasses import dataclass, field, fields

import numpy as np

# what produced a contact (the ``feature`` column)
FEATURES = ("vertex_face", "edge_face", "face_face", "swept", "sphere", "plane")


def _f(shape):
    return field(default_factory=lambda: np.zeros(shape))


@dataclass
class Contacts:
    """Contact points of one detection or step.

    ``body_a, body_b (K,) int`` index ``World.body_names``; ``point (K, 3)`` world position;
    ``normal (K, 3)`` unit, from B to A; ``depth (K,)`` > 0 when penetrating; ``impulse (K, 3)``
    total impulse applied to A during the step (B received its negative), split into
    ``normal_impulse (K,)`` (along ``normal``) and ``friction_impulse (K, 3)`` (tangential);
    ``relative_normal_velocity (K,)`` is ``n·(ṗ_A − ṗ_B)`` before the response (< 0 approaching);
    ``feature (K,) int`` indexes ``FEATURES``.
    """

    body_a: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    body_b: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    point: np.ndarray = _f((0, 3))
    normal: np.ndarray = _f((0, 3))
    depth: np.ndarray = _f((0,))
    impulse: np.ndarray = _f((0, 3))
    normal_impulse: np.ndarray = _f((0,))
    friction_impulse: np.ndarray = _f((0, 3))
    relative_normal_velocity: np.ndarray = _f((0,))
    feature: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def __len__(self):
        return len(self.depth)

    @classmethod
    def empty(cls):
        return cls()

    def select(self, mask):
        """A new ``Contacts`` with the rows picked by a boolean mask or index array."""
        return Contacts(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})

    @classmethod
    def concat(cls, parts):
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls()
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)})
