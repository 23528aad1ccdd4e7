"""How often `so3-sdp` certifies its local answer without solving the SDP, and whether the answer
is the SDP's (plugins/so3_sdp/single.py, ``local_first``; docs/solvers/so3-sdp.md, "Local certificate").

For every data set: so3-sdp as it runs by default (local minimum, certificate from its first-order
conditions, the SDP only when that fails) and with ``local_first=False`` (always the SDP), on the
same data. Printed per cell: how many answers the local certificate gave, how many fell back to
the SDP, the largest rotation (rad) and relative translation difference between the two answers,
statuses that differ, and the median solve times of both (through `handeye.solve`).

Data: the accuracy study's simulations (`handeye.harness.accuracy_study`: noise on A and B and ten
times that, m = 8, 16, 50, random unknowns; ``axyb`` and ``axxb``), the same at 30x and 100x
(heavier than any real cell: where relaxations stop being tight), and the bundled examples (as
A X = Y B, and as A X = X B on their consecutive motions).

Usage: python bench/certification.py [--trials 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from typing import Any

import numpy as np

import handeye
from handeye.geometry.se3 import rotation_angle
from handeye.harness import accuracy_study
from handeye.harness.runner import simulate
from handeye.io.examples import list_examples, load_example
from handeye.problems.axxb import relative_motions

LEVELS = (1.0, 10.0, 30.0, 100.0)


def compare(problem: str, data: dict[str, Any]) -> dict[str, Any]:
    """so3-sdp with and without the local certificate on one data set."""
    start = time.perf_counter()
    fast = handeye.solve(problem, solver="so3-sdp", **data)
    fast_s = time.perf_counter() - start
    start = time.perf_counter()
    sdp = handeye.solve(problem, solver="so3-sdp", local_first=False, **data)
    sdp_s = time.perf_counter() - start
    rot = max(rotation_angle(fast.unknowns[k][:3, :3].T @ sdp.unknowns[k][:3, :3]) for k in sdp.unknowns)
    trans = max(np.linalg.norm(fast.unknowns[k][:3, 3] - sdp.unknowns[k][:3, 3])
                / max(np.linalg.norm(sdp.unknowns[k][:3, 3]), 1e-300) for k in sdp.unknowns)
    return {"local": fast.diagnostics["certificate_path"] == "local", "rot": rot, "trans": trans,
            "same_status": fast.status is sdp.status, "fast_s": fast_s, "sdp_s": sdp_s,
            "sdp_certified": sdp.diagnostics["certified"]}


def report(name: str, rows: list[dict[str, Any]]) -> None:
    local = sum(r["local"] for r in rows)
    print(f"{name:<40} {len(rows):>4} {local:>6} {len(rows) - local:>6} {sum(r['sdp_certified'] for r in rows):>6}"
          f" {max(r['rot'] for r in rows):>9.1e} {max(r['trans'] for r in rows):>9.1e}"
          f" {sum(not r['same_status'] for r in rows):>5}"
          f" {1e3 * statistics.median(r['fast_s'] for r in rows):>8.2f} {1e3 * statistics.median(r['sdp_s'] for r in rows):>8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=20)
    args = parser.parse_args()
    print(f"{'data':<40} {'sets':>4} {'local':>6} {'sdp':>6} {'sdp ok':>6} {'max rot':>9} {'max tr':>9}"
          f" {'diff':>5} {'ms fast':>8} {'ms sdp':>8}")
    print("(local: certified without the SDP; sdp: fell back to it; sdp ok: the SDP's own answer certified; "
          "max rot / max tr: largest difference of the two answers, rad / relative; diff: statuses that differ)")
    totals = [0, 0]
    for problem in ("axyb", "axxb"):
        study = accuracy_study(problem=problem, trials=args.trials, oracle=False)
        study = dataclasses.replace(study, sweeps=tuple(dataclasses.replace(s, levels=LEVELS) for s in study.sweeps))
        for cell in study.cells():
            rows = [compare(problem, simulate(study, cell, trial)[0]) for trial in range(args.trials)]
            report(f"{problem} accuracy noise x{cell.level:g} m={cell.pairs}", rows)
            if cell.level in (1.0, 10.0):  # the accuracy study itself
                totals[0] += sum(r["local"] for r in rows)
                totals[1] += len(rows)
    for name in list_examples():
        data, _, _ = load_example(name)
        report(f"example {name} (axyb)", [compare("axyb", data)])
        # A_k X = Y B_k gives A_k+1^-1 A_k X = X B_k+1^-1 B_k whatever the setup
        A, B = data["A"], data["B"]
        relative = dict(zip("AB", relative_motions(A, B, "consecutive")))
        report(f"example {name} (axxb, consecutive)", [compare("axxb", relative)])
    print(f"\naccuracy studies: {totals[0]} of {totals[1]} data sets certified without the SDP "
          f"({100.0 * totals[0] / totals[1]:.1f}%)")


if __name__ == "__main__":
    main()
