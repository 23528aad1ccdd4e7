"""The reliability campaign: no solver may return a wrong answer silently.

    python bench/reliability.py [--runs 500] [--seed 0] [--csv out.csv]

`handeye.harness.campaign` draws --runs recordings spread over its kinds (heavy noise with few
stations, pure rotation, a tiny cell, weak excitation, planar motion, 10-30% gross outliers);
each is solved as ``axyb`` (stations) and as ``axxb`` (all motions) by every registered solver
that can run here. A solve is **wrong** when its error (largest rotation angle or translation
distance over the unknowns, against the truth) is more than 5x `auto`'s on the same data; it is
**silent** when it also reports status ``optimal`` with no warning at all. The target is zero
silent wrong solves. Stricter columns: **unflagged** (``optimal`` and no self-check finding:
neither a failure nor a "standard deviations from the best fit" warning; precision warnings do
not count) and **beyond 3 sigma** (wrong, and also more than 3 of `auto`'s predicted standard
deviations from the truth: an answer 5x `auto`'s error can still be within the data's
uncertainty when `auto` happened to land unusually close). The silent wrong solves are also
given in units of `auto`'s 1-sigma.

Prints one row per kind and problem and the totals; exit status 1 when a silent wrong solve is
found. A benchmark, not a test (tests/host/test_properties.py runs a small seeded part of it).
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
import sys
import time
import warnings

from handeye.harness import campaign


def wrong(row: dict, auto: dict) -> bool:
    if row["status"] == "raised" or auto.get("status") == "raised":
        return False
    return row["rotation_deg"] > 5 * auto["rotation_deg"] + 1e-9 or row["translation"] > 5 * auto["translation"] + 1e-12


def sigmas(row: dict, auto: dict) -> float:
    """The row's error in units of auto's predicted 1-sigma (the largest over rotation and
    translation of the unknowns' worst directions); inf when auto gave none."""
    std = (auto.get("self_check") or {}).get("std") or {}
    if not std or row["status"] == "raised":
        return float("inf")
    rot = max(s["rotation_deg"] for s in std.values())
    trans = max(s["translation"] for s in std.values())
    return max(row["rotation_deg"] / max(rot, 1e-300), row["translation"] / max(trans, 1e-300))


def unflagged(row: dict) -> bool:
    check = row.get("self_check") or {}
    return row["status"] == "optimal" and check.get("reliable", True) and check.get("distance_sigmas", 0.0) <= 5.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--csv", help="write every solve as a row")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    start = time.perf_counter()
    rows = []
    for case in campaign.cases(args.runs, seed=args.seed):
        for problem in ("axyb", "axxb"):
            result = campaign.run_case(case, problem, campaign.solver_runs(problem))
            auto = next(r for r in result if r["solver"] == "auto")
            for r in result:
                r["wrong"] = wrong(r, auto)
                r["silent"] = r["wrong"] and r["status"] == "optimal" and r["warnings"] == 0
                r["unflagged"] = r["wrong"] and unflagged(r)
                r["sigmas"] = sigmas(r, auto)
                r["beyond_3_sigma"] = r["wrong"] and r["sigmas"] > 3.0
                rows.append(r)
    table = collections.defaultdict(collections.Counter)
    for r in rows:
        t = table[r["kind"], r["problem"]]
        t["solves"] += 1
        t[r["status"]] += 1
        for key in ("wrong", "silent", "unflagged"):
            t[key] += r[key]
        t["unflagged beyond 3 sigma"] += r["unflagged"] and r["beyond_3_sigma"]
    columns = ["solves", "raised", "unreliable", "not_converged", "wrong", "silent", "unflagged",
               "unflagged beyond 3 sigma"]
    print(f"{args.runs} recordings x (axyb, axxb) x every solver: {len(rows)} solves in "
          f"{time.perf_counter() - start:.0f} s")
    print("| kind | problem | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    total = collections.Counter()
    for (kind, problem), t in sorted(table.items()):
        total.update(t)
        print(f"| {kind} | {problem} | " + " | ".join(str(t[c]) for c in columns) + " |")
    print("| all | | " + " | ".join(str(total[c]) for c in columns) + " |")
    silent = [r["sigmas"] for r in rows if r["silent"]]
    if silent:
        print(f"silent wrong solves: {len(silent)}, within {max(silent):.2g} of auto's 1-sigma from the truth "
              f"(median {sorted(silent)[len(silent) // 2]:.2g})")
    for r in rows:
        if r["silent"] or (r["unflagged"] and r["beyond_3_sigma"]):
            print(f"  {'SILENT' if r['silent'] else 'unflagged'}: {r['kind']} seed {r['seed']} {r['problem']} "
                  f"{r['solver']}/{r['backend']}: {r['rotation_deg']:.3g} deg / {r['translation']:.3g}")
    if args.csv:
        keys = ["kind", "seed", "problem", "solver", "backend", "status", "warnings", "rotation_deg", "translation",
                "wrong", "silent", "unflagged", "sigmas", "beyond_3_sigma", "error"]
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, keys, extrasaction="ignore")
            writer.writeheader()
            writer.writerows({k: (r.get(k, "") if not isinstance(r.get(k), float) or math.isfinite(r[k]) else "")
                              for k in keys} for r in rows)
    return 1 if total["silent"] else 0


if __name__ == "__main__":
    sys.exit(main())
