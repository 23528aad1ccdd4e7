"""The contract between a problem and the least-squares engine (`handeye.estimation.nlls`): a
`PoseModel` gives the residuals of its equation at k unknown poses (`Poses`) and their Jacobian;
the engine, its objective (`handeye.estimation.lm_objective`) and the host's checks need nothing
else of a problem's data.
"""

from __future__ import annotations

import abc
import math
from typing import Any

import numpy as np

Poses = tuple[np.ndarray, ...]


class PoseModel(abc.ABC):
    """What a problem supplies to the engine: residuals and Jacobians of its equation.

    Attributes: `unknowns` (names of the k poses, in parameter order), `m` (pairs), `scale` (the
    data's length unit, e.g. RMS translation, for the floors of estimated sigmas),
    `profile_min_pairs` (fewest pairs for which the profile likelihood is bounded: below it the
    translation residuals can be fitted exactly), `sums_min_pairs` (from this many pairs on,
    `normal_equations` replaces the Jacobian for per-group sigmas; inf: never), `fixed`
    (translation components the refinement keeps: pairs (index of the unknown, unit direction d
    in the frame its translation is expressed in), so that t_j . d stays as it starts; empty: none).
    The constraint travels with the model, not with a solver's settings, so that every fit of
    the same data (a solver's, the host's self-check) honours it.
    """

    unknowns: tuple[str, ...]
    m: int
    scale: float
    profile_min_pairs: int
    sums_min_pairs: float = math.inf
    fixed: tuple[tuple[int, np.ndarray], ...] = ()
    #: the model states where its residuals' noise comes from (`noise_factors`), for
    #: `handeye.estimation.noise_sources`
    noise_sources: bool = False
    #: the self-check's last local fit near an answer, kept with the model it fitted
    #: (`handeye.checks.best_fit`): (key of the poses, the fit); None: none yet
    best_fit_memo: tuple[bytes, Any] | None = None

    @abc.abstractmethod
    def residuals(self, poses: Poses) -> np.ndarray:
        """e: (m, 6) = [r_i; t_i] at the poses (each (4, 4))."""

    @abc.abstractmethod
    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 6k) = d e_i / d (xi_1, ..., xi_k) at the poses, e from `residuals`."""

    def noise_factors(self, data: Any, poses: Poses) -> Any:
        """Where `noise_sources` is True: the noise sources of the residuals at the poses, a
        `handeye.estimation.noise_sources.Sources`."""
        raise NotImplementedError

    def normal_equations(self, poses: Poses, e: np.ndarray, wr: float, wt: float,
                         d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Optional closed-form sums, for C = diag(I3 / wr, I3 / wt) and pair weights d: (m,):
        g_rot, g_trans: (6k,) = sum_i d_i J_i,group^T C^-1 e_i,group per residual group, and
        Hw: (6k, 6k) = sum_i d_i J_i^T C^-1 J_i (symmetric)."""
        raise NotImplementedError
