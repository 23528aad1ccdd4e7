"""The ``handeye`` command line, mostly in-process through handeye.cli.main(argv)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from handeye import SolverError
from handeye.cli import COMMANDS
from handeye.host.registry import get_registry
from handeye.io.data_files import load_data, save_data
from tests.conftest import run_cli


def test_commands_registered_in_one_list():
    from handeye.cli import build_parser

    assert all(callable(c.add_parser) and callable(c.run) for c in COMMANDS)
    subparsers = next(a for a in build_parser()._actions if a.dest == "command")
    assert {"list", "simulate", "solve"} <= set(subparsers.choices)
    assert len(subparsers.choices) == len(COMMANDS)  # one subcommand per module in COMMANDS


def test_list_text_and_json(capsys):
    code, out, _ = run_cli(capsys, "list")
    assert code == 0
    assert "axyb" in out and "kron-lstsq" in out and "numpy*" in out and "handeye" in out
    code, out, _ = run_cli(capsys, "list", "--json")
    assert code == 0
    listing = json.loads(out)
    assert [p["name"] for p in listing["problems"]] == sorted(get_registry().problems)
    by_name = {s["name"]: s for s in listing["solvers"]}
    assert set(by_name) == set(get_registry().solvers)
    kron = by_name["kron-lstsq"]
    assert kron["distribution"] == "handeye" and kron["version"]
    assert kron["citation"] and kron["problems"][0] == "axyb"
    assert [b["name"] for b in kron["backends"] if b["default"]] == ["numpy"]
    assert all(b["available"] for b in kron["backends"])


def test_list_markdown_table_has_a_row_per_solver(capsys):
    code, out, _ = run_cli(capsys, "list", "--markdown")
    rows = out.strip().splitlines()
    assert code == 0 and rows[0].startswith("| solver | problems |")
    assert [r.split("|")[1].strip(" `") for r in rows[2:]] == sorted(get_registry().solvers)


def test_readme_solver_table_is_the_registry_table(capsys):
    """README's solver table is `handeye list --markdown` for handeye's own solvers: regenerate
    it with that command when a solver changes (third-party rows are left out of the comparison)."""
    from pathlib import Path

    _, out, _ = run_cli(capsys, "list", "--json")
    ours = {s["name"] for s in json.loads(out)["solvers"] if s["distribution"] == "handeye"}
    _, out, _ = run_cli(capsys, "list", "--markdown")
    rows = out.strip().splitlines()
    expected = rows[:2] + [r for r in rows[2:] if r.split("|")[1].strip(" `") in ours]
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8").splitlines()
    start = readme.index(expected[0])
    assert readme[start:start + len(expected)] == expected
    assert not readme[start + len(expected)].startswith("|")  # no stale extra rows


def test_version_and_help_exit_0(capsys):
    import handeye

    code, out, _ = run_cli(capsys, "--version")
    assert code == 0 and handeye.__version__ in out
    code, out, _ = run_cli(capsys, "solve", "--help")
    assert code == 0 and "--example" in out


def test_list_shows_unavailable_backend_with_reason(capsys, monkeypatch):
    spec = get_registry().solver("kron-lstsq", "axyb")
    monkeypatch.setattr(type(spec), "unavailable_reason", lambda self, b: "needs the moon" if self is spec else None)
    code, out, _ = run_cli(capsys, "list")
    assert code == 0 and "UNAVAILABLE: needs the moon" in out


@pytest.mark.parametrize("ext", ["npz", "json"])
def test_simulate_then_solve_reports_truth_errors(capsys, tmp_path, ext):
    path = tmp_path / f"data.{ext}"
    code, out, err = run_cli(capsys, "simulate", "--problem", "axyb", "--pairs", "16", "--noise-rot", "0.001",
                             "--noise-trans", "0.1", "--seed", "1", "-o", str(path))
    assert code == 0, err
    data, truth = load_data(path)
    assert data["A"].shape == (16, 4, 4) and truth is not None
    code, out, err = run_cli(capsys, "solve", "--problem", "axyb", "--solver", "kron-lstsq", str(path))
    assert code == 0, err
    assert "X =" in out and "Y =" in out and "errors against the file's truth" in out and "median" in out
    code, out, err = run_cli(capsys, "solve", "--solver", "kron-lstsq", "--json", str(path))
    report = json.loads(out)
    assert report["status"] == "optimal" and report["units"] == "mm" and report["pairs"] == 16
    assert np.asarray(report["unknowns"]["X"]).shape == (4, 4)
    assert report["errors"]["X"]["rotation"] < 0.01 and report["errors"]["Y"]["translation"] < 5
    assert len(report["residuals_per_pair"]["rotation"]) == 16
    assert report["residuals"]["rotation"]["max"] >= report["residuals"]["rotation"]["median"] > 0


def test_noise_free_simulation_recovers_truth(capsys, tmp_path):
    path = tmp_path / "clean.json"
    assert run_cli(capsys, "simulate", "--pairs", "8", "--seed", "4", "-o", str(path))[0] == 0
    _, out, _ = run_cli(capsys, "solve", "--solver", "kron-lstsq", "--json", str(path))
    errors = json.loads(out)["errors"]
    assert max(e["rotation"] for e in errors.values()) < 1e-8
    assert max(e["translation"] for e in errors.values()) < 1e-5  # mm


def test_noise_on_both_and_bad_noise_target(capsys, tmp_path):
    path = tmp_path / "both.npz"
    assert run_cli(capsys, "simulate", "--pairs", "5", "--noise-rot", "0.01", "--noise-on", "both",
                   "--seed", "2", "-o", str(path))[0] == 0
    data, truth = load_data(path)
    # noise on A too: A is no longer exactly the noise-free forward kinematics, so A X != Y B
    assert np.abs(data["A"] @ truth["X"] - truth["Y"] @ data["B"]).max() > 1e-6
    code, _, err = run_cli(capsys, "simulate", "--noise-on", "C", "-o", str(tmp_path / "c.npz"))
    assert code == 2 and err.startswith("handeye: error:") and "'both'" in err


def test_option_values_parsed_as_json(capsys, tmp_path):
    path = tmp_path / "d.npz"
    run_cli(capsys, "simulate", "--pairs", "6", "--seed", "3", "-o", str(path))
    code, out, err = run_cli(capsys, "solve", "--solver", "kron-lstsq", "--option", "normalize=false", "--json", str(path))
    assert code == 0, err
    assert json.loads(out)["options"] == {"normalize": False}


def test_example_solve(capsys):
    code, out, err = run_cli(capsys, "solve", "--example", "--solver", "kron-lstsq")
    assert code == 0, err
    assert "eth-robot-arm" in out and "lengths in m" in out and "errors against" not in out
    code, out, err = run_cli(capsys, "solve", "--example", "simulated", "--solver", "kron-lstsq", "--json")
    report = json.loads(out)
    assert report["source"] == "example 'simulated'" and report["errors"]["X"]["rotation"] < 0.01


def test_default_solver_is_explicit(capsys, tmp_path):
    from handeye.cli.solve_cmd import default_solver

    expected = "auto" if "auto" in get_registry().solver_names("axyb") else "kron-lstsq"
    assert default_solver("axyb") == expected
    code, out, err = run_cli(capsys, "solve", "--example", "--json")
    assert code == 0, err
    assert json.loads(out)["solver"] == expected
    if expected == "auto":  # 50 real pairs: auto weighs them by where the noise lives, and says so
        gain = json.loads(out)["diagnostics"]["refine"]["loglik_gain"]
        code, out, err = run_cli(capsys, "solve", "--example")
        assert code == 0 and f"noise per source, 1-sigma ({gain:.0f} nats" in out and "rotation of B, reference frame" in out


@pytest.mark.parametrize("argv, message", [
    (["solve", "{tmp}/missing.npz"], "not found"),
    (["solve", "{tmp}/bad.json"], "invalid JSON"),
    (["solve", "{tmp}/data.txt"], "unsupported file extension"),
    (["solve", "--solver", "no-such-solver", "{tmp}/good.json"], "unknown solver"),
    (["solve", "--solver", "kron-lstsq", "--backend", "fortran", "{tmp}/good.json"], "unknown backend"),
    (["solve", "--solver", "kron-lstsq", "--option", "bogus=1", "{tmp}/good.json"], "known option"),
    (["solve", "--solver", "kron-lstsq", "--option", "novalue", "{tmp}/good.json"], "key=value"),
    (["solve", "--solver", "kron-lstsq", "--option", "A=1", "{tmp}/good.json"], "clashes"),
    (["solve", "--problem", "axxbz", "{tmp}/good.json"], "unknown problem"),
    (["solve", "--example", "nope"], "unknown example"),
    (["solve"], "either a data FILE or --example"),
    (["solve", "--example", "{tmp}/good.json"], "unknown example"),
])
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, argv, message):
    data = {"A": np.stack([np.eye(4)] * 3), "B": np.stack([np.eye(4)] * 3)}
    data["A"][1, :3, :3] = data["B"][1, :3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    data["A"][2, :3, :3] = data["B"][2, :3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    save_data(tmp_path / "good.json", data)
    (tmp_path / "bad.json").write_text("{oops")
    (tmp_path / "data.txt").write_text("")
    code, _, err = run_cli(capsys, *[a.format(tmp=tmp_path) for a in argv])
    assert code == 2
    assert err.startswith("handeye: error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert message in err


def test_argparse_usage_error_exits_2(capsys):
    code, _, err = run_cli(capsys, "simulate", "--pairs", "many", "-o", "x.npz")
    assert code == 2 and "invalid int value" in err


def test_degenerate_data_exits_2(capsys, tmp_path):
    path = tmp_path / "flat.json"
    save_data(path, {"A": np.stack([np.eye(4)] * 4), "B": np.stack([np.eye(4)] * 4)})
    code, _, err = run_cli(capsys, "solve", "--solver", "kron-lstsq", str(path))
    assert code == 2 and "rotations of X and Y cannot be determined" in err
    assert "Record poses that rotate about at least two different axes" in err


def test_solver_failure_exits_1(capsys, monkeypatch):
    spec = get_registry().solver("kron-lstsq", "axyb")

    def explode(data, options, backend):
        raise SolverError("the solver gave up: numerical trouble")

    monkeypatch.setitem(get_registry().solvers["kron-lstsq"], "axyb", dataclasses.replace(spec, run=explode))
    code, out, err = run_cli(capsys, "solve", "--example", "--solver", "kron-lstsq")
    assert code == 1 and out == ""
    assert err == "handeye: error: the solver gave up: numerical trouble\n"


def test_console_script_exit_codes(tmp_path):
    """The installed ``handeye`` console script in a real subprocess (exit codes, no traceback)."""
    exe = shutil.which("handeye", path=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""))
    assert exe, "the handeye console script is not installed next to this Python (pip install .)"
    cmd = [exe]
    ok = subprocess.run([*cmd, "solve", "--example", "--solver", "kron-lstsq"], capture_output=True, text=True, timeout=120, check=False)
    assert ok.returncode == 0, ok.stderr
    assert "residuals" in ok.stdout
    bad = subprocess.run([*cmd, "solve", str(tmp_path / "missing.json")], capture_output=True, text=True, timeout=120, check=False)
    assert bad.returncode == 2
    assert bad.stderr.startswith("handeye: error:") and "Traceback" not in bad.stderr


@pytest.mark.parametrize("text, value", [("False", False), ("false", False), ("FALSE", False),
                                         ("True", True), ("true", True), (" tRuE ", True)])
def test_option_true_false_in_any_case_is_a_bool(text, value):
    from handeye.cli._common import parse_key_values

    assert parse_key_values([f"normalize={text}", "tol=1e-8", "init=identity"]) == {
        "normalize": value, "tol": 1e-8, "init": "identity"}


def test_option_normalize_False_reaches_the_solver_as_false(capsys):
    """``--option normalize=False`` (Python spelling) is the bool False, not the truthy "False"."""
    code, out, err = run_cli(capsys, "solve", "--example", "simulated", "--solver", "li",
                             "--option", "normalize=False", "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["options"] == {"normalize": False} and report["diagnostics"]["normalize"] is False


def test_unexpected_exception_is_one_line_internal_error(capsys, monkeypatch):
    from handeye.cli import list_cmd

    def broken(args):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(list_cmd, "run", broken)
    code, out, err = run_cli(capsys, "list")
    assert code == 1 and out == ""
    assert err == "handeye: internal error: RuntimeError: boom second line (please report)\n"


def test_keyboard_interrupt_still_exits_130(capsys, monkeypatch):
    from handeye.cli import list_cmd

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(list_cmd, "run", interrupted)
    code, _, err = run_cli(capsys, "list")
    assert code == 130 and err == "handeye: error: interrupted\n"


def test_not_converged_solution_is_printed_and_exits_1(capsys, tmp_path):
    """iterative from R = I with 2 iterations on general data (tests/plugins/test_iterative.py) stops
    with status not_converged: the result is shown, with the warning, and the exit code is 1."""
    from handeye.problems.axyb import PROBLEM, random_truth

    truth = random_truth(np.random.default_rng(0))
    data, truth = PROBLEM.simulate(pairs=12, seed=0, X=truth["X"], Y=truth["Y"])
    path = save_data(tmp_path / "general.json", data, truth)
    argv = ["solve", "--solver", "iterative", "--option", "init=identity", "--option", "max_iter=2", str(path)]
    code, out, err = run_cli(capsys, *argv)
    assert code == 1
    assert "status not_converged" in out and "X =" in out and "do not use X, Y" in out
    assert err.startswith("handeye: error: solver 'iterative' ended with status not_converged")
    assert err.count("\n") == 1
    code, out, _ = run_cli(capsys, *argv, "--json")
    assert code == 1 and json.loads(out)["status"] == "not_converged"


@pytest.mark.parametrize("status, exit_code", [("optimal", 0), ("optimal_inaccurate", 0), ("uncertified", 0),
                                               ("not_converged", 1), ("failed", 1)])
def test_solve_exit_code_follows_the_status(capsys, monkeypatch, status, exit_code):
    spec = get_registry().solver("kron-lstsq", "axyb")

    def with_status(data, options, backend):
        return dataclasses.replace(spec.run(data, options, backend), status=status)

    monkeypatch.setitem(get_registry().solvers["kron-lstsq"], "axyb", dataclasses.replace(spec, run=with_status))
    code, out, err = run_cli(capsys, "solve", "--example", "--solver", "kron-lstsq")
    assert code == exit_code and f"status {status}," in out
    assert (err == "") == (exit_code == 0)
    assert ("could not prove it globally optimal" in out) == (status == "uncertified")


def test_bench_times_the_selected_rows_and_judges_the_targets(capsys):
    """`handeye bench` runs end to end (a smoke test: timings are not asserted, machines are
    noisy): the selected solvers, the OpenCV reference rows, the extra row a target asks for
    (refine from the closed-form start) and one verdict line per target."""
    code, out, _ = run_cli(capsys, "bench", "--pairs", "16", "--repeats", "1", "--no-progress",
                           "--solvers", "kron-lstsq,refine")
    assert code == 0
    for label in ("kron-lstsq/numpy", "refine/numpy", "refine/numpy [init=kron-lstsq]", "opencv [method=shah]"):
        assert f"\n{label} " in out
    verdicts = [line for line in out.splitlines() if line.startswith("  target: ")]
    targets = get_registry().problem("axyb").bench.targets  # the default problem's

    assert len(verdicts) == len(targets)
    judged = [line for line in verdicts if "refine/numpy [init=kron-lstsq]" in line and "m=16" in line]
    assert len(judged) == 1 and ("PASS" in judged[0] or "MISS" in judged[0])
    assert "issue" not in out.lower()  # targets are named by what they are


@pytest.mark.parametrize("solver", ["so3-sdp", "lmi-sdp"])
def test_first_sdp_solve_reports_its_compilation(capsys, monkeypatch, solver):
    """The solve that compiles a cvxpy problem says so (compile_seconds > 0, and the CLI notes
    that the time includes the one-time set-up); the next solve of the same problem does not."""
    from handeye.plugins import lmi_sdp, so3_sdp

    cvxpy = ("--solver", solver, "--backend", "cvxpy") + (("--option", "local_first=false") if solver == "so3-sdp" else ())
    monkeypatch.setattr(so3_sdp.CVXPY_CACHE, "problems", {})  # as in a fresh process
    monkeypatch.setattr(lmi_sdp.CVXPY_CACHE, "problems", {})
    code, out, _ = run_cli(capsys, "solve", "--example", *cvxpy, "--json")
    assert code == 0 and json.loads(out)["diagnostics"]["compile_seconds"] > 0
    code, out, _ = run_cli(capsys, "solve", "--example", *cvxpy)
    assert code == 0 and "first SDP solve in this process" not in out
    code, out, _ = run_cli(capsys, "solve", "--example", *cvxpy, "--json")
    assert json.loads(out)["diagnostics"]["compile_seconds"] == 0.0
    monkeypatch.setattr(so3_sdp.CVXPY_CACHE, "problems", {})
    monkeypatch.setattr(lmi_sdp.CVXPY_CACHE, "problems", {})
    code, out, _ = run_cli(capsys, "solve", "--example", *cvxpy)
    assert "first SDP solve in this process" in out


def test_default_solve_compiles_nothing(capsys):
    """auto's start (so3-sdp on its native Clarabel backend) builds no cvxpy problem: no
    one-time set-up note, compile_seconds 0."""
    code, out, _ = run_cli(capsys, "solve", "--example", "--json")
    assert code == 0 and json.loads(out)["diagnostics"]["compile_seconds"] == 0.0
    code, out, _ = run_cli(capsys, "solve", "--example")
    assert "first SDP solve in this process" not in out


# --- problem axxb (A_i X = X B_i) ------------------------------------------------------------------

def axxb_solver() -> str:
    """The solver the axxb CLI tests use: kron-lstsq (closed form, fast), else any registered one."""
    names = get_registry().solver_names("axxb")
    assert names, "no solver is registered for problem axxb"
    return "kron-lstsq" if "kron-lstsq" in names else names[0]


def eye_to_hand_stations(n: int = 8, seed: int = 3) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Noise-free stations of an eye-to-hand cell built from named frames: a camera fixed at
    T_base_cam, a board on the flange at T_flange_target; robot_poses = T_base_flange,
    camera_poses = T_cam_target = T_base_cam^-1 T_base_flange T_flange_target."""
    from handeye.geometry.kinematics import random_flange_poses
    from handeye.geometry.se3 import inverse
    from handeye.problems.axxb import PROBLEM as AXXB

    rng = np.random.default_rng(seed)
    T_base_flange = random_flange_poses(n, rng)
    T_base_cam, T_flange_target = (AXXB.random_unknowns(rng, 300.0)["X"] for _ in range(2))
    return {"robot_poses": T_base_flange,
            "camera_poses": inverse(T_base_cam) @ T_base_flange @ T_flange_target}, T_base_cam


