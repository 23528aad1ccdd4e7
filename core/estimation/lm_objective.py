"""The objective `handeye.estimation.nlls` minimises and its local quadratic model: how the
weights are obtained (`mode_of`), the objective itself with the profile likelihood over the two
variances (`objective`), and the gradient, Gauss-Newton Hessian and information matrix at a point
(`local_model`), from the model's Jacobian (`jacobian_model`: one BLAS product J^T J) or from its
closed-form sums (`sums_model`, `PoseModel.normal_equations`, at large m). docs/solvers/refine.md
derives them.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from handeye.estimation.pose_model import PoseModel, Poses
from handeye.estimation.robust import loss_terms
from handeye.estimation.whitening import (
    SIGMA_FLOOR,
    Whitening,
    rms_whitening,
    sums_of_squares,
)
from handeye.geometry.linalg import einsum, row_sums_of_squares


def mode_of(W: Whitening | None, loss: str, m: int, estimate: str = "profile", profile_min_pairs: int = 4) -> str:
    """How the weights are obtained: "fixed" (stated); estimated with estimate="profile":
    "profile" (least squares, m >= profile_min_pairs), "irls" (robust loss), "initial" (least
    squares with fewer pairs); estimate="initial": "initial" (the start's residuals, then fixed)."""
    if W is not None:
        return "fixed"
    if estimate == "initial":
        return "initial"
    if loss != "linear":
        return "irls"
    return "profile" if m >= profile_min_pairs else "initial"


def objective(e: np.ndarray, W: Whitening | None, mode: str, loss: str, c: float, scale: float) -> tuple[float, Whitening]:
    """The objective minimised, at residuals e: (m, 6), and the weights it uses there.

    "fixed", "irls", "initial": F = 1/2 sum_i rho(|W^(1/2) e_i|^2) under the given W.
    "profile": the negative log-likelihood with the two variances unknown, minimised over them
    (profile likelihood): sigma_rot, sigma_trans = RMS of the residuals (`estimate_sigmas`) and
    L = 3m log sigma_rot + 3m log sigma_trans + 1/2 sum_i |W^(1/2) e_i|^2 (= 3m (log sigma_rot +
    log sigma_trans + 1) unless a sigma is at its floor). Unlike a fixed point of "estimate the
    weights, then minimise", L is one smooth function: monotone descent, quadratic convergence.
    """
    if mode == "profile":
        sum_rot, sum_trans = sums_of_squares(e)
        W = rms_whitening(sum_rot, sum_trans, len(e), scale)
        return (3.0 * len(e) * (math.log(W.sigma_rot) + math.log(W.sigma_trans))
                + 0.5 * (sum_rot / W.sigma_rot**2 + sum_trans / W.sigma_trans**2)), W
    ew = W.residual(e)
    return 0.5 * float(loss_terms(row_sums_of_squares(ew), loss, c)[0].sum()), W


def cost_of(model: PoseModel, poses: Poses, W: Whitening, loss: str, c: float) -> float:
    """F = 1/2 sum_i rho(|W^(1/2) e_i|^2) at the poses under weights W."""
    return objective(model.residuals(poses), W, "fixed", loss, c, 1.0)[0]


def jacobian_model(e: np.ndarray, J: np.ndarray, W: Whitening, mode: str, loss: str, c: float,
                    scale: float, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Gradient g (n), Gauss-Newton Hessian H of the objective, Hw = sum rho' J_w^T J_w (the
    information matrix, for the covariance) and F under W, from residuals e: (m, 6) and their
    Jacobian J: (m, 6, n).

    "profile": d L = sum_groups J_w^T e_w (as least squares under the current RMS weights) and
    H = Hw - 2 / (3m) sum_groups a a^T with a = J_w,group^T e_w,group (the log's curvature), for
    each group (rotation, translation) whose sigma is above its floor; Hw when that is not
    positive definite (far from the minimum), which keeps the step a descent direction.
    With a basis P of the allowed perturbations (`fixed_basis`) everything is in its
    coordinates (J P).
    """
    if P is not None:
        J = J @ P
    n = J.shape[2]
    ew, Jw = W.residual(e), W.jacobian(J)
    if loss == "linear":
        F = 0.5 * float((ew * ew).sum())
    else:
        rho, drho = loss_terms((ew * ew).sum(axis=1), loss, c)
        F = 0.5 * float(rho.sum())
        sq = np.sqrt(drho)
        ew, Jw = ew * sq[:, None], Jw * sq[:, None, None]
    Jf = Jw.reshape(-1, n)
    Hw = Jf.T @ Jf
    if mode != "profile":
        return Jf.T @ ew.reshape(-1), Hw, Hw, F
    m = len(e)
    a = einsum("ngik,ngi->gk", Jw.reshape(m, 2, 3, n), ew.reshape(m, 2, 3))  # gradient per group
    return a[0] + a[1], profile_hessian(Hw, a, W, m, scale), Hw, F


def sums_model(model: PoseModel, poses: Poses, e: np.ndarray, W: Whitening, mode: str, loss: str,
                c: float, scale: float, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """`jacobian_model` for per-group sigmas from the model's closed-form `normal_equations`."""
    ew = W.residual(e)
    rho, d = loss_terms(einsum("ni,ni->n", ew, ew), loss, c)
    F = 0.5 * float(np.sum(rho))
    g_rot, g_trans, Hw = model.normal_equations(poses, e, 1.0 / W.sigma_rot**2, 1.0 / W.sigma_trans**2, d)
    if P is not None:
        g_rot, g_trans, Hw = g_rot @ P, g_trans @ P, P.T @ Hw @ P
    g = g_rot + g_trans
    H = profile_hessian(Hw, np.stack([g_rot, g_trans]), W, model.m, scale) if mode == "profile" else Hw
    return g, H, Hw, F


def profile_hessian(Hw: np.ndarray, a: np.ndarray, W: Whitening, m: int, scale: float) -> np.ndarray:
    """Hw - 2/(3m) a_g a_g^T for each group g (rows of a: (2, n), rotation and translation) whose
    sigma is above its floor (the logs' curvature of the profile likelihood); Hw itself when that
    is not positive definite (far from the minimum)."""
    if W.sigma_rot <= SIGMA_FLOOR or W.sigma_trans <= SIGMA_FLOOR * scale:
        a = a[[W.sigma_rot > SIGMA_FLOOR, W.sigma_trans > SIGMA_FLOOR * scale]]
    H = Hw - (2.0 / (3.0 * m)) * (a.T @ a)
    return H if lapack.dpotrf(H)[1] == 0 else Hw  # LAPACK's Cholesky: info 0 = positive definite


def local_model(model: PoseModel, poses: Poses, e: np.ndarray, W: Whitening, mode: str, loss: str,
                c: float, scale: float, P: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(g, H, Hw, F) at the poses: the model's closed-form sums for per-group sigmas and
    m >= sums_min_pairs, else from the explicit Jacobian (fewer numpy calls: faster at small m);
    in the coordinates of the basis P of allowed perturbations when given (`fixed_basis`)."""
    if W.L is None and model.m >= model.sums_min_pairs:
        return sums_model(model, poses, e, W, mode, loss, c, scale, P)
    return jacobian_model(e, model.jacobian(poses, e), W, mode, loss, c, scale, P)
