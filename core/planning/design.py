"""Choosing stations by what they tell: D-optimal selection on the Fisher information of the
unknowns (`greedy`, with an exchange pass), and the 1-sigma it predicts (`predicted_std`).

Each candidate station c brings an information matrix I_c (the problem's
`station_information`), and the maximum-likelihood fit of a set S of stations has covariance
(I_0 + sum_{c in S} I_c)^-1 to first order, I_0 that of the stations already recorded. D-optimal
design maximises log det of that information (of its Schur complement on the unknowns of
interest, where others are nuisances: the board's pose for A X = X B): it shrinks the volume of
the confidence ellipsoid of every unknown at once and, unlike a criterion on the 1-sigma in one
unit, does not depend on the length unit or on how rotations are weighed against translations.

Greedy selection adds the candidate of largest gain log det(I + I_c) - log det(I) (all candidates
at once: I_c = F_c F_c^T of rank <= 6, so the gain is log det(1 + F_c^T I^-1 F_c), a 6 x 6
determinant each), then one exchange pass (Fedorov) swaps a chosen station for a candidate where
that raises the criterion. Before the information is full rank, a ridge of RIDGE times the
candidates' mean diagonal keeps the determinant defined (and unit invariant).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

#: the ridge that makes an empty design's information invertible, relative to the candidates'
#: mean information per parameter
RIDGE = 1e-9
#: exchange passes after the greedy selection
EXCHANGE_PASSES = 2


def factors(information: np.ndarray) -> np.ndarray:
    """F_c (n, p, r) with I_c = F_c F_c^T for information matrices (n, p, p) (rank r <= p: the
    eigenvectors of the nonzero eigenvalues, times their roots)."""
    w, V = np.linalg.eigh(0.5 * (information + np.swapaxes(information, 1, 2)))
    keep = max(int(np.max(np.sum(w > 1e-12 * np.maximum(w[:, -1:], 1e-300), axis=1))), 1)
    return V[:, :, -keep:] * np.sqrt(np.maximum(w[:, None, -keep:], 0.0))


def log_det(M: np.ndarray) -> float:
    sign, value = np.linalg.slogdet(M)
    return float(value) if sign > 0 else -math.inf


def criterion(information: np.ndarray, interest: np.ndarray | None) -> float:
    """log det of the information of the unknowns of interest (their Schur complement), or of all."""
    if interest is None or interest.all():
        return log_det(information)
    return log_det(information) - log_det(information[np.ix_(~interest, ~interest)])


def gains(total: np.ndarray, F: np.ndarray, interest: np.ndarray | None) -> np.ndarray:
    """Each candidate's gain of `criterion` when added to `total`: F (n, p, r) the candidates'
    `factors` (module docstring)."""
    def gain(info: np.ndarray, Fc: np.ndarray) -> np.ndarray:
        inv = np.linalg.inv(info)
        small = np.eye(Fc.shape[2]) + np.swapaxes(Fc, 1, 2) @ inv @ Fc
        sign, value = np.linalg.slogdet(small)
        return np.where(sign > 0, value, -np.inf)

    out = gain(total, F)
    if interest is not None and not interest.all():
        nuisance = ~interest
        out = out - gain(total[np.ix_(nuisance, nuisance)], F[:, nuisance])
    return out


def greedy(candidates: np.ndarray, count: int, *, prior: np.ndarray | None = None,
           interest: np.ndarray | None = None, candidate_factors: np.ndarray | None = None,
           admissible: Callable[[int], bool] | None = None) -> list[int]:
    """Indices of `count` candidates (information (n, p, p)) that maximise `criterion` of
    prior + their sum: greedy, then EXCHANGE_PASSES exchange passes. Each candidate at most once.
    candidate_factors: their `factors`, where a caller chooses from one pool many times (the
    eigen decompositions are most of a selection's cost). admissible(i): a test too costly to run
    on every candidate (the arm reaching it: `reach.Reach`), asked of the best ones in turn and
    only of those (each at most once); fewer than `count` come back when too few pass."""
    n, p, _ = candidates.shape
    scale = np.mean(np.diagonal(candidates, axis1=1, axis2=2), axis=0)
    ridge = np.diag(RIDGE * np.where(scale > 0, scale, 1.0))
    base = ridge + (np.zeros((p, p)) if prior is None else prior)
    F = factors(candidates) if candidate_factors is None else candidate_factors
    allowed = _Admissible(admissible)
    chosen: list[int] = []
    total = base.copy()
    for _ in range(min(count, n)):
        best = allowed.best(gains(total, F, interest), chosen)
        if best is None:
            break
        chosen.append(best)
        total = total + candidates[best]
    for _ in range(EXCHANGE_PASSES):
        if not _exchange(candidates, F, base, chosen, interest, allowed):
            break
    return chosen


class _Admissible:
    """`greedy`'s admissibility test, each candidate asked at most once."""

    def __init__(self, test: Callable[[int], bool] | None) -> None:
        self.test, self.known = test, {}

    def best(self, g: np.ndarray, taken: list[int]) -> int | None:
        """The admissible candidate of largest gain g not in `taken`, or None."""
        g = np.array(g)
        g[taken] = -np.inf
        for i in np.argsort(-g, kind="stable"):
            if not np.isfinite(g[i]):
                return None
            if self.test is None:
                return int(i)
            if int(i) not in self.known:
                self.known[int(i)] = bool(self.test(int(i)))
            if self.known[int(i)]:
                return int(i)
        return None


def _exchange(candidates: np.ndarray, F: np.ndarray, base: np.ndarray, chosen: list[int],
              interest: np.ndarray | None, allowed: _Admissible) -> bool:
    """One exchange pass in place: each chosen station in turn is replaced by the admissible
    candidate that raises `criterion` most without it, where one does; whether any was."""
    changed = False
    for k in range(len(chosen)):
        without = base + candidates[[c for j, c in enumerate(chosen) if j != k]].sum(axis=0)
        current = criterion(without + candidates[chosen[k]], interest)
        best = allowed.best(gains(without, F, interest), chosen)
        if best is not None and criterion(without + candidates[best], interest) > current + 1e-9:
            chosen[k] = best
            changed = True
    return changed


def predicted_std(information: np.ndarray, names: Sequence[str]) -> dict[str, dict[str, float]]:
    """1-sigma of each unknown (its 6 parameters (omega, v) in its own frame, in `names` order)
    from the total information: the worst direction, rotation in deg and translation in the
    data's length unit, as the self-check reports an answer's (`self_check.std`)."""
    cov = np.linalg.inv(information)
    out = {}
    for j, name in enumerate(names):
        rot = np.linalg.eigvalsh(cov[6 * j:6 * j + 3, 6 * j:6 * j + 3])[-1]
        trans = np.linalg.eigvalsh(cov[6 * j + 3:6 * j + 6, 6 * j + 3:6 * j + 6])[-1]
        out[name] = {"rotation_deg": math.degrees(math.sqrt(max(rot, 0.0))), "translation": math.sqrt(max(trans, 0.0))}
    return out
