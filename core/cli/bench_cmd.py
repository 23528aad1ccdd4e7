"""``handeye bench``: median solve time of every registered solver/backend of a problem beside
OpenCV, measured in the same run.

Generic over the registry: every solver of ``--problem`` (``axyb``, the default, ``axxb`` or ``axbycz``) on
every available backend (third-party plugins included) is timed through `handeye.solve` on
simulated noisy data at each pair count m. Per m and per row: one warm-up solve, then
``--repeats`` timed solves taken round-robin over the rows (so that load changes on a shared
machine hit every row alike), reported as the median.

``axyb``: data `PROBLEM.simulate` (the paper's X, Y, arm poses of Sec. IV-A, Gaussian noise on A
and B). Reference rows: OpenCV's SHAH and LI through the `opencv` plugin, and
``cv2.calibrateRobotWorldHandEye`` called directly on prebuilt lists (the difference is handeye's
wrapper overhead: validation, list building, SE(3) checks). The ratio column divides by the
``opencv`` plugin's SHAH time at the same m (same path through `handeye.solve`, so the ratio
compares the methods, not the wrappers); the targets also show the ratio to cv2 called directly.

``axxb``: the same cell's stations (`handeye.problems.axxb.simulate_stations`, Gaussian noise on
the robot poses and the camera poses), n of them, the fewest with n (n - 1) / 2 >= m; the
solvers get the motions of all pairs i < j (``pairing="all"``), and
``cv2.calibrateHandEye`` is called directly on the n stations' prebuilt lists with each of its
five methods (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS); it forms the same pairs itself, all
n (n - 1) / 2 >= m of them (21, 105, 1035 motions at m = 16, 100, 1000). The ratio column divides
by cv2 direct TSAI (OpenCV's default method) at the same m, and handeye's own classic methods are
listed beside OpenCV's implementation of the same method.

``axbycz``: two facing arms (`handeye.problems.axbycz`), Gaussian noise on A, B and C. No OpenCV
function solves A X B = Y C Z, so there are no reference rows; the ratio column divides by the
closed form ``wu`` at the same m. A solver whose `SolverSpec.simulate_options` ask for another
data protocol (``fu-dq``: one robot still at a time) is timed on data of that protocol (same seed).

Two times per solve: "call" is the wall time of the `handeye.solve` call (what a user waits for);
"run" is `Solution.seconds`, the solver's own ``run`` only (without validation and checks).
Targets (``axyb``) are judged on the call time; the run time is printed beside it.

A row whose single solve takes longer than ``--budget`` seconds is not repeated and not run at
larger m ("skipped (>5 s)"); its repeats are also capped so that one cell stays within the budget.
This is a benchmark, not a test: numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from handeye import __version__
from handeye.cli import _kinhec
from handeye.cli._common import add_force_flag, check_new_file
from handeye.estimation.noise import NoiseModel
from handeye.framework.api import solve
from handeye.framework.errors import InputError, UnknownPluginError
from handeye.framework.registry import get_registry
from handeye.geometry.se3 import inverse
from handeye.io.output_files import check_writable, new_file

NAME = "bench"
DEFAULT_REPEATS = 7
DEFAULT_BUDGET = 5.0


@dataclasses.dataclass(frozen=True)
class Row:
    """One timed configuration: a solver/backend with options, or OpenCV called directly."""

    label: str
    solver: str | None = None  # None: cv2 called directly
    backend: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    cv2_method: str | None = None  # for cv2 called directly: e.g. "SHAH" (axyb), "TSAI" (axxb)


@dataclasses.dataclass
class Cell:
    """Timings of one row at one m (seconds)."""

    warmup: float | None = None
    calls: list[float] = dataclasses.field(default_factory=list)
    runs: list[float] = dataclasses.field(default_factory=list)
    planned: int = 0
    note: str = ""  # "", "error", "skipped (>5 s)", "single solve (warm-up)"
    error: str = ""  # the exception, when note is "error"

    @property
    def call(self) -> float | None:
        return statistics.median(self.calls) if self.calls else None

    @property
    def run(self) -> float | None:
        return statistics.median(self.runs) if self.runs else None


@dataclasses.dataclass(frozen=True)
class Target:
    """A speed target: absolute (`seconds`) or relative to the problem's reference row (`ratio`)."""

    solver: str
    m: int
    seconds: float | None = None
    ratio: float | None = None
    backend: str | None = None  # None: the solver's default backend
    options: tuple[tuple[str, Any], ...] = ()  # timed as an extra row of the solver

    def label(self, backend: str) -> str:
        """The row label this target is judged on."""
        return row_label(self.solver, backend, self.options)

    def limit(self, reference: str) -> str:
        return f"< {self.seconds * 1e3:g} ms" if self.seconds is not None else f"< {self.ratio:g}x {reference}"


