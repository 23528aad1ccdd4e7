"""Linear algebra shared by solvers: the triangular factor of a tall stack of small blocks, the
median, and LAPACK's routines called directly on the small matrices of a solve (triangular solve,
Cholesky, symmetric eigenproblem, least squares, singular values, norms): the numbers numpy's and
scipy's wrappers give (measured bit for bit), without the wrappers' checks and dispatch, which at
these sizes cost more than the work."""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

#: np.einsum(subscripts, *operands) without its Python wrapper: the function np.einsum itself calls
#: when not asked to optimise (its default), so the same numbers; ~1 us less a call at the sizes
#: of a solve, ~30 calls a solve. Only for calls without ``optimize``.
try:
    from numpy._core.multiarray import c_einsum as einsum
except ImportError:  # another numpy's layout
    einsum = np.einsum
try:
    from numpy.linalg import _umath_linalg
except ImportError:  # another numpy's layout
    _umath_linalg = None
if _umath_linalg is not None and not all(hasattr(_umath_linalg, name) for name in
                                         ("solve1", "eigvalsh_lo", "eigh_lo", "svd_f", "det")):
    _umath_linalg = None  # another numpy's gufuncs: numpy's own functions instead


def triangular_factor(blocks: np.ndarray) -> np.ndarray:
    """R: (c, c) with R^T R = M^T M for the tall matrix M stacked from blocks: (m, r, c).

    Tree (tall-skinny) QR: the rows are cut into chunks of 8c rows, each chunk reduced to its c x c
    factor by one batched small QR, and the stacked factors reduced again the same way until one
    chunk remains. Backward stable like a QR of the whole (m r) x c matrix (M and R have the same
    singular values and right singular vectors to rounding). The small chunks matter on a shared
    machine: a LAPACK QR or SVD of a large tall matrix goes multi-threaded, and with busy cores
    that made it 5 to 80 times slower than single-threaded in our measurements, while
    chunks of <= 8c rows stay single-threaded. Needs m r >= c (R has min(m r, c) rows otherwise).
    """
    c = blocks.shape[-1]
    X = blocks.reshape(-1, c)
    per = 8 * c
    while len(X) > per:
        n = -(-len(X) // per)
        padded = np.zeros((n * per, c))
        padded[:len(X)] = X
        X = np.linalg.qr(padded.reshape(n, per, c), mode="r").reshape(-1, c)
    return np.linalg.qr(X, mode="r")


def frobenius_norm(M: np.ndarray) -> float:
    """|M|_F without overflow: scaled by max |M_ij| first (np.linalg.norm squares the entries and
    returns inf for finite entries above ~1e154). inf or nan only when M holds them."""
    peak = float(np.abs(M).max()) if M.size else 0.0
    if peak == 0.0 or not np.isfinite(peak):
        return peak
    return peak * vector_norm((M / peak).ravel(order="K"))  # np.linalg.norm's arithmetic (sqrt of the dot)


def median(x: np.ndarray) -> float:
    """The median of an array's values (the mean of the two middle values for an even count), as
    np.median: by one sort for up to 1000 values (~1 us against np.median's ~10 us for the few a
    self-check takes it of), by a partial sort (O(n)) beyond. NaN for an empty array."""
    x = np.asarray(x, dtype=float).ravel()
    n = len(x)
    if n == 0:
        return float("nan")
    middle = [(n - 1) // 2, n // 2]
    s = x.copy()  # x may be the caller's (ravel): sorted as np.sort and np.partition do, on a copy
    if n <= 1000:
        s.sort()
    else:
        s.partition(middle)
    return float(0.5 * (s[middle[0]] + s[middle[1]]))


def solve_triangular(a: np.ndarray, b: np.ndarray, lower: bool = False, trans: int = 0) -> np.ndarray:
    """x with a x = b (trans 0) or a^T x = b (trans 1), a: (n, n) triangular and finite, b: (n,)
    or (n, k), float64: scipy.linalg.solve_triangular's LAPACK call (dtrtrs, on a or, row-major,
    on a^T with the triangle and the transposition swapped, as scipy does: the same numbers) without
    its checks, which cost more than the solve at these sizes (~15 of ~20 us at 24 x 24).
    LinAlgError when a is singular."""
    if a.flags.f_contiguous:
        x, info = lapack.dtrtrs(a, b, lower=lower, trans=trans)
    else:
        x, info = lapack.dtrtrs(a.T, b, lower=not lower, trans=not trans)
    if info != 0:
        raise np.linalg.LinAlgError(f"singular matrix: resolution failed at diagonal {info - 1}")
    return x


def cholesky_upper(a: np.ndarray) -> np.ndarray:
    """The upper Cholesky factor R (R^T R = a) of a finite symmetric (n, n) float64 array:
    scipy.linalg.cholesky(a, lower=False)'s LAPACK call (dpotrf, the other triangle zeroed)
    without its checks (the same numbers). LinAlgError when a is not positive definite."""
    c, info = lapack.dpotrf(a, lower=0, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"{info}-th leading minor of the array is not positive definite")
    return c


def eigh(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (ascending) and eigenvectors of a finite symmetric (n, n) float64 S: LAPACK's
    dsyevd on the lower triangle called directly, the routine behind np.linalg.eigh (the same
    numbers, measured bit for bit; the vectors row-major as numpy's, so that products with them
    sum alike) without its wrapper (~15 us of ~60 at 18 x 18); np.linalg.eigh where it fails."""
    d, V, info = lapack.dsyevd(S, compute_v=1, lower=1)
    if info != 0:
        return np.linalg.eigh(S)
    return d, np.ascontiguousarray(V)


def _raising(message: str):
    """numpy.linalg's floating-point callback: a LAPACK failure flagged by the gufunc raises
    LinAlgError(message), as numpy's wrappers do."""
    def callback(err: str, flag: int) -> None:
        raise np.linalg.LinAlgError(message)
    return callback


_SINGULAR = _raising("Singular matrix")
_EIGH_FAILED = _raising("Eigenvalues did not converge")
_SVD_FAILED = _raising("SVD did not converge")


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.linalg.solve(a, b) for float64 a: (n, n) and b: (n,): the gufunc it calls, under its
    floating-point settings (a singular a raises LinAlgError), without its checks and
    conversions: the same numbers, ~3 of ~5 us less (three times a solve)."""
    if _umath_linalg is None:
        return np.linalg.solve(a, b)
    with np.errstate(call=_SINGULAR, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _umath_linalg.solve1(a, b, signature="dd->d")


def eigvalsh(a: np.ndarray) -> np.ndarray:
    """np.linalg.eigvalsh(a) (lower triangle) of a float64 (..., n, n) array, as `solve` calls it:
    the same numbers, ~3 us less (twice a solve)."""
    if _umath_linalg is None:
        return np.linalg.eigvalsh(a)
    with np.errstate(call=_EIGH_FAILED, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _umath_linalg.eigvalsh_lo(a, signature="d->d")


def eigh_stack(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.linalg.eigh(a) (lower triangle) of a float64 (..., n, n) array, as `solve` calls it:
    (eigenvalues, eigenvectors), the same numbers; `eigh` is the faster route for one matrix."""
    if _umath_linalg is None:
        return tuple(np.linalg.eigh(a))
    with np.errstate(call=_EIGH_FAILED, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _umath_linalg.eigh_lo(a, signature="d->dd")


def svd(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """np.linalg.svd(a) (full matrices) of a float64 (..., m, n) array, as `solve` calls it:
    (U, s, Vh), the same numbers, ~4 us less."""
    if _umath_linalg is None:
        return tuple(np.linalg.svd(a))
    with np.errstate(call=_SVD_FAILED, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _umath_linalg.svd_f(a, signature="d->ddd")


def det(a: np.ndarray) -> np.ndarray | float:
    """np.linalg.det of a float64 (..., n, n) array: the gufunc np.linalg.det calls, called as it
    calls it (the same numbers), without its checks (~2 of ~3 us; twice a solve)."""
    if _umath_linalg is None:
        return np.linalg.det(a)
    return _umath_linalg.det(a, signature="d->d")


def row_norms(x: np.ndarray) -> np.ndarray:
    """The Euclidean norm of each row of a real (n, k) array: np.linalg.norm(x, axis=1)'s own
    arithmetic (sqrt of the summed squares) without its wrapper (~2 us, a dozen times a solve)."""
    return np.sqrt(row_sums_of_squares(x))


#: from this many rows on, `row_sums_of_squares` adds column by column
_COLUMNWISE_ROWS = 256


def row_sums_of_squares(x: np.ndarray) -> np.ndarray:
    """sum_j x_ij^2 of each row of a real (n, k) array, with the bits of np.add.reduce(x * x,
    axis=1). numpy adds fewer than 8 numbers in order, so for k < 8 and many rows the sum is
    taken column by column over whole columns instead: the same additions in the same order,
    4-13x faster at n = 1e5 (a reduction along short rows runs a loop per row)."""
    n, k = x.shape
    if n < _COLUMNWISE_ROWS or k >= 8:
        return np.add.reduce(x * x, axis=1)
    out = x[:, 0] * x[:, 0]
    for j in range(1, k):
        out += x[:, j] * x[:, j]
    return out


def vector_norm(x: np.ndarray) -> float:
    """The Euclidean norm of a real 1-D array: np.linalg.norm(x)'s arithmetic (sqrt(x . x)) as a
    float, without its wrapper."""
    return math.sqrt(float(x.dot(x)))


def lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The least-squares (minimum-norm where rank deficient) solution x of a x = b for a finite
    float64 a: (m, n) and b: (m,): np.linalg.lstsq(a, b, rcond=None)[0]'s LAPACK call (dgelsd,
    rcond = eps max(m, n)) without its wrapper (the same numbers, measured; ~8 of ~35 us at 19 x 13).
    np.linalg.lstsq where LAPACK reports a failure."""
    m, n = a.shape
    work = _GELSD_WORK.get((m, n))
    if work is None:
        lwork, liwork, info = lapack.dgelsd_lwork(m, n, 1, -1)
        if info != 0:
            return np.linalg.lstsq(a, b, rcond=None)[0]
        work = _GELSD_WORK[(m, n)] = (int(lwork), int(liwork))
    rhs = np.zeros((max(m, n), 1))
    rhs[:m, 0] = b
    x, _, _, info = lapack.dgelsd(a, rhs, work[0], work[1], np.finfo(float).eps * max(m, n))
    if info != 0:
        return np.linalg.lstsq(a, b, rcond=None)[0]
    return x[:n, 0]


#: dgelsd's workspace sizes per (m, n), asked of LAPACK once
_GELSD_WORK: dict[tuple[int, int], tuple[int, int]] = {}


def singular_values(M: np.ndarray) -> np.ndarray:
    """The singular values (descending) of a finite float64 (m, n) M: np.linalg.svd(M,
    compute_uv=False)'s LAPACK call (dgesdd) without its wrapper (the same numbers, measured;
    7 against 16 us at 9 x 9); numpy's where LAPACK reports a failure."""
    _, s, _, info = lapack.dgesdd(M, compute_uv=0)
    return s if info == 0 else np.linalg.svd(M, compute_uv=False)
