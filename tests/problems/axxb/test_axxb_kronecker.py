"""The Kronecker solvers for ``axxb`` (A_i X = X B_i): `kron-lstsq`, `lmi-sdp` (cvxpy, picos,
casadi) and `so3-sdp` (cvxpy, picos), and the trust-region solver behind them
(`handeye.estimation.trust_region`).

What is special about AX = XB here (docs/solvers/kron-lstsq.md): the rotation rows of the linear
system are homogeneous, so plain least squares is singular when every motion rotates about one
common point (t_Ai = (I - R_Ai) u); every solver here fixes the scale by |vec R_X|^2 = 3 (or by
R_X in SO(3)) instead and still solves that rig. The shared suite (test_solvers.py) runs the
generic recovery, noisy-accuracy, bad-input and unit-invariance tests for these specs as well.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize
from tolerances import solved

import handeye
from handeye import Status
from handeye.base.errors import DegenerateDataError
from handeye.estimation.noise import NoiseModel
from handeye.estimation.rotation_cost import (
    RotationCost,
    rotations_vector,
    signed_rotations,
    sphere_least_squares,
)
from handeye.estimation.trust_region import refine_trust_region, solve_trust_region
from handeye.geometry.se3 import (
    gram_schmidt,
    inverse,
    make_pose,
    project_to_so3,
    random_rotations,
    rotation_angle,
)
from handeye.problems.axxb import PROBLEM, regression_blocks, solve_translation

NOISE = NoiseModel.on(("A", "B"), 0.002, 0.2)
#: (solver, backend) pairs held to the noise-free bound (casadi included: it reaches ~1e-15)
SOLVERS = [("kron-lstsq", "numpy"), ("so3-sdp", "clarabel"), ("so3-sdp", "cvxpy"), ("so3-sdp", "picos"),
           ("lmi-sdp", "cvxpy"), ("lmi-sdp", "picos"), ("lmi-sdp", "casadi")]
NOISE_FREE_TOL = 1e-9  # rad, and relative to the data's translation scale
#: options that make so3-sdp solve its SDP (by default it certifies a local answer first)
SDP = {"local_first": False}


def solve(raw: dict, solver: str, backend: str | None = None, **options) -> handeye.Solution:
    return handeye.solve("axxb", solver=solver, backend=backend, **raw, **options)


def noise_free(seed: int, pairs: int = 8):
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    return PROBLEM.simulate(pairs=pairs, seed=seed, **truth)


def cost_of(raw: dict, normalize: bool = True) -> RotationCost:
    data = PROBLEM.validate(**raw)
    scale = data.translation_scale if normalize else 1.0
    return RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)


def trs_r(raw: dict, normalize: bool = True) -> np.ndarray:
    """kron-lstsq's r (vec R_X on |r|^2 = 3, before projection), sign as it chooses it."""
    cost = cost_of(raw, normalize)
    x = sphere_least_squares(cost).x
    return -x if signed_rotations(cost, x)[1] else x


def rotation_rig(pairs: int, seed: int) -> tuple[dict, np.ndarray]:
    """Every robot motion a pure rotation about one fixed point u: t_Ai = (I - R_Ai) u (a camera
    rotating about its own centre, in the frame of A). Noise-free; returns data and X."""
    rng = np.random.default_rng(seed)
    X = PROBLEM.random_unknowns(rng)["X"]
    u = 400.0 * rng.standard_normal(3)
    R = random_rotations(pairs, rng)
    A = make_pose(R, np.einsum("nij,j->ni", np.eye(3) - R, u))
    return {"A": A, "B": inverse(X) @ A @ X}, X


def assert_recovers(sol: handeye.Solution, raw: dict, X: np.ndarray, tol: float = NOISE_FREE_TOL) -> None:
    errors = PROBLEM.errors(sol.unknowns, {"X": X})["X"]
    scale = PROBLEM.validate(**raw).translation_scale
    assert errors["rotation"] < tol and errors["translation"] < tol * scale, errors


# --------------------------------------------------------------------------------------------
# noise-free recovery, the rig


@pytest.mark.parametrize("solver, backend", SOLVERS, ids=[f"{s}/{b}" for s, b in SOLVERS])
def test_noise_free_recovery(solver, backend):
    """Measured (seeds 0-9): <= 5.1e-15 rad, <= 2.0e-15 relative for every solver and backend."""
    for seed in (21, 22):
        raw, truth = noise_free(seed)
        sol = solve(raw, solver, backend)
        assert sol.status is Status.OPTIMAL
        assert_recovers(sol, raw, truth["X"])


