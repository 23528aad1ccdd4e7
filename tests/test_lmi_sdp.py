"""`lmi-sdp` (plugins/lmi_sdp.py): the paper's LMI of eq. 14 on cvxpy and picos.

The shared suite (test_solvers.py) covers recovery, noisy accuracy and bad input for every
backend; here: the SDP optimum is the least squares of eq. 8, the options, the diagnostics, the
status mapping, the cvxpy cache and the backend-specific options.

Solver tolerance: beta of every SDP backend equals `KroneckerSystem.least_squares` to 1e-10
relative (max-abs difference / max-abs entry); measured <= 6e-16 on these data, <= 2e-12 with
translations scaled by 1e-6 ... 1e6 (docs/solvers/lmi-sdp.md).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import threading

import numpy as np
import pytest

import handeye
from handeye import Status
from handeye.errors import BackendUnavailableError, InputError, SolverError
from handeye.noise import NoiseModel
from handeye.plugins import lmi_sdp
from handeye.problems.axyb import PROBLEM, solve_translations, split_beta
from handeye.se3 import gram_schmidt, project_to_so3, rotation_angle

SDP_BACKENDS = ("cvxpy", "picos")
NOISE = NoiseModel(sigmas={"A": (0.001, 0.3), "B": (0.005, 0.5)})
BETA_RTOL = 1e-10


@pytest.fixture(scope="module")
def noisy():
    raw, _ = PROBLEM.simulate(pairs=16, seed=5, noise=NOISE)
    return raw, PROBLEM.validate(**raw)


def _solve(raw, backend="cvxpy", **options):
    return handeye.solve("axyb", solver="lmi-sdp", backend=backend, **raw, **options)


def _rel(a, b) -> float:
    return float(np.abs(np.asarray(a) - b).max() / np.abs(b).max())


@pytest.mark.parametrize("backend", SDP_BACKENDS)
def test_sdp_optimum_is_least_squares_of_eq8(noisy, backend):
    raw, data = noisy
    system = data.kronecker_system
    sol = _solve(raw, backend)
    d = sol.diagnostics
    beta_ls = system.least_squares()
    assert _rel(d["beta"], beta_ls) < BETA_RTOL
    # u* = rest (|R1 beta - q1| = 0 at the optimum); the Schur complement is ~0 there
    assert d["u"] == pytest.approx(system.rest, rel=1e-8)
    assert d["rest"] == system.rest
    assert d["cost"] == pytest.approx(system.rest, rel=1e-12)
    assert abs(d["schur_complement"]) < 1e-8 * system.rest
    # the paper's defaults: Gram-Schmidt, translations of beta
    MX, MY, tX, tY = split_beta(beta_ls)
    np.testing.assert_allclose(sol.X[:3, :3], gram_schmidt(MX), rtol=0, atol=1e-12)
    np.testing.assert_allclose(sol.Y[:3, :3], gram_schmidt(MY), rtol=0, atol=1e-12)
    scale = data.translation_scale
    np.testing.assert_allclose(sol.X[:3, 3], tX, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(sol.Y[:3, 3], tY, rtol=0, atol=1e-10 * scale)


def test_orthogonalize_and_translations_options(noisy):
    raw, data = noisy
    MX, MY, _, _ = split_beta(data.kronecker_system.least_squares())
    gs = _solve(raw, orthogonalize="gram-schmidt")
    svd = _solve(raw, orthogonalize="svd", translations="resolve")
    np.testing.assert_allclose(svd.X[:3, :3], project_to_so3(MX), rtol=0, atol=1e-12)
    np.testing.assert_allclose(svd.Y[:3, :3], project_to_so3(MY), rtol=0, atol=1e-12)
    # on noisy data the two orthogonalisations differ measurably (Gram-Schmidt favours column 1)
    for name in ("X", "Y"):
        angle = rotation_angle(gs.unknowns[name][:3, :3] @ svd.unknowns[name][:3, :3].T)
        assert 1e-6 < angle < 1e-2, (name, angle)
    tX, tY = solve_translations(data, svd.X[:3, :3], svd.Y[:3, :3])
    np.testing.assert_allclose(svd.X[:3, 3], tX, rtol=0, atol=1e-9 * data.translation_scale)
    np.testing.assert_allclose(svd.Y[:3, 3], tY, rtol=0, atol=1e-9 * data.translation_scale)
    assert svd.diagnostics["orthogonalize"] == "svd" and svd.diagnostics["translations"] == "resolve"


@pytest.mark.parametrize("backend", SDP_BACKENDS)
def test_diagnostics(noisy, backend):
    raw, data = noisy
    sol = _solve(raw, backend)
    d = sol.diagnostics
    assert sol.status is Status.OPTIMAL and d["solver_status"] == "optimal"
    assert d["backend_solver"] == {"cvxpy": "CLARABEL", "picos": "cvxopt"}[backend]
    assert isinstance(d["iterations"], int) and 0 < d["iterations"] < 50
    assert d["sigma_min_R1"] == pytest.approx(data.kronecker_system.smallest_singular_value(), rel=1e-12)
    assert d["normalized"] is False and d["translation_scale"] == 1.0
    assert d["beta"].shape == (24,) and not d["beta"].flags.writeable
    assert np.isfinite(d["u"]) and np.isfinite(d["cost"])


@pytest.mark.parametrize("translations", ["beta", "resolve"])
@pytest.mark.parametrize("s", [1e-3, 1e3])
def test_normalize_gives_unit_invariance(noisy, s, translations):
    """Measured: rotations 1e-15 rad, translations 1e-15 relative."""
    raw, data = noisy
    scaled = {k: np.array(v) for k, v in raw.items()}
    for T in scaled.values():
        T[:, :3, 3] *= s
    a = _solve(raw, normalize=True, translations=translations)
    b = _solve(scaled, normalize=True, translations=translations)
    assert a.diagnostics["normalized"] and a.diagnostics["translation_scale"] == data.translation_scale
    for name in ("X", "Y"):
        ta, tb = a.unknowns[name], b.unknowns[name]
        assert rotation_angle(tb[:3, :3] @ ta[:3, :3].T) < 1e-9
        assert np.linalg.norm(tb[:3, 3] / s - ta[:3, 3]) < 1e-9 * data.translation_scale


def test_default_is_not_unit_invariant(noisy):
    raw, _ = noisy
    scaled = {k: np.array(v) for k, v in raw.items()}
    for T in scaled.values():
        T[:, :3, 3] *= 1e-3
    a, b = _solve(raw), _solve(scaled)
    assert rotation_angle(b.X[:3, :3] @ a.X[:3, :3].T) > 1e-6  # hence unit_invariant=False
    spec = handeye.get_registry().solver("lmi-sdp", "axyb")
    assert spec.is_unit_invariant() is False and spec.is_unit_invariant({"normalize": True}) is True


def test_cvxpy_problem_compiled_once_and_reused(noisy):
    raw, _ = noisy
    _solve(raw)
    cached = lmi_sdp.cvxpy_problem("CLARABEL")
    assert cached.problem.is_dpp()
    builds = lmi_sdp.CVXPY_CACHE.builds
    program = cached.problem._cache.param_prog  # cvxpy's compiled parameter -> data map
    assert program is not None
    other, _ = PROBLEM.simulate(pairs=40, seed=6, noise=NOISE)
    _solve(other)
    assert lmi_sdp.cvxpy_problem("CLARABEL") is cached and lmi_sdp.CVXPY_CACHE.builds == builds
    assert cached.problem._cache.param_prog is program  # no re-canonicalisation


def test_cvxpy_solver_option(noisy):
    raw, data = noisy
    sol = _solve(raw, cvxpy_solver="cvxopt")  # case-insensitive
    assert sol.diagnostics["backend_solver"] == "CVXOPT"
    assert _rel(sol.diagnostics["beta"], data.kronecker_system.least_squares()) < BETA_RTOL
    with pytest.raises(InputError, match="no_such_solver.*CLARABEL") as info:
        _solve(raw, cvxpy_solver="no_such_solver")
    for name in lmi_sdp.sdp_cvxpy_solvers():
        assert name in str(info.value)
    lp_only = sorted(set(importlib.import_module("cvxpy").installed_solvers()) - set(lmi_sdp.sdp_cvxpy_solvers()))
    if lp_only:
        with pytest.raises(InputError, match="cannot solve semidefinite"):
            _solve(raw, cvxpy_solver=lp_only[0])


@pytest.mark.parametrize("backend, option", [
    ("cvxpy", {"multistart": 2}), ("cvxpy", {"ipopt_options": {"max_iter": 5}}), ("picos", {"seed": 1}),
    ("picos", {"cvxpy_solver": "SCS"}), ("casadi", {"cvxpy_solver": "CLARABEL"}),
])
def test_backend_specific_options_rejected_elsewhere(noisy, backend, option):
    raw, _ = noisy
    with pytest.raises(InputError, match=f"option {next(iter(option))} applies only to backend"):
        _solve(raw, backend, **option)


@pytest.mark.parametrize("option", [{"orthogonalize": "qr"}, {"translations": "both"},
                                    {"normalize": "yes"}, {"multistart": -1}, {"cvxpy_solver": 3},
                                    {"ipopt_options": "tol=1"}])
def test_bad_option_values(noisy, option):
    raw, _ = noisy
    with pytest.raises(InputError, match=next(iter(option))):
        _solve(raw, **option)


def test_casadi_backend_wiring(noisy):
    raw, data = noisy
    sol = _solve(raw, "casadi", multistart=1, seed=0, translations="resolve")
    d = sol.diagnostics
    assert d["starts_tried"] == 2 and d["ipopt_status"] == "Solve_Succeeded"
    assert d["sigma_min_R1"] == pytest.approx(data.kronecker_system.smallest_singular_value(), rel=1e-12)
    # exact SO(3): cost of eq. 8 not below the unconstrained least squares, close to it
    assert d["cost"] >= data.kronecker_system.rest * (1 - 1e-12)


class _FakeProblem:
    def __init__(self, status):
        self.status = status
        self.solver_stats = type("Stats", (), {"num_iters": 3})()

    def solve(self, **kwargs):
        pass


@pytest.mark.parametrize("status, expected", [("optimal_inaccurate", Status.OPTIMAL_INACCURATE),
                                              ("infeasible", None), ("unbounded", None),
                                              ("solver_error", None), ("user_limit", None)])
def test_status_mapping(noisy, monkeypatch, status, expected):
    raw, data = noisy
    real = lmi_sdp.cvxpy_problem("CLARABEL")
    gamma = type("V", (), {"value": data.kronecker_system.least_squares() / lmi_sdp.ScaledLMI.of(
        data.kronecker_system, 1.0).d})()
    u = type("V", (), {"value": 1.0})()
    fake = dataclasses.replace(real, problem=_FakeProblem(status), gamma=gamma, u=u, lock=threading.Lock())
    monkeypatch.setitem(lmi_sdp.CVXPY_CACHE.problems, ("CLARABEL", 24), fake)
    if expected is None:
        with pytest.raises(SolverError, match=status):
            _solve(raw)
    else:
        sol = _solve(raw)
        assert sol.status is expected and sol.diagnostics["solver_status"] == status


def test_picos_missing_is_backend_unavailable(noisy, monkeypatch):
    raw, _ = noisy
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "picos" else real_find_spec(name, *a))
    with pytest.raises(BackendUnavailableError, match=r"module 'picos'.*pip install picos"):
        _solve(raw, "picos")


def test_cached_problem_is_thread_safe(noisy):
    from concurrent.futures import ThreadPoolExecutor

    raw, _ = noisy
    other, _ = PROBLEM.simulate(pairs=20, seed=8, noise=NOISE)
    cases = [raw, other] * 4
    expected = [_solve(case) for case in cases[:2]]
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(_solve, cases))
    for k, sol in enumerate(results):
        for name in ("X", "Y"):
            np.testing.assert_allclose(sol.unknowns[name], expected[k % 2].unknowns[name], rtol=0, atol=1e-12)
