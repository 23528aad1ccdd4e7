"""The classic AX=XB methods (plugins/classic_handeye.py: tsai, park, horaud, andreff,
daniilidis) against OpenCV's ``cv2.calibrateHandEye``, and the `opencv` solver's ``axxb`` spec."""

from __future__ import annotations

import numpy as np
import pytest
from tolerances import solved

import handeye
from handeye.base.errors import (
    BackendUnavailableError,
    DegenerateDataError,
    InputError,
)
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import (
    inverse,
    make_pose,
    orthonormality_error,
    random_poses,
    rotation_angle,
    so3_exp,
)
from handeye.plugins import classic_handeye as classic
from handeye.plugins import opencv as opencv_plugin
from handeye.problems.axxb import motions

cv2 = pytest.importorskip("cv2")
if not hasattr(cv2, "calibrateHandEye"):
    pytest.skip("this OpenCV has no calibrateHandEye", allow_module_level=True)

METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis")
FUNCTIONS = {name: getattr(classic, name) for name in METHODS}
FLAGS = {name: getattr(cv2, f"CALIB_HAND_EYE_{name.upper()}") for name in METHODS}
UNIT_INVARIANT = {"tsai": True, "park": True, "horaud": True, "andreff": False, "daniilidis": False}
TOL = 1e-12  # rotation [rad]; translation relative to |t|
#: cases: (seed, noise, wide): wide draws uniform robot rotations (motions beyond 120 deg, where
#: the quaternion sign alignment matters) instead of the arm's joint box
CASES = {
    "flange-0": (0, False, False), "flange-1": (1, False, False), "flange-2": (2, False, False),
    "flange-0-noisy": (0, True, False), "flange-1-noisy": (1, True, False), "flange-2-noisy": (2, True, False),
    "wide-3": (3, False, True), "wide-3-noisy": (3, True, True),
}


def cell(seed: int, noise: bool = False, wide: bool = False, n: int = 10):
    """Absolute poses G = T_base_gripper, C = T_cam_target: (n, 4, 4) of an eye-in-hand cell and
    the true X = T_gripper_cam; G_k X C_k = W (T_base_target) for every k when noise-free."""
    rng = np.random.default_rng(seed)
    G = random_poses(n, rng, 300.0) if wide else random_flange_poses(n, rng)
    X = random_poses(1, rng, 100.0)[0]
    W = random_poses(1, rng, 1000.0)[0]
    C = inverse(X) @ inverse(G) @ W
    if noise:  # 0.01 rad and 1 mm on every absolute pose
        G = G @ make_pose(so3_exp(0.01 * rng.standard_normal((n, 3))), rng.standard_normal((n, 3)))
        C = C @ make_pose(so3_exp(0.01 * rng.standard_normal((n, 3))), rng.standard_normal((n, 3)))
    return G, C, X


