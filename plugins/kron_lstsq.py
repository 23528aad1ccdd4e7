"""`kron-lstsq`: closed-form least squares on the Kronecker system of eq. 8.

beta = argmin |H beta - w| (the optimum of the paper's eq. 14, without an SDP solver), R_X and
R_Y projected onto SO(3) by SVD (det +1), then t_X, t_Y re-solved by least squares given the
rotations (eqs. 20-21). With ``normalize=True`` (default) translations are divided by the data's
RMS translation before eq. 8 is built, which balances the rotation and translation rows and makes
the answer independent of the length unit.
"""

from __future__ import annotations

import dataclasses

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.problems.axyb import AXYBData, solve_translations, split_beta
from handeye.se3 import make_pose, project_to_so3


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by the data's RMS translation first (see module docstring)."""

    normalize: bool = True


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    system = data.kronecker(data.translation_scale if options.normalize else 1.0)
    MX, MY, _, _ = split_beta(system.least_squares())
    RX, RY = project_to_so3(MX), project_to_so3(MY)
    tX, tY = solve_translations(data, RX, RY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=Status.OPTIMAL,
        diagnostics={"residual_eq8": system.rest, "sigma_min_R1": system.smallest_singular_value()},
    )


SPEC = SolverSpec(
    name="kron-lstsq",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="closed-form least squares on the Kronecker system (eq. 8), SVD projection",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8; cf. Li, Wang, Wu, Int. J. Phys. Sci. 2010",
    unit_invariant=lambda options: options.normalize,  # not with normalize=False (module docstring)
)


@hookimpl
def register_solvers(register):
    register(SPEC)
