"""An answer that predicts held-out stations best is not refused for residuals above the noise
(handeye.checks.self_check, check 1 with the solver's held-out evidence), and its 1-sigma covers
errors its stations share (the reprojection solver's jackknife over the stations)."""

from __future__ import annotations

import numpy as np

from handeye.checks.self_check import _rotation_residual
from handeye.framework.reported import Reported
from handeye.plugins.reprojection.corners import Fit, station_jackknife


class Residuals10xNoise:
    """A problem whose answer leaves rotation residuals 20x what the noise gives."""

    def expected_rotation_residual(self, data):
        return 0.001

    def residuals(self, data, unknowns):
        return {"rotation": np.full(12, 0.02)}


EVIDENCE = {"best": True, "measure": "board corners of held-out stations, px RMS", "answer_px": 1.23,
            "others_px": {"with the robot's noise estimated": 1.85, "the pose-based answer": 1.76}}


def test_residuals_above_the_noise_fail_an_answer_without_held_out_evidence():
    failures, warnings, figures = [], [], {}
    _rotation_residual(Residuals10xNoise(), None, {}, failures, figures, None, Reported.of({}).held_out_best, warnings)
    assert len(failures) == 1 and "20 times what the noise of these data gives" in failures[0] and not warnings
    beaten = {"held_out": {**EVIDENCE, "best": False}}
    assert Reported.of(beaten).held_out_best is None and Reported.of({"held_out": "yes"}).held_out_best is None


def test_the_answer_that_predicts_held_out_stations_best_gets_a_warning_not_a_failure():
    failures, warnings, figures = [], [], {}
    _rotation_residual(Residuals10xNoise(), None, {}, failures, figures, None,
                       Reported.of({"held_out": EVIDENCE}).held_out_best, warnings)
    assert failures == [] and figures["rotation_residual"]["systematic"] is True
    assert len(warnings) == 1 and "20 times what the noise of these data gives" in warnings[0]
    assert ("board corners of held-out stations, px RMS: 1.23; with the robot's noise estimated 1.85, the "
            "pose-based answer 1.76") in warnings[0]
    assert "systematic error" in warnings[0] and "in the stated 1-sigma" in warnings[0]


def test_the_stations_jackknife_is_the_covariance_of_the_leave_one_station_out_fits():
    """On a linear least-squares problem one Gauss-Newton step is the exact refit: the jackknife's
    covariance equals the brute-force one over the 9 fits leaving one station out (to 1e-12), and
    where every station shares an error of its own it is several times sigma^2 (J^T J)^-1."""
    rng = np.random.default_rng(3)
    stations, corners, p = 9, 40, 4
    station = np.repeat(np.arange(stations), corners)
    # a station's corners see the unknowns alike (one pose), so an error they share does not average out
    J = rng.normal(size=(stations, 2, p))[station] + 0.3 * rng.normal(size=(stations * corners, 2, p))
    shared = rng.normal(scale=1.0, size=(stations, 2))[station]  # one error per station
    y = J @ np.ones(p) + shared + rng.normal(scale=0.1, size=(stations * corners, 2))
    A, b = J.reshape(-1, p), y.ravel()
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    fit = Fit({}, np.zeros(0), (J @ theta) - y, J, 0.0, np.ones(stations * corners), 1, True)
    jack = station_jackknife(fit, np.bincount(station), p)
    loo = np.array([np.linalg.lstsq(A[np.repeat(station != i, 2)], b[np.repeat(station != i, 2)], rcond=None)[0]
                    for i in range(stations)])
    brute = (stations - 1) / stations * (loo - loo.mean(axis=0)).T @ (loo - loo.mean(axis=0))
    assert np.allclose(jack, brute, rtol=1e-9, atol=1e-14)
    naive = np.sum(fit.r**2) / (fit.r.size - p) * np.linalg.inv(A.T @ A)
    assert np.trace(jack) > 4 * np.trace(naive)


def test_too_few_stations_give_no_jackknife():
    fit = Fit({}, np.zeros(0), np.zeros((4, 2)), np.ones((4, 2, 2)), 0.0, np.ones(4), 1, True)
    assert station_jackknife(fit, np.array([2, 2]), 2) is None
