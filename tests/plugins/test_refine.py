"""Tests of the `refine` solver (plugins/refine.py): model, Jacobians, weights, losses, covariance,
init handling. The shared suite (test_solvers.py) adds noise-free / noisy / invariance checks."""

from __future__ import annotations

import numpy as np
import pytest
from tolerances import solved

import handeye
from handeye.base.errors import InputError, UnknownPluginError
from handeye.estimation import lm_objective, nlls
from handeye.estimation.noise import NoiseModel
from handeye.estimation.whitening import estimate_sigmas
from handeye.geometry.se3 import make_pose, rotation_angle, so3_exp
from handeye.plugins import refine as R
from handeye.problems.axxb import PROBLEM as AXXB
from handeye.problems.axxb.geometry import AXXBModel
from handeye.problems.axyb import PROBLEM, random_truth
from handeye.problems.axyb.geometry import AXYBModel

NOISE = NoiseModel({"B": (0.002, 0.5), "A": (0.0002, 0.05)})


def _perturb(T, rng, rot=0.05, trans=20.0):
    return make_pose(T[:3, :3] @ so3_exp(rot * rng.standard_normal(3)), T[:3, 3] + trans * rng.standard_normal(3))


def _errors(sol, truth):
    return PROBLEM.errors(sol.unknowns, truth)


@pytest.fixture(scope="module")
def noisy16():
    return PROBLEM.simulate(pairs=16, seed=7, noise=NOISE)


def test_noise_free_recovery_from_perturbed_init():
    rng = np.random.default_rng(3)
    truth = random_truth(rng)
    data, _ = PROBLEM.simulate(pairs=10, seed=3, X=truth["X"], Y=truth["Y"])
    X0, Y0 = _perturb(truth["X"], rng), _perturb(truth["Y"], rng)
    sol = handeye.solve("axyb", solver="refine", init_X=X0, init_Y=Y0, **data)
    scale = PROBLEM.validate(**data).translation_scale
    err = _errors(sol, truth)
    assert sol.status == handeye.Status.OPTIMAL and sol.diagnostics["converged"]
    for name in ("X", "Y"):
        assert err[name]["rotation"] < 1e-10
        assert err[name]["translation"] < 1e-10 * scale
    assert sol.diagnostics["init"] == "given"


def test_residual_definition_matches_problem_residuals(noisy16):
    data, truth = noisy16
    d = PROBLEM.validate(**data)
    e = AXYBModel(d).residuals((truth["X"], truth["Y"]))
    ref = PROBLEM.residuals(d, truth)
    np.testing.assert_allclose(np.linalg.norm(e[:, :3], axis=1), ref["rotation"], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(e[:, 3:], axis=1), ref["translation"], rtol=1e-12)


@pytest.mark.parametrize("residual_angle", [0.0, 0.3, 2.5])
def test_analytic_jacobian_matches_finite_differences(residual_angle):
    """Central differences of e_i(X exp(xi_X), Y exp(xi_Y)) against `jacobian`, including large
    rotation residuals where Jl^-1 differs from the identity."""
    rng = np.random.default_rng(11)
    truth = random_truth(rng)
    data, _ = PROBLEM.simulate(pairs=6, seed=11, X=truth["X"], Y=truth["Y"])
    d = PROBLEM.validate(**data)
    P = AXYBModel(d)
    X = make_pose(truth["X"][:3, :3] @ so3_exp(residual_angle * np.array([0.6, -0.48, 0.64])),
                  truth["X"][:3, 3] + 30.0 * rng.standard_normal(3))
    Y = _perturb(truth["Y"], rng, rot=0.01, trans=10.0)
    e = P.residuals((X, Y))
    J = P.jacobian((X, Y), e)
    h = 1e-6
    Jfd = np.zeros_like(J)
    for k in range(12):
        xi = np.zeros(12)
        xi[k] = h
        ep = P.residuals(nlls.retract_all((X, Y), xi))
        em = P.residuals(nlls.retract_all((X, Y), -xi))
        Jfd[:, :, k] = (ep - em) / (2 * h)
    np.testing.assert_allclose(J, Jfd, atol=1e-6 * max(1.0, np.abs(J).max()), rtol=1e-6)


