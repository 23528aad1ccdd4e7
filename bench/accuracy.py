"""The accuracy benchmark of ``axyb``: every solver against the "oracle" on the harness's accuracy study.

Study (`handeye.harness.accuracy_study`): noise on both A and B (B: 0.002 rad, 0.5 mm; A: 0.0002 rad,
0.05 mm) and a heavy level ten times that, m = 8, 16, 50, random X and Y per trial. The oracle is
`refine` started at the ground truth: the accuracy floor of the data. OpenCV's
`cv2.calibrateRobotWorldHandEye` (SHAH and LI) runs beside them, called directly through a run-time
plugin (mapping of docs/conventions.md: A -> world2cam, B -> base2gripper, X <- base2world,
Y <- gripper2cam), so this benchmark does not depend on how the `opencv` plugin names its options.

The study is run twice, with the data in mm and in m (the harness reports errors in mm either way),
and the script checks the accuracy targets:

- `auto` within 3% of the oracle's median rotation and translation errors of X and Y, every cell;
- `auto` better (lower median) than OpenCV SHAH and LI in every cell and metric;
- identical numbers in mm and m (largest relative difference of any per-trial error of every
  solver whose options it declares unit invariant, ``SolverSpec.is_unit_invariant``).

Usage::

    python bench/accuracy.py                       # 50 trials per cell, all cores
    python bench/accuracy.py --trials 10 --out out/accuracy   # also writes the harness report

The same study (without the OpenCV rows unless the `opencv` plugin is installed) is
``handeye compare --accuracy OUTDIR``. Exit status 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.geometry.se3 import make_pose
from handeye.harness import Spec, accuracy_study, run_study, write_report
from handeye.host.registry import get_registry, register_plugin

METRICS = ("err_rot_X", "err_trans_X", "err_rot_Y", "err_trans_Y")
#: auto's median may exceed the oracle's by at most this fraction (accuracy target)
ORACLE_MARGIN = 0.03
#: relative difference of per-trial errors between the mm and the m run that counts as identical
#: (8 significant digits; the iterative solvers stop at ~1e-11 rad, so errors of ~1e-3 rad agree
#: to ~1e-9 relative, not to rounding)
UNIT_TOLERANCE = 1e-8


# --------------------------------------------------------------------------------------------
# OpenCV, called directly


def _cv2_run(method_name: str):
    def run(data: Any, options: Any, backend: str) -> SolverOutput:
        import cv2

        A, B = data.A, data.B
        R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
            list(A[:, :3, :3]), list(A[:, :3, 3:4]), list(B[:, :3, :3]), list(B[:, :3, 3:4]),
            method=getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{method_name}"))
        return SolverOutput(
            unknowns={"X": make_pose(np.asarray(R_b2w), np.ravel(t_b2w)),
                      "Y": make_pose(np.asarray(R_g2c), np.ravel(t_g2c))},
            status=Status.OPTIMAL, diagnostics={})

    return run


CV2_SPECS = {
    f"cv2-{m.lower()}": SolverSpec(name=f"cv2-{m.lower()}", problems=("axyb",), run=_cv2_run(m),
                                   backends={"cv2": ("cv2",)}, default_backend="cv2",
                                   summary=f"cv2.calibrateRobotWorldHandEye, method {m} (benchmark only)")
    for m in ("SHAH", "LI")
}


class _CV2Plugin:
    @hookimpl
    def register_solvers(self, register):
        for spec in CV2_SPECS.values():
            register(spec)


def ensure_cv2_solvers() -> None:
    if not all(name in get_registry().solvers for name in CV2_SPECS):
        register_plugin(_CV2Plugin(), "bench-accuracy-cv2")


# --------------------------------------------------------------------------------------------


def specs(names: list[str] | None) -> tuple[Spec, ...]:
    registry = get_registry()
    names = names or [n for n in registry.solver_names("axyb") if n not in CV2_SPECS] + list(CV2_SPECS)
    out = []
    for name in names:
        solver = registry.solver(name, "axyb")
        if solver.unavailable_reason(solver.default_backend) is None:
            out.append(Spec(name, solver.default_backend, label=name))
    return tuple(out)


def medians(result) -> dict[tuple[float, int], dict[str, dict[str, float]]]:
    """{(level, m): {label: {metric: median}}}, plus the count of failed runs as "failed"."""
    out: dict[tuple[float, int], dict[str, dict[str, float]]] = {}
    for entry in result.summary():
        cell = out.setdefault((entry["level"], entry["pairs"]), {})
        cell[entry["label"]] = {m: entry[f"{m}_median"] for m in METRICS}
        cell[entry["label"]]["failed"] = entry["failed"]
        cell[entry["label"]]["not_optimal"] = entry["not_optimal"]
    return out


def table(cells, labels: list[str]) -> str:
    head = ["level", "m", "solver", "rot X [mrad]", "t X [mm]", "rot Y [mrad]", "t Y [mm]", "vs oracle (worst)", "failed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (level, m), by_label in cells.items():
        oracle = by_label.get("oracle")
        for label in labels:
            if label not in by_label:
                continue
            v = by_label[label]
            vals = [f"{v[k] * 1e3:.4g}" if "rot" in k else f"{v[k]:.4g}" for k in METRICS]
            ratio = "-"
            if oracle and label != "oracle":
                ratio = f"{max(v[k] / oracle[k] for k in METRICS):.3f}x"
            lines.append("| " + " | ".join([f"{level:g}", str(m), label, *vals, ratio, str(v["failed"])]) + " |")
    return "\n".join(lines) + "\n"


def paired(result, level: float, m: int, metric: str, subject: str, other: str) -> str:
    """Paired comparison on the same trials: share of trials where `subject` has the lower error,
    and the ratio of the mean errors (the median alone can tie by chance)."""
    a = {r["trial"]: float(r[metric]) for r in result.select(label=subject, level=level, pairs=m)}
    b = {r["trial"]: float(r[metric]) for r in result.select(label=other, level=level, pairs=m)}
    common = sorted(set(a) & set(b))
    x, y = np.array([a[t] for t in common]), np.array([b[t] for t in common])
    return f"{subject} lower in {np.mean(x < y) * 100:.0f}% of {len(common)} paired trials, mean {x.mean() / y.mean():.3f}x"


def check_targets(cells, subject: str = "auto", result=None) -> list[str]:
    misses = []
    for (level, m), by_label in cells.items():
        s = by_label.get(subject)
        if s is None:
            misses.append(f"level {level:g} m={m}: no {subject!r} results")
            continue
        if s["failed"]:
            misses.append(f"level {level:g} m={m}: {subject} failed {s['failed']} times")
        oracle = by_label.get("oracle")
        for k in METRICS:
            if oracle and not s[k] <= (1 + ORACLE_MARGIN) * oracle[k]:
                misses.append(f"level {level:g} m={m} {k}: {subject} {s[k]:.4g} > {1 + ORACLE_MARGIN:g} x oracle {oracle[k]:.4g}")
            for other in CV2_SPECS:
                if other in by_label and not s[k] < by_label[other][k]:
                    extra = f" ({paired(result, level, m, k, subject, other)})" if result is not None else ""
                    misses.append(f"level {level:g} m={m} {k}: {subject} {s[k]:.4g} >= {other} {by_label[other][k]:.4g}{extra}")
    return misses


def unit_differences(mm, m) -> dict[str, float]:
    """Largest relative difference of any per-trial error, per label, between the two runs."""
    out: dict[str, float] = {}
    for a, b in zip(mm.records, m.records, strict=True):
        assert a["label"] == b["label"] and a["seed"] == b["seed"]
        worst = out.get(a["label"], 0.0)
        for k in METRICS:
            x, y = float(a[k]), float(b[k])
            if math.isnan(x) and math.isnan(y):
                continue
            worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-300))
        out[a["label"]] = worst
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=50, help="trials per cell (default 50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--solvers", help="comma-separated solver names (default: all, plus cv2-shah, cv2-li)")
    parser.add_argument("--out", help="also write the harness report (CSV, JSON, figures) of the mm run here")
    parser.add_argument("--no-units", action="store_true", help="skip the second run in metres")
    args = parser.parse_args(argv)

    ensure_cv2_solvers()
    chosen = specs(args.solvers.split(",") if args.solvers else None)
    study = accuracy_study(trials=args.trials, seed=args.seed, specs=chosen)
    labels = [s.label for s in study.specs]
    print(f"accuracy study: {args.trials} trials per cell, solvers {', '.join(labels)}", flush=True)
    result_mm = run_study(study, jobs=args.jobs, progress=False)
    cells = medians(result_mm)
    print(f"\nmedian errors, data in mm ({result_mm.seconds:.0f} s)\n")
    print(table(cells, labels))
    if args.out:
        paths = write_report(result_mm, args.out)
        print(f"report: {paths['errors']}")

    misses = check_targets(cells, result=result_mm)
    registry = get_registry()
    if not args.no_units:
        result_m = run_study(study.replace(units="m"), jobs=args.jobs, progress=False)
        diffs = unit_differences(result_mm, result_m)
        print(f"mm vs m: largest relative difference of any per-trial error ({result_m.seconds:.0f} s)")
        for label, d in diffs.items():
            spec = next(s for s in study.specs if s.label == label)
            invariant = registry.solver(spec.solver, "axyb").is_unit_invariant(spec.options)
            print(f"  {label:18s} {d:.2e}  {'(declares unit_invariant)' if invariant else ''}")
            if invariant and d > UNIT_TOLERANCE:
                misses.append(f"{label} declares unit_invariant but mm and m differ by {d:.2e}")
        variant = [lab for lab in labels if lab == "auto" or diffs.get(lab, 0.0) > UNIT_TOLERANCE]
        print("\nmedian errors, data in m (translations reported in mm), solvers whose numbers change:\n")
        cells_m = medians(result_m)
        print(table(cells_m, variant))
        misses += [f"[m] {x}" for x in check_targets(cells_m, result=result_m)]
    times = {s.label: np.median([r["seconds"] for r in result_mm.select(label=s.label, pairs=16)
                                 if r["status"] != "failed"] or [math.nan]) * 1e3 for s in study.specs}
    print("\nmedian solve time at m = 16 [ms] (parallel study; bench/speed.py times properly): "
          + ", ".join(f"{k} {v:.3g}" for k, v in times.items()))
    print("\ntargets (auto within 3% of the oracle, better than OpenCV SHAH and LI, mm == m):",
          "all met" if not misses else f"{len(misses)} missed")
    for miss in misses:
        print("  MISSED:", miss)
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main())
