"""Accuracy of `refine` and `auto` on A_i X = X B_i against refine started at the truth, OpenCV's
five hand-eye methods and A X = Y B's refine on the same absolute poses; and auto's time.

    python bench/axxb_refine_study.py [--pairs 8,16,50] [--trials 200] [--seed 0]

Per trial: n = m + 1 stations of the simulator (`problems.axxb.simulate_stations`: the paper's
arm at random joints, the paper's X and Y), noise on the robot AND camera poses
(NoiseModel.on(("A", "B"), 0.002 rad, 0.2 mm)). From the same noisy stations:

- motions "consecutive" (m motions, station k with k + 1) and "all" (every pair i < j,
  n (n - 1) / 2 motions, the pair set cv2.calibrateHandEye forms itself), each solved by
  `auto`, and by `refine` started at the truth ("oracle");
- cv2.calibrateHandEye (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS) on the n absolute poses;
- `refine` of A X = Y B on the n absolute poses (X and Y jointly: the stations' noise is
  independent there, so this is the maximum-likelihood estimate the differenced data lose).

Printed: RMS and median over the trials of the rotation error of X (mrad) and of its translation
error (mm), the ratio of auto's RMS to the oracle's, and the calibration of refine's stated
covariance (RMS of the predicted std over RMS of the error; 1 = calibrated). Then the time of
`handeye.solve("axxb", solver="auto")` at m = 16 (median of --repeats, after a warm-up) and its parts.
"""

from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.problems.axxb import PROBLEM, relative_motions, simulate_stations

