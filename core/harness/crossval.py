"""Held-out residuals: compare solvers on real data (no truth) by k-fold cross-validation.

Each spec is fitted on k - 1 folds of the data and its per-pair residuals (the problem's
`residuals`: eqs. 32-33 for ``axyb``, the rotation angle and translation distance between the
two sides of the equation) are computed on the held-out fold. A held-out residual mixes the
answer's error with that pair's own noise, so the numbers rank solvers only relative to each
other on the same folds (docs/harness.md, "Held-out residuals on your own data").

What is folded:

- pairs (``axyb``; a file of ``axxb`` motions): the m pairs (motions) are shuffled with the seed
  and split into k folds; a solver is fitted on the other folds' pairs.
- stations (a file of absolute poses read as ``axxb``, or any problem whose `StationReader` forms
  motions): the n stations are folded, never the motions, since a motion between a test and a
  training station would carry the test station's noise into the fit. A solver is fitted on the
  motions (of the file's pairing) whose two stations are both training stations and scored on
  those whose two stations are both test stations; motions between a test and a training station
  are dropped, because the training station's noise was fitted and would make the score
  optimistic. Stations are shuffled into folds for pairing ``all``; for ``consecutive`` (a
  drifting camera: only neighbouring stations form good motions) the folds are contiguous blocks,
  so that test motions exist at all.

Reuses the harness: `Spec` contenders, `runner.limited_solve` for the per-solve time limit, the
progress bar, `result.describe`; `crossval_report` writes the tables, CSV, JSON and the figure.
"""

from __future__ import annotations

import dataclasses
import math
import time
import types
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError
from handeye.estimation.folds import make_folds  # noqa: F401 (the harness's folds, named here too)
from handeye.framework.problem_cell import StationReader
from handeye.framework.progress import progress_bar
from handeye.framework.solution import Status
from handeye.harness.runner import SolveTimeout, limited_solve
from handeye.harness.study import Spec
from handeye.host.registry import get_registry

#: the label of the reference row when the data carry a truth: the true unknowns' residuals on
#: the same held-out pairs (the noise floor of the data)
TRUTH_LABEL = "truth"


@dataclasses.dataclass(frozen=True)
class CrossValData:
    """Data to cross-validate: either the problem's data fields (folded by pair) or the absolute
    poses of stations (folded by station, motions formed within a side by `reader`)."""

    problem: str
    data: dict[str, np.ndarray]
    truth: dict[str, np.ndarray] | None = None
    poses: dict[str, np.ndarray] | None = None
    setup: str | None = None
    pairing: str | None = None
    reader: StationReader | None = None
    #: factor from the data's length unit to mm (None: unit unknown, numbers in the file's unit)
    to_mm: float | None = None

    @property
    def by_station(self) -> bool:
        return self.poses is not None and self.reader is not None and self.reader.pairing

    @property
    def count(self) -> int:
        """How many items are folded: stations or pairs."""
        return len(self.poses["robot_poses"]) if self.by_station else len(next(iter(self.data.values())))

    @property
    def item(self) -> str:
        return "station" if self.by_station else "pair"

    def subset(self, index: np.ndarray) -> tuple[dict[str, np.ndarray], list[str]]:
        """The data fields of the items `index` (sorted) and a name per pair (``"7"``, or
        ``"3-7"`` for the motion of stations 3 and 7)."""
        index = np.asarray(index)
        if not self.by_station:
            return {f: v[index] for f, v in self.data.items()}, [str(i) for i in index]
        runs = [index]  # pairing all: every i < j among them
        if self.pairing == "consecutive":  # only stations next to each other in the file
            runs = np.split(index, np.flatnonzero(np.diff(index) != 1) + 1)
        parts, names = [], []
        for run in runs:
            if len(run) < 2:
                continue
            parts.append(self.reader.convert(self.poses["robot_poses"][run], self.poses["camera_poses"][run],
                                             setup=self.setup, pairing=self.pairing))
            i, j = (np.arange(len(run) - 1), np.arange(1, len(run))) if self.pairing == "consecutive" \
                else np.triu_indices(len(run), k=1)
            names += [f"{run[a]}-{run[b]}" for a, b in zip(i, j)]
        fields = get_registry().problem(self.problem).data_fields
        if not parts:
            return {f: np.empty((0, 4, 4)) for f in fields}, []
        return {f: np.concatenate([p[f] for p in parts]) for f in fields}, names

    def folds(self, k: int, seed: int) -> list[np.ndarray]:
        """The test items of each fold, after checking every fold leaves enough to fit and score."""
        n, problem = self.count, get_registry().problem(self.problem)
        if self.by_station:
            if n < 2 * k:
                raise InputError(f"{n} stations cannot make {k} folds of at least 2 stations (a held-out "
                                 f"motion needs two held-out stations); use --folds {n // 2} or fewer"
                                 if n >= 4 else f"{n} stations are too few to cross-validate (need >= 4)")
            folds = make_folds(n, k, seed, contiguous=self.pairing == "consecutive")
        else:
            folds = make_folds(n, k, seed)
        fewest = n - max(len(f) for f in folds)
        needed = problem.min_pairs if not self.by_station else 3
        if fewest < needed:
            raise InputError(f"{n} {self.item}s in {k} folds leave {fewest} to fit, fewer than the {needed} "
                             f"problem {self.problem!r} needs; use fewer --folds or more data")
        return folds