def test_plain_least_squares_is_singular_on_a_rotation_rig():
    """t_Ai = (I - R_Ai) u for all i: H [vec R_X; t_X - u] = 0 (module docstring of
    plugins/kron_lstsq.py), so H has a null vector and plain least squares has no unique answer;
    on ordinary data it has none."""
    raw, X = rotation_rig(8, seed=1)
    data = PROBLEM.validate(**raw).scaled(PROBLEM.validate(**raw).translation_scale)
    H, _ = regression_blocks(data.A, data.B)
    sigma = np.linalg.svd(H.reshape(-1, 12), compute_uv=False)
    assert sigma[-1] < 1e-13 * sigma[0]  # measured 1.7e-16 .. 3.4e-16
    u = np.linalg.lstsq((np.eye(3) - data.A[:, :3, :3]).reshape(-1, 3), data.A[:, :3, 3].ravel(), rcond=None)[0]
    null = np.concatenate([X[:3, :3].ravel(order="F"), X[:3, 3] / PROBLEM.validate(**raw).translation_scale - u])
    assert np.abs(H.reshape(-1, 12) @ null).max() < 1e-12
    simulated, _ = noise_free(1)
    d = PROBLEM.validate(**simulated)
    d = d.scaled(d.translation_scale)
    H2, _ = regression_blocks(d.A, d.B)
    s2 = np.linalg.svd(H2.reshape(-1, 12), compute_uv=False)
    assert s2[-1] > 1e-3 * s2[0]  # measured 0.048 .. 0.15
    # the Cholesky reduction of plain least squares fails or is meaningless on the rig
    try:
        system = PROBLEM.validate(**raw).kronecker_system
    except DegenerateDataError:
        pass
    else:
        assert system.smallest_singular_value() < 1e-6 * np.linalg.norm(system.R1, 2)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_rotation_rig_is_solved(seed):
    raw, X = rotation_rig(8, seed)
    sol = solve(raw, "kron-lstsq")
    assert sol.status is Status.OPTIMAL and sol.diagnostics["hard_case"]
    assert sol.diagnostics["relative_lambda_min"] < 1e-13
    assert_recovers(sol, raw, X)
    # the SDP of lmi-sdp is rank two there (both signs of r optimal); the rotation is still found
    lmi = solve(raw, "lmi-sdp", "cvxpy")
    assert lmi.diagnostics["rank_two"] and lmi.diagnostics["eigenvalue_ratio"] > 0.1
    assert_recovers(lmi, raw, X)
    assert_recovers(solve(raw, "so3-sdp"), raw, X)


def test_rotation_rig_sign_is_chosen_by_the_cost():
    """On the rig r and -r are both minimisers on the sphere; only one is near a rotation."""
    flips = set()
    for seed in range(1, 9):
        raw, X = rotation_rig(6, seed)
        sol = solve(raw, "kron-lstsq")
        flips.add(sol.diagnostics["sign_flipped"])
        assert rotation_angle(sol.X[:3, :3] @ X[:3, :3].T) < NOISE_FREE_TOL
    assert flips == {True, False}  # the eigensolver's sign is arbitrary: both occur


# --------------------------------------------------------------------------------------------
# lmi-sdp: the SDP is tight, its optimum is the trust-region solution


@pytest.mark.parametrize("backend", ["cvxpy", "picos"])
@pytest.mark.parametrize("normalize", [False, True])
def test_sdp_optimum_is_the_trust_region_solution(backend, normalize):
    """Measured on 5 seeds: eigenvalue ratio <= 4e-11 (rank one); the SDP's own r within
    4e-7 (Clarabel) / 3.3e-6 (CVXOPT) of the trust-region r, polished to <= 1.3e-15."""
    raw, _ = PROBLEM.simulate(pairs=16, seed=3, noise=NOISE)
    reference = trs_r(raw, normalize)
    sol = solve(raw, "lmi-sdp", backend, normalize=normalize)
    d = sol.diagnostics
    assert sol.status is Status.OPTIMAL and not d["rank_two"]
    assert d["eigenvalue_ratio"] < 1e-8
    assert np.abs(d["sdp_r"] - reference).max() < 1e-5
    assert np.abs(d["beta"][:9] - reference).max() < 1e-12
    cost = cost_of(raw, normalize)
    # the SDP's optimal value is the trust-region minimum, to the SDP solver's tolerance (relative
    # to |M|: with normalize=False, in mm, the minimum is ~1e-7 |M|)
    assert abs(d["sdp_objective"] - cost.value(reference)) < 1e-9 * np.linalg.norm(cost.matrix)
    raw_sol = solve(raw, "lmi-sdp", backend, normalize=normalize, polish=False)
    np.testing.assert_array_equal(raw_sol.diagnostics["beta"][:9], raw_sol.diagnostics["sdp_r"])


