"""Reading a cell's pose streams as its `PoseStream` settings say: a ROS bag (its topic), a
folder of one pose file per station, or a pose file (format, unit, column layout), with the
readers' messages in the cell's words (``robot.unit``, ``camera.columns``) rather than the
readers' Python keywords; and, for the plausibility checks, a stream re-read with another Euler
sequence (`rereader`).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import inverse
from handeye.io.bag_readers import is_bag, read_bag_poses
from handeye.io.pose_formats import parse_format
from handeye.io.pose_readers import PoseStack, read_pose_dir, read_poses
from handeye.workflow.cell import PoseStream


def in_cell_words(text: str, which: str) -> str:
    """A pose reader's message with its keyword asides (``unit='mm'``, ``layout=[...]``,
    ``orthonormalize=True``) in the words of stream `which` of a cell (```robot.unit: mm```)."""
    text = (text.replace("pass unit='mm' or unit='m' (CLI --unit)", f"give `{which}.unit: mm` or `{which}.unit: m`")
            .replace("with orthonormalize=True (CLI --orthonormalize)", "with `orthonormalize: true`")
            .replace(" or pass degrees=True/False (CLI --degrees/--radians)", ""))
    text = re.sub(r"but unit='(\w+)' was passed", rf"but `{which}.unit: \1` was given", text)
    return re.sub(r"layout=\[[^\]]*\] \(CLI --robot-columns / --camera-columns ([^)]*)\)",
                  rf"`{which}.columns: \1`", text)


def read_stream(stream: PoseStream, which: str, orthonormalize: bool) -> PoseStack:
    """The poses of `stream` (``which``: ``"robot"`` or ``"camera"``, for messages): a ROS bag
    (metres; its `topic` required), a folder of pose files, or a pose file (its `format`
    required). InputError naming the setting for anything wrong."""
    path = str(stream.file)
    if is_bag(path):
        if stream.topic is None:
            raise InputError(f"`{which}` {path!r} is a ROS bag: name its pose topic with `{which}.topic: TOPIC` "
                             "(or /tf:PARENT,CHILD)")
        if stream.unit not in (None, "m"):
            raise InputError(f"`{which}` {path!r}: ROS bags hold metres; drop `{which}.unit: {stream.unit}`")
        try:
            return read_bag_poses(path, stream.topic)
        except InputError as exc:
            raise InputError(f"`{which}`: {exc}") from None
    if stream.topic is not None:
        raise InputError(f"`{which}.topic` applies to ROS bags (.bag, .db3, .mcap, or a bag directory), and "
                         f"`{which}` {path!r} is none; drop it")
    if stream.format is None:
        raise InputError(f"`{which}.format` is required for the pose file {path!r} (see docs/formats.md); ROS bags "
                         "need none")
    try:
        if Path(path).is_dir():  # a folder: one pose file per station
            if stream.columns is not None:
                raise InputError(f"`{which}.columns` applies to a pose file, not to a folder of them")
            return read_pose_dir(path, stream.format, unit=stream.unit, orthonormalize=orthonormalize)
        return read_poses(path, stream.format, unit=stream.unit, orthonormalize=orthonormalize,
                          layout=None if stream.columns is None else list(stream.columns))
    except InputError as exc:
        raise InputError(f"`{which}`: {in_cell_words(str(exc), which)}") from None


def rereader(stream: PoseStream, stack: PoseStack, unit: str, orthonormalize: bool, rows: np.ndarray | None = None,
             invert: bool = False) -> Callable[[str], np.ndarray] | None:
    """For an Euler format: seq -> the file of `stream` (read as `stack`) read with that Euler
    sequence (same columns, angle unit and length unit), translations in `unit`, the paired `rows`
    only (default all), inverted if `invert`; None for other formats. The plausibility checks try
    the other sequences with it (a robot's angles read in the wrong order)."""
    fmt = parse_format(stack.format)
    if fmt.kind != "euler":
        return None
    path = str(stream.file)
    layout = None if stream.columns is None else list(stream.columns)

    def reread(seq: str) -> np.ndarray:
        other = dataclasses.replace(fmt, seq=seq, name=f"euler:{seq}")
        if Path(path).is_dir():
            read = read_pose_dir(path, other, unit=stack.unit, orthonormalize=orthonormalize)
        else:
            read = read_poses(path, other, unit=stack.unit, orthonormalize=orthonormalize, layout=layout)
        poses = read.in_unit(unit).poses
        poses = poses if rows is None else poses[rows]
        return inverse(poses) if invert else poses

    return reread