@dataclasses.dataclass(frozen=True)
class Setting:
    """What the benchmark of one problem times beside the registered solvers.

    reference: the row label the ratio column divides by. opencv_methods: ``method`` options of
    the `opencv` plugin timed as rows (when it serves the problem). cv2_methods: OpenCV flag
    suffixes timed by calling the OpenCV function directly. reference_name: how the targets
    name the reference.
    """

    problem: str
    default_pairs: str
    reference: str
    reference_name: str
    opencv_methods: tuple[str, ...]
    cv2_methods: tuple[str, ...]
    targets: tuple[Target, ...] = ()
    #: how the data are described in the printout (None: the axyb wording)
    data_note: str | None = None


SETTINGS = {
    "axyb": Setting(
        "axyb", "10,16,100,1000,10000", "opencv [method=shah]", "OpenCV SHAH", ("shah", "li"), ("SHAH", "LI"),
        targets=(
            Target("lmi-sdp", 16, seconds=5e-3, backend="cvxpy"),
            Target("kron-lstsq", 10000, seconds=20e-3),
            Target("iterative", 100, ratio=5.0),
            Target("dual-quaternion", 100, ratio=5.0),
            Target("so3-sdp", 16, seconds=20e-3),
            # refine's own cost: started from the closed form (~1 ms); its default start, so3-sdp,
            # is judged on its own line and inside auto's
            Target("refine", 16, seconds=5e-3, options=(("init", "kron-lstsq"),)),
            Target("auto", 16, seconds=30e-3),
            Target("refine", 10000, seconds=200e-3),
        )),
    "axxb": Setting(
        "axxb", "16,100,1000", "cv2 direct TSAI", "cv2 TSAI", ("tsai", "park", "horaud", "andreff", "daniilidis"),
        ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")),
    "axbycz": Setting(
        "axbycz", "8,16,100,1000", "wu/numpy", "wu", (), (),
        data_note="two facing arms (PROBLEM.simulate, free motion; solvers that need the phase protocol get "
                  "phase data of the same seed), noise on A, B and C"),
}
#: the targets of the default problem (``axyb``)
TARGETS = SETTINGS["axyb"].targets


def setting(problem: str) -> Setting:
    """The `Setting` of `problem`; an error listing the problems the benchmark knows otherwise."""
    get_registry().problem(problem)  # an unknown name: the registry's error
    if problem not in SETTINGS:
        raise InputError(f"handeye bench times problems {sorted(SETTINGS)}, not {problem!r}")
    return SETTINGS[problem]


def row_label(solver: str, backend: str, options: tuple[tuple[str, Any], ...] = ()) -> str:
    """"solver/backend", with " [k=v, ...]" when options are given."""
    label = f"{solver}/{backend}"
    return label + (" [" + ", ".join(f"{k}={v}" for k, v in options) + "]" if options else "")


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="time every solver against OpenCV (benchmark)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    parser.set_defaults(run=run)
    return parser


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--problem", default="axyb", choices=sorted(SETTINGS),
                        help="problem whose solvers are timed (default axyb)")
    parser.add_argument("--pairs", default=None, metavar="LIST",
                        help="comma-separated pair counts m (motions for axxb) (default: "
                             + "; ".join(f"{p} {s.default_pairs}" for p, s in SETTINGS.items()) + ")")
    parser.add_argument("--repeats", type=int, default=DEFAULT_REPEATS, metavar="N",
                        help=f"timed solves per cell after the warm-up; the median is shown (default {DEFAULT_REPEATS})")
    parser.add_argument("--solvers", metavar="LIST",
                        help="comma-separated solver or solver/backend names (default: all registered); "
                             "the OpenCV reference rows are always timed")
    parser.add_argument("--budget", type=float, default=DEFAULT_BUDGET, metavar="SECONDS",
                        help=f"per-solve time budget: slower rows are not repeated nor run at larger m "
                             f"(default {DEFAULT_BUDGET:g})")
    parser.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    parser.add_argument("--noise-rot", type=float, default=0.005, metavar="RAD",
                        help="rotation noise std on A and B (axxb: robot and camera poses; axbycz: A, B and C), rad "
                             "(default 0.005)")
    parser.add_argument("--noise-trans", type=float, default=0.5, metavar="MM",
                        help="translation noise std on A and B (axxb: robot and camera poses; axbycz: A, B and C), mm "
                             "(default 0.5)")
    parser.add_argument("--json", metavar="FILE",
                        help="also write every timing to FILE (JSON; an existing file is kept unless --force)")
    add_force_flag(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    _kinhec.add_arguments(parser)  # --kinhec DATA_DIR: KinHEC's protocol (docs/kinhec.md)


def parse_pairs(text: str, minimum: int = 3) -> list[int]:
    try:
        pairs = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise InputError(f"--pairs expects comma-separated integers, got {text!r}") from None
    if not pairs or min(pairs) < minimum:
        raise InputError(f"--pairs needs pair counts >= {minimum}, got {text!r}")
    return sorted(set(pairs))


def build_rows(selection: str | None, problem: str = "axyb") -> tuple[list[Row], list[str]]:
    """The rows to time (reference rows first) and notes on registered backends that cannot run."""
    registry = get_registry()
    bench = setting(problem)
    names = registry.solver_names(bench.problem)
    wanted: set[tuple[str, str | None]] | None = None
    if selection:
        wanted = set()
        for item in (s.strip() for s in selection.split(",") if s.strip()):
            name, _, backend = item.partition("/")
            spec = registry.solver(name, bench.problem)  # unknown name: error listing the known ones
            if backend and backend not in spec.backends:
                raise UnknownPluginError("backend", backend, spec.backends, owner=f"of solver {name!r}")
            wanted.add((name, backend or None))
    rows: list[Row] = []
    unavailable: list[str] = []
    if "opencv" in names and not registry.solver("opencv", bench.problem).unavailable_reason("opencv"):
        rows += [Row(f"opencv [method={m}]", "opencv", "opencv", (("method", m),)) for m in bench.opencv_methods]
    elif "opencv" in names:
        unavailable.append(f"opencv/opencv: {registry.solver('opencv', bench.problem).unavailable_reason('opencv')}")
    reason = _cv2_missing(bench.problem, bench.cv2_methods) if bench.cv2_methods else None
    if reason:
        unavailable.append(f"cv2 direct: {reason}")
    else:
        rows += [Row(f"cv2 direct {m}", cv2_method=m) for m in bench.cv2_methods]
    for name in names:
        if name == "opencv":
            continue
        spec = registry.solver(name, bench.problem)
        for backend in spec.backends:
            if wanted is not None and (name, backend) not in wanted and (name, None) not in wanted:
                continue
            reason = spec.unavailable_reason(backend)
            if reason:
                unavailable.append(f"{name}/{backend}: {reason}")
            else:
                rows.append(Row(row_label(name, backend), name, backend))
                rows += [Row(t.label(backend), name, backend, t.options) for t in bench.targets
                         if t.options and t.solver == name and (t.backend or spec.default_backend) == backend]
    return rows, unavailable


#: problem -> the OpenCV function timed directly and the prefix of its method flags
CV2_FUNCTIONS = {"axyb": ("calibrateRobotWorldHandEye", "CALIB_ROBOT_WORLD_HAND_EYE_"),
                 "axxb": ("calibrateHandEye", "CALIB_HAND_EYE_")}


def _cv2_missing(problem: str, methods: Sequence[str]) -> str | None:
    """Why OpenCV cannot be called directly here (cv2 missing, or without the function), or None."""
    try:
        import cv2
    except ImportError as exc:
        return f"importing cv2 failed ({exc}); pip install opencv-python-headless"
    function, prefix = CV2_FUNCTIONS[problem]
    missing = [name for name in (function, *(prefix + m for m in methods)) if not hasattr(cv2, name)]
    return f"this OpenCV ({cv2.__version__}) has no cv2.{', cv2.'.join(missing)}" if missing else None


def bench_data(problem: str, m: int, noise: NoiseModel, seed: int,
               simulate_options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], tuple[list[np.ndarray], ...]]:
    """(data for `handeye.solve`, the argument lists of the direct OpenCV call) at m pairs.

    ``axyb``: `PROBLEM.simulate(pairs=m)`; OpenCV gets A as world2cam and B as base2gripper
    (docs/conventions.md). ``axxb``: the fewest stations n with n (n - 1) / 2 >= m
    (`simulate_stations`, noise "A" on the robot poses, "B" on the camera poses), the solvers get
    the motions of every pair i < j (n (n - 1) / 2 >= m of them), OpenCV the n stations:
    gripper2base = the robot poses T_base_flange, target2cam = T_cam_target (it forms the same
    pairs itself), so both solve the same data.
    """
    if problem == "axxb":
        from handeye.problems.axxb import relative_motions, simulate_stations

        n = int(np.ceil((1 + np.sqrt(1 + 8 * m)) / 2))
        stations, _ = simulate_stations(n, seed=seed, noise=noise)
        A, B = relative_motions(stations["A"], stations["B"], "all")
        robot, camera = stations["A"], inverse(stations["B"])
        return {"A": A, "B": B}, _lists(robot, camera)
    data, _ = get_registry().problem(problem).simulate(pairs=m, seed=seed, noise=noise, **(simulate_options or {}))
    data = {k: np.asarray(v) if k in ("A", "B", "C") else v for k, v in data.items()}  # images stay observations
    return data, _lists(data["A"], data["B"])


