"""``handeye.calibrate(cell)``: a cell's recordings to its hand-eye transform, checked.

The calibrate workflow, once, for the library and the command line (``handeye calibrate`` builds a
`Cell` from its flags and calls this; it only prints and writes):

1. read the streams and pair them into stations (`handeye.workflow.stations`; board images:
   detect, calibrate the camera if needed, solve the board poses, `handeye.workflow.image_stations`);
2. take the camera poses of the stations, invert them when the file holds T_target_cam
   (``camera.poses: camera-in-board``), convert them to the robot's length unit;
3. turn the stations into the problem's data (`handeye.io.from_poses`: eye-in-hand /
   eye-to-hand, axxb's pairing) and solve (`handeye.solve`) with the cell's solver, or the default
   (`handeye.workflow.solving`); for images the corner fit (with the robot's noise estimated or its
   poses as measured, whichever predicts held-out corners better) gives way to the pose-based
   answer where that predicts them better still, with a warning;
4. measure the residuals and run the plausibility checks (`handeye.workflow.plausibility`: the usual
   setup mistakes, residuals beyond a calibrated cell's noise): an implausible fit, or a clock
   offset the stream pairing does not trust, makes the status ``unreliable``. Nothing is switched:
   the answer is the one for the data as given, and the first warning says what explains them.

Errors in the cell or its data raise `handeye.InputError` (one line, naming the cell's setting);
a solver failure raises `handeye.SolverError`. An unusable answer (``not_converged``, ``failed``,
``unreliable``) is returned, not raised: `CalibrationResult.usable` says whether to use it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError
from handeye.framework.solution import Status
from handeye.geometry.se3 import inverse
from handeye.host.api import solve
from handeye.host.registry import get_registry
from handeye.io.data_files import from_poses
from handeye.workflow.cell import Cell
from handeye.workflow.image_stations import image_stations
from handeye.workflow.plausibility import Streams, check
from handeye.workflow.reading import rereader
from handeye.workflow.result import CalibrationResult
from handeye.workflow.solving import (
    UNUSABLE,
    default_solver,
    image_data,
    image_solver,
    measured_data,
    pose_based_instead,
    pose_based_intrinsics,
    time_limit,
)
from handeye.workflow.stations import Log, pose_stations, reliable, take


@dataclasses.dataclass(frozen=True)
class ReadStations:
    """A cell of one camera read into its stations (steps 1-3 of the module docstring, before the
    solve): the `Stations`, the camera poses as read (inverted where the file holds T_target_cam:
    `invert`) and in the robot's unit, the problem's data (`handeye.io.PoseFile`), the solver's
    options and the data's facts."""

    stations: Any
    camera_read: Any
    camera: Any
    pose_file: Any
    options: dict[str, Any]
    facts: dict[str, Any]
    invert: bool


def read_stations(cell: Cell, log: Log | None = None, *, workers: int | None = None,
                  cache: bool | str | Path | None = None) -> ReadStations:
    """`cell` (one camera: images or a pose file) read into its stations and the problem's data,
    as `calibrate` reads it (InputError as there)."""
    stations = (image_stations(cell, log, workers=workers, cache=cache) if cell.images is not None
                else pose_stations(cell, log))
    robot = stations.robot
    invert = cell.camera is not None and cell.camera.poses == "camera-in-board"
    camera_read = take(stations.camera_file, stations.camera_rows)
    if invert:
        inverted = inverse(camera_read.poses)
        inverted.setflags(write=False)
        camera_read = dataclasses.replace(camera_read, poses=inverted)
    camera = camera_read.in_unit(robot.unit)
    camera_source = cell.images.folder if cell.images is not None else cell.camera.file
    pose_file = from_poses(robot.poses, camera.poses, cell.problem, setup=cell.setup, pairing=cell.pairing,
                           metadata={"units": robot.unit}, source=f"{cell.robot.file} + {camera_source}")
    options, facts = cell.solver_options(), cell.facts()
    clash = sorted(set(options) & set(pose_file.data))
    if clash:
        raise InputError(f"`options` {clash} clash with the data field(s) of problem {cell.problem!r}")
    return ReadStations(stations, camera_read, camera, pose_file, options, facts, invert)


