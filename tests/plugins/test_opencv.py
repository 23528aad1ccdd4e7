"""The `opencv` reference plugin: slot mapping, method routing, option errors, availability,
re-projection and unit (in)variance. The shared suite (test_solvers.py) covers the rest."""

from __future__ import annotations

import runpy

import numpy as np
import pytest
from tolerances import solved

import handeye
from handeye.base.errors import BackendUnavailableError, InputError, SolverError
from handeye.cli import main as cli_main
from handeye.cli.list_cmd import collect
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import orthonormality_error, rotation_angle
from handeye.plugins import opencv as plugin
from handeye.problems.axyb import PROBLEM, random_truth

cv2 = pytest.importorskip("cv2")
if not hasattr(cv2, "calibrateRobotWorldHandEye"):
    pytest.skip("this OpenCV has no calibrateRobotWorldHandEye", allow_module_level=True)

FLAGS = {"shah": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, "li": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI}


def noisy_case(seed: int = 3, pairs: int = 20):
    return PROBLEM.simulate(pairs=pairs, seed=seed, noise=NoiseModel.on(("A", "B"), 0.01, 1.0))


def cv2_direct(A: np.ndarray, B: np.ndarray, method: str) -> tuple[np.ndarray, ...]:
    """OpenCV called by hand, with the documented mapping: (R_X, t_X, R_Y, t_Y)."""
    R_bw, t_bw, R_gc, t_gc = cv2.calibrateRobotWorldHandEye(
        [R for R in A[:, :3, :3]], [t for t in A[:, :3, 3]],
        [R for R in B[:, :3, :3]], [t for t in B[:, :3, 3]], method=FLAGS[method])
    return R_bw, np.ravel(t_bw), R_gc, np.ravel(t_gc)


