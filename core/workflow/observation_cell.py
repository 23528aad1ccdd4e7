"""``handeye.calibrate(cell)`` for a cell of several cameras and targets: its tables of
observations (`Cell.observations`: one long table, or one file per camera) and its robot pose
file become the problem's data through the problem (`Problem.from_observations`), and are solved.

1. read the robot's poses (one per station) and each table (`handeye.io.observation_tables`),
   invert a table's poses when it holds T_target_cam (``poses: camera-in-board``), convert them
   to the robot's length unit;
2. give each row its station's robot pose: the robot file's row whose name (its name/index
   column) is the row's station, or, for a robot file without names, its 0-based row; a station
   the robot file lacks is an error naming the row;
3. the problem makes its data from the observations (`Observations`), with the names of its
   stacked unknowns' poses (the cameras' and targets' names); solve with the cell's solver, or
   the default, and the cell's monocular cameras (``camera_scale: [names]``, each of them a
   camera of the tables); the residuals per observation and per pair of poses
   (`Problem.residual_table`), measured on the data the solve validated (`Solution.data`), or,
   with monocular cameras, on the data with each one's translations times its estimated scale,
   so that they are in the robot's unit (`handeye.workflow.solving.measured_data`).

A camera's images (an ``observations`` entry with ``images``) become a table of their own first
(`handeye.workflow.observation_images`: every board found in an image one row; what was left
out in `Stations.dropped`).

The plausibility checks of one camera's stations do not apply (the solve's own self-check does).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.framework.problem_cell import Observations
from handeye.geometry.se3 import inverse
from handeye.host.api import solve
from handeye.host.registry import get_registry
from handeye.io.observation_tables import (
    ObservationTable,
    check_unrepeated,
    read_observation_table,
    robot_of_stations,
)
from handeye.io.pose_readers import PoseStack, natural_key
from handeye.workflow.cell import Cell, ObservationStream
from handeye.workflow.observation_images import (
    image_tables,
    intrinsics_entries,
    with_intrinsics,
)
from handeye.workflow.reading import in_cell_words, read_stream
from handeye.workflow.result import CalibrationResult, frame_ids
from handeye.workflow.solving import default_solver, measured_data, time_limit
from handeye.workflow.stations import Log, Stations


def read_tables(cell: Cell, unit: str | None) -> list[ObservationTable]:
    """Each of the cell's tables of observations, poses as T_cam_target in `unit` (None: the
    table's own), with the robot's poses when the table carries them (``robot_*`` columns)."""
    tables = []
    for k, stream in enumerate(cell.observations):
        if stream.images is not None:  # a camera's images: handeye.workflow.observation_images
            continue
        which = f"observations[{k}]" if len(cell.observations) > 1 else "observations"
        try:
            table = read_observation_table(stream.file, stream.format, unit=stream.unit, camera=stream.camera,
                                           orthonormalize=cell.orthonormalize,
                                           columns=None if stream.columns is None else list(stream.columns),
                                           robot_format=cell.robot.format, robot_unit=cell.robot.unit)
        except InputError as exc:
            raise InputError(f"`{which}`: {in_cell_words(str(exc), which)}") from None
        poses = table.poses
        if stream.poses == "camera-in-board":
            inverted = inverse(poses.poses)
            inverted.setflags(write=False)
            poses = dataclasses.replace(poses, poses=inverted)
        tables.append(dataclasses.replace(table, poses=poses if unit is None else poses.in_unit(unit)))
    return tables


def station_rows(robot: PoseStack, stations: tuple[str, ...], where: tuple[str, ...], table: str,
                 robot_file: str) -> np.ndarray:
    """The robot file's row of each station id (module docstring, step 2)."""
    if robot.names is not None:
        index = {name: k for k, name in enumerate(robot.names)}
        missing = [(w, s) for w, s in zip(where, stations) if s not in index]
        if missing:
            w, s = missing[0]
            shown = ", ".join(robot.names[:3]) + (", ..." if len(robot.names) > 3 else "")
            raise InputError(f"station {s!r} ({table} {w}) is not in the robot file {robot_file!r} (its stations: "
                             f"{shown}); record its robot pose or drop its rows")
        return np.array([index[s] for s in stations], dtype=np.int64)
    rows = []
    for w, s in zip(where, stations):
        if not s.strip().isdigit() or int(s) >= len(robot):
            raise InputError(f"station {s!r} ({table} {w}) is not a row of the robot file {robot_file!r} (no name "
                             f"column: stations are its rows 0..{len(robot) - 1}); give the robot file a name column "
                             "or number the stations by row")
        rows.append(int(s))
    return np.array(rows, dtype=np.int64)


