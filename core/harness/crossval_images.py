"""Held-out board corners: rank solvers on a real cell's images, which have no truth, by k-fold
cross-validation over its stations.

Each contender is fitted on the other folds' stations and predicts where the board's corners
appear in the images of the held-out stations: through its X, Y and the held-out stations' robot
poses as measured (their robot errors were not fitted: they are part of what a prediction must
live with), projected with the camera's intrinsics. The figure is the RMS pixel distance between
predicted and detected corners over every held-out corner of every fold; every contender sees
the same corners, intrinsics (those of the whole set: calibrated from every image, or given) and
folds. It is the measure the image path's default chooses by (`handeye.workflow.solving`,
``held_out``), here for every solver of a study, a third party's too:

- a pose-based solver gets the training stations' robot and board poses (A, B);
- a solver that fits the corners themselves (``images`` in its `SolverSpec.simulate_options`:
  ``reprojection``) also gets their corners;
- ``default`` is what ``handeye calibrate`` answers (`DEFAULT_LABEL`): the corner fit with its own
  held-out choice of the robot's noise, or the pose-based default where that predicts its inner
  folds better.

The folds are shuffled with the seed (`handeye.harness.crossval.make_folds`). A contender that
fails on a fold (an exception, a time limit, an unusable status) is recorded as failed there and
gets no figure. `write_image_crossval` writes the ranking (markdown), the folds (CSV) and a JSON
summary; docs/harness.md, "Held-out corners on your own images".
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError
from handeye.estimation.folds import make_folds
from handeye.framework.solution import USABLE
from handeye.harness.runner import SolveTimeout, limited_solve
from handeye.harness.study import Spec, default_specs
from handeye.host.registry import get_registry
from handeye.vision.observations import BoardObservations, board_in_camera
from handeye.vision.projection import project

#: the contender that answers as ``handeye calibrate`` does on images
DEFAULT_LABEL = "default"
#: what `write_image_crossval` writes, after the study's name
FILES = ("_corners.md", "_corners.csv", "_corners.json")


def image_specs(problem: str, solvers: Sequence[Spec] | None = None) -> tuple[Spec, ...]:
    """The contenders for `problem` (the cell's, whose data take board images): `solvers`
    (default: every registered solver with its default backend and OpenCV's methods one by one,
    `default_specs`, and the solvers that fit the corners themselves), after ``default`` (what
    ``handeye calibrate`` answers)."""
    from handeye.workflow.solving import image_solver

    registry = get_registry()
    if solvers is None:
        corner_fits = [Spec(name) for name in registry.solver_names(problem) if registry.solver(name, problem).fits_images]
        solvers = (*default_specs(problem), *corner_fits)
    default = image_solver(problem)
    if default is None:
        raise InputError(f"no solver of problem {problem!r} fits board images; install one (e.g. handeye's reprojection)")
    return (Spec(default, label=DEFAULT_LABEL), *solvers)


@dataclasses.dataclass(frozen=True)
class ImageCrossVal:
    """A held-out corner study: per contender (``rows``, best first) its label, solver, held-out
    RMS in pixels (None where some fold failed), the folds it failed and why, and its fit time;
    per fold and contender (``folds``) the squared pixel errors' sum and the corners."""

    source: str
    stations: int
    corners: int
    folds: int
    seed: int
    rows: tuple[dict[str, Any], ...]
    per_fold: tuple[dict[str, Any], ...]
    seconds: float

    def best_opencv(self) -> float | None:
        """The lowest held-out RMS of OpenCV's methods (the reference a ratio is given to)."""
        return min((r["held_out_px"] for r in self.rows if r["solver"] == "opencv" and r["held_out_px"] is not None),
                   default=None)


def corner_errors(A: np.ndarray, images: BoardObservations, X: np.ndarray, Y: np.ndarray) -> tuple[float, int]:
    """(sum of squared pixel distances, corners) of the corners of `images` predicted through X, Y
    and the robot poses A (one per station); NaN where the board falls behind the camera."""
    T = board_in_camera(images.setup, A, X, Y)
    total, count = 0.0, 0
    for pose, points, seen in zip(T, images.object_points, images.image_points):
        pixels, _, _ = project(points @ pose[:3, :3].T + pose[:3, 3], images.camera)
        total += float(np.sum((pixels - seen) ** 2))
        count += len(seen)
    return total, count


def run_image_crossval(problem: str, fields: Mapping[str, np.ndarray], images: BoardObservations,
                       specs: Sequence[Spec], *, facts: Mapping[str, Any] | None = None, folds: int = 5, seed: int = 0,
                       timeout: float | None = 30.0, source: str = "images") -> ImageCrossVal:
    """The study of the module docstring on the stations' data `fields` of `problem` (A, B of
    A_i X = Y B_i as ``handeye.solve`` takes them, one station a row) and their `images`;
    `facts`: the data's facts (camera_scale, ...); `timeout`: seconds per fit (None: none)."""
    started = time.perf_counter()
    A, B = np.asarray(fields["A"], dtype=float), np.asarray(fields["B"], dtype=float)
    parts = make_folds(len(A), folds, seed)
    sums = {spec.label: [0.0, 0] for spec in specs}
    failed: dict[str, list[str]] = {spec.label: [] for spec in specs}
    seconds = dict.fromkeys(sums, 0.0)
    per_fold = []
    for k, test in enumerate(parts):
        train = np.setdiff1d(np.arange(len(A)), test)
        for spec in specs:
            begun = time.perf_counter()
            try:
                X, Y = _fit(problem, spec, A[train], B[train], _stations(images, train), dict(facts or {}), timeout)
                squared, corners = corner_errors(A[test], _stations(images, test), X, Y)
                if not math.isfinite(squared):
                    raise HandEyeError("the board falls behind the camera at a held-out station")
            except (HandEyeError, SolveTimeout, np.linalg.LinAlgError) as exc:
                failed[spec.label].append(f"fold {k + 1}: {str(exc).splitlines()[0][:160]}")
                per_fold.append({"fold": k + 1, "label": spec.label, "status": "failed", "squared_px": None,
                                 "corners": None})
                continue
            finally:
                seconds[spec.label] += time.perf_counter() - begun
            sums[spec.label][0] += squared
            sums[spec.label][1] += corners
            per_fold.append({"fold": k + 1, "label": spec.label, "status": "ok", "squared_px": squared,
                             "corners": corners, "rms_px": math.sqrt(squared / max(corners, 1))})
    rows = [{"label": spec.label, "solver": spec.solver, "backend": spec.backend, "options": dict(spec.options),
             "held_out_px": None if failed[spec.label] else math.sqrt(sums[spec.label][0] / max(sums[spec.label][1], 1)),
             "failed": failed[spec.label], "fit_seconds": seconds[spec.label] / len(parts)} for spec in specs]
    rows.sort(key=lambda r: (r["held_out_px"] is None, r["held_out_px"] or 0.0))
    corners = sum(len(p) for p in images.image_points)
    return ImageCrossVal(source, len(A), corners, folds, seed, tuple(rows), tuple(per_fold),
                         time.perf_counter() - started)


def _stations(images: BoardObservations, which: np.ndarray) -> BoardObservations:
    return dataclasses.replace(images, image_points=tuple(images.image_points[i] for i in which),
                               object_points=tuple(images.object_points[i] for i in which),
                               names=None if images.names is None else tuple(images.names[i] for i in which))


def _fit(problem: str, spec: Spec, A: np.ndarray, B: np.ndarray, images: BoardObservations, facts: dict[str, Any],
         timeout: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) of `spec` fitted on the training stations; HandEyeError for an unusable answer."""
    from handeye.workflow.solving import (
        HELD_OUT_FOLDS,
        default_solver,
        pose_based_instead,
    )

    registry = get_registry()
    data = {"A": A, "B": B, **facts}
    if spec.label == DEFAULT_LABEL:  # as handeye calibrate answers
        folds = {"held_out": HELD_OUT_FOLDS} if len(A) >= 2 * HELD_OUT_FOLDS else {}
        solution = limited_solve(problem, spec.solver, None, {**data, "images": images}, folds, timeout)
        if pose_based_instead(solution, defaulted=True):
            solution = limited_solve(problem, default_solver(problem), None, data, {}, timeout)
    else:
        if registry.solver(spec.solver, problem).fits_images:
            data["images"] = images
        solution = limited_solve(problem, spec.solver, spec.backend, data, dict(spec.options), timeout)
    if solution.status not in USABLE:
        raise HandEyeError(f"status {solution.status.value}")
    return np.asarray(solution.unknowns["X"], dtype=float), np.asarray(solution.unknowns["Y"], dtype=float)


def corners_table(result: ImageCrossVal) -> str:
    """The ranking as a markdown table: held-out corner RMS and its ratio to OpenCV's best."""
    best = result.best_opencv()
    lines = ["| rank | contender | held-out corners, px RMS | / OpenCV's best | fit time | failed folds |",
             "|---|---|---|---|---|---|"]
    for rank, row in enumerate(result.rows, 1):
        px = row["held_out_px"]
        ratio = "" if px is None or not best else f"{px / best:.2f}x"
        lines.append(f"| {rank if px is not None else '-'} | {row['label']} | {'-' if px is None else f'{px:.3g}'} | "
                     f"{ratio} | {row['fit_seconds'] * 1e3:.0f} ms | {len(row['failed']) or ''} |")
    return "\n".join(lines) + "\n"


def write_image_crossval(result: ImageCrossVal, outdir: str | Path, name: str) -> dict[str, Path]:
    """``NAME_corners.md`` (the ranking), ``NAME_corners.csv`` (every fold) and
    ``NAME_corners.json`` (the summary) in `outdir`; their paths by kind."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = {kind: outdir / f"{name}{suffix}" for kind, suffix in zip(("table", "folds", "json"), FILES)}
    paths["table"].write_text(f"# Held-out board corners: {result.source}\n\n{result.stations} stations, "
                              f"{result.corners} corners, {result.folds} folds (seed {result.seed})\n\n"
                              + corners_table(result), encoding="utf-8")
    with paths["folds"].open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=["fold", "label", "status", "squared_px", "corners", "rms_px"])
        writer.writeheader()
        writer.writerows(result.per_fold)
    summary = {k: v for k, v in dataclasses.asdict(result).items() if k != "per_fold"}
    summary["best_opencv_px"] = result.best_opencv()
    paths["json"].write_text(json.dumps(summary, indent=1), encoding="utf-8")
    return paths