def test_lmi_sdp_options():
    raw, _ = PROBLEM.simulate(pairs=16, seed=4, noise=NOISE)
    data = PROBLEM.validate(**raw)
    r = trs_r(raw, normalize=False)
    gs = solve(raw, "lmi-sdp")  # the paper's defaults: Gram-Schmidt, translations of beta
    svd = solve(raw, "lmi-sdp", orthogonalize="svd", translations="resolve")
    np.testing.assert_allclose(gs.X[:3, :3], gram_schmidt(r.reshape(3, 3, order="F")), atol=1e-12)
    np.testing.assert_allclose(svd.X[:3, :3], project_to_so3(r.reshape(3, 3, order="F")), atol=1e-12)
    np.testing.assert_allclose(gs.X[:3, 3], gs.diagnostics["beta"][9:], atol=1e-12 * data.translation_scale)
    np.testing.assert_allclose(svd.X[:3, 3], solve_translation(data, svd.X[:3, :3]),
                               atol=1e-9 * data.translation_scale)
    spec = handeye.get_registry().solver("lmi-sdp", "axxb")
    assert "polish" in spec.option_names() and "polish" not in handeye.get_registry().solver("lmi-sdp", "axyb").option_names()


def test_cvxpy_problems_compiled_once_per_process(monkeypatch):
    """lmi-sdp's SDP and so3-sdp's one-rotation relaxation: built and compiled on their first
    solve (compile_seconds > 0), then reused with new parameters only."""
    from handeye.plugins import so3_sdp
    from handeye.plugins.lmi_sdp import axxb as lmi_sdp_axxb

    monkeypatch.setattr(lmi_sdp_axxb.CVXPY_CACHE, "problems", {})
    monkeypatch.setattr(so3_sdp.CVXPY_CACHE, "problems", {})
    a, _ = PROBLEM.simulate(pairs=5, seed=8, noise=NOISE)
    b, _ = PROBLEM.simulate(pairs=40, seed=9, noise=NOISE)
    for solver, module, key, options in (("lmi-sdp", lmi_sdp_axxb, ("CLARABEL",), {}),
                                         ("so3-sdp", so3_sdp, (True, "CLARABEL", 1), SDP)):
        assert solve(a, solver, "cvxpy", **options).diagnostics["compile_seconds"] > 0
        cached, builds = module.cvxpy_problem(*key), module.CVXPY_CACHE.builds
        assert solve(b, solver, "cvxpy", **options).diagnostics["compile_seconds"] == 0.0
        assert module.cvxpy_problem(*key) is cached and module.CVXPY_CACHE.builds == builds
    assert so3_sdp.cvxpy_problem(True, "CLARABEL", 1) is not so3_sdp.cvxpy_problem(True, "CLARABEL", 2)


# --------------------------------------------------------------------------------------------
# so3-sdp: certified, and never worse than kron-lstsq in the cost


@pytest.mark.parametrize("backend", ["clarabel", "cvxpy", "picos"])
def test_so3_sdp_certifies_and_beats_kron_lstsq(backend):
    for seed in (5, 6):
        raw, _ = PROBLEM.simulate(pairs=6, seed=seed, noise=NoiseModel.on(("A", "B"), 0.02, 2.0))
        sol = solve(raw, "so3-sdp", backend, **SDP)
        d = sol.diagnostics
        assert solved(sol) and d["certified"]
        assert d["eigenvalue_ratio"] < 1e-3 and d["relative_gap"] < 1e-6 and d["lower_bound"] <= d["cost"]
        cost = cost_of(raw)
        kron = solve(raw, "kron-lstsq")
        sdp_cost = cost.value(rotations_vector(sol.X[:3, :3]))
        assert sdp_cost <= cost.value(rotations_vector(kron.X[:3, :3])) * (1 + 1e-12)
        assert d["cost"] == pytest.approx(sdp_cost, rel=1e-9)
        # the translations are those of the cost for the returned rotation
        scale = PROBLEM.validate(**raw).translation_scale
        np.testing.assert_allclose(sol.X[:3, 3], solve_translation(PROBLEM.validate(**raw), sol.X[:3, :3]),
                                   atol=1e-9 * scale)


