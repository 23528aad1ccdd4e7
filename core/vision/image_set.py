"""A folder of board images and the robot's poses, turned into stations: which image goes with
which robot pose, the board's pose in each kept image, and why the others were dropped.

`images_and_poses(images, board, camera, robot=..., match=..., setup=...)`:

1. lists the images (`list_images`: natural order, ``2.png`` before ``10.png``);
2. pairs them with the robot poses (`pair_images`) *before* anything can fail, so that an image
   dropped later takes its own robot pose with it and never shifts the others:
   ``name``: file stem = the robot pose's name (its name/index column, its file stem for a pose
   directory, else its 0-based row number; integers compare as numbers, ``007`` = ``7``);
   ``index``: the k-th image with the k-th robot pose (equal counts required);
   ``time``: a stamp in the file name or a sidecar file (`image_stamp`) with the robot pose at the
   nearest time stamp within `max_dt` (``handeye.streams.station_matching.match_by_time``);
3. reads each image (`read_image`: grayscale; 16-bit and float images scaled to 8 bits by their
   own range) and detects the board; unreadable images, images of another size than most
   (`_majority_size`) and images where the board is not found are dropped with their robot pose
   and the reason (over the cores, and from the detection cache for images seen before:
   `handeye.vision.detection_plan`);
   where the detector offers several detections of an image (OpenCV detectors or flag sets), the
   one fitting the camera best is kept (`handeye.vision.best_corners.choose`: with the given
   intrinsics, or with intrinsics calibrated from the images);
4. without intrinsics, calibrates the camera from the detections (`handeye.vision.intrinsics`),
   and refuses intrinsics no real lens gives (`handeye.vision.lens_check`: a board described wrongly);
5. solves each board pose (`handeye.vision.camera_poses`) in the robot's length unit (board
   lengths converted) and drops images whose reprojection error is far above the others'
   (recalibrating the intrinsics without them when they were calibrated here).

A directory of one robot pose file per station (ROS-Industrial's ``poses/N.yaml`` with x, y, z,
qx, qy, qz, qw) is read by `handeye.io.pose_readers.read_pose_dir` (re-exported here), names = file stems.

Nothing passed in is modified; bad input raises `handeye.base.errors.InputError` with a one-line
message; an `InputError` is raised only when no usable station remains.
"""

from __future__ import annotations

import dataclasses
import re
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.checks.stations import Dropped
from handeye.io.input_files import load_json, load_yaml, number
from handeye.io.pose_readers import PoseStack, natural_key, read_pose_dir  # noqa: F401 (re-exported)
from handeye.streams.station_matching import default_max_dt, match_by_time
from handeye.vision.best_corners import choose
from handeye.vision.boards import UNITS, Board
from handeye.vision.camera_poses import board_pose, flag_outliers
from handeye.vision.image_files import depth_name, read_any, read_image, to_8bit  # noqa: F401 (re-exported)
from handeye.vision.intrinsics import CameraCalibration, calibrate_camera
from handeye.vision.intrinsics_check import (
    given_intrinsics_check,
    given_std,
    with_jackknife,
)
from handeye.vision.lens_check import lens_problem
from handeye.vision.observations import BoardObservations, Camera

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
MATCH_METHODS = ("name", "index", "time")
#: sidecar files holding an image's time stamp, tried in this order
SIDECAR_EXTENSIONS = (".txt", ".json", ".yaml", ".yml")
_STAMP_KEYS = ("stamp", "time", "t", "timestamp")
#: integer stamps with at least this many digits are nanoseconds (ROS' sec * 1e9 + nanosec)
_NANOSECOND_DIGITS = 18
_NUMBER = re.compile(r"\d+(?:\.\d+)?")
#: images named in a warning before "and N more"
_NAMED = 5

Detector = Callable[[np.ndarray, Board], Any]


@dataclasses.dataclass(frozen=True)
class Pairing:
    """Images paired with robot poses: image_rows[k] (into the image list) with robot_rows[k]
    (into the robot stack), in image order; what was left unpaired; the method."""

    image_rows: np.ndarray
    robot_rows: np.ndarray
    dropped: tuple[Dropped, ...]
    method: str
    note: str = ""


