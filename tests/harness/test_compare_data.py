"""``handeye compare --data FILE``: held-out residuals by k-fold cross-validation (harness.crossval)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from handeye.cli import main
from handeye.estimation.noise import NoiseModel
from handeye.harness import Spec
from handeye.harness.crossval import TRUTH_LABEL, CrossValData, make_folds, run_crossval
from handeye.host.registry import get_registry
from handeye.io.data_files import load_file, save_data
from tests.conftest import run_cli

#: a solver's held-out median residual may exceed the truth's on the same held-out pairs by at
#: most this factor (the answer's own error adds to the pairs' noise; ~1.0-1.1 seen at m = 40)
TRUTH_FACTOR = 1.3


@pytest.fixture(scope="module")
def axyb_file(tmp_path_factory) -> Path:
    data, truth = get_registry().problem("axyb").simulate(pairs=40, seed=3, noise=NoiseModel.on("B", 0.002, 0.5))
    return save_data(tmp_path_factory.mktemp("cv") / "sim.json", data, truth, metadata={"units": "mm"})


@pytest.fixture(scope="module")
def stations_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cv") / "stations.npz"
    assert main(["simulate", "--problem", "axxb", "--stations", "14", "--noise-rot", "0.002", "--noise-trans",
                 "0.5", "--seed", "5", "-o", str(path)]) == 0
    return path


@pytest.mark.parametrize(("n", "k"), [(10, 2), (50, 5), (17, 4), (7, 7)])
@pytest.mark.parametrize("contiguous", [False, True])
def test_folds_partition_the_items(n, k, contiguous):
    folds = make_folds(n, k, seed=1, contiguous=contiguous)
    assert len(folds) == k
    assert np.array_equal(np.sort(np.concatenate(folds)), np.arange(n))  # every item once
    sizes = [len(f) for f in folds]
    assert max(sizes) - min(sizes) <= 1
    if contiguous:
        assert all(np.array_equal(f, np.arange(f[0], f[-1] + 1)) for f in folds)


def test_folds_deterministic_and_seeded():
    assert all(np.array_equal(a, b) for a, b in zip(make_folds(30, 5, 7), make_folds(30, 5, 7)))
    assert not all(np.array_equal(a, b) for a, b in zip(make_folds(30, 5, 7), make_folds(30, 5, 8)))


def test_heldout_residuals_close_to_the_truths(axyb_file):
    pose_file = load_file(axyb_file, "axyb")
    cv = CrossValData("axyb", pose_file.data, pose_file.truth, to_mm=1.0)
    result = run_crossval(cv, (Spec("kron-lstsq"), Spec("auto")), folds=5, seed=0, progress=False)
    summary = {e["label"]: e for e in result.summary()}
    truth = summary[TRUTH_LABEL]
    assert truth["heldout_pairs"] == 40
    for label in ("kron-lstsq", "auto"):
        entry = summary[label]
        assert entry["failed"] == 0 and entry["heldout_pairs"] == 40
        for kind in ("rot", "trans"):
            ratio = entry[f"heldout_{kind}_median"] / truth[f"heldout_{kind}_median"]
            assert 1 / TRUTH_FACTOR < ratio < TRUTH_FACTOR, (label, kind, ratio)
            # fitting the held-out pairs would only lower them: in-sample <= held-out (RMS)
            assert entry[f"insample_{kind}_rms"] <= entry[f"heldout_{kind}_rms"] * 1.05
    # the held-out pairs of the folds are the pairs of the file, each once per solver
    pairs = sorted(int(r["pair"]) for r in result.pairs if r["label"] == "auto")
    assert pairs == list(range(40))


def test_axxb_station_folds_leak_no_test_station(stations_file, monkeypatch):
    from handeye.harness import runner
    from handeye.problems.axxb import motions

    pose_file = load_file(stations_file, "axxb")
    cv = CrossValData("axxb", pose_file.data, None, pose_file.poses, pose_file.metadata["setup"], "all",
                      get_registry().problem("axxb").station_reader)
    assert cv.by_station and cv.count == 14
    seen = []
    real_solve = runner.solve

    def spy(problem, **kwargs):
        seen.append(kwargs["A"].copy())
        return real_solve(problem, **kwargs)

    monkeypatch.setattr(runner, "solve", spy)  # every fit goes through runner.limited_solve
    result = run_crossval(cv, (Spec("kron-lstsq"),), folds=3, seed=0, progress=False)
    robot, camera = pose_file.poses["robot_poses"], pose_file.poses["camera_poses"]
    assert len(seen) == 4  # the full fit, then one per fold
    for fold, test in enumerate(result.fold_items):
        train = np.setdiff1d(np.arange(14), test)
        expected = motions(robot[train], camera[train], setup="eye-in-hand", pairing="all")["A"]
        assert np.allclose(seen[1 + fold], expected)  # fitted on motions among training stations only
        names = [r["pair"] for r in result.pairs if r["fold"] == fold]
        stations = {int(s) for name in names for s in name.split("-")}
        assert stations <= set(test.tolist())  # scored on motions among test stations only
        assert len(names) == len(test) * (len(test) - 1) // 2


def test_consecutive_pairing_folds_in_blocks(stations_file):
    pose_file = load_file(stations_file, "axxb", pairing="consecutive")
    cv = CrossValData("axxb", pose_file.data, None, pose_file.poses, "eye-in-hand", "consecutive",
                      get_registry().problem("axxb").station_reader)
    data, names = cv.subset(np.array([0, 1, 2, 5, 6, 9]))
    assert names == ["0-1", "1-2", "5-6"]  # only neighbours in the file, never across a gap
    assert len(data["A"]) == 3
    folds = cv.folds(3, seed=0)
    assert all(np.array_equal(f, np.arange(f[0], f[-1] + 1)) for f in folds)


def test_cli_writes_outputs_and_is_deterministic(capsys, tmp_path, axyb_file):
    outs = []
    for name in ("a", "b"):
        code, out, err = run_cli(capsys, "compare", "--data", str(axyb_file), "--solvers", "kron-lstsq,shah",
                                 "--folds", "4", "--seed", "2", "--no-progress", "-o", str(tmp_path / name))
        assert code == 0, err
        assert "| kron-lstsq |" in out and "| truth |" in out
        outs.append(tmp_path / name)
    for suffix in ("_pairs.csv",):
        assert (outs[0] / f"sim{suffix}").read_text() == (outs[1] / f"sim{suffix}").read_text()
    summary = json.loads((outs[0] / "sim_summary.json").read_text())
    assert summary["folds"] == 4 and summary["folded"] == "pair" and summary["items"] == 40
    assert sorted(i for f in summary["fold_items"] for i in f) == list(range(40))
    with (outs[0] / "sim_folds.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * 4  # (2 solvers + truth) x 4 folds
    assert (outs[0] / "sim_heldout.png").stat().st_size > 0 and (outs[0] / "sim_heldout.md").exists()


def test_cli_stations_file_axxb(capsys, tmp_path, stations_file):
    code, out, err = run_cli(capsys, "compare", "--data", str(stations_file), "--problem", "axxb",
                             "--solvers", "park", "--folds", "3", "--no-progress", "-o", str(tmp_path))
    assert code == 0, err
    assert "over 14 stations" in out


@pytest.mark.parametrize("argv", [
    ["--folds", "5"],  # 4 pairs: too few for 5 folds
    ["--folds", "2"],  # 4 pairs in 2 folds leave 2 to fit: fewer than axyb's 3
    ["--solvers", "no-such-solver"],
    ["--folds", "1"],
    ["--trials", "3"],  # a flag of the simulated studies
])
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, argv):
    data, truth = get_registry().problem("axyb").simulate(pairs=4, seed=1)
    path = save_data(tmp_path / "few.json", data, truth)
    code, _out, err = run_cli(capsys, "compare", "--data", str(path), *argv, "--no-progress", "-o", str(tmp_path / "o"))
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("handeye: error:"), err


def test_example_eth_robot_arm(capsys, tmp_path):
    code, out, err = run_cli(capsys, "compare", "--example", "eth-robot-arm", "--folds", "3", "--solvers",
                             "kron-lstsq,auto", "--no-progress", "-o", str(tmp_path))
    assert code == 0, err
    assert "| kron-lstsq |" in out and "| auto |" in out and "truth" not in out.split("|---")[1]
    summary = json.loads((tmp_path / "eth-robot-arm_summary.json").read_text())
    for entry in summary["solvers"]:  # real data: ~0.4 deg and ~7 mm per pair (core/data/README.md)
        assert 0.002 < entry["heldout_rot_median"] < 0.03
        assert 2 < entry["heldout_trans_median"] < 30
