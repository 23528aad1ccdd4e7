"""``handeye calibrate --images`` against OpenCV's own sequential pipeline on the same images, in
the same run: the time a user waits, from image files to the hand-eye answer.

Sets (each skipped when absent):

- ``chessboard``: 30 rendered 1280 x 1024 (1.3 MP) views of a 10 x 7 chessboard, 30 mm squares
  (blur 0.8 px, noise 2 grey levels, barrel distortion; eye in hand), written once to
  ``--chessboard-dir`` (default: a folder in the system's temp dir). No real chessboard set is
  stored with the project; this stands for the 28-30 real 1.3 MP images users calibrate from.
- ``charuco``: industrial_calibration's 16 real 1600 x 1200 ChArUco images (eye to hand,
  /work/shared/data/industrial_calibration_rct).
- ``circles``: the bundled 15 real 640 x 480 circle-grid images (eye in hand).

Rows, timed per set in turn (round-robin over ``--repeats``, so that load on the shared machine
hits every row alike; the median is printed):

- ``opencv``: cv2.imread, the board's OpenCV detector (chessboard: ``findChessboardCornersSB`` with
  its default flags; ``opencv accuracy``: with ``CALIB_CB_ACCURACY``, the flag set handeye's corner
  choice keeps on most images; ChArUco: ``CharucoDetector.detectBoard``; circle grid:
  ``findCirclesGrid``), ``calibrateCamera``, ``solvePnP`` per image and ``calibrateHandEye`` (PARK),
  one image after the other, as OpenCV's samples do;
- ``handeye``: ``handeye.cli.main(["calibrate", "--images", ...])`` in this process with an empty
  detection cache;
- ``handeye rerun``: the same call again, detections from the cache of the run before;
- ``handeye before`` (``--before``): one worker, no cache, every flag set on every image: the
  pipeline as it was before the threads, the cache and the chessboard plan;
- ``handeye full image`` (``--full-image``, chessboard only): as ``handeye`` with no detection
  cache and SB's ACCURACY flag sets on the full image instead of a crop around the board
  (`handeye.vision.chessboard_region` told it cannot locate the board): the pipeline as it was
  before the crop.

The ratio column divides by ``opencv``. Targets: ``handeye`` no slower than ``opencv`` on the
chessboard set; ``handeye rerun`` below 3 s.

Usage: python bench/images_speed.py [--sets chessboard,charuco,circles] [--repeats 3] [--workers N] [--before]
       [--full-image] [--real-chessboard FOLDER BOARD ROBOT ...]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "industrial_calibration_rct"
CHESSBOARD = "chessboard:10x7:30mm"
CHESS_STATIONS = 30


# ----------------------------------------------------------------------------- the image sets


def render_chessboard_set(folder: Path) -> Path:
    """Write the rendered chessboard set (module docstring) into `folder` unless it is there:
    ``images/N.png`` and ``robot.csv`` (T_base_flange, xyz-quat-xyzw, mm). Deterministic."""
    from scipy.spatial.transform import Rotation

    from handeye.geometry.se3 import inverse, make_pose
    from handeye.io.pose_readers import PoseStack
    from handeye.io.pose_writers import write_poses
    from handeye.vision.boards import parse_board
    from handeye.vision.observations import Camera
    from handeye.vision.render import render

    if (folder / "robot.csv").is_file() and len(list((folder / "images").glob("*.png"))) == CHESS_STATIONS:
        return folder
    (folder / "images").mkdir(parents=True, exist_ok=True)
    board = parse_board(CHESSBOARD)
    camera = Camera(np.array([[1150.0, 0, 642.0], [0, 1152.0, 509.0], [0, 0, 1]]),
                    np.array([-0.15, 0.08, 0.0005, -0.0003, 0.0]), (1280, 1024))
    rng = np.random.default_rng(7)
    points = board.object_points()
    centre = (points.min(0) + points.max(0)) / 2
    X = make_pose(Rotation.from_euler("xyz", [5, -80, 10], degrees=True).as_matrix(), [40.0, -25.0, 110.0])
    Y = make_pose(Rotation.from_euler("xyz", [180, 5, 95], degrees=True).as_matrix(), [900.0, 150.0, -30.0])
    A = []
    for i in range(CHESS_STATIONS):
        tilt, azimuth = np.radians(35.0) * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
        direction = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)])
        position = centre + rng.uniform(550, 900) * direction
        z = (centre - position) / np.linalg.norm(centre - position)
        x = np.cross([0, 1.0, 0], z)
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z]) @ Rotation.from_rotvec([0, 0, rng.uniform(-0.5, 0.5)]).as_matrix()
        T_target_cam = make_pose(R, position)
        image = render(board, camera, inverse(T_target_cam), blur=0.8, noise=2.0, rng=rng)
        cv2.imwrite(str(folder / "images" / f"{i}.png"), image)
        A.append(Y @ T_target_cam @ inverse(X))
    names = tuple(str(i) for i in range(CHESS_STATIONS))
    write_poses(folder / "robot.csv", PoseStack(np.array(A), "mm", "matrix", names, None, None, "rendered"),
                "xyz-quat-xyzw")
    return folder


def image_sets(which: list[str], chess_dir: Path, real: list[list[str]] | None = None) -> list[dict]:
    """Each set: name, images folder, board spec, CLI arguments of its robot poses and setup, and
    the robot poses as T_base_flange (n, 4, 4) in the image order, for OpenCV. `real`: real
    chessboard sets given as (folder, board, robot file of row-major 4x4 matrices in metres, one a
    line, paired with the images in order: the KUKA sets' RobotPosesVec.txt), eye in hand."""
    from handeye.io.examples import image_example_dir
    from handeye.io.pose_readers import read_pose_dir, read_poses

    sets = []
    for folder, board, robot_file in real or []:
        robot = read_poses(robot_file, "matrix", unit="m")
        sets.append({"name": f"{board} (real, {Path(folder).name})", "images": Path(folder), "board": board,
                     "robot": robot.poses, "setup": "eye-in-hand", "match": "index",
                     "args": ["--robot", robot_file, "--robot-format", "matrix", "--robot-unit", "m"]})
    if "chessboard" in which:
        folder = render_chessboard_set(chess_dir)
        robot = read_poses(folder / "robot.csv", "xyz-quat-xyzw", unit="mm")
        sets.append({"name": "chessboard (rendered, 30 x 1.3 MP)", "images": folder / "images", "board": CHESSBOARD,
                     "robot": robot.poses, "setup": "eye-in-hand",
                     "args": ["--robot", folder / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm"]})
    if "charuco" in which and SHARED.is_dir():
        folder = SHARED / "test_set_charuco"
        robot = read_pose_dir(folder / "poses", "xyz-quat-xyzw", unit="m")
        sets.append({"name": "charuco (real, 16 x 1.9 MP)", "images": folder / "images",
                     "board": "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250", "robot": robot.poses,
                     "setup": "eye-to-hand", "names": robot.names,
                     "args": ["--robot", folder / "poses", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m"]})
    if "circles" in which:
        folder = image_example_dir()
        robot = read_pose_dir(folder / "poses", "xyz-quat-xyzw", unit="m")
        sets.append({"name": "circle grid (real, 15 x 0.3 MP)", "images": folder / "images",
                     "board": "circlegrid:10x10:25.4mm", "robot": robot.poses, "setup": "eye-in-hand",
                     "names": robot.names,
                     "args": ["--robot", folder / "poses", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m"]})
    return sets


# ----------------------------------------------------------------------------- OpenCV's pipeline


def opencv_pipeline(image_set: dict, accuracy: bool = False) -> float:
    """Seconds of OpenCV's sequential pipeline on the set (module docstring): detect every image,
    calibrateCamera, solvePnP each, calibrateHandEye (PARK)."""
    from handeye.vision.boards import parse_board
    from handeye.vision.image_set import list_images

    started = time.perf_counter()
    board = parse_board(image_set["board"])
    files = list_images(image_set["images"])
    detect = _opencv_detector(board, accuracy)
    obj, img, rows = [], [], []
    for k, path in enumerate(files):
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        found = detect(gray)
        if found is not None and len(found[0]) >= 6:
            obj.append(found[0].astype(np.float32))
            img.append(found[1].astype(np.float32))
            rows.append(k)
    size = (gray.shape[1], gray.shape[0])
    _, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None)
    R_t2c, t_t2c = [], []
    for o, u in zip(obj, img):
        _, rvec, tvec = cv2.solvePnP(o, u, K, dist)
        R_t2c.append(cv2.Rodrigues(rvec)[0])
        t_t2c.append(tvec)
    A = image_set["robot"][_robot_rows(image_set, files, rows)]
    if image_set["setup"] == "eye-to-hand":
        A = np.linalg.inv(A)
    cv2.calibrateHandEye(A[:, :3, :3], A[:, :3, 3], R_t2c, t_t2c, method=cv2.CALIB_HAND_EYE_PARK)
    return time.perf_counter() - started


def _robot_rows(image_set: dict, files: list[Path], rows: list[int]) -> list[int]:
    """The robot pose of each detected image: by name where the poses are named, else in order."""
    names = image_set.get("names")
    if names is None:
        return rows
    where = {str(int(n)) if str(n).isdigit() else str(n): i for i, n in enumerate(names)}
    return [where[str(int(files[k].stem))] for k in rows]


def _opencv_detector(board, accuracy: bool) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray] | None]:
    """(board points, pixels) of the board in a grey image by OpenCV's own detector, None if not found."""
    points = board.object_points()
    if board.kind == "chessboard":
        flags = cv2.CALIB_CB_ACCURACY if accuracy else 0

        def chessboard(gray):
            ok, corners = cv2.findChessboardCornersSB(gray, (board.cols, board.rows), flags=flags)
            return (points, corners.reshape(-1, 2)) if ok else None
        return chessboard
    if board.kind == "charuco":
        from handeye.vision.detect import charuco_board

        cv_board = charuco_board(board)
        detector = cv2.aruco.CharucoDetector(cv_board)

        def charuco(gray):
            corners, ids, _, _ = detector.detectBoard(gray)
            return None if ids is None else (points[ids.ravel()], corners.reshape(-1, 2))
        return charuco

    def circles(gray):
        ok, centres = cv2.findCirclesGrid(gray, (board.cols, board.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
        return (points, centres.reshape(-1, 2)) if ok else None
    return circles


# ----------------------------------------------------------------------------- handeye


def handeye_run(image_set: dict, cache: Path | None, out: Path, workers: int | None, before: bool = False,
                crop: bool = True) -> float:
    """Seconds of ``handeye calibrate --images`` (the CLI's main, in this process) on the set.
    `cache`: the detection cache folder (None: off); `before`: one worker and every flag set on
    every image, as before the threads, cache and plan; `crop` False: ACCURACY on the full image,
    as before the crop (give no cache: the entries' keys do not tell the two apart)."""
    from handeye.cli import main
    from handeye.vision import chessboard_region, detection_plan

    env = {"HANDEYE_CACHE_DIR": str(cache) if cache else None, "HANDEYE_NO_CACHE": None if cache else "1",
           "HANDEYE_WORKERS": "1" if before else (str(workers) if workers else None)}
    saved = {k: os.environ.get(k) for k in env}
    plan_min, locate = detection_plan.PLAN_MIN_IMAGES, chessboard_region.locate
    argv = ["calibrate", "--images", image_set["images"], "--board", image_set["board"], *image_set["args"],
            "--setup", image_set["setup"], "--match", image_set.get("match", "name"), "-o", out, "--force"]
    try:
        for k, v in env.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
        if before:
            detection_plan.PLAN_MIN_IMAGES = 10**9
        if not crop:
            chessboard_region.locate = lambda gray, size: None
        started = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = main([str(a) for a in argv])
        seconds = time.perf_counter() - started
    finally:
        detection_plan.PLAN_MIN_IMAGES, chessboard_region.locate = plan_min, locate
        for k, v in saved.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
    if code != 0:
        raise RuntimeError(f"handeye calibrate exited {code} on {image_set['name']}")
    return seconds


# ----------------------------------------------------------------------------- the table


def measure(image_set: dict, repeats: int, workers: int | None, before: bool, scratch: Path,
            full_image: bool = False) -> dict[str, list[float]]:
    """Every row's times on one set, round-robin over the repeats."""
    times: dict[str, list[float]] = {}
    is_chess = image_set["board"].startswith("chessboard")
    for r in range(repeats):
        cache = scratch / f"cache-{image_set['board'][:5]}-{r}"
        times.setdefault("opencv", []).append(opencv_pipeline(image_set))
        if is_chess:
            times.setdefault("opencv accuracy", []).append(opencv_pipeline(image_set, accuracy=True))
        times.setdefault("handeye", []).append(handeye_run(image_set, cache, scratch / "out.json", workers))
        times.setdefault("handeye rerun", []).append(handeye_run(image_set, cache, scratch / "out.json", workers))
        if full_image and is_chess:
            times.setdefault("handeye full image", []).append(
                handeye_run(image_set, None, scratch / "out.json", workers, crop=False))
        if before and r == 0:
            times["handeye before"] = [handeye_run(image_set, None, scratch / "out.json", workers, before=True)]
    return times


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", default="chessboard,charuco,circles")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=None, help="detection threads (default: the cores)")
    parser.add_argument("--before", action="store_true", help="also time the pipeline as before (slow: ~1 min)")
    parser.add_argument("--full-image", action="store_true",
                        help="also time handeye with ACCURACY on the full image, as before the crop")
    parser.add_argument("--chessboard-dir", type=Path, default=Path(tempfile.gettempdir()) / "handeye-bench-chess")
    parser.add_argument("--real-chessboard", nargs=3, action="append", metavar=("FOLDER", "BOARD", "ROBOT"),
                        help="a real chessboard set: its images, board spec and robot file (4x4 per line, m, in order)")
    args = parser.parse_args(argv)
    from handeye.cli import main as cli_main
    from handeye.io.examples import image_example_dir

    with tempfile.TemporaryDirectory() as scratch:
        warm = image_example_dir()  # imports and the solver registry, outside the timings
        os.environ.setdefault("HANDEYE_CACHE_DIR", str(Path(scratch) / "warm-cache"))  # not the user's cache
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            cli_main(["calibrate", "--images", str(warm / "images"), "--board", "circlegrid:10x10:25.4mm", "--robot",
                      str(warm / "poses"), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--setup",
                      "eye-in-hand", "--match", "name", "-o", str(Path(scratch) / "warm.json"), "--force"])
        print(f"cores {len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()}, "
              f"OpenCV {cv2.__version__}, load {os.getloadavg()[0]:.1f}, median of {args.repeats}")
        for image_set in image_sets(args.sets.split(","), args.chessboard_dir, args.real_chessboard):
            times = measure(image_set, args.repeats, args.workers, args.before, Path(scratch), args.full_image)
            reference = statistics.median(times["opencv"])
            print(f"\n{image_set['name']}")
            for row, values in times.items():
                median = statistics.median(values)
                print(f"  {row:<18} {median:7.2f} s   x{median / reference:5.2f}   "
                      f"({', '.join(f'{v:.2f}' for v in values)})")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