def opencv_motions(G: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The motions calibrateHandEye forms: every i < j (i outer), inv(G_j) G_i and C_j inv(C_i)."""
    i, j = np.triu_indices(len(G), k=1)
    return inverse(G[j]) @ G[i], C[j] @ inverse(C[i])


def cv2_hand_eye(G: np.ndarray, C: np.ndarray, method: str) -> np.ndarray:
    R, t = cv2.calibrateHandEye(list(G[:, :3, :3]), list(G[:, :3, 3]), list(C[:, :3, :3]),
                                list(C[:, :3, 3]), method=FLAGS[method])
    return make_pose(R, np.ravel(t))


def assert_same(X: np.ndarray, ref: np.ndarray, tol: float = TOL) -> None:
    angle = float(rotation_angle(X[:3, :3] @ ref[:3, :3].T))
    gap = float(np.linalg.norm(X[:3, 3] - ref[:3, 3]))
    assert angle < tol, angle
    assert gap < tol * np.linalg.norm(ref[:3, 3]), (gap, ref[:3, 3])


def assert_se3(X: np.ndarray) -> None:
    assert X.shape == (4, 4) and X[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    assert orthonormality_error(X[:3, :3]) < 1e-12 and np.linalg.det(X[:3, :3]) > 0


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("method", METHODS)
def test_equals_opencv(method, case):
    seed, noise, wide = CASES[case]
    G, C, truth = cell(seed, noise, wide)
    A, B = opencv_motions(G, C)
    ours = FUNCTIONS[method](A, B)
    assert_se3(ours)
    assert_same(ours, cv2_hand_eye(G, C, method))  # measured <= 1e-13 (rotation and translation)
    if not noise:
        assert_same(ours, truth)


def test_motions_helper_pairs_as_opencv():
    G, C, _ = cell(5, noise=True)
    data = motions(G, C, pairing="all")
    A, B = opencv_motions(G, C)
    np.testing.assert_allclose(data["A"], A, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data["B"], B, rtol=0, atol=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_registered_solver(method):
    G, C, _ = cell(6, noise=True)
    A, B = opencv_motions(G, C)
    sol = handeye.solve("axxb", solver=method, A=A, B=B)
    assert sol.X.tolist() == FUNCTIONS[method](A, B).tolist()
    assert solved(sol) and sol.diagnostics
    spec = handeye.get_registry().solver(method, "axxb")
    assert spec.problems == ("axxb",) and spec.citation and spec.summary
    assert spec.is_unit_invariant() is UNIT_INVARIANT[method]


def test_tsai_uses_opencvs_selection_of_motions():
    G, C, _ = cell(7, noise=True)
    A, B = opencv_motions(G, C)
    sol = handeye.solve("axxb", solver="tsai", A=A, B=B)
    assert 2 <= sol.diagnostics["motions_used"] < len(A)  # some pairs rotate < 17 deg here
    all_motions = handeye.solve("axxb", solver="tsai", select_motions=False, A=A, B=B)
    assert rotation_angle(sol.X[:3, :3] @ all_motions.X[:3, :3].T) > 1e-6
    assert all_motions.diagnostics["motions_used"] == len(A)


def small_rotation_cell():
    """Robot poses rotating by at most ~6 deg between stations (axes vary): Tsai as OpenCV
    selects no motion, the other methods solve."""
    rng = np.random.default_rng(8)
    G = make_pose(so3_exp(0.03 * rng.standard_normal((6, 3))), 100.0 * rng.standard_normal((6, 3)))
    X, W = random_poses(2, rng, 100.0)
    return G, inverse(X) @ inverse(G) @ W, X


def test_tsai_refuses_too_small_rotations():
    G, C, truth = small_rotation_cell()
    A, B = opencv_motions(G, C)
    with pytest.raises(DegenerateDataError, match="select_motions=False"):
        classic.tsai(A, B)
    assert_same(classic.tsai(A, B, select_motions=False), truth, 1e-8)
    with pytest.raises(DegenerateDataError, match="OpenCV's Tsai"):  # OpenCV only logs and returns I
        handeye.solve("axxb", solver="opencv", method="tsai", **motions(G, C))
    assert_same(handeye.solve("axxb", solver="opencv", method="park", **motions(G, C)).X, truth, 1e-8)


@pytest.mark.parametrize("method", METHODS)
def test_parallel_axes_are_degenerate(method):
    rng = np.random.default_rng(9)
    angles = np.deg2rad([30.0, 50.0, -70.0, 90.0, 40.0])
    A = make_pose(so3_exp(angles[:, None] * np.array([0.0, 0.6, 0.8])), 100.0 * rng.standard_normal((5, 3)))
    X = random_poses(1, rng, 100.0)[0]
    B = inverse(X) @ A @ X
    with pytest.raises(DegenerateDataError, match="two different axes"):
        FUNCTIONS[method](A, B)
    with pytest.raises(DegenerateDataError):  # also refused by the problem's validation
        handeye.solve("axxb", solver=method, A=A, B=B)


@pytest.mark.parametrize("method", METHODS)
def test_two_motions_suffice(method):
    rng = np.random.default_rng(10)
    A = make_pose(so3_exp([[0.6, 0.0, 0.1], [0.0, 0.7, -0.2]]), 100.0 * rng.standard_normal((2, 3)))
    X = random_poses(1, rng, 100.0)[0]
    assert_same(FUNCTIONS[method](A, inverse(X) @ A @ X), X)


def test_bad_shapes():
    A = np.tile(np.eye(4), (3, 1, 1))
    with pytest.raises(InputError, match=r"shape \(m, 4, 4\)"):
        classic.park(A[:, :3], A)
    with pytest.raises(InputError, match="same number"):
        classic.park(A, A[:2])


def test_inputs_unmodified():
    G, C, _ = cell(11, noise=True)
    A, B = opencv_motions(G, C)
    data = motions(G, C)
    kept = [T.copy() for T in (A, B, data["A"], data["B"])]
    for T in (A, B, data["A"], data["B"]):
        T.flags.writeable = False  # any write raises
    for method in METHODS:
        FUNCTIONS[method](A, B)
        handeye.solve("axxb", solver=method, A=A, B=B)
        handeye.solve("axxb", solver="opencv", method=method, **data)
    for T, before in zip((A, B, data["A"], data["B"]), kept):
        assert T.tolist() == before.tolist()


@pytest.mark.parametrize("solver", [*METHODS, *(f"opencv:{m}" for m in METHODS)])
def test_unit_invariance_as_declared(solver):
    name, _, method = solver.partition(":")
    options = {"method": method} if method else {}
    G, C, _ = cell(12, noise=True)
    data = motions(G, C) if method else dict(zip("AB", opencv_motions(G, C)))
    base = handeye.solve("axxb", solver=name, **options, **data).X
    changes = []
    for s in (1e-3, 1e3):
        scaled = {k: v.copy() for k, v in data.items()}
        for T in scaled.values():
            T[:, :3, 3] *= s
        X = handeye.solve("axxb", solver=name, **options, **scaled).X
        changes.append(max(float(rotation_angle(X[:3, :3] @ base[:3, :3].T)),
                           float(np.linalg.norm(X[:3, 3] / s - base[:3, 3]) / np.linalg.norm(base[:3, 3]))))
    declared = handeye.get_registry().solver(name, "axxb").is_unit_invariant(options)
    assert declared is UNIT_INVARIANT[method or name]
    if declared:
        assert max(changes) < 1e-12, changes
    else:  # measured: ~1e-2 at s = 1e-3 (mm -> m), ~1e-6 at s = 1e3
        assert max(changes) > 1e-6, changes


@pytest.mark.parametrize("noise", [False, True])
@pytest.mark.parametrize("method", METHODS)
def test_opencv_axxb_on_consecutive_motions_equals_cv2_on_the_poses(method, noise):
    G, C, _ = cell(13, noise)
    sol = handeye.solve("axxb", solver="opencv", method=method, **motions(G, C))
    assert_same(sol.X, cv2_hand_eye(G, C, method))  # measured <= 1e-14
    assert sol.diagnostics["method"] == method and sol.diagnostics["reprojected"] == []
    assert sol.backend == "opencv" and solved(sol)


def test_opencv_axxb_default_method_and_chain():
    G, C, _ = cell(14, noise=True)
    data = motions(G, C)
    default = handeye.solve("axxb", solver="opencv", **data)
    assert default.diagnostics["method"] == "park"
    assert default.X.tolist() == handeye.solve("axxb", solver="opencv", method="park", **data).X.tolist()
    chain_G, chain_H = opencv_plugin.absolute_chain(data["A"], data["B"])
    np.testing.assert_allclose(inverse(chain_G[1:]) @ chain_G[:-1], data["A"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(chain_H[1:] @ inverse(chain_H[:-1]), data["B"], rtol=0, atol=1e-9)


def test_opencv_axxb_options_and_availability(monkeypatch):
    G, C, _ = cell(15)
    data = motions(G, C)
    with pytest.raises(InputError, match=r"method='shah'.*'tsai'.*'daniilidis'"):
        handeye.solve("axxb", solver="opencv", method="shah", **data)
    monkeypatch.delattr(cv2, "calibrateHandEye")
    spec = handeye.get_registry().solver("opencv", "axxb")
    reason = spec.unavailable_reason("opencv")
    assert reason and "no cv2.calibrateHandEye" in reason and "opencv-python-headless" in reason
    with pytest.raises(BackendUnavailableError, match="calibrateHandEye"):
        handeye.solve("axxb", solver="opencv", **data)
    assert handeye.get_registry().solver("opencv", "axyb").unavailable_reason("opencv") is None


def test_daniilidis_says_when_its_constraints_have_no_exact_solution():
    """Very noisy motions (0.2 rad, 50 mm on 5 stations): the quadratic of eqs. 34-35 has no real
    root; the answer is not claimed optimal and a warning says why and what to use."""
    from handeye.estimation.noise import NoiseModel
    from handeye.problems.axxb import PROBLEM

    data, _ = PROBLEM.simulate(pairs=4, seed=0, noise=NoiseModel.on(("A", "B"), 0.2, 50.0))
    sol = handeye.solve("axxb", solver="daniilidis", **data)
    assert sol.diagnostics["discriminant"] < 0
    # its own status, which the host's checks then make unreliable: 4 motions this noisy determine nothing
    assert sol.diagnostics["status_before_checks"] == handeye.Status.OPTIMAL_INACCURATE
    assert sol.status is handeye.Status.UNRELIABLE
    assert any("too noisy" in w and "'auto'" in w for w in sol.warnings)
    clean, _ = PROBLEM.simulate(pairs=4, seed=0)
    assert handeye.solve("axxb", solver="daniilidis", **clean).status is handeye.Status.OPTIMAL