@dataclasses.dataclass(frozen=True)
class ImageSet:
    """The stations a set of images gives.

    names / files: the kept images (file stems / paths), in image order.
    T_cam_target: (m, 4, 4) board poses, translations in `unit`.
    observations: the kept images' corners (handeye.vision.observations.BoardObservations, board
        points in `unit`), for a reprojection-error solver.
    errors: (m,) RMS reprojection error of each kept image at its board pose (pixels).
    robot_rows: (m,) the robot pose (row of the robot stack) of each kept image, or None without robot.
    pose_names: the robot poses' names, one a kept image (or None without robot).
    dropped: every image or robot pose left out, with the reason.
    camera: the intrinsics used; calibration: their calibration here (None when given).
    warnings: what the caller must print.
    """

    names: tuple[str, ...]
    files: tuple[str, ...]
    T_cam_target: np.ndarray
    observations: BoardObservations
    errors: np.ndarray
    robot_rows: np.ndarray | None
    pose_names: tuple[str, ...] | None
    dropped: tuple[Dropped, ...]
    camera: Camera
    calibration: CameraCalibration | None
    unit: str
    match: str | None
    match_note: str = ""
    warnings: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.names)


# ----------------------------------------------------------------------------- listing and reading


def list_images(source: str | Path | Sequence[str | Path]) -> list[Path]:
    """The image files of a directory (extensions `IMAGE_EXTENSIONS`), or the files given, in
    natural order of their names."""
    if isinstance(source, (str, Path)):
        folder = Path(source)
        if not folder.exists():
            raise InputError(f"image folder {str(folder)!r} not found; give --images an existing folder")
        if not folder.is_dir():
            raise InputError(f"{str(folder)!r} is not a folder; give --images the folder holding the images")
        files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS]
        if not files:
            raise InputError(f"no images in {str(folder)!r} (looked for {', '.join(IMAGE_EXTENSIONS)})")
    else:
        files = [Path(p) for p in source]
        if not files:
            raise InputError("no image files given")
    stems = [p.stem for p in files]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise InputError(f"images {twice[:3]} appear twice (same name, other extension); keep one file per station")
    return sorted(files, key=lambda p: natural_key(p.name))


def image_stamp(path: str | Path) -> float | None:
    """The time stamp (seconds) of an image: from a sidecar file with its stem (``.txt``: one
    number; ``.json`` / ``.yaml``: key stamp, time, t or timestamp, a number or {sec(s), nanosec /
    nsecs}), else the last number in its file name (``frame_1700000000.25.png``; integers of
    `_NANOSECOND_DIGITS` or more digits are nanoseconds). None when there is none."""
    path = Path(path)
    for ext in SIDECAR_EXTENSIONS:
        sidecar = path.with_suffix(ext)
        if sidecar.is_file():
            return _sidecar_stamp(sidecar)
    numbers = _NUMBER.findall(path.stem)
    if not numbers:
        return None
    text = numbers[-1]
    if "." not in text and len(text) >= _NANOSECOND_DIGITS:
        return int(text) / 1e9
    return float(text)


def _sidecar_stamp(path: Path) -> float:
    src = f"time stamp file {str(path)!r}"
    text = path.read_text(encoding="utf-8-sig").strip()
    if path.suffix == ".txt":
        value: Any = text
    else:
        try:
            doc = load_json(text, src) if path.suffix == ".json" else load_yaml(text, src)
        except InputError as exc:
            raise InputError(f"{exc}; write the stamp as {{stamp: SECONDS}}") from None
        value = doc
        if isinstance(doc, dict):
            value = next((doc[k] for k in _STAMP_KEYS if k in doc), None)
            if isinstance(value, dict):
                sec = value.get("sec", value.get("secs"))
                nsec = value.get("nanosec", value.get("nsecs", 0))
                sec, nsec = (None, None) if isinstance(sec, str) or isinstance(nsec, str) else (number(sec), number(nsec))
                value = None if sec is None or nsec is None else sec + nsec * 1e-9
    seconds = None if isinstance(value, str) and path.suffix != ".txt" else number(value)  # JSON/YAML: no "12.5"
    if seconds is None:
        raise InputError(f"{src}: expected one number of seconds (or a key stamp / time), got {str(value)[:40]!r}")
    return seconds


# ----------------------------------------------------------------------------- pairing


def _name_key(name: str) -> str:
    name = str(name).strip()
    return str(int(name)) if name.isdigit() else name


def pose_names(robot: PoseStack) -> tuple[str, ...]:
    """The names robot poses are matched by: the name/index column, else 0-based row numbers."""
    return robot.names if robot.names is not None else tuple(str(i) for i in range(len(robot)))


