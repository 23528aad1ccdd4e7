"""From board points to stations: intrinsics files and calibration (handeye.vision.intrinsics), board
poses by PnP (handeye.vision.camera_poses), and the image set (handeye.vision.image_set): listing,
pairing images with robot poses by name / index / time, dropping failed images together with
their robot pose, checked against a simulated cell's truth.

The image-set tests use synthetic detections: each image file is a tiny PNG whose grey value
names its station, and the detector projects the board's points of that station's true pose
(cv2.projectPoints) -- so every number is known and a misaligned pair would show at once.
Rendered images and the real detectors are tested end to end in tests/workflow/test_calibrate_images.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from handeye.base.errors import InputError
from handeye.geometry.se3 import inverse, make_pose, rotation_angle
from handeye.io.data_files import from_poses
from handeye.io.pose_readers import PoseStack, read_pose_dir
from handeye.vision.boards import parse_board
from handeye.vision.camera_poses import board_pose, flag_outliers
from handeye.vision.detect import BoardNotFound, Detection
from handeye.vision.image_set import (
    image_stamp,
    images_and_poses,
    list_images,
    pair_images,
)
from handeye.vision.intrinsics import K3_MIN_VIEWS, calibrate_camera, load_camera
from handeye.vision.observations import Camera

#: the simulated camera: 640 x 480, mild barrel distortion
K_TRUE = np.array([[520.0, 0.0, 318.0], [0.0, 524.0, 243.0], [0.0, 0.0, 1.0]])
DIST_TRUE = np.array([-0.12, 0.05, 0.001, -0.0005, 0.0])
CAMERA = Camera(K_TRUE, DIST_TRUE, (640, 480))
BOARD = parse_board("chessboard:9x6:25mm")


# ----------------------------------------------------------------------------- a simulated cell


def look_at(center: np.ndarray, rng: np.random.Generator, distance: tuple[float, float] = (450.0, 600.0),
            tilt_deg: float = 30.0, side: float = -1.0) -> np.ndarray:
    """T_target_cam of a camera on the board's `side` (-1: -z, the printed face of OpenCV's boards;
    +1: circlegrid, aprilgrid), looking at `center` (board frame, mm), from a direction within
    `tilt_deg` of the board's normal, at a random roll."""
    tilt, azimuth = np.radians(tilt_deg) * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
    direction = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), side * np.cos(tilt)])
    position = center + rng.uniform(*distance) * direction
    z = (center - position) / np.linalg.norm(center - position)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z]) @ Rotation.from_rotvec([0, 0, rng.uniform(-0.4, 0.4)]).as_matrix()
    return make_pose(R, position)


def simulated_cell(stations: int, setup: str, board=BOARD, seed: int = 0, **look) -> dict[str, np.ndarray]:
    """Truth X, Y (mm) and per station A = T_base_flange and T_cam_target (mm), noise-free."""
    rng = np.random.default_rng(seed)
    X = make_pose(Rotation.from_euler("xyz", [5, -80, 10], degrees=True).as_matrix(), [40.0, -25.0, 110.0])
    Y = make_pose(Rotation.from_euler("xyz", [180, 5, 95], degrees=True).as_matrix(), [900.0, 150.0, -30.0])
    points = board.in_unit("mm").object_points()
    center = (points.min(axis=0) + points.max(axis=0)) / 2
    side = 1.0 if board.kind in ("circlegrid", "aprilgrid") else -1.0
    T_target_cam = np.array([look_at(center, rng, side=side, **look) for _ in range(stations)])
    T_cam_target = inverse(T_target_cam)
    # eye-in-hand: A X = Y T_target_cam; eye-to-hand: A X = Y T_cam_target
    B = T_target_cam if setup == "eye-in-hand" else T_cam_target
    A = Y @ B @ inverse(X)
    return {"A": A, "X": X, "Y": Y, "T_cam_target": T_cam_target}


def projected(board, camera: Camera, T_cam_target: np.ndarray, noise: float = 0.0,
              rng: np.random.Generator | None = None) -> Detection:
    """The board's points seen at T_cam_target (board unit) by `camera`, with pixel noise."""
    obj = board.object_points()
    rvec, _ = cv2.Rodrigues(T_cam_target[:3, :3])
    pixels = cv2.projectPoints(obj, rvec, T_cam_target[:3, 3], camera.K, camera.dist)[0].reshape(-1, 2)
    if noise:
        pixels = pixels + rng.normal(0.0, noise, pixels.shape)
    return Detection(np.arange(len(obj)), pixels, obj)


