"""Cells of several cameras and targets for the tests of the ``axyb-multi`` solvers
(test_axyb_multi_kron.py, test_pairwise.py), made here with known truth: random X_j, Y_k, robot
poses of the simulated arm (mm), and B_i = Y_k^-1 A_s X_j for a random subset of the
(station, X, Y) triples (each observed pair of X and Y has at least `min_per_pair` of them), with
optional noise on B. `stations_about_one_axis` makes robot poses that all turn about one axis,
degenerate for a pair alone.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import (
    inverse,
    make_pose,
    random_poses,
    rotation_angle,
    so3_exp,
)
from handeye.problems.axyb_multi.data import AXYBMultiData, validated

PROBLEM = "axyb-multi"


def cell(seed: int, *, stations: int = 20, nX: int = 2, nY: int = 3, fraction: float = 0.6,  # noqa: N803
         pairs: Sequence[tuple[int, int]] | None = None, min_per_pair: int = 4,
         noise: tuple[float, float] | None = None) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(raw data {"A", "B", "x_index", "y_index"}, truth {"X": (nX, 4, 4), "Y": (nY, 4, 4)}).

    pairs: the (j, k) that may be observed (default: all); each is observed at a random `fraction`
    of the stations, at least `min_per_pair`. noise: (rad, mm) standard deviations per axis of a
    rotation and a translation applied to each B_i."""
    rng = np.random.default_rng(seed)
    X = random_poses(nX, rng, 100.0)
    Y = random_poses(nY, rng, 1000.0)
    robot = random_flange_poses(stations, rng)
    pairs = [(j, k) for j in range(nX) for k in range(nY)] if pairs is None else list(pairs)
    s, j, k = [], [], []
    for jj, kk in pairs:
        seen = rng.random(stations) < fraction
        seen[rng.choice(stations, min_per_pair, replace=False)] = True
        idx = np.flatnonzero(seen)
        s += idx.tolist()
        j += [jj] * len(idx)
        k += [kk] * len(idx)
    s, j, k = np.array(s), np.array(j), np.array(k)
    return observe(robot[s], X, Y, j, k, rng, noise), {"X": X, "Y": Y}


def observe(A: np.ndarray, X: np.ndarray, Y: np.ndarray, j: np.ndarray, k: np.ndarray,  # noqa: N803
            rng: np.random.Generator | None = None, noise: tuple[float, float] | None = None) -> dict[str, np.ndarray]:
    """The raw data of observations (A_i, X_{j_i}, Y_{k_i}): B_i = Y^-1 A_i X, noise as in `cell`."""
    B = inverse(Y[k]) @ A @ X[j]
    if noise is not None:
        sigma_rot, sigma_trans = noise
        w = sigma_rot * rng.standard_normal((len(B), 3))
        dt = sigma_trans * rng.standard_normal((len(B), 3))
        B = np.einsum("mab,mbc->mac", make_pose(np.stack([so3_exp(v) for v in w]), dt), B)
    return {"A": np.array(A), "B": B, "x_index": np.asarray(j, dtype=np.int64), "y_index": np.asarray(k, dtype=np.int64)}


def stations_about_one_axis(n: int, rng: np.random.Generator) -> np.ndarray:
    """n robot poses that differ by rotations about the flange's z axis only (and translations):
    a pair of X and Y observed only there is degenerate alone."""
    base = random_flange_poses(1, rng)[0]
    angles = rng.uniform(-1.5, 1.5, n)
    turn = make_pose(np.stack([so3_exp([0.0, 0.0, a]) for a in angles]), np.zeros((n, 3)))
    shift = make_pose(np.broadcast_to(np.eye(3), (n, 3, 3)), 50.0 * rng.standard_normal((n, 3)))
    return shift @ base @ turn


def concatenate(*parts: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def validated_cell(raw: dict) -> AXYBMultiData:
    return validated(PROBLEM, raw, 3)


def errors(unknowns: dict[str, np.ndarray], truth: dict[str, np.ndarray]) -> dict[str, tuple[float, float]]:
    """Per stack, the largest (rotation angle [rad], translation distance) against the truth."""
    out = {}
    for name, T in truth.items():
        U = np.asarray(unknowns[name])
        out[name] = (float(rotation_angle(U[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)).max()),
                     float(np.linalg.norm(U[:, :3, 3] - T[:, :3, 3], axis=1).max()))
    return out
