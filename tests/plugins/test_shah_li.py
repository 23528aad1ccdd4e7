"""`shah` and `li` (our NumPy code) against OpenCV's methods of the same name, and their derivations."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import random_rotations
from handeye.plugins.shah import normalize_rotation
from handeye.problems.axyb import PROBLEM, random_truth, regression_blocks

if "opencv" not in handeye.get_registry().solver_names("axyb"):
    pytest.skip("the opencv reference plugin is not registered", allow_module_level=True)
_OPENCV_REASON = handeye.get_registry().solver("opencv", "axyb").unavailable_reason("opencv")
if _OPENCV_REASON:
    pytest.skip(_OPENCV_REASON, allow_module_level=True)

OURS = {"shah": {}, "li": {"normalize": False}}  # OpenCV does not normalise translations
NOISE = {
    "noise-free": None,
    "noise-B": NoiseModel.on("B", 0.01, 1.0),
    "noise-AB": NoiseModel.on(("A", "B"), 0.05, 5.0),
}


def opencv_solution(A: np.ndarray, B: np.ndarray, method: str) -> dict[str, np.ndarray]:
    """X, Y from OpenCV's method of that name, through the `opencv` plugin (its slot mapping:
    A -> world2cam, B -> base2gripper, X <- base2world, Y <- gripper2cam)."""
    return dict(handeye.solve("axyb", solver="opencv", method=method, A=A, B=B).unknowns)


def case(seed: int, noise: str, pairs: int = 20):
    if noise == "noise-free":  # random X, Y as well, not only the paper's
        truth = random_truth(np.random.default_rng(seed))
        return PROBLEM.simulate(pairs=pairs, seed=seed, X=truth["X"], Y=truth["Y"])
    return PROBLEM.simulate(pairs=pairs, seed=seed, noise=NOISE[noise])


@pytest.mark.parametrize("noise", list(NOISE))
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("method", ["shah", "li"])
def test_equals_opencv(method, seed, noise):
    data, _ = case(seed, noise)
    A, B = np.asarray(data["A"]), np.asarray(data["B"])
    ours = handeye.solve("axyb", solver=method, **OURS[method], **data)
    ref = opencv_solution(A, B, method)
    scale = PROBLEM.validate(**data).translation_scale
    for name in ("X", "Y"):
        np.testing.assert_allclose(ours.unknowns[name][:3, :3], ref[name][:3, :3], rtol=0, atol=1e-9)
        # translations in mm (~1e3): 1e-9 relative to the data's scale
        np.testing.assert_allclose(ours.unknowns[name][:3, 3], ref[name][:3, 3], rtol=0, atol=1e-9 * scale)


def test_li_normalised_differs_from_opencv_only_under_noise():
    free, _ = case(5, "noise-free")
    noisy, _ = case(5, "noise-AB")
    for data, same in ((free, True), (noisy, False)):
        a = handeye.solve("axyb", solver="li", normalize=True, **data)
        b = handeye.solve("axyb", solver="li", normalize=False, **data)
        close = np.allclose(a.X, b.X, atol=1e-7) and np.allclose(a.Y, b.Y, atol=1e-7)
        assert close is same


def test_shah_rotations_are_the_null_vector_of_the_stacked_eq6():
    """The leading singular pair of sum_i K_i is the null vector of [K_i, -I] stacked (derivation)."""
    data, _ = case(1, "noise-AB", pairs=8)
    A, B = np.asarray(data["A"]), np.asarray(data["B"])
    H, _ = regression_blocks(A, B)
    rot_rows = H[:, :9, :18].reshape(-1, 18)  # [R_B kron R_A, -I] per pair
    v = np.linalg.svd(rot_rows)[2][-1]
    ours = handeye.solve("axyb", solver="shah", **data)
    RX = normalize_rotation(v[:9].reshape(3, 3, order="F"))
    RY = normalize_rotation(v[9:].reshape(3, 3, order="F"))
    np.testing.assert_allclose(ours.X[:3, :3], RX, atol=1e-10)
    np.testing.assert_allclose(ours.Y[:3, :3], RY, atol=1e-10)


def test_li_rotations_are_those_of_kron_lstsq_on_eq8():
    """Li's system has the residual norm of eq. 8 pair by pair, so the same least-squares rotations."""
    data, _ = case(2, "noise-AB")
    for normalize in (True, False):
        li = handeye.solve("axyb", solver="li", normalize=normalize, **data)
        kron = handeye.solve("axyb", solver="kron-lstsq", normalize=normalize, **data)
        np.testing.assert_allclose(li.X[:3, :3], kron.X[:3, :3], atol=1e-8)
        np.testing.assert_allclose(li.Y[:3, :3], kron.Y[:3, :3], atol=1e-8)


def test_normalize_rotation():
    R = random_rotations(1, np.random.default_rng(0))[0]
    np.testing.assert_allclose(normalize_rotation(-2.5 * R), R, atol=1e-14)  # det < 0: sign fixed
    M = R + 0.01 * np.random.default_rng(1).standard_normal((3, 3))
    U, _, Vt = np.linalg.svd(M)
    np.testing.assert_allclose(normalize_rotation(7.0 * M), U @ Vt, atol=1e-14)
    with pytest.raises(handeye.DegenerateDataError):
        normalize_rotation(np.diag([1.0, 1.0, 0.0]))


@pytest.mark.parametrize("sequence", ["motion-000049", "motion-000060", "motion-000061"])
def test_li_semi_normal_solution_equals_the_qr_solution_on_weak_excitation(sequence):
    """li solves eq. 8 by the semi-normal equations with one correction step (plugins/li.py);
    on KinHEC's weakly excited motion sequences the uncorrected solution is off the QR least
    squares by up to 1.9e-9 (relative), the corrected one by 1.4e-14."""
    from pathlib import Path

    from handeye.plugins import li

    fixture = np.load(Path(__file__).parents[1] / "data" / "kinhec" / f"{sequence}.npz")
    data = PROBLEM.validate(A=fixture["A"], B=fixture["B"])
    beta_qr, _ = li.least_squares_beta_qr(data)
    beta, _, method = li.least_squares_beta(data)
    assert method == "seminormal"
    assert np.linalg.norm(beta - beta_qr) <= 1e-12 * np.linalg.norm(beta_qr)
