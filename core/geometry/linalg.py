"""Linear algebra shared by solvers: the triangular factor of a tall stack of small blocks."""

from __future__ import annotations

import numpy as np


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
    peak = float(np.max(np.abs(M))) if M.size else 0.0
    if peak == 0.0 or not np.isfinite(peak):
        return peak
    return peak * float(np.linalg.norm(M / peak))


def median(x: np.ndarray) -> float:
    """The median of an array's values (the mean of the two middle values for an even count), as
    np.median: by one sort for up to 1000 values (~1 us against np.median's ~10 us for the few a
    self-check takes it of), by a partial sort (O(n)) beyond. NaN for an empty array."""
    x = np.asarray(x, dtype=float).ravel()
    n = len(x)
    if n == 0:
        return float("nan")
    middle = [(n - 1) // 2, n // 2]
    s = np.sort(x) if n <= 1000 else np.partition(x, middle)
    return float(0.5 * (s[middle[0]] + s[middle[1]]))
