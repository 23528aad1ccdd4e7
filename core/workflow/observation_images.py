"""The cameras' images of a cell of several cameras and targets, as tables of observations: each
``observations`` entry with ``images`` (a camera's folder, one image per station, its intrinsics,
the targets it looks for) gives one `ObservationTable` whose rows are the boards found (station,
camera, target, T_cam_target by PnP in the robot's unit), so that the rest of the multi-camera
path (`handeye.workflow.observation_cell`) treats them as it treats a table read from a file.
Each camera's images are detected as one camera's image set is (over the cores, from the detection
cache, a chessboard's flag-set plan judged on that camera's images: docs/images.md, "Speed").

The images are paired with the robot's stations by the cell's ``matching.method`` (``row`` /
``index``: the k-th image with the k-th robot pose; ``name``: file stem = station name; ``time``)
exactly as one camera's images are; what each camera's images left out (an unreadable image, a
board not found or with too few points, a board pose whose reprojection error is far above the
camera's others) is listed as `handeye.checks.stations.Dropped` entries (``image cam0/003``),
and the unreliable poses also as warnings. Each camera's intrinsics are treated as one camera's
images treat them (`handeye.vision.image_observations`, step 5: a jackknife 1-sigma when
calibrated here, a focal-length check of a given file, its warning prefixed ``camera NAME:``);
`with_intrinsics` then gives the answer their share.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.checks.stations import Dropped
from handeye.io.observation_tables import ObservationTable
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import IMAGE_MATCHES, Cell, ObservationStream


@dataclasses.dataclass(frozen=True)
class ImageTables:
    """The tables of the cell's cameras' images (one per camera, in the cell's order), what was
    left out, the warnings, each camera's observations (`handeye.vision.image_observations.
    CameraObservations`, by camera name) and the summary in lines."""

    tables: tuple[ObservationTable, ...]
    dropped: tuple[Dropped, ...]
    warnings: tuple[str, ...]
    cameras: dict[str, Any]
    summary: tuple[str, ...]


def target_boards(cell: Cell) -> dict[str, Any]:
    """The cell's targets as `Board`s, by name; InputError naming ``targets.NAME`` for a bad spec."""
    from handeye.vision.boards import parse_board

    boards = {}
    for name, spec in (cell.targets or {}).items():
        try:
            boards[name] = parse_board(spec)
        except InputError as exc:
            raise InputError(f"`targets.{name}`: {exc}") from None
    return boards


def image_tables(cell: Cell, robot: PoseStack, *, workers: int | None = None,
                 cache: bool | str | Path | None = None) -> ImageTables:
    """The tables of observations of the cell's cameras' images (module docstring); `robot` is
    the robot's pose file as read (its unit is the poses'); `workers` (detection threads) and
    `cache` (the detection cache) as `handeye.vision.image_observations.camera_observations`."""
    from handeye.vision.image_observations import camera_observations, summary
    from handeye.vision.intrinsics import load_camera_of

    boards = target_boards(cell)
    tables, dropped, warnings, cameras, lines = [], [], [], {}, []
    for k, stream in enumerate(cell.observations):
        if stream.images is None:
            continue
        which = f"observations[{k}]"
        camera = load_camera_of(stream.intrinsics, f"{which}.intrinsics")
        seen = {name: boards[name] for name in (stream.targets or boards)}
        try:
            obs = camera_observations(stream.images, seen, camera, robot=robot,
                                      match=IMAGE_MATCHES[cell.matching.method], max_dt=cell.matching.max_dt,
                                      unit=robot.unit, workers=workers, cache=cache)
        except InputError as exc:
            text = re.sub(r"\bmatch='(\w+)'", r"`matching.method: \1`", str(exc))
            raise InputError(f"`{which}` (camera {stream.camera!r}): {text}") from None
        tables.append(_table(stream, obs))
        cameras[stream.camera] = obs
        # an image left out takes no robot pose with it: the station may still have other cameras' images
        dropped += [Dropped("image", f"{stream.camera}/{d.name}", d.reason) if d.kind == "image"
                    else Dropped("robot", d.name, f"camera {stream.camera}: {d.reason}") for d in obs.dropped]
        warnings += [f"camera {stream.camera}: {w}" for w in obs.warnings]
        lines += summary(stream.camera, stream.images, obs)
    return ImageTables(tuple(tables), tuple(dropped), tuple(warnings), cameras, tuple(lines))


def intrinsics_entries(cell: Cell, imaged: ImageTables) -> dict[str, dict[str, Any]]:
    """Each imaged camera's intrinsics, by name in the cell's order, as the single camera's result
    writes its ``camera`` entry (`handeye.workflow.image_stations.intrinsics_entry`: K, dist,
    image_size, source: the entry's ``intrinsics`` file or ``calibrated``; when calibrated, the
    model, RMS and 1-sigma in px), with ``views``: the (image, board) views calibrated from."""
    from handeye.workflow.image_stations import intrinsics_entry

    given = {s.camera: s.intrinsics for s in cell.observations if s.images is not None}
    out = {}
    for name, obs in imaged.cameras.items():
        out[name] = intrinsics_entry(obs.camera, obs.calibration, given.get(name), *obs.intrinsics_std)
        if obs.calibration is not None:
            out[name]["views"] = len(obs.calibration.per_image_rms)
    return out


def _table(stream: ObservationStream, obs: Any) -> ObservationTable:
    """One camera's observations as a table (rows named ``image 003, board1`` in messages)."""
    poses = np.array(obs.T_cam_target)
    poses.setflags(write=False)
    stack = PoseStack(poses, obs.unit, "matrix", obs.station, None, None, str(stream.images))
    return ObservationTable(station=obs.station, camera=(stream.camera,) * len(obs), target=obs.target, poses=stack,
                            where=tuple(f"image {i}, {t}" for i, t in zip(obs.image, obs.target)),
                            source=str(stream.images))


def with_intrinsics(solution: Any, cell: Cell, imaged: ImageTables | None, observations: Any,
                    facts: dict[str, Any], options: dict[str, Any]) -> Any:
    """`solution` (of the cell's observations `observations`, a `handeye.framework.problem.
    Observations` whose rows of an imaged camera are its `imaged` table's) with what each imaged
    camera's intrinsics do to it (`handeye.vision.intrinsics_effect`), per camera its board poses
    moved as PnP would move them (from the corners it found) and the problem re-solved (3 solves
    per camera): the uncertainty of the intrinsics (`CameraObservations.intrinsics_std`:
    calibrated from its images, or given with a 1-sigma the file states or, stating none, the
    images' own) added to the answer's covariance and 1-sigma, the cameras independent, and the
    warning where a translation's 1-sigma at least doubles.

    Unchanged where no camera applies, the answer is unusable, or a moved solve fails."""
    from handeye.base.errors import HandEyeError
    from handeye.framework.solution import jsonable
    from handeye.host.api import solve
    from handeye.host.registry import get_registry
    from handeye.vision import intrinsics_effect as effect
    from handeye.workflow.solving import UNUSABLE

    cameras = {} if imaged is None else {n: o for n, o in imaged.cameras.items() if o.intrinsics_std[0] is not None}
    if not cameras or solution.status in UNUSABLE:
        return solution
    problem = get_registry().problem(cell.problem)
    boards = target_boards(cell)
    T0 = np.asarray(observations.camera_poses, dtype=float)
    names = list(effect.flat_poses(solution.unknowns))
    camera_of = np.array(observations.camera)
    stacked = problem.from_observations(observations, cell.setup).names  # {"Y": ("cam0", "cam1")}
    labels = {f"{k}[{j}]": user for k, users in stacked.items() for j, user in enumerate(users)}

    def resolve(T: np.ndarray) -> dict[str, np.ndarray]:
        made = problem.from_observations(dataclasses.replace(observations, camera_poses=T), cell.setup)
        return solve(cell.problem, solver=solution.solver, backend=solution.backend, **dict(made.fields), **facts,
                     **options).unknowns

    blocks, percents, sources, shares = [], {}, {}, {}
    try:
        for name, obs in cameras.items():
            rows = np.flatnonzero(camera_of == name)
            if len(rows) != len(obs):
                continue
            slopes = [effect.pose_sensitivity(T0[r], points, obs.camera)
                      for r, points in zip(rows, _board_points(obs, boards))]
            std, sources[name] = obs.intrinsics_std
            blocks.append(effect.answer_moves(resolve, solution.unknowns, names, T0, slopes,
                                              effect.one_sigma_moves(std), rows))
            percents[name] = effect.focal_percent(std, obs.camera)
            shares[name] = effect.focal_moves(blocks[-1], names, percents[name], sources[name])
    except (HandEyeError, np.linalg.LinAlgError):
        return solution
    if not blocks:
        return solution
    whose = (f"camera {next(iter(percents))}'s intrinsics" if len(percents) == 1
             else f"the intrinsics of cameras {', '.join(percents)}")
    widest = max(percents, key=percents.get)  # the note speaks of the least known camera's source
    diagnostics, note = effect.with_moves(
        dict(solution.diagnostics), names, np.hstack(blocks),
        lambda b, a: effect.growth_note(b, a, names, percents[widest], whose, labels, sources[widest]))
    diagnostics["intrinsics_effect"] = shares
    if note:
        diagnostics["warnings"] = [*diagnostics.get("warnings", []), note]
    return dataclasses.replace(solution, diagnostics=jsonable(diagnostics))


def _board_points(obs: Any, boards: dict[str, Any]) -> list[np.ndarray]:
    """Per observation of a camera (`CameraObservations`), the board points (n, 3) its PnP pose
    rests on, in the poses' unit: the corners found (``detections``), or, without them, the
    board's points that fall in the image at that pose."""
    from handeye.vision import intrinsics_effect as effect
    from handeye.vision.boards import UNITS

    out = []
    for k, target in enumerate(obs.target):
        board = boards[target]
        scale = UNITS[board.unit] / UNITS[obs.unit]
        if k < len(obs.detections):
            out.append(np.asarray(obs.detections[k].object_points) * scale)
        else:
            out.append(effect.visible_points(board.object_points() * scale, obs.T_cam_target[k], obs.camera))
    return out