def pose_error(T: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(rotation angle [rad], translation distance) between two poses."""
    return rotation_angle(T[:3, :3] @ T_true[:3, :3].T), float(np.linalg.norm(T[:3, 3] - T_true[:3, 3]))


# ----------------------------------------------------------------------------- intrinsics files


def test_load_camera_reads_opencv_filestorage_yaml_xml_and_json(tmp_path):
    for ext in ("yaml", "xml", "json"):
        path = tmp_path / f"camera.{ext}"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", 640)
        fs.write("image_height", 480)
        fs.write("camera_matrix", K_TRUE)
        fs.write("distortion_coefficients", DIST_TRUE.reshape(1, 5))
        fs.release()
        camera = load_camera(path)
        np.testing.assert_array_equal(camera.K, K_TRUE)
        np.testing.assert_array_equal(camera.dist, DIST_TRUE)
        assert camera.size == (640, 480)


def test_load_camera_reads_ros_camera_info_and_industrial_calibration(tmp_path):
    dist8 = [-0.1, 0.02, 0.001, 0.002, 0.0, 0.01, 0.0, 0.0]
    info = {"image_width": 1280, "image_height": 720, "camera_name": "cam",
            "camera_matrix": {"rows": 3, "cols": 3, "data": K_TRUE.ravel().tolist()},
            "distortion_model": "rational_polynomial",
            "distortion_coefficients": {"rows": 1, "cols": 8, "data": dist8}}
    (tmp_path / "info.yaml").write_text(yaml.safe_dump(info))
    camera = load_camera(tmp_path / "info.yaml")
    np.testing.assert_array_equal(camera.K, K_TRUE)
    np.testing.assert_array_equal(camera.dist, dist8)
    assert camera.size == (1280, 720)
    (tmp_path / "cal_data.yaml").write_text("intrinsics:\n  fx: 1352.02747\n  fy: 1356.14287\n  cx: 789.67065\n"
                                            "  cy: 627.2995\ndata: []\n")
    camera = load_camera(tmp_path / "cal_data.yaml")
    np.testing.assert_array_equal(camera.K, [[1352.02747, 0, 789.67065], [0, 1356.14287, 627.2995], [0, 0, 1]])
    assert camera.dist.size == 0 and camera.size is None


@pytest.mark.parametrize("content, message", [
    ("camera_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\ndistortion_model: equidistant\n",
     "distortion_model 'equidistant' is not supported"),
    ("camera_matrix: [1, 2, 3]\n", "must hold 9 numbers"),
    ("camera_name: x\n", "no camera matrix found"),
    ("intrinsics: {fx: 500, fy: 500, cx: 320}\n", "lacks cy"),
    (("camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
      "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 3, data: [0.1, 0.2, 0.3]}\n"),
     "plumb_bob has 5 coefficients, the file gives 3"),
])
def test_load_camera_errors_are_one_line(tmp_path, content, message):
    path = tmp_path / "camera.yaml"
    path.write_text(content)
    with pytest.raises(InputError, match=message) as info:
        load_camera(path)
    assert "\n" not in str(info.value)


def test_load_camera_missing_file_and_extension(tmp_path):
    with pytest.raises(InputError, match="not found; give --intrinsics an existing file"):
        load_camera(tmp_path / "nope.yaml")
    (tmp_path / "camera.ini").write_text("fx=1")
    with pytest.raises(InputError, match="unsupported extension '.ini'"):
        load_camera(tmp_path / "camera.ini")


# ----------------------------------------------------------------------------- calibration


def test_calibrate_camera_recovers_the_intrinsics():
    """12 views, 0.1 px noise: f within 0.5 %, c within 2 px, and the camera reprojects a new view's
    noise-free points within 0.1 px RMS (k1 and k3 trade off, so coefficients are not compared);
    the RMS is the noise level (0.1 px per axis -> 0.141 px per point)."""
    rng = np.random.default_rng(3)
    cell = simulated_cell(12, "eye-in-hand", seed=3)
    detections = [projected(BOARD, CAMERA, T, noise=0.1, rng=rng) for T in cell["T_cam_target"]]
    camera, per_image, rms = calibrate_camera(detections, (640, 480))
    assert np.all(np.abs(np.diag(camera.K)[:2] / np.diag(K_TRUE)[:2] - 1) < 5e-3)
    assert np.all(np.abs(camera.K[:2, 2] - K_TRUE[:2, 2]) < 2.0)
    new_view = simulated_cell(1, "eye-in-hand", seed=30)["T_cam_target"][0]
    seen = projected(BOARD, CAMERA, new_view).image_points  # noise-free pixels of a view not calibrated on
    assert board_pose(BOARD.object_points(), seen, camera).rms < 0.1
    assert camera.size == (640, 480)
    assert 0.1 < rms < 0.18 and per_image.shape == (12,) and np.all(per_image < 0.25)


def test_calibrate_camera_is_exact_without_noise_and_fixes_k3_for_few_views():
    cell = simulated_cell(6, "eye-in-hand", seed=4)
    detections = [projected(BOARD, CAMERA, T) for T in cell["T_cam_target"]]
    result = calibrate_camera(detections, (640, 480))
    assert len(detections) < K3_MIN_VIEWS and "k3 fixed" in result.model and result.camera.dist[4] == 0
    # exact up to OpenCV's float32 points (calibrateCamera takes Point3f / Point2f: ~2e-5 px)
    np.testing.assert_allclose(result.camera.K, K_TRUE, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(result.camera.dist[:4], DIST_TRUE[:4], atol=2e-5)
    assert result.rms < 1e-4


def test_calibrate_camera_refuses_too_few_views():
    cell = simulated_cell(2, "eye-in-hand", seed=5)
    detections = [projected(BOARD, CAMERA, T) for T in cell["T_cam_target"]]
    with pytest.raises(InputError, match="at least 3 images, found it in 2; give --intrinsics FILE"):
        calibrate_camera(detections, (640, 480))


# ----------------------------------------------------------------------------- board poses


def test_board_pose_is_exact_without_noise_and_close_with_noise():
    cell = simulated_cell(8, "eye-in-hand", seed=6)
    rng = np.random.default_rng(6)
    for T in cell["T_cam_target"]:
        exact = board_pose(BOARD.object_points(), projected(BOARD, CAMERA, T).image_points, CAMERA)
        rot, trans = pose_error(exact.T_cam_target, T)
        assert rot < 1e-9 and trans < 1e-7 and exact.rms < 1e-8
        noisy = board_pose(BOARD.object_points(), projected(BOARD, CAMERA, T, 0.2, rng).image_points, CAMERA)
        rot, trans = pose_error(noisy.T_cam_target, T)
        # 0.2 px on 54 corners at ~0.5 m with f = 520 px: measured up to 6.4e-3 rad and ~1 mm
        assert rot < 1e-2 and trans < 3.0 and 0.15 < noisy.rms < 0.4


def test_board_pose_scales_with_the_board_unit():
    T = simulated_cell(1, "eye-in-hand", seed=7)["T_cam_target"][0]
    pixels = projected(BOARD, CAMERA, T).image_points
    in_m = board_pose(BOARD.in_unit("m").object_points(), pixels, CAMERA).T_cam_target
    in_mm = board_pose(BOARD.object_points(), pixels, CAMERA).T_cam_target
    np.testing.assert_allclose(in_m[:3, 3] * 1000, in_mm[:3, 3], rtol=1e-9)
    np.testing.assert_allclose(in_m[:3, :3], in_mm[:3, :3], atol=1e-12)


def test_flag_outliers_names_the_image_far_above_the_others():
    rms = [0.3, 0.25, 0.35, 0.28, 4.0, 0.31]
    flagged = flag_outliers(rms, [str(i) for i in range(6)])
    assert [i for i, _ in flagged] == [4] and "4 px is far above" in flagged[0][1]
    assert flag_outliers([0.3, 0.25, 1.9, 0.28], list("abcd")) == []  # 5x the median but below 2 px


# ----------------------------------------------------------------------------- listing and pairing


def test_list_images_is_natural_order(tmp_path):
    for name in ("10.png", "2.png", "1.png", "notes.txt", "img_3.jpg"):
        (tmp_path / name).write_bytes(b"")
    assert [p.name for p in list_images(tmp_path)] == ["1.png", "2.png", "10.png", "img_3.jpg"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no images in"):
        list_images(tmp_path / "empty")
    with pytest.raises(InputError, match="not found; give --images an existing folder"):
        list_images(tmp_path / "missing")


def test_read_pose_dir_reads_industrial_calibration_pose_files(tmp_path):
    rng = np.random.default_rng(8)
    q = Rotation.random(12, random_state=9)
    for i in range(12):
        x = dict(zip(("x", "y", "z"), rng.normal(size=3).tolist()))
        x.update(zip(("qx", "qy", "qz", "qw"), q[i].as_quat().tolist()))
        (tmp_path / f"{i}.yaml").write_text(yaml.safe_dump(x))
    stack = read_pose_dir(tmp_path, "xyz-quat-xyzw", unit="m")
    assert stack.names == tuple(str(i) for i in range(12))  # 2 before 10
    np.testing.assert_allclose(stack.poses[:, :3, :3], q.as_matrix(), atol=1e-12)


def _robot(n: int, names=None, stamps=None) -> PoseStack:
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses.setflags(write=False)
    return PoseStack(poses, "mm", "matrix", names, None if stamps is None else np.asarray(stamps, float))


def test_pair_images_by_name_index_and_time(tmp_path):
    files = [tmp_path / f"{n}.png" for n in ("0", "1", "2", "3", "10")]
    paired = pair_images(files, _robot(5, names=("10", "3", "2", "1", "7")), "name")
    assert dict(zip(paired.image_rows.tolist(), paired.robot_rows.tolist())) == {1: 3, 2: 2, 3: 1, 4: 0}
    assert {d.name for d in paired.dropped if d.kind == "image"} == {"0"}
    assert {d.name for d in paired.dropped if d.kind == "robot"} == {"7"}
    assert pair_images(files, _robot(5), "name").robot_rows.tolist() == [0, 1, 2, 3]  # row numbers as names
    assert pair_images(files, _robot(5), "index").robot_rows.tolist() == [0, 1, 2, 3, 4]
    with pytest.raises(InputError, match="5 images and 4 robot poses"):
        pair_images(files, _robot(4), "index")
    stamped = [tmp_path / f"frame_{t}.png" for t in ("100.02", "100.51", "101.0", "107.0")]
    paired = pair_images(stamped, _robot(4, stamps=[100.0, 100.5, 101.0, 101.5]), "time")
    assert paired.image_rows.tolist() == [0, 1, 2] and paired.robot_rows.tolist() == [0, 1, 2]
    assert [d.name for d in paired.dropped if d.kind == "image"] == ["frame_107.0"]
    with pytest.raises(InputError, match="no time stamp column"):
        pair_images(stamped, _robot(4), "time")


def test_image_stamp_from_name_and_sidecars(tmp_path):
    assert image_stamp(tmp_path / "cam_1700000000.250.png") == pytest.approx(1700000000.25)
    assert image_stamp(tmp_path / "1700000000250000000.png") == pytest.approx(1700000000.25)
    assert image_stamp(tmp_path / "board.png") is None
    (tmp_path / "a.json").write_text(json.dumps({"stamp": {"sec": 12, "nanosec": 500000000}}))
    assert image_stamp(tmp_path / "a.png") == pytest.approx(12.5)
    (tmp_path / "b.txt").write_text("42.125\n")
    assert image_stamp(tmp_path / "b.png") == 42.125


# ----------------------------------------------------------------------------- the image set


class StationDetector:
    """Synthetic detections: the image's grey value v names station v - 1 (0 = no board)."""

    def __init__(self, cell, board=BOARD, camera=CAMERA, noise=0.0):
        self.cell, self.board, self.camera, self.noise = cell, board, camera, noise
        self.rng = np.random.default_rng(11)

    def __call__(self, image, board):
        station = int(image[0, 0]) - 1
        if station < 0:
            raise BoardNotFound("only 0 chessboard corners found, need 54")
        T = np.array(self.cell["T_cam_target"][station])
        T[:3, 3] *= 1e-3 if board.unit == "m" else 1.0  # the truth is in mm
        return projected(board, self.camera, T, self.noise, self.rng)


def write_station_images(folder, names_and_stations, size=(640, 480)):
    """One PNG per (file name, station or None for no board); grey value = station + 1."""
    folder.mkdir(exist_ok=True)
    for name, station in names_and_stations:
        value = 0 if station is None else station + 1
        cv2.imwrite(str(folder / name), np.full((size[1], size[0]), value, np.uint8))
    return folder


def robot_stack(A: np.ndarray, names) -> PoseStack:
    poses = np.array(A)
    poses.setflags(write=False)
    return PoseStack(poses, "mm", "matrix", tuple(names))


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_dropped_image_takes_its_robot_pose_and_the_rest_stay_aligned(tmp_path, setup):
    """Ten stations; image 3 shows no board, 7.png is damaged, 12.png has no robot pose, robot
    pose 9 has no image. Every kept image must sit with its own robot pose: the noise-free
    hand-eye solution then reproduces the truth to 1e-6 (a single shifted pair would not)."""
    cell = simulated_cell(10, setup, seed=12)
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", None if i == 3 else i)
                                                         for i in range(10) if i not in (7, 9)] + [("12.png", 5)])
    (folder / "7.png").write_bytes(b"not a png")
    robot = robot_stack(cell["A"], [str(i) for i in range(10)])
    images = images_and_poses(folder, BOARD, CAMERA, setup=setup, robot=robot, match="name",
                              detector=StationDetector(cell))
    assert images.names == ("0", "1", "2", "4", "5", "6", "8")
    np.testing.assert_array_equal(images.robot_rows, [0, 1, 2, 4, 5, 6, 8])
    assert images.pose_names == images.names
    reasons = {(d.kind, d.name, d.robot): d.reason for d in images.dropped}
    assert reasons[("image", "3", "3")].startswith("board not found")
    assert reasons[("image", "7", "7")].startswith("unreadable image file")
    assert reasons[("image", "12", None)] == "no robot pose of that name"
    assert reasons[("robot", "9", None)] == "no image of that name"
    for T, row in zip(images.T_cam_target, images.robot_rows):
        rot, trans = pose_error(T, cell["T_cam_target"][row])
        assert rot < 1e-9 and trans < 1e-7
    assert np.all(images.errors < 1e-6) and images.calibration is None and len(images.observations) == 7
    data = from_poses(robot.poses[images.robot_rows], images.T_cam_target, "axyb", setup=setup).data
    solution = handeye.solve("axyb", solver="kron-lstsq", **data)
    for name in ("X", "Y"):
        rot, trans = pose_error(solution.unknowns[name], cell[name])
        assert rot < 1e-8 and trans < 1e-5


