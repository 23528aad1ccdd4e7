"""The `dual-quaternion` solver (paper Sec. III.C) and the helpers of `handeye.geometry.dualquat`."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tolerances import solved

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.dualquat import (
    conjugate,
    dual_quat_from_pose,
    pose_from_dual_quat,
    q_left,
    q_right,
    quat_from_rotation,
    quat_multiply,
    rotation_from_quat,
)
from handeye.geometry.linalg import triangular_factor
from handeye.geometry.se3 import (
    quat_from_matrix,
    random_poses,
    random_rotations,
    so3_exp,
)
from handeye.plugins.dual_quaternion import (
    dq_matrix,
    pair_signs,
    solve_dual_quaternions,
)
from handeye.problems.axyb import PROBLEM, random_truth

finite = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
quaternion = st.lists(finite, min_size=4, max_size=4).map(np.array)


@settings(max_examples=60, deadline=None)
@given(quaternion, quaternion)
def test_eq25_left_and_right_product_matrices(a, b):
    """a b = Q_L(a) b = Q_R(b) a, the Hamilton product written out componentwise."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    hamilton = np.array([
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    ])
    np.testing.assert_allclose(quat_multiply(a, b), hamilton, atol=1e-9)
    np.testing.assert_allclose(q_left(a) @ b, hamilton, atol=1e-9)
    np.testing.assert_allclose(q_right(b) @ a, hamilton, atol=1e-9)


def test_quaternion_product_is_rotation_product():
    rng = np.random.default_rng(1)
    R1, R2 = random_rotations(20, rng), random_rotations(20, rng)
    q = quat_multiply(quat_from_rotation(R1), quat_from_rotation(R2))
    np.testing.assert_allclose(rotation_from_quat(q), R1 @ R2, atol=1e-12)
    assert np.all(quat_from_rotation(R1)[:, 0] >= 0)
    # unit quaternion: Q_L(q) and Q_R(q) are orthogonal, q* = q^-1
    Q = quat_from_rotation(R1)
    np.testing.assert_allclose(q_left(Q) @ np.swapaxes(q_left(Q), 1, 2), np.broadcast_to(np.eye(4), (20, 4, 4)), atol=1e-12)
    np.testing.assert_allclose(quat_multiply(Q, conjugate(Q)), np.tile([1.0, 0, 0, 0], (20, 1)), atol=1e-12)


def test_quat_from_rotation_matches_scipy_including_half_turns():
    rng = np.random.default_rng(3)
    half_turns = so3_exp(np.pi * np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.8, 0], [0, -0.6, 0.8]]))
    R = np.concatenate([random_rotations(200, rng), half_turns, np.eye(3)[None]])
    q = quat_from_rotation(R)
    ref = quat_from_matrix(R)[:, [3, 0, 1, 2]]
    np.testing.assert_allclose(np.abs(np.sum(q * ref, axis=1)), 1.0, atol=1e-14)  # same up to sign
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(rotation_from_quat(q), R, atol=1e-14)
    assert np.all(q[:, 0] >= 0)


def test_dual_quaternion_of_pose_products_and_round_trip():
    rng = np.random.default_rng(2)
    T1, T2 = random_poses(10, rng, 100.0), random_poses(10, rng, 100.0)
    a, ad = dual_quat_from_pose(T1)
    b, bd = dual_quat_from_pose(T2)
    np.testing.assert_allclose(np.sum(a * ad, axis=1), 0.0, atol=1e-12)  # q . q' = 0
    np.testing.assert_allclose(pose_from_dual_quat(a, ad), T1, atol=1e-12)
    # (a + eps a')(b + eps b') = a b + eps (a b' + a' b) is the dual quaternion of T1 T2 (same sign)
    c, cd = quat_multiply(a, b), quat_multiply(a, bd) + quat_multiply(ad, b)
    np.testing.assert_allclose(pose_from_dual_quat(c, cd), T1 @ T2, atol=1e-10)


def noise_free_case(seed: int, pairs: int = 12):
    truth = random_truth(np.random.default_rng(seed))
    return PROBLEM.simulate(pairs=pairs, seed=seed, X=truth["X"], Y=truth["Y"])


def true_signs_and_delta(data, truth):
    """Per-pair sign s_i with a_i x = s_i y b_i x (from the truth), and Delta* of eq. 24."""
    a, _ = dual_quat_from_pose(np.asarray(data["A"]))
    b, _ = dual_quat_from_pose(np.asarray(data["B"]))
    x, xd = dual_quat_from_pose(truth["X"])
    y, yd = dual_quat_from_pose(truth["Y"])
    s = np.sign(np.sum(quat_multiply(a, x) * quat_multiply(y, b), axis=1))
    return s, np.concatenate([x, xd, y, yd])


