"""``handeye calibrate`` end to end: simulated stations written as a robot file and a camera file
in vendor formats and units, calibrated through handeye.cli.main, and checked against the truth
(both setups, axyb and axxb), with the exported JSON / YAML, the ROS line and the bad-input exits."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, rotation_angle
from handeye.io.pose_writers import write_poses
from handeye.problems.axxb import simulate_stations
from tests.conftest import run_cli

KEYS = {"X", "frames", "units", "setup", "problem", "solver", "status", "std", "residuals", "warnings",
        "inputs", "ros", "poses", "stations"}
#: the truth of the simulated cell (A_k X = Y B_k, A = T_base_flange, B = T_target_cam, mm):
#: which simulated unknown each problem/setup's unknowns are (docs/conventions.md). Eye-to-hand
#: the same numbers are read as a cell whose camera file holds B itself (then T_cam_target = B,
#: X = T_flange_target, Y = T_base_cam).
TRUTH = {("axyb", "eye-in-hand"): {"X": "X", "Y": "Y"}, ("axyb", "eye-to-hand"): {"X": "X", "Y": "Y"},
         ("axxb", "eye-in-hand"): {"X": "X"}, ("axxb", "eye-to-hand"): {"X": "Y"}}


def cell(tmp_path, *, setup="eye-in-hand", robot_format="fanuc-wpr", robot_unit="mm", camera_format="opencv-rvec",
         camera_unit="mm", stations=10, seed=2, noise=None, ext="csv"):
    """Write a simulated cell's robot and camera files; return (robot path, camera path, truth in mm)."""
    st, truth = simulate_stations(stations, seed=seed, noise=noise)
    camera = inverse(st["B"]) if setup == "eye-in-hand" else st["B"]  # T_cam_target
    scale = {"mm": 1.0, "m": 1e-3}
    robot_poses, camera_poses = np.array(st["A"]), np.array(camera)
    robot_poses[:, :3, 3] *= scale[robot_unit]
    camera_poses[:, :3, 3] *= scale[camera_unit]
    robot = write_poses(tmp_path / f"robot.{ext}", robot_poses, robot_format, unit=robot_unit)
    cam = write_poses(tmp_path / f"camera.{ext}", camera_poses, camera_format, unit=camera_unit)
    return robot, cam, truth


def args(robot, camera, robot_format="fanuc-wpr", camera_format="opencv-rvec", setup="eye-in-hand", *extra):
    return ["calibrate", "--robot", robot, "--robot-format", robot_format, "--camera", camera,
            "--camera-format", camera_format, "--setup", setup, *extra]


def check_pose(T, T_true, rot_tol, trans_tol):
    T, T_true = np.asarray(T), np.asarray(T_true)
    assert rotation_angle(T[:3, :3] @ T_true[:3, :3].T) <= rot_tol
    assert np.linalg.norm(T[:3, 3] - T_true[:3, 3]) <= trans_tol * max(1.0, np.linalg.norm(T_true[:3, 3]))


def ros_numbers(line: str) -> dict[str, str]:
    return dict(re.findall(r"--([\w-]+) (\S+)", line))


