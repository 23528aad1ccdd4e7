"""The cameras' images of a cell of several cameras and targets, as tables of observations: each
``observations`` entry with ``images`` (a camera's folder, one image per station, its intrinsics,
the targets it looks for) gives one `ObservationTable` whose rows are the boards found (station,
camera, target, T_cam_target by PnP in the robot's unit), so that the rest of the multi-camera
path (`handeye.workflow.observation_cell`) treats them as it treats a table read from a file.

The images are paired with the robot's stations by the cell's ``matching.method`` (``row`` /
``index``: the k-th image with the k-th robot pose; ``name``: file stem = station name; ``time``)
exactly as one camera's images are; what each camera's images left out (an unreadable image, a
board not found or with too few points, a board pose whose reprojection error is far above the
camera's others) is listed as `handeye.workflow.stations.Dropped` entries (``image cam0/003``),
and the unreliable poses also as warnings.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from handeye.framework.errors import InputError
from handeye.io.observation_tables import ObservationTable
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import IMAGE_MATCHES, Cell, ObservationStream
from handeye.workflow.stations import Dropped


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


def image_tables(cell: Cell, robot: PoseStack) -> ImageTables:
    """The tables of observations of the cell's cameras' images (module docstring); `robot` is
    the robot's pose file as read (its unit is the poses')."""
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
                                      unit=robot.unit)
        except InputError as exc:
            text = re.sub(r"\bmatch='(\w+)'", r"`matching.method: \1`", str(exc))
            raise InputError(f"`{which}` (camera {stream.camera!r}): {text}") from None
        tables.append(_table(stream, obs))
        cameras[stream.camera] = obs
        # an image left out takes no robot pose with it: the station may still have other cameras' images
        dropped += [Dropped("image", f"{stream.camera}/{d.image}", d.reason) if d.image is not None
                    else Dropped("robot", d.pose, f"camera {stream.camera}: {d.reason}") for d in obs.dropped]
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
        out[name] = intrinsics_entry(obs.camera, obs.calibration, given.get(name))
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
