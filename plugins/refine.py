"""`refine`: geometric maximum-likelihood refinement of A_i X = Y B_i on SE(3) x SE(3).

Beyond the paper (issue 4, item 3). The Kronecker cost of eq. 8 mixes rotation entries and
translations in one algebraic residual whose relative weight depends on the length unit; this
solver instead minimises a weighted sum of squared *geometric* residuals, one 6-vector per pair:

    r_i = log(R_Ai R_X R_Bi^T R_Y^T)            rotation vector of the discrepancy [rad]
    t_i = R_Ai t_X + t_Ai - R_Y t_Bi - t_Y       t(A_i X) - t(Y B_i)              [data units]

(the per-pair quantities of eqs. 32-33, as vectors). With Gaussian noise of standard deviation
sigma_rot (rad, per axis) and sigma_trans (data units, per axis) on the poses, r_i and t_i are
isotropic with those variances to first order (rotation noise of A also leaks sigma_rot_A |t_X|
into t_i, which the diagonal model neglects), so the cost

    F = 1/2 sum_i rho(|e_i|^2),   e_i = W^(1/2) [r_i; t_i]  (whitened residual)

is the negative log-likelihood for rho(s) = s. Unknowns are updated by right perturbations
X <- X exp(xi_X), xi = (omega, v) (rotation in rad, translation in data units, both in the frame
of X), retracted as (R exp([omega]_x), t + R v), which agrees with SE(3)'s exp to first order.
Analytic Jacobians of e_i with respect to (xi_X, xi_Y) (derived in docs/solvers/refine.md,
checked against central differences in tests/test_refine.py):

    d r / d omega_X = Jl^-1(r) R_A R_X        d r / d omega_Y = -Jr^-1(r) R_Y
    d t / d v_X     = R_A R_X                 d t / d omega_Y = R_Y [t_B]_x
    d t / d v_Y     = -R_Y                    (other blocks zero)

with Jl^-1, Jr^-1 = (Jl^-1)^T the inverse left / right Jacobians of SO(3). The minimiser is a
vectorised Levenberg-Marquardt (no Python loop over pairs) with Marquardt's diagonal scaling
(invariant to the units of the parameters), iteratively re-weighted for the robust losses
(Huber, Cauchy, on the norm of each pair's whitened 6-vector).

Weights: stated by the user (``sigma_rot`` and ``sigma_trans``, or a 6x6 / (m, 6, 6) ``covariance``
of [r_i; t_i]) or, by default, estimated. With least squares the estimate is the maximum of the
likelihood over the two variances as well (profile likelihood: sigma^2 = RMS of each residual
group at the answer, L = 3m log sigma_rot + 3m log sigma_trans + const, minimised by
Levenberg-Marquardt with its exact gradient and the log's curvature in the Hessian). It is one
smooth function, so the answer does not depend on the start within its basin (the "oracle"
started at the truth and `auto` agree to ~1e-13) and scales exactly with the length unit. With
m = 3 pairs the translation residuals can be fitted exactly and that likelihood is unbounded, so
the weights are then the RMS of the start's residuals, kept fixed. With a robust loss the scales
are robust (median norm / median of chi_3) and re-estimated until they are a fixed point.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.linalg import lapack
from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import BackendUnavailableError, DegenerateDataError, InputError, SolverError
from handeye.options import check_choice, check_positive
from handeye.problems.axyb import AXYBData
from handeye.solution import jsonable
from handeye.se3 import so3_log
from handeye.validation import pose_stack

LOSSES = ("linear", "huber", "cauchy")
ESTIMATES = ("profile", "initial")
#: sqrt of the 95% quantile of chi^2 with 6 degrees of freedom: a pair whose whitened 6-vector is
#: longer than this is an outlier at the 5% level; the default threshold of the robust losses.
DEFAULT_LOSS_SCALE = 3.5484626592
#: median of the chi distribution with 3 degrees of freedom: median |n| for n ~ N(0, sigma^2 I3)
#: is CHI3_MEDIAN * sigma; turns the median residual norm into a per-axis standard deviation.
CHI3_MEDIAN = 1.5381722544550522
#: relative floor of estimated sigmas (rad, and times the data's RMS translation): keeps weights
#: finite on exact data, where any positive weights give the same (exact) answer.
SIGMA_FLOOR = 1e-12
#: a Gauss-Newton step whose predicted decrease is below JUDGE_TOL * |objective| is taken without
#: testing the objective, which cannot resolve it (Levenberg-Marquardt would reject it on rounding
#: and stop short: answers then differed by ~1e-9 rad between mm and m).
JUDGE_TOL = 1e-10
#: from this many pairs on, the normal equations are summed in closed form (`model_sigmas`)
#: instead of from the (m, 6, 12) Jacobian: measured 0.38 vs 0.08 ms at m = 16, 0.84 vs 0.52 ms
#: at 600, 0.76 vs 1.7 ms at 1000, 4.8 vs 17 ms at m = 10000.
BLOCKS_MIN_PAIRS = 700
JUDGE_STEPS = 3
#: damping (relative to diag(Hw)) tried first after an undamped step failed. A damping much
#: smaller than 1e-3 barely changes a 12-parameter Gauss-Newton step, so starting lower only
#: repeats the rejected step: measured on the bench data (m = 16, noise on A and B) 1e-6 cost
#: four rejected trials before the first accepted one.
MIN_DAMPING = 1e-3
#: relative change of estimated sigmas between iterations that counts as a fixed point.
WEIGHT_TOL = 1e-6
#: solvers that cannot serve as `init` because they call `refine` themselves.
RECURSIVE = ("refine", "auto")


@dataclasses.dataclass(frozen=True)
class Options:
    """Options of `refine`.

    init: name of the solver giving the starting point (default: "so3-sdp" when registered and
        available, else "kron-lstsq"), or a mapping {"X": 4x4, "Y": 4x4} of starting poses (the
        harness's "oracle" passes the ground truth this way); ignored when init_X, init_Y given.
    init_X, init_Y: (4, 4) starting poses (both or neither).
    sigma_rot, sigma_trans: stated noise of the residual, per axis (rad, data units); both or
        neither. covariance: (6, 6) or (m, 6, 6) covariance of [r_i; t_i] instead.
        Without them the weights are estimated from the residuals (see module docstring):
    estimate: how, "profile" (default: maximum likelihood over the two variances too, i.e. RMS
        of the residuals at the answer; independent of the start) or "initial" (RMS, or for a
        robust loss the median-based scale, of the start's residuals, then fixed).
    loss: "linear" (least squares, default), "huber" or "cauchy", on the norm of each pair's
        whitened residual; loss_scale: where the robust loss departs from least squares, in units
        of that norm (default sqrt(chi2_6 quantile 0.95) = 3.55).
    max_iter: total Levenberg-Marquardt iterations; tol: stop when the cost decrease predicted by a
        Gauss-Newton step is below tol * cost.
    """

    init: str | None = None
    init_X: Any = None
    init_Y: Any = None
    sigma_rot: float | None = None
    sigma_trans: float | None = None
    covariance: Any = None
    estimate: str = "profile"
    loss: str = "linear"
    loss_scale: float = DEFAULT_LOSS_SCALE
    max_iter: int = 200
    tol: float = 1e-14

    def __post_init__(self) -> None:
        check_choice("loss", self.loss, LOSSES)
        check_choice("estimate", self.estimate, ESTIMATES)
        check_positive("loss_scale", self.loss_scale)
        check_positive("tol", self.tol)
        if not isinstance(self.max_iter, (int, np.integer)) or self.max_iter < 1:
            raise InputError(f"option max_iter={self.max_iter!r} must be an integer >= 1")
        if isinstance(self.init, Mapping):  # {"X": 4x4, "Y": 4x4}: start from given poses
            if set(self.init) != {"X", "Y"} or self.init_X is not None:
                raise InputError(f"option init as a mapping must be {{'X': 4x4, 'Y': 4x4}} (and no init_X/init_Y), got keys {sorted(self.init)}")
            object.__setattr__(self, "init_X", self.init["X"])
            object.__setattr__(self, "init_Y", self.init["Y"])
            object.__setattr__(self, "init", None)
        if self.init is not None:
            if not isinstance(self.init, str):
                raise InputError(f"option init={self.init!r} must be a solver name (str)")
            if self.init in RECURSIVE:
                raise InputError(
                    f"option init={self.init!r} would make refine start from itself; use a "
                    "closed-form or certifiable solver such as 'kron-lstsq' or 'so3-sdp'"
                )
        if (self.init_X is None) != (self.init_Y is None):
            raise InputError("options init_X and init_Y must be given together (both 4x4 poses)")
        if self.init_X is not None:
            X, Y = _pose_options(self.init_X, self.init_Y)
            object.__setattr__(self, "init_X", X)
            object.__setattr__(self, "init_Y", Y)
        if (self.sigma_rot is None) != (self.sigma_trans is None):
            raise InputError("options sigma_rot and sigma_trans must be given together (the ratio sets the weights)")
        if self.sigma_rot is not None:
            check_positive("sigma_rot", self.sigma_rot)
            check_positive("sigma_trans", self.sigma_trans)
            if self.covariance is not None:
                raise InputError("give either sigma_rot/sigma_trans or covariance, not both")
        if self.covariance is not None:
            object.__setattr__(self, "covariance", _covariance_option(self.covariance))


def _pose_option(value: Any, name: str) -> np.ndarray:
    T = np.asarray(value, dtype=float)
    if T.shape != (4, 4):
        raise InputError(f"option {name} must be a 4x4 pose, got shape {T.shape}")
    return pose_stack(T[None], name)[0]


def _pose_options(X: Any, Y: Any) -> tuple[np.ndarray, np.ndarray]:
    """init_X, init_Y as validated poses. Both are checked in one `pose_stack` call, which is
    most of the cost of parsing the options at small m; when that fails, each is checked alone,
    for an error naming the bad one."""
    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    if X.shape == Y.shape == (4, 4):
        try:
            both = pose_stack(np.stack([X, Y]), "init_X, init_Y")
            return both[0], both[1]
        except InputError:
            pass
    return _pose_option(X, "init_X"), _pose_option(Y, "init_Y")


def _covariance_option(value: Any) -> np.ndarray:
    C = np.array(value, dtype=float)
    if C.shape[-2:] != (6, 6) or C.ndim not in (2, 3):
        raise InputError(f"option covariance must have shape (6, 6) or (m, 6, 6), got {C.shape}")
    if not np.all(np.isfinite(C)) or np.max(np.abs(C - np.swapaxes(C, -1, -2))) > 1e-12 * np.max(np.abs(C)):
        raise InputError("option covariance must be finite and symmetric")
    try:
        L = np.linalg.cholesky(C)
    except np.linalg.LinAlgError:
        raise InputError("option covariance must be positive definite") from None
    L.setflags(write=False)
    return L  # stored as its Cholesky factor


# --------------------------------------------------------------------------- model
#
# At the usual m (tens of pairs) every array here is tiny and the cost of a Levenberg-Marquardt
# iteration is the number of numpy calls (1-3 us each), not arithmetic: the helpers below build
# 3x3 blocks from (m, 9) rows with one product against a constant (`_SKEW`, `_LOG_MAP`) instead of
# entry-by-entry assignments, use batched `@` (faster than einsum at every m), and the 12x12
# systems are solved by LAPACK's Cholesky called directly (`_newton_step`).

#: v @ _SKEW = [v]_x flattened row-major: (..., 3) -> (..., 9)
_SKEW = np.zeros((3, 9))
_SKEW[2, 1], _SKEW[1, 2], _SKEW[2, 3], _SKEW[0, 5], _SKEW[1, 6], _SKEW[0, 7] = -1.0, 1.0, 1.0, -1.0, -1.0, 1.0
#: the 3x3 identity
_I3 = np.eye(3)
#: smallest normal float: keeps theta / sin(theta) finite at theta = 0
_TINY = np.finfo(float).tiny
#: the 12x12 identity: right-hand side that turns the normal matrix into the covariance
_I12 = np.eye(12)
#: R.reshape(m, 9) @ _LOG_MAP = [vee(R - R^T) / 2, tr(R) / 2]: (m, 4), the parts of R that its
#: rotation vector depends on (sin(theta) axis, and (1 + 2 cos theta) / 2).
_LOG_MAP = np.zeros((9, 4))
_LOG_MAP[7, 0], _LOG_MAP[5, 0], _LOG_MAP[2, 1], _LOG_MAP[6, 1], _LOG_MAP[3, 2], _LOG_MAP[1, 2] = 0.5, -0.5, 0.5, -0.5, 0.5, -0.5
_LOG_MAP[[0, 4, 8], 3] = 0.5
for _array in (_SKEW, _I3, _I12, _LOG_MAP):
    _array.setflags(write=False)
del _array


def _so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors of R: (m, 3, 3) -> (m, 3), angle in [0, pi].

    theta = atan2(|s|, (tr R - 1) / 2) with s = vee(R - R^T) / 2 = sin(theta) axis (one product
    with `_LOG_MAP`), then phi = theta / |s| s (at small angles atan2 returns |s| itself to
    rounding, so the ratio is accurate down to 0 and needs no series; s = 0 gives phi = 0);
    within 1e-3 rad of pi, where s loses the axis, scipy's quaternion route is used for those
    rotations only. Plain numpy: at m = 16 this is ~20x cheaper than scipy's Rotation.
    """
    parts = R.reshape(len(R), 9) @ _LOG_MAP
    s = parts[:, :3]
    sin = np.sqrt((s * s).sum(axis=1))
    theta = np.arctan2(sin, parts[:, 3] - 0.5)
    phi = (theta / np.maximum(sin, _TINY))[:, None] * s
    if theta.max(initial=0.0) > np.pi - 1e-3:
        near_pi = theta > np.pi - 1e-3
        phi[near_pi] = so3_log(R[near_pi])
    return phi


def _so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation exp([w]_x) of one rotation vector w: (3,): Rodrigues' I + a [w]_x + b [w]_x^2 with
    a = sin(theta) / theta, b = (1 - cos theta) / theta^2 (series below 1e-6 rad) and
    [w]_x^2 = w w^T - theta^2 I, entry by entry in Python floats (cheaper than numpy calls for one
    3x3; two per iteration)."""
    x, y, z = w.tolist()
    theta2 = x * x + y * y + z * z
    theta = math.sqrt(theta2)
    if theta < 1e-6:
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta2
    ax, ay, az, bx, by, bz = a * x, a * y, a * z, b * x, b * y, b * z
    return np.array([[1.0 - by * y - bz * z, bx * y - az, bx * z + ay],
                     [bx * y + az, 1.0 - bx * x - bz * z, by * z - ax],
                     [bx * z - ay, by * z + ax, 1.0 - bx * x - by * y]])


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]_x: (..., 3) -> (..., 3, 3)."""
    return (v @ _SKEW).reshape(v.shape[:-1] + (3, 3))


@dataclasses.dataclass(frozen=True)
class Pairs:
    """The data, arranged for cheap evaluation: RA9: (3m, 3) = stacked R_A, RBt9: (3m, 3) =
    stacked R_B^T, tA, tB: (m, 3), TBx_T: (3, 3m) = [t_B]_x stacked side by side (so that
    R_Y [t_B]_x for all pairs is one product R_Y @ TBx_T)."""

    RA9: np.ndarray
    RBt9: np.ndarray
    tA: np.ndarray
    tB: np.ndarray
    m: int
    TBx_T: np.ndarray

    @classmethod
    def of(cls, data: AXYBData) -> Pairs:
        RA, RB = data.A[:, :3, :3], data.B[:, :3, :3]
        m = len(RA)
        tB = np.ascontiguousarray(data.B[:, :3, 3])
        return cls(np.ascontiguousarray(RA.reshape(3 * m, 3)),
                   np.ascontiguousarray(np.swapaxes(RB, 1, 2)).reshape(3 * m, 3),
                   np.ascontiguousarray(data.A[:, :3, 3]), tB, m,
                   np.ascontiguousarray(_skew(tB).transpose(1, 0, 2)).reshape(3, 3 * m))


def residuals(P: Pairs, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Unwhitened residuals e: (m, 6) = [r_i; t_i], r_i the rotation vector of the discrepancy
    Q_i = R_A R_X R_B^T R_Y^T (two BLAS products, one batched 3x3)."""
    RY = Y[:3, :3]
    m = P.m
    AX = P.RA9 @ X[:3]  # (3m, 4): [R_A R_X, R_A t_X] per pair
    Q = AX[:, :3].reshape(m, 3, 3) @ (P.RBt9 @ RY.T).reshape(m, 3, 3)
    e = np.empty((m, 6))
    e[:, :3] = _so3_log(Q)
    e[:, 3:] = AX[:, 3].reshape(m, 3) - P.tB @ RY.T + (P.tA - Y[:3, 3])
    return e


def _jl_coefficient(theta2: np.ndarray) -> np.ndarray:
    """c(theta) = 1/theta^2 - (1 + cos theta) / (2 theta sin theta) = (1 - (theta/2) cot(theta/2)) /
    theta^2 at theta^2 = |r|^2: (m,), the coefficient of [r]_x^2 in the inverse Jacobians of SO(3)
    (`inverse_jacobians`). When every theta < 0.1 rad (the usual case: residual rotations) its
    Taylor series 1/12 + theta^2/720 + theta^4/30240 + theta^6/1209600, exact to rounding there
    (the closed form loses digits to cancellation at small angles) and fewer numpy calls; else the
    closed form, with 1/12 + theta^2/720 below 1e-4 rad."""
    if theta2.max(initial=0.0) < 0.01:
        return ((theta2 / 1209600.0 + 1.0 / 30240.0) * theta2 + 1.0 / 720.0) * theta2 + 1.0 / 12.0
    theta = np.sqrt(theta2)
    small = theta < 1e-4
    ts = np.where(small, 1.0, theta)
    half = 0.5 * ts
    return np.where(small, 1.0 / 12.0 + theta2 / 720.0, (1.0 - half / np.tan(half)) / (ts * ts))


def inverse_jacobians(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse left and right Jacobians of SO(3) at rotation vectors r: (m, 3) -> two (m, 3, 3):
    Jl^-1(r) = I - [r]_x / 2 + c(theta) [r]_x^2 and Jr^-1(r) = Jl^-1(r)^T = I + [r]_x / 2 +
    c(theta) [r]_x^2 ([r]_x^2 = r r^T - theta^2 I; c of `_jl_coefficient`)."""
    K = _skew(r)
    common = _jl_coefficient((r * r).sum(axis=1))[:, None, None] * (K @ K) + _I3
    half = 0.5 * K
    return common - half, common + half


def jacobian(P: Pairs, X: np.ndarray, Y: np.ndarray, e: np.ndarray) -> np.ndarray:
    """J: (m, 6, 12) = d e_i / d (omega_X, v_X, omega_Y, v_Y) at (X, Y), e from `residuals`.

    With Q_i = R_A R_X R_B^T R_Y^T = exp([r_i]_x): X exp(omega_X) gives Q <- exp([R_A R_X omega_X]_x) Q
    and Y exp(omega_Y) gives Q <- Q exp(-[R_Y omega_Y]_x), hence
    rotation rows [Jl^-1(r) R_A R_X, 0, -Jr^-1(r) R_Y, 0];
    translation rows [0, R_A R_X, R_Y [t_B]_x, -R_Y] (R_Y [t_B]_x = [R_Y t_B]_x R_Y).
    """
    m = P.m
    RX, minus_RY = X[:3, :3], -Y[:3, :3]
    RAX = (P.RA9 @ RX).reshape(m, 3, 3)
    Jl_inv, Jr_inv = inverse_jacobians(e[:, :3])
    J = np.zeros((m, 6, 12))
    np.matmul(Jl_inv, RAX, out=J[:, :3, 0:3])
    J[:, :3, 6:9] = (Jr_inv.reshape(3 * m, 3) @ minus_RY).reshape(m, 3, 3)
    J[:, 3:, 3:6] = RAX
    J[:, 3:, 6:9] = (Y[:3, :3] @ P.TBx_T).reshape(3, m, 3).transpose(1, 0, 2)
    J[:, 3:, 9:12] = minus_RY
    return J


def retract(T: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """T exp(xi) to first order: (R exp([omega]_x), t + R v) for xi = (omega, v) and a pose T
    (whose last row [0, 0, 0, 1] is kept)."""
    R, out = T[:3, :3], T.copy()
    out[:3, :3] = R @ _so3_exp(xi[:3])
    out[:3, 3] += R @ xi[3:]
    return out


# --------------------------------------------------------------------------- weights, losses

@dataclasses.dataclass(frozen=True)
class Whitening:
    """e -> W^(1/2) e, by per-axis sigmas (sigma_rot, sigma_trans) or a Cholesky factor L."""

    sigma_rot: float | None = None
    sigma_trans: float | None = None
    L: np.ndarray | None = None  # (6, 6) or (m, 6, 6) lower Cholesky factor of the covariance

    def residual(self, e: np.ndarray) -> np.ndarray:
        """Whitened residuals L^-1 e_i: (m, 6)."""
        if self.L is None:
            return e * self._inv_sigmas()
        if self.L.ndim == 2:
            return np.linalg.solve(self.L, e.T).T
        return np.linalg.solve(self.L, e[:, :, None])[:, :, 0]

    def jacobian(self, J: np.ndarray) -> np.ndarray:
        """Whitened Jacobians L^-1 J_i: (m, 6, 12)."""
        if self.L is None:
            return J * self._inv_sigmas()[:, None]
        if self.L.ndim == 2:
            return np.einsum("ij,njk->nik", np.linalg.inv(self.L), J)
        return np.linalg.solve(self.L, J)

    def _inv_sigmas(self) -> np.ndarray:
        a, b = 1.0 / self.sigma_rot, 1.0 / self.sigma_trans
        return np.array([a, a, a, b, b, b])


def estimate_sigmas(e: np.ndarray, scale: float, robust: bool = False) -> Whitening:
    """Per-axis sigmas (rad, data units) of residuals e: (m, 6), floored at SIGMA_FLOOR (rad) and
    SIGMA_FLOOR * scale (data units).

    robust=False (least squares): RMS, sigma^2 = sum_i |r_i|^2 / 3m (likewise for t_i). The fixed
    point of "estimate, then minimise" is then a stationary point of the likelihood with the two
    variances unknown (concentrated: 3m/2 (log sum |r_i|^2 + log sum |t_i|^2)), a smooth function,
    so the answer does not depend on the start or the path to it.
    robust=True (huber, cauchy): median norm / CHI3_MEDIAN, so that outliers do not set the scale.
    """
    m = len(e)
    if not robust:
        return _rms_whitening(*_sums_of_squares(e), m, scale)
    norms = np.sort(np.sqrt((e * e).reshape(m, 2, 3).sum(axis=2)), axis=0)  # (m, 2)
    s_rot, s_trans = (0.5 * (norms[(m - 1) // 2] + norms[m // 2]) / CHI3_MEDIAN).tolist()  # medians
    return Whitening(max(s_rot, SIGMA_FLOOR), max(s_trans, SIGMA_FLOOR * scale))


def _sums_of_squares(e: np.ndarray) -> tuple[float, float]:
    """sum_i |r_i|^2 and sum_i |t_i|^2 of residuals e: (m, 6)."""
    sum_rot, sum_trans = (e * e).reshape(len(e), 2, 3).sum(axis=(0, 2)).tolist()
    return sum_rot, sum_trans


def _rms_whitening(sum_rot: float, sum_trans: float, m: int, scale: float) -> Whitening:
    """The RMS sigmas of `estimate_sigmas` (robust=False) from the sums of squares of m residuals."""
    s_rot, s_trans = math.sqrt(sum_rot / (3 * m)), math.sqrt(sum_trans / (3 * m))
    return Whitening(max(s_rot, SIGMA_FLOOR), max(s_trans, SIGMA_FLOOR * scale))


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


# --------------------------------------------------------------------------- Levenberg-Marquardt

#: fewest pairs for the profile likelihood. The translation residuals (3m numbers) depend on 9
#: parameters (t_X, t_Y, R_Y); with m = 3 they can be fitted exactly, and the likelihood with an
#: unknown translation variance is unbounded there (sigma_trans -> 0): measured in 6% of m = 3
#: simulations started at the truth, never from the usual starts (docs/solvers/refine.md).
PROFILE_MIN_PAIRS = 4


def mode_of(W: Whitening | None, loss: str, m: int, estimate: str = "profile") -> str:
    """How the weights are obtained: "fixed" (stated); estimated with estimate="profile":
    "profile" (least squares, m >= PROFILE_MIN_PAIRS), "irls" (robust loss), "initial" (least
    squares with fewer pairs); estimate="initial": "initial" (the start's residuals, then fixed)."""
    if W is not None:
        return "fixed"
    if estimate == "initial":
        return "initial"
    if loss != "linear":
        return "irls"
    return "profile" if m >= PROFILE_MIN_PAIRS else "initial"


@dataclasses.dataclass
class LMResult:
    X: np.ndarray
    Y: np.ndarray
    W: Whitening  # weights at the end (estimated ones: those of the final residuals)
    cost: float  # the objective at the end (see `objective`)
    iterations: int
    converged: bool
    H: np.ndarray  # (12, 12) Gauss-Newton matrix sum_i rho'_i J_i^T J_i (whitened) at the end
    ew: np.ndarray  # (m, 6) whitened residuals at the end
    e: np.ndarray  # (m, 6) residuals at the end
    mode: str
    e0: np.ndarray  # (m, 6) residuals at the start


def objective(e: np.ndarray, W: Whitening, mode: str, loss: str, c: float, scale: float) -> tuple[float, Whitening]:
    """The objective minimised, at residuals e: (m, 6), and the weights it uses there.

    "fixed", "irls": F = 1/2 sum_i rho(|W^(1/2) e_i|^2) under the given W.
    "profile": the negative log-likelihood with the two variances unknown, minimised over them
    (profile likelihood): sigma_rot, sigma_trans = RMS of the residuals (`estimate_sigmas`) and
    L = 3m log sigma_rot + 3m log sigma_trans + 1/2 sum_i |W^(1/2) e_i|^2 (= 3m (log sigma_rot +
    log sigma_trans + 1) unless a sigma is at its floor). Unlike a fixed point of "estimate the
    weights, then minimise", L is one smooth function: monotone descent, quadratic convergence.
    """
    if mode == "profile":
        sum_rot, sum_trans = _sums_of_squares(e)
        W = _rms_whitening(sum_rot, sum_trans, len(e), scale)
        return (3.0 * len(e) * (math.log(W.sigma_rot) + math.log(W.sigma_trans))
                + 0.5 * (sum_rot / W.sigma_rot**2 + sum_trans / W.sigma_trans**2)), W
    ew = W.residual(e)
    return 0.5 * float(loss_terms((ew * ew).sum(axis=1), loss, c)[0].sum()), W


def cost_of(P: Pairs, X: np.ndarray, Y: np.ndarray, W: Whitening, loss: str, c: float) -> float:
    """F = 1/2 sum_i rho(|W^(1/2) e_i|^2) at (X, Y) under weights W."""
    return objective(residuals(P, X, Y), W, "fixed", loss, c, 1.0)[0]


def _model(e: np.ndarray, J: np.ndarray, W: Whitening, mode: str, loss: str, c: float,
           scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """Gradient g (12), Gauss-Newton Hessian H of the objective, Hw = sum rho' J_w^T J_w (the
    information matrix, for the covariance), F under W, and the whitened residuals e_w: (m, 6).

    "profile": d L = sum_groups J_w^T e_w (as least squares under the current RMS weights) and
    H = Hw - 2 / (3m) sum_groups a a^T with a = J_w,group^T e_w,group (the log's curvature), for
    each group (rotation, translation) whose sigma is above its floor; Hw when that is not
    positive definite (far from the minimum), which keeps the step a descent direction.
    """
    ew, Jw = W.residual(e), W.jacobian(J)
    if loss == "linear":
        F = 0.5 * float((ew * ew).sum())
    else:
        rho, drho = loss_terms((ew * ew).sum(axis=1), loss, c)
        F = 0.5 * float(rho.sum())
        sq = np.sqrt(drho)
        ew, Jw = ew * sq[:, None], Jw * sq[:, None, None]
    Jf = Jw.reshape(-1, 12)
    Hw = Jf.T @ Jf
    if mode != "profile":
        return Jf.T @ ew.reshape(-1), Hw, Hw, F, ew
    m = len(e)
    a = np.einsum("ngik,ngi->gk", Jw.reshape(m, 2, 3, 12), ew.reshape(m, 2, 3))  # gradient per group
    return a[0] + a[1], _profile_hessian(Hw, a, W, m, scale), Hw, F, ew


def _profile_hessian(Hw: np.ndarray, a: np.ndarray, W: Whitening, m: int, scale: float) -> np.ndarray:
    """Hw - 2/(3m) a_g a_g^T for each group g (rows of a: (2, 12), rotation and translation) whose
    sigma is above its floor (the logs' curvature of the profile likelihood); Hw itself when that
    is not positive definite (far from the minimum)."""
    if W.sigma_rot <= SIGMA_FLOOR or W.sigma_trans <= SIGMA_FLOOR * scale:
        a = a[[W.sigma_rot > SIGMA_FLOOR, W.sigma_trans > SIGMA_FLOOR * scale]]
    H = Hw - (2.0 / (3.0 * m)) * (a.T @ a)
    return H if lapack.dpotrf(H)[1] == 0 else Hw  # LAPACK's Cholesky: info 0 = positive definite


def model_sigmas(P: Pairs, X: np.ndarray, Y: np.ndarray, e: np.ndarray, W: Whitening, mode: str,
                 loss: str, c: float, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """`_model` for per-group sigmas (no full covariance), without forming J: (m, 6, 12).

    The blocks of J^T W J and J^T W e are sums over pairs of small products (derivation in
    docs/solvers/refine.md), using Jl^-T r = Jl^-1 r = r, Jl^-T Jl^-1 = Jl^-1 Jl^-T = I + beta [r]_x^2
    and Jl^-T Jl^-T = I + gamma [r]_x + delta [r]_x^2, with beta = 2c - 1/4 - c^2 theta^2,
    gamma = 1 - c theta^2, delta = 1/4 + 2c - c^2 theta^2 (c of `_jl_coefficient`). Each sum is one BLAS
    contraction over the pairs: this is several times faster than `_model` at large m and equal
    to it to rounding (tested).
    """
    m = P.m
    RX, RY = X[:3, :3], Y[:3, :3]
    wr, wt = 1.0 / W.sigma_rot**2, 1.0 / W.sigma_trans**2
    ew = W.residual(e)
    s = np.einsum("ni,ni->n", ew, ew)
    rho, d = loss_terms(s, loss, c)
    F = 0.5 * float(np.sum(rho))
    r, t = e[:, :3], e[:, 3:]
    RA = P.RA9.reshape(m, 3, 3)
    dr, dt = d[:, None] * r, d[:, None] * t
    theta2 = np.einsum("ni,ni->n", r, r)
    cc = _jl_coefficient(theta2)
    beta = 2.0 * cc - 0.25 - cc * cc * theta2
    gamma = 1.0 - cc * theta2
    delta = 0.25 + 2.0 * cc - cc * cc * theta2
    u = np.einsum("nji,nj->ni", RA, r)  # R_A^T r
    sum_d = float(np.sum(d))
    # gradient
    g_rot, g_trans = np.zeros(12), np.zeros(12)
    g_rot[0:3] = wr * (RX.T @ np.einsum("nji,nj->i", RA, dr))
    g_rot[6:9] = -wr * (RY.T @ dr.sum(axis=0))
    q = P.tB @ RY.T  # R_Y t_B
    g_trans[3:6] = wt * (RX.T @ np.einsum("nji,nj->i", RA, dt))
    g_trans[6:9] = wt * (RY.T @ np.cross(dt, q).sum(axis=0))
    g_trans[9:12] = -wt * (RY.T @ dt.sum(axis=0))
    # information matrix
    H = np.zeros((12, 12))
    db = d * beta
    H[0:3, 0:3] = wr * (RX.T @ (float(np.sum(d * (1.0 - beta * theta2))) * _I3 + (db[:, None] * u).T @ u) @ RX)
    H[6:9, 6:9] = wr * (RY.T @ (float(np.sum(d * (1.0 - beta * theta2))) * _I3 + (db[:, None] * r).T @ r) @ RY)
    K = _skew(r)
    T = (np.einsum("n,nij->ji", d * (1.0 - delta * theta2), RA)
         + np.tensordot(RA, (d * gamma)[:, None, None] * K, axes=([0, 1], [0, 1]))
         + ((d * delta)[:, None] * u).T @ r)
    H[0:3, 6:9] = -wr * (RX.T @ T @ RY)
    H[3:6, 3:6] = wt * sum_d * _I3
    H[9:12, 9:12] = wt * sum_d * _I3
    H[3:6, 6:9] = wt * (RX.T @ np.tensordot(RA, d[:, None, None] * _skew(q), axes=([0, 1], [0, 1])) @ RY)
    H[3:6, 9:12] = -wt * (RX.T @ np.einsum("n,nij->ji", d, RA) @ RY)
    dq = d[:, None] * q
    H[6:9, 6:9] += wt * (RY.T @ (float(np.sum(dq * q)) * _I3 - dq.T @ q) @ RY)
    H[6:9, 9:12] = wt * (RY.T @ _skew(dq.sum(axis=0)) @ RY)
    Hw = np.triu(H) + np.triu(H, 1).T  # mirror the upper blocks filled above
    g = g_rot + g_trans
    Hm = _profile_hessian(Hw, np.stack([g_rot, g_trans]), W, m, scale) if mode == "profile" else Hw
    return g, Hm, Hw, F, ew


def model_at(P: Pairs, X: np.ndarray, Y: np.ndarray, e: np.ndarray, W: Whitening, mode: str, loss: str,
             c: float, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """The local model at (X, Y): `model_sigmas` for per-group sigmas and m >= BLOCKS_MIN_PAIRS,
    else `_model` with the explicit Jacobian (fewer numpy calls: faster for small m)."""
    if W.L is None and P.m >= BLOCKS_MIN_PAIRS:
        return model_sigmas(P, X, Y, e, W, mode, loss, c, scale)
    return _model(e, jacobian(P, X, Y, e), W, mode, loss, c, scale)


def levenberg_marquardt(P: Pairs, X: np.ndarray, Y: np.ndarray, W: Whitening | None, loss: str,
                        c: float, max_iter: int, tol: float, scale: float,
                        estimate: str = "profile") -> LMResult:
    """Minimise the objective over (X, Y) from (X, Y) by Levenberg-Marquardt.

    Weights (`mode_of`): W given ("fixed"): F under W. W None with least squares ("profile"): the
    profile likelihood L of `objective`, weights = RMS of the current residuals; with fewer than
    PROFILE_MIN_PAIRS pairs ("initial"): F under the RMS weights of the start. W None with a
    robust loss ("irls"): F, with median-based scales re-estimated after every accepted step;
    convergence then also requires that they changed by at most WEIGHT_TOL (relative), a fixed
    point of estimate + minimise. Every accepted step decreases the objective (under the current
    weights for "irls"); Marquardt's damping lam * diag(Hw) keeps the method invariant to the
    units of the parameters. Converged: the decrease predicted by the Gauss-Newton step is below
    tol * F; that last (tiny) step is then taken without testing the objective, whose rounding
    is larger than the change.
    """
    mode = mode_of(W, loss, P.m, estimate)
    e0 = e = residuals(P, X, Y)
    if mode == "profile":  # the objective (carried along with e: each point is evaluated once) and its weights
        value, W = objective(e, None, mode, loss, c, scale)
    elif mode != "fixed":
        W = estimate_sigmas(e, scale, robust=loss != "linear")
    weight_change = np.inf if mode == "irls" else 0.0
    lam, iterations, converged, unjudged = 0.0, 0, False, 0
    while True:
        g, H, Hw, F, _ = model_at(P, X, Y, e, W, mode, loss, c, scale)
        if mode != "profile":
            value = F
        step_gn = _newton_step(H, g)
        decrement = -0.5 * float(g @ step_gn)  # objective decrease predicted by the Gauss-Newton step
        if decrement <= tol * F or F == 0.0:
            if decrement > 0.0:
                # The remaining Gauss-Newton step changes the objective by less than its rounding,
                # so it can no longer be judged; it is tiny and taken as is: it removes the last
                # ~1e-7 (relative to the errors) that tol leaves, so the answer does not depend
                # on the path taken (unit invariance to ~1e-14, one answer from every start).
                X, Y = retract(X, step_gn[:6]), retract(Y, step_gn[6:])
                e = residuals(P, X, Y)
                if mode == "profile":
                    value, W = objective(e, None, mode, loss, c, scale)
            if weight_change <= WEIGHT_TOL:
                converged = True
                break
            new = estimate_sigmas(e, scale, robust=True)  # optimal for these weights: move them
            weight_change, W = _relative_change(new, W), new
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
            X, Y = retract(X, step_gn[:6]), retract(Y, step_gn[6:])
            e = residuals(P, X, Y)
            if mode == "profile":
                value, W = objective(e, None, mode, loss, c, scale)
            elif mode == "irls":
                new = estimate_sigmas(e, scale, robust=True)
                weight_change, W = _relative_change(new, W), new
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
            Xn, Yn = retract(X, step[:6]), retract(Y, step[6:])
            en = residuals(P, Xn, Yn)
            value_n, Wn = objective(en, W, mode, loss, c, scale)
            if value_n < value and predicted > 0:
                gain = (value - value_n) / predicted
                if gain > 0.75:
                    lam = 0.0 if lam < 1e-9 else lam / 3.0
                elif gain < 0.25:
                    lam = max(2.0 * lam, MIN_DAMPING)
                X, Y, e, W, value = Xn, Yn, en, Wn, value_n
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
            weight_change, W = _relative_change(new, W), new
            continue
        if not accepted:  # out of iterations
            break
        if mode == "irls":
            new = estimate_sigmas(e, scale, robust=True)
            weight_change, W = _relative_change(new, W), new
    _, _, Hw, F, _ = model_at(P, X, Y, e, W, "fixed", loss, c, scale)
    if mode != "profile":
        value = F
    return LMResult(X, Y, W, value, iterations, converged, Hw, W.residual(e), e, mode, e0)


def _newton_step(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """-H^-1 g for the (12, 12) Gauss-Newton matrix H (positive definite; damped or not), by
    LAPACK's Cholesky solver called directly: np.linalg.solve costs ~5x more at this size, which
    shows at small m. DegenerateDataError when H is not positive definite."""
    _, x, info = lapack.dposv(H, g)
    if info != 0:
        raise DegenerateDataError("the refinement's normal matrix is singular: the data do not determine X and Y")
    return -x


def _relative_change(new: Whitening, old: Whitening) -> float:
    return max(abs(new.sigma_rot / old.sigma_rot - 1.0), abs(new.sigma_trans / old.sigma_trans - 1.0))


# --------------------------------------------------------------------------- solver

#: the start when so3-sdp, the default start, is unavailable or fails
FALLBACK_INIT = "kron-lstsq"


def default_init() -> str:
    """"so3-sdp" when registered and available here, else "kron-lstsq"."""
    from handeye.registry import get_registry

    registry = get_registry()
    spec = registry.solvers.get("so3-sdp", {}).get("axyb")
    if spec is not None and spec.unavailable_reason(spec.default_backend) is None:
        return "so3-sdp"
    return FALLBACK_INIT


def start(data: AXYBData, requested: str | None) -> tuple[str, np.ndarray, np.ndarray, Status, dict[str, Any], list[str]]:
    """The starting poses: (solver name, X0, Y0, its status, its diagnostics, warnings).

    `requested` None means the default start (`default_init`); when that solve fails
    (SolverError, or its backend turns out unavailable) the closed form FALLBACK_INIT is used and
    a warning says so. A start the user asked for by name is never replaced: its failure raises.
    """
    name = requested or default_init()
    try:
        return (name, *run_init(name, data), [])
    except (SolverError, BackendUnavailableError) as exc:
        if requested is not None or name == FALLBACK_INIT:
            raise
        warning = f"the start solver {name!r} failed ({exc}); started from {FALLBACK_INIT!r}"
        return (FALLBACK_INIT, *run_init(FALLBACK_INIT, data), [warning])


def run_init(name: str, data: AXYBData) -> tuple[np.ndarray, np.ndarray, Status, dict[str, Any]]:
    """Run registered solver `name` (default backend and options) on validated data, as handeye.solve does."""
    from handeye.api import _checked_pose
    from handeye.options import parse_options
    from handeye.registry import get_registry

    if name in RECURSIVE:
        raise InputError(f"init solver {name!r} would call refine recursively")
    spec = get_registry().solver(name, "axyb")  # UnknownPluginError listing the solvers
    reason = spec.unavailable_reason(spec.default_backend)
    if reason:
        raise BackendUnavailableError(f"init solver {name!r} is unavailable: {reason}")
    output = spec.run(data, parse_options(spec.options, {}, name), spec.default_backend)
    X, Y = (_checked_pose(output.unknowns, k, name) for k in ("X", "Y"))
    return X, Y, Status(output.status), dict(output.diagnostics)


def weights_of(options: Options, m: int) -> tuple[Whitening | None, str]:
    """The stated whitening (None when to be estimated) and its kind."""
    if options.covariance is not None:
        L = options.covariance
        if L.ndim == 3 and len(L) != m:
            raise InputError(f"option covariance has {len(L)} blocks of 6x6 for {m} pairs")
        return Whitening(L=L), "covariance"
    if options.sigma_rot is not None:
        return Whitening(float(options.sigma_rot), float(options.sigma_trans)), "stated"
    return None, "estimated"


def refine(data: AXYBData, X0: np.ndarray, Y0: np.ndarray, options: Options) -> tuple[np.ndarray, np.ndarray, Status, dict[str, Any]]:
    """Refine (X0, Y0) on `data` with `options` (the init options are not used here)."""
    P = Pairs.of(data)
    loss, c, scale = options.loss, float(options.loss_scale), data.translation_scale
    W0, weights = weights_of(options, data.m)
    res = levenberg_marquardt(P, X0, Y0, W0, loss, c, int(options.max_iter), options.tol, scale, options.estimate)
    iterations = res.iterations
    # The objective at the start; for "irls" under the final weights. Fixed weights and the
    # profile likelihood are monotone; with "irls" the weights moved on the way, so a start that
    # is better under the final weights (another basin) is refined under them too and the better
    # answer kept.
    initial_cost = objective(res.e0, res.W, res.mode, loss, c, scale)[0]
    if res.mode == "irls" and initial_cost < res.cost:
        again = levenberg_marquardt(P, X0, Y0, res.W, loss, c, int(options.max_iter), options.tol, scale)
        iterations += again.iterations
        if again.cost < res.cost:
            res = again
    X, Y = res.X, res.Y

    _, cov, info = lapack.dposv(res.H, _I12)  # the inverse, by Cholesky (as the steps)
    if info != 0:
        raise DegenerateDataError("the refinement's normal matrix is singular at the solution")
    cov = 0.5 * (cov + cov.T)
    s = (res.ew * res.ew).sum(axis=1)
    _, drho = loss_terms(s, loss, c)
    dof = 6.0 * float(drho.sum()) - 12.0
    variance_factor = float((drho * s).sum()) / dof if dof > 0 else float("nan")
    if weights == "estimated":
        if not math.isfinite(variance_factor):
            raise DegenerateDataError("too few pairs to estimate the noise and the covariance")
        cov = cov * variance_factor
    var = cov.diagonal().tolist()
    sum_rot, sum_trans = _sums_of_squares(res.e)
    diagnostics: dict[str, Any] = {
        "iterations": iterations,
        "initial_cost": initial_cost,
        "final_cost": res.cost,
        "converged": res.converged,
        "weights": weights,
        "weight_mode": res.mode,
        "objective": {"fixed": "F = 1/2 sum rho(|whitened residual|^2), stated weights",
                      "initial": "F = 1/2 sum rho(|whitened residual|^2), weights from the start's residuals "
                                 f"(estimate='initial', or fewer than {PROFILE_MIN_PAIRS} pairs, where the "
                                 "profile likelihood is unbounded)",
                      "profile": "negative log-likelihood with sigma_rot, sigma_trans estimated (profile)",
                      "irls": "F = 1/2 sum rho(|whitened residual|^2), median-based scales at a fixed point"}[res.mode],
        "loss": loss,
        "loss_scale": c,
        "variance_factor": variance_factor,
        "covariance": {"X": cov[:6, :6].tolist(), "Y": cov[6:, 6:].tolist()},
        "covariance_XY": cov.tolist(),
        "std": {k: {"rotation": math.sqrt(sum(var[o:o + 3])), "translation": math.sqrt(sum(var[o + 3:o + 6]))}
                for k, o in (("X", 0), ("Y", 6))},
        "residual_rms": {"rotation": math.sqrt(sum_rot / res.e.shape[0]),
                         "translation": math.sqrt(sum_trans / res.e.shape[0])},
    }
    if res.W.L is None:
        diagnostics["sigma_rot"], diagnostics["sigma_trans"] = res.W.sigma_rot, res.W.sigma_trans
    status = Status.OPTIMAL if res.converged else Status.NOT_CONVERGED
    if not res.converged:
        diagnostics["warnings"] = [
            (f"refine did not converge within max_iter={options.max_iter} iterations; the answer "
             "is the last iterate")
        ]
    return X, Y, status, diagnostics


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    if options.init_X is not None:
        X0, Y0, init_name, init_status, init_diag, warnings = options.init_X, options.init_Y, "given", None, {}, []
    else:
        init_name, X0, Y0, init_status, init_diag, warnings = start(data, options.init)
    X, Y, status, diagnostics = refine(data, X0, Y0, options)
    diagnostics["warnings"] = warnings + diagnostics.get("warnings", [])
    diagnostics["init"] = init_name
    if init_status is not None:
        diagnostics["compile_seconds"] = float(init_diag.get("compile_seconds", 0.0))
        diagnostics["init_status"] = str(init_status)
        diagnostics["init_diagnostics"] = jsonable(init_diag)
    return SolverOutput(unknowns={"X": X, "Y": Y}, status=status, diagnostics=diagnostics)


SPEC = SolverSpec(
    name="refine",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="maximum-likelihood refinement on SE(3) x SE(3) (Levenberg-Marquardt, robust losses)",
    citation="geometric ML refinement of A_i X = Y B_i; cf. Strobl & Hirzinger, IROS 2006; Pan et al., T-ASE 2022 (init)",
    unit_invariant=True,
    exact=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
