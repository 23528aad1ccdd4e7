"""The self-check's best fit near an answer: the local least-squares fit with estimated weights
(refine's engine, `handeye.estimation.nlls`), robust where pairs are far off, with its covariance. Shared by
the self-check's checks (`handeye.checks.self_check`, `handeye.checks.scale_checks`) and the
studies of systematic errors (bench/systematic.py)."""

from __future__ import annotations

import contextlib
from typing import Any

import numpy as np

from handeye.estimation import lm_objective, nlls
from handeye.estimation.robust import DEFAULT_LOSS_SCALE, OUTLIER_CHI2
from handeye.estimation.whitening import Whitening, estimate_sigmas
from handeye.geometry.linalg import einsum

#: iterations of the local fit (it starts at the answer; good answers converge in a few) and
#: its tolerance: the fit stops when a Gauss-Newton step would lower the objective (~3m, in
#: whitened units) by less than FIT_TOL of it, i.e. d^2 / 2 is known to ~1e-3 * 3m. Measured
#: (shah, li, kron-lstsq at m = 10 and 50): d the same to 3-4 digits as at 1e-6, with one to
#: two iterations fewer (a third of the check's time); the thresholds need d to ~10%.
MAX_ITER = 50
FIT_TOL = 1e-3


def best_fit(model: Any, poses: tuple[np.ndarray, ...], disagreeing: bool = False
              ) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray, Any, np.ndarray, float]:
    """The best fit near the answer `poses`: (fit, its covariance (6k, 6k), the pairs flagged far
    off at it, the engine's result there, the residuals at the answer itself, the variance
    factor of the covariance). The local least-squares fit with estimated weights (`nlls`,
    refine's engine, to FIT_TOL), and when pairs are far off at it, or some pairs disagree with
    the others (`disagreeing`: many gross pairs can pull the fit so far that none looks far off
    at it), a robust (Cauchy) one: from that fit and from the answer, the lower Cauchy cost kept
    (`robust_fit`). The result is kept on the model (`PoseModel.best_fit_memo`) and given again
    for the same poses (to the bit) and `disagreeing`, its arrays read-only: `auto` asks check 5
    alone at its answer (`scale_checks.camera_scale_verdict`) and the host's self-check then asks
    the same fit of the same model at the same answer (at m = 1e5 a second fit of ~0.2 s)."""
    key = b"".join(np.ascontiguousarray(p, dtype=float).tobytes() for p in poses) + bytes([disagreeing])
    memo = getattr(model, "best_fit_memo", None)
    if memo is not None and memo[0] == key:
        return memo[1]
    out = _fit(model, poses, disagreeing)
    for array in (out[1], out[2], out[4]):
        array.setflags(write=False)
    with contextlib.suppress(AttributeError):  # a model that takes no attributes (slots, frozen) fits again
        model.best_fit_memo = (key, out)
    return out


def _fit(model: Any, poses: tuple[np.ndarray, ...], disagreeing: bool
         ) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray, Any, np.ndarray, float]:
    loss = "linear"
    res = nlls.levenberg_marquardt(model, poses, None, loss, DEFAULT_LOSS_SCALE, MAX_ITER, FIT_TOL)
    at_answer = res.e0
    flagged = beyond(res.e, model.scale)
    if flagged.any() or disagreeing:
        loss = "cauchy"
        res = robust_fit(model, res.poses, poses)
        flagged = beyond(res.e, model.scale)
    cov, factor = nlls.covariance(res, loss, DEFAULT_LOSS_SCALE, estimated=True)
    return res.poses, cov, flagged, res, at_answer, factor


def robust_fit(model: Any, least_squares: tuple[np.ndarray, ...], answer: tuple[np.ndarray, ...]) -> Any:
    """The Cauchy fit from the least-squares fit and the one from the answer, whichever has the
    lower Cauchy cost under the sharper of their noise scales. Many gross pairs (40%, measured)
    pull the least-squares fit into another basin, where a Cauchy fit from it stays (1-sigma
    9 deg for an answer 0.05 deg off, which auto found by leaving those pairs out); the answer
    itself is the other start, and the cost, not the start, decides."""
    fits = [nlls.levenberg_marquardt(model, start, None, "cauchy", DEFAULT_LOSS_SCALE, MAX_ITER, FIT_TOL)
            for start in (least_squares, answer)]
    scales = [estimate_sigmas(f.e, model.scale, robust=True) for f in fits]
    W = Whitening(min(s.sigma_rot for s in scales), min(s.sigma_trans for s in scales))
    cost = [lm_objective.cost_of(model, f.poses, W, "cauchy", DEFAULT_LOSS_SCALE) for f in fits]
    return fits[1] if cost[1] < cost[0] else fits[0]


def beyond(e: np.ndarray, scale: float) -> np.ndarray:
    """Pairs whose residual, whitened by median-based scales, is beyond OUTLIER_CHI2."""
    ew = estimate_sigmas(e, scale, robust=True).residual(e)
    return einsum("ni,ni->n", ew, ew) > OUTLIER_CHI2
