"""The input contract: inputs that used to crash, hang, allocate without bound or be silently
misread each give one of our own errors (a `handeye.HandEyeError`), in one line that names what is
wrong and what to do, through the API and through the command line (exit code 2 for bad input,
1 for a solver that cannot handle the data; no traceback), without modifying what was passed,
and without numpy RuntimeWarnings or IPOPT / CasADi text on the user's terminal.

One test (or one parametrised test) per item of the audit: tiny translations, option types,
covariance / init / casadi start options, a non-string solver name, the loaders, the CLI's sizes
and output files, lmi-sdp on translations near zero, and what reaches stdout / stderr.
"""

from __future__ import annotations

import copy
import io
import json
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

import handeye
from handeye.base.errors import HandEyeError, InputError, SolverError
from handeye.cli import main
from handeye.estimation.kronecker import MIN_TRANSLATION
from handeye.framework.options import check_int, check_positive, parse_options
from handeye.geometry.se3 import rotation_angle
from handeye.io.data_files import load_data, save_data
from handeye.io.pose_readers import poses_from_rows, read_poses
from handeye.plugins.lmi_sdp.casadi import MAX_MULTISTART
from handeye.problems.axxb import motions, simulate_stations

PROBLEMS = ("axyb", "axxb")


def simulated(problem: str, pairs: int = 10, seed: int = 1, noise=None):
    """(data, truth) of the problem's simulator, as writable copies."""
    data, truth = handeye.get_registry().problem(problem).simulate(pairs=pairs, seed=seed, noise=noise)
    return {k: np.array(v) for k, v in data.items()}, truth


def scaled(data: dict[str, np.ndarray], factor: float) -> dict[str, np.ndarray]:
    """The data with every translation multiplied by `factor` (new arrays)."""
    out = {k: np.array(v) for k, v in data.items()}
    for T in out.values():
        T[:, :3, 3] *= factor
    return out


def available(problem: str, solver: str, backend: str | None = None) -> bool:
    reg = handeye.get_registry()
    if solver not in reg.solver_names(problem):
        return False
    spec = reg.solver(solver, problem)
    return spec.unavailable_reason(backend or spec.default_backend) is None