def test_refine_is_more_accurate_than_kronecker_and_matches_oracle(noisy16):
    data, truth = noisy16
    kron = handeye.solve("axyb", solver="kron-lstsq", **data)
    ref = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
    oracle = handeye.solve("axyb", solver="refine", init_X=truth["X"], init_Y=truth["Y"], **data)
    # the same estimator from the truth lands on the same optimum (one smooth objective, the
    # profile likelihood, whatever the start)
    assert ref.diagnostics["weight_mode"] == oracle.diagnostics["weight_mode"] == "profile"
    np.testing.assert_allclose(ref.X[:3, :3], oracle.X[:3, :3], rtol=0, atol=1e-11)
    np.testing.assert_allclose(ref.Y[:3, :3], oracle.Y[:3, :3], rtol=0, atol=1e-11)
    np.testing.assert_allclose(ref.X[:3, 3], oracle.X[:3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.Y[:3, 3], oracle.Y[:3, 3], rtol=0, atol=1e-9)
    ek, er = _errors(kron, truth), _errors(ref, truth)
    assert er["Y"]["rotation"] < ek["Y"]["rotation"]
    assert ref.diagnostics["init"] == "kron-lstsq" and ref.diagnostics["init_status"] == "optimal"


def test_cost_never_increases(noisy16):
    data, truth = noisy16
    rng = np.random.default_rng(5)
    for init in ({"init": "kron-lstsq"}, {"init_X": _perturb(truth["X"], rng), "init_Y": _perturb(truth["Y"], rng)},
                 {"init": "kron-lstsq", "loss": "cauchy"}, {"init": "kron-lstsq", "sigma_rot": 0.01, "sigma_trans": 0.1}):
        d = handeye.solve("axyb", solver="refine", **init, **data).diagnostics
        assert d["final_cost"] <= d["initial_cost"]
        assert d["iterations"] >= 1


def test_stated_sigmas_with_the_estimated_ratio_give_the_same_optimum(noisy16):
    data, _ = noisy16
    est = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
    assert est.diagnostics["weights"] == "estimated"
    k = 3.7  # overall scale is irrelevant for least squares, only the ratio matters
    stated = handeye.solve("axyb", solver="refine", init="kron-lstsq", sigma_rot=k * est.diagnostics["sigma_rot"],
                           sigma_trans=k * est.diagnostics["sigma_trans"], **data)
    assert stated.diagnostics["weights"] == "stated"
    np.testing.assert_allclose(stated.X, est.X, atol=1e-9 * 100)
    np.testing.assert_allclose(stated.Y, est.Y, atol=1e-9 * 1000)
    # ... and a full 6x6 covariance with the same diagonal is the same weighting
    cov = np.diag([est.diagnostics["sigma_rot"] ** 2] * 3 + [est.diagnostics["sigma_trans"] ** 2] * 3)
    full = handeye.solve("axyb", solver="refine", init="kron-lstsq", covariance=cov, **data)
    np.testing.assert_allclose(full.Y, est.Y, atol=1e-6)
    # a different ratio gives a different optimum (the weights are used)
    other = handeye.solve("axyb", solver="refine", init="kron-lstsq", sigma_rot=1.0, sigma_trans=1e-3, **data)
    assert np.abs(other.Y - est.Y).max() > 1e-6


def test_robust_losses_downweight_a_gross_outlier():
    data, truth = PROBLEM.simulate(pairs=20, seed=21, noise=NOISE)
    A = np.array(data["A"])
    A[4] = make_pose(A[4, :3, :3] @ so3_exp([0.5, 0.0, 0.0]), A[4, :3, 3] + [100.0, 0.0, 0.0])
    data = {"A": A, "B": data["B"]}
    errs = {}
    for loss in ("linear", "huber", "cauchy"):
        sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", loss=loss, **data)
        assert sol.diagnostics["loss"] == loss
        e = _errors(sol, truth)
        errs[loss] = (max(e["X"]["rotation"], e["Y"]["rotation"]), max(e["X"]["translation"], e["Y"]["translation"]))
    for loss in ("huber", "cauchy"):
        assert errs[loss][0] < 0.25 * errs["linear"][0]
        assert errs[loss][1] < 0.25 * errs["linear"][1]


def test_covariance_is_symmetric_psd_and_shrinks_with_more_pairs():
    stds = []
    for m in (10, 40):
        data, _ = PROBLEM.simulate(pairs=m, seed=31, noise=NOISE)
        d = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data).diagnostics
        for name in ("X", "Y"):
            C = np.array(d["covariance"][name])
            assert C.shape == (6, 6)
            np.testing.assert_allclose(C, C.T, rtol=0, atol=1e-15 * np.abs(C).max())
            assert np.linalg.eigvalsh(C).min() > 0
        full = np.array(d["covariance_XY"])
        assert full.shape == (12, 12) and np.linalg.eigvalsh(full).min() > 0
        stds.append([d["std"][n][q] for n in ("X", "Y") for q in ("rotation", "translation")])
    assert np.all(np.array(stds[1]) < np.array(stds[0]))


