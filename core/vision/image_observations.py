"""One camera's folder of images, each possibly showing several named boards, turned into
observations: a (station, target, T_cam_target) per board found, and why every other (image,
board) was left out. The images of a cell of several cameras and targets (``axyb-multi``;
`handeye.workflow.observation_images` makes them rows of its table of observations).

`camera_observations(folder, boards, camera, robot=..., match=...)`:

1. lists the images and pairs them with the robot's stations as the single-camera image path
   does (`handeye.vision.image_set.pair_images`: ``index``, ``name`` or ``time``), before anything
   can fail, so that an image left out never shifts the others;
2. reads each image and looks for every board in it (`handeye.vision.board_set.detect_board_files`:
   over the cores, from the detection cache, a chessboard's flag-set plan judged on this camera's
   images, as one camera's image set is detected), keeping per board and image the detector whose
   corners fit the camera best (`handeye.vision.best_corners.choose`, as for one camera's images);
   an unreadable image or one of another size than most is dropped whole; a board not found, or
   found with fewer points than its detector needs, is dropped for that image only, with the
   detector's reason;
3. without intrinsics, calibrates the camera from every board found (each a view);
4. solves each board's pose by PnP (`handeye.vision.camera_poses.board_pose`, in the robot's
   unit) and drops a pose whose reprojection error is far above the camera's others (`flag_outliers`:
   a wrong detection, blur, a moved board), with a note, recalibrating intrinsics calibrated here;
5. as for one camera's images (`handeye.vision.intrinsics_check`): intrinsics calibrated here are
   refused where no real lens gives them (`handeye.vision.lens_check`: a board described wrongly)
   and get the larger of OpenCV's 1-sigma and a delete-one jackknife's over the images
   (`with_jackknife`, an image's boards left out together); intrinsics given are checked against
   the camera calibrated from the same corners (`given_intrinsics_check`: their fit, their focal
   length), with the warning where the images contradict them. The corners are kept
   (`CameraObservations.detections`) for what the answer's uncertainty needs of them
   (`handeye.workflow.observation_images`).

InputError (one line) only when nothing usable remains or the input cannot apply (no folder,
pairing impossible, intrinsics for another image size, intrinsics no lens gives).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.checks.stations import Dropped
from handeye.io.pose_readers import PoseStack
from handeye.vision.best_corners import choose
from handeye.vision.board_set import Detector, check_distinct, detect_board_files
from handeye.vision.boards import UNITS, Board
from handeye.vision.camera_poses import board_pose, flag_outliers
from handeye.vision.image_set import (
    _majority_size,
    list_images,
    pair_images,
    pose_names,
)
from handeye.vision.intrinsics import CameraCalibration, calibrate_camera
from handeye.vision.intrinsics_check import (
    FocalCheck,
    given_intrinsics_check,
    given_std,
    with_jackknife,
)
from handeye.vision.lens_check import lens_problem
from handeye.vision.observations import Camera


@dataclasses.dataclass(frozen=True)
class CameraObservations:
    """What one camera's images gave: per observation k (a board found and kept in an image),
    image[k] (file stem), station[k] (the robot pose's name), robot_row[k] (its row in the robot
    stack), target[k] (the board's name), T_cam_target[k] (4x4, translations in `unit`),
    errors[k] (RMS reprojection error at that pose, px), points[k] (points detected); dropped:
    every image or (image, board) left out, with why; camera: the intrinsics used (calibration:
    their calibration here, its 1-sigma widened by the jackknife, None when given); images: how
    many images the folder holds; note: the pairing in words; warnings: what the caller must
    print; detections[k]: the corners (``image_points``, px, and ``object_points``, in the
    board's own unit); focal_check: given intrinsics' focal length against the images' own
    (None when calibrated here, or too few images to say)."""

    image: tuple[str, ...]
    station: tuple[str, ...]
    robot_row: np.ndarray
    target: tuple[str, ...]
    T_cam_target: np.ndarray
    errors: np.ndarray
    points: np.ndarray
    dropped: tuple[Dropped, ...]
    camera: Camera
    calibration: CameraCalibration | None
    unit: str
    images: int
    note: str
    warnings: tuple[str, ...] = ()
    detections: tuple[Any, ...] = ()
    focal_check: FocalCheck | None = None

    def __len__(self) -> int:
        return len(self.image)

    @property
    def intrinsics_std(self) -> tuple[tuple[float, float, float, float] | None, str]:
        """The 1-sigma (px) of fx, fy, cx, cy that answers from these observations owe the
        intrinsics, and where it comes from (`handeye.vision.observations.STD_SOURCES`): the
        calibration here, else the file's own or the images' (`given_std`); None: exact."""
        if self.calibration is not None:
            return tuple(float(v) for v in self.calibration.std_fx_fy_cx_cy), "images"
        return given_std(self.camera, self.focal_check)


def camera_observations(folder: str | Path, boards: Mapping[str, Board], camera: Camera | None, *,
                        robot: PoseStack, match: str = "index", max_dt: float | None = None,
                        unit: str | None = None, detector: Detector | None = None, workers: int | None = None,
                        cache: bool | str | Path | None = None) -> CameraObservations:
    """The observations of the images in `folder` (module docstring). boards: the targets this
    camera may see, by name; camera: its intrinsics, or None to calibrate them from the boards
    found; robot: the stations' robot poses; match / max_dt: how images pair with them; unit: the
    poses' length unit (default the robot's); detector: ``(image, board) -> Detection`` (called on
    one image at a time, never cached; the built-in detectors run on `workers` threads, default the
    cores, their detections kept in the detection cache: `cache` None / True the environment's,
    False none, a folder that one, as `handeye.vision.image_set.images_and_poses`)."""
    if not boards:
        raise InputError("a camera's images need at least one target (board) to look for")
    check_distinct(boards)
    unit = unit or robot.unit
    if unit not in UNITS:
        raise InputError(f"unit must be 'mm' or 'm', got {unit!r}")
    files = list_images(folder)
    pairing = pair_images(files, robot, match, max_dt=max_dt)
    names = pose_names(robot)
    dropped = list(pairing.dropped)
    used = [files[i] for i in pairing.image_rows]
    rows = [int(r) for r in pairing.robot_rows]
    found, sizes = [], []
    outcomes = detect_board_files(used, boards, camera, workers=workers, cache=cache, detector=detector)
    for k, (path, outcome) in enumerate(zip(used, outcomes)):
        if isinstance(outcome, InputError):
            dropped.append(Dropped("image", path.stem, str(outcome).removeprefix(f"{path.name}: "), names[rows[k]]))
            found.append({})
            sizes.append(None)
            continue
        size_k, result = outcome
        sizes.append(size_k)
        dropped += [Dropped("image", path.stem, f"{name} not found: {why}") for name, why in result.missing.items()]
        found.append(result.found)
    size = _majority_size(sizes)
    warnings: list[str] = []
    for k, s in enumerate(sizes):
        if s is not None and s != size:
            reason = f"image size {s[0]}x{s[1]} differs from the {size[0]}x{size[1]} of most images"
            dropped.append(Dropped("image", used[k].stem, reason, names[rows[k]]))
            warnings.append(f"dropped image {used[k].name}: {reason} (another camera or resolution?)")
            found[k] = {}
    views = [(k, name) for k, f in enumerate(found) for name in f]
    if not views:
        raise InputError(f"no board ({', '.join(boards)}) was found in any of the {len(used)} images of "
                         f"{str(folder)!r}; check the targets' specs and the images")
    if camera is not None and camera.size is not None and tuple(camera.size) != size:
        raise InputError(f"the intrinsics are for {camera.size[0]}x{camera.size[1]} images but the images of "
                         f"{str(folder)!r} are {size[0]}x{size[1]}; give this camera's intrinsics at this resolution")
    for name in boards:  # each board's corners: the detector that fits the camera best (`best_corners.choose`)
        seen = [k for k, n in views if n == name]
        if seen:
            for k, detection in zip(seen, choose([found[k][name] for k in seen], camera, size).detections):
                found[k] = {**found[k], name: detection}
    calibration: CameraCalibration | None = None
    while True:  # until no pose is left out: the median, and intrinsics calibrated here, change
        if camera is None or calibration is not None:
            calibration = calibrate_camera([found[k][n] for k, n in views], size,
                                           names=[f"{used[k].stem} ({n})" for k, n in views])
        camera_used = camera if calibration is None else calibration.camera
        poses, errors, bad = [], [], []
        for k, name in views:
            board, detection = boards[name], found[k][name]
            scale = UNITS[board.unit] / UNITS[unit]
            try:
                pose = board_pose(detection.object_points * scale, detection.image_points, camera_used,
                                  name=f"image {used[k].name}, {name}")
            except InputError as exc:
                bad.append(((k, name), str(exc).split(": ", 1)[-1]))
                continue
            poses.append(pose.T_cam_target)
            errors.append(pose.rms)
        kept = [v for v in views if v not in {b for b, _ in bad}]
        outliers = [(kept[i], reason) for i, reason in flag_outliers(errors, [str(v) for v in kept])]
        if not bad and not outliers:
            break
        for (k, name), reason in bad + outliers:
            dropped.append(Dropped("image", used[k].stem, f"{name}: unreliable pose, {reason}"))
        warnings += [f"dropped {name} in image {used[k].name} ({names[rows[k]]}): unreliable pose, {reason}"
                     for (k, name), reason in outliers]
        views = [v for v in kept if v not in {o for o, _ in outliers}]
        if not views:
            raise InputError(f"no usable board pose left in the images of {str(folder)!r}: {(bad + outliers)[0][1]}")
    detections = tuple(found[k][n] for k, n in views)
    stems = [used[k].stem for k, _ in views]  # an image's boards leave the jackknife together
    check = None
    if calibration is not None and (problem := lens_problem(calibration, boards)):
        raise InputError(f"images of {str(folder)!r}: {problem}")
    if calibration is not None:
        calibration = with_jackknife(calibration, detections, size, stems)
    else:  # as one camera's images check a file (image_set)
        checked, check = given_intrinsics_check(detections, np.array(errors), size, camera_used, stems)
        warnings += checked
    T = np.array(poses, dtype=float).reshape(-1, 4, 4)
    T.setflags(write=False)
    return CameraObservations(
        image=tuple(used[k].stem for k, _ in views), station=tuple(names[rows[k]] for k, _ in views),
        robot_row=np.array([rows[k] for k, _ in views], dtype=np.intp), target=tuple(n for _, n in views),
        T_cam_target=T, errors=np.array(errors, dtype=float),
        points=np.array([len(found[k][n]) for k, n in views], dtype=np.int64), dropped=tuple(dropped),
        camera=camera_used, calibration=calibration, unit=unit, images=len(files), note=pairing.note,
        warnings=tuple(warnings), detections=detections, focal_check=check)


def summary(name: str, folder: Any, obs: CameraObservations) -> list[str]:
    """What one camera's images gave, in lines: the pairing, the boards found per image with their
    reprojection RMS, what was dropped, and the intrinsics when calibrated here."""
    lines = [f"camera {name}: images {folder}: {obs.note}; {len(obs)} board poses"]
    per_image: dict[str, list[str]] = {}
    for image, target, err in zip(obs.image, obs.target, obs.errors):
        per_image.setdefault(image, []).append(f"{target} {err:.3f} px")
    lines += [f"  image {image}: {', '.join(seen)}" for image, seen in per_image.items()]
    lines += [f"  dropped {d.describe()}" for d in obs.dropped]
    if obs.calibration is not None:
        cal = obs.calibration
        K = cal.camera.K
        std = cal.std_fx_fy_cx_cy
        lines.append(f"  intrinsics calibrated from {len(cal.per_image_rms)} board views ({cal.model}): RMS "
                     f"{cal.rms:.3f} px, fx {K[0, 0]:.2f} +- {std[0]:.2f} fy {K[1, 1]:.2f} +- {std[1]:.2f} "
                     f"cx {K[0, 2]:.2f} +- {std[2]:.2f} cy {K[1, 2]:.2f} +- {std[3]:.2f} px (1-sigma"
                     + ("" if cal.opencv_std is None else ", the larger of OpenCV's and a jackknife's over the images")
                     + ")")
    elif obs.focal_check is not None:
        c = obs.focal_check
        lines.append(f"  intrinsics file's focal length fx {c.given[0]:.2f} fy {c.given[1]:.2f} px; calibrated from these "
                     f"{c.views} images: fx {c.own[0]:.2f} fy {c.own[1]:.2f} +- {c.std[0]:.2f} px (1-sigma); the file "
                     f"{c.percent:+.2f}%, {c.sigmas:+.1f} of that 1-sigma")
    std, source = obs.intrinsics_std
    if obs.calibration is None and std is not None:
        lines.append(f"  the answer's 1-sigma carries the file's fx, fy, cx, cy to {std[0]:.2f}, {std[1]:.2f}, "
                     f"{std[2]:.2f}, {std[3]:.2f} px: "
                     + ("as the file states" if source == "file" else
                        "the file states none, so the images' own (state the file's as std_px where it is known better)"))
    return lines
