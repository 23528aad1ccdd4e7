"""The geometric model of A_i X = X B_i for the least-squares engine (`handeye.estimation.nlls`): residuals
and Jacobians on SE(3).

One 6-vector per motion:

    r_i = log(R_Ai R_X R_Bi^T R_X^T)            rotation vector of the discrepancy [rad]
    t_i = R_Ai t_X + t_Ai - R_X t_Bi - t_X       t(A_i X) - t(X B_i)              [data units]

This is the model of A_i X = Y B_i (`axyb_geometry`) on the diagonal Y = X, which is how it is
built: `AXXBModel` shares `AXYBModel`'s arrangement of the data and its residuals (called with
(X, X)). X is perturbed on the right, X <- X exp(xi), xi = (omega, v). With
Q_i = R_A R_X R_B^T R_X^T = exp([r_i]_x), X exp(omega) changes Q to
exp([R_A R_X omega]_x) Q exp(-[R_X omega]_x) to first order, so (derivation in
docs/solvers/refine.md, checked against central differences in tests/plugins/test_refine.py)

    d r / d omega = Jl^-1(r) R_A R_X - Jr^-1(r) R_X      d r / d v = 0
    d t / d omega = R_X [t_B]_x                          d t / d v = (R_A - I) R_X

i.e. the sum of the X and Y columns of A X = Y B's Jacobian at Y = X (the chain rule), and the
closed-form normal equations are those of A X = Y B folded the same way:
g = g_X + g_Y, H = H_XX + H_XY + H_YX + H_YY.

The ML weights treat the motions as independent. Motions differenced from absolute poses
(`problems.axxb.relative_motions`) share the noise of a station, so they are correlated; the
estimate stays consistent, but is not the exact ML estimate of such data and its covariance is
approximate (docs/solvers/refine.md measures both).
"""

from __future__ import annotations

import numpy as np

from handeye.estimation import camera_scale
from handeye.estimation.kronecker import PosePairs
from handeye.estimation.nlls import Poses
from handeye.geometry import so3_fast
from handeye.problems.axyb.geometry import AXYBModel

#: fewest motions for the profile likelihood: the translation residuals (3m numbers) depend on 6
#: parameters (R_X, t_X), so with m = 2 they can be fitted exactly and the likelihood with an
#: unknown translation variance is unbounded (sigma_trans -> 0).
PROFILE_MIN_PAIRS = 3


class AXXBModel(AXYBModel):
    """A_i X = X B_i on X: `AXYBModel` restricted to Y = X (module docstring)."""

    unknowns = ("X",)
    profile_min_pairs = PROFILE_MIN_PAIRS
    noise_sources = False  # motions: each shares its stations' noise, which the sources do not model

    def __init__(self, data: PosePairs) -> None:
        super().__init__(data)  # the same fields A, B and translation_scale

    def residuals(self, poses: Poses) -> np.ndarray:
        """e: (m, 6) = [r_i; t_i] at X."""
        X, = poses
        return super().residuals((X, X))

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 6) = d e_i / d (omega, v) at X, e from `residuals`: rotation rows
        [Jl^-1(r) R_A R_X - Jr^-1(r) R_X, 0], translation rows [R_X [t_B]_x, R_A R_X - R_X]."""
        X, = poses
        m = self.m
        RX = X[:3, :3]
        RAX = (self.RA9 @ RX).reshape(m, 3, 3)
        Jl_inv, Jr_inv = so3_fast.inverse_jacobians(e[:, :3])
        J = np.empty((m, 6, 6))
        J[:, :3, 0:3] = Jl_inv @ RAX - (Jr_inv.reshape(3 * m, 3) @ RX).reshape(m, 3, 3)
        J[:, :3, 3:6] = 0.0
        J[:, 3:, 0:3] = (RX @ self.TBx_T).reshape(3, m, 3).transpose(1, 0, 2)
        J[:, 3:, 3:6] = RAX - RX
        return J

    def camera_direction(self, poses: Poses) -> np.ndarray:
        """d e / d s for camera translations s t_B: (m, 6) = [0; -R_X t_B]."""
        X, = poses
        return super().camera_direction((X, X))

    def translation_gradient(self, poses: Poses, t: np.ndarray) -> np.ndarray:
        """`AXYBModel.translation_gradient` at (X, X), folded onto X: (6,)."""
        X, = poses
        g = super().translation_gradient((X, X), t)
        return g[:6] + g[6:]

    def normal_equations(self, poses: Poses, e: np.ndarray, wr: float, wt: float,
                         d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A X = Y B's closed-form sums at (X, X), folded onto X (module docstring)."""
        X, = poses
        g_rot, g_trans, H = super().normal_equations((X, X), e, wr, wt, d)
        return g_rot[:6] + g_rot[6:], g_trans[:6] + g_trans[6:], H[:6, :6] + H[:6, 6:] + H[6:, :6] + H[6:, 6:]


# --------------------------------------------------------------------------- the host's self-check

def expected_rotation_residual(data: PosePairs) -> float | None:
    """`Problem.expected_rotation_residual` for A_i X = X B_i: from the angle and pitch differences
    of the motions themselves; a motion's residual carries two stations' noise, as its angle
    difference."""
    from handeye.checks.self_check import (
        angle_noise,
        expected_from_invariants,
        pitch_noise,
    )

    phi_A, phi_B = data.rotation_vectors
    pitch = None if data.camera_scale_unknown else pitch_noise(phi_A, data.A[:, :3, 3], phi_B, data.B[:, :3, 3])
    return expected_from_invariants(angle_noise(*data.angles), pitch, data.translation_scale, 2.0)


def rotation_axes(data: PosePairs) -> dict[str, np.ndarray]:
    """The robot's main rotation axis in X's frame: that of the motions A_i."""
    from handeye.checks.self_check import main_axis

    axis = main_axis(data.rotation_vectors[0])
    return {} if axis is None else {"X": axis}


def check_model(data: PosePairs, unknowns: dict[str, np.ndarray]) -> tuple[AXYBModel, tuple[np.ndarray, ...], tuple[str, ...]]:
    """`Problem.check_model` for A_i X = X B_i. Motions made from every pair of n stations share
    their noise, so a motion model would count each station n - 1 times: when the stations are
    recoverable (`AXXBData.stations`) the model is A_k X = Y B_k on them, with Y (the pose of
    station 0, a nuisance) fitted to the answer's X; else the motion model."""
    from handeye.problems.axyb.data import AXYBData
    from handeye.problems.axyb.geometry import fitted_Y

    X = np.asarray(unknowns["X"], dtype=float)
    if data.stations is not None:
        A, B = data.stations
        stations = AXYBData(A, B, planar=data.planar, camera_scale_unknown=data.camera_scale_unknown)
        return camera_scale.model_for(stations, AXYBModel(stations)), (X, fitted_Y(A, B, X)), ("X",)
    return camera_scale.model_for(data, data.pose_model), (X,), ("X",)
