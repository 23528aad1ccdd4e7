"""The robot-world / hand-eye problem A_i X = Y B_i (paper eq. 2).

Data: A, B: (m, 4, 4) with A_i X = Y B_i. Unknowns: X, Y (4x4). In an eye-in-hand cell
A_i = T_base_flange, B_i = T_target_cam (camera pose in the target frame), X = T_flange_cam,
Y = T_base_target (docs/conventions.md gives the eye-to-hand mapping and OpenCV's).

Shared by the solvers here:
- `kronecker(scale)` (`kronecker_system` in the data's units): the linear system of eqs. 5-8
  with translations divided by `scale`, reduced in O(m) (closed-form sums over the pairs, no
  loop) to the 24x24 triangular factor R1 of eq. 10 (plus Q1^T w and |Q2^T w|^2), so that no
  solver's cost grows with m beyond that reduction. `regression_blocks` builds the
  explicit per-pair H_i, w_i (for tests and for solvers that need the rows).
- `solve_translations`: eqs. 20-21, translations by least squares given the rotations.
- residuals (eqs. 32-33), errors against truth (eqs. 30-31) and the simulator of Sec. IV-A.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.base.vocabulary import SETUPS
from handeye.estimation.kronecker import (
    KroneckerSystem,
    PosePairs,
    reduce_normal_equations,
)
from handeye.framework.caching import cached_property
from handeye.geometry.kinematics import PAPER_X, PAPER_Y  # noqa: F401 (re-exported: the paper's truth)
from handeye.geometry.linalg import singular_values
from handeye.geometry.se3 import inverse
from handeye.geometry.validation import (
    AGREEMENT_STATIONS,
    agreeing_group,
    agreement_angles,
    pose_stack,
)
from handeye.problems import planar as planar_mode

#: Relative rotation excitation (see `AXYBData.rotation_excitation`) below which the rotations
#: are undetermined. (How well stronger data determine X and Y at their noise is the host's
#: self-check, `handeye.checks.self_check`, not a threshold on the data alone.)
DEGENERATE_EXCITATION = 1e-10


@dataclasses.dataclass(frozen=True)
class AXYBData(PosePairs):
    """Validated data of A_i X = Y B_i: read-only float64 stacks A, B of shape (m, 4, 4), with the
    sums over the pairs behind eq. 8 taken once (`handeye.estimation.kronecker.PosePairs`).

    planar: for a robot whose rotations share one axis, the translation along it that the user
    gave (``tz_X`` = t_X . b, b the axis in the flange frame, or ``tz_Y`` = t_Y . a, a the axis
    in the base frame; `handeye.problems.planar`), which the data cannot determine; else None.
    """

    planar: planar_mode.Planar | None = None
    #: the board's image observations behind B (`handeye.vision.observations.BoardObservations`),
    #: for solvers that fit the images themselves (`reprojection`); None for pose data
    images: Any = None
    #: the camera's translations are known only up to scale (`handeye.estimation.camera_scale`)
    camera_scale_unknown: bool = False

    def scaled(self, s: float) -> AXYBData:
        """The same data with every translation divided by s (the planar value and the board too)."""
        out = super().scaled(s)
        if self.planar is not None:
            out = dataclasses.replace(out, planar=self.planar.scaled(s))
        return out if self.images is None else dataclasses.replace(out, images=self.images.scaled(s))

    @cached_property
    def rotation_excitation(self) -> float:
        """How well the rotations determine R_X, R_Y, in [0, 1]: 1 - sigma_2(S) / m.

        With K_i = R_Bi kron R_Ai (orthogonal 9x9), the normal matrix of the rotation rows of eq. 8
        is [[m I, -S^T], [-S, m I]] with S = sum_i K_i (`rotation_sum`), whose eigenvalues are
        m -+ sigma_j(S). Noise-free data make sigma_1(S) = m (the solution); sigma_2(S) = m means a
        second null direction, i.e. undetermined rotations (all equal, or all about one axis).
        """
        sigma = singular_values(self.rotation_sum)  # LAPACK directly (`handeye.geometry.linalg`: numpy's numbers)
        return float(max(0.0, 1.0 - sigma[1] / self.m))

    @cached_property
    def pose_model(self) -> Any:
        """The engine's model of these data (`axyb_geometry.AXYBModel`), built once: the solver's
        refinement, its outlier step and the host's self-check all use it (read-only)."""
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.AXYBModel(self)

    @cached_property
    def consecutive_motions(self) -> tuple[np.ndarray, ...]:
        """`axyb_geometry.consecutive_motions` of the stations, computed once (the self-check's
        noise estimate and its naming of directions both use them); beyond MOTION_SAMPLE + 1
        stations those of MOTION_SAMPLE stations spread over the data and their successors
        (medians and main axes need no more: 70 ms of a 1 s solve at 1e5 stations)."""
        from handeye.problems.axyb import geometry as axyb_geometry

        if len(self.A) <= MOTION_SAMPLE + 1:
            return axyb_geometry.consecutive_motions(self.A, self.B)
        k = np.linspace(0, len(self.A) - 2, MOTION_SAMPLE).round().astype(int)
        pairs = [np.stack([T[k], T[k + 1]], axis=1).reshape(-1, 4, 4) for T in (self.A, self.B)]
        return tuple(x[::2] for x in axyb_geometry.consecutive_motions(*pairs))  # k -> k + 1, not k + 1 -> next k

    @cached_property
    def agreeing_group(self) -> np.ndarray:
        """(m,) bool: the largest group of pairs that agree with each other, without X or Y
        (`handeye.geometry.validation.agreeing_group`): a robust start, and a majority or not."""
        return agreeing_group(self.A, self.B, self._agreement_angles)

    @cached_property
    def _agreement_angles(self) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """`handeye.geometry.validation.agreement_angles` of the stations, once: the validation's motion
        check and `agreeing_group` both read them."""
        return agreement_angles(self.A, self.B)

    def station_angles(self) -> tuple[np.ndarray, np.ndarray]:
        """`station_angles` of A and B; up to AGREEMENT_STATIONS stations read from the angles
        between every two stations (`_agreement_angles`, which auto and the self-check need too:
        the same numbers, 35 us less a solve at m = 16)."""
        m = self.m
        if not 3 <= m <= min(AGREEMENT_STATIONS, MOTION_CHECK_STATIONS):
            return station_angles(self.A, self.B)
        _, angles_A, angles_B = self._agreement_angles
        i = np.concatenate([np.arange(1, m), np.arange(2, m)])  # as station_angles' (np.r_ costs 6 us more)
        j = np.concatenate([np.zeros(m - 1, dtype=int), np.arange(1, m - 1)])
        return angles_A[j, i], angles_B[j, i]

    @property
    def agreeing_share(self) -> float:
        """The share of the pairs in `agreeing_group` (of those it looked at): at one half or
        below no consistent majority exists (`handeye.geometry.validation.agreeing_share`)."""
        return float(self.agreeing_group.sum()) / min(self.m, AGREEMENT_STATIONS)

    def normal_equations(self, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
        """Eq. 8's normal equations (`normal_equations`)."""
        return normal_equations(self, scale)


def regression_blocks(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-pair blocks H_i: (m, 12, 24) and w_i: (m, 12) of eq. 8, without a loop over pairs."""
    m = len(A)
    RA, RB, tA, tB = A[:, :3, :3], B[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    H = np.zeros((m, 12, 24))
    H[:, :9, :9] = np.einsum("nij,nkl->nikjl", RB, RA).reshape(m, 9, 9)  # R_B kron R_A (eq. 6)
    H[:, :9, 9:18] = -np.eye(9)
    H[:, 9:, 9:18] = np.einsum("nj,kl->nkjl", tB, np.eye(3)).reshape(m, 3, 9)  # t_B^T kron I (eq. 7)
    H[:, 9:, 18:21] = -RA
    H[:, 9:, 21:24] = np.eye(3)
    w = np.zeros((m, 12))
    w[:, 9:] = tA
    return H, w


_EYE3, _EYE9 = np.eye(3), np.eye(9)
_EYE3.setflags(write=False)
_EYE9.setflags(write=False)


def normal_equations(data: AXYBData, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """N = H^T H (24x24), g = H^T w (24), w^T w of eq. 8 with every translation divided by
    `scale`, from the sums over the pairs that `data` caches (no (12m, 24) matrix; O(1) once
    they exist).

    The blocks of H_i (eq. 8) give, with K_i = R_Bi kron R_Ai and T_i = t_Bi^T kron I:
    K^T K = (R_B^T R_B) kron (R_A^T R_A), T^T T = (t_B t_B^T) kron I, T^T R_A = t_B kron R_A.
    Dividing the translations by s divides the blocks linear in them by s, quadratic by s^2.
    """
    m, s = data.m, float(scale)
    sums = data.translation_sums
    N = np.zeros((24, 24))
    N[:9, :9] = data.rotation_gram_sum
    S = data.rotation_sum
    N[:9, 9:18], N[9:18, :9] = -S.T, -S
    # kron(., I3) as the broadcast product np.kron forms (the same numbers, without its ~10 us)
    N[9:18, 9:18] = m * _EYE9 + (sums.TB[:, None, :, None] * _EYE3[None, :, None, :]).reshape(9, 9) / s**2
    C = sums.C.reshape(9, 3) / s
    N[9:18, 18:21], N[18:21, 9:18] = -C, -C.T
    E = (sums.sum_tB[:, None, None] * _EYE3).reshape(9, 3) / s  # sum_i t_Bi kron I
    N[9:18, 21:24], N[21:24, 9:18] = E, E.T
    N[18:21, 18:21] = sums.GA
    N[18:21, 21:24], N[21:24, 18:21] = -sums.sum_RA.T, -sums.sum_RA
    N[21:24, 21:24] = m * _EYE3
    g = np.zeros(24)
    g[9:18] = sums.tB_tA.reshape(9) / s**2  # sum_i t_Bi kron t_Ai
    g[18:21] = -sums.RAt_tA / s
    g[21:24] = sums.sum_tA / s
    return N, g, sums.tA_tA / s**2


def reduce_system(A: np.ndarray, B: np.ndarray) -> KroneckerSystem:
    """Reduce eq. 8 of the pose stacks A, B: (m, 4, 4) to the triangular form of eqs. 10-12."""
    return reduce_normal_equations(*normal_equations(AXYBData(A, B)))


def split_beta(beta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(M_X, M_Y, t_X, t_Y) from beta of eq. 8; M are 3x3 (not yet rotations)."""
    beta = np.asarray(beta, dtype=float).ravel()
    return (beta[:9].reshape(3, 3, order="F"), beta[9:18].reshape(3, 3, order="F"),
            beta[18:21].copy(), beta[21:24].copy())


def solve_translations(data: AXYBData, RX: np.ndarray, RY: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t_X, t_Y by least squares given rotations (eqs. 20-21): [R_Ai, -I] [t_X; t_Y] = R_Y t_Bi - t_Ai.

    Solved by its 6x6 normal equations, whose entries are sums over the pairs taken once
    (`AXYBData.translation_sums`): with p_i = R_Y t_Bi - t_Ai,
    [[sum R_A^T R_A, -sum R_A^T], [-sum R_A, m I]] [t_X; t_Y] = [sum R_A^T p_i; -sum p_i].
    The matrix is well conditioned whenever the rotations of A vary (which validation demands).
    """
    from scipy.linalg import LinAlgError, solve

    sums = data.translation_sums
    RAt_p = sums.RAt_R_tB(RY) - sums.RAt_tA  # sum R_A^T (R_Y t_B - t_A)
    sum_p = RY @ sums.sum_tB - sums.sum_tA
    N = np.block([[sums.GA, -sums.sum_RA.T], [-sums.sum_RA, sums.m * np.eye(3)]])
    try:
        t = solve(N, np.concatenate([RAt_p, -sum_p]), assume_a="pos")
    except LinAlgError:
        raise DegenerateDataError(
            "the translations of X and Y cannot be determined: the robot poses rotate about fewer "
            "than two different axes. Record poses that rotate about at least two different axes"
        ) from None
    return t[:3], t[3:]


#: the self-check's consecutive motions: at most this many (`AXYBData.consecutive_motions`)
MOTION_SAMPLE = 5000
#: `station_angles` looks at this many stations at most (enough to see whether they move)
MOTION_CHECK_STATIONS = 2000


def station_angles(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation angles (rad, to ~1e-8) of the robot's and the camera's motions from the first
    station and between consecutive stations (2m - 3 motions), over at most MOTION_CHECK_STATIONS
    evenly spread stations: A_j^-1 A_i = X (B_j^-1 B_i) X^-1, so each motion turns by the same
    angle on both sides."""
    if len(A) > MOTION_CHECK_STATIONS:
        k = np.unique(np.linspace(0, len(A) - 1, MOTION_CHECK_STATIONS).astype(int))
        A, B = A[k], B[k]
    m = len(A)
    i = np.r_[np.arange(1, m), np.arange(2, m)]
    j = np.r_[np.zeros(m - 1, dtype=int), np.arange(1, m - 1)]

    def angles(T: np.ndarray) -> np.ndarray:  # from tr(R_j^T R_i) = sum of R_j * R_i: no matrix products
        trace = np.einsum("nab,nab->n", T[j, :3, :3], T[i, :3, :3])
        return np.arccos((0.5 * (trace - 1.0)).clip(-1.0, 1.0))

    return angles(A), angles(B)





def pairs_from_stations(robot_poses: Any, camera_poses: Any, setup: str = "eye-in-hand",
                        pairing: str | None = None) -> dict[str, np.ndarray]:
    """The pairs {"A", "B"} of the stations' absolute poses (docs/conventions.md):
    A_i = robot_poses[i] = T_base_flange; B_i = camera_poses[i]^-1 = T_target_cam eye-in-hand,
    B_i = camera_poses[i] = T_cam_target eye-to-hand. `pairing` does not apply (every station is
    one pair) and is ignored."""
    if setup not in SETUPS:
        raise InputError(f"setup={setup!r} is not one of {', '.join(SETUPS)}")
    robot = pose_stack(robot_poses, "robot_poses")
    camera = pose_stack(camera_poses, "camera_poses")
    return {"A": np.array(robot), "B": inverse(camera) if setup == "eye-in-hand" else np.array(camera)}
