"""The corner fit with the robot's own pose errors (``reprojection``'s default, plugins/
reprojection/robot_noise.py) and the held-out comparison that picks the answer for images
(plugins/reprojection/held_out.py), on simulated board images with known truth."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel

PROBLEM = handeye.get_registry().problem("axyb")
#: robot pose noise per axis (rad, mm, flange frame): ~3x the 0.3 px corners' effect at 350-750 mm
ROBOT = (0.0005, 0.3)


def cell(setup: str, seed: int, robot=ROBOT, pairs: int = 20):
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    data, _ = PROBLEM.simulate(pairs=pairs, seed=seed, noise=NoiseModel({"A": robot, "B": (1.0, 1.0)}),
                               images={"setup": setup, "pixel_noise": 0.3}, **truth)
    return data, truth


def errors(sol, truth) -> np.ndarray:
    e = PROBLEM.errors(sol.unknowns, truth)
    return np.array([e["X"]["rotation"], e["X"]["translation"], e["Y"]["rotation"], e["Y"]["translation"]])


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_robot_and_pixel_noise_are_found_and_the_answer_beats_the_exact_robot_fit(setup):
    """4 seeds: the pixel noise found within 5% (0.3 px), the robot's within 35% (measured 0.38-0.65
    of 0.5 mrad, 0.22-0.37 of 0.3 mm); the answer is the fit started at the truth (the same
    minimum) and its errors, summed, at most 0.7x those of the fit with exact robot poses
    (measured 0.2-0.6x, bench/robot_noise_images.py)."""
    joint_sum, exact_sum = np.zeros(4), np.zeros(4)
    for seed in range(4):
        data, truth = cell(setup, seed)
        sol = handeye.solve("axyb", solver="reprojection", **data)
        floor = handeye.solve("axyb", solver="reprojection", init_X=truth["X"], init_Y=truth["Y"], **data)
        exact = handeye.solve("axyb", solver="reprojection", robot_noise="none", **data)
        assert sol.status is handeye.Status.OPTIMAL and not sol.warnings
        robot = sol.diagnostics["robot_noise"]
        assert sol.diagnostics["noise_model"] == "reprojection with robot noise"
        assert sol.diagnostics["sigma_px"] == pytest.approx(0.3, rel=0.05)
        assert robot["rotation"] == pytest.approx(ROBOT[0], rel=0.35) and robot["translation"] == pytest.approx(ROBOT[1], rel=0.35)
        for name in ("X", "Y"):
            np.testing.assert_allclose(sol.unknowns[name], floor.unknowns[name], atol=1e-6)
        joint_sum += errors(sol, truth)
        exact_sum += errors(exact, truth)
    assert np.all(joint_sum < 0.7 * exact_sum), joint_sum / exact_sum


def test_it_beats_the_pose_based_answer_eye_in_hand():
    """Eye in hand, 8 seeds: RMS errors below auto's on the PnP poses in every one of X's and Y's
    rotation and translation (measured 0.56-0.82x over 10 seeds)."""
    joint, auto = [], []
    for seed in range(8):
        data, truth = cell("eye-in-hand", seed)
        joint.append(errors(handeye.solve("axyb", solver="reprojection", **data), truth))
        auto.append(errors(handeye.solve("axyb", A=data["A"], B=data["B"]), truth))
    ratio = np.sqrt(np.mean(np.square(joint), axis=0) / np.mean(np.square(auto), axis=0))
    assert np.all(ratio < 0.95), ratio


def test_exact_robot_poses_give_the_exact_robot_fit():
    """No robot noise: its standard deviations fall to their floor within a few rounds and the
    answer is the fit with exact robot poses to 1e-6 of its 1-sigma."""
    data, truth = cell("eye-in-hand", 3, robot=(0.0, 0.0))
    sol = handeye.solve("axyb", solver="reprojection", **data)
    exact = handeye.solve("axyb", solver="reprojection", robot_noise="none", **data)
    robot = sol.diagnostics["robot_noise"]
    assert robot["rounds"] <= 5 and robot["rotation"] < 1e-6 and robot["translation"] < 1e-3
    gaps = PROBLEM.errors(sol.unknowns, exact.unknowns)
    for name, d in gaps.items():
        std = sol.diagnostics["std"][name]
        assert d["rotation"] < 1e-3 * std["rotation"] and d["translation"] < 1e-3 * std["translation"]


def test_exact_corners_and_robot_are_recovered():
    truth = PROBLEM.random_unknowns(np.random.default_rng(5))
    clean, _ = PROBLEM.simulate(pairs=10, seed=5, images={"setup": "eye-to-hand"}, **truth)
    sol = handeye.solve("axyb", solver="reprojection", **clean)
    for e in PROBLEM.errors(sol.unknowns, truth).values():
        assert e["rotation"] < 1e-10 and e["translation"] < 1e-8


def test_the_held_out_comparison_picks_the_answer():
    """held_out=3: every contender's held-out corner RMS is reported, the answer is the better
    corner fit (exactly the one fitted alone), and pose_based_better compares it with auto's."""
    data, truth = cell("eye-in-hand", 1)
    sol = handeye.solve("axyb", solver="reprojection", held_out=3, **data)
    held = sol.diagnostics["held_out"]
    assert held["folds"] == 3 and {"joint_px", "exact_robot_px", "pose_based_px"} <= set(held)
    corner = {"joint": held["joint_px"], "exact_robot": held["exact_robot_px"]}
    assert held["chosen"] == min(corner, key=corner.get)
    assert 0.5 < held["reprojection_px"] < 5.0  # the held-out robot poses' own error: ~1-2 px
    assert held["pose_based_better"] == (held["pose_based_px"] < held["reprojection_px"])
    alone = handeye.solve("axyb", solver="reprojection", robot_noise="estimated" if held["chosen"] == "joint" else "none",
                          **data)
    np.testing.assert_array_equal(sol.X, alone.X)


@pytest.mark.parametrize("options, message", [
    ({"held_out": 1}, "held_out must be 0"),
    ({"held_out": 11}, "held_out=11 needs at least 22 stations"),
    ({"robot_noise": "estimated", "loss": "cauchy"}, "robot_noise='estimated' fits the pixels by least squares"),
    ({"robot_noise": "sometimes"}, "robot_noise"),
])
def test_bad_options_are_refused_in_one_line(options, message):
    data, _ = cell("eye-in-hand", 2)
    with pytest.raises(InputError, match=message) as caught:
        handeye.solve("axyb", solver="reprojection", **data, **options)
    assert "\n" not in str(caught.value)
