"""Intrinsics calibrated from the same images, or given in a file: is the stated 1-sigma honest?

1. z-scores (``--trials``): simulated image sets (`handeye.problems.axyb.images`: 15 stations
   of a 9 x 6 board, 0.3 px corner noise, robot noise ROBOT_NOISE) whose intrinsics are
   calibrated from the same corners (`handeye.vision.intrinsics.calibrate_camera`, as
   ``handeye calibrate --images`` does without --intrinsics, their 1-sigma the larger of
   OpenCV's and a jackknife's over the images), the board poses by PnP with them.
   Answers: the corner fit (``reprojection``, its 1-sigma widened by the intrinsics',
   plugins/reprojection) and the pose-based ``auto`` widened by re-solving
   (`handeye.workflow.solving.pose_based_intrinsics`). Printed per setup and answer: RMS over
   the trials of |translation error| / translation 1-sigma of X and Y (target 0.7-1.4), with
   the intrinsics' share and without it.
2. The file-intrinsics check (``--detect``): the same simulated sets with the true intrinsics
   given, and with the focal length 0.3%, 0.5%, 1%, 2% off; and the real ChArUco set
   (/work/shared/data) with its cal_data.yaml intrinsics scaled likewise. Printed: how often
   `handeye.vision.intrinsics_check.focal_check` warns (false alarms at 0%, detections above).

Usage: python bench/intrinsics_uncertainty.py [--trials 40] [--detect 40]
"""

from __future__ import annotations

import argparse
import dataclasses
import types
from pathlib import Path

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.vision.camera_poses import board_pose
from handeye.vision.intrinsics import calibrate_camera
from handeye.vision.intrinsics_check import with_jackknife
from handeye.workflow.solving import pose_based_intrinsics

PROBLEM = handeye.get_registry().problem("axyb")
#: robot pose noise per axis (rad, mm): about the pixel noise's share of the board poses
ROBOT_NOISE = (0.0005, 0.3)
STATIONS = 15
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def simulated(seed: int, setup: str, stations: int = STATIONS) -> tuple[dict, dict, np.ndarray, object]:
    """(truth, data {A, B, images} with intrinsics calibrated from the corners, the board poses
    T_cam_target, the calibration) of one simulated image set."""
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    data, _ = PROBLEM.simulate(pairs=stations, seed=seed, noise=NoiseModel({"A": ROBOT_NOISE, "B": (1.0, 1.0)}),
                               images={"setup": setup, "pixel_noise": 0.3}, **truth)
    obs = data["images"]
    views = [types.SimpleNamespace(image_points=u, object_points=p) for u, p in zip(obs.image_points, obs.object_points)]
    cal = with_jackknife(calibrate_camera(views, obs.camera.size), views, obs.camera.size)  # as images_and_poses
    T = np.array([board_pose(p, u, cal.camera).T_cam_target for u, p in zip(obs.image_points, obs.object_points)])
    images = dataclasses.replace(obs, camera=cal.camera, intrinsics_std=tuple(cal.std_fx_fy_cx_cy))
    return truth, {"A": data["A"], "B": inverse(T) if setup == "eye-in-hand" else T, "images": images}, T, cal


def z_scores(trials: int) -> None:
    if trials == 0:
        return
    print(f"\n## z-scores: RMS of |translation error| / 1-sigma over {trials} simulated sets, intrinsics "
          f"calibrated from the same {STATIONS} images (target 0.7-1.4; in brackets: the 1-sigma with them exact)")
    print("| setup | answer | X | Y | focal 1-sigma |")
    print("|---|---|---|---|---|")
    for setup in ("eye-in-hand", "eye-to-hand"):
        z = {name: [] for name in ("reprojection", "auto (poses)")}
        exact = {name: [] for name in z}
        focal = []
        for seed in range(trials):
            truth, data, T, cal = simulated(seed, setup)
            focal.append(cal.std_fx_fy_cx_cy[0] / cal.camera.K[0, 0])
            corner = handeye.solve("axyb", solver="reprojection", **data)
            plain = handeye.solve("axyb", solver="reprojection", **{**data, "images": dataclasses.replace(
                data["images"], intrinsics_std=None)})
            poses = handeye.solve("axyb", A=data["A"], B=data["B"])
            cell = types.SimpleNamespace(problem="axyb", setup=setup, pairing=None)
            widened = pose_based_intrinsics(poses, types.SimpleNamespace(observations=data["images"], T_cam_target=T),
                                            data["A"], cell, {}, {})
            for name, sol, before in (("reprojection", corner, plain), ("auto (poses)", widened, poses)):
                std = _std(sol.diagnostics)
                std0 = _std(before.diagnostics)
                errors = PROBLEM.errors(sol.unknowns, truth)
                z[name].append([errors[k]["translation"] / std[k]["translation"] for k in ("X", "Y")])
                exact[name].append([errors[k]["translation"] / std0[k]["translation"] for k in ("X", "Y")])
        for name in z:
            rms = np.sqrt(np.mean(np.array(z[name]) ** 2, axis=0))
            rms0 = np.sqrt(np.mean(np.array(exact[name]) ** 2, axis=0))
            print(f"| {setup} | {name} | {rms[0]:.2f} ({rms0[0]:.2f}) | {rms[1]:.2f} ({rms0[1]:.2f}) | "
                  f"{100 * np.median(focal):.2g}% |")


