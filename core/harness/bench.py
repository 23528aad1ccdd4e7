"""The speed benchmark (``handeye bench``): median solve time of every registered solver/backend of
a problem beside the reference rows the problem names, measured in the same run.

Generic over the registry: every solver of the problem on every available backend (third-party
plugins included) is timed through `handeye.solve` on simulated noisy data at each pair count m.
What else is timed, and on which data, the problem says in its `Problem.bench`
(`handeye.BenchSettings`): rows of registered solvers with options (e.g. OpenCV's methods through
the ``opencv`` plugin), rows calling a library directly (`BenchRow`, e.g. OpenCV's own function
on prebuilt lists: the difference is handeye's wrapper cost), the reference row the ratio column
divides by, speed targets, and the data maker (default: the problem's simulator with the same
noise on every data stack). A problem registered at run time is benchmarked the same way.

Per m and per row: one warm-up solve, then up to `repeats` timed solves taken round-robin over
the rows (so that load changes on a shared machine hit every row alike), reported as the median.
Two times per solve: "call" is the wall time of the `handeye.solve` call (what a user waits for);
"run" is `Solution.seconds`, the solver's own ``run`` only (without validation and checks); a
direct row's two times are its call. A solver whose `SolverSpec.simulate_options` ask for another
data protocol is timed on data of that protocol (same seed). A row whose single solve takes
longer than `budget` seconds is not repeated and not run at larger m; its repeats are also capped
so that one cell stays within the budget.

`run_bench` does all of it and returns a `BenchRun`; `handeye.harness.bench_report` turns one
into tables and verdicts. This is a benchmark, not a test: numbers depend on the machine and its
load.
"""

from __future__ import annotations

import dataclasses
import gc
import json
import os
import platform
import statistics
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from handeye import __version__
from handeye.base.errors import InputError, UnknownPluginError
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import Problem
from handeye.framework.problem_studies import BenchRow, BenchSettings
from handeye.framework.progress import progress_bar
from handeye.host.api import solve
from handeye.host.registry import get_registry

DEFAULT_REPEATS = 7
DEFAULT_BUDGET = 5.0


@dataclasses.dataclass(frozen=True)
class Row:
    """One timed configuration: a registered solver/backend with options, or a direct row."""

    label: str
    solver: str | None = None  # None: a direct row
    backend: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    direct: BenchRow | None = None


@dataclasses.dataclass
class Timings:
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


#: cells of a run: (row label, m) -> Timings
TimingTable = dict[tuple[str, int], Timings]


@dataclasses.dataclass
class BenchRun:
    """What `run_bench` measured: the rows in order, their cells, the rows that could not run
    here (one note each), and the settings of the run."""

    problem: str
    pairs: list[int]
    repeats: int
    budget: float
    seed: int
    noise_rot: float
    noise_trans: float
    rows: list[Row]
    cells: TimingTable
    unavailable: list[str]
    machine: str

    @property
    def settings(self) -> BenchSettings:
        return get_registry().problem(self.problem).bench

    @property
    def reference(self) -> str:
        """The label of the row the ratio column divides by (`BenchSettings.reference`, or the
        first row)."""
        return reference_label(self.settings, self.rows)


def settings_of(problem: str) -> BenchSettings:
    """The `BenchSettings` of the registered problem `problem` (an unknown name: the registry's
    error listing the known ones)."""
    return get_registry().problem(problem).bench


def min_pairs(problem: str) -> int:
    """The fewest pairs the benchmark of `problem` accepts (its `Problem.min_pairs`, at least 2)."""
    return max(get_registry().problem(problem).min_pairs, 2)


def reference_label(settings: BenchSettings, rows: Sequence[Row]) -> str:
    """The label of the reference row: the problem's, or the first row's."""
    return settings.reference or (rows[0].label if rows else "")


def reference_name(settings: BenchSettings, rows: Sequence[Row]) -> str:
    """How the targets name the reference row."""
    return settings.reference_name or reference_label(settings, rows)


def row_label(solver: str, backend: str, options: tuple[tuple[str, Any], ...] = ()) -> str:
    """"solver/backend", with " [k=v, ...]" when options are given."""
    label = f"{solver}/{backend}"
    return label + (" [" + ", ".join(f"{k}={v}" for k, v in options) + "]" if options else "")


