"""The AX=XB problem module: its linear system, translation least squares, motions from absolute
poses (against OpenCV's calibrateHandEye in both setups), validation, diagnostics, simulator."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.problems.axxb import (
    MISMATCH_ANGLE_FLOOR,
    PROBLEM,
    motions,
    normal_equations,
    regression_blocks,
    relative_motions,
    simulate_stations,
    solve_translation,
)


def _beta(X: np.ndarray) -> np.ndarray:
    """[vec(R_X); t_X], vec column-major."""
    return np.concatenate([X[:3, :3].T.ravel(), X[:3, 3]])


@pytest.fixture(scope="module")
def exact():
    truth = PROBLEM.random_unknowns(np.random.default_rng(7))
    data, truth = PROBLEM.simulate(pairs=10, seed=7, pairing="consecutive", **truth)
    return PROBLEM.validate(**data), truth


@pytest.fixture(scope="module")
def noisy():
    data, truth = PROBLEM.simulate(pairs=26, seed=8, noise=NoiseModel.on(("A", "B"), 0.01, 1.0), pairing="consecutive")
    return PROBLEM.validate(**data), truth


def test_true_beta_solves_the_linear_system(exact):
    data, truth = exact
    H, w = regression_blocks(data.A, data.B)
    assert H.shape == (9, 12, 12) and w.shape == (9, 12)
    assert np.max(np.abs(H @ _beta(truth["X"]) - w)) < 1e-12 * data.translation_scale
    assert np.max(np.abs(H @ _beta(inverse(truth["X"])) - w)) > 1e-3


def test_rows_by_hand(exact):
    """Motion 0 written out: R_A R_X R_B^T - R_X = 0 and R_X t_B + (I - R_A) t_X - t_A = 0."""
    data, _ = exact
    H, w = regression_blocks(data.A[:1], data.B[:1])
    M = np.random.default_rng(1).standard_normal((3, 4))  # any matrix: the rows are linear in it
    RA, tA, RB, tB = data.A[0, :3, :3], data.A[0, :3, 3], data.B[0, :3, :3], data.B[0, :3, 3]
    r = H[0] @ np.concatenate([M[:, :3].T.ravel(), M[:, 3]]) - w[0]
    np.testing.assert_allclose(r[:9], (RA @ M[:, :3] @ RB.T - M[:, :3]).T.ravel(), atol=1e-12)
    np.testing.assert_allclose(r[9:], M[:, :3] @ tB + (np.eye(3) - RA) @ M[:, 3] - tA, atol=1e-9)


@pytest.mark.parametrize("scale", [1.0, 1e-3, 250.0])
def test_normal_equations_equal_the_explicit_blocks(noisy, scale):
    data, _ = noisy
    N, g, ww = normal_equations(data, scale)
    H, w = regression_blocks(*(data.scaled(scale).A, data.scaled(scale).B))
    H, w = H.reshape(-1, 12), w.reshape(-1)
    np.testing.assert_allclose(N, H.T @ H, rtol=0, atol=1e-12 * np.abs(N).max())
    np.testing.assert_allclose(g, H.T @ w, rtol=0, atol=1e-12 * np.abs(g).max())
    assert ww == pytest.approx(w @ w, rel=1e-12)


def test_least_squares_and_translation_exact_on_noise_free_data(exact):
    data, truth = exact
    beta = data.kronecker_system.least_squares()
    np.testing.assert_allclose(beta, _beta(truth["X"]), rtol=0, atol=1e-9 * data.translation_scale)
    t = solve_translation(data, truth["X"][:3, :3])
    np.testing.assert_allclose(t, truth["X"][:3, 3], rtol=0, atol=1e-9 * data.translation_scale)


def test_translation_is_least_squares(noisy):
    data, truth = noisy
    RX = truth["X"][:3, :3]
    D = np.eye(3) - data.A[:, :3, :3]
    rhs = data.A[:, :3, 3] - data.B[:, :3, 3] @ RX.T
    expected, *_ = np.linalg.lstsq(D.reshape(-1, 3), rhs.reshape(-1), rcond=None)
    np.testing.assert_allclose(solve_translation(data, RX), expected, rtol=1e-10)


def test_residuals_zero_at_truth_and_positive_elsewhere(exact):
    data, truth = exact
    res = PROBLEM.residuals(data, truth)
    assert res["rotation"].shape == res["translation"].shape == (9,)
    assert res["rotation"].max() < 1e-12 and res["translation"].max() < 1e-10
    off = PROBLEM.residuals(data, {"X": truth["X"] @ make_pose(so3_exp([0.01, 0, 0]), [1, 0, 0])})
    assert off["rotation"].min() > 0 and off["translation"].max() > 0.1


def test_errors_against_truth(exact):
    _, truth = exact
    moved = {"X": truth["X"] @ make_pose(so3_exp([0, 0.02, 0]), [0, 0, 0])}
    moved["X"] = moved["X"].copy()
    moved["X"][:3, 3] += [3.0, 4.0, 0.0]
    errors = PROBLEM.errors(moved, truth)
    assert errors["X"]["rotation"] == pytest.approx(0.02, rel=1e-9)
    assert errors["X"]["translation"] == pytest.approx(5.0, rel=1e-12)


# ------------------------------------------------------------------ absolute poses and OpenCV

def _stations(n: int = 7, seed: int = 3):
    """Absolute poses of an eye-in-hand cell: robot T_base_flange, board T_cam_target, truth."""
    rng = np.random.default_rng(seed)
    stations, truth = simulate_stations(n, seed=seed, X=PROBLEM.random_unknowns(rng)["X"])
    return stations["A"], inverse(stations["B"]), truth


def _cv2_hand_eye(gripper2base: np.ndarray, target2cam: np.ndarray, method: str) -> np.ndarray:
    cv2 = pytest.importorskip("cv2")
    if not hasattr(cv2, "calibrateHandEye"):
        pytest.skip("this OpenCV has no calibrateHandEye")
    R, t = cv2.calibrateHandEye([T[:3, :3] for T in gripper2base], [T[:3, 3] for T in gripper2base],
                                [T[:3, :3] for T in target2cam], [T[:3, 3] for T in target2cam],
                                method=getattr(cv2, f"CALIB_HAND_EYE_{method}"))
    return make_pose(R, t.ravel())


@pytest.mark.parametrize("pairing", ["consecutive", "all"])
def test_motions_eye_in_hand_agree_with_opencv(pairing):
    robot, camera, truth = _stations()
    data = motions(robot, camera, "eye-in-hand", pairing)
    n = len(robot)
    assert len(data["A"]) == (n - 1 if pairing == "consecutive" else n * (n - 1) // 2)
    X_cv = _cv2_hand_eye(robot, camera, "PARK")  # cam2gripper
    np.testing.assert_allclose(X_cv, truth["X"], atol=1e-9 * np.abs(truth["X"]).max())
    res = PROBLEM.residuals(PROBLEM.validate(**data), {"X": X_cv})
    assert res["rotation"].max() < 1e-12 and res["translation"].max() < 1e-9


def test_motions_eye_to_hand_agree_with_opencv():
    """Camera fixed (T_base_cam), board on the flange (T_flange_target): OpenCV is given
    base2gripper poses and returns cam2base; our X for eye-to-hand is that T_base_cam."""
    rng = np.random.default_rng(11)
    robot, _, _ = _stations(8, seed=11)
    base_cam, flange_target = (PROBLEM.random_unknowns(rng)["X"] for _ in range(2))
    camera = inverse(base_cam) @ robot @ flange_target  # T_cam_target
    data = motions(robot, camera, "eye-to-hand")
    X_cv = _cv2_hand_eye(inverse(robot), camera, "TSAI")
    np.testing.assert_allclose(X_cv, base_cam, atol=1e-9 * np.abs(base_cam).max())
    res = PROBLEM.residuals(PROBLEM.validate(**data), {"X": base_cam})
    assert res["rotation"].max() < 1e-12 and res["translation"].max() < 1e-9
    # the eye-in-hand mapping of the same poses does not fit this X
    wrong = PROBLEM.residuals(PROBLEM.validate(**motions(robot, camera, "eye-in-hand")), {"X": base_cam})
    assert wrong["translation"].max() > 1.0


def test_relative_motions_order_is_opencvs():
    robot, camera, _ = _stations(4)
    A, B = relative_motions(robot, inverse(camera), "all")
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    for k, (i, j) in enumerate(pairs):
        np.testing.assert_allclose(A[k], inverse(robot[j]) @ robot[i], atol=1e-12)
        np.testing.assert_allclose(B[k], camera[j] @ inverse(camera[i]), atol=1e-9)


def test_motions_bad_input_one_line_errors():
    robot, camera, _ = _stations(5)
    with pytest.raises(handeye.InputError, match="setup='eye-on-hand' is not one of eye-in-hand, eye-to-hand"):
        motions(robot, camera, "eye-on-hand")
    with pytest.raises(handeye.InputError, match="pairing='pairs' is not one of consecutive, all"):
        motions(robot, camera, pairing="pairs")
    with pytest.raises(handeye.InputError, match="same length"):
        motions(robot, camera[:-1])
    with pytest.raises(handeye.InputError, match="camera_poses.*NaN"):
        bad = camera.copy()
        bad[0, 0, 0] = np.nan
        motions(robot, bad)


# ------------------------------------------------------------------ validation and diagnostics

def test_validation_errors_one_line_each(noisy):
    data, _ = noisy
    A, B = np.array(data.A), np.array(data.B)
    A_before, B_before = A.copy(), B.copy()
    cases = [
        ({"A": A[:, :3], "B": B}, handeye.InputError, r"expected A to have shape \(m, 4, 4\)"),
        ({"A": A, "B": B[:-1]}, handeye.InputError, "same length"),
        ({"A": A[:1], "B": B[:1]}, handeye.DegenerateDataError, "at least 2"),
        ({"A": A, "B": B * np.array([1, 1, 2, 1])[None, :, None]}, handeye.InputError, "not orthonormal"),
        ({"A": A}, handeye.InputError, "missing"),
        ({"A": A, "B": B, "C": B}, handeye.InputError, "not"),
    ]
    nan = A.copy()
    nan[3, 1, 1] = np.inf
    cases.append(({"A": nan, "B": B}, handeye.InputError, "NaN or inf in pose"))
    for kwargs, error, message in cases:
        with pytest.raises(error, match=message) as info:
            PROBLEM.validate(**kwargs)
        assert "\n" not in str(info.value)
    np.testing.assert_array_equal(A, A_before)
    np.testing.assert_array_equal(B, B_before)


def _about_one_axis(m: int = 6, axis=(0.0, 0.0, 1.0)):
    rng = np.random.default_rng(5)
    X = PROBLEM.random_unknowns(rng)["X"]
    A = make_pose(so3_exp(np.outer(rng.uniform(0.3, 1.5, m), axis)), rng.standard_normal((m, 3)) * 100)
    return {"A": A, "B": inverse(X) @ A @ X}


def test_parallel_axes_are_degenerate_in_words():
    with pytest.raises(handeye.DegenerateDataError, match="rotate about at least two different axes") as info:
        PROBLEM.validate(**_about_one_axis())
    assert "parallel" in str(info.value)
    with pytest.raises(handeye.DegenerateDataError, match="0 of 3 motions rotate"):
        PROBLEM.validate(A=np.stack([make_pose(np.eye(3), [1, 2, k]) for k in range(3)]),
                         B=np.stack([make_pose(np.eye(3), [2, 1, k]) for k in range(3)]))


def test_axis_spread_and_largest_rotation_are_figures():
    data = _about_one_axis(8)
    A = data["A"].copy()
    A[0] = make_pose(so3_exp([0.04, 0.0, 1.0]), A[0, :3, 3])  # tilted by ~2.3 deg (not planar: test_planar)
    X = PROBLEM.random_unknowns(np.random.default_rng(9))["X"]
    diag = PROBLEM.diagnose(PROBLEM.validate(A=A, B=inverse(X) @ A @ X))
    assert 0.01 < diag["axis_spread"] < 0.05 and diag["warnings"] == []  # judged at the noise: test_self_check
    small_A = make_pose(so3_exp(np.random.default_rng(2).normal(0, 0.02, (5, 3))), np.ones((5, 3)))
    diag = PROBLEM.diagnose(PROBLEM.validate(A=small_A, B=inverse(X) @ small_A @ X))
    assert diag["largest_rotation"] < 0.1 and diag["warnings"] == []


def test_good_data_have_no_warnings(noisy):
    data, _ = noisy
    diag = PROBLEM.diagnose(data)
    assert diag["warnings"] == [] and diag["likely_mismatched"] == []
    assert MISMATCH_ANGLE_FLOOR < diag["angle_difference_max"] < 0.1  # noise of 0.01 rad per station: above the floor, not flagged


def test_swapped_pairs_are_listed_as_mismatched():
    data, _ = PROBLEM.simulate(pairs=21, seed=2, noise=NoiseModel.on(("A", "B"), 0.002, 0.2),
                               pairing="consecutive")
    A = data["A"].copy()
    A[[3, 4]] = A[[4, 3]]
    diag = PROBLEM.diagnose(PROBLEM.validate(A=A, B=data["B"]))
    assert diag["likely_mismatched"] == [3, 4]
    assert any("paired in the same order" in w and "3 (angle" in w for w in diag["warnings"])


# ------------------------------------------------------------------ simulator

def test_simulator_differences_noisy_absolute_poses():
    """The motions are the differences of noisy stations (noise on robot and camera poses), so
    consecutive motions share a station's noise, as real data do."""
    noise = NoiseModel.on(("A", "B"), 0.003, 0.4)
    data, truth = PROBLEM.simulate(pairs=12, seed=4, noise=noise)
    stations, full_truth = simulate_stations(12, seed=4, noise=noise)
    A, B = relative_motions(stations["A"], stations["B"], "all")
    np.testing.assert_array_equal(data["A"], A)
    np.testing.assert_array_equal(data["B"], B)
    np.testing.assert_array_equal(truth["X"], full_truth["X"])
    clean, _ = PROBLEM.simulate(pairs=12, seed=4)
    assert np.abs(clean["A"] - data["A"]).max() > 1e-3  # the noise is there
    np.testing.assert_array_equal(clean["B"], PROBLEM.simulate(pairs=12, seed=4)[0]["B"])  # deterministic


