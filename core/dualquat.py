"""Quaternion and dual-quaternion algebra for the dual-quaternion solver (paper Sec. III.C).

Convention here (unlike `handeye.se3`, which follows scipy): Hamilton quaternions with the scalar
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

from .se3 import Array, make_pose, matrix_from_quat, quat_from_matrix, skew


def quat_from_rotation(R: ArrayLike) -> Array:
    """Unit quaternions (q0, qx, qy, qz) of rotations R: (..., 3, 3) -> (..., 4), sign with q0 >= 0."""
    xyzw = quat_from_matrix(R)
    q = np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)
    return np.where(q[..., :1] < 0, -q, q)


def rotation_from_quat(q: ArrayLike) -> Array:
    """Rotations of quaternions (q0, qx, qy, qz): (..., 4) -> (..., 3, 3); q is normalised first."""
    q = np.asarray(q, dtype=float)
    return matrix_from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1))


def conjugate(q: ArrayLike) -> Array:
    """q* = (q0, -v): (..., 4) -> (..., 4)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., :1], -q[..., 1:]], axis=-1)


def q_left(q: ArrayLike) -> Array:
    """Q_L(q): (..., 4) -> (..., 4, 4) with q p = Q_L(q) p (eq. 25)."""
    q = np.asarray(q, dtype=float)
    out = np.empty(q.shape[:-1] + (4, 4))
    out[..., 0, 0] = q[..., 0]
    out[..., 0, 1:] = -q[..., 1:]
    out[..., 1:, 0] = q[..., 1:]
    out[..., 1:, 1:] = q[..., 0, None, None] * np.eye(3) + skew(q[..., 1:])
    return out


def q_right(q: ArrayLike) -> Array:
    """Q_R(q): (..., 4) -> (..., 4, 4) with p q = Q_R(q) p (eq. 25)."""
    q = np.asarray(q, dtype=float)
    out = np.empty(q.shape[:-1] + (4, 4))
    out[..., 0, 0] = q[..., 0]
    out[..., 0, 1:] = -q[..., 1:]
    out[..., 1:, 0] = q[..., 1:]
    out[..., 1:, 1:] = q[..., 0, None, None] * np.eye(3) - skew(q[..., 1:])
    return out


def quat_multiply(a: ArrayLike, b: ArrayLike) -> Array:
    """Hamilton product a b: (..., 4) x (..., 4) -> (..., 4) (broadcasting)."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    out = np.empty(a.shape)
    out[..., 0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3
    out[..., 1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2
    out[..., 2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1
    out[..., 3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0
    return out


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
