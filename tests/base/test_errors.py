"""Bad input gets its own exception type (a ValueError) with a clear message, and nothing the
caller passed is modified. Uses the closed-form `kron-lstsq` where a solver is needed; the shared
suite (test_solvers.py) checks that every solver raises the same way."""

from __future__ import annotations

import copy
import dataclasses
import importlib.util

import numpy as np
import pytest
from conftest import SolverPlugin, identity_run

import handeye
from handeye import (
    BackendUnavailableError,
    DegenerateDataError,
    HandEyeError,
    InputError,
    PluginRegistrationError,
    SolverError,
    SolverOutput,
    SolverSpec,
    UnknownPluginError,
)
from handeye.estimation.noise import NoiseModel
from handeye.framework.options import check_positive
from handeye.geometry.se3 import ORTHONORMALITY_TOL, inverse, make_pose, so3_exp
from handeye.problems.axyb import PROBLEM

SOLVER = "kron-lstsq"


@pytest.fixture
def data():
    d, _ = PROBLEM.simulate(pairs=6, seed=5, noise=NoiseModel.on("B", 0.01, 0.5))
    return {k: np.array(v) for k, v in d.items()}  # writable arrays, as a caller would have


def _solve_raises(exc_type, match, A, B, **kwargs):
    """Assert handeye.solve raises exc_type matching `match`, and that A, B are unchanged."""
    before = [copy.deepcopy(A), copy.deepcopy(B)]
    kwargs.setdefault("solver", SOLVER)
    with pytest.raises(exc_type, match=match) as info:
        handeye.solve("axyb", A=A, B=B, **kwargs)
    for value, old in zip((A, B), before):
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, old)
            assert value.flags.writeable
        else:
            assert value == old
    return info.value


@pytest.mark.parametrize("exc", [HandEyeError, InputError, DegenerateDataError, SolverError,
                                 UnknownPluginError, BackendUnavailableError, PluginRegistrationError])
def test_every_error_is_a_value_error(exc):
    assert issubclass(exc, ValueError) and issubclass(exc, HandEyeError)


def test_degenerate_data_is_an_input_error():
    assert issubclass(DegenerateDataError, InputError)


# ---------------------------------------------------------------------------- shapes and lengths

def test_wrong_shape_3x4(data):
    err = _solve_raises(InputError, r"expected A to have shape \(m, 4, 4\), got \(6, 3, 4\)",
                        data["A"][:, :3, :], data["B"])
    assert "A" in str(err)


def test_single_pose_is_not_a_stack(data):
    _solve_raises(InputError, r"expected B to have shape \(m, 4, 4\), got \(4, 4\)", data["A"], data["B"][0])


def test_ragged_lists(data):
    A = data["A"].tolist()
    A[1] = A[1][:3]  # one pose with three rows
    _solve_raises(InputError, r"A must be an array of 4x4 poses with shape \(m, 4, 4\)", A, data["B"])


def test_non_numeric_input(data):
    _solve_raises(InputError, "could not convert it to floats", "not poses", data["B"])


def test_mismatched_lengths(data):
    err = _solve_raises(InputError, "same length", data["A"], data["B"][:5])
    assert "6" in str(err) and "5" in str(err)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_and_inf(data, bad):
    B = data["B"].copy()
    B[3, 1, 2] = bad
    _solve_raises(InputError, r"B contains NaN or inf in pose\(s\) 3", data["A"], B)


# ---------------------------------------------------------------------------- SE(3) membership

def test_orthonormality_tolerance_is_the_documented_boundary(data):
    """Rotation blocks off by half the tolerance are accepted, by twice it rejected; the value is
    the one docs/formats.md states."""
    from pathlib import Path

    formats = (Path(__file__).resolve().parents[2] / "docs" / "formats.md").read_text(encoding="utf-8")
    import re

    assert float(re.search(r"orthonormal to ([0-9.e+-]+)", formats).group(1)) == ORTHONORMALITY_TOL
    for factor, accepted in ((0.5, True), (2.0, False)):
        A = data["A"].copy()
        A[2, :3, 0] *= np.sqrt(1 + factor * ORTHONORMALITY_TOL)  # |c0|^2 - 1 = factor * tol
        if accepted:
            handeye.solve("axyb", solver="kron-lstsq", A=A, B=data["B"])
        else:
            _solve_raises(InputError, r"not orthonormal .* in pose\(s\) 2", A, data["B"])