def test_simulator_pairings_and_options():
    """`pairs` stations (robot/camera pose pairs, as for axyb): all pairs of them by default,
    or the consecutive ones."""
    data, truth = PROBLEM.simulate(pairs=10, seed=1)
    assert data["A"].shape == (45, 4, 4) and set(truth) == {"X"}
    assert PROBLEM.residuals(PROBLEM.validate(**data), truth)["translation"].max() < 1e-9
    consecutive, _ = PROBLEM.simulate(pairs=10, seed=1, pairing="consecutive")
    assert consecutive["A"].shape == (9, 4, 4)
    np.testing.assert_array_equal(consecutive["A"][0], data["A"][0])  # stations (0, 1) in both
    with pytest.raises(handeye.InputError, match="pairs must be >= 2"):
        PROBLEM.simulate(pairs=1, seed=1)
    with pytest.raises(handeye.InputError, match="unknown simulate option"):
        PROBLEM.simulate(pairs=3, seed=1, stations=4)
    with pytest.raises(handeye.InputError, match="pairing"):
        PROBLEM.simulate(pairs=3, seed=1, pairing="random")


def test_numbers_beyond_float64_and_complex_input_are_bad_input():
    """An integer too large for float64 and complex entries are InputErrors (one line), never a
    bare OverflowError or a silently dropped imaginary part."""
    data, _ = PROBLEM.simulate(pairs=6, seed=1)
    huge = np.array(data["A"], dtype=object)
    huge[0, 0, 3] = 10**400
    with pytest.raises(handeye.InputError, match="could not convert it to floats"):
        PROBLEM.validate(A=huge, B=data["B"])
    with pytest.raises(handeye.InputError, match="complex numbers"):
        PROBLEM.validate(A=data["A"] + 0j, B=data["B"])


