"""`li`: Li, Wang and Wu's simultaneous Kronecker method (Int. J. Phys. Sci. 5, 1530-1536, 2010).

Rotations and translations together by one linear least-squares problem on the Kronecker system,
then each rotation block made a rotation. Li et al. write, per pair (row-major vec),

    (R_Ai kron I) vec(R_X) - (I kron R_Bi^T) vec(R_Y) = 0            (R_Ai R_X = R_Y R_Bi)
    -R_Ai t_X + (I kron t_Bi^T) vec(R_Y) + t_Y = t_Ai               (translation part of A X = Y B)

The rotation rows are vec(R_Ai R_X - R_Y R_Bi), which is vec(R_Ai R_X R_Bi^T - R_Y) of the paper's
eq. 6 multiplied on the right by the orthogonal R_Bi: same residual norm pair by pair. The
translation rows are those of eq. 7. So the least-squares problem is exactly the paper's eq. 8,
H beta = w; we build H with `regression_blocks` and solve the stacked 12m x 24 system by QR least
squares (OpenCV uses an SVD, DECOMP_SVD: the same minimiser of a full-rank problem), with columns
scaled to unit norm first for conditioning. Rotations: unvec of beta
made a rotation by Li/OpenCV's normalisation (scale to det +1, orthogonal polar factor;
`handeye.plugins.shah.normalize_rotation`); translations are taken from beta as they are (not
re-solved), as in the method.

Option ``normalize`` (default True): translations divided by the data's RMS translation before
the system is built, translations of the answer multiplied back: unit invariant. With
``normalize=False`` this is exactly OpenCV's CALIB_ROBOT_WORLD_HAND_EYE_LI (which does not
normalise; tests/test_shah_li.py checks equality to 1e-9). Without normalisation, data in mm give
the translation rows ~10^3 times the weight of the rotation rows.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.linalg import solve_triangular

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import DegenerateDataError
from handeye.plugins.dual_quaternion import triangular_factor
from handeye.plugins.shah import normalize_rotation
from handeye.problems.axyb import AXYBData, regression_blocks, split_beta
from handeye.se3 import make_pose


@dataclasses.dataclass(frozen=True)
class Options:
    normalize: bool = True


def least_squares_beta(data: AXYBData) -> tuple[np.ndarray, float]:
    """beta: (24,) minimising |H beta - w| over the stacked eq. 8, and sigma_min of the scaled H.

    QR least squares: the augmented [H S | w] (S scales the columns of H to unit norm) is reduced
    to its 25 x 25 triangular factor (`triangular_factor`, a two-level QR), then
    R[:24, :24] y = R[:24, 24] by back substitution and beta = S y.
    """
    H, w = regression_blocks(data.A, data.B)
    col = np.sqrt(np.einsum("nij,nij->j", H, H))
    col = np.where(col > 0, col, 1.0)
    R = triangular_factor(np.concatenate([H / col, w[:, :, None]], axis=2))
    R1 = R[:24, :24]
    sigma = np.linalg.svd(R1, compute_uv=False)
    if not sigma[-1] > 1e-12 * sigma[0]:
        raise DegenerateDataError("li: the Kronecker system of eq. 8 is rank deficient (the data do "
                                  "not determine X and Y)")
    return solve_triangular(R1, R[:24, 24]) / col, float(sigma[-1])


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    scale = data.translation_scale if options.normalize else 1.0
    beta, sigma_min = least_squares_beta(data.scaled(scale) if options.normalize else data)
    MX, MY, tX, tY = split_beta(beta)
    RX, RY = normalize_rotation(MX), normalize_rotation(MY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, scale * tX), "Y": make_pose(RY, scale * tY)},
        status=Status.OPTIMAL,
        diagnostics={"sigma_min_scaled_H": sigma_min, "normalize": options.normalize},
    )


SPEC = SolverSpec(
    name="li",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="Li et al.'s Kronecker method: rotations and translations by one least squares, then orthogonalised",
    citation="A. Li, L. Wang, D. Wu, Int. J. Physical Sciences 5(10), 1530-1536, 2010",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
