"""The fast image path on a cell of several cameras and targets (handeye.vision.board_set.
detect_board_files: per camera and board, handeye.vision.detection_plan.detect_set): a rerun reads
every detection from the cache and detects nothing; the answer is the same to the last bit with
and without the cache and on one or two threads; a chessboard's flag-set plan, made per camera,
keeps the corners of the full run; ``handeye calibrate --workers / --no-cache`` on such a cell.

The ChArUco cell is tests/multi_images.py's (two cameras, two boards, 8 stations, 640 x 480); the
chessboard cell is rendered here (two cameras with other lenses, 8 views each, 480 x 360)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from multi_images import write_cell

import handeye
from handeye.cli import main
from handeye.io.pose_readers import PoseStack
from handeye.vision import detection_plan, detection_pool
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera
from handeye.vision.render import render, view_pose
from handeye.workflow.cell import Cell
from handeye.workflow.observation_images import image_tables

STATIONS = 8
CHESS_SPEC = "chessboard:9x6:25mm"
#: two cameras that are not alike: another focal length and distortion each
CHESS_CAMERAS = {"left": Camera(np.array([[430.0, 0, 240], [0, 430.0, 180], [0, 0, 1]]),
                                np.array([-0.12, 0.05, 0, 0, 0]), (480, 360)),
                 "right": Camera(np.array([[380.0, 0, 236], [0, 380.0, 184], [0, 0, 1]]),
                                 np.array([0.03, -0.01, 0, 0, 0]), (480, 360))}


@pytest.fixture(scope="module")
def charuco_cell(tmp_path_factory) -> Path:
    """The two-camera, two-ChArUco-board cell of tests/multi_images.py (its cell file)."""
    folder = tmp_path_factory.mktemp("multi_cache")
    write_cell(folder, STATIONS)
    return folder / "cell.yaml"


@pytest.fixture(scope="module")
def chess_cell(tmp_path_factory) -> Path:
    """Two cameras, one chessboard, 8 views each (blur, noise, each camera's own distortion) and a
    robot file of 8 named stations (the images are not solved here, only detected)."""
    folder = tmp_path_factory.mktemp("multi_chess")
    board = parse_board(CHESS_SPEC)
    rng = np.random.default_rng(5)
    for name, camera in CHESS_CAMERAS.items():
        (folder / name).mkdir()
        for i in range(STATIONS):
            T = view_pose(board, rng.uniform(330, 430), tilt=tuple(rng.uniform(-0.35, 0.35, 3)),
                          roll=rng.uniform(-0.5, 0.5))
            cv2.imwrite(str(folder / name / f"{i:02d}.png"), render(board, camera, T, blur=0.7, noise=1.5, rng=rng))
    rows = ["name,x,y,z,qx,qy,qz,qw"] + [f"{i:02d},{i},0,0,0,0,0,1" for i in range(STATIONS)]
    (folder / "robot.csv").write_text("\n".join(rows) + "\n")
    (folder / "cell.yaml").write_text(
        "setup: eye-to-hand\nproblem: axyb-multi\nrobot: {file: robot.csv, format: xyz-quat-xyzw, unit: mm}\n"
        "observations:\n  - {camera: left, images: left}\n  - {camera: right, images: right}\n"
        f"targets: {{chess: '{CHESS_SPEC}'}}\nmatching: {{method: name}}\n")
    return folder / "cell.yaml"


@pytest.fixture
def counted(monkeypatch) -> list[int]:
    """How many images each call of the detecting threads detected (`detection_pool.run`)."""
    calls: list[int] = []
    real = detection_pool.run

    def run(items, *args, **kwargs):
        calls.append(len(items))
        return real(items, *args, **kwargs)

    monkeypatch.setattr(detection_pool, "run", run)
    return calls


def answer(result) -> dict[str, np.ndarray]:
    """What a calibration gave, to compare to the last bit: every named pose, the board poses and
    the observations' labels."""
    out = {p.name: np.asarray(p.T) for p in result.named_poses()}
    out["board poses"] = np.asarray(result.camera_read.poses)
    out["labels"] = np.array([" ".join(label) for label in result.observation_labels])
    return out


def assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_a_rerun_reads_every_detection_from_the_cache_and_gives_the_same_answer(charuco_cell, tmp_path,
                                                                               monkeypatch, counted):
    """First run: 2 cameras x 8 images x 2 boards detected and stored; the rerun (through
    HANDEYE_CACHE_DIR) detects nothing; both the same to the last bit as a serial run without the
    cache and one on two threads."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("HANDEYE_CACHE_DIR", str(cache))
    monkeypatch.delenv("HANDEYE_NO_CACHE", raising=False)
    cell = Cell.from_file(charuco_cell)
    first = answer(handeye.calibrate(cell, workers=2))
    assert sum(counted) == 2 * STATIONS * 2
    assert len(list((cache / "detections").rglob("*.npz"))) == 2 * STATIONS * 2

    counted.clear()
    again = handeye.calibrate(cell, workers=2)
    assert sum(counted) == 0 and again.usable
    assert_same(first, answer(again))

    serial = answer(handeye.calibrate(cell, workers=1, cache=False))
    assert sum(counted) == 2 * STATIONS * 2
    assert_same(first, serial)


def test_no_cache_writes_nothing_and_a_folder_given_is_used(charuco_cell, tmp_path, monkeypatch):
    """HANDEYE_NO_CACHE=1 and cache=False leave the environment's folder empty; cache=FOLDER
    fills that folder."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("HANDEYE_CACHE_DIR", str(cache))
    monkeypatch.delenv("HANDEYE_NO_CACHE", raising=False)
    cell = Cell.from_file(charuco_cell)
    robot = PoseStack(np.tile(np.eye(4), (STATIONS, 1, 1)), "mm", "matrix", tuple(f"{i:02d}" for i in range(STATIONS)),
                      None, None, "robot")
    image_tables(cell, robot, cache=False)
    monkeypatch.setenv("HANDEYE_NO_CACHE", "1")
    image_tables(cell, robot)
    assert not cache.exists()
    image_tables(cell, robot, cache=tmp_path / "given")
    assert len(list((tmp_path / "given" / "detections").rglob("*.npz"))) == 2 * STATIONS * 2


def test_the_chessboard_plan_is_made_per_camera_and_keeps_the_corners_of_the_full_run(chess_cell, monkeypatch):
    """Each camera's images plan their own flag sets (one plan per camera, each leaving flag sets
    out); the board poses, their errors and the corners' counts are those of every flag set run
    on every image."""
    cell = Cell.from_file(chess_cell)
    robot = PoseStack(np.tile(np.eye(4), (STATIONS, 1, 1)), "mm", "matrix", tuple(f"{i:02d}" for i in range(STATIONS)),
                      None, None, "robot")
    plans: list[tuple[str, ...] | None] = []
    real_plan = detection_plan.flag_set_plan

    def recorded(probe, camera):
        plans.append(real_plan(probe, camera))
        return plans[-1]

    monkeypatch.setattr(detection_plan, "flag_set_plan", recorded)
    planned = image_tables(cell, robot, cache=False)
    assert len(plans) == 2 and all(p is not None and len(p) < 4 for p in plans), plans

    monkeypatch.setattr(detection_plan, "PLAN_MIN_IMAGES", 10 ** 6)  # every flag set on every image
    full = image_tables(cell, robot, cache=False)
    assert len(plans) == 2
    for name in CHESS_CAMERAS:
        a, b = planned.cameras[name], full.cameras[name]
        assert a.image == b.image and len(a) == STATIONS
        np.testing.assert_array_equal(a.T_cam_target, b.T_cam_target)
        np.testing.assert_array_equal(a.errors, b.errors)
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.camera.K, b.camera.K)