def test_noise_free_fanuc_and_opencv_eye_in_hand(tmp_path, capsys):
    robot, camera, truth = cell(tmp_path)
    out_json, out_yaml = tmp_path / "result.json", tmp_path / "result.yaml"
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand",
                                           "--camera-unit", "mm", "-o", out_json, "--yaml", out_yaml))
    assert code == 0, err
    r = json.loads(out_json.read_text())
    assert KEYS | {"Y"} <= set(r)
    assert yaml.safe_load(out_yaml.read_text()) == r
    check_pose(r["X"], truth["X"], 1e-6, 1e-6)
    check_pose(r["Y"], truth["Y"], 1e-6, 1e-6)
    assert r["frames"] == {"X": "T_flange_cam", "Y": "T_base_target"}
    assert r["units"] == {"translation": "mm", "rotation": "deg"} and r["status"] == "optimal"
    assert r["setup"] == "eye-in-hand" and r["problem"] == "axyb" and r["solver"] == "auto"
    assert r["inputs"]["robot"] == {"file": str(robot), "format": "fanuc-wpr", "unit": "mm", "poses": 10}
    assert r["inputs"]["camera"]["format"] == "opencv-rvec"
    assert set(r["std"]) == {"X", "Y"} and r["std"]["X"]["rotation_deg"] < 1e-6
    assert r["residuals"]["per"] == "pair" and r["residuals"]["count"] == 10
    assert r["residuals"]["translation"]["max"] < 1e-6 and r["residuals"]["rotation_deg"]["max"] < 1e-6
    # xyz + quaternion and the robot's own format
    x = r["poses"]["X"]["xyz_quat"]
    assert np.allclose(x[:3], truth["X"][:3, 3], atol=1e-6)
    assert np.allclose(Rotation.from_quat(x[3:]).as_matrix(), truth["X"][:3, :3], atol=1e-6)
    wpr = r["poses"]["X"]["robot_format"]
    assert list(wpr) == ["x", "y", "z", "w", "p", "r"]
    R = Rotation.from_euler("xyz", [wpr["w"], wpr["p"], wpr["r"]], degrees=True).as_matrix()
    assert np.allclose(R, truth["X"][:3, :3], atol=1e-6)
    # the ROS line: X = T_flange_cam, metres, quaternion of X
    ros = r["ros"]["command"]
    assert ros.startswith("ros2 run tf2_ros static_transform_publisher ") and ros in out
    n = ros_numbers(ros)
    assert n["frame-id"] == "flange" and n["child-frame-id"] == "camera_optical_frame"
    t = [float(n[k]) for k in "xyz"]
    assert np.allclose(t, truth["X"][:3, 3] * 1e-3, atol=1e-8)
    q = np.array([float(n[k]) for k in ("qx", "qy", "qz", "qw")])
    assert np.allclose(q, Rotation.from_matrix(truth["X"][:3, :3]).as_quat(canonical=True), atol=1e-6)
    # the text output
    assert "X = T_flange_cam" in out and "Y = T_base_target" in out and "1-sigma" in out
    assert f"wrote {out_json}" in out and f"wrote {out_yaml}" in out
    assert "median" in out and "rotation [deg]" in out and "translation [mm]" in out


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
@pytest.mark.parametrize("problem", ["axyb", "axxb"])
@pytest.mark.parametrize(("robot_format", "robot_unit", "camera_format", "camera_unit", "ext"), [
    ("kuka-abc", "m", "xyz-quat-xyzw", "mm", "csv"),
    ("fanuc-wpr", "mm", "matrix", "m", "json"),
    ("ur-rotvec", "m", "opencv-rvec", "mm", "yaml"),
], ids=["kuka-m+quat-mm", "fanuc-mm+matrix-m", "ur-m+rvec-mm"])
def test_formats_units_setups_problems(tmp_path, capsys, setup, problem, robot_format, robot_unit,
                                       camera_format, camera_unit, ext):
    robot, camera, truth = cell(tmp_path, setup=setup, robot_format=robot_format, robot_unit=robot_unit,
                                camera_format=camera_format, camera_unit=camera_unit, ext=ext)
    out_json = tmp_path / "r.json"
    code, out, err = run_cli(capsys, *args(robot, camera, robot_format, camera_format, setup, "--problem", problem,
                                           "--robot-unit", robot_unit, "--camera-unit", camera_unit,
                                           "-o", out_json, "--json"))
    assert code == 0, err
    r = json.loads(out)
    assert r == json.loads(out_json.read_text()) and f"wrote {out_json}" in err
    assert r["units"]["translation"] == robot_unit and r["problem"] == problem and r["setup"] == setup
    scale = 1e-3 if robot_unit == "m" else 1.0
    expected = TRUTH[(problem, setup)]
    assert set(expected) == {k for k in ("X", "Y") if k in r}
    for name, true_name in expected.items():
        T_true = np.array(truth[true_name])
        T_true[:3, 3] *= scale
        check_pose(r[name], T_true, 1e-6, 1e-6)
    # the camera's pose is published: X eye-in-hand, T_base_cam eye-to-hand (axyb Y, axxb X)
    published = "X" if setup == "eye-in-hand" or problem == "axxb" else "Y"
    n = ros_numbers(r["ros"]["command"])
    assert n["frame-id"] == ("flange" if setup == "eye-in-hand" else "base")
    T = np.array(r[published])
    assert np.allclose([float(n[k]) for k in "xyz"], T[:3, 3] * (1e-3 if robot_unit == "mm" else 1.0), atol=1e-8)
    if problem == "axxb":
        assert r["pairing"] == "all" and r["residuals"]["per"] == "motion" and r["residuals"]["count"] == 45