#: focal-length errors (fraction) of the intrinsics file in the detection study
FOCAL_ERRORS = (0.0, 0.003, 0.005, 0.01, 0.02)


def detection(trials: int) -> None:
    """How often the file-intrinsics check warns: simulated sets (the true intrinsics given,
    times 1 + e), and the real ChArUco set (its cal_data.yaml, and the images' own calibration,
    times 1 + e)."""
    from handeye.vision.intrinsics_check import focal_check
    from handeye.vision.observations import Camera

    if trials == 0:
        return
    print(f"\n## the file-intrinsics check: warnings in {trials} simulated sets of {STATIONS} images per focal "
          "error of the file (fx, fy both; 0: the true intrinsics)")
    hits = {e: 0 for e in FOCAL_ERRORS}
    ratio, z0 = [], []
    for seed in range(trials):
        truth, data, T, cal = simulated(seed, "eye-to-hand")
        obs = data["images"]
        views = [types.SimpleNamespace(image_points=u, object_points=p) for u, p in zip(obs.image_points, obs.object_points)]
        from handeye.problems.axyb import images as sim

        for e in FOCAL_ERRORS:
            K = sim.K.copy()
            K[0, 0] *= 1 + e
            K[1, 1] *= 1 + e
            check = focal_check(views, Camera(K, sim.DIST, sim.SIZE), sim.SIZE, cal)
            hits[e] += check.off
            if e == 0:
                ratio.append(check.std[0] / check.opencv_std[0])
                z0.append(check.sigmas)
    print("| focal error | " + " | ".join(f"{100 * e:g}%" for e in FOCAL_ERRORS) + " |")
    print("|---|" + "---|" * len(FOCAL_ERRORS))
    print("| warned | " + " | ".join(f"{hits[e]}/{trials}" for e in FOCAL_ERRORS) + " |")
    print(f"1-sigma used / OpenCV's (median): {np.median(ratio):.2f}; z of the true file: RMS {np.sqrt(np.mean(np.square(z0))):.2f}, "
          f"largest |z| {np.max(np.abs(z0)):.2f}")
    real_detection()


def real_detection() -> None:
    from handeye.vision.boards import parse_board
    from handeye.vision.image_set import images_and_poses
    from handeye.vision.intrinsics import load_camera
    from handeye.vision.intrinsics_check import focal_check
    from handeye.vision.observations import Camera

    sets = {"ChArUco (eye to hand, 1600 x 1200)": ("test_set_charuco", "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250"),
            "circle grid (eye in hand, 640 x 480)": ("test_set_10x10", "circlegrid:10x10:25.4mm")}
    for title, (name, board) in sets.items():
        folder = SHARED / "industrial_calibration_rct" / name
        if not folder.is_dir():
            continue
        found = images_and_poses(folder / "images", parse_board(board), None, setup="eye-to-hand")
        obs, own = found.observations, found.calibration
        views = [types.SimpleNamespace(image_points=u, object_points=p) for u, p in zip(obs.image_points, obs.object_points)]
        files = {"own calibration": own.camera, "cal_data.yaml": load_camera(folder / "cal_data.yaml")}
        opencv = own.std_fx_fy_cx_cy if own.opencv_std is None else own.opencv_std
        print(f"\n## real {title}: {len(views)} images; own fx {own.camera.K[0, 0]:.1f} px, OpenCV 1-sigma "
              f"{opencv[0]:.2g} px")
        print("| file | " + " | ".join(f"{100 * e:g}%" for e in FOCAL_ERRORS) + " |")
        print("|---|" + "---|" * len(FOCAL_ERRORS))
        for label, cam in files.items():
            cells = []
            for e in FOCAL_ERRORS:
                K = cam.K.copy()
                K[0, 0] *= 1 + e
                K[1, 1] *= 1 + e
                check = focal_check(views, Camera(K, cam.dist, obs.camera.size), obs.camera.size, own)
                cells.append(f"{'warns' if check.off else 'quiet'} ({check.sigmas:+.2g} sigma)")
            print(f"| {label} | " + " | ".join(cells) + " |")
        print(f"1-sigma used {check.std[0]:.3g} px ({100 * check.std[0] / own.camera.K[0, 0]:.2g}%), "
              f"{check.std[0] / check.opencv_std[0]:.2g}x OpenCV's")


def _std(diagnostics: dict) -> dict:
    from handeye.framework.solution import standard_deviations

    return standard_deviations(diagnostics)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--detect", type=int, default=0)
    args = parser.parse_args()
    z_scores(args.trials)
    detection(args.detect)


if __name__ == "__main__":
    main()