def test_non_orthonormal_rotation(data):
    A = data["A"].copy()
    A[4, :3, :3] *= 1 + 10 * ORTHONORMALITY_TOL
    err = _solve_raises(InputError, "not orthonormal", A, data["B"])
    assert "pose(s) 4" in str(err) and f"{ORTHONORMALITY_TOL:g}" in str(err)


def test_orthonormality_within_tolerance_is_accepted(data):
    A = data["A"].copy()
    A[4, :3, :3] *= 1 + 0.1 * ORTHONORMALITY_TOL  # |R^T R - I| = 2e-7 < 1e-6
    handeye.solve("axyb", A=A, B=data["B"], solver=SOLVER)


def test_reflection_det_minus_one(data):
    B = data["B"].copy()
    B[2, :3, 0] *= -1  # still orthonormal, det -1
    _solve_raises(InputError, r"det -1 \(a reflection\) in pose\(s\) 2", data["A"], B)


@pytest.mark.parametrize("row", [[0, 0, 0, 2], [0, 0.1, 0, 1], [0, 0, 0, 0]])
def test_last_row(data, row):
    A = data["A"].copy()
    A[0, 3] = row
    _solve_raises(InputError, r"last row must be \[0, 0, 0, 1\]", A, data["B"])


# ---------------------------------------------------------------------------- degenerate data

def test_fewer_than_three_pairs(data):
    _solve_raises(DegenerateDataError, "at least 3 pose pairs, got 2", data["A"][:2], data["B"][:2])


def _one_axis_data(angles, rng):
    m = len(angles)
    A = make_pose(so3_exp(np.outer(angles, [0.0, 0.0, 1.0])), 100 * rng.standard_normal((m, 3)))
    X = make_pose(so3_exp([0.3, -0.2, 1.0]), [10.0, 20.0, 30.0])
    Y = make_pose(so3_exp([1.3, 0.2, -1.0]), [100.0, -200.0, 300.0])
    return A, inverse(Y) @ A @ X


def test_rotations_about_one_axis_are_degenerate():
    rng = np.random.default_rng(1)
    A, B = _one_axis_data(rng.uniform(-2, 2, 8), rng)
    _solve_raises(DegenerateDataError, "at least two different axes", A, B)


def test_identical_rotations_are_degenerate():
    rng = np.random.default_rng(2)
    A, B = _one_axis_data(np.full(8, 0.7), rng)  # translations differ, rotations identical
    err = _solve_raises(DegenerateDataError, "the rotations of X and Y cannot be determined", A, B)
    assert "Record poses that rotate about at least two different axes" in str(err)


# ---------------------------------------------------------------------------- unknown names

def test_unknown_problem(data):
    with pytest.raises(UnknownPluginError, match="unknown problem 'axbc'") as info:
        handeye.solve("axbc", solver=SOLVER, **data)
    assert "'axyb'" in str(info.value) and info.value.known == handeye.list_problems()


def test_unknown_solver(data):
    with pytest.raises(UnknownPluginError, match="'no-such-solver'") as info:
        handeye.solve("axyb", solver="no-such-solver", **data)
    for name in handeye.list_solvers("axyb"):
        assert repr(name) in str(info.value)


def test_unknown_backend(data):
    with pytest.raises(UnknownPluginError, match="unknown backend 'gpu' of solver 'kron-lstsq'; known backends: ") as info:
        handeye.solve("axyb", solver=SOLVER, backend="gpu", **data)
    assert "'numpy'" in str(info.value)


def test_unknown_option(data):
    err = _solve_raises(UnknownPluginError, "unknown option 'normalise' of solver 'kron-lstsq'; known options: ",
                        data["A"], data["B"], normalise=True)
    assert "'normalize'" in str(err)  # the known option is listed


def test_missing_data_field(data):
    with pytest.raises(InputError, match=r"needs data \['A', 'B'\]; missing \['B'\]"):
        handeye.solve("axyb", solver=SOLVER, A=data["A"])


# ---------------------------------------------------------------------------- backends

def test_backend_module_not_installed(data, runtime_plugins):
    spec = SolverSpec("needs-missing", ("axyb",), identity_run,
                      backends={"numpy": (), "exotic": ("handeye_no_such_module_xyz",)})
    runtime_plugins(SolverPlugin(spec), "test-needs-missing")
    err = _solve_raises(BackendUnavailableError, "pip install handeye_no_such_module_xyz",
                        data["A"], data["B"], solver="needs-missing", backend="exotic")
    assert "'exotic'" in str(err) and "'needs-missing'" in str(err)
    handeye.solve("axyb", solver="needs-missing", backend="numpy", **data)  # the other backend runs


