"""AX=YB or AX=XB? The same recorded stations solved both ways, X's errors against the truth.

A robot cell records, at n stations, the robot's pose T_base_flange and the camera's pose (the
board pose solvePnP gives). With them a user can solve

- AX=YB (problem ``axyb``, solver ``auto``): A_i = T_base_flange, B_i = T_target_cam, for X and
  Y jointly, or
- AX=XB (problem ``axxb``, solver ``auto``): the relative motions between stations
  (`handeye.problems.axxb.motions`), ``consecutive`` (station i with i + 1, n - 1 motions) or
  ``all`` (every i < j, n (n - 1) / 2 motions), for X alone (given all pairs, auto recognises
  the stations and solves them as AX=YB; ``refine`` on all pairs shows the per-motion model), or
- OpenCV's ``cv2.calibrateHandEye`` (method PARK), called directly on the stations; it forms all
  pairs i < j itself.

The stations are `handeye.problems.axxb.simulate_stations` (an eye-in-hand cell: the paper's arm
at random joints, its X = T_flange_cam and Y = T_base_target, millimetres), with noise in one of
four scenarios:

- ``camera``: white noise on every camera pose (rotation 0.002 rad, translation 0.5 mm);
- ``robot``: white noise on every robot pose (0.0002 rad, 0.05 mm);
- ``both``: both (the accuracy study's realistic noise, `handeye.harness.ACCURACY_NOISE`);
- ``drift``: a drifting camera, as visual odometry gives: the camera pose of station k is the
  previous station's estimate composed with the true motion since it and a fresh error,
  B'_k = B'_(k-1) (B_(k-1)^-1 B_k) E_k, E_k = exp of a (0.002 rad, 0.5 mm) Gaussian step, so each
  pose's error is a random walk (implemented here, `drift`, not in handeye).

For each scenario and n = 8, 16, 50 stations, every trial draws new stations (the same stations
in every scenario: common random numbers) and every method solves them; the table gives the
median and RMS over the trials of X's rotation error (angle of R_cal R_true^T) and translation
error (|t_cal - t_true|). docs/when-to-use-which.md discusses the answer.

Usage::

    python bench/axyb_vs_axxb.py                       # 100 trials per cell, all cores (~3 min)
    python bench/axyb_vs_axxb.py --trials 50 --out docs/figures/axyb-vs-axxb

Writes ``axyb_vs_axxb_table.md`` (the medians and RMS, then paired comparisons: in how many
trials of a cell AX=YB's error is below each other method's) and the figures
``axyb_vs_axxb_rotation.png``, ``axyb_vs_axxb_translation.png`` to ``--out``; with ``--csv FILE``
also every trial's errors (one row per trial and method).
"""

from __future__ import annotations

import argparse
import csv
import math
import multiprocessing
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import pose_errors
from handeye.geometry.se3 import inverse, so3_exp
from handeye.problems.axxb import relative_motions, simulate_stations

#: white noise (rad, mm) of the camera and robot poses: the accuracy study's realistic noise
CAMERA_NOISE = (0.002, 0.5)
ROBOT_NOISE = (0.0002, 0.05)
#: per-station step (rad, mm) of the drifting camera's random walk
DRIFT_STEP = (0.002, 0.5)
SCENARIOS = {
    "camera": NoiseModel({"B": CAMERA_NOISE}),
    "robot": NoiseModel({"A": ROBOT_NOISE}),
    "both": NoiseModel({"A": ROBOT_NOISE, "B": CAMERA_NOISE}),
    "drift": None,  # `drift`
}
SCENARIO_TEXT = {
    "camera": f"camera white noise ({CAMERA_NOISE[0]:g} rad, {CAMERA_NOISE[1]:g} mm)",
    "robot": f"robot white noise ({ROBOT_NOISE[0]:g} rad, {ROBOT_NOISE[1]:g} mm)",
    "both": "both (camera and robot white noise)",
    "drift": f"drifting camera (random walk, step {DRIFT_STEP[0]:g} rad, {DRIFT_STEP[1]:g} mm)",
}
STATIONS = (8, 16, 50)


