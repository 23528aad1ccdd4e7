"""handeye.streams: resampling, clock offset, motion selection, pairing; --match interpolate.

Simulated cell: an LR Mate 200iD-like arm (handeye.geometry.kinematics) moving its joints along smooth
sines, recorded at 100 Hz (robot, mm) and ~30 Hz (camera, T_cam_target, with a clock offset
t_robot = t_camera + offset), the paper's X and Y. Real data: the ETH ASL sets (skipped when
absent). Figures are in docs/streams.md.
"""

from __future__ import annotations

import glob
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from handeye import DegenerateDataError, InputError, solve
from handeye.cli import main
from handeye.framework.problem import pose_errors
from handeye.geometry.kinematics import LR_MATE_200ID, LR_MATE_SIM_JOINTS
from handeye.geometry.se3 import inverse, make_pose, rotation_angle, so3_exp
from handeye.io.pose_readers import PoseStack, read_poses
from handeye.io.pose_writers import write_poses
from handeye.problems.axyb import PAPER_X, PAPER_Y, PROBLEM
from handeye.streams import angular_speed, checked_stream, pair_streams, resample_poses

ETH = Path(__file__).parents[3] / "shared" / "data" / "ethz_asl_handeye_2017"
TRUTH = {"X": PAPER_X, "Y": PAPER_Y}
#: camera pose noise of the noisy cases: 0.1 deg per axis, 0.5 mm per axis
NOISE = (math.radians(0.1), 0.5)


def joints(t: np.ndarray, static: tuple[tuple[float, float], ...] = ()) -> np.ndarray:
    """Joint angles (n, 6) of a smooth motion inside the simulator's box; frozen during each
    (start, end) of `static` (and resuming where it stopped)."""
    lo, hi = LR_MATE_SIM_JOINTS[:, 0], LR_MATE_SIM_JOINTS[:, 1]
    s = np.array(t, dtype=float)
    for a, b in sorted(static, reverse=True):
        s = np.where((s > a) & (s < b), a, np.where(s >= b, s - (b - a), s))
    f = 0.5 * np.array([0.07, 0.11, 0.13, 0.17, 0.19, 0.23])  # Hz
    phase = np.array([0.3, 1.1, 2.0, 0.7, 2.5, 1.7])
    return (lo + hi) / 2 + 0.3 * (hi - lo) * np.sin(2 * np.pi * f * s[:, None] + phase)


def cell(offset: float, noise: tuple[float, float] = (0.0, 0.0), *, seconds: float = 20.0, seed: int = 0,
         static=(), setup: str = "eye-in-hand", camera_hz: float = 30.0, t0: float = 1.7e9):
    """(robot stream, camera stream): robot T_base_flange at 100 Hz, camera T_cam_target at
    `camera_hz` stamped on its own clock, t_robot = t_camera + offset."""
    rng = np.random.default_rng(seed)
    tr = np.arange(0.0, seconds, 0.01)
    tau = np.arange(0.5, seconds - 0.5, 1.0 / camera_hz)  # true (robot-clock) times of the images
    A = LR_MATE_200ID.forward(joints(tau, static))
    # B = Y^-1 A X: eye-in-hand T_target_cam (the camera stream holds its inverse), eye-to-hand
    # T_cam_target (X = T_flange_target, Y = T_base_cam; the stream holds B)
    B = inverse(PAPER_Y) @ A @ PAPER_X
    if noise[0]:
        B = B @ make_pose(so3_exp(rng.normal(0, noise[0], (len(tau), 3))), rng.normal(0, noise[1], (len(tau), 3)))
    cam = inverse(B) if setup == "eye-in-hand" else B
    robot = PoseStack(LR_MATE_200ID.forward(joints(tr, static)), "mm", "matrix", stamps=t0 + tr)
    camera = PoseStack(cam, "mm", "matrix", stamps=t0 + tau - offset)
    return robot, camera


def solved_errors(pairs, setup="eye-in-hand"):
    sol = solve("axyb", solver="kron-lstsq", **pairs.data("axyb", setup=setup))
    return pose_errors(sol.unknowns, TRUTH, ("X", "Y"))


# ----------------------------------------------------------------------------- resampling


def screw(t: np.ndarray) -> np.ndarray:
    """Constant angular and linear velocity: SLERP + linear interpolation reproduce it exactly."""
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    return make_pose(so3_exp(0.8 * t[:, None] * axis), np.stack([3 * t, -t, 0.5 * t + 2], axis=1))


