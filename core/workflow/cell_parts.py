"""The parts of a `handeye.workflow.cell.Cell`, each a small frozen value: the robot's pose
stream (`PoseStream`) or its joint readings (`JointStream`), the camera's (`CameraStream`) or its
board images (`Images`), how the two pair into stations (`Matching`) and where the command line
writes (`Outputs`); the names each
setting may take; and the checks that name a setting in its messages as the cell file spells it
(```robot.unit```). `Cell` checks its parts when it is built (a part alone does not know
whether it is the robot's or the camera's).

The defaults of `Matching`'s interpolation settings are the stream pairing's own
(`handeye.streams`), read here so that they are defined once.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
from collections.abc import Sequence
from typing import Any

from handeye.base.errors import InputError, shown
from handeye.base.vocabulary import ANGLE_UNITS, LENGTH_UNITS, PAIRINGS, SETUPS  # noqa: F401 (the cell's words, named here too)

#: the setups: camera on the flange (board fixed), or camera fixed (board on the flange)
#: what a camera pose file holds: T_cam_target (as solvePnP gives it) or T_target_cam
CAMERA_POSES = ("board-in-camera", "camera-in-board")
#: length units of pose files
UNITS = LENGTH_UNITS
#: how robot and camera poses pair into stations (`Matching.method`)
MATCH_METHODS = ("row", "index", "name", "time", "interpolate")
#: the methods of board images: row and index both pair the k-th image with the k-th robot pose
IMAGE_MATCHES = {"row": "index", "index": "index", "name": "name", "time": "time"}
#: motions between stations for axxb: every pair i < j, or consecutive stations only
#: facts about the cell (not solver options) that the problem's validation also reads
FACTS = ("tz_X", "tz_Y", "camera_scale")
#: the interpolation settings of `Matching`, which apply to ``method: interpolate`` only
INTERPOLATE_ONLY = ("time_offset", "max_offset", "max_gap", "min_speed", "max_pairs")


def _max_offset() -> float:
    from handeye.streams.pairing import MAX_OFFSET

    return MAX_OFFSET


def _min_speed() -> float:
    from handeye.streams.selection import MIN_ANGULAR_SPEED

    return math.degrees(MIN_ANGULAR_SPEED)


def _max_pairs() -> int:
    from handeye.streams.selection import MAX_PAIRS

    return MAX_PAIRS


def check_path(value: Any, field: str) -> str | None:
    """A path setting as text (None stays None); InputError for anything but a non-empty path."""
    if value is None:
        return None
    if isinstance(value, (str, os.PathLike)) and str(os.fspath(value)).strip():
        return os.fspath(value)
    raise InputError(f"`{field}` must be the path of a file or folder, got {shown(value)}")


def check_text(value: Any, field: str) -> str | None:
    """InputError unless `value` is None or a non-empty text; `field` names the setting."""
    if value is None or (isinstance(value, str) and value.strip()):
        return value
    raise InputError(f"`{field}` must be a non-empty text, got {shown(value)}")


def check_choice(value: Any, choices: Sequence[str], field: str, optional: bool = False) -> None:
    """InputError unless `value` is one of `choices` (or None when `optional`)."""
    if (value is None and optional) or (isinstance(value, str) and value in choices):
        return
    raise InputError(f"`{field}` must be one of {', '.join(choices)}, got {shown(value)}")


def check_number(value: Any, field: str, *, low: float = -math.inf, strict: bool = False, what: str = "number") -> None:
    """InputError unless `value` is None or a finite real above `low` (at least `low` unless strict)."""
    if value is None:
        return
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok and (value > low if strict else value >= low):
        return
    bound = "" if low == -math.inf else f" {'>' if strict else '>='} {low:g}"
    raise InputError(f"`{field}` must be a finite {what}{bound}, got {shown(value)}")


def check_flag(value: Any, field: str) -> None:
    """InputError unless `value` is True or False."""
    if not isinstance(value, bool):
        raise InputError(f"`{field}` must be true or false, got {shown(value)}")


@dataclasses.dataclass(frozen=True)
class PoseStream:
    """A stream of poses: a pose file (.csv .tsv .txt .json .yaml .npz), a folder of one pose
    file per station (ROS-Industrial's ``poses/N.yaml``; robot only), or a ROS bag.

    file: the path. format: the pose format (``fanuc-wpr``, ``xyz-quat-xyzw``, ``opencv-rvec``,
        ``matrix``, ``euler:ZYX:deg``, ...; docs/formats.md), required for pose files, not for
        bags. unit: ``mm`` or ``m`` (default: the unit the file states, else the robot maker's).
    columns: what each column of the file holds, in file order (the format's fields, ``t``,
        ``name``, ``-``), e.g. ``("qw", "qx", "qy", "qz", "x", "y", "z")`` or the same as one
        comma-separated text; default: by header, else by position.
    topic: a ROS bag's pose topic (or ``/tf:PARENT,CHILD``).
    """

    file: str | os.PathLike | None = None
    format: str | None = None
    unit: str | None = None
    columns: tuple[str, ...] | str | None = None
    topic: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.file, os.PathLike):
            object.__setattr__(self, "file", os.fspath(self.file))
        if isinstance(self.columns, str):
            object.__setattr__(self, "columns", tuple(c.strip() for c in self.columns.split(",")))
        elif isinstance(self.columns, (list, tuple)):
            object.__setattr__(self, "columns", tuple(self.columns))

    def check(self, name: str) -> None:
        """InputError naming `name` (``robot``, ``camera``) for a value no stream can have."""
        check_path(self.file, f"{name}.file")
        check_text(self.format, f"{name}.format")
        if self.format is not None:
            from handeye.io.pose_formats import parse_format

            try:
                parse_format(self.format)
            except InputError as exc:
                raise InputError(f"`{name}.format`: {exc}") from None
        check_choice(self.unit, UNITS, f"{name}.unit", optional=True)
        if self.columns is not None and (not isinstance(self.columns, tuple) or not self.columns
                                         or not all(isinstance(c, str) and c for c in self.columns)):
            raise InputError(f"`{name}.columns` must list what each column of the file holds, e.g. "
                             f"qw,qx,qy,qz,x,y,z (t: time stamps, name: names, -: skip), got {shown(self.columns)}")
        check_text(self.topic, f"{name}.topic")

    def given(self) -> list[str]:
        """The names of the settings given (not None)."""
        return [f.name for f in dataclasses.fields(self) if getattr(self, f.name) != f.default]


@dataclasses.dataclass(frozen=True)
class CameraStream(PoseStream):
    """The camera's board poses, one per station (a `PoseStream`).

    poses: what the file holds: ``board-in-camera`` (default), the board's pose in the camera
        frame T_cam_target, as ``cv2.solvePnP`` gives it; ``camera-in-board``, the camera's pose
        in the board frame T_target_cam (e.g. a tracked camera), inverted on reading.
    """

    poses: str = "board-in-camera"

    def check(self, name: str) -> None:
        """As `PoseStream.check`, and what the file holds (`poses`)."""
        super().check(name)
        check_choice(self.poses, CAMERA_POSES, f"{name}.poses")


@dataclasses.dataclass(frozen=True)
class ObservationStream(CameraStream):
    """A source of observations of a cell with several cameras and targets: a table (`handeye.io.
    observation_tables`), a row per (station, camera, target) with the camera's pose of the
    target, in pose format `format` (a `CameraStream`: unit, columns, poses as for one camera); or
    one camera's board images (`images`), every board found in an image one observation.

    camera: the camera whose poses the file holds, when it holds one camera's (one file per
    camera); None: the table names each row's camera in a ``camera`` column. Required with images.
    images: instead of `file`, the camera's folder of images, one per station (paired with the
    robot's poses by the cell's `matching`, as one camera's images are). intrinsics: the camera's
    intrinsics file (default: calibrated from the boards found). targets: the names of the cell's
    targets (`Cell.targets`) this camera looks for (default: all of them).
    """

    camera: str | None = None
    images: str | os.PathLike | None = None
    intrinsics: str | os.PathLike | None = None
    targets: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("images", "intrinsics"):
            if isinstance(getattr(self, name), os.PathLike):
                object.__setattr__(self, name, os.fspath(getattr(self, name)))
        if isinstance(self.targets, str):
            object.__setattr__(self, "targets", tuple(t.strip() for t in self.targets.split(",")))
        elif isinstance(self.targets, (list, tuple)):
            object.__setattr__(self, "targets", tuple(self.targets))

    @property
    def source(self) -> str | None:
        """The table file, or the image folder."""
        return self.file if self.images is None else self.images

    def check(self, name: str) -> None:
        """As `CameraStream.check`, the file required (a format only for text tables), and the
        camera's name; with `images`, no setting of a pose file and the camera named."""
        if self.images is not None:
            self._check_images(name)
            return
        super().check(name)
        if self.file is None:
            raise InputError(f"`{name}.file: FILE` is required: the table of observations (or `{name}.images: DIR`, "
                             "the camera's images)")
        check_text(self.camera, f"{name}.camera")
        if self.topic is not None:
            raise InputError(f"`{name}.topic` applies to ROS bags; a table of observations is a file: drop it")
        for key in ("intrinsics", "targets"):
            if getattr(self, key) is not None:
                raise InputError(f"`{name}.{key}` applies to `{name}.images`, a camera's images; a table gives the "
                                 "poses: drop it")

    def _check_images(self, name: str) -> None:
        """A camera's images: named camera, no pose-file settings, targets a non-empty list of names."""
        check_path(self.images, f"{name}.images")
        check_path(self.intrinsics, f"{name}.intrinsics")
        stray = [g for g in ("file", "format", "unit", "columns", "topic") if getattr(self, g) is not None]
        if self.poses != "board-in-camera":
            stray.append("poses")
        if stray:
            raise InputError(f"`{name}.{stray[0]}` applies to a table of observations; `{name}.images` gives the "
                             "poses from the images (board poses by PnP, in the robot's unit): drop it")
        if self.camera is None:
            raise InputError(f"`{name}.camera: NAME` is required with `{name}.images`: the name of the camera that "
                             "took the images")
        check_text(self.camera, f"{name}.camera")
        if self.targets is not None and (not self.targets or not all(isinstance(t, str) and t.strip()
                                                                     for t in self.targets)):
            raise InputError(f"`{name}.targets` must list names of the cell's `targets`, got {shown(self.targets)}")


#: the angle units of joint readings (`JointStream.unit`)
JOINT_UNITS = ANGLE_UNITS


@dataclasses.dataclass(frozen=True)
class JointStream:
    """The robot's joint readings, one row per station (`handeye.io.joint_files`): a text table
    with a header (a name and/or time-stamp column, one column per joint) or a ROS bag.

    file: the path. unit: ``deg`` or ``rad``, required for a table (a ROS bag holds radians).
    topic: a ROS bag's ``sensor_msgs/JointState`` topic (e.g. ``/joint_states``).
    """

    file: str | os.PathLike | None = None
    unit: str | None = None
    topic: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.file, os.PathLike):
            object.__setattr__(self, "file", os.fspath(self.file))

    def check(self) -> None:
        """InputError for a value no joint stream can have, or one without its file."""
        check_path(self.file, "joints.file")
        if self.file is None:
            raise InputError("`joints.file: FILE` is required: the robot's joint readings, one row per station (a "
                             "table with a header, or a ROS bag)")
        check_choice(self.unit, JOINT_UNITS, "joints.unit", optional=True)
        check_text(self.topic, "joints.topic")