def test_eq24_holds_for_the_truth_and_has_a_two_dimensional_null_space():
    data, truth = noise_free_case(3)
    s, delta = true_signs_and_delta(data, truth)
    a, ad = dual_quat_from_pose(np.asarray(data["A"]))
    b, bd = dual_quat_from_pose(np.asarray(data["B"]))
    D = dq_matrix(a, ad, s[:, None] * b, s[:, None] * bd)
    assert D.shape == (8 * 12, 16)
    np.testing.assert_allclose(D @ delta, 0.0, atol=1e-10)
    eps_delta = np.concatenate([np.zeros(4), delta[:4], np.zeros(4), delta[8:12]])
    np.testing.assert_allclose(D @ eps_delta, 0.0, atol=1e-10)  # the dual unit times the solution
    sigma = np.linalg.svd(D, compute_uv=False)
    assert sigma[-1] < 1e-12 and sigma[-2] < 1e-12 and sigma[-3] > 1e-3
    # a wrong sign on one pair destroys the second null vector
    s_bad = s.copy()
    s_bad[4] *= -1
    D_bad = dq_matrix(a, ad, s_bad[:, None] * b, s_bad[:, None] * bd)
    assert np.linalg.svd(D_bad, compute_uv=False)[-2] > 1e-3


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_sign_rule_recovers_the_true_signs_from_data_alone(seed):
    data, truth = noise_free_case(seed, pairs=20)
    s_true, _ = true_signs_and_delta(data, truth)
    a, _ = dual_quat_from_pose(np.asarray(data["A"]))
    b, _ = dual_quat_from_pose(np.asarray(data["B"]))
    rng = np.random.default_rng(seed)
    flip = rng.choice([-1.0, 1.0], size=len(b))  # arbitrary input signs of b
    s, margin = pair_signs(a, flip[:, None] * b)
    assert margin > 0
    product = s * flip * s_true
    assert np.all(product == product[0])  # equal to the truth up to one global sign


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_free_recovery(seed, normalize):
    data, truth = noise_free_case(seed)
    sol = handeye.solve("axyb", solver="dual-quaternion", normalize=normalize, **data)
    scale = PROBLEM.validate(**data).translation_scale
    errors = PROBLEM.errors(sol.unknowns, truth)
    for name in ("X", "Y"):
        assert errors[name]["rotation"] < 1e-9
        assert errors[name]["translation"] < 1e-9 * scale
    d = sol.diagnostics
    assert d["orthogonality_real_root"] and d["sign_inconsistent_pairs"] == 0
    assert max(d["singular_values_tail"][1:]) < 1e-12 < d["singular_values_tail"][0]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_noisy_accuracy_close_to_kron_lstsq(seed):
    data, truth = PROBLEM.simulate(pairs=30, seed=seed, noise=NoiseModel.on("B", 0.005, 0.5))
    dq = PROBLEM.errors(handeye.solve("axyb", solver="dual-quaternion", **data).unknowns, truth)
    kron = PROBLEM.errors(handeye.solve("axyb", solver="kron-lstsq", **data).unknowns, truth)
    for name in ("X", "Y"):
        assert dq[name]["rotation"] < 2 * kron[name]["rotation"] + 1e-3
        assert dq[name]["translation"] < 3 * kron[name]["translation"] + 2.0


def test_heavy_noise_second_pass_keeps_signs_consistent():
    data, truth = PROBLEM.simulate(pairs=40, seed=9, noise=NoiseModel.on(("A", "B"), 0.1, 5.0))
    sol = handeye.solve("axyb", solver="dual-quaternion", **data)
    d = sol.diagnostics
    assert d["sign_inconsistent_pairs"] == 0
    errors = PROBLEM.errors(sol.unknowns, truth)
    assert errors["X"]["rotation"] < 0.2 and errors["Y"]["rotation"] < 0.2


@pytest.mark.parametrize("wrong", [[3], [0, 7]])
def test_second_pass_corrects_wrong_first_pass_signs(monkeypatch, wrong):
    """If the first sign choice is wrong for some pairs, the consistency check flips them back."""
    from handeye.plugins import dual_quaternion

    original = dual_quaternion.pair_signs

    def spoiled(a, b):
        s, margin = original(a, b)
        s = s.copy()
        s[wrong] *= -1
        return s, margin

    monkeypatch.setattr(dual_quaternion, "pair_signs", spoiled)
    data, truth = noise_free_case(4, pairs=15)
    sol = handeye.solve("axyb", solver="dual-quaternion", **data)
    d = sol.diagnostics
    assert d["sign_flips_second_pass"] == len(wrong) and d["sign_inconsistent_pairs"] == 0
    errors = PROBLEM.errors(sol.unknowns, truth)
    assert errors["X"]["rotation"] < 1e-9 and errors["Y"]["rotation"] < 1e-9


def _poses(sol):
    return pose_from_dual_quat(sol["x"], sol["xd"]), pose_from_dual_quat(sol["y"], sol["yd"])


