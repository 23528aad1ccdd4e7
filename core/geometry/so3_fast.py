"""Fast SO(3) helpers for iterative solvers: log of a stack, exp of one vector, skew matrices and
the inverse Jacobians of SO(3), in plain numpy.

`handeye.geometry.se3` holds the general helpers (scipy's `Rotation` behind so3_exp / so3_log). These are
the versions an inner loop calls many times on small stacks (`handeye.estimation.nlls`, and through it
`refine` for every problem): at the usual m (tens of pairs) the cost of an iteration is the
number of numpy calls (1-3 us each), not arithmetic, so 3x3 blocks are built from (m, 9) rows
with one product against a constant (`_SKEW`, `_LOG_MAP`) instead of entry-by-entry
assignments, and the exp of one rotation vector is computed in Python floats. `quat` (Shepperd's
quaternions from one product) and `log_from_quat` give the quaternions and rotation vectors of
a whole data set (``axxb``'s validation and its quaternion solvers) in ~20 numpy calls. Inputs
are finite float arrays (no validation here).
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from handeye.geometry.linalg import einsum
from handeye.geometry.se3 import so3_log

#: v @ _SKEW = [v]_x flattened row-major: (..., 3) -> (..., 9)
_SKEW = np.zeros((3, 9))
_SKEW[2, 1], _SKEW[1, 2], _SKEW[2, 3], _SKEW[0, 5], _SKEW[1, 6], _SKEW[0, 7] = -1.0, 1.0, 1.0, -1.0, -1.0, 1.0
#: the 3x3 identity
I3 = np.eye(3)
#: smallest normal float: keeps theta / sin(theta) finite at theta = 0
_TINY = np.finfo(float).tiny
#: R.reshape(m, 9) @ _LOG_MAP = [vee(R - R^T) / 2, tr(R) / 2]: (m, 4), the parts of R that its
#: rotation vector depends on (sin(theta) axis, and (1 + 2 cos theta) / 2).
_LOG_MAP = np.zeros((9, 4))
_LOG_MAP[7, 0], _LOG_MAP[5, 0], _LOG_MAP[2, 1], _LOG_MAP[6, 1], _LOG_MAP[3, 2], _LOG_MAP[1, 2] = 0.5, -0.5, 0.5, -0.5, 0.5, -0.5
_LOG_MAP[[0, 4, 8], 3] = 0.5
for _array in (_SKEW, I3, _LOG_MAP):
    _array.setflags(write=False)
del _array


def log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors of R: (m, 3, 3) -> (m, 3), angle in [0, pi].

    theta = atan2(|s|, (tr R - 1) / 2) with s = vee(R - R^T) / 2 = sin(theta) axis (one product
    with `_LOG_MAP`), then phi = theta / |s| s (at small angles atan2 returns |s| itself to
    rounding, so the ratio is accurate down to 0 and needs no series; s = 0 gives phi = 0);
    within 1e-3 rad of pi, where s loses the axis, scipy's quaternion route (`se3.so3_log`) is
    used for those rotations only. At m = 16 this is ~20x cheaper than scipy's Rotation.
    """
    parts = R.reshape(len(R), 9) @ _LOG_MAP
    s = parts[:, :3]
    x, y, z = parts[:, 0], parts[:, 1], parts[:, 2]
    sin = np.sqrt(x * x + y * y + z * z)  # the bits of (s * s).sum(axis=1), 13x faster at m = 1e5
    theta = np.arctan2(sin, parts[:, 3] - 0.5)
    phi = (theta / np.maximum(sin, _TINY))[:, None] * s
    if len(theta) and theta.max() > np.pi - 1e-3:
        near_pi = theta > np.pi - 1e-3
        phi[near_pi] = so3_log(R[near_pi])
    return phi


