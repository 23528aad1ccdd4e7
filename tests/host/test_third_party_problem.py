"""Third-party proof for problems: the example package docs/examples/handeye-example-problem
(problem ``registration``, A_i X_b(i) = B_i, whose unknown X is a stack of one pose per body,
and its closed-form solver ``registration-mean``) is found through its entry point and gets every
shared tool through the `handeye.Problem` contract, with nothing in handeye naming it: ``refine``
and ``auto``, the host's checks and self-check, studies (``compare``), the benchmark, the report
and ``calibrate``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import PROBLEM_EXAMPLE_DIR, example_entry_points, example_project

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import make_pose, so3_exp
from handeye.host import registry
from tests.conftest import run_cli

NAME, SOLVER = "registration", "registration-mean"
#: the accuracy study's noise (robot 0.0002 rad / 0.05 mm, camera 0.002 rad / 0.5 mm)
NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def test_the_package_declares_its_entry_point():
    assert example_project(PROBLEM_EXAMPLE_DIR)["name"] == "handeye-example-problem"
    assert example_entry_points(PROBLEM_EXAMPLE_DIR) == {"example-problem": "handeye_example_problem"}


def test_found_through_its_entry_point_with_the_shared_solvers(installed_problem):
    reg = handeye.get_registry()
    assert NAME in handeye.list_problems()
    assert reg.problem_provider(NAME).distribution == "handeye-example-problem"
    # refine and auto serve it because it gives the engine a model; its own solver is its start
    assert set(handeye.list_solvers(NAME)) == {SOLVER, "refine", "auto"}
    assert reg.is_builtin("refine", NAME) and not reg.is_builtin(SOLVER, NAME)
    assert reg.solver("refine", NAME).options.INIT_FIELDS == ("init_X",)


@pytest.mark.parametrize("solver", [SOLVER, "refine", "auto"])
@pytest.mark.parametrize("bodies", [1, 3])
def test_noise_free_data_are_recovered(installed_problem, solver, bodies):
    data, truth = installed_problem.PROBLEM.simulate(pairs=12, seed=bodies, bodies=bodies)
    sol = handeye.solve(NAME, solver=solver, **data)
    assert sol.status is handeye.Status.OPTIMAL and sol.X.shape == (bodies, 4, 4)
    errors = installed_problem.PROBLEM.errors(sol.unknowns, truth)["X"]
    assert errors["rotation"] < 1e-9 and errors["translation"] < 1e-9 * 500
    assert sol.diagnostics["self_check"]["reliable"]


@pytest.mark.parametrize("solver", ["refine", "auto"])
def test_noisy_data_within_the_noise_with_uncertainty(installed_problem, solver):
    """30 stations, 3 cameras (10 each), camera noise 0.002 rad / 0.5 mm: each X_b is the mean of
    10 measurements, so its error is ~0.002 / sqrt(10) rad and ~0.5 / sqrt(10) mm per axis, plus
    the rotation noise's lever (~1 m x 0.002 rad / sqrt(10) = 0.6 mm); bounds 4 sigma."""
    data, truth = installed_problem.PROBLEM.simulate(pairs=30, seed=7, noise=NOISE, bodies=3)
    sol = handeye.solve(NAME, solver=solver, **data)
    errors = installed_problem.PROBLEM.errors(sol.unknowns, truth)["X"]
    assert sol.status is handeye.Status.OPTIMAL
    assert errors["rotation"] < 4 * 0.002 / np.sqrt(10) * np.sqrt(3)
    assert errors["translation"] < 4 * 0.7 * np.sqrt(3)
    std = handeye.framework.solution.standard_deviations(sol.diagnostics)
    assert set(std) == {"X[0]", "X[1]", "X[2]"}  # one 1-sigma per pose of the stack
    assert all(0 < s["rotation"] < 0.01 and 0 < s["translation"] < 3 for s in std.values())


def test_refine_starts_from_a_given_stack_and_checks_its_shape(installed_problem):
    data, truth = installed_problem.PROBLEM.simulate(pairs=12, seed=4, bodies=2)
    near = np.stack([T @ make_pose(so3_exp(np.array([0.05, 0.0, -0.03])), [3.0, -2.0, 1.0]) for T in truth["X"]])
    sol = handeye.solve(NAME, solver="refine", init={"X": near}, **data)
    assert sol.diagnostics["init"] == "given"
    assert installed_problem.PROBLEM.errors(sol.unknowns, truth)["X"]["rotation"] < 1e-9
    with pytest.raises(handeye.InputError, match="init_X has shape .*a stack of 2 poses"):
        handeye.solve(NAME, solver="refine", init_X=near[0], **data)