def test_noisy_answer_within_tolerance_and_uncertainty(tmp_path, capsys):
    """0.001 rad / 0.1 mm on both streams, 16 stations: X, Y within 0.3 deg and 2 mm (observed
    ~0.05 deg, ~0.3 mm) and within 5 of the reported 1-sigma (plus a floor)."""
    noise = NoiseModel({"A": (0.001, 0.1), "B": (0.001, 0.1)})
    robot, camera, truth = cell(tmp_path, stations=16, seed=5, noise=noise)
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand",
                                           "--camera-unit", "mm", "--json"))
    assert code == 0, err
    r = json.loads(out)
    for name in ("X", "Y"):
        T, T_true = np.array(r[name]), truth[name]
        rot = np.degrees(rotation_angle(T[:3, :3] @ T_true[:3, :3].T))
        trans = np.linalg.norm(T[:3, 3] - T_true[:3, 3])
        std = r["std"][name]
        assert rot < 0.3 and trans < 2.0
        assert std["rotation_deg"] > 0 and std["translation"] > 0
        assert rot < 5 * std["rotation_deg"] + 0.01 and trans < 5 * std["translation"] + 0.05
    assert 0 < r["residuals"]["rotation_deg"]["median"] < 1 and 0 < r["residuals"]["translation"]["rms"] < 5


def test_consecutive_pairing_and_frame_ids_and_overwrite(tmp_path, capsys):
    robot, camera, truth = cell(tmp_path)
    out_json = tmp_path / "r.json"
    out_json.write_text("old")
    argv = args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", "--camera-unit", "mm", "--problem", "axxb",
                "--pairing", "consecutive", "--frame-ids", "tool0,cam_optical", "-o", out_json)
    _bad(capsys, argv, "--force")  # an existing file is kept without --force
    assert out_json.read_text() == "old"
    code, out, err = run_cli(capsys, *argv, "--force")
    assert code == 0, err
    r = json.loads(out_json.read_text())
    assert r["pairing"] == "consecutive" and r["residuals"]["count"] == 9 and "Y" not in r
    check_pose(r["X"], truth["X"], 1e-6, 1e-6)
    n = ros_numbers(r["ros"]["command"])
    assert n["frame-id"] == "tool0" and n["child-frame-id"] == "cam_optical"
    assert f"wrote {out_json}" in out


def test_row_names_that_differ_are_a_warning(tmp_path, capsys):
    robot, camera, _ = cell(tmp_path)
    for path, prefix in ((robot, "p"), (camera, "img")):
        lines = path.read_text().splitlines()
        rows = [lines[1].replace("x,", "name,x,", 1) if lines[1].startswith("x") else "name," + lines[1]]
        rows += [f"{prefix}{i},{line}" for i, line in enumerate(lines[2:])]
        path.write_text("\n".join(rows) + "\n")
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand",
                                           "--camera-unit", "mm", "--json"))
    assert code == 0, err
    warnings = json.loads(out)["warnings"]
    assert any("row names differ" in w and "'p0' vs 'img0'" in w for w in warnings)


