"""Tables, CSV, JSON and the box plot of a `CrossValResult` (held-out residuals, `crossval`).

`heldout_table` is the markdown table per solver (held-out and in-sample median / RMS of the
rotation and translation residuals, solve time, failures); `plot_heldout` the box plots of the
held-out residuals per solver (rotation and translation); `write_crossval` writes
``<name>_folds.csv`` (one row per solver x fold), ``<name>_pairs.csv`` (one row per solver x
fold x held-out pair), ``<name>_summary.json``, ``<name>_heldout.md`` and ``<name>_heldout.png``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

from handeye.harness.crossval import TRUTH_LABEL, CrossValResult
from handeye.harness.report import _ms
from handeye.harness.result import (
    _csv_value,
    _plain,
    environment,
    moved,
    staged_outputs,
)


def _unit(result: CrossValResult) -> str:
    return "mm" if result.data.to_mm is not None else "file units"


def _num(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.3g}"


def heldout_table(result: CrossValResult) -> str:
    """Markdown: one row per solver (and ``truth`` when the data carry one), in spec order."""
    unit = _unit(result)
    head = ["solver", "held-out rot median [rad]", "held-out rot RMS [rad]", f"held-out trans median [{unit}]",
            f"held-out trans RMS [{unit}]", "in-sample rot median [rad]", f"in-sample trans median [{unit}]",
            "median time [ms]", "failed folds"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in result.summary():
        cells = [e["label"], _num(e["heldout_rot_median"]), _num(e["heldout_rot_rms"]),
                 _num(e["heldout_trans_median"]), _num(e["heldout_trans_rms"]),
                 _num(e["insample_rot_median"]), _num(e["insample_trans_median"]),
                 _ms(e["seconds_median"]), "-" if e["label"] == TRUTH_LABEL else f"{e['failed']}/{result.k}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_heldout(result: CrossValResult, path: str | Path, *, dpi: int = 100) -> Path:
    """Box plots of the held-out residuals per solver: rotation (left), translation (right)."""
    from matplotlib.figure import Figure  # a bare Figure: Agg, no pyplot state

    labels = [label for label in result.labels if result.heldout(label, "rot").size]
    fig = Figure(figsize=(max(7.0, 1.1 * len(labels) + 3), 4.8))
    axes = fig.subplots(1, 2)
    for ax, kind, what, unit in ((axes[0], "rot", "rotation", "rad"), (axes[1], "trans", "translation", _unit(result))):
        if labels:
            ax.boxplot([result.heldout(label, kind) for label in labels], showfliers=True)
            ax.set_xticks(range(1, len(labels) + 1), labels, rotation=35, ha="right", fontsize=8)
        ax.set_ylabel(f"held-out {what} residual [{unit}]")
        ax.set_title(f"{what}", fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(f"held-out residuals, {result.k}-fold cross-validation over {result.data.item}s "
                 f"(seed {result.seed}); lower is better relative to the others", fontsize=10)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.88, bottom=0.28, wspace=0.3)
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    return path


def _write_csv(rows: list[dict[str, Any]], path: Path) -> Path:
    columns: dict[str, None] = {}
    for row in rows:
        columns.update(dict.fromkeys(row))
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(columns))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(row.get(k, "")) for k in columns})
    return path


def write_crossval(result: CrossValResult, outdir: str | Path, name: str = "heldout",
                   source: str = "") -> dict[str, Path]:
    """Write everything to `outdir`, whole or not at all (`staged_outputs`: a run stopped while
    writing leaves no half-written file); return {"folds", "pairs", "json", "table", "figure"}
    paths."""
    with staged_outputs(outdir, name) as stage:
        paths = _write_crossval_files(result, stage, name, source)
    return moved(paths, outdir)


def _write_crossval_files(result: CrossValResult, outdir: Path, name: str, source: str) -> dict[str, Path]:
    """`write_crossval`'s files, written to `outdir` (its staging folder)."""
    data = result.data
    summary = {
        "source": source, "problem": data.problem, "folded": data.item, "items": data.count,
        "folds": result.k, "seed": result.seed, "fold_items": [f.tolist() for f in result.fold_items],
        "setup": data.setup, "pairing": data.pairing if data.by_station else None,
        "units": {"rotation": "rad", "translation": _unit(result)},
        "solvers": result.summary(), "full_fit": result.full, "seconds": result.seconds,
        "environment": environment(),
    }
    table = outdir / f"{name}_heldout.md"
    table.write_text(f"Held-out residuals ({result.k}-fold cross-validation over {data.count} {data.item}s, "
                     f"seed {result.seed}, {source}): median and RMS over every held-out pair of every "
                     "fold; in-sample: the fit on all the data. Lower is better only relative to the "
                     "other solvers on the same folds (docs/harness.md).\n\n" + heldout_table(result))
    json_path = outdir / f"{name}_summary.json"
    json_path.write_text(json.dumps(_plain(summary), indent=2) + "\n")
    return {"folds": _write_csv(result.folds, outdir / f"{name}_folds.csv"),
            "pairs": _write_csv(result.pairs, outdir / f"{name}_pairs.csv"),
            "json": json_path, "table": table, "figure": plot_heldout(result, outdir / f"{name}_heldout.png")}
