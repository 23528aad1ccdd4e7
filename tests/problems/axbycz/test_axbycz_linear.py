"""The linear and convex solvers of A_i X B_i = Y C_i Z: the lifted Kronecker system
(problems/axbycz/kronecker.py), `kron-lstsq`, `lmi-sdp` (cvxpy, picos, casadi) and `wu`
(plugins/axbycz_wu.py). The shared suite (test_solvers.py) runs them too; here: the system's
algebra, exact recovery with each method's protocol, accuracy on noisy data against the truth,
the LMI = least-squares equivalence, and the errors on data they cannot solve.

Noisy reference: 30 triples of the simulated two-arm cell, 0.002 rad / 0.2 mm on A, B and C
(test_solvers.NOISY's default for a problem), seeds 0..19. Measured (docs/solvers/wu.md,
kron-lstsq.md, lmi-sdp.md), worst over the 20 seeds and the three unknowns: rotation 2.8e-3 rad
(kron-lstsq), 3.0e-3 (lmi-sdp cvxpy / picos), 2.4e-3 (lmi-sdp casadi), 6.2e-3 (wu, the paper's
10 sign triples), 2.8e-3 (wu, all triples); translation 2.0, 2.2, 1.7, 5.6, 2.4 mm. The bounds
below are ~2x those.
"""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.kronecker import reduce_normal_equations
from handeye.estimation.noise import NoiseModel
from handeye.estimation.trust_region import solve_trust_region
from handeye.geometry.dualquat import quat_from_rotation, quat_multiply
from handeye.problems.axbycz import PROBLEM
from handeye.problems.axbycz import kronecker as lifted

NOISE = NoiseModel.on(("A", "B", "C"), 0.002, 0.2)
SDP_BACKENDS = ("cvxpy", "picos")
#: (solver, backend, options, triples) recovering exact data (free protocol)
EXACT = [
    ("kron-lstsq", "numpy", {}, 12),
    ("lmi-sdp", "cvxpy", {}, 12),
    ("lmi-sdp", "picos", {}, 12),
    ("lmi-sdp", "casadi", {}, 12),
    ("lmi-sdp", "cvxpy", {"scale": "translations"}, 16),
    ("lmi-sdp", "picos", {"scale": "translations", "translations": "beta"}, 16),
    ("lmi-sdp", "cvxpy", {"translations": "beta", "orthogonalize": "svd"}, 16),
    ("wu", "numpy", {}, 12),
    ("wu", "numpy", {"all_triples": True}, 12),
]
#: (solver, backend, options) -> bounds on the noisy reference: rotation [rad], translation [mm]
NOISY_BOUNDS = {
    ("kron-lstsq", "numpy", ()): (0.006, 5.0),
    ("lmi-sdp", "cvxpy", ()): (0.006, 5.0),
    ("lmi-sdp", "casadi", ()): (0.006, 5.0),
    ("wu", "numpy", ()): (0.012, 11.0),
    ("wu", "numpy", (("all_triples", True),)): (0.006, 5.0),
}


def solve(solver: str, backend: str, data: dict, **options) -> handeye.Solution:
    return handeye.solve("axbycz", solver=solver, backend=backend, **data, **options)


def exact_case(seed: int, triples: int, protocol: str = "free"):
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    return PROBLEM.simulate(pairs=triples, seed=seed, protocol=protocol, **truth)


def worst(errors) -> tuple[float, float]:
    return (max(e["rotation"] for e in errors.values()), max(e["translation"] for e in errors.values()))


# ---------------------------------------------------------------------------------------------
# the lifted system


@pytest.mark.parametrize("seed", [0, 1])
def test_normal_equations_are_the_sums_of_the_explicit_rows(seed):
    raw, truth = exact_case(seed, 13)
    data = PROBLEM.validate(**raw)
    for scale in (1.0, data.translation_scale):
        H, w = lifted.regression_blocks(data, scale)
        H, w = H.reshape(-1, lifted.N_BETA), w.reshape(-1)
        N, g, ww = lifted.normal_equations(data, scale)
        np.testing.assert_allclose(N, H.T @ H, rtol=0, atol=1e-12 * np.abs(N).max())
        np.testing.assert_allclose(g, H.T @ w, rtol=0, atol=1e-12 * np.abs(g).max())
        assert ww == pytest.approx(w @ w, rel=1e-12)
    beta = lifted.lift(truth["X"], truth["Y"], truth["Z"])  # exact data: H beta = w in the data's units
    H, w = lifted.regression_blocks(data)
    assert np.abs(H @ beta - w).max() < 1e-9 * np.abs(w).max()


