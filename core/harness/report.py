"""Figures and tables of a `StudyResult`: the paper's Fig. 3-4 style plots and Table I style times.

`plot_study` draws, per sweep, error vs noise level (one figure per pair count) and error vs
pair count (one figure per level) when the sweep varies them: a 2 x k grid (rows: rotation
error, eq. 30, and translation error, eq. 31; columns: the unknowns X, Y), one line per spec at
the median over trials with the interquartile range as a band (or, with ``Study.center =
"mean"``, the mean +- one standard deviation, as the paper's means over five trials).
`time_table` is the markdown table of solve times per spec (mean per sweep, like Table I's
columns, and the overall median); `error_table` the median (or mean) errors per cell and spec,
optionally as ratios to a reference spec
(e.g. the ground-truth "oracle" of the accuracy study). `write_report` writes everything.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.harness.result import StudyResult, describe, moved, staged_outputs
from handeye.host.registry import get_registry

#: y axis goes logarithmic when the centres and lower band edges plotted (noise level 0 excluded)
#: span more than this ratio
LOG_RATIO = 30.0
BAND_TEXT = {"median": "median over trials, band = interquartile range",
             "mean": "mean over trials, band = +- one standard deviation"}
MARKERS = ("o", "s", "^", "v", "D", "x", "+", "<", ">", "P", "*", "h")
LINESTYLES = ("-", "--", "-.", ":")


def _unknowns(result: StudyResult) -> tuple[str, ...]:
    return tuple(get_registry().problem(result.study.problem).unknowns)


def plot_study(result: StudyResult, outdir: str | Path, *, fmt: str = "png", dpi: int = 100) -> list[Path]:
    """Write the figures of every sweep to `outdir`; return their paths.

    File names: ``<study>_<sweep>_vs_noise_m<m>.png`` and ``<study>_<sweep>_vs_pairs_level<l>.png``.
    """
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = []
    for sweep in result.study.sweeps:
        if len(sweep.levels) > 1:
            for m in sweep.pairs:
                rows = result.select(sweep=sweep.name, pairs=m)
                title = f"{result.study.name}: error vs noise level ({sweep.name}, m = {m})"
                path = outdir / f"{result.study.name}_{sweep.name}_vs_noise_m{m}.{fmt}"
                paths.append(_grid(result, rows, "level", result.study.level_label, title, path, dpi))
        if len(sweep.pairs) > 1:
            for level in sweep.levels:
                rows = result.select(sweep=sweep.name, level=level)
                title = f"{result.study.name}: error vs number of pairs ({sweep.name}, level = {level:g})"
                path = outdir / f"{result.study.name}_{sweep.name}_vs_pairs_level{level:g}.{fmt}"
                paths.append(_grid(result, rows, "pairs", "number of pairs m", title, path, dpi))
    return paths


def band(stats: Sequence[dict[str, float]], center: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Line and band of `describe` statistics: median with the interquartile range, or mean
    +- one standard deviation (lower edge clipped at 0)."""
    if center == "median":
        keys = ("median", "q25", "q75")
        return tuple(np.array([s[k] for s in stats]) for k in keys)  # type: ignore[return-value]
    mean = np.array([s["mean"] for s in stats])
    std = np.array([s["std"] for s in stats])
    return mean, np.maximum(mean - std, 0.0), mean + std


