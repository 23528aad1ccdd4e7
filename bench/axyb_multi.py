"""The multi-sensor cell (``axyb-multi``): accuracy, certification and time of `auto` against
a fit started at the truth and against solving each camera-marker pair alone.

The study (the issue's protocol): the simulator's default cell (`simulate_cell`, eye to hand:
8 fixed cameras 1-2 m around the workspace, 16 markers on the flange, each camera seeing 3-6 of
them at every station), 20, 50, 100 and 200 stations of the simulated arm, the accuracy study's
noise (`AXYBMulti.study_noise`: camera poses B 0.002 rad / 0.5 mm per axis, robot poses A
0.0002 rad / 0.05 mm, one robot reading per station), `--trials` seeds per size. Per trial:

- ``auto`` (certified start, ML refinement, outliers, self-check);
- ``oracle``: ``refine`` started at the truth (the accuracy floor of the data);
- ``pairwise``: every (X, Y) pair solved alone by ``auto`` for ``axyb``, then averaged;
- ``kron-lstsq`` (the closed-form start), for reference.

Errors are RMS over the poses of each stack (rotation angle in rad, translation distance in mm).
Printed per size: the medians per solver; auto's RMS over oracle's (median and largest; target
<= 1.03); pairwise's over auto's (median; target >= 1.5); the share of trials whose answer is
certified (auto's start: target >= 99%) and ``optimal``; the pairs that pairwise had to skip
(undetermined alone) while the joint solve answered them. Then the time of auto on ~3000
observations (83 stations), median of `--repeats` solves (target <= 2 s).

With ``--uneven U`` the cameras differ: each camera's noise is the study's times a factor
log-uniform in [1/U, U] (`simulate_cell`'s camera_noise), the oracle is refine from the truth
with a noise level per camera and marker, and ``one level`` (auto with noise="groups") shows what
the levels gain.

Usage: python bench/axyb_multi.py [--trials 10] [--sizes 20,50,100,200] [--repeats 5] [--uneven 4]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import rotation_angle
from handeye.problems.axyb_multi import PROBLEM, simulate_cell

NOISE = NoiseModel(PROBLEM.study_noise)
SOLVERS = ("auto", "oracle", "one level", "pairwise", "kron-lstsq")


def rms_errors(unknowns: dict, truth: dict) -> dict[str, float]:
    """RMS over each stack's poses of the rotation (rad) and translation (mm) errors."""
    out = {}
    for name in ("X", "Y"):
        cal, true = np.asarray(unknowns[name]), np.asarray(truth[name])
        rot = rotation_angle(cal[:, :3, :3] @ np.swapaxes(true[:, :3, :3], 1, 2))
        trans = np.linalg.norm(cal[:, :3, 3] - true[:, :3, 3], axis=1)
        out[f"rot_{name}"] = float(np.sqrt(np.mean(rot**2)))
        out[f"trans_{name}"] = float(np.sqrt(np.mean(trans**2)))
    return out


def camera_factors(seed: int, spread: float, cameras: int = 8) -> dict[str, float]:
    """Each camera's noise factor, log-uniform in [1/spread, spread] (1 for every camera at spread 1)."""
    rng = np.random.default_rng(1000 + seed)
    return {f"cam{k}": float(f) for k, f in enumerate(np.exp(rng.uniform(-np.log(spread), np.log(spread), cameras)))}


def trial(stations: int, seed: int, spread: float = 1.0) -> dict:
    uneven = spread > 1.0
    cell = simulate_cell(stations, seed=seed, noise=NOISE, camera_noise=camera_factors(seed, spread) if uneven else None)
    # the oracle: refine from the truth under the model the data follow (a level per camera where they differ)
    oracle_noise = "sources" if uneven else "groups"
    runs = {
        "auto": lambda: handeye.solve(PROBLEM.name, **cell.data),
        "oracle": lambda: handeye.solve(PROBLEM.name, solver="refine", init=cell.truth, noise=oracle_noise, **cell.data),
        "one level": lambda: handeye.solve(PROBLEM.name, noise="groups", **cell.data),
        "pairwise": lambda: handeye.solve(PROBLEM.name, solver="pairwise", **cell.data),
        "kron-lstsq": lambda: handeye.solve(PROBLEM.name, solver="kron-lstsq", **cell.data),
    }
    out: dict = {"m": len(cell.data["A"])}
    for name, run in runs.items():
        t = time.perf_counter()
        try:
            sol = run()
        except handeye.HandEyeError as exc:
            out[name] = {"failed": str(exc)[:120]}
            continue
        out[name] = {**rms_errors(sol.unknowns, cell.truth), "seconds": time.perf_counter() - t,
                     "status": sol.status.value}
        if name == "auto":
            out[name]["certified"] = bool(sol.diagnostics.get("init_certified"))
            out[name]["sources"] = sol.diagnostics["refine"].get("noise_model") == "sources"
        if name == "pairwise":
            out[name]["skipped"] = sum(not r["used"] for r in sol.diagnostics["pairs"])
            out[name]["pairs"] = len(sol.diagnostics["pairs"])
    return out


