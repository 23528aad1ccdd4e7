"""What each planned station of A_i X = Y B_i would tell about X and Y: the Fisher information of
(X, Y) from one station at the expected noise (the planner's `Problem.station_information`).

The residual e_i = [r_i; t_i] of `AXYBModel` at the truth moves with the unknowns by its Jacobian
J_i (right perturbations of X and Y) and with the noise of the measured poses by

- the camera pose B <- B exp(xi), xi = (omega, v) in B's own frame with covariance C_i (from the
  board's corners, `handeye.planning.views`): G_B = -[[R_Y R_B, 0], [0, R_Y R_B]] (a rotation of
  B about its own origin leaves t_B where it is);
- the robot's rotation in its own frame A <- A exp(omega) (`noise.robot_factors`) and its
  translation, isotropic in the base frame: G = [0; I];

so Cov(e_i) = G_B C_i G_B^T + s_rA^2 G_rA G_rA^T + s_tA^2 [0, 0; 0, I], and the station's
information is J_i^T Cov(e_i)^-1 J_i (12 x 12). The maximum-likelihood fit of many stations has
the covariance (sum of those)^-1 to first order.
"""

from __future__ import annotations

import types

import numpy as np

from handeye.problems.axyb.geometry import AXYBModel
from handeye.problems.axyb.noise import robot_factors


def residual_covariance(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray, robot_sigma: tuple[float, float],
                        camera_cov: np.ndarray) -> np.ndarray:
    """(m, 6, 6) covariance of each station's residual (module docstring)."""
    RYRB = Y[:3, :3] @ B[:, :3, :3]
    G = np.zeros((len(A), 6, 6))
    G[:, :3, :3] = -RYRB
    G[:, 3:, 3:] = -RYRB
    cov = G @ camera_cov @ np.swapaxes(G, 1, 2)
    rot, trans = robot_sigma
    G_rot = robot_factors(A[:, :3, :3], A[:, :3, 3], X[:3, 3])[0]
    cov += rot**2 * G_rot @ np.swapaxes(G_rot, 1, 2)
    cov[:, 3:, 3:] += trans**2 * np.eye(3)
    return cov


def station_information(A: np.ndarray, B: np.ndarray, unknowns: dict[str, np.ndarray], robot_sigma: tuple[float, float],
                        camera_cov: np.ndarray) -> np.ndarray:
    """(m, 12, 12): the information of (X, Y), in `AXYBModel`'s order (omega_X, v_X, omega_Y,
    v_Y), from each station (A_i, B_i) exactly as planned, B_i's own-frame covariance camera_cov
    (m, 6, 6) and the robot's noise robot_sigma (rad, length) per axis."""
    X, Y = unknowns["X"], unknowns["Y"]
    model = AXYBModel(types.SimpleNamespace(A=A, B=B, translation_scale=1.0))
    J = model.jacobian((X, Y), np.zeros((len(A), 6)))
    cov = residual_covariance(A, B, X, Y, robot_sigma, camera_cov)
    return np.swapaxes(J, 1, 2) @ np.linalg.solve(cov, J)
