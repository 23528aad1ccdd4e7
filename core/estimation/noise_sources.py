"""Where the noise of A_i X = Y B_i lives, estimated by maximum likelihood with the unknowns.

The least squares of `handeye.nlls` with estimated weights assumes one noise level per residual
group (rotation, translation), the same for every pair. Real noise enters through the measured
poses, each in its own frame: a camera's rotation error in the target frame moves the translation
residual by the camera-target distance (a lever of 0.3-1 m); a camera's translation error is
largest along its optical axis (a pose from PnP is 3-10x less sure of its depth than of its
sideways position); a robot's rotation error in the base frame moves the translation by the
camera's distance from the base. The residual's covariance then differs from pair to pair and
couples its rotation and translation. Each source k (an error w ~ N(0, s_k^2 I) of one pose, in
one frame, along one axis or all three) maps to pair i's residual e_i = [r_i; t_i] of `AXYBModel`
through a 6 x r_k matrix G_ik (its first-order change when that pose is perturbed so), and

    Cov(e_i) = Sigma_i(theta) = sum_k theta_k G_ik G_ik^T,   theta = s^2 >= 0.

The sources (`SOURCES`), named by the side of A or B the error multiplies: its reference frame
(left: P <- exp(w) P) or its own frame (right: P <- P exp(w)). In axyb's terms (docs/conventions.md)
A = T_base_flange in both setups (own frame: the flange; reference: the base); B = T_target_cam
eye-in-hand (own frame: the camera; reference: the target) and T_cam_target eye-to-hand (own
frame: the target; reference: the camera, whose z is the optical axis):

- rotation of B, reference frame (B <- exp(w) B):   G = [-R_Y; R_Y [t_B]x] (a lever of |t_B|)
- rotation of B, own frame (B <- B exp(w)):         G = [-R_Y R_B; 0]
- rotation of A, own frame (A <- A exp(w)):         G = [R_A; -R_A [t_X]x]
- rotation of A, reference frame (A <- exp(w) A):   G = [I; -[R_A t_X + t_A]x]
- translation of B along its own x, y and z (one source each): G = [0; R_Y R_B e_j]. Together
  they hold any isotropic translation error (either pose, any frame: the robot's too), and
  eye-in-hand the extra depth error of a camera along its optical axis z.
- translation of B along its reference frame's z: G = [0; R_Y e_3]: the optical axis eye-to-hand.

Chosen by measurement (KinHEC small tier, and the simulator's isotropic noise, where the
per-group model is the true one): per-axis translation sources in both of the camera pose's
frames (6) or a robot translation along its flange axes made the answers no better on KinHEC
and up to 9% worse on the simulator at 16 pairs; these 8 sources cost 1-3% there (geometric
mean of X's translation error, 30 data sets at 16, 30 and 60 pairs).

`fit` takes two steps (feasible generalised least squares): the per-group least squares, the
variances by maximum likelihood at its residuals (`variances`: Fisher scoring from a moment
estimate, non-negative, with an EM step wherever scoring would lower the likelihood), then the
unknowns by `handeye.nlls` with every pair whitened by its Sigma_i. The first step's answer is
consistent, so the second is as efficient as the joint maximum likelihood to first order.
Measured on the KinHEC small tier (docs/solvers/auto.md, "Noise sources"): median X translation
0.68x the per-group model's on the noise track and 0.36x on the PnP track; alternating the two
steps to convergence (3-4 rounds) moved the track medians by 1-9% (better on motion, 9%, and
PnP, 2%; worse on the other five) at 1.5x the time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import nnls

from handeye.estimation import nlls
from handeye.estimation.whitening import Whitening
from handeye.geometry.so3_fast import skew

#: the noise sources, in the order of the variances
SOURCES = ("rotation of B, reference frame", "rotation of B, own frame", "rotation of A, own frame",
           "rotation of A, reference frame", "translation of B, own x", "translation of B, own y",
           "translation of B, own z", "translation of B, reference z")
#: the variances' iterations stop when the log-likelihood gains less than this (nats) or after
#: VARIANCE_ITER
LOGLIK_TOL = 0.01
VARIANCE_ITER = 20
#: the variances are estimated on at most this many pairs, evenly spaced in the data's order:
#: 8 variances from 12,000 residuals are known to ~1-2%, which moves no weight that matters, and
#: every pair still enters the fit of X and Y (measured: auto at m = 1e5 took 4.1 s with every
#: pair in the variances' iterations, against 0.55 s for the per-group model alone)
VARIANCE_PAIRS = 2000
#: relative floor of Sigma_i's diagonal (of the mean trace of its rotation block, and of its
#: translation block): keeps it positive definite where every source that reaches a direction
#: went to zero
COVARIANCE_FLOOR = 1e-12
#: relative floor of each variance (of its start, the residual group's mean square): keeps the
#: scoring step's variances positive, so that a source can come back. Relative to its own
#: group, not to all variances, so that the answer does not depend on the length unit.
VARIANCE_FLOOR = 1e-10


def factors(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> list[np.ndarray]:
    """G_k: (m, 6, r_k) for each source of `SOURCES` (module docstring), in that order."""
    RA, tA, RB, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3]
    tX, RY = X[:3, 3], Y[:3, :3]
    m = len(A)

    def rotation(top: np.ndarray, bottom: np.ndarray | None = None) -> np.ndarray:
        G = np.zeros((m, 6, 3))
        G[:, :3] = top
        if bottom is not None:
            G[:, 3:] = bottom
        return G

    def axis(frame: np.ndarray, j: int) -> np.ndarray:
        G = np.zeros((m, 6, 1))
        G[:, 3:, 0] = frame[..., j]
        return G

    camera_axes = RY @ RB
    return [rotation(-RY, RY @ skew(tB)), rotation(-camera_axes), rotation(RA, -RA @ skew(tX)),
            rotation(np.eye(3), -skew(RA @ tX + tA)),
            axis(camera_axes, 0), axis(camera_axes, 1), axis(camera_axes, 2), axis(np.broadcast_to(RY, (m, 3, 3)), 2)]


def _floored(S: np.ndarray) -> np.ndarray:
    """S with COVARIANCE_FLOOR added to the diagonal of its rotation and translation blocks."""
    for block in (np.arange(3), np.arange(3, 6)):  # rotation, translation
        S[:, block, block] += COVARIANCE_FLOOR * max(float(np.mean(S[:, block, block])), 1e-300)
    return S


class _Stack:
    """The sources' factors side by side, H = [G_1 ... G_K]: (m, 6, R), and Sigma_i(theta)."""

    def __init__(self, G: list[np.ndarray]) -> None:
        self.H = np.concatenate(G, axis=2)
        sizes = [g.shape[2] for g in G]
        self.column_source = np.repeat(np.arange(len(G)), sizes)
        self.starts = np.cumsum([0] + sizes[:-1])

    def sigma(self, theta: np.ndarray) -> np.ndarray:
        return _floored((self.H * theta[self.column_source]) @ np.swapaxes(self.H, 1, 2))

    def per_source(self, values: np.ndarray, axis: int) -> np.ndarray:
        """Sums of `values` over each source's columns along `axis`."""
        return np.add.reduceat(values, self.starts, axis=axis)


