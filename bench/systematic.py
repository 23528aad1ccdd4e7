"""The self-check's test for systematic robot errors (handeye.checks.systematic): how often it
fires on arms with DH errors, how often on plain noise, and on KinHEC (docs/reliability.md).

    python bench/systematic.py                      # simulations: detection and false alarms
    python bench/systematic.py --compare            # the candidate statistics side by side
    python bench/systematic.py --kinhec DIR [DIR..] # KinHEC datasets (kinhec generate ...)

Detection: `axyb-kinematic`'s simulator (the LR Mate-like arm, A the nominal forward kinematics
of the joint readings, the true flange poses those of the arm with DH errors), its DH errors
(offsets and twists 0.1-0.5 deg, a and d 0.2-1 mm, random signs) times a factor, joint noise
0.005 deg, camera noise 0.002 rad / 0.5 mm; solved as `axyb` by `auto`, the warning read from the
answer's self-check. False alarms: `axyb`'s simulator with plain noise, robot and camera noise,
a camera's rotation noise in the board's frame (a lever arm of ~1 m: tests/estimation/test_noise_sources.py),
a robot's rotation noise in the base frame (lever arm: the flange's distance from the base) and
heavy noise, at 8 to 60 stations.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

import handeye
from handeye.checks import best_fit, self_check, systematic
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import pose_errors
from handeye.geometry.kinematics import LR_MATE_200ID, simulate_stations
from handeye.geometry.se3 import make_pose, so3_exp
from handeye.problems.axyb import PROBLEM as AXYB
from handeye.problems.axyb_kinematic.problem import PROBLEM as KINEMATIC
from handeye.problems.axyb_kinematic.problem import random_errors

DH_FACTORS = (0.05, 0.1, 0.2, 0.5, 1.0)
STATIONS = (15, 30, 50)
NULL_KINDS = ("camera", "robot+camera", "lever-camera", "lever-robot", "heavy")
NULL_STATIONS = (8, 15, 30, 60)


def dh_data(m: int, seed: int, factor: float) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Stations of the LR Mate-like arm with its DH errors (`random_errors`) times `factor`."""
    errors = factor * random_errors(LR_MATE_200ID.table, np.random.default_rng(10_000 + seed))
    noise = NoiseModel({"A": (math.radians(0.005), 0.0), "B": (0.002, 0.5)})
    data, truth = KINEMATIC.simulate(pairs=m, seed=seed, errors=errors, noise=noise)
    return data["A"], data["B"], truth


