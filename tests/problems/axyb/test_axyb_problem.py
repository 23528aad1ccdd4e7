"""The AX=YB problem module: Kronecker system (eqs. 5-12), translations (eqs. 20-21), residuals
(eqs. 32-33), errors (eqs. 30-31), the simulator of Sec. IV-A and the excitation diagnostic."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, orthonormality_error, so3_exp
from handeye.problems.axyb import (
    PAPER_X,
    PAPER_Y,
    PROBLEM,
    AXYBData,
    random_truth,
    reduce_system,
    regression_blocks,
    solve_translations,
    split_beta,
)


def _beta(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """beta of eq. 8 written out: [vec(R_X); vec(R_Y); t_X; t_Y], vec column-major."""
    return np.concatenate([X[:3, :3].T.ravel(), Y[:3, :3].T.ravel(), X[:3, 3], Y[:3, 3]])


@pytest.fixture(scope="module")
def exact():
    truth = random_truth(np.random.default_rng(7))
    data, truth = PROBLEM.simulate(pairs=9, seed=7, X=truth["X"], Y=truth["Y"])
    return PROBLEM.validate(**data), truth


@pytest.fixture(scope="module")
def noisy():
    data, truth = PROBLEM.simulate(pairs=25, seed=8, noise=NoiseModel.on(("A", "B"), 0.01, 1.0))
    return PROBLEM.validate(**data), truth


def test_beta_true_satisfies_eq8_on_noise_free_data(exact):
    data, truth = exact
    H, w = regression_blocks(data.A, data.B)
    assert H.shape == (9, 12, 24) and w.shape == (9, 12)
    r = H @ _beta(truth["X"], truth["Y"]) - w
    assert np.max(np.abs(r)) < 1e-12 * data.translation_scale
    # and a wrong beta does not
    assert np.max(np.abs(H @ _beta(truth["Y"], truth["X"]) - w)) > 1e-3


def test_eq8_rows_by_hand(exact):
    """Pair 0 written as in the paper: R_A R_X - R_Y R_B = 0 and R_A t_X + t_A - R_Y t_B - t_Y = 0."""
    data, truth = exact
    H, w = regression_blocks(data.A[:1], data.B[:1])
    X, Y = truth["X"] + 0.1, truth["Y"] - 0.2  # any matrices: H beta - w is linear in them
    RA, tA, RB, tB = data.A[0, :3, :3], data.A[0, :3, 3], data.B[0, :3, :3], data.B[0, :3, 3]
    RX, tX, RY, tY = X[:3, :3], X[:3, 3], Y[:3, :3], Y[:3, 3]
    rot = (RA @ RX @ RB.T - RY).T.ravel()  # eq. 6 is R_A R_X R_B^T = R_Y in column-major vec
    trans = RY @ tB - RA @ tX + tY - tA  # eq. 7 sign convention: (t_B^T kron I) vec R_Y - R_A t_X + t_Y = t_A
    np.testing.assert_allclose((H[0] @ _beta(X, Y) - w[0])[:9], rot, atol=1e-9)
    np.testing.assert_allclose((H[0] @ _beta(X, Y) - w[0])[9:], trans, atol=1e-9)


def test_least_squares_equals_numpy_lstsq(noisy):
    data, _ = noisy
    H, w = regression_blocks(data.A, data.B)
    H, w = H.reshape(-1, 24), w.reshape(-1)
    reference, *_ = np.linalg.lstsq(H, w, rcond=None)
    system = data.kronecker_system
    beta = system.least_squares()
    assert np.linalg.norm(beta - reference) < 1e-10 * np.linalg.norm(reference)
    # the reduction is exact: R1^T R1 = H^T H, upper triangular, and rest = min |H beta - w|^2
    assert np.allclose(system.R1, np.triu(system.R1), rtol=0, atol=0)
    np.testing.assert_allclose(system.R1.T @ system.R1, H.T @ H, rtol=1e-10, atol=1e-8 * np.abs(H.T @ H).max())
    np.testing.assert_allclose(system.rest, np.sum((H @ reference - w) ** 2), rtol=1e-6)
    np.testing.assert_allclose(system.smallest_singular_value(), np.linalg.svd(H, compute_uv=False)[-1], rtol=1e-8)


def test_reduce_system_on_noise_free_data(exact):
    data, truth = exact
    system = reduce_system(data.A, data.B)
    beta = system.least_squares()
    np.testing.assert_allclose(beta, _beta(truth["X"], truth["Y"]), rtol=0, atol=1e-9 * data.translation_scale)
    assert system.rest < 1e-12 * data.translation_scale**2
    assert data.kronecker_system is data.kronecker_system  # built once


def test_split_beta_is_column_major(exact):
    _, truth = exact
    MX, MY, tX, tY = split_beta(_beta(truth["X"], truth["Y"]))
    np.testing.assert_array_equal(MX, truth["X"][:3, :3])
    np.testing.assert_array_equal(MY, truth["Y"][:3, :3])
    np.testing.assert_array_equal(tX, truth["X"][:3, 3])
    np.testing.assert_array_equal(tY, truth["Y"][:3, 3])


def test_solve_translations_given_true_rotations(exact):
    data, truth = exact
    tX, tY = solve_translations(data, truth["X"][:3, :3], truth["Y"][:3, :3])
    np.testing.assert_allclose(tX, truth["X"][:3, 3], atol=1e-9 * data.translation_scale)
    np.testing.assert_allclose(tY, truth["Y"][:3, 3], atol=1e-9 * data.translation_scale)


def test_solve_translations_equals_lstsq_on_the_explicit_rows(noisy):
    """Eqs. 20-21 solved from sums over the pairs = dense least squares on the stacked rows."""
    data, truth = noisy
    RX, RY = truth["X"][:3, :3], truth["Y"][:3, :3]
    RA, tA, tB = data.A[:, :3, :3], data.A[:, :3, 3], data.B[:, :3, 3]
    J = np.concatenate([RA, np.broadcast_to(-np.eye(3), RA.shape)], axis=2).reshape(-1, 6)
    reference, *_ = np.linalg.lstsq(J, (tB @ RY.T - tA).reshape(-1), rcond=None)
    np.testing.assert_allclose(np.concatenate(solve_translations(data, RX, RY)), reference,
                               rtol=0, atol=1e-10 * data.translation_scale)


def test_kronecker_at_a_scale_equals_the_system_of_scaled_data(noisy):
    """data.kronecker(s) (from sums taken once) = the system of the data with translations / s."""
    data, _ = noisy
    for s in (1.0, 250.0, 1e-3):
        direct, reference = data.kronecker(s), data.scaled(s).kronecker_system
        np.testing.assert_allclose(direct.R1, reference.R1, rtol=1e-12, atol=1e-12 * np.abs(reference.R1).max())
        np.testing.assert_allclose(direct.q1, reference.q1, rtol=1e-10, atol=1e-12 * np.abs(reference.q1).max())
        assert direct.rest == pytest.approx(reference.rest, rel=1e-8)
    assert data.kronecker(250.0) is data.kronecker(250.0)  # cached per scale


def test_residuals_zero_on_noise_free_data(exact):
    data, truth = exact
    res = PROBLEM.residuals(data, truth)
    assert res["rotation"].shape == res["translation"].shape == (data.m,)
    assert np.max(res["rotation"]) < 1e-12
    assert np.max(res["translation"]) < 1e-12 * data.translation_scale


def test_residuals_match_hand_computation(noisy):
    data, truth = noisy
    res = PROBLEM.residuals(data, truth)
    i = 4
    AX, YB = data.A[i] @ truth["X"], truth["Y"] @ data.B[i]
    D = AX[:3, :3] @ YB[:3, :3].T
    angle = np.arccos(np.clip((np.trace(D) - 1) / 2, -1, 1))  # fine for angles ~1e-2
    np.testing.assert_allclose(res["rotation"][i], angle, rtol=1e-8)
    np.testing.assert_allclose(res["translation"][i], np.linalg.norm(AX[:3, 3] - YB[:3, 3]), rtol=1e-12)
    assert np.all(res["rotation"] > 0)


def test_errors_against_truth():
    truth = {"X": PAPER_X, "Y": PAPER_Y}
    zero = PROBLEM.errors(truth, truth)
    assert zero == {"X": {"rotation": 0.0, "translation": 0.0}, "Y": {"rotation": 0.0, "translation": 0.0}}
    moved = {"X": make_pose(so3_exp([0.0, 0.0, 1e-9]) @ PAPER_X[:3, :3], PAPER_X[:3, 3] + [3.0, 4.0, 0.0]),
             "Y": make_pose(so3_exp([0.2, 0.0, 0.0]) @ PAPER_Y[:3, :3], PAPER_Y[:3, 3])}
    err = PROBLEM.errors(moved, truth)
    assert err["X"]["rotation"] == pytest.approx(1e-9, rel=1e-6)  # stable for tiny angles
    assert err["X"]["translation"] == pytest.approx(5.0, rel=1e-12)
    assert err["Y"]["rotation"] == pytest.approx(0.2, rel=1e-12)
    assert err["Y"]["translation"] == 0.0


def test_simulate_is_deterministic_per_seed():
    noise = NoiseModel.on("B", 0.01, 0.5)
    d1, t1 = PROBLEM.simulate(pairs=8, seed=3, noise=noise)
    d2, t2 = PROBLEM.simulate(pairs=8, seed=3, noise=noise)
    d3, _ = PROBLEM.simulate(pairs=8, seed=4, noise=noise)
    for k in ("A", "B"):
        np.testing.assert_array_equal(d1[k], d2[k])
        assert d1[k].shape == (8, 4, 4)
        assert not np.allclose(d1[k], d3[k])
    for k in ("X", "Y"):
        np.testing.assert_array_equal(t1[k], t2[k])


def test_simulate_follows_the_model():
    clean, truth = PROBLEM.simulate(pairs=10, seed=5)
    noisy, _ = PROBLEM.simulate(pairs=10, seed=5, noise=NoiseModel.on("B", 0.01, 0.5))
    np.testing.assert_array_equal(truth["X"], PAPER_X)
    np.testing.assert_array_equal(truth["Y"], PAPER_Y)
    # B_i = Y^-1 A_i X without noise; with noise on B only, A is the same poses
    np.testing.assert_allclose(clean["B"], inverse(PAPER_Y) @ clean["A"] @ PAPER_X, atol=1e-9)
    np.testing.assert_array_equal(noisy["A"], clean["A"])
    data = PROBLEM.validate(**noisy)
    res = PROBLEM.residuals(data, truth)
    assert 0.002 < np.median(res["rotation"]) < 0.05  # ~ sqrt(3) * 0.01 rad, chi with 3 dof
    # realistic arm: translations of the flange in mm, hundreds of mm from the base
    assert 100 < data.translation_scale < 5000


def test_simulate_rejects_bad_arguments():
    with pytest.raises(handeye.InputError, match="pairs must be >= 1"):
        PROBLEM.simulate(pairs=0, seed=1)
    with pytest.raises(handeye.InputError, match="unknown simulate option"):
        PROBLEM.simulate(pairs=3, seed=1, noise_level=2)
    with pytest.raises(handeye.InputError, match="noise for B"):
        NoiseModel.on("B", -0.1, 0.5)


@pytest.mark.parametrize("T", [PAPER_X, PAPER_Y], ids=["X", "Y"])
def test_paper_truth_is_se3_and_close_to_printed(T):
    R = T[:3, :3]
    assert orthonormality_error(R) < 1e-14
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])
    printed = {id(PAPER_X): [[0.0162, 0.9995, 0.0289], [-0.9996, 0.0168, -0.0207], [-0.0211, -0.0285, 0.9994]],
               id(PAPER_Y): [[-0.9990, -0.0327, 0.0279], [0.0274, 0.0155, 0.9995], [-0.0331, 0.9994, -0.0146]]}
    np.testing.assert_allclose(R, printed[id(T)], atol=1e-3)


def test_scaled_and_translation_scale(noisy):
    data, _ = noisy
    s = 250.0
    small = data.scaled(s)
    np.testing.assert_allclose(small.A[:, :3, 3] * s, data.A[:, :3, 3], rtol=1e-15)
    np.testing.assert_array_equal(small.B[:, :3, :3], data.B[:, :3, :3])
    assert small.translation_scale == pytest.approx(data.translation_scale / s, rel=1e-14)
    t = np.concatenate([data.A[:, :3, 3], data.B[:, :3, 3]])
    assert data.translation_scale == pytest.approx(np.sqrt(np.mean(np.sum(t**2, axis=1))), rel=1e-14)


def test_validated_data_is_a_read_only_copy(noisy):
    raw, _ = PROBLEM.simulate(pairs=5, seed=1)
    data = PROBLEM.validate(**raw)
    assert isinstance(data, AXYBData) and data.m == 5
    assert data.A is not raw["A"] and not data.A.flags.writeable and not data.B.flags.writeable
    assert raw["A"].flags.writeable
    with pytest.raises(handeye.InputError, match="takes data"):
        PROBLEM.validate(A=raw["A"], B=raw["B"], C=raw["A"])


def test_rotation_excitation_diagnostic(noisy):
    data, _ = noisy
    assert 0.05 < data.rotation_excitation <= 1.0
    assert PROBLEM.diagnose(data)["warnings"] == []
    sol = handeye.solve("axyb", solver="kron-lstsq", A=data.A, B=data.B)
    assert sol.warnings == [] and sol.diagnostics["data"]["rotation_excitation"] == data.rotation_excitation

    # weak data: rotations about z plus 1e-3 rad wobble: the excitation is a figure, the warning
    # (how well these data determine X and Y at their noise) is the self-check's (test_self_check)
    rng = np.random.default_rng(0)
    m = 8
    wobble = so3_exp(1e-3 * rng.standard_normal((m, 3)))
    A = make_pose(so3_exp(np.outer(rng.uniform(-2, 2, m), [0, 0, 1.0])) @ wobble, 300 * rng.standard_normal((m, 3)))
    B = inverse(PAPER_Y) @ A @ PAPER_X
    weak = PROBLEM.validate(A=A, B=B, tz_X=0.0)  # one axis: planar (tests/problems/test_planar.py)
    assert weak.planar is not None and 0 < weak.rotation_excitation < 1e-4
    assert PROBLEM.diagnose(weak)["warnings"] == []


def _huge(factor: float = 1e160) -> dict[str, np.ndarray]:
    """Finite SE(3) data whose translations (paper simulation, mm, times `factor`) are so large
    that their squares overflow float64."""
    data, _ = PROBLEM.simulate(pairs=10, seed=1)
    A, B = data["A"].copy(), data["B"].copy()
    A[:, :3, 3] *= factor
    B[:, :3, 3] *= factor
    return {"A": A, "B": B}


def test_large_but_summable_translations_still_solve():
    data = _huge(1e140)
    sol = handeye.solve("axyb", solver="kron-lstsq", **data)
    errors = PROBLEM.errors(sol.unknowns, {"X": PAPER_X, "Y": PAPER_Y})
    assert errors["X"]["rotation"] < 1e-8 and errors["Y"]["rotation"] < 1e-8


def test_reduce_normal_equations_refuses_overflowed_sums():
    """Below validation too (reduce_system takes raw stacks): non-finite normal equations are an
    InputError naming the overflow, not scipy's "array must not contain infs or NaNs"."""
    data = _huge()
    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(handeye.InputError, match="sums of the linear system overflow"):
        reduce_system(data["A"], data["B"])