NOISE = NoiseModel.on(("A", "B"), 0.002, 0.2)
CV2_METHODS = {"tsai": cv2.CALIB_HAND_EYE_TSAI, "park": cv2.CALIB_HAND_EYE_PARK, "horaud": cv2.CALIB_HAND_EYE_HORAUD,
               "andreff": cv2.CALIB_HAND_EYE_ANDREFF, "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS}


def errors(X: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    e = PROBLEM.errors({"X": X}, {"X": truth})["X"]
    return 1e3 * e["rotation"], e["translation"]


def motion_covariances(A_abs: np.ndarray, B_abs: np.ndarray, X: np.ndarray) -> np.ndarray:
    """First-order covariance (m, 6, 6) of each consecutive motion's residual [r; t] under the
    simulator's noise on the stations (NOISE; true poses ~ noisy ones to first order), motions
    taken as independent: with the motion (i -> j = i + 1), R_A = R_j^T R_i, the rotation noise
    of the motion alpha = a_i - R_A^T a_j and t_A picks up [t_A]_x a_j + R_j^T (u_i - u_j) (likewise
    for B), so r = R_A (alpha - R_X beta) and
    t = -R_A [t_X]_x alpha + [t_A]_x a_j + R_j^T (u_i - u_j) - R_X ([t_B]_x b_j + S_j^T (w_i - w_j))."""
    from handeye.geometry.se3 import skew

    (sa, su), (sb, sw) = NOISE.sigmas["A"], NOISE.sigmas["B"]
    A, B = relative_motions(A_abs, B_abs, "consecutive")
    m = len(A)
    RX, tX = X[:3, :3], X[:3, 3]
    out = np.zeros((m, 6, 6))
    for k in range(m):
        RA, tA, RB, tB = A[k, :3, :3], A[k, :3, 3], B[k, :3, :3], B[k, :3, 3]
        Rj, Sj = A_abs[k + 1, :3, :3], B_abs[k + 1, :3, :3]
        G = np.zeros((6, 24))  # noise: a_i, a_j, b_i, b_j, u_i, u_j, w_i, w_j (3 each)
        dalpha = np.hstack([np.eye(3), -RA.T])  # alpha from (a_i, a_j)
        dbeta = np.hstack([np.eye(3), -RB.T])
        G[:3, 0:6] = RA @ dalpha
        G[:3, 6:12] = -RA @ RX @ dbeta
        G[3:, 0:6] = -RA @ skew(tX) @ dalpha
        G[3:, 3:6] += skew(tA)
        G[3:, 9:12] = -RX @ skew(tB)
        G[3:, 12:15], G[3:, 15:18] = Rj.T, -Rj.T
        G[3:, 18:21], G[3:, 21:24] = -RX @ Sj.T, RX @ Sj.T
        S = np.diag([sa**2] * 6 + [sb**2] * 6 + [su**2] * 6 + [sw**2] * 6)
        out[k] = G @ S @ G.T
    return out


def trial(n: int, seed: int) -> tuple[dict[str, tuple[float, float]], dict[str, tuple[float, float]]]:
    """Errors (mrad, mm) per row, and refine's predicted std (mrad, mm) per motion set."""
    stations, truth = simulate_stations(n, seed=seed, noise=NOISE)
    A_abs, B_abs = stations["A"], stations["B"]
    X = truth["X"]
    out, std = {}, {}
    for pairing in ("consecutive", "all"):
        A, B = relative_motions(A_abs, B_abs, pairing)
        auto = handeye.solve("axxb", A=A, B=B)
        oracle = handeye.solve("axxb", solver="refine", init_X=X, A=A, B=B)
        out[f"auto ({pairing})"] = errors(auto.X, X)
        out[f"oracle ({pairing})"] = errors(oracle.X, X)
        s = oracle.diagnostics["std"]["X"]
        std[pairing] = (1e3 * s["rotation"], s["translation"])
    A, B = relative_motions(A_abs, B_abs, "consecutive")
    C = motion_covariances(A_abs, B_abs, X)
    weighted = handeye.solve("axxb", solver="refine", init_X=X, covariance=C, A=A, B=B)
    out["oracle, per-motion covariance (consecutive)"] = errors(weighted.X, X)
    cam = np.linalg.inv(B_abs)  # T_cam_target
    for name, method in CV2_METHODS.items():
        R, t = cv2.calibrateHandEye(list(A_abs[:, :3, :3]), list(A_abs[:, :3, 3]), list(cam[:, :3, :3]),
                                    list(cam[:, :3, 3]), method=method)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, t.ravel()
        out[f"OpenCV {name.upper()}"] = errors(T, X)
    joint = handeye.solve("axyb", solver="refine", A=A_abs, B=B_abs)
    out["axyb refine (stations)"] = errors(joint.X, X)
    return out, std


def study(pairs: list[int], trials: int, seed: int) -> None:
    print(f"noise on robot and camera poses: 0.002 rad, 0.2 mm; {trials} trials per m; RMS (median) of the errors of X")
    for m in pairs:
        rows: dict[str, list[tuple[float, float]]] = {}
        stds: dict[str, list[tuple[float, float]]] = {}
        for k in range(trials):
            out, std = trial(m + 1, seed + 10007 * m + k)
            for key, v in out.items():
                rows.setdefault(key, []).append(v)
            for key, v in std.items():
                stds.setdefault(key, []).append(v)
        n = m + 1
        print(f"\nm = {m} motions (consecutive) / {n * (n - 1) // 2} (all pairs) from {n} stations")
        print("| estimator | rot X RMS (median) [mrad] | t X RMS (median) [mm] |")
        print("|---|---|---|")
        rms = {}
        for key, v in rows.items():
            a = np.array(v)
            rms[key] = np.sqrt(np.mean(a * a, axis=0))
            med = np.median(a, axis=0)
            print(f"| {key} | {rms[key][0]:.3f} ({med[0]:.3f}) | {rms[key][1]:.4f} ({med[1]:.4f}) |")
        for pairing in ("consecutive", "all"):
            ratio = rms[f"auto ({pairing})"] / rms[f"oracle ({pairing})"]
            predicted = np.sqrt(np.mean(np.square(np.array(stds[pairing])), axis=0))
            calib = predicted / rms[f"oracle ({pairing})"]
            print(f"auto / oracle RMS ({pairing}): rotation {ratio[0]:.4f}, translation {ratio[1]:.4f}; "
                  f"refine's predicted std / observed RMS: rotation {calib[0]:.2f}, translation {calib[1]:.2f}")
        best = min((k for k in rows if k.startswith("OpenCV")), key=lambda k: rms[k][0])
        best_t = min((k for k in rows if k.startswith("OpenCV")), key=lambda k: rms[k][1])
        print(f"best OpenCV: rotation {best} {rms[best][0]:.3f}, translation {best_t} {rms[best_t][1]:.4f}")


def timing(repeats: int) -> None:
    data, truth = PROBLEM.simulate(pairs=16, seed=0, noise=NOISE)
    rows = {"auto": {}, "refine (init_X = truth)": {"solver": "refine", "init_X": truth["X"]}}
    for start in handeye.list_solvers("axxb"):
        if start in ("so3-sdp", "kron-lstsq", "park"):
            rows[start] = {"solver": start}
    print(f"\ntime of handeye.solve('axxb', ...) at m = 16: median of {repeats} (call; solver's run)")
    for label, options in rows.items():
        handeye.solve("axxb", **options, **data)
        calls, runs = [], []
        for _ in range(repeats):
            t = time.perf_counter()
            sol = handeye.solve("axxb", **options, **data)
            calls.append(time.perf_counter() - t)
            runs.append(sol.seconds)
        print(f"  {label:26s} {1e3 * statistics.median(calls):7.2f} ms; run {1e3 * statistics.median(runs):7.2f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pairs", default="8,16,50")
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    study([int(p) for p in args.pairs.split(",")], args.trials, args.seed)
    timing(args.repeats)


if __name__ == "__main__":
    main()
