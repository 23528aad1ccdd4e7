"""Robust losses of the nonlinear least-squares engine (`handeye.estimation.nlls`), shared by every problem.

A loss rho acts on s = |e_i|^2, the squared norm of one pair's whitened residual 6-vector, and the
objective is F = 1/2 sum_i rho(s_i) (rho(s) = s is least squares):

    linear   rho(s) = s
    huber    rho(s) = s for sqrt(s) <= c,  2 c sqrt(s) - c^2 beyond
    cauchy   rho(s) = c^2 log(1 + s / c^2)

c (`loss_scale`) is where a robust loss departs from least squares, in units of that norm; the
default is the 95% quantile of the norm of a 6-vector of standard normal noise. Gauss-Newton on F
weights pair i by rho'(s_i) (iteratively re-weighted least squares).
"""

from __future__ import annotations

import numpy as np

from handeye.base.errors import InputError

LOSSES = ("linear", "huber", "cauchy")
#: sqrt of the 95% quantile of chi^2 with 6 degrees of freedom: a pair whose whitened 6-vector is
#: longer than this is an outlier at the 5% level; the default threshold of the robust losses.
DEFAULT_LOSS_SCALE = 3.5484626592
#: a pair whose residual, whitened by median-based scales, has squared norm beyond this (8 robust
#: sigmas) is far off the others: a gross error, not noise (`auto`'s outlier step, the host's
#: self-check). Not chi^2_6 at 99.9% (22.46): real residuals have heavier tails than chi^2_6 (a
#: station's rotation noise reaches the translation residual through the lever arm,
#: anisotropically; consecutive motions share stations), and that threshold flagged a pair in
#: 5-9% of clean simulated axyb data sets (m = 16-50) and 19-30% of clean consecutive-motion axxb
#: sets; 64 flagged none of 100 in each cell, while gross pairs (>= 5 deg) sit at norms of ~40
#: and beyond (bench/outliers.py, docs/solvers/auto.md).
OUTLIER_CHI2 = 64.0
#: sigma = MAD_TO_SIGMA * median |x| for x ~ N(0, sigma^2): 1 / (the 75% quantile of the standard
#: normal), the robust standard deviation of differences about 0
MAD_TO_SIGMA = 1.482602218505602


def loss_terms(s: np.ndarray, loss: str, c: float) -> tuple[np.ndarray, np.ndarray]:
    """rho(s) and rho'(s) of squared whitened norms s: (m,) (rho(s) = s for "linear")."""
    if loss == "linear":
        return s, np.ones_like(s)
    c2 = c * c
    if loss == "huber":
        root = np.sqrt(s)
        inlier = s <= c2
        return np.where(inlier, s, 2.0 * c * root - c2), np.where(inlier, 1.0, c / np.maximum(root, c))
    if loss == "cauchy":
        return c2 * np.log1p(s / c2), 1.0 / (1.0 + s / c2)
    raise InputError(f"unknown loss {loss!r}; known: {', '.join(LOSSES)}")