def _bad(capsys, argv, *words):
    code, out, err = run_cli(capsys, *argv)
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 or err.startswith("usage:"), err
    for w in words:
        assert w in err, err
    return err


def test_bad_input_exits_2_with_one_line(tmp_path, capsys):
    robot, camera, _ = cell(tmp_path)
    short = tmp_path / "short.csv"
    short.write_text("\n".join(robot.read_text().splitlines()[:7]) + "\n")  # comment, header, 5 poses
    ok = ["--camera-unit", "mm"]
    _bad(capsys, args(short, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok),
         "5 poses", "10", str(short), str(camera), "paired by row")
    _bad(capsys, args(robot, camera, "fanuc", "opencv-rvec", "eye-in-hand", *ok), "--robot-format", "unknown pose format")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand"), "--camera-unit")
    _bad(capsys, args(robot, camera, "matrix", "opencv-rvec", "eye-in-hand", *ok), "--robot-unit")
    _bad(capsys, args(tmp_path / "none.csv", camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok), "not found")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", "--camera-unit", "cm"))
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok, "--pairing", "all"), "axxb")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok, "-o", robot), "input")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok, "--frame-ids", "a"), "PARENT,CHILD")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "sideways", *ok))
    _bad(capsys, ["calibrate", "--robot", robot, "--robot-format", "fanuc-wpr", "--setup", "eye-in-hand"])
    assert not (tmp_path / "r.json").exists()


def test_help(capsys):
    code, out, _ = run_cli(capsys, "calibrate", "--help")
    assert code == 0 and "T_cam_target" in out and "--robot-unit" in out and "--force" in out


# ----------------------------------------------------------------------------- --match, --camera-poses

from pathlib import Path

from handeye.base.errors import InputError
from handeye.streams.station_matching import (
    default_max_dt,
    match_by_name,
    match_by_time,
)

ETH = Path(__file__).parents[3] / "shared" / "data" / "ethz_asl_handeye_2017" / "robot_arm"


def test_match_by_time_nearest_stamp_and_max_dt():
    robot = [0.0, 0.02, 0.04, 0.06, 0.08]
    camera = [-0.05, 0.011, 0.027, 0.0605, 0.2, 0.03]
    ri, ci, dt = match_by_time(robot, camera, 0.0085)
    assert ci.tolist() == [2, 3] and ri.tolist() == [1, 3]
    assert np.allclose(dt, [0.007, 0.0005])
    ri, ci, _ = match_by_time(robot, camera, 0.0105)  # 0.011 nearest to 0.02 (0.009), not 0.0 (0.011)
    assert ci.tolist() == [1, 2, 3, 5] and ri.tolist() == [1, 1, 3, 1]
    assert match_by_time([0.0, 1.0], [0.5], 1.0)[0].tolist() == [0]  # a tie: the earlier stamp
    ri, ci, _ = match_by_time([0.08, 0.0, 0.04], [0.079, 0.001], 0.005)  # unsorted robot stamps: file rows
    assert ri.tolist() == [0, 1] and ci.tolist() == [0, 1]
    assert default_max_dt(robot) == pytest.approx(0.01) and default_max_dt([1.0]) == 0.02
    with pytest.raises(InputError):
        match_by_time(robot, camera, -1.0)


def test_match_by_name_pairs_and_lists_unmatched():
    ri, ci = match_by_name(["a", "b", "c"], ["c", "a", "b"])
    assert ri.tolist() == [0, 1, 2] and ci.tolist() == [1, 2, 0]
    with pytest.raises(InputError, match=r"only in the robot file: 'c'; only in the camera file: 'd'"):
        match_by_name(["a", "b", "c"], ["b", "a", "d"])
    with pytest.raises(InputError, match="more than once"):
        match_by_name(["a", "a"], ["a", "b"])


def _named(path, names, stamps=None):
    """Prefix the rows of a write_poses CSV with a name (and time) column."""
    lines = path.read_text().splitlines()
    head = "name," + ("t," if stamps is not None else "") + lines[1]
    rows = [f"{n}," + (f"{stamps[i]!r}," if stamps is not None else "") + line
            for i, (n, line) in enumerate(zip(names, lines[2:]))]
    path.write_text("\n".join([head, *rows]) + "\n")


