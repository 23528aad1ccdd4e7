"""The fast paths of ``axbycz`` (A_i X B_i = Y C_i Z) equal the slow ones they replace: the
closed-form normal equations of the refinement against those of the (m, 6, 18) Jacobian, fu-dq's
phase search against the (m, m) table of still pairs, and ``auto`` with the closed-form sums
against ``auto`` through the Jacobian. No timing is asserted (bench/README.md has the figures)."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.estimation import lm_objective
from handeye.estimation.noise import NoiseModel
from handeye.estimation.whitening import Whitening
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.plugins import axbycz_fu, axbycz_wang
from handeye.problems.axbycz import PROBLEM
from handeye.problems.axbycz.geometry import AXBYCZModel

NOISE = NoiseModel.on(("A", "B", "C"), 0.01, 1.0)


def model_at(m: int, seed: int, protocol: str = "free") -> tuple[AXBYCZModel, tuple[np.ndarray, ...]]:
    """The model of simulated noisy triples and poses 0.05 rad / 5 mm off the truth (residuals of
    every size, including large rotation residuals where the Jacobians' higher terms matter)."""
    data, truth = PROBLEM.simulate(pairs=m, seed=seed, noise=NOISE, protocol=protocol)
    rng = np.random.default_rng(seed)
    poses = tuple(np.asarray(truth[k]) @ make_pose(so3_exp(rng.normal(0, 0.05, 3)), rng.normal(0, 5.0, 3))
                  for k in "XYZ")
    return PROBLEM.pose_model(PROBLEM.validate(**data)), poses


def jacobian_sums(model: AXBYCZModel, poses: tuple[np.ndarray, ...], e: np.ndarray, wr: float, wt: float,
                  d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """g_rot, g_trans, Hw of the engine's contract from the explicit Jacobian."""
    J = model.jacobian(poses, e)
    Jr, Jt = J[:, :3], J[:, 3:]
    g_rot = wr * np.einsum("n,nai,na->i", d, Jr, e[:, :3])
    g_trans = wt * np.einsum("n,nai,na->i", d, Jt, e[:, 3:])
    H = wr * np.einsum("n,nai,naj->ij", d, Jr, Jr) + wt * np.einsum("n,nai,naj->ij", d, Jt, Jt)
    return g_rot, g_trans, H


@pytest.mark.parametrize("m, seed, protocol", [(6, 1, "free"), (40, 2, "phases"), (300, 3, "free")])
def test_closed_form_normal_equations_equal_the_jacobians(m, seed, protocol):
    model, poses = model_at(m, seed, protocol)
    e = model.residuals(poses)
    d = np.random.default_rng(seed).uniform(0.1, 1.0, m)  # pair weights of a robust loss
    wr, wt = 1.0 / 0.02**2, 1.0 / 3.0**2
    expected = jacobian_sums(model, poses, e, wr, wt, d)
    for got, want in zip(model.normal_equations(poses, e, wr, wt, d), expected):
        assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()
    g_rot, g_trans, H = model.normal_equations(poses, e, wr, wt, d)
    assert np.array_equal(H, H.T) and not g_rot[3:6].any() and not g_trans[12:15].any()
    assert np.all(np.linalg.eigvalsh(H) > 0)


def test_the_engine_takes_the_sums_from_sums_min_pairs_on_with_the_same_step():
    """`lm_objective.local_model` switches to the closed form at `sums_min_pairs`; the gradient and the
    (profile) Hessian it returns are those of the Jacobian route."""
    model, poses = model_at(60, 4)
    e = model.residuals(poses)
    W = Whitening(0.02, 3.0)
    routes = []
    for threshold in (np.inf, 0):
        model.sums_min_pairs = threshold
        routes.append(lm_objective.local_model(model, poses, e, W, "profile", "linear", 1.0, model.scale))
    for a, b in zip(*routes):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12 * np.abs(np.asarray(b)).max())


def test_auto_with_the_sums_equals_auto_through_the_jacobian(monkeypatch):
    """m = 800 (above `SUMS_MIN_PAIRS`): the same answer to 1e-9 of its size, the same status."""
    from handeye.problems.axbycz import geometry

    assert geometry.SUMS_MIN_PAIRS <= 800
    data, truth = PROBLEM.simulate(pairs=800, seed=5, noise=NoiseModel.on(("A", "B", "C"), 0.005, 0.5))
    fast = handeye.solve("axbycz", solver="auto", **data)
    monkeypatch.setattr(AXBYCZModel, "sums_min_pairs", np.inf)
    slow = handeye.solve("axbycz", solver="auto", **data)
    assert fast.status == slow.status == "optimal"
    for k in "XYZ":
        np.testing.assert_allclose(fast.unknowns[k][:3, :3], slow.unknowns[k][:3, :3], atol=1e-9)
        np.testing.assert_allclose(fast.unknowns[k][:3, 3], slow.unknowns[k][:3, 3], atol=1e-9 * 100)
        assert np.abs(fast.unknowns[k][:3, 3] - truth[k][:3, 3]).max() < 1.0  # mm: the answer is a good one


def brute_force_phase(T: np.ndarray, rotation_tol: float, translation_tol: float) -> np.ndarray:
    """fu-dq's phase from the full (m, m) table (the implementation before the k-d tree)."""
    R, t = T[:, :3, :3], T[:, :3, 3]
    cos = (np.einsum("ikl,jkl->ij", R, R) - 1.0) / 2.0
    close = (cos >= np.cos(rotation_tol)) & (np.linalg.norm(t[:, None] - t[None], axis=-1) <= translation_tol)
    return np.flatnonzero(close[int(np.argmax(close.sum(axis=1)))])


@pytest.mark.parametrize("protocol, m, seed", [("phases", 60, 1), ("phases", 31, 2), ("free", 200, 3)])
@pytest.mark.parametrize("chunk", [axbycz_fu.PAIRS_PER_CHUNK, 7])
def test_fu_phase_search_equals_the_full_table(monkeypatch, protocol, m, seed, chunk):
    monkeypatch.setattr(axbycz_fu, "PAIRS_PER_CHUNK", chunk)
    data, _ = PROBLEM.simulate(pairs=m, seed=seed, noise=NOISE, protocol=protocol)
    C = np.asarray(data["C"])
    scale = PROBLEM.validate(**data).translation_scale
    for rot, trans in ((0.05, 0.01), (0.5, 0.3), (1e-4, 1e-4)):
        got = axbycz_fu.find_phase(C, rot, trans * scale)
        assert got.tolist() == brute_force_phase(C, rot, trans * scale).tolist()
    pairs = axbycz_fu.still_pairs(C, 0.5, 0.3 * scale)
    assert np.all(pairs[:, 0] < pairs[:, 1]) and len(np.unique(pairs, axis=0)) == len(pairs)
    if protocol == "phases":
        assert len(axbycz_fu.find_phase(C, 0.05, 0.01 * scale)) >= m // 2


def test_fu_refuses_a_long_free_motion_recording_in_one_line():
    """10,000 triples of free motion: the phase search (which took (m, m) tables, 2.4 GB) finds no
    phase and fu-dq says so."""
    data, _ = PROBLEM.simulate(pairs=10_000, seed=6, noise=NOISE)
    assert len(axbycz_fu.find_phase(np.asarray(data["C"]), 0.05, 0.01 * PROBLEM.validate(**data).translation_scale)) < 3
    with pytest.raises(handeye.InputError, match="robot 2 holding still"):
        handeye.solve("axbycz", solver="fu-dq", **data)


def test_wang_linearisation_cost_and_normal_equations_on_poses_with_noise():
    """`_linearisation` gives `rotation_cost` and, on rotations orthonormal to rounding, the
    normal equations of the stacked system (for one iterate and a stack of them)."""
    data, truth = PROBLEM.simulate(pairs=25, seed=7, noise=NOISE)
    RA, RB, RC = (np.asarray(data[k])[:, :3, :3] for k in "ABC")  # views of (m, 4, 4), as wang gets them
    rng = np.random.default_rng(7)
    iterates = [tuple(truth[k][:3, :3] @ so3_exp(rng.normal(0, 0.3, 3)) for k in "XYZ") for _ in range(3)]
    RX, RY, RZ = (np.stack(R) for R in zip(*iterates))
    H, g, cost = axbycz_wang._linearisation(*axbycz_wang._contiguous(RA, RB, RC), RX, RY, RZ)
    np.testing.assert_allclose(cost, axbycz_wang.rotation_cost(RA, RB, RC, RX, RY, RZ), rtol=1e-13)
    for k, (rx, ry, rz) in enumerate(iterates):
        F, E = axbycz_wang.linearised_system(RA, RB, RC, rx, ry, rz)
        np.testing.assert_allclose(H[k], F.T @ F, atol=1e-12 * np.abs(F.T @ F).max())
        np.testing.assert_allclose(g[k], F.T @ E, atol=1e-12 * np.abs(F.T @ E).max())
        np.testing.assert_allclose(cost[k], np.sum(E**2), rtol=1e-12)


def test_wang_records_a_cost_per_iterate():
    """costs: C at the start and after every step (the last one evaluated after the loop)."""
    data, _ = PROBLEM.simulate(pairs=30, seed=8, noise=NOISE)
    RA, RB, RC = (np.asarray(data[k])[:, :3, :3] for k in "ABC")
    starts = axbycz_wang.grid_starts(RA, RB, RC, 4)
    runs = axbycz_wang.iterate_rotations(RA, RB, RC, *(np.stack(R) for R in zip(*starts)), 1e-12, 100)
    for run, start in zip(runs, starts):
        assert len(run["costs"]) == run["iterations"] + 1
        assert run["costs"][0] == pytest.approx(float(axbycz_wang.rotation_cost(RA, RB, RC, *start)), rel=1e-12)
        assert run["costs"][-1] == pytest.approx(float(axbycz_wang.rotation_cost(RA, RB, RC, *run["R"])), rel=1e-12)
    best = min((r for r in runs if r["converged"]), key=lambda r: r["costs"][-1])
    assert best["costs"][-1] <= min(best["costs"]) * (1 + 1e-12) < best["costs"][0]


def test_camera_poses_inverted_do_not_reach_the_sums_unnoticed():
    """A wrong B (camera poses inverted) at m = 800: the sums are used and auto's answer does not
    fit (its rotation residual is far above the noise), as through the Jacobian."""
    data, _ = PROBLEM.simulate(pairs=800, seed=9, noise=NoiseModel.on(("A", "B", "C"), 0.005, 0.5))
    wrong = dict(data, B=inverse(np.asarray(data["B"])))
    sol = handeye.solve("axbycz", solver="auto", **wrong)
    res = PROBLEM.residuals(sol.data, sol.unknowns)
    assert np.sqrt(np.mean(res["rotation"] ** 2)) > 0.05


def test_speed_bench_compare_with_another_version_checks_its_arguments(tmp_path, capsys):
    """bench/speed.py --compare-with: the options of the comparison are not passed on to the
    benchmarks it runs, and a directory without the package is refused in one line."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "bench" / "speed.py"
    spec = importlib.util.spec_from_file_location("speed_bench", path)
    speed = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(speed)
    argv = ["--problem", "axbycz", "--compare-with", "/old", "--rounds=2", "--pairs", "16", "--json", "x.json"]
    assert speed._without(argv, "--compare-with", "--rounds", "--json") == ["--problem", "axbycz", "--pairs", "16"]
    assert speed.main(["--problem", "axbycz", "--compare-with", str(tmp_path)]) == 2
    assert "holds no package handeye/" in capsys.readouterr().err
