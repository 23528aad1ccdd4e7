"""The evaluation harness (handeye.harness) and ``handeye compare`` on tiny, fast studies."""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import InputError, UnknownPluginError
from handeye.estimation.noise import NoiseModel
from handeye.harness import (
    PAPER_METHODS,
    Spec,
    Study,
    Sweep,
    default_specs,
    error_table,
    load_study,
    missing_paper_methods,
    paper_study,
    parse_floats,
    parse_specs,
    read_csv,
    run_study,
    time_table,
    write_report,
)
from handeye.harness.report import band
from handeye.host.registry import list_solvers, register_plugin, unregister_plugin

ERROR_COLUMNS = ["err_rot_X", "err_trans_X", "err_rot_Y", "err_trans_Y"]
RESIDUAL_COLUMNS = ["res_rot_mean", "res_rot_median", "res_trans_mean", "res_trans_median"]


def tiny_study(**changes: Any) -> Study:
    """2 solvers x 2 noise levels x 1 pair count x 2 trials = 8 records."""
    study = Study(
        name="tiny",
        specs=(Spec("kron-lstsq"), Spec("shah")),
        noise=NoiseModel({"A": (0.0005, 0.05), "B": (0.005, 0.5)}),
        sweeps=(Sweep("noise", levels=(0.0, 1.0), pairs=(8,)),),
        trials=2, seed=7, warmup=False,
    )
    return dataclasses.replace(study, **changes)


@pytest.fixture(scope="module")
def serial_result():
    return run_study(tiny_study(), jobs=1, progress=False)


# --- run-time test plugins -------------------------------------------------------------------

def _raise(data, options, backend):
    raise RuntimeError("deliberate failure for the harness test")


@dataclasses.dataclass(frozen=True)
class TruthOptions:
    init: Any = None


def _return_init(data, options, backend):
    if options.init is None:
        raise ValueError("this test solver needs init")
    return SolverOutput(unknowns={k: np.asarray(v) for k, v in options.init.items()})


def _give_up(data, options, backend):
    return SolverOutput(unknowns={"X": np.eye(4), "Y": np.eye(4)}, status=Status.NOT_CONVERGED,
                        diagnostics={"warnings": ["harness test: gave up   after 0 iterations"]})


def _hang(data, options, backend):
    import time

    time.sleep(30)  # interrupted by the study's time limit
    raise AssertionError("the time limit did not stop this solve")


class HarnessTestPlugin:
    @hookimpl
    def register_solvers(self, register):
        register(SolverSpec(name="harness-test-fail", problems=("axyb",), run=_raise, summary="always raises"))
        register(SolverSpec(name="harness-test-hang", problems=("axyb",), run=_hang, summary="sleeps"))
        register(SolverSpec(name="harness-test-unsure", problems=("axyb",), run=_give_up,
                            summary="returns the identity, not converged"))
        register(SolverSpec(name="harness-test-truth", problems=("axyb",), run=_return_init,
                            options=TruthOptions, summary="returns its init option"))


@pytest.fixture()
def test_plugin():
    register_plugin(HarnessTestPlugin(), "harness-test-plugin")
    try:
        yield
    finally:
        unregister_plugin("harness-test-plugin")


# --- shapes, determinism ---------------------------------------------------------------------