def test_the_lifted_cost_at_the_truth_is_the_frobenius_error():
    raw, truth = PROBLEM.simulate(pairs=20, seed=3, noise=NOISE)
    data = PROBLEM.validate(**raw)
    N, g, ww = lifted.normal_equations(data)
    beta = lifted.lift(truth["X"], truth["Y"], truth["Z"])
    top = (data.A @ truth["X"] @ data.B - truth["Y"] @ data.C @ truth["Z"])[:, :3, :]
    assert beta @ N @ beta - 2 * g @ beta + ww == pytest.approx(np.sum(top**2), rel=1e-9)


@pytest.mark.parametrize(("triples", "rank"), [(12, 125), (14, 131), (15, 132)])
def test_the_unconstrained_system_needs_15_triples(triples, rank):
    """42 translation-side unknowns and the scale of r from 3 rows per triple: full rank from 15."""
    raw, _ = exact_case(5, triples)
    data = PROBLEM.validate(**raw)
    H, _ = lifted.regression_blocks(data, data.translation_scale)
    s = np.linalg.svd(H.reshape(-1, lifted.N_BETA), compute_uv=False)
    assert int(np.sum(s > 1e-9 * s[0])) == rank
    cost = lifted.lifted_cost(data, data.translation_scale)
    assert cost.translations_determined == (triples >= lifted.MIN_TRIPLES_TAU)  # tau given r: from 14


def test_the_rotation_rows_have_one_null_direction_from_10_triples():
    for triples, determined in ((9, False), (10, True)):
        raw, truth = exact_case(6, triples)
        data = PROBLEM.validate(**raw)
        lam = np.linalg.eigvalsh(lifted.rotation_gram(data))
        assert (lam[1] > 1e-6 * lam[-1]) == determined
        r = lifted.rotations_vector(*(truth[n][:3, :3] for n in "XYZ"))
        assert r @ lifted.rotation_gram(data) @ r < 1e-12 * lam[-1]