@pytest.mark.parametrize("match", ["index", "time"])
def test_index_and_time_matching_keep_the_stations_aligned_around_a_dropped_image(tmp_path, match):
    """Eight stations, image 3 without board. By time the robot stream is stored in reverse order
    with 40 ms of clock jitter, so only the stamps can pair it right."""
    cell = simulated_cell(8, "eye-to-hand", seed=16)
    stamps = 100.0 + 0.5 * np.arange(8)
    names = [f"{i}.png" if match == "index" else f"cam_{t:.3f}.png" for i, t in enumerate(stamps)]
    folder = write_station_images(tmp_path / "images", [(n, None if i == 3 else i) for i, n in enumerate(names)])
    order = np.arange(8) if match == "index" else np.arange(8)[::-1]
    jitter = np.random.default_rng(16).uniform(-0.04, 0.04, 8)
    robot = PoseStack(np.array(cell["A"][order]), "mm", "matrix", None, (stamps + jitter)[order])
    images = images_and_poses(folder, BOARD, CAMERA, setup="eye-to-hand", robot=robot, match=match,
                              detector=StationDetector(cell))
    kept = [0, 1, 2, 4, 5, 6, 7]
    np.testing.assert_array_equal(order[images.robot_rows], kept)  # each image with its own station
    assert [(d.name, d.robot) for d in images.dropped] == [(Path(names[3]).stem, str(order.tolist().index(3)))]
    data = from_poses(robot.poses[images.robot_rows], images.T_cam_target, "axyb", setup="eye-to-hand").data
    solution = handeye.solve("axyb", solver="kron-lstsq", **data)
    for name in ("X", "Y"):
        rot, trans = pose_error(solution.unknowns[name], cell[name])
        assert rot < 1e-8 and trans < 1e-5