def test_covariance_predicts_the_spread_of_the_estimate():
    """Over repeated noise draws, the predicted std of Y's rotation matches the observed one
    within a factor of 1.5 (a calibration check of (J^T W J)^-1 times the variance factor)."""
    errs, pred = [], []
    for seed in range(12):
        data, truth = PROBLEM.simulate(pairs=30, seed=100 + seed, noise=NOISE)
        sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
        errs.append(_errors(sol, truth)["Y"]["rotation"])
        pred.append(sol.diagnostics["std"]["Y"]["rotation"])
    rms, predicted = np.sqrt(np.mean(np.square(errs))), np.sqrt(np.mean(np.square(pred)))
    assert predicted / 1.5 < rms < predicted * 1.5


def test_iteration_limit_reports_not_converged(noisy16):
    data, _ = noisy16
    sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", max_iter=1, **data)
    assert sol.status == handeye.Status.NOT_CONVERGED
    assert not sol.diagnostics["converged"] and sol.diagnostics["warnings"]


def test_unknown_init_lists_solvers(noisy16):
    data, _ = noisy16
    with pytest.raises(UnknownPluginError) as info:
        handeye.solve("axyb", solver="refine", init="no-such-solver", **data)
    assert "kron-lstsq" in str(info.value)


@pytest.mark.parametrize("init", ["refine", "auto"])
def test_recursive_init_is_rejected(noisy16, init):
    data, _ = noisy16
    with pytest.raises(InputError, match="init"):
        handeye.solve("axyb", solver="refine", init=init, **data)


@pytest.mark.parametrize("bad", [
    {"loss": "l1"}, {"loss_scale": 0.0}, {"max_iter": 0}, {"tol": -1.0},
    {"sigma_rot": 0.01}, {"sigma_rot": 0.01, "sigma_trans": -1.0},
    {"sigma_rot": 0.01, "sigma_trans": 0.5, "covariance": np.eye(6)},
    {"covariance": -np.eye(6)}, {"covariance": np.eye(5)},
    {"init_X": np.eye(4)}, {"init_X": np.eye(3), "init_Y": np.eye(4)},
])
def test_bad_options_raise_input_error(noisy16, bad):
    data, _ = noisy16
    with pytest.raises(InputError):
        handeye.solve("axyb", solver="refine", **bad, **data)


def test_inputs_untouched(noisy16):
    data, truth = noisy16
    copies = {k: np.array(v) for k, v in data.items()}
    X0 = np.array(truth["X"])
    handeye.solve("axyb", solver="refine", init_X=X0, init_Y=truth["Y"], **data)
    for k in data:
        np.testing.assert_array_equal(data[k], copies[k])
    np.testing.assert_array_equal(X0, truth["X"])


def test_default_init_is_registered():
    assert R.default_init() in handeye.list_solvers("axyb")
    spec = handeye.get_registry().solvers.get("so3-sdp", {}).get("axyb")
    if spec is not None and spec.unavailable_reason(spec.default_backend) is None:
        assert R.default_init() == "so3-sdp"
    else:
        assert R.default_init() == "kron-lstsq"


def test_unit_invariance_with_robust_loss(noisy16):
    data, _ = noisy16
    base = handeye.solve("axyb", solver="refine", init="kron-lstsq", loss="huber", **data)
    s = 1e-3
    scaled = {k: np.array(v) for k, v in data.items()}
    for v in scaled.values():
        v[:, :3, 3] *= s
    sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", loss="huber", **scaled)
    for name in ("X", "Y"):
        assert rotation_angle(sol.unknowns[name][:3, :3] @ base.unknowns[name][:3, :3].T) < 1e-9
        np.testing.assert_allclose(sol.unknowns[name][:3, 3], s * base.unknowns[name][:3, 3],
                                   rtol=0, atol=1e-9 * s * np.linalg.norm(base.unknowns[name][:3, 3]))