@pytest.mark.parametrize("method", ["shah", "li"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mapping_recovers_noise_free_truth(method, seed):
    truth = random_truth(np.random.default_rng(seed))
    data, truth = PROBLEM.simulate(pairs=12, seed=seed, X=truth["X"], Y=truth["Y"])
    sol = handeye.solve("axyb", solver="opencv", method=method, **data)
    scale = PROBLEM.validate(**data).translation_scale
    errors = PROBLEM.errors(sol.unknowns, truth)
    for name in ("X", "Y"):
        # measured: SHAH <= 1e-15 rad, LI <= 3e-11 rad; translations <= 1e-11 mm at scale ~1e3 mm
        assert errors[name]["rotation"] < (1e-12 if method == "shah" else 1e-10), (name, errors)
        assert errors[name]["translation"] < 1e-12 * scale, (name, errors, scale)


def test_swapped_slots_do_not_recover_truth():
    """The mapping matters: X and Y swapped (or A and B) is not a solution (the test can fail)."""
    data, truth = PROBLEM.simulate(pairs=12, seed=4)
    sol = handeye.solve("axyb", solver="opencv", **data)
    swapped = PROBLEM.errors({"X": sol.Y, "Y": sol.X}, truth)
    assert swapped["X"]["rotation"] > 0.1
    flipped = handeye.solve("axyb", solver="opencv", A=data["B"], B=data["A"])
    assert PROBLEM.errors(flipped.unknowns, truth)["X"]["rotation"] > 0.1


def test_method_routing_matches_cv2_called_directly():
    data, _ = noisy_case()
    A, B = np.asarray(data["A"]), np.asarray(data["B"])
    sols = {m: handeye.solve("axyb", solver="opencv", method=m, **data) for m in FLAGS}
    assert handeye.solve("axyb", solver="opencv", **data).X.tolist() == sols["shah"].X.tolist()  # default
    for method, sol in sols.items():
        R_X, t_X, R_Y, t_Y = cv2_direct(A, B, method)
        np.testing.assert_allclose(sol.X[:3, :3], R_X, rtol=0, atol=1e-14)
        np.testing.assert_allclose(sol.Y[:3, :3], R_Y, rtol=0, atol=1e-14)
        np.testing.assert_allclose(sol.X[:3, 3], t_X, rtol=0, atol=1e-10)
        np.testing.assert_allclose(sol.Y[:3, 3], t_Y, rtol=0, atol=1e-10)
        assert sol.diagnostics["method"] == method
        assert sol.diagnostics["opencv_version"] == cv2.__version__
        assert sol.diagnostics["reprojected"] == []
        assert sol.backend == "opencv" and solved(sol)
    # on noisy data the two methods differ clearly
    assert rotation_angle(sols["shah"].X[:3, :3] @ sols["li"].X[:3, :3].T) > 1e-5
    assert np.linalg.norm(sols["shah"].Y[:3, 3] - sols["li"].Y[:3, 3]) > 1e-3


def test_unknown_method_lists_known_ones():
    data, _ = noisy_case()
    with pytest.raises(InputError, match=r"method='tsai'.*'shah'.*'li'"):
        handeye.solve("axyb", solver="opencv", method="tsai", **data)
    with pytest.raises(InputError, match="'shah'"):
        handeye.solve("axyb", solver="opencv", method="SHAH", **data)  # no silent case folding


def test_unavailable_when_cv2_lacks_the_function(monkeypatch, capsys):
    data, _ = noisy_case()
    monkeypatch.delattr(cv2, "calibrateRobotWorldHandEye")
    spec = handeye.get_registry().solver("opencv", "axyb")
    reason = spec.unavailable_reason("opencv")
    assert reason and "calibrateRobotWorldHandEye" in reason and "opencv-python-headless" in reason
    with pytest.raises(BackendUnavailableError, match="no cv2.calibrateRobotWorldHandEye") as info:
        handeye.solve("axyb", solver="opencv", **data)
    assert str(info.value) == reason
    (entry,) = [s for s in collect("axyb")["solvers"] if s["name"] == "opencv"]
    assert entry["backends"] == [{"name": "opencv", "default": True, "available": False, "reason": reason}]
    assert cli_main(["list"]) == 0  # the listing itself still works and shows why
    assert "UNAVAILABLE: " + reason in capsys.readouterr().out
    fresh = runpy.run_path(plugin.__file__)  # the module itself still executes without it
    assert fresh["SPEC"].unavailable_reason("opencv") == reason
    monkeypatch.undo()
    assert spec.unavailable_reason("opencv") is None


def test_opencv_error_becomes_solver_error(monkeypatch):
    data, _ = noisy_case()

    def broken(*args, **kwargs):
        raise cv2.error("simulated failure inside OpenCV")

    monkeypatch.setattr(cv2, "calibrateRobotWorldHandEye", broken)
    with pytest.raises(SolverError, match="simulated failure inside OpenCV"):
        handeye.solve("axyb", solver="opencv", **data)


def test_rotation_reprojected_only_when_off_so3(monkeypatch):
    data, _ = noisy_case()
    exact = handeye.solve("axyb", solver="opencv", **data)
    real = cv2.calibrateRobotWorldHandEye

    def sloppy(*args, **kwargs):  # as if OpenCV had computed R_base2world in float32
        R_bw, t_bw, R_gc, t_gc = real(*args, **kwargs)
        return R_bw * (1 + 1e-7), t_bw, R_gc, t_gc

    monkeypatch.setattr(cv2, "calibrateRobotWorldHandEye", sloppy)
    sol = handeye.solve("axyb", solver="opencv", **data)
    assert sol.diagnostics["reprojected"] == ["X"]
    assert orthonormality_error(sol.X[:3, :3]) < 1e-14
    np.testing.assert_allclose(sol.X, exact.X, rtol=0, atol=1e-12)
    assert sol.Y.tolist() == exact.Y.tolist()


def test_shah_is_unit_invariant_li_is_not():
    """Why unit invariance is declared for method "shah" only (module docstring)."""
    data, _ = noisy_case()
    small = {k: np.array(v) for k, v in data.items()}
    for T in small.values():
        T[:, :3, 3] *= 1e-3  # mm -> m
    for method, invariant in (("shah", True), ("li", False)):
        a = handeye.solve("axyb", solver="opencv", method=method, **data)
        b = handeye.solve("axyb", solver="opencv", method=method, **small)
        angle = float(rotation_angle(a.X[:3, :3] @ b.X[:3, :3].T))
        assert (angle < 1e-12) is invariant, (method, angle)
        assert handeye.get_registry().solver("opencv", "axyb").is_unit_invariant({"method": method}) is invariant