def combined(errors: dict) -> float:
    """One figure per answer: the RMS of the four RMS errors, each over the oracle's median of
    that error (so that rad and mm weigh alike)."""
    return float(np.sqrt(np.mean([errors[k] ** 2 for k in errors])))


def report(stations: int, trials: list[dict]) -> None:
    keys = ("rot_X", "trans_X", "rot_Y", "trans_Y")
    print(f"\n## {stations} stations (median {int(np.median([t['m'] for t in trials]))} observations), "
          f"{len(trials)} trials")
    print("| solver | " + " | ".join(f"median RMS {k}" for k in keys) + " | median s | failed |")
    print("|---|" + "---|" * (len(keys) + 2))
    for name in SOLVERS:
        ok = [t[name] for t in trials if "failed" not in t[name]]
        cells = [f"{np.median([r[k] for r in ok]):.3g}" if ok else "-" for k in keys]
        seconds = f"{np.median([r['seconds'] for r in ok]):.3f}" if ok else "-"
        print(f"| {name} | " + " | ".join(cells) + f" | {seconds} | {len(trials) - len(ok)} |")
    both = [t for t in trials if all("failed" not in t[s] for s in ("auto", "oracle"))]
    ratios = np.array([[t["auto"][k] / t["oracle"][k] for k in keys] for t in both])
    print(f"auto / oracle (RMS, per error): median {np.median(ratios):.4f}, largest {ratios.max():.4f} "
          f"(per error: {', '.join(f'{k} {v:.4f}' for k, v in zip(keys, ratios.max(axis=0)))})")
    pw = [t for t in trials if all("failed" not in t[s] for s in ("auto", "pairwise"))]
    if pw:
        gain = np.array([[t["pairwise"][k] / t["auto"][k] for k in keys] for t in pw])
        print(f"pairwise / auto (RMS): median per error {', '.join(f'{k} {v:.2f}' for k, v in zip(keys, np.median(gain, axis=0)))}"
              f"; smallest trial median over the errors {np.median(gain, axis=1).min():.2f}")
    print(f"pairwise failed (an unknown no pair determines alone): {sum('failed' in t['pairwise'] for t in trials)}"
          f"; pairs skipped by pairwise: {sum(t['pairwise'].get('skipped', 0) for t in trials)} of "
          f"{sum(t['pairwise'].get('pairs', 0) for t in trials)}")
    certified = [t["auto"].get("certified", False) for t in trials]
    optimal = [t["auto"].get("status") == "optimal" for t in trials]
    print(f"auto certified: {sum(certified)}/{len(trials)}; optimal: {sum(optimal)}/{len(trials)}; "
          f"a noise level per camera and marker kept: {sum(t['auto'].get('sources', False) for t in trials)}/{len(trials)}")
    one = [t for t in trials if all("failed" not in t[s] for s in ("auto", "one level"))]
    if one:
        gain = np.array([[t["one level"][k] / t["auto"][k] for k in keys] for t in one])
        print("one level / auto (RMS): median per error " + ", ".join(f"{k} {v:.2f}" for k, v in zip(keys, np.median(gain, axis=0))))


def timing(repeats: int) -> None:
    cell = simulate_cell(83, seed=12345, noise=NOISE)
    handeye.solve(PROBLEM.name, **cell.data)  # imports, caches
    seconds = []
    for _ in range(repeats):
        t = time.perf_counter()
        sol = handeye.solve(PROBLEM.name, **cell.data)
        seconds.append(time.perf_counter() - t)
    print(f"\nauto on {len(cell.data['A'])} observations of 8 cameras and 16 markers: median "
          f"{np.median(seconds):.3f} s over {repeats} solves (min {min(seconds):.3f}), status {sol.status.value}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--sizes", default="20,50,100,200")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--uneven", type=float, default=1.0,
                        help="cameras differ in noise: each camera's factor log-uniform in [1/U, U] (default 1: alike)")
    args = parser.parse_args()
    if args.uneven > 1.0:
        print(f"cameras' noise factors log-uniform in [1/{args.uneven:g}, {args.uneven:g}]; oracle: refine from the "
              "truth with a level per camera and marker")
    for stations in (int(s) for s in args.sizes.split(",")):
        report(stations, [trial(stations, seed, args.uneven) for seed in range(args.trials)])
    timing(args.repeats)


if __name__ == "__main__":
    main()