@pytest.mark.parametrize("ext", ["json", "npz"])
def test_axxb_simulate_stations_then_solve(capsys, tmp_path, ext):
    path = tmp_path / f"stations.{ext}"
    code, out, err = run_cli(capsys, "simulate", "--problem", "axxb", "--stations", "9", "--noise-rot", "0.001",
                             "--noise-trans", "0.1", "--noise-on", "both", "--seed", "1", "-o", str(path))
    assert code == 0, err
    assert "wrote 9 axxb stations" in out
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), str(path))
    assert code == 0, err
    assert "36 motions from 9 stations (all pairs, eye-in-hand, lengths in mm)" in out
    assert "X = T_flange_cam (camera in the flange frame) =" in out and "Y =" not in out
    assert "residuals of A_i X = X B_i over the motions (angle and distance between the two sides):" in out
    assert "errors against the file's truth" in out
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--pairing",
                             "consecutive", str(path))
    assert code == 0, err
    assert "8 motions from 9 stations (consecutive pairs, eye-in-hand, lengths in mm)" in out
    assert "per motion:" in out and "0 (0->1)" in out and "7 (7->8)" in out
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--json", str(path))
    report = json.loads(out)
    assert code == 0 and report["problem"] == "axxb" and report["pairing"] == "all"
    assert (report["pairs"], report["stations"]) == (36, 9) and report["motions"][:2] == [[0, 1], [0, 2]]
    assert report["frames"] == {"X": "T_flange_cam"} and set(report["unknowns"]) == {"X"}
    assert len(report["residuals_per_pair"]["rotation"]) == 36
    assert report["errors"]["X"]["rotation"] < 0.01 and report["errors"]["X"]["translation"] < 2  # mm
    code, out, _ = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--pairing", "all", str(path))
    assert "the 10 largest of the 36 motions" in out
    # the same stations as AX=YB: one pair per station, X and Y against the cell's truth
    code, out, err = run_cli(capsys, "solve", "--solver", "kron-lstsq", "--json", str(path))
    report = json.loads(out)
    assert code == 0, err
    assert (report["problem"], report["pairs"], report["stations"]) == ("axyb", 9, 9) and "pairing" not in report
    assert report["frames"] == {"X": "T_flange_cam", "Y": "T_base_target"}
    assert report["errors"]["X"]["rotation"] < 0.01 and set(report["errors"]) == {"X", "Y"}


