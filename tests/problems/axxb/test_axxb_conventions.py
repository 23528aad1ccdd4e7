"""docs/conventions.md for problem axxb, checked on noise-free cells built from named frames: what
A, B and X are for an eye-in-hand and an eye-to-hand cell, and how OpenCV's
``cv2.calibrateHandEye`` arguments map to them (it forms every pair i < j itself)."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import inverse
from handeye.io.data_files import from_poses
from handeye.problems.axxb import PROBLEM as AXXB

STATIONS = 7


def solver() -> str:
    names = handeye.list_solvers("axxb")
    return "kron-lstsq" if "kron-lstsq" in names else names[0]


@pytest.fixture(scope="module")
def cells() -> dict[str, dict[str, np.ndarray]]:
    """Per setup: robot poses T_base_flange, camera poses T_cam_target (as solvePnP gives them)
    and the X that docs/conventions.md names."""
    rng = np.random.default_rng(11)
    T_base_flange = random_flange_poses(STATIONS, rng)
    a, b = (AXXB.random_unknowns(rng, 300.0)["X"] for _ in range(2))
    # eye-in-hand: camera on the flange at T_flange_cam = a, board fixed at T_base_target = b
    T_cam_target_hand = inverse(T_base_flange @ a) @ b
    # eye-to-hand: camera fixed at T_base_cam = a, board on the flange at T_flange_target = b
    T_cam_target_fixed = inverse(a) @ T_base_flange @ b
    return {"eye-in-hand": {"robot": T_base_flange, "camera": T_cam_target_hand, "X": a},
            "eye-to-hand": {"robot": T_base_flange, "camera": T_cam_target_fixed, "X": a}}


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
@pytest.mark.parametrize("pairing", ["consecutive", "all"])
def test_motions_and_x_for_both_setups(cells, setup, pairing):
    """A_i X = X B_i with X = T_flange_cam (eye-in-hand) or T_base_cam (eye-to-hand)."""
    cell = cells[setup]
    data = from_poses(cell["robot"], cell["camera"], "axxb", setup=setup, pairing=pairing).data
    X = cell["X"]
    assert len(data["A"]) == (STATIONS - 1 if pairing == "consecutive" else STATIONS * (STATIONS - 1) // 2)
    assert np.abs(data["A"] @ X - X @ data["B"]).max() < 1e-9
    sol = handeye.solve("axxb", solver=solver(), **data)
    np.testing.assert_allclose(sol.X, X, atol=1e-7)


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_opencv_calibrate_hand_eye_argument_mapping(cells, setup):
    """eye-in-hand: gripper2base = robot poses, target2cam = camera poses -> cam2gripper = X;
    eye-to-hand: gripper2base slots get the inverted robot poses (base2gripper) -> cam2base = X."""
    cv2 = pytest.importorskip("cv2")
    if not hasattr(cv2, "calibrateHandEye"):
        pytest.skip("this OpenCV has no calibrateHandEye")
    cell = cells[setup]
    robot = cell["robot"] if setup == "eye-in-hand" else inverse(cell["robot"])
    R, t = cv2.calibrateHandEye(list(robot[:, :3, :3]), list(robot[:, :3, 3:]),
                                list(cell["camera"][:, :3, :3]), list(cell["camera"][:, :3, 3:]),
                                method=cv2.CALIB_HAND_EYE_PARK)
    np.testing.assert_allclose(R, cell["X"][:3, :3], atol=1e-8)
    np.testing.assert_allclose(np.ravel(t), cell["X"][:3, 3], atol=1e-5)
