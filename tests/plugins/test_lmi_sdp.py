"""`lmi-sdp` (plugins/lmi_sdp/): the paper's LMI of eq. 14 on clarabel (native,
plugins/lmi_sdp/clarabel.py), cvxpy and picos.

The shared suite (test_solvers.py) covers recovery, noisy accuracy and bad input for every
backend; here: the SDP optimum is the least squares of eq. 8, the options, the diagnostics, the
status mapping, the cvxpy cache, the native backend's cached structure and the backend-specific
options; at the end the native backend on ``axxb`` and ``axbycz`` (their cvxpy and picos backends
are tested in test_axxb_kronecker.py and test_axbycz_linear.py).

Solver tolerance: beta of every SDP backend equals `KroneckerSystem.least_squares` to 1e-10
relative (max-abs difference / max-abs entry); measured <= 6e-16 on these data; with translations
scaled by 1e-6 ... 1e6 <= 3e-14 (clarabel), 6e-12 (cvxpy), 4e-15 (picos) (docs/solvers/lmi-sdp.md).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import threading
import types

import numpy as np
import pytest
from tolerances import solved

import handeye
from handeye import Status
from handeye.base.errors import BackendUnavailableError, InputError, SolverError
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import gram_schmidt, project_to_so3, rotation_angle
from handeye.plugins import lmi_sdp
from handeye.plugins._sdp_backends import svec
from handeye.plugins.lmi_sdp import clarabel as lmi_sdp_clarabel
from handeye.problems.axyb import PROBLEM, solve_translations, split_beta

SDP_BACKENDS = ("clarabel", "cvxpy", "picos")
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
    assert solved(sol) and d["solver_status"] == "optimal"
    assert d["backend_solver"] == {"clarabel": "CLARABEL", "cvxpy": "CLARABEL", "picos": "cvxopt"}[backend]
    assert isinstance(d["iterations"], int) and 0 < d["iterations"] < 50
    assert d["sigma_min_R1"] == pytest.approx(data.kronecker_system.smallest_singular_value(), rel=1e-12)
    assert d["normalized"] is False and d["translation_scale"] == 1.0
    assert d["beta"].shape == (24,) and not d["beta"].flags.writeable
    assert np.isfinite(d["u"]) and np.isfinite(d["cost"])


@pytest.mark.parametrize("backend", ["clarabel", "cvxpy"])
@pytest.mark.parametrize("translations", ["beta", "resolve"])
@pytest.mark.parametrize("s", [1e-3, 1e3])
def test_normalize_gives_unit_invariance(noisy, s, translations, backend):
    """Measured: rotations 1e-15 rad, translations 1e-15 relative."""
    raw, data = noisy
    scaled = {k: np.array(v) for k, v in raw.items()}
    for T in scaled.values():
        T[:, :3, 3] *= s
    a = _solve(raw, backend, normalize=True, translations=translations)
    b = _solve(scaled, backend, normalize=True, translations=translations)
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
    ("clarabel", {"cvxpy_solver": "CLARABEL"}), ("clarabel", {"multistart": 1}),
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


@pytest.mark.parametrize("module", ["picos", "clarabel"])
def test_missing_package_is_backend_unavailable(noisy, monkeypatch, module):
    raw, _ = noisy
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == module else real_find_spec(name, *a))
    with pytest.raises(BackendUnavailableError, match=rf"module '{module}'.*pip install {module}"):
        _solve(raw, module)


@pytest.mark.parametrize("backend", ["clarabel", "cvxpy"])
def test_cached_problem_is_thread_safe(noisy, backend):
    from concurrent.futures import ThreadPoolExecutor

    raw, _ = noisy
    other, _ = PROBLEM.simulate(pairs=20, seed=8, noise=NOISE)
    cases = [raw, other] * 4
    expected = [_solve(case, backend) for case in cases[:2]]
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda case: _solve(case, backend), cases))
    for k, sol in enumerate(results):
        for name in ("X", "Y"):
            np.testing.assert_allclose(sol.unknowns[name], expected[k % 2].unknowns[name], rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# backend clarabel (plugins/lmi_sdp/clarabel.py): the same eq. 14 in Clarabel's own API


def test_clarabel_is_the_default_backend(noisy):
    raw, _ = noisy
    registry = handeye.get_registry()
    for problem in ("axyb", "axxb", "axbycz"):
        spec = registry.solver("lmi-sdp", problem)
        assert spec.default_backend == "clarabel" and next(iter(spec.backends)) == "clarabel"
        assert spec.backends["clarabel"] == ("clarabel",)
    sol = handeye.solve("axyb", solver="lmi-sdp", **raw)
    assert sol.backend == "clarabel" and sol.diagnostics["compile_seconds"] == 0.0


@pytest.mark.parametrize("n", [24, 132])
def test_clarabel_data_are_svec_of_the_lmi(n):
    """s = b - A x is svec of [[u - rest, (R gamma - q)^T], [R gamma - q, I]] (Clarabel's
    convention: upper triangle column by column, sqrt(2) off the diagonal) for any u, gamma."""
    rng = np.random.default_rng(n)
    R, q, rest = np.triu(rng.standard_normal((n, n))), rng.standard_normal(n), 0.7
    u, gamma = 1.3, rng.standard_normal(n)
    e = R @ gamma - q
    L = np.eye(n + 1)
    L[0, 0], L[0, 1:], L[1:, 0] = u - rest, e, e
    structure = lmi_sdp_clarabel.eq14_structure(n)
    A, b = structure.data(R, q, rest)
    np.testing.assert_allclose(b - A @ np.r_[u, gamma], svec(L), rtol=0, atol=1e-12)
    assert A.nnz == n * (n + 1) // 2 + 1  # the upper triangle of R and u: the fixed pattern
    with pytest.raises(ValueError, match="upper triangular"):
        lmi_sdp_clarabel.solve_eq14(R + np.tril(np.ones((n, n)), -1), q, rest)


def test_clarabel_structure_built_once_per_n(noisy):
    raw, _ = noisy
    _solve(raw, "clarabel")
    structure = lmi_sdp_clarabel.eq14_structure(24)
    builds = lmi_sdp_clarabel.eq14_structure.cache_info().misses
    other, _ = PROBLEM.simulate(pairs=40, seed=6, noise=NOISE)
    a, b = _solve(other, "clarabel"), _solve(raw, "clarabel")
    assert lmi_sdp_clarabel.eq14_structure(24) is structure
    assert lmi_sdp_clarabel.eq14_structure.cache_info().misses == builds
    assert not structure.indices.flags.writeable and not structure.b_constant.flags.writeable
    assert a.diagnostics["iterations"] > 0 and b.diagnostics["compile_seconds"] == 0.0


@pytest.mark.parametrize("s", [1e-6, 1e-3, 1e3, 1e6])
@pytest.mark.parametrize("backend", ["clarabel", "cvxpy"])
def test_beta_is_least_squares_in_any_unit(backend, s):
    """Every translation times s, noisy and noise-free data (module docstring of lmi_sdp.axyb,
    Numerics: c capped at 1 for Clarabel). Measured: <= 3e-14 (clarabel), 6e-12 (cvxpy)."""
    noise_free, _ = PROBLEM.simulate(pairs=12, seed=3, **PROBLEM.random_unknowns(np.random.default_rng(3)))
    noisy_raw, _ = PROBLEM.simulate(pairs=16, seed=4, noise=NOISE)
    for raw in (noise_free, noisy_raw):
        scaled = {k: np.array(v) for k, v in raw.items()}
        for T in scaled.values():
            T[:, :3, 3] *= s
        sol = _solve(scaled, backend)
        beta_ls = PROBLEM.validate(**scaled).kronecker_system.least_squares()
        # (at 1e-6 the host's self-check may call the noisy answer unreliable: the translations are
        # too small for the method, `lmi_sdp.SMALL_TRANSLATION`; the SDP is still solved exactly)
        assert _rel(sol.diagnostics["beta"], beta_ls) < BETA_RTOL


def test_clarabel_and_cvxpy_give_the_same_answer(noisy):
    raw, _ = noisy
    native, cvxpy = _solve(raw, "clarabel"), _solve(raw, "cvxpy")
    assert _rel(native.diagnostics["beta"], cvxpy.diagnostics["beta"]) < 1e-13
    assert native.diagnostics["u"] == pytest.approx(cvxpy.diagnostics["u"], rel=1e-10)
    for name in ("X", "Y"):
        np.testing.assert_allclose(native.unknowns[name], cvxpy.unknowns[name], rtol=0, atol=1e-10)


def _clarabel_reports(monkeypatch, status: str) -> None:
    """Make Clarabel solve as usual but report `status`."""
    import clarabel

    real = clarabel.DefaultSolver

    class Reporting:
        def __init__(self, *args):
            self.solver = real(*args)

        def solve(self):
            s = self.solver.solve()
            return types.SimpleNamespace(status=status, x=s.x, z=s.z, iterations=s.iterations, solve_time=s.solve_time)

    monkeypatch.setattr(clarabel, "DefaultSolver", Reporting)


@pytest.mark.parametrize("status, expected", [("AlmostSolved", Status.OPTIMAL_INACCURATE), ("MaxIterations", None),
                                              ("PrimalInfeasible", None), ("DualInfeasible", None),
                                              ("NumericalError", None), ("InsufficientProgress", None)])
def test_clarabel_status_mapping(noisy, monkeypatch, status, expected):
    """Solved -> optimal (test_diagnostics), AlmostSolved -> optimal_inaccurate (the cvxpy
    backend's names), anything else a one-line SolverError naming clarabel and the status."""
    raw, _ = noisy
    _clarabel_reports(monkeypatch, status)
    if expected is None:
        with pytest.raises(SolverError, match=rf"^lmi-sdp: clarabel returned status '{status}' for the semidefinite "
                                              r"program \(after \d+ iterations\); no solution is returned$"):
            _solve(raw, "clarabel")
    else:
        sol = _solve(raw, "clarabel")
        assert sol.status is expected and sol.diagnostics["solver_status"] == "optimal_inaccurate"


def test_clarabel_failures_raise_solver_error(noisy, monkeypatch):
    raw, _ = noisy
    # a real iteration limit
    monkeypatch.setattr(lmi_sdp_clarabel, "CLARABEL_SETTINGS", {**lmi_sdp_clarabel.CLARABEL_SETTINGS, "max_iter": 1})
    with pytest.raises(SolverError, match="clarabel returned status 'MaxIterations'"):
        _solve(raw, "clarabel")
    # Clarabel itself raising (here: a setting it does not have)
    monkeypatch.setattr(lmi_sdp_clarabel, "CLARABEL_SETTINGS", {"no_such_setting": 1})
    with pytest.raises(SolverError, match="^lmi-sdp: Clarabel failed on the SDP: "):
        _solve(raw, "clarabel")


# --------------------------------------------------------------------------------------------
# backend clarabel on axxb and axbycz


def _axxb_case(seed: int = 3):
    from handeye.problems import axxb

    raw, _ = axxb.PROBLEM.simulate(pairs=16, seed=seed, noise=NoiseModel.on(("A", "B"), 0.002, 0.2))
    return raw, axxb.PROBLEM.validate(**raw)


@pytest.mark.parametrize("normalize", [False, True])
def test_axxb_clarabel_sdp_is_the_trust_region_solution(normalize):
    """As test_axxb_kronecker.test_sdp_optimum_is_the_trust_region_solution for cvxpy and picos.
    Measured: eigenvalue ratio <= 7e-14, the SDP's r within 1.5e-7 of the trust-region r."""
    from handeye.estimation.rotation_cost import (
        RotationCost,
        signed_rotations,
        sphere_least_squares,
    )

    raw, data = _axxb_case()
    scale = data.translation_scale if normalize else 1.0
    cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)
    x = sphere_least_squares(cost).x
    reference = -x if signed_rotations(cost, x)[1] else x
    sol = handeye.solve("axxb", solver="lmi-sdp", backend="clarabel", normalize=normalize, **raw)
    d = sol.diagnostics
    assert sol.status is Status.OPTIMAL and not d["rank_two"] and d["backend_solver"] == "CLARABEL"
    assert d["eigenvalue_ratio"] < 1e-8 and d["solver_status"] in ("optimal", "optimal_inaccurate")
    assert np.abs(d["sdp_r"] - reference).max() < 1e-5
    assert np.abs(d["beta"][:9] - reference).max() < 1e-12
    assert abs(d["sdp_objective"] - cost.value(reference)) < 1e-9 * np.linalg.norm(cost.matrix)
    cvxpy = handeye.solve("axxb", solver="lmi-sdp", backend="cvxpy", normalize=normalize, **raw)
    np.testing.assert_allclose(sol.X, cvxpy.X, rtol=0, atol=1e-10 * data.translation_scale)
    unpolished = handeye.solve("axxb", solver="lmi-sdp", backend="clarabel", normalize=normalize, polish=False, **raw)
    np.testing.assert_array_equal(unpolished.diagnostics["beta"][:9], unpolished.diagnostics["sdp_r"])