def test_init_as_mapping_of_poses(noisy16):
    data, truth = noisy16
    a = handeye.solve("axyb", solver="refine", init={"X": truth["X"], "Y": truth["Y"]}, **data)
    b = handeye.solve("axyb", solver="refine", init_X=truth["X"], init_Y=truth["Y"], **data)
    assert a.diagnostics["init"] == "given"
    np.testing.assert_array_equal(a.X, b.X)
    with pytest.raises(InputError):
        handeye.solve("axyb", solver="refine", init={"X": truth["X"]}, **data)


def _profile_objective(P, X, Y, scale):
    return lm_objective.objective(P.residuals((X, Y)), None, "profile", "linear", 1.0, scale)[0]


def test_estimated_weights_are_the_profile_likelihood_optimum(noisy16):
    """Default weights: sigma = RMS of each residual group at the answer, and the answer is a
    stationary point of the profile likelihood L (checked by central differences of L)."""
    data, _ = noisy16
    sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
    d = PROBLEM.validate(**data)
    P = AXYBModel(d)
    e = P.residuals((sol.X, sol.Y))
    m = len(e)
    assert sol.diagnostics["sigma_rot"] == pytest.approx(np.sqrt(np.sum(e[:, :3] ** 2) / (3 * m)), rel=1e-12)
    assert sol.diagnostics["sigma_trans"] == pytest.approx(np.sqrt(np.sum(e[:, 3:] ** 2) / (3 * m)), rel=1e-12)
    assert sol.diagnostics["final_cost"] == pytest.approx(_profile_objective(P, sol.X, sol.Y, d.translation_scale), rel=1e-12)
    # stationary: dL/dxi ~ 0 relative to the curvature (a step of one std changes L by ~1/2)
    std = np.sqrt(np.diag(np.array(sol.diagnostics["covariance_XY"])))
    for k in range(12):
        xi = np.zeros(12)
        xi[k] = 1e-3 * std[k]
        up = _profile_objective(P, *nlls.retract_all((sol.X, sol.Y), xi), d.translation_scale)
        down = _profile_objective(P, *nlls.retract_all((sol.X, sol.Y), -xi), d.translation_scale)
        slope = (up - down) / 2e-3  # dL per std
        assert abs(slope) < 1e-4, (k, slope)
        assert up + down - 2 * sol.diagnostics["final_cost"] > 0  # a minimum, not a saddle


def test_initial_estimate_and_three_pairs_use_the_start_residuals(noisy16):
    data, truth = noisy16
    a = handeye.solve("axyb", solver="refine", init="kron-lstsq", estimate="initial", **data)
    b = handeye.solve("axyb", solver="refine", init=truth, estimate="initial", **data)
    assert a.diagnostics["weight_mode"] == b.diagnostics["weight_mode"] == "initial"
    assert a.diagnostics["sigma_rot"] != b.diagnostics["sigma_rot"]  # from the start: differ
    d = PROBLEM.validate(**data)
    e0 = AXYBModel(d).residuals((truth["X"], truth["Y"]))
    assert b.diagnostics["sigma_trans"] == pytest.approx(np.sqrt(np.sum(e0[:, 3:] ** 2) / (3 * len(e0))), rel=1e-12)
    # with m = 3 the translations can be fitted exactly (unbounded likelihood): "initial"
    three = {k: v[:3] for k, v in data.items()}
    sol = handeye.solve("axyb", solver="refine", init="kron-lstsq", **three)
    assert sol.diagnostics["weight_mode"] == "initial" and sol.status == handeye.Status.OPTIMAL
    assert sol.diagnostics["sigma_trans"] > 1e-3  # not collapsed onto an exact fit
    with pytest.raises(InputError):
        handeye.solve("axyb", solver="refine", estimate="nope", **data)


