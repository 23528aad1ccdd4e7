"""The geometric model of A_i X B_i = Y C_i Z for the least-squares engine (`handeye.nlls`):
residuals and analytic Jacobians on SE(3) x SE(3) x SE(3), and the hooks of the host's
self-check (`handeye.self_check`).

One 6-vector per triple (the per-triple quantities of `AXBYCZ.residuals`, as vectors):

    r_i = log(R_Ai R_X R_Bi R_Z^T R_Ci^T R_Y^T)                 rotation of (A X B)(Y C Z)^-1 [rad]
    t_i = R_Ai R_X t_Bi + R_Ai t_X + t_Ai - R_Y R_Ci t_Z - R_Y t_Ci - t_Y
                                                               t(A X B) - t(Y C Z)  [data units]

Unknowns are perturbed on the right, T <- T exp(xi), xi = (omega, v) (the engine's `retract`:
R <- R exp([omega]_x), t <- t + R v). With Q_i = exp([r_i]_x) the rotation discrepancy:

- X exp(omega_X): R_A R_X exp(omega_X) R_B ... = exp([R_A R_X omega_X]_x) Q, a left perturbation
  of Q, so d r / d omega_X = Jl^-1(r) R_A R_X;
- Y exp(omega_Y): ... R_Y^T becomes exp(-[omega_Y]_x) R_Y^T, Q <- Q exp(-[R_Y omega_Y]_x), a
  right perturbation: d r / d omega_Y = -Jr^-1(r) R_Y;
- Z exp(omega_Z): R_Z^T becomes exp(-[omega_Z]_x) R_Z^T, Q <- Q (R_Y R_C R_Z) exp(-[omega_Z]_x)
  (R_Y R_C R_Z)^T = Q exp(-[R_Y R_C R_Z omega_Z]_x): d r / d omega_Z = -Jr^-1(r) R_Y R_C R_Z;

and the translation discrepancy, with R exp([w]_x) p = R p + R (w x p) to first order:

    d t / d omega_X = -R_A R_X [t_B]_x          d t / d v_X = R_A R_X
    d t / d omega_Y = R_Y [R_C t_Z + t_C]_x     d t / d v_Y = -R_Y
    d t / d omega_Z = 0                         d t / d v_Z = -R_Y R_C R_Z

(Jl^-1, Jr^-1 = (Jl^-1)^T: the inverse left / right Jacobians of SO(3), `handeye.so3_fast`).
Checked against central differences in tests/test_axbycz_problem.py. The normal equations are
formed from this Jacobian (one BLAS product; no closed-form sums: `sums_min_pairs` is infinite).
"""

from __future__ import annotations

import math

import numpy as np

from handeye.estimation.nlls import PoseModel, Poses
from handeye.geometry import so3_fast
from handeye.problems.axbycz.data import AXBYCZData

#: fewest triples for the profile likelihood. The translation residuals (3m numbers) depend on 15
#: parameters (R_X, t_X, R_Y, t_Y, t_Z; R_Z does not enter them), so up to m = 5 they can in
#: general be fitted exactly, and the likelihood with an unknown translation variance is then
#: unbounded (sigma_trans -> 0); from m = 6 on, 18 > 15 equations. (The rotation residuals, 3m
#: numbers in 9 parameters, fit exactly only at m = 3.) Below it the engine uses the start's
#: residuals for the weights ("initial").
PROFILE_MIN_PAIRS = 6


