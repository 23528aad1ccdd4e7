"""``handeye.calibrate(cell)``, the calibrate workflow as a library call, against the command line:

- the same answer to the last digit (np.array_equal) from ``handeye calibrate`` with flags, with
  ``--config`` (the file ``--write-config`` wrote from those flags) and from the library, on the
  bundled examples as the README and docs/calibrate.md run them: the board images (eye-in-hand),
  the ETH robot_arm stations (eye-in-hand, axyb and axxb), the paper's simulated stations read as
  an eye-to-hand cell, and a time-stamped stream pair matched by interpolation; the real ChArUco
  set (eye-to-hand) and the ETH recording matched by time when /work/shared/data is present;
- a shifted pairing caught on both paths: board images numbered from 1 against robot rows
  numbered from 0 (an error naming the fix), and a camera file one row off (status unreliable);
- the result: frames, stations, dropped images and rows with their reasons, and every export
  (JSON, YAML, ROS 2 line, URDF joint, xacro macro, quality report).
"""

from __future__ import annotations

import json
import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from handeye.checks.stations import Dropped
from handeye.cli._cell_flags import cell_words
from handeye.geometry.se3 import inverse
from handeye.io.examples import image_example_dir, load_example
from handeye.io.pose_readers import PoseStack, read_pose_dir
from handeye.io.pose_writers import write_poses
from handeye.workflow.cell import CameraStream, Cell, Images, Matching, PoseStream
from handeye.workflow.exports import plain
from tests.conftest import run_cli

SHARED = Path(__file__).parents[3] / "shared" / "data"
CHARUCO = SHARED / "industrial_calibration_rct" / "test_set_charuco"
ETH = SHARED / "ethz_asl_handeye_2017" / "robot_arm"
BUNDLED = image_example_dir()
IMAGE_FLAGS = ["--images", BUNDLED / "images", "--board", "circlegrid:10x10:25.4mm", "--robot", BUNDLED / "poses",
               "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--setup", "eye-in-hand"]


# ----------------------------------------------------------------------------- the bundled cells


def eth_files(folder: Path) -> list:
    """The bundled ETH robot_arm stations as the recording's files: robot T_base_hand and camera
    T_target_camera (camera-in-board), x y z qx qy qz qw in metres."""
    data, _, _ = load_example("eth-robot-arm")
    write_poses(folder / "robot.csv", data["A"], "xyz-quat-xyzw", unit="m")
    write_poses(folder / "camera.csv", data["B"], "xyz-quat-xyzw", unit="m")
    return ["--robot", folder / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m",
            "--camera", folder / "camera.csv", "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand"]


def simulated_eye_to_hand(folder: Path) -> list:
    """The bundled simulated stations read as an eye-to-hand cell: the camera file holds B =
    T_cam_target (docs/conventions.md), written as the README's FANUC and solvePnP files."""
    data, _, _ = load_example("simulated")
    write_poses(folder / "robot.csv", data["A"], "fanuc-wpr", unit="mm")
    write_poses(folder / "board.csv", data["B"], "opencv-rvec", unit="mm")
    return ["--robot", folder / "robot.csv", "--robot-format", "fanuc-wpr", "--camera", folder / "board.csv",
            "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-to-hand"]


def interpolated_streams(folder: Path) -> list:
    """Two unsynchronised streams (robot 100 Hz, camera 30 Hz, clocks 37 ms apart; tests/streams/test_streams.py)."""
    from test_streams import NOISE
    from test_streams import cell as streams

    robot, camera = streams(-0.037, NOISE, seed=5, seconds=12.0)
    write_poses(folder / "robot.csv", robot.in_unit("m"), "xyz-quat-xyzw")
    cam = camera.in_unit("m")
    write_poses(folder / "camera.csv", PoseStack(inverse(cam.poses), "m", "matrix", stamps=cam.stamps),
                "xyz-quat-xyzw")
    return ["--robot", folder / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m",
            "--camera", folder / "camera.csv", "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand", "--match", "interpolate"]


