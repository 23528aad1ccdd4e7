"""Stations as they are recorded: a robot pose file and a camera pose file that grow while a cell
records (`PoseFilePair`), read again at every poll, and the stations not seen before returned in
the A X = Y B convention a `handeye.planning.session.Session` takes.

The files are those of ``handeye calibrate`` (`handeye.workflow.cell.PoseStream` and
`CameraStream`: a pose file in any pose format, a folder of one pose file per station, a ROS bag),
read by the same reader (`handeye.workflow.reading.read_stream`), the camera's poses inverted when
the file holds T_target_cam and converted to the robot's length unit. While recording, one file
is often a pose ahead of the other, so stations pair as far as both go: ``row``: row k of both
files, up to the shorter; ``name``: the names in both files, in the robot file's order. Time
stamp matching needs the whole streams and is left to ``handeye calibrate``. A text file's last
line is read once it is complete (ends in a line break), so a line being written is not an error.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from pathlib import Path

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import inverse
from handeye.io.pose_readers import TEXT_EXTENSIONS, PoseStack
from handeye.workflow.cell_parts import SETUPS, CameraStream, PoseStream
from handeye.workflow.reading import read_stream

#: how a live pair of files pairs its poses into stations
MATCHES = ("row", "name")


class RecordingRewritten(InputError):
    """The files no longer hold the stations read before (a recorder restarted, a file replaced or
    cut short): the stations of a session are not those of these files."""


@dataclasses.dataclass(frozen=True)
class Station:
    """One station: its name (the files' name column, else ``row N``), robot pose A (4, 4)
    T_base_flange and camera pose B (4, 4) as A X = Y B takes it (eye in hand T_target_cam, eye to
    hand T_cam_target), both in `unit`."""

    name: str
    A: np.ndarray
    B: np.ndarray
    unit: str


class PoseFilePair:
    """A robot pose stream and a camera pose stream that may still grow (module docstring).

    `poll` reads both and returns the stations not returned before, in order; `signature` tells
    whether the files changed (to tell a line being written from a bad file). A file that no
    longer holds a station returned before, as it was (cut short, replaced, rewritten by a
    restarted recorder), raises `RecordingRewritten` at the next poll; `restart` forgets what was
    read, to follow the new recording from its start."""

    def __init__(self, robot: PoseStream, camera: CameraStream, setup: str, match: str = "row",
                 orthonormalize: bool = False) -> None:
        if setup not in SETUPS:
            raise InputError(f"`setup` must be one of {', '.join(SETUPS)}, got {setup!r}")
        if match not in MATCHES:
            raise InputError(f"`matching.method: {match}` does not apply to files that are still growing; use row or "
                             "name (time stamps: run handeye calibrate on the finished files)")
        robot.check("robot")
        camera.check("camera")
        for which, stream in (("robot", robot), ("camera", camera)):
            if stream.file is None:
                raise InputError(f"`{which}` is required: the {which}'s pose file")
        self.robot, self.camera, self.setup, self.match = robot, camera, setup, match
        self.orthonormalize = orthonormalize
        self.unit: str | None = None
        self.robot_format: str = robot.format or "xyz-quat-xyzw"  # the robot file's, once read
        self._seen: dict[tuple[int, int], tuple[str, np.ndarray, np.ndarray]] = {}

    def restart(self) -> None:
        """Forget the stations returned so far: the next poll returns every station of the files."""
        self._seen.clear()

    def signature(self) -> tuple[tuple[int, int], ...]:
        """(size, modification time) of both files (folders: of their entries), (-1, -1) for one
        that is missing."""
        return tuple(_signature(Path(str(s.file))) for s in (self.robot, self.camera))

    def poll(self) -> list[Station]:
        """The stations not returned before (module docstring). InputError for a file that cannot
        be read (also while a line is half written: poll again)."""
        robot = _read_complete(self.robot, "robot", self.orthonormalize)
        camera = _read_complete(self.camera, "camera", self.orthonormalize)
        if self.camera.poses == "camera-in-board":
            camera = dataclasses.replace(camera, poses=inverse(camera.poses))
        camera = camera.in_unit(robot.unit)
        self.unit, self.robot_format = robot.unit, robot.format
        pairs = self._pairs(robot, camera)
        self._check_unchanged(robot, camera, pairs)
        out = []
        for r, c in pairs:
            if (r, c) in self._seen:
                continue
            self._seen[(r, c)] = (_label(robot, r), np.array(robot.poses[r]), np.array(camera.poses[c]))
            T = np.array(camera.poses[c])
            B = inverse(T) if self.setup == "eye-in-hand" else T
            out.append(Station(_label(robot, r), np.array(robot.poses[r]), B, robot.unit))
        return out

    def _check_unchanged(self, robot: PoseStack, camera: PoseStack, pairs: list[tuple[int, int]]) -> None:
        """`RecordingRewritten` where a station returned before is gone from the files, or its
        name or poses are no longer what they were (read the same way, they are equal to the bit)."""
        now = set(pairs)
        for (r, c), (name, A, T) in self._seen.items():
            gone = (r, c) not in now
            if gone or _label(robot, r) != name or not (np.array_equal(robot.poses[r], A)
                                                         and np.array_equal(camera.poses[c], T)):
                what = ("is no longer in the files" if gone else "is no longer the pose it was")
                raise RecordingRewritten(f"the recording was rewritten: station {name} (robot row {r + 1}, camera row "
                                         f"{c + 1}) {what}, so the stations read before are not this recording's "
                                         f"(files {self.robot.file}, {self.camera.file})")

    def _pairs(self, robot: PoseStack, camera: PoseStack) -> list[tuple[int, int]]:
        if self.match == "row":
            return [(k, k) for k in range(min(len(robot), len(camera)))]
        for which, stack in (("robot", robot), ("camera", camera)):
            if stack.names is None:
                raise InputError(f"`matching.method: name`: the `{which}` file {stack.source} has no name column (e.g. "
                                 "a header 'name' or 'index'); use `matching.method: row`")
        where = {n: k for k, n in enumerate(camera.names)}
        return [(k, where[n]) for k, n in enumerate(robot.names) if n in where]


def _read_complete(stream: PoseStream, which: str, orthonormalize: bool) -> PoseStack:
    """`read_stream`, a text file up to its last complete line: a line still being written (no
    line end yet) is read at the next poll, not taken for a bad one."""
    path = Path(str(stream.file))
    if path.suffix.lower() not in TEXT_EXTENSIONS or not path.is_file():
        return read_stream(stream, which, orthonormalize)
    data = path.read_bytes()
    if not data or data.endswith(b"\n"):
        return read_stream(stream, which, orthonormalize)
    with tempfile.TemporaryDirectory() as folder:
        complete = Path(folder) / path.name
        complete.write_bytes(data[:data.rfind(b"\n") + 1])
        try:
            return dataclasses.replace(read_stream(dataclasses.replace(stream, file=str(complete)), which,
                                                   orthonormalize), source=repr(str(path)))
        except InputError as exc:
            raise InputError(str(exc).replace(str(complete), str(path))) from None


def _label(stack: PoseStack, row: int) -> str:
    return stack.names[row] if stack.names is not None else f"row {row + 1}"


def _signature(path: Path) -> tuple[int, int]:
    try:
        if path.is_dir():
            stats = [e.stat() for e in os.scandir(path)]
            return sum(s.st_size for s in stats), max((s.st_mtime_ns for s in stats), default=0)
        s = path.stat()
        return s.st_size, s.st_mtime_ns
    except OSError:
        return -1, -1
