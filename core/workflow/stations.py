"""From a cell's recorded streams to its stations: which robot pose goes with which camera pose,
by the cell's `Matching` (row, name, time or interpolate; board images in
`handeye.workflow.image_stations`), with every pose left out and why (`Dropped`), the checks
of a row pairing, and the ``matching`` entry of the result.

Pairing is where a calibration silently goes wrong (a file one row off gives an ``optimal``
answer for the wrong stations), so each method refuses what it cannot pair unambiguously and
says what it did: `pairing_checks` warns when row names or stamps disagree under ``row``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.checks.stations import Dropped
from handeye.io.pose_readers import PoseStack
from handeye.streams.station_matching import (
    default_max_dt,
    match_by_name,
    match_by_time,
)
from handeye.workflow.cell import Cell, Matching
from handeye.workflow.reading import read_stream

#: a progress callback: (stage, text), stage ``"images"`` or ``"matching"``
Log = Callable[[str, str], None]


@dataclasses.dataclass(frozen=True)
class Stations:
    """The stations of a cell.

    robot_file, camera_file: the streams as read (images: the kept images' board poses,
        T_cam_target in the robot's unit). robot: the robot poses of the stations (rows of
        robot_file, or interpolated); robot_rows: their rows in robot_file (None when
        interpolated); camera_rows: the stations' rows of camera_file. matching: the result's
        ``matching`` entry. dropped: every pose or image left out, with why. warnings: about the
        pairing. images: the image path's `handeye.workflow.image_stations.ImageStations`, or None.
    """

    robot_file: PoseStack
    camera_file: PoseStack
    robot: PoseStack
    robot_rows: np.ndarray | None
    camera_rows: np.ndarray
    matching: dict[str, Any]
    dropped: tuple[Dropped, ...]
    warnings: tuple[str, ...]
    images: Any = None

    def __len__(self) -> int:
        return len(self.robot)


def pose_stations(cell: Cell, log: Log | None = None, robot_file: PoseStack | None = None) -> Stations:
    """Read the cell's two pose streams and pair them into stations (module docstring; a cell of
    images: `handeye.workflow.image_stations`). `log` is called with what the pairing did as soon
    as it is known (the command line prints it). `robot_file`: the robot's poses when not read
    from the cell's robot file (a kinematic calibration's forward kinematics of its joints)."""
    if robot_file is None:
        robot_file = read_stream(cell.robot, "robot", cell.orthonormalize)
    camera_file = read_stream(cell.camera, "camera", cell.orthonormalize)
    if cell.matching.method == "interpolate":  # robot poses interpolated, not rows of the file
        stations = _interpolated(cell, robot_file, camera_file)  # not with joints (`Cell` refuses it)
    else:
        robot_rows, camera_rows, matching, warnings, dropped = match_rows(cell, robot_file, camera_file)
        stations = Stations(robot_file, camera_file, take(robot_file, robot_rows), robot_rows, camera_rows, matching,
                            dropped, tuple(warnings))
    if log is not None and "message" in stations.matching:
        log("matching", stations.matching["message"])
    return stations


def label(stack: PoseStack, row: int) -> str:
    """How a row of a stream is named: its name, else ``row N`` (1-based)."""
    return stack.names[row] if stack.names is not None else f"row {row + 1}"


def take(stack: PoseStack, rows: np.ndarray) -> PoseStack:
    """The poses (names, stamps) of `rows`, in that order."""
    poses = np.array(stack.poses[rows])
    poses.setflags(write=False)
    names = None if stack.names is None else tuple(stack.names[i] for i in rows)
    stamps = None if stack.stamps is None else np.array(stack.stamps)[rows]
    return dataclasses.replace(stack, poses=poses, names=names, stamps=stamps)


def pairing_checks(robot: PoseStack, camera: PoseStack, robot_path: str, camera_path: str) -> list[str]:
    """Stations are paired by row: equal counts (else an InputError); warnings when both files
    name their rows and the names differ, or both carry time stamps further apart than half the
    spacing of the stations."""
    names_differ = ""
    if robot.names is not None and camera.names is not None:
        diff = [i for i, (a, b) in enumerate(zip(robot.names, camera.names)) if a != b]
        if diff or len(robot) != len(camera):
            only_r = [n for n in robot.names if n not in set(camera.names)][:3]
            only_c = [n for n in camera.names if n not in set(robot.names)][:3]
            names_differ = "; the row names differ" + (
                f" (first at row {diff[0] + 1}: {robot.names[diff[0]]!r} vs {camera.names[diff[0]]!r})" if diff else "")
            if only_r or only_c:
                names_differ += f"; only in the robot file: {only_r}, only in the camera file: {only_c}"
    if len(robot) != len(camera):
        raise InputError(f"the robot file {robot_path!r} has {len(robot)} poses and the camera file {camera_path!r} "
                         f"has {len(camera)}; stations are paired by row, so both need one pose per station, "
                         f"in the same order{names_differ}")
    warnings = []
    if names_differ:
        warnings.append(f"stations are paired by row{names_differ}; check that row k of both files is the same station")
    if robot.stamps is not None and camera.stamps is not None and len(robot) > 1:
        gap = np.abs(np.asarray(robot.stamps) - np.asarray(camera.stamps))
        spacing = min(float(np.min(np.abs(np.diff(s)))) for s in (robot.stamps, camera.stamps))
        k = int(np.argmax(gap))
        if gap[k] > 0.5 * spacing:
            warnings.append(f"the time stamps of row {k + 1} differ by {gap[k]:.3g} s, more than half the "
                            f"{spacing:.3g} s between stations: stations are paired by row; check the order")
    return warnings


def match_rows(cell: Cell, robot: PoseStack, camera: PoseStack) -> tuple[np.ndarray, np.ndarray, dict, list[str],
                                                                       tuple[Dropped, ...]]:
    """(robot rows, camera rows, the `matching` entry of the result, warnings, dropped) of the
    cell's row, index, name or time matching of two pose streams."""
    method, camera_path = cell.matching.method, str(cell.camera.file)
    robot_path = str(cell.robot.file) if cell.robot.file is not None else robot.source
    if method in ("row", "index"):  # a pose file's rows: index and row say the same
        warnings = pairing_checks(robot, camera, robot_path, camera_path)
        rows = np.arange(len(robot))
        return rows, rows, {"method": "row", "matched": len(robot)}, warnings, ()
    if method == "name":
        missing = [f"`{w}` {p!r}" for w, p, s in (("robot", robot_path, robot), ("camera", camera_path, camera))
                   if s.names is None]
        if missing:
            raise InputError(f"`matching.method: name`: {' and '.join(missing)} has no name/index column (e.g. a "
                             "header 'name' or 'index'); use `matching.method: row` or time")
        ri, ci = match_by_name(robot.names, camera.names)
        note = f"matched {len(ri)} stations by name"
        return ri, ci, {"method": "name", "matched": len(ri), "message": note}, [], ()
    return _match_time(cell.matching, robot, camera, robot_path, camera_path)