def test_axxb_clarabel_on_the_rotation_rig():
    """Every motion rotating about one point: Z has rank two (both signs of r optimal), and the
    rotation is still found (test_axxb_kronecker.test_rotation_rig_is_solved for cvxpy)."""
    from handeye.geometry.se3 import inverse, make_pose, random_rotations
    from handeye.problems import axxb

    rng = np.random.default_rng(2)
    X = axxb.PROBLEM.random_unknowns(rng)["X"]
    R = random_rotations(8, rng)
    A = make_pose(R, np.einsum("nij,j->ni", np.eye(3) - R, 400.0 * rng.standard_normal(3)))
    sol = handeye.solve("axxb", solver="lmi-sdp", backend="clarabel", A=A, B=inverse(X) @ A @ X)
    assert sol.diagnostics["rank_two"] and sol.diagnostics["eigenvalue_ratio"] > 0.1
    assert rotation_angle(sol.X[:3, :3] @ X[:3, :3].T) < 1e-9


@pytest.mark.parametrize("problem", ["axxb", "axbycz"])
def test_clarabel_status_is_mapped_on_axxb_and_axbycz(monkeypatch, problem):
    from handeye.problems import axbycz

    if problem == "axxb":
        raw, _ = _axxb_case()
        what = "AX=XB"
    else:
        raw, _ = axbycz.PROBLEM.simulate(pairs=12, seed=9, noise=NoiseModel.on(("A", "B", "C"), 0.002, 0.2))
        what = "AXB=YCZ"
    _clarabel_reports(monkeypatch, "NumericalError")
    with pytest.raises(SolverError, match=rf"clarabel returned status 'NumericalError' for the semidefinite program "
                                          rf"of {what}"):
        handeye.solve(problem, solver="lmi-sdp", backend="clarabel", **raw)
    _clarabel_reports(monkeypatch, "AlmostSolved")  # the polish certifies the point: optimal
    sol = handeye.solve(problem, solver="lmi-sdp", backend="clarabel", **raw)
    assert solved(sol) and sol.diagnostics["solver_status"] == "optimal_inaccurate"