def _grid(result: StudyResult, rows: list[dict[str, Any]], xkey: str, xlabel: str,
          title: str, path: Path, dpi: int) -> Path:
    # a bare Figure (no pyplot): no GUI backend, no global state, nothing to close
    import matplotlib
    from matplotlib.figure import Figure

    center = result.study.center
    unknowns = _unknowns(result)
    labels = result.labels
    colors = matplotlib.colormaps["tab10" if len(labels) <= 10 else "tab20"]
    unit = {"rot": "rad", "trans": "mm"}
    fig = Figure(figsize=(5.2 * len(unknowns), 7.2))
    axes = fig.subplots(2, len(unknowns), squeeze=False)
    for col, name in enumerate(unknowns):
        for r, kind in enumerate(("rot", "trans")):
            ax = axes[r][col]
            metric = f"err_{kind}_{name}"
            lines = []  # (index, label, xs, centre, band low, band high) of every spec with a value
            for i, label in enumerate(labels):
                xs = sorted({row[xkey] for row in rows if row["label"] == label})
                stats = [describe(np.array([float(row[metric]) for row in rows
                                            if row["label"] == label and row[xkey] == x])) for x in xs]
                med, lo, hi = band(stats, center)
                if np.isfinite(med).any():
                    lines.append((i, label, np.array(xs, dtype=float), med, lo, hi))
            # centres and lower band edges decide the y scale (noise level 0 excluded: ~1e-12)
            scale_values = [v for _, _, xs, med, lo, _ in lines
                            for v in np.concatenate([med[(xs != 0) | (xkey != "level")], lo[(xs != 0) | (xkey != "level")]])
                            if np.isfinite(v) and v > 0]
            log = bool(scale_values) and max(scale_values) / min(scale_values) > LOG_RATIO
            bottom = min(scale_values) / 1.5 if log else None
            for i, label, xs, med, lo, hi in lines:
                if log:  # points below the axis (noise-free ~1e-12) are left out, not drawn off it
                    below = med < bottom
                    med = np.where(below, np.nan, med)
                    lo, hi = np.where(below, np.nan, np.maximum(lo, bottom)), np.where(below, np.nan, hi)
                color = colors(i % colors.N)
                ax.plot(xs, med, LINESTYLES[i % len(LINESTYLES)], marker=MARKERS[i % len(MARKERS)], ms=4,
                        lw=1.3, color=color, label=label, mfc="none")
                ax.fill_between(xs, lo, hi, color=color, alpha=0.12, lw=0)
            if log:
                ax.set_yscale("log")
                ax.set_ylim(bottom=bottom)
            what = "rotation" if kind == "rot" else "translation"
            ax.set_title(f"{what} error of {name}", fontsize=10)
            ax.set_ylabel(f"{what} error [{unit[kind]}]")
            ax.set_xlabel(xlabel)
            ax.grid(True, alpha=0.3, which="both")
    legend: dict[str, Any] = {}  # every spec drawn on any axis, in spec order
    for ax in axes.flat:
        for handle, name in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(name, handle)
    names = [label for label in labels if label in legend]
    handles = [legend[name] for name in names]
    if names:  # none when every run of the figure failed (e.g. too few pairs for the problem)
        fig.legend(handles, names, loc="lower center", ncol=min(len(names), 5), fontsize=8, frameon=False)
    fig.suptitle(f"{title}\n{BAND_TEXT[center]}; units: "
                 f"{result.study.units} given to solvers, errors in rad / mm", fontsize=10)
    # fixed margins: tight_layout would draw the figure once more (seconds on a busy machine)
    legend_rows = math.ceil(len(names) / 5)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.88, bottom=0.11 + 0.025 * legend_rows,
                        hspace=0.38, wspace=0.25)
    fig.savefig(path, dpi=dpi)
    return path


