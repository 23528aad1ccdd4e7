"""Checking a time-stamped pose stream before it is resampled: order, duplicates, spacing.

A stream is a `handeye.io.pose_readers.PoseStack` with `stamps` (seconds). Recorders write stamps
out of order (several publishers in one bag) or twice (a message logged twice): out-of-order
stamps are sorted (with a warning, because the order of the file is then not the order of time),
a stamp repeated with the same pose is dropped (warning), a stamp repeated with a different pose
(stamps rounded to 10 ms in a 100 Hz stream, as in the ETH ASL sets) keeps its first pose, with a
warning, as long as that is rare (`MAX_CLASHES`); more often it is refused as a broken time column,
since no rule says which of the two poses is right.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from handeye.base.errors import InputError
from handeye.io.pose_readers import PoseStack

#: two poses at one stamp count as the same when they differ by less than this (rad; unit of the stream)
SAME_POSE_TOL = 1e-9
#: a stream may have at most this fraction of its stamps twice with different poses (rounded
#: stamps of a fast stream; the first is kept); more is refused as a broken time column
MAX_CLASHES = 0.01
#: stamps beyond this are not seconds (Unix time is ~1.7e9 s; in ms it is ~1.7e12)
MAX_SECONDS = 1e11
#: default largest spacing of source samples an interpolation may bridge, in median intervals
GAP_FACTOR = 3.0


def checked_stream(stack: PoseStack, name: str) -> tuple[PoseStack, NDArray[np.intp], list[str]]:
    """(the stream sorted by stamp with repeated stamps dropped, the rows of `stack` it kept in
    that order, warnings saying what was changed).

    name: what the stream is called in messages (e.g. ``"--robot 'arm.csv'"``).
    Raises InputError when the stream has no stamps, fewer than 2 poses, non-finite stamps, or one
    stamp with two different poses.
    """
    if stack.stamps is None:
        raise InputError(f"{name} has no time stamps (a header 't', 'time' or 'stamp', or a first column of "
                         "non-integer seconds); interpolation needs a stamp per pose")
    t = np.asarray(stack.stamps, dtype=float)
    if not np.all(np.isfinite(t)):
        raise InputError(f"{name}: time stamp {int(np.flatnonzero(~np.isfinite(t))[0]) + 1} is not finite")
    if np.max(np.abs(t)) > MAX_SECONDS:
        raise InputError(f"{name}: time stamps of {np.max(np.abs(t)):.3g} look like milli-, micro- or nanoseconds; "
                         "give them in seconds")
    warnings = []
    order = np.argsort(t, kind="stable")
    late = int(np.sum(np.diff(t) < 0))
    if late:
        warnings.append(f"{name}: {late} time stamps go backwards; the poses were sorted by time stamp")
    t, T = t[order], np.asarray(stack.poses)[order]
    same = np.flatnonzero(np.diff(t) == 0)
    if len(same):
        differ = [i for i in same if np.max(np.abs(T[i] - T[i + 1])) > SAME_POSE_TOL]
        if len(differ) > MAX_CLASHES * len(t):
            i = differ[0]
            raise InputError(f"{name}: {len(differ)} time stamps carry two different poses (first at t = "
                             f"{t[i]:.9g} s, rows {order[i] + 1} and {order[i + 1] + 1}); remove the duplicates "
                             "or fix the stamps")
        keep = np.ones(len(t), bool)
        keep[same + 1] = False
        t, T, order = t[keep], T[keep], order[keep]
        copies = len(same) - len(differ)
        if copies:
            warnings.append(f"{name}: {copies} poses were recorded twice with the same stamp; dropped the copies")
        if differ:
            warnings.append(f"{name}: {len(differ)} time stamps occur twice with different poses (stamps rounded?); "
                            "kept the first pose of each")
    if len(t) < 2:
        raise InputError(f"{name}: {len(t)} distinct time stamp(s); a stream needs at least 2 to interpolate")
    T.setflags(write=False)
    t.setflags(write=False)
    names = None if stack.names is None else tuple(stack.names[i] for i in order)
    return dataclasses.replace(stack, poses=T, stamps=t, names=names), order.astype(np.intp), warnings


def median_interval(stamps: np.ndarray) -> float:
    """Median spacing of sorted, distinct stamps (seconds)."""
    return float(np.median(np.diff(np.asarray(stamps, dtype=float))))


def default_max_gap(stamps: np.ndarray) -> float:
    """`GAP_FACTOR` times the median spacing: a regular stream is bridged everywhere, a dropout of
    more than a few samples is not."""
    return GAP_FACTOR * median_interval(stamps)


def overlap(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """The time interval (start, end) both stamp arrays span; end < start when they do not overlap."""
    return max(float(a[0]), float(b[0])), min(float(a[-1]), float(b[-1]))


def span_text(stamps: np.ndarray) -> str:
    """'first..last s' for messages."""
    return f"{float(stamps[0]):.6f}..{float(stamps[-1]):.6f} s"


#: two streams of one recording whose time spans differ by about a power of 1000 (within this
#: factor of it, and at least 300x in all) have their stamps in different units
UNIT_RATIO_TOL = 3.0


def check_same_time_unit(robot: NDArray[np.float64], camera: NDArray[np.float64], robot_name: str,
                         camera_name: str) -> None:
    """InputError where the robot's and the camera's stamps (seconds, both streams of one
    recording) span times about 1000, 10^6 or 10^9 times apart: one is in milli-, micro- or
    nanoseconds (it was taken for a robot that hardly rotates, or stations that do not move)."""
    spans = [float(np.ptp(t)) if len(t) > 1 else 0.0 for t in (robot, camera)]
    if min(spans) <= 0:
        return
    ratio = spans[0] / spans[1]
    power = round(math.log(ratio, 1000)) if ratio > 0 else 0
    if power == 0 or not 1 / UNIT_RATIO_TOL <= ratio / 1000.0 ** power <= UNIT_RATIO_TOL:
        return
    unit = {1: "milliseconds", 2: "microseconds", 3: "nanoseconds"}.get(abs(power), f"1e{3 * abs(power)} s")
    slower, faster = (robot_name, camera_name) if power > 0 else (camera_name, robot_name)
    raise InputError(f"the time stamps of {slower} span {max(spans):.4g} against {min(spans):.4g} for {faster}: those "
                     f"of {slower} look like {unit}, the others like seconds; give both in seconds")
