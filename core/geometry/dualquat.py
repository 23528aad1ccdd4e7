"""Quaternion and dual-quaternion algebra for the dual-quaternion solver (paper Sec. III.C).

Convention here (unlike `handeye.geometry.se3`, which follows scipy): Hamilton quaternions with the scalar
FIRST, ``q = (q0, qx, qy, qz)``, as in the paper's eq. 25 and Daniilidis (1999). Every function is
vectorised over leading axes and returns new arrays.

A rigid motion T = (R, t) is the unit dual quaternion q + eps q' with q the rotation's quaternion
and q' = 1/2 (0, t) q (eq. 23); q' is orthogonal to q (q . q' = 0) and t = 2 q' q*. Products of
dual quaternions follow from eps^2 = 0:

    (a + eps a')(b + eps b') = a b + eps (a b' + a' b).

Quaternion products are linear in either factor (eq. 25): ``a b = Q_L(a) b = Q_R(b) a`` with,
for a = (a0, v), Omega(v) = [v]_x,

    Q_L(a) = [[a0, -v^T], [v, a0 I + [v]_x]],    Q_R(b) = [[b0, -w^T], [w, b0 I - [w]_x]].

(The paper prints the first row of Q_L as [q0, +q^T], a sign typo: the scalar part of a b is
a0 b0 - v . w. The tests check both identities on random quaternions.)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from handeye.geometry.se3 import Array, make_pose, matrix_from_quat

#: Q_L(q) = q[_L_IDX] * _L_SIGN and Q_R(q) = q[_R_IDX] * _R_SIGN (entries of eq. 25 written out).
_L_IDX = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_L_SIGN = np.array([[1, -1, -1, -1], [1, 1, -1, 1], [1, 1, 1, -1], [1, -1, 1, 1]], dtype=float)
_R_IDX = _L_IDX
_R_SIGN = np.array([[1, -1, -1, -1], [1, 1, 1, -1], [1, -1, 1, 1], [1, 1, -1, 1]], dtype=float)


def quat_from_rotation(R: ArrayLike) -> Array:
    """Unit quaternions (q0, qx, qy, qz) of rotations R: (..., 3, 3) -> (..., 4), sign with q0 >= 0.

    Shepperd's method, vectorised: of the four expressions 4 q_k^2 (from the trace and the
    diagonal) the largest is used as the divisor, so no component is taken from a small,
    cancellation-prone number; the result is normalised (inputs orthonormal only to ~1e-6 give
    the quaternion of a nearby rotation, as scipy's `from_matrix` does).
    """
    R = np.asarray(R, dtype=float)
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    d0, d1, d2 = r21 - r12, r02 - r20, r10 - r01
    s01, s02, s12 = r01 + r10, r02 + r20, r12 + r21
    t = np.stack([1 + r00 + r11 + r22, 1 + r00 - r11 - r22, 1 - r00 + r11 - r22, 1 - r00 - r11 + r22], -1)
    candidates = np.stack([  # row k: 4 q_k q (up to the positive factor), for divisor k
        np.stack([t[..., 0], d0, d1, d2], -1),
        np.stack([d0, t[..., 1], s01, s02], -1),
        np.stack([d1, s01, t[..., 2], s12], -1),
        np.stack([d2, s02, s12, t[..., 3]], -1),
    ], -2)
    k = np.argmax(t, axis=-1)[..., None, None]
    q = np.take_along_axis(candidates, np.broadcast_to(k, k.shape[:-1] + (4,)), axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rotation_from_quat(q: ArrayLike) -> Array:
    """Rotations of quaternions (q0, qx, qy, qz): (..., 4) -> (..., 3, 3); q is normalised first."""
    q = np.asarray(q, dtype=float)
    return matrix_from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1))


def conjugate(q: ArrayLike) -> Array:
    """q* = (q0, -v): (..., 4) -> (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def q_left(q: ArrayLike) -> Array:
    """Q_L(q): (..., 4) -> (..., 4, 4) with q p = Q_L(q) p (eq. 25)."""
    return np.asarray(q, dtype=float)[..., _L_IDX] * _L_SIGN


def q_right(q: ArrayLike) -> Array:
    """Q_R(q): (..., 4) -> (..., 4, 4) with p q = Q_R(q) p (eq. 25)."""
    return np.asarray(q, dtype=float)[..., _R_IDX] * _R_SIGN


def quat_multiply(a: ArrayLike, b: ArrayLike) -> Array:
    """Hamilton product a b: (..., 4) x (..., 4) -> (..., 4) (broadcasting)."""
    return np.einsum("...ij,...j->...i", q_left(a), np.asarray(b, dtype=float))


def dual_quat_from_pose(T: ArrayLike) -> tuple[Array, Array]:
    """(q, q') of rigid motions T: (..., 4, 4): q: (..., 4) with q0 >= 0, q' = 1/2 (0, t) q."""
    T = np.asarray(T, dtype=float)
    q = quat_from_rotation(T[..., :3, :3])
    t = np.concatenate([np.zeros(T.shape[:-2] + (1,)), T[..., :3, 3]], axis=-1)
    return q, 0.5 * quat_multiply(t, q)


def pose_from_dual_quat(q: ArrayLike, qd: ArrayLike) -> Array:
    """Rigid motions (..., 4, 4) from dual quaternions (q, q') (..., 4) each.

    q need not be unit: it is normalised and q' divided by the same norm; t is the vector part of
    2 q' q* (whose scalar part 2 q . q' vanishes for an exact unit dual quaternion and is dropped).
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    q, qd = q / norm, qd / norm
    t = 2.0 * quat_multiply(qd, conjugate(q))[..., 1:]
    return make_pose(rotation_from_quat(q), t)