class AXBYCZModel(PoseModel):
    """A_i X B_i = Y C_i Z on (X, Y, Z), parameters (omega_X, v_X, omega_Y, v_Y, omega_Z, v_Z)."""

    unknowns = ("X", "Y", "Z")
    profile_min_pairs = PROFILE_MIN_PAIRS

    def __init__(self, data: AXBYCZData) -> None:
        self.m, self.scale = data.m, data.translation_scale
        self.RA = np.ascontiguousarray(data.A[:, :3, :3])
        self.RB = np.ascontiguousarray(data.B[:, :3, :3])
        self.RC = np.ascontiguousarray(data.C[:, :3, :3])
        self.tA = np.ascontiguousarray(data.A[:, :3, 3])
        self.tB = np.ascontiguousarray(data.B[:, :3, 3])
        self.tC = np.ascontiguousarray(data.C[:, :3, 3])
        self.TBx = so3_fast.skew(self.tB)  # [t_B]_x: (m, 3, 3)

    def _sides(self, poses: Poses) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """R_A R_X, rotations of A X B and of Y C Z, and R_C t_Z + t_C (t(C Z)): the products the
        residuals and the Jacobian share."""
        X, Y, Z = poses
        RAX = self.RA @ X[:3, :3]
        CZ_t = self.RC @ Z[:3, 3] + self.tC
        return RAX, RAX @ self.RB, Y[:3, :3] @ self.RC @ Z[:3, :3], CZ_t, X[:3, 3]

    def residuals(self, poses: Poses) -> np.ndarray:
        """Unwhitened residuals e: (m, 6) = [r_i; t_i] at (X, Y, Z)."""
        Y = poses[1]
        RAX, left, right, CZ_t, tX = self._sides(poses)
        e = np.empty((self.m, 6))
        e[:, :3] = so3_fast.log(left @ np.swapaxes(right, 1, 2))
        e[:, 3:] = (np.einsum("nij,nj->ni", RAX, self.tB) + self.RA @ tX + self.tA
                    - CZ_t @ Y[:3, :3].T - Y[:3, 3])
        return e

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 18) = d e_i / d (omega_X, v_X, omega_Y, v_Y, omega_Z, v_Z) at the poses (module
        docstring), e from `residuals`."""
        _, Y, _ = poses
        RY = Y[:3, :3]
        RAX, _, right, CZ_t, _ = self._sides(poses)
        Jl_inv, Jr_inv = so3_fast.inverse_jacobians(e[:, :3])
        J = np.zeros((self.m, 6, 18))
        J[:, :3, 0:3] = Jl_inv @ RAX
        J[:, :3, 6:9] = -(Jr_inv @ RY)
        J[:, :3, 12:15] = -(Jr_inv @ right)  # right = R_Y R_C R_Z
        J[:, 3:, 0:3] = -(RAX @ self.TBx)
        J[:, 3:, 3:6] = RAX
        J[:, 3:, 6:9] = RY @ so3_fast.skew(CZ_t)
        J[:, 3:, 9:12] = -RY
        J[:, 3:, 15:18] = -right
        return J


# --------------------------------------------------------------------------- the host's self-check

def check_model(data: AXBYCZData, unknowns: dict[str, np.ndarray]) -> tuple[AXBYCZModel, tuple[np.ndarray, ...], tuple[str, ...]]:
    """`Problem.check_model` for A_i X B_i = Y C_i Z: this model at the answer (X, Y, Z)."""
    poses = tuple(np.asarray(unknowns[n], dtype=float) for n in AXBYCZModel.unknowns)
    return AXBYCZModel(data), poses, AXBYCZModel.unknowns


def motion_invariants(data: AXBYCZData, still: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Rotation vectors and translations of paired motions that must be conjugate, between
    consecutive triples i < j of each group where one robot holds still (`AXBYCZData.still_groups`):

    still "C" (robot 2 still): A_i X B_i = A_j X B_j, so (A_j^-1 A_i) X = X (B_j B_i^-1);
    still "A" (robot 1 still): (C_j^-1 C_i) Z = Z (B_j^-1 B_i).

    Returns (phi_robot, t_robot, phi_camera, t_camera), each (n, 3), or None without such pairs.
    """
    i, j = [], []
    for group in data.still_groups(still):
        i.extend(group[:-1])
        j.extend(group[1:])
    if not i:
        return None
    i, j = np.asarray(i), np.asarray(j)
    from handeye.geometry.se3 import inverse

    if still == "C":
        robot = inverse(data.A[j]) @ data.A[i]
        camera = data.B[j] @ inverse(data.B[i])
    else:
        robot = inverse(data.C[j]) @ data.C[i]
        camera = inverse(data.B[j]) @ data.B[i]
    return (so3_fast.log(robot[:, :3, :3]), robot[:, :3, 3], so3_fast.log(camera[:, :3, :3]), camera[:, :3, 3])


def expected_rotation_residual(data: AXBYCZData) -> float | None:
    """`Problem.expected_rotation_residual` for A_i X B_i = Y C_i Z, from the invariants of the
    phase protocol (`motion_invariants`); None unless the data hold both kinds of phases.

    With per-axis rotation noise s_A, s_B, s_C on a pose of A, B, C, the angle difference of a
    robot-1 motion and its camera motion (robot 2 still) has variance s1^2 = 2 s_A^2 + 2 s_B^2,
    that of robot 2's (robot 1 still) s2^2 = 2 s_C^2 + 2 s_B^2, and a triple's residual per-axis
    variance s_A^2 + s_B^2 + s_C^2 = (s1^2 + s2^2) / 2 - s_B^2: at most (s1^2 + s2^2) / 2, which
    is what this returns (the check flags answers ten times over it; the noise of B cannot be
    told from that of A and C). Free motion has no such invariant: robot 1 and robot 2 move
    together, and no motion of one robot alone is conjugate to one of the camera."""
    from handeye.checks.self_check import (
        angle_noise,
        expected_from_invariants,
        pitch_noise,
    )

    sigmas, pitches = [], []
    for still in ("C", "A"):
        found = motion_invariants(data, still)
        if found is None:
            return None
        phi_r, t_r, phi_c, t_c = found
        sigma = angle_noise(np.linalg.norm(phi_r, axis=1), np.linalg.norm(phi_c, axis=1))
        if sigma is None:
            return None
        sigmas.append(sigma)
        pitches.append(pitch_noise(phi_r, t_r, phi_c, t_c) or 0.0)
    return expected_from_invariants(math.hypot(*sigmas), math.hypot(*pitches), data.translation_scale, 1.0)


def rotation_axes(data: AXBYCZData) -> dict[str, np.ndarray]:
    """The main rotation axis of robot 1 in X's frame (its flange: A_k^-1 A_k+1) and in Y's (its
    base: A_k+1 A_k^-1), and of robot 2 in Z's frame (its flange: C_k^-1 C_k+1)."""
    from handeye.checks.self_check import main_axis

    if data.m < 2:
        return {}
    axes = {"X": main_axis(so3_fast.consecutive_logs(data.A)),
            "Y": main_axis(so3_fast.consecutive_logs(data.A, moving=False)),
            "Z": main_axis(so3_fast.consecutive_logs(data.C))}
    return {k: v for k, v in axes.items() if v is not None}
