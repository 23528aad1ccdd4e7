"""A_i X B_i = Y C_i Z: dual-robot calibration (hand-eye X, robot-robot Y, tool-flange Z).

`data`: the validated triples; `problem`: the `Problem` and its registration; `geometry`: the model
of the shared least-squares engine; `kronecker`: the lifted linear system of the closed forms.
"""

from handeye.problems.axbycz.data import (
    DEFAULT_X,
    DEFAULT_Y,
    DEFAULT_Z,
    DEGENERATE_AXIS_SPREAD,
    FIELDS,
    MIN_MOTION_ANGLE,
    PROTOCOLS,
    STACKS,
    STILL_ROTATION,
    STILL_TRANSLATION,
    AXBYCZData,
)
from handeye.problems.axbycz.problem import (
    AXBYCZ,
    PROBLEM,
    register_problems,
)

__all__ = [
    "AXBYCZ",
    "AXBYCZData",
    "DEFAULT_X",
    "DEFAULT_Y",
    "DEFAULT_Z",
    "DEGENERATE_AXIS_SPREAD",
    "FIELDS",
    "MIN_MOTION_ANGLE",
    "PROBLEM",
    "PROTOCOLS",
    "STACKS",
    "STILL_ROTATION",
    "STILL_TRANSLATION",
    "register_problems",
]
