"""Tests of the default solver `auto` (plugins/auto.py), for axyb, axxb and axbycz."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import handeye
from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.framework.solution import Status
from handeye.plugins import refine
from handeye.problems.axxb import PROBLEM as AXXB
from handeye.problems.axyb import PROBLEM

NOISE = NoiseModel({"B": (0.002, 0.5), "A": (0.0002, 0.05)})


@pytest.fixture(scope="module")
def noisy():
    return PROBLEM.simulate(pairs=16, seed=17, noise=NOISE)


def test_auto_is_the_default_solver(noisy):
    data, truth = noisy
    sol = handeye.solve("axyb", A=data["A"], B=data["B"])
    assert sol.solver == "auto"
    assert sol.status == Status.OPTIMAL
    d = sol.diagnostics
    assert d["pipeline"][-1] == "refine" and d["init"] == refine.default_init()
    assert d["refine"]["converged"] and d["refine"]["final_cost"] <= d["refine"]["initial_cost"]
    if d["init"] == "so3-sdp":
        assert d["init_certified"] and d["certificate"]["certified"]
        assert "eigenvalue_ratio" in d["certificate"] and "relative_gap" in d["certificate"]
    err = PROBLEM.errors(sol.unknowns, truth)
    kron = PROBLEM.errors(handeye.solve("axyb", solver="kron-lstsq", **data).unknowns, truth)
    assert err["Y"]["rotation"] < kron["Y"]["rotation"]


def test_auto_is_refine_from_its_start_then_the_noise_sources(noisy):
    """With one noise level per group auto is refine from its start (the default below
    SOURCES_MIN_PAIRS); with the noise sources it then fits them from that answer, which gains
    likelihood."""
    data, _ = noisy
    groups = handeye.solve("axyb", noise="groups", **data)
    r = handeye.solve("axyb", solver="refine", init=groups.diagnostics["init"], **data)
    np.testing.assert_allclose(groups.X, r.X, atol=1e-12)
    np.testing.assert_allclose(groups.Y, r.Y, atol=1e-9)
    np.testing.assert_array_equal(handeye.solve("axyb", **data).X, groups.X)  # 16 pairs
    a = handeye.solve("axyb", noise="sources", **data)
    s = handeye.solve("axyb", solver="refine", noise="sources", init_X=groups.X, init_Y=groups.Y, **data)
    np.testing.assert_allclose(a.X, s.X, atol=1e-12)
    np.testing.assert_allclose(a.Y, s.Y, atol=1e-9)
    assert a.diagnostics["refine"]["noise_model"] == "sources" and a.diagnostics["refine"]["loglik_gain"] > 0
    assert a.diagnostics["init"] == groups.diagnostics["init"]


def test_auto_falls_back_to_kron_lstsq_when_so3_sdp_is_unavailable(noisy, monkeypatch):
    data, _ = noisy
    monkeypatch.setattr(refine, "default_init", lambda problem: "kron-lstsq")
    sol = handeye.solve("axyb", **data)
    assert sol.diagnostics["pipeline"] == ["kron-lstsq", "refine"]
    assert not sol.diagnostics["init_certified"] and sol.diagnostics["certificate"] == {}
    assert sol.status == Status.OPTIMAL


def test_uncertified_start_triggers_a_second_start(noisy, monkeypatch):
    """When the so3-sdp start is not certified, refine also runs from kron-lstsq; the lower cost
    wins. The so3-sdp start is faked: uncertified, far away, and its refinement cut to one
    iteration, so that it ends worse and the selection is visible."""
    if "so3-sdp" not in handeye.list_solvers("axyb"):
        pytest.skip("so3-sdp not registered")
    data, truth = noisy
    real_init, real_refine = refine.run_init, refine.refine
    from handeye.geometry.se3 import make_pose, so3_exp

    def uncertified(problem, name, d):
        (X, Y), status, diag = real_init(problem, name, d)
        if name == "so3-sdp":
            X = make_pose(X[:3, :3] @ so3_exp([2.5, 0.0, 0.0]), X[:3, 3] + 500.0)
            return (X, Y), Status.UNCERTIFIED, {**diag, "certified": False}
        return (X, Y), status, diag

    def truncated(problem, d, poses0, options):
        if np.abs(poses0[0][:3, 3] - truth["X"][:3, 3]).max() > 100.0:  # the faked far start
            options = dataclasses.replace(options, max_iter=1)
        return real_refine(problem, d, poses0, options)

    monkeypatch.setattr(refine, "run_init", uncertified)
    monkeypatch.setattr(refine, "refine", truncated)
    monkeypatch.setattr(refine, "default_init", lambda problem: "so3-sdp")
    sol = handeye.solve("axyb", noise="groups", **data)
    d = sol.diagnostics
    assert d["pipeline"] == ["so3-sdp | kron-lstsq", "refine", "best"]
    assert [s["init"] for s in d["starts"]] == ["so3-sdp", "kron-lstsq"]
    assert d["init_status"] == "uncertified" and not d["init_certified"]
    costs = [s["compared_cost"] for s in d["starts"]]
    assert costs[1] < costs[0]
    assert d["init"] == "kron-lstsq" and sol.status == Status.OPTIMAL
    np.testing.assert_allclose(sol.X, handeye.solve("axyb", solver="refine", init="kron-lstsq", **data).X, atol=1e-9)
    err = PROBLEM.errors(sol.unknowns, truth)
    assert err["X"]["rotation"] < 0.01 and err["Y"]["rotation"] < 0.01


def test_auto_passes_loss_and_weights_to_refine(noisy):
    data, _ = noisy
    sol = handeye.solve("axyb", loss="cauchy", loss_scale=2.0, **data)
    assert sol.diagnostics["refine"]["loss"] == "cauchy" and sol.diagnostics["refine"]["loss_scale"] == 2.0
    sol = handeye.solve("axyb", sigma_rot=0.002, sigma_trans=0.5, **data)
    assert sol.diagnostics["refine"]["weights"] == "stated"
    sol = handeye.solve("axyb", init="kron-lstsq", **data)
    assert sol.diagnostics["pipeline"] == ["kron-lstsq", "refine"]


@pytest.mark.parametrize("bad", [{"init": "auto"}, {"init": "refine"}, {"loss": "nope"}, {"sigma_trans": 1.0}])
def test_auto_rejects_bad_options(noisy, bad):
    data, _ = noisy
    with pytest.raises(InputError):
        handeye.solve("axyb", **bad, **data)


@pytest.mark.parametrize("solver", ["auto", "refine"])
def test_a_failing_default_start_falls_back_to_kron_lstsq(noisy, monkeypatch, solver):
    from handeye.base.errors import SolverError

    data, _ = noisy
    real = refine.run_init

    def failing(problem, name, d):
        if name == "so3-sdp":
            raise SolverError("so3-sdp: Clarabel returned status 'infeasible' for the relaxation")
        return real(problem, name, d)

    monkeypatch.setattr(refine, "run_init", failing)
    monkeypatch.setattr(refine, "default_init", lambda problem: "so3-sdp")
    sol = handeye.solve("axyb", solver=solver, noise="groups", **data)
    assert sol.diagnostics["init"] == "kron-lstsq" and sol.status == Status.OPTIMAL
    if solver == "auto":
        assert sol.diagnostics["pipeline"] == ["kron-lstsq", "refine"]
    assert any("so3-sdp" in w and "kron-lstsq" in w for w in sol.warnings)
    reference = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
    np.testing.assert_allclose(sol.X, reference.X, atol=1e-12)
    with pytest.raises(SolverError):  # a start the user asked for is not replaced
        handeye.solve("axyb", solver=solver, init="so3-sdp", **data)


# --------------------------------------------------------------------------- axxb (A_i X = X B_i)

#: noise on the absolute robot and camera poses (the simulator differences them into motions)
AXXB_NOISE = NoiseModel.on(("A", "B"), 0.002, 0.2)
#: bounds of the noisy axxb case (m = 16, AXXB_NOISE): worst over seeds 0..19 measured
#: 3.0e-3 rad and 0.66 mm (medians 1.7e-3 rad, 0.31 mm); the bounds are 3.3x and 3x that.
AXXB_NOISY_BOUNDS = {"rotation": 0.01, "translation": 2.0}


def _axxb_start_or_skip():
    start = refine.default_init("axxb")
    if start not in handeye.list_solvers("axxb"):
        pytest.skip(f"no start solver for axxb registered (tried {AXXB.starts})")
    return start


def test_auto_axxb_noise_free():
    start = _axxb_start_or_skip()
    rng = np.random.default_rng(23)
    X = AXXB.random_unknowns(rng, 100.0)["X"]
    data, truth = AXXB.simulate(pairs=11, seed=23, X=X, pairing="consecutive")
    sol = handeye.solve("axxb", **data)
    assert sol.solver == "auto" and sol.status == Status.OPTIMAL and set(sol.unknowns) == {"X"}
    assert sol.diagnostics["pipeline"][-1] == "refine" and sol.diagnostics["init"] == start
    err = AXXB.errors(sol.unknowns, truth)["X"]
    assert err["rotation"] < 1e-9 and err["translation"] < 1e-9 * AXXB.validate(**data).translation_scale


def test_auto_axxb_noisy_against_truth_and_oracle():
    _axxb_start_or_skip()
    data, truth = AXXB.simulate(pairs=17, seed=17, noise=AXXB_NOISE, pairing="consecutive")
    sol = handeye.solve("axxb", **data)
    assert "formulation" not in sol.diagnostics  # consecutive motions: the per-motion model
    err = AXXB.errors(sol.unknowns, truth)["X"]
    assert err["rotation"] < AXXB_NOISY_BOUNDS["rotation"] and err["translation"] < AXXB_NOISY_BOUNDS["translation"], err
    d = sol.diagnostics
    assert d["refine"]["converged"] and d["refine"]["weight_mode"] == "profile"
    assert set(d["refine"]["covariance"]) == {"X"} and d["refine"]["std"]["X"]["rotation"] > 0
    oracle = handeye.solve("axxb", solver="refine", init_X=truth["X"], **data)  # one objective: one answer
    np.testing.assert_allclose(sol.X[:3, :3], oracle.X[:3, :3], rtol=0, atol=1e-11)
    np.testing.assert_allclose(sol.X[:3, 3], oracle.X[:3, 3], rtol=0, atol=1e-9)
    robust = handeye.solve("axxb", loss="huber", **data)
    assert robust.diagnostics["refine"]["loss"] == "huber"


def test_auto_axxb_uncertified_start_triggers_a_second_start(monkeypatch):
    start = _axxb_start_or_skip()
    other = refine.fallback_init("axxb", start)
    if start != AXXB.starts[0] or other is None:
        pytest.skip("the certifiable start or a second start is not available for axxb")
    data, truth = AXXB.simulate(pairs=17, seed=18, noise=AXXB_NOISE, pairing="consecutive")
    real_init = refine.run_init

    def uncertified(problem, name, d):
        poses, status, diag = real_init(problem, name, d)
        if name == start:
            return poses, Status.UNCERTIFIED, {**diag, "certified": False}
        return poses, status, diag

    monkeypatch.setattr(refine, "run_init", uncertified)
    sol = handeye.solve("axxb", **data)
    d = sol.diagnostics
    assert d["pipeline"] == [f"{start} | {other}", "refine", "best"]
    assert [s["init"] for s in d["starts"]] == [start, other] and not d["init_certified"]
    err = AXXB.errors(sol.unknowns, truth)["X"]
    assert err["rotation"] < AXXB_NOISY_BOUNDS["rotation"]


def test_auto_axxb_on_every_pair_of_stations_solves_the_stations():
    """Motions that are every pair of n stations (the default of motions()) share the stations'
    noise: auto rebuilds the stations and solves A_k X = Y B_k on them, the maximum-likelihood
    answer, equal to auto for axyb on the user's own stations (a common origin is absorbed by Y)."""
    from handeye.geometry.se3 import inverse
    from handeye.problems.axxb import motions, simulate_stations

    stations, truth = simulate_stations(12, seed=31, noise=AXXB_NOISE)
    data = motions(stations["A"], inverse(stations["B"]))  # robot poses, board poses in the camera
    sol = handeye.solve("axxb", **data)
    assert "12 stations the 66 motions" in sol.diagnostics["formulation"]
    start = refine.default_init("axxb")
    if start == "so3-sdp":  # its certified start on the motions (one rotation), then AX=YB's refine
        assert sol.diagnostics["pipeline"] == ["stations", "so3-sdp (motions)", "refine"]
        assert sol.diagnostics["init_certified"]
    on_stations = handeye.solve("axyb", A=stations["A"], B=stations["B"])
    np.testing.assert_allclose(sol.X[:3, :3], on_stations.X[:3, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.X[:3, 3], on_stations.X[:3, 3], rtol=0, atol=1e-6)
    np.testing.assert_allclose(sol.diagnostics["refine"]["std"]["X"]["rotation"],
                               on_stations.diagnostics["refine"]["std"]["X"]["rotation"], rtol=1e-5)
    err = AXXB.errors(sol.unknowns, truth)["X"]
    assert err["rotation"] < AXXB_NOISY_BOUNDS["rotation"] and err["translation"] < AXXB_NOISY_BOUNDS["translation"]
    refined = handeye.solve("axxb", solver="refine", **data)
    assert any("every pair of 12 stations" in w and "'auto'" in w for w in refined.warnings)
    # stated weights describe the motions: then the per-motion model is used
    stated = handeye.solve("axxb", sigma_rot=0.003, sigma_trans=0.3, **data)
    assert "formulation" not in stated.diagnostics


def test_auto_axxb_stations_without_a_certified_start_run_the_axyb_pipeline(monkeypatch):
    from handeye.geometry.se3 import inverse
    from handeye.problems.axxb import motions, simulate_stations

    stations, _ = simulate_stations(9, seed=32, noise=AXXB_NOISE)
    data = motions(stations["A"], inverse(stations["B"]))
    real_init = refine.run_init

    def uncertified_on_motions(problem, name, d):
        poses, status, diag = real_init(problem, name, d)
        if problem.name == "axxb":
            return poses, Status.UNCERTIFIED, {**diag, "certified": False}
        return poses, status, diag

    monkeypatch.setattr(refine, "run_init", uncertified_on_motions)
    sol = handeye.solve("axxb", **data)
    assert sol.diagnostics["pipeline"][0] == "stations" and "(motions)" not in " ".join(sol.diagnostics["pipeline"])
    on_stations = handeye.solve("axyb", A=stations["A"], B=stations["B"])
    np.testing.assert_allclose(sol.X[:3, :3], on_stations.X[:3, :3], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- outliers (outliers="reject", default)

def _gross(T, indices, degrees=15.0, length=30.0):
    """T with the poses at `indices` moved by `degrees` about a fixed oblique axis and `length`
    along a fixed direction (left-multiplied)."""
    from handeye.geometry.se3 import make_pose, so3_exp

    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    E = make_pose(so3_exp(np.deg2rad(degrees) * axis), length * np.array([0.6, 0.0, -0.8]))
    T = np.array(T, copy=True)
    T[list(indices)] = E @ T[list(indices)]
    return T


def _angle_deg(R1, R2):
    return float(np.rad2deg(np.arccos(np.clip((np.trace(R1.T @ R2) - 1.0) / 2.0, -1.0, 1.0))))


def test_auto_clean_data_flag_nothing_and_equal_least_squares(noisy):
    data, _ = noisy
    sol = handeye.solve("axyb", **data)
    keep = handeye.solve("axyb", outliers="keep", **data)
    assert sol.diagnostics["outliers"] == [] and "outliers" not in keep.diagnostics
    np.testing.assert_allclose(sol.X, keep.X, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sol.Y, keep.Y, rtol=0, atol=1e-12)
    with pytest.raises(InputError):
        handeye.solve("axyb", outliers="drop", **data)


def test_auto_flags_and_leaves_out_one_gross_pair(noisy):
    """One pair off by 15 deg / 30 mm: least squares on every pair is ~12x off; auto lists the
    pair, warns, and its answer is least squares on the other 15 pairs, within 0.03 deg / 0.3 mm
    of the clean data's (measured 0.012 deg / 0.056 mm: one pair's information less)."""
    data, truth = noisy
    clean = handeye.solve("axyb", **data)
    B = _gross(data["B"], [3])
    sol = handeye.solve("axyb", A=data["A"], B=B)
    d = sol.diagnostics
    assert [o["index"] for o in d["outliers"]] == [3] and sol.status == Status.OPTIMAL
    assert d["outliers"][0]["rotation_deg"] > 10 and d["outliers"][0]["translation"] > 10
    assert any("pair no. 4 (index 3) is far off" in w for w in sol.warnings), sol.warnings
    assert _angle_deg(sol.X[:3, :3], clean.X[:3, :3]) < 0.03 and np.abs(sol.X[:3, 3] - clean.X[:3, 3]).max() < 0.3
    without = handeye.solve("axyb", outliers="keep", A=np.delete(data["A"], 3, axis=0), B=np.delete(B, 3, axis=0))
    np.testing.assert_allclose(sol.X[:3, :3], without.X[:3, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.X[:3, 3], without.X[:3, 3], rtol=0, atol=1e-6)
    keep = handeye.solve("axyb", outliers="keep", noise="groups", A=data["A"], B=B)  # least squares on every pair
    assert PROBLEM.errors(keep.unknowns, truth)["X"]["rotation"] > 5 * PROBLEM.errors(sol.unknowns, truth)["X"]["rotation"]
    robust = handeye.solve("axyb", loss="cauchy", A=data["A"], B=B)  # a robust loss: as before, nothing left out
    assert "outliers" not in robust.diagnostics and robust.diagnostics["refine"]["loss"] == "cauchy"


def test_auto_handles_fifteen_percent_gross_pairs():
    data, truth = PROBLEM.simulate(pairs=20, seed=5, noise=NOISE)
    clean = PROBLEM.errors(handeye.solve("axyb", **data).unknowns, truth)
    bad = [2, 9, 15]
    B = _gross(_gross(data["B"], [2], 25.0, 80.0), [9, 15], 8.0, -40.0)
    sol = handeye.solve("axyb", A=data["A"], B=B)
    assert [o["index"] for o in sol.diagnostics["outliers"]] == bad
    err = PROBLEM.errors(sol.unknowns, truth)
    for k in ("X", "Y"):  # within 1.5x of the clean data's errors (plus a small floor)
        assert err[k]["rotation"] < 1.5 * clean[k]["rotation"] + 2e-4, (k, err, clean)
        assert err[k]["translation"] < 1.5 * clean[k]["translation"] + 0.1, (k, err, clean)


def test_auto_axxb_outlier_motion_and_outlier_station():
    _axxb_start_or_skip()
    from handeye.geometry.se3 import inverse
    from handeye.problems.axxb import motions, relative_motions, simulate_stations

    stations, truth = simulate_stations(14, seed=8, noise=NOISE)
    # consecutive motions, one motion's camera pose corrupted: the per-motion route
    A, B = relative_motions(stations["A"], stations["B"], "consecutive")
    clean = handeye.solve("axxb", A=A, B=B)
    keep = handeye.solve("axxb", outliers="keep", A=A, B=B)
    assert clean.diagnostics["outliers"] == []
    np.testing.assert_allclose(clean.X, keep.X, rtol=0, atol=1e-12)
    sol = handeye.solve("axxb", A=A, B=_gross(B, [6]))
    assert [o["index"] for o in sol.diagnostics["outliers"]] == [6] and sol.status == Status.OPTIMAL
    # the answer is least squares on the other motions (one optimum: equal to the iterations' tolerance)
    without = handeye.solve("axxb", outliers="keep", A=np.delete(A, 6, axis=0), B=np.delete(B, 6, axis=0))
    np.testing.assert_allclose(sol.X[:3, :3], without.X[:3, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.X[:3, 3], without.X[:3, 3], rtol=0, atol=1e-6)
    assert _angle_deg(sol.X[:3, :3], clean.X[:3, :3]) < 0.1 and np.abs(sol.X[:3, 3] - clean.X[:3, 3]).max() < 0.5
    # every pair of stations, station 5's camera pose corrupted: the station route lists the station
    clean = handeye.solve("axxb", **motions(stations["A"], inverse(stations["B"])))
    sol = handeye.solve("axxb", **motions(stations["A"], inverse(_gross(stations["B"], [5]))))
    assert sol.diagnostics["pipeline"][0] == "stations"
    assert [o["index"] for o in sol.diagnostics["outliers"]] == [5]
    assert any("station no. 6 (index 5) is far off" in w for w in sol.warnings), sol.warnings
    assert _angle_deg(sol.X[:3, :3], clean.X[:3, :3]) < 0.05 and np.abs(sol.X[:3, 3] - clean.X[:3, 3]).max() < 0.5
    assert AXXB.errors(sol.unknowns, truth)["X"]["rotation"] < AXXB_NOISY_BOUNDS["rotation"]


# --------------------------------------------------------------------------- axbycz (more in test_axbycz_problem.py)

def test_auto_axbycz_second_start_is_the_first_that_solves_the_data(monkeypatch):
    """Free motion with 8 triples: fu-dq (no phase) and kron-lstsq (< 10 triples) refuse, so wu is
    the second start; with wang as the only start there is none."""
    from handeye.problems.axbycz import PROBLEM as AXBYCZ

    data, truth = AXBYCZ.simulate(pairs=8, seed=6, noise=NoiseModel.on(("A", "B", "C"), 0.002, 0.2))
    sol = handeye.solve("axbycz", **data)
    assert sol.diagnostics["pipeline"] == ["wang | wu", "refine", "best"]
    assert [s["init"] for s in sol.diagnostics["starts"]] == ["wang", "wu"]
    oracle = handeye.solve("axbycz", solver="refine", init=truth, **data)
    for k in ("X", "Y", "Z"):
        np.testing.assert_allclose(sol.unknowns[k], oracle.unknowns[k], atol=1e-6)
    monkeypatch.setattr(type(handeye.get_registry().problem("axbycz")), "starts", ("wang",))
    alone = handeye.solve("axbycz", **data)
    assert alone.diagnostics["pipeline"] == ["wang", "refine"]
    for k in ("X", "Y", "Z"):
        np.testing.assert_allclose(alone.unknowns[k], sol.unknowns[k], atol=1e-6)


def drifting(B: np.ndarray, rng: np.random.Generator, rot: float = 0.002, trans: float = 1.0) -> np.ndarray:
    """The camera poses B (T_target_cam) with an error that accumulates along the recording in
    the world (board) frame, as visual odometry's: D_k B_k with D_k = D_k-1 exp(xi_k),
    xi_k ~ N(0, rot^2, trans^2)."""
    from handeye.geometry.se3 import make_pose, so3_exp

    out, D = np.array(B), np.eye(4)
    for k in range(len(B)):
        D = D @ make_pose(so3_exp(rng.normal(0.0, rot, 3)), rng.normal(0.0, trans, 3))
        out[k] = D @ B[k]
    return out


def test_drifting_camera_poses_take_the_consecutive_motions():
    """Camera poses whose error accumulates: the A X = Y B residuals are correlated from one
    station to the next and auto takes X from the consecutive motions (A X = X B), which is
    several times more accurate there; independent noise keeps A X = Y B."""
    from handeye.plugins.auto import DRIFT_AUTOCORRELATION

    drift_err, axyb_err = [], []
    for seed in range(5):
        data, truth = PROBLEM.simulate(pairs=40, seed=seed)
        B = drifting(data["B"], np.random.default_rng(seed))
        sol = handeye.solve("axyb", A=data["A"], B=B)
        assert sol.diagnostics["drift_autocorrelation"] > DRIFT_AUTOCORRELATION
        assert "consecutive motions" in sol.diagnostics["formulation"] and "drift" in sol.warnings[0]
        drift_err.append(PROBLEM.errors(sol.unknowns, truth)["X"]["translation"])
        plain = handeye.solve("axyb", solver="refine", A=data["A"], B=B)
        axyb_err.append(PROBLEM.errors(plain.unknowns, truth)["X"]["translation"])
        clean, _ = PROBLEM.simulate(pairs=40, seed=seed, noise=NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)}))
        kept = handeye.solve("axyb", **clean)
        assert kept.diagnostics["drift_autocorrelation"] < DRIFT_AUTOCORRELATION and "formulation" not in kept.diagnostics
    assert np.median(drift_err) < 0.5 * np.median(axyb_err)


def test_refine_options_validated_once_per_values():
    """auto's refine options are validated once per set of plain values and kept (frozen): the
    same values give the same object; values that compare equal but mean otherwise (1 and True,
    1 and 1.0) are told apart, so a refused value stays refused after an accepted one."""
    from handeye.plugins import auto

    first = auto.Options(max_iter=1).refine_options(PROBLEM)
    assert auto.Options(max_iter=1).refine_options(PROBLEM) is first and first.max_iter == 1
    assert type(first) is refine.options_for(PROBLEM)
    for bad in (True, 1.0):
        with pytest.raises(InputError, match="max_iter"):
            auto.Options(max_iter=bad)
    assert auto.Options(tol=1e-10).refine_options().tol == 1e-10


@pytest.mark.parametrize("correlated", [False, True])
def test_a_stated_covariance_weighs_auto_as_it_weighs_refine(correlated):
    """auto passes a stated covariance on to refine as given: the same weights, so the same
    answer (it once handed refine its own Cholesky factor, which refine factored again: a
    correlated covariance was refused as asymmetric, a diagonal one weighted by the fourth root
    of its variances)."""
    data, _ = PROBLEM.simulate(pairs=30, seed=1, noise=NoiseModel.on(("A", "B"), 0.002, 0.5))
    C = np.diag([4e-6] * 3 + [1.0] * 3)
    if correlated:
        C[0, 1] = C[1, 0] = 1e-6
    given = C.copy()
    plain = handeye.solve("axyb", solver="refine", covariance=C, **data)
    weighted = handeye.solve("axyb", solver="auto", covariance=C, **data)
    assert weighted.status == Status.OPTIMAL
    for k in ("X", "Y"):
        np.testing.assert_allclose(weighted.unknowns[k], plain.unknowns[k], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(C, given)  # the caller's array untouched


def test_the_drift_switch_is_taken_only_where_held_out_stations_agree(monkeypatch):
    """The switch to consecutive motions is judged by held-out prediction (5 contiguous blocks of
    stations): on drifting poses the two answers predict held-out stations alike (ratio 0.9-1.2)
    and the switch is taken; where the consecutive motions' answer predicts worse than the
    tolerance allows (here made 0.5 so that it must), A X = Y B is kept with a warning giving both
    figures, as on a real rig whose residuals correlate through the arm's configuration."""
    from handeye.plugins import _auto_steps

    data, truth = PROBLEM.simulate(pairs=40, seed=2)
    B = drifting(data["B"], np.random.default_rng(2))
    switched = handeye.solve("axyb", A=data["A"], B=B)
    figures = switched.diagnostics["drift_held_out"]
    ratio = figures["drift_translation"] / figures["axyb_translation"]
    assert figures["drift_agrees"] and 0.8 < ratio < _auto_steps.DRIFT_TOLERANCE and figures["folds"] == 5
    monkeypatch.setattr(_auto_steps, "DRIFT_TOLERANCE", 0.5)
    kept = handeye.solve("axyb", A=data["A"], B=B)
    plain = handeye.solve("axyb", solver="auto", A=data["A"], B=B, init="so3-sdp")  # no drift step with a start
    assert "formulation" not in kept.diagnostics and not kept.diagnostics["drift_held_out"]["drift_agrees"]
    assert kept.diagnostics["drift_held_out"]["drift_translation"] == figures["drift_translation"]
    warning = [w for w in kept.warnings if "predicts held-out stations worse" in w]
    assert len(warning) == 1 and f"{figures['drift_translation']:.3g} against {figures['axyb_translation']:.3g}" in warning[0]
    np.testing.assert_allclose(kept.unknowns["X"], plain.unknowns["X"], atol=1e-6)