def consecutive_logs(T: np.ndarray, moving: bool = True) -> np.ndarray:
    """Rotation vectors (m-1, 3) of the consecutive motions of a pose stack T: (m, 4, 4): in the
    moving frame, R_k^T R_k+1 (a robot's flange, for flange poses), or (moving=False) in the fixed
    frame, R_k+1 R_k^T (its base).

    A read-only stack (validated data: the planar check, the self-check's invariants and axes and
    kron-lstsq's planar rows all ask for the same ones, up to seven times a solve) is computed
    once: the result (read-only) is kept for the last `_LOGS_KEPT` stacks while they live."""
    key = (id(T), bool(moving))
    if not T.flags.writeable:
        kept = _LOGS.get(key)
        if kept is not None and kept[0]() is T:
            return kept[1]
    R = T[:, :3, :3]
    if moving:
        phi = log(np.swapaxes(R[:-1], 1, 2) @ R[1:])
    else:  # R_k+1 R_k^T = R_k (R_k^T R_k+1) R_k^T: the moving frame's rotation vector, turned by R_k
        phi = einsum("nij,nj->ni", R[:-1], consecutive_logs(T, moving=True))
    if not T.flags.writeable:
        phi.setflags(write=False)
        _LOGS.pop(key, None)
        _LOGS[key] = (weakref.ref(T), phi)
        try:
            while len(_LOGS) > _LOGS_KEPT:
                _LOGS.pop(next(iter(_LOGS)), None)
        except (RuntimeError, StopIteration):  # another thread trimmed it meanwhile
            pass
    return phi


#: `consecutive_logs` of the last few read-only stacks: id -> (weak reference to the stack, logs)
_LOGS: dict[tuple[int, bool], tuple[weakref.ref, np.ndarray]] = {}
_LOGS_KEPT = 8


def exp(w: np.ndarray) -> np.ndarray:
    """Rotation exp([w]_x) of one rotation vector w: (3,) -> (3, 3): Rodrigues' I + a [w]_x +
    b [w]_x^2 with a = sin(theta) / theta, b = (1 - cos theta) / theta^2 (series below 1e-6
    rad) and [w]_x^2 = w w^T - theta^2 I, entry by entry in Python floats (cheaper than numpy
    calls for one 3x3)."""
    x, y, z = w.tolist()
    theta2 = x * x + y * y + z * z
    theta = math.sqrt(theta2)
    if theta < 1e-6:
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta2
    ax, ay, az, bx, by, bz = a * x, a * y, a * z, b * x, b * y, b * z
    return np.array([1.0 - by * y - bz * z, bx * y - az, bx * z + ay,  # one flat list: ~0.3 us less
                     bx * y + az, 1.0 - bx * x - bz * z, by * z - ax,
                     bx * z - ay, by * z + ax, 1.0 - bx * x - by * y]).reshape(3, 3)


def skew(v: np.ndarray) -> np.ndarray:
    """[v]_x: (..., 3) -> (..., 3, 3) by one product with a constant (finite float input; the
    general `handeye.geometry.se3.skew` takes any array-like)."""
    return (v @ _SKEW).reshape(v.shape[:-1] + (3, 3))


