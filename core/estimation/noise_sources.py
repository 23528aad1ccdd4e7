"""Where the noise of pose residuals lives, estimated by maximum likelihood with the unknowns.

The least squares of `handeye.estimation.nlls` with estimated weights assumes one noise level per residual
group (rotation, translation), the same for every observation. Real noise enters through the
measured poses, each in its own frame, and differs from camera to camera: a rotation error of a
camera's pose moves the translation residual by a lever arm, a pose from PnP is less sure of its
depth, one camera of a cell is noisier than the next. The residual's covariance then differs
from observation to observation and couples its rotation and translation. Each source k (an
error w ~ N(0, s_k^2 I) of one pose, in one frame, along one axis or all three) maps to
observation i's residual e_i = [r_i; t_i] through a 6 x r_k matrix G_ik (its first-order change
when that pose is perturbed so), and

    Cov(e_i) = Sigma_i(theta) = sum_k theta_k G_ik G_ik^T,   theta = s^2 >= 0.

The model says which sources act on its residuals (`PoseModel.noise_factors`, a `Sources`): A_i X
= Y B_i's eight (`handeye.problems.axyb.noise`), the multi-camera cell's per camera and per
target (`handeye.problems.axyb_multi.noise`). Only the sources that reach an observation are
stored for it (a few columns each, with the source of every column), so that many sources cost
no more per observation than a few.

`fit` takes two steps (feasible generalised least squares): the per-group least squares, the
variances by maximum likelihood at its residuals (`variances`: Fisher scoring from a moment
estimate, non-negative, with an EM step wherever scoring would lower the likelihood), then the
unknowns by `handeye.estimation.nlls` with every pair whitened by its Sigma_i. The first step's answer is
consistent, so the second is as efficient as the joint maximum likelihood to first order.
Measured on the KinHEC small tier (docs/solvers/auto.md, "Noise sources"): median X translation
0.68x the per-group model's on the noise track and 0.36x on the PnP track; alternating the two
steps to convergence (3-4 rounds) moved the track medians by 1-9% (better on motion, 9%, and
PnP, 2%; worse on the other five) at 1.5x the time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import nnls
from scipy.stats import chi2

from handeye.base.errors import DegenerateDataError
from handeye.estimation import nlls
from handeye.estimation.whitening import Whitening

#: the variances' iterations stop when the log-likelihood gains less than this (nats) or after
#: VARIANCE_ITER
LOGLIK_TOL = 0.01
VARIANCE_ITER = 20
#: the variances are estimated on at most this many observations, evenly spaced in the data's
#: order: 8 variances from 12,000 residuals are known to ~1-2%, which moves no weight that
#: matters, and every observation still enters the fit of the unknowns (measured: axyb's auto at
#: m = 1e5 took 4.1 s with every pair in the variances' iterations, against 0.55 s for the
#: per-group model alone)
VARIANCE_PAIRS = 2000
#: relative floor of Sigma_i's diagonal (of the mean trace of its rotation block, and of its
#: translation block): keeps it positive definite where every source that reaches a direction
#: went to zero
COVARIANCE_FLOOR = 1e-12
#: relative floor of each variance (of its start, the residual group's mean square): keeps the
#: scoring step's variances positive, so that a source can come back. Relative to its own
#: group, not to all variances, so that the answer does not depend on the length unit.
VARIANCE_FLOOR = 1e-10
#: why the sources cannot be estimated from residuals whose squares overflow
OVERFLOW = ("the residuals or the poses are too large to estimate where the noise comes from (their squares "
            "overflow): check the data's length unit and for corrupted poses")
#: the sources replace the per-group model where they explain the residuals better than chance
#: would at this level: the likelihood-ratio test of their variances against the two groups'
#: (`min_gain`)
TEST_LEVEL = 0.01


@dataclasses.dataclass(frozen=True)
class Sources:
    """The noise sources that act on a model's residuals, at given unknowns.

    H: (m, 6, R), the factors G_ik of the sources that reach observation i, side by side (R
    columns, the same count for every observation); column_source: (m, R), the source of each
    column (columns of one source are adjacent); names: (K,) the sources' names, in the order of
    the variances; translation: (K,) True for a source that moves translations only (its floor
    is the translation group's)."""

    H: np.ndarray
    column_source: np.ndarray
    names: tuple[str, ...]
    translation: np.ndarray

    @classmethod
    def of(cls, G: Sequence[np.ndarray], names: Sequence[str], translation: Sequence[bool]) -> Sources:
        """Sources that reach every observation: G_k: (m, 6, r_k), one per name."""
        return cls.side_by_side(np.concatenate(G, axis=2), [g.shape[2] for g in G], names, translation)

    @classmethod
    def side_by_side(cls, H: np.ndarray, widths: Sequence[int], names: Sequence[str],
                     translation: Sequence[bool]) -> Sources:
        """Sources that reach every observation, their G_k side by side in H: (m, 6, R), widths[k]
        columns each, one per name."""
        columns = np.repeat(np.arange(len(widths)), widths)
        return cls(H, np.broadcast_to(columns, H.shape[::2]), tuple(names), np.asarray(translation, dtype=bool))

    @property
    def count(self) -> int:
        return len(self.names)

    def rows(self, which: np.ndarray) -> Sources:
        """The same sources on the observations `which` only."""
        return dataclasses.replace(self, H=self.H[which], column_source=self.column_source[which])

    def sigma(self, theta: np.ndarray) -> np.ndarray:
        """Sigma_i(theta): (m, 6, 6), floored (`_floored`)."""
        return _floored((self.H * theta[self.column_source][:, None, :]) @ np.swapaxes(self.H, 1, 2))

    def per_source(self, values: np.ndarray) -> np.ndarray:
        """(K,): sums of values: (m, R) over each source's columns and every observation."""
        return np.bincount(self.column_source.ravel(), weights=values.ravel(), minlength=self.count)

    def per_source_pair(self, values: np.ndarray) -> np.ndarray:
        """(K, K): sums of values: (m, R, R) over the columns of each pair of sources."""
        cs, K = self.column_source, self.count
        index = cs[:, :, None] * K + cs[:, None, :]
        return np.bincount(index.ravel(), weights=values.ravel(), minlength=K * K).reshape(K, K)


def min_gain(count: int) -> float:
    """The log-likelihood gain (nats) that `count` sources need over the two groups' variances:
    half the (1 - TEST_LEVEL) point of chi^2 with count - 2 degrees of freedom (8.4 nats for 8)."""
    return 0.5 * float(chi2.ppf(1.0 - TEST_LEVEL, max(count - 2, 1)))


def _floored(S: np.ndarray) -> np.ndarray:
    """S with COVARIANCE_FLOOR added to the diagonal of its rotation and translation blocks."""
    for block in (np.arange(3), np.arange(3, 6)):  # rotation, translation
        S[:, block, block] += COVARIANCE_FLOOR * max(float(np.mean(S[:, block, block])), 1e-300)
    return S


def _inverse_and_log_likelihood(S: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, float]:
    """(S^-1, the Gaussian log-likelihood of residuals e: (m, 6) under covariances S, up to its
    constant)."""
    Si = np.linalg.inv(S)
    logdet = np.linalg.slogdet(S)[1]
    return Si, -0.5 * float(np.sum(logdet) + np.einsum("mi,mij,mj->", e, Si, e))


def _nonnegative(DtD: np.ndarray, Dtb: np.ndarray) -> np.ndarray:
    """argmin |D x - b| over x >= 0 from the normal equations D^T D, D^T b: |D x - b|^2 = |L^T x
    - L^-1 D^T b|^2 + const with D^T D = L L^T (columns scaled to unit norm, and a ridge of 1e-12
    where sources cannot be told apart), a K x K problem instead of D's many rows."""
    d = np.sqrt(np.maximum(np.diag(DtD), 1e-300))
    N = DtD / np.outer(d, d) + 1e-12 * np.eye(len(d))
    L = np.linalg.cholesky(N)
    return nnls(L.T, np.linalg.solve(L, Dtb / d))[0] / d


def variances(sources: Sources, e: np.ndarray, theta: np.ndarray, floor: np.ndarray,
              iterations: int = VARIANCE_ITER) -> tuple[np.ndarray, np.ndarray]:
    """The maximum-likelihood variances theta >= 0 of Sigma_i = sum_k theta_k G_ik G_ik^T for the
    residuals e: (m, 6), from `theta`, each kept at `floor` or above; returns (theta, Sigma).

    Fisher scoring: with u_i = Sigma_i^-1 e_i, the stationary points solve F theta = q, where
    F_kl = sum_i ||G_ik^T Sigma_i^-1 G_il||_F^2 and q_k = sum_i ||G_ik^T u_i||^2 (both at the
    current theta); the step solves it with theta >= 0 (non-negative least squares). Where that
    would lower the likelihood the EM update theta_k <- theta_k q_k / trace(G_k^T Sigma^-1 G_k)
    (summed over i) is taken instead, which never does."""
    H = sources.H
    S = sources.sigma(theta)
    Si, loglik = _inverse_and_log_likelihood(S, e)
    for _ in range(iterations):
        SiH = Si @ H
        M = np.swapaxes(H, 1, 2) @ SiH                        # H^T Sigma^-1 H: (m, R, R)
        v = np.einsum("mir,mi->mr", SiH, e)                   # H^T u
        F = sources.per_source_pair(M * M)
        q = sources.per_source(v * v)
        if not (np.all(np.isfinite(F)) and np.all(np.isfinite(q))):  # overflow: keep the last variances
            break
        d = np.sqrt(np.maximum(np.diag(F), 1e-300))
        new = nnls(F / np.outer(d, d), q / d)[0] / d
        if np.any(new > 0):
            new = np.maximum(new, floor)
            S_new = sources.sigma(new)
            Si_new, loglik_new = _inverse_and_log_likelihood(S_new, e)
        if not np.any(new > 0) or loglik_new < loglik:
            trace = sources.per_source(np.einsum("mrr->mr", M))
            new = np.maximum(theta * q / np.maximum(trace, 1e-300), floor)
            S_new = sources.sigma(new)
            Si_new, loglik_new = _inverse_and_log_likelihood(S_new, e)
        gain = loglik_new - loglik
        theta, S, Si, loglik = new, S_new, Si_new, loglik_new
        if gain <= LOGLIK_TOL:
            break
    return theta, S


def moment_start(sources: Sources, e: np.ndarray, rotation_var: float, translation_var: float) -> np.ndarray:
    """The variances that best match the residuals' outer products, e_i e_i^T ~ Sigma_i(theta), by
    non-negative least squares over the entries (each scaled by its groups' mean squares): a
    moment estimate, linear in theta, that starts the likelihood's iterations close to their end
    (measured on the KinHEC PnP track: 4-6 iterations instead of 8-13 from an even split)."""
    rows, cols = np.triu_indices(6)
    scale = np.sqrt(np.where(np.arange(6) < 3, rotation_var, translation_var))
    norm = (scale[rows] * scale[cols])[:, None]
    H = sources.H
    P = H[:, rows, :] * H[:, cols, :] / norm                  # each column's share of the entries: (m, 21, R)
    target = (e[:, rows] * e[:, cols]) / norm[:, 0]
    DtD = sources.per_source_pair(np.swapaxes(P, 1, 2) @ P)  # the design's normal equations, per source
    Dtb = sources.per_source(np.einsum("mer,me->mr", P, target))
    if not (np.all(np.isfinite(DtD)) and np.all(np.isfinite(Dtb))):
        raise DegenerateDataError(OVERFLOW)
    return _nonnegative(DtD, Dtb)


def fit(model: Any, data: Any, poses: tuple[np.ndarray, ...], settings: nlls.Settings,
        per_group_fit: Sources | None = None) -> tuple[tuple[np.ndarray, ...], Any, dict[str, Any]]:
    """The unknowns weighted by the model's noise sources (`PoseModel.noise_factors`), in two
    steps (feasible generalised least squares; module docstring): the per-group fit from `poses`
    with `settings` (estimated weights, least squares), the sources' variances by maximum
    likelihood at its residuals, then the unknowns converged with every observation whitened by
    its Sigma_i. Returns (poses, status, diagnostics of the last fit with ``noise_sources``: each
    source's standard deviation, rad or data units, and ``loglik_gain``: the log-likelihood at
    the end over the per-group model's at its fit, nats). `per_group_fit`: the noise factors at
    `poses` when these already are the per-group fit with `settings` (auto's answer): the first
    step is then not run again (at m = 1e5 it and the factors cost ~0.3 s)."""
    if per_group_fit is None:
        poses = nlls.levenberg_marquardt(model, poses, settings.W, settings.loss, settings.loss_scale,
                                         settings.max_iter, settings.tol, settings.estimate).poses
    e = model.residuals(poses)
    m = len(e)
    sources = model.noise_factors(data, poses) if per_group_fit is None else per_group_fit
    if not (np.all(np.isfinite(e * e)) and np.all(np.isfinite(sources.H))):
        raise DegenerateDataError(OVERFLOW)
    rotation_var = max(float(np.sum(e[:, :3] ** 2)) / (3 * m), 1e-300)
    translation_var = max(float(np.sum(e[:, 3:] ** 2)) / (3 * m), 1e-300 * model.scale**2)
    floor = VARIANCE_FLOOR * np.where(sources.translation, translation_var, rotation_var)
    some = np.unique(np.linspace(0, m - 1, min(m, VARIANCE_PAIRS)).astype(int))
    sampled = sources.rows(some)
    start = np.maximum(moment_start(sampled, e[some], rotation_var, translation_var), floor)
    theta, S = variances(sampled, e[some], start, floor)
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(S))):
        raise DegenerateDataError(OVERFLOW)
    if len(some) < m:
        S = sources.sigma(theta)
    W = Whitening(L=np.linalg.cholesky(S))
    stated = nlls.Settings(W=W, weights="covariance", loss=settings.loss, loss_scale=settings.loss_scale,
                           max_iter=settings.max_iter, tol=settings.tol)
    poses, status, diag = nlls.refine(model, poses, stated)
    # final_cost: 1/2 the whitened residuals' sum of squares at the answer (least squares, fixed weights)
    loglik = -float(np.sum(np.log(np.diagonal(W.L, axis1=1, axis2=2)))) - float(diag["final_cost"])
    groups_loglik = -1.5 * m * (math.log(rotation_var) + math.log(translation_var) + 2.0)
    diag = {**diag, "weights": "estimated", "noise_model": "sources", "loglik_gain": loglik - groups_loglik,
            "noise_sources": {name: math.sqrt(float(t)) if t > 2.0 * f else 0.0  # at its floor: gone
                              for name, t, f in zip(sources.names, theta, floor)}}
    return poses, status, diag
