"""``handeye calibrate --images DIR --board SPEC [--intrinsics FILE]``: board images instead of a
camera pose file.

The images are paired with the robot poses (``--match``: ``name`` = file stem and robot pose
name; ``index`` (or ``row``, the default) = k-th image in natural order and k-th robot pose;
``time`` = stamp in the file name or a sidecar), the board is detected in each, the camera is
calibrated from the same images when no ``--intrinsics`` is given, and the board poses
(T_cam_target, solvePnP) become the camera stream of the ordinary ``calibrate`` path
(`handeye.cli.calibrate_cmd.run`). An image whose board is not found, or whose reprojection error
is far above the others', is dropped together with its robot pose, and the reason printed.
What this module adds to the result: ``camera`` (the intrinsics, calibrated or read) and
``images`` (which image went with which robot pose, per-image errors, what was dropped).
docs/images.md is the reference.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from handeye.framework.errors import InputError
from handeye.framework.registry import get_registry
from handeye.io.pose_readers import PoseStack

#: the solver that refines on the corners' reprojection error, used by default when installed
REPROJECTION_SOLVER = "reprojection"
#: --match values of the image path and what they mean there (row is the command's default)
IMAGE_MATCHES = {"row": "index", "index": "index", "name": "name", "time": "time"}


@dataclasses.dataclass(frozen=True)
class ImageInputs:
    """What the image path hands to the calibrate command: the robot file as read, the kept
    images' board poses as the camera stream (robot unit), the rows pairing them, the result's
    ``matching`` entry, warnings, and the image set itself."""

    robot_file: PoseStack
    camera_file: PoseStack
    robot_rows: np.ndarray
    camera_rows: np.ndarray
    matching: dict[str, Any]
    warnings: list[str]
    image_set: Any


def add_flags(parser: argparse.ArgumentParser) -> None:
    """--images, --board, --intrinsics."""
    parser.add_argument("--images", metavar="DIR",
                        help="a folder of board images, one per station (instead of --camera/--camera-format): the "
                             "board is detected in each and its pose solved; paired with the robot poses by --match "
                             "index (= row, the default: k-th image in natural order), name (file stem = robot pose "
                             "name) or time (stamp in the file name or a sidecar); docs/images.md")
    parser.add_argument("--board", metavar="SPEC",
                        help="--images: the calibration board, e.g. chessboard:9x6:25mm, "
                             "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250, circlegrid:10x10:25.4mm (docs/boards.md)")
    parser.add_argument("--intrinsics", metavar="FILE",
                        help="--images: camera intrinsics (OpenCV YAML/XML/JSON, ROS camera_info YAML, "
                             "industrial_calibration cal_data.yaml); default: calibrated from the same images")


def check_flags(args: argparse.Namespace) -> bool:
    """True for the image path. One-line InputErrors for a wrong combination of flags."""
    if args.images is not None:
        given = [f for f, v in (("--camera", args.camera), ("--camera-format", args.camera_format),
                                ("--camera-unit", args.camera_unit)) if v is not None]
        if given:
            raise InputError(f"--images replaces --camera and --camera-format: give either --images DIR --board SPEC "
                             f"or --camera FILE --camera-format FORMAT, not both (drop {', '.join(given)})")
        if args.match not in IMAGE_MATCHES:
            raise InputError(f"--match {args.match} applies to pose streams; with --images use name, index or time")
        if args.board is None:
            raise InputError("--images needs --board SPEC (e.g. --board chessboard:9x6:25mm; docs/boards.md)")
        if args.camera_poses != "board-in-camera":
            raise InputError("--camera-poses applies to a camera pose file, not to --images; drop it")
        return True
    stray = [f for f, v in (("--board", args.board), ("--intrinsics", args.intrinsics)) if v is not None]
    if stray:
        raise InputError(f"{' and '.join(stray)} apply to --images DIR; give --images or drop them")
    if args.camera is None:
        raise InputError("give the camera's side: --camera FILE --camera-format FORMAT (board poses) or --images DIR "
                         "--board SPEC (board images)")
    if args.match == "index":
        args.match = "row"  # a pose file's rows: index and row say the same
    return False


def load(args: argparse.Namespace, read_robot: Callable[..., PoseStack]) -> ImageInputs:
    """The image path up to the camera stream: read the robot poses (`read_robot`, the command's
    reader), pair, detect, calibrate if needed, solve the board poses, print what happened (on
    stderr with --json)."""
    from handeye.vision.boards import parse_board
    from handeye.vision.image_set import images_and_poses
    from handeye.vision.intrinsics import load_camera

    if args.max_dt is not None and IMAGE_MATCHES[args.match] != "time":
        raise InputError("--max-dt applies to --match time; drop it")
    try:
        board = parse_board(args.board)
    except InputError as exc:
        raise InputError(f"--board: {exc}") from None
    camera = None
    if args.intrinsics is not None:
        try:
            camera = load_camera(args.intrinsics)
        except InputError as exc:
            raise InputError(f"--intrinsics: {exc}") from None
    robot = read_robot(args.robot, args.robot_format, args.robot_unit, args.orthonormalize, "robot",
                       args.robot_columns)
    images = images_and_poses(args.images, board, camera, setup=args.setup, robot=robot,
                              match=IMAGE_MATCHES[args.match], max_dt=args.max_dt, unit=robot.unit)
    poses = np.array(images.T_cam_target)
    poses.setflags(write=False)
    camera_file = PoseStack(poses, robot.unit, "matrix", images.names, None, None, repr(str(args.images)))
    rows = np.arange(len(images))
    matching = {"method": images.match, "matched": len(images), "message": images.match_note,
                "pairs": [{"image": n, "robot_pose": p} for n, p in zip(images.names, images.pose_names)],
                "dropped": [dataclasses.asdict(d) for d in images.dropped]}
    _print(args, board, images)
    warnings = [*images.warnings, *[f"dropped {d.describe()}" for d in images.dropped
                                    if d.image is not None and d.pose is not None
                                    and not any(d.reason in w for w in images.warnings)]]  # said once
    return ImageInputs(robot, camera_file, np.asarray(images.robot_rows), rows, matching, warnings, images)


def default_solver(problem: str) -> str | None:
    """`REPROJECTION_SOLVER` for axyb when it is installed, else None (the command's default)."""
    if problem == "axyb" and REPROJECTION_SOLVER in get_registry().solver_names("axyb"):
        return REPROJECTION_SOLVER
    return None


def pose_based_instead(solution: Any, defaulted: bool) -> str | None:
    """Why the default reprojection answer gives way to the pose-based default solver, or None:
    when the robot's poses explain the corners far worse than each image alone does
    (``robot_misfit`` above the solver's limit), the robot's pose errors dominate, which the
    reprojection model (robot poses exact) does not describe; only when the user chose no solver."""
    from handeye.plugins.reprojection import robot_errors_dominate

    d = solution.diagnostics
    if not defaulted or solution.solver != REPROJECTION_SOLVER or d.get("robot_misfit") is None:
        return None
    if not robot_errors_dominate(d):
        return None
    return (f"the robot's poses explain the board corners only to {solution.diagnostics['rms_px']:.2g} px RMS while "
            f"each image alone fits them to {solution.diagnostics['pnp_rms_px']:.2g} px: the robot's pose errors "
            "dominate the pixel noise, so the answer is the pose-based one (noise on both sides), not the "
            "reprojection fit (exact robot poses; --solver reprojection forces it)")


def solver_data(inputs: ImageInputs | None, solver: str, problem: str) -> dict[str, Any]:
    """The image observations as the solver's ``images`` field, for the reprojection solver only."""
    if inputs is None or solver != REPROJECTION_SOLVER or problem != "axyb":
        return {}
    return {"images": inputs.image_set.observations}


def inputs_entry(args: argparse.Namespace, inputs: ImageInputs) -> dict[str, Any]:
    """The result's ``inputs.camera``: where the board poses came from."""
    images = inputs.image_set
    return {"file": args.images, "format": f"images, board {args.board}", "unit": images.unit,
            "poses": len(images) + sum(d.image is not None for d in images.dropped),
            "holds": "T_cam_target", "intrinsics": args.intrinsics or "calibrated from the images"}


def result_entries(args: argparse.Namespace, inputs: ImageInputs) -> dict[str, Any]:
    """The result's ``camera`` (intrinsics) and ``images`` (stations, errors, dropped) entries."""
    images = inputs.image_set
    cam = images.camera
    camera: dict[str, Any] = {"K": cam.K.tolist(), "dist": cam.dist.tolist(),
                              "image_size": None if cam.size is None else list(cam.size),
                              "source": args.intrinsics or "calibrated"}
    if images.calibration is not None:
        cal = images.calibration
        camera.update({"model": cal.model, "rms_px": cal.rms,
                       "std_px": dict(zip(("fx", "fy", "cx", "cy"), cal.std_fx_fy_cx_cy.tolist())),
                       "per_image_rms_px": dict(zip(images.names, cal.per_image_rms.tolist()))})
    stations = [{"image": f, "robot_pose": p, "points": len(u), "rms_px": float(e)}
                for f, p, u, e in zip(images.files, images.pose_names, images.observations.image_points,
                                      images.errors)]
    return {"camera": camera, "images": {"folder": args.images, "board": args.board, "stations": stations,
                                         "dropped": [dataclasses.asdict(d) for d in images.dropped]}}


def _print(args: argparse.Namespace, board: Any, images: Any) -> None:
    out = sys.stderr if args.json else sys.stdout
    lines = [f"images {args.images}: board {board.describe()}; {images.match_note}"]
    for name, pose, u, err in zip(images.names, images.pose_names, images.observations.image_points, images.errors):
        lines.append(f"  image {name} <-> robot pose {pose}: {len(u)} points, reprojection RMS {err:.3f} px")
    lines += [f"  dropped {d.describe()}" for d in images.dropped]
    cal = images.calibration
    if cal is not None:
        K = cal.camera.K
        std = cal.std_fx_fy_cx_cy
        lines += [f"camera calibrated from {len(cal.per_image_rms)} images ({cal.model}): RMS {cal.rms:.3f} px",
                  (f"  fx {K[0, 0]:.2f} +- {std[0]:.2f}, fy {K[1, 1]:.2f} +- {std[1]:.2f}, cx {K[0, 2]:.2f} +- "
                   f"{std[2]:.2f}, cy {K[1, 2]:.2f} +- {std[3]:.2f} px (1-sigma)"),
                  "  K " + np.array2string(K, precision=3, suppress_small=True).replace("\n", ""),
                  "  dist (k1, k2, p1, p2, k3) " + " ".join(f"{v:.6g}" for v in cal.camera.dist)]
    print("\n".join(lines), file=out)
