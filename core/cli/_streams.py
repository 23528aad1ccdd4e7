"""``handeye calibrate --match interpolate``: the flags and the glue to `handeye.streams`.

Kept apart from calibrate_cmd.py (which only adds the flags and calls `read` / `match`): reading
ROS bags (``--robot-topic`` / ``--camera-topic``), pairing two time-stamped streams with the
clock offset estimated or given, and the ``matching`` entry of the result. docs/streams.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

import numpy as np

from handeye.framework.errors import InputError
from handeye.io.bag_readers import is_bag, read_bag_poses
from handeye.io.pose_readers import PoseStack
from handeye.streams import MAX_OFFSET, MAX_PAIRS, MIN_ANGULAR_SPEED, pair_streams

#: the --match value of this module
INTERPOLATE = "interpolate"
#: flags that apply to --match interpolate only (dest, flag)
_ONLY_INTERPOLATE = (("time_offset", "--time-offset"), ("max_offset", "--max-offset"), ("max_gap", "--max-gap"),
                     ("min_speed", "--min-speed"), ("max_pairs", "--max-pairs"))


def add_flags(parser: argparse.ArgumentParser) -> None:
    """The stream flags of handeye calibrate."""
    parser.add_argument("--time-offset", metavar="auto|SECONDS",
                        help="--match interpolate: the clock offset, t_robot = t_camera + offset; 'auto' (default) "
                             "estimates it (cross-correlation of the angular speeds, refined on the residuals)")
    parser.add_argument("--max-offset", type=float, metavar="SECONDS",
                        help=f"--match interpolate: search the offset within +-SECONDS (default {MAX_OFFSET:g})")
    parser.add_argument("--max-gap", type=float, metavar="SECONDS",
                        help="--match interpolate: largest spacing of robot samples interpolated across (default "
                             "3 x the robot's median interval); camera stamps in wider gaps are dropped")
    parser.add_argument("--min-speed", type=float, metavar="DEG_PER_S",
                        help="--match interpolate: drop stations where the robot turns slower (default "
                             f"{math.degrees(MIN_ANGULAR_SPEED):g} deg/s)")
    parser.add_argument("--max-pairs", type=int, metavar="N",
                        help=f"--match interpolate: keep at most N well-spread stations (default {MAX_PAIRS})")
    parser.add_argument("--robot-topic", metavar="TOPIC",
                        help="--robot is a ROS bag: its pose topic (PoseStamped, TransformStamped, "
                             "PoseWithCovarianceStamped, Odometry) or /tf:PARENT,CHILD")
    parser.add_argument("--camera-topic", metavar="TOPIC", help="--camera is a ROS bag: its pose topic, as --robot-topic")


def read(path: str, which: str, topic: str | None, unit: str | None) -> PoseStack | None:
    """The stream of a ROS bag (metres), or None when `path` is no bag (read it as a pose file).
    `which` is ``robot`` or ``camera`` (for the flags named in messages)."""
    if not is_bag(path):
        if topic is not None:
            raise InputError(f"--{which}-topic applies to ROS bags (.bag, .db3, .mcap, or a bag directory), and "
                             f"--{which} {path!r} is none; drop it")
        return None
    if topic is None:
        raise InputError(f"--{which} {path!r} is a ROS bag: name its pose topic with --{which}-topic TOPIC "
                         "(or /tf:PARENT,CHILD)")
    if unit not in (None, "m"):
        raise InputError(f"--{which} {path!r}: ROS bags hold metres; drop --{which}-unit {unit}")
    try:
        return read_bag_poses(path, topic)
    except InputError as exc:
        raise InputError(f"--{which}: {exc}") from None


def check_format(flag: str, fmt: str | None, path: str) -> bool:
    """Whether `fmt` needs parsing: a ROS bag needs no format flag, a pose file does."""
    if is_bag(path):
        return fmt is not None
    if fmt is None:
        raise InputError(f"{flag} is required for the pose file {path!r} (see docs/formats.md); ROS bags need none")
    return True


def check_flags(args: argparse.Namespace) -> None:
    """InputError when a stream flag is given without --match interpolate."""
    if args.match == INTERPOLATE:
        if getattr(args, "max_dt", None) is not None:
            raise InputError("--max-dt applies to --match time; with --match interpolate use --max-gap")
        return
    given = [flag for dest, flag in _ONLY_INTERPOLATE if getattr(args, dest, None) is not None]
    if given:
        raise InputError(f"{', '.join(given)} apply to --match interpolate; drop them or use --match interpolate")


def _time_offset(text: str | None) -> float | str:
    if text is None or text.strip().lower() == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--time-offset must be 'auto' or a number of seconds, got {text!r}") from None
    if not math.isfinite(value):
        raise InputError(f"--time-offset must be a finite number of seconds, got {text!r}")
    return value


def match(args: argparse.Namespace, robot: PoseStack, camera: PoseStack) -> tuple[PoseStack, np.ndarray, dict[str, Any], list[str]]:
    """(the robot interpolated at the kept camera stamps + offset, as a PoseStack in the robot's
    unit; the kept camera rows; the `matching` entry; warnings) of --match interpolate."""
    pairs = pair_streams(
        robot, camera, setup=args.setup, camera_poses=args.camera_poses, time_offset=_time_offset(args.time_offset),
        max_offset=MAX_OFFSET if args.max_offset is None else args.max_offset, max_gap=args.max_gap,
        min_angular_speed=MIN_ANGULAR_SPEED if args.min_speed is None else math.radians(args.min_speed),
        max_pairs=MAX_PAIRS if args.max_pairs is None else args.max_pairs)
    stamps = np.array(pairs.camera_stamps + pairs.offset)
    stamps.setflags(write=False)
    interpolated = dataclasses.replace(robot, poses=pairs.robot_poses, stamps=stamps, names=None)
    return interpolated, np.array(pairs.camera_rows), pairs.to_dict(), list(pairs.warnings)


def reliable(matching: dict[str, Any]) -> bool:
    """False when --match interpolate estimated a clock offset it does not trust (its warning says why)."""
    estimate = matching.get("estimate") if matching.get("method") == INTERPOLATE else None
    return estimate is None or bool(estimate["reliable"])