def _inverse_and_log_likelihood(S: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, float]:
    """(S^-1, the Gaussian log-likelihood of residuals e: (m, 6) under covariances S, up to its
    constant)."""
    Si = np.linalg.inv(S)
    logdet = np.linalg.slogdet(S)[1]
    return Si, -0.5 * float(np.sum(logdet) + np.einsum("mi,mij,mj->", e, Si, e))


def variances(G: list[np.ndarray], e: np.ndarray, theta: np.ndarray, floor: np.ndarray,
              iterations: int = VARIANCE_ITER) -> tuple[np.ndarray, np.ndarray]:
    """The maximum-likelihood variances theta >= 0 of Sigma_i = sum_k theta_k G_ik G_ik^T for the
    residuals e: (m, 6), from `theta`, each kept at `floor` or above; returns (theta, Sigma).

    Fisher scoring: with u_i = Sigma_i^-1 e_i, the stationary points solve F theta = q, where
    F_kl = sum_i ||G_ik^T Sigma_i^-1 G_il||_F^2 and q_k = sum_i ||G_ik^T u_i||^2 (both at the
    current theta); the step solves it with theta >= 0 (non-negative least squares). Where that
    would lower the likelihood the EM update theta_k <- theta_k q_k / trace(G_k^T Sigma^-1 G_k)
    (summed over i) is taken instead, which never does."""
    stack = _Stack(G)
    S = stack.sigma(theta)
    Si, loglik = _inverse_and_log_likelihood(S, e)
    for _ in range(iterations):
        SiH = Si @ stack.H
        M = np.swapaxes(stack.H, 1, 2) @ SiH                  # H^T Sigma^-1 H: (m, R, R)
        v = np.einsum("mir,mi->mr", SiH, e)                   # H^T u
        F = stack.per_source(stack.per_source(np.einsum("mab,mab->ab", M, M), 0), 1)
        q = stack.per_source(np.sum(v * v, axis=0), 0)
        d = np.sqrt(np.maximum(np.diag(F), 1e-300))
        new = nnls(F / np.outer(d, d), q / d)[0] / d
        if np.any(new > 0):
            new = np.maximum(new, floor)
            S_new = stack.sigma(new)
            Si_new, loglik_new = _inverse_and_log_likelihood(S_new, e)
        if not np.any(new > 0) or loglik_new < loglik:
            new = np.maximum(theta * q / np.maximum(stack.per_source(np.einsum("mrr->r", M), 0), 1e-300), floor)
            S_new = stack.sigma(new)
            Si_new, loglik_new = _inverse_and_log_likelihood(S_new, e)
        gain = loglik_new - loglik
        theta, S, Si, loglik = new, S_new, Si_new, loglik_new
        if gain <= LOGLIK_TOL:
            break
    return theta, S


