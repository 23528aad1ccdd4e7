"""Folds for k-fold cross-validation: which items each fold holds out. Shared by the harness's
held-out comparisons (`handeye.harness.crossval`, `handeye.harness.crossval_images`) and the corner
fit's own held-out choice (`handeye.plugins.reprojection.held_out`), so that both split alike."""

from __future__ import annotations

import numpy as np

from handeye.base.errors import InputError


def make_folds(n: int, k: int, seed: int = 0, *, contiguous: bool = False) -> list[np.ndarray]:
    """Test indices of k folds partitioning ``range(n)``: sorted int arrays, sizes differing by at
    most one. Shuffled by ``numpy.random.default_rng(seed)`` (deterministic), or with `contiguous`
    consecutive blocks (the seed is then unused)."""
    if k < 2:
        raise InputError(f"--folds must be >= 2, got {k}")
    if n < k:
        raise InputError(f"cannot split {n} items into {k} folds; use --folds {max(2, n)} or fewer, or more data")
    order = np.arange(n) if contiguous else np.random.default_rng(seed).permutation(n)
    return [np.sort(part) for part in np.array_split(order, k)]
