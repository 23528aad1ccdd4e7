"""A board described wrongly is named, not calibrated: the survey of the chessboard the images
show (handeye.vision.board_survey) and the refusal of intrinsics no real lens gives
(handeye.vision.lens_check)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_vision_pipeline import simulated_cell

from handeye.base.errors import InputError
from handeye.vision.board_survey import (
    BoardSizeError,
    Survey,
    check_chessboard_size,
    chessboard_grid,
)
from handeye.vision.boards import parse_board
from handeye.vision.detection_plan import probe_indices
from handeye.vision.intrinsics import CameraCalibration
from handeye.vision.lens_check import lens_problem
from handeye.vision.observations import Camera
from handeye.vision.render import render

BOARD = parse_board("chessboard:9x6:25mm")
CAMERA = Camera(np.array([[420.0, 0, 320], [0, 420.0, 240], [0, 0, 1]]), np.zeros(0), (640, 480))


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    """Six renders of a 9x6 chessboard (inner corners) in a folder."""
    folder = tmp_path_factory.mktemp("survey")
    cell = simulated_cell(6, "eye-in-hand", board=BOARD, seed=5, distance=(450.0, 550.0), tilt_deg=15.0)
    rng = np.random.default_rng(5)
    files = []
    for i, T in enumerate(cell["T_cam_target"]):
        files.append(folder / f"{i}.png")
        cv2.imwrite(str(files[-1]), render(BOARD, CAMERA, T, blur=0.6, noise=1.5, rng=rng))
    return files


def test_the_survey_finds_the_printed_board_in_every_image(images):
    for path in images:
        assert sorted(chessboard_grid(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE), BOARD)) == [6, 9]


@pytest.mark.parametrize("given, named", [
    ("chessboard:10x7:25mm", "9x6"),   # squares counted instead of inner corners: larger, confirmed absent
    ("chessboard:7x5:25mm", "9x6"),    # a sub-board the detector would find
    ("chessboard:5x7:25mm", "6x9"),    # ... named the way round it was given
])
def test_a_wrong_size_is_named_with_the_size_the_images_show(images, given, named):
    with pytest.raises(BoardSizeError) as error:
        check_chessboard_size([images[k] for k in probe_indices(len(images))], parse_board(given), workers=1)
    message = str(error.value)
    assert "\n" not in message and isinstance(error.value, InputError)
    assert f"the images show a {named} chessboard (inner corners)" in message
    assert "found in 4 of the 4 images looked at first" in message
    assert f"give the board as chessboard:{named}:25mm" in message


@pytest.mark.parametrize("given", ["chessboard:9x6:25mm", "chessboard:6x9:25mm", "circlegrid:9x6:25mm"])
def test_the_right_size_either_way_round_and_other_kinds_pass(images, given):
    check_chessboard_size([images[k] for k in probe_indices(len(images))], parse_board(given), workers=1)


def test_a_verdict_needs_a_majority_and_no_image_showing_the_given_size():
    def survey(*grids):
        return Survey(tuple((f"{i}.png", g) for i, g in enumerate(grids)))

    board = parse_board("chessboard:24x17:15mm")
    assert survey((24, 17), (20, 17), (20, 17), (20, 17)).verdict(board) is None  # the given one seen once
    assert survey((17, 24), None, None, None).verdict(board) is None
    assert survey((28, 17), (28, 17), (24, 10), None).verdict(board) == ((28, 17), 2)
    assert survey((28, 17), (20, 17), (24, 10), None).verdict(board) is None  # no majority
    assert survey((28, 17), None, None, None).verdict(board) is None  # one image is not enough
    assert survey((28, 17),).verdict(board) == ((28, 17), 1)  # ... unless it is the only one
    assert survey(None, None).verdict(board) is None


def test_intrinsics_no_lens_gives_are_refused_naming_the_board():
    def calibration(fx, fy, rms):
        K = np.array([[fx, 0, 960], [0, fy, 600], [0, 0, 1.0]])
        return CameraCalibration(Camera(K, np.zeros(5), (1920, 1200)), np.full(3, rms), rms, np.ones(4), "k1")

    board = parse_board("chessboard:17x12:15mm")
    message = lens_problem(calibration(8639.0, 1829.0, 12.9), board)
    assert "fits the board's points to 12.9 px RMS with fx 8639 px against fy 1829 px" in message
    assert board.describe() in message and "\n" not in message
    assert "2.9 px RMS" in lens_problem(calibration(1800.0, 1800.0, 2.9), board)
    assert lens_problem(calibration(2000.0, 1800.0, 0.1), board) is not None  # 11% apart
    assert lens_problem(calibration(1800.0, 1805.0, 0.52), board) is None  # the real ChArUco set's figures
    # a camera of a cell, which may see several boards: each named with its spec
    other = parse_board("charuco:5x7:36.195mm:18.256mm:DICT_6X6_250")
    several = lens_problem(calibration(8639.0, 1829.0, 12.9), {"left": board, "right": other})
    assert f"one of the boards (left: {board.describe()}; right: {other.describe()}) is probably not" in several
    assert f"the board (left: {board.describe()}) is probably not" in lens_problem(calibration(8639.0, 1829.0, 12.9),
                                                                                   {"left": board})


def test_a_sub_board_the_survey_does_not_see_is_refused_by_the_lens_check(images):
    """With a detector of the caller's own (no survey), a 5x4 sub-board of the printed 9x6 is
    found where the detector locks on, and the camera calibrated from such corners is no real
    lens's (measured: 4.05 px RMS, fx 2422 against fy 14131): refused, naming the board, instead of
    a hand-eye answer built on it."""
    from handeye.vision.detect import detect
    from handeye.vision.image_set import images_and_poses

    with pytest.raises(InputError) as error:
        images_and_poses(images[0].parent, parse_board("chessboard:5x4:25mm"), setup="eye-in-hand", cache=False,
                         detector=lambda image, board: detect(image, board))
    message = str(error.value)
    assert "which no real lens gives" in message and "chessboard 5x4 inner corners, 25 mm squares" in message
