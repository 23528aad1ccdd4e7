"""Relative motions between absolute poses: what A X = X B is made of.

Shared by the problem that solves motions (``axxb``), the planar mode of every problem, and the
files of stations (`handeye.io`): with A_k X = Y B_k at every station, the motions between two
stations remove Y.
"""

from __future__ import annotations

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import PAIRINGS
from handeye.geometry.se3 import inverse

#: which pairs of stations make the motions: consecutive ones, or every pair i < j


def relative_motions(A_abs: np.ndarray, B_abs: np.ndarray, pairing: str = "all") -> tuple[np.ndarray, np.ndarray]:
    """Motions A_ij = inv(A_j) A_i, B_ij = inv(B_j) B_i of absolute poses with A_k X = Y B_k.

    Then A_ij X = inv(A_j) Y B_i = X inv(B_j) B_i = X B_ij. pairing "all" (default): every
    i < j, i outer and j inner (the order of OpenCV's ``calibrateHandEye``, which forms these
    pairs itself); "consecutive": (i, i + 1) for i = 0 .. n-2.

    Why "all" by default (docs/when-to-use-which.md): with independent noise on each station (a
    board pose from solvePnP, a robot pose from the controller) every pair carries information,
    and all pairs gave lower errors than consecutive ones in every cell of that study; with a
    drifting camera (visual odometry: the error of a pose accumulates along the recording) only
    consecutive motions are accurate, and "consecutive" is the right choice.
    """
    if pairing not in PAIRINGS:
        raise InputError(f"pairing={pairing!r} is not one of {', '.join(PAIRINGS)}")
    n = len(A_abs)
    if pairing == "consecutive":
        i, j = np.arange(n - 1), np.arange(1, n)
    else:
        i, j = np.triu_indices(n, k=1)
    return inverse(A_abs[j]) @ A_abs[i], inverse(B_abs[j]) @ B_abs[i]