def time_table(result: StudyResult) -> str:
    """Markdown table of solve times (`Solution.seconds`) per spec: mean per sweep, overall
    median, runs and failures. Failed runs have no time and are not in the averages."""
    sweeps = [s.name for s in result.study.sweeps]
    head = ["solver", "backend"] + [f"mean [ms] ({s})" for s in sweeps] + ["median [ms] (all)", "runs", "failed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for spec in result.specs:
        rows = result.select(label=spec.label)
        if not rows:
            continue
        backend = rows[0]["backend"]
        cells = [spec.label, backend]
        for sweep in sweeps:
            t = np.array([float(r["seconds"]) for r in rows if r["sweep"] == sweep])
            cells.append(_ms(describe(t)["mean"]))
        cells.append(_ms(describe(np.array([float(r["seconds"]) for r in rows]))["median"]))
        cells.append(str(len(rows)))
        cells.append(str(sum(r["status"] == "failed" for r in rows)))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _ms(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "-"
    ms = seconds * 1e3
    return f"{ms:.3g}" if ms < 100 else f"{ms:.0f}"


def error_table(result: StudyResult, *, stat: str = "median", reference: str | None = None,
                metrics: Sequence[str] | None = None) -> str:
    """Markdown table of `stat` errors per cell (sweep, level, m) and spec.

    With `reference` (a spec label, e.g. ``"oracle"``), each value is followed by its ratio to
    the reference's value in the same cell, e.g. ``1.03e-03 (1.02x)``.
    """
    unknowns = _unknowns(result)
    metrics = list(metrics) if metrics else [f"err_{k}_{u}" for u in unknowns for k in ("rot", "trans")]
    head = ["sweep", "level", "m", "solver"] + [f"{stat} {m}" for m in metrics] + ["failed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    summary = result.summary()
    by_cell: dict[tuple[Any, ...], dict[str, dict[str, Any]]] = {}
    for entry in summary:
        by_cell.setdefault((entry["sweep"], entry["level"], entry["pairs"]), {})[entry["label"]] = entry
    for (sweep, level, m), entries in by_cell.items():
        ref = entries.get(reference) if reference else None
        for label, entry in entries.items():
            cells = [sweep, f"{level:g}", str(m), label]
            for metric in metrics:
                value = entry.get(f"{metric}_{stat}", math.nan)
                text = "-" if not math.isfinite(value) else f"{value:.3g}"
                if ref is not None and label != reference and math.isfinite(value):
                    base = ref.get(f"{metric}_{stat}", math.nan)
                    if math.isfinite(base) and base > 0:
                        text += f" ({value / base:.2f}x)"
                cells.append(text)
            cells.append(str(entry["failed"]))
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_report(result: StudyResult, outdir: str | Path, *, reference: str | None = None) -> dict[str, Any]:
    """Write ``<study>.csv`` (records), ``<study>_summary.json``, the PNG figures,
    ``<study>_times.md`` and ``<study>_errors.md`` (errors per cell, `Study.center` over the
    trials) to `outdir`, whole or not at all (`staged_outputs`: a run stopped while writing
    leaves no half-written file).
    Returns {"csv": path, "json": path, "times": path, "errors": path, "figures": [paths]}."""
    with staged_outputs(outdir, result.study.name) as stage:
        paths = _write_report_files(result, stage, reference)
    return moved(paths, outdir)


def _write_report_files(result: StudyResult, outdir: Path, reference: str | None) -> dict[str, Any]:
    """`write_report`'s files, written to `outdir` (its staging folder)."""
    name = result.study.name
    if reference is None and "oracle" in result.labels:
        reference = "oracle"
    paths: dict[str, Any] = {
        "csv": result.to_csv(outdir / f"{name}.csv"),
        "json": result.to_json(outdir / f"{name}_summary.json"),
    }
    times = outdir / f"{name}_times.md"
    times.write_text(f"Solve times of study {name!r} ({len(result.records)} runs, jobs={result.jobs}, "
                     f"wall {result.seconds:.1f} s, CPU {result.cpu_seconds:.1f} s)\n\n" + time_table(result))
    errors = outdir / f"{name}_errors.md"
    center = result.study.center
    errors.write_text(f"{center.capitalize()} errors of study {name!r} over the trials of each cell "
                      "(rotation rad, translation mm)"
                      + (f"; ratios to {reference!r}" if reference else "") + "\n\n"
                      + error_table(result, stat=center, reference=reference))
    paths["times"], paths["errors"] = times, errors
    paths["figures"] = plot_study(result, outdir)
    return paths
