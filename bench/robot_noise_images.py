"""Board images from an imperfect robot: the joint fit of corners, robot-pose corrections and both
noises (``reprojection``'s default, plugins/reprojection/robot_noise.py) against the corner fit
with the robot's poses taken as exact, the pose-based ``auto`` and OpenCV.

1. Simulated (known truth): per setup and seed, 20 stations of a 9 x 6 board seen by a 1280 x 960
   camera (`handeye.problems.axyb.images`), 0.3 px of noise on the corners and robot pose noise
   ROBOT_NOISE (0.0005 rad and 0.3 mm per axis, in the flange frame: about 3x the pixel noise's
   effect on a board 350-750 mm away). Answers: the joint fit; the joint fit started at the
   truth (the floor); the corner fit with exact robot poses (robot_noise="none"); auto on the
   PnP poses. Printed: RMS over the seeds of each error, and the ratios (targets: joint within
   1.05x of the floor, below both others).
2. Real (no truth): the bundled circle-grid set (eye in hand) and the industrial_calibration
   ChArUco set (eye to hand, /work/shared/data), through `handeye.calibrate`'s detection and
   intrinsics. Each answer is fitted on 2 of 3 folds of the stations and predicts the corners of
   the third through its X, Y and the held-out robot poses (plugins/reprojection/held_out.py):
   RMS pixel error over every held-out corner. Contenders: the joint fit, the exact-robot corner
   fit, auto on the poses, OpenCV's calibrateRobotWorldHandEye (SHAH) and calibrateHandEye PARK
   (Y then the chordal mean of A_i X B_i^-1, as OpenCV users do).

Usage: python bench/robot_noise_images.py [--seeds 20] [--folds 3]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose
from handeye.plugins.reprojection.held_out import held_out

ROBOT_NOISE = (0.0005, 0.3)
PROBLEM = handeye.get_registry().problem("axyb")
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def simulated(seeds: int) -> None:
    if seeds == 0:
        return
    names = ("joint", "floor", "exact robot", "auto (poses)")
    for setup in ("eye-in-hand", "eye-to-hand"):
        errs = {n: [] for n in names}
        seconds = {n: [] for n in names}
        for seed in range(seeds):
            truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
            data, _ = PROBLEM.simulate(pairs=20, seed=seed, noise=NoiseModel({"A": ROBOT_NOISE, "B": (1.0, 1.0)}),
                                       images={"setup": setup, "pixel_noise": 0.3}, **truth)
            poses = {k: v for k, v in data.items() if k != "images"}
            runs = {"joint": lambda: handeye.solve("axyb", solver="reprojection", **data),
                    "floor": lambda: handeye.solve("axyb", solver="reprojection", init_X=truth["X"], init_Y=truth["Y"], **data),
                    "exact robot": lambda: handeye.solve("axyb", solver="reprojection", robot_noise="none", **data),
                    "auto (poses)": lambda: handeye.solve("axyb", **poses)}
            for name, run in runs.items():
                t = time.perf_counter()
                sol = run()
                seconds[name].append(time.perf_counter() - t)
                e = PROBLEM.errors(sol.unknowns, truth)
                errs[name].append([e["X"]["rotation"], e["X"]["translation"], e["Y"]["rotation"], e["Y"]["translation"]])
        rms = {n: np.sqrt(np.mean(np.array(errs[n]) ** 2, axis=0)) for n in names}
        print(f"\n## simulated, {setup}, {seeds} seeds: RMS errors (X rad, X mm, Y rad, Y mm), median s")
        for n in names:
            print(f"| {n} | " + " | ".join(f"{v:.3g}" for v in rms[n]) + f" | {np.median(seconds[n]):.3f} |")
        for n in ("floor", "exact robot", "auto (poses)"):
            print(f"joint / {n}: " + ", ".join(f"{v:.3f}" for v in rms["joint"] / rms[n]))


def chordal_mean(T: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(T[:, :3, :3].sum(axis=0))
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return make_pose(R, T[:, :3, 3].mean(axis=0))


def opencv_park(data) -> dict[str, np.ndarray]:
    """X by cv2.calibrateHandEye (PARK), Y the chordal mean of A_i X B_i^-1 (eye in hand) or X the
    mean of A_i^-1 Y B_i from Y (eye to hand, robot poses inverted, as OpenCV's docs say)."""
    import cv2

    A, B = np.asarray(data.A), np.asarray(data.B)
    if data.images.setup == "eye-in-hand":  # B = T_target_cam: OpenCV wants target2cam = B^-1
        Bi = inverse(B)
        R, t = cv2.calibrateHandEye(A[:, :3, :3], A[:, :3, 3], Bi[:, :3, :3], Bi[:, :3, 3], method=cv2.CALIB_HAND_EYE_PARK)
        X = make_pose(R, t.ravel())
        return {"X": X, "Y": chordal_mean(A @ X @ inverse(B))}
    Ai = inverse(A)  # eye to hand: base2gripper in, cam2base (our Y) out; B = T_cam_marker = target2cam
    R, t = cv2.calibrateHandEye(Ai[:, :3, :3], Ai[:, :3, 3], B[:, :3, :3], B[:, :3, 3], method=cv2.CALIB_HAND_EYE_PARK)
    Y = make_pose(R, t.ravel())
    return {"X": chordal_mean(Ai @ Y @ B), "Y": Y}


def calibrated(cell):
    """(handeye.calibrate's result, the validated data its solve was given: poses, corners and
    intrinsics as the library made them)."""
    from handeye.workflow import calibration

    given = {}
    solve = calibration.solve

    def keep(problem, **kwargs):
        given.setdefault("data", {k: kwargs[k] for k in ("A", "B", "images")})
        return solve(problem, **kwargs)

    calibration.solve = keep
    try:
        result = handeye.calibrate(cell)
    finally:
        calibration.solve = solve
    return result, PROBLEM.validate(**given["data"])


def real(folds: int) -> None:
    from handeye.workflow.cell import Cell, Images, Matching, PoseStream

    circle = Path(handeye.__file__).parent / "data" / "rct_circle_grid"
    charuco = SHARED / "industrial_calibration_rct" / "test_set_charuco"
    sets = {"circle grid, eye in hand": Cell(robot=PoseStream(circle / "poses", format="xyz-quat-xyzw", unit="m"),
                                             images=Images(circle / "images", board="circlegrid:10x10:25.4mm"),
                                             setup="eye-in-hand")}
    if charuco.is_dir():
        sets["ChArUco, eye to hand"] = Cell(robot=PoseStream(charuco / "poses", format="xyz-quat-xyzw", unit="m"),
                                            images=Images(charuco / "images", board="charuco:5x7:36.195mm:18.256mm:DICT_6X6_250"),
                                            setup="eye-to-hand", matching=Matching(method="name"))
    for title, cell in sets.items():
        result, data = calibrated(cell)
        poses_only = lambda d: {"A": d.A, "B": d.B}  # noqa: E731
        fitters = {
            "joint (default)": lambda d: handeye.solve("axyb", solver="reprojection", **poses_only(d), images=d.images).unknowns,
            "exact robot": lambda d: handeye.solve("axyb", solver="reprojection", robot_noise="none", **poses_only(d),
                                                   images=d.images).unknowns,
            "auto (poses)": lambda d: handeye.solve("axyb", **poses_only(d)).unknowns,
            "OpenCV SHAH": lambda d: handeye.solve("axyb", solver="opencv", **poses_only(d)).unknowns,
            "OpenCV PARK": opencv_park,
        }
        found = held_out(data, fitters, folds)
        joint = handeye.solve("axyb", solver="reprojection", **poses_only(data), images=data.images)
        rn = joint.diagnostics.get("robot_noise", {})
        print(f"\n## {title}: {len(data.A)} stations, {folds} folds; held-out corner RMS (px); calibrate chose "
              f"{result.solver}")
        print(f"joint fit: pixels {joint.diagnostics['sigma_px']:.3g} px per axis, robot {rn.get('rotation', 0):.3g} rad "
              f"/ {rn.get('translation', 0) * 1000:.3g} mm per axis (flange frame)")
        for name, px in found.items():
            print(f"| {name} | {'failed' if px is None else f'{px:.3f}'} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--folds", type=int, default=3)
    args = parser.parse_args()
    simulated(args.seeds)
    real(args.folds)


if __name__ == "__main__":
    main()