def test_match_name_and_time_on_shuffled_files(tmp_path, capsys):
    robot, camera, truth = cell(tmp_path, stations=10)
    lines = camera.read_text().splitlines()
    order = [3, 7, 0, 9, 1, 5, 2, 8, 6, 4]
    camera.write_text("\n".join(lines[:2] + [lines[2 + k] for k in order]) + "\n")
    _named(robot, [f"s{i}" for i in range(10)], [10.0 * i + 0.5 for i in range(10)])
    _named(camera, [f"s{k}" for k in order], [10.0 * k + 0.5 + 0.003 for k in order])
    ok = ["--camera-unit", "mm", "--json"]
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok,
                                           "--match", "name"))
    assert code == 0, err
    r = json.loads(out)
    assert r["matching"]["matched"] == 10 and "matched 10 stations by name" in err
    check_pose(r["X"], truth["X"], 1e-6, 1e-6)
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok,
                                           "--match", "time", "--max-dt", "0.01"))
    assert code == 0, err
    assert "matched 10 of 10 camera poses by time (max |dt| 3 ms" in err
    check_pose(json.loads(out)["X"], truth["X"], 1e-6, 1e-6)
    # row pairing of the shuffled files fails; name matching with a missing partner is exit 2
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok))
    assert code == 1
    text = camera.read_text().replace("s9,", "s99,")
    camera.write_text(text)
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok, "--match", "name"),
         "'s9'", "'s99'", "no partner")
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok, "--max-dt", "0.1"), "--match time")


def test_time_matching_refuses_two_robot_poses_at_one_stamp(tmp_path, capsys):
    """Two different robot poses at one time stamp: which was the station? Refused as interpolation
    refuses it (one line naming the file, the stamp and both rows), not the first one taken (Y was
    50 mm off). Stamps in milliseconds against the camera's seconds are named as such."""
    robot, camera, _ = cell(tmp_path, stations=10)
    stamps = [10.0 * i + 0.5 for i in range(10)]
    _named(camera, [f"s{i}" for i in range(10)], stamps)
    twice = list(stamps)
    twice[4] = twice[3]  # the fifth pose stamped as the fourth
    _named(robot, [f"s{i}" for i in range(10)], twice)
    ok = ["--camera-unit", "mm", "--match", "time", "--max-dt", "0.01"]
    _bad(capsys, args(robot, camera, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok),
         "time stamps carry two different poses", "rows 4 and 5", str(robot))
    (tmp_path / "ms").mkdir()
    robot2, camera2, _ = cell(tmp_path / "ms", stations=10)
    _named(camera2, [f"s{i}" for i in range(10)], stamps)
    _named(robot2, [f"s{i}" for i in range(10)], [1.7e12 + 1e4 * i for i in range(10)])
    _bad(capsys, args(robot2, camera2, "fanuc-wpr", "opencv-rvec", "eye-in-hand", *ok),
         "look like milli-, micro- or nanoseconds")


def test_camera_in_board_is_inverted(tmp_path, capsys):
    robot, camera, truth = cell(tmp_path, camera_format="xyz-quat-xyzw")
    from handeye.io.pose_readers import read_poses
    stack = read_poses(camera, "xyz-quat-xyzw", unit="mm")
    write_poses(camera, inverse(stack.poses), "xyz-quat-xyzw", unit="mm")
    code, out, err = run_cli(capsys, *args(robot, camera, "fanuc-wpr", "xyz-quat-xyzw", "eye-in-hand",
                                           "--camera-unit", "mm", "--camera-poses", "camera-in-board"))
    assert code == 0, err
    assert "T_target_cam inverted" in out
    X = np.array([[float(v) for v in line.split()] for line in out.split("X = T_flange_cam")[1].splitlines()[1:5]])
    check_pose(X, truth["X"], 1e-5, 1e-5)


