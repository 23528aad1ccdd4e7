"""The accuracy benchmark of ``axbycz`` (A_i X B_i = Y C_i Z): every solver against the "oracle".

Study (`handeye.harness.accuracy_study` of problem ``axbycz``): two facing arms, noise on A and C
(the robots' flange poses: 0.0002 rad, 0.05 mm) and on B (the marker's pose in the camera:
0.002 rad, 0.5 mm), and a heavy level ten times that; m = 8, 16, 50 triples; random X, Y, Z per
trial; free motion (both robots move at every triple), the protocol of the targets, and, with
``--phases``, also the phase protocol (one robot still at a time), which fu-dq needs. Every
registered axbycz solver runs on its default backend (``--solvers`` to choose), and the oracle is
`refine` started at the ground truth: the accuracy floor of the data.

Per cell and solver the script prints the RMS error over the trials of each unknown (rotation in
mrad, translation in mm) and auto's ratio to the oracle, and checks its targets:

- `auto` within 3% of the oracle's RMS error, every unknown, rotation and translation, every cell;
- `auto` never worse (RMS) than the best other method (oracle excluded) in any cell and metric.

A solver that refuses the data (e.g. fu-dq on free motion, kron-lstsq below 10 triples) is
counted as failed; RMS is over its successful runs, and a solver with failed runs does not count
as "best other method" in that cell (its RMS leaves out the data it could not solve).

Usage::

    python bench/axbycz_accuracy.py                    # 50 trials per cell, free motion, all cores
    python bench/axbycz_accuracy.py --phases --trials 20 --out out/axbycz   # + the harness report

Exit status 1 when a target is missed on free motion (the phase protocol is reported, not judged).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from handeye.harness import Spec, accuracy_study, run_study, write_report
from handeye.host.registry import get_registry

PROBLEM = "axbycz"
UNKNOWNS = ("X", "Y", "Z")
METRICS = tuple(f"err_{kind}_{u}" for u in UNKNOWNS for kind in ("rot", "trans"))
#: auto's RMS error may exceed the oracle's by at most this fraction (accuracy target)
ORACLE_MARGIN = 0.03
PAIRS = (8, 16, 50)


def specs(names: list[str] | None) -> tuple[Spec, ...]:
    """One spec per solver, on its default backend."""
    registry = get_registry()
    out = []
    for name in names or registry.solver_names(PROBLEM):
        solver = registry.solver(name, PROBLEM)
        if solver.unavailable_reason(solver.default_backend) is None:
            out.append(Spec(name, solver.default_backend, label=name))
    return tuple(out)


def rms(result) -> dict[tuple[str, float, int], dict[str, dict[str, float]]]:
    """{(sweep, level, m): {label: {metric: RMS over the successful trials, "failed": count,
    "runs": count, "seconds": median}}}."""
    out: dict[tuple[str, float, int], dict[str, dict[str, float]]] = {}
    for row in result.records:
        cell = out.setdefault((row["sweep"], float(row["level"]), int(row["pairs"])), {})
        cell.setdefault(row["label"], {"rows": []})["rows"].append(row)
    for cell in out.values():
        for entry in cell.values():
            rows = entry.pop("rows")
            ok = [r for r in rows if r["status"] != "failed"]
            entry["runs"], entry["failed"] = len(rows), len(rows) - len(ok)
            entry["seconds"] = float(np.median([r["seconds"] for r in ok])) if ok else math.nan
            for k in METRICS:
                values = np.array([float(r[k]) for r in ok])
                entry[k] = float(np.sqrt(np.mean(values**2))) if len(values) else math.nan
    return out


def table(cells, labels: list[str], sweep: str) -> str:
    head = ["level", "m", "solver"] + [f"rot {u} [mrad]" for u in UNKNOWNS] + [f"t {u} [mm]" for u in UNKNOWNS] + \
        ["worst vs oracle", "failed", "median ms"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (name, level, m), by_label in cells.items():
        if name != sweep:
            continue
        oracle = by_label.get("oracle")
        for label in labels:
            if label not in by_label:
                continue
            v = by_label[label]
            rot = [f"{v[f'err_rot_{u}'] * 1e3:.4g}" for u in UNKNOWNS]
            trans = [f"{v[f'err_trans_{u}']:.4g}" for u in UNKNOWNS]
            ratio = "-"
            if oracle and label != "oracle" and v["failed"] < v["runs"]:
                ratio = f"{max(v[k] / oracle[k] for k in METRICS):.3f}x"
            lines.append("| " + " | ".join([f"{level:g}", str(m), label, *rot, *trans, ratio,
                                            f"{v['failed']}/{v['runs']}", f"{v['seconds'] * 1e3:.3g}"]) + " |")
    return "\n".join(lines) + "\n"


def check_targets(cells, sweep: str, subject: str = "auto") -> list[str]:
    misses = []
    for (name, level, m), by_label in cells.items():
        if name != sweep:
            continue
        where = f"{sweep} level {level:g} m={m}"
        s, oracle = by_label.get(subject), by_label.get("oracle")
        if s is None or oracle is None:
            misses.append(f"{where}: no {subject!r} or oracle results")
            continue
        if s["failed"]:
            misses.append(f"{where}: {subject} failed {s['failed']} times")
        others = {k: v for k, v in by_label.items() if k not in (subject, "oracle") and v["failed"] == 0}
        for k in METRICS:
            if not s[k] <= (1 + ORACLE_MARGIN) * oracle[k]:
                misses.append(f"{where} {k}: {subject} {s[k]:.4g} > {1 + ORACLE_MARGIN:g} x oracle {oracle[k]:.4g}")
            if others:
                best = min(others, key=lambda label: others[label][k])
                if not s[k] <= others[best][k]:
                    misses.append(f"{where} {k}: {subject} {s[k]:.4g} > best other ({best}) {others[best][k]:.4g}")
    return misses


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=50, help="trials per cell (default 50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--solvers", help="comma-separated solver names (default: every axbycz solver)")
    parser.add_argument("--pairs", default=",".join(map(str, PAIRS)), help="triple counts (default 8,16,50)")
    parser.add_argument("--phases", action="store_true", help="also run the phase protocol (reported, not judged)")
    parser.add_argument("--out", help="also write the harness report (CSV, JSON, figures) here")
    args = parser.parse_args(argv)

    chosen = specs(args.solvers.split(",") if args.solvers else None)
    protocols = ("free", "phases") if args.phases else ("free",)
    pairs = tuple(int(p) for p in args.pairs.split(","))
    study = accuracy_study(problem=PROBLEM, trials=args.trials, seed=args.seed, specs=chosen, pairs=pairs,
                           protocols=protocols)
    labels = [s.label for s in study.specs]
    print(f"axbycz accuracy study: {args.trials} trials per cell, protocols {', '.join(protocols)}, "
          f"solvers {', '.join(labels)}; noise {dict(study.noise.sigmas)} (rad, mm) x level", flush=True)
    start = time.perf_counter()
    result = run_study(study, jobs=args.jobs, progress=False)
    cells = rms(result)
    print(f"({time.perf_counter() - start:.0f} s)")
    for sweep in (s.name for s in study.sweeps):
        print(f"\nRMS errors over the trials, {sweep} (rotation mrad, translation mm)\n")
        print(table(cells, labels, sweep))
    if args.out:
        paths = write_report(result, args.out)
        print(f"report: {paths['errors']}")

    misses = check_targets(cells, study.sweeps[0].name)
    if len(study.sweeps) > 1:
        notes = check_targets(cells, study.sweeps[1].name)
        print(f"phase protocol (not judged): {len(notes)} cell/metric(s) where auto misses the free-motion targets")
        for note in notes:
            print(f"  {note}")
    if misses:
        print(f"\nTARGETS MISSED ({len(misses)}):")
        for miss in misses:
            print(f"  {miss}")
        return 1
    print(f"\nall targets met: auto within {ORACLE_MARGIN:.0%} of the oracle and never worse than the best other "
          "method, every cell and metric (free motion)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