def _lists(P: np.ndarray, Q: np.ndarray) -> tuple[list[np.ndarray], ...]:
    """Rotation and translation lists (R_P, t_P, R_Q, t_Q) as OpenCV's calibration functions take them."""
    return ([R for R in np.ascontiguousarray(P[:, :3, :3])], [t for t in np.ascontiguousarray(P[:, :3, 3:])],
            [R for R in np.ascontiguousarray(Q[:, :3, :3])], [t for t in np.ascontiguousarray(Q[:, :3, 3:])])


def make_timer(row: Row, data: dict[str, np.ndarray], problem: str = "axyb",
               cv2_args: tuple[list[np.ndarray], ...] = ()) -> Callable[[], tuple[float, float]]:
    """A function doing one solve of `row` on `data` (OpenCV called directly: on `cv2_args`),
    returning (call seconds, run seconds)."""
    if row.solver is None:
        import cv2

        function_name, prefix = CV2_FUNCTIONS[problem]
        function, flag = getattr(cv2, function_name), getattr(cv2, prefix + str(row.cv2_method))

        def direct() -> tuple[float, float]:
            start = time.perf_counter()
            function(*cv2_args, method=flag)
            seconds = time.perf_counter() - start
            return seconds, seconds

        return direct
    kwargs = dict(data, solver=row.solver, backend=row.backend, **dict(row.options))

    def through_handeye() -> tuple[float, float]:
        start = time.perf_counter()
        sol = solve(problem, **kwargs)
        return time.perf_counter() - start, sol.seconds

    return through_handeye


