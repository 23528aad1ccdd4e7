"""`StudyResult`: the records of a run, and the tidy CSV / JSON summaries made from them.

A record is one trial x spec (columns in `handeye.harness.runner`). `summary` groups records by
(sweep, level, pairs, label) and gives count, failures, statuses and mean / median / std /
quartiles of every metric column (errors, residuals, seconds). Failed runs have no metrics (NaN)
and are left out of the statistics; runs that returned an answer with a non-optimal status
(``not_converged``, ``uncertified``, ...) are included and counted in ``not_optimal``.

`StudyJournal` keeps the records of a run on disk as its units finish, so that a run stopped
at any moment (Ctrl-C, SIGTERM, SIGKILL, a crash) loses at most the units in flight and a rerun
of the same study resumes it. `staged_outputs` writes a report's files whole or not at all.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import datetime
import importlib.metadata
import json
import math
import os
import platform
import shutil
import signal
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.harness.study import Spec, Study

GROUP_KEYS = ("sweep", "level", "pairs", "label")
STATS = ("mean", "median", "std", "q25", "q75")


def metric_columns(columns: Iterable[str]) -> list[str]:
    """The numeric result columns: errors (err_*), residuals (res_*) and seconds."""
    return [c for c in columns if c.startswith(("err_", "res_")) or c == "seconds"]


@dataclasses.dataclass
class StudyResult:
    """What `run_study` returns: the study, the specs it ran, one record per trial x spec."""

    study: Study
    specs: tuple[Spec, ...]
    records: list[dict[str, Any]]
    seconds: float = math.nan
    jobs: int = 1
    executor: str = "process"
    cpu_seconds: float = math.nan
    #: units (trials of a cell) taken from the journal of an earlier, interrupted session;
    #: `seconds` and `cpu_seconds` are those of this session
    resumed: int = 0

    @property
    def labels(self) -> list[str]:
        return [s.label for s in self.specs]

    def columns(self) -> list[str]:
        """Every column, in order of first appearance."""
        seen: dict[str, None] = {}
        for row in self.records:
            for key in row:
                seen.setdefault(key, None)
        return list(seen)

    def select(self, **equal: Any) -> list[dict[str, Any]]:
        """Records whose columns equal the given values, e.g. ``select(label="kron-lstsq")``."""
        return [r for r in self.records if all(r.get(k) == v for k, v in equal.items())]

    def column(self, name: str, **equal: Any) -> np.ndarray:
        """One column as a float array (over `select(**equal)`)."""
        return np.array([float(r.get(name, math.nan)) for r in self.select(**equal)], dtype=float)

    def to_csv(self, path: str | Path) -> Path:
        """Write the tidy table (one row per trial x spec). NaN is written as an empty field."""
        path = Path(path)
        columns = self.columns()
        with path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=columns, extrasaction="raise")
            writer.writeheader()
            for row in self.records:
                writer.writerow({k: _csv_value(row.get(k, "")) for k in columns})
        return path

    def summary(self) -> list[dict[str, Any]]:
        """Grouped statistics per (sweep, level, pairs, label), in study order."""
        groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
        for row in self.records:
            groups.setdefault(tuple(row[k] for k in GROUP_KEYS), []).append(row)
        metrics = metric_columns(self.columns())
        out = []
        for key, rows in groups.items():
            entry: dict[str, Any] = dict(zip(GROUP_KEYS, key))
            entry["solver"], entry["backend"] = rows[0]["solver"], rows[0]["backend"]
            statuses: dict[str, int] = {}
            for r in rows:
                statuses[r["status"]] = statuses.get(r["status"], 0) + 1
            entry["n"] = len(rows)
            entry["failed"] = statuses.get("failed", 0)
            entry["not_optimal"] = len(rows) - statuses.get("optimal", 0) - entry["failed"]
            entry["statuses"] = statuses
            errors = sorted({r["error"] for r in rows if r.get("error")})
            if errors:
                entry["errors"] = errors[:3]
            for metric in metrics:
                values = np.array([float(r.get(metric, math.nan)) for r in rows], dtype=float)
                for stat, value in describe(values).items():
                    entry[f"{metric}_{stat}"] = value
            out.append(entry)
        return out

    def to_json(self, path: str | Path) -> Path:
        """Write the study definition, run facts and `summary` as JSON (NaN as null)."""
        path = Path(path)
        doc = {
            "study": self.study.to_dict(),
            "specs": [s.to_dict() for s in self.specs],
            "run": {"seconds": self.seconds, "cpu_seconds": self.cpu_seconds, "jobs": self.jobs,
                    "executor": self.executor, "resumed_units": self.resumed,
                    "records": len(self.records), "environment": environment()},
            "summary": self.summary(),
        }
        path.write_text(json.dumps(_plain(doc), indent=1, default=str) + "\n")
        return path


def describe(values: np.ndarray) -> dict[str, float]:
    """mean, median, std (ddof 0), 25th and 75th percentiles of the finite values (NaN if none)."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return {s: math.nan for s in STATS}
    q25, median, q75 = np.percentile(v, [25, 50, 75])
    return {"mean": float(v.mean()), "median": float(median), "std": float(v.std()),
            "q25": float(q25), "q75": float(q75)}


