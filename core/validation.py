"""Validation of pose stacks shared by every problem.

`pose_stack` turns user input (array or sequence of 4x4) into a read-only float64 copy of shape
(m, 4, 4) after checking that every entry is a rigid motion: finite, last row [0, 0, 0, 1],
rotation block orthonormal to `ORTHONORMALITY_TOL` with det +1.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import DegenerateDataError, InputError
from .se3 import ORTHONORMALITY_TOL, orthonormality_error

LAST_ROW_TOL = 1e-9


def pose_stack(value: Any, name: str, *, tol: float = ORTHONORMALITY_TOL) -> np.ndarray:
    """Validated read-only copy of `value` as (m, 4, 4) float64.  Raises InputError naming `name`."""
    try:
        T = np.array(value, dtype=float, copy=True)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of 4x4 poses with shape (m, 4, 4); could not convert it to floats ({exc})") from None
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"expected {name} to have shape (m, 4, 4), got {T.shape}")
    bad = ~np.all(np.isfinite(T), axis=(1, 2))
    if bad.any():
        raise InputError(f"{name} contains NaN or inf in pose(s) {_indices(bad)}")
    bad = np.any(np.abs(T[:, 3, :] - (0.0, 0.0, 0.0, 1.0)) > LAST_ROW_TOL, axis=1)
    if bad.any():
        raise InputError(f"{name}: last row must be [0, 0, 0, 1]; it is not in pose(s) {_indices(bad)}")
    R = T[:, :3, :3]
    err = orthonormality_error(R)
    bad = err > tol
    if bad.any():
        raise InputError(
            f"{name}: rotation block is not orthonormal (max |R^T R - I| = {err.max():.1e} > "
            f"tolerance {tol:g}) in pose(s) {_indices(bad)}; re-orthonormalise the data or check "
            "its units and layout (row-major 4x4 expected)"
        )
    bad = np.sum(R[:, :, 0] * np.cross(R[:, :, 1], R[:, :, 2]), axis=1) < 0  # det(R)
    if bad.any():
        raise InputError(f"{name}: rotation block has det -1 (a reflection) in pose(s) {_indices(bad)}")
    T[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
    T.setflags(write=False)
    return T


def same_length(stacks: dict[str, np.ndarray], min_pairs: int) -> int:
    """Check that all stacks have the same length m >= min_pairs; return m."""
    lengths = {name: len(s) for name, s in stacks.items()}
    if len(set(lengths.values())) != 1:
        raise InputError(f"data stacks must have the same length; got {lengths}")
    m = next(iter(lengths.values()))
    if m < min_pairs:
        raise DegenerateDataError(f"need at least {min_pairs} pose pairs, got {m}")
    return m


def _indices(mask: np.ndarray, limit: int = 5) -> str:
    idx = np.flatnonzero(mask)
    shown = ", ".join(str(i) for i in idx[:limit])
    return shown + (f", ... ({len(idx)} in all)" if len(idx) > limit else "")