def null_data(kind: str, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Stations of a perfect arm with noise of `kind` (module docstring)."""
    rng = np.random.default_rng(seed + 777)
    if kind == "camera":
        d, _ = simulate_stations(m, seed=seed, noise=NoiseModel({"B": (0.002, 0.5)}))
    elif kind == "robot+camera":
        d, _ = simulate_stations(m, seed=seed, noise=NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)}))
    elif kind == "lever-camera":  # B <- exp(xi) B: rotation noise in the board's frame
        d, _ = simulate_stations(m, seed=seed)
        d["B"] = np.stack([make_pose(so3_exp(rng.normal(0.0, 0.002, 3)), rng.normal(0.0, 0.2, 3)) @ B for B in d["B"]])
    elif kind == "lever-robot":  # A <- exp(omega) A: rotation noise in the base frame
        d, _ = simulate_stations(m, seed=seed, noise=NoiseModel({"B": (0.0005, 0.1)}))
        d["A"] = np.stack([make_pose(so3_exp(rng.normal(0.0, 0.0005, 3)), np.zeros(3)) @ A for A in d["A"]])
    elif kind == "heavy":
        d, _ = simulate_stations(m, seed=seed, noise=NoiseModel({"B": (0.01, 2.0)}))
    else:
        raise ValueError(kind)
    return d["A"], d["B"]


def verdict(sol: handeye.Solution) -> tuple[bool, float]:
    """(the warning fired, the test's p-value or nan when it did not run)."""
    fig = sol.diagnostics.get("self_check", {}).get("systematic")
    fired = any("follow the arm's configuration" in w for w in sol.warnings)
    return fired, float(fig["p_value"]) if fig else math.nan


def x_sigmas(sol: handeye.Solution, X_true: np.ndarray) -> tuple[float, float, float]:
    """(X rotation error deg, translation error (data unit), the larger of each over auto's
    stated 1-sigma of it (worst direction))."""
    err = pose_errors({"X": sol.unknowns["X"]}, {"X": X_true}, ("X",))["X"]
    std = sol.diagnostics.get("self_check", {}).get("std", {}).get("X")
    rot = math.degrees(err["rotation"])
    if not std:
        return rot, err["translation"], math.nan
    return rot, err["translation"], max(rot / std["rotation_deg"], err["translation"] / std["translation"])


def detection(seeds: int) -> None:
    print(f"Detection on arms with DH errors ({seeds} seeds per cell): share warned; median p; "
          "median X error in auto's sigmas")
    print("| DH factor (offsets/twists deg, a/d mm) | " + " | ".join(f"m = {m}" for m in STATIONS) + " |")
    print("|---|" + "---|" * len(STATIONS))
    for factor in DH_FACTORS:
        cells = []
        for m in STATIONS:
            fired, ps, sig = [], [], []
            for seed in range(seeds):
                A, B, truth = dh_data(m, seed, factor)
                sol = handeye.solve("axyb", A=A, B=B)
                f, p = verdict(sol)
                fired.append(f)
                ps.append(p)
                sig.append(x_sigmas(sol, truth["X"])[2])
            cells.append(f"{np.mean(fired):.0%} (p {np.nanmedian(ps):.1g}; {np.nanmedian(sig):.1f} sigma)")
        lo, hi = 0.1 * factor, 0.5 * factor
        print(f"| {factor:g} ({lo:.2g}-{hi:.2g} deg, {0.2 * factor:.2g}-{factor:.2g} mm) | " + " | ".join(cells) + " |")


def false_alarms(seeds: int) -> None:
    print(f"\nFalse alarms on perfect arms ({seeds} seeds per cell): warned / data sets (smallest p)")
    print("| noise | " + " | ".join(f"m = {m}" for m in NULL_STATIONS) + " |")
    print("|---|" + "---|" * len(NULL_STATIONS))
    total = fired_total = 0
    for kind in NULL_KINDS:
        cells = []
        for m in NULL_STATIONS:
            fired, ps = 0, []
            for seed in range(seeds):
                A, B = null_data(kind, m, seed)
                f, p = verdict(handeye.solve("axyb", A=A, B=B))
                fired += f
                ps.append(p)
            total += seeds
            fired_total += fired
            cells.append(f"{fired}/{seeds} ({np.nanmin(ps):.1g})" if not np.all(np.isnan(ps)) else f"{fired}/{seeds} (not run)")
        print(f"| {kind} | " + " | ".join(cells) + " |")
    print(f"all: {fired_total} of {total} warned ({fired_total / total:.2%})")


# ------------------------------------------------------------------ the candidates, side by side

def _fit(A: np.ndarray, B: np.ndarray) -> tuple[Any, Any, np.ndarray, np.ndarray]:
    sol = handeye.solve("axyb", A=A, B=B)
    data = AXYB.validate(A=A, B=B)
    model, poses, _ = AXYB.check_model(data, sol.unknowns)
    fit, cov, flagged, res, _, _ = best_fit.best_fit(model, poses)
    return sol, model, res, cov


def _neighbours(A: np.ndarray, ew: np.ndarray, k: int = 3, perms: int = 300) -> float:
    """Nearest-neighbour autocorrelation of the residuals' directions (stations close in flange
    pose: position over its RMS spread and rotation angle in rad), as a z-score against a
    permutation null."""
    m = len(A)
    p = A[:, :3, 3] - A[:, :3, 3].mean(0)
    dp = np.linalg.norm(p[:, None] - p[None], axis=2) / math.sqrt(float(np.mean(np.sum(p * p, axis=1))))
    cos = (np.einsum("iab,jab->ij", A[:, :3, :3], A[:, :3, :3]) - 1.0) / 2.0
    D = np.hypot(dp, np.arccos(np.clip(cos, -1.0, 1.0)))
    np.fill_diagonal(D, np.inf)
    W = np.zeros((m, m))
    W[np.repeat(np.arange(m), k), np.argsort(D, axis=1)[:, :k].ravel()] = 1.0
    W = W + W.T
    u = ew / np.linalg.norm(ew, axis=1, keepdims=True)
    G = u @ u.T
    rng = np.random.default_rng(0)
    null = np.array([np.sum(W * G[np.ix_(P, P)]) for P in (rng.permutation(m) for _ in range(perms))])
    return float((np.sum(W * G) - null.mean()) / null.std())


def _halves(A: np.ndarray, B: np.ndarray, sol: handeye.Solution) -> float:
    """Chow test: X and Y fitted on each half of the workspace (split at the median along the
    flange positions' principal direction), d^2 = delta^T (Sigma_1 + Sigma_2)^-1 delta, as a
    chi^2(12) p-value."""
    from scipy.stats import chi2

    p = A[:, :3, 3] - A[:, :3, 3].mean(0)
    s = p @ np.linalg.svd(p, full_matrices=False)[2][0]
    fits, covs = [], []
    for half in (s <= np.median(s), s > np.median(s)):
        data = AXYB.validate(A=A[half], B=B[half])
        model, poses, _ = AXYB.check_model(data, sol.unknowns)
        fit, cov, *_ = best_fit.best_fit(model, poses)
        fits.append(fit)
        covs.append(cov)
    delta = self_check._difference(fits[0], fits[1])
    return float(chi2.sf(delta @ np.linalg.solve(covs[0] + covs[1], delta), 12))


def compare(seeds: int) -> None:
    """Each candidate's rate at its own false-alarm level: F tests at p < P_WARN; the
    neighbours' z > 3.1 (p ~ 1e-3 one-sided); the halves' chi^2 p < P_WARN."""
    print(f"\nCandidates ({seeds} seeds per cell, m = 30): share flagged")
    rows = {"F, position (18 regressors)": [], "F, position + rotation matrix (72)": [],
            "F, position, no decorrelation": [], "neighbours (k = 3, permutations)": [],
            "held-out halves (Chow)": []}
    cases = [("DH x%g" % f, lambda s, f=f: dh_data(30, s, f)[:2]) for f in (0.2, 0.5, 1.0)]
    cases += [(kind, lambda s, k=kind: null_data(k, 30, s)) for kind in ("camera", "lever-camera", "lever-robot")]
    header = [c[0] for c in cases]
    for name, make in cases:
        hits = {r: 0 for r in rows}
        for seed in range(seeds):
            A, B = make(seed)
            sol, model, res, _ = _fit(A, B)
            ew = res.W.residual(res.e)
            J = res.W.jacobian(model.jacobian(res.poses, res.e))
            Z = systematic.position_features(A)
            R = A[:, :3, :3].reshape(len(A), 9)
            hits["F, position (18 regressors)"] += systematic.configuration_test(ew, J, Z)["p_value"] < systematic.P_WARN
            out = systematic.configuration_test(ew, J, np.hstack([Z, R - R.mean(0)]))
            hits["F, position + rotation matrix (72)"] += out is not None and out["p_value"] < systematic.P_WARN
            hits["F, position, no decorrelation"] += _plain_f(ew, J, Z) < systematic.P_WARN
            hits["neighbours (k = 3, permutations)"] += _neighbours(A, ew) > 3.1
            try:
                hits["held-out halves (Chow)"] += _halves(A, B, sol) < systematic.P_WARN
            except Exception:  # a half that cannot be fitted
                pass
        for r in rows:
            rows[r].append(hits[r] / seeds)
    print("| statistic | " + " | ".join(header) + " |")
    print("|---|" + "---|" * len(header))
    for r, v in rows.items():
        print(f"| {r} | " + " | ".join(f"{x:.0%}" for x in v) + " |")


def _plain_f(ew: np.ndarray, J: np.ndarray, Z: np.ndarray) -> float:
    """The F test with the per-group weights only (no 6x6 decorrelation)."""
    from scipy.stats import f as fdist

    m, q = len(ew), Z.shape[1]
    Q, _ = np.linalg.qr(J.reshape(6 * m, -1))
    D = np.zeros((m, 6, 6, q))
    D[:, np.arange(6), np.arange(6), :] = Z[:, None, :]
    D = D.reshape(6 * m, 6 * q)
    D -= Q @ (Q.T @ D)
    y = ew.ravel() - Q @ (Q.T @ ew.ravel())
    U = np.linalg.svd(D, full_matrices=False)[0]
    k = U.shape[1]
    dof = 6 * m - Q.shape[1] - k
    ex = float(np.sum((U.T @ y) ** 2))
    return float(fdist.sf((ex / k) / ((float(y @ y) - ex) / dof), k, dof))


# ------------------------------------------------------------------ KinHEC

def kinhec(dirs: list[str], csv: str | None = None) -> None:
    """Every sequence of the datasets (oracle synchronisation, KinHEC's keyframes), solved as
    axyb by auto: whether the warning fired, the test's p, and X's error in auto's sigmas."""
    import pandas as pd
    from kinhec.benchmark import _keyframe_data
    from kinhec.io import load_sequence

    rows = []
    for root in dirs:
        table = pd.read_csv(f"{root}/sequences.csv")
        for _, info in table.iterrows():
            seq = load_sequence(root, info.sequence_id)
            data = _keyframe_data(seq, None if seq.synchronous else seq.time_offset)
            if data is None:
                continue
            try:
                sol = handeye.solve("axyb", A=data[0], B=data[1])  # as handeye:auto in KinHEC's protocol
            except handeye.HandEyeError:
                continue
            fired, p = verdict(sol)
            rot, trans, sig = x_sigmas(sol, seq.X)
            dh = (info.dh_len_std_m or 0) > 0 or (info.dh_ang_std_rad or 0) > 0
            rows.append((info.sequence_id, info.track, info.robot, dh, len(data[0]), fired, p, rot, 1000 * trans, sig,
                         sol.status.value))
    df = pd.DataFrame(rows, columns=["sequence", "track", "robot", "dh_errors", "m", "warned", "p", "X_rot_deg",
                                     "X_mm", "X_sigmas", "status"])
    print(f"\nKinHEC ({len(df)} sequences solved)")
    print(f"| track | DH errors | sequences | warned (p < {systematic.P_WARN:g}) | p < 0.01 | X beyond 5 sigma | of those warned |")
    print("|---|---|---|---|---|---|---|")
    for (track, dh), g in df.groupby(["track", "dh_errors"]):
        far = g[g.X_sigmas > 5]
        print(f"| {track} | {'yes' if dh else 'no'} | {len(g)} | {int(g.warned.sum())} | {int((g.p < 0.01).sum())} | "
              f"{len(far)} | {int(far.warned.sum())} |")
    if csv:
        df.to_csv(csv, index=False)
    far = df[df.X_sigmas > 5].sort_values("X_sigmas", ascending=False)
    print("\nX beyond 5 of auto's sigmas:")
    print(far.to_string(index=False))
    print("\nwarned:")
    print(df[df.warned | (df.p < 0.01)].sort_values("p").to_string(index=False))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20, help="data sets per cell (default 20)")
    parser.add_argument("--compare", action="store_true", help="the candidate statistics side by side")
    parser.add_argument("--kinhec", nargs="+", metavar="DIR", help="KinHEC datasets (kinhec generate --out DIR)")
    parser.add_argument("--csv", help="with --kinhec: every sequence's figures to this CSV file")
    args = parser.parse_args()
    t0 = time.perf_counter()
    if args.kinhec:
        kinhec(args.kinhec, args.csv)
    elif args.compare:
        compare(args.seeds)
    else:
        detection(args.seeds)
        false_alarms(args.seeds)
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
