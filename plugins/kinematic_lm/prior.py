"""The regularised kinematic fit's prior: zero-mean Gaussian DH corrections whose spread is
estimated from the stations (empirical Bayes, type-II maximum likelihood).

Why: fitting 17-22 DH corrections freely pays when the arm's errors are large against the
camera's noise and costs precision when they are small; a prior delta ~ N(0, diag(tau^2)),
one tau for the angles (offsets, twists: rad) and one for the lengths (a, d: units of the
data's RMS translation), shrinks the corrections towards zero by as much as the data call for:
tau -> 0 is the pose-only fit, tau -> infinity the free one.

The hyperparameters (sigma_rot, sigma_trans: the per-axis noise of the two residual groups;
tau_angle, tau_length) maximise the marginal likelihood of the stations with the corrections
and the 12 pose parameters of X and Y integrated out (delta over its prior, X and Y over a flat
one: a restricted likelihood, so that the noise is not underestimated by the unknowns' degrees of
freedom), the model linearised at the current fit (MacKay, "Bayesian interpolation", Neural
Computation 4(3), 1992; Tipping, JMLR 1, 2001). With theta = (u, delta), u the right
perturbations of X and Y, J the residuals' Jacobian, e0 the residuals at the linearisation point
and delta0 its corrections, the stations say b = J_delta delta0 - e0 = J theta + noise, and

    -2 log p(b | sigma, tau) = r^T r + delta^T diag(tau^-2) delta + sum log s_k^2 + sum log tau_k^2
                               + log det(Jw^T Jw + diag(0, tau^-2))      (+ const)

with Jw = J / s (whitened by the noise per residual), theta the posterior mean and r its
whitened residual. The posterior covariance (Jw^T Jw + diag(0, tau^-2))^-1 is the answer's
covariance: it carries the corrections' uncertainty into X and Y.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

from handeye.estimation.whitening import SIGMA_FLOOR

#: bounds of the prior spreads tau (rad; units of the data's RMS translation): below the lower
#: one the corrections are zero to working precision, above the upper one the prior is flat
TAU_BOUNDS = (1e-9, 1.0)
#: the pose unknowns (X, Y) ahead of the corrections in the parameter vector
POSE_UNKNOWNS = 12


@dataclasses.dataclass(frozen=True)
class Hyper:
    """The prior's and the noise's spreads: sigma (rotation rad, translation) per residual axis,
    tau (angle rad, length) per DH correction; lengths in units of the data's RMS translation."""

    sigma: tuple[float, float]
    tau: tuple[float, float]

    def noise(self) -> np.ndarray:
        """(6,): the noise standard deviation of each residual component."""
        return np.repeat(self.sigma, 3)

    def spreads(self, is_length: np.ndarray) -> np.ndarray:
        """(p,): the prior standard deviation of each correction."""
        return np.where(is_length, self.tau[1], self.tau[0])

    def as_log(self) -> np.ndarray:
        """(4,): log(sigma_rot, sigma_trans, tau_angle, tau_length), the evidence's variables."""
        return np.log(np.array([*self.sigma, *self.tau]))

    @staticmethod
    def from_log(x: np.ndarray) -> Hyper:
        """The inverse of `as_log`."""
        v = np.exp(x)
        return Hyper((float(v[0]), float(v[1])), (float(v[2]), float(v[3])))


