"""Calibration boards (handeye.vision.boards / .detect): the spec parser, the board frames, and
detection on rendered images against the exact projected truth (every kind, tilted, upside down,
distorted, noisy), the failures (blank image, another board, a wrong size), and the real
industrial_calibration images when present."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye.base.errors import InputError
from handeye.vision.boards import Board, parse_board
from handeye.vision.detect import BoardNotFound, Detection, detect
from handeye.vision.observations import Camera
from handeye.vision.render import project, render, view_pose

SPECS = {
    "chessboard": "chessboard:9x6:25mm",
    "charuco": "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250",
    "circles": "circles:4x11:20mm",
    "circlegrid": "circlegrid:10x10:25.4mm",
    "aprilgrid": "aprilgrid:6x6:88mm:0.3",
}
K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
PINHOLE = Camera(K, np.zeros(0), (640, 480))
#: barrel distortion of a typical wide lens (k1, k2, p1, p2, k3)
DISTORTED = Camera(K, np.array([-0.12, 0.05, 0.001, -0.0005, 0.0]), (640, 480))
#: (camera, tilt rotation vector, roll, render options, median corner error bound px)
VIEWS = {
    "tilted": (PINHOLE, (0.2, -0.3, 0.0), 0.0, {}, 0.1),
    "upside-down": (PINHOLE, (0.2, -0.3, 0.0), np.pi, {}, 0.1),
    "distorted": (DISTORTED, (-0.35, 0.25, 0.1), 0.3, {}, 0.1),
    "noisy": (PINHOLE, (0.3, 0.2, 0.0), 0.5, {"blur": 0.8, "noise": 2.0}, 0.3),
}
#: a PnP pose from the detection (true K) must match the truth this well (noise-free and noisy)
POSE_DEG, POSE_REL = 0.1, 1e-3


def distance_for(board: Board) -> float:
    """Far enough that the whole pattern fits a 640x480 view at 600 px focal length."""
    x0, y0, x1, y1 = board.extent()
    return 2.0 * max(x1 - x0, y1 - y0)


def pnp_error(detection: Detection, camera: Camera, T: np.ndarray) -> tuple[float, float]:
    """(rotation error deg, translation error / distance) of the PnP pose of `detection`."""
    ok, rvec, tvec = cv2.solvePnP(detection.object_points, detection.image_points, camera.K, camera.dist)
    assert ok
    R = cv2.Rodrigues(rvec)[0]
    angle = np.degrees(Rotation.from_matrix(R.T @ T[:3, :3]).magnitude())
    return float(angle), float(np.linalg.norm(tvec.ravel() - T[:3, 3]) / np.linalg.norm(T[:3, 3]))


# -- parse_board ---------------------------------------------------------------------------------
def test_every_kind_parses_with_the_documented_points():
    chess = parse_board("chessboard:9x6:25mm")
    assert (chess.cols, chess.rows, chess.spacing, chess.unit) == (9, 6, 25.0, "mm")
    assert chess.object_points().shape == (54, 3)
    np.testing.assert_array_equal(chess.object_points()[10], [25.0, 25.0, 0.0])  # id = r * cols + c
    np.testing.assert_array_equal(chess.object_points()[53], [200.0, 125.0, 0.0])

    charuco = parse_board(SPECS["charuco"])
    assert (charuco.marker, charuco.dictionary, charuco.legacy) == (18.256, "DICT_6X6_250", False)
    cv_board = cv2.aruco.CharucoBoard((5, 7), 36.195, 18.256, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    np.testing.assert_allclose(charuco.object_points(), cv_board.getChessboardCorners(), atol=1e-4)

    circles = parse_board("circles:4x11:20mm")
    np.testing.assert_array_equal(circles.object_points()[[0, 3, 4, 43]],
                                  [[0, 0, 0], [120, 0, 0], [20, 20, 0], [120, 200, 0]])  # ((2c + r%2) s, r s)
    assert circles.diameter == pytest.approx(10.0)

    grid = parse_board("circlegrid:10x10:25.4mm")
    np.testing.assert_allclose(grid.object_points()[[0, 1, 10, 99]],
                               [[0, 0, 0], [25.4, 0, 0], [0, 25.4, 0], [228.6, 228.6, 0]])
    assert grid.diameter == pytest.approx(10.16)

    april = parse_board("aprilgrid:6x6:88mm:0.3")
    points = april.object_points()
    assert points.shape == (144, 3) and april.tag_spacing == 0.3 and april.dictionary == "DICT_APRILTAG_36H11"
    # tag 0 corners bottom-left, bottom-right, top-right, top-left; tag 7 = column 1, row 1
    np.testing.assert_allclose(points[:4, :2], [[0, 0], [88, 0], [88, 88], [0, 88]])
    np.testing.assert_allclose(points[28, :2], [1.3 * 88, 1.3 * 88])


def test_units_convert_and_the_same_board_in_metres_is_the_same_board():
    mm = parse_board(SPECS["charuco"])
    m = mm.in_unit("m")
    assert m.unit == "m" and m.spacing == pytest.approx(0.036195) and m.marker == pytest.approx(0.018256)
    np.testing.assert_allclose(m.object_points() * 1000, mm.object_points(), atol=1e-9)
    assert parse_board("charuco:5x7:0.036195m:18.256mm:DICT_6X6_250").marker == pytest.approx(0.018256)
    back = m.in_unit("mm")
    assert (back.spacing, back.marker) == (pytest.approx(mm.spacing), pytest.approx(mm.marker))
    circles = parse_board("circlegrid:10x10:0.0254m:0.01m")
    assert circles.in_unit("mm").diameter == pytest.approx(10.0)
    for spec in SPECS.values():
        board = parse_board(spec)
        assert parse_board(board.spec()) == board
        assert "\n" not in board.describe()
    assert parse_board("chessboard:9x6:25mm").describe() == "chessboard 9x6 inner corners, 25 mm squares"


def test_board_files_in_yaml_and_json(tmp_path):
    yaml_file = tmp_path / "board.yaml"
    yaml_file.write_text("board:\n  kind: charuco\n  cols: 5\n  rows: 7\n  spacing: 0.036195\n  unit: m\n"
                         "  marker: 0.018256\n  dictionary: DICT_6X6_250\n")
    assert parse_board(str(yaml_file)) == parse_board("charuco:5x7:0.036195m:0.018256m:DICT_6X6_250")
    json_file = tmp_path / "grid.json"
    json_file.write_text(json.dumps({"kind": "aprilgrid", "cols": 6, "rows": 6, "spacing": 88, "unit": "mm",
                                     "tag_spacing": 0.3}))
    assert parse_board(str(json_file)) == parse_board("aprilgrid:6x6:88mm:0.3")
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: chessboard\ncols: 9\nrows: 6\nspacing: 25\nsquare: 25\n")
    with pytest.raises(InputError, match="unknown key"):
        parse_board(str(bad))


@pytest.mark.parametrize("spec, words", [
    ("hexboard:9x6:25mm", "unknown board kind"),
    ("chessboard:9x6", "fields"),
    ("chessboard:9*6:25mm", "COLSxROWS"),
    ("chessboard:9x6:25cm", "mm or m"),
    ("chessboard:9x6:-25mm", "mm or m"),
    ("chessboard:1x6:25mm", "cols"),
    ("charuco:5x7:36mm:18mm:DICT_9X9_1", "unknown ArUco dictionary"),
    ("charuco:5x7:18mm:36mm:DICT_6X6_250", "smaller than the square"),
    ("charuco:5x7:36mm:18mm:DICT_6X6_250:old", "legacy"),
    ("aprilgrid:6x6:88mm:abc", "spacing ratio"),
    ("aprilgrid:6x6:88mm:3", "spacing ratio"),
    ("circlegrid:10x10:25mm:20mm", "too large"),
    ("circles:4x10:20mm", "odd number of rows"),
    ("missing_board.yaml", "does not exist"),
    ("", "non-empty"),
])
def test_bad_specs_raise_one_line_input_errors_showing_the_syntax(spec, words):
    with pytest.raises(InputError, match=words) as error:
        parse_board(spec)
    message = str(error.value)
    assert "\n" not in message and "e.g." in message


def test_only_symmetric_chessboards_are_flagged_ambiguous():
    assert not parse_board("chessboard:9x6:25mm").orientation_ambiguous
    assert parse_board("chessboard:8x6:25mm").orientation_ambiguous
    assert parse_board("chessboard:7x7:25mm").orientation_ambiguous
    assert not any(parse_board(spec).orientation_ambiguous for kind, spec in SPECS.items() if kind != "chessboard")


# -- detection on renders ------------------------------------------------------------------------
@pytest.mark.parametrize("view", list(VIEWS))
@pytest.mark.parametrize("kind", list(SPECS))
def test_detection_matches_the_projected_truth_and_recovers_the_pose(kind, view):
    board = parse_board(SPECS[kind])
    camera, tilt, roll, options, bound = VIEWS[view]
    T = view_pose(board, distance_for(board), tilt=tilt, roll=roll)
    image = render(board, camera, T, rng=np.random.default_rng(7), **options)
    found = detect(image, board)
    truth = project(board, camera, T)
    assert len(found) >= (0.75 if view == "noisy" else 1.0) * board.point_count  # noisy: a marker may go
    np.testing.assert_array_equal(found.object_points, board.object_points()[found.ids])
    errors = np.linalg.norm(found.image_points - truth[found.ids], axis=1)
    assert np.median(errors) < bound and errors.max() < 3 * bound
    # the ids name the right board points: PnP with the true K gives the true pose
    angle, shift = pnp_error(found, camera, T)
    assert angle < POSE_DEG and shift < POSE_REL


def test_symmetric_chessboard_numbering_follows_the_image_not_the_board():
    """An 8x6 chessboard looks the same turned 180 deg: OpenCV numbers it from the image, so one of
    the two views yields the board frame turned by 180 deg about its centre (flagged, not guessed)."""
    board = parse_board("chessboard:8x6:25mm")
    truth_angles = []
    for roll in (0.0, np.pi):
        T = view_pose(board, distance_for(board), tilt=(0.2, -0.3, 0.0), roll=roll)
        found = detect(render(board, PINHOLE, T), board)
        truth_angles.append(pnp_error(found, PINHOLE, T)[0])
    assert board.orientation_ambiguous
    assert sorted(round(a / 180.0) for a in truth_angles) == [0, 1]
    assert min(truth_angles) < POSE_DEG and abs(max(truth_angles) - 180.0) < POSE_DEG


@pytest.mark.parametrize("roll", [0.0, np.pi])
def test_classic_chessboard_detector_numbers_the_board_as_the_sb_detector(monkeypatch, roll):
    """When findChessboardCornersSB fails, findChessboardCorners + cornerSubPix take over; the order is
    made the same (right-handed, first inner square white), so the frame does not flip."""
    board = parse_board(SPECS["chessboard"])
    T = view_pose(board, distance_for(board), tilt=(0.2, -0.3, 0.0), roll=roll)
    image = render(board, PINHOLE, T)
    monkeypatch.setattr(cv2, "findChessboardCornersSB", lambda *args, **kwargs: (False, None))
    found = detect(image, board)
    errors = np.linalg.norm(found.image_points - project(board, PINHOLE, T)[found.ids], axis=1)
    assert np.median(errors) < 0.1
    angle, shift = pnp_error(found, PINHOLE, T)
    assert angle < POSE_DEG and shift < POSE_REL


def test_colour_input_is_the_same_and_left_untouched():
    board = parse_board(SPECS["charuco"])
    gray = render(board, PINHOLE, view_pose(board, distance_for(board), tilt=(0.1, 0.2, 0.0)))
    bgr = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    before = bgr.copy()
    np.testing.assert_allclose(detect(bgr, board).image_points, detect(gray, board).image_points, atol=1e-9)
    np.testing.assert_array_equal(bgr, before)


# -- failures -----------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", list(SPECS))
def test_a_blank_image_is_no_board(kind):
    with pytest.raises(BoardNotFound) as error:
        detect(np.full((480, 640), 128, np.uint8), parse_board(SPECS[kind]))
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("shown, wanted", [
    ("chessboard:9x6:25mm", "chessboard:7x5:25mm"),  # wrong size
    ("chessboard:9x6:25mm", "circles:4x11:20mm"),
    ("circlegrid:10x10:25.4mm", "circlegrid:8x8:25.4mm"),
    ("circles:4x11:20mm", "circlegrid:10x10:25.4mm"),
    ("aprilgrid:6x6:88mm:0.3", "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250"),
    ("charuco:5x7:36.195mm:18.256mm:DICT_6X6_250", "aprilgrid:6x6:88mm:0.3"),
    ("charuco:5x7:36.195mm:18.256mm:DICT_6X6_250", "charuco:5x7:36.195mm:18.256mm:DICT_4X4_50"),
])
def test_another_board_or_a_wrong_size_is_no_board(shown, wanted):
    board = parse_board(shown)
    image = render(board, PINHOLE, view_pose(board, distance_for(board), tilt=(0.1, -0.2, 0.0)))
    with pytest.raises(BoardNotFound) as error:
        detect(image, parse_board(wanted))
    assert "\n" not in str(error.value)


def test_a_circle_grid_without_a_big_dot_has_no_origin(monkeypatch):
    """All dots alike: the grid is found but its orientation cannot be told, so no numbering is given."""
    import handeye.vision.render as rendering

    board = parse_board("circlegrid:6x5:20mm")
    monkeypatch.setattr(rendering, "BIG_DOT_RATIO", 1.0)
    rendering.board_texture.cache_clear()
    rendering._prefiltered_texture.cache_clear()
    image = render(board, PINHOLE, view_pose(board, distance_for(board), tilt=(0.1, 0.2, 0.0)))
    rendering.board_texture.cache_clear()
    rendering._prefiltered_texture.cache_clear()
    with pytest.raises(BoardNotFound, match="no corner circle is clearly the big origin dot.*ambiguous orientation"):
        detect(image, board)


def test_too_few_charuco_corners_says_how_many():
    """Most of the board outside the view: a few corners remain, fewer than asked for."""
    board = parse_board(SPECS["charuco"])
    T = view_pose(board, 0.8 * distance_for(board))
    T[:3, 3] += T[:3, :3] @ np.array([0.4 * board.cols * board.spacing, 0.4 * board.rows * board.spacing, 0])
    image = render(board, PINHOLE, T)
    seen = len(detect(image, board, min_corners=4))
    with pytest.raises(BoardNotFound, match=rf"^only {seen} ChArUco corners found, need {seen + 1} "):
        detect(image, board, min_corners=seen + 1)


def test_legacy_charuco_boards_need_the_legacy_flag():
    """OpenCV < 4.6 drew boards with an even number of rows differently: the flag picks that layout."""
    legacy = parse_board("charuco:5x6:30mm:15mm:DICT_5X5_100:legacy")
    T = view_pose(legacy, distance_for(legacy), tilt=(0.2, 0.1, 0.0))
    image = render(legacy, PINHOLE, T)
    found = detect(image, legacy)
    assert len(found) == legacy.point_count and pnp_error(found, PINHOLE, T)[0] < POSE_DEG
    with pytest.raises(BoardNotFound, match="legacy flag"):
        detect(image, parse_board("charuco:5x6:30mm:15mm:DICT_5X5_100"))


@pytest.mark.parametrize("image, words", [
    (np.zeros((480, 640), np.float32), "8-bit"),
    (np.zeros((480, 640, 2), np.uint8), "shape"),
    ([[0, 1], [2, 3]], "numpy array"),
])
def test_bad_images_and_options_are_input_errors(image, words):
    with pytest.raises(InputError, match=words):
        detect(image, parse_board(SPECS["chessboard"]))
    with pytest.raises(InputError, match="min_corners"):
        detect(np.zeros((480, 640), np.uint8), parse_board(SPECS["charuco"]), min_corners=2)


# -- real images (ROS-Industrial's industrial_calibration examples) ------------------------------
RCT = Path(__file__).parents[3] / "shared" / "data" / "industrial_calibration_rct"
needs_rct = pytest.mark.skipif(not RCT.is_dir(), reason="industrial_calibration example images not present")


def reprojection(found: Detection, K_: np.ndarray) -> np.ndarray:
    """Squared reprojection errors (px^2) of the PnP pose of a detection, no distortion."""
    _, rvec, tvec = cv2.solvePnP(found.object_points, found.image_points, K_, None)
    projected, _ = cv2.projectPoints(found.object_points, rvec, tvec, K_, None)
    return np.sum((projected.reshape(-1, 2) - found.image_points) ** 2, axis=1)


@needs_rct
def test_real_charuco_images():
    """15 of 16 found (image 2 sees 4 corners); measured pooled PnP RMS 0.74 px, worst image 1.03 px."""
    board = parse_board(SPECS["charuco"])
    import yaml

    data = yaml.safe_load((RCT / "test_set_charuco" / "cal_data.yaml").read_text())["intrinsics"]
    K_ = np.array([[data["fx"], 0, data["cx"]], [0, data["fy"], data["cy"]], [0, 0, 1]])
    squared, found = [], []
    for i in range(16):
        image = cv2.imread(str(RCT / "test_set_charuco" / "images" / f"{i}.png"), cv2.IMREAD_GRAYSCALE)
        if i == 2:
            with pytest.raises(BoardNotFound, match="^only 4 ChArUco corners found, need 6"):
                detect(image, board)
            continue
        detection = detect(image, board)
        found.append(i)
        squared.append(reprojection(detection, K_))
        assert np.sqrt(squared[-1].mean()) < 1.5
    assert len(found) == 15
    assert np.sqrt(np.concatenate(squared).mean()) < 1.0


@needs_rct
def test_real_circlegrid_images_are_numbered_from_the_big_dot():
    """15 of 15 found; point 0 is the big dot (its dark area, measured independently of the detector,
    is over twice the median dot's), z points toward the camera in every view; measured pooled PnP RMS
    with the nominal intrinsics 0.41 px."""
    board = parse_board(SPECS["circlegrid"])
    K_ = np.array([[550.0, 0, 320.0], [0, 550.0, 240.0], [0, 0, 1]])
    squared = []
    for image_file in sorted((RCT / "test_set_10x10" / "images").glob("*.png")):
        image = cv2.imread(str(image_file), cv2.IMREAD_GRAYSCALE)
        found = detect(image, board)
        assert len(found) == 100
        areas = [dark_area(image, point) for point in found.image_points[[0, 1, 10, 11, 45, 99]]]
        assert areas[0] > 2.0 * np.median(areas[1:]), image_file.name
        _, rvec, _ = cv2.solvePnP(found.object_points, found.image_points, K_, None)
        assert cv2.Rodrigues(rvec)[0][2, 2] < 0  # board z toward the camera
        squared.append(reprojection(found, K_))
    assert len(squared) == 15
    assert np.sqrt(np.concatenate(squared).mean()) < 1.0


def dark_area(image: np.ndarray, point: np.ndarray, half: int = 14) -> int:
    """Pixels of the dark blob under `point`: Otsu threshold of the surrounding patch, the connected
    component containing the point."""
    x, y = int(np.rint(point[0])), int(np.rint(point[1]))
    patch = image[max(y - half, 0):y + half + 1, max(x - half, 0):x + half + 1]
    _, dark = cv2.threshold(patch, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    _, labels = cv2.connectedComponents(dark)
    label = labels[min(y, half), min(x, half)]
    return int(np.sum(labels == label)) if label else 0