def charuco_images(folder: Path) -> list:
    if not CHARUCO.is_dir():
        pytest.skip("needs /work/shared/data/industrial_calibration_rct")
    return ["--images", CHARUCO / "images", "--board", "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250", "--robot",
            CHARUCO / "poses", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--setup", "eye-to-hand",
            "--match", "name"]


def eth_by_time(folder: Path) -> list:
    """docs/calibrate.md's --match time example: 150 evenly spaced camera rows of the recording."""
    if not ETH.is_dir():
        pytest.skip("needs /work/shared/data/ethz_asl_handeye_2017")
    rows = (ETH / "robot_arm_complete_bag_color_and_ir_target_ir.csv").read_text().splitlines()
    keep = np.linspace(0, len(rows) - 1, 150).round().astype(int)
    (folder / "camera.csv").write_text("\n".join(rows[k] for k in keep) + "\n")
    shutil.copy(ETH / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv", folder / "robot.csv")
    return ["--robot", folder / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m",
            "--camera", folder / "camera.csv", "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand", "--match", "time", "--max-dt", "0.02"]


CELLS = {
    "images-eye-in-hand": lambda folder: IMAGE_FLAGS,
    "eth-eye-in-hand": eth_files,
    "eth-eye-in-hand-axxb": lambda folder: [*eth_files(folder), "--problem", "axxb"],
    "simulated-eye-to-hand": simulated_eye_to_hand,
    "simulated-eye-to-hand-axxb": lambda folder: [*simulated_eye_to_hand(folder), "--problem", "axxb"],
    "streams-interpolated": interpolated_streams,
    "charuco-eye-to-hand": charuco_images,
    "eth-matched-by-time": eth_by_time,
}


@pytest.mark.parametrize("name", list(CELLS))
def test_flags_config_and_library_give_the_same_answer_to_the_last_digit(name, tmp_path, capsys, monkeypatch):
    flags = [str(a) for a in CELLS[name](tmp_path)]
    code, out, err = run_cli(capsys, "calibrate", *flags, "--json")
    assert code == 0, err
    by_flags = json.loads(out)
    cell_file = tmp_path / "cells" / "cell.yaml"
    cell_file.parent.mkdir()
    assert run_cli(capsys, "calibrate", *flags, "--write-config", cell_file)[0] == 0
    monkeypatch.chdir(tmp_path / "cells")  # the file's paths do not depend on where it is run from
    code, out, err = run_cli(capsys, "calibrate", "--config", "cell.yaml", "--json")
    assert code == 0, err
    by_config = json.loads(out)
    result = handeye.calibrate(Cell.from_file("cell.yaml"))
    library = result.to_dict()
    for unknown in ("X", "Y") if "Y" in by_flags else ("X",):
        assert np.array_equal(by_flags[unknown], by_config[unknown]), unknown
        assert np.array_equal(np.array(by_flags[unknown]), result.unknowns[unknown]), unknown
        assert np.abs(np.array(by_flags[unknown]) - result.unknowns[unknown]).max() == 0.0
    per = "per_" + by_flags["residuals"]["per"]
    for kind in ("rotation_deg", "translation"):
        assert np.array_equal(by_flags["residuals"][per][kind], by_config["residuals"][per][kind])
        assert np.array_equal(by_flags["residuals"][per][kind], library["residuals"][per][kind])
    assert by_flags["status"] == by_config["status"] == library["status"] == str(result.status)
    assert by_flags["stations"] == by_config["stations"] == library["stations"] == len(result.stations)
    assert by_flags["warnings"] == by_config["warnings"] == [cell_words(w) for w in library["warnings"]]
    assert by_flags["ros"]["command"] == by_config["ros"]["command"] == result.ros2_static_transform()
    assert by_flags["checks"] == by_config["checks"] == library["checks"]
    assert result.usable and result.plausible


def test_a_cell_built_in_python_is_the_readme_command(capsys):
    """The README's image command and the same cell written in Python (relative paths, defaults)."""
    code, out, _ = run_cli(capsys, "calibrate", *IMAGE_FLAGS, "--json")
    assert code == 0
    cli = json.loads(out)
    cell = Cell(robot=PoseStream(BUNDLED / "poses", format="xyz-quat-xyzw", unit="m"),
                images=Images(BUNDLED / "images", board="circlegrid:10x10:25.4mm"), setup="eye-in-hand")
    seen = []
    result = handeye.calibrate(cell, log=lambda stage, text: seen.append(stage))
    assert seen == ["images"]
    assert np.array_equal(cli["X"], result.X) and np.array_equal(cli["Y"], result.Y)
    # over 3 folds of the stations the corner fit with the robot's poses as measured predicts the
    # held-out corners best (measured 2.11 px RMS; with the robot's noise estimated 4.42, the pose-based
    # answer 4.45, OpenCV PARK 4.78: bench/robot_noise_images.py), on both paths
    assert result.solver == "reprojection" and cli["solver"] == "reprojection"
    held = result.solution.diagnostics["held_out"]
    assert held["chosen"] == "exact_robot" and not held["pose_based_better"]
    assert held["exact_robot_px"] < 0.6 * min(held["joint_px"], held["pose_based_px"])
    assert any("predicts the corners of images it was not fitted to best" in w for w in result.warnings)


# ----------------------------------------------------------------------------- a shifted pairing


def one_based_images(folder: Path) -> tuple[Path, Path]:
    """The bundled images renamed 1..15 (image k+1 is station k) and the robot poses as one CSV
    without a name column (rows 0..14)."""
    (folder / "images").mkdir()
    for k in range(15):
        shutil.copy(BUNDLED / "images" / f"{k}.png", folder / "images" / f"{k + 1}.png")
    robot = read_pose_dir(BUNDLED / "poses", "xyz-quat-xyzw", unit="m")
    write_poses(folder / "robot.csv", robot.poses, "xyz-quat-xyzw", unit="m")
    return folder / "images", folder / "robot.csv"


def test_one_based_images_against_zero_based_rows_are_caught_on_both_paths(tmp_path, capsys):
    """By name, images 1..15 would pair with robot rows 1..14, every station one off, and the
    solve would end optimal on the wrong stations. Both paths refuse, naming the fix; the default
    matching (k-th image with k-th robot pose) pairs them right, to the same digit on both."""
    images, robot = one_based_images(tmp_path)
    flags = ["--images", images, "--board", "circlegrid:10x10:25.4mm", "--robot", robot, "--robot-format",
             "xyz-quat-xyzw", "--robot-unit", "m", "--setup", "eye-in-hand"]
    code, out, err = run_cli(capsys, "calibrate", *flags, "--match", "name")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "--match name: the images are numbered 1..15 and the robot poses 0..14" in err
    assert "one station after its own" in err and "use --match index" in err
    cell = Cell(robot=PoseStream(robot, "xyz-quat-xyzw", "m"), images=Images(images, "circlegrid:10x10:25.4mm"),
                setup="eye-in-hand", matching=Matching("name"))
    with pytest.raises(handeye.InputError, match=r"use `matching.method: index` to pair the k-th image"):
        handeye.calibrate(cell)
    # the hand-made path of the issue: images_and_poses pairs by name unless told otherwise
    from handeye.io.pose_readers import read_poses
    from handeye.vision.boards import parse_board
    from handeye.vision.image_set import images_and_poses

    with pytest.raises(handeye.InputError, match=r"match='name': the images are numbered 1..15.*use match='index'"):
        images_and_poses(images, parse_board("circlegrid:10x10:25.4mm"), None, setup="eye-in-hand",
                         robot=read_poses(robot, "xyz-quat-xyzw", unit="m"))
    code, out, err = run_cli(capsys, "calibrate", *flags, "--json")
    assert code == 0, err
    by_default = handeye.calibrate(cell.replace(matching=Matching()))
    assert np.array_equal(json.loads(out)["X"], by_default.X)
    assert [p["image"] for p in by_default.stations.matching["pairs"]] == [str(k + 1) for k in range(15)]
    assert [p["robot_pose"] for p in by_default.stations.matching["pairs"]] == [str(k) for k in range(15)]
    bundled = handeye.calibrate(Cell(robot=PoseStream(BUNDLED / "poses", "xyz-quat-xyzw", "m"),
                                     images=Images(BUNDLED / "images", "circlegrid:10x10:25.4mm"), setup="eye-in-hand"))
    np.testing.assert_allclose(by_default.X, bundled.X, atol=1e-9)  # the CSV holds the poses to ~1e-16


def test_a_camera_file_one_row_off_is_unreliable_on_both_paths(tmp_path, capsys):
    """Row k of the camera file is station k+1 of the robot's: solved optimal, found implausible
    (the shift explains the data), exit 1 and status unreliable, with the same first warning."""
    data, _, _ = load_example("simulated")
    write_poses(tmp_path / "robot.csv", data["A"][:-1], "fanuc-wpr", unit="mm")
    write_poses(tmp_path / "board.csv", data["B"][1:], "opencv-rvec", unit="mm")
    flags = ["--robot", tmp_path / "robot.csv", "--robot-format", "fanuc-wpr", "--camera", tmp_path / "board.csv",
             "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-to-hand"]
    out_json = tmp_path / "result.json"
    code, out, err = run_cli(capsys, "calibrate", *flags, "--json", "-o", out_json)
    assert code == 1 and not out_json.exists()
    cli = json.loads(out)
    assert cli["status"] == "unreliable" and "station" in cli["checks"]["explanation"]["description"]
    assert "handeye: error: status unreliable: implausible fit" in err
    result = handeye.calibrate(Cell(robot=PoseStream(tmp_path / "robot.csv", "fanuc-wpr"),
                                    camera=CameraStream(tmp_path / "board.csv", "opencv-rvec", "mm"),
                                    setup="eye-to-hand"))
    assert result.status is handeye.Status.UNRELIABLE and not result.usable and result.plausible is False
    assert result.solution.solver == "auto" and np.array_equal(cli["X"], result.X)
    assert result.checks.warnings[0] == cli["warnings"][0] and "one station" in cli["warnings"][0]


def test_a_setup_mistake_is_named_as_a_setting_in_python_and_as_a_flag_on_the_command_line(tmp_path, capsys):
    """Camera poses written as T_target_cam: the library's warning names the cell's setting, the
    command line's the flag that says the same."""
    data, _, _ = load_example("simulated")
    write_poses(tmp_path / "robot.csv", data["A"], "fanuc-wpr", unit="mm")
    write_poses(tmp_path / "board.csv", inverse(data["B"]), "opencv-rvec", unit="mm")  # camera-in-board
    result = handeye.calibrate(Cell(robot=PoseStream(tmp_path / "robot.csv", "fanuc-wpr"),
                                    camera=CameraStream(tmp_path / "board.csv", "opencv-rvec", "mm"),
                                    setup="eye-to-hand"))
    assert result.status is handeye.Status.UNRELIABLE
    assert "`camera.poses: camera-in-board`" in result.warnings[0]
    code, out, err = run_cli(capsys, "calibrate", "--robot", tmp_path / "robot.csv", "--robot-format", "fanuc-wpr",
                             "--camera", tmp_path / "board.csv", "--camera-format", "opencv-rvec", "--camera-unit", "mm",
                             "--setup", "eye-to-hand")
    assert code == 1 and "--camera-poses camera-in-board" in err and "`" not in err


# ----------------------------------------------------------------------------- the result


@pytest.fixture(scope="module")
def dropped_image(tmp_path_factory):
    """The bundled images with image 4 replaced by a view without the board, calibrated."""
    folder = tmp_path_factory.mktemp("dropped")
    shutil.copytree(BUNDLED / "images", folder / "images")
    cv2.imwrite(str(folder / "images" / "4.png"), np.full((480, 640), 128, np.uint8))
    cell = Cell(robot=PoseStream(BUNDLED / "poses", "xyz-quat-xyzw", "m"),
                images=Images(folder / "images", "circlegrid:10x10:25.4mm"), setup="eye-in-hand",
                frame_ids=("tool0", "camera_color_optical_frame"))
    return folder, handeye.calibrate(cell)


def test_the_result_carries_frames_stations_and_what_was_dropped(dropped_image):
    _, result = dropped_image
    assert result.usable and result.status is handeye.Status.OPTIMAL and result.unit == "m"
    x, y = result.frames["X"], result.frames["Y"]
    assert (x.name, x.parent, x.child) == ("T_flange_cam", "flange", "camera")
    assert (y.name, y.parent, y.child) == ("T_base_target", "base", "target")
    assert len(result.stations) == 14 and result.stations.robot_rows.tolist() == [k for k in range(15) if k != 4]
    (dropped,) = result.dropped
    assert (dropped.kind, dropped.name, dropped.robot) == ("image", "4", "4")
    assert dropped.reason.startswith("board not found")
    assert dropped.describe().startswith("image 4 with robot pose 4: board not found")
    assert result.to_dict()["images"]["dropped"][0] == {"kind": "image", "name": "4", "robot": "4",
                                                           "reason": dropped.reason}
    assert any(w.startswith("dropped image 4 with robot pose 4") for w in result.warnings)


def test_time_matching_lists_the_camera_rows_it_dropped(tmp_path):
    data, _, _ = load_example("simulated")
    stamps = 10.0 * np.arange(16) + 0.5
    write_poses(tmp_path / "robot.csv", PoseStack(data["A"], "mm", "matrix", stamps=stamps), "fanuc-wpr")
    camera = np.concatenate([data["B"], data["B"][:1]])
    write_poses(tmp_path / "board.csv", PoseStack(camera, "mm", "matrix", stamps=np.append(stamps + 0.003, 500.0)),
                "opencv-rvec")
    result = handeye.calibrate(Cell(robot=PoseStream(tmp_path / "robot.csv", "fanuc-wpr"),
                                    camera=CameraStream(tmp_path / "board.csv", "opencv-rvec", "mm"),
                                    setup="eye-to-hand", matching=Matching("time", max_dt=0.01)))
    assert len(result.stations) == 16 and result.stations.matching["matched"] == 16
    assert result.dropped == (Dropped("camera", "row 17", "no robot pose within 0.01 s of its stamp 500.000000 s"),)


def test_interpolation_says_why_each_camera_sample_is_no_station(tmp_path):
    from test_streams import cell as streams

    robot, camera = streams(0.0, static=((3.0, 5.0),), seconds=12.0)
    result = handeye.calibrate(Cell(
        robot=PoseStream(write_poses(tmp_path / "robot.csv", robot, "xyz-quat-xyzw"), "xyz-quat-xyzw", "mm"),
        camera=CameraStream(write_poses(tmp_path / "camera.csv", PoseStack(inverse(camera.poses), "mm", "matrix",
                                                                           stamps=camera.stamps), "xyz-quat-xyzw"),
                            "xyz-quat-xyzw", "mm", poses="camera-in-board"),
        setup="eye-in-hand", matching=Matching("interpolate", max_pairs=100)))
    counts = result.stations.matching["counts"]
    assert len(result.stations) == counts["kept"] == 100
    assert len(result.dropped) == counts["camera_samples"] - counts["kept"]
    reasons = [d.reason for d in result.dropped]
    assert sum("static" in r for r in reasons) == counts["static"] > 0
    assert sum("well-spread" in r for r in reasons) == counts["not_selected"] > 0
    assert sum("outside the robot stream" in r for r in reasons) == counts["outside"]
    kept = set(result.stations.camera_rows.tolist())
    assert {int(d.name.removeprefix("row ")) - 1 for d in result.dropped}.isdisjoint(kept)


def test_the_exports(dropped_image, tmp_path):
    _, result = dropped_image
    X = result.X
    t_m = X[:3, 3]  # the robot's unit is metres
    # ROS 2
    line = result.ros2_static_transform()
    assert line.startswith("ros2 run tf2_ros static_transform_publisher --x ")
    assert line.endswith("--frame-id tool0 --child-frame-id camera_color_optical_frame")
    # URDF: the joint's origin is X (metres; rpy about the fixed x, y, z axes)
    joint = ET.fromstring(result.urdf_joint())
    assert joint.get("type") == "fixed" and joint.get("name") == "tool0_to_camera_color_optical_frame"
    assert joint.find("parent").get("link") == "tool0"
    assert joint.find("child").get("link") == "camera_color_optical_frame"
    origin = joint.find("origin")
    np.testing.assert_allclose([float(v) for v in origin.get("xyz").split()], t_m, atol=1e-9)
    rpy = [float(v) for v in origin.get("rpy").split()]
    np.testing.assert_allclose(Rotation.from_euler("xyz", rpy).as_matrix(), X[:3, :3], atol=1e-8)
    # xacro: a macro with the same origin, parent and child as parameters
    root = ET.fromstring(result.xacro())
    ns = {"xacro": "http://www.ros.org/wiki/xacro"}
    macro = root.find("xacro:macro", ns)
    assert macro.get("name") == "handeye_calibration"
    assert macro.get("params") == "parent:=tool0 child:=camera_color_optical_frame"
    assert macro.find("joint/origin").attrib == origin.attrib
    assert macro.find("joint/parent").get("link") == "${parent}"
    # JSON and YAML: the same data
    as_json = json.loads(result.to_json())
    assert as_json == plain(result.to_dict()) == yaml.safe_load(result.to_yaml())
    assert np.array_equal(as_json["X"], X) and as_json["frames"] == {"X": "T_flange_cam", "Y": "T_base_target"}
    assert as_json["ros"]["command"] == line and as_json["stations"] == 14
    q = as_json["poses"]["X"]["xyz_quat"][3:]
    assert math.isclose(abs(float(np.dot(q, Rotation.from_matrix(X[:3, :3]).as_quat()))), 1.0, abs_tol=1e-12)
    # the quality report: written whole, kept without force
    written = result.write_report(tmp_path / "report.html")
    assert written == [tmp_path / "report.html"] and "T_flange_cam" in written[0].read_text()
    assert "handeye.calibrate(cell)" in written[0].read_text()
    with pytest.raises(handeye.InputError, match="the file exists"):
        result.write_report(tmp_path / "report.html")
    markdown = result.write_report(tmp_path / "report.md", command="my pipeline")
    assert markdown[0].read_text().count("my pipeline") == 1 and all(p.exists() for p in markdown)


def test_calibrate_takes_a_cell_only():
    with pytest.raises(handeye.InputError, match="calibrate expects a handeye.Cell"):
        handeye.calibrate({"robot": "robot.csv"})
    assert {"calibrate", "Cell", "CalibrationResult"} <= set(handeye.__all__)
    assert handeye.Cell is Cell and handeye.CalibrationResult.__name__ == "CalibrationResult"


def test_the_readme_library_example_runs(tmp_path, monkeypatch, capsys):
    """README's handeye.calibrate block, run in a folder that sees the repository's core/data."""
    import re

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    code = next(body for body in re.findall(r"^```python\n(.*?)^```$", readme, re.S | re.M)
                if "handeye.calibrate(cell)" in body)
    (tmp_path / "core").symlink_to(Path(__file__).resolve().parents[2] / "core")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "T_flange_cam optimal True" in out and "static_transform_publisher" in out and "<joint" in out
    assert (tmp_path / "report.html").stat().st_size > 10_000