@pytest.mark.skipif(not ETH.is_dir(), reason="ETH ASL hand-eye data set not present")
def test_eth_robot_arm_matched_by_time(tmp_path, capsys):
    """ETH ASL robot_arm (real, asynchronous 50 Hz robot / ~30 Hz camera, camera file T_target_cam):
    150 evenly spaced camera rows matched to the nearest robot stamp within 20 ms. The data set's
    README check: median residual 0.52 deg / 7.4 mm, |t_X| 0.017 m, |t_Y| 0.69 m (measured here:
    148 pairs, 0.46 deg / 7.4 mm, |t_X| 0.0170 m, |t_Y| 0.692 m)."""
    robot_src = ETH / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv"
    camera_src = ETH / "robot_arm_complete_bag_color_and_ir_target_ir.csv"
    rows = camera_src.read_text().splitlines()
    keep = np.linspace(0, len(rows) - 1, 150).round().astype(int)
    robot, camera = tmp_path / "robot.csv", tmp_path / "camera.csv"
    robot.write_text(robot_src.read_text())
    camera.write_text("\n".join(rows[k] for k in keep) + "\n")
    code, out, err = run_cli(capsys, "calibrate", "--robot", robot, "--robot-format", "xyz-quat-xyzw",
                             "--robot-unit", "m", "--camera", camera, "--camera-format", "xyz-quat-xyzw",
                             "--camera-unit", "m", "--camera-poses", "camera-in-board", "--setup", "eye-in-hand",
                             "--match", "time", "--max-dt", "0.02", "--json")
    assert code == 0, err  # a real cell, matched by time: an answer it stands behind
    r = json.loads(out)
    assert "camera poses by time" in err and 140 <= r["matching"]["matched"] <= 150 == r["matching"]["camera_poses"]
    assert r["matching"]["max_abs_dt"] <= 0.02 and r["stations"] == r["matching"]["matched"]
    assert 0.2 < r["residuals"]["rotation_deg"]["median"] < 1.0
    assert 0.003 < r["residuals"]["translation"]["median"] < 0.015
    # the data set's figures (|t_X| 0.017 m, |t_Y| 0.69 m), within what its 1-sigma allows (~3 mm)
    assert abs(np.linalg.norm(np.array(r["X"])[:3, 3]) - 0.017) < 0.004
    assert abs(np.linalg.norm(np.array(r["Y"])[:3, 3]) - 0.69) < 0.01


@pytest.mark.skipif(not ETH.is_dir(), reason="ETH ASL hand-eye data set not present")
@pytest.mark.parametrize("match", ["time", "interpolate"])
def test_robot_stamps_in_ms_against_camera_seconds_are_named(tmp_path, capsys, match):
    """The real ETH robot_arm streams with the robot's stamps in milliseconds (from the start of
    the recording) and the camera's in seconds: named as such, for matching by time and by
    interpolation (they were taken for a robot that hardly rotates, or stations that do not move)."""
    robot_src = ETH / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv"
    camera_src = ETH / "robot_arm_complete_bag_color_and_ir_target_ir.csv"

    def restamped(lines, factor):
        out, start = [], None
        for line in lines:
            parts = line.split(",")
            try:
                t = float(parts[0])
            except ValueError:
                out.append(line)
                continue
            start = t if start is None else start
            out.append(",".join([repr((t - start) * factor), *parts[1:]]))
        return "\n".join(out) + "\n"

    robot, camera = tmp_path / "robot.csv", tmp_path / "camera.csv"
    robot.write_text(restamped(robot_src.read_text().splitlines(), 1000.0))
    camera.write_text(restamped(camera_src.read_text().splitlines(), 1.0))
    _bad(capsys, ["calibrate", "--robot", robot, "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--camera",
                  camera, "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m", "--camera-poses",
                  "camera-in-board", "--setup", "eye-in-hand", "--match", match],
         "look like milliseconds", "give both in seconds")