def test_records_one_per_cell_trial_spec(serial_result):
    rows = serial_result.records
    assert len(rows) == 2 * 1 * 2 * 2
    assert [r["label"] for r in rows[:2]] == ["kron-lstsq", "shah"]
    for column in ["study", "sweep", "level", "pairs", "trial", "seed", "label", "solver", "backend",
                   "status", "error", "seconds", *ERROR_COLUMNS, *RESIDUAL_COLUMNS,
                   "sigma_rot_A", "sigma_trans_A", "sigma_rot_B", "sigma_trans_B"]:
        assert column in rows[0], column
    assert all(r["status"] == "optimal" and r["error"] == "" for r in rows)
    # every solver of a unit sees the same data; trials differ; the levels of a trial share the
    # seed (common random numbers: same poses, same standard-normal noise scaled by the level)
    seeds = {(r["level"], r["trial"]): set() for r in rows}
    for r in rows:
        seeds[(r["level"], r["trial"])].add(r["seed"])
    assert all(len(s) == 1 for s in seeds.values())
    assert seeds[(0.0, 0)] == seeds[(1.0, 0)] != seeds[(0.0, 1)] == seeds[(1.0, 1)]
    noise_free = [r for r in rows if r["level"] == 0.0]
    assert max(r[c] for r in noise_free for c in ERROR_COLUMNS + RESIDUAL_COLUMNS) < 1e-6
    noisy = [r for r in rows if r["level"] == 1.0]
    assert min(r["err_rot_X"] for r in noisy) > 1e-5
    assert noisy[0]["sigma_rot_B"] == 0.005 and noise_free[0]["sigma_rot_B"] == 0.0


def test_results_identical_whatever_the_job_count(serial_result):
    parallel = run_study(tiny_study(), jobs=2, progress=False)
    assert len(parallel.records) == len(serial_result.records)
    for a, b in zip(serial_result.records, parallel.records):
        assert (a["label"], a["level"], a["trial"], a["seed"]) == (b["label"], b["level"], b["trial"], b["seed"])
        for column in ERROR_COLUMNS + RESIDUAL_COLUMNS:
            assert a[column] == b[column], column


def test_levels_of_a_trial_see_the_same_poses_with_scaled_noise():
    from handeye.harness import data_seed
    from handeye.harness.runner import simulate

    study = tiny_study(sweeps=(Sweep("noise", levels=(0.0, 1.0, 2.0), pairs=(8,)),))
    cells = list(study.cells())
    (clean, _, s0), (one, _, s1), (two, _, s2) = (simulate(study, c, 1) for c in cells)
    assert s0 == s1 == s2 == data_seed(study, cells[0], 1) != data_seed(study, cells[0], 0)
    for name in ("A", "B"):
        delta1 = one[name][:, :3, 3] - clean[name][:, :3, 3]
        delta2 = two[name][:, :3, 3] - clean[name][:, :3, 3]
        assert np.abs(delta1).max() > 0.01
        np.testing.assert_allclose(delta2, 2 * delta1, rtol=1e-9, atol=1e-9)


def test_seed_changes_the_data(serial_result):
    other = run_study(tiny_study(seed=8), jobs=1, progress=False)
    assert other.records[2]["seed"] != serial_result.records[2]["seed"]
    assert other.records[-1]["err_rot_X"] != serial_result.records[-1]["err_rot_X"]


def test_metres_give_the_same_errors_in_mm_for_a_unit_invariant_solver(serial_result):
    metres = run_study(tiny_study(units="m", specs=(Spec("kron-lstsq"),)), jobs=1, progress=False)
    mm = [r for r in serial_result.records if r["label"] == "kron-lstsq" and r["level"] == 1.0]
    m = [r for r in metres.records if r["level"] == 1.0]
    assert [r["seed"] for r in m] == [r["seed"] for r in mm]
    for a, b in zip(mm, m):
        assert b["units"] == "m"
        for column in ERROR_COLUMNS + ["res_trans_mean"]:
            assert b[column] == pytest.approx(a[column], rel=1e-6), column


# --- failures and the oracle hook ------------------------------------------------------------

