"""The self-check's warning for a camera scale a little off (docs/camera-scale.md, "A metric
camera whose scale is a little off"): how often it fires where one camera's translations are a
little too long, how often on exact cameras, and on KinHEC.

    python bench/scale_effect.py                  # one camera: detection and false alarms
    python bench/scale_effect.py --cells          # cells of several cameras
    python bench/scale_effect.py --kinhec DIR     # a KinHEC dataset (kinhec generate ...)

Detection: axyb's simulator with the accuracy study's noise (A 0.0002 rad / 0.05 mm, B 0.002 rad
/ 0.5 mm), the camera's translations times 1.001-1.005; counted: warned, and answers whose Y is
more than 5 of its stated 1-sigma (worst direction) off without the warning. False alarms: the
five noise kinds of bench/systematic.py at 8-60 stations. Cells: `simulate_cell`, camera 3's
translations (eye in hand: camera 1's) 0.2-0.3% long; exact cells with cameras alike and 0.25-4x each other's noise.
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np
from systematic import NULL_KINDS, NULL_STATIONS, null_data, x_sigmas

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.problems.axyb import PROBLEM as AXYB
from handeye.problems.axyb_multi import simulate_cell

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def warned(sol: handeye.Solution) -> bool:
    return any("fit the robot's best" in w and "stated 1-sigma" in w for w in sol.warnings)


def detection(seeds: int) -> None:
    print("| camera translations too long by | stations | warned | Y off > 5 sigma without the warning (before -> now) |")
    print("|---|---|---|---|")
    for factor in (1.001, 1.002, 1.003, 1.005):
        for m in (15, 30, 60):
            hits = before = after = 0
            for seed in range(seeds):
                data, truth = AXYB.simulate(pairs=m, seed=seed, noise=NOISE)
                B = np.array(data["B"])
                B[:, :3, 3] *= factor
                sol = handeye.solve("axyb", A=data["A"], B=B)
                std = sol.diagnostics["self_check"]["std"]["Y"]["translation"]
                off = np.linalg.norm(sol.Y[:3, 3] - truth["Y"][:3, 3]) > 5 * std
                hits += warned(sol)
                before += off
                after += off and not warned(sol)
            print(f"| {100 * (factor - 1):.1f}% | {m} | {hits}/{seeds} | {before} -> {after} |")


def false_alarms(seeds: int) -> None:
    counts: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    for kind in NULL_KINDS:
        for m in NULL_STATIONS:
            for seed in range(seeds):
                A, B = null_data(kind, m, seed)
                try:
                    sol = handeye.solve("axyb", A=A, B=B)
                except handeye.HandEyeError:
                    continue
                counts[kind][0] += warned(sol)
                counts[kind][1] += 1
    print("\nexact cameras, warned: " + ", ".join(f"{k} {w}/{n}" for k, (w, n) in counts.items()))


def cells(seeds: int) -> None:
    print("| cell | stations | cameras | warned |")
    print("|---|---|---|---|")
    for setup in ("eye-to-hand", "eye-in-hand"):
        for m in (20, 50):
            for kind in ("alike", "0.25-4x noise", "one camera 0.2% long", "one camera 0.3% long"):
                hits = named = 0
                for seed in range(seeds):
                    count = 8 if setup == "eye-to-hand" else 2
                    spread = {f"cam{k}": float(np.exp(np.random.default_rng(100 * seed + k).uniform(np.log(0.25), np.log(4))))
                              for k in range(count)} if kind.startswith("0.25") else None
                    cell = simulate_cell(m, seed=seed, setup=setup, camera_noise=spread, noise=NOISE)
                    data = dict(cell.data)
                    if "long" in kind:
                        rows = np.asarray(data["y_index" if setup == "eye-to-hand" else "x_index"]) == (3 if setup == "eye-to-hand" else 1)
                        B = np.array(data["B"])
                        B[rows, :3, 3] *= 1.002 if "0.2" in kind else 1.003
                        data["B"] = B
                    sol = handeye.solve("axyb-multi", **data)
                    hits += warned(sol)
                    target = "'cam3'" if setup == "eye-to-hand" else "'cam1'"
                    named += any(target in w for w in sol.warnings if "stated 1-sigma" in w)
                extra = f" ({named} naming the camera)" if "long" in kind else ""
                print(f"| {setup} | {m} | {kind} | {hits}/{seeds}{extra} |")


def kinhec(root: str) -> None:
    import pandas as pd
    from kinhec.benchmark import _keyframe_data
    from kinhec.io import load_sequence

    rows = []
    for _, info in pd.read_csv(f"{root}/sequences.csv").iterrows():
        seq = load_sequence(root, info.sequence_id)
        data = _keyframe_data(seq, None if seq.synchronous else seq.time_offset)
        if data is None:
            continue
        try:
            sol = handeye.solve("axyb", A=data[0], B=data[1])
        except handeye.HandEyeError:
            continue
        std = sol.diagnostics["self_check"].get("std", {})
        y_sigmas = (float(np.linalg.norm(sol.Y[:3, 3] - seq.Y[:3, 3]) / std["Y"]["translation"])
                    if "Y" in std and getattr(seq, "Y", None) is not None else float("nan"))
        dh = (info.dh_len_std_m or 0) > 0 or (info.dh_ang_std_rad or 0) > 0
        rows.append((info.sequence_id, info.track, dh, len(data[0]), warned(sol), x_sigmas(sol, seq.X)[2], y_sigmas))
    df = pd.DataFrame(rows, columns=["sequence", "track", "dh_errors", "m", "warned", "X_sigmas", "Y_sigmas"])
    print(f"KinHEC: {len(df)} sequences solved, {int(df.warned.sum())} warned")
    print(df[df.warned].to_string(index=False))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--cells", action="store_true")
    parser.add_argument("--kinhec", metavar="DIR")
    args = parser.parse_args()
    t0 = time.perf_counter()
    if args.kinhec:
        kinhec(args.kinhec)
    elif args.cells:
        cells(min(args.seeds, 30))
    else:
        detection(args.seeds)
        false_alarms(5 * args.seeds)
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