@pytest.mark.parametrize("backend", ["clarabel", "cvxpy"])
def test_so3_sdp_weak_relaxation_is_not_certified(backend):
    """Without the redundant constraints the relaxation is over O(3): rank one at a reflection
    (ratio ~1e-9), caught by the gap (docs/solvers/so3-sdp.md: 39 of 150 such draws)."""
    # seed 9 of that study: ratio 4e-8, relative gap 1.6
    raw, _ = PROBLEM.simulate(pairs=3, seed=9, noise=NoiseModel.on(("A", "B"), 0.2, 20.0), pairing="consecutive",
                              **PROBLEM.random_unknowns(np.random.default_rng(10_009)))
    weak = solve(raw, "so3-sdp", backend, redundant=False, **SDP)
    # the solver's own status; the host's checks then find the data too weak to use (status unreliable)
    assert weak.diagnostics.get("status_before_checks", weak.status) == Status.UNCERTIFIED
    assert weak.diagnostics["relative_gap"] > 1e-2
    assert weak.diagnostics["eigenvalue_ratio"] < 1e-3  # rank one: only the gap shows it
    strong = solve(raw, "so3-sdp", backend, **SDP)
    assert strong.diagnostics.get("status_before_checks", strong.status) == Status.OPTIMAL
    assert strong.diagnostics["cost"] < weak.diagnostics["cost"]


@pytest.mark.parametrize("seed, pairing", [(1, "consecutive"), (2, "consecutive"), (1, "all"), (3, "all")])
def test_so3_sdp_clarabel_backend_matches_cvxpy(seed, pairing):
    """Backend clarabel (the default) poses the cvxpy backend's conic program directly: the same
    polished answer and certificate (measured: bit-identical)."""
    raw, _ = PROBLEM.simulate(pairs=17 if pairing == "consecutive" else 7, seed=seed, noise=NOISE, pairing=pairing)
    native, ref = solve(raw, "so3-sdp", **SDP), solve(raw, "so3-sdp", "cvxpy", **SDP)
    assert native.backend == "clarabel"
    assert native.status is Status.OPTIMAL and ref.status is Status.OPTIMAL
    assert native.diagnostics["eigenvalue_ratio"] < 1e-3
    assert native.diagnostics["relative_gap"] == pytest.approx(ref.diagnostics["relative_gap"], abs=1e-9)
    assert rotation_angle(native.X[:3, :3].T @ ref.X[:3, :3]) < 1e-10
    np.testing.assert_allclose(native.X[:3, 3], ref.X[:3, 3], rtol=1e-10, atol=1e-10 * np.abs(ref.X[:3, 3]).max())


# --------------------------------------------------------------------------------------------
# units


@pytest.mark.parametrize("solver, options", [("kron-lstsq", {}), ("so3-sdp", {}), ("lmi-sdp", {"normalize": True})])
def test_unit_invariance_with_normalize(solver, options):
    raw, _ = PROBLEM.simulate(pairs=12, seed=7, noise=NOISE)
    base = solve(raw, solver, **options)
    for s in (1e-3, 1e3):
        scaled = {k: v.copy() for k, v in raw.items()}
        for v in scaled.values():
            v[:, :3, 3] *= s
        other = solve(scaled, solver, **options)
        assert rotation_angle(other.X[:3, :3] @ base.X[:3, :3].T) < 1e-9
        np.testing.assert_allclose(other.X[:3, 3] / s, base.X[:3, 3], rtol=0,
                                   atol=1e-9 * PROBLEM.validate(**raw).translation_scale)


# --------------------------------------------------------------------------------------------
# the trust-region solver against brute force


