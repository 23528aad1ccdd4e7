"""A_i X = Y B_i: robot-world and hand-eye calibration (the paper's problem).

`data`: the validated pose pairs and their algebra (eq. 8's Kronecker system, the translations),
`problem`: the `Problem` (validation, residuals, checks, simulator) and its registration,
`geometry`: the residuals and Jacobians of the shared least-squares engine, `images`: the board
images behind B for a reprojection fit.
"""

from handeye.problems.axyb.data import (
    DEGENERATE_EXCITATION,
    MOTION_CHECK_STATIONS,
    PAPER_X,
    PAPER_Y,
    SETUPS,
    AXYBData,
    normal_equations,
    pairs_from_stations,
    reduce_system,
    regression_blocks,
    solve_translations,
    split_beta,
    station_angles,
)
from handeye.problems.axyb.problem import (
    AXYB,
    PROBLEM,
    random_truth,
    register_problems,
)

__all__ = [
    "AXYB",
    "AXYBData",
    "DEGENERATE_EXCITATION",
    "MOTION_CHECK_STATIONS",
    "PAPER_X",
    "PAPER_Y",
    "PROBLEM",
    "SETUPS",
    "normal_equations",
    "pairs_from_stations",
    "random_truth",
    "reduce_system",
    "register_problems",
    "regression_blocks",
    "solve_translations",
    "split_beta",
    "station_angles",
]