@pytest.mark.parametrize("loss,mode", [("linear", "profile"), ("linear", "fixed"), ("cauchy", "irls")])
def test_block_normal_equations_equal_the_jacobian_ones(loss, mode):
    """`AXYBModel.normal_equations` (closed-form sums, no (m, 6, 12) Jacobian) against J^T W J,
    J^T W e from `jacobian`, away from the optimum (rotation residuals up to ~1 rad)."""
    rng = np.random.default_rng(8)
    truth = random_truth(rng)
    data, _ = PROBLEM.simulate(pairs=9, seed=8, noise=NoiseModel.on("B", 0.3, 40.0), X=truth["X"], Y=truth["Y"])
    d = PROBLEM.validate(**data)
    P = AXYBModel(d)
    X, Y = _perturb(truth["X"], rng, rot=0.4), _perturb(truth["Y"], rng, rot=0.4)
    e = P.residuals((X, Y))
    W = estimate_sigmas(e, d.translation_scale, robust=loss != "linear")
    fast = lm_objective.sums_model(P, (X, Y), e, W, mode, loss, 2.0, d.translation_scale)
    ref = lm_objective.jacobian_model(e, P.jacobian((X, Y), e), W, mode, loss, 2.0, d.translation_scale)
    for a, b in zip(fast[:3], ref[:3]):  # g, H, Hw
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())
    assert fast[3] == pytest.approx(ref[3], rel=1e-12)


# --------------------------------------------------------------------------- axxb (A_i X = X B_i)

def _axxb_exact(m, seed):
    """Exact motions of a random X (`random_unknowns`), and the truth."""
    rng = np.random.default_rng(seed)
    X = AXXB.random_unknowns(rng, 100.0)["X"]
    data, truth = AXXB.simulate(pairs=m, seed=seed, X=X)
    return data, truth, rng


def _independent_motions(m, seed, noise):
    """Motions with independent noise on each motion (the model refine assumes), and the truth."""
    data, truth = AXXB.simulate(pairs=m, seed=seed)
    rng = np.random.default_rng(seed + 1000)
    return {k: noise.apply(k, v, rng) for k, v in data.items()}, truth


def test_axxb_noise_free_recovery_from_perturbed_init():
    data, truth, rng = _axxb_exact(10, 41)
    X0 = _perturb(truth["X"], rng, rot=0.3, trans=50.0)
    sol = handeye.solve("axxb", solver="refine", init_X=X0, **data)
    scale = AXXB.validate(**data).translation_scale
    err = AXXB.errors(sol.unknowns, truth)["X"]
    assert sol.status == handeye.Status.OPTIMAL and sol.diagnostics["converged"]
    assert sol.diagnostics["init"] == "given" and set(sol.unknowns) == {"X"}
    assert err["rotation"] < 1e-9 and err["translation"] < 1e-9 * scale
    res = AXXB.residuals(AXXB.validate(**data), sol.unknowns)
    assert res["rotation"].max() < 1e-9 and res["translation"].max() < 1e-9 * scale


@pytest.mark.parametrize("residual_angle", [0.0, 0.3, 2.5])
def test_axxb_analytic_jacobian_matches_finite_differences(residual_angle):
    """Central differences of e_i(X exp(xi)) against `AXXBModel.jacobian`, and the Jacobian is
    A X = Y B's at Y = X with the X and Y columns added (the chain rule)."""
    data, truth, rng = _axxb_exact(6, 13)
    d = AXXB.validate(**data)
    P = AXXBModel(d)
    X = make_pose(truth["X"][:3, :3] @ so3_exp(residual_angle * np.array([0.6, -0.48, 0.64])),
                  truth["X"][:3, 3] + 30.0 * rng.standard_normal(3))
    e = P.residuals((X,))
    J = P.jacobian((X,), e)
    h = 1e-6
    Jfd = np.zeros_like(J)
    for k in range(6):
        xi = np.zeros(6)
        xi[k] = h
        Jfd[:, :, k] = (P.residuals(nlls.retract_all((X,), xi)) - P.residuals(nlls.retract_all((X,), -xi))) / (2 * h)
    np.testing.assert_allclose(J, Jfd, atol=1e-6 * max(1.0, np.abs(J).max()), rtol=1e-6)
    J2 = AXYBModel(d).jacobian((X, X), e)
    np.testing.assert_allclose(J, J2[:, :, :6] + J2[:, :, 6:], rtol=0, atol=1e-12 * np.abs(J).max())


