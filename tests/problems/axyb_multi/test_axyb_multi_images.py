"""A cell of several cameras and targets calibrated from IMAGES: two fixed cameras, two ChArUco
boards on the flange (disjoint marker ids) in each image, rendered at 10 robot stations
(tests/multi_images.py). Every board found in every image is one observation of ``axyb-multi``;
a board not found (hidden, too few corners) is reported per image and the rest still solves; a
board pose far off by reprojection is dropped with a note; bad cell files give one-line errors
(exit 2, no traceback).

Tolerances from the pixel accuracy: the renders' corners are found to ~0.03-0.1 px RMS (blur 0.6
px, noise 1.5 grey levels), which at fx = 600 px, 24 corners on a 150 x 210 mm board 550-600 mm
away gives each board pose to ~0.01 deg and ~0.05 mm (depth); the 37 observations' X and Y come
out within ~0.04 deg and ~0.31 mm of the truth (measured), so 0.15 deg and 1 mm hold with margin
and still catch a wrong pairing, unit or frame (degrees and tens of mm off).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from multi_images import BOARDS, CAMERA, CELL_YAML, write_cell

import handeye
from handeye.base.errors import InputError
from handeye.cli import main
from handeye.geometry.se3 import inverse
from handeye.io.pose_readers import read_poses
from handeye.vision.board_set import check_distinct
from handeye.vision.boards import parse_board
from handeye.vision.image_observations import camera_observations
from handeye.workflow.cell import Cell

ROTATION_TOL_DEG = 0.15
TRANSLATION_TOL_MM = 1.0
STATIONS = 10
HIDDEN = ("cam1", 4)  # board1 left out of cam1's image 04


def pose_error(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    D = inverse(truth) @ np.asarray(T)
    angle = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1.0, 1.0)))
    return float(angle), float(np.linalg.norm(D[:3, 3]))


@pytest.fixture(scope="module")
def cell_dir(tmp_path_factory) -> tuple[Path, dict]:
    folder = tmp_path_factory.mktemp("multi_images")
    truth = write_cell(folder, STATIONS, hide={HIDDEN: ("board1",)})
    return folder, truth


def copy_cell(cell_dir, tmp_path: Path, text: str) -> Path:
    """The rendered cell beside a new cell file holding `text`."""
    folder, _ = cell_dir
    for name in ("images", "robot.csv", "cam0.json", "cam1.json"):
        source = folder / name
        (shutil.copytree if source.is_dir() else shutil.copy)(source, tmp_path / name)
    (tmp_path / "cell.yaml").write_text(text)
    return tmp_path / "cell.yaml"


def test_images_of_two_cameras_and_two_boards_calibrate_to_the_truth(cell_dir):
    folder, truth = cell_dir
    result = handeye.calibrate(Cell.from_file(folder / "cell.yaml"))
    assert result.usable and result.status.value in ("optimal", "optimal_inaccurate")
    named = {p.name: p for p in result.named_poses()}
    assert sorted(named) == ["board0", "board1", "cam0", "cam1"]
    for name, p in named.items():
        expected = truth["X"].get(name, truth["Y"].get(name))
        rotation, translation = pose_error(p.T, expected)
        assert rotation < ROTATION_TOL_DEG, (name, rotation)
        assert translation < TRANSLATION_TOL_MM, (name, translation)
    assert named["cam0"].parent == "base" and named["board0"].parent == "flange"
    # 2 cameras x 2 boards x 10 stations, less the hidden board and any board seen too obliquely
    observations = len(result.camera_read)
    dropped = result.dropped
    assert observations + len(dropped) == 2 * 2 * STATIONS
    assert observations >= 34
    hidden = [d for d in dropped if d.name == "cam1/04"]
    assert len(hidden) == 1 and hidden[0].reason.startswith("board1 not found")
    assert all(d.kind == "image" and d.reason.split()[0] in BOARDS for d in dropped)
    assert any("ChArUco corners found, need 6" in d.reason for d in dropped)  # seen too obliquely
    assert result.stations.matching["dropped"][0]["name"].startswith("cam")


def test_the_same_images_eye_in_hand(cell_dir, tmp_path):
    """The images again, with every robot pose inverted and setup eye-in-hand: the board in the
    camera is then X_cam^-1 A'^-1 Y_board with A' = A^-1, so the same images are a cell of two
    wrist cameras (X = T_flange_cam, the eye-to-hand Y's) seeing two boards fixed in the cell
    (Y = T_base_board, the eye-to-hand X's)."""
    from scipy.spatial.transform import Rotation

    _, truth = cell_dir
    cell = copy_cell(cell_dir, tmp_path, CELL_YAML.replace("eye-to-hand", "eye-in-hand"))
    robot = read_poses(tmp_path / "robot.csv", "xyz-quat-xyzw", unit="mm")
    rows = ["name,x,y,z,qx,qy,qz,qw"]
    for name, T in zip(robot.names, inverse(robot.poses)):
        rows.append(",".join([name, *(f"{v:.17g}" for v in (*T[:3, 3], *Rotation.from_matrix(T[:3, :3]).as_quat()))]))
    (tmp_path / "robot.csv").write_text("\n".join(rows) + "\n")
    result = handeye.calibrate(Cell.from_file(cell))
    assert result.usable
    named = {p.name: p for p in result.named_poses()}
    assert named["cam0"].parent == "flange" and named["board1"].parent == "base"
    for name, p in named.items():
        expected = truth["Y"].get(name, truth["X"].get(name))
        rotation, translation = pose_error(p.T, expected)
        assert rotation < ROTATION_TOL_DEG and translation < TRANSLATION_TOL_MM, (name, rotation, translation)


def test_cli_prints_each_image_and_what_was_dropped_and_exports(cell_dir, tmp_path, capsys):
    cell = copy_cell(cell_dir, tmp_path, CELL_YAML)
    code = main(["calibrate", "--config", str(cell), "-o", str(tmp_path / "r.json"), "--report",
                 str(tmp_path / "report.html")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "camera cam1: images" in out and "image 04: board0" in out
    assert "dropped image 04: board1 not found" in out
    assert "Y[1] cam1 = T_base_cam1" in out
    import json

    r = json.loads((tmp_path / "r.json").read_text())
    assert sorted(r["transforms"]) == ["board0", "board1", "cam0", "cam1"]
    assert r["inputs"]["camera"]["files"] == ["images/cam0", "images/cam1"] or \
        all(f.endswith(("cam0", "cam1")) for f in r["inputs"]["camera"]["files"])
    report = (tmp_path / "report.html").read_text()
    # the residuals per observation labelled by station, camera and target, not by index
    assert "<th class='l'>station</th><th class='l'>camera</th><th class='l'>target</th>" in report
    assert "<td class='l'>04</td><td class='l'>cam1</td><td class='l'>board0</td>" in report


def test_a_board_pose_far_off_by_reprojection_is_dropped_with_a_note(cell_dir):
    """A detection spoiled in one image (its corners moved 3 px at random, as a wrong corner or
    blur would) gives a pose whose reprojection RMS is far above the camera's others: dropped."""
    from handeye.vision.detect import detect

    folder, _ = cell_dir
    boards = {name: parse_board(spec) for name, spec in BOARDS.items()}
    rng = np.random.default_rng(3)
    calls = {"n": 0}

    def spoiled(image, board):
        found = detect(image, board)
        calls["n"] += 1
        if calls["n"] == 5:  # image 02, board0
            return type(found)(found.ids, found.image_points + rng.normal(0, 3.0, found.image_points.shape),
                               found.object_points)
        return found

    robot = read_poses(folder / "robot.csv", "xyz-quat-xyzw", unit="mm")
    obs = camera_observations(folder / "images" / "cam0", boards, CAMERA, robot=robot, match="name",
                              detector=spoiled)
    assert len(obs) == 2 * STATIONS - 1
    (note,) = [d for d in obs.dropped if "unreliable" in d.reason]
    assert note.name == "02" and note.reason.startswith("board0: unreliable pose, reprojection error")
    assert any("dropped board0 in image 02.png" in w for w in obs.warnings)
    assert np.all(obs.errors < 0.5)


def test_without_intrinsics_the_camera_is_calibrated_from_the_boards(cell_dir):
    folder, _ = cell_dir
    boards = {name: parse_board(spec) for name, spec in BOARDS.items()}
    robot = read_poses(folder / "robot.csv", "xyz-quat-xyzw", unit="mm")
    obs = camera_observations(folder / "images" / "cam0", boards, None, robot=robot, match="name")
    assert obs.calibration is not None and obs.calibration.rms < 0.2
    K = obs.camera.K
    assert abs(K[0, 0] - 600) < 6 and abs(K[0, 2] - 320) < 6 and abs(K[1, 2] - 240) < 6


def test_two_aprilgrids_and_a_charuco_board_in_one_image():
    """Two AprilGrids (tags 0..8 and 9..17) and a ChArUco board side by side, the nearer grid
    hiding a third of the farther one: each found at its own points (the renders' ~0.03 px), the
    hidden tags simply missing."""
    from handeye.vision.board_set import detect_boards
    from handeye.vision.render import project, render_boards, view_pose

    boards = {"grid0": parse_board("aprilgrid:3x3:40mm:0.3"), "grid1": parse_board("aprilgrid:3x3:40mm:0.3:first=9"),
              "charuco": parse_board("charuco:4x5:30mm:22mm:DICT_4X4_50")}
    check_distinct(boards)
    scene = []
    for board, dx, tilt in zip(boards.values(), (-170, 0, 170), ((0.2, 0.1, 0), (-0.1, -0.2, 0), (0.1, 0.25, 0))):
        T = view_pose(board, 550, tilt=tilt)
        T[0, 3] += dx
        scene.append((board, T))
    image = render_boards(scene, CAMERA, blur=0.6, noise=1.5, rng=np.random.default_rng(0))
    seen = detect_boards(image, boards)
    assert not seen.missing
    for (name, board), (_, T) in zip(boards.items(), scene):
        found = seen.found[name]
        error = np.linalg.norm(found.image_points - project(board, CAMERA, T)[found.ids], axis=1)
        assert np.median(error) < 0.06 and error.max() < 0.15, name
    assert len(seen.found["grid1"]) == 36 and 12 <= len(seen.found["grid0"]) < 36  # partly behind grid1
    assert set(seen.found["grid0"].ids // 4) <= set(range(9))


def test_boards_that_one_image_cannot_tell_apart_are_refused():
    same = {"a": parse_board(BOARDS["board0"]), "b": parse_board(BOARDS["board0"])}
    with pytest.raises(InputError, match=r"'a' \(ids 0..16\) and 'b' \(ids 0..16\) share DICT_4X4_50 .*first=17"):
        check_distinct(same)
    with pytest.raises(InputError, match="without marker ids"):
        check_distinct({"a": parse_board("chessboard:9x6:25mm"), "b": parse_board("circlegrid:5x5:30mm")})
    check_distinct({"a": parse_board(BOARDS["board0"]), "b": parse_board("aprilgrid:4x4:30mm:0.3"),
                    "c": parse_board("chessboard:9x6:25mm")})
    board = parse_board("aprilgrid:4x4:30mm:0.3:first=16")
    assert board.marker_ids == range(16, 32) and parse_board(board.spec()) == board
    with pytest.raises(InputError, match="run past the 50 markers of DICT_4X4_50"):
        parse_board("charuco:5x7:30mm:22mm:DICT_4X4_50:first=40")
    with pytest.raises(InputError, match="'first_id' does not apply to a chessboard"):
        parse_board("chessboard:9x6:25mm:first=3")


def test_a_camera_looks_for_its_own_targets_only(cell_dir, tmp_path):
    cell = copy_cell(cell_dir, tmp_path, CELL_YAML.replace("intrinsics: cam1.json}",
                                                           "intrinsics: cam1.json, targets: [board1]}"))
    result = handeye.calibrate(Cell.from_file(cell))
    labels = result.observation_labels
    assert {t for _, c, t in labels if c == "cam1"} == {"board1"}
    assert {t for _, c, t in labels if c == "cam0"} == {"board0", "board1"}
    assert not [d for d in result.dropped if d.name.startswith("cam1/") and "board0" in d.reason]


def test_cell_files_round_trip(cell_dir, tmp_path):
    cell = copy_cell(cell_dir, tmp_path, CELL_YAML)
    read = Cell.from_file(cell)
    text = read.to_yaml(relative_to=tmp_path)
    assert "targets:" in text and "images: images/cam0" in text and "method: name" in text
    (tmp_path / "again.yaml").write_text(text)
    assert Cell.from_file(tmp_path / "again.yaml") == read


BAD = {
    "no targets": (CELL_YAML.split("targets:")[0] + "matching: {method: name}\n",
                   r"`observations\[0\]\.images` need `targets`"),
    "unknown target": (CELL_YAML.replace("intrinsics: cam1.json}", "intrinsics: cam1.json, targets: [board9]}"),
                       r"`observations\[1\]\.targets` names 'board9', which is not in `targets`"),
    "shared ids": (CELL_YAML.replace(":first=17", ""), r"'board0' \(ids 0..16\) and 'board1' \(ids 0..16\) share"),
    "pose file setting": (CELL_YAML.replace("intrinsics: cam0.json}", "intrinsics: cam0.json, format: matrix}"),
                          r"`observations\[0\]\.format` applies to a table of observations"),
    "no camera name": (CELL_YAML.replace("camera: cam0, ", ""), r"`observations\[0\]\.camera: NAME` is required"),
    "interpolate": (CELL_YAML.replace("method: name", "method: interpolate"), "applies to pose streams"),
    "bad board": (CELL_YAML.replace("5x7:30mm:22mm:DICT_4X4_50:first", "5x7:30mm:DICT_4X4_50:first"),
                  r"`targets\.board1`: board spec"),
    "missing folder": (CELL_YAML.replace("images/cam1", "images/cam9"), r"`observations\[1\]` \(camera 'cam1'\): "
                                                                       "image folder .* not found"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_cell_files_are_one_line_errors_and_exit_2(case, cell_dir, tmp_path, capsys):
    text, message = BAD[case]
    cell = copy_cell(cell_dir, tmp_path, text)
    with pytest.raises(InputError, match=message.replace("`", "[`']")) as caught:
        handeye.calibrate(Cell.from_file(cell))
    assert "\n" not in str(caught.value)
    code = main(["calibrate", "--config", str(cell)])
    _, err = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in err and err.count("\n") == 1 and err.startswith("handeye: error:")