def _match_time(matching: Matching, robot: PoseStack, camera: PoseStack, robot_path: str,
                camera_path: str) -> tuple[np.ndarray, np.ndarray, dict, list[str], tuple[Dropped, ...]]:
    missing = [f"`{w}` {p!r}" for w, p, s in (("robot", robot_path, robot), ("camera", camera_path, camera))
               if s.stamps is None]
    if missing:
        raise InputError(f"`matching.method: time`: {' and '.join(missing)} has no time stamp column (a header 't', "
                         "'time' or 'stamp', or a first column of non-integer numbers); use `matching.method: row` "
                         "or name")
    # each stream checked as interpolation checks it (`handeye.streams.timeline.checked_stream`): a stamp
    # with two different poses is ambiguous (which one was the station?), stamps in ms are not seconds
    from handeye.streams.timeline import check_same_time_unit, checked_stream

    robot_kept, robot_rows, robot_notes = checked_stream(robot, f"`robot` {robot_path!r}")
    camera_kept, camera_rows, camera_notes = checked_stream(camera, f"`camera` {camera_path!r}")
    check_same_time_unit(robot_kept.stamps, camera_kept.stamps, f"`robot` {robot_path!r}", f"`camera` {camera_path!r}")
    max_dt = default_max_dt(robot_kept.stamps) if matching.max_dt is None else matching.max_dt
    ri, ci, dt = match_by_time(robot_kept.stamps, camera_kept.stamps, max_dt)
    ri, ci = robot_rows[ri], camera_rows[ci]
    worst = float(np.max(np.abs(dt))) if len(dt) else float("nan")
    note = (f"matched {len(ci)} of {len(camera)} camera poses by time (max |dt| {worst * 1e3:.3g} ms, "
            f"limit {max_dt * 1e3:.3g} ms{'' if matching.max_dt is not None else ' = default'})")
    if len(ci) == 0:
        span = lambda t: f"{float(np.min(t)):.6g}..{float(np.max(t)):.6g} s"  # noqa: E731
        raise InputError(f"`matching.method: time`: no camera pose has a robot pose within {max_dt:.3g} s (robot "
                         f"stamps {span(robot.stamps)}, camera stamps {span(camera.stamps)}); check that both use the "
                         "same clock and unit (seconds), or raise `matching.max_dt`")
    entry = {"method": "time", "matched": len(ci), "camera_poses": len(camera), "max_dt": max_dt,
             "max_abs_dt": worst, "median_abs_dt": float(np.median(np.abs(dt))), "message": note}
    warnings = [*robot_notes, *camera_notes]
    if len(np.unique(ri)) < len(ri):
        warnings.append(f"`matching.method: time`: {len(ri) - len(np.unique(ri))} robot poses were paired with more "
                        "than one camera pose (the camera stream is faster than the robot's); fine for a moving "
                        "stream, but check `matching.max_dt`")
    kept = set(ci.tolist())
    dropped = tuple(Dropped("camera", label(camera, k), f"no robot pose within {max_dt:.3g} s of its stamp "
                                                        f"{float(camera.stamps[k]):.6f} s")
                    for k in range(len(camera)) if k not in kept)
    return ri, ci, entry, warnings, dropped


