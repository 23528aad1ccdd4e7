"""The board corners fitted with the robot's own pose errors: X, Y, a correction of every robot
pose and the noise of both, by maximum likelihood.

On real cells the robot, not the camera, limits the answer: a robot pose is off by tenths of a
millimetre where the corners are placed to a tenth of a pixel. Fitting the corners with the robot's
poses taken as exact then spreads the robot's error over the pixels, and every image weighs the
same however well its board was seen. Here each station's robot pose is A_i exp(delta_i), with
delta_i = (omega, v) in the flange frame a random error, N(0, diag(s_r^2 I3, s_t^2 I3)), and the
corners carry isotropic pixel noise s_px (`corners.residuals` with ``robot``). For given
variances the maximum a posteriori fit minimises

    F = 1/2 sum_ij |u_ij - pi(X, Y, delta_i; P_j)|^2 / s_px^2 + 1/2 sum_i delta_i^T Pr delta_i,
    Pr = diag(I3 / s_r^2, I3 / s_t^2),

by Levenberg-Marquardt with each station's 6 corrections eliminated by their Schur complement
(the normal equations are an arrow: delta_i touches X, Y and its own corners only), so a step
costs a 12 x 12 solve plus m 6 x 6 ones. The variances are then re-estimated by the EM update of
a linear mixed model at that fit (C_i the posterior covariance of delta_i, N the corners, p the
free global parameters):

    s_px^2 = (sum |r|^2 + sum_i tr(C_i (J_i^T J_i))) / (2N - p),
    s_r^2 = sum_i (|omega_i|^2 + tr C_i,omega) / 3m,     s_t^2 = sum_i (|v_i|^2 + tr C_i,v) / 3m,

and the two steps alternate until the variances settle (`fit`). Exact robot poses drive s_r, s_t
toward zero and the fit toward the exact-robot one (`corners.levenberg_marquardt`); a robot far
noisier than the pixels lets each image keep its board pose and weighs the images by how well
their boards were seen. The covariance of X and Y is the inverse of the reduced (Schur) normal
matrix: the corrections marginalised.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from scipy.optimize import nnls

from handeye.base.errors import SolverError
from handeye.estimation.nlls import retract
from handeye.plugins.reprojection.corners import (
    TOL,
    StationChains,
    at_rounding,
    camera_with,
    intrinsics,
    residuals,
    station_grams,
)

#: the alternation stops when the variances' step gains less than this in log-likelihood (nats)
#: or after OUTER_ITER rounds
LOGLIK_TOL = 0.01
OUTER_ITER = 100
#: Levenberg-Marquardt iterations in the first round, and in each later one (warm-started from
#: the last, whose variances moved little: one step keeps up with them)
INNER_ITER = 50
LATER_ITER = 1
#: relative floor of the robot's standard deviations (of their start): keeps the prior's weight
#: within reach of double precision where the robot is exact (its corrections then shrink to a
#: ten-thousandth of the robot's misfit, a tiny share of the pixel noise's effect)
ROBOT_FLOOR = 1e-4


@dataclasses.dataclass
class RobotFit:
    """The joint fit: poses X, Y; intrinsics theta; corrections delta (m, 6); pixel residuals r
    (n, 2); the standard deviations (s_px, s_r, s_t); the covariance of the free global
    parameters; rounds, converged."""

    poses: dict[str, np.ndarray]
    theta: np.ndarray
    delta: np.ndarray
    r: np.ndarray
    sigmas: tuple[float, float, float]
    covariance: np.ndarray
    rounds: int
    converged: bool


@dataclasses.dataclass
class _Sums:
    """The corners' sums at one point, unweighted: JgJg (p, p), JgJd (m, p, 6), JdJd (m, 6, 6),
    Jgr (p,), Jdr (m, 6), rr; the residuals r and corrections delta there."""

    JgJg: np.ndarray
    JgJd: np.ndarray
    JdJd: np.ndarray
    Jgr: np.ndarray
    Jdr: np.ndarray
    r: np.ndarray
    delta: np.ndarray

    @classmethod
    def at(cls, cell: StationChains, poses: dict[str, np.ndarray], camera: Any, delta: np.ndarray, free: int) -> _Sums:
        r, J = residuals(cell, poses, camera, True, robot=delta)
        # [Jg | Jd | r]^T [Jg | Jd | r] station by station: every sum in one product each
        blocks = station_grams(np.concatenate([J[:, :, :free], J[:, :, -6:], r[:, :, None]], axis=2), cell.counts)
        g, d = slice(0, free), slice(free, free + 6)
        return cls(blocks[:, g, g].sum(axis=0), blocks[:, g, d], blocks[:, d, d], blocks[:, g, -1].sum(axis=0),
                   blocks[:, d, -1], r, delta)

    def normal(self, sigmas: tuple[float, float, float]) -> _Normal:
        """The arrow's blocks under the variances `sigmas`."""
        s_px, s_r, s_t = sigmas
        w = 1.0 / s_px**2
        prior = np.r_[[1.0 / s_r**2] * 3, [1.0 / s_t**2] * 3]
        F = 0.5 * (w * float(np.sum(self.r * self.r)) + float(np.sum(self.delta * self.delta * prior)))
        return _Normal(w * self.JgJg, w * self.JgJd, w * self.JdJd + np.diag(prior), w * self.Jgr,
                       w * self.Jdr + self.delta * prior, F, self)