def moment_start(G: list[np.ndarray], e: np.ndarray, rotation_var: float, translation_var: float) -> np.ndarray:
    """The variances that best match the residuals' outer products, e_i e_i^T ~ Sigma_i(theta), by
    non-negative least squares over the entries (each scaled by its groups' mean squares): a
    moment estimate, linear in theta, that starts the likelihood's iterations close to their end
    (measured on the KinHEC PnP track: 4-6 iterations instead of 8-13 from an even split)."""
    rows, cols = np.triu_indices(6)
    scale = np.sqrt(np.where(np.arange(6) < 3, rotation_var, translation_var))
    norm = scale[rows] * scale[cols]
    design = np.stack([np.einsum("mir,mjr->mij", g, g)[:, rows, cols] / norm for g in G], axis=-1)  # (m, 21, K)
    target = (e[:, rows] * e[:, cols]) / norm
    return nnls(design.reshape(-1, len(G)), target.ravel())[0]


def fit(model: Any, data: Any, poses: tuple[np.ndarray, ...], settings: nlls.Settings
        ) -> tuple[tuple[np.ndarray, ...], Any, dict[str, Any]]:
    """The unknowns (X, Y) of A_i X = Y B_i weighted by the noise sources, in two steps (feasible
    generalised least squares; module docstring): the per-group fit from `poses` with
    `settings` (estimated weights, least squares), the sources' variances by maximum likelihood
    at its residuals, then the unknowns converged with every pair whitened by its Sigma_i.
    Returns (poses, status, diagnostics of the last fit with ``noise_sources``: each source's
    standard deviation, rad or data units, and ``loglik_gain``: the log-likelihood at the end over
    the per-group model's at its fit, nats)."""
    poses = nlls.levenberg_marquardt(model, poses, settings.W, settings.loss, settings.loss_scale, settings.max_iter,
                                     settings.tol, settings.estimate).poses  # the per-group fit (auto's answer already)
    e = model.residuals(poses)
    m = len(e)
    G = factors(data.A, data.B, poses[0], poses[1])
    rotation_var = max(float(np.sum(e[:, :3] ** 2)) / (3 * m), 1e-300)
    translation_var = max(float(np.sum(e[:, 3:] ** 2)) / (3 * m), 1e-300 * model.scale**2)
    floor = VARIANCE_FLOOR * np.array([rotation_var] * 4 + [translation_var] * (len(G) - 4))
    some = np.unique(np.linspace(0, m - 1, min(m, VARIANCE_PAIRS)).astype(int))
    G_some = [g[some] for g in G]
    start = np.maximum(moment_start(G_some, e[some], rotation_var, translation_var), floor)
    theta, S = variances(G_some, e[some], start, floor)
    if len(some) < m:
        S = _Stack(G).sigma(theta)
    W = Whitening(L=np.linalg.cholesky(S))
    stated = nlls.Settings(W=W, weights="covariance", loss=settings.loss, loss_scale=settings.loss_scale,
                           max_iter=settings.max_iter, tol=settings.tol)
    poses, status, diag = nlls.refine(model, poses, stated)
    z = W.residual(model.residuals(poses))
    loglik = -float(np.sum(np.log(np.diagonal(W.L, axis1=1, axis2=2)))) - 0.5 * float(np.sum(z * z))
    groups_loglik = -1.5 * m * (math.log(rotation_var) + math.log(translation_var) + 2.0)
    diag = {**diag, "weights": "estimated", "noise_model": "sources", "loglik_gain": loglik - groups_loglik,
            "noise_sources": {name: math.sqrt(float(t)) if t > 2.0 * f else 0.0  # at its floor: gone
                              for name, t, f in zip(SOURCES, theta, floor)}}
    return poses, status, diag
