"""Weighted, robust nonlinear least squares on SE(3)^k: the engine of `refine` for every problem.

A problem with k unknown poses (A X = Y B: X, Y; A X = X B: X; A X B = Y C Z: X, Y, Z) supplies
a `PoseModel` (`handeye.estimation.pose_model`): per pair i a residual 6-vector e_i = [r_i; t_i]
(rotation group in rad, then translation group in data units) at the unknowns, and its Jacobian
(m, 6, 6k) with respect to right perturbations of each pose, T <- T exp(xi), xi = (omega, v) in
the frame of T, retracted as (R exp([omega]_x), t + R v) (`retract`; SE(3)'s exp to first
order). Everything else is here, once:

- the objective F = 1/2 sum_i rho(|W^(1/2) e_i|^2) with the whitening of `handeye.estimation.whitening`
  (stated per-group sigmas or a Cholesky covariance, or estimated) and the losses of
  `handeye.estimation.robust`; with estimated weights and least squares the profile likelihood over the two
  variances, L = 3m log sigma_rot + 3m log sigma_trans + 3m (`objective`);
- Levenberg-Marquardt with Marquardt's diagonal scaling (invariant to the units of the
  parameters), its weight modes (`mode_of`: fixed, profile, irls, initial) and its convergence
  rules (`levenberg_marquardt`);
- the covariance of the unknowns from the information matrix, with the variance factor when the
  weights were estimated, and the diagnostics (`refine`);
- fixed translation components (`PoseModel.fixed`, e.g. the planar mode of
  `handeye.problems.planar`, where the data cannot determine a translation along the robot's
  rotation axis): the steps are restricted to the 6k - r dimensional subspace that keeps them
  (`fixed_basis`, recomputed at every point), and the covariance is the projected inverse, with
  zero variance along them.

The objective and its local model live in `handeye.estimation.lm_objective`: the normal equations
from the model's Jacobian (one BLAS product J^T J), or summed in closed form
(`PoseModel.normal_equations`, used for per-group sigmas from `PoseModel.sums_min_pairs` pairs
on), a speed-up at large m only.
docs/solvers/refine.md derives the models and states the measured accuracy and speed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.linalg import lapack

from handeye.base.errors import DegenerateDataError
from handeye.estimation.lm_objective import local_model, mode_of, objective
from handeye.estimation.pose_model import PoseModel, Poses
from handeye.estimation.robust import DEFAULT_LOSS_SCALE, loss_terms
from handeye.estimation.whitening import (
    Whitening,
    estimate_sigmas,
    relative_change,
    sums_of_squares,
)
from handeye.framework.solution import Status
from handeye.geometry import so3_fast

ESTIMATES = ("profile", "initial")
#: a Gauss-Newton step whose predicted decrease is below JUDGE_TOL * |objective| is taken without
#: testing the objective, which cannot resolve it (Levenberg-Marquardt would reject it on rounding
#: and stop short: answers then differed by ~1e-9 rad between mm and m).
JUDGE_TOL = 1e-10
#: after this many such unjudged steps in a row the point is stationary to working precision.
JUDGE_STEPS = 3
#: damping (relative to diag(Hw)) tried first after an undamped step failed. A damping much
#: smaller than 1e-3 barely changes a Gauss-Newton step of a few poses, so starting lower only
#: repeats the rejected step: measured on the bench data (A X = Y B, m = 16, noise on A and B)
#: 1e-6 cost four rejected trials before the first accepted one.
MIN_DAMPING = 1e-3
#: profile likelihood: where the Gauss-Newton step with the profile Hessian promises a decrease
#: above this (in units of the objective, a log-likelihood), the start is far from the minimum,
#: where that Hessian's model overshoots (its first step was rejected from closed-form answers at
#: m = 10); the step then uses the information matrix at the current weights (Gauss-Newton for
#: the weights held fixed, a descent direction of the profile likelihood too), and the profile
#: Hessian takes over near the minimum (quadratic convergence). Measured (A X = Y B, m = 5-200,
#: three noise levels, 150 refinements from kron-lstsq): 576 iterations instead of 820, the
#: same answers; the self-check's fits from shah, li and kron-lstsq: 99 instead of 157.
PROFILE_NEAR = 1.0
#: relative change of estimated sigmas between iterations that counts as a fixed point.
WEIGHT_TOL = 1e-6

def retract(T: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """T exp(xi) to first order: (R exp([omega]_x), t + R v) for xi = (omega, v) and a pose T
    (whose last row [0, 0, 0, 1] is kept)."""
    R, out = T[:3, :3], T.copy()
    out[:3, :3] = R @ so3_fast.exp(xi[:3])
    out[:3, 3] += R @ xi[3:]
    return out


def retract_all(poses: Poses, xi: np.ndarray) -> Poses:
    """Each pose j retracted by its 6 parameters xi[6j:6j+6] (`retract`, written out: no reshape
    and map, ~6 times an LM run)."""
    out = []
    for j, T in enumerate(poses):
        R, new = T[:3, :3], T.copy()
        new[:3, :3] = R @ so3_fast.exp(xi[6 * j:6 * j + 3])
        new[:3, 3] += R @ xi[6 * j + 3:6 * j + 6]
        out.append(new)
    return tuple(out)


def fixed_basis(poses: Poses, fixed: Sequence[tuple[int, np.ndarray]]) -> np.ndarray | None:
    """P: (6k, 6k - r), an orthonormal basis of the perturbations xi that keep the fixed
    translation components (None when nothing is fixed): the retraction moves t_j by R_j v_j, so
    t_j . d stays when v_j . (R_j^T d) = 0. P is the identity except in the v-block of each
    unknown with fixed directions, where it holds a basis of the plane (or line) normal to them,
    so that rotation and translation parameters are never mixed (Marquardt's scaling stays
    unit-invariant)."""
    if not fixed:
        return None
    columns, identity = [], np.eye(6 * len(poses))
    for j, T in enumerate(poses):
        eye = identity[:, 6 * j:6 * j + 6]
        columns.append(eye[:, :3])
        normals = [T[:3, :3].T @ np.asarray(d, dtype=float) for k, d in fixed if k == j]
        if not normals:
            columns.append(eye[:, 3:])
            continue
        Q = np.linalg.qr(np.stack(normals, axis=1), mode="complete")[0][:, len(normals):]
        columns.append(eye[:, 3:] @ Q)
    return np.concatenate(columns, axis=1)


def _full(P: np.ndarray | None, step: np.ndarray) -> np.ndarray:
    """A step in the restricted coordinates as the 6k perturbation parameters."""
    return step if P is None else P @ step


@dataclasses.dataclass
class LMResult:
    poses: Poses
    W: Whitening  # weights at the end (estimated ones: those of the final residuals)
    cost: float  # the objective at the end (see `objective`)
    iterations: int
    converged: bool
    H: np.ndarray  # (n, n) Gauss-Newton matrix sum_i rho'_i J_i^T J_i (whitened) at the end, n = 6k - fixed
    ew: np.ndarray  # (m, 6) whitened residuals at the end
    e: np.ndarray  # (m, 6) residuals at the end
    mode: str
    e0: np.ndarray  # (m, 6) residuals at the start
    P: np.ndarray | None = None  # (6k, n) basis of the allowed perturbations at the end (`fixed_basis`), None: all
    #: the objective at the start where it does not depend on the weights at the end (the profile
    #: likelihood's), else None
    cost0: float | None = None


def levenberg_marquardt(model: PoseModel, poses: Poses, W: Whitening | None, loss: str, c: float,
                        max_iter: int, tol: float, estimate: str = "profile") -> LMResult:
    """Minimise the objective over the poses from `poses` by Levenberg-Marquardt.

    Weights (`mode_of`): W given ("fixed"): F under W. W None with least squares ("profile"): the
    profile likelihood L of `objective`, weights = RMS of the current residuals; with fewer than
    the model's profile_min_pairs ("initial"): F under the RMS weights of the start. W None with
    a robust loss ("irls"): F, with median-based scales re-estimated after every accepted step;
    convergence then also requires that they changed by at most WEIGHT_TOL (relative), a fixed
    point of estimate + minimise. Every accepted step decreases the objective (under the current
    weights for "irls"); Marquardt's damping lam * diag(Hw) keeps the method invariant to the
    units of the parameters. Converged: the decrease predicted by the Gauss-Newton step is below
    tol * F; that last (tiny) step is then taken without testing the objective, whose rounding
    is larger than the change. The model's fixed translation components (`PoseModel.fixed`) keep
    their starting values: every step lies in the span of `fixed_basis` at its point.
    """
    scale = model.scale
    fixed = model.fixed
    mode = mode_of(W, loss, model.m, estimate, model.profile_min_pairs)
    e0 = e = model.residuals(poses)
    cost0 = None
    if mode == "profile":  # the objective (carried along with e: each point is evaluated once) and its weights
        value, W = objective(e, None, mode, loss, c, scale)
        cost0 = value
    elif mode != "fixed":
        W = estimate_sigmas(e, scale, robust=loss != "linear")
    weight_change = np.inf if mode == "irls" else 0.0
    lam, iterations, converged, unjudged = 0.0, 0, False, 0
    while True:
        last_step_unjudged = False
        P = fixed_basis(poses, fixed)
        g, H, Hw, F = local_model(model, poses, e, W, mode, loss, c, scale, P)
        evaluated = (poses, W, P, Hw, F)  # the information matrix at the end, if no step follows
        if weight_change <= WEIGHT_TOL and _at_rounding(e, scale):
            converged = True  # exact data fitted to working precision: no step can be judged any more
            break
        if mode != "profile":
            value = F
        step_gn = _newton_step(H, g)
        decrement = -0.5 * float(g @ step_gn)  # objective decrease predicted by the Gauss-Newton step
        if mode == "profile" and decrement > PROFILE_NEAR and H is not Hw:  # far: see PROFILE_NEAR
            H = Hw
            step_gn = _newton_step(H, g)
            decrement = -0.5 * float(g @ step_gn)
        if decrement <= tol * F or F == 0.0:
            if decrement > 0.0:
                # The remaining Gauss-Newton step changes the objective by less than its rounding,
                # so it can no longer be judged; it is tiny and taken as is: it removes the last
                # ~1e-7 (relative to the errors) that tol leaves, so the answer does not depend
                # on the path taken (unit invariance to ~1e-14, one answer from every start).
                poses = retract_all(poses, _full(P, step_gn))
                e = model.residuals(poses)
                if mode == "profile":
                    value, W = objective(e, None, mode, loss, c, scale)
                last_step_unjudged = True
            if weight_change <= WEIGHT_TOL:
                converged = True
                break
            new = estimate_sigmas(e, scale, robust=True)  # optimal for these weights: move them
            weight_change, W = relative_change(new, W), new
            continue
        if iterations >= max_iter:
            break
        if decrement <= JUDGE_TOL * (abs(value) + F):
            # too small for the objective to judge (its rounding is ~1e-13 of its size): a
            # Gauss-Newton step this close to the minimum is reliable, take it; after JUDGE_STEPS
            # of them in a row the point is stationary to working precision (exact data, where
            # tol * F is below the rounding of the gradient)
            unjudged += 1
            if unjudged > JUDGE_STEPS and weight_change <= WEIGHT_TOL:
                converged = True
                break
            iterations += 1
            poses = retract_all(poses, _full(P, step_gn))
            e = model.residuals(poses)
            if mode == "profile":
                value, W = objective(e, None, mode, loss, c, scale)
            elif mode == "irls":
                new = estimate_sigmas(e, scale, robust=True)
                weight_change, W = relative_change(new, W), new
            continue
        unjudged = 0
        accepted = False
        while not accepted:  # try steps, raising the damping until one decreases the objective
            iterations += 1
            if lam == 0.0:
                step, predicted = step_gn, decrement
            else:
                step = _newton_step(H + lam * np.diag(Hw.diagonal()), g)
                predicted = -float(g @ step + 0.5 * step @ H @ step)
            trial = retract_all(poses, _full(P, step))
            en = model.residuals(trial)
            value_n, Wn = objective(en, W, mode, loss, c, scale)
            if value_n < value and predicted > 0:
                gain = (value - value_n) / predicted
                if gain > 0.75:
                    lam = 0.0 if lam < 1e-9 else lam / 3.0
                elif gain < 0.25:
                    lam = max(2.0 * lam, MIN_DAMPING)
                poses, e, W, value = trial, en, Wn, value_n
                accepted = True
            else:
                lam = max(lam * 10.0, MIN_DAMPING)
                if lam > 1e12 or iterations >= max_iter:
                    break
        if not accepted and lam > 1e12:
            # no step decreases the objective: stationary to working precision for these weights
            lam = 0.0
            if weight_change <= WEIGHT_TOL:
                converged = True
                break
            new = estimate_sigmas(e, scale, robust=True)
            weight_change, W = relative_change(new, W), new
            continue
        if not accepted:  # out of iterations
            break
        if mode == "irls":
            new = estimate_sigmas(e, scale, robust=True)
            weight_change, W = relative_change(new, W), new
    if evaluated[0] is poses and evaluated[1] is W:
        P, Hw, F = evaluated[2:]
    elif last_step_unjudged:
        # the last move was the Gauss-Newton step below tol: the information matrix evaluated just
        # before it holds at the end to the step's relative size (~1e-7 of the noise at most), so
        # only F is evaluated again (the model's Jacobian is most of an iteration: 0.15 s at 1e5),
        # where it is the objective (the profile likelihood's was evaluated with e)
        P, Hw = evaluated[2], evaluated[3]
        if mode != "profile":
            F = objective(e, W, "fixed", loss, c, scale)[0]
    else:
        P = fixed_basis(poses, fixed)
        _, _, Hw, F = local_model(model, poses, e, W, "fixed", loss, c, scale, P)
    if mode != "profile":
        value = F
    return LMResult(poses, W, value, iterations, converged, Hw, W.residual(e), e, mode, e0, P, cost0)


#: residuals below this (rad, and times the data's length scale) are rounding: the data are
#: exact and fitted (measured: exact data leave ~1e-16 rad and ~1e-13 of the scale)
ROUNDING = 1e-12


def _at_rounding(e: np.ndarray, scale: float) -> bool:
    """Whether every residual is at the rounding level of exact data (ROUNDING): the largest
    |entry| of each column in one pass (asked at every iteration), the first rows alone first:
    noisy data are told by them (at m = 1e5 the full pass costs 3 ms)."""
    if not len(e):
        return True
    limit = ROUNDING * scale
    for rows in (e[:_HEAD_ROWS], e) if len(e) > _HEAD_ROWS else (e,):
        top = np.abs(rows).max(axis=0).tolist()  # numpy's max: NaN stays NaN (not at rounding)
        # each column's largest against its bound, in Python floats (a NaN fails its comparison)
        if not (top[0] <= ROUNDING and top[1] <= ROUNDING and top[2] <= ROUNDING
                and top[3] <= limit and top[4] <= limit and top[5] <= limit):
            return False
    return True


#: `_at_rounding` looks at this many rows first
_HEAD_ROWS = 256


def _newton_step(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """-H^-1 g for the (n, n) Gauss-Newton matrix H (positive definite; damped or not), by
    LAPACK's Cholesky solver called directly: np.linalg.solve costs ~5x more at this size, which
    shows at small m. DegenerateDataError when H is not positive definite."""
    _, x, info = lapack.dposv(H, g)
    if info != 0:
        raise DegenerateDataError("the refinement's normal matrix is singular: the data do not determine the unknowns (do the poses "
                                  "rotate about at least two different axes?)")
    return -x


# --------------------------------------------------------------------------- the whole refinement

@dataclasses.dataclass(frozen=True)
class Settings:
    """How to refine: stated whitening W (None: estimate it) and its kind ("stated",
    "covariance", "estimated"; `handeye.estimation.whitening.stated`), loss and loss_scale, estimate
    ("profile" or "initial"), max_iter, tol (see `levenberg_marquardt`)."""

    W: Whitening | None
    weights: str
    loss: str = "linear"
    loss_scale: float = DEFAULT_LOSS_SCALE
    estimate: str = "profile"
    max_iter: int = 200
    tol: float = 1e-14


OBJECTIVES = {
    "fixed": "F = 1/2 sum rho(|whitened residual|^2), stated weights",
    "initial": "F = 1/2 sum rho(|whitened residual|^2), weights from the start's residuals "
               "(estimate='initial', or fewer than {n} pairs, where the profile likelihood is unbounded)",
    "profile": "negative log-likelihood with sigma_rot, sigma_trans estimated (profile)",
    "irls": "F = 1/2 sum rho(|whitened residual|^2), median-based scales at a fixed point",
}


def covariance(res: LMResult, loss: str, c: float, estimated: bool) -> tuple[np.ndarray, float]:
    """(covariance (6k, 6k) of the unknowns at the end of `levenberg_marquardt`, variance factor):
    the inverse information matrix, projected when translation components are fixed, times the
    variance factor when the weights were `estimated`. DegenerateDataError when the information
    matrix is singular, or too few pairs are left to estimate the noise."""
    n = res.H.shape[0]  # free parameters: 6k less the fixed components
    _, cov, info = lapack.dposv(res.H, np.eye(n))  # the inverse, by Cholesky (as the steps)
    if info != 0:
        raise DegenerateDataError("the refinement's normal matrix is singular at the solution: the data do not "
                                  "determine the unknowns there (do the poses rotate about at least two "
                                  "different axes?)")
    if res.P is not None:
        cov = res.P @ cov @ res.P.T
    cov = 0.5 * (cov + cov.T)
    s = (res.ew * res.ew).sum(axis=1)
    _, drho = loss_terms(s, loss, c)
    dof = 6.0 * float(drho.sum()) - n
    variance_factor = float((drho * s).sum()) / dof if dof > 0 else float("nan")
    if estimated:
        if not math.isfinite(variance_factor):
            raise DegenerateDataError("too few pairs to estimate the noise and the covariance")
        cov = cov * variance_factor
    return cov, variance_factor


def refine(model: PoseModel, poses0: Sequence[np.ndarray], settings: Settings) -> tuple[Poses, Status, dict[str, Any]]:
    """Refine the poses from `poses0`: (poses, status, diagnostics).

    Diagnostics: iterations, initial_cost, final_cost, converged, weights, weight_mode,
    objective, loss, loss_scale, variance_factor, covariance {name: (6, 6)} and
    covariance_<names> (6k, 6k) of (omega, v) of each unknown in its own frame, std {name:
    {rotation, translation}}, residual_rms, and sigma_rot, sigma_trans for per-group weights.
    With fixed translation components (`PoseModel.fixed`) the covariance is P H^-1 P^T in the
    basis P of the allowed perturbations: zero variance along the fixed directions.
    """
    loss, c, scale, max_iter = settings.loss, float(settings.loss_scale), model.scale, int(settings.max_iter)
    poses0 = tuple(poses0)
    res = levenberg_marquardt(model, poses0, settings.W, loss, c, max_iter, settings.tol, settings.estimate)
    iterations = res.iterations
    # The objective at the start; for "irls" under the final weights. Fixed weights and the
    # profile likelihood are monotone; with "irls" the weights moved on the way, so a start that
    # is better under the final weights (another basin) is refined under them too and the better
    # answer kept.
    initial_cost = res.cost0 if res.cost0 is not None else objective(res.e0, res.W, res.mode, loss, c, scale)[0]
    if res.mode == "irls" and initial_cost < res.cost:
        again = levenberg_marquardt(model, poses0, res.W, loss, c, max_iter, settings.tol)
        iterations += again.iterations
        if again.cost < res.cost:
            res = again

    cov, variance_factor = covariance(res, loss, c, settings.weights == "estimated")
    var = cov.diagonal().tolist()
    sum_rot, sum_trans = sums_of_squares(res.e)
    names = model.unknowns
    diagnostics: dict[str, Any] = {
        "iterations": iterations,
        "initial_cost": initial_cost,
        "final_cost": res.cost,
        "converged": res.converged,
        "weights": settings.weights,
        "weight_mode": res.mode,
        "objective": OBJECTIVES[res.mode].format(n=model.profile_min_pairs),
        "loss": loss,
        "loss_scale": c,
        "variance_factor": variance_factor,
        "covariance": {k: cov[6 * j:6 * j + 6, 6 * j:6 * j + 6].tolist() for j, k in enumerate(names)},
        "covariance_" + "".join(names): cov.tolist(),
        "std": {k: {"rotation": math.sqrt(sum(var[6 * j:6 * j + 3])),
                    "translation": math.sqrt(sum(var[6 * j + 3:6 * j + 6]))} for j, k in enumerate(names)},
        "residual_rms": {"rotation": math.sqrt(sum_rot / res.e.shape[0]),
                         "translation": math.sqrt(sum_trans / res.e.shape[0])},
    }
    if res.W.L is None:
        diagnostics["sigma_rot"], diagnostics["sigma_trans"] = res.W.sigma_rot, res.W.sigma_trans
    status = Status.OPTIMAL if res.converged else Status.NOT_CONVERGED
    if not res.converged:
        diagnostics["warnings"] = [
            (f"refine did not converge within max_iter={max_iter} iterations; the answer "
             "is the last iterate")
        ]
    return res.poses, status, diagnostics