@dataclasses.dataclass
class _Normal:
    """The arrow's blocks at one point under given variances: Hgg (p, p), Hgd (m, p, 6), Hdd
    (m, 6, 6) (prior included), gg (p,), gd (m, 6), the cost F, and the sums they came from."""

    Hgg: np.ndarray
    Hgd: np.ndarray
    Hdd: np.ndarray
    gg: np.ndarray
    gd: np.ndarray
    F: float
    sums: _Sums


def _reduced(n: _Normal, lam: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(S, b, Hdd^-1, damped Hgg diagonal, damped Hdd) of the Schur complement with Marquardt's
    damping lam."""
    Hgg = n.Hgg + lam * np.diag(np.maximum(np.diag(n.Hgg), 1e-300))
    dd = np.maximum(np.einsum("mii->mi", n.Hdd), 1e-300)
    Hdd = n.Hdd + lam * dd[:, :, None] * np.eye(6)
    Hdd_inv = np.linalg.inv(Hdd)
    HgdHi = n.Hgd @ Hdd_inv                                       # (m, p, 6)
    S = Hgg - np.einsum("mab,mcb->ac", HgdHi, n.Hgd)
    b = n.gg - np.einsum("mab,mb->a", HgdHi, n.gd)
    return S, b, Hdd_inv, Hgg, Hdd


def _step(n: _Normal, lam: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(global step, corrections' steps (m, 6), predicted decrease) at damping lam."""
    S, b, Hdd_inv, Hgg, Hdd = _reduced(n, lam)
    dg = -np.linalg.solve(S, b)
    dd = -np.einsum("mab,mb->ma", Hdd_inv, n.gd + np.einsum("mpa,p->ma", n.Hgd, dg))
    # predicted decrease of the (undamped) quadratic model
    quad = (dg @ n.Hgg @ dg + 2.0 * np.einsum("p,mpa,ma->", dg, n.Hgd, dd) + np.einsum("ma,mab,mb->", dd, n.Hdd, dd))
    predicted = -(n.gg @ dg + np.sum(n.gd * dd)) - 0.5 * quad
    return dg, dd, float(predicted)


def _map_fit(cell: StationChains, poses: dict[str, np.ndarray], theta: np.ndarray, camera: Any, delta: np.ndarray,
             free: int, sigmas: tuple[float, float, float], refine_intrinsics: bool, iterations: int = INNER_ITER,
             sums: _Sums | None = None) -> tuple[dict[str, np.ndarray], np.ndarray, Any, np.ndarray, _Normal]:
    """Levenberg-Marquardt on F at fixed variances, from (poses, theta, delta) (whose `sums`,
    when the caller has them): at most `iterations` steps."""
    cam = camera_with(camera, theta) if refine_intrinsics else camera
    n = (sums if sums is not None else _Sums.at(cell, poses, cam, delta, free)).normal(sigmas)
    lam = 1e-3
    for _ in range(iterations):
        while True:
            try:
                dg, dd, predicted = _step(n, lam)
            except np.linalg.LinAlgError:
                lam *= 10.0
                if lam > 1e16:
                    return poses, theta, cam, delta, n
                continue
            trial = {"X": retract(poses["X"], dg[:6]), "Y": retract(poses["Y"], dg[6:12])}
            trial_theta = theta + np.concatenate([dg[12:], np.zeros(len(theta) - (free - 12))])
            trial_cam = camera_with(camera, trial_theta) if refine_intrinsics else cam
            try:
                trial_n = _Sums.at(cell, trial, trial_cam, delta + dd, free).normal(sigmas)
            except SolverError:
                trial_n = None
            if trial_n is not None and (trial_n.F <= n.F or predicted <= TOL * n.F):
                break
            lam *= 10.0
            if lam > 1e16:
                return poses, theta, cam, delta, n
        decrease = n.F - trial_n.F
        poses, theta, cam, delta, n = trial, trial_theta, trial_cam, delta + dd, trial_n
        lam = max(lam / 10.0, 1e-12)
        if decrease <= TOL * max(n.F, 1e-300):
            break
    return poses, theta, cam, delta, n


def _marginal(sums: _Sums, theta: np.ndarray, counts: np.ndarray) -> dict[str, Any]:
    """What the variances' likelihood needs at theta = (s_px^2, s_r^2, s_t^2), station by
    station, with the corrections integrated out: the corners' residual before correction
    rt_i = r_i - G_i delta_i (r_i at the correction delta_i, G_i = d r_i / d delta_i, 2n_i x 6:
    to first order the residual at no correction) has covariance V_i = s_px^2 I +
    G_i D G_i^T, D = diag(s_r^2 I3, s_t^2 I3). By Woodbury everything is 6 x 6: with A = G^T G,
    b = G^T rt and K = D^(1/2) (s_px^2 I + D^(1/2) A D^(1/2))^-1 D^(1/2) (finite at D = 0),
    V^-1 = (I - G K G^T) / s_px^2."""
    px, r2, t2 = theta
    A = sums.JdJd
    b = sums.Jdr - np.einsum("mab,mb->ma", A, sums.delta)
    rr = (np.add.reduceat(np.sum(sums.r**2, axis=1), np.r_[0, np.cumsum(counts)[:-1]])
          - 2.0 * np.sum(sums.delta * sums.Jdr, axis=1) + np.einsum("ma,mab,mb->m", sums.delta, A, sums.delta))
    d = np.sqrt(np.r_[[r2] * 3, [t2] * 3])
    inner = px * np.eye(6) + d[:, None] * A * d[None, :]
    K = d[:, None] * np.linalg.inv(inner) * d[None, :]
    I_KA = np.eye(6) - K @ A
    coords = 2.0 * counts
    logdet = coords * math.log(px) + np.linalg.slogdet(inner / px)[1]
    Kb = np.einsum("mab,mb->ma", K, b)
    quad = (rr - np.sum(b * Kb, axis=1)) / px                       # rt^T V^-1 rt
    return {"A": A, "K": K, "I_KA": I_KA, "b": b, "Kb": Kb, "rr": rr, "coords": coords,
            "loglik": -0.5 * float(np.sum(logdet + quad))}


def _scoring(sums: _Sums, theta: np.ndarray, counts: np.ndarray, floors: np.ndarray) -> np.ndarray:
    """One Fisher-scoring step of the variances theta = (s_px^2, s_r^2, s_t^2) with theta >= floors
    (non-negative least squares, as `handeye.estimation.noise_sources.variances`), or an EM-like halving
    back toward theta where it would lower the likelihood. F_kl = sum_i tr(V^-1 V_k V^-1 V_l),
    q_k = sum_i u^T V_k u, u = V^-1 rt, V_px = I, V_r = G_r G_r^T, V_t = G_t G_t^T (`_marginal`)."""
    px = theta[0]
    g = _marginal(sums, theta, counts)
    A, K, I_KA, b, Kb = g["A"], g["K"], g["I_KA"], g["b"], g["Kb"]
    M = (A - A @ K @ A) / px                                        # G^T V^-1 G
    N2 = np.swapaxes(I_KA, 1, 2) @ A @ I_KA / px**2                 # G^T V^-2 G
    KA = K @ A
    tr_V2 = (g["coords"] - 2.0 * np.einsum("mii->m", KA) + np.einsum("mab,mba->m", KA, KA)) / px**2
    u2 = (g["rr"] - 2.0 * np.sum(b * Kb, axis=1) + np.einsum("ma,mab,mb->m", Kb, A, Kb)) / px**2
    Gu = (b - np.einsum("mab,mb->ma", A, Kb)) / px                  # G^T u
    blocks = (slice(0, 3), slice(3, 6))
    F = np.empty((3, 3))
    F[0, 0] = np.sum(tr_V2)
    for k, sk in enumerate(blocks, start=1):
        F[0, k] = F[k, 0] = float(np.einsum("mii->", N2[:, sk, sk]))
        for j, sj in enumerate(blocks, start=1):
            F[k, j] = float(np.sum(M[:, sk, sj] ** 2))
    q = np.array([np.sum(u2), np.sum(Gu[:, :3] ** 2), np.sum(Gu[:, 3:] ** 2)])
    scale = np.sqrt(np.maximum(np.diag(F), 1e-300))
    new = np.maximum(nnls(F / np.outer(scale, scale), q / scale)[0] / scale, floors)
    for _ in range(30):  # never lower the likelihood: step back toward theta
        if _marginal(sums, new, counts)["loglik"] >= g["loglik"] - 1e-9 * abs(g["loglik"]):
            return new
        new = np.sqrt(new * theta)
    return theta


def fit(cell: StationChains, poses: dict[str, np.ndarray], camera: Any, refine_intrinsics: bool,
        start_sigmas: tuple[float, float, float]) -> RobotFit:
    """The joint fit from `poses` (X, Y) and the variances' start (s_px, s_r, s_t): rounds of the
    fit at fixed variances and their EM update (module docstring)."""
    theta = intrinsics(camera)
    free = 12 + (len(theta) if refine_intrinsics else 0)
    delta = np.zeros((len(cell.M), 6))
    sigmas = start_sigmas
    floors = np.array([1e-24 * start_sigmas[0], ROBOT_FLOOR * start_sigmas[1], ROBOT_FLOOR * start_sigmas[2]]) ** 2
    converged, rounds, sums = False, 0, None
    for rounds in range(1, OUTER_ITER + 1):
        poses, theta, cam, delta, n = _map_fit(cell, poses, theta, camera, delta, free, sigmas, refine_intrinsics,
                                               INNER_ITER if rounds == 1 else LATER_ITER, sums)
        sums = n.sums
        if at_rounding(0.5 * float(np.sum(sums.r**2)), len(sums.r)):  # exact corners: nothing left to weigh
            converged = True
            break
        theta2 = np.array(sigmas) ** 2
        new = _scoring(sums, theta2, cell.counts, floors)
        gain = _marginal(sums, new, cell.counts)["loglik"] - _marginal(sums, theta2, cell.counts)["loglik"]
        sigmas = tuple(np.sqrt(new))
        if gain <= LOGLIK_TOL:
            converged = True
            break
        # the corrections' own optimum under the new variances, before X and Y move (exact for the
        # linearised model: rt_i = r_i - G_i delta_i is fixed, delta_i = -(G^T G + s_px^2 Pr)^-1 G^T rt_i)
        normal = sums.normal(sigmas)
        resolved = delta - np.einsum("mab,mb->ma", np.linalg.inv(normal.Hdd), normal.gd)
        try:
            sums = _Sums.at(cell, poses, cam, resolved, free)
            delta = resolved
        except SolverError:  # too far for the linearisation: Levenberg-Marquardt takes it from here
            pass
    poses, theta, cam, delta, n = _map_fit(cell, poses, theta, camera, delta, free, sigmas, refine_intrinsics,
                                           INNER_ITER, sums)
    S = _reduced(n, 0.0)[0]
    return RobotFit(poses, theta, delta, n.sums.r, sigmas, np.linalg.pinv(S), rounds, converged)
