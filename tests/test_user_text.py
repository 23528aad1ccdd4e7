"""The words a user sees: `--help` of every command, and the errors of degenerate data, speak of
the user's data and what to do, never of our equation numbers or our issue tracker (those belong
in docs and docstrings); and ``import handeye`` gives ``handeye.io`` and ``handeye.examples``
without importing them first, while staying cheap."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

import handeye
from handeye import DegenerateDataError
from handeye.cli import COMMANDS, build_parser, main
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.plugins import classic_handeye, li, shah
from handeye.problems.axyb import PROBLEM, AXYBData

#: what a user-facing text must not contain: equation numbers and references to our tracker
FORBIDDEN = re.compile(r"\beqs?\.\s|\bequation \d|\bissue", re.IGNORECASE)


def _subcommands() -> list[str]:
    action = next(a for a in build_parser()._actions if a.dest == "command")
    return list(action.choices)


def test_every_subcommand_is_scanned():
    names = _subcommands()
    assert len(names) == len(COMMANDS) and {"solve", "simulate", "list", "bench", "compare"} <= set(names)


@pytest.mark.parametrize("argv", [["--help"]] + [[name, "--help"] for name in _subcommands()],
                         ids=lambda argv: " ".join(argv))
def test_help_speaks_the_users_words(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0 and "usage: handeye" in out
    assert not FORBIDDEN.search(out + err), FORBIDDEN.search(out + err)


def test_list_output_names_no_equations(capsys):
    """Solver summaries in ``handeye list`` say what a method does; equation numbers appear only
    in the citation lines (``cite``), which point into the literature."""
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for line in out.splitlines():
        if not line.strip().startswith("cite "):
            assert not FORBIDDEN.search(line), line


# ------------------------------------------------------------------ errors of degenerate data

def _assert_plain(message: str, *remedy: str) -> None:
    assert not FORBIDDEN.search(message), message
    for words in remedy:
        assert words in message, message


def _one_axis_poses(m: int = 8, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Absolute poses A (robot) rotating about z only, and B = Y^-1 A X of a true cell."""
    rng = np.random.default_rng(seed)
    A = make_pose(so3_exp(np.outer(rng.uniform(-2, 2, m), [0.0, 0.0, 1.0])), 100 * rng.standard_normal((m, 3)))
    X = make_pose(so3_exp([0.3, -0.2, 1.0]), [10.0, 20.0, 30.0])
    Y = make_pose(so3_exp([1.3, 0.2, -1.0]), [100.0, -200.0, 300.0])
    return A, inverse(Y) @ A @ X