def test_board_poses_come_in_the_robot_unit_and_intrinsics_are_calibrated_when_missing(tmp_path):
    cell = simulated_cell(12, "eye-in-hand", seed=13)
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", i) for i in range(12)])
    A_m = np.array(cell["A"])
    A_m[:, :3, 3] *= 1e-3
    robot = PoseStack(A_m, "m", "matrix", None)
    images = images_and_poses(folder, BOARD, None, setup="eye-in-hand", robot=robot, match="index",
                              detector=StationDetector(cell, noise=0.05))
    assert images.unit == "m" and images.calibration is not None
    np.testing.assert_allclose(images.camera.K, K_TRUE, rtol=3e-3, atol=1.0)
    for T, T_true in zip(images.T_cam_target, cell["T_cam_target"]):
        rot, trans = pose_error(T, T_true * np.array([1, 1, 1, 1e-3]))
        assert rot < 3e-3 and trans < 2e-3  # metres
    np.testing.assert_allclose(images.observations.object_points[0], BOARD.in_unit("m").object_points())


def test_an_image_far_off_the_others_is_dropped_with_a_warning(tmp_path):
    cell = simulated_cell(8, "eye-in-hand", seed=14)
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", i) for i in range(8)])
    detector = StationDetector(cell, noise=0.2)

    def one_bad(image, board):
        found = detector(image, board)
        if int(image[0, 0]) == 5:  # station 4: corners shifted by a wrong detection
            shift = np.where(np.arange(len(found))[:, None] % 2 == 0, 6.0, -6.0)
            return Detection(found.ids, found.image_points + shift, found.object_points)
        return found

    images = images_and_poses(folder, BOARD, CAMERA, setup="eye-in-hand", robot=_robot(8), match="index",
                              detector=one_bad)
    assert "4" not in images.names and len(images) == 7
    assert any(d.name == "4" and "far above the others" in d.reason for d in images.dropped)
    assert any("dropped image 4.png" in w for w in images.warnings)


