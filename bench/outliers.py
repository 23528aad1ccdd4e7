"""Gross outlier pairs and `auto`'s default ``outliers="reject"`` (plugins/auto.py).

Simulations (the accuracy study's noise: B 0.002 rad / 0.5 mm, A 0.0002 rad / 0.05 mm), per trial
a clean data set and the same data with 15% of the pairs corrupted (at least one): a random
rotation of 5-30 deg about a random axis and a random translation of 20-100 mm, applied to B.

- axyb: m = 16, 30, 50 pairs;
- axxb, stations: 15% of n = 16, 30, 50 stations' camera poses corrupted before forming every
  pair of motions (auto's station route, solved as A X = Y B on the stations);
- axxb, motions: n = 16, 30, 50 stations, consecutive motions (n - 1), 15% of the motions' B
  corrupted (the per-motion route).

Printed per cell: median and RMS errors of X (and Y for axyb) over the trials for today's least
squares on the clean data (outliers="keep"), auto (reject) on clean data, auto (reject) and least
squares (keep) on the corrupted data; the ratio corrupted-reject / clean-keep (target <= 1.5);
clean reject vs keep: largest relative RMS difference (target < 1%) and how many clean data sets
had a pair flagged (false positives); on corrupted data: corrupted pairs found, clean pairs
flagged.

Usage: python bench/outliers.py [--trials 50]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.problems.axxb import PROBLEM as AXXB
from handeye.problems.axxb import motions, relative_motions, simulate_stations
from handeye.problems.axyb import PROBLEM as AXYB

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})
FRACTION = 0.15
SIZES = (16, 30, 50)


def corrupt(T: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, list[int]]:
    """T with 15% (at least one) of its poses moved by 5-30 deg and 20-100 mm (left-multiplied)."""
    T = T.copy()
    idx = sorted(rng.choice(len(T), max(1, round(FRACTION * len(T))), replace=False).tolist())
    for i in idx:
        axis, direction = rng.normal(size=3), rng.normal(size=3)
        E = make_pose(so3_exp(axis / np.linalg.norm(axis) * np.deg2rad(rng.uniform(5, 30))),
                      direction / np.linalg.norm(direction) * rng.uniform(20, 100))
        T[i] = E @ T[i]
    return T, idx


def cases(kind: str, n: int, seed: int):
    """(problem, clean data, corrupted data, truth, corrupted indices)."""
    rng = np.random.default_rng(10_000 + seed)
    if kind == "axyb":
        data, truth = AXYB.simulate(pairs=n, seed=seed, noise=NOISE)
        B, idx = corrupt(data["B"], rng)
        return "axyb", data, {"A": data["A"], "B": B}, truth, idx
    stations, truth = simulate_stations(n, seed=seed, noise=NOISE)
    if kind == "axxb-stations":
        B, idx = corrupt(stations["B"], rng)
        return ("axxb", motions(stations["A"], inverse(stations["B"])), motions(stations["A"], inverse(B)),
                {"X": truth["X"]}, idx)
    A, B = relative_motions(stations["A"], stations["B"], "consecutive")
    Bc, idx = corrupt(B, rng)
    return "axxb", {"A": A, "B": B}, {"A": A, "B": Bc}, {"X": truth["X"]}, idx


def errors(problem: str, sol, truth) -> list[float]:
    P = AXYB if problem == "axyb" else AXXB
    e = P.errors(sol.unknowns, truth)
    return [v for k in sorted(e) for v in (np.rad2deg(e[k]["rotation"]), e[k]["translation"])]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--trials", type=int, default=50)
    args = parser.parse_args()
    for kind in ("axyb", "axxb-stations", "axxb-motions"):
        names = ["rot X", "t X", "rot Y", "t Y"] if kind == "axyb" else ["rot X", "t X"]
        print(f"\n## {kind}  (errors: deg, mm; median / RMS over {args.trials} trials)")
        print(("| n stations (m = n - 1 motions) |" if kind == "axxb-motions" else "| m |") + " case | " + " | ".join(names) + " |")
        print("|---|---|" + "---|" * len(names))
        for n in SIZES:
            runs = {k: [] for k in ("clean keep", "clean reject", "outliers reject", "outliers keep")}
            fp = exact = found = missed = wrong = 0
            worst_clean = 0.0
            seconds = []
            for seed in range(args.trials):
                problem, clean, bad, truth, idx = cases(kind, n, seed)
                keep = handeye.solve(problem, outliers="keep", **clean)
                rej = handeye.solve(problem, **clean)
                t0 = time.perf_counter()
                bad_rej = handeye.solve(problem, **bad)
                seconds.append(time.perf_counter() - t0)
                bad_keep = handeye.solve(problem, outliers="keep", **bad)
                for k, s in zip(runs, (keep, rej, bad_rej, bad_keep)):
                    runs[k].append(errors(problem, s, truth))
                if rej.diagnostics["outliers"]:
                    fp += 1
                else:
                    exact += bool(np.array_equal(rej.X, keep.X))
                worst_clean = max(worst_clean, float(np.abs(rej.X - keep.X).max()))
                flagged = {o["index"] for o in bad_rej.diagnostics["outliers"]}
                truth_set = set(idx)  # axxb-stations: station indices, as the station route reports them
                found += len(flagged & truth_set)
                missed += len(truth_set - flagged)
                wrong += len(flagged - truth_set)
            stats = {k: np.array(v) for k, v in runs.items()}
            for k, v in stats.items():
                cells = [f"{np.median(v[:, j]):.4g} / {np.sqrt(np.mean(v[:, j] ** 2)):.4g}" for j in range(len(names))]
                print(f"| {n} | {k} | " + " | ".join(cells) + " |")
            ratio_med = np.median(stats["outliers reject"], 0) / np.median(stats["clean keep"], 0)
            ratio_rms = np.sqrt((stats["outliers reject"] ** 2).mean(0) / (stats["clean keep"] ** 2).mean(0))
            clean_rms = np.sqrt((stats["clean reject"] ** 2).mean(0) / (stats["clean keep"] ** 2).mean(0)) - 1
            print(f"| {n} | ratio outliers-reject / clean-keep | " + " | ".join(
                f"{a:.3f} / {b:.3f}" for a, b in zip(ratio_med, ratio_rms)) + " |")
            print(f"<!-- m={n}: clean data: flagged in {fp}/{args.trials} (false positives), identical X when "
                  f"nothing flagged {exact}/{args.trials - fp}, largest |dX| {worst_clean:.2g}, RMS change "
                  f"{np.abs(clean_rms).max() * 100:.3f}%; corrupted: {found} of {found + missed} outliers found, "
                  f"{wrong} clean flagged; auto median {np.median(seconds) * 1e3:.1f} ms on corrupted data -->")


if __name__ == "__main__":
    main()