def methods() -> dict[str, tuple[str, str | None, str]]:
    """label -> (problem or "cv2", pairing, solver): auto for both problems where registered
    (else kron-lstsq, then park, for axxb), and OpenCV PARK."""
    axxb = handeye.list_solvers("axxb")
    solver = next((s for s in ("auto", "kron-lstsq", "park") if s in axxb), None)
    out: dict[str, tuple[str, str | None, str]] = {"AX=YB auto": ("axyb", None, "auto")}
    if solver is not None:
        out[f"AX=XB {solver}, consecutive"] = ("axxb", "consecutive", solver)
        out[f"AX=XB {solver}, all pairs"] = ("axxb", "all", solver)
    if "refine" in axxb:  # the per-motion model on all pairs (auto solves their stations instead)
        out["AX=XB refine, all pairs (per-motion model)"] = ("axxb", "all", "refine")
    out["OpenCV PARK (all pairs)"] = ("cv2", "all", "PARK")
    return out


def drift(B: np.ndarray, rng: np.random.Generator, step: tuple[float, float] = DRIFT_STEP) -> np.ndarray:
    """Camera poses B: (n, 4, 4) as a drifting odometry estimates them: B'_0 = B_0 E_0,
    B'_k = B'_(k-1) (B_(k-1)^-1 B_k) E_k, E_k = [exp(w), v] with w ~ N(0, step_rot^2 I),
    v ~ N(0, step_trans^2 I); so B'_k = B_k (E-products): the error is a random walk."""
    n = len(B)
    E = np.tile(np.eye(4), (n, 1, 1))
    E[:, :3, :3] = so3_exp(step[0] * rng.standard_normal((n, 3)))
    E[:, :3, 3] = step[1] * rng.standard_normal((n, 3))
    out = np.empty_like(B)
    out[0] = B[0] @ E[0]
    for k in range(1, n):
        out[k] = out[k - 1] @ inverse(B[k - 1]) @ B[k] @ E[k]
    return out


def unit(args: tuple[str, int, int, int, int]) -> list[dict[str, Any]]:
    """One trial of one scenario: simulate the stations, solve with every method, the X errors."""
    scenario, n, n_index, trial, seed = args
    seq = np.random.SeedSequence(seed, spawn_key=(n_index, trial))
    data_seed = int(seq.generate_state(1, np.uint64)[0] >> np.uint64(1))
    noise = SCENARIOS[scenario]
    stations, truth = simulate_stations(n, seed=data_seed, noise=noise)
    robot, B = stations["A"], stations["B"]  # T_base_flange, T_target_cam
    if scenario == "drift":
        B = drift(B, np.random.default_rng(np.random.SeedSequence(data_seed, spawn_key=(2,))))
    rows = []
    for label, (problem, pairing, solver) in methods().items():
        row = {"scenario": scenario, "stations": n, "trial": trial, "seed": data_seed, "method": label}
        start = time.perf_counter()
        try:
            X = solve_x(problem, pairing, solver, robot, B)
            err = pose_errors({"X": X}, truth, ("X",))["X"]
            row.update(rot=err["rotation"], trans=err["translation"], error="")
        except Exception as exc:  # noqa: BLE001 - a failing method is a row, the study goes on
            row.update(rot=math.nan, trans=math.nan, error=f"{type(exc).__name__}: {exc}")
        row["seconds"] = time.perf_counter() - start
        rows.append(row)
    return rows