@pytest.mark.parametrize("jobs", [1, 2])
def test_failing_solver_is_recorded_and_the_study_goes_on(test_plugin, jobs):
    study = tiny_study(specs=(Spec("harness-test-fail"), Spec("kron-lstsq")))
    result = run_study(study, jobs=jobs, progress=False)
    failed = result.select(label="harness-test-fail")
    ok = result.select(label="kron-lstsq")
    assert len(failed) == len(ok) == 4
    for row in failed:
        assert row["status"] == "failed"
        # the plugin's exception, wrapped by handeye.solve in a SolverError that names the plugin
        assert row["error"] == ("SolverError: solver 'harness-test-fail' (plugin 'harness-test-plugin', registered at "
                                "run time) failed: RuntimeError: deliberate failure for the harness test"), row["error"]
        assert all(math.isnan(row[c]) for c in ERROR_COLUMNS + ["seconds"])
    assert all(r["status"] == "optimal" and np.isfinite(r["err_rot_X"]) for r in ok)
    summary = {(e["label"], e["level"]): e for e in result.summary()}
    assert summary[("harness-test-fail", 1.0)]["failed"] == 2
    assert math.isnan(summary[("harness-test-fail", 1.0)]["err_rot_X_median"])
    assert "| harness-test-fail | numpy | - | - | 4 | 4 |" in time_table(result)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_hanging_solver_is_stopped_by_the_time_limit(test_plugin, jobs):
    study = tiny_study(specs=(Spec("harness-test-hang"), Spec("kron-lstsq")), timeout=0.2,
                       sweeps=(Sweep("noise", levels=(1.0,), pairs=(8,)),))
    result = run_study(study, jobs=jobs, progress=False)
    hung, ok = result.select(label="harness-test-hang"), result.select(label="kron-lstsq")
    assert len(hung) == len(ok) == 2
    for row in hung:
        assert row["status"] == "failed"
        # a plugin's solver runs in a worker process killed at the limit (runner.limited_solve)
        assert row["error"].startswith("SolverTimeoutError: solver 'harness-test-hang'"), row["error"]
        assert "gave no answer within 0.2 s and was stopped" in row["error"]
    assert all(r["status"] == "optimal" for r in ok)


def test_non_optimal_answers_are_kept_with_their_warnings(test_plugin):
    result = run_study(tiny_study(specs=(Spec("harness-test-unsure"),)), jobs=1, progress=False)
    for row in result.records:
        assert row["status"] == "not_converged" and row["error"] == ""
        # the solver's warning, then the host's self-check (identity is far from the best fit)
        assert row["warnings"] == 2 and row["notes"].startswith("harness test: gave up after 0 iterations")
        assert np.isfinite(row["err_rot_X"]) and row["err_rot_X"] > 1.0  # identity vs the paper's X
    assert [e["not_optimal"] for e in result.summary()] == [2, 2]


def test_default_specs_include_run_time_plugins(test_plugin):
    specs = default_specs("axyb")
    assert {"harness-test-fail", "harness-test-hang", "harness-test-unsure", "harness-test-truth",
            "kron-lstsq"} <= {s.solver for s in specs}
    assert Study(specs=()).resolved_specs() == specs


def test_init_from_truth_passes_the_truth_in_the_data_units(test_plugin):
    study = tiny_study(units="m", truth="random", specs=(
        Spec("harness-test-truth", label="oracle", init_from_truth=True),
        Spec("kron-lstsq", label="no-init-option", init_from_truth=True),
    ))
    result = run_study(study, jobs=1, progress=False)
    for row in result.select(label="oracle"):
        assert row["status"] == "optimal"
        assert all(row[c] == 0.0 for c in ERROR_COLUMNS)
    for row in result.select(label="no-init-option"):  # kron-lstsq has no `init` option
        assert row["status"] == "failed" and row["error"].startswith("UnknownPluginError")
    table = error_table(result, reference="oracle")
    assert "| noise | 1 | 8 | oracle |" in table


# --- outputs ---------------------------------------------------------------------------------

