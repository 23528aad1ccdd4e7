"""Rigid-motion helpers on plain numpy arrays.

Poses are 4x4 homogeneous matrices, stacked as arrays of shape (m, 4, 4); rotations are (m, 3, 3);
rotation vectors (axis * angle, radians) are (m, 3). Every function is vectorised over the leading
axis and returns new arrays (inputs are never modified).

Quaternions follow scipy's convention: Hamilton, scalar LAST, ``(x, y, z, w)``, unless a function
says otherwise.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from handeye.geometry.linalg import det, einsum, svd

Array = NDArray[np.float64]

#: Largest deviation |R^T R - I| (max abs entry) accepted for a rotation block of input data.
ORTHONORMALITY_TOL = 1e-6


def skew(v: ArrayLike) -> Array:
    """Skew-symmetric matrices [v]_x with [v]_x w = v x w.  v: (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def vee(S: ArrayLike) -> Array:
    """Inverse of `skew` on the skew part of S.  S: (..., 3, 3) -> (..., 3)."""
    S = np.asarray(S, dtype=float)
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        axis=-1,
    )


def make_pose(R: ArrayLike, t: ArrayLike) -> Array:
    """Homogeneous matrices from rotations (..., 3, 3) and translations (..., 3) -> (..., 4, 4)."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    out = np.zeros(R.shape[:-2] + (4, 4))
    out[..., :3, :3] = R
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def inverse(T: ArrayLike) -> Array:
    """Inverse of rigid motions T: (..., 4, 4), using R^T (exact for SE(3) input)."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_pose(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def so3_exp(w: ArrayLike) -> Array:
    """Rotation matrices exp([w]_x) from rotation vectors w: (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    flat = Rotation.from_rotvec(w.reshape(-1, 3)).as_matrix()
    return flat.reshape(w.shape[:-1] + (3, 3))


def so3_log(R: ArrayLike) -> Array:
    """Rotation vectors of rotations R: (..., 3, 3) -> (..., 3), angle in [0, pi]."""
    R = np.asarray(R, dtype=float)
    flat = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec()
    return flat.reshape(R.shape[:-2] + (3,))


def rotation_angle(R: ArrayLike) -> Array:
    """Angle (radians, in [0, pi]) of rotations R: (..., 3, 3).

    Computed as atan2(|vee(R - R^T)|, tr(R) - 1), which is accurate for tiny angles (where
    arccos((tr R - 1) / 2) loses half the digits) and near pi alike.
    """
    R = np.asarray(R, dtype=float)
    sin_part = np.linalg.norm(2.0 * vee(R), axis=-1)  # = 2 sin(theta)
    cos_part = np.trace(R, axis1=-2, axis2=-1) - 1.0  # = 2 cos(theta)
    return np.arctan2(sin_part, cos_part)


def project_to_so3(M: ArrayLike) -> Array:
    """Nearest rotation (Frobenius norm) to each M: (..., 3, 3), by SVD with det = +1."""
    M = np.asarray(M, dtype=float)
    U, _, Vt = svd(M)
    d = np.sign(det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    U[..., :, 2] *= d[..., None]  # U is svd's own array
    return U @ Vt


def gram_schmidt(M: ArrayLike) -> Array:
    """Orthonormalise the columns of M: (..., 3, 3) in order (classical Gram-Schmidt).

    This is the "Schmidt orthogonalization" the paper applies after eq. 14. The third column is
    taken as c1 x c2 so that the result is a proper rotation (det = +1) even when the input has
    det < 0; for an input with det > 0 that equals orthogonalising the third column.
    """
    M = np.asarray(M, dtype=float)
    c1 = M[..., :, 0] / np.linalg.norm(M[..., :, 0], axis=-1, keepdims=True)
    c2 = M[..., :, 1] - np.sum(c1 * M[..., :, 1], axis=-1, keepdims=True) * c1
    c2 = c2 / np.linalg.norm(c2, axis=-1, keepdims=True)
    c3 = np.cross(c1, c2)
    return np.stack([c1, c2, c3], axis=-1)


def gram(R: ArrayLike) -> Array:
    """R^T R for R: (..., 3, 3), from the six distinct dot products of the columns (a batched
    3x3 matmul is 2-3x slower on large stacks, where this dominates validating the data). Up to
    _SMALL_STACK matrices one einsum, which sums the same products in the same order (the same
    numbers, measured; 4x faster at 16, equal at 128, 3x slower at 1e5)."""
    R = np.asarray(R, dtype=float)
    if R.ndim == 3 and len(R) <= _SMALL_STACK:
        return einsum("nki,nkj->nij", R, R)
    c0, c1, c2 = R[..., 0], R[..., 1], R[..., 2]
    dot = functools.partial(np.einsum, "...i,...i->...")
    d00, d11, d22, d01, d02, d12 = dot(c0, c0), dot(c1, c1), dot(c2, c2), dot(c0, c1), dot(c0, c2), dot(c1, c2)
    return np.stack([d00, d01, d02, d01, d11, d12, d02, d12, d22], axis=-1).reshape(R.shape)


#: column pairs (i, j), i <= j, of the six distinct entries of R^T R, and those entries of I
_GRAM_I, _GRAM_J = np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2])
_GRAM_EYE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
#: up to this many matrices `orthonormality_error` gathers the column pairs in one indexing
#: (fewer numpy calls: 4x faster for one matrix); above, the strided gather costs more than `gram`
_SMALL_STACK = 128


def orthonormality_error(R: ArrayLike) -> Array:
    """Max abs entry of R^T R - I for R: (..., 3, 3) -> (...)."""
    R = np.asarray(R, dtype=float)
    if R.size <= 9 * _SMALL_STACK:
        return np.abs((R[..., _GRAM_I] * R[..., _GRAM_J]).sum(axis=-2) - _GRAM_EYE).max(axis=-1)
    return np.max(np.abs(gram(R) - np.eye(3)), axis=(-2, -1))


def random_rotations(n: int, rng: np.random.Generator) -> Array:
    """n rotations uniformly distributed on SO(3): (n, 3, 3)."""
    return Rotation.random(n, random_state=rng).as_matrix()


def random_poses(n: int, rng: np.random.Generator, translation_scale: float = 1.0) -> Array:
    """n random rigid motions: uniform rotation, Gaussian translation of std translation_scale."""
    return make_pose(random_rotations(n, rng), translation_scale * rng.standard_normal((n, 3)))


def quat_from_matrix(R: ArrayLike) -> Array:
    """Unit quaternions (x, y, z, w) of rotations R: (..., 3, 3) -> (..., 4)."""
    R = np.asarray(R, dtype=float)
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[:-2] + (4,))


def largest_relative_angle(R: ArrayLike, chunk: int = 2048) -> float:
    """The largest rotation angle (rad) between any two of the rotations R: (n, 3, 3).

    From unit quaternions: the angle between q_i and q_j is 2 arccos |q_i . q_j|, so the largest
    angle is that of the smallest |Q Q^T| entry, taken `chunk` rows at a time (memory grows
    with n, not n^2: a 12,000-station recording's 9 n^2 products were 10 GB)."""
    q = quat_from_matrix(np.asarray(R, dtype=float))
    if len(q) < 2:
        return 0.0
    smallest = 1.0
    for start in range(0, len(q), chunk):
        smallest = min(smallest, float(np.abs(q[start:start + chunk] @ q.T).min()))
    return float(2.0 * np.arccos(np.clip(smallest, 0.0, 1.0)))


def matrix_from_quat(q: ArrayLike) -> Array:
    """Rotations from quaternions (x, y, z, w): (..., 4) -> (..., 3, 3) (normalised first)."""
    q = np.asarray(q, dtype=float)
    return Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))
