"""Tables of observations: a cell of several cameras and targets as one long table, a row per
(station, camera, target) with the camera's pose of the target (T_cam_target, as solvePnP gives
it), or one such file per camera (its camera then named by the caller).

Forms (docs/formats.md, "Tables of observations"):

- text (.csv .tsv .txt) with a header: ``station`` (the station's id: the robot pose file's
  name/index column, or its 0-based row), ``camera`` (or ``sensor``; optional in a file of one
  camera's poses), ``target`` (or ``marker``, ``board``), and the pose's columns in the table's
  pose format, found by header as the pose readers find them (`handeye.io.pose_readers`);
- JSON / NPZ (as handeye's data files, `handeye.io.data_files`): arrays ``station``, ``camera``,
  ``target`` (text), ``camera_poses`` (m, 4, 4) and ``units``.

A repeated (station, camera, target) is an error naming both rows: one observation is one pose.

A table may also carry the robot's pose of each row's station, instead of a robot pose file:
text columns ``robot_<field>`` in the robot's pose format (``robot_x, robot_y, robot_z, robot_qx,
...`` for ``xyz-quat-xyzw``), or ``robot_poses`` (m, 4, 4) in a JSON / NPZ table (its ``units``).
The rows of one station must then agree on its pose (`robot_of_stations`: one station is one robot
pose; a conflict is an error naming both rows).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.io.input_files import check_not_looping, load_json
from handeye.io.npz import load_npz
from handeye.io.pose_formats import normalise_header
from handeye.io.pose_readers import (
    TEXT_EXTENSIONS,
    PoseStack,
    poses_from_rows,
    read_poses,
)
from handeye.io.pose_tables import read_text

#: the id columns of a table and the header names each is found by (case-insensitive)
ID_COLUMNS = {"station": ("station", "station_id", "stationid"),
              "camera": ("camera", "sensor", "cam", "camera_name", "sensor_name"),
              "target": ("target", "marker", "board", "target_name", "marker_name", "board_name")}
#: the extensions of a table
EXTENSIONS = (*TEXT_EXTENSIONS, ".json", ".npz")
#: the keys of a JSON / NPZ table
ARRAY_KEYS = ("station", "camera", "target", "camera_poses", "robot_poses", "units")
#: the prefix of a text table's robot pose columns
ROBOT_PREFIX = "robot_"
#: two rows' robot poses of one station agree when their rotations differ by less than this
#: (radians) and their translations by less than this times (1 + |t|): written from the same numbers
SAME_POSE_TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class ObservationTable:
    """One file's observations: station, camera, target (m,) names; poses: the camera's pose of
    the target per row (`PoseStack`, T_cam_target as the file holds it, its unit); where: each row's place in the file (``line 4``, ``row 3``), for messages; source: the file; robot: the robot's pose
    per row (T_base_flange, its unit) when the table carries it, else None."""

    station: tuple[str, ...]
    camera: tuple[str, ...]
    target: tuple[str, ...]
    poses: PoseStack
    where: tuple[str, ...]
    source: str
    robot: PoseStack | None = None

    def __len__(self) -> int:
        return len(self.station)


def read_observation_table(path: str | Path, format: str | None, *, unit: str | None = None,
                           camera: str | None = None, orthonormalize: bool = False,
                           columns: Sequence[str] | None = None, robot_format: str | None = None,
                           robot_unit: str | None = None) -> ObservationTable:
    """The observations of file `path` (module docstring). format: the pose format of a text
    table's pose columns (JSON / NPZ hold 4x4 matrices); unit: its length unit (default: the
    file's ``units``); camera: the camera of every row when the file holds one camera's poses
    (then a camera column, if any, must name it); columns: what each column holds, in file order
    (``station``, ``camera``, ``target``, the format's fields, ``robot_`` + the robot format's
    fields, ``-``), default: by header; robot_format / robot_unit: the pose format and unit of a
    text table's robot columns (module docstring)."""
    path = Path(path)
    src = repr(str(path))
    ext = path.suffix.lower()
    if ext not in EXTENSIONS:
        raise InputError(f"table of observations {src}: unsupported extension {ext or '(none)'!r}; use "
                         f"{', '.join(EXTENSIONS)}")
    check_not_looping(path, "table of observations")
    if not path.is_file():
        raise InputError(f"table of observations not found: {src}")
    if ext in TEXT_EXTENSIONS:
        if format is None:
            raise InputError(f"table of observations {src}: give its pose format (e.g. opencv-rvec for solvePnP's "
                             "tvec and rvec columns; docs/formats.md)")
        table = _text_table(path, src, format, unit, orthonormalize, columns)
        table = dataclasses.replace(table, robot=_robot_columns(path, src, columns, robot_format, robot_unit,
                                                                orthonormalize))
    else:
        table = _array_table(path, src, ext, unit)
    return _finished(table, camera, src)


