"""The speed benchmark's library (`handeye.harness.bench`, `handeye.harness.bench_report`): generic
over the registered problems, each benchmarked by what its `Problem.bench` declares.

Timings are never asserted (machines are noisy); what is checked is which rows are timed, on which
data, against which reference, and how targets and rows that cannot run are reported.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SolverPlugin, identity_run

import handeye
from handeye import SolverSpec, hookimpl
from handeye.framework.problem_studies import BenchRow, BenchSettings, BenchTarget
from handeye.harness import bench
from handeye.harness.bench_report import (
    data_line,
    payload,
    same_method_lines,
    table,
    target_lines,
)
from handeye.problems import opencv_reference
from handeye.problems.axyb import AXYB

PROBLEM, SOLVER = "test-bench-problem", "test-bench-solver"


class ProblemPlugin:
    def __init__(self, problem):
        self.problem = problem

    @hookimpl
    def register_problems(self, register):
        register(self.problem)


def _problem(seen: list[int]) -> AXYB:
    """A problem known to handeye only at run time (AX=YB under another name) whose bench
    settings name a direct row (recording the m of its inputs), one that cannot run here, a
    target, and a data note."""

    def direct(inputs):
        m = len(inputs["A"])  # prepared outside the timing
        return lambda: seen.append(m)

    class Timed(AXYB):
        name = PROBLEM
        default = False
        bench = BenchSettings(
            pairs=(5, 6),
            reference="plain direct",
            reference_name="the plain call",
            direct_rows=(BenchRow("plain direct", direct, same_method=SOLVER),
                         BenchRow("lib direct A", direct, missing=lambda: "no such library here"),
                         BenchRow("lib direct B", direct, missing=lambda: "no such library here")),
            targets=(BenchTarget(SOLVER, 5, seconds=60.0), BenchTarget(SOLVER, 6, ratio=1e9),
                     BenchTarget(SOLVER, 7, seconds=1.0), BenchTarget(SOLVER, 5, ratio=1e-12, against="plain direct"),
                     BenchTarget(SOLVER, 5, ratio=2.0, against="lib direct A")),
            data_note="my cell (seed {seed}), {rot:g} rad, {trans:g} mm",
        )

    return Timed()


def test_a_problem_registered_at_run_time_is_benchmarked_by_its_own_settings(runtime_plugins):
    seen: list[int] = []
    runtime_plugins(ProblemPlugin(_problem(seen)), "test-bench-problem-plugin")
    runtime_plugins(SolverPlugin(SolverSpec(SOLVER, (PROBLEM,), identity_run)), "test-bench-solver-plugin")

    run = bench.run_bench(PROBLEM, repeats=2, solvers=SOLVER, seed=3, noise_rot=0.01, noise_trans=1.0)

    assert run.pairs == [5, 6] and run.reference == "plain direct"  # the problem's pairs and reference
    assert [row.label for row in run.rows] == ["plain direct", f"{SOLVER}/numpy"]
    assert sorted(set(seen)) == [5, 6] and len(seen) == 2 * 3  # per m: warm-up + 2 repeats, on m pairs
    assert run.unavailable == ["lib direct A, B: no such library here"]  # one note for one reason
    for label in ("plain direct", f"{SOLVER}/numpy"):
        assert all(run.cells[(label, m)].call is not None for m in (5, 6))
    assert data_line(run) == "my cell (seed 3), 0.01 rad, 1 mm"
    verdicts = target_lines(run)
    assert len(verdicts) == 5
    assert "< 60000 ms" in verdicts[0] and verdicts[0].endswith("PASS")
    assert "x the plain call" in verdicts[1] and verdicts[1].endswith("PASS")
    assert "n/a: m=7 not measured" in verdicts[2]
    # a target against a row of its own choosing: divided by that row, or said to be unmeasured
    assert "< 1e-12x plain direct" in verdicts[3] and verdicts[3].endswith("MISS")
    assert verdicts[4].endswith("n/a: lib direct A not measured")
    assert same_method_lines(run)[0].startswith(f"  {SOLVER}/numpy") and "vs plain direct" in same_method_lines(run)[0]
    assert "1.00x" in table(run, "call").splitlines()[1]  # the reference row divides by itself
    assert payload(run)["reference"] == "plain direct" and payload(run)["unavailable"] == run.unavailable


def test_the_command_line_benchmarks_a_problem_registered_at_run_time(runtime_plugins, capsys):
    runtime_plugins(ProblemPlugin(_problem([])), "test-bench-problem-plugin")
    runtime_plugins(SolverPlugin(SolverSpec(SOLVER, (PROBLEM,), identity_run)), "test-bench-solver-plugin")
    from handeye.cli import main

    assert main(["bench", "--problem", PROBLEM, "--repeats", "1", "--no-progress", "--solvers", SOLVER]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"handeye bench ({PROBLEM}): ") and "\ndata: my cell (seed 0)" in out
    assert "ratio to 'plain direct'" in out and "\n  lib direct A, B: no such library here" in out


def test_a_problem_without_bench_settings_is_timed_on_its_own_simulator(runtime_plugins):
    class Plain(AXYB):
        name = PROBLEM
        default = False
        bench = BenchSettings(pairs=(4,))

    runtime_plugins(ProblemPlugin(Plain()), "test-bench-problem-plugin")
    runtime_plugins(SolverPlugin(SolverSpec(SOLVER, (PROBLEM,), identity_run)), "test-bench-solver-plugin")
    data, inputs = bench.bench_data(PROBLEM, 4, bench.noise_model(PROBLEM, 0.0, 0.0), seed=1)
    assert data is inputs and data["A"].shape == (4, 4, 4)
    run = bench.run_bench(PROBLEM, repeats=1, solvers=SOLVER)
    assert run.reference == f"{SOLVER}/numpy"  # no reference named: the first row
    assert data_line(run) == "PROBLEM.simulate(seed=0), noise on A and B: 0.005 rad, 0.5 mm"
    assert target_lines(run) == [] and same_method_lines(run) == []


def test_pair_counts_below_the_problem_minimum_are_refused():
    with pytest.raises(handeye.InputError, match="pair counts >= 3"):
        bench.run_bench("axyb", [2, 16])


@pytest.mark.parametrize("problem", ["axyb", "axxb", "axbycz"])
def test_each_builtin_problem_times_its_reference(problem):
    """The reference a built-in problem names is one of its rows (OpenCV's when cv2 is here)."""
    settings = handeye.get_registry().problem(problem).bench
    rows, unavailable = bench.build_rows(problem)
    labels = [row.label for row in rows]
    if settings.direct_rows and any(row.missing() for row in settings.direct_rows):
        assert any("cv2" in note for note in unavailable)
    else:
        assert settings.reference in labels
    for target in settings.targets:
        assert target.solver in handeye.list_solvers(problem)


def test_the_axxb_direct_rows_get_the_stations_the_motions_are_made_of():
    """cv2.calibrateHandEye forms the motions of all pairs of n stations itself: the solvers get
    those n (n - 1) / 2 >= m motions, the direct rows the n stations."""
    noise = bench.noise_model("axxb", 0.0, 0.0)
    data, inputs = bench.bench_data("axxb", 16, noise, seed=0)
    n = len(inputs["robot"])
    assert n * (n - 1) // 2 == len(data["A"]) >= 16 > (n - 1) * (n - 2) // 2
    robot, camera = inputs["robot"], inputs["camera"]  # T_base_flange, T_cam_target
    T = np.linalg.inv(robot[0]) @ robot[1]
    assert np.allclose(data["A"][0], T) or np.allclose(data["A"][0], np.linalg.inv(T))
    assert camera.shape == robot.shape


def test_opencv_direct_rows_say_why_they_cannot_run(monkeypatch):
    import sys

    rows = opencv_reference.direct_rows("calibrateHandEye", "CALIB_HAND_EYE_", ("TSAI", "PARK"),
                                        lambda inputs: (inputs["robot"], inputs["camera"]))
    assert [row.label for row in rows] == ["cv2 direct TSAI", "cv2 direct PARK"]
    assert [row.same_method for row in rows] == ["tsai", "park"]
    monkeypatch.setitem(sys.modules, "cv2", None)
    assert all(row.missing().startswith("importing cv2 failed") for row in rows)
    fake = type(sys)("cv2")
    fake.__version__ = "5.0.0"
    monkeypatch.setitem(sys.modules, "cv2", fake)
    assert rows[0].missing() == "this OpenCV (5.0.0) has no cv2.calibrateHandEye"