def option_label(solver: str, options: tuple[tuple[str, Any], ...]) -> str:
    """The label of a `BenchSettings.solver_rows` row: "solver [k=v, ...]"."""
    return f"{solver} [" + ", ".join(f"{k}={v}" for k, v in options) + "]"


def build_rows(problem: str, selection: str | None = None) -> tuple[list[Row], list[str]]:
    """The rows to time and notes on rows that cannot run here.

    Order: the problem's solver rows, its direct rows, then every registered solver/backend
    (only those of `selection`, comma-separated ``solver`` or ``solver/backend``, when given),
    each followed by the rows its targets with options ask for. Solver and direct rows are timed
    whatever `selection` says.
    """
    registry = get_registry()
    settings = settings_of(problem)
    names = registry.solver_names(problem)
    wanted = _selection(problem, selection)
    rows: list[Row] = []
    unavailable: list[str] = []
    for name, options in settings.solver_rows:
        if name not in names:
            continue
        spec = registry.solver(name, problem)
        reason = spec.unavailable_reason(spec.default_backend)
        if reason:
            note = f"{name}/{spec.default_backend}: {reason}"
            unavailable += [] if note in unavailable else [note]
        else:
            rows.append(Row(option_label(name, options), name, spec.default_backend, options))
    missing: dict[str, list[str]] = {}  # reason -> labels of the direct rows giving it
    for direct in settings.direct_rows:
        reason = direct.missing()
        if reason:
            missing.setdefault(reason, []).append(direct.label)
        else:
            rows.append(Row(direct.label, direct=direct))
    unavailable += [f"{_labels(labels)}: {reason}" for reason, labels in missing.items()]
    as_rows = {name for name, _ in settings.solver_rows}
    for name in names:
        if name in as_rows:
            continue
        spec = registry.solver(name, problem)
        for backend in spec.backends:
            if wanted is not None and (name, backend) not in wanted and (name, None) not in wanted:
                continue
            reason = spec.unavailable_reason(backend)
            if reason:
                unavailable.append(f"{name}/{backend}: {reason}")
                continue
            rows.append(Row(row_label(name, backend), name, backend))
            rows += [Row(row_label(name, backend, t.options), name, backend, t.options) for t in settings.targets
                     if t.options and t.solver == name and (t.backend or spec.default_backend) == backend]
    return rows, unavailable


def _selection(problem: str, selection: str | None) -> set[tuple[str, str | None]] | None:
    """{(solver, backend or None)} of a ``--solvers`` list; None: every solver."""
    if not selection:
        return None
    registry = get_registry()
    wanted: set[tuple[str, str | None]] = set()
    for item in (s.strip() for s in selection.split(",") if s.strip()):
        name, _, backend = item.partition("/")
        spec = registry.solver(name, problem)  # unknown name: error listing the known ones
        if backend and backend not in spec.backends:
            raise UnknownPluginError("backend", backend, spec.backends, owner=f"of solver {name!r}")
        wanted.add((name, backend or None))
    return wanted


def _labels(labels: Sequence[str]) -> str:
    """Labels sharing their leading words said once: "cv2 direct TSAI, PARK"."""
    words = [label.split(" ") for label in labels]
    common = 0
    while all(len(w) > common + 1 and w[common] == words[0][common] for w in words):
        common += 1
    if len(labels) < 2 or common == 0:
        return ", ".join(labels)
    return " ".join(words[0][:common]) + " " + ", ".join(" ".join(w[common:]) for w in words)


def noise_model(problem: str, rot: float, trans: float) -> NoiseModel:
    """Gaussian noise of std `rot` (rad) and `trans` (data units) on every data stack."""
    return NoiseModel.on(tuple(get_registry().problem(problem).data_fields), rot, trans)


def bench_data(problem: str, m: int, noise: NoiseModel, seed: int,
               options: Mapping[str, Any] | None = None) -> tuple[Mapping[str, Any], Mapping[str, Any]]:
    """(data fields for `handeye.solve`, inputs of the direct rows) at m pairs: the problem's
    `BenchSettings.simulate`, or its simulator (the data fields then being both)."""
    target = get_registry().problem(problem)
    simulate = target.bench.simulate
    if simulate is not None:
        return simulate(pairs=m, seed=seed, noise=noise, **dict(options or {}))
    return _simulated(target, m, noise, seed, options)


