"""The quick fit of a recording session: A_i X = Y B_i on the stations so far, warm-started from
the previous answer, and the tests a session makes with it (`handeye.planning.session`).

A full ``handeye.solve`` (global start, refinement, self-check) costs ~20 ms; adding one station
to a fit that already sits at the optimum of the others moves it by a fraction of its 1-sigma,
so a few Gauss-Newton steps from there reach the new optimum. `fit` takes them on the engine's
model of the equation (`model_of`: the cell problem's own `Problem.pose_model` of its validated
stations, `Registry.cell_problem`) with the two noise levels (rotation, translation) estimated
as the RMS of the current residuals at every step: its fixed point is the maximum of the
likelihood with those two variances unknown, the point ``handeye.solve``'s refinement and the
self-check's best fit reach, and its information matrix at that point, times the variance factor,
is their covariance.

`disagreement` tests one station against an answer it did not take part in: its residual e at
the answer has covariance S = (the station's noise) + J Cov J^T (the answer's own uncertainty,
carried by the station's Jacobian J), and e^T S^-1 e is chi-square on 6 degrees of freedom when
the station agrees with the others. The station's noise N follows from the information
I = J^T N^-1 J it gives at the expected noise (the problem's `Problem.station_information`) and
J: N^-1 = P^T I P with P = J^T (J J^T)^-1, J of full row rank (`residual_covariance`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.nlls import PoseModel, retract_all
from handeye.estimation.whitening import rms_whitening, sums_of_squares
from handeye.framework.problem import Problem

#: Gauss-Newton steps per fit at most (from a warm start one or two are taken)
MAX_STEPS = 6
#: a step whose predicted decrease of the whitened sum of squares is below this is the last
STEP_TOL = 1e-10


@dataclasses.dataclass(frozen=True)
class Fit:
    """The fit of the stations: X, Y; information (12, 12) of (X, Y) (rotation then translation of
    each, in its own frame) under the estimated noise; sigmas: the RMS residual per axis (rad,
    length), the estimated noise; factor: the variance factor 6m / (6m - 12) that turns the
    inverse information into the covariance (nan with fewer than 3 stations); steps taken."""

    X: np.ndarray
    Y: np.ndarray
    information: np.ndarray
    sigmas: tuple[float, float]
    factor: float
    steps: int

    @property
    def covariance(self) -> np.ndarray:
        """(12, 12) covariance of (X, Y) with the noise estimated from the residuals."""
        return np.linalg.inv(self.information) * self.factor


def model_of(problem: Problem, A: np.ndarray, B: np.ndarray) -> PoseModel:
    """The engine's model of A_i X = Y B_i on these stations: `problem` (the cell problem, data A
    and B, unknowns X and Y) validates them and gives its model (`Problem.pose_model`). The
    problem's InputError / DegenerateDataError when it refuses them."""
    model = problem.pose_model(problem.validate(A=A, B=B))
    if model is None:
        raise InputError(f"problem {problem.name!r} offers no least-squares model of its stations")
    return model


def fit(model: PoseModel, X: np.ndarray, Y: np.ndarray, max_steps: int = MAX_STEPS) -> Fit:
    """Gauss-Newton from (X, Y) on the stations of `model` (`model_of`; module docstring).
    DegenerateDataError when the stations do not determine X and Y there."""
    m = model.m
    poses = (X, Y)
    steps = 0
    while True:
        e = model.residuals(poses)
        J = model.jacobian(poses, e)
        p = J.shape[2]
        W = rms_whitening(*sums_of_squares(e), m, model.scale)
        wr, wt = 1.0 / W.sigma_rot**2, 1.0 / W.sigma_trans**2
        Jr, Jt = J[:, :3].reshape(-1, p), J[:, 3:].reshape(-1, p)
        H = wr * (Jr.T @ Jr) + wt * (Jt.T @ Jt)
        g = wr * (Jr.T @ e[:, :3].ravel()) + wt * (Jt.T @ e[:, 3:].ravel())
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            raise DegenerateDataError("the stations do not determine X and Y yet (do they rotate about two "
                                      "different axes?)") from None
        if not np.all(np.isfinite(step)):
            raise DegenerateDataError("the stations do not determine X and Y yet")
        if -float(g @ step) <= STEP_TOL or steps >= max_steps:
            break
        poses = retract_all(poses, step)
        steps += 1
    dof = 6 * m - p
    return Fit(poses[0], poses[1], H, (W.sigma_rot, W.sigma_trans), 6.0 * m / dof if dof > 0 else math.nan, steps)


def residual(model: PoseModel, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e (m, 6), J (m, 6, 12)) of the stations of `model` at (X, Y)."""
    e = model.residuals((X, Y))
    return e, model.jacobian((X, Y), e)


def residual_covariance(J: np.ndarray, information: np.ndarray) -> np.ndarray:
    """(6, 6) covariance N of one station's residual from its Jacobian J (6, p), of full row rank,
    and the information I = J^T N^-1 J (p, p) it gives (module docstring)."""
    P = np.linalg.solve(J @ J.T, J).T  # J^T (J J^T)^-1
    return np.linalg.inv(P.T @ information @ P)


def disagreement(e: np.ndarray, J: np.ndarray, noise: np.ndarray, covariance: np.ndarray) -> float:
    """e^T S^-1 e for one station's residual e (6,) at an answer of covariance (12, 12), its
    Jacobian J (6, 12) and its own noise's covariance (6, 6) (module docstring)."""
    S = noise + J @ covariance @ J.T
    return float(e @ np.linalg.solve(S, e))


def chi2_p_value(value: float, dof: int = 6) -> float:
    """The probability of a chi-square value at least this large, for an even number of degrees
    of freedom 2n: exp(-x/2) sum_{j<n} (x/2)^j / j! (closed form; no need for scipy.stats)."""
    if dof % 2 or dof < 2:
        raise ValueError(f"chi2_p_value takes an even number of degrees of freedom, got {dof}")
    half = max(value, 0.0) / 2.0
    term, total = 1.0, 1.0
    for j in range(1, dof // 2):
        term *= half / j
        total += term
    return math.exp(-half) * total


def chi2_threshold(p_value: float, dof: int = 6) -> float:
    """The chi-square value exceeded with probability p_value (0 < p_value < 1), by bisection on
    `chi2_p_value` (decreasing)."""
    low, high = 0.0, 1.0
    while chi2_p_value(high, dof) > p_value:
        high *= 2.0
    for _ in range(100):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if chi2_p_value(mid, dof) > p_value else (low, mid)
    return 0.5 * (low + high)
