"""Choosing which interpolated stations to solve with.

Two steps:

1. `moving`: drop stations where the robot turns slower than a threshold. A stream records many
   samples while the robot stands still; they repeat one station and so weight it in the fit as
   if it had been measured dozens of times, and they carry no information about the time offset.
2. `spread`: keep at most `max_pairs` stations, chosen by greedy farthest-point sampling of the
   robot poses (distance: rotation angle + translation / L, L the spread of the positions): a
   calibration is as good as the spread of its poses, and a few hundred well-spread stations
   determine X and Y as well as thousands of neighbours, at a fraction of the solving time.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from handeye.geometry.se3 import rotation_angle

#: default: a station counts as moving above this robot angular speed (rad/s)
MIN_ANGULAR_SPEED = math.radians(1.0)
#: default largest number of stations kept
MAX_PAIRS = 300


def position_spread(poses: NDArray) -> float:
    """RMS distance of the translations from their mean (the workspace size); 1.0 if zero."""
    t = np.asarray(poses)[:, :3, 3]
    L = float(np.sqrt(np.mean(np.sum((t - t.mean(axis=0)) ** 2, axis=1)))) if len(t) else 0.0
    return L if L > 0 else 1.0


def moving(speed: NDArray, min_speed: float) -> NDArray[np.bool_]:
    """Stations whose angular speed (rad/s; NaN = unknown, counted as moving) is at least `min_speed`."""
    s = np.asarray(speed, dtype=float)
    return ~(s < min_speed)


def spread(poses: NDArray, max_pairs: int) -> NDArray[np.intp]:
    """Indices (sorted) of at most `max_pairs` poses chosen by greedy farthest-point sampling,
    starting from the pose farthest from the mean orientation; all of them when there are fewer."""
    T = np.asarray(poses, dtype=float)
    n = len(T)
    if n <= max_pairs:
        return np.arange(n, dtype=np.intp)
    R, t = T[:, :3, :3], T[:, :3, 3]
    L = position_spread(T)

    def distance(i: int) -> NDArray:
        return rotation_angle(np.swapaxes(R, 1, 2) @ R[i]) + np.linalg.norm(t - t[i], axis=1) / L

    mean = np.linalg.svd(R.sum(axis=0))  # chordal mean orientation
    Rm = mean[0] @ np.diag([1, 1, np.linalg.det(mean[0] @ mean[2])]) @ mean[2]
    first = int(np.argmax(rotation_angle(np.swapaxes(R, 1, 2) @ Rm)))
    chosen = [first]
    nearest = distance(first)
    for _ in range(max_pairs - 1):
        nxt = int(np.argmax(nearest))
        chosen.append(nxt)
        nearest = np.minimum(nearest, distance(nxt))
    return np.sort(np.array(chosen, dtype=np.intp))