def calibrate(cell: Cell, *, log: Log | None = None, workers: int | None = None,
              cache: bool | str | Path | None = None) -> CalibrationResult:
    """Calibrate `cell` (module docstring) and return the `CalibrationResult`.

    log: called as ``log(stage, text)`` with what the pairing found as soon as it is known
    (``"images"``: the images' summary; ``"matching"``: how the stations were matched), for a
    caller that shows progress; the same is in the result.
    workers, cache: how board images are detected, one camera's or several cameras' (they change
    the time, never the answer): `workers` threads (default the cores, or `HANDEYE_WORKERS`);
    `cache` None / True the detection cache of the environment (`HANDEYE_CACHE_DIR`,
    `HANDEYE_NO_CACHE`), False none, a folder that one (docs/images.md, "Speed").
    """
    if not isinstance(cell, Cell):
        raise InputError(f"calibrate expects a handeye.Cell (e.g. handeye.Cell.from_file('cell.yaml')), got "
                         f"{type(cell).__name__}")
    if workers is not None:  # refused before anything is read
        from handeye.vision.detection_pool import check_workers

        check_workers(workers)
    if cell.joints is not None:  # joint readings and the arm's DH table: a kinematic calibration
        from handeye.workflow.joint_cell import calibrate_joints

        return calibrate_joints(cell, log, workers=workers, cache=cache)
    if cell.observations is not None:  # several cameras and targets: tables of observations
        from handeye.workflow.observation_cell import calibrate_observations

        result = calibrate_observations(cell, log, workers=workers, cache=cache)
        if log is not None:
            log("matching", result.stations.matching["message"])
        return result
    read = read_stations(cell, log, workers=workers, cache=cache)
    stations, robot, camera_read, camera, pose_file = (read.stations, read.stations.robot, read.camera_read,
                                                       read.camera, read.pose_file)
    options, facts, invert = read.options, read.facts, read.invert
    warnings = list(stations.warnings)
    images = stations.images
    solver = cell.solver or (images is not None and image_solver(cell.problem)) or default_solver(cell.problem)
    solution = solve(cell.problem, solver=solver, backend=cell.backend,
                     time_limit=time_limit(cell.time_limit, cell.problem, solver),
                     **pose_file.data, **facts, **options,
                     **image_data(images, solver, cell.problem, compare=cell.solver is None))
    instead = pose_based_instead(solution, defaulted=cell.solver is None)
    if instead:
        solver = default_solver(cell.problem)
        solution = solve(cell.problem, solver=solver, **pose_file.data, **facts, **options)
        warnings.append(instead)
    if images is not None:  # the intrinsics' own uncertainty in a pose-based answer's 1-sigma
        solution = pose_based_intrinsics(solution, images, robot.poses, cell, facts, options)

    problem = get_registry().problem(cell.problem)
    residuals = problem.residuals(measured_data(problem, solution, pose_file.data, facts), solution.unknowns)
    report = None
    if cell.checks:  # also when the solve failed: a setup mistake (pairs shifted by one) is often why
        report = check(Streams(robot.poses, camera.poses, robot.unit, cell.setup, cell.problem,
                               pose_file.metadata.get("pairing"), facts=facts, robot_format=robot.format,
                               camera_format=camera_read.format, camera_unit=camera_read.unit,
                               reread_robot=None if stations.robot_rows is None else rereader(
                                   cell.robot, stations.robot_file, robot.unit, cell.orthonormalize,
                                   stations.robot_rows),
                               reread_camera=None if images is not None else rereader(
                                   cell.camera, camera_read, robot.unit, cell.orthonormalize,
                                   stations.camera_rows, invert)),
                       residuals)
        warnings += list(report.warnings)
        if not report.plausible and solution.status not in UNUSABLE:
            solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    if not reliable(stations.matching) and solution.status not in UNUSABLE:  # the clock offset is not trusted
        solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    return CalibrationResult(cell=cell, solution=solution, solver=solver, unit=robot.unit, stations=stations,
                             camera=camera, camera_read=camera_read, residuals=residuals, checks=report,
                             pairing=pose_file.metadata.get("pairing"), facts=facts,
                             warnings=(*warnings, *solution.warnings))