def _column(header: Sequence[str], key: str) -> int | None:
    names = [normalise_header(h) for h in header]
    hits = [i for i, n in enumerate(names) if n in ID_COLUMNS[key]]
    return hits[0] if hits else None


def _text_table(path: Path, src: str, format: str, unit: str | None, orthonormalize: bool,
                columns: Sequence[str] | None) -> ObservationTable:
    raw = read_text(path, src, None)
    header = tuple(columns) if columns is not None else raw.header
    if header is None:
        raise InputError(f"table of observations {src}: no header line; name its columns (station, camera, target, "
                         "then the pose's columns, e.g. x,y,z,rx,ry,rz for opencv-rvec)")
    if len(header) != len(raw.rows[0]):
        raise InputError(f"table of observations {src}: {len(header)} column names for {len(raw.rows[0])} columns")
    at = {key: _column(header, key) for key in ID_COLUMNS}
    for key in ("station", "target"):
        if at[key] is None:
            raise InputError(f"table of observations {src}: missing column {key!r} (header: {', '.join(header)}); "
                             f"name it {' or '.join(repr(n) for n in ID_COLUMNS[key][:3])}")
    ids = {i for i in at.values() if i is not None}
    layout = ["name" if i == at["station"] else "-" if i in ids or _is_robot(h) else h for i, h in enumerate(header)]
    poses = read_poses(path, format, unit=unit, layout=layout, orthonormalize=orthonormalize)
    text = lambda i: tuple(row[i] for row in raw.rows)  # noqa: E731
    return ObservationTable(text(at["station"]), () if at["camera"] is None else text(at["camera"]),
                            text(at["target"]), poses, tuple(raw.where), str(path))


def _is_robot(header: str) -> bool:
    return normalise_header(header).startswith(ROBOT_PREFIX)


def _robot_columns(path: Path, src: str, columns: Sequence[str] | None, format: str | None, unit: str | None,
                   orthonormalize: bool) -> PoseStack | None:
    """The robot poses of a text table's ``robot_*`` columns (None when it has none)."""
    header = tuple(columns) if columns is not None else read_text(path, src, None).header
    if not any(_is_robot(h) for h in header):
        return None
    if format is None:
        raise InputError(f"table of observations {src} has robot pose columns ({', '.join(h for h in header if _is_robot(h))})"
                         "; give their pose format as `robot.format`")
    layout = [normalise_header(h)[len(ROBOT_PREFIX):] if _is_robot(h) else "-" for h in header]
    try:
        return read_poses(path, format, unit=unit, layout=layout, orthonormalize=orthonormalize)
    except InputError as exc:
        raise InputError(f"the robot pose columns of {exc}") from None


def robot_of_stations(tables: Sequence[ObservationTable], unit: str | None = None) -> PoseStack:
    """One robot pose per station from tables that carry them (module docstring), stations in the
    order they first appear, named by their ids; in `unit` (default: the first table's robot unit).
    InputError naming the table without robot poses, or both rows of a station whose poses differ."""
    missing = [t.source for t in tables if t.robot is None]
    if missing:
        raise InputError(f"table of observations {missing[0]!r} has no robot pose columns (robot_x, robot_y, ...; "
                         "JSON/NPZ: robot_poses) and the cell names no robot pose file; give `robot.file` or the "
                         "robot's pose in every row")
    unit = unit or tables[0].robot.unit
    first: dict[str, tuple[np.ndarray, str]] = {}
    for t in tables:
        for station, where, T in zip(t.station, t.where, t.robot.in_unit(unit).poses):
            if station not in first:
                first[station] = (T, f"{t.source!r} {where}")
                continue
            T0, where0 = first[station]
            cos = np.clip((np.trace(T0[:3, :3].T @ T[:3, :3]) - 1) / 2, -1.0, 1.0)
            angle, shift = float(np.arccos(cos)), float(np.linalg.norm(T[:3, 3] - T0[:3, 3]))
            if angle > SAME_POSE_TOL or shift > SAME_POSE_TOL * (1 + float(np.linalg.norm(T0[:3, 3]))):
                raise InputError(f"station {station!r}: the robot pose of {t.source!r} {where} differs from {where0}'s "
                                 f"by {np.degrees(angle):.3g} deg and {shift:.3g} {unit}; one station is one robot "
                                 "pose: fix the rows or give them other station ids")
    poses = np.array([T for T, _ in first.values()])
    poses.setflags(write=False)
    fmt = tables[0].robot.format
    return PoseStack(poses, unit, fmt, tuple(first), None, None, ", ".join(dict.fromkeys(t.source for t in tables)))


