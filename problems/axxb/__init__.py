"""A_i X = X B_i: hand-eye calibration from relative motions.

`data`: the validated motions and their algebra, the motions made from stations; `problem`: the
`Problem` and its registration; `geometry`: the model of the shared least-squares engine.
"""

from handeye.geometry.motions import PAIRINGS, relative_motions  # noqa: F401 (public names of axxb)
from handeye.problems.axxb.data import (
    DEGENERATE_AXIS_SPREAD,
    MAX_MOTIONS,
    MIN_MOTION_ANGLE,
    MISMATCH_ANGLE_FLOOR,
    MISMATCH_SIGMAS,
    SETUPS,
    STATIONS_TOL,
    WEAK_ROTATION,
    AXXBData,
    motions,
    normal_equations,
    regression_blocks,
    solve_translation,
)
from handeye.problems.axxb.problem import (
    AXXB,
    PROBLEM,
    register_problems,
    simulate_stations,
)

__all__ = [
    "PAIRINGS",
    "AXXB",
    "AXXBData",
    "DEGENERATE_AXIS_SPREAD",
    "MAX_MOTIONS",
    "MIN_MOTION_ANGLE",
    "MISMATCH_ANGLE_FLOOR",
    "MISMATCH_SIGMAS",
    "PROBLEM",
    "SETUPS",
    "STATIONS_TOL",
    "WEAK_ROTATION",
    "motions",
    "normal_equations",
    "register_problems",
    "regression_blocks",
    "simulate_stations",
    "solve_translation",
]
