"""The classic hand-eye problem A_i X = X B_i (relative motions).

Data: A, B: (m, 4, 4) relative motions with A_i X = X B_i. Unknown: X (4x4). They are built from
the absolute poses a robot cell records by `motions` (docs/conventions.md): with robot poses
T_base_flange and board poses T_cam_target (what OpenCV's ``calibrateHandEye`` takes), X is
T_flange_cam for a camera on the flange (eye-in-hand) and T_base_cam for a fixed camera
(eye-to-hand), exactly the ``cam2gripper`` / ``cam2base`` that OpenCV returns.

Shared by the solvers here (the analogue of the paper's eq. 8 for AX=XB):
- `AXXBData.kronecker(scale)`: with beta = [vec(R_X); t_X] (column-major vec), each motion gives
  (R_Bi kron R_Ai - I9) vec(R_X) = 0                          (rotation rows, homogeneous)
  (t_Bi^T kron I3) vec(R_X) + (I3 - R_Ai) t_X = t_Ai           (translation rows)
  reduced in O(m) to its 12x12 triangular factor (`handeye.estimation.kronecker`), translations divided by
  `scale`. The rotation rows alone admit beta = 0; what makes a solver's problem well posed is
  its own business (docs/solvers/kron-lstsq.md states the constraint used there).
- `solve_translation`: t_X by least squares given R_X, (I - R_Ai) t_X = t_Ai - R_X t_Bi.
- residuals, errors against a truth, `diagnose` (rotation spread, axis spread, motions whose
  rotation angles or screw pitches disagree), and a simulator that puts the noise on the
  absolute poses before differencing them, so that the motions carry the correlated noise of
  real data.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.base.vocabulary import SETUPS
from handeye.estimation.kronecker import PosePairs
from handeye.geometry import so3_fast
from handeye.geometry.motions import relative_motions
from handeye.geometry.se3 import inverse
from handeye.geometry.validation import (
    agreeing_motions,
    agreeing_share,
    pose_stack,
    same_length,
)
from handeye.problems import planar as planar_mode

#: A motion rotating by less than this (rad) has no usable rotation axis.
MIN_MOTION_ANGLE = 1e-6
#: Axis spread (rad, see `AXXBData.axis_spread`) below which the rotation axes count as parallel:
#: R_X is then undetermined about that axis, and the data are refused.
DEGENERATE_AXIS_SPREAD = 1e-6
#: Below this motion angle (rad, 5.7 deg) a motion's axis, hence its screw pitch, is too
#: uncertain to compare between A and B. (Whether the motions determine X well enough is not
#: judged from the data alone: the host's self-check states the 1-sigma of the answer at the
#: noise the data show, `handeye.checks.self_check`.)
WEAK_ROTATION = 0.1
#: A motion is listed as likely mismatched when |angle(A_i) - angle(B_i)| exceeds both this
#: floor (rad, 1 deg) and MISMATCH_SIGMAS robust standard deviations of those differences over
#: all motions (MAD_TO_SIGMA x their median: the noise of the angles is about the same for every
#: motion). The screw pitch (translation along the axis, also invariant) is reported but not used
#: to flag: its noise grows with |t| / angle, so one threshold does not fit every motion.
MISMATCH_ANGLE_FLOOR = np.deg2rad(1.0)
#: relative tolerance of `AXXBData.stations`: motions of one set of stations agree to rounding
#: (~1e-13 of the translations); independent motions miss by their noise.
STATIONS_TOL = 1e-9
#: the most motions `motions` forms from stations (pairing "all" makes n (n - 1) / 2: 1,415
#: stations); beyond, their memory (256 bytes each) and time grow with the square of a recording
MAX_MOTIONS = 1_000_000
MISMATCH_SIGMAS = 5.0


@dataclasses.dataclass(frozen=True)
class AXXBData(PosePairs):
    """Validated data of A_i X = X B_i: read-only float64 stacks A, B of shape (m, 4, 4), with the
    sums over the motions taken once (`handeye.estimation.kronecker.PosePairs`).

    planar: for motions that all rotate about one axis b (X's parent frame), the translation
    ``tz_X`` = t_X . b the user gave, which the data cannot determine
    (`handeye.problems.planar`); else None.
    """

    planar: planar_mode.Planar | None = None
    #: the camera's translations are known only up to scale (`handeye.estimation.camera_scale`)
    camera_scale_unknown: bool = False

    def scaled(self, s: float) -> AXXBData:
        """The same data with every translation divided by s (the planar value too)."""
        out = super().scaled(s)
        return out if self.planar is None else dataclasses.replace(out, planar=self.planar.scaled(s))

    @functools.cached_property
    def pose_model(self) -> Any:
        """The engine's model of these motions (`axxb_geometry.AXXBModel`), built once (read-only)."""
        from handeye.problems.axxb import geometry as axxb_geometry

        return axxb_geometry.AXXBModel(self)

    @functools.cached_property
    def _quaternions(self) -> np.ndarray:
        """Unit quaternions (scalar first, >= 0) of R_A1 .. R_Am, R_B1 .. R_Bm: (2m, 4), from one
        vectorised Shepperd pass over both stacks (`handeye.geometry.so3_fast.quat`)."""
        R = np.concatenate([self.A[:, :3, :3], self.B[:, :3, :3]])
        return so3_fast.quat(R)

    @functools.cached_property
    def quaternions(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit quaternions (q0, qx, qy, qz) of R_Ai and R_Bi with q0 >= 0: two (m, 4) (the
        convention of `handeye.geometry.dualquat`; shared by the quaternion solvers and the logs)."""
        q = self._quaternions
        return q[:self.m], q[self.m:]

    @functools.cached_property
    def _logs(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation vectors (2m, 3) and angles (2m,) of A then B, from `_quaternions`."""
        return so3_fast.log_from_quat(self._quaternions)

    @functools.cached_property
    def rotation_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation vectors (axis times angle, rad) of A_i and B_i: two (m, 3) (scipy's
        ``as_rotvec`` to rounding, from the quaternions: `handeye.geometry.so3_fast.log_from_quat`)."""
        phi = self._logs[0]
        return phi[:self.m], phi[self.m:]

    @functools.cached_property
    def angles(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation angles of A_i and of B_i (rad): two (m,). Equal for exact data (conjugation)."""
        theta = self._logs[1]
        return theta[:self.m], theta[self.m:]

    @functools.cached_property
    def axis_spread(self) -> float:
        """How far apart the rotation axes of the motions of A are (rad, in [0, pi/2]).

        With the unit axes n_i of the motions that rotate by more than MIN_MOTION_ANGLE and
        lambda_1 >= lambda_2 the two largest eigenvalues of sum n_i n_i^T (insensitive to the
        axes' signs), the spread is 2 atan(sqrt(lambda_2 / lambda_1)): for two motions the angle
        between their axes, 0 when all axes are parallel (R_X is then undetermined by a rotation
        about that axis, and t_X along it).
        """
        rotvec, angle = self.rotation_vectors[0], self.angles[0]
        moving = angle > MIN_MOTION_ANGLE
        if moving.sum() < 2:
            return 0.0
        n = rotvec[moving] / angle[moving, None]
        lam = np.linalg.eigvalsh(n.T @ n)
        return float(2.0 * np.arctan(np.sqrt(max(lam[1], 0.0) / lam[2])))

    @functools.cached_property
    def agreeing_share(self) -> float:
        """The share of the data that agree with each other: of the stations the motions were
        made from, when they are every pair of stations (`handeye.geometry.validation.agreeing_share`: a
        gross station spoils all its motions), else of the motions (`agreeing_motions`). At one
        half or below no consistent majority exists."""
        stations = self.stations
        return agreeing_share(*stations) if stations is not None else float(np.mean(self.agreeing_group))

    @functools.cached_property
    def agreeing_group(self) -> np.ndarray:
        """(m,) bool: the motions whose robot and camera rotation angles agree
        (`handeye.geometry.validation.agreeing_motions`), a robust start."""
        return agreeing_motions(*self.angles)

    def normal_equations(self, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
        """The normal equations of the linear system (`normal_equations`)."""
        return normal_equations(self, scale)

    @functools.cached_property
    def stations(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The absolute poses the motions were made from, when they are every pair of n stations
        in `relative_motions` order ("all", the default of `motions`); else None.

        With station 0 as the origin on both sides, A_abs_j = inv(A_(0,j)), B_abs_j =
        inv(B_(0,j)) (j = 1 .. n-1; A_abs_0 = B_abs_0 = I) give A_abs_j X = Y B_abs_j with Y = X
        for exact data; every motion is checked to be inv(A_abs_j) A_abs_i to rounding
        (STATIONS_TOL), which motions made from one set of stations are and independent motions
        are not. These are the absolute poses the motions were made from (`motions`: robot and
        inverse camera poses eye-in-hand, inverse robot and inverse camera poses eye-to-hand) up
        to one common pose on each side, which an AX=YB solve absorbs into Y: its residuals,
        hence its maximum-likelihood X and covariance, are those of A_k X = Y B_k on those poses.
        Eye-in-hand that is ``axyb`` on the recorded stations; eye-to-hand it is the same cell
        written with inverted poses, whose translation residual lives in the flange frame
        rather than the base frame (docs/solvers/auto.md).
        """
        m = self.m
        n = round(float(np.sqrt(1 + 8 * m) + 1) / 2)
        if n * (n - 1) // 2 != m or n < 3:
            return None
        A_abs = np.concatenate([np.eye(4)[None], inverse(self.A[:n - 1])])
        B_abs = np.concatenate([np.eye(4)[None], inverse(self.B[:n - 1])])
        i, j = np.triu_indices(n, k=1)
        tol = STATIONS_TOL * max(self.translation_scale, 1.0)
        for T_abs, T in ((A_abs, self.A), (B_abs, self.B)):
            if np.abs(inverse(T_abs[j]) @ T_abs[i] - T).max() > tol:
                return None
            T_abs.setflags(write=False)  # cached: shared by every solver of these data
        return A_abs, B_abs


def normal_equations(data: AXXBData, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """N = H^T H (12x12), g = H^T w, w^T w of the linear system of the module docstring, with
    every translation divided by `scale`, from sums over the motions taken once.

    With K_i = R_Bi kron R_Ai, T_i = t_Bi^T kron I3 and D_i = I3 - R_Ai:
    N_rr = sum (K_i - I)^T (K_i - I) + T_i^T T_i,  N_rt = sum T_i^T D_i = sum t_Bi kron D_i,
    N_tt = sum D_i^T D_i,  g_r = sum t_Bi kron t_Ai,  g_t = sum D_i^T t_Ai.
    """
    m, s = data.m, float(scale)
    sums = data.translation_sums
    I3 = np.eye(3)
    S = data.rotation_sum
    N = np.zeros((12, 12))
    N[:9, :9] = data.rotation_gram_sum - S - S.T + m * np.eye(9) + np.kron(sums.TB, I3) / s**2
    Nrt = (np.kron(sums.sum_tB[:, None], I3) - sums.C.reshape(9, 3)) / s
    N[:9, 9:], N[9:, :9] = Nrt, Nrt.T
    N[9:, 9:] = m * I3 - sums.sum_RA - sums.sum_RA.T + sums.GA
    g = np.zeros(12)
    g[:9] = sums.tB_tA.reshape(9) / s**2
    g[9:] = (sums.sum_tA - sums.RAt_tA) / s
    return N, g, sums.tA_tA / s**2


def regression_blocks(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-motion blocks H_i: (m, 12, 12) and w_i: (m, 12) of the linear system (module
    docstring), explicitly (for tests and for solvers that need the rows)."""
    m = len(A)
    RA, RB, tA, tB = A[:, :3, :3], B[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    H = np.zeros((m, 12, 12))
    H[:, :9, :9] = np.einsum("nij,nkl->nikjl", RB, RA).reshape(m, 9, 9) - np.eye(9)
    H[:, 9:, :9] = np.einsum("nj,kl->nkjl", tB, np.eye(3)).reshape(m, 3, 9)
    H[:, 9:, 9:] = np.eye(3) - RA
    w = np.zeros((m, 12))
    w[:, 9:] = tA
    return H, w


def solve_translation(data: AXXBData, RX: np.ndarray) -> np.ndarray:
    """t_X by least squares given R_X: (I - R_Ai) t_X = t_Ai - R_X t_Bi, from its 3x3 normal
    equations (sums over the motions taken once). Needs two motions with different axes."""
    from scipy.linalg import LinAlgError, lapack, solve

    sums = data.translation_sums
    D = data.m * np.eye(3) - sums.sum_RA - sums.sum_RA.T + sums.GA  # sum (I - R_A)^T (I - R_A)
    rhs = sums.sum_tA - sums.RAt_tA - RX @ sums.sum_tB + sums.RAt_R_tB(RX)  # sum (I - R_A)^T (t_A - R_X t_B)
    try:
        if np.isfinite(D.sum() + rhs.sum()):  # LAPACK's posv, what solve(assume_a="pos") calls, without its ~50 us of checks
            _, x, info = lapack.dposv(D, rhs)
            if info == 0:
                return x
            raise LinAlgError("not positive definite")
        return solve(D, rhs, assume_a="pos")  # non-finite sums: its error
    except LinAlgError:
        raise DegenerateDataError(
            "the translation of X cannot be determined: the robot motions rotate about fewer than "
            "two different axes. Record motions that rotate about at least two different axes"
        ) from None


def motions(robot_poses: Any, camera_poses: Any, setup: str = "eye-in-hand",
            pairing: str = "all") -> dict[str, np.ndarray]:
    """Relative motions {"A", "B"} for `axxb` from the absolute poses a cell records.

    robot_poses: (n, 4, 4) T_base_flange, the flange pose in the robot base (OpenCV's
        ``gripper2base``). camera_poses: (n, 4, 4) T_cam_target, the calibration board's pose in
        the camera as solvePnP gives it (OpenCV's ``target2cam``). Same order, same length unit.
    setup: "eye-in-hand" (camera on the flange): X = T_flange_cam (OpenCV's ``cam2gripper``);
        "eye-to-hand" (camera fixed, board on the flange): X = T_base_cam (what OpenCV returns
        when given base2gripper poses).
    pairing: "all" (every pair i < j, OpenCV's choice; the default) or "consecutive" (station i
        with i + 1, for drifting cameras): see `relative_motions`.

    With the absolute poses A_k = T_base_flange (eye-in-hand) or T_flange_base (eye-to-hand) and
    B_k = T_target_cam, A_k X = Y B_k holds with a constant Y (T_base_target, T_flange_target),
    and `relative_motions` removes Y.
    """
    if setup not in SETUPS:
        raise InputError(f"setup={setup!r} is not one of {', '.join(SETUPS)}")
    robot = pose_stack(robot_poses, "robot_poses")
    camera = pose_stack(camera_poses, "camera_poses")
    same_length({"robot_poses": robot, "camera_poses": camera}, 2)
    n = len(robot)
    if pairing == "all" and n * (n - 1) // 2 > MAX_MOTIONS:
        raise InputError(
            f"{n} stations make {n * (n - 1) // 2:,} motions with pairing all, more than the {MAX_MOTIONS:,} "
            "handeye forms (about 1,400 stations); solve the stations as problem axyb (A_i X = Y B_i: the same "
            "X, from every station, in linear time), pair consecutive stations only (pairing consecutive), "
            "or keep fewer, well-spread stations")
    A_abs = robot if setup == "eye-in-hand" else inverse(robot)
    A, B = relative_motions(A_abs, inverse(camera), pairing)
    return {"A": A, "B": B}