@pytest.mark.parametrize("noise", [None, NoiseModel.on(("A", "B"), 0.02, 2.0)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_answer_does_not_depend_on_the_input_quaternion_signs(seed, noise):
    """Flipping the sign of any a_i (with a'_i) or b_i (with b'_i) leaves X and Y unchanged."""
    truth = random_truth(np.random.default_rng(seed))
    data, _ = PROBLEM.simulate(pairs=15, seed=seed, X=truth["X"], Y=truth["Y"], noise=noise)
    work = PROBLEM.validate(**data)
    work = work.scaled(work.translation_scale)
    a, ad = dual_quat_from_pose(work.A)
    b, bd = dual_quat_from_pose(work.B)
    X0, Y0 = _poses(solve_dual_quaternions(a, ad, b, bd))
    rng = np.random.default_rng(100 + seed)
    for _ in range(4):
        fa, fb = rng.choice([-1.0, 1.0], size=(2, len(a), 1))
        sol = solve_dual_quaternions(fa * a, fa * ad, fb * b, fb * bd)
        X, Y = _poses(sol)
        np.testing.assert_allclose(X, X0, atol=1e-11)
        np.testing.assert_allclose(Y, Y0, atol=1e-11)
        assert sol["wrong"] == 0


def test_solver_is_invariant_to_the_sign_the_conversion_gives(monkeypatch):
    """End to end: a conversion that returns arbitrary signs gives the same solution."""
    from handeye.plugins import dual_quaternion

    data, _ = PROBLEM.simulate(pairs=20, seed=6, noise=NoiseModel.on("B", 0.005, 0.5))
    reference = handeye.solve("axyb", solver="dual-quaternion", **data)
    rng = np.random.default_rng(6)
    original = dual_quaternion.dual_quat_from_pose

    def random_signs(T):
        q, qd = original(T)
        f = rng.choice([-1.0, 1.0], size=(len(q), 1))
        return f * q, f * qd

    monkeypatch.setattr(dual_quaternion, "dual_quat_from_pose", random_signs)
    for _ in range(3):
        sol = handeye.solve("axyb", solver="dual-quaternion", **data)
        for name in ("X", "Y"):
            np.testing.assert_allclose(sol.unknowns[name], reference.unknowns[name], atol=1e-9)


@pytest.mark.parametrize(("m", "r", "c"), [(2, 8, 16), (3, 12, 25), (17, 8, 16), (301, 8, 16), (1000, 12, 25)])
def test_tree_qr_factor_equals_the_qr_of_the_whole_stack(m, r, c):
    """One, two and three levels of chunks: R^T R = M^T M, and R equals numpy's R up to row signs."""
    blocks = np.random.default_rng(m).standard_normal((m, r, c)) * np.logspace(0, 3, c)
    R = triangular_factor(blocks)
    M = blocks.reshape(-1, c)
    R_ref = np.linalg.qr(M, mode="r")
    assert R.shape == (c, c)
    np.testing.assert_allclose(np.abs(R), np.abs(R_ref), rtol=1e-10, atol=1e-10 * np.abs(R_ref).max())
    np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False), np.linalg.svd(M, compute_uv=False), rtol=1e-11)


def _first_seed(make_data, condition, seeds=range(500)):
    """(seed, solution) of the first seed whose data make `condition(solution)` true."""
    for seed in seeds:
        sol = handeye.solve("axyb", solver="dual-quaternion", **make_data(seed))
        if condition(sol):
            return seed, sol
    pytest.fail("no seed in range gave the case under test")


def test_no_real_root_of_eq26_is_not_optimal():
    """Heavy noise on few pairs can make the quadratic of eq. 26 definite (no real root): the
    answer is an approximation, so status optimal_inaccurate, with the warning."""
    noise = NoiseModel.on(("A", "B"), 1.0, 50.0)
    seed, sol = _first_seed(lambda s: PROBLEM.simulate(pairs=3, seed=s, noise=noise)[0],
                            lambda sol: not sol.diagnostics["orthogonality_real_root"])
    assert sol.diagnostics.get("status_before_checks", sol.status) == handeye.Status.OPTIMAL_INACCURATE, seed
    assert sol.status is not handeye.Status.OPTIMAL
    assert any("has no real root" in w for w in sol.warnings)


def test_sign_inconsistent_pairs_are_not_optimal():
    """Unrelated A and B (pure noise) leave pairs sign-inconsistent after the second pass."""
    def unrelated(seed):
        rng = np.random.default_rng(seed)
        return {"A": random_poses(8, rng, 100.0), "B": random_poses(8, rng, 100.0)}

    seed, sol = _first_seed(unrelated, lambda sol: sol.diagnostics["sign_inconsistent_pairs"] > 0
                            and sol.diagnostics["orthogonality_real_root"])
    assert sol.diagnostics.get("status_before_checks", sol.status) == handeye.Status.OPTIMAL_INACCURATE, seed
    assert sol.status is not handeye.Status.OPTIMAL
    assert any("sign-inconsistent" in w for w in sol.warnings)


def test_clean_data_stay_optimal_without_warning():
    data, _ = PROBLEM.simulate(pairs=10, seed=4, noise=NoiseModel.on("B", 0.001, 0.1))
    sol = handeye.solve("axyb", solver="dual-quaternion", **data)
    assert solved(sol)
    assert not any(w.startswith("dual-quaternion") for w in sol.warnings)