def test_cli_workers_and_no_cache_on_a_cell_of_several_cameras(charuco_cell, tmp_path, monkeypatch, capsys):
    """``--no-cache`` leaves the cache folder empty; without it the folder fills, and the JSON
    answers are the same; ``--workers 0`` is one line, exit 2, before anything is read."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("HANDEYE_CACHE_DIR", str(cache))
    monkeypatch.delenv("HANDEYE_NO_CACHE", raising=False)
    argv = ["calibrate", "--config", str(charuco_cell), "--json"]
    assert main([*argv, "--no-cache", "--workers", "1"]) == 0
    uncached = json.loads(capsys.readouterr().out)
    assert not cache.exists()
    assert main([*argv, "--workers", "2"]) == 0
    cached = json.loads(capsys.readouterr().out)
    assert len(list((cache / "detections").rglob("*.npz"))) == 2 * STATIONS * 2
    for key in ("X[0]", "X[1]", "Y[0]", "Y[1]", "names", "cameras", "observations"):
        assert cached[key] == uncached[key], key

    code = main([*argv, "--workers", "0"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("handeye: error: --workers") and "at least 1" in err


def test_the_library_refuses_workers_below_one_before_reading_anything(tmp_path):
    """``handeye.calibrate(cell, workers=0)``: InputError naming the argument; the cell's files
    (which do not exist here) are never read."""
    cell = Cell.from_dict({"setup": "eye-to-hand", "problem": "axyb-multi",
                           "robot": {"file": str(tmp_path / "missing.csv"), "format": "xyz-quat-xyzw"},
                           "observations": [{"camera": "cam0", "images": str(tmp_path / "none")}],
                           "targets": {"chess": CHESS_SPEC}})
    with pytest.raises(handeye.InputError, match="whole number >= 1, got 0"):
        handeye.calibrate(cell, workers=0)
