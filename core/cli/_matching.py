"""``handeye calibrate``: from the files read to the stations, i.e. which robot pose goes with which
camera pose (``--match row | name | time``, ``--match interpolate`` in `_streams`, board images in
`_images`), with the checks and the ``matching`` entry of the result.

Kept apart from calibrate_cmd.py, which reads flags and writes results.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from handeye.cli import _images, _streams
from handeye.framework.errors import InputError
from handeye.io.pose_readers import PoseStack
from handeye.streams.station_matching import (
    default_max_dt,
    match_by_name,
    match_by_time,
)


def stations(args: argparse.Namespace, from_images: bool, read: Callable[..., PoseStack]) -> tuple[Any, ...]:
    """(images or None, robot file, camera file, robot poses of the stations, their rows in the
    robot file (None when interpolated), the camera rows, the matching entry, warnings)."""
    if from_images:  # board images: the kept images' board poses are the camera stream
        images = _images.load(args, read)
        robot_rows, camera_rows, matching, warnings = (images.robot_rows, images.camera_rows, images.matching,
                                                       images.warnings)
        robot = take(images.robot_file, robot_rows)
        return images, images.robot_file, images.camera_file, robot, robot_rows, camera_rows, matching, warnings
    robot_file = (_streams.read(args.robot, "robot", args.robot_topic, args.robot_unit)
                  or read(args.robot, args.robot_format, args.robot_unit, args.orthonormalize, "robot",
                          args.robot_columns))
    camera_file = (_streams.read(args.camera, "camera", args.camera_topic, args.camera_unit)
                   or read(args.camera, args.camera_format, args.camera_unit, args.orthonormalize, "camera",
                           args.camera_columns))
    if args.match == _streams.INTERPOLATE:  # robot poses interpolated, not rows of the file
        robot, camera_rows, matching, warnings = _streams.match(args, robot_file, camera_file)
        robot_rows = None
    else:
        robot_rows, camera_rows, matching, warnings = match_rows(args, robot_file, camera_file)
        robot = take(robot_file, robot_rows)
    return None, robot_file, camera_file, robot, robot_rows, camera_rows, matching, warnings


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


def take(stack: PoseStack, rows: np.ndarray) -> PoseStack:
    """The poses (names, stamps) of `rows`, in that order."""
    poses = np.array(stack.poses[rows])
    poses.setflags(write=False)
    names = None if stack.names is None else tuple(stack.names[i] for i in rows)
    stamps = None if stack.stamps is None else np.array(stack.stamps)[rows]
    return dataclasses.replace(stack, poses=poses, names=names, stamps=stamps)


def match_rows(args: argparse.Namespace, robot: PoseStack, camera: PoseStack) -> tuple[np.ndarray, np.ndarray, dict, list[str]]:
    """(robot rows, camera rows, the `matching` entry of the result, warnings) of --match."""
    if args.max_dt is not None and args.match != "time":
        raise InputError("--max-dt applies to --match time; drop it")
    if args.match == "row":
        warnings = pairing_checks(robot, camera, args.robot, args.camera)
        rows = np.arange(len(robot))
        return rows, rows, {"method": "row", "matched": len(robot)}, warnings
    if args.match == "name":
        missing = [f"--{w} {p!r}" for w, p, s in (("robot", args.robot, robot), ("camera", args.camera, camera))
                   if s.names is None]
        if missing:
            raise InputError(f"--match name: {' and '.join(missing)} has no name/index column (e.g. a header "
                             "'name' or 'index'); use --match row or time")
        ri, ci = match_by_name(robot.names, camera.names)
        note = f"matched {len(ri)} stations by name"
        return ri, ci, {"method": "name", "matched": len(ri), "message": note}, []
    missing = [f"--{w} {p!r}" for w, p, s in (("robot", args.robot, robot), ("camera", args.camera, camera))
               if s.stamps is None]
    if missing:
        raise InputError(f"--match time: {' and '.join(missing)} has no time stamp column (a header 't', 'time' or "
                         "'stamp', or a first column of non-integer numbers); use --match row or name")
    max_dt = default_max_dt(robot.stamps) if args.max_dt is None else args.max_dt
    ri, ci, dt = match_by_time(robot.stamps, camera.stamps, max_dt)
    worst = float(np.max(np.abs(dt))) if len(dt) else float("nan")
    note = (f"matched {len(ci)} of {len(camera)} camera poses by time (max |dt| {worst * 1e3:.3g} ms, "
            f"limit {max_dt * 1e3:.3g} ms{'' if args.max_dt is not None else ' = default'})")
    if len(ci) == 0:
        span = lambda t: f"{float(np.min(t)):.6g}..{float(np.max(t)):.6g} s"
        raise InputError(f"--match time: no camera pose has a robot pose within {max_dt:.3g} s (robot stamps "
                         f"{span(robot.stamps)}, camera stamps {span(camera.stamps)}); check that both use the "
                         "same clock and unit (seconds), or raise --max-dt")
    entry = {"method": "time", "matched": len(ci), "camera_poses": len(camera), "max_dt": max_dt,
             "max_abs_dt": worst, "median_abs_dt": float(np.median(np.abs(dt))), "message": note}
    warnings = []
    if len(np.unique(ri)) < len(ri):
        warnings.append(f"--match time: {len(ri) - len(np.unique(ri))} robot poses were paired with more than "
                        "one camera pose (the camera stream is faster than the robot's); fine for a moving "
                        "stream, but check --max-dt")
    return ri, ci, entry, warnings