def measure(rows: Sequence[Row], pairs: Sequence[int], repeats: int, budget: float, noise: NoiseModel,
            seed: int, progress: bool = True, problem: str = "axyb") -> dict[tuple[str, int], Cell]:
    """Time every row at every m: warm-up, then `repeats` solves round-robin over the rows."""
    cells: dict[tuple[str, int], Cell] = {}
    over_budget: dict[str, float] = {}  # row label -> the m at which one solve exceeded the budget
    bar = _progress(len(rows) * len(pairs) * (1 + repeats), enabled=progress)
    registry = get_registry()
    for m in pairs:
        data, cv2_args = bench_data(problem, m, noise, seed)
        by_protocol: dict[str, dict[str, np.ndarray]] = {}  # data of the rows whose solver asks for other simulator options
        timers = {}
        for row in rows:
            cell = cells[(row.label, m)] = Cell()
            if row.label in over_budget:
                cell.note = f"skipped (>{budget:g} s)"
                bar.update(1 + repeats)
                continue
            row_data = data
            wanted = dict(registry.solver(row.solver, problem).simulate_options) if row.solver else {}
            if wanted:
                key = json.dumps(wanted, sort_keys=True)
                if key not in by_protocol:
                    by_protocol[key] = bench_data(problem, m, noise, seed, wanted)[0]
                row_data = by_protocol[key]
            timer = make_timer(row, row_data, problem, cv2_args)
            gc.collect()
            try:
                cell.warmup, warmup_run = timer()
            except Exception as exc:  # noqa: BLE001 -- a failing plugin must not stop the benchmark
                cell.note, cell.error = "error", _error_text(exc)
                bar.update(1 + repeats)
                continue
            bar.update(1)
            if cell.warmup > budget:
                over_budget[row.label] = m
                cell.calls, cell.runs, cell.note = [cell.warmup], [warmup_run], "single solve (warm-up)"
                bar.update(repeats)
                continue
            cell.planned = max(1, min(repeats, int(budget / max(cell.warmup, 1e-9))))
            bar.update(repeats - cell.planned)
            timers[row.label] = timer
        for r in range(repeats):
            for row in rows:
                cell = cells[(row.label, m)]
                if row.label in timers and r < cell.planned:
                    try:
                        call, run_seconds = timers[row.label]()
                    except Exception as exc:  # noqa: BLE001 -- as in the warm-up
                        cell.note, cell.error, cell.calls, cell.runs = "error", _error_text(exc), [], []
                        del timers[row.label]
                        continue
                    cell.calls.append(call)
                    cell.runs.append(run_seconds)
                    bar.update(1)
    bar.close()
    return cells


