"""The planar (4-DOF) mode on simulated SCARA cells (handeye.problems.planar, docs/planar.md).

Per seed a SCARA-like eye-in-hand cell (`planar.simulate`: flange rotating about the base z only,
15 stations by default, noise on robot and camera poses), solved

- in planar mode: `auto` with the true tz_X (60 mm);
- as before the mode existed: the same solvers with the planar detection switched off (the
  validation of the time), so that they solve the 6-DOF problem the data do not determine:
  `auto`, `kron-lstsq`, `dual-quaternion` (axyb); `auto`, `kron-lstsq`, `park`, `daniilidis` (axxb,
  every pair of stations).

Printed per (problem, solver, status): median and max over the seeds of the rotation error (deg),
translation error and its component along the axis (mm) of each unknown.

Usage: python bench/planar.py [--seeds 20] [--stations 15] [--rot 0.002] [--trans 0.2]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.host.registry import get_registry
from handeye.problems import planar

BEFORE = {"axyb": ("auto", "kron-lstsq", "dual-quaternion"), "axxb": ("auto", "kron-lstsq", "park", "daniilidis")}


def errors(problem: str, unknowns, truth) -> dict[str, tuple[float, float, float]]:
    """Per unknown: rotation error (deg), translation error, its component along z (the axis)."""
    out = {}
    for name, e in get_registry().problem(problem).errors(unknowns, truth).items():
        dz = float(np.asarray(unknowns[name])[2, 3] - truth[name][2, 3])
        out[name] = (float(np.rad2deg(e["rotation"])), e["translation"], dz)
    return out


def before(problem: str, solver: str, data) -> handeye.Solution:
    """The solve with planar detection off: what handeye did before the mode."""
    saved = planar.for_axyb, planar.for_axxb
    planar.for_axyb = planar.for_axxb = lambda *args, **kwargs: None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return handeye.solve(problem, **data, solver=solver)
    finally:
        planar.for_axyb, planar.for_axxb = saved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--stations", type=int, default=15)
    parser.add_argument("--rot", type=float, default=0.002, help="rotation noise (rad) on robot and camera poses")
    parser.add_argument("--trans", type=float, default=0.2, help="translation noise (mm) on robot and camera poses")
    args = parser.parse_args()
    noise = NoiseModel.on(("A", "B"), args.rot, args.trans)
    rows: dict[tuple[str, str, str], list] = {}
    for seed in range(args.seeds):
        for problem in ("axyb", "axxb"):
            data, truth = planar.simulate(problem, args.stations, seed=seed, noise=noise)
            sol = handeye.solve(problem, **data, tz_X=float(truth["X"][2, 3]))
            rows.setdefault((problem, "auto, planar mode", str(sol.status)), []).append(errors(problem, sol.unknowns, truth))
            for solver in BEFORE[problem]:
                try:
                    sol = before(problem, solver, data)
                except handeye.HandEyeError as exc:
                    rows.setdefault((problem, f"{solver}, before", type(exc).__name__), []).append(None)
                    continue
                rows.setdefault((problem, f"{solver}, before", str(sol.status)), []).append(
                    errors(problem, sol.unknowns, truth))
    print(f"{args.seeds} seeds, {args.stations} stations, noise {args.rot} rad / {args.trans} mm on robot and camera")
    for (problem, solver, status), found in sorted(rows.items()):
        print(f"{problem:5} {solver:28} {status:22} n={len(found)}")
        done = [f for f in found if f is not None]
        for name in done[0] if done else ():
            e = np.array([f[name] for f in done])
            print(f"      {name}: rotation {np.median(e[:, 0]):.3g} deg (max {e[:, 0].max():.3g})   translation "
                  f"{np.median(e[:, 1]):.3g} mm (max {e[:, 1].max():.3g})   along the axis "
                  f"{np.median(np.abs(e[:, 2])):.3g} mm (max {np.abs(e[:, 2]).max():.3g})")


if __name__ == "__main__":
    main()