def one_line_error(kind: type[Exception], call, *words: str) -> str:
    """Run `call` with RuntimeWarnings as errors; assert it raises `kind` (ours) in one line
    containing every one of `words` (case-insensitive); return the message."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(kind) as info:
            call()
    assert isinstance(info.value, HandEyeError)
    message = str(info.value)
    assert "\n" not in message and message.strip() == message, message
    for word in words:
        assert word.lower() in message.lower(), (word, message)
    return message


def cli(capfd, *argv) -> tuple[int, str, str]:
    """handeye's main() in this process; (exit code, stdout, stderr) as the file descriptors saw
    them (C libraries' output included)."""
    code = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    return code, out, err


def assert_cli_error(code: int, err: str, expected: int, *words: str) -> None:
    assert code == expected, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("handeye: error: "), err
    for word in words:
        assert word.lower() in err.lower(), (word, err)


# --------------------------------------------------------------------- 1. tiny translations


@pytest.mark.parametrize("problem", PROBLEMS)
@pytest.mark.parametrize("solver", ["auto", "refine", "lmi-sdp"])
def test_translations_too_small_to_compute_with_are_bad_input(problem, solver):
    """Translations of 1e-160 (squares underflow float64, weights overflow): an InputError saying
    so, for every solver (the check is in the shared validation), data untouched."""
    if not available(problem, solver):
        pytest.skip(f"{solver} not available")
    data, _ = simulated(problem)
    tiny = scaled(data, 1e-160)
    before = copy.deepcopy(tiny)
    one_line_error(InputError, lambda: handeye.solve(problem, solver=solver, **tiny),
                   "too small", f"{MIN_TRANSLATION:g}", "smaller unit")
    for k in tiny:
        np.testing.assert_array_equal(tiny[k], before[k])


@pytest.mark.parametrize("problem", PROBLEMS)
def test_translations_just_above_the_limit_solve_correctly(problem):
    """The limit leaves a margin: at 1e-90 auto still finds the rotations and the scaled
    translations (noise-free data), without a RuntimeWarning."""
    factor = 1e-90
    data, truth = simulated(problem)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        sol = handeye.solve(problem, **scaled(data, factor))
    for name, T in sol.unknowns.items():
        assert rotation_angle(T[:3, :3] @ truth[name][:3, :3].T) < 1e-8
        np.testing.assert_allclose(T[:3, 3] / factor, truth[name][:3, 3], rtol=1e-6, atol=1e-6)


def test_cli_reports_tiny_translations_as_bad_input(tmp_path, capfd):
    data, truth = simulated("axyb")
    path = save_data(tmp_path / "tiny.json", scaled(data, 1e-160))
    code, _, err = cli(capfd, "solve", path)
    assert_cli_error(code, err, 2, "too small")


# --------------------------------------------------------------------- 2. option types


def numeric_options() -> list[tuple[str, str, str, object]]:
    """(solver, problem, option, default) for every option of a registered solver whose default
    is a number (not a bool)."""
    import dataclasses

    reg = handeye.get_registry()
    return [(name, problem, f.name, f.default) for name, specs in sorted(reg.solvers.items())
            for problem, spec in specs.items() for f in dataclasses.fields(spec.options)
            if isinstance(f.default, (int, float)) and not isinstance(f.default, bool)]


def test_the_numeric_options_we_know_of_are_all_found():
    found = {(s, o) for s, _, o, _ in numeric_options()}
    assert {("refine", "tol"), ("refine", "max_iter"), ("refine", "loss_scale"), ("auto", "tol"),
            ("auto", "max_iter"), ("auto", "loss_scale"), ("iterative", "tol"), ("iterative", "max_iter")} <= found


@pytest.mark.parametrize("solver, problem, option, default", numeric_options(),
                         ids=[f"{s}:{p}:{o}" for s, p, o, _ in numeric_options()])
def test_numeric_options_refuse_text_bools_and_inf(solver, problem, option, default):
    """Every built-in numeric option: its value as text ('1e-8', 'inf'), a bool, inf and (for an
    integer option) a fraction are refused in one line naming the option; the default passes."""
    spec = handeye.get_registry().solver(solver, problem)
    bad = [str(default), "inf", True, float("inf")] + ([2.5, -1] if isinstance(default, int) else [])
    for value in bad:
        message = one_line_error(InputError, lambda: parse_options(spec.options, {option: value}, solver),
                                 f"option {option}=")
        assert ("integer" if isinstance(default, int) else "finite number") in message
    parse_options(spec.options, {option: default}, solver)


@pytest.mark.parametrize("option, value, words", [
    ("tol", "1e-8", ["tol='1e-8'", "not a str"]),
    ("tol", "inf", ["tol='inf'", "finite number"]),
    ("loss_scale", "inf", ["loss_scale='inf'", "finite number"]),
    ("max_iter", True, ["max_iter=True", "not a bool"]),
    ("max_iter", 2.5, ["max_iter=2.5", "integer"]),
    ("max_iter", -1, ["max_iter=-1", "integer >= 1"]),
])
def test_auto_and_refine_refuse_the_audits_option_values(option, value, words):
    data, _ = simulated("axyb", pairs=6)
    for solver in ("auto", "refine"):
        one_line_error(InputError, lambda: handeye.solve("axyb", solver=solver, **data, **{option: value}), *words)


def test_number_validators():
    """check_positive / check_int take numbers only: no text, no bools, finite, in range."""
    for value in (1e-8, 3, np.float32(0.5), np.int64(2)):
        check_positive("tol", value)
    for value in ("1e-8", True, np.bool_(True), None, 0, -1.0, float("nan"), float("inf"), 10**400, 1j):
        with pytest.raises(InputError, match="option tol="):
            check_positive("tol", value)
    check_positive("damping", 0, allow_zero=True)
    check_int("n", np.int64(3), minimum=1, maximum=3)
    for value in (True, 2.0, "3", 0, 4):
        with pytest.raises(InputError, match="option n="):
            check_int("n", value, minimum=1, maximum=3)
    with pytest.raises(InputError) as info:
        check_int("n", 10**400, maximum=3)
    assert len(str(info.value)) < 120  # a huge value is quoted cut, not in full


def test_cli_refuses_text_and_bool_options(capfd):
    code, _, err = cli(capfd, "solve", "--example", "--solver", "refine", "--option", "tol=inf")
    assert_cli_error(code, err, 2, "tol='inf'")
    code, _, err = cli(capfd, "solve", "--example", "--solver", "refine", "--option", "max_iter=true")
    assert_cli_error(code, err, 2, "max_iter=True")


# --------------------------------------------------------------------- 3. covariance, init, casadi starts


@pytest.mark.parametrize("value", [object(), {}, "abc", [[1.0, 2.0]], np.eye(6) * 1j,
                                   np.full((6, 6), np.nan)], ids=["object", "dict", "str", "shape", "complex", "nan"])
def test_bad_covariance_is_an_input_error(value):
    data, _ = simulated("axyb", pairs=6)
    for solver in ("auto", "refine"):
        one_line_error(InputError, lambda: handeye.solve("axyb", solver=solver, covariance=value, **data),
                       "option covariance")


@pytest.mark.parametrize("value", ["abc", np.eye(4) + 0j, {"X": 1},
                                   np.ma.masked_array(np.eye(4), mask=np.eye(4, dtype=bool))],
                         ids=["str", "complex", "dict", "masked"])
def test_bad_init_pose_is_an_input_error(value):
    data, _ = simulated("axxb", pairs=6)
    one_line_error(InputError, lambda: handeye.solve("axxb", solver="refine", init_X=value, **data), "init_X")
    one_line_error(InputError, lambda: handeye.solve("axxb", solver="refine", init={"X": value}, **data), "init_X")


@pytest.mark.parametrize("problem", PROBLEMS)
def test_casadi_start_options_are_checked_before_anything_is_allocated(problem):
    if not available(problem, "lmi-sdp", "casadi"):
        pytest.skip("casadi not available")
    data, _ = simulated(problem, pairs=6)

    def solve(**options):
        return handeye.solve(problem, solver="lmi-sdp", backend="casadi", **data, **options)

    one_line_error(InputError, lambda: solve(multistart=2, seed=-1), "seed=-1", ">= 0")
    one_line_error(InputError, lambda: solve(multistart=10**10), "multistart=10000000000", str(MAX_MULTISTART))
    one_line_error(InputError, lambda: solve(multistart=True), "multistart=True")
    assert solve(multistart=2, seed=0).status.value in ("optimal", "optimal_inaccurate")


# --------------------------------------------------------------------- 4. solver name of another type


@pytest.mark.parametrize("what", ["solver", "backend", "problem"])
def test_a_name_that_is_not_a_string_is_an_input_error(what):
    data, _ = simulated("axyb", pairs=6)
    kwargs = {"solver": "auto", "backend": None, **{what: ["auto"]}}
    problem = kwargs.pop("problem", "axyb")
    one_line_error(InputError, lambda: handeye.solve(problem, **kwargs, **data), f"{what} must be a name")


# --------------------------------------------------------------------- 5. loaders


def npy_bytes(shape: tuple[int, ...], payload: bytes = b"") -> bytes:
    """A .npy member whose header claims `shape` (float64), followed by `payload`."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buf.getvalue() + payload


def test_loaders_refuse_bad_files_in_one_line(tmp_path, capfd):
    """Deep JSON, NPZ members that are not arrays or claim more than they hold, complex arrays:
    InputError from load_data and read_poses, exit 2 from the CLI."""
    data, truth = simulated("axyb", pairs=6)
    cases = {}
    deep = tmp_path / "deep.json"
    deep.write_text('{"A": ' + "[" * 100_000 + "]" * 100_000 + "}")
    cases[deep] = "nested more than 64 levels deep"
    member = tmp_path / "member.npz"
    with zipfile.ZipFile(member, "w") as z:
        z.writestr("A.txt", "not an array")
    cases[member] = "not a .npy array"
    huge = tmp_path / "huge.npz"
    with zipfile.ZipFile(huge, "w") as z:
        z.writestr("A.npy", npy_bytes((10**12, 4, 4), b"\0" * 128))
        z.writestr("B.npy", npy_bytes((1, 4, 4), np.eye(4).tobytes()))
    cases[huge] = "claims shape (1000000000000, 4, 4)"
    complex_file = tmp_path / "complex.npz"
    np.savez(complex_file, A=data["A"] + 1j, B=data["B"])
    cases[complex_file] = "complex"
    for path, words in cases.items():
        one_line_error(InputError, lambda: load_data(path), str(path.name), words)
        code, _, err = cli(capfd, "solve", path)
        assert_cli_error(code, err, 2, words)
    for path in (deep, member, huge):  # the robot / camera pose readers share the checks
        one_line_error(InputError, lambda: read_poses(path, "matrix", unit="mm"), cases[path])


@pytest.mark.parametrize("value", ["null", "{}"])
def test_a_data_key_without_poses_is_a_bad_value_not_an_unexpected_key(tmp_path, value):
    data, truth = simulated("axyb", pairs=6)
    path = save_data(tmp_path / "ok.json", data, truth)
    doc = json.loads(path.read_text())
    doc["A"] = json.loads(value)
    path.write_text(json.dumps(doc))
    message = one_line_error(InputError, lambda: load_data(path), "A ")
    assert "unexpected" not in message
    doc["truth"]["X"] = json.loads(value)
    doc["A"] = data["A"].tolist()
    path.write_text(json.dumps(doc))
    one_line_error(InputError, lambda: load_data(path), "truth X")


def test_complex_and_masked_arrays_are_refused_everywhere_poses_are_read():
    """The imaginary part and the mask would otherwise be dropped silently."""
    data, _ = simulated("axyb", pairs=6)
    masked = np.ma.masked_array(data["A"], mask=np.zeros(data["A"].shape, dtype=bool))
    masked.mask[2, 0, 3] = True
    stations, _ = simulate_stations(6, seed=1)
    calls = {
        "solve complex": (lambda: handeye.solve("axyb", A=data["A"] + 0j, B=data["B"]), "complex"),
        "solve masked": (lambda: handeye.solve("axyb", A=masked, B=data["B"]), "1 masked entry"),
        "save masked": (lambda: save_data("never-written.json", {"A": masked, "B": data["B"]}), "masked"),
        "motions masked": (lambda: motions(np.ma.masked_array(stations["A"], mask=masked.mask), stations["B"],
                                           setup="eye-in-hand"), "masked"),
        "rows masked": (lambda: poses_from_rows(np.ma.masked_array(np.zeros((3, 6)), mask=[[1] + [0] * 5] + [[0] * 6] * 2),
                                                "fanuc-wpr", unit="mm"), "masked"),
        "solve None": (lambda: handeye.solve("axyb", A=None, B=data["B"]), "no value"),
    }
    for name, (call, words) in calls.items():
        one_line_error(InputError, call, words)
    assert not Path("never-written.json").exists()
    # a masked array without masked entries holds plain data: accepted
    sol = handeye.solve("axyb", solver="kron-lstsq", A=np.ma.masked_array(data["A"]), B=data["B"])
    assert sol.status.value == "optimal"


# --------------------------------------------------------------------- 6. CLI sizes and output files


@pytest.mark.parametrize("argv, words", [
    (["--pairs", "1000000000"], ["at most 1000000 pairs"]),
    (["--problem", "axxb", "--pairs", "100000"], ["makes 4999950000 motions", "--pairing consecutive"]),
    (["--stations", "2000000"], ["at most 1000000 stations"]),
])
def test_simulate_caps_the_size_of_a_file(tmp_path, capfd, argv, words):
    out = tmp_path / "big.npz"
    code, _, err = cli(capfd, "simulate", *argv, "-o", out)
    assert_cli_error(code, err, 2, *words)
    assert not out.exists()


def test_no_command_writes_over_an_existing_file_without_force(tmp_path, capfd):
    """simulate, solve --report, calibrate -o / --yaml / --report, compare's folders and bench
    --json keep an existing file (bytes unchanged) and stop before any work; --force overwrites."""
    existing = tmp_path / "existing.json"
    existing.write_text("keep me")

    def refused(*argv, flag):
        code, _, err = cli(capfd, *argv)
        assert_cli_error(code, err, 2, flag, "--force")
        assert existing.read_text() == "keep me"

    refused("simulate", "--pairs", "6", "-o", existing, flag="-o")
    refused("solve", "--example", "--report", _existing_copy(existing, "report.html"), flag="--report")
    # calibrate: refused before the (missing) input files are even read
    for flag in ("-o", "--yaml", "--report"):
        target = _existing_copy(existing, "result.html" if flag == "--report" else "result.out")
        refused("calibrate", "--robot", tmp_path / "missing-robot.csv", "--robot-format", "fanuc-wpr",
                "--camera", tmp_path / "missing-camera.csv", "--camera-format", "opencv-rvec",
                "--setup", "eye-in-hand", flag, target, flag=flag)
    refused("bench", "--json", existing, flag="--json")
    study = tmp_path / "study"
    study.mkdir()
    (study / "mine.csv").write_text("keep me")
    code, _, err = cli(capfd, "compare", "--solvers", "kron-lstsq", "--noise-levels", "0", "--pairs", "8",
                       "--trials", "1", "--jobs", "1", "--no-progress", "--name", "mine", "-o", study)
    assert_cli_error(code, err, 2, "mine.csv", "--force")
    assert (study / "mine.csv").read_text() == "keep me"
    stations = tmp_path / "stations.json"
    assert cli(capfd, "simulate", "--stations", "8", "--seed", "1", "-o", stations)[0] == 0
    cv = tmp_path / "cv"
    cv.mkdir()
    (cv / "stations_summary.json").write_text("keep me")
    code, _, err = cli(capfd, "compare", "--data", stations, "--solvers", "kron-lstsq", "--folds", "2",
                       "--no-progress", "-o", cv)
    assert_cli_error(code, err, 2, "stations_summary.json", "--force")

    code, out, err = cli(capfd, "simulate", "--pairs", "6", "--seed", "1", "-o", existing, "--force")
    assert code == 0, err
    assert load_data(existing)[0]["A"].shape == (6, 4, 4)


def _existing_copy(existing: Path, name: str) -> Path:
    """A second existing file, next to `existing`, with its content (an extension a flag accepts)."""
    path = existing.parent / name
    path.write_text(existing.read_text())
    return path


# --------------------------------------------------------------------- 7. lmi-sdp on translations near zero


@pytest.mark.parametrize("factor, noisy", [(0.0, False), (0.0, True), (1e-12, False)],
                         ids=["zero", "zero-noisy", "1e-12"])
def test_lmi_sdp_on_translations_near_zero_says_so_and_auto_solves_them(factor, noisy):
    if not available("axyb", "lmi-sdp"):
        pytest.skip("lmi-sdp not available")
    from handeye.estimation.noise import NoiseModel

    data, truth = simulated("axyb", noise=NoiseModel.on("B", 0.002, 0.2) if noisy else None)
    flat = scaled(data, factor)
    backends = [b for b in handeye.get_registry().solver("lmi-sdp", "axyb").backends if available("axyb", "lmi-sdp", b)]
    for backend in backends:
        if backend == "casadi" and (noisy or factor):
            continue  # exact SO(3) constraints: casadi solves these (below)
        message = one_line_error(SolverError, lambda: handeye.solve("axyb", solver="lmi-sdp", backend=backend, **flat),
                                 "translation", "near zero" if factor else "is zero", "solver 'auto'")
        assert "nan" not in message.lower()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        sol = handeye.solve("axyb", **flat)
    tol = 0.02 if noisy else 1e-8
    for name, T in sol.unknowns.items():
        assert rotation_angle(T[:3, :3] @ truth[name][:3, :3].T) < tol


def test_cli_lmi_sdp_on_pure_rotations_exits_1_in_one_line(tmp_path, capfd):
    if not available("axyb", "lmi-sdp"):
        pytest.skip("lmi-sdp not available")
    data, _ = simulated("axyb")
    path = save_data(tmp_path / "rotations.json", scaled(data, 0.0))
    code, _, err = cli(capfd, "solve", "--solver", "lmi-sdp", path)
    assert_cli_error(code, err, 1, "every translation of the data is zero", "solver 'auto'")


# --------------------------------------------------------------------- 8. nothing printed


def test_no_warning_or_ipopt_text_reaches_the_terminal(capfd):
    """The cases above that run solvers, with every warning recorded: none is a RuntimeWarning, and
    IPOPT's text (its banner, an invalid option value and its documentation) stays off stdout
    and stderr."""
    data, _ = simulated("axyb", pairs=8)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for call in (lambda: handeye.solve("axyb", **scaled(data, 1e-160)),
                     lambda: handeye.solve("axyb", solver="lmi-sdp", **scaled(data, 0.0)),
                     lambda: handeye.solve("axyb", solver="lmi-sdp", **scaled(data, 1e-4))):
            try:
                call()
            except HandEyeError:
                pass
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in caught]
    if available("axyb", "lmi-sdp", "casadi"):
        for options in ({}, {"multistart": 2, "seed": 1}):
            handeye.solve("axyb", solver="lmi-sdp", backend="casadi", **data, **options)
        one_line_error(InputError, lambda: handeye.solve("axyb", solver="lmi-sdp", backend="casadi",
                                                         ipopt_options={"tol": -1.0}, **data),
                       "ipopt rejected", "tol")
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)


def test_arrays_of_text_are_refused_not_parsed():
    """np.array of strings would convert to floats silently; the reader should have done that."""
    data, _ = simulated("axyb", pairs=6)
    with pytest.raises(handeye.InputError, match="A is an array of text") as info:
        handeye.solve("axyb", A=data["A"].astype(str), B=data["B"])
    assert "\n" not in str(info.value)