def test_resample_is_exact_for_constant_velocity_and_never_extrapolates():
    s = np.array([0.0, 0.1, 0.2, 0.3, 1.0, 1.1])  # a 0.7 s dropout
    times = np.array([-0.05, 0.05, 0.2, 0.25, 0.6, 1.05, 1.2])
    res = resample_poses(s, screw(s), times, max_gap=0.3)
    assert res.kept.tolist() == [1, 2, 3, 5]
    assert (res.outside, res.gaps) == (2, 1)
    np.testing.assert_allclose(res.poses, screw(times[res.kept]), atol=1e-12)


def test_angular_speed_is_the_same_in_any_frame_and_inverted():
    s = np.arange(0.0, 2.0, 0.01)
    T = screw(s)
    times = np.array([0.5, 1.0, 1.5])
    w = angular_speed(s, T, times, 0.05, 0.03)
    np.testing.assert_allclose(w, 0.8, rtol=1e-9)
    other = inverse(PAPER_Y) @ T @ PAPER_X
    np.testing.assert_allclose(angular_speed(s, inverse(other), times, 0.05, 0.03), 0.8, rtol=1e-9)
    assert np.isnan(angular_speed(s, T, np.array([0.01]), 0.05, 0.03)).all()  # would extrapolate


def test_stamps_are_sorted_and_repeated_copies_dropped_but_clashes_refused():
    s = np.array([0.0, 0.2, 0.1, 0.3, 0.3])
    T = screw(np.array([0.0, 0.2, 0.1, 0.3, 0.3]))
    stack, rows, warnings = checked_stream(PoseStack(T, "m", "matrix", stamps=s), "robot")
    assert stack.stamps.tolist() == [0.0, 0.1, 0.2, 0.3]
    assert rows.tolist() == [0, 2, 1, 3]
    assert any("sorted" in w for w in warnings) and any("twice" in w for w in warnings)
    clash = screw(np.array([0.0, 0.1, 0.2, 0.3, 0.4]))
    with pytest.raises(InputError, match="carry two different poses"):
        checked_stream(PoseStack(clash, "m", "matrix", stamps=np.array([0, 0.1, 0.1, 0.2, 0.2])), "robot")
    with pytest.raises(InputError, match="no time stamps"):
        checked_stream(PoseStack(clash, "m", "matrix"), "robot")
    with pytest.raises(InputError, match="look like milli-, micro- or nanoseconds"):
        checked_stream(PoseStack(clash, "m", "matrix", stamps=1.7e18 + 1e7 * np.arange(5)), "robot")


# ----------------------------------------------------------------------------- the simulated cell


def test_no_offset_noise_free_is_recovered_to_a_microsecond():
    pairs = pair_streams(*cell(0.0), setup="eye-in-hand")
    assert abs(pairs.offset) < 1e-6
    assert pairs.reliable and pairs.warnings == ()
    err = solved_errors(pairs)
    # what is left is SLERP's error on a curved 100 Hz trajectory
    assert err["X"]["rotation"] < 1e-5 and err["X"]["translation"] < 5e-3
    assert err["Y"]["rotation"] < 1e-5 and err["Y"]["translation"] < 5e-3


@pytest.mark.parametrize("offset", [0.037, -0.037])
def test_offset_of_37_ms_is_recovered_within_2_ms_with_noise(offset):
    pairs = pair_streams(*cell(offset, NOISE, seed=3), setup="eye-in-hand")
    e = pairs.estimate
    assert abs(pairs.offset - offset) < 2e-3
    assert abs(e.coarse - offset) < 5e-3  # the cross-correlation alone
    assert 1e-6 < e.std < 1e-3 and abs(pairs.offset - offset) < 5 * e.std
    assert pairs.counts == {"camera_samples": 570, "outside": 0, "gaps": 0, "static": 0, "not_selected": 270,
                            "kept": 300}
    err = solved_errors(pairs)
    assert err["X"]["rotation"] < math.radians(0.05) and err["X"]["translation"] < 0.5  # mm
    assert err["Y"]["rotation"] < math.radians(0.05) and err["Y"]["translation"] < 2.0


