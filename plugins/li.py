"""`li`: Li, Wang and Wu's simultaneous Kronecker method (Int. J. Phys. Sci. 5, 1530-1536, 2010).

Rotations and translations together by one linear least-squares problem on the Kronecker system,
then each rotation block made a rotation. Li et al. write, per pair (row-major vec),

    (R_Ai kron I) vec(R_X) - (I kron R_Bi^T) vec(R_Y) = 0            (R_Ai R_X = R_Y R_Bi)
    -R_Ai t_X + (I kron t_Bi^T) vec(R_Y) + t_Y = t_Ai               (translation part of A X = Y B)

The rotation rows are vec(R_Ai R_X - R_Y R_Bi), which is vec(R_Ai R_X R_Bi^T - R_Y) of the paper's
eq. 6 multiplied on the right by the orthogonal R_Bi: same residual norm pair by pair. The
translation rows are those of eq. 7. So the least-squares problem is exactly the paper's eq. 8,
H beta = w (OpenCV solves it by SVD, DECOMP_SVD: the same minimiser of a full-rank problem).

How we solve it, in O(m) without forming H: the shared reduction `AXYBData.kronecker_system`
gives the Cholesky factor R1 of the (column-equilibrated) normal matrix H^T H, summed in closed
form, and beta_0 from it. Normal equations alone lose accuracy (error ~ eps kappa^2; ~1e-8 on
our tests), so one correction step follows (semi-normal equations with one refinement):
r = w - H beta_0 is computed pair by pair (r_rot,i = M_Y - R_Ai M_X R_Bi^T,
r_t,i = t_Ai - M_Y t_Bi + R_Ai t_X - t_Y), H^T r summed in closed form, and
beta = beta_0 + (R1^T R1)^-1 H^T r. The step contracts the error by a factor ~ eps kappa^2, which
the size of the correction itself estimates: if it exceeds 1e-6 (relative, in equilibrated
coordinates) the problem is too ill-conditioned for this and we fall back to a QR of the stacked
12m x 24 system (`least_squares_beta_qr`, columns scaled to unit norm, tree QR). On the
equality tests with OpenCV and on weakly excited data the corrected solution agrees with the QR
one to ~2e-13. Rotations: unvec of beta
made a rotation by Li/OpenCV's normalisation (scale to det +1, orthogonal polar factor;
`handeye.plugins.shah.normalize_rotation`); translations are taken from beta as they are (not
re-solved), as in the method.

Option ``normalize`` (default True): translations divided by the data's RMS translation before
the system is built, translations of the answer multiplied back: unit invariant. With
``normalize=False`` this is exactly OpenCV's CALIB_ROBOT_WORLD_HAND_EYE_LI (which does not
normalise; tests/plugins/test_shah_li.py checks equality to 1e-9). Without normalisation, data in mm give
the translation rows ~10^3 times the weight of the rotation rows.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.linalg import solve_triangular

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import DegenerateDataError
from handeye.checks.self_check import rotation_block_figures
from handeye.geometry.linalg import triangular_factor
from handeye.geometry.se3 import make_pose
from handeye.plugins.shah import normalize_rotation
from handeye.problems.axyb import AXYBData, regression_blocks, split_beta


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by the data's RMS translation first (see module docstring)."""

    normalize: bool = True


#: Largest relative size of the correction step for which the corrected semi-normal solution is
#: accepted (the error left after it is about this squared); above it, QR.
CORRECTION_LIMIT = 1e-6