def test_extraction_takes_the_sign_and_the_rank_one_factors():
    raw, truth = exact_case(7, 12)
    data = PROBLEM.validate(**raw)
    cost = lifted.lifted_cost(data, data.translation_scale)
    r = lifted.rotations_vector(*(truth[n][:3, :3] for n in "XYZ"))
    for sign in (1.0, -1.0):
        estimate = lifted.extract_rotations(sign * r, cost)
        assert estimate.flipped == (sign < 0)
        assert estimate.rank_one_ratio < 1e-12
        for R, name in zip(estimate.rotations, "XYZ"):
            np.testing.assert_allclose(R, truth[name][:3, :3], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# exact and noisy data


@pytest.mark.parametrize(("solver", "backend", "options", "triples"), EXACT,
                         ids=[f"{s}/{b}-{o}" for s, b, o, _ in EXACT])
def test_noise_free_recovery(solver, backend, options, triples):
    for seed in (21, 22):
        raw, truth = exact_case(seed, triples)
        scale = PROBLEM.validate(**raw).translation_scale
        sol = solve(solver, backend, raw, **options)
        rotation, translation = worst(PROBLEM.errors(sol.unknowns, truth))
        assert rotation < 1e-9 and translation < 1e-9 * scale, (seed, rotation, translation)
        assert sol.status is handeye.Status.OPTIMAL


def test_the_default_cell_half_turn_is_recovered():
    """The cell's Y is a half turn (q_Y0 = 0), where the paper's rule for q_Y, q_Z breaks down."""
    raw, truth = PROBLEM.simulate(pairs=12, seed=1)
    for solver, backend in (("wu", "numpy"), ("kron-lstsq", "numpy"), ("lmi-sdp", "cvxpy")):
        assert worst(PROBLEM.errors(solve(solver, backend, raw).unknowns, truth))[0] < 1e-9


@pytest.mark.parametrize("solver", ["kron-lstsq", "lmi-sdp"])
def test_phase_data_with_enough_triples(solver):
    """The lifted system needs the poses of each robot to span: with one robot still for half of
    the triples 16 are enough here, 12 are not (clear error)."""
    raw, truth = exact_case(4, 16, "phases")
    assert worst(PROBLEM.errors(solve(solver, "cvxpy" if solver == "lmi-sdp" else "numpy", raw).unknowns,
                                truth))[0] < 1e-9
    raw, _ = exact_case(4, 12, "phases")
    with pytest.raises(DegenerateDataError, match="do not determine the rotations"):
        solve(solver, "cvxpy" if solver == "lmi-sdp" else "numpy", raw)


@pytest.mark.parametrize(("solver", "backend", "options"), [(*key[:2], dict(key[2])) for key in NOISY_BOUNDS],
                         ids=[f"{k[0]}/{k[1]}-{dict(k[2])}" for k in NOISY_BOUNDS])
def test_noisy_accuracy_against_the_truth(solver, backend, options):
    rot_bound, trans_bound = NOISY_BOUNDS[(solver, backend, tuple(options.items()))]
    for seed in (0, 7):
        raw, truth = PROBLEM.simulate(pairs=30, seed=seed, noise=NOISE)
        sol = solve(solver, backend, raw, **options)
        rotation, translation = worst(PROBLEM.errors(sol.unknowns, truth))
        assert rotation < rot_bound and translation < trans_bound, (seed, rotation, translation)


def test_wu_all_triples_uses_every_triple():
    raw, _ = PROBLEM.simulate(pairs=30, seed=3, noise=NOISE)
    paper = solve("wu", "numpy", raw)
    ours = solve("wu", "numpy", raw, all_triples=True)
    assert paper.diagnostics["sign_triples"] == 10 and paper.diagnostics["sign_patterns"] == 2**9
    assert not np.allclose(paper.X, ours.X)


def test_wu_quaternion_blocks():
    from handeye.plugins.axbycz_wu import system_blocks

    raw, truth = PROBLEM.simulate(pairs=6, seed=2)
    data = PROBLEM.validate(**raw)
    W_AB, W_C = system_blocks(data)
    qX, qY, qZ = quat_from_rotation(np.stack([truth[n][:3, :3] for n in "XYZ"]))
    qC = quat_from_rotation(data.C[:, :3, :3])
    np.testing.assert_allclose(W_C @ np.kron(qY, qZ), quat_multiply(quat_multiply(qY, qC), qZ), atol=1e-14)
    left = W_AB @ qX
    right = W_C @ np.kron(qY, qZ)
    signs = np.sign(np.sum(left * right, axis=1))
    np.testing.assert_allclose(left, signs[:, None] * right, atol=1e-12)  # one sign per triple


# ---------------------------------------------------------------------------------------------
# the LMI and the least squares


@pytest.mark.parametrize("backend", SDP_BACKENDS)
def test_eq14_on_the_lifted_system_is_its_least_squares(backend):
    """scale="translations": the paper's LMI has no constraint but its Schur complement, so its
    optimum beta is the least squares of the lifted system."""
    raw, _ = PROBLEM.simulate(pairs=20, seed=8, noise=NOISE)
    data = PROBLEM.validate(**raw)
    sol = solve("lmi-sdp", backend, raw, scale="translations")
    system = reduce_normal_equations(*lifted.normal_equations(data, data.translation_scale))
    beta = system.least_squares()
    assert np.abs(sol.diagnostics["beta"] - beta).max() < 1e-8 * np.abs(beta).max()
    assert sol.diagnostics["u"] == pytest.approx(system.rest, rel=1e-6)
    assert abs(sol.diagnostics["schur_complement"]) < 1e-6 * system.rest


@pytest.mark.parametrize("backend", SDP_BACKENDS)
@pytest.mark.parametrize("triples", [12, 30])
def test_the_sphere_sdp_is_the_trust_region_least_squares(backend, triples):
    """scale="norm": the SDP is tight; its optimum is kron-lstsq's trust-region solution (the
    polish then takes the SDP's r there to rounding; without it r is within the solver's
    tolerance)."""
    raw, _ = PROBLEM.simulate(pairs=triples, seed=9, noise=NOISE)
    data = PROBLEM.validate(**raw)
    cost = lifted.lifted_cost(data, data.translation_scale)
    trs = solve_trust_region(cost.P, cost.p, np.sqrt(lifted.SPHERE))
    sol = solve("lmi-sdp", backend, raw)
    assert sol.diagnostics["sdp_objective"] == pytest.approx(trs.value + cost.c, rel=1e-6, abs=1e-9 * np.abs(cost.P).max())
    assert sol.diagnostics["kkt_residual"] < 1e-10
    r = sol.diagnostics["sdp_r"]
    sign = 1.0 if r @ trs.x > 0 else -1.0
    assert np.abs(r - sign * trs.x).max() < 1e-4
    # (below 14 triples p is rounding, ~1e-12, and r, -r cost the same to that)
    assert sol.diagnostics["cost"] == pytest.approx(trs.value + cost.c, rel=1e-9, abs=1e-9 * np.abs(cost.P).max())
    ref = solve("kron-lstsq", "numpy", raw)
    for name in "XYZ":  # kron-lstsq: SVD projection, lmi-sdp: Gram-Schmidt (its default)
        assert handeye.geometry.se3.rotation_angle(sol.unknowns[name][:3, :3] @ ref.unknowns[name][:3, :3].T) < 0.01
    svd = solve("lmi-sdp", backend, raw, orthogonalize="svd")
    for name in "XYZ":
        np.testing.assert_allclose(svd.unknowns[name], ref.unknowns[name], atol=1e-8)


# ---------------------------------------------------------------------------------------------
# unit invariance and errors


@pytest.mark.parametrize(("solver", "options"), [("wu", {"all_triples": True}), ("lmi-sdp", {"scale": "translations"})])
def test_unit_invariance_of_options_the_shared_suite_does_not_try(solver, options):
    raw, _ = PROBLEM.simulate(pairs=20, seed=10, noise=NOISE)
    base = solve(solver, "cvxpy" if solver == "lmi-sdp" else "numpy", raw, **options)
    scaled = {k: np.array(v) for k, v in raw.items()}
    for T in scaled.values():
        T[:, :3, 3] *= 1e-3
    sol = solve(solver, "cvxpy" if solver == "lmi-sdp" else "numpy", scaled, **options)
    for name in "XYZ":
        np.testing.assert_allclose(sol.unknowns[name][:3, :3], base.unknowns[name][:3, :3], atol=1e-9)
        np.testing.assert_allclose(sol.unknowns[name][:3, 3] * 1e3, base.unknowns[name][:3, 3], atol=1e-6)


@pytest.mark.parametrize(("solver", "backend"), [("kron-lstsq", "numpy"), ("lmi-sdp", "cvxpy"), ("lmi-sdp", "casadi")])
def test_too_few_triples(solver, backend):
    raw, _ = exact_case(1, 9)
    with pytest.raises(DegenerateDataError, match="at least 10 triples; got 9"):
        solve(solver, backend, raw)


def test_eq14_as_it_is_needs_15_triples_and_beta_translations_too():
    raw, _ = exact_case(1, 14)
    with pytest.raises(DegenerateDataError, match="at least 15 triples"):
        solve("lmi-sdp", "cvxpy", raw, scale="translations")
    solve("lmi-sdp", "cvxpy", raw, translations="beta")  # tau given r: from 14
    raw, _ = exact_case(1, 13)
    with pytest.raises(DegenerateDataError, match="translations='beta'.*at least 14.*use translations='resolve'"):
        solve("lmi-sdp", "cvxpy", raw, translations="beta")


@pytest.mark.parametrize(("solver", "backend"), [("kron-lstsq", "numpy"), ("lmi-sdp", "picos"), ("wu", "numpy")])
def test_robot_two_still_is_degenerate(solver, backend):
    """C constant: Y and Z enter only through R_Y R_C R_Z, which cannot be split."""
    raw, truth = exact_case(2, 20)
    raw["C"][:] = raw["C"][0]
    raw["B"] = np.linalg.inv(raw["A"] @ truth["X"]) @ truth["Y"] @ raw["C"] @ truth["Z"]
    with pytest.raises(DegenerateDataError, match="do not determine the rotations"):
        solve(solver, backend, raw)


@pytest.mark.parametrize(("solver", "backend"), [("kron-lstsq", "numpy"), ("lmi-sdp", "casadi")])
def test_barely_determined_rotations_are_warned_about(solver, backend):
    """Noise hides the second null direction of undetermined data (one robot still for half of 12
    triples): no error then, but a warning (lifted.WEAK_GAP); none on ordinary data."""
    raw, _ = PROBLEM.simulate(pairs=12, seed=1, noise=NOISE, protocol="phases")
    sol = solve(solver, backend, raw)
    assert sol.diagnostics["rotation_gap"] < lifted.WEAK_GAP
    assert any("barely determine the rotations" in w for w in sol.warnings)
    raw, _ = PROBLEM.simulate(pairs=12, seed=1, noise=NOISE)
    assert not any("barely" in w for w in solve(solver, backend, raw).warnings)


def test_wu_on_phase_data_says_what_it_needs():
    raw, _ = exact_case(3, 30, "phases")
    with pytest.raises(DegenerateDataError, match=r"first 10 triples.*both robots must move.*'fu-dq' or 'wang'"):
        solve("wu", "numpy", raw)
    raw, _ = exact_case(3, 4)
    with pytest.raises(DegenerateDataError, match="at least 5 triples"):
        solve("wu", "numpy", raw)


def test_options_are_checked():
    raw, _ = exact_case(1, 12)
    with pytest.raises(InputError, match="scale='sphere' is not one of 'norm', 'translations'"):
        solve("lmi-sdp", "cvxpy", raw, scale="sphere")
    with pytest.raises(InputError, match="sign_triples"):
        solve("wu", "numpy", raw, sign_triples=20)
    spec = handeye.get_registry().solver("lmi-sdp", "axbycz")
    assert spec.options().normalize is True and spec.options().translations == "resolve"
    assert spec.is_unit_invariant() and not spec.is_unit_invariant({"normalize": False})
    assert handeye.get_registry().solver("wu", "axbycz").simulate_options == {"protocol": "free"}