@pytest.mark.parametrize("loss,mode", [("linear", "profile"), ("cauchy", "irls")])
def test_axxb_block_normal_equations_equal_the_jacobian_ones(loss, mode):
    data, truth, rng = _axxb_exact(9, 8)
    d = AXXB.validate(**data)
    P = AXXBModel(d)
    X = _perturb(truth["X"], rng, rot=0.4)
    e = P.residuals((X,))
    W = estimate_sigmas(e, d.translation_scale, robust=loss != "linear")
    fast = lm_objective.sums_model(P, (X,), e, W, mode, loss, 2.0, d.translation_scale)
    ref = lm_objective.jacobian_model(e, P.jacobian((X,), e), W, mode, loss, 2.0, d.translation_scale)
    for a, b in zip(fast[:3], ref[:3]):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())


def test_axxb_robust_losses_reject_a_gross_outlier_motion():
    noise = NoiseModel({"A": (0.0, 0.1), "B": (0.002, 0.2)})
    data, truth = _independent_motions(20, 21, noise)
    A = np.array(data["A"])
    A[4] = make_pose(A[4, :3, :3] @ so3_exp([0.5, 0.0, 0.0]), A[4, :3, 3] + [100.0, 0.0, 0.0])
    data = {"A": A, "B": data["B"]}
    X0 = _perturb(truth["X"], np.random.default_rng(2), rot=0.05, trans=10.0)
    errs = {}
    for loss in ("linear", "huber", "cauchy"):
        sol = handeye.solve("axxb", solver="refine", init_X=X0, loss=loss, **data)
        assert solved(sol)  # least squares, pulled by the gross motion: suboptimal beside the robust fits
        e = AXXB.errors(sol.unknowns, truth)["X"]
        errs[loss] = (e["rotation"], e["translation"])
    for loss in ("huber", "cauchy"):
        assert errs[loss][0] < 0.25 * errs["linear"][0], errs
        assert errs[loss][1] < 0.25 * errs["linear"][1], errs


def test_axxb_covariance_matches_the_spread_over_seeds():
    """Motions with independent noise (refine's model): over 50 seeds the predicted RMS error
    of R_X and of t_X (sqrt of the mean predicted variance) is within 30% of the observed one."""
    noise = NoiseModel({"A": (0.0, 0.1), "B": (0.002, 0.2)})
    err, pred = [], []
    for seed in range(50):
        data, truth = _independent_motions(20, 300 + seed, noise)
        sol = handeye.solve("axxb", solver="refine", init_X=truth["X"], **data)
        e = AXXB.errors(sol.unknowns, truth)["X"]
        err.append([e["rotation"], e["translation"]])
        pred.append([sol.diagnostics["std"]["X"]["rotation"], sol.diagnostics["std"]["X"]["translation"]])
        C = np.array(sol.diagnostics["covariance"]["X"])
        np.testing.assert_array_equal(C, np.array(sol.diagnostics["covariance_X"]))
    observed = np.sqrt(np.mean(np.square(err), axis=0))
    predicted = np.sqrt(np.mean(np.square(pred), axis=0))
    assert np.all(np.abs(observed / predicted - 1.0) < 0.3), (observed, predicted)


@pytest.mark.parametrize("loss", ["linear", "huber"])
def test_axxb_unit_invariance(loss):
    data, truth = AXXB.simulate(pairs=12, seed=5, noise=NoiseModel.on(("A", "B"), 0.002, 0.2))
    X0 = _perturb(truth["X"], np.random.default_rng(5), rot=0.05, trans=10.0)
    base = handeye.solve("axxb", solver="refine", init_X=X0, loss=loss, **data)
    for s in (1e-3, 1e3):
        scaled = {k: np.array(v) for k, v in data.items()}
        for v in scaled.values():
            v[:, :3, 3] *= s
        X0s = np.array(X0)
        X0s[:3, 3] *= s
        sol = handeye.solve("axxb", solver="refine", init_X=X0s, loss=loss, **scaled)
        assert rotation_angle(sol.X[:3, :3] @ base.X[:3, :3].T) < 1e-9
        np.testing.assert_allclose(sol.X[:3, 3], s * base.X[:3, 3], rtol=0, atol=1e-9 * s * np.linalg.norm(base.X[:3, 3]))


