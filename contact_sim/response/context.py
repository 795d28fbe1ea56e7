"""What the stages of one step share (Box2D's ``b2StepContext``): ``StepContext``.

The step (``stepper._impulse_step``) is a list of named stages: detect → the sub-step's compiled
stages (``response.substep``: prepare, impacts, correction plan, resting, store, advance) → time of
impact between its solves and its advance when the models ask for it, repeated per sub-step when a
time of impact splits the step. A stage reads what the earlier ones wrote here and writes its own
fields; nothing is carried between steps except ``World.contact_cache``.

Shapes: ``N`` bodies, ``K`` contacts of the current sub-step.
"""
from dataclasses import dataclass, field

import numpy as np

from ..constants import IMPACT_SPEED_FRACTION


@dataclass(eq=False, init=False)
class StepContext:
    """Made once per step by ``start``; a field's default is its class attribute until a stage
    writes it (``__init__`` sets only what the step fixes: a step is short, its context cheap)."""
    world: object
    models: object                 # response.models.Models chosen for the step
    dt: float
    # ---- fixed for the step
    settings: object = None
    exact_toi: bool = False        # fractional/swept: contacts get exact times of impact
    speculative: bool = False      # next_step with speculative contacts (settings.speculative)
    gdt: float = 0.0               # |g|·dt
    impact_speed: float = 0.0      # approach faster than this bounces (IMPACT_SPEED_FRACTION·|g|·dt)
    gravity: np.ndarray = None     # (N,3) gravity of the dynamic bodies, 0 for the others
    rotating: np.ndarray = None    # (N,) bool: dynamic bodies that rotate (not particles)
    any_kinematic: bool = False    # a body is kinematic
    # ---- the current sub-step (written by the stages, in order)
    t_left: float = 0.0            # time left in the step
    R: np.ndarray = None           # (N,3,3) the bodies' rotation matrices at the sub-step's start (detect)
    contacts: object = None        # Contacts of the sub-step (detect; the sub-step drops the speculative
                                   # ones that cannot close)
    look_ahead: tuple = None       # (t_left, margin): the speculative contacts to filter (detect)
    pos0: np.ndarray = None        # (N,3) the centres at the sub-step's start, with a kinematic body
                                   # (its work is taken where the contact points are)
    touching: np.ndarray = None    # (K,) bool: within the margin (or the time of impact's tolerance)
    rest_mask: np.ndarray = None   # (K,) bool: the contacts that rest, None when no resting solve ran
    dv_rest: np.ndarray = None     # (N,3) velocity change of the resting force over the rest of the step
    pending: tuple = None          # what substep.finish stores and advances after a time of impact
    # ---- accumulated over the step
    first: bool = True             # the first sub-step (position correction is planned there)
    events: int = 0                # times of impact handled
    swept_pair: object = None      # the pair a sweep stopped at (its contacts are marked swept)
    records: list = field(default_factory=list)   # [(Contacts, local (k,3))] of the sub-steps
    iterations: int = 0
    residual: float = 0.0
    unconverged: bool = False      # a solve stopped still changing: at the iteration limit, or stalled
    max_penetration: float = 0.0
    pseudo: tuple = None           # (vp, wp) (N,3) split-impulse pseudo-velocities
    warm_out: tuple = None         # what the contact cache keeps of the last resting solve
    kinematic_work: float = 0.0    # work of the kinematic bodies' contacts (J), sub-step by sub-step
    pose_work: float = 0.0         # work of the poses given since the last step on the springs (J)
    drift: float = 0.0             # free rotation's energy drift (J)
    rest_bound: float = 0.0        # bound of the resting force's first-order work error (J)
    kick_error: float = 0.0        # bound of the torque half-kicks' first-order energy error (J)

    def __init__(self, world, models, dt):
        st = world.settings
        bm = world.body_masks()   # cached: read-only, never written by the stages
        self.world, self.models, self.dt, self.settings, self.t_left = world, models, dt, st, dt
        self.exact_toi = exact_toi = models.toi in ("fractional", "swept")
        self.speculative = st.speculative and not exact_toi
        self.gdt = gdt = world.gravity_norm() * dt
        self.impact_speed = IMPACT_SPEED_FRACTION * gdt
        self.gravity, self.rotating, self.any_kinematic = bm.gravity, bm.rotating, bm.any_kinematic
        self.records = []

    @classmethod
    def start(cls, world, dt, models):
        """The context of a step of ``dt`` with ``models`` (``response.models.Models``)."""
        return cls(world, models, dt)

    @property
    def k(self):
        """Contacts of the current sub-step."""
        return 0 if self.contacts is None else len(self.contacts)