def least_squares_beta_qr(data: AXYBData) -> tuple[np.ndarray, float]:
    """beta: (24,) minimising |H beta - w| over the stacked eq. 8, and sigma_min of the scaled H.

    QR least squares: the augmented [H S | w] (S scales the columns of H to unit norm) is reduced
    to its 25 x 25 triangular factor (`triangular_factor`, a tree QR of small chunks), then
    R[:24, :24] y = R[:24, 24] by back substitution and beta = S y.
    """
    H, w = regression_blocks(data.A, data.B)
    col = np.sqrt(np.einsum("nij,nij->j", H, H))
    col = np.where(col > 0, col, 1.0)
    R = triangular_factor(np.concatenate([H / col, w[:, :, None]], axis=2))
    R1 = R[:24, :24]
    sigma = np.linalg.svd(R1, compute_uv=False)
    if not sigma[-1] > 1e-12 * sigma[0]:
        raise DegenerateDataError("li: the linear system is rank deficient: the poses rotate about too "
                                  "few axes, so X and Y cannot be determined. Record poses that rotate "
                                  "about at least two different axes")
    return solve_triangular(R1, R[:24, 24]) / col, float(sigma[-1])


def normal_residual(data: AXYBData, beta: np.ndarray) -> np.ndarray:
    """H^T (w - H beta): (24,) of eq. 8, from per-pair residuals, without forming H."""
    RA, RB, tA, tB = data.A[:, :3, :3], data.B[:, :3, :3], data.A[:, :3, 3], data.B[:, :3, 3]
    MX, MY, tX, tY = split_beta(beta)
    r_rot = MY - RA @ MX @ np.swapaxes(RB, 1, 2)  # (m, 3, 3): -(R_B kron R_A) vec M_X + vec M_Y
    r_t = tA - tB @ MY.T + RA @ tX - tY  # (m, 3)
    g = np.empty(24)
    g[:9] = (np.swapaxes(RA, 1, 2) @ r_rot @ RB).sum(axis=0).ravel(order="F")  # (R_B kron R_A)^T r_rot
    g[9:18] = (r_t.T @ tB - r_rot.sum(axis=0)).ravel(order="F")  # -r_rot + (t_B kron I) r_t
    g[18:21] = -np.einsum("nji,nj->i", RA, r_t)  # -R_A^T r_t
    g[21:24] = r_t.sum(axis=0)
    return g


def least_squares_beta(data: AXYBData) -> tuple[np.ndarray, float, str]:
    """(beta: (24,), sigma_min of the column-scaled H, method) for eq. 8 (module docstring)."""
    try:
        system = data.kronecker_system
    except DegenerateDataError:
        return (*least_squares_beta_qr(data), "qr")  # raises with li's own message if rank deficient
    R1 = system.R1
    beta = system.least_squares()
    delta = solve_triangular(R1, solve_triangular(R1, normal_residual(data, beta), trans="T"))
    d = np.linalg.norm(R1, axis=0)  # column norms of H
    if not np.linalg.norm(d * delta) <= CORRECTION_LIMIT * np.linalg.norm(d * beta):
        return (*least_squares_beta_qr(data), "qr")
    sigma = np.linalg.svd(R1 / d, compute_uv=False)
    return beta + delta, float(sigma[-1]), "seminormal"


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    scale = data.translation_scale if options.normalize else 1.0
    beta, sigma_min, method = least_squares_beta(data.scaled(scale) if options.normalize else data)
    MX, MY, tX, tY = split_beta(beta)
    RX, RY = normalize_rotation(MX), normalize_rotation(MY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, scale * tX), "Y": make_pose(RY, scale * tY)},
        status=Status.OPTIMAL,
        diagnostics={"sigma_min_scaled_H": sigma_min, "least_squares": method, "normalize": options.normalize,
                     "rotation_blocks": {"X": rotation_block_figures(MX), "Y": rotation_block_figures(MY)}},
    )


SPEC = SolverSpec(
    name="li",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="Li et al.'s Kronecker method: rotations and translations by one least squares, then orthogonalised",
    citation="A. Li, L. Wang, D. Wu, Int. J. Physical Sciences 5(10), 1530-1536, 2010",
    unit_invariant=lambda options: options.normalize,  # not with normalize=False (module docstring)
)


@hookimpl
def register_solvers(register):
    register(SPEC)