def test_axxb_options_and_weights():
    data, truth = AXXB.simulate(pairs=8, seed=9, noise=NoiseModel.on(("A", "B"), 0.002, 0.2))
    a = handeye.solve("axxb", solver="refine", init={"X": truth["X"]}, **data)
    b = handeye.solve("axxb", solver="refine", init_X=truth["X"], **data)
    np.testing.assert_array_equal(a.X, b.X)
    assert a.diagnostics["weight_mode"] == "profile" and "covariance_X" in a.diagnostics
    stated = handeye.solve("axxb", solver="refine", init_X=truth["X"], sigma_rot=a.diagnostics["sigma_rot"],
                           sigma_trans=a.diagnostics["sigma_trans"], **data)
    assert stated.diagnostics["weights"] == "stated"
    np.testing.assert_allclose(stated.X, a.X, atol=1e-9 * 100)
    cov = handeye.solve("axxb", solver="refine", init_X=truth["X"], covariance=np.diag([4e-6] * 3 + [0.04] * 3), **data)
    assert cov.diagnostics["weights"] == "covariance" and "sigma_rot" not in cov.diagnostics
    two = {k: v[:2] for k, v in data.items()}  # two motions: the profile likelihood is unbounded
    assert handeye.solve("axxb", solver="refine", init_X=truth["X"], **two).diagnostics["weight_mode"] == "initial"
    for bad in ({"init_Y": truth["X"]}, {"init": {"X": truth["X"], "Y": truth["X"]}}, {"init": "refine"},
                {"init_X": np.eye(3)}, {"loss": "l1"}):
        with pytest.raises((InputError, UnknownPluginError)):
            handeye.solve("axxb", solver="refine", **bad, **data)
    assert R.default_init("axxb") in AXXB.starts


# --------------------------------------------------------------------------- axbycz (more in test_axbycz_problem.py)

def test_axbycz_is_served_with_three_start_poses():
    from handeye.problems.axbycz import PROBLEM as AXBYCZ

    data, truth = AXBYCZ.simulate(pairs=8, seed=4, noise=NoiseModel.on(("A", "B", "C"), 0.002, 0.2))
    d = AXBYCZ.validate(**data)
    assert handeye.get_registry().problem_of(d).name == "axbycz" and R.options_for(handeye.get_registry().problem("axbycz")).UNKNOWNS == ("X", "Y", "Z")
    assert R.default_init("axbycz") == "wang"
    a = handeye.solve("axbycz", solver="refine", init=truth, **data)
    b = handeye.solve("axbycz", solver="refine", init_X=truth["X"], init_Y=truth["Y"], init_Z=truth["Z"], **data)
    for k in ("X", "Y", "Z"):
        np.testing.assert_array_equal(a.unknowns[k], b.unknowns[k])
    assert a.diagnostics["weight_mode"] == "profile" and np.shape(a.diagnostics["covariance_XYZ"]) == (18, 18)
    five = {k: v[:5] for k, v in data.items()}  # 15 translation equations for 15 parameters: unbounded profile
    assert handeye.solve("axbycz", solver="refine", init=truth, **five).diagnostics["weight_mode"] == "initial"


def test_axbycz_a_start_that_refuses_the_data_gives_way_to_the_next(monkeypatch):
    """Each axbycz start serves one data protocol: wu (both robots moving) refuses exact phase
    data, and the next start takes over, with a warning; a start asked for by name is not replaced."""
    from handeye.base.errors import DegenerateDataError
    from handeye.problems.axbycz import PROBLEM as AXBYCZ

    data, truth = AXBYCZ.simulate(pairs=30, seed=5, protocol="phases")
    monkeypatch.setattr(type(handeye.get_registry().problem("axbycz")), "starts", ("wu", "fu-dq"))
    sol = handeye.solve("axbycz", solver="refine", **data)
    assert sol.diagnostics["init"] == "fu-dq"
    assert any(w.startswith("the start solver 'wu' failed (wu: the first 10 triples") and w.endswith("started from 'fu-dq'")
               for w in sol.warnings)
    assert max(e["rotation"] for e in AXBYCZ.errors(sol.unknowns, truth).values()) < 1e-9
    with pytest.raises(DegenerateDataError, match="wu: the first 10 triples"):
        handeye.solve("axbycz", solver="refine", init="wu", **data)