@dataclasses.dataclass(frozen=True)
class Images:
    """Board images instead of camera poses: one image per station.

    folder: the folder of images. board: the board spec (``chessboard:9x6:25mm``,
        ``charuco:5x7:36.195mm:18.256mm:DICT_6X6_250``, ``circlegrid:10x10:25.4mm``, or a board
        file; docs/boards.md). intrinsics: the camera's intrinsics file (OpenCV YAML/XML/JSON, ROS
        camera_info, industrial_calibration cal_data.yaml); default: calibrated from the images.
    """

    folder: str | os.PathLike | None = None
    board: str | None = None
    intrinsics: str | os.PathLike | None = None

    def __post_init__(self) -> None:
        for name in ("folder", "intrinsics"):
            if isinstance(getattr(self, name), os.PathLike):
                object.__setattr__(self, name, os.fspath(getattr(self, name)))
        if isinstance(self.board, os.PathLike):  # a board file
            object.__setattr__(self, "board", os.fspath(self.board))

    def check(self) -> None:
        """InputError for a value no image set can have (whether it is complete: `Cell`)."""
        check_path(self.folder, "images.folder")
        check_text(self.board, "images.board")
        check_path(self.intrinsics, "images.intrinsics")


@dataclasses.dataclass(frozen=True)
class Matching:
    """How robot and camera poses pair into stations (docs/calibrate.md, docs/streams.md).

    method: ``row`` (default): row k of both files is station k (board images: the k-th image in
        natural order); ``index``: the same; ``name``: equal name columns (images: file stem =
        robot pose name); ``time``: each camera pose (image) with the robot pose at the nearest
        time stamp within `max_dt`; ``interpolate``: the robot stream interpolated at each camera
        stamp + the clock offset (pose streams only).
    max_dt: ``time``: largest |camera stamp - robot stamp| paired, seconds (default: half the
        median interval between robot stamps, or 0.02 s with fewer than two robot stamps).
    time_offset: ``interpolate``: the clock offset t_robot = t_camera + offset in seconds, or
        ``"auto"`` (default) to estimate it. max_offset: its search range +-seconds. max_gap:
        largest robot sample spacing interpolated across, seconds (default 3 x the robot's median
        interval). min_speed: stations where the robot turns slower (deg/s) are dropped.
        max_pairs: at most this many well-spread stations are kept.
    """

    method: str = "row"
    max_dt: float | None = None
    time_offset: float | str = "auto"
    max_offset: float = dataclasses.field(default_factory=_max_offset)
    max_gap: float | None = None
    min_speed: float = dataclasses.field(default_factory=_min_speed)
    max_pairs: int = dataclasses.field(default_factory=_max_pairs)

    def __post_init__(self) -> None:
        if isinstance(self.time_offset, str) and self.time_offset.strip().lower() != "auto":
            try:
                object.__setattr__(self, "time_offset", float(self.time_offset))
            except ValueError:
                raise InputError(f"`matching.time_offset` must be 'auto' or a number of seconds, got "
                                 f"{shown(self.time_offset)}") from None
        elif isinstance(self.time_offset, str):
            object.__setattr__(self, "time_offset", "auto")

    def given(self) -> list[str]:
        """The settings that differ from their defaults, in field order."""
        default = Matching()
        return [f.name for f in dataclasses.fields(self) if getattr(self, f.name) != getattr(default, f.name)]

    def check(self, images: bool) -> None:
        """InputError for a value no matching can have, or a setting of another method than
        `method`; `images`: the camera's side is board images."""
        check_choice(self.method, MATCH_METHODS, "matching.method")
        check_number(self.max_dt, "matching.max_dt", low=0.0, what="number of seconds")
        if not isinstance(self.time_offset, str):
            check_number(self.time_offset, "matching.time_offset", what="number of seconds (or 'auto')")
        check_number(self.max_offset, "matching.max_offset", low=0.0, strict=True, what="number of seconds")
        check_number(self.max_gap, "matching.max_gap", low=0.0, strict=True, what="number of seconds")
        check_number(self.min_speed, "matching.min_speed", low=0.0, what="angular speed in deg/s")
        from handeye.streams.pairing import MIN_STATIONS

        if (isinstance(self.max_pairs, bool) or not isinstance(self.max_pairs, numbers.Integral)
                or self.max_pairs < MIN_STATIONS):
            raise InputError(f"`matching.max_pairs` must be a whole number >= {MIN_STATIONS}, got "
                             f"{shown(self.max_pairs)}")
        if self.method == "interpolate":
            if images:
                raise InputError("`matching.method: interpolate` applies to pose streams; with `images` use name, "
                                 "index or time")
            if self.max_dt is not None:
                raise InputError("`matching.max_dt` applies to `matching.method: time`; with `matching.method: "
                                 "interpolate` use `matching.max_gap`")
            return
        given = [name for name in self.given() if name in INTERPOLATE_ONLY]
        if given:
            raise InputError(f"{', '.join(f'`matching.{g}`' for g in given)} apply to `matching.method: "
                             "interpolate`; drop them or use `matching.method: interpolate`")
        if self.max_dt is not None and self.method != "time":
            raise InputError("`matching.max_dt` applies to `matching.method: time`; drop it")


@dataclasses.dataclass(frozen=True)
class Outputs:
    """Where ``handeye calibrate`` writes the result: `json` (``-o``), `yaml` (``--yaml``) and
    `report` (``--report``, .html or .md), and for a kinematic calibration `arm` (``--arm-out``, the
    corrected DH table). ``handeye.calibrate`` writes nothing itself; its result has ``to_json()``,
    ``to_yaml()``, ``write_report(path)`` and ``arm_yaml()``."""

    json: str | os.PathLike | None = None
    yaml: str | os.PathLike | None = None
    report: str | os.PathLike | None = None
    #: a kinematic calibration (`Cell.joints`): the corrected DH table as an arm file (``--arm-out``)
    arm: str | os.PathLike | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if isinstance(getattr(self, f.name), os.PathLike):
                object.__setattr__(self, f.name, os.fspath(getattr(self, f.name)))

    def check(self) -> None:
        """InputError unless each output is a path or None."""
        for f in dataclasses.fields(self):
            check_path(getattr(self, f.name), f"outputs.{f.name}")
