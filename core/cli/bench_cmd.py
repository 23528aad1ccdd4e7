"""``handeye bench``: median solve time of every registered ``axyb`` solver/backend against OpenCV.

Generic over the registry: every solver of problem ``axyb`` on every available backend (third-party
plugins included) is timed through `handeye.solve` on simulated noisy data (`PROBLEM.simulate`:
the paper's X, Y, arm poses of Sec. IV-A, Gaussian noise on A and B) at each pair count m. Per m
and per row: one warm-up solve, then ``--repeats`` timed solves taken round-robin over the rows
(so that load changes on a shared machine hit every row alike), reported as the median.

Reference rows, measured in the same run: OpenCV's SHAH and LI through the `opencv` plugin, and
``cv2.calibrateRobotWorldHandEye`` called directly on prebuilt lists (the difference is handeye's
wrapper overhead: validation, list building, SE(3) checks). The ratio column divides by the
``opencv`` plugin's SHAH time at the same m (same path through `handeye.solve`, so the ratio
compares the methods, not the wrappers); the targets also show the ratio to cv2 called directly.

Two times per solve: "call" is the wall time of the `handeye.solve` call (what a user waits for);
"run" is `Solution.seconds`, the solver's own ``run`` only (without validation and checks).
Targets (issues 2, 3, 4) are judged on the call time; the run time is printed beside it.

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

from .. import __version__
from ..api import solve
from ..errors import InputError, UnknownPluginError
from ..noise import NoiseModel
from ..registry import get_registry

NAME = "bench"
PROBLEM = "axyb"
DEFAULT_PAIRS = "10,16,100,1000,10000"
DEFAULT_REPEATS = 7
DEFAULT_BUDGET = 5.0
REFERENCE = "opencv [method=shah]"


@dataclasses.dataclass(frozen=True)
class Row:
    """One timed configuration: a solver/backend with options, or OpenCV called directly."""

    label: str
    solver: str | None = None  # None: cv2 called directly
    backend: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    cv2_method: str | None = None  # for cv2 called directly: "SHAH" or "LI"


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
    """A speed target from an issue: absolute (`seconds`) or relative to OpenCV SHAH (`ratio`)."""

    issue: str
    solver: str
    m: int
    seconds: float | None = None
    ratio: float | None = None
    backend: str | None = None  # None: the solver's default backend
    options: tuple[tuple[str, Any], ...] = ()  # timed as an extra row of the solver

    def label(self, backend: str) -> str:
        """The row label this target is judged on."""
        return row_label(self.solver, backend, self.options)

    def limit(self) -> str:
        return f"< {self.seconds * 1e3:g} ms" if self.seconds is not None else f"< {self.ratio:g}x OpenCV SHAH"


TARGETS = (
    Target("issue 2", "lmi-sdp", 16, seconds=5e-3, backend="cvxpy"),
    Target("issue 2", "kron-lstsq", 10000, seconds=20e-3),
    Target("issue 3", "iterative", 100, ratio=5.0),
    Target("issue 3", "dual-quaternion", 100, ratio=5.0),
    Target("issue 4", "so3-sdp", 16, seconds=20e-3),
    # refine's own cost: started from the closed form (~1 ms); its default start, so3-sdp, is
    # judged on its own line and inside auto's
    Target("issue 4", "refine", 16, seconds=5e-3, options=(("init", "kron-lstsq"),)),
    Target("issue 4", "auto", 16, seconds=30e-3),
    Target("issue 4", "refine", 10000, seconds=200e-3),
)


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
    parser.add_argument("--pairs", default=DEFAULT_PAIRS, metavar="LIST",
                        help=f"comma-separated pair counts m (default {DEFAULT_PAIRS})")
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
                        help="rotation noise std on A and B, rad (default 0.005)")
    parser.add_argument("--noise-trans", type=float, default=0.5, metavar="MM",
                        help="translation noise std on A and B, mm (default 0.5)")
    parser.add_argument("--json", metavar="FILE", help="also write every timing to FILE (JSON)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def parse_pairs(text: str) -> list[int]:
    try:
        pairs = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise InputError(f"--pairs expects comma-separated integers, got {text!r}") from None
    if not pairs or min(pairs) < 3:
        raise InputError(f"--pairs needs pair counts >= 3, got {text!r}")
    return sorted(set(pairs))


def build_rows(selection: str | None) -> tuple[list[Row], list[str]]:
    """The rows to time (reference rows first) and notes on registered backends that cannot run."""
    registry = get_registry()
    names = registry.solver_names(PROBLEM)
    wanted: set[tuple[str, str | None]] | None = None
    if selection:
        wanted = set()
        for item in (s.strip() for s in selection.split(",") if s.strip()):
            name, _, backend = item.partition("/")
            spec = registry.solver(name, PROBLEM)  # unknown name: error listing the known ones
            if backend and backend not in spec.backends:
                raise UnknownPluginError(f"backend of solver {name!r}", backend, spec.backends)
            wanted.add((name, backend or None))
    rows: list[Row] = []
    unavailable: list[str] = []
    if "opencv" in names and not registry.solver("opencv", PROBLEM).unavailable_reason("opencv"):
        rows += [Row(REFERENCE, "opencv", "opencv", (("method", "shah"),)),
                 Row("opencv [method=li]", "opencv", "opencv", (("method", "li"),)),
                 Row("cv2 direct SHAH", cv2_method="SHAH"), Row("cv2 direct LI", cv2_method="LI")]
    elif "opencv" in names:
        unavailable.append(f"opencv/opencv: {registry.solver('opencv', PROBLEM).unavailable_reason('opencv')}")
    for name in names:
        if name == "opencv":
            continue
        spec = registry.solver(name, PROBLEM)
        for backend in spec.backends:
            if wanted is not None and (name, backend) not in wanted and (name, None) not in wanted:
                continue
            reason = spec.unavailable_reason(backend)
            if reason:
                unavailable.append(f"{name}/{backend}: {reason}")
            else:
                rows.append(Row(row_label(name, backend), name, backend))
                rows += [Row(t.label(backend), name, backend, t.options) for t in TARGETS
                         if t.options and t.solver == name and (t.backend or spec.default_backend) == backend]
    return rows, unavailable


def make_timer(row: Row, data: dict[str, np.ndarray]) -> Callable[[], tuple[float, float]]:
    """A function doing one solve of `row` on `data`, returning (call seconds, run seconds)."""
    if row.solver is None:
        import cv2

        A, B = data["A"], data["B"]
        args = ([R for R in A[:, :3, :3]], [t for t in A[:, :3, 3:]],
                [R for R in B[:, :3, :3]], [t for t in B[:, :3, 3:]])
        flag = getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{row.cv2_method}")

        def direct() -> tuple[float, float]:
            start = time.perf_counter()
            cv2.calibrateRobotWorldHandEye(*args, method=flag)
            seconds = time.perf_counter() - start
            return seconds, seconds

        return direct
    kwargs = dict(data, solver=row.solver, backend=row.backend, **dict(row.options))

    def through_handeye() -> tuple[float, float]:
        start = time.perf_counter()
        sol = solve(PROBLEM, **kwargs)
        return time.perf_counter() - start, sol.seconds

    return through_handeye


def measure(rows: Sequence[Row], pairs: Sequence[int], repeats: int, budget: float, noise: NoiseModel,
            seed: int, progress: bool = True) -> dict[tuple[str, int], Cell]:
    """Time every row at every m: warm-up, then `repeats` solves round-robin over the rows."""
    problem = get_registry().problem(PROBLEM)
    cells: dict[tuple[str, int], Cell] = {}
    over_budget: dict[str, float] = {}  # row label -> the m at which one solve exceeded the budget
    bar = _progress(len(rows) * len(pairs) * (1 + repeats), enabled=progress)
    for m in pairs:
        data, _ = problem.simulate(pairs=m, seed=seed, noise=noise)
        data = {k: np.asarray(v) for k, v in data.items()}
        timers = {}
        for row in rows:
            cell = cells[(row.label, m)] = Cell()
            if row.label in over_budget:
                cell.note = f"skipped (>{budget:g} s)"
                bar.update(1 + repeats)
                continue
            timer = make_timer(row, data)
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
          which: str) -> str:
    """Rows x m: median `which` ("call" or "run") time and, for "call", the ratio to OpenCV SHAH."""
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
            ref = cells.get((REFERENCE, m))
            if which == "call" and ref is not None and ref.call and value is not None:
                entry += f" {value / ref.call:6.2f}x"
            if cell.note.startswith("single"):
                entry += "*"
            text += f"{entry:>{col}}"
        lines.append(text.rstrip())
    return "\n".join(lines)


def target_lines(cells: dict[tuple[str, int], Cell], pairs: Sequence[int]) -> list[str]:
    """One line per target: the measured value and PASS / MISS (or why it could not be judged)."""
    registry = get_registry()
    lines = []
    for t in TARGETS:
        spec = registry.solvers.get(t.solver, {}).get(PROBLEM)
        backend = t.backend or (spec.default_backend if spec else "?")
        label = t.label(backend)
        head = f"  {t.issue}  {label:<34} m={t.m:<6} {t.limit():<22}"
        cell = cells.get((label, t.m))
        ref = cells.get((REFERENCE, t.m))
        direct = cells.get(("cv2 direct SHAH", t.m))
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
            lines.append(f"{head} n/a: OpenCV SHAH not measured")
        else:
            ratio = cell.call / ref.call
            verdict = "PASS" if ratio < t.ratio else "MISS"
            vs_direct = f", {cell.call / direct.call:.2f}x cv2 direct" if direct and direct.call else ""
            lines.append(f"{head} {ratio:.2f}x ({fmt_seconds(cell.call)} vs {fmt_seconds(ref.call)}"
                         f"{vs_direct})  {verdict}")
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
    pairs = parse_pairs(args.pairs)
    if args.repeats < 1:
        raise InputError(f"--repeats must be >= 1, got {args.repeats}")
    if not args.budget > 0:
        raise InputError(f"--budget must be > 0 seconds, got {args.budget}")
    noise = NoiseModel.on(("A", "B"), args.noise_rot, args.noise_trans)
    rows, unavailable = build_rows(args.solvers)
    if not rows:
        raise InputError("nothing to time: no available solver matches --solvers")
    cells = measure(rows, pairs, args.repeats, args.budget, noise, args.seed, progress=not args.no_progress)

    machine = machine_note()
    print(f"handeye bench ({PROBLEM}): {machine}")
    print(f"data: PROBLEM.simulate(seed={args.seed}), noise on A and B: {args.noise_rot:g} rad, "
          f"{args.noise_trans:g} mm; median of up to {args.repeats} solves after one warm-up, "
          f"round-robin over the rows; budget {args.budget:g} s per solve")
    print()
    print("time of the handeye.solve call (validation + solver + checks); ratio to "
          f"'{REFERENCE}' at the same m; * = a single solve over the budget")
    print(table(rows, pairs, cells, "call"))
    print()
    print("solver run alone (Solution.seconds; cv2 direct rows: the cv2 call)")
    print(table(rows, pairs, cells, "run"))
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
    print()
    print("targets (judged on the handeye.solve call time):")
    targets = target_lines(cells, pairs)
    for line in targets:
        print(line)
    if args.json:
        payload = {
            "machine": machine, "pairs": pairs, "repeats": args.repeats, "seed": args.seed,
            "noise": {"rot": args.noise_rot, "trans": args.noise_trans}, "reference": REFERENCE,
            "cells": [{"row": label, "m": m, "warmup": c.warmup, "calls": c.calls, "runs": c.runs,
                       "median_call": c.call, "median_run": c.run, "note": c.note, "error": c.error}
                      for (label, m), c in cells.items()],
            "targets": targets, "unavailable": unavailable,
        }
        with open(args.json, "w") as f:
            json.dump(payload, f, indent=1)
    return 0