def pair_images(files: Sequence[Path], robot: PoseStack, match: str, *, max_dt: float | None = None) -> Pairing:
    """Pair image files with robot poses (module docstring, step 2); unpaired ones are listed in
    `Pairing.dropped`. Raises InputError when the method cannot apply (index with unequal counts,
    time without stamps) or nothing pairs."""
    if match not in MATCH_METHODS:
        raise InputError(f"image matching must be one of {', '.join(MATCH_METHODS)}, got {match!r}")
    names = [Path(f).stem for f in files]
    robot_names = pose_names(robot)
    if match == "index":
        if len(files) != len(robot):
            raise InputError(f"--match index pairs the k-th image with the k-th robot pose, but there are "
                             f"{len(files)} images and {len(robot)} robot poses; give one pose per image or use "
                             "--match name")
        rows = np.arange(len(files))
        return Pairing(rows, rows.copy(), (), match, f"paired {len(files)} images with the robot poses in order")
    if match == "name":
        _refuse_shifted_numbers(names, robot)
        where: dict[str, int] = {}
        for i, n in enumerate(robot_names):
            if _name_key(n) in where:
                raise InputError(f"--match name: the robot poses name {n!r} twice; each station's name must be unique")
            where[_name_key(n)] = i
        image_rows = [i for i, n in enumerate(names) if _name_key(n) in where]
        robot_rows = [where[_name_key(names[i])] for i in image_rows]
        dropped = [Dropped("image", n, "no robot pose of that name")
                   for n in names if _name_key(n) not in where]
        used = set(robot_rows)
        dropped += [Dropped("robot", robot_names[i], "no image of that name") for i in range(len(robot)) if i not in used]
        note = f"paired {len(image_rows)} of {len(files)} images with robot poses by name"
    else:
        if robot.stamps is None:
            raise InputError("--match time: the robot poses have no time stamp column (a header 't', 'time' or "
                             "'stamp'); use --match name or index")
        stamps = [image_stamp(f) for f in files]
        missing = [n for n, s in zip(names, stamps) if s is None]
        if missing:
            raise InputError(f"--match time: image {missing[0]!r} has no time stamp in its name or in a sidecar "
                             f"file ({'/'.join(SIDECAR_EXTENSIONS)} with its name); use --match name or index")
        limit = default_max_dt(robot.stamps) if max_dt is None else float(max_dt)
        robot_rows, image_rows, dt = match_by_time(robot.stamps, np.asarray(stamps), limit)
        robot_rows, image_rows = list(robot_rows), list(image_rows)
        kept = set(image_rows)
        dropped = [Dropped("image", n, f"no robot pose within {limit:.3g} s of its stamp {s:.6f} s")
                   for i, (n, s) in enumerate(zip(names, stamps)) if i not in kept]
        unused = len(robot) - len(set(robot_rows))
        if unused and unused <= 10:
            dropped += [Dropped("robot", robot_names[i], "no image at its time")
                        for i in range(len(robot)) if i not in set(robot_rows)]
        worst = float(np.max(np.abs(dt))) * 1e3 if len(dt) else float("nan")
        note = (f"paired {len(image_rows)} of {len(files)} images with robot poses by time (max |dt| {worst:.3g} ms, "
                f"limit {limit * 1e3:.3g} ms)" + (f"; {unused} robot poses without an image" if unused > 10 else ""))
    if not image_rows:
        first = "; ".join(d.describe() for d in dropped[:2])
        raise InputError(f"--match {match}: no image pairs with a robot pose ({first}); check the file names or "
                         "use --match index")
    return Pairing(np.asarray(image_rows, dtype=np.intp), np.asarray(robot_rows, dtype=np.intp), tuple(dropped),
                   match, note)


def _refuse_shifted_numbers(image_names: Sequence[str], robot: PoseStack) -> None:
    """InputError when pairing by name would pair every image with the robot pose one station
    off: the images and the robot poses are numbered (a robot file without a name column by its
    rows from 0) and one set is the other shifted by one (images 1..N against rows 0..N-1, the
    usual 1-based against 0-based count)."""
    robot_names = pose_names(robot)
    if len(image_names) < 2 or not all(str(n).strip().isdigit() for n in (*image_names, *robot_names)):
        return
    images = sorted(int(n) for n in image_names)
    poses = sorted(int(n) for n in robot_names)
    shift = images[0] - poses[0]
    if shift not in (1, -1) or images[-1] - poses[-1] != shift:
        return
    poses_are = ("named by their rows from 0, as the robot file has no name column" if robot.names is None
                 else "named so")
    raise InputError(f"match='name': the images are numbered {images[0]}..{images[-1]} and the robot poses "
                     f"{poses[0]}..{poses[-1]} ({poses_are}): by name every image would go with the robot pose one "
                     f"station {'after' if shift > 0 else 'before'} its own if the two count the same stations from "
                     f"{images[0]} and {poses[0]}; use match='index' to pair the k-th image with the k-th robot pose, "
                     "or name them alike")