def test_frobenius_norm_does_not_overflow():
    from handeye.geometry.linalg import frobenius_norm

    M = np.array([[3e200, 4e200], [0.0, 0.0]])
    assert frobenius_norm(M) == pytest.approx(5e200, rel=1e-15)
    assert frobenius_norm(np.zeros((2, 2))) == 0.0 and not np.isfinite(frobenius_norm(np.array([np.inf])))


def test_so3_sdp_solves_data_whose_cost_entries_pass_1e154():
    """|M|_F is computed without squaring overflow: motions in a tiny unit still solve."""
    data, truth = PROBLEM.simulate(pairs=8, seed=1, pairing="consecutive")
    for T in data.values():
        T[:, :3, 3] *= 1e80
    sol = handeye.solve("axxb", solver="so3-sdp", normalize=False, **data)
    assert PROBLEM.errors(sol.unknowns, truth)["X"]["rotation"] < 1e-9


@pytest.mark.parametrize("seed", range(5))
def test_a_motion_mispaired_by_a_few_degrees_is_flagged(seed):
    """Among 14 noisy motions (the accuracy study's noise), one whose camera side turns 4 deg more
    than its robot side cannot be a true pair (the angle is invariant under A = X B X^-1): the
    diagnosis names it, at ~25 robust sigmas of the others' disagreement (threshold 5)."""
    from scipy.spatial.transform import Rotation

    noise = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})
    data, _ = PROBLEM.simulate(pairs=15, seed=seed, noise=noise, pairing="consecutive")
    B = np.array(data["B"])
    rv = Rotation.from_matrix(B[6, :3, :3]).as_rotvec()
    angle = np.linalg.norm(rv)
    B[6, :3, :3] = Rotation.from_rotvec(rv / angle * (angle + np.radians(4.0))).as_matrix()
    diagnosis = PROBLEM.diagnose(PROBLEM.validate(A=data["A"], B=B))
    assert diagnosis["likely_mismatched"] == [6]
    assert any("rotate by a different angle" in w for w in diagnosis["warnings"])
