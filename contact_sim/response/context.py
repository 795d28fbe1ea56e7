"""What the stages of one step share (Box2D's ``b2StepContext``): ``StepContext``.

The step (``stepper._impulse_step``) is a list of named stages, each a function of the context:
detect → prepare contacts → impact solve → resting solve (warm started) → position correction →
time of impact → store impulses → advance, repeated per sub-step when a time of impact splits
the step. A stage reads what the earlier ones wrote here and writes its own fields; nothing is
carried between steps except ``World.contact_cache``.

Shapes: ``N`` bodies, ``K`` contacts of the current sub-step.
"""
from dataclasses import dataclass, field

import numpy as np

from . import solver
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
    # ---- the current sub-step (written by the stages, in order)
    t_left: float = 0.0            # time left in the step
    R: np.ndarray = None           # (N,3,3) the bodies' rotation matrices at the sub-step's start (detect)
    contacts: object = None        # Contacts of the sub-step (detect)
    look_ahead: tuple = None       # (t_left, margin): the speculative contacts to filter (detect)
    rel_vel: np.ndarray = None     # (K,3) relative velocity of the contact points (velocity stage)
    rows: object = None            # solver.Rows (prepare)
    local: np.ndarray = None       # (K,3) points in A's frame: the contacts' identity across steps
    e_material: np.ndarray = None  # (K,) restitution of the two materials combined
    restitution: np.ndarray = None  # (K,) restitution, 0 where the rebound would rest
    mu_s: np.ndarray = None        # (K,) static friction (zero without friction)
    mu_d: np.ndarray = None        # (K,) dynamic friction (zero without friction)
    friction: bool = False         # the solves take friction (the models' friction, not kinematic)
    stiffness: np.ndarray = None   # (K,) N/m of the compliant contacts, 0 for rigid ones (compliance)
    zeta: np.ndarray = None        # (K,) their damping ratio
    soft: np.ndarray = None        # (K,) bool: the compliant contacts, or (0,) when none is
    vn0: np.ndarray = None         # (K,) normal velocity at preparation (the approach speed)
    touching: np.ndarray = None    # (K,) bool: within the margin (or the time of impact's tolerance)
    spec_target: np.ndarray = None  # (K,) normal velocity that closes a speculative gap exactly
    closing: np.ndarray = None     # (K,) bool: speculative contacts that would overlap by the end
    impact: np.ndarray = None      # (K,) bool: touching contacts that approach fast enough to bounce
    bounced: np.ndarray = None     # (K,) bool: impact, or a closing one that bounces (e > 0)
    counts: object = None          # prepare.Counts: how many touch, impact, close, bounce; the deepest depth
    impulse: np.ndarray = None     # (K,3) impulses of the sub-step (n, t1, t2), on A
    vn1: np.ndarray = None         # (K,) normal velocity after the impact solve
    push_ref: tuple = None         # (vel, omega) (N,3) at the impact stage's start, with a kinematic
                                   # body: what the push cap measures every solve of the sub-step from
    rest_impulse: np.ndarray = None  # (K,3) the resting solve's impulse over the rest of the step
    rest_mask: np.ndarray = None   # (K,) bool: the contacts that rest
    dv_rest: np.ndarray = None     # (N,3) velocity change of the resting force over the rest of the step
    dw_rest: np.ndarray = None     # (N,3) angular velocity change of the same
    # ---- accumulated over the step
    first: bool = True             # the first sub-step (position correction is planned there)
    events: int = 0                # times of impact handled
    swept_pair: object = None      # the pair a sweep stopped at (its contacts are marked swept)
    records: list = field(default_factory=list)   # [(Contacts, local (k,3))] of the sub-steps
    iterations: int = 0
    residual: float = 0.0
    unconverged: bool = False      # a solve stopped at the iteration limit, still changing (note)
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
        self.gravity, self.rotating = bm.gravity, bm.rotating
        self.records = []

    @classmethod
    def start(cls, world, dt, models):
        """The context of a step of ``dt`` with ``models`` (``response.models.Models``)."""
        return cls(world, models, dt)

    @property
    def k(self):
        """Contacts of the current sub-step."""
        return 0 if self.contacts is None else len(self.contacts)

    def solve(self, rows, vel, omega, **kw):
        """``solver.solve_auto`` with the settings' solver choice, iterations and tolerance."""
        st = self.settings
        return solver.solve_auto(rows, vel, omega, iterations=st.solver_iterations, tolerance=st.solver_tolerance,
                                 method=st.solver_method, direct_max=st.direct_max_contacts, **kw)

    def note(self, res, residual=True):
        """A solve's sweeps (and residual) into the step's statistics; one that stopped at
        ``settings.solver_iterations`` with an impulse still changing by more than
        ``settings.solver_tolerance`` marks the step unconverged."""
        st = self.settings
        self.iterations = max(self.iterations, res.iterations)
        if residual:
            self.residual = max(self.residual, res.residual)
        if res.iterations >= st.solver_iterations and res.residual > st.solver_tolerance:
            self.unconverged = True