def test_validate_names_a_missing_or_unexpected_field():
    """Called directly (not through handeye.solve), validation still says what is missing."""
    data, _ = PROBLEM.simulate(pairs=5, seed=1)
    with pytest.raises(handeye.InputError, match=r"needs data \['A', 'B'\]; missing \['B'\]"):
        PROBLEM.validate(A=data["A"])
    with pytest.raises(handeye.InputError, match=r"takes data \['A', 'B'\], not \['C'\]"):
        PROBLEM.validate(**data, C=data["A"])


def test_a_robot_that_barely_rotates_is_refused():
    """Stations whose rotations differ by ~1e-6 rad (a robot that only translates, with encoder
    jitter) leave the rotations of X and Y undetermined: rotation excitation ~4e-13, below the
    threshold (1e-10), so validation refuses them rather than solving the jitter."""
    from handeye.problems.axyb import PAPER_X, PAPER_Y

    rng = np.random.default_rng(1)
    R = so3_exp(np.array([0.3, -0.2, 0.5])) @ so3_exp(1e-6 * rng.standard_normal((12, 3)))
    t = np.array([400.0, 0.0, 300.0]) + rng.uniform(-150.0, 150.0, (12, 3))
    A = np.stack([make_pose(R[k], t[k]) for k in range(12)])
    with pytest.raises(handeye.DegenerateDataError, match="rotate about fewer than two different axes"):
        handeye.solve("axyb", A=A, B=inverse(PAPER_Y) @ A @ PAPER_X)