def solve_x(problem: str, pairing: str | None, solver: str, robot: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X = T_flange_cam by one method from the stations' robot poses and camera poses B = T_target_cam."""
    if problem == "axyb":
        return handeye.solve("axyb", solver=solver, A=robot, B=B).X
    if problem == "axxb":
        A, Bm = relative_motions(robot, B, pairing)
        return handeye.solve("axxb", solver=solver, A=A, B=Bm).X
    import cv2

    camera = inverse(B)  # T_cam_target, what solvePnP gives
    R, t = cv2.calibrateHandEye(list(robot[:, :3, :3]), list(robot[:, :3, 3:]), list(camera[:, :3, :3]),
                                list(camera[:, :3, 3:]), method=getattr(cv2, f"CALIB_HAND_EYE_{solver}"))
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R, np.ravel(t)
    return X


def summary(rows: list[dict[str, Any]]) -> dict[tuple[str, int, str], dict[str, float]]:
    """(scenario, stations, method) -> median and RMS of the rotation and translation errors."""
    groups: dict[tuple[str, int, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["stations"], r["method"]), []).append(r)
    out = {}
    for key, group in groups.items():
        rot = np.array([r["rot"] for r in group], dtype=float)
        trans = np.array([r["trans"] for r in group], dtype=float)
        ok = np.isfinite(rot)
        out[key] = {"rot_median": float(np.median(rot[ok])) if ok.any() else math.nan,
                    "rot_rms": float(np.sqrt(np.mean(rot[ok] ** 2))) if ok.any() else math.nan,
                    "trans_median": float(np.median(trans[ok])) if ok.any() else math.nan,
                    "trans_rms": float(np.sqrt(np.mean(trans[ok] ** 2))) if ok.any() else math.nan,
                    "rot_q25": float(np.percentile(rot[ok], 25)) if ok.any() else math.nan,
                    "rot_q75": float(np.percentile(rot[ok], 75)) if ok.any() else math.nan,
                    "trans_q25": float(np.percentile(trans[ok], 25)) if ok.any() else math.nan,
                    "trans_q75": float(np.percentile(trans[ok], 75)) if ok.any() else math.nan,
                    "n": int(ok.sum()), "failed": int((~ok).sum())}
    return out


def table(stats: dict[tuple[str, int, str], dict[str, float]], labels: list[str]) -> str:
    """Markdown: per scenario and n, every method's median / RMS rotation error (mrad) and
    translation error (mm); the best median of a cell in bold."""
    head = ["noise", "stations", "method", "rotation median [mrad]", "rotation RMS [mrad]",
            "translation median [mm]", "translation RMS [mm]", "failed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for scenario in SCENARIOS:
        for n in STATIONS:
            cell = {label: stats[(scenario, n, label)] for label in labels if (scenario, n, label) in stats}
            if not cell:
                continue
            best_rot = min(v["rot_median"] for v in cell.values())
            best_trans = min(v["trans_median"] for v in cell.values())
            for label, v in cell.items():
                rot = f"{v['rot_median'] * 1e3:.3f}"
                trans = f"{v['trans_median']:.3f}"
                rot = f"**{rot}**" if v["rot_median"] == best_rot else rot
                trans = f"**{trans}**" if v["trans_median"] == best_trans else trans
                lines.append("| " + " | ".join([scenario, str(n), label, rot, f"{v['rot_rms'] * 1e3:.3f}", trans,
                                                f"{v['trans_rms']:.3f}", str(v["failed"])]) + " |")
    return "\n".join(lines) + "\n"


def paired_table(rows: list[dict[str, Any]], labels: list[str]) -> str:
    """Markdown: per scenario and n, for each method after the first, the share of trials in
    which the first method (AX=YB auto) has the lower rotation / translation error of X than it
    on the same stations (a paired comparison: medians of 100 trials differ by chance by ~10%)."""
    first, others = labels[0], labels[1:]
    by_trial: dict[tuple[str, int, int], dict[str, dict[str, Any]]] = {}
    for r in rows:
        by_trial.setdefault((r["scenario"], r["stations"], r["trial"]), {})[r["method"]] = r
    head = ["noise", "stations"] + [f"vs {other}: rotation / translation" for other in others]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for scenario in SCENARIOS:
        for n in STATIONS:
            trials = [t for (sc, m, _), t in by_trial.items() if sc == scenario and m == n]
            if not trials:
                continue
            cells = [scenario, str(n)]
            for other in others:
                shares = []
                for kind in ("rot", "trans"):
                    pairs = [(t[first][kind], t[other][kind]) for t in trials
                             if first in t and other in t and np.isfinite(t[first][kind]) and np.isfinite(t[other][kind])]
                    shares.append(f"{100 * np.mean([a < b for a, b in pairs]):.0f}%" if pairs else "-")
                cells.append(" / ".join(shares))
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(stats: dict[tuple[str, int, str], dict[str, float]], labels: list[str], kind: str, path: Path,
         trials: int) -> Path:
    """One row of panels (a panel per scenario): the median error of X vs the number of stations,
    one line per method, interquartile band; log axes."""
    from matplotlib.figure import Figure

    unit_scale, unit = (1e3, "mrad") if kind == "rot" else (1.0, "mm")
    what = "rotation" if kind == "rot" else "translation"
    fig = Figure(figsize=(16, 4.6))
    axes = fig.subplots(1, len(SCENARIOS), sharey=True)
    markers = ("o", "s", "^", "D", "v")
    for ax, scenario in zip(axes, SCENARIOS):
        for i, label in enumerate(labels):
            xs = [n for n in STATIONS if (scenario, n, label) in stats]
            med = np.array([stats[(scenario, n, label)][f"{kind}_median"] for n in xs]) * unit_scale
            lo = np.array([stats[(scenario, n, label)][f"{kind}_q25"] for n in xs]) * unit_scale
            hi = np.array([stats[(scenario, n, label)][f"{kind}_q75"] for n in xs]) * unit_scale
            line, = ax.plot(xs, med, marker=markers[i % len(markers)], lw=1.4, ms=5, label=label, mfc="none")
            ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.12, lw=0)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(STATIONS, [str(n) for n in STATIONS])
        ax.set_xticks([], minor=True)
        ax.set_title(SCENARIO_TEXT[scenario], fontsize=9)
        ax.set_xlabel("stations n")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(f"{what} error of X [{unit}]")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=len(names), fontsize=9, frameon=False)
    fig.suptitle(f"{what} error of X = T_flange_cam from the same stations: median over {trials} trials, "
                 "band = interquartile range", fontsize=10)
    fig.subplots_adjust(left=0.05, right=0.99, top=0.86, bottom=0.2, wspace=0.08)
    fig.savefig(path, dpi=100)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=100, help="trials per (noise, stations) cell (default 100)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--out", default="docs/figures/axyb-vs-axxb", help="output directory")
    parser.add_argument("--csv", metavar="FILE", help="also write every trial's errors to FILE")
    args = parser.parse_args(argv)

    labels = list(methods())
    print(f"methods: {', '.join(labels)}; {args.trials} trials per cell", flush=True)
    if "auto" not in handeye.list_solvers("axxb"):
        print("note: 'auto' does not solve axxb here; the AX=XB rows use the first of kron-lstsq, park", flush=True)
    work = [(scenario, n, i, trial, args.seed) for scenario in SCENARIOS for i, n in enumerate(STATIONS)
            for trial in range(args.trials)]
    start = time.perf_counter()
    jobs = args.jobs or len(os.sched_getaffinity(0))
    if jobs == 1:
        results = [unit(w) for w in work]
    else:
        with multiprocessing.get_context("fork").Pool(jobs) as pool:
            results = pool.map(unit, work, chunksize=4)
    rows = [r for rs in results for r in rs]
    seconds = time.perf_counter() - start

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.csv:
        with Path(args.csv).open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    stats = summary(rows)
    text = table(stats, labels)
    paired = paired_table(rows, labels)
    (out / "axyb_vs_axxb_table.md").write_text(
        f"X's errors from the same stations ({args.trials} trials per row, seed {args.seed}; bold: the lowest "
        "median of the cell); written by bench/axyb_vs_axxb.py\n\n" + text
        + f"\nPaired: the share of the {args.trials} trials of a cell in which {labels[0]} has the lower error "
          "of X than the other method on the same stations\n\n" + paired)
    for kind, name in (("rot", "rotation"), ("trans", "translation")):
        plot(stats, labels, kind, out / f"axyb_vs_axxb_{name}.png", args.trials)
    print(text)
    print(paired)
    failures = sorted({r["error"] for r in rows if r["error"]})
    for message in failures[:5]:
        print("failed:", message)
    print(f"{len(rows)} solves in {seconds:.0f} s with {jobs} jobs; wrote {out}/axyb_vs_axxb_table.md, "
          "axyb_vs_axxb_rotation.png, axyb_vs_axxb_translation.png" + (f" and {args.csv}" if args.csv else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
