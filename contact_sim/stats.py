"""What a step reports about itself: ``World.last_solve``, a ``StepStats``."""
from dataclasses import asdict, dataclass, fields


@dataclass
class StepStats:
    """Statistics of the last step (``World.last_solve``), typed, and readable as a mapping too
    (``stats["residual"]``, ``stats.get(...)``, ``dict(stats.items())``) as the earlier dict was.

    The energy fields are what the step declares it may add to the total energy, each a bound or
    an exact figure of a known term, so a caller (and the property tests) can check that nothing
    else did."""

    iterations: int = 0            # solver sweeps of the last solve (1 for the active set)
    residual: float = 0.0          # m/s: the largest velocity change a row made in the last sweep, or
                                   # how far a row of the exact active set misses its target
    unconverged: bool = False      # a solve stopped with a velocity still changing by more than
                                   # settings.solver_tolerance (see residual): at settings.solver_iterations,
                                   # or Gauss–Seidel stalled (no progress in PGS_STALL_SWEEPS sweeps)
    max_penetration: float = 0.0   # deepest overlap at the start of the step (m)
    contacts: int = 0              # contact points recorded for the step
    impacts: int = 0               # time-of-impact events handled within the step
    toi: str = ""                  # the time-of-impact mode used
    response: str = ""             # the response model used
    correction_energy: float = 0.0  # potential energy position correction added (J)
    kinematic_work: float = 0.0    # work done by kinematic bodies' contacts during the step (J)
    pose_work: float = 0.0         # work the poses given since the last step did on compliant springs,
                                   # moving kinematic bodies at once (J): already in World.energy()
                                   # before the step; energy between two steps may grow by both works
    rotation_drift: float = 0.0    # rotational energy change of the free-rotation splitting (J)
    kick_error_bound: float = 0.0  # bound of the torque half-kicks' first-order energy error (J)
    rest_work_bound: float = 0.0   # bound of the resting force's first-order work error (J)

    def __getitem__(self, key):
        if key not in self.keys():
            raise KeyError(key)
        return getattr(self, key)

    def get(self, key, default=None):
        return getattr(self, key) if key in self.keys() else default

    def keys(self):
        return [f.name for f in fields(self)]

    def items(self):
        return asdict(self).items()

    def __contains__(self, key):
        return key in self.keys()