# ----------------------------------------------------------------------------- the stations


def _detect_all(files: Sequence[Path], board: Board, detector: Detector | None, camera: Camera | None,
                workers: int | None, cache: bool | str | Path | None
                ) -> tuple[list, list[str | None], tuple | None, list[str]]:
    """Per file: the detection or None, the reason it failed or None; the set's image size (the
    one most readable images have, None when none is readable); warnings (images scaled to 8 bits,
    images of another size dropped). The default detector runs over the cores with the cache and,
    for chessboards, a flag-set plan (`handeye.vision.detection_plan`); another one file by file."""
    if detector is None:
        from handeye.vision.detection_plan import detect_set

        outcomes = detect_set(files, board, camera, workers=workers, cache=cache)
    else:
        from handeye.vision.image_detection import detect_file

        outcomes = [detect_file(Path(f), board, detector) for f in files]
    found: list = [o.detection for o in outcomes]
    reasons: list[str | None] = [o.reason for o in outcomes]
    sizes = [o.size for o in outcomes]
    converted: dict[str, list[tuple[str, float]]] = {}
    for path, outcome in zip(files, outcomes):
        if outcome.depth is not None:
            converted.setdefault(outcome.depth[0], []).append((path.name, outcome.depth[1]))
    size = _majority_size(sizes)
    odd = [k for k, s in enumerate(sizes) if s is not None and s != size]
    for k in odd:
        found[k] = None
        reasons[k] = (f"image size {sizes[k][0]}x{sizes[k][1]} differs from the {size[0]}x{size[1]} of most "
                      "images")
    warnings = [_converted_warning(depth, named, len(files)) for depth, named in converted.items()]
    warnings += [f"dropped image {files[k].name}: {reasons[k]} (another camera or resolution?)" for k in odd]
    return found, reasons, size, warnings


def _majority_size(sizes: Sequence[tuple[int, int] | None]) -> tuple[int, int] | None:
    """The image size (width, height) most readable images have; a tie goes to the size seen first
    (Counter keeps first-seen order). One odd image, first or not, then drops alone."""
    counts = Counter(s for s in sizes if s is not None)
    return counts.most_common(1)[0][0] if counts else None


def _converted_warning(depth: str, named: list[tuple[str, float]], total: int) -> str:
    """One line for the images of one depth that were scaled to 8 bits."""
    largest = max(value for _, value in named)
    which = (f"all {total} images are" if len(named) == total else
             f"{len(named)} image{'s are' if len(named) > 1 else ' is'} ({_names([n for n, _ in named])})")
    return (f"{which} {depth} (largest value {largest:g}): each was scaled from its own min..max to 8 bits to "
            "detect the board")


def _names(names: Sequence[str]) -> str:
    """Up to `_NAMED` names, then "and N more"."""
    shown = ", ".join(names[:_NAMED])
    return shown + (f" and {len(names) - _NAMED} more" if len(names) > _NAMED else "")