def _interpolated(cell: Cell, robot: PoseStack, camera: PoseStack) -> Stations:
    """The stations of ``matching.method: interpolate``: the robot interpolated at the kept
    camera stamps + offset (`handeye.streams.pair_streams`), in the robot's unit."""
    from handeye.streams import pair_streams

    m = cell.matching
    pairs = pair_streams(robot, camera, setup=cell.setup, camera_poses=cell.camera.poses, time_offset=m.time_offset,
                         max_offset=m.max_offset, max_gap=m.max_gap, min_angular_speed=math.radians(m.min_speed),
                         max_pairs=m.max_pairs)
    stamps = np.array(pairs.camera_stamps + pairs.offset)
    stamps.setflags(write=False)
    interpolated = dataclasses.replace(robot, poses=pairs.robot_poses, stamps=stamps, names=None)
    dropped = tuple(Dropped("camera", label(camera, row), reason) for row, reason in pairs.dropped)
    return Stations(robot, camera, interpolated, None, np.array(pairs.camera_rows), pairs.to_dict(), dropped,
                    tuple(pairs.warnings))


def reliable(matching: dict[str, Any]) -> bool:
    """False when ``interpolate`` estimated a clock offset it does not trust (its warning says why)."""
    estimate = matching.get("estimate") if matching.get("method") == "interpolate" else None
    return estimate is None or bool(estimate["reliable"])
