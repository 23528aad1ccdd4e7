"""Measure every registered solver on the noisy reference case and write tests/data/noisy_bounds.json.

For every (problem, solver, backend) that is registered and available, and every seed of
`tolerances.BOUND_SEEDS`, the noisy case (`tolerances.noisy_case`) is solved and each unknown's
rotation error [rad] and translation error [mm] against the truth recorded. The file keeps, per
unknown and kind, the worst and the median over the seeds and the bound the shared suite holds
the solver to (`tolerances.BOUND_FACTOR` x the worst), the same for the self-check's distance of
the answer from the best fit (standard deviations), and whether every answer was free of a
self-check failure and of a self-check distance warning ("clean"), with the statuses seen.

Usage: python tools/noisy_bounds.py [--check]   (--check: print the table, write nothing)
Takes ~1-2 minutes on 2 cores. Rerun it after a deliberate change of a solver's accuracy, and say
why in the commit.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from tolerances import BOUND_FACTOR, BOUND_SEEDS, BOUNDS_FILE, measured_key, noisy_case  # noqa: E402

import handeye  # noqa: E402


def runs() -> list[tuple[str, str, str]]:
    """(problem, solver, backend) of every registered, available solver of the problems with a
    noisy reference case in the suite (every problem)."""
    reg = handeye.get_registry()
    out = []
    for problem in sorted(reg.problems):
        for name in reg.solver_names(problem):
            spec = reg.solver(name, problem)
            out += [(problem, name, b) for b in spec.backends if spec.unavailable_reason(b) is None]
    return out


def measure(problem: str, solver: str, backend: str) -> dict:
    reg = handeye.get_registry()
    prob, spec = reg.problem(problem), reg.solver(solver, problem)
    errors: dict[str, dict[str, list[float]]] = {u: {"rotation": [], "translation": []} for u in prob.unknowns}
    clean, statuses, distances = True, set(), []
    for seed in BOUND_SEEDS:
        data, truth = noisy_case(prob, spec.simulate_options, seed)
        sol = handeye.solve(problem, solver=solver, backend=backend, **data)
        statuses.add(sol.status.value)
        check = sol.diagnostics["self_check"]
        if not check["reliable"] or any(w.startswith("self-check:") for w in sol.warnings):
            clean = False
        distances.append(float(check.get("distance_sigmas", 0.0)))
        for name, e in prob.errors(sol.unknowns, truth).items():
            errors[name]["rotation"].append(float(e["rotation"]))
            errors[name]["translation"].append(float(e["translation"]))
    unknowns = {}
    for name, kinds in errors.items():
        unknowns[name] = {kind: {"worst": max(v), "median": float(np.median(v)), "bound": BOUND_FACTOR * max(v)}
                          for kind, v in kinds.items()}
    return {"unknowns": unknowns, "clean": clean, "statuses": sorted(statuses),
            "distance_sigmas": {"worst": max(distances), "median": float(np.median(distances)),
                                "bound": BOUND_FACTOR * max(distances)}}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="print the table, write nothing")
    args = parser.parse_args()
    entries = {}
    for problem, solver, backend in runs():
        entry = measure(problem, solver, backend)
        entries[measured_key(problem, solver, backend)] = entry
        cells = "  ".join(f"{u} {k[:3]} {v[k]['worst']:.3g}" for u, v in entry["unknowns"].items() for k in v)
        print(f"{measured_key(problem, solver, backend):34s} clean={entry['clean']!s:5s} {cells}", flush=True)
    if not args.check:
        doc = {"generated": datetime.date.today().isoformat(), "handeye": handeye.__version__,
               "seeds": list(BOUND_SEEDS), "factor": BOUND_FACTOR,
               "units": {"rotation": "rad", "translation": "mm (the simulator's unit)"}, "entries": entries}
        BOUNDS_FILE.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        print(f"wrote {BOUNDS_FILE.relative_to(ROOT)} ({len(entries)} solver runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
