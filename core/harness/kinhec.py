"""``handeye bench --kinhec DATA_DIR``: handeye's solvers run by KinHEC's own benchmark protocol.

KinHEC (PyPI ``kinhec``, MIT) is the public benchmark of hand-eye / robot-world calibration:
simulated pose streams of 13 arm models, eye-in-hand and eye-to-hand, in tracks (``noise``,
``motion``, ``temporal``, ``outliers``, ``monocular``, ``robot_error``, ``pnp``, ``mixed``) and
11 reference solvers. Its documented extension point is the dict ``kinhec.benchmark.SOLVERS`` of
callables ``f(data, rng) -> {"X": (4, 4), "Y": (4, 4) or None}``, where data is the protocol's
``(A_abs, B_abs, A_rel, B_rel)``: the absolute keyframe poses (``A_i X = Y B_i``, eye-in-hand
``A_i = T_base_ee``, ``B_i = inv(T_cam_target)``: handeye's own conventions, metres) and the
consecutive keyframe motions (``A_i X = X B_i``). Running our solvers through KinHEC's
``run_benchmark`` (rather than re-implementing its protocol) is what makes the figures comparable
with everyone else's.

This module registers the solvers and runs the benchmark (docs/kinhec.md):

- `handeye_entries`: every solver of problem ``axyb`` on its default backend (``auto`` first),
  registered as ``handeye:<name>`` and given the absolute keyframe poses, and every solver of
  ``axxb``, registered as ``handeye-axxb:<name>`` and given the consecutive motions. A solver
  that needs more than poses (``reprojection``: board images) is left out, found by one probe
  solve on simulated data, which also warms up the solvers' imports (cvxpy, Clarabel) so that
  KinHEC's first timed sequence does not pay for them.
- `register_solvers` puts them in ``SOLVERS`` (and ``SOLVER_DOCS``, which KinHEC's protocol.json
  reads); `run_kinhec` runs ``run_benchmark`` with them, then has handeye.harness.kinhec_report
  write, beside KinHEC's own outputs (results.csv, leaderboard.md, ...), handeye's head-to-head
  of ``handeye:auto`` against KinHEC's best AX=YB method ``shah+lm`` per sequence and a
  per-track summary of every solver, as markdown and CSV.
The --kinhec flags of ``handeye bench`` and its printing are in handeye.cli._kinhec.

Its siblings: handeye.harness.kinhec_report (the tables) and handeye.harness.kinhec_fixtures
(`export_fixture`: one sequence's keyframe data as a regression fixture, tests/data/kinhec/).

Statuses. KinHEC records a solve that raises as a failed row (``ok`` False, ``error`` the
exception) and every finite answer as a success. A handeye solve that returns a status other than
``optimal`` (``not_converged``, ``unreliable``, ...) still returns its answer to KinHEC, so that
the leaderboard compares like with like (KinHEC's references have no status and always answer),
and its status goes into extra columns (``handeye_status``, ``handeye_note``) of results.csv and
of the head-to-head CSV; the per-track summary shows the share of *usable* answers (status
``optimal``, ``optimal_inaccurate`` or ``uncertified``) beside KinHEC's success rate. The status
is captured by wrapping ``kinhec.benchmark.evaluate_sequence`` for the run (the solver callable
does not see which sequence it solves), and both the wrapper and the registrations are removed
afterwards.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import importlib
import math
import multiprocessing
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from handeye.base.errors import (
    DegenerateDataError,
    HandEyeError,
    InputError,
    SolverError,
)
from handeye.harness.kinhec_report import (
    AUTO,
    HANDEYE_FILES,
    REFERENCE,
    SCALE_SUFFIX,
    KinhecRun,
    auto_vs_best,
    head_to_head,
    is_handeye,
    kinhec_prefix,
    machine_line,
    track_summary,
    write_outputs,
)

#: the oldest KinHEC whose protocol this module follows
MIN_VERSION = (1, 1)
INSTALL_HINT = 'pip install "handeye[kinhec]"'
#: what KinHEC's run_benchmark writes to the output folder (handeye's tables add `HANDEYE_FILES`)
KINHEC_FILES = ("results.csv", "results.parquet", "leaderboard.md", "summary.json", "protocol.json")
#: pose pairs of the probe solve (simulated, noise-free) that finds the solvers able to run
PROBE_PAIRS = 12


# ---------------------------------------------------------------------------------------------
# KinHEC and the solvers registered into it
# ---------------------------------------------------------------------------------------------

def import_kinhec() -> ModuleType:
    """``kinhec.benchmark``; InputError (one line, naming the pip extra) when KinHEC is missing or
    older than `MIN_VERSION`."""
    try:
        kinhec = importlib.import_module("kinhec")
        benchmark = importlib.import_module("kinhec.benchmark")
    except ImportError as exc:
        raise InputError(f"--kinhec needs the kinhec package, which cannot be imported here ({exc}); "
                         f"{INSTALL_HINT}") from None
    version = str(getattr(kinhec, "__version__", "0"))
    if _version_tuple(version) < MIN_VERSION:
        raise InputError(f"kinhec {version} is older than {'.'.join(map(str, MIN_VERSION))}, whose benchmark "
                         f"protocol --kinhec follows; pip install -U \"handeye[kinhec]\"")
    for name in ("SOLVERS", "run_benchmark"):
        if not hasattr(benchmark, name):
            raise InputError(f"kinhec {version} has no kinhec.benchmark.{name}; pip install -U \"handeye[kinhec]\"")
    return benchmark


def _version_tuple(text: str) -> tuple[int, ...]:
    parts = []
    for part in text.split(".")[:3]:
        digits = "".join(c for c in part if c.isdigit())
        parts.append(int(digits) if digits else 0)
    return tuple(parts)


@dataclasses.dataclass(frozen=True)
class Entry:
    """One handeye solver as KinHEC sees it.

    name: the KinHEC solver name (``handeye:auto``, ``handeye-axxb:park``, ``handeye:auto+scale``).
    problem: ``axyb`` (given the absolute keyframe poses) or ``axxb`` (given the consecutive
    motions). solver, backend, camera_scale: what `handeye.solve` is called with ("unknown": the
    scale-aware variant, ``+scale``, like KinHEC's ``andreff_scale``). doc: the line of KinHEC's
    protocol.json.
    """

    name: str
    problem: str
    solver: str
    backend: str
    doc: str
    camera_scale: str = "known"


def handeye_entries(probe: bool = True) -> tuple[list[Entry], list[str]]:
    """The handeye solvers to register (axyb ones first, ``auto`` first of each problem) and one
    note per solver left out (backend unavailable, or, when `probe`, an InputError on simulated
    poses: it needs other inputs).

    The probe solves a noise-free simulated problem once with each solver; it also imports what
    each solver needs, so the timings KinHEC takes do not include first-call import costs.
    """
    from handeye.host.api import solve
    from handeye.host.registry import get_registry

    registry = get_registry()
    entries: list[Entry] = []
    skipped: list[str] = []
    for problem, spec_problem in registry.problems.items():
        form = kinhec_form(spec_problem)
        if form is None:
            continue
        prefix = kinhec_prefix(problem, registry.default_problem())
        data = None
        if probe:
            simulated, _ = spec_problem.simulate(pairs=PROBE_PAIRS, seed=0)
            data = {field: simulated[field] for field in spec_problem.data_fields}
        for name in sorted(registry.solver_names(problem), key=lambda n: (n != "auto", n)):
            spec = registry.solver(name, problem)
            backend = spec.default_backend
            reason = spec.unavailable_reason(backend)
            if reason:
                skipped.append(f"{prefix}{name}: {reason}")
                continue
            if data is not None:
                try:
                    solve(problem, solver=name, backend=backend, **data)
                except DegenerateDataError:
                    pass  # a data verdict on the probe, not a missing input
                except InputError as exc:
                    skipped.append(f"{prefix}{name}: {_one_line(exc)}")
                    continue
                except HandEyeError:
                    pass  # a solver failure: KinHEC records those per sequence
            what = "absolute keyframe poses" if form == "stations" else "consecutive keyframe motions"
            doc = f"handeye {name} ({backend}) on the {what} ({spec_problem.equation or problem}): {spec.summary}"
            entries.append(Entry(prefix + name, problem, name, backend, doc))
            if spec.camera_scale_mode:  # its scale-aware variant, for cameras known up to scale
                entries.append(Entry(f"{prefix}{name}{SCALE_SUFFIX}", problem, name, backend,
                                     f"{doc}; the camera's scale unknown (camera_scale='unknown')", "unknown"))
    return entries, skipped


#: the handeye outcome of the last solve of each registered solver in this process, read by the
#: evaluate_sequence wrapper (`_with_outcomes`) into the rows of the sequence just solved
_OUTCOMES: dict[str, dict[str, Any]] = {}


def kinhec_form(problem: Any) -> str | None:
    """Which of KinHEC's two data forms `problem` (a `handeye.Problem`) solves: "stations" (the
    absolute keyframe poses, as A, B: a problem read from a cell's stations one pair per station)
    or "motions" (the consecutive keyframe motions: a problem read from motions between stations),
    both in KinHEC's eye-in-hand conventions, which are handeye's; None: neither (other data
    fields, no station reader, or unknowns that are not the cell's X and Y)."""
    reader = problem.station_reader
    if reader is None or tuple(problem.data_fields) != ("A", "B"):
        return None
    cell = _cell_names(problem)
    if "X" not in cell.values() or not set(cell.values()) <= {"X", "Y"}:
        return None
    return "motions" if reader.pairing else "stations"


def _cell_names(problem: Any) -> Mapping[str, str]:
    """The problem's unknowns -> the cell's (X, Y of AX=YB), eye-in-hand (`StationReader.cell_truth`)."""
    reader = problem.station_reader
    return reader.cell_truth["eye-in-hand"] if reader.cell_truth else {u: u for u in problem.unknowns}


def cell_answer(problem: Any, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray | None]:
    """KinHEC's answer {"X": hand-eye, "Y": robot-world or None} from `problem`'s unknowns."""
    answer: dict[str, np.ndarray | None] = {"X": None, "Y": None}
    for unknown, name in _cell_names(problem).items():
        answer[name] = np.array(unknowns[unknown])
    return answer


def adaptor(entry: Entry) -> Callable[[Sequence[np.ndarray], Any], dict[str, Any]]:
    """The KinHEC solver callable of `entry`: ``f(data, rng) -> {"X", "Y"}``.

    data = (A_abs, B_abs, A_rel, B_rel), each (n, 4, 4), translations in metres. An exception of
    `handeye.solve` propagates (KinHEC records the row as failed); any returned answer is given
    back whatever its status, and the status, the solver's own time and the first warning are
    kept for the results' ``handeye_*`` columns (module docstring).
    """

    def run(data: Sequence[np.ndarray], rng: Any = None) -> dict[str, Any]:
        from handeye.host.api import solve
        from handeye.host.registry import get_registry

        A_abs, B_abs, A_rel, B_rel = data
        problem = get_registry().problem(entry.problem)
        A, B = (A_abs, B_abs) if kinhec_form(problem) == "stations" else (A_rel, B_rel)
        try:
            sol = solve(entry.problem, solver=entry.solver, backend=entry.backend, A=A, B=B,
                        camera_scale=entry.camera_scale)
        except Exception as exc:
            _OUTCOMES[entry.name] = {"handeye_status": "raised", "handeye_seconds": math.nan,
                                     "handeye_note": f"{type(exc).__name__}: {_one_line(exc)}"[:300]}
            raise
        _OUTCOMES[entry.name] = {"handeye_status": sol.status.value, "handeye_seconds": sol.seconds,
                                 "handeye_note": (sol.warnings[0] if sol.warnings else "")[:300]}
        return cell_answer(problem, sol.unknowns)

    run.__name__ = run.__qualname__ = f"handeye_{entry.problem}_{entry.solver.replace('-', '_')}"
    return run


def register_solvers(entries: Sequence[Entry] | None = None, benchmark: ModuleType | None = None) -> list[str]:
    """Register `entries` (default: `handeye_entries()`) into KinHEC's ``SOLVERS`` (and
    ``SOLVER_DOCS``); return their names. For use from Python::

        from handeye.harness.kinhec import register_solvers
        import kinhec.benchmark
        names = register_solvers()
        kinhec.benchmark.run_benchmark("data/smoke", solver_names=names + ["shah+lm"])

    (statuses are captured only by `run_kinhec`, which also removes the registrations).
    """
    benchmark = benchmark if benchmark is not None else import_kinhec()
    entries = list(entries) if entries is not None else handeye_entries()[0]
    docs = getattr(benchmark, "SOLVER_DOCS", None)
    for entry in entries:
        benchmark.SOLVERS[entry.name] = adaptor(entry)
        if isinstance(docs, dict):
            docs[entry.name] = entry.doc
    return [entry.name for entry in entries]


def _with_outcomes(evaluate: Callable[..., list[dict[str, Any]]]) -> Callable[..., list[dict[str, Any]]]:
    """``kinhec.benchmark.evaluate_sequence`` that adds the handeye outcome of each registered
    solver to its row (KinHEC writes every key of a row as a column of results.csv)."""

    @functools.wraps(evaluate)
    def evaluate_sequence(*args: Any, **kwargs: Any) -> list[dict[str, Any]]:
        _OUTCOMES.clear()
        rows = evaluate(*args, **kwargs)
        for row in rows:
            name = row.get("solver")
            if is_handeye(name):
                row.update(_OUTCOMES.get(name, {"handeye_status": "not run", "handeye_seconds": math.nan,
                                                "handeye_note": str(row.get("error", ""))}))
        _OUTCOMES.clear()
        return rows

    return evaluate_sequence


@contextlib.contextmanager
def registered(benchmark: ModuleType, entries: Sequence[Entry]) -> Iterator[list[str]]:
    """`register_solvers` and the status-capturing ``evaluate_sequence`` for the duration of the
    block; KinHEC's SOLVERS, SOLVER_DOCS and evaluate_sequence are restored afterwards."""
    solvers = dict(benchmark.SOLVERS)
    docs = getattr(benchmark, "SOLVER_DOCS", None)
    saved_docs = dict(docs) if isinstance(docs, dict) else None
    evaluate = getattr(benchmark, "evaluate_sequence", None)
    try:
        names = register_solvers(entries, benchmark)
        if evaluate is not None:
            benchmark.evaluate_sequence = _with_outcomes(evaluate)
        yield names
    finally:
        benchmark.SOLVERS.clear()
        benchmark.SOLVERS.update(solvers)
        if saved_docs is not None:
            docs.clear()
            docs.update(saved_docs)
        if evaluate is not None:
            benchmark.evaluate_sequence = evaluate


def select_solvers(selection: str | None, available: Sequence[str], references: Sequence[str]) -> list[str]:
    """The KinHEC solver names to run, from ``--solvers`` (comma-separated KinHEC names, or the
    groups ``handeye``, ``handeye-axxb``, ``kinhec``); default all. `AUTO` and `REFERENCE` are
    always run (the head-to-head needs them)."""
    groups: dict[str, list[str]] = {"kinhec": list(references)}
    for name in available:
        if is_handeye(name):
            groups.setdefault(name.split(":", 1)[0], []).append(name)
    if not selection:
        names = list(available)
    else:
        names = []
        for item in (s.strip() for s in selection.split(",") if s.strip()):
            if item in groups:
                names += groups[item]
            elif item in available:
                names.append(item)
            else:
                raise InputError(f"--solvers: {item!r} is not a KinHEC solver here; give names among "
                                 f"{', '.join(available)}, or the groups {', '.join(groups)}")
    for name in (REFERENCE, AUTO):
        if name not in available:
            raise InputError(f"KinHEC solver {name!r} is not registered (known: {', '.join(available)}); "
                             "the head-to-head needs it")
        if name not in names:
            names.insert(0, name)
    return list(dict.fromkeys(names))


# ---------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------

def run_kinhec(data_dir: str | Path, out_dir: str | Path | None = None, *, tracks: Sequence[str] | None = None,
               max_sequences: int | None = None, solvers: str | None = None, workers: int = 1,
               progress: bool = True, force: bool = False) -> KinhecRun:
    """Run KinHEC's protocol (``kinhec.benchmark.run_benchmark``) on the dataset `data_dir` with
    handeye's solvers registered beside KinHEC's references; write KinHEC's outputs and handeye's
    (`HANDEYE_FILES`) to `out_dir` (default ``<data_dir>/benchmarks``, KinHEC's default).

    tracks: KinHEC tracks to run (default all); max_sequences: a random subset of that many
    (KinHEC's sampling, seed 0); solvers: see `select_solvers`; workers: KinHEC's process pool
    (needs the ``fork`` start method, which hands the registrations to the workers).
    Raises InputError for a bad folder, flag or a missing KinHEC; SolverError when KinHEC's run
    itself fails.
    """
    benchmark = import_kinhec()
    root = Path(data_dir)
    if not (root / "sequences.parquet").is_file():
        raise InputError(f"--kinhec {str(root)!r}: not a KinHEC dataset folder (no sequences.parquet); make one "
                         f"with: kinhec generate --tier smoke --out {root}")
    out = Path(out_dir) if out_dir is not None else root / "benchmarks"
    existing = [name for name in KINHEC_FILES + HANDEYE_FILES if (out / name).exists()]
    if existing and not force:
        raise InputError(f"--kinhec-out {str(out)!r} already holds {existing[0]!r} from an earlier run; pass --force "
                         "to overwrite its results, or name another folder with --kinhec-out")
    if workers < 1:
        raise InputError(f"--workers must be >= 1, got {workers}")
    if workers > 1 and multiprocessing.get_start_method(allow_none=False) != "fork":
        raise InputError(f"--workers {workers} needs the 'fork' start method (KinHEC's workers must inherit the "
                         f"registered solvers), not {multiprocessing.get_start_method()!r}; use --workers 1")
    if max_sequences is not None and max_sequences < 1:
        raise InputError(f"--max-sequences must be >= 1, got {max_sequences}")
    tracks = list(tracks) if tracks else None
    _check_tracks(root, tracks)

    references = [name for name in benchmark.SOLVERS if not is_handeye(name)]
    entries, skipped = handeye_entries()
    available = references + [e.name for e in entries]
    names = select_solvers(solvers, available, references)
    version = str(getattr(sys.modules.get("kinhec"), "__version__", "?"))
    machine = machine_line(version)
    start = time.perf_counter()
    with registered(benchmark, [e for e in entries if e.name in names]), contextlib.redirect_stdout(sys.stderr):
        try:
            result = benchmark.run_benchmark(root, out, names, tracks, max_sequences, None, progress=progress,
                                             workers=workers)
        except RuntimeError as exc:  # KinHEC: no results, or chunks that crashed (not solver failures)
            raise SolverError(f"KinHEC's run_benchmark failed: {_one_line(exc)}") from None
    seconds = time.perf_counter() - start
    rows = result.to_dict("records") if hasattr(result, "to_dict") else [dict(r) for r in result]
    run = KinhecRun(rows, head_to_head(rows), track_summary(rows), auto_vs_best(rows, references),
                    out, names, [n for n in references if n in names], skipped, seconds, version, machine)
    write_outputs(run, root)
    return run


def _check_tracks(root: Path, tracks: Sequence[str] | None) -> None:
    """InputError for a track the dataset does not hold (read from its light index sequences.csv)."""
    index = root / "sequences.csv"
    if not tracks or not index.is_file():
        return
    with open(index, newline="", encoding="utf-8") as f:
        present = sorted({row.get("track", "") for row in csv.DictReader(f)} - {""})
    unknown = [t for t in tracks if t not in present]
    if unknown:
        raise InputError(f"--tracks: {str(root)!r} holds no track {unknown[0]!r}; it holds {', '.join(present)}")


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