def _residuals(problem: Any, data: Mapping[str, np.ndarray], unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-pair residuals of `unknowns` on `data`; empty arrays for no pairs. A held-out fold may
    be too small or rotate too little for the problem's `validate` (min pairs, degeneracy), but
    its residuals are still defined: then the fields are passed as they are (every problem's
    data object exposes its data fields as attributes)."""
    if len(next(iter(data.values()))) == 0:
        return {"rotation": np.empty(0), "translation": np.empty(0)}
    try:
        validated = problem.validate(**data)
    except HandEyeError:
        validated = types.SimpleNamespace(**{k: np.asarray(v, dtype=float) for k, v in data.items()})
    return problem.residuals(validated, unknowns)


def _stats(res: dict[str, np.ndarray], to_mm: float) -> dict[str, float]:
    out = {}
    for kind, key in (("rot", "rotation"), ("trans", "translation")):
        v = np.asarray(res[key], dtype=float) * (to_mm if kind == "trans" else 1.0)
        out[f"{kind}_median"] = float(np.median(v)) if v.size else math.nan
        out[f"{kind}_rms"] = float(np.sqrt(np.mean(v**2))) if v.size else math.nan
    return out


@dataclasses.dataclass
class CrossValResult:
    """What `run_crossval` returns. folds: one row per spec x fold (status, seconds, sizes,
    in-fold and held-out medians / RMS); pairs: one row per spec x fold x held-out pair
    (``res_rot`` rad, ``res_trans`` mm or the file's unit); full: one row per spec, the fit on all
    the data (in-sample residuals, seconds)."""

    data: CrossValData
    specs: tuple[Spec, ...]
    k: int
    seed: int
    fold_items: list[np.ndarray]
    folds: list[dict[str, Any]]
    pairs: list[dict[str, Any]]
    full: list[dict[str, Any]]
    seconds: float = math.nan

    @property
    def labels(self) -> list[str]:
        labels = [s.label for s in self.specs]
        return labels + [TRUTH_LABEL] if self.data.truth is not None else labels

    def heldout(self, label: str, kind: str) -> np.ndarray:
        """Every held-out residual of `label` (kind ``rot`` or ``trans``), pooled over the folds."""
        return np.array([r[f"res_{kind}"] for r in self.pairs if r["label"] == label], dtype=float)

    def summary(self) -> list[dict[str, Any]]:
        """One entry per label: held-out median and RMS (pooled over folds), in-sample median and
        RMS (the fit on all data), median solve time over the folds, failures."""
        out = []
        for label in self.labels:
            folds = [r for r in self.folds if r["label"] == label]
            full = next((r for r in self.full if r["label"] == label), {})
            entry: dict[str, Any] = {"label": label, "solver": folds[0]["solver"] if folds else label}
            for kind in ("rot", "trans"):
                v = self.heldout(label, kind)
                entry[f"heldout_{kind}_median"] = float(np.median(v)) if v.size else math.nan
                entry[f"heldout_{kind}_rms"] = float(np.sqrt(np.mean(v**2))) if v.size else math.nan
                entry[f"insample_{kind}_median"] = full.get(f"insample_{kind}_median", math.nan)
                entry[f"insample_{kind}_rms"] = full.get(f"insample_{kind}_rms", math.nan)
            times = np.array([r["seconds"] for r in folds], dtype=float)
            entry["seconds_median"] = float(np.nanmedian(times)) if np.isfinite(times).any() else math.nan
            entry["heldout_pairs"] = int(self.heldout(label, "rot").size)
            entry["failed"] = sum(r["status"] == Status.FAILED.value for r in folds)
            entry["failed_full"] = full.get("status") == Status.FAILED.value
            entry["not_optimal"] = sum(r["status"] not in (Status.FAILED.value, Status.OPTIMAL.value) for r in folds)
            out.append(entry)
        return out


def _fit(problem: str, spec: Spec, data: Mapping[str, np.ndarray], timeout: float | None) -> tuple[Any, str]:
    """(solution or None, error text)."""
    try:
        return limited_solve(problem, spec.solver, spec.backend, dict(data), dict(spec.options), timeout), ""
    except (Exception, SolveTimeout) as exc:  # noqa: BLE001 - a failing solver is a record, the comparison goes on
        return None, " ".join(f"{type(exc).__name__}: {exc}".split())


def run_crossval(cv: CrossValData, specs: Sequence[Spec], *, folds: int = 5, seed: int = 0,
                 timeout: float | None = 30.0, progress: bool = True) -> CrossValResult:
    """Fit every spec on all the data (in-sample residuals; also the warm-up, so that one-off
    import costs stay out of the fold timings), then on each fold's training items, and score the
    held-out items. Serial, in this process (k x specs solves on one data set)."""
    problem = get_registry().problem(cv.problem)
    problem.validate(**cv.data)  # bad data: exit 2 before any solver runs
    fold_items = cv.folds(folds, seed)
    splits = []
    for test in fold_items:
        train = np.setdiff1d(np.arange(cv.count), test)
        splits.append((train, test, cv.subset(train)[0], cv.subset(test)))
    to_mm = cv.to_mm or 1.0
    full_rows, fold_rows, pair_rows = [], [], []
    start = time.perf_counter()
    bar = progress_bar(len(specs) * (folds + 1), "held-out", "fit", progress, in_logs=True)
    try:
        for spec in specs:
            sol, error = _fit(cv.problem, spec, cv.data, timeout)
            row = {"label": spec.label, "solver": spec.solver, "backend": spec.backend or "",
                   "status": Status(sol.status).value if sol else Status.FAILED.value, "error": error,
                   "seconds": float(sol.seconds) if sol else math.nan}
            stats = _stats(_residuals(problem, cv.data, sol.unknowns), to_mm) if sol else {}
            row.update({f"insample_{k}": stats.get(k, math.nan) for k in ("rot_median", "rot_rms", "trans_median", "trans_rms")})
            full_rows.append(row)
            bar.update()
            for f, (train, test, train_data, (test_data, names)) in enumerate(splits):
                sol, error = _fit(cv.problem, spec, train_data, timeout)
                fold_rows.append(_fold_row(problem, spec.label, spec.solver, spec.backend or "", f, train,
                                           test, train_data, test_data, names, sol, error, to_mm, pair_rows))
                bar.update()
        if cv.truth is not None:
            for f, (train, test, train_data, (test_data, names)) in enumerate(splits):
                truth = types.SimpleNamespace(unknowns=cv.truth, status=Status.OPTIMAL, seconds=math.nan)
                fold_rows.append(_fold_row(problem, TRUTH_LABEL, TRUTH_LABEL, "", f, train, test, train_data,
                                           test_data, names, truth, "", to_mm, pair_rows))
            stats = _stats(_residuals(problem, cv.data, cv.truth), to_mm)
            full_rows.append({"label": TRUTH_LABEL, "solver": TRUTH_LABEL, "backend": "", "status": "optimal",
                              "error": "", "seconds": math.nan, **{f"insample_{k}": v for k, v in stats.items()}})
    finally:
        bar.close()
    return CrossValResult(cv, tuple(specs), folds, seed, fold_items, fold_rows, pair_rows, full_rows,
                          time.perf_counter() - start)


def _fold_row(problem: Any, label: str, solver: str, backend: str, fold: int, train: np.ndarray, test: np.ndarray,
              train_data: Mapping[str, np.ndarray], test_data: Mapping[str, np.ndarray], names: list[str],
              sol: Any, error: str, to_mm: float, pair_rows: list[dict[str, Any]]) -> dict[str, Any]:
    row: dict[str, Any] = {"label": label, "solver": solver, "backend": backend, "fold": fold,
                           "train_items": len(train), "test_items": len(test),
                           "train_pairs": len(next(iter(train_data.values()))), "test_pairs": len(names),
                           "status": Status(sol.status).value if sol else Status.FAILED.value, "error": error,
                           "seconds": float(sol.seconds) if sol else math.nan}
    if sol is None:
        row.update({f"{w}_{k}": math.nan for w in ("fit", "heldout") for k in ("rot_median", "rot_rms", "trans_median", "trans_rms")})
        return row
    fit = _residuals(problem, train_data, sol.unknowns)
    held = _residuals(problem, test_data, sol.unknowns)
    row.update({f"fit_{k}": v for k, v in _stats(fit, to_mm).items()})
    row.update({f"heldout_{k}": v for k, v in _stats(held, to_mm).items()})
    for name, rot, trans in zip(names, held["rotation"], held["translation"]):
        pair_rows.append({"label": label, "fold": fold, "pair": name, "res_rot": float(rot),
                          "res_trans": float(trans) * to_mm})
    return row
