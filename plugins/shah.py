"""`shah`: Shah's separable Kronecker method (Shah 2013, J. Mech. Robot. 5, 031007).

Rotations first, from rotations only. Eq. 6 of the paper, (R_Bi kron R_Ai) vec(R_X) = vec(R_Y),
stacked over the pairs as [K_i, -I_9] [vec(R_X); vec(R_Y)] = 0 (K_i = R_Bi kron R_Ai), has on
exact data a one-dimensional null space. Its normal matrix is [[m I, -S^T], [-S, m I]] with
S = sum_i K_i (9 x 9), whose eigenvalues are m -+ sigma_j(S); the null vector (the right singular
vector of the smallest singular value of the stacked 9m x 18 system) is therefore [v_1; u_1] / sqrt(2)
with u_1, v_1 the leading singular vectors of S. So, without building the stacked system:

    S = U Sigma V^T,  M_X = unvec(v_1),  M_Y = unvec(u_1)   (column-major, as vec in eq. 6),

each made a rotation by (Shah's normalisation) scaling to determinant +1 -- which also fixes the
common sign of the singular pair, as det(-M) = -det(M) -- and taking the orthogonal polar factor
(SVD, U V^T). Then translations by linear least squares given R_Y (Shah's second step, which is the
paper's eqs. 20-21): [R_Ai, -I] [t_X; t_Y] = R_Y t_Bi - t_Ai.

This is the method OpenCV implements as CALIB_ROBOT_WORLD_HAND_EYE_SHAH
(`cv2.calibrateRobotWorldHandEye`); tests/plugins/test_shah_li.py checks equality to 1e-9.
Rotations depend on rotations only and translations enter linearly, so the solver is unit
invariant.
"""

from __future__ import annotations

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import DegenerateDataError
from handeye.geometry.se3 import make_pose
from handeye.problems.axyb import AXYBData, solve_translations


def normalize_rotation(M: np.ndarray) -> np.ndarray:
    """Rotation from M: (3, 3): scale to det +1 (sign included), then the orthogonal polar factor.
    Singular means det(M) small against M's own size, (|M|_F / sqrt 3)^3 (the det of a rotation
    of that Frobenius norm): a block that is a small multiple of a rotation (li's least squares
    on weak translations, kinhec small tier mixed-000066, motion-000060/61: det ~1e-9 at
    |M| ~ 1e-3) is not singular."""
    det = float(np.linalg.det(M))
    size = (float(np.linalg.norm(M)) / np.sqrt(3.0)) ** 3
    if not (abs(det) >= np.finfo(np.float32).eps * size and det != 0.0 and np.isfinite(det)):
        raise DegenerateDataError(
            f"the estimated rotation matrix is singular (det {det:.1e}): the poses rotate about fewer "
            "than two different axes, so the rotations of X and Y cannot be determined. Record poses "
            "that rotate about at least two different axes"
        )
    M = np.cbrt(np.sign(det) / abs(det)) * M
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:  # only after a rounding accident: det(M) > 0 here
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def kron_rotations(data: AXYBData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R_X, R_Y, singular values of S / m) from the leading singular pair of S = sum_i R_Bi kron R_Ai."""
    U, sigma, Vt = np.linalg.svd(data.rotation_sum)  # S = sum_i kron(R_Bi, R_Ai)
    RX = normalize_rotation(Vt[0].reshape(3, 3, order="F"))
    RY = normalize_rotation(U[:, 0].reshape(3, 3, order="F"))
    return RX, RY, sigma / data.m


def run(data: AXYBData, options, backend: str) -> SolverOutput:
    RX, RY, sigma = kron_rotations(data)
    tX, tY = solve_translations(data, RX, RY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=Status.OPTIMAL,
        # sigma_1(S)/m = 1 on exact data; 1 - sigma_2/m is the rotation excitation
        diagnostics={"sigma1_over_m": float(sigma[0]), "sigma2_over_m": float(sigma[1])},
    )


SPEC = SolverSpec(
    name="shah",
    problems=("axyb",),
    run=run,
    summary="Shah's Kronecker method: rotations from the SVD of sum R_B kron R_A, then translations",
    citation="M. Shah, J. Mechanisms Robotics 5(3), 031007, 2013",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
