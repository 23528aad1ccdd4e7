"""`StudyResult`: the records of a run, and the tidy CSV / JSON summaries made from them.

A record is one trial x spec (columns in `handeye.harness.runner`). `summary` groups records by
(sweep, level, pairs, label) and gives count, failures, statuses and mean / median / std /
quartiles of every metric column (errors, residuals, seconds). Failed runs have no metrics (NaN)
and are left out of the statistics; runs that returned an answer with a non-optimal status
(``not_converged``, ``uncertified``, ...) are included and counted in ``not_optimal``.
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.metadata
import json
import math
import platform
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from .study import Spec, Study

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
                    "executor": self.executor,
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
    from .. import __version__

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
