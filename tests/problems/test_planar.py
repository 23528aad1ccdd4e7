"""The planar (4-DOF) mode: a robot whose rotations share one axis (a SCARA) and the translation
along it that the user gives (handeye.problems.planar, docs/planar.md).

Simulated cells are SCARA-like and eye-in-hand (`planar.simulate`): the flange rotates about the
base z only, its z along the joint axis, so tz_X = X[2, 3] (60 mm) and tz_Y = Y[2, 3].
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

import handeye
from handeye import DegenerateDataError, InputError
from handeye.cli import main
from handeye.estimation import nlls
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.host.registry import get_registry
from handeye.io.data_files import save_data
from handeye.io.pose_writers import write_poses
from handeye.problems import planar
from handeye.problems.axxb import motions

PLANAR_SOLVERS = ("auto", "refine", "kron-lstsq")
PROBLEMS = ("axyb", "axxb")
#: noise-free recovery (rotation rad, translation mm)
EXACT = 1e-9
#: 15 stations, noise 0.001 rad / 0.1 mm on robot and camera poses: the largest errors over 10
#: seeds were 0.054 deg / 0.23 mm (kron-lstsq's Y; auto 0.050 deg / 0.23 mm)
NOISY_DEG, NOISY_MM = 0.15, 0.6
TZ_X = float(planar.PLANAR_X[2, 3])


def _errors(problem: str, unknowns, truth) -> dict[str, dict[str, float]]:
    return get_registry().problem(problem).errors(unknowns, truth)


@pytest.mark.parametrize("problem", PROBLEMS)
@pytest.mark.parametrize("solver", PLANAR_SOLVERS)
def test_noise_free_planar_data_are_recovered_given_tz(problem, solver):
    data, truth = planar.simulate(problem, 12, seed=3)
    before = copy.deepcopy(data)
    sol = handeye.solve(problem, **data, tz_X=TZ_X, solver=solver)
    assert sol.status == "optimal"
    for name, e in _errors(problem, sol.unknowns, truth).items():
        assert e["rotation"] < EXACT and e["translation"] < EXACT, (name, e)
    for key in data:  # inputs untouched
        np.testing.assert_array_equal(data[key], before[key])
    assert sol.diagnostics["self_check"]["reliable"]


@pytest.mark.parametrize("solver", PLANAR_SOLVERS)
def test_tz_Y_fixes_the_pair_too(solver):
    data, truth = planar.simulate("axyb", 12, seed=4)
    sol = handeye.solve("axyb", **data, tz_Y=float(truth["Y"][2, 3]), solver=solver)
    for e in _errors("axyb", sol.unknowns, truth).values():
        assert e["rotation"] < EXACT and e["translation"] < EXACT
    assert any("tz_Y = -20 (not measured)" in w for w in sol.warnings)


@pytest.mark.parametrize("problem", PROBLEMS)
@pytest.mark.parametrize("solver", PLANAR_SOLVERS)
def test_noisy_planar_data(problem, solver):
    noise = NoiseModel.on(("A", "B"), 0.001, 0.1)
    for seed in range(3):
        data, truth = planar.simulate(problem, 15, seed=seed, noise=noise)
        sol = handeye.solve(problem, **data, tz_X=TZ_X, solver=solver)
        assert sol.status == "optimal"
        for name, e in _errors(problem, sol.unknowns, truth).items():
            assert np.rad2deg(e["rotation"]) < NOISY_DEG and e["translation"] < NOISY_MM, (seed, name, e)
        assert abs(sol.X[:3, 3] @ sol.diagnostics["planar"]["axis"] - TZ_X) < 1e-9  # kept exactly


@pytest.mark.parametrize("problem", PROBLEMS)
def test_wrong_tz_moves_only_that_translation(problem):
    """tz_X = 0 where the truth is 60: X is off by exactly 60 along the axis, nothing else is
    (Y's translation moves by the same 60 along the base axis: R_A X's shift is constant)."""
    data, truth = planar.simulate(problem, 12, seed=5)
    for solver in PLANAR_SOLVERS:
        sol = handeye.solve(problem, **data, tz_X=0.0, solver=solver)
        shift = np.array([0.0, 0.0, -TZ_X])  # the axis is the flange z
        np.testing.assert_allclose(sol.X[:3, :3], truth["X"][:3, :3], atol=EXACT)
        np.testing.assert_allclose(sol.X[:3, 3], truth["X"][:3, 3] + shift, atol=1e-6)
        if problem == "axyb":
            np.testing.assert_allclose(sol.Y[:3, :3], truth["Y"][:3, :3], atol=EXACT)
            np.testing.assert_allclose(sol.Y[:3, 3], truth["Y"][:3, 3] + data["A"][0, :3, :3] @ shift, atol=1e-6)
        residuals = get_registry().problem(problem).residuals(
            get_registry().problem(problem).validate(**data, tz_X=0.0), sol.unknowns)
        assert residuals["rotation"].max() < 1e-9 and residuals["translation"].max() < 1e-7  # fits as well


@pytest.mark.parametrize("problem", PROBLEMS)
def test_planar_data_without_tz_name_the_option(problem):
    data, _ = planar.simulate(problem, 10, seed=1, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    before = copy.deepcopy(data)
    with pytest.raises(DegenerateDataError) as info:
        handeye.solve(problem, **data)
    message = str(info.value)
    assert "\n" not in message and "tz_X=" in message and "SCARA" in message
    assert "auto, kron-lstsq or refine" in message
    for key in data:
        np.testing.assert_array_equal(data[key], before[key])


@pytest.mark.parametrize(("problem", "solver"), [("axxb", "tsai"), ("axxb", "so3-sdp"), ("axyb", "shah"),
                                                 ("axyb", "dual-quaternion")])
def test_solvers_without_the_mode_are_refused(problem, solver):
    data, _ = planar.simulate(problem, 10, seed=1)
    with pytest.raises(InputError, match="no planar") as info:
        handeye.solve(problem, **data, tz_X=TZ_X, solver=solver)
    assert "auto, kron-lstsq, refine" in str(info.value)
    with pytest.raises(InputError, match="no planar"):
        handeye.solve(problem, **data, tz_X=TZ_X, solver="refine", init="so3-sdp")


@pytest.mark.parametrize("problem", PROBLEMS)
def test_tz_on_data_that_determine_it_is_refused(problem):
    data, _ = get_registry().problem(problem).simulate(pairs=10, seed=1)  # a 6-axis arm
    with pytest.raises(InputError, match="do not pass tz_X") as info:
        handeye.solve(problem, **data, tz_X=60.0)
    assert "determine the translation" in str(info.value) and "\n" not in str(info.value)


def test_tz_values_are_checked():
    data, _ = planar.simulate("axyb", 10, seed=1)
    with pytest.raises(InputError, match="one of tz_X and tz_Y, not both"):
        handeye.solve("axyb", **data, tz_X=60.0, tz_Y=0.0)
    for bad in ("60", float("nan"), [60.0], True, 1j):
        with pytest.raises(InputError, match="tz_X must be a finite number"):
            handeye.solve("axyb", **data, tz_X=bad)
    sol = handeye.solve("axyb", **data, tz_X=np.float32(60), tz_Y=None, solver="kron-lstsq")  # None: not given
    assert abs(sol.X[2, 3] - 60.0) < 1e-9


def test_the_warning_names_the_value():
    data, _ = planar.simulate("axyb", 10, seed=2)
    for solver in PLANAR_SOLVERS:
        sol = handeye.solve("axyb", **data, tz_X=60.0, solver=solver)
        assert sol.status == "optimal"
        assert sol.warnings[0] == (
            "the translation of X along the robot's rotation axis (direction (0.000, 0.000, 1.000) in the flange "
            "frame) is not determined by the data: it is the value you gave, tz_X = 60 (not measured); Y's "
            "translation along the axis follows from it"), solver
        assert sum("tz_X = 60" in w for w in sol.warnings) == 1


def test_rotation_about_one_fixed_line_stays_degenerate():
    """The flange only turns about one fixed line (no sideways motion): even the rotation about
    the axis is undetermined, tz or not."""
    theta = np.linspace(-2.0, 2.0, 8)
    G = make_pose(so3_exp(np.outer(theta, [0.0, 0.0, 1.0])), np.zeros((8, 3)))
    pivot = make_pose(np.eye(3), [100.0, 50.0, 0.0])
    A = pivot @ G @ inverse(pivot) @ make_pose(np.diag([1.0, -1.0, -1.0]), [300.0, 0.0, 200.0])
    A[:, 2, 3] += np.linspace(0.0, 70.0, 8)  # moving along the axis does not help
    B = inverse(planar.PLANAR_Y) @ A @ planar.PLANAR_X
    with pytest.raises(DegenerateDataError, match="rotations of X and Y about that axis cannot be determined"):
        handeye.solve("axyb", A=A, B=B, tz_X=60.0)
    Am, Bm = inverse(A[:-1]) @ A[1:], inverse(B[:-1]) @ B[1:]
    with pytest.raises(DegenerateDataError, match="do not determine X's rotation about that axis"):
        handeye.solve("axxb", A=Am, B=Bm, tz_X=60.0)


def test_eye_to_hand_tz_is_along_the_base_axis():
    """Eye-to-hand X = T_base_cam: tz_X is its translation along the robot's axis in the base."""
    stations, _ = planar.simulate_stations(10, seed=6)
    T_base_cam = make_pose(so3_exp([3.0, 0.1, 0.0]), [450.0, -80.0, 900.0])
    T_flange_target = make_pose(so3_exp([0.0, 0.2, 0.1]), [10.0, 5.0, 40.0])
    camera_poses = inverse(T_base_cam) @ stations["A"] @ T_flange_target  # T_cam_target
    data = motions(stations["A"], camera_poses, setup="eye-to-hand", pairing="consecutive")
    for solver in PLANAR_SOLVERS:
        sol = handeye.solve("axxb", **data, tz_X=900.0, solver=solver)
        np.testing.assert_allclose(sol.X, T_base_cam, atol=1e-8)