def _array_table(path: Path, src: str, ext: str, unit: str | None) -> ObservationTable:
    if ext == ".npz":
        values: dict[str, Any] = dict(load_npz(path, src))
    else:
        try:
            values = load_json(path.read_text(encoding="utf-8"), src)
        except UnicodeDecodeError:
            raise InputError(f"table of observations {src}: not UTF-8 text") from None
        if not isinstance(values, dict):
            raise InputError(f"table of observations {src}: expected an object with keys {', '.join(ARRAY_KEYS)}")
    odd = [k for k in values if k not in ARRAY_KEYS]
    if odd:
        raise InputError(f"table of observations {src}: unknown key {odd[0]!r}; the keys are {', '.join(ARRAY_KEYS)}")
    for key in ("station", "target", "camera_poses"):
        if key not in values:
            raise InputError(f"table of observations {src}: missing column {key!r}")
    units = values.get("units")
    units = None if units is None else str(np.asarray(units).item() if isinstance(units, np.ndarray) else units)
    if unit is None and units is None:
        raise InputError(f"table of observations {src}: give its length unit (mm or m) or a 'units' entry")
    unit = unit or units

    def names(key: str) -> tuple[str, ...]:
        if key not in values:
            return ()
        array = np.asarray(values[key])
        if array.ndim != 1:
            raise InputError(f"table of observations {src}: {key!r} must be a list of names, got shape {array.shape}")
        return tuple(str(v) for v in array.tolist())

    def stack(key: str) -> PoseStack:
        try:
            return poses_from_rows(np.asarray(values[key], dtype=float), "matrix", unit=unit, source=f"{src} {key}")
        except (TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"table of observations {src}: {key!r} must be 4x4 matrices ({exc})") from None

    poses = dataclasses.replace(stack("camera_poses"), source=str(path))
    m = len(poses)
    robot = stack("robot_poses") if "robot_poses" in values else None
    if robot is not None and len(robot) != m:
        raise InputError(f"table of observations {src}: {len(robot)} robot poses for {m} camera poses")
    return ObservationTable(names("station"), names("camera"), names("target"), poses,
                            tuple(f"row {k + 1}" for k in range(m)), str(path), robot)


def _finished(table: ObservationTable, camera: str | None, src: str) -> ObservationTable:
    """Counts agree, names are non-empty, the camera given or in every row, no repeated row."""
    m = len(table.poses)
    cameras = table.camera
    if camera is not None:
        wrong = [(w, c) for w, c in zip(table.where, cameras) if c != camera]
        if cameras and wrong:
            raise InputError(f"table of observations {src}: {wrong[0][0]} names camera {wrong[0][1]!r}, but the file "
                             f"holds the poses of camera {camera!r}; drop its camera column or fix the row")
        cameras = (camera,) * m
    elif not cameras:
        raise InputError(f"table of observations {src}: missing column 'camera' (or 'sensor'); give it, or name the "
                         "file's camera (`observations: [{camera: NAME, file: ...}]`)")
    for key, values in (("station", table.station), ("camera", cameras), ("target", table.target)):
        if len(values) != m:
            raise InputError(f"table of observations {src}: {len(values)} {key} names for {m} poses")
        empty = [w for w, v in zip(table.where, values) if not str(v).strip()]
        if empty:
            raise InputError(f"table of observations {src}: {empty[0]} has no {key} name")
    check_unrepeated(zip(table.where, zip(table.station, cameras, table.target)), f"table of observations {src}: ")
    return dataclasses.replace(table, camera=cameras)


def check_unrepeated(rows: Iterable[tuple[str, tuple[str, str, str]]], prefix: str = "") -> None:
    """Raise InputError naming both rows when a (station, camera, target) comes twice. rows:
    (where the row is, for the message; its key); prefix: what the message starts with."""
    seen: dict[tuple[str, str, str], str] = {}
    for where, key in rows:
        if key in seen:
            raise InputError(f"{prefix}{where} repeats {seen[key]} (station {key[0]!r}, camera {key[1]!r}, target "
                             f"{key[2]!r}); one observation is one pose: drop one of them")
        seen[key] = where
