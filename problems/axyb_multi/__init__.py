"""A_i X_{x_i} = Y_{y_i} B_i: a cell with several cameras and several targets in one solve.

`data`: the validated observations and their graph (components of X's and Y's tied together),
`geometry`: the residuals and Jacobians of the shared least-squares engine and the self-check's
figures, `observability`: what the observations determine (the rule, refusals, warnings),
`problem`: the `Problem` (validation, residuals) and its registration, `simulation`: the
simulated cell, `noise`: a noise level per camera and marker, `cell_files`: a cell from its files.
"""

from handeye.problems.axyb_multi.data import (
    AXYBMultiData,
    Component,
    components,
    validated,
)
from handeye.problems.axyb_multi.geometry import AXYBMultiModel
from handeye.problems.axyb_multi.problem import (
    PROBLEM,
    AXYBMulti,
    errors_per_pose,
    register_problems,
)
from handeye.problems.axyb_multi.simulation import SETUPS, SimulatedCell, simulate_cell

__all__ = [
    "PROBLEM",
    "SETUPS",
    "AXYBMulti",
    "AXYBMultiData",
    "AXYBMultiModel",
    "Component",
    "SimulatedCell",
    "components",
    "errors_per_pose",
    "register_problems",
    "simulate_cell",
    "validated",
]
