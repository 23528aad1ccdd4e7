"""Tests of the default solver `auto` (plugins/auto.py)."""

from __future__ import annotations

import dataclasses

import handeye
import numpy as np
import pytest
from handeye.errors import InputError
from handeye.noise import NoiseModel
from handeye.plugins import auto, refine
from handeye.problems.axyb import PROBLEM
from handeye.solution import Status

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


def test_auto_equals_refine_from_its_start(noisy):
    data, _ = noisy
    a = handeye.solve("axyb", **data)
    r = handeye.solve("axyb", solver="refine", init=a.diagnostics["init"], **data)
    np.testing.assert_allclose(a.X, r.X, atol=1e-12)
    np.testing.assert_allclose(a.Y, r.Y, atol=1e-9)


def test_auto_falls_back_to_kron_lstsq_when_so3_sdp_is_unavailable(noisy, monkeypatch):
    data, _ = noisy
    monkeypatch.setattr(refine, "default_init", lambda: "kron-lstsq")
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
    from handeye.se3 import make_pose, so3_exp

    def uncertified(name, d):
        X, Y, status, diag = real_init(name, d)
        if name == "so3-sdp":
            X = make_pose(X[:3, :3] @ so3_exp([2.5, 0.0, 0.0]), X[:3, 3] + 500.0)
            return X, Y, Status.UNCERTIFIED, {**diag, "certified": False}
        return X, Y, status, diag

    def truncated(d, X0, Y0, options):
        if np.abs(X0[:3, 3] - truth["X"][:3, 3]).max() > 100.0:  # the faked far start
            options = dataclasses.replace(options, max_iter=1)
        return real_refine(d, X0, Y0, options)

    monkeypatch.setattr(refine, "run_init", uncertified)
    monkeypatch.setattr(refine, "refine", truncated)
    monkeypatch.setattr(refine, "default_init", lambda: "so3-sdp")
    sol = handeye.solve("axyb", **data)
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
    from handeye.errors import SolverError

    data, _ = noisy
    real = refine.run_init

    def failing(name, d):
        if name == "so3-sdp":
            raise SolverError("so3-sdp: Clarabel returned status 'infeasible' for the relaxation")
        return real(name, d)

    monkeypatch.setattr(refine, "run_init", failing)
    monkeypatch.setattr(refine, "default_init", lambda: "so3-sdp")
    sol = handeye.solve("axyb", solver=solver, **data)
    assert sol.diagnostics["init"] == "kron-lstsq" and sol.status == Status.OPTIMAL
    if solver == "auto":
        assert sol.diagnostics["pipeline"] == ["kron-lstsq", "refine"]
    assert any("so3-sdp" in w and "kron-lstsq" in w for w in sol.warnings)
    reference = handeye.solve("axyb", solver="refine", init="kron-lstsq", **data)
    np.testing.assert_allclose(sol.X, reference.X, atol=1e-12)
    with pytest.raises(SolverError):  # a start the user asked for is not replaced
        handeye.solve("axyb", solver=solver, init="so3-sdp", **data)