def _one_axis_motions(m: int = 6, seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Motions A rotating about one axis, and B = X^-1 A X."""
    rng = np.random.default_rng(seed)
    A = make_pose(so3_exp(np.outer(np.deg2rad(rng.uniform(20, 90, m)), [0.0, 0.6, 0.8])),
                  100 * rng.standard_normal((m, 3)))
    X = make_pose(so3_exp([0.3, -0.2, 1.0]), [10.0, 20.0, 30.0])
    return A, inverse(X) @ A @ X


@pytest.mark.parametrize("solver", ["kron-lstsq", "auto"])
def test_axyb_rotations_about_one_axis(solver):
    A, B = _one_axis_poses()
    with pytest.raises(DegenerateDataError) as info:
        handeye.solve("axyb", A=A, B=B, solver=solver)
    # one axis, translations across it: a planar robot, whose one undetermined translation the
    # user can give (tests/problems/test_planar.py)
    _assert_plain(str(info.value), "translations of X and Y along that axis cannot be determined", "tz_X=",
                  "record poses that rotate about at least two different axes")


@pytest.mark.parametrize("solver", ["kron-lstsq", "park", "auto"])
def test_axxb_rotations_about_one_axis(solver):
    A, B = _one_axis_motions()
    with pytest.raises(DegenerateDataError) as info:
        handeye.solve("axxb", A=A, B=B, solver=solver)
    _assert_plain(str(info.value), "do not determine X", "tz_X=", "record motions that rotate about at least two different axes")


@pytest.mark.parametrize("method", ["tsai", "park", "horaud", "andreff", "daniilidis"])
def test_classic_methods_called_directly_on_one_axis(method):
    """The classic functions are public and skip the problem's validation: their own messages."""
    A, B = _one_axis_motions()
    with pytest.raises(DegenerateDataError) as info:
        getattr(classic_handeye, method)(A, B)
    _assert_plain(str(info.value), "X cannot be determined" if method != "tsai" else "Tsai's method",
                  "Record motions that rotate about at least two different axes")


def test_li_and_shah_on_one_axis():
    A, B = _one_axis_poses()
    with pytest.raises(DegenerateDataError) as info:
        li.least_squares_beta_qr(AXYBData(A, B))
    _assert_plain(str(info.value), "li: the linear system is rank deficient", "X and Y cannot be determined",
                  "Record poses that rotate about at least two different axes")
    with pytest.raises(DegenerateDataError) as info:
        shah.normalize_rotation(np.zeros((3, 3)))
    _assert_plain(str(info.value), "rotations of X and Y cannot be determined",
                  "Record poses that rotate about at least two different axes")


@pytest.mark.parametrize(("problem", "pairs"), [("axyb", 2), ("axxb", 1)])
def test_too_few_pairs(problem, pairs):
    A, B = _one_axis_poses(m=pairs)
    with pytest.raises(DegenerateDataError) as info:
        handeye.solve(problem, A=A, B=B, solver="kron-lstsq")
    need = {"axyb": 3, "axxb": 2}[problem]
    _assert_plain(str(info.value), f"need at least {need} pose pairs, got {pairs}", "record more poses")


def test_unknown_names_read_as_english():
    """The kind of name and what it belongs to, in that order: no "'kron-lstsq''s"."""
    data, _ = PROBLEM.simulate(pairs=5, seed=3)
    A, B = data["A"], data["B"]
    with pytest.raises(handeye.UnknownPluginError) as info:
        handeye.solve("axyb", A=A, B=B, solver="kron-lstsq", normalise=True)
    message = str(info.value)
    assert message.startswith("unknown option 'normalise' of solver 'kron-lstsq'; known options: 'normalize'")
    assert "'s" not in message
    with pytest.raises(handeye.UnknownPluginError) as info:
        handeye.solve("axyb", A=A, B=B, solver="kron-lstsq", backend="gpu")
    assert str(info.value) == "unknown backend 'gpu' of solver 'kron-lstsq'; known backends: 'numpy'"


# ------------------------------------------------------------------ lazy submodules

def test_submodules_without_importing_them_first():
    """``handeye.io`` and ``handeye.examples`` (and ``harness``, ``problems``) are imported on first
    use (PEP 562); ``import handeye`` alone imports none of them, nor cvxpy, casadi or matplotlib, and
    a closed-form solve loads no modelling layer, SDP solver, OpenCV, plotting or bag reader."""
    code = """
import sys
import handeye
lazy = ("handeye.io", "handeye.examples", "handeye.harness")
assert not [m for m in lazy if m in sys.modules], [m for m in lazy if m in sys.modules]
assert {"io", "examples", "harness", "problems"} <= set(dir(handeye)) & set(handeye.__all__)
assert callable(handeye.io.load_file) and "simulated" in handeye.examples.list_examples()
assert handeye.harness.__name__ == "handeye.harness" and handeye.problems.__name__ == "handeye.problems"
try:
    handeye.no_such_name
except AttributeError as exc:
    assert "no_such_name" in str(exc)
else:
    raise AssertionError("handeye.no_such_name did not raise AttributeError")
data, truth, metadata = handeye.examples.load_example("simulated")
for closed_form in ("kron-lstsq", "shah", "li"):
    handeye.solve("axyb", A=data["A"], B=data["B"], solver=closed_form)
heavy = [m for m in ("cvxpy", "casadi", "matplotlib", "picos", "clarabel", "cv2", "rosbags") if m in sys.modules]
assert not heavy, heavy
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr


# ----------------------------------------------------------------------------- a new user's trip-ups

def _quaternion_first_files(tmp_path):
    """A robot file written quaternion first (qw qx qy qz x y z, as many trackers do) and a camera
    file of T_target_cam in the usual x y z qx qy qz qw, no headers."""
    from scipy.spatial.transform import Rotation

    data, truth = PROBLEM.simulate(pairs=12, seed=3)
    q = Rotation.from_matrix(data["A"][:, :3, :3]).as_quat(scalar_first=True)
    robot, camera = tmp_path / "robot.txt", tmp_path / "camera.txt"
    np.savetxt(robot, np.column_stack([q, data["A"][:, :3, 3]]))
    qc = Rotation.from_matrix(data["B"][:, :3, :3]).as_quat()
    np.savetxt(camera, np.column_stack([data["B"][:, :3, 3], qc]))
    args = ["calibrate", "--robot", str(robot), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm",
            "--camera", str(camera), "--camera-format", "xyz-quat-xyzw", "--camera-unit", "mm",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand"]
    return args, truth


def test_a_quaternion_first_file_is_named_and_read_with_its_column_layout(tmp_path, capsys):
    """It used to be refused with advice to --orthonormalize, the wrong fix: the columns that do
    hold unit quaternions are named, with the layout flag that reads the file."""
    args, truth = _quaternion_first_files(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "columns 1-4 of the file hold unit quaternions" in err and "--robot-columns qw,qx,qy,qz,x,y,z" in err
    assert "orthonormalize" not in err and "layout=" not in err and err.count("\n") == 0
    assert main([*args, "--robot-columns", "qw,qx,qy,qz,x,y,z", "--json"]) == 0
    import json

    X = np.array(json.loads(capsys.readouterr().out)["X"])
    np.testing.assert_allclose(X, truth["X"], atol=1e-6)


@pytest.mark.parametrize("layout, message", [
    ("qw,qx,qy,qz,x,y", "names 6 columns but the file has 7"),
    ("qw,qx,qy,qz,x,y,y", "names 'y' twice"),
    ("qw,qx,qy,qz,x,y,w", "column 7 of the layout, 'w', is not a field of xyz-quat-xyzw"),
])
def test_a_wrong_column_layout_is_one_line(tmp_path, capsys, layout, message):
    args, _ = _quaternion_first_files(tmp_path)
    assert main([*args, "--robot-columns", layout]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and err.startswith("handeye: error: --robot:") and err.count("\n") == 0


def test_cli_errors_name_cli_flags_not_python_keywords(tmp_path, capsys):
    """A planar robot's data: the library says tz_X=..., the command line --tz-X VALUE."""
    from handeye.estimation.noise import NoiseModel
    from handeye.io.data_files import save_data
    from handeye.problems import planar

    stations, truth = planar.simulate_stations(12, seed=9, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    path = tmp_path / "scara.json"
    save_data(path, stations, truth, metadata={"units": "mm", "setup": "eye-in-hand"})
    assert main(["solve", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--tz-X VALUE" in err and "--tz-X 0" in err and "--tz-Y" in err
    assert not re.search(r"\btz_[XY]\b|=<", err)
    with pytest.raises(DegenerateDataError, match=r"tz_X=<"):  # the library keeps its own words
        handeye.solve("axyb", **stations)


def test_image_pairing_is_said_once(capsys):
    from pathlib import Path

    data = Path(handeye.__file__).parent / "data" / "rct_circle_grid"
    argv = ["calibrate", "--images", str(data / "images"), "--board", "circlegrid:10x10:25.4mm", "--robot",
            str(data / "poses"), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--setup", "eye-in-hand"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert (out + err).count("paired 15 images with the robot poses in order") == 1
    assert main([*argv, "--json"]) == 0
    out, err = capsys.readouterr()
    assert err.count("paired 15 images with the robot poses in order") == 1
