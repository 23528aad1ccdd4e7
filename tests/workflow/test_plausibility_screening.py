"""The plausibility check on long streams (handeye.workflow.plausibility): the hypotheses are
screened on a subsample of the stations and fitted on all only where they may explain the data.
The verdict, the mistake named, its figures and the alternatives named must be those of fitting
every hypothesis on all stations (SCREEN_STATIONS = 0), for each usual mistake and on clean data."""

from __future__ import annotations

import json

import numpy as np
import pytest

import handeye
from handeye.cli import main
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.problems.axxb import simulate_stations
from handeye.workflow import plausibility as P

STATIONS = 120


def streams_with(mistake: str | None, problem: str, stations: int = STATIONS, level: float = 1.0) -> P.Streams:
    """The streams of a simulated eye-in-hand cell (the accuracy study's noise times `level`) with one mistake."""
    noise = NoiseModel({"A": (0.0002 * level, 0.05 * level), "B": (0.002 * level, 0.5 * level)})
    st, _ = simulate_stations(stations + (mistake == "shift"), seed=11, noise=noise)
    robot, camera, setup = np.array(st["A"]), inverse(st["B"]), "eye-in-hand"
    if mistake == "camera-inverted":
        camera = inverse(camera)
    elif mistake == "robot-inverted":
        robot = inverse(robot)
    elif mistake == "shift":
        robot, camera = robot[:-1], camera[1:]
    elif mistake == "unit":
        camera[:, :3, 3] *= 1e-3
    elif mistake == "setup":
        setup = "eye-to-hand"
    return P.Streams(robot, camera, "mm", setup, problem, pairing="all" if problem == "axxb" else None,
                     camera_unit="mm")


def checked(streams: P.Streams) -> P.Report:
    """`P.check` of the solution kron-lstsq gives on the streams as given."""
    from handeye.io.data_files import from_poses

    pose_file = from_poses(streams.robot, streams.camera, streams.problem, setup=streams.setup,
                           pairing=streams.pairing)
    sol = handeye.solve(streams.problem, solver="kron-lstsq", **pose_file.data)
    problem = handeye.get_registry().problem(streams.problem)
    return P.check(streams, problem.residuals(sol.data, sol.unknowns))


def test_screen_rows_are_evenly_spaced_and_only_for_long_streams(monkeypatch):
    k = P.SCREEN_STATIONS
    assert P.screen_rows(2 * k - 1) is None
    rows = P.screen_rows(501)
    assert len(rows) == k and rows[0] == 0 and rows[-1] == 500 and np.all(np.diff(rows) >= 12)
    monkeypatch.setattr(P, "SCREEN_STATIONS", 0)
    assert P.screen_rows(10_000) is None


@pytest.mark.parametrize("problem", ["axxb", "axyb"])
@pytest.mark.parametrize("mistake", [None, "camera-inverted", "robot-inverted", "shift", "unit", "setup"])
def test_screened_verdict_is_the_full_verdict(monkeypatch, mistake, problem):
    """Same plausibility, explanation (its figures to the last digit: it is fitted on all
    stations in both), messages and set of hypotheses; the hypotheses fitted on all stations are
    the ones that explain the data (and, on clean data, none)."""
    streams = streams_with(mistake, problem)
    screened, k = checked(streams), P.SCREEN_STATIONS
    monkeypatch.setattr(P, "SCREEN_STATIONS", 0)
    full = checked(streams)
    assert screened.plausible == full.plausible == (mistake is None)
    assert screened.warnings == full.warnings
    assert screened.explanation == full.explanation
    assert screened.baseline == full.baseline
    assert sorted(h.description for h in screened.hypotheses) == sorted(h.description for h in full.hypotheses)
    assert all(h.stations is None for h in full.hypotheses)
    explaining = {h.description for h in full.hypotheses if h.score < 1.0 and h.ratio >= P.EXPLAIN_FACTOR}
    fitted_on_all = {h.description for h in screened.hypotheses if h.stations is None}
    assert explaining <= fitted_on_all
    assert (fitted_on_all == set()) == (mistake is None)
    assert all(h.stations == k for h in screened.hypotheses if h.description not in fitted_on_all)
    by_name = {h.description: h for h in full.hypotheses}
    for h in screened.hypotheses:  # a screened fit scores like the full one, far from explaining
        if h.stations is not None:
            assert 0.5 < h.score / by_name[h.description].score < 2.0


def test_screening_at_ten_times_the_noise_keeps_the_verdicts(monkeypatch):
    """At 10x the study's noise undoing a mistake improves the fit only tens of times: the margin
    of the screen must still send the right hypothesis to the full fit."""
    for mistake in (None, "camera-inverted"):
        streams = streams_with(mistake, "axxb", level=10.0)
        screened = checked(streams)
        monkeypatch.setattr(P, "SCREEN_STATIONS", 0)
        full = checked(streams)
        monkeypatch.undo()
        assert screened.plausible == full.plausible == (mistake is None)
        assert screened.warnings == full.warnings and screened.explanation == full.explanation


def test_a_hypothesis_whose_screening_fit_fails_is_fitted_on_all_stations(monkeypatch):
    """The screening rows may not determine a fit that all stations determine: such a hypothesis
    is fitted on all stations, not dropped."""
    streams = streams_with("camera-inverted", "axxb")
    fit = P._fit

    def failing_on_subsamples(s, robot, camera, setup):
        return None if len(robot) <= P.SCREEN_STATIONS else fit(s, robot, camera, setup)

    monkeypatch.setattr(P, "_fit", failing_on_subsamples)
    report = checked(streams)
    assert not report.plausible and "camera poses are inverted" in report.explanation.description
    assert report.hypotheses and all(h.stations is None for h in report.hypotheses)


def test_calibrate_euler_mistake_on_a_long_file(tmp_path, capsys, monkeypatch):
    """Through ``handeye calibrate`` (the robot file re-read with the other Euler sequences): the
    same message and explanation with and without the screening, and the Euler sequence named."""
    from handeye.io.pose_writers import write_poses

    st, _ = simulate_stations(100, seed=3, noise=NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)}))
    robot = write_poses(tmp_path / "robot.csv", np.array(st["A"]), "yaskawa", unit="mm")
    camera = write_poses(tmp_path / "camera.csv", inverse(st["B"]), "opencv-rvec", unit="mm")
    args = ["calibrate", "--robot", str(robot), "--robot-format", "staubli", "--camera", str(camera),
            "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand", "--problem",
            "axxb", "--json"]
    assert main(args) == 1
    screened = json.loads(capsys.readouterr().out)
    monkeypatch.setattr(P, "SCREEN_STATIONS", 0)
    assert main(args) == 1
    full = json.loads(capsys.readouterr().out)
    assert screened["warnings"][0] == full["warnings"][0] and "robot angles are Euler xyz" in full["warnings"][0]
    assert screened["checks"]["explanation"] == full["checks"]["explanation"]
    assert sum(h["stations"] is None for h in screened["checks"]["hypotheses"]) < 5


def test_the_large_files_bench_runs_and_the_two_columns_agree(capsys):
    """bench/large_files.py at 90 stations (screened: 40 of them) with the robot poses inverted:
    one row, the mistake named, the same verdict with and without the screening."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "bench" / "large_files.py"
    spec = importlib.util.spec_from_file_location("large_files_bench", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--stations", "90", "--mistake", "robot-inverted"]) == 0
    row = capsys.readouterr().out.strip().splitlines()[-1]
    assert row.startswith("| 90 | robot-inverted |") and "robot poses are inverted" in row and row.endswith("| yes |")