def calibrate_observations(cell: Cell, log: Log | None = None, *, workers: int | None = None,
                           cache: bool | str | Path | None = None) -> CalibrationResult:
    """Calibrate a cell of tables of observations (module docstring); `log` gets the cameras'
    images' summary (``"images"``) as soon as they are done; `workers` and `cache`: how the
    cameras' images are detected (`handeye.workflow.observation_images.image_tables`)."""
    if cell.robot.file is None:  # the tables carry the robot's pose of each row's station
        tables = read_tables(cell, None)
        robot_file = robot_of_stations(tables, cell.robot.unit)
        unit = robot_file.unit
        tables = [dataclasses.replace(t, poses=t.poses.in_unit(unit)) for t in tables]
    else:
        robot_file = read_stream(cell.robot, "robot", cell.orthonormalize)
        unit = robot_file.unit
        tables = read_tables(cell, unit)
        both = [t.source for t in tables if t.robot is not None]
        if both:
            raise InputError(f"table of observations {both[0]!r} carries robot poses and the cell names the robot pose "
                             f"file {str(cell.robot.file)!r}; give the robot's poses once (drop `robot.file` or the "
                             "table's robot columns)")
    imaged = (image_tables(cell, robot_file, workers=workers, cache=cache)
              if any(s.images is not None for s in cell.observations) else None)
    if imaged is not None:
        tables += list(imaged.tables)
        if log is not None:
            log("images", "\n".join(imaged.summary))
    robot_source = str(cell.robot.file) if cell.robot.file is not None else robot_file.source
    rows = np.concatenate([station_rows(robot_file, t.station, t.where, repr(t.source), robot_source)
                           for t in tables])
    check_unrepeated((f"{t.source!r} {w}", key) for t in tables  # also across the files
                     for w, key in zip(t.where, zip(t.station, t.camera, t.target)))
    robot = robot_file.poses[rows]
    camera_poses = np.concatenate([t.poses.poses for t in tables])
    observations = Observations(station=tuple(s for t in tables for s in t.station),
                                camera=tuple(c for t in tables for c in t.camera),
                                target=tuple(g for t in tables for g in t.target),
                                robot=robot, camera_poses=camera_poses)
    problem = get_registry().problem(cell.problem)
    made = problem.from_observations(observations, cell.setup)
    fields = dict(made.fields)
    options, facts = cell.solver_options(), monocular_cameras(cell, observations)
    clash = sorted(set(options) & set(fields))
    if clash:
        raise InputError(f"`options` {clash} clash with the data field(s) of problem {cell.problem!r}")
    solver = cell.solver or default_solver(cell.problem)
    solution = solve(cell.problem, solver=solver, backend=cell.backend,
                     time_limit=time_limit(cell.time_limit, cell.problem, solver), **fields, **facts, **options)
    solution = with_intrinsics(solution, cell, imaged, observations, facts, options)  # cameras calibrated here
    data = measured_data(problem, solution, fields, facts)
    residuals = problem.residuals(data, solution.unknowns)
    pair_table = tuple(problem.residual_table(data, solution.unknowns))

    used = np.unique(rows)
    first = tables[0].poses
    camera = dataclasses.replace(first, poses=_frozen(camera_poses), names=observations.station,
                                 source=", ".join(t.source for t in tables))
    message = (f"{len(observations)} observations of {len(set(observations.camera))} cameras and "
               f"{len(set(observations.target))} targets at {len(used)} of the robot file's {len(robot_file)} stations")
    matching = {"method": "station", "matched": len(observations), "stations": int(len(used)), "message": message}
    if imaged is not None:  # what the cameras' images left out, as the single camera's images list it
        matching["dropped"] = [dataclasses.asdict(d) for d in imaged.dropped]
    stations = Stations(robot_file, camera, dataclasses.replace(robot_file, poses=_frozen(robot_file.poses[used]),
                                                                names=None if robot_file.names is None else tuple(
                                                                    robot_file.names[k] for k in used), stamps=None),
                        used, np.arange(len(observations)), matching, () if imaged is None else imaged.dropped,
                        () if imaged is None else imaged.warnings)
    _, clash = frame_ids([name for names in made.names.values() for name in names])
    return CalibrationResult(cell=cell, solution=solution, solver=solver, unit=unit, stations=stations, camera=camera,
                             camera_read=camera, residuals=residuals, checks=None, pairing=None, facts=facts,
                             warnings=(*stations.warnings, *(named_observations(w, data, observations)
                                                             for w in solution.warnings), *([clash] if clash else [])),
                             names=dict(made.names),
                             pair_table=pair_table, observation_labels=tuple(zip(observations.station,
                                                                                 observations.camera,
                                                                                 observations.target)),
                             cameras=None if imaged is None else intrinsics_entries(cell, imaged))


def monocular_cameras(cell: Cell, observations: Observations) -> dict[str, Any]:
    """The fact ``camera_scale`` of the solve: ``{"camera_scale": [names]}`` for the cell's
    monocular cameras (`Cell.camera_scale`, or ``options.camera_scale``), each checked to be a
    camera of the observations; empty when every camera is metric."""
    given = cell.facts().get("camera_scale")
    if given is None or given == "known":
        return {}
    cameras = sorted(set(observations.camera), key=natural_key)
    stray = [name for name in given if name not in cameras]
    if stray:
        raise InputError(f"`camera_scale` names {stray[0]!r}, which is not a camera of the observations (their "
                         f"cameras: {', '.join(cameras)}); name the monocular cameras among them")
    return {"camera_scale": list(given)}


#: an observation as a solver's message lists it, "(index 3: marker3 with cam5 at station 4)"
_LISTED = re.compile(r"\(index (\d+): ([^()]*)\)")


def named_observations(text: str, data: Any, observations: Observations) -> str:
    """`text` (a solver's warning) with each observation it lists in the problem's words
    (``(index 3: marker3 with cam5 at station 4)``, the data's `item_label`, stations numbered
    in order) named by the cell's station, camera and target instead
    (``(index 3: station s07 (cam5, marker3))``), as the report and the docs name them."""
    label = getattr(data, "item_label", None)
    if label is None:
        return text

    def name(match: re.Match[str]) -> str:
        i = int(match.group(1))
        if i >= len(observations) or match.group(2) != label(i):
            return match.group(0)
        return f"(index {i}: station {observations.station[i]} ({observations.camera[i]}, {observations.target[i]}))"

    return _LISTED.sub(name, text)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


__all__ = ["ObservationStream", "calibrate_observations", "monocular_cameras", "named_observations", "read_tables",
           "station_rows"]