def test_static_periods_are_dropped_and_the_offset_still_found():
    static = ((4.0, 8.0), (12.0, 15.0))  # 7 s of 19 without motion
    pairs = pair_streams(*cell(0.037, NOISE, seed=4, static=static, seconds=26.0), setup="eye-in-hand")
    # 7 s at 30 Hz = 210 images; the speed is a central difference over +-0.05 s, so the ends of
    # each stop (and the slow turn-arounds of the sines) shift the count by a few samples
    assert 190 <= pairs.counts["static"] <= 240
    assert abs(pairs.offset - 0.037) < 2e-3
    assert solved_errors(pairs)["X"]["rotation"] < math.radians(0.05)


def test_eye_to_hand_and_max_pairs():
    pairs = pair_streams(*cell(-0.02, setup="eye-to-hand"), setup="eye-to-hand", max_pairs=60)
    assert len(pairs) == 60 and pairs.counts["kept"] == 60
    assert abs(pairs.offset + 0.02) < 1e-5
    assert solved_errors(pairs, "eye-to-hand")["X"]["rotation"] < 1e-4


def test_given_offset_is_used_as_is_and_units_scale():
    robot, camera = cell(0.037)
    given = pair_streams(robot, camera, setup="eye-in-hand", time_offset=0.037)
    assert given.estimate is None and given.offset == 0.037
    true = LR_MATE_200ID.forward(joints(given.camera_stamps + 0.037 - 1.7e9))
    # SLERP between 100 Hz samples of this curved motion is off by at most ~5e-5 rad
    assert np.max(rotation_angle(given.robot_poses[:, :3, :3] @ np.swapaxes(true[:, :3, :3], 1, 2))) < 1e-4
    metres = pair_streams(robot.in_unit("m"), camera.in_unit("m"), setup="eye-in-hand")
    mm = pair_streams(robot, camera.in_unit("m"), setup="eye-in-hand")  # camera converted to the robot's mm
    assert abs(metres.offset - mm.offset) < 1e-7
    np.testing.assert_allclose(metres.robot_poses[:, :3, 3] * 1e3, mm.robot_poses[:, :3, 3], atol=1e-6)
    np.testing.assert_allclose(mm.camera_poses, pair_streams(robot, camera, setup="eye-in-hand").camera_poses,
                               atol=1e-9)


# ----------------------------------------------------------------------------- edge cases


def test_streams_that_do_not_overlap_are_refused():
    robot, camera = cell(0.0)
    late = PoseStack(camera.poses, "mm", "matrix", stamps=np.asarray(camera.stamps) + 100.0)
    with pytest.raises(InputError, match="do not overlap in time"):
        pair_streams(robot, late, setup="eye-in-hand")
    with pytest.raises(InputError, match="do not overlap in time"):
        pair_streams(robot, late, setup="eye-in-hand", time_offset=0.0)


def test_an_offset_beyond_the_search_range_is_said_not_returned():
    with pytest.raises(InputError, match="edge of the offset search range.*widen --max-offset"):
        pair_streams(*cell(0.3, seed=1), setup="eye-in-hand", max_offset=0.1)


def test_a_robot_that_hardly_moves_is_refused():
    robot, camera = cell(0.0, static=((0.0, 100.0),))
    with pytest.raises(DegenerateDataError, match="hardly rotates"):
        pair_streams(robot, camera, setup="eye-in-hand")
    with pytest.raises(DegenerateDataError, match="too little motion"):
        pair_streams(robot, camera, setup="eye-in-hand", time_offset=0.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"time_offset": "soon"}, "'auto' or a number"), ({"max_offset": -1.0}, "--max-offset must be"),
    ({"max_gap": float("nan")}, "--max-gap must be"), ({"max_pairs": 3}, "--max-pairs must be"),
    ({"setup": "eye-on-hand"}, "setup must be"), ({"camera_poses": "camera"}, "camera_poses must be"),
])
def test_bad_arguments_get_one_line_messages(kwargs, message):
    robot, camera = cell(0.0, seconds=3.0)
    args = {"setup": "eye-in-hand", **kwargs}
    with pytest.raises(InputError, match=message) as info:
        pair_streams(robot, camera, **args)
    assert "\n" not in str(info.value)


# ----------------------------------------------------------------------------- the command