def test_backend_package_name_is_the_pip_name(data, runtime_plugins, monkeypatch):
    spec = SolverSpec("needs-cv2", ("axyb",), identity_run, backends={"opencv": ("cv2",)},
                      default_backend="opencv")
    runtime_plugins(SolverPlugin(spec), "test-needs-cv2")
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "cv2" else real_find_spec(name, *a))
    _solve_raises(BackendUnavailableError, r"module 'cv2'.*pip install opencv-python-headless",
                  data["A"], data["B"], solver="needs-cv2")


def test_backend_check_reason(data, runtime_plugins):
    spec = SolverSpec("needs-feature", ("axyb",), identity_run,
                      check=lambda backend: "cv2 lacks calibrateRobotWorldHandEye; upgrade to 4.8")
    runtime_plugins(SolverPlugin(spec), "test-needs-feature")
    _solve_raises(BackendUnavailableError, "upgrade to 4.8", data["A"], data["B"], solver="needs-feature")


# ---------------------------------------------------------------------------- solver output

@pytest.mark.parametrize("unknowns, match", [
    ({"X": np.eye(4)}, "did not return unknown 'Y'"),
    ({"X": np.eye(4), "Y": np.diag([1.0, 1.0, 1.001, 1.0])}, "not in SO"),
    ({"X": np.eye(4), "Y": np.diag([1.0, 1.0, -1.0, 1.0])}, r"det = -1"),
    ({"X": np.eye(4), "Y": np.full((4, 4), np.nan)}, "Y with 16 non-finite entries"),
    ({"X": np.eye(3), "Y": np.eye(4)}, r"X of shape \(3, 3\), not a 4x4 pose"),
    ({"X": "abc", "Y": np.eye(4)}, "X as a str that is not an array of numbers"),
])
def test_solver_returning_non_se3_is_a_solver_error(data, runtime_plugins, unknowns, match):
    spec = SolverSpec("broken", ("axyb",), lambda d, o, b: SolverOutput(unknowns))
    runtime_plugins(SolverPlugin(spec), "test-broken")
    _solve_raises(SolverError, match, data["A"], data["B"], solver="broken")


def test_options_are_validated(data, runtime_plugins):
    @dataclasses.dataclass(frozen=True)
    class Options:
        iterations: int = 10

        def __post_init__(self):
            check_positive("iterations", self.iterations)

    spec = SolverSpec("with-options", ("axyb",), identity_run, options=Options)
    runtime_plugins(SolverPlugin(spec), "test-with-options")
    _solve_raises(InputError, "iterations=-1 must be a finite number > 0", data["A"], data["B"],
                  solver="with-options", iterations=-1)
    sol = handeye.solve("axyb", solver="with-options", iterations=3, **data)
    assert sol.solver == "with-options"


@pytest.mark.parametrize("fault, match", [
    ("norm 2x", r"not orthonormal .* in pose\(s\) 250"),
    ("shear 2x", r"not orthonormal .* in pose\(s\) 250"),
    ("reflection", r"det -1 \(a reflection\) in pose\(s\) 250"),
])
def test_a_large_stack_is_checked_pose_by_pose_as_a_small_one(fault, match):
    """Above 128 poses the rotations are checked entry by entry (another code path): the same
    boundary, named pose and message; half the tolerance passes."""
    d, _ = PROBLEM.simulate(pairs=300, seed=5, noise=NoiseModel.on("B", 0.01, 0.5))
    A, B = np.array(d["A"]), np.array(d["B"])
    bad, fine = A.copy(), A.copy()
    if fault.startswith("norm"):
        bad[250, :3, 1] *= np.sqrt(1 + 2.0 * ORTHONORMALITY_TOL)
        fine[250, :3, 1] *= np.sqrt(1 + 0.5 * ORTHONORMALITY_TOL)
    elif fault.startswith("shear"):  # columns 0 and 2 no longer orthogonal: c0 . c2 = 2 tol
        bad[250, :3, 2] += 2.0 * ORTHONORMALITY_TOL * A[250, :3, 0]
        fine[250, :3, 2] += 0.5 * ORTHONORMALITY_TOL * A[250, :3, 0]
    else:
        bad[250, :3, 0] *= -1
    _solve_raises(InputError, match, bad, B)
    if fault != "reflection":
        handeye.solve("axyb", solver="kron-lstsq", A=fine, B=B)