def _error_text(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def _progress(total: int, enabled: bool) -> Any:
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm is optional: no bar
        enabled = False
    if not enabled:
        class _NoBar:
            def update(self, n: int = 1) -> None: ...
            def close(self) -> None: ...
        return _NoBar()
    return tqdm(total=total, file=sys.stderr, unit="solve", leave=False, disable=None)


def fmt_seconds(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    ms = seconds * 1e3
    return f"{ms:.3g} ms" if ms < 1000 else f"{seconds:.3g} s"


def table(rows: Sequence[Row], pairs: Sequence[int], cells: dict[tuple[str, int], Cell],
          which: str, reference: str = SETTINGS["axyb"].reference) -> str:
    """Rows x m: median `which` ("call" or "run") time and, for "call", the ratio to the
    `reference` row."""
    width = max(len(r.label) for r in rows) + 2
    col = 20
    lines = [f"{'solver/backend [options]':<{width}}" + "".join(f"{'m=' + str(m):>{col}}" for m in pairs)]
    for row in rows:
        text = f"{row.label:<{width}}"
        for m in pairs:
            cell = cells[(row.label, m)]
            value = getattr(cell, which)
            if cell.note and value is None:
                text += f"{cell.note[:col - 2]:>{col}}"
                continue
            entry = fmt_seconds(value)
            ref = cells.get((reference, m))
            if which == "call" and ref is not None and ref.call and value is not None:
                entry += f" {value / ref.call:6.2f}x"
            if cell.note.startswith("single"):
                entry += "*"
            text += f"{entry:>{col}}"
        lines.append(text.rstrip())
    return "\n".join(lines)


def target_lines(cells: dict[tuple[str, int], Cell], pairs: Sequence[int], problem: str = "axyb") -> list[str]:
    """One line per target: what it is, the measured value and PASS / MISS (or why it could not
    be judged)."""
    registry = get_registry()
    bench = setting(problem)
    lines = []
    for t in bench.targets:
        spec = registry.solvers.get(t.solver, {}).get(problem)
        backend = t.backend or (spec.default_backend if spec else "?")
        label = t.label(backend)
        head = f"  target: {label:<34} m={t.m:<6} {t.limit(bench.reference_name):<22}"
        cell = cells.get((label, t.m))
        ref = cells.get((bench.reference, t.m))
        direct = cells.get((f"cv2 direct {bench.cv2_methods[0]}", t.m))
        if spec is None:
            lines.append(f"{head} n/a: solver {t.solver!r} is not registered")
        elif backend not in spec.backends:
            lines.append(f"{head} n/a: {t.solver!r} has no backend {backend!r}")
        elif t.m not in pairs:
            lines.append(f"{head} n/a: m={t.m} not measured (add it to --pairs)")
        elif cell is None:
            lines.append(f"{head} n/a: not measured ({spec.unavailable_reason(backend) or 'not selected'})")
        elif cell.call is None:
            lines.append(f"{head} MISS: {(cell.error or cell.note)[:80]}")
        elif t.seconds is not None:
            verdict = "PASS" if cell.call < t.seconds else "MISS"
            if verdict == "MISS" and cell.run is not None and cell.run < t.seconds:
                verdict += " (solver run alone would pass)"
            lines.append(f"{head} {fmt_seconds(cell.call)} (run {fmt_seconds(cell.run)})  {verdict}")
        elif ref is None or not ref.call:
            lines.append(f"{head} n/a: {bench.reference_name} not measured")
        else:
            ratio = cell.call / ref.call
            verdict = "PASS" if ratio < t.ratio else "MISS"
            vs_direct = (f", {cell.call / direct.call:.2f}x cv2 direct"
                         if direct and direct.call and direct is not ref else "")
            lines.append(f"{head} {ratio:.2f}x ({fmt_seconds(cell.call)} vs {fmt_seconds(ref.call)}"
                         f"{vs_direct})  {verdict}")
    return lines


def same_method_lines(rows: Sequence[Row], cells: dict[tuple[str, int], Cell], pairs: Sequence[int],
                      problem: str) -> list[str]:
    """For every registered solver named like one of the directly called OpenCV methods (``axxb``:
    tsai, park, ...): its call time over OpenCV's time of the same method, per m."""
    lines = []
    for method in setting(problem).cv2_methods:
        name = method.lower()
        row = next((r for r in rows if r.solver == name and not r.options), None)
        if row is None:
            continue
        ratios = []
        for m in pairs:
            ours, theirs = cells.get((row.label, m)), cells.get((f"cv2 direct {method}", m))
            if ours and theirs and ours.call and theirs.call:
                ratios.append(f"m={m}: {ours.call / theirs.call:.2f}x ({fmt_seconds(ours.call)} vs {fmt_seconds(theirs.call)})")
            else:
                ratios.append(f"m={m}: -")
        lines.append(f"  {row.label:<20} vs cv2 direct {method:<11} " + ", ".join(ratios))
    return lines


def machine_note() -> str:
    load = ""
    if hasattr(os, "getloadavg"):
        load = ", load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())
    versions = [f"python {platform.python_version()}", f"numpy {np.__version__}", f"handeye {__version__}"]
    try:
        import cv2

        versions.append(f"opencv {cv2.__version__}")
    except ImportError:
        pass
    return (f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {platform.machine()}, "
            f"{os.cpu_count()} cores{load}; {', '.join(versions)}")


def run(args: argparse.Namespace) -> int:
    if _kinhec.requested(args):
        return _kinhec.run(args)
    bench = setting(args.problem)
    problem = get_registry().problem(bench.problem)
    pairs = parse_pairs(args.pairs or bench.default_pairs, max(problem.min_pairs, 2))
    if args.repeats < 1:
        raise InputError(f"--repeats must be >= 1, got {args.repeats}")
    if not args.budget > 0:
        raise InputError(f"--budget must be > 0 seconds, got {args.budget}")
    check_new_file("--json", args.json, args.force)
    if args.json:
        check_writable("--json", args.json)  # before the benchmark, not after it
    noise = NoiseModel.on(tuple(problem.data_fields), args.noise_rot, args.noise_trans)
    rows, unavailable = build_rows(args.solvers, bench.problem)
    if not rows:
        raise InputError("nothing to time: no available solver matches --solvers")
    cells = measure(rows, pairs, args.repeats, args.budget, noise, args.seed, progress=not args.no_progress,
                    problem=bench.problem)

    machine = machine_note()
    print(f"handeye bench ({bench.problem}): {machine}")
    if bench.data_note is not None:
        print(f"data: {bench.data_note}: {args.noise_rot:g} rad, {args.noise_trans:g} mm (seed {args.seed})")
    elif bench.problem == "axxb":
        print(f"data: simulate_stations(seed={args.seed}), noise on the robot and camera poses: "
              f"{args.noise_rot:g} rad, {args.noise_trans:g} mm; solvers: the motions of all pairs "
              "of the fewest stations giving at least m; cv2 direct: those stations (it forms the same pairs)")
    else:
        print(f"data: PROBLEM.simulate(seed={args.seed}), noise on A and B: {args.noise_rot:g} rad, "
              f"{args.noise_trans:g} mm")
    print(f"median of up to {args.repeats} solves after one warm-up, round-robin over the rows; "
          f"budget {args.budget:g} s per solve")
    print()
    print("time of the handeye.solve call (validation + solver + checks); ratio to "
          f"'{bench.reference}' at the same m; * = a single solve over the budget")
    print(table(rows, pairs, cells, "call", bench.reference))
    print()
    print("solver run alone (Solution.seconds; cv2 direct rows: the cv2 call)")
    print(table(rows, pairs, cells, "run", bench.reference))
    errors = {(label, m): c.error for (label, m), c in cells.items() if c.error}
    if errors:
        print()
        print("errors (the row's solve raised; first 200 characters):")
        for (label, m), text in errors.items():
            print(f"  {label} at m={m}: {text[:200]}")
    if unavailable:
        print()
        print("not timed (unavailable here):")
        for note in unavailable:
            print(f"  {note}")
    same = same_method_lines(rows, cells, pairs, bench.problem)
    if same:
        print()
        print("handeye's implementation of a classic method beside OpenCV's (call time ratio):")
        for line in same:
            print(line)
    targets = target_lines(cells, pairs, bench.problem)
    if targets:
        print()
        print("targets (judged on the handeye.solve call time):")
        for line in targets:
            print(line)
    if args.json:
        payload = {
            "machine": machine, "problem": bench.problem, "pairs": pairs, "repeats": args.repeats, "seed": args.seed,
            "noise": {"rot": args.noise_rot, "trans": args.noise_trans}, "reference": bench.reference,
            "cells": [{"row": label, "m": m, "warmup": c.warmup, "calls": c.calls, "runs": c.runs,
                       "median_call": c.call, "median_run": c.run, "note": c.note, "error": c.error}
                      for (label, m), c in cells.items()],
            "targets": targets, "same_method": same, "unavailable": unavailable,
        }
        with new_file(args.json, force=args.force, flag="--json") as f:
            json.dump(payload, f, indent=1)
    return 0
