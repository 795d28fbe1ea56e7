"""Closed-form answers for the reference scenes of the accuracy study (independent of the engine).

Each formula is written once, in ``contact_sim.study.references`` (the accuracy studies' reference
recorders use them); this module names them for the benchmarks and their tests.
"""
from contact_sim.study.references import (bouncing_height, damping_for_restitution, head_on,  # noqa: F401
                                          incline_acceleration, penalty_rest_depth, rod_impact,
                                          sliding_stop_distance)
