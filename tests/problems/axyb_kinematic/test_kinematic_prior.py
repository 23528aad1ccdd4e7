"""The regularised kinematic fit (kinematic-lm's default, `handeye.plugins.kinematic_lm.prior`):
a zero-mean Gaussian prior on the DH corrections whose spreads (angles, lengths) and the noise
are estimated from the stations by type-II maximum likelihood. It must shrink to the pose-only
answer where the arm's errors are too small to see, match the free fit where they are large,
report a covariance that covers its errors, and keep exact recovery without noise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import LR_MATE_200ID
from handeye.plugins.kinematic_lm import prior
from handeye.problems.axyb_kinematic import PROBLEM, random_errors

#: the study's noise (joints 0.005 deg, camera 0.002 rad / 0.5 mm) and a noisier camera
STUDY_NOISE = NoiseModel({"A": (math.radians(0.005), 0.0), "B": (0.002, 0.5)})
NOISY_CAMERA = NoiseModel({"A": (math.radians(0.005), 0.0), "B": (0.005, 1.5)})
SEEDS = range(6)


def x_errors(data: dict, truth: dict, **solver) -> tuple[float, float, handeye.Solution]:
    """X's rotation (deg) and translation (mm) error of one solve, and the solution."""
    sol = handeye.solve("axyb-kinematic", **solver, **data)
    e = PROBLEM.errors(sol.unknowns, truth)["X"]
    return math.degrees(e["rotation"]), e["translation"], sol


def cell(m: int, seed: int, factor: float, noise: NoiseModel) -> tuple[dict, dict, np.ndarray]:
    """The default cell with the simulator's random DH errors scaled by `factor`."""
    errors = factor * random_errors(LR_MATE_200ID.table, np.random.default_rng(1000 + seed))
    data, truth = PROBLEM.simulate(pairs=m, seed=seed, noise=noise, errors=errors)
    return data, truth, errors


def test_evidence_gradient_matches_finite_differences():
    """The evidence's analytic gradient (used by the maximisation) against central differences."""
    rng = np.random.default_rng(0)
    J, e = rng.normal(size=(20, 6, 29)), rng.normal(size=(20, 6))
    linear = prior.Linearised.at(J, e, 0.1 * rng.normal(size=17), rng.random(17) < 0.5)
    x = np.log([0.5, 2.0, 0.3, 0.05])
    value, gradient = linear.evidence(x)
    numeric = [(linear.evidence(x + 1e-6 * k)[0] - linear.evidence(x - 1e-6 * k)[0]) / 2e-6 for k in np.eye(4)]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-6, atol=1e-6)
    assert math.isfinite(value)


def test_tiny_errors_and_a_noisy_camera_shrink_to_the_pose_only_answer():
    """DH errors 20x smaller than the simulator's (0.005-0.025 deg, 0.01-0.05 mm), camera 0.005
    rad / 1.5 mm, 30 stations, 6 seeds. Measured medians of X (deg / mm): free fit 0.15 / 0.87,
    regularised 0.10 / 0.36, auto 0.073 / 0.33 (the pose-only answer in every seed: the
    likelihood ratio does not see the errors), axyb's auto 0.073 / 0.33. Bounds: regularised
    within 1.6x of the pose-only median and better than the free fit; auto pose-only in at least
    5 of 6 seeds and within 1.1x of the pose-only median."""
    rows, pose_chosen = [], 0
    for seed in SEEDS:
        data, truth, _ = cell(30, seed, 0.05, NOISY_CAMERA)
        free = x_errors(data, truth, solver="kinematic-lm", prior="none")[:2]
        regularised = x_errors(data, truth, solver="kinematic-lm")[:2]
        *auto, sol = x_errors(data, truth)
        pose_chosen += sol.diagnostics["answer"].startswith("pose-only")
        only = handeye.solve("axyb", A=data["A"], B=data["B"])
        e = PROBLEM.errors({**only.unknowns, "links": data["dh"].links()}, truth)["X"]
        rows.append([*free, *regularised, *auto, math.degrees(e["rotation"]), e["translation"]])
    med = np.median(rows, axis=0)
    free, regularised, auto, pose = med[0:2], med[2:4], med[4:6], med[6:8]
    assert np.all(regularised < 1.6 * pose) and np.all(regularised < free), med
    assert pose_chosen >= 5 and np.all(auto < 1.1 * pose), (pose_chosen, med)


def test_large_errors_match_the_free_fit_and_their_spread_is_estimated():
    """The simulator's errors (0.1-0.5 deg: RMS 0.32 deg; 0.2-1 mm: RMS 0.64 mm), 50 stations,
    the study's noise, 4 seeds. Measured: the regularised fit's X errors within 2% of the free
    fit's (medians 0.049 deg / 0.18 mm against 0.048 / 0.18), the estimated spreads 0.26-0.38
    deg and 0.40-0.67 mm. Bounds: medians within 1.25x of the free fit's, every spread within a
    factor 2 of the errors' RMS, auto the kinematic answer."""
    free, regularised = [], []
    for seed in range(4):
        data, truth, errors = cell(50, seed, 1.0, STUDY_NOISE)
        free.append(x_errors(data, truth, solver="kinematic-lm", prior="none")[:2])
        *err, sol = x_errors(data, truth, solver="kinematic-lm")
        regularised.append(err)
        p = sol.diagnostics["prior"]
        flat = errors.ravel()[np.flatnonzero(errors.ravel())]
        angles, lengths = flat[np.abs(flat) < 0.05], flat[np.abs(flat) >= 0.05]
        assert 0.5 < p["tau_angle"] / np.sqrt(np.mean(angles ** 2)) < 2, (seed, p)
        assert 0.5 < p["tau_length"] / np.sqrt(np.mean(lengths ** 2)) < 2, (seed, p)
        assert handeye.solve("axyb-kinematic", **data).diagnostics["answer"] == "kinematic"
    ratio = np.median(regularised, axis=0) / np.median(free, axis=0)
    assert np.all(ratio < 1.25), ratio


@pytest.mark.parametrize("factor", [0.1, 1.0])
def test_reported_covariance_covers_the_errors(factor):
    """Over 6 seeds (30 stations, the noisy camera), the regularised fit's errors of X and Y
    divided by their reported 1-sigma (norms over the 3 axes) have an RMS near 1. Measured:
    0.92-1.05 (errors x0.1), 1.01-1.19 (x1). Bound: every group's RMS in [0.5, 1.6]."""
    z = []
    for seed in SEEDS:
        data, truth, _ = cell(30, seed, factor, NOISY_CAMERA)
        sol = handeye.solve("axyb-kinematic", solver="kinematic-lm", **data)
        err, std = PROBLEM.errors(sol.unknowns, truth), sol.diagnostics["std"]
        z.append([err[k][c] / std[k][c] for k in "XY" for c in ("rotation", "translation")])
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.5) & (rms < 1.6)), rms


def test_noise_free_stations_give_the_exact_answer_through_the_prior():
    """Without noise the estimated noise goes to its floor and the prior costs nothing."""
    data, truth, errors = cell(15, 1, 1.0, NoiseModel())
    sol = handeye.solve("axyb-kinematic", solver="kinematic-lm", **data)
    scale = PROBLEM.validate(**data).translation_scale
    for name, err in PROBLEM.errors(sol.unknowns, truth).items():
        assert err["rotation"] < 1e-9 and err["translation"] < 1e-9 * scale, (name, err)
    assert sol.diagnostics["prior"]["p"] < 1e-6
