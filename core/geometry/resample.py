"""Resampling a pose stream at other times, and its angular speed.

Rotations are interpolated by SLERP (`scipy.spatial.transform.Slerp`), translations linearly:
the pose moves at constant angular and linear velocity between two samples, which is what a
stream sampled fast relative to its motion looks like. Nothing is extrapolated: a time outside the
stream's span, or between two samples farther apart than `max_gap` (a dropout), gets no pose and
is reported as dropped rather than bridged by a guess.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation, Slerp

from handeye.geometry.se3 import make_pose, rotation_angle


@dataclasses.dataclass(frozen=True)
class Resampled:
    """Poses at the requested times that could be interpolated.

    poses: (k, 4, 4) at ``times[kept]``; kept: indices into the requested times;
    outside: how many times lay outside the stream's span; gaps: how many fell in a gap wider than
    the limit.
    """

    poses: NDArray[np.float64]
    kept: NDArray[np.intp]
    outside: int
    gaps: int


def valid_times(stamps: ArrayLike, times: ArrayLike, max_gap: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """(inside, bridged): per time, whether it is within [stamps[0], stamps[-1]], and whether its
    two neighbouring stamps are at most `max_gap` apart (an exact hit always is)."""
    s = np.asarray(stamps, dtype=float)
    t = np.asarray(times, dtype=float)
    inside = (t >= s[0]) & (t <= s[-1])
    hi = np.clip(np.searchsorted(s, t, side="left"), 1, len(s) - 1)
    exact = s[np.clip(np.searchsorted(s, t), 0, len(s) - 1)] == t
    bridged = exact | ((s[hi] - s[hi - 1]) <= max_gap)
    return inside, bridged & inside


def resample_poses(stamps: ArrayLike, poses: ArrayLike, times: ArrayLike, max_gap: float) -> Resampled:
    """The stream (stamps (n,) strictly increasing, poses (n, 4, 4)) at `times` (any order):
    SLERP for rotations, linear for translations; times outside the span or in a gap wider than
    `max_gap` seconds are dropped and counted."""
    s = np.asarray(stamps, dtype=float)
    T = np.asarray(poses, dtype=float)
    t = np.asarray(times, dtype=float)
    inside, ok = valid_times(s, t, max_gap)
    kept = np.flatnonzero(ok)
    tk = t[kept]
    rot = Slerp(s, Rotation.from_matrix(T[:, :3, :3]))(tk).as_matrix() if len(tk) else np.empty((0, 3, 3))
    trans = np.stack([np.interp(tk, s, T[:, k, 3]) for k in range(3)], axis=-1)
    return Resampled(make_pose(rot, trans), kept, int(np.sum(~inside)), int(np.sum(inside & ~ok)))


def angular_speed(stamps: ArrayLike, poses: ArrayLike, times: ArrayLike, half_window: float,
                  max_gap: float) -> NDArray[np.float64]:
    """Angular speed (rad/s) at `times` by a central difference over +-half_window seconds:
    angle(R(t - h)^T R(t + h)) / 2h, NaN where either end cannot be interpolated.

    The angle between two orientations of one rigid body does not depend on the frame the body's
    poses are given in, nor on which fixed frame they are measured from (nor on inverting all of
    them), so a robot's flange and the camera on it (or the board it holds) have the same angular
    speed: this is what lets two streams be aligned in time before any calibration. A window of a
    few samples averages the measurement noise that differencing amplifies.
    """
    t = np.asarray(times, dtype=float)
    out = np.full(len(t), np.nan)
    before = resample_poses(stamps, poses, t - half_window, max_gap)
    after = resample_poses(stamps, poses, t + half_window, max_gap)
    both, ib, ia = np.intersect1d(before.kept, after.kept, return_indices=True)
    Rb = before.poses[ib, :3, :3]
    Ra = after.poses[ia, :3, :3]
    out[both] = rotation_angle(np.swapaxes(Rb, 1, 2) @ Ra) / (2.0 * half_window)
    return out