def test_write_report_writes_csv_json_figures_and_tables(serial_result, tmp_path):
    paths = write_report(serial_result, tmp_path)
    rows = read_csv(paths["csv"])
    assert len(rows) == 8
    assert list(rows[0]) == serial_result.columns()
    assert [float(r["err_rot_X"]) for r in rows] == [r["err_rot_X"] for r in serial_result.records]
    doc = json.loads(paths["json"].read_text())
    assert doc["study"]["trials"] == 2 and doc["run"]["records"] == 8
    assert doc["run"]["seconds"] > 0 and doc["run"]["cpu_seconds"] > 0
    assert len(doc["summary"]) == 2 * 2  # cells x specs
    entry = doc["summary"][-1]
    assert entry["n"] == 2 and entry["label"] == "shah" and entry["level"] == 1.0
    assert entry["err_rot_X_median"] == pytest.approx(
        float(np.median([r["err_rot_X"] for r in serial_result.select(label="shah", level=1.0)])))
    assert [p.name for p in paths["figures"]] == ["tiny_noise_vs_noise_m8.png"]
    assert paths["figures"][0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    times = paths["times"].read_text()
    assert "| kron-lstsq | numpy |" in times and "| shah | numpy |" in times
    assert "| noise | 1 | 8 | shah |" in paths["errors"].read_text()


# --- study definitions -----------------------------------------------------------------------

def test_study_file_round_trip(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("""
name = "mine"
trials = 3
seed = 11
units = "m"
center = "mean"
timeout = 0
[noise]
B = [0.002, 0.5]
[[sweep]]
name = "noise"
levels = [0, 1, 2]
pairs = [16]
[[sweep]]
name = "pairs"
pairs = [8, 32]
noise = { A = [0.0002, 0.05], B = [0.002, 0.5] }
[[solver]]
name = "kron-lstsq"
[[solver]]
name = "kron-lstsq"
label = "raw"
options = { normalize = false }
""")
    study = load_study(path)
    assert (study.name, study.trials, study.seed, study.units, study.center) == ("mine", 3, 11, "m", "mean")
    assert study.timeout is None and Study().timeout == 30.0
    assert study.noise.sigmas == {"B": (0.002, 0.5)}
    assert [s.name for s in study.sweeps] == ["noise", "pairs"]
    assert study.sweeps[1].levels == (1.0,) and study.sweeps[1].noise.sigmas["A"] == (0.0002, 0.05)
    assert [s.label for s in study.specs] == ["kron-lstsq", "raw"] and study.specs[1].options == {"normalize": False}
    cells = list(study.cells())
    assert [(c.sweep, c.level, c.pairs) for c in cells] == [
        ("noise", 0.0, 16), ("noise", 1.0, 16), ("noise", 2.0, 16), ("pairs", 1.0, 8), ("pairs", 1.0, 32)]
    assert cells[2].noise.sigmas == {"B": (0.004, 1.0)}

    path.write_text('trials = 2\ncolour = "red"\n')
    with pytest.raises(InputError, match="colour"):
        load_study(path)


def test_bad_studies_are_rejected():
    with pytest.raises(InputError, match="trials"):
        Study(trials=0)
    with pytest.raises(InputError, match="labels must be unique"):
        Study(specs=(Spec("kron-lstsq"), Spec("kron-lstsq")))
    with pytest.raises(InputError, match="noise levels"):
        Sweep("s", levels=(-1.0,))
    with pytest.raises(UnknownPluginError):
        Study(specs=(Spec("no-such-solver"),)).resolved_specs()


def test_parse_specs_and_levels():
    specs = parse_specs("kron-lstsq, so3-sdp/*") if "so3-sdp" in __import__("handeye").list_solvers() else parse_specs("kron-lstsq")
    assert specs[0] == Spec("kron-lstsq", "numpy", label="kron-lstsq")
    with pytest.raises(UnknownPluginError):
        parse_specs("kron-lstsq/gpu")
    assert parse_floats("0:0.1:0.01", "x") == tuple(round(0.01 * i, 12) for i in range(11))
    assert parse_floats("1, 2.5", "x") == (1.0, 2.5)
    with pytest.raises(InputError):
        parse_floats("a,b", "x")


def test_paper_study_is_the_papers_protocol():
    study = paper_study()
    cells = list(study.cells())
    noise = [c for c in cells if c.sweep == "noise"]
    assert [c.level for c in noise] == [round(0.01 * i, 2) for i in range(11)]  # Fig. 3
    assert {c.pairs for c in noise} == {16}
    pairs = [c for c in cells if c.sweep == "pairs"]
    assert [c.pairs for c in pairs] == list(range(10, 101, 10)) and {c.level for c in pairs} == {0.05}  # Fig. 4
    assert pairs[0].noise.sigmas == {"A": (0.05, 0.05), "B": (0.05, 0.05)}  # sigma_N rad and mm on A and B
    assert (study.trials, study.truth, study.units, study.center) == (5, "paper", "mm", "mean")
    registered = set(list_solvers("axyb"))
    expected = [n for n in PAPER_METHODS if n in registered] + sorted(registered - set(PAPER_METHODS))
    assert list(dict.fromkeys(s.solver for s in study.specs)) == expected
    for spec in study.specs:  # the paper's dual quaternions work on the data in mm, not normalised
        assert spec.options == ({"normalize": False} if spec.solver == "dual-quaternion" else {})
    assert missing_paper_methods() == [n for n in PAPER_METHODS if n not in registered]
    custom = paper_study(trials=2, pairs=20, specs=(Spec("kron-lstsq"),))
    assert custom.trials == 2 and [s.label for s in custom.specs] == ["kron-lstsq"]
    assert {c.pairs for c in custom.cells() if c.sweep == "noise"} == {20}


def test_bands_median_iqr_or_mean_std():
    stats = [{"mean": 2.0, "median": 1.5, "std": 3.0, "q25": 1.0, "q75": 2.5}]
    assert [v.tolist() for v in band(stats, "median")] == [[1.5], [1.0], [2.5]]
    assert [v.tolist() for v in band(stats, "mean")] == [[2.0], [0.0], [5.0]]  # lower edge clipped at 0
    with pytest.raises(InputError, match="center"):
        Study(center="mode")
    with pytest.raises(InputError, match="timeout"):
        Study(timeout=0)


# --- CLI and dask ----------------------------------------------------------------------------

def test_compare_paper_writes_csv_json_figures_and_time_table(tmp_path, capsys):
    from handeye.cli import main

    out = tmp_path / "paper"
    code = main(["compare", "--paper", str(out), "--solvers", "kron-lstsq,shah", "--trials", "1",
                 "--jobs", "2", "--no-progress"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "42 runs (0 failed) of 2 solver(s)" in text  # (11 + 10 cells) x 1 trial x 2 solvers
    assert len(read_csv(out / "paper.csv")) == 42
    doc = json.loads((out / "paper_summary.json").read_text())
    assert len(doc["summary"]) == 42 and doc["study"]["center"] == "mean"
    assert sorted(p.name for p in out.glob("*.png")) == ["paper_noise_vs_noise_m16.png",
                                                         "paper_pairs_vs_pairs_level0.05.png"]
    times = (out / "paper_times.md").read_text()
    assert "| solver | backend | mean [ms] (noise) | mean [ms] (pairs) |" in times
    assert "| kron-lstsq | numpy |" in times and "| shah | numpy |" in times

def test_compare_command(tmp_path, capsys):
    from handeye.cli import main

    code = main(["compare", "--solvers", "kron-lstsq", "--noise-levels", "0,0.01", "--pairs", "8",
                 "--trials", "2", "--jobs", "1", "--no-progress", "--name", "cli", "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "4 runs (0 failed)" in out
    assert len(read_csv(tmp_path / "cli.csv")) == 4
    assert (tmp_path / "cli_grid_vs_noise_m8.png").exists()
    assert main(["compare", "--paper", str(tmp_path), "--pairs", "8"]) == 2  # a grid flag with --paper


def test_dask_executor_on_a_local_cluster(serial_result, tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    from handeye.cli import main

    study = ["compare", "--solvers", "kron-lstsq,auto,so3-sdp", "--noise-levels", "0,0.01", "--pairs", "8",
             "--trials", "2", "--no-progress", "-o", str(tmp_path)]
    assert main([*study, "--name", "local", "--jobs", "2"]) == 0
    # in-process workers (threads): fast to start; the scheduler is reached by its address, as
    # `handeye compare --executor dask --scheduler ADDRESS` does with a remote cluster
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        result = run_study(tiny_study(), progress=False, executor="dask", scheduler=cluster.scheduler_address)
        code = main([*study, "--name", "dask", "--executor", "dask", "--scheduler", cluster.scheduler_address])
    # the same CSV, row for row and to the last digit, but for the measured times
    local, dask = read_csv(tmp_path / "local.csv"), read_csv(tmp_path / "dask.csv")
    assert len(local) == len(dask) == 12
    assert [{**r, "seconds": None, "study": None} for r in local] == [{**r, "seconds": None, "study": None} for r in dask]
    assert result.executor == "dask"
    assert len(result.records) == len(serial_result.records)
    for a, b in zip(serial_result.records, result.records):
        assert (a["label"], a["level"], a["trial"], a["seed"]) == (b["label"], b["level"], b["trial"], b["seed"])
        assert all(a[c] == b[c] for c in ERROR_COLUMNS + RESIDUAL_COLUMNS)
    out = capsys.readouterr().out
    assert code == 0 and "[dask]" in out, out


def test_dask_executor_without_dask_says_how_to_install(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_distributed(name, *args, **kwargs):
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError("No module named 'distributed'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_distributed)
    with pytest.raises(InputError, match=r"handeye\[dask\]"):
        run_study(tiny_study(), progress=False, executor="dask", scheduler="tcp://127.0.0.1:1")


# --- problem axxb ------------------------------------------------------------------------------

def axxb_solver() -> str:
    """kron-lstsq for axxb (closed form, fast), else any registered axxb solver."""
    names = list_solvers("axxb")
    assert names, "no solver is registered for problem axxb"
    return "kron-lstsq" if "kron-lstsq" in names else names[0]


def tiny_axxb_study(**changes: Any) -> Study:
    """1 solver x 2 noise levels x 2 motion counts x 2 trials = 8 records, noise on robot and camera."""
    study = Study(name="tiny-axxb", problem="axxb", specs=(Spec(axxb_solver()),),
                  noise=NoiseModel({"A": (0.0005, 0.05), "B": (0.005, 0.5)}),
                  sweeps=(Sweep("noise", levels=(0.0, 1.0), pairs=(4, 8)),), trials=2, seed=3, warmup=False)
    return dataclasses.replace(study, **changes)


def test_axxb_study_rows_per_solver_and_trial_and_deterministic(tmp_path):
    result = run_study(tiny_axxb_study(), jobs=1, progress=False)
    rows = result.records
    assert len(rows) == 8 and {r["label"] for r in rows} == {axxb_solver()}
    assert sorted((r["level"], r["pairs"], r["trial"]) for r in rows) == [
        (lv, m, t) for lv in (0.0, 1.0) for m in (4, 8) for t in (0, 1)]
    assert all(r["status"] == "optimal" for r in rows)
    assert "err_rot_X" in rows[0] and "err_rot_Y" not in rows[0]  # the unknowns of axxb
    assert max(r["err_rot_X"] for r in rows if r["level"] == 0.0) < 1e-8
    assert min(r["err_rot_X"] for r in rows if r["level"] == 1.0) > 1e-6
    again = run_study(tiny_axxb_study(), jobs=1, progress=False)
    assert [(r["seed"], r["err_rot_X"], r["err_trans_X"]) for r in again.records] == [
        (r["seed"], r["err_rot_X"], r["err_trans_X"]) for r in rows]
    csv_rows = read_csv(result.to_csv(tmp_path / "axxb.csv"))
    assert len(csv_rows) == 8 and [float(r["err_rot_X"]) for r in csv_rows] == [r["err_rot_X"] for r in rows]
    table = error_table(result)
    assert f"| noise | 1 | 8 | {axxb_solver()} |" in table and "err_rot_Y" not in table


def test_axxb_pairing_reaches_the_simulator():
    from handeye.harness.runner import simulate

    study = tiny_axxb_study(simulation={"pairing": "consecutive"})
    cell = next(c for c in study.cells() if c.pairs == 8 and c.level == 1.0)
    data, truth, _ = simulate(study, cell, 0)
    assert data["A"].shape == (7, 4, 4) and set(truth) == {"X"}  # 8 stations
    every_pair, _, _ = simulate(tiny_axxb_study(), cell, 0)
    assert every_pair["A"].shape == (28, 4, 4)
    assert not np.allclose(data["A"][1], every_pair["A"][1])  # motion 1: stations (1, 2), not (0, 2)
    assert load_study_text('problem = "axxb"\nsimulation = { pairing = "all" }\n').simulation == {"pairing": "all"}


def load_study_text(text: str) -> Study:
    import tomllib

    from handeye.harness import study_from_dict

    return study_from_dict(tomllib.loads(text))


def test_axxb_default_specs_have_opencvs_five_methods():
    from handeye.host.registry import get_registry

    specs = default_specs("axxb")
    assert {s.solver for s in specs} <= set(list_solvers("axxb"))
    opencv = [s for s in specs if s.solver == "opencv"]
    spec = get_registry().solvers.get("opencv", {}).get("axxb")
    if spec is None or spec.unavailable_reason(spec.default_backend):
        assert opencv == []
        return
    assert [(s.label, s.options) for s in opencv] == [
        (f"opencv ({m})", {"method": m}) for m in ("tsai", "park", "horaud", "andreff", "daniilidis")]
    assert all(s.solver != "opencv" for s in default_specs("axyb") if "(" in s.label)  # axyb: one opencv


def test_axxb_accuracy_study_runs_every_solver_against_the_oracle():
    from handeye.harness import accuracy_study

    study = accuracy_study(problem="axxb")
    assert study.problem == "axxb" and [c.pairs for c in study.cells()][:3] == [8, 16, 50]
    assert study.noise.sigmas == {"A": (0.0002, 0.05), "B": (0.002, 0.5)}
    if "refine" not in list_solvers("axxb"):
        pytest.skip("refine does not solve axxb here: no oracle")
    assert study.specs[-1].label == "oracle" and study.specs[-1].init_from_truth
    tiny = study.replace(specs=(Spec(axxb_solver()), study.specs[-1]), trials=2,
                         sweeps=(Sweep("accuracy", (1.0,), (8,)),))
    result = run_study(tiny, jobs=1, progress=False)
    assert [r["status"] for r in result.records] == ["optimal"] * 4, [r["error"] for r in result.records]
    oracle = result.select(label="oracle")
    assert all(0 < r["err_rot_X"] < 0.01 for r in oracle)
    assert "(1." in error_table(result, reference="oracle") or "(0." in error_table(result, reference="oracle")


def test_compare_axxb_default_sweeps_and_flags(tmp_path, capsys):
    from handeye.cli import main

    code = main(["compare", "--problem", "axxb", "--solvers", axxb_solver(), "--trials", "1", "--jobs", "1",
                 "--no-progress", "--pairing", "all", "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "8 runs (0 failed)" in out  # noise sweep: 4 levels at m = 16; pairs sweep: m = 8, 16, 32, 64
    doc = json.loads((tmp_path / "study_summary.json").read_text())
    assert doc["study"]["problem"] == "axxb" and doc["study"]["simulation"] == {"pairing": "all"}
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["study_noise_vs_noise_m16.png",
                                                              "study_pairs_vs_pairs_level0.05.png"]
    assert main(["compare", "--paper", str(tmp_path / "p"), "--problem", "axxb"]) == 2
    assert main(["compare", "--pairing", "all", "-o", str(tmp_path / "q")]) == 2  # axyb has no pairing
    assert "the paper's study of problem 'axyb'" in capsys.readouterr().err


def test_progress_bar_shows_rate_and_time_left(capsys):
    """The bar on stderr counts the simulated data sets, with their rate and the time left."""
    import re

    result = run_study(tiny_study(), jobs=1, progress=True)
    err = capsys.readouterr().err
    final = err.replace("\r", "\n").strip().splitlines()[-1]
    units = len(result.records) // len({r["label"] for r in result.records})
    assert f"{units}/{units}" in final, final
    assert re.search(r"\[\d\d:\d\d<\d\d:\d\d, +[\d.]+(trial/s|s/trial)\]", final), final


def test_default_studies_leave_out_solvers_that_need_board_images():
    from handeye.harness.study import default_specs

    labels = [spec.label for spec in default_specs("axyb")]
    assert "reprojection" not in labels and "auto" in labels and "lmi-sdp/cvxpy" in labels