def test_nothing_usable_is_one_input_error(tmp_path):
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", None) for i in range(4)])
    with pytest.raises(InputError, match=r"found in none of the 4 images \(board not found: only 0") as info:
        images_and_poses(folder, BOARD, CAMERA, setup="eye-in-hand", robot=_robot(4), match="index",
                         detector=StationDetector({}))
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="the intrinsics are for 1280x720 images but the images are 640x480"):
        cell = simulated_cell(3, "eye-in-hand", seed=15)
        write_station_images(folder, [(f"{i}.png", i) for i in range(3)])
        images_and_poses(folder, BOARD, Camera(K_TRUE, DIST_TRUE, (1280, 720)), setup="eye-in-hand",
                         detector=StationDetector(cell))


def test_a_half_turn_symmetric_chessboard_is_warned_about(tmp_path):
    board = parse_board("chessboard:8x6:25mm")  # 8 + 6 even: the corner order can flip 180 deg
    cell = simulated_cell(3, "eye-in-hand", board=board, seed=17)
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", i) for i in range(3)])
    images = images_and_poses(folder, board, CAMERA, setup="eye-in-hand", detector=StationDetector(cell, board))
    assert len(images) == 3 and any("may flip 180 deg between images" in w for w in images.warnings)
    assert not images_and_poses(folder, BOARD, CAMERA, setup="eye-in-hand",
                                detector=StationDetector(simulated_cell(3, "eye-in-hand", seed=17))).warnings


def test_intrinsics_that_fit_the_images_worse_than_their_own_calibration_are_warned_about(tmp_path):
    """The images come from a lens with barrel distortion (DIST_TRUE); an intrinsics file without
    the distortion fits them clearly worse than intrinsics calibrated from them: a warning naming
    both RMS figures. The right intrinsics give no such warning (their RMS is within the few per
    cent the calibration's extra parameters buy)."""
    cell = simulated_cell(12, "eye-in-hand", seed=21, distance=(280.0, 350.0), tilt_deg=40.0)  # board fills the view
    folder = write_station_images(tmp_path / "images", [(f"{i}.png", i) for i in range(12)])
    robot = robot_stack(cell["A"], [str(i) for i in range(12)])

    def warnings_with(camera):
        return [w for w in images_and_poses(folder, BOARD, camera, setup="eye-in-hand", robot=robot,
                                            detector=StationDetector(cell, noise=0.1)).warnings
                if "given intrinsics" in w]

    assert warnings_with(CAMERA) == []
    (warning,) = warnings_with(Camera(K_TRUE, np.zeros(5), (640, 480)))
    assert "fit the images worse than intrinsics calibrated from them (0.48 px against 0.14 px RMS" in warning
    assert "\n" not in warning
