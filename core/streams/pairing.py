"""From two time-stamped pose streams to the stations of a calibration: `pair_streams`.

The robot stream (T_base_flange) is interpolated at every camera stamp shifted by the clock
offset (t_robot = t_camera + offset, `handeye.streams.offset`), because the robot is usually the
faster and the more precise stream, and the camera poses are the measurements kept as they are.
The offset is given, or estimated (cross-correlation of the angular speeds, then refined on the
residuals of A_i X = Y B_i). Static stations are dropped and at most `max_pairs` well-spread ones
kept (`handeye.streams.selection`). Every count is reported, so that nothing is dropped silently.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from handeye.base.errors import DegenerateDataError, InputError
from handeye.base.vocabulary import SETUPS
from handeye.geometry.resample import angular_speed, resample_poses, valid_times
from handeye.geometry.se3 import inverse
from handeye.io.pose_readers import PoseStack
from handeye.streams.offset import OffsetEstimate, coarse_offset, refine_offset
from handeye.streams.selection import (
    MAX_PAIRS,
    MIN_ANGULAR_SPEED,
    moving,
    position_spread,
    spread,
)
from handeye.streams.timeline import (
    check_same_time_unit,
    checked_stream,
    default_max_gap,
    median_interval,
    span_text,
)

CAMERA_POSES = ("board-in-camera", "camera-in-board")
#: default half-width of the offset search (s)
MAX_OFFSET = 1.0
#: smallest half-width of the refinement window around the cross-correlation offset (s)
MIN_WINDOW = 0.05
#: fewest moving stations a calibration is attempted with
MIN_STATIONS = 10


@dataclasses.dataclass(frozen=True)
class StreamPairs:
    """Stations made from two streams, in the robot's length unit.

    robot_poses: (m, 4, 4) T_base_flange interpolated at ``camera_stamps + offset``;
    camera_poses: (m, 4, 4) T_cam_target (as solvePnP; inverted on input for camera-in-board);
    camera_stamps: (m,) the camera's stamps (its clock); camera_rows: (m,) the rows of the camera
    stack passed in that they come from; offset: seconds, t_robot = t_camera +
    offset; estimate: how it was estimated (None when given); counts: camera samples, outside
    (t + offset outside the robot stream, or within the refinement window of its ends), gaps (robot dropout wider than max_gap), static (robot
    slower than the threshold), not_selected (beyond max_pairs), kept; max_gap (s),
    min_angular_speed (rad/s); warnings; reliable: False when a warning says the stations are not
    to be trusted (the offset estimate); dropped: (row of the camera stack passed in, why it is no
    station) for every camera sample left out, in row order.
    """

    robot_poses: NDArray[np.float64]
    camera_poses: NDArray[np.float64]
    camera_stamps: NDArray[np.float64]
    camera_rows: NDArray[np.intp]
    unit: str
    offset: float
    estimate: OffsetEstimate | None
    counts: dict[str, int]
    max_gap: float
    min_angular_speed: float
    warnings: tuple[str, ...] = ()
    dropped: tuple[tuple[int, str], ...] = ()

    @property
    def reliable(self) -> bool:
        return self.estimate is None or self.estimate.reliable

    def __len__(self) -> int:
        return len(self.robot_poses)

    def data(self, problem: str | None = None, *, setup: str, pairing: str | None = None) -> dict[str, Any]:
        """The data fields of `problem` (default: the default problem) via `handeye.io.from_poses`."""
        from handeye.io.data_files import from_poses

        return from_poses(self.robot_poses, self.camera_poses, problem, setup=setup, pairing=pairing,
                          metadata={"units": self.unit}, source="streams").data

    @property
    def message(self) -> str:
        """One line: offset (ms, 1-sigma) and the counts."""
        c = self.counts
        if self.estimate is None:
            off = f"time offset {self.offset * 1e3:+.3f} ms (given)"
        else:
            e = self.estimate
            std = f" +- {e.std * 1e3:.2g}" if e.std is not None else " (no 1-sigma)"
            off = (f"time offset {e.offset * 1e3:+.3f}{std} ms (t_robot = t_camera + offset; cross-correlation "
                   f"{e.coarse * 1e3:+.1f} ms, peak {e.correlation:.2f})")
        return (f"{off}; robot interpolated at {c['camera_samples'] - c['outside'] - c['gaps']} of "
                f"{c['camera_samples']} camera stamps ({c['outside']} outside the robot stream, {c['gaps']} in "
                f"gaps > {self.max_gap * 1e3:.3g} ms); dropped {c['static']} static (robot < "
                f"{math.degrees(self.min_angular_speed):.3g} deg/s); kept {c['kept']} well-spread stations")

    def to_dict(self) -> dict[str, Any]:
        """The ``matching`` entry of a calibrate result (seconds)."""
        return {"method": "interpolate", "matched": len(self), "camera_poses": self.counts["camera_samples"],
                "time_offset": self.offset, "time_offset_std": None if self.estimate is None else self.estimate.std,
                "time_offset_estimated": self.estimate is not None,
                "estimate": None if self.estimate is None else self.estimate.to_dict(),
                "counts": dict(self.counts), "max_gap": self.max_gap,
                "min_angular_speed_deg_s": math.degrees(self.min_angular_speed), "message": self.message}


def pair_streams(robot: PoseStack, camera: PoseStack, *, setup: str, camera_poses: str = "board-in-camera",
                 time_offset: float | str = "auto", max_offset: float = MAX_OFFSET, max_gap: float | None = None,
                 min_angular_speed: float = MIN_ANGULAR_SPEED, max_pairs: int = MAX_PAIRS) -> StreamPairs:
    """Pair a robot stream (T_base_flange) with a camera stream into stations.

    robot, camera: `PoseStack` with stamps (seconds; e.g. from `handeye.io.pose_readers.read_poses`
        or `handeye.io.bag_readers.read_bag_poses`); the camera is converted to the robot's unit.
    setup: ``"eye-in-hand"`` or ``"eye-to-hand"`` (needed to refine the offset on A_i X = Y B_i).
    camera_poses: ``"board-in-camera"`` (T_cam_target, solvePnP) or ``"camera-in-board"`` (T_target_cam).
    time_offset: ``"auto"`` to estimate it, or seconds: t_robot = t_camera + time_offset.
    max_offset: the estimate is searched within +-max_offset seconds (an InputError says so when the
        best value is at its edge, rather than returning the edge).
    max_gap: largest spacing of robot samples an interpolation bridges (s); default 3 x the robot's
        median interval (and the camera's for its own angular speed).
    min_angular_speed: stations where the robot turns slower (rad/s) are dropped as static.
    max_pairs: at most this many well-spread stations are kept.
    """
    if setup not in SETUPS:
        raise InputError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
    if camera_poses not in CAMERA_POSES:
        raise InputError(f"camera_poses must be one of {', '.join(CAMERA_POSES)}, got {camera_poses!r}")
    auto = isinstance(time_offset, str)
    if auto and time_offset != "auto":
        raise InputError(f"--time-offset must be 'auto' or a number of seconds, got {time_offset!r}")
    for flag, value, low in (("--max-offset", max_offset, 0.0), ("--max-gap", max_gap, 0.0),
                             ("--time-offset", None if auto else time_offset, -math.inf)):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > low):
            raise InputError(f"{flag} must be a finite number of seconds{' > 0' if low == 0 else ''}, got {value!r}")
    if not (math.isfinite(min_angular_speed) and min_angular_speed >= 0):
        raise InputError(f"--min-speed must be a finite angular speed >= 0, got {min_angular_speed!r}")
    if int(max_pairs) != max_pairs or max_pairs < MIN_STATIONS:
        raise InputError(f"--max-pairs must be a whole number >= {MIN_STATIONS}, got {max_pairs!r}")

    robot, _, warnings = checked_stream(robot, f"the robot stream {robot.source}".rstrip())
    camera_rows_in = len(camera)
    camera, camera_order, more = checked_stream(camera, f"the camera stream {camera.source}".rstrip())
    check_same_time_unit(robot.stamps, camera.stamps, f"the robot stream {robot.source}".rstrip(),
                         f"the camera stream {camera.source}".rstrip())
    warnings += more
    camera = camera.in_unit(robot.unit)
    rt, rT = np.asarray(robot.stamps), np.asarray(robot.poses)
    ct = np.asarray(camera.stamps)
    cT = np.asarray(camera.poses) if camera_poses == "board-in-camera" else inverse(camera.poses)
    robot_gap = default_max_gap(rt) if max_gap is None else float(max_gap)
    camera_gap = default_max_gap(ct) if max_gap is None else float(max_gap)

    coarse = None
    if auto:
        coarse = coarse_offset(rt, rT, ct, cT, max_offset=max_offset, robot_gap=robot_gap, camera_gap=camera_gap)
        center = coarse.offset
        half = max(MIN_WINDOW, 2 * median_interval(ct), 4 * coarse.step)
        window = (center - half, center + half)
        margin = 1.1 * half  # the window and the curvature step beyond it
    else:
        center, window, margin = float(time_offset), None, 0.0

    inside, ok = _interpolable(rt, ct + center, margin, robot_gap)
    outside, gaps = int(np.sum(~inside)), int(np.sum(inside & ~ok))
    if not ok.any():
        raise InputError(f"no camera stamp + offset ({center * 1e3:+.1f} ms) falls inside the robot stream "
                         f"(robot {span_text(rt)}, camera {span_text(ct)}): the streams do not overlap in time; "
                         "check that both use the same clock and seconds, and the offset")
    cand = np.flatnonzero(ok)
    A0 = resample_poses(rt, rT, ct[cand] + center, robot_gap).poses
    speed = angular_speed(rt, rT, ct[cand] + center, max(2 * median_interval(rt), 0.05), robot_gap)
    move = moving(speed, min_angular_speed)
    static = int(np.sum(~move))
    if move.sum() < MIN_STATIONS:
        raise DegenerateDataError(
            f"only {int(move.sum())} of {len(cand)} paired stations show the robot turning faster than "
            f"{math.degrees(min_angular_speed):.3g} deg/s (--min-speed); too little motion to calibrate: record a "
            f"moving robot, or lower --min-speed")
    cand = cand[move]
    pick = cand[spread(A0[move], int(max_pairs))]

    estimate = None
    offset = center
    cam_sel = cT[pick]
    if auto:
        B = inverse(cam_sel) if setup == "eye-in-hand" else cam_sel
        estimate = refine_offset(rt, rT, ct[pick], B, coarse=coarse, window=window, max_gap=robot_gap,
                                 length=position_spread(A0[move]))
        offset = estimate.offset
        warnings += list(estimate.warnings)
    A = resample_poses(rt, rT, ct[pick] + offset, robot_gap).poses
    for arr in (A, cam_sel):
        arr.setflags(write=False)
    counts = {"camera_samples": len(ct), "outside": outside, "gaps": gaps, "static": static,
              "not_selected": len(cand) - len(pick), "kept": len(pick)}
    stamps = np.array(ct[pick])
    stamps.setflags(write=False)
    rows = camera_order[pick]
    rows.setflags(write=False)
    why = _why_dropped(len(ct), inside, ok, cand, pick, robot_gap, min_angular_speed, int(max_pairs))
    kept_rows = {int(r) for r in camera_order}
    dropped = [(r, "its time stamp repeats the one before it (a copy, or a second pose at the same stamp)")
               for r in range(camera_rows_in) if r not in kept_rows]
    dropped += [(int(camera_order[k]), reason) for k, reason in why]
    return StreamPairs(A, cam_sel, stamps, rows, robot.unit, offset, estimate, counts, robot_gap,
                       float(min_angular_speed), tuple(warnings), tuple(sorted(dropped)))


def _why_dropped(n: int, inside: NDArray, ok: NDArray, cand: NDArray, pick: NDArray, max_gap: float,
                 min_angular_speed: float, max_pairs: int) -> list[tuple[int, str]]:
    """(sample, reason) of the camera samples (indices of the sorted stream) not kept: outside
    the robot stream, in a robot gap, static, or not selected."""
    reasons: dict[int, str] = {}
    for k in np.flatnonzero(~inside):
        reasons[int(k)] = "its stamp + the clock offset lies outside the robot stream"
    for k in np.flatnonzero(inside & ~ok):
        reasons[int(k)] = f"it falls in a gap of the robot stream wider than {max_gap * 1e3:.3g} ms"
    kept = {int(k) for k in pick}
    moving_set = {int(k) for k in cand}
    for k in range(n):
        if k in reasons or k in kept:
            continue
        reasons[k] = (f"not among the {max_pairs} well-spread stations kept" if k in moving_set else
                      f"the robot turns slower than {math.degrees(min_angular_speed):.3g} deg/s there (static)")
    return sorted(reasons.items())


def _interpolable(stamps: NDArray, times: NDArray, margin: float, max_gap: float) -> tuple[NDArray, NDArray]:
    """(inside, ok): whether every time in [t - margin, t + margin] lies within the stream's span
    (inside) and, besides, crosses no gap wider than max_gap (ok)."""
    inside = (times - margin >= stamps[0]) & (times + margin <= stamps[-1])
    _, ok = valid_times(stamps, times, max_gap)
    ok &= inside
    wide = np.flatnonzero(np.diff(stamps) > max_gap)
    for i in wide:
        ok &= ~((times - margin < stamps[i + 1]) & (times + margin > stamps[i]))
    return inside, ok