def test_unit_invariance():
    data, _ = planar.simulate("axyb", 12, seed=7, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    metres = {k: v.copy() for k, v in data.items()}
    for T in metres.values():
        T[:, :3, 3] /= 1000.0
    for solver in PLANAR_SOLVERS:
        mm = handeye.solve("axyb", **data, tz_X=60.0, solver=solver)
        m = handeye.solve("axyb", **metres, tz_X=0.06, solver=solver)
        for name in ("X", "Y"):
            np.testing.assert_allclose(m.unknowns[name][:3, :3], mm.unknowns[name][:3, :3], atol=1e-9)
            np.testing.assert_allclose(1000.0 * m.unknowns[name][:3, 3], mm.unknowns[name][:3, 3], atol=1e-6)


def test_refine_from_given_poses_keeps_the_value_and_reports_zero_variance():
    data, truth = planar.simulate("axyb", 15, seed=8, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    X0 = truth["X"].copy()
    X0[:3, 3] += [1.0, -2.0, 5.0]  # off the constraint: moved onto it first
    sol = handeye.solve("axyb", **data, tz_X=60.0, solver="refine", init_X=X0, init_Y=truth["Y"])
    axis = np.array(sol.diagnostics["planar"]["axis"])  # the flange z to the robot's noise
    assert abs(sol.X[:3, 3] @ axis - 60.0) < 1e-9 and sol.diagnostics["init"] == "given"
    cov = np.array(sol.diagnostics["covariance"]["X"])
    along = sol.X[:3, :3].T @ axis  # the axis in X's own frame (v of the covariance)
    # zero to rounding (the projected inverse leaves ~1e-18 of the trace there; the free
    # directions carry ~1/3 of it each)
    assert abs(along @ cov[3:, 3:] @ along) < 1e-12 * np.trace(cov[3:, 3:])
    assert np.all(np.linalg.eigvalsh(cov[3:, 3:])[1:] > 0)


def test_fixed_basis_keeps_the_component():
    rng = np.random.default_rng(0)
    poses = (make_pose(so3_exp(rng.standard_normal(3)), rng.standard_normal(3)),
             make_pose(so3_exp(rng.standard_normal(3)), rng.standard_normal(3)))
    d = np.array([0.6, 0.0, 0.8])
    P = nlls.fixed_basis(poses, ((1, d),))
    assert P.shape == (12, 11) and np.allclose(P.T @ P, np.eye(11))
    moved = nlls.retract_all(poses, P @ rng.standard_normal(11))
    assert abs(moved[1][:3, 3] @ d - poses[1][:3, 3] @ d) < 1e-14
    assert nlls.fixed_basis(poses, ()) is None


@pytest.mark.parametrize("command", ["solve", "calibrate"])
def test_cli_tz_X(tmp_path, capsys, command):
    stations, truth = planar.simulate_stations(12, seed=9, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    if command == "solve":
        path = tmp_path / "scara.json"
        save_data(path, stations, truth, metadata={"units": "mm", "setup": "eye-in-hand"})
        argv = ["solve", str(path), "--json"]
    else:
        robot = write_poses(tmp_path / "robot.csv", stations["A"], "fanuc-wpr", unit="mm")
        camera = write_poses(tmp_path / "camera.csv", inverse(stations["B"]), "opencv-rvec", unit="mm")
        argv = ["calibrate", "--robot", str(robot), "--robot-format", "fanuc-wpr", "--camera", str(camera),
                "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand", "--json"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--tz-X VALUE" in err and "tz_X" not in err  # the command line's words, not Python's
    assert main(argv + ["--tz-X", "60"]) == 0
    out = json.loads(capsys.readouterr().out)
    X = np.array(out["X"] if command == "calibrate" else out["unknowns"]["X"])
    # t_X . axis = 60 exactly; the axis is the flange z to the robot's noise (~1e-3)
    assert abs(X[2, 3] - 60.0) < 0.05 and np.abs(X[:3, 3] - truth["X"][:3, 3]).max() < NOISY_MM
    assert any("tz_X = 60 (not measured)" in w for w in out["warnings"])