def jl_products(theta2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(beta, gamma, delta) at theta^2 = |r|^2, the coefficients of the products of the inverse
    Jacobians of SO(3) that closed-form normal equations need: Jl^-T Jl^-1 = Jl^-1 Jl^-T =
    I + beta [r]_x^2 and Jl^-T Jl^-T = I + gamma [r]_x + delta [r]_x^2, with beta = 2c - 1/4 -
    c^2 theta^2, gamma = 1 - c theta^2, delta = 1/4 + 2c - c^2 theta^2 (c: `jl_coefficient`)."""
    c = jl_coefficient(theta2)
    return 2.0 * c - 0.25 - c * c * theta2, 1.0 - c * theta2, 0.25 + 2.0 * c - c * c * theta2


def jl_coefficient(theta2: np.ndarray) -> np.ndarray:
    """c(theta) = 1/theta^2 - (1 + cos theta) / (2 theta sin theta) = (1 - (theta/2) cot(theta/2)) /
    theta^2 at theta^2 = |r|^2: (m,), the coefficient of [r]_x^2 in the inverse Jacobians of SO(3)
    (`inverse_jacobians`). When every theta < 0.1 rad (the usual case: residual rotations) its
    Taylor series 1/12 + theta^2/720 + theta^4/30240 + theta^6/1209600, exact to rounding there
    (the closed form loses digits to cancellation at small angles) and fewer numpy calls; else the
    closed form, with 1/12 + theta^2/720 below 1e-4 rad."""
    if not len(theta2) or theta2.max() < 0.01:
        return ((theta2 / 1209600.0 + 1.0 / 30240.0) * theta2 + 1.0 / 720.0) * theta2 + 1.0 / 12.0
    theta = np.sqrt(theta2)
    small = theta < 1e-4
    ts = np.where(small, 1.0, theta)
    half = 0.5 * ts
    return np.where(small, 1.0 / 12.0 + theta2 / 720.0, (1.0 - half / np.tan(half)) / (ts * ts))


def inverse_jacobians(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse left and right Jacobians of SO(3) at rotation vectors r: (m, 3) -> two (m, 3, 3):
    Jl^-1(r) = I - [r]_x / 2 + c(theta) [r]_x^2 and Jr^-1(r) = Jl^-1(r)^T = I + [r]_x / 2 +
    c(theta) [r]_x^2 ([r]_x^2 = r r^T - theta^2 I; c of `jl_coefficient`).

    They linearise the log: log(exp([d]_x) exp([r]_x)) = r + Jl^-1(r) d and
    log(exp([r]_x) exp([d]_x)) = r + Jr^-1(r) d to first order in d.
    """
    K = skew(r)
    common = jl_coefficient((r * r).sum(axis=1))[:, None, None] * (K @ K) + I3
    half = 0.5 * K
    return common - half, common + half


#: R.reshape(m, 9) @ _QUAT_MAP + _QUAT_ONE: (m, 16), the four candidate rows of Shepperd's method
#: (row k: 4 q_k q for the divisor k, `handeye.geometry.dualquat.quat_from_rotation`) in one product:
#: diagonal terms 1 +- r00 +- r11 +- r22, off-diagonal sums and differences r_ij +- r_ji.
_QUAT_MAP = np.zeros((9, 16))
_QUAT_ONE = np.zeros(16)
for _k, _signs in enumerate(((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1))):
    _QUAT_ONE[5 * _k] = 1.0
    _QUAT_MAP[[0, 4, 8], 5 * _k] = _signs
for (_a, _b), (_i, _j, _sign) in {(0, 1): (7, 5, -1), (0, 2): (2, 6, -1), (0, 3): (3, 1, -1),  # d = r21 - r12, ...
                                  (1, 2): (1, 3, 1), (1, 3): (2, 6, 1), (2, 3): (5, 7, 1)}.items():  # s = r01 + r10, ...
    for _row, _col in ((_a, _b), (_b, _a)):
        _QUAT_MAP[_i, 4 * _row + _col], _QUAT_MAP[_j, 4 * _row + _col] = 1.0, _sign
for _array in (_QUAT_MAP, _QUAT_ONE):
    _array.setflags(write=False)
del _array, _k, _signs, _a, _b, _i, _j, _sign, _row, _col


def quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (q0, qx, qy, qz), scalar FIRST, with q0 >= 0, of R: (m, 3, 3) -> (m, 4).

    Shepperd's method exactly as `handeye.geometry.dualquat.quat_from_rotation` (the candidate with the
    largest of the four diagonal expressions, normalised), equal to it to rounding, with the 16
    candidate entries from one product with a constant (`_QUAT_MAP`): 3-10x fewer numpy calls.
    """
    m = len(R)
    cand = R.reshape(m, 9) @ _QUAT_MAP + _QUAT_ONE  # (m, 16): 4 candidate rows of 4 per rotation
    q = cand.reshape(4 * m, 4)[np.argmax(cand[:, ::5], axis=1) + np.arange(0, 4 * m, 4)]  # ::5: the diagonal
    q *= (np.where(q[:, 0] < 0, -1.0, 1.0) / np.sqrt(np.einsum("ni,ni->n", q, q)))[:, None]
    return q


def log_from_quat(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation vectors and angles of unit quaternions q: (m, 4) (scalar first, q0 >= 0) ->
    (m, 3), (m,): theta = 2 atan2(|v|, q0), phi = theta / |v| v (v = 0 gives phi = 0); accurate
    at every angle in [0, pi] (scipy's ``as_rotvec`` route)."""
    v = q[:, 1:]
    sin_half = np.sqrt((v * v).sum(axis=1))
    theta = 2.0 * np.arctan2(sin_half, q[:, 0])
    return (theta / np.maximum(sin_half, _TINY))[:, None] * v, theta