def test_axbycz_clarabel_matches_the_least_squares_and_cvxpy():
    """scale="translations": eq. 14 at n = 132 (the same native code as axyb) is the least squares
    of the lifted system; scale="norm": the arrow SDP gives cvxpy's answer (both the
    trust-region solution after the polish)."""
    from handeye.estimation.kronecker import reduce_normal_equations
    from handeye.problems import axbycz
    from handeye.problems.axbycz import kronecker as lifted

    raw, _ = axbycz.PROBLEM.simulate(pairs=20, seed=8, noise=NoiseModel.on(("A", "B", "C"), 0.002, 0.2))
    data = axbycz.PROBLEM.validate(**raw)
    literal = handeye.solve("axbycz", solver="lmi-sdp", backend="clarabel", scale="translations", **raw)
    system = reduce_normal_equations(*lifted.normal_equations(data, data.translation_scale))
    beta = system.least_squares()
    assert np.abs(literal.diagnostics["beta"] - beta).max() < BETA_RTOL * np.abs(beta).max()
    assert literal.diagnostics["u"] == pytest.approx(system.rest, rel=1e-8)
    assert lmi_sdp_clarabel.eq14_structure(132).n == 132
    native = handeye.solve("axbycz", solver="lmi-sdp", backend="clarabel", **raw)
    cvxpy = handeye.solve("axbycz", solver="lmi-sdp", backend="cvxpy", **raw)
    assert native.status is Status.OPTIMAL and native.diagnostics["kkt_residual"] < 1e-10
    assert native.diagnostics["sdp_objective"] == pytest.approx(cvxpy.diagnostics["sdp_objective"], rel=1e-8)
    for name in "XYZ":
        np.testing.assert_allclose(native.unknowns[name], cvxpy.unknowns[name], rtol=0, atol=1e-9 * data.translation_scale)