def environment() -> dict[str, str]:
    """Versions that matter for timings and numbers."""
    from handeye import __version__

    info = {"handeye": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "machine": platform.machine(), "system": platform.system(), "processor": platform.processor()}
    for dist in ("scipy", "cvxpy", "clarabel", "picos", "casadi", "opencv-python-headless"):
        try:  # from the metadata: importing cvxpy & co. just for a version costs seconds
            info[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
    return info


def _csv_value(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return ""
    if isinstance(value, float):
        return repr(value)  # shortest round-trip text: the CSV reproduces the numbers exactly
    return value


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def read_csv(path: str | Path) -> list[dict[str, str]]:
    """The rows of a results CSV as dicts of strings (for tests and quick looks)."""
    with Path(path).open(newline="") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------------------------
# the journal of a run, and reports written whole

#: the journal of a run in its output folder: ``<study>.journal.jsonl``
JOURNAL_SUFFIX = ".journal.jsonl"
JOURNAL_FORMAT = "handeye-study-journal"
JOURNAL_VERSION = 1

#: what identifies a unit in a journal: (sweep name, level index, pair-count index, trial)
UnitKey = tuple[str, int, int, int]


def journal_path(outdir: str | Path, name: str) -> Path:
    """Where a run of study `name` into `outdir` keeps its journal."""
    return Path(outdir) / f"{name}{JOURNAL_SUFFIX}"


class StudyJournal:
    """The finished units of a run on disk, one JSON line each, appended as each unit returns.

    Why JSON lines rather than a partial CSV: a line holds one whole unit (the records of every
    spec on one trial of a cell) with its key, so a unit is on disk entirely or not at all; the
    records keep their Python types (int, float to the last bit, bool, NaN as Python's json
    writes it), so a resumed run writes the same CSV as an uninterrupted one; and the columns
    may differ between units (sweeps with their own noise stacks), which a CSV header fixed at
    the first row could not hold.

    Line 1 is a header: ``{"format", "version", "fingerprint", "study", "units", "started",
    "definition"}``; `Study.fingerprint` says which study the journal belongs to. Every other
    line is ``{"unit": [sweep, level index, pairs index, trial], "pid": the worker process,
    "records": [...]}``, written with one write(2) to a file opened with O_APPEND: a process
    killed at any moment leaves whole lines and at most a torn last one, which reading drops (that
    unit runs again). The file is created, or a torn tail cut off, at the first append, so
    opening a journal changes nothing on disk (but ``fresh=True``, which removes it).
    """

    def __init__(self, path: Path, fingerprint: str, header: dict[str, Any],
                 done: dict[UnitKey, list[dict[str, Any]]], valid_bytes: int) -> None:
        self.path = path
        self.fingerprint = fingerprint
        self.header = header
        #: the records of every finished unit, by key (read at open, then appended)
        self.done = done
        #: units read from the file at open
        self.resumed = len(done)
        self._valid_bytes = valid_bytes  # the file up to its last whole line; -1: start a new file
        self._fd: int | None = None

    @property
    def total(self) -> int:
        """Units of the study (cells x trials)."""
        return int(self.header["units"])

    @classmethod
    def open(cls, path: str | Path, study: Study, specs: Sequence[Spec] | None = None, *, fresh: bool = False,
             hint: str = "pass fresh=True to discard it and start afresh") -> StudyJournal:
        """The journal at `path` of a run of `study` (`specs`: default its resolved specs): the
        units an earlier session finished when the file is there, else none. `fresh` removes an
        existing journal. Raises InputError (ending with `hint`, what to do) when the file is
        the journal of another study definition, not a journal, or damaged before its last line."""
        path = Path(path)
        specs = study.resolved_specs() if specs is None else tuple(specs)
        fingerprint = study.fingerprint(specs)
        header = {"format": JOURNAL_FORMAT, "version": JOURNAL_VERSION, "fingerprint": fingerprint,
                  "study": study.name, "units": sum(1 for _ in study.cells()) * study.trials,
                  "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                  "definition": {**study.to_dict(), "solvers": [s.to_dict() for s in specs]}}
        if fresh:
            path.unlink(missing_ok=True)
        if not path.exists():
            return cls(path, fingerprint, header, {}, -1)
        done, valid_bytes, found = _read_journal(path, fingerprint, hint, tuple(spec.label for spec in specs))
        return cls(path, fingerprint, found or header, done, valid_bytes if found else -1)

    def append(self, key: UnitKey, records: list[dict[str, Any]], pid: int | None = None) -> None:
        """Put a finished unit on disk (one line, one write(2): whole or not at all, and in the
        kernel's hands as soon as this returns, so that even SIGKILL cannot lose it)."""
        line = json.dumps({"unit": list(key), "pid": pid, "records": records}, default=str)
        self._write(line)
        self.done.setdefault(key, records)

    def close(self) -> None:
        """Sync the file to disk and close it (a later `append` reopens it)."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def remove(self) -> None:
        """Close and delete the journal: once a run's final outputs are written it is not needed."""
        self.close()
        self.path.unlink(missing_ok=True)

    def _write(self, line: str) -> None:
        data = (line + "\n").encode()
        if self._fd is None:
            self._fd = self._open_for_append()
        written = os.write(self._fd, data)
        if written != len(data):  # a full disk: the torn line is dropped when the journal is read
            raise OSError(f"{self.path}: wrote {written} of {len(data)} bytes of a journal line; is the disk full?")

    def _open_for_append(self) -> int:
        """Open the file for appending: a new file starts with the header; an existing one loses
        a torn last line (a session killed while writing it)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self._valid_bytes < 0:
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
            os.write(fd, (json.dumps(self.header, default=str) + "\n").encode())
            self._valid_bytes = 0
            return fd
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        if os.fstat(fd).st_size > self._valid_bytes:
            os.ftruncate(fd, self._valid_bytes)
        return fd


def _read_journal(path: Path, fingerprint: str, hint: str, labels: tuple[str, ...]
                  ) -> tuple[dict[UnitKey, list[dict[str, Any]]], int, dict[str, Any] | None]:
    """(records by unit key, bytes up to the last whole line, header) of the journal at `path`;
    no header when the file is empty or holds only a torn header (treated as no journal). A unit's
    line must hold one record per spec, in the specs' order (`labels`), each with its status:
    anything else is a damaged line (InputError naming it, before any work is redone)."""
    data = path.read_bytes()
    lines = data.split(b"\n")[:-1]  # a torn last line (no newline) is left out
    if not lines:
        return {}, 0, None
    try:
        header = json.loads(lines[0])
    except ValueError:
        header = None
    if not isinstance(header, dict) or header.get("format") != JOURNAL_FORMAT:
        raise InputError(f"{path} is not a journal of a handeye study; remove it, or {hint}")
    if header.get("version") != JOURNAL_VERSION:
        raise InputError(f"{path} is a version {header.get('version')} journal, this handeye reads version "
                         f"{JOURNAL_VERSION}; {hint}")
    if header.get("fingerprint") != fingerprint:
        raise InputError(f"{path} holds an unfinished run of another definition of study {header.get('study')!r} "
                         "(solvers, sweeps, trials, seed, noise, units or timeout differ); rerun that study unchanged "
                         f"to resume it, or {hint}")
    done: dict[UnitKey, list[dict[str, Any]]] = {}
    for number, line in enumerate(lines[1:], start=2):
        try:
            entry = json.loads(line)
            key = tuple(entry["unit"])
            records = entry["records"]
            whole = (len(key) == 4 and isinstance(records, list)
                     and [r.get("label") if isinstance(r, dict) else None for r in records] == list(labels)
                     and all(isinstance(r.get("status"), str) for r in records))
        except (ValueError, KeyError, TypeError, AttributeError):
            whole = False
        if not whole:
            raise InputError(f"{path}: line {number} is damaged (a unit's line holds one record per solver of the "
                             f"study, {len(labels)} here); {hint}")
        done.setdefault(key, records)  # type: ignore[arg-type]
    return done, len(data) - len(data.split(b"\n")[-1]), header


@contextlib.contextmanager
def staged_outputs(outdir: str | Path, name: str) -> Iterator[Path]:
    """A hidden folder in `outdir` to write a report into. When the block ends, its files move
    into `outdir` together (SIGINT and SIGTERM held off for those few renames); when the block
    raises (an error, Ctrl-C, SIGTERM), the folder goes with its files. So a report is there
    whole or not at all, never half a CSV; only SIGKILL while writing leaves the hidden folder
    (``.<name>.writing-*``)."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{name}.writing-", dir=outdir))
    try:
        yield stage
        with _signals_held():
            for path in sorted(stage.iterdir()):
                os.replace(path, outdir / path.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def moved(paths: dict[str, Any], outdir: str | Path) -> dict[str, Any]:
    """`paths` (paths, or lists of them, in the staging folder) as they are in `outdir`."""
    outdir = Path(outdir)
    return {key: [outdir / p.name for p in value] if isinstance(value, list) else outdir / Path(value).name
            for key, value in paths.items()}


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait (are blocked) in the block and are delivered after it (POSIX)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