def test_axxb_simulated_motions_file(capsys, tmp_path):
    path = tmp_path / "motions.npz"
    code, _, err = run_cli(capsys, "simulate", "--problem", "axxb", "--pairs", "6", "--pairing", "all",
                           "--seed", "2", "-o", str(path))
    assert code == 0, err
    data, truth = load_data(path, problem="axxb")
    assert data["A"].shape == (15, 4, 4) and set(truth) == {"X"}  # every pair of 6 stations
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--json", str(path))
    report = json.loads(out)
    assert code == 0, err
    assert report["pairs"] == 15 and "stations" not in report
    assert report["errors"]["X"]["rotation"] < 1e-8  # noise free


def test_axxb_eye_to_hand_gives_the_camera_in_the_base(capsys, tmp_path):
    """docs/conventions.md: eye-to-hand, X = T_base_cam; the setup comes from --setup."""
    poses, T_base_cam = eye_to_hand_stations()
    path = tmp_path / "fixed-camera.json"
    path.write_text(json.dumps({k: v.tolist() for k, v in poses.items()}))
    code, _, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), str(path))
    assert code == 2 and "need the setup" in err
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--setup",
                             "eye-to-hand", "--json", str(path))
    assert code == 0, err
    report = json.loads(out)
    assert report["setup"] == "eye-to-hand" and report["frames"] == {"X": "T_base_cam"}
    np.testing.assert_allclose(report["unknowns"]["X"], T_base_cam, atol=1e-6)
    code, out, _ = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), "--setup",
                           "eye-to-hand", str(path))
    assert "X = T_base_cam (camera in the robot base frame) =" in out