def images_and_poses(images: str | Path | Sequence[str | Path], board: Board, camera: Camera | None = None, *,
                     setup: str, robot: PoseStack | None = None, match: str = "name", max_dt: float | None = None,
                     unit: str | None = None, detector: Detector | None = None, workers: int | None = None,
                     cache: bool | str | Path | None = None) -> ImageSet:
    """The stations of a set of board images (module docstring).

    images: a folder or a list of image files. board: the calibration board. camera: the
    intrinsics, or None to calibrate them from these images. setup: ``eye-in-hand`` or
    ``eye-to-hand`` (recorded in the observations). robot: the robot's poses to pair with, or None.
    match / max_dt: how images pair with robot poses (`pair_images`). unit: the length unit of the
    board poses (default: the robot's, else the board's). detector: ``(image, board) -> Detection``
    (default `handeye.vision.detect.detect`, run on `workers` threads, default the cores, and
    its detections kept in the detection cache: `cache` None / True the environment's, False none,
    a folder that one; `handeye.vision.detection_plan`).
    """
    files = list_images(images)
    unit = unit or (robot.unit if robot is not None else board.unit)
    if unit not in UNITS:
        raise InputError(f"unit must be 'mm' or 'm', got {unit!r}")
    if robot is not None:
        pairing = pair_images(files, robot, match, max_dt=max_dt)
        robot_names = pose_names(robot)
    else:
        rows = np.arange(len(files))
        pairing = Pairing(rows, rows, (), "none")
        robot_names = None
    dropped = list(pairing.dropped)
    files_used = [files[i] for i in pairing.image_rows]
    robot_rows = list(pairing.robot_rows)

    def pose_of(k: int) -> str | None:
        return None if robot_names is None else robot_names[robot_rows[k]]

    found, reasons, size, warnings = _detect_all(files_used, board, detector, camera, workers, cache)
    keep = [k for k, d in enumerate(found) if d is not None]
    dropped += [Dropped("image", files_used[k].stem, reasons[k], pose_of(k)) for k in range(len(found)) if found[k] is None]
    if size is None:
        raise InputError(f"none of the {len(files_used)} images could be read ({files_used[0].name}: {reasons[0]})")
    if not keep:
        raise InputError(f"the board ({board.describe()}) was found in none of the {len(files_used)} images "
                         f"({reasons[0]}); check --board (counts, kind) and the images")
    if camera is not None and camera.size is not None and size is not None and tuple(camera.size) != size:
        raise InputError(f"the intrinsics are for {camera.size[0]}x{camera.size[1]} images but the images are "
                         f"{size[0]}x{size[1]}; give the intrinsics of this camera at this resolution")
    if board.orientation_ambiguous:
        warnings.append(f"the board ({board.describe()}) looks the same after a half turn (cols + rows even): "
                        "its corner order may flip 180 deg between images, which spoils the board poses; prefer "
                        "cols + rows odd or a ChArUco board")
    choice = choose([found[k] for k in keep], camera, size)
    for k, detection in zip(keep, choice.detections):
        found[k] = detection
    scale = UNITS[board.unit] / UNITS[unit]
    calibration, calibrated = None, choice.calibration if choice.calibrated_kept else None  # once per set
    while True:
        names = [files_used[k].stem for k in keep]
        if camera is None or calibration is not None:
            calibration = calibrated or calibrate_camera([found[k] for k in keep], size, names=names)
            calibrated = None
            camera_used = calibration.camera
        else:
            camera_used = camera
        poses, errors, failed = [], [], []
        for k in keep:
            try:
                pose = board_pose(found[k].object_points * scale, found[k].image_points, camera_used,
                                  name=f"image {files_used[k].name}")
            except InputError as exc:
                failed.append((k, str(exc)))
                continue
            poses.append(pose.T_cam_target)
            errors.append(pose.rms)
        ok = [k for k in keep if k not in {f for f, _ in failed}]
        outliers = [(ok[i], reason) for i, reason in flag_outliers(errors, [files_used[k].stem for k in ok])]
        bad = failed + outliers
        if not bad:
            break
        dropped += [Dropped("image", files_used[k].stem, reason, pose_of(k)) for k, reason in bad]
        warnings += [f"dropped image {files_used[k].name}: {reason}" for k, reason in outliers]
        keep = [k for k in keep if k not in {b for b, _ in bad}]
        if not keep:
            raise InputError(f"no usable image left: {bad[0][1]}")
    focal = None  # the images' own focal length against given intrinsics (`_intrinsics_check`)
    if calibration is not None and (problem := lens_problem(calibration, board)):
        raise InputError(problem)
    if calibration is not None:  # its 1-sigma as a jackknife over the images finds it, where larger than OpenCV's
        calibration = with_jackknife(calibration, [found[k] for k in keep], size)
    else:
        checked, focal = given_intrinsics_check([found[k] for k in keep], np.array(errors), size, camera_used)
        warnings += checked
    kept_names = tuple(files_used[k].stem for k in keep)
    T = np.array(poses)
    T.setflags(write=False)
    std, source = ((tuple(float(v) for v in calibration.std_fx_fy_cx_cy), "images") if calibration is not None
                   else given_std(camera_used, focal))
    observations = BoardObservations(tuple(found[k].image_points for k in keep),
                                     tuple(found[k].object_points * scale for k in keep), camera_used, setup,
                                     kept_names, intrinsics_std=std, intrinsics_std_from=source, focal_check=focal)
    rows = None if robot is None else np.array([robot_rows[k] for k in keep], dtype=np.intp)
    return ImageSet(kept_names, tuple(str(files_used[k]) for k in keep), T, observations, np.array(errors), rows,
                    None if rows is None else tuple(robot_names[r] for r in rows), tuple(dropped), camera_used,
                    calibration, unit, None if robot is None else pairing.method, pairing.note, tuple(warnings))
