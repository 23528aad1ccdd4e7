"""A cell's stations from board images instead of a camera pose file (docs/images.md).

The images are paired with the robot poses (the cell's ``matching.method``: ``row`` / ``index``
the k-th image in natural order with the k-th robot pose, ``name`` file stem = robot pose name,
``time`` a stamp in the file name or a sidecar), the board is detected in each, the camera is
calibrated from the same images when the cell gives no intrinsics, and the board poses
(T_cam_target, solvePnP, in the robot's unit) become the camera stream of the ordinary path. An
image whose board is not found, or whose reprojection error is far above the others', is dropped
together with its robot pose, with the reason (`handeye.vision.image_set.images_and_poses`).

What the image path adds to a result: where the board poses came from (`inputs_entry`), the
intrinsics and every image's station (`result_entries`), and the summary a user reads first
(`summary_lines`).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import IMAGE_MATCHES, Cell
from handeye.workflow.reading import read_stream
from handeye.workflow.stations import Log, Stations, take


def image_stations(cell: Cell, log: Log | None = None, robot: PoseStack | None = None, *,
                   workers: int | None = None, cache: bool | str | Path | None = None) -> Stations:
    """The stations of the cell's images (module docstring); `log` gets `summary_lines` as soon as
    the images are done (``"images"``); `robot`: the robot's poses when not read from the cell's
    robot file (a kinematic calibration's forward kinematics of the joint readings); `workers`
    (detection threads) and `cache` (the detection cache) as `images_and_poses` takes them."""
    from handeye.vision.boards import parse_board
    from handeye.vision.image_set import images_and_poses
    from handeye.vision.intrinsics import load_camera_of

    spec = cell.images
    try:
        board = parse_board(spec.board)
    except InputError as exc:
        raise InputError(f"`images.board`: {exc}") from None
    camera = load_camera_of(spec.intrinsics, "images.intrinsics")
    robot = read_stream(cell.robot, "robot", cell.orthonormalize) if robot is None else robot
    try:
        images = images_and_poses(spec.folder, board, camera, setup=cell.setup, robot=robot,
                                  match=IMAGE_MATCHES[cell.matching.method], max_dt=cell.matching.max_dt,
                                  unit=robot.unit, workers=workers, cache=cache)
    except InputError as exc:
        raise InputError(re.sub(r"\bmatch='(\w+)'", r"`matching.method: \1`", str(exc))) from None
    poses = np.array(images.T_cam_target)
    poses.setflags(write=False)
    camera_file = PoseStack(poses, robot.unit, "matrix", images.names, None, None, repr(str(spec.folder)))
    rows = np.arange(len(images))
    matching = {"method": images.match, "matched": len(images), "message": images.match_note,
                "pairs": [{"image": n, "robot_pose": p} for n, p in zip(images.names, images.pose_names)],
                "dropped": [dataclasses.asdict(d) for d in images.dropped]}
    if log is not None:
        log("images", "\n".join(summary_lines(cell, board, images)))
    warnings = [*images.warnings, *[f"dropped {d.describe()}" for d in images.dropped
                                    if d.kind == "image" and d.robot is not None
                                    and not any(d.reason in w for w in images.warnings)]]  # said once
    dropped = tuple(images.dropped)
    robot_rows = np.asarray(images.robot_rows)
    return Stations(robot, camera_file, take(robot, robot_rows), robot_rows, rows, matching, dropped,
                    tuple(warnings), images)


def summary_lines(cell: Cell, board: Any, images: Any) -> list[str]:
    """What the images gave: the board, the pairing, each image's station and reprojection RMS,
    what was dropped, and the intrinsics calibrated from the images (when they were)."""
    lines = [f"images {cell.images.folder}: board {board.describe()}; {images.match_note}"]
    for name, pose, u, err in zip(images.names, images.pose_names, images.observations.image_points, images.errors):
        lines.append(f"  image {name} <-> robot pose {pose}: {len(u)} points, reprojection RMS {err:.3f} px")
    lines += [f"  dropped {d.describe()}" for d in images.dropped]
    cal = images.calibration
    if cal is not None:
        K = cal.camera.K
        std = cal.std_fx_fy_cx_cy
        lines += [f"camera calibrated from {len(cal.per_image_rms)} images ({cal.model}): RMS {cal.rms:.3f} px",
                  (f"  fx {K[0, 0]:.2f} +- {std[0]:.2f}, fy {K[1, 1]:.2f} +- {std[1]:.2f}, cx {K[0, 2]:.2f} +- "
                   f"{std[2]:.2f}, cy {K[1, 2]:.2f} +- {std[3]:.2f} px (1-sigma"
                   + ("" if cal.opencv_std is None else ", the larger of OpenCV's and a jackknife's over the images")
                   + ")"),
                  "  K " + np.array2string(K, precision=3, suppress_small=True).replace("\n", ""),
                  "  dist (k1, k2, p1, p2, k3) " + " ".join(f"{v:.6g}" for v in cal.camera.dist)]
    else:
        lines += given_lines(images.camera, images.observations.intrinsics_std,
                             images.observations.intrinsics_std_from, cell.images.intrinsics)
    return lines


#: how the 1-sigma of intrinsics given apart is described (`given_lines`)
_GIVEN_STD = {"file": "as the file states it", "assumed": "the file states none, so the images' own (state the file's "
              "as std_px: {fx, fy, cx, cy} where it is known better)"}


def given_lines(camera: Any, std: Any, source: str, given: str | None) -> list[str]:
    """Intrinsics given apart, in lines: the file's values and the 1-sigma the answer carries for
    them, with where that comes from (`handeye.vision.observations.STD_SOURCES`), or that they
    are taken as exact."""
    K = camera.K
    head = (f"intrinsics {given or 'given'}: fx {K[0, 0]:.2f}, fy {K[1, 1]:.2f}, cx {K[0, 2]:.2f}, cy {K[1, 2]:.2f} px")
    if std is None:
        return [head, "  taken as exact (too few images to check them and the file states no 1-sigma)"]
    return [head, (f"  1-sigma in the answer: fx {std[0]:.2f}, fy {std[1]:.2f}, cx {std[2]:.2f}, cy {std[3]:.2f} px, "
                   + _GIVEN_STD[source])]


def intrinsics_source(cell: Cell) -> str:
    """Where the intrinsics came from, in words: the file, or calibrated from the images."""
    return cell.images.intrinsics or "calibrated from the images"


def inputs_entry(cell: Cell, images: Any) -> dict[str, Any]:
    """The result's ``inputs.camera``: where the board poses came from."""
    return {"file": cell.images.folder, "format": f"images, board {cell.images.board}", "unit": images.unit,
            "poses": len(images) + sum(d.kind == "image" for d in images.dropped),
            "holds": "T_cam_target", "intrinsics": intrinsics_source(cell)}


def intrinsics_entry(cam: Any, calibration: Any, given: str | None, std: Any = None,
                     std_from: str | None = None) -> dict[str, Any]:
    """A camera's intrinsics as the result's ``camera`` entry: K, dist, image_size, source (the
    intrinsics file `given`, else ``calibrated``) and, when calibrated from the images
    (`calibration`, a `handeye.vision.intrinsics.CameraCalibration`), the model, the RMS
    reprojection error and the 1-sigma of fx, fy, cx, cy (px), and OpenCV's own where a
    jackknife over the images widened it; when given, the 1-sigma the answer carries for them
    (`std`, px) and where it comes from (`std_from`: ``file`` or ``assumed``)."""
    entry: dict[str, Any] = {"K": cam.K.tolist(), "dist": cam.dist.tolist(),
                             "image_size": None if cam.size is None else list(cam.size),
                             "source": given or "calibrated"}
    if calibration is None and std is not None:
        entry.update({"std_px": dict(zip(("fx", "fy", "cx", "cy"), [float(v) for v in std])), "std_from": std_from})
    if calibration is not None:
        entry.update({"model": calibration.model, "rms_px": calibration.rms,
                      "std_px": dict(zip(("fx", "fy", "cx", "cy"), calibration.std_fx_fy_cx_cy.tolist()))})
        if calibration.opencv_std is not None:  # std_px widened by a jackknife over the images
            entry["opencv_std_px"] = dict(zip(("fx", "fy", "cx", "cy"), calibration.opencv_std.tolist()))
    return entry


def result_entries(cell: Cell, images: Any) -> dict[str, Any]:
    """The result's ``camera`` (intrinsics) and ``images`` (stations, errors, dropped) entries."""
    obs = images.observations
    camera = intrinsics_entry(images.camera, images.calibration, cell.images.intrinsics, obs.intrinsics_std,
                              obs.intrinsics_std_from)
    if images.calibration is not None:
        camera["per_image_rms_px"] = dict(zip(images.names, images.calibration.per_image_rms.tolist()))
    check = images.observations.focal_check  # given intrinsics against the images' own (docs/images.md)
    if check is not None:
        camera["focal_check"] = {"images_fx_fy": list(check.own), "images_std_px": list(check.std),
                                 "sigmas": check.sigmas, "percent": check.percent, "images": check.views,
                                 "warned": check.off}
    stations = [{"image": f, "robot_pose": p, "points": len(u), "rms_px": float(e)}
                for f, p, u, e in zip(images.files, images.pose_names, images.observations.image_points,
                                      images.errors)]
    return {"camera": camera, "images": {"folder": cell.images.folder, "board": cell.images.board,
                                         "stations": stations,
                                         "dropped": [dataclasses.asdict(d) for d in images.dropped]}}