def test_axxb_example_is_the_bundled_stations(capsys):
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--example", "simulated", "--solver",
                             axxb_solver(), "--pairing", "all", "--json")
    report = json.loads(out)
    assert code == 0, err
    assert (report["stations"], report["pairs"], report["setup"]) == (16, 120, "eye-in-hand")
    assert report["errors"]["X"]["rotation"] < 0.02  # the axyb example's X is T_flange_cam


@pytest.mark.parametrize("content, argv, message", [
    ({"robot_poses": "{robot}", "setup": "eye-in-hand"}, [], "missing ['camera_poses']"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera}", "A": "{robot}", "B": "{camera}", "setup": "eye-in-hand"},
     [], "both data field(s)"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera}", "setup": "sideways"}, [], "setup must be one of"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera}", "pairing": "random"}, ["--setup", "eye-in-hand"],
     "pairing must be one of"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera_short}", "setup": "eye-in-hand"}, [], "same length"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera}"}, [], "need the setup"),
    ({"A": "{robot}", "B": "{camera}"}, ["--pairing", "all"], "pairing applies to a file of absolute poses"),
    ({"robot_poses": "{robot}", "camera_poses": "{camera}"}, ["--setup", "upside-down"], "invalid choice"),
])
def test_axxb_bad_input_exits_2_with_one_line(capsys, tmp_path, content, argv, message):
    poses, _ = eye_to_hand_stations(5)
    values = {"{robot}": poses["robot_poses"].tolist(), "{camera}": poses["camera_poses"].tolist(),
              "{camera_short}": poses["camera_poses"][:4].tolist()}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({k: values.get(v, v) for k, v in content.items()}))
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), *argv, str(path))
    assert code == 2 and out == ""
    assert message in err and "Traceback" not in err
    if "invalid choice" not in message:  # argparse's own usage message has two lines
        assert err.startswith("handeye: error: ") and err.count("\n") == 1