@dataclasses.dataclass(frozen=True)
class Linearised:
    """The linear model b = J theta + noise of the module docstring per residual group g
    (rotation, translation): its rows J_g, b_g and Gram matrices G_g = J_g^T J_g, c_g = J_g^T b_g
    (the residual is formed from the rows: its expansion through G cancels catastrophically when
    the noise is small)."""

    J: tuple[np.ndarray, np.ndarray]
    b: tuple[np.ndarray, np.ndarray]
    G: np.ndarray
    c: np.ndarray
    n: np.ndarray
    is_length: np.ndarray

    @staticmethod
    def at(J: np.ndarray, e: np.ndarray, delta: np.ndarray, is_length: np.ndarray) -> Linearised:
        """From residuals e (m, 6), Jacobian J (m, 6, 12 + p), corrections delta (p,)."""
        b = J[:, :, POSE_UNKNOWNS:] @ delta - e
        Jg = tuple(J[:, g].reshape(-1, J.shape[2]) for g in (slice(0, 3), slice(3, 6)))
        bg = tuple(b[:, g].ravel() for g in (slice(0, 3), slice(3, 6)))
        return Linearised(Jg, bg, np.array([j.T @ j for j in Jg]), np.array([j.T @ v for j, v in zip(Jg, bg)]),
                          np.array([len(v) for v in bg]), np.asarray(is_length, dtype=bool))

    def evidence(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """-2 log p(stations | hyperparameters) (+ const) and its gradient in x = log(sigma_rot,
        sigma_trans, tau_angle, tau_length); +inf where the precision is singular."""
        s2, t2 = np.exp(2 * x[:2]), np.exp(2 * x[2:])
        prior = np.where(self.is_length, t2[1], t2[0])
        H = np.tensordot(1 / s2, self.G, axes=1)
        k = np.arange(POSE_UNKNOWNS, len(H))
        H[k, k] += 1 / prior
        try:
            factor = cho_factor(H)
        except np.linalg.LinAlgError:
            return math.inf, np.zeros(4)
        theta = cho_solve(factor, (self.c / s2[:, None]).sum(axis=0))
        cov = cho_solve(factor, np.eye(len(H)))
        d = theta[POSE_UNKNOWNS:]
        residual = np.array([float(np.sum((v - j @ theta) ** 2)) for j, v in zip(self.J, self.b)])  # per group
        value = float((residual / s2).sum() + (d ** 2 / prior).sum() + (self.n * np.log(s2)).sum()
                      + np.log(prior).sum() + 2 * np.log(np.diag(factor[0])).sum())
        hat = np.einsum("ij,gji->g", cov, self.G) / s2  # per group: tr(Sigma J_g^T J_g) / s_g^2
        var = np.diag(cov)[POSE_UNKNOWNS:]
        shrink = [((d ** 2 + var) / prior)[self.is_length == kind].sum() for kind in (False, True)]
        counts = np.array([(self.is_length == kind).sum() for kind in (False, True)])
        gradient = 2 * np.concatenate([self.n - residual / s2 - hat, counts - np.array(shrink)])
        return value, gradient


#: the grid of prior spreads tau whose best point starts the evidence's maximisation when no
#: start is given (rad; units of the data's RMS translation): the evidence may have a local
#: maximum where the arm's errors pass for noise
TAU_GRID = np.logspace(-6, -1, 6)


def _maximise(linear: Linearised, x0: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, float]:
    """The log hyperparameters within [low, high] that maximise the evidence from x0 (TNC: bounded
    Newton steps; the evidence's curvature in log sigma is large when the noise is small), and
    -2 log evidence there."""
    bounds = list(zip(low, np.where(np.isfinite(high), high, None)))
    result = minimize(linear.evidence, np.clip(x0, low, high), jac=True, method="TNC", bounds=bounds,
                      options={"ftol": 1e-13, "gtol": 1e-9, "maxfun": 500})
    x = np.clip(result.x, low, high)
    return x, linear.evidence(x)[0]


def _limits() -> tuple[np.ndarray, np.ndarray]:
    """The bounds of the log hyperparameters (`as_log`'s order)."""
    return (np.log([SIGMA_FLOOR, SIGMA_FLOOR, TAU_BOUNDS[0], TAU_BOUNDS[0]]),
            np.log([np.inf, np.inf, TAU_BOUNDS[1], TAU_BOUNDS[1]]))


def estimate(J: np.ndarray, e: np.ndarray, delta: np.ndarray, is_length: np.ndarray, start: Hyper | None = None
             ) -> Hyper:
    """The hyperparameters that maximise the linearised marginal likelihood over their
    logarithms, within `TAU_BOUNDS` and above `SIGMA_FLOOR`, from `start`, or from the best
    point of `TAU_GRID` x `TAU_GRID` with the noise at the residuals' RMS."""
    linear = Linearised.at(J, e, delta, is_length)
    low, high = _limits()
    if start is None:
        rms = [max(math.sqrt(float((e[:, g] ** 2).mean())), 10 * SIGMA_FLOOR) for g in (slice(0, 3), slice(3, 6))]
        grid = [np.log([*rms, ta, tl]) for ta in TAU_GRID for tl in TAU_GRID]
        x0 = min(grid, key=lambda x: linear.evidence(x)[0])
    else:
        x0 = start.as_log()
    return Hyper.from_log(_maximise(linear, x0, low, high)[0])


def without_errors(J: np.ndarray, e: np.ndarray, delta: np.ndarray, is_length: np.ndarray, h: Hyper
                   ) -> tuple[float, float]:
    """The restricted likelihood ratio of the arm's errors: 2 log (evidence at h / evidence with
    every tau at its lower bound, the noise re-estimated), and its p value under no DH errors
    (tau = 0 is on the boundary: with k kinds of corrections present the statistic is a mixture
    of chi-square with 0..k degrees of freedom, binomial(k, 1/2) weights, e.g. 1/4 : 1/2 : 1/4;
    Self & Liang, JASA 82(398), 1987)."""
    from scipy.stats import binom, chi2

    linear = Linearised.at(J, e, delta, is_length)
    low, high = _limits()
    high0 = high.copy()
    high0[2:] = low[2:]
    _, value0 = _maximise(linear, np.concatenate([h.as_log()[:2], low[2:]]), low, high0)
    statistic = max(value0 - linear.evidence(h.as_log())[0], 0.0)
    k = len(set(np.asarray(is_length, dtype=bool).tolist()))
    p = sum(binom.pmf(j, k, 0.5) * (chi2.sf(statistic, j) if j else float(statistic <= 0)) for j in range(k + 1))
    return statistic, float(p)


def posterior_covariance(J: np.ndarray, h: Hyper, is_length: np.ndarray) -> np.ndarray:
    """(12 + p, 12 + p): the posterior covariance of (u, delta) at hyperparameters h, the inverse
    of Jw^T Jw + diag(0, tau^-2) (Jw: J whitened by the noise)."""
    Jw = (J / h.noise()[None, :, None]).reshape(-1, J.shape[2])
    H = Jw.T @ Jw
    k = np.arange(POSE_UNKNOWNS, J.shape[2])
    H[k, k] += h.spreads(is_length) ** -2.0
    return np.linalg.inv(H)


def effective_parameters(cov: np.ndarray, h: Hyper, is_length: np.ndarray) -> np.ndarray:
    """(p,): how much of each correction the data determine, 1 - posterior var / prior var
    (MacKay's gamma: 0 where the prior alone decides, 1 where the stations do)."""
    var = np.diag(cov)[POSE_UNKNOWNS:]
    return 1.0 - var / h.spreads(is_length) ** 2