def brute_force(P: np.ndarray, p: np.ndarray, rho: float, rng: np.random.Generator) -> float:
    """min of x^T P x - 2 p^T x on |x| = rho: dense sampling of the sphere, then local descent
    (on the sphere, through x = rho y / |y|) from the best samples."""
    n = len(p)

    def f(y):
        x = rho * y / np.linalg.norm(y)
        return float(x @ P @ x - 2 * p @ x)

    if n == 2:
        a = np.linspace(0, 2 * np.pi, 20001)
        Y = np.stack([np.cos(a), np.sin(a)], axis=1)
    else:
        Y = rng.standard_normal((40000, n))
    X = rho * Y / np.linalg.norm(Y, axis=1, keepdims=True)
    values = np.einsum("ni,ij,nj->n", X, P, X) - 2 * X @ p
    best = np.argsort(values)[:5]
    return min(minimize(f, Y[i], method="BFGS", options={"gtol": 1e-12}).fun for i in best)


def random_problem(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, float]:
    G = rng.standard_normal((n, n))
    return G + G.T, rng.standard_normal(n), float(rng.uniform(0.3, 3.0))


def assert_global_conditions(P, p, rho, sol, atol=1e-10):
    d = np.linalg.eigvalsh(P)
    assert np.linalg.norm(sol.x) == pytest.approx(rho, rel=1e-12)
    assert np.abs(P @ sol.x - sol.multiplier * sol.x - p).max() < atol * (np.abs(P).max() * rho + np.abs(p).max())
    assert sol.multiplier <= d[0] + 1e-12 * np.abs(d).max()


def test_trust_region_against_brute_force():
    rng = np.random.default_rng(0)
    for trial in range(24):
        n = (2, 3, 4)[trial % 3]
        P, p, rho = random_problem(rng, n)
        if trial % 4 == 3:
            P = P @ P  # PSD, like the cost matrices of the solvers
        sol = solve_trust_region(P, p, rho)
        assert not sol.hard_case
        assert_global_conditions(P, p, rho, sol)
        assert sol.value == pytest.approx(float(sol.x @ P @ sol.x - 2 * p @ sol.x), rel=1e-12, abs=1e-12)
        assert sol.value <= brute_force(P, p, rho, rng) + 1e-9 * (1 + abs(sol.value))


@pytest.mark.parametrize("n", [2, 3, 4])
def test_trust_region_hard_case(n):
    """p orthogonal to the eigenvector of the smallest eigenvalue and small enough: lambda = d_1
    and x = x(d_1) +- tau v_1, both minimisers."""
    rng = np.random.default_rng(n)
    V = np.linalg.qr(rng.standard_normal((n, n)))[0]
    d = np.sort(rng.uniform(-2.0, 3.0, n))
    d[1:] += 0.5  # a simple smallest eigenvalue
    P = V @ np.diag(d) @ V.T
    q = np.zeros(n)
    q[1:] = 0.1 * rng.standard_normal(n - 1)
    p = V @ q
    rho = 2.0
    sol = solve_trust_region(P, p, rho)
    assert sol.hard_case and sol.multiplier == pytest.approx(d[0], abs=1e-12)
    assert_global_conditions(P, p, rho, sol)
    v1 = V[:, 0]
    other = sol.x - 2 * (sol.x @ v1) * v1  # the reflected minimiser
    assert float(other @ P @ other - 2 * p @ other) == pytest.approx(sol.value, abs=1e-12)
    assert sol.value <= brute_force(P, p, rho, rng) + 1e-9
    # near the hard case (a tiny component along v_1) the secular equation takes over smoothly
    near = solve_trust_region(P, p + 1e-9 * v1, rho)
    assert not near.hard_case and near.value == pytest.approx(sol.value, abs=1e-7)
    # p = 0: x = rho v_1 (up to sign)
    zero = solve_trust_region(P, np.zeros(n), rho)
    assert zero.hard_case and abs(abs(zero.x @ v1) - rho) < 1e-12


def test_trust_region_refine_from_a_perturbed_point():
    rng = np.random.default_rng(3)
    for _ in range(10):
        P, p, rho = random_problem(rng, 9)
        P = P @ P
        exact = solve_trust_region(P, p, rho)
        refined = refine_trust_region(P, p, rho, exact.x + 1e-4 * rng.standard_normal(9))
        assert refined.global_optimum and refined.iterations < 10
        assert np.abs(refined.x - exact.x).max() < 1e-12 * rho
    # from the wrong side of the sphere Newton finds another stationary point: not global
    P, p, rho = random_problem(rng, 4)
    exact = solve_trust_region(P, p, rho)
    far = refine_trust_region(P, p, rho, -exact.x)
    if np.abs(far.x - exact.x).max() > 1e-6:
        assert not far.global_optimum