def test_number_beyond_float64_in_a_file_exits_2(capsys, tmp_path):
    """A 400-digit integer in a JSON file is bad input (exit 2, one line), not an internal error."""
    poses, _ = eye_to_hand_stations(5)
    robot = poses["robot_poses"].tolist()
    text = json.dumps({"robot_poses": robot, "camera_poses": poses["camera_poses"].tolist(), "setup": "eye-to-hand"})
    path = tmp_path / "huge.json"
    path.write_text(text.replace(repr(robot[0][0][3]), "1" + "0" * 400, 1))
    code, out, err = run_cli(capsys, "solve", "--problem", "axxb", "--solver", axxb_solver(), str(path))
    assert code == 2 and out == "" and err.count("\n") == 1 and "could not convert it to floats" in err


def test_simulate_axxb_flags_are_checked(capsys, tmp_path):
    out = str(tmp_path / "x.npz")
    code, _, err = run_cli(capsys, "simulate", "--problem", "axxb", "--pairs", "5", "--stations", "6", "-o", out)
    assert code == 2 and "not both" in err
    code, _, err = run_cli(capsys, "simulate", "--pairing", "all", "-o", out)
    assert code == 2 and "--pairing applies to problems whose data are motions (['axxb'])" in err


def test_bench_axxb_times_the_solvers_beside_cv2_calibrate_hand_eye(capsys):
    """A smoke test of `handeye bench --problem axxb` at one small m (timings are not asserted)."""
    pytest.importorskip("cv2")
    code, out, err = run_cli(capsys, "bench", "--problem", "axxb", "--pairs", "6", "--repeats", "1",
                             "--no-progress", "--solvers", axxb_solver())
    assert code == 0, err
    assert out.startswith("handeye bench (axxb)") and "ratio to 'cv2 direct TSAI'" in out
    for method in ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"):
        assert f"\ncv2 direct {method} " in out
    assert f"\n{axxb_solver()}/numpy " in out and "issue" not in out.lower()


def test_solve_prints_the_uncertainties(capsys):
    """The text output gives each unknown's 1-sigma (from the solver's covariance, when it has one)."""
    code, out, _ = run_cli(capsys, "solve", "--example")
    assert code == 0 and out.count("  1-sigma: rotation ") == 2  # X and Y, from auto's refinement
    code, out, _ = run_cli(capsys, "solve", "--example", "--solver", "kron-lstsq")
    assert code == 0 and "1-sigma" not in out  # a closed form reports none
