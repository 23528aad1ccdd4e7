"""Backend ``casadi`` of lmi-sdp (plugins/lmi_sdp/casadi.py): eq. 8 under exact SO(3), IPOPT.

Called directly on validated data (`PROBLEM.validate`), so these tests do not depend on how the
lmi-sdp plugin wires the backend. The eq. 8 cost is recomputed here from the explicit per-pair
blocks (`regression_blocks`), independently of the module's QR reduction.
"""

from __future__ import annotations

import numpy as np
import pytest

from handeye import Status
from handeye.base.errors import InputError, SolverError
from handeye.estimation.noise import NoiseModel
from handeye.plugins import kron_lstsq
from handeye.plugins.lmi_sdp import casadi as lc
from handeye.problems.axyb import (
    PROBLEM,
    random_truth,
    regression_blocks,
    solve_translations,
)

pytest.importorskip("casadi")

NOISE = NoiseModel.on("B", 0.002, 0.5)
NOISE_AB = NoiseModel(sigmas={"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def _data(seed: int, pairs: int = 16, noise: NoiseModel | None = NOISE):
    raw, truth = PROBLEM.simulate(pairs=pairs, seed=seed, noise=noise)
    return PROBLEM.validate(**raw), truth


def _eq8_cost(data, X: np.ndarray, Y: np.ndarray, normalize: bool) -> float:
    """|H beta - w|^2 of eq. 8 (of the normalised data when normalize), from the explicit blocks."""
    scale = data.translation_scale if normalize else 1.0
    used = data.scaled(scale) if normalize else data
    H, w = regression_blocks(used.A, used.B)
    beta = np.concatenate([X[:3, :3].reshape(9, order="F"), Y[:3, :3].reshape(9, order="F"),
                           X[:3, 3] / scale, Y[:3, 3] / scale])
    return float(np.sum((H @ beta - w) ** 2))


def _assert_so3(R: np.ndarray) -> None:
    assert np.abs(R.T @ R - np.eye(3)).max() < 1e-9
    assert abs(np.linalg.det(R) - 1.0) < 1e-9


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("seed", [11, 12])
def test_noise_free_recovery(seed, normalize):
    truth = random_truth(np.random.default_rng(seed))
    raw, _ = PROBLEM.simulate(pairs=12, seed=seed, X=truth["X"], Y=truth["Y"])
    data = PROBLEM.validate(**raw)
    out = lc.solve_casadi(data, normalize=normalize)
    assert out.status is Status.OPTIMAL
    assert out.diagnostics["ipopt_status"] == "Solve_Succeeded" and out.diagnostics["success"]
    errors = PROBLEM.errors(out.unknowns, truth)
    for name in ("X", "Y"):
        assert errors[name]["rotation"] < 1e-9, errors
        assert errors[name]["translation"] < 1e-9 * data.translation_scale, errors


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("noise", [NOISE, NOISE_AB], ids=["B", "AB"])
def test_noisy_cost_not_above_kron_lstsq(noise, normalize):
    for seed in range(4):
        data, _ = _data(seed, noise=noise)
        out = lc.solve_casadi(data, normalize=normalize)
        assert out.status is Status.OPTIMAL, out.diagnostics
        start = kron_lstsq.run(data, kron_lstsq.Options(normalize=normalize), "numpy").unknowns
        start_cost = _eq8_cost(data, start["X"], start["Y"], normalize)
        cost = _eq8_cost(data, out.unknowns["X"], out.unknowns["Y"], normalize)
        assert cost <= start_cost * (1 + 1e-12), (seed, cost, start_cost)
        # the reported figures are the same eq. 8 cost, computed through the QR reduction
        assert out.diagnostics["cost"] == pytest.approx(cost, rel=1e-8)
        assert out.diagnostics["start_cost"] == pytest.approx(start_cost, rel=1e-8)
        # translations are the least squares of eqs. 20-21 for the returned rotations
        tX, tY = solve_translations(data, out.unknowns["X"][:3, :3], out.unknowns["Y"][:3, :3])
        scale = data.translation_scale
        assert np.abs(out.unknowns["X"][:3, 3] - tX).max() < 1e-9 * scale
        assert np.abs(out.unknowns["Y"][:3, 3] - tY).max() < 1e-9 * scale


def test_rotations_exactly_so3_and_multistart_keeps_best():
    data, _ = _data(1)
    out = lc.solve_casadi(data, normalize=True, multistart=5, seed=0)
    for name in ("X", "Y"):
        _assert_so3(out.unknowns[name][:3, :3])
    d = out.diagnostics
    assert d["starts_tried"] == 6 and len(d["start_statuses"]) == 6 and len(d["start_costs"]) == 6
    assert d["constraint_violation"] < 1e-9
    converged = [c for c, s in zip(d["start_costs"], d["start_statuses"]) if s == "Solve_Succeeded"]
    assert d["cost"] == pytest.approx(min(converged), rel=1e-9)
    # seed 0 draws a start that ends in another local minimum: multistart must not pick it
    assert max(converged) > 10 * min(converged)


def test_multistart_is_deterministic_with_seed():
    data, _ = _data(2)
    a = lc.solve_casadi(data, normalize=True, multistart=3, seed=7)
    b = lc.solve_casadi(data, normalize=True, multistart=3, seed=7)
    assert a.diagnostics["start_costs"] == b.diagnostics["start_costs"]
    assert a.diagnostics["iterations_total"] == b.diagnostics["iterations_total"]
    for name in ("X", "Y"):
        np.testing.assert_array_equal(a.unknowns[name], b.unknowns[name])


def test_nlpsol_built_once_and_reused_for_every_m():
    first = lc.nlp_solver()
    assert lc.nlp_solver() is first
    assert lc.nlp_solver({"ipopt.tol": 1e-12}) is first  # same merged options -> same object
    built = len(lc._CACHE)
    for pairs in (5, 40):
        lc.solve_casadi(_data(3, pairs=pairs)[0], normalize=True)
    assert len(lc._CACHE) == built and lc.nlp_solver() is first
    assert lc.nlp_solver({"max_iter": 57}) is not first


@pytest.mark.parametrize("s", [1e-3, 1e3])
def test_unit_invariance_with_normalize(s):
    raw, _ = PROBLEM.simulate(pairs=16, seed=4, noise=NOISE_AB)
    scaled = {k: v.copy() for k, v in raw.items()}
    for v in scaled.values():
        v[:, :3, 3] *= s
    data = PROBLEM.validate(**raw)
    a = lc.solve_casadi(data, normalize=True)
    b = lc.solve_casadi(PROBLEM.validate(**scaled), normalize=True)
    ref = data.translation_scale
    for name in ("X", "Y"):
        np.testing.assert_allclose(b.unknowns[name][:3, :3], a.unknowns[name][:3, :3], rtol=0, atol=1e-9)
        err = np.abs(b.unknowns[name][:3, 3] / s - a.unknowns[name][:3, 3]).max()
        assert err < 1e-9 * ref


def test_non_success_is_reported_not_hidden():
    data, _ = _data(5)
    out = lc.solve_casadi(data, normalize=True, ipopt_options={"max_iter": 0})
    assert out.status is Status.NOT_CONVERGED
    assert out.diagnostics["ipopt_status"] == "Maximum_Iterations_Exceeded"
    assert not out.diagnostics["success"] and out.diagnostics["warnings"]
    for name in ("X", "Y"):
        _assert_so3(out.unknowns[name][:3, :3])


def test_hard_failure_raises(monkeypatch):
    class Failing:
        def __call__(self, **kwargs):
            return {"x": np.full(18, np.nan)}

        def stats(self):
            return {"return_status": "Invalid_Number_Detected", "iter_count": 3}

    monkeypatch.setattr(lc, "nlp_solver", lambda options=None, rotations=2: Failing())
    with pytest.raises(SolverError, match="Invalid_Number_Detected"):
        lc.solve_casadi(_data(6)[0], normalize=True)


def test_bad_options_raise_input_error():
    data, _ = _data(7)
    with pytest.raises(InputError, match="multistart"):
        lc.solve_casadi(data, normalize=True, multistart=-1)
    with pytest.raises(InputError, match="bogus_option"):
        lc.solve_casadi(data, normalize=True, ipopt_options={"bogus_option": 1})
