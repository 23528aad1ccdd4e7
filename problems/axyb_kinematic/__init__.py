"""FK(q_i) X = Y B_i: hand-eye and robot-world calibration together with the arm's kinematic (DH)
errors, from joint readings.

`model`: forward kinematics with the sensitivity to each DH parameter and which parameters
hand-eye data can determine; `data`: the validated data; `problem`: the `Problem` (validation,
residuals, simulator, diagnosis) and its registration. The solver is `kinematic-lm`
(handeye.plugins.kinematic_lm), also the problem's `auto`; docs/kinematic.md.
"""

from handeye.problems.axyb_kinematic.data import KinematicData
from handeye.problems.axyb_kinematic.model import (
    Identifiability,
    parameter_name,
    structural,
)
from handeye.problems.axyb_kinematic.problem import (
    PROBLEM,
    AXYBKinematic,
    canonical,
    chain,
    random_errors,
    register_problems,
)

__all__ = [
    "AXYBKinematic",
    "Identifiability",
    "KinematicData",
    "PROBLEM",
    "canonical",
    "chain",
    "parameter_name",
    "random_errors",
    "register_problems",
    "structural",
]