def _solver(run):
    class Plugin:
        @handeye.hookimpl
        def register_solvers(self, register):
            register(handeye.SolverSpec(name="bad", problems=(NAME,), run=run))

    return Plugin()


def test_the_host_checks_each_pose_of_a_stack(installed_problem):
    data, _ = installed_problem.PROBLEM.simulate(pairs=12, seed=5, bodies=2)
    one_pose = _solver(lambda d, o, b: handeye.SolverOutput({"X": np.eye(4)}))
    registry.register_plugin(one_pose, "one-pose")
    try:
        with pytest.raises(handeye.SolverError, match=r"returned X of shape \(4, 4\), not a stack of 2 4x4 poses"):
            handeye.solve(NAME, solver="bad", **data)
    finally:
        registry.unregister_plugin("one-pose")
    broken = np.stack([np.eye(4), np.diag([1.0, 1.0, -1.0, 1.0])])
    registry.register_plugin(_solver(lambda d, o, b: handeye.SolverOutput({"X": broken})), "reflection")
    try:
        with pytest.raises(handeye.SolverError, match=r"returned X\[1\] whose rotation is not in SO\(3\)"):
            handeye.solve(NAME, solver="bad", **data)
    finally:
        registry.unregister_plugin("reflection")


def test_the_self_check_refuses_a_wrong_answer(installed_problem):
    """A solver answering 3 deg off the truth on data good to 0.1 deg: the host's self-check
    (through the problem's model) makes it unreliable."""
    data, truth = installed_problem.PROBLEM.simulate(pairs=20, seed=6, noise=NOISE)
    off = truth["X"] @ make_pose(so3_exp(np.array([0.0, np.radians(3.0), 0.0])), np.zeros(3))
    registry.register_plugin(_solver(lambda d, o, b: handeye.SolverOutput({"X": off})), "off")
    try:
        sol = handeye.solve(NAME, solver="bad", **data)
    finally:
        registry.unregister_plugin("off")
    assert sol.status is handeye.Status.UNRELIABLE
    assert sol.diagnostics["self_check"]["distance_sigmas"] > 10
    assert "self-check failed" in sol.warnings[0]


def test_compare_studies_it(installed_problem, tmp_path):
    from handeye.harness import accuracy_study, run_study

    study = accuracy_study(problem=NAME, trials=2, pairs=(8,))
    result = run_study(study, jobs=1, progress=False)
    rows = result.records
    assert {r["label"] for r in rows} >= {SOLVER, "refine", "auto", "oracle"}
    assert all(r["status"] == "optimal" for r in rows)
    # noise x1 and x10 of the camera's 0.5 mm: errors of a few mm at most
    assert max(r["err_trans_X"] for r in rows) < 20.0
    assert study.noise.sigmas == {"A": (0.0002, 0.05), "B": (0.002, 0.5)}


def test_the_cli_lists_and_simulates_it(installed_problem, tmp_path, capsys):
    code, out, _ = run_cli(capsys, "list")
    assert code == 0 and NAME in out and SOLVER in out
    path = tmp_path / "reg.json"
    code, out, err = run_cli(capsys, "simulate", "--problem", NAME, "--pairs", "10", "--seed", "3", "-o", path)
    assert code == 0, err
    saved = json.loads(path.read_text())
    assert np.asarray(saved["truth"]["X"]).shape in ((1, 4, 4), (4, 4))


def test_bench_times_it(installed_problem, capsys):
    """The benchmark on the problem's own simulator, every solver of it, the first row the
    reference (the problem states no bench settings)."""
    from handeye.harness.bench import run_bench
    from handeye.harness.bench_report import table

    run = run_bench(NAME, pairs=(10,), repeats=2, progress=False)
    labels = [row.label for row in run.rows]
    assert {f"{SOLVER}/numpy", "refine/numpy", "auto/numpy"} <= set(labels)
    assert all(cell.call is not None and cell.call > 0 for cell in run.cells.values())
    assert "1.00x" in table(run, "call")
    code, out, err = run_cli(capsys, "bench", "--problem", NAME, "--pairs", "10", "--repeats", "1", "--no-progress")
    assert code == 0, err
    assert f"handeye bench ({NAME})" in out and f"{SOLVER}/numpy" in out


