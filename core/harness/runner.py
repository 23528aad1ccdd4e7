"""Running a `Study`: work units, seeds, executors, and the per-trial records.

Generic over problems: the data come from the study's problem's simulator, the error columns from
its unknowns (``err_*_X``, ``err_*_Y`` for ``axyb``; ``err_*_X`` for ``axxb``), the residuals from
its equation, and the oracle's truth (`Spec.init_from_truth`) is its unknowns.

One work unit is one (cell, trial): it simulates the data once and runs every spec on them, so
every solver of a cell sees the same data and process overhead is paid once per unit, not per
solve. The data seed of a unit comes from the master seed and the unit's indices,
``SeedSequence(seed, spawn_key=(sweep, pairs, trial))`` (the same as spawning children of the
master sequence), never from the order in which units run: results are the same for any job
count and executor. The noise level is not in the key: trial k of every level of a sweep draws
the same poses and the same standard-normal noise, scaled by the level (common random numbers),
so error-vs-noise curves compare levels on paired data instead of adding the scatter of new
poses at every level. Units run in-process (``jobs=1``), on worker processes or on a
dask.distributed cluster (`handeye.harness.executors`).

Each record (one per trial x spec) holds: where it comes from (study, sweep, level, pairs,
trial, data seed, noise sigmas), what ran (label, solver, backend, options), how it went (status,
error, seconds = `Solution.seconds`), errors against the truth (eqs. 30-31, ``err_rot_<U>`` rad,
``err_trans_<U>`` mm for every unknown U) and residual summaries (eqs. 32-33, ``res_rot_mean``,
``res_rot_median`` rad, ``res_trans_mean``, ``res_trans_median`` mm), and the solution's warnings
(``warnings``: how many, ``notes``: their text, e.g. why a run did not converge). Translations are always
reported in mm, the simulator's unit, whatever `Study.units` the solvers were given.

Interruptions: with a journal (`run_study(journal=...)`, `handeye.harness.result.StudyJournal`)
every finished unit's records are on disk as soon as the unit returns, and a rerun of the same
study skips them. While a study runs, SIGINT and SIGTERM stop it cleanly (`stop_on_signals`): no
more units start, queued ones are cancelled, the process-pool workers are terminated, and
`StudyInterrupted` (a KeyboardInterrupt) says how many units are saved. The workers also end
when the process running the study is killed outright (SIGKILL): `handeye.framework.processes.die_with_parent`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import signal
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.framework.isolation import fork_available
from handeye.framework.problem import Problem
from handeye.framework.progress import progress_bar
from handeye.framework.solution import Status
from handeye.geometry.se3 import random_poses
from handeye.harness.executors import EXECUTORS, available_cores, cpu_seconds, execute
from handeye.harness.interrupts import (
    StudyInterrupted,
    stop_on_signals,
)
from handeye.harness.result import StudyJournal, StudyResult, UnitKey
from handeye.harness.study import UNITS, GridPoint, Spec, Study
from handeye.host.api import solve
from handeye.host.registry import get_registry

#: std of each translation axis of a random truth (mm), as `handeye.problems.axyb.random_truth`
RANDOM_TRUTH_MM = 500.0


@dataclasses.dataclass(frozen=True)
class Unit:
    """One work unit: trial `trial` of `cell`, run with every spec."""

    index: int
    study: Study
    specs: tuple[Spec, ...]
    cell: GridPoint
    trial: int

    @property
    def key(self) -> UnitKey:
        """What identifies the unit in a journal: (sweep, level index, pairs index, trial)."""
        return (self.cell.sweep, self.cell.level_index, self.cell.pairs_index, self.trial)


def data_seed(study: Study, cell: GridPoint, trial: int) -> int:
    """The 63-bit simulation seed of a unit, from the master seed and the unit's sweep, pair-count
    and trial indices only (the same at every noise level of the sweep)."""
    seq = np.random.SeedSequence(study.seed, spawn_key=(cell.sweep_index, cell.pairs_index, trial))
    return int(seq.generate_state(1, np.uint64)[0] >> np.uint64(1))


def units_of(study: Study, specs: Sequence[Spec]) -> list[Unit]:
    """Every unit of `study`, in a fixed order (cells as `Study.cells`, then trials)."""
    units = []
    for cell in study.cells():
        for trial in range(study.trials):
            units.append(Unit(len(units), study, tuple(specs), cell, trial))
    return units


def simulate(study: Study, cell: GridPoint, trial: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], int]:
    """The unit's data and truth (in mm, the simulator's unit) and its seed."""
    problem = get_registry().problem(study.problem)
    seed = data_seed(study, cell, trial)
    truth_kwargs: dict[str, Any] = {}
    if study.truth == "random":
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))
        if type(problem).random_unknowns is not Problem.random_unknowns:  # its own (e.g. a stack of links)
            truth_kwargs = problem.random_unknowns(rng, RANDOM_TRUTH_MM)
        else:
            poses = random_poses(len(problem.unknowns), rng, RANDOM_TRUTH_MM)
            truth_kwargs = dict(zip(problem.unknowns, poses))
    options = {**study.simulation, **cell.simulation}  # the sweep's own options over the study's
    data, truth = problem.simulate(pairs=cell.pairs, seed=seed, noise=cell.noise, **options, **truth_kwargs)
    return data, truth, seed


def _in_units(poses: dict[str, Any], divisor: float) -> dict[str, Any]:
    """Copies with every translation divided by `divisor` (mm -> the study's units). Fields that
    are not poses (a problem's indices or names, e.g. axyb-multi's ``x_index``) are passed as they
    are."""
    out: dict[str, Any] = {}
    for name, T in poses.items():
        if np.ndim(T) < 2 or np.shape(T)[-2:] != (4, 4):
            out[name] = T
            continue
        T = np.array(T, dtype=float, copy=True)
        T[..., :3, 3] /= divisor
        out[name] = T
    return out


_warmed: set[tuple[str, str]] = set()
#: the warm-up solve (imports, compilation) may take this many times `Study.timeout`
WARMUP_TIMEOUT_FACTOR = 4.0


class SolveTimeout(BaseException):
    """A solve ran past `Study.timeout`; recorded as a failure of that run. A BaseException, so
    that a solver's ``except Exception`` does not swallow it (a bare ``except`` still can: third
    parties' solvers run in a worker process instead, `limited_solve`)."""


@contextlib.contextmanager
def time_limit(seconds: float | None) -> Iterator[None]:
    """Raise `SolveTimeout` in the block after `seconds` (SIGALRM interval timer).

    Enforced only where signals can be: POSIX, the main thread of the process (this process with
    ``jobs=1``, every process-pool worker). A signal interrupts Python code, so a solver looping
    in Python (an interior-point loop, a sleep) is stopped; a single C call that never returns is
    not. Dask runs tasks in worker threads: no limit there.
    """
    if not seconds or not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise SolveTimeout(f"no answer within {seconds:g} s (the study's time limit per solve)")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def limited_solve(problem: str, solver: str, backend: str | None, data: dict[str, Any], options: dict[str, Any],
                  seconds: float | None) -> Any:
    """`handeye.solve` within `seconds` (None: no limit). A third party's solver runs in a forked
    worker process that is killed at the limit (``solve(time_limit=...)``): it cannot swallow the
    limit, outlast it in a C call or leave a thread behind. handeye's own solvers run here, under
    `time_limit` (a fork per solve would cost more than most solves)."""
    registry = get_registry()
    third_party = seconds and solver in registry.solver_names(problem) and not registry.is_builtin(solver, problem)
    if third_party and fork_available():
        return solve(problem, solver=solver, backend=backend, time_limit=seconds, **data, **options)
    with time_limit(seconds):
        return solve(problem, solver=solver, backend=backend, **data, **options)


def run_unit(unit: Unit) -> tuple[int, list[dict[str, Any]]]:
    """Run every spec on the unit's data; return (unit index, records). Never raises for a
    failing solver: its record has status ``failed`` and the exception's type and message."""
    study, cell = unit.study, unit.cell
    problem = get_registry().problem(study.problem)
    divisor = UNITS[study.units]
    base = {
        "study": study.name, "sweep": cell.sweep, "level": cell.level, "pairs": cell.pairs,
        "trial": unit.trial, "units": study.units,
    }
    for name, (rot, trans) in sorted(cell.noise.sigmas.items()):
        base[f"sigma_rot_{name}"] = rot
        base[f"sigma_trans_{name}"] = trans
    try:
        data_mm, truth_mm, seed = simulate(study, cell, unit.trial)
        base["seed"] = seed
        data, truth = _in_units(data_mm, divisor), _in_units(truth_mm, divisor)
        validated = problem.validate(**data)
    except Exception as exc:  # noqa: BLE001 - the data could not be made: every spec fails alike
        reason = f"simulation: {type(exc).__name__}: {exc}"
        return unit.index, [_failed(base, spec, reason, problem.unknowns) for spec in unit.specs]
    records = []
    for spec in unit.specs:
        options = dict(spec.options)
        if spec.init_from_truth:
            options[spec.truth_option] = {k: v.copy() for k, v in truth.items()}
        key = (study.problem, spec.label)
        if study.warmup and key not in _warmed:
            _warmed.add(key)
            try:  # one-off costs (imports, compiled-problem caches) stay out of the timings
                limited_solve(study.problem, spec.solver, spec.backend, data, options,
                              None if study.timeout is None else WARMUP_TIMEOUT_FACTOR * study.timeout)
            except (Exception, SolveTimeout):  # noqa: BLE001, S110 - the timed solve below records any failure
                pass
        try:
            sol = limited_solve(study.problem, spec.solver, spec.backend, data, options, study.timeout)
        except (Exception, SolveTimeout) as exc:  # noqa: BLE001 - any solver failure is a record, the study goes on
            records.append(_failed(base, spec, f"{type(exc).__name__}: {exc}", problem.unknowns))
            continue
        row = _row(base, spec, sol.backend)
        row["status"] = Status(sol.status).value
        row["error"] = ""
        row["seconds"] = float(sol.seconds)
        errors = problem.errors(sol.unknowns, truth)
        for name in problem.unknowns:
            row[f"err_rot_{name}"] = float(errors[name]["rotation"])
            row[f"err_trans_{name}"] = float(errors[name]["translation"]) * divisor
        res = problem.residuals(validated, sol.unknowns)
        row["res_rot_mean"] = float(np.mean(res["rotation"]))
        row["res_rot_median"] = float(np.median(res["rotation"]))
        row["res_trans_mean"] = float(np.mean(res["translation"])) * divisor
        row["res_trans_median"] = float(np.median(res["translation"])) * divisor
        row["warnings"] = len(sol.warnings)
        row["notes"] = " | ".join(" ".join(str(w).split()) for w in sol.warnings)
        records.append(row)
    return unit.index, records


def _row(base: dict[str, Any], spec: Spec, backend: str | None) -> dict[str, Any]:
    row = dict(base)
    row["label"] = spec.label
    row["solver"] = spec.solver
    row["backend"] = backend if backend is not None else ""
    row["options"] = json.dumps(spec.options, sort_keys=True, default=str)
    row["init_from_truth"] = spec.init_from_truth
    return row


def _failed(base: dict[str, Any], spec: Spec, reason: str, unknowns: Iterable[str]) -> dict[str, Any]:
    row = _row(base, spec, spec.backend)
    row.update(status=Status.FAILED.value, error=" ".join(reason.split()), seconds=math.nan)
    for name in unknowns:
        row[f"err_rot_{name}"] = row[f"err_trans_{name}"] = math.nan
    for key in ("res_rot_mean", "res_rot_median", "res_trans_mean", "res_trans_median"):
        row[key] = math.nan
    row["warnings"] = 0
    row["notes"] = ""
    return row


def _tagged(unit: Unit) -> tuple[int, list[dict[str, Any]], int]:
    """`run_unit` plus the id of the process that ran it (kept in the journal)."""
    index, records = run_unit(unit)
    return index, records, os.getpid()


def run_study(study: Study, jobs: int | None = None, progress: bool = True, *,
              executor: str = "process", scheduler: Any = None,
              journal: StudyJournal | str | Path | None = None) -> StudyResult:
    """Run every (cell, trial) unit of `study` and collect the records.

    jobs: worker processes (default: all cores, `available_cores`; 1 runs in this process). progress: show a tqdm
    bar on stderr. executor: ``"process"`` or ``"dask"``; scheduler: for dask, a scheduler
    address (``"tcp://host:8786"``), a `distributed.Client`, or None for a local cluster of
    `jobs` workers. journal: a `StudyJournal` or the path of one (None: none): every finished
    unit is appended to it at once, and the units it holds from an earlier session of the same
    study are not run again (InputError when it belongs to another study definition). Returns
    a `StudyResult` whose records are in unit order, then spec order.

    SIGINT and SIGTERM stop the run (`stop_on_signals`): the units finished so far stay in the
    journal, the others are cancelled, the workers terminated, and `StudyInterrupted` is raised.
    """
    if executor not in EXECUTORS:
        raise InputError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    jobs = available_cores() if jobs is None else int(jobs)
    if jobs < 1:
        raise InputError(f"jobs must be >= 1, got {jobs}")
    specs = study.resolved_specs()
    units = units_of(study, specs)
    if journal is not None and not isinstance(journal, StudyJournal):
        journal = StudyJournal.open(journal, study, specs)
    elif journal is not None and journal.fingerprint != study.fingerprint(specs):
        raise InputError(f"journal {journal.path} was opened for another study than {study.name!r}; open it with this one")
    done = journal.done if journal is not None else {}
    by_index = {unit.index: done[unit.key] for unit in units if unit.key in done}
    resumed = len(by_index)
    todo = [unit for unit in units if unit.index not in by_index]
    start, cpu_start = time.perf_counter(), cpu_seconds()
    bar = progress_bar(len(units), study.name, "trial", progress, in_logs=True, initial=resumed)

    def finish(index: int, records: list[dict[str, Any]], pid: int) -> None:
        if index in by_index:
            return
        if journal is not None:
            journal.append(units[index].key, records, pid)
        by_index[index] = records
        bar.update()

    try:
        with stop_on_signals():
            execute(todo, _tagged, executor, scheduler, jobs, finish)
    except KeyboardInterrupt as stop:
        raise StudyInterrupted(getattr(stop, "signum", signal.SIGINT), len(by_index), len(units),
                               journal.path if journal is not None else None) from None
    finally:
        bar.close()
        if journal is not None:
            journal.close()
    records = [row for index in sorted(by_index) for row in by_index[index]]
    return StudyResult(study=study, specs=specs, records=records, seconds=time.perf_counter() - start,
                       jobs=jobs, executor=executor, cpu_seconds=cpu_seconds() - cpu_start, resumed=resumed)