def _simulated(problem: Problem, m: int, noise: NoiseModel, seed: int,
               options: Mapping[str, Any] | None) -> tuple[dict[str, Any], dict[str, Any]]:
    data, _ = problem.simulate(pairs=m, seed=seed, noise=noise, **dict(options or {}))
    # the data stacks as arrays; other fields (e.g. image observations) as the simulator made them
    data = {k: np.asarray(v) if k in problem.data_fields else v for k, v in data.items()}
    return data, data


def make_timer(problem: str, row: Row, data: Mapping[str, Any],
               inputs: Mapping[str, Any]) -> Callable[[], tuple[float, float]]:
    """A function doing one solve of `row` (on `data`; a direct row on `inputs`), returning
    (call seconds, run seconds). A direct row is prepared here, outside the timing."""
    if row.direct is not None:
        once = row.direct.call(inputs)

        def direct() -> tuple[float, float]:
            start = time.perf_counter()
            once()
            seconds = time.perf_counter() - start
            return seconds, seconds

        return direct
    kwargs = dict(data, solver=row.solver, backend=row.backend, **dict(row.options))

    def through_handeye() -> tuple[float, float]:
        start = time.perf_counter()
        sol = solve(problem, **kwargs)
        return time.perf_counter() - start, sol.seconds

    return through_handeye


def measure(problem: str, rows: Sequence[Row], pairs: Sequence[int], repeats: int, budget: float,
            noise: NoiseModel, seed: int, progress: bool = False) -> TimingTable:
    """Time every row at every m: warm-up, then `repeats` solves round-robin over the rows; a
    progress bar on stderr when `progress` (on a terminal)."""
    cells: TimingTable = {}
    over_budget: dict[str, float] = {}  # row label -> the m at which one solve exceeded the budget
    bar = progress_bar(len(rows) * len(pairs) * (1 + repeats), None, "solve", progress)
    registry = get_registry()
    for m in pairs:
        data, inputs = bench_data(problem, m, noise, seed)
        by_protocol: dict[str, Mapping[str, Any]] = {}  # data of the rows whose solver asks for other simulator options
        timers = {}
        for row in rows:
            cell = cells[(row.label, m)] = Timings()
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
            gc.collect()
            try:
                timer = make_timer(problem, row, row_data, inputs)
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


def run_bench(problem: str, pairs: Sequence[int] | None = None, *, repeats: int = DEFAULT_REPEATS,
              budget: float = DEFAULT_BUDGET, seed: int = 0, noise_rot: float = 0.005, noise_trans: float = 0.5,
              solvers: str | None = None, progress: bool = False) -> BenchRun:
    """Benchmark `problem`: `build_rows`, then `measure` at each m of `pairs` (default: the
    problem's `BenchSettings.pairs`). InputError for pair counts below `min_pairs`, repeats < 1,
    a budget <= 0, or when no row can be timed."""
    counts = sorted(set(pairs if pairs is not None else settings_of(problem).pairs))
    fewest = min_pairs(problem)
    if not counts or counts[0] < fewest:
        raise InputError(f"the benchmark of {problem} needs pair counts >= {fewest}, got {counts}")
    if repeats < 1:
        raise InputError(f"repeats must be >= 1, got {repeats}")
    if not budget > 0:
        raise InputError(f"the budget must be > 0 seconds, got {budget}")
    rows, unavailable = build_rows(problem, solvers)
    if not rows:
        raise InputError("nothing to time: no available solver matches the selection")
    cells = measure(problem, rows, counts, repeats, budget, noise_model(problem, noise_rot, noise_trans), seed,
                    progress=progress)
    return BenchRun(problem, counts, repeats, budget, seed, noise_rot, noise_trans, rows, cells, unavailable,
                    machine_note())


def machine_note() -> str:
    """When and where: the UTC time, the machine, its cores and load, the versions that matter."""
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


def _error_text(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())