def test_calibrate_match_interpolate_end_to_end(tmp_path, capsys):
    robot, camera = cell(-0.037, NOISE, seed=5)
    write_poses(tmp_path / "robot.csv", robot.in_unit("m"), "xyz-quat-xyzw")
    cam = camera.in_unit("m")  # T_target_cam with stamps, as the ETH files
    write_poses(tmp_path / "camera.csv", PoseStack(inverse(cam.poses), "m", "matrix", stamps=cam.stamps),
                "xyz-quat-xyzw")
    out = tmp_path / "result.json"
    argv = ["calibrate", "--robot", tmp_path / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m",
            "--camera", tmp_path / "camera.csv", "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand", "--match", "interpolate", "-o", out]
    code = main([str(a) for a in argv])
    text = capsys.readouterr().out
    assert code == 0, text
    shown = re.search(r"time offset ([+-][0-9.]+) \+- ([0-9.e-]+) ms", text)
    assert shown and abs(float(shown[1]) + 37.0) < 2.0 and "kept 300 well-spread stations" in text
    result = json.loads(out.read_text())
    m = result["matching"]
    assert m["method"] == "interpolate" and abs(m["time_offset"] + 0.037) < 2e-3 and m["time_offset_std"] > 0
    assert result["stations"] == 300
    X = np.array(result["X"])
    assert rotation_angle(X[:3, :3] @ PAPER_X[:3, :3].T) < math.radians(0.05)
    assert np.linalg.norm(X[:3, 3] * 1e3 - PAPER_X[:3, 3]) < 0.5
    code = main([str(a) for a in argv[:-2]] + ["--time-offset", "later"])
    assert code == 2 and "--time-offset must be 'auto' or a number" in capsys.readouterr().err
    code = main([str(a) for a in argv[:-4]] + ["--match", "time", "--max-gap", "0.1"])
    assert code == 2 and "--max-gap apply to --match interpolate" in capsys.readouterr().err


# ----------------------------------------------------------------------------- real data (ETH ASL)


def _eth(name: str, robot_glob: str, camera_glob: str):
    robot_file, camera_file = (glob.glob(str(ETH / name / g)) for g in (robot_glob, camera_glob))
    if not (robot_file and camera_file):
        pytest.skip(f"ETH ASL data not found in {ETH / name}")
    return (read_poses(robot_file[0], "xyz-quat-xyzw", unit="m"), read_poses(camera_file[0], "xyz-quat-xyzw", unit="m"))


def _median_residuals(pairs):
    data = pairs.data("axyb", setup="eye-in-hand")
    sol = solve("axyb", solver="kron-lstsq", **data)
    r = PROBLEM.residuals(PROBLEM.validate(**data), sol.unknowns)
    return math.degrees(float(np.median(r["rotation"]))), 1e3 * float(np.median(r["translation"]))


@pytest.mark.parametrize("name, robot_glob, camera_glob, low, high, rot_max", [
    ("robot_arm", "*sr300_hinge.csv", "*target_ir.csv", -0.026, -0.014, 0.45),
    ("prime_sense_1", "*vicon_prime_sense.csv", "*W_camera_rgb_image_raw.csv", 0.010, 0.030, 1.2),
    ("prime_sense_2", "*vicon_prime_sense.csv", "*W_camera_rgb_image_raw.csv", 0.014, 0.034, 1.1),
])
def test_eth_asl_offsets(name, robot_glob, camera_glob, low, high, rot_max):
    robot, camera = _eth(name, robot_glob, camera_glob)
    pairs = pair_streams(robot, camera, setup="eye-in-hand", camera_poses="camera-in-board")
    assert low < pairs.offset < high and pairs.reliable
    assert pairs.estimate.std < 0.005
    rot, _ = _median_residuals(pairs)
    assert rot < rot_max


@pytest.mark.parametrize("offset", [0.0123, -0.0071, 0.037])
def test_the_cross_correlation_peak_is_refined_between_its_lags(offset):
    """The coarse offset lies between the lags of the cross-correlation (a grid of half the
    camera interval, ~17 ms here); the parabola through the peak and its neighbours places it to
    a microsecond on noise-free streams (measured 0.6-0.7 us), where the peak lag alone is off by
    up to half a step (a parabolic step of the wrong sign: twice that)."""
    robot, camera = cell(offset)
    pairs = pair_streams(robot, camera, setup="eye-in-hand")
    assert abs(pairs.estimate.coarse - offset) < 1e-5