def _stations(tmp_path, module, *, pairs=12, seed=8, noise=None):
    """A cell's files: the robot's flange poses and the camera's board poses T_cam_target."""
    from handeye.geometry.se3 import inverse
    from handeye.io.pose_writers import write_poses

    data, truth = module.PROBLEM.simulate(pairs=pairs, seed=seed, noise=noise)
    write_poses(tmp_path / "robot.csv", data["A"], "xyz-quat-xyzw", unit="mm")
    write_poses(tmp_path / "camera.csv", inverse(data["B"]), "xyz-quat-xyzw", unit="mm")
    return truth


def test_calibrate_reads_a_cell_for_it(installed_problem, tmp_path, capsys):
    """`handeye.calibrate` and `handeye calibrate` on a cell's two files, through the problem's
    station reader; the same answer on both paths, the truth to 1e-9, no ROS line (the problem
    publishes no camera pose)."""
    from handeye.workflow.cell import CameraStream, Cell, PoseStream

    truth = _stations(tmp_path, installed_problem)
    cell = Cell(robot=PoseStream(str(tmp_path / "robot.csv"), "xyz-quat-xyzw", "mm"),
                camera=CameraStream(str(tmp_path / "camera.csv"), "xyz-quat-xyzw", "mm"),
                setup="eye-in-hand", problem=NAME)
    result = handeye.calibrate(cell)
    assert result.status is handeye.Status.OPTIMAL and result.plausible and result.published is None
    assert installed_problem.PROBLEM.errors(result.unknowns, truth)["X"]["translation"] < 1e-9
    assert result.frames["X"].name == "T_flange_cam"
    assert result.to_dict()["ros"] is None and set(result.to_dict()["poses"]) == {"X[0]"}
    with pytest.raises(handeye.InputError, match="names no camera pose to publish"):
        result.ros2_static_transform()
    out_file = tmp_path / "result.json"
    code, out, err = run_cli(capsys, "calibrate", "--robot", tmp_path / "robot.csv", "--robot-format", "xyz-quat-xyzw",
                             "--robot-unit", "mm", "--camera", tmp_path / "camera.csv", "--camera-format",
                             "xyz-quat-xyzw", "--camera-unit", "mm", "--setup", "eye-in-hand", "--problem", NAME,
                             "-o", out_file)
    assert code == 0, err
    assert "X[0] = T_flange_cam" in out and "ROS 2" not in out
    written = json.loads(out_file.read_text())
    assert np.array_equal(np.asarray(written["X[0]"]), result.X[0])


def test_calibrate_finds_a_setup_mistake_for_it(installed_problem, tmp_path):
    """The plausibility check tries the usual mistakes with the problem's own closed form: robot
    poses given as T_flange_base."""
    from handeye.geometry.se3 import inverse
    from handeye.io.pose_readers import read_poses
    from handeye.io.pose_writers import write_poses
    from handeye.workflow.cell import CameraStream, Cell, PoseStream

    _stations(tmp_path, installed_problem, noise=NOISE)
    robot = read_poses(tmp_path / "robot.csv", "xyz-quat-xyzw", unit="mm")
    write_poses(tmp_path / "robot.csv", inverse(robot.poses), "xyz-quat-xyzw", unit="mm")
    cell = Cell(robot=PoseStream(str(tmp_path / "robot.csv"), "xyz-quat-xyzw", "mm"),
                camera=CameraStream(str(tmp_path / "camera.csv"), "xyz-quat-xyzw", "mm"),
                setup="eye-in-hand", problem=NAME)
    result = handeye.calibrate(cell)
    assert result.status is handeye.Status.UNRELIABLE and not result.plausible
    assert "the robot poses are inverted" in result.warnings[0]


def test_the_report_shows_it(installed_problem, tmp_path, capsys):
    """`handeye solve --report` on a data file of the problem: the HTML names its equation, its
    unknown's poses and their 1-sigma."""
    from handeye.io.data_files import save_data

    data, truth = installed_problem.PROBLEM.simulate(pairs=20, seed=9, noise=NOISE, bodies=2)
    path = save_data(tmp_path / "reg.json", data, truth, problem=NAME, metadata={"units": "mm"})
    report = tmp_path / "report.html"
    code, out, err = run_cli(capsys, "solve", path, "--problem", NAME, "--report", report)
    assert code == 0, err
    assert "X[0] = T_flange_cam" in out and "X[1] = T_flange_cam" in out
    html = report.read_text()
    assert "A_i X_b(i) = B_i" in html and "X[1]" in html and "T_flange_cam" in html
