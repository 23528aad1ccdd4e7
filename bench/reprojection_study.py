"""Image data: the reprojection-error fit against the pose-based answer, with a known truth.

Per setup (eye-in-hand, eye-to-hand) and seed: 20 stations of a 9 x 6 board seen by a
1280 x 960 camera (`handeye.problems.axyb.images`), 0.3 px Gaussian noise on the corners, B the
PnP poses of the noisy corners, random X, Y. Three answers:

- (a) ``auto`` on the PnP poses (pose-based maximum likelihood, isotropic pose noise);
- (b) ``reprojection`` (started from auto): the corners' reprojection error, robot poses exact;
- (c) the same reprojection fit started from the truth: the floor of the data.

With ``--rendered K`` also K seeds of rendered images (`handeye.vision.render`: a 9 x 6
chessboard, blur 0.7 px, grey-level noise 2) through detection, then 0.3 px of noise added to the
detected corners (the detector alone is ~0.02 px accurate on renders), PnP, same three answers.

Printed per setup: median and 90th percentile of the rotation (deg) and translation (mm) errors
of X and Y, the ratio of (b) to (c) and to (a) (medians), and the time per solve. Targets:
(b) within 1.2x of (c); (b) at least as accurate as (a).
``--figure DIR`` writes the error distributions (reprojection.png).

Usage::

    python bench/reprojection_study.py --seeds 50 [--rendered 5] [--figure docs/figures/reprojection]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.problems.axyb import images as axyb_images

SETUPS = ("eye-in-hand", "eye-to-hand")
METHODS = ("auto (poses)", "reprojection", "reprojection from truth")
STATIONS = 20
PIXEL_NOISE = 0.3


def errors(problem, unknowns, truth) -> np.ndarray:
    """[X rot deg, X trans mm, Y rot deg, Y trans mm]."""
    e = problem.errors(unknowns, truth)
    return np.array([np.degrees(e["X"]["rotation"]), e["X"]["translation"],
                     np.degrees(e["Y"]["rotation"]), e["Y"]["translation"]])


def three_answers(problem, data, truth) -> tuple[list[np.ndarray], list[float]]:
    poses = {k: v for k, v in data.items() if k != "images"}
    out, seconds = [], []
    for run in (lambda: handeye.solve("axyb", solver="auto", **poses),
                lambda: handeye.solve("axyb", solver="reprojection", **data),
                lambda: handeye.solve("axyb", solver="reprojection", **data, init_X=truth["X"], init_Y=truth["Y"])):
        start = time.perf_counter()
        solution = run()
        seconds.append(time.perf_counter() - start)
        out.append(errors(problem, solution.unknowns, truth))
    return out, seconds


def simulated(problem, setup: str, seed: int):
    truth = problem.random_unknowns(np.random.default_rng(seed))
    return problem.simulate(pairs=STATIONS, seed=seed, noise=NoiseModel.on("B", 1.0, 1.0),
                            images={"setup": setup, "pixel_noise": PIXEL_NOISE}, **truth)


def rendered(problem, setup: str, seed: int):
    """The same cell as `simulated`, but the corners detected in rendered images."""
    from handeye.vision.boards import parse_board
    from handeye.vision.camera_poses import board_pose
    from handeye.vision.detect import detect
    from handeye.vision.observations import BoardObservations, Camera
    from handeye.vision.render import render

    board = parse_board("chessboard:9x6:30mm")
    camera = Camera(axyb_images.K, axyb_images.DIST, axyb_images.SIZE)
    rng = np.random.default_rng(seed)
    truth = problem.random_unknowns(rng)
    T_cam_target = axyb_images.views(STATIONS, rng, points=board.object_points())
    B_true = inverse(T_cam_target) if setup == "eye-in-hand" else T_cam_target
    A = truth["Y"] @ B_true @ inverse(truth["X"])
    keep, pixels, points, B = [], [], [], []
    for i, T in enumerate(T_cam_target):
        image = render(board, camera, T, blur=0.7, noise=2.0, rng=rng)
        try:
            found = detect(image, board)
        except handeye.InputError:
            continue
        corners = found.image_points + PIXEL_NOISE * rng.standard_normal(found.image_points.shape)
        pose = board_pose(found.object_points, corners, camera).T_cam_target
        keep.append(i)
        pixels.append(corners)
        points.append(found.object_points)
        B.append(inverse(pose) if setup == "eye-in-hand" else pose)
    images = BoardObservations(tuple(pixels), tuple(points), camera, setup)
    return {"A": A[keep], "B": np.array(B), "images": images}, truth


def study(make, seeds, setups=SETUPS) -> dict[str, dict]:
    problem = handeye.get_registry().problem("axyb")
    results = {}
    for setup in setups:
        errs, times = [], []
        for seed in seeds:
            data, truth = make(problem, setup, seed)
            e, t = three_answers(problem, data, truth)
            errs.append(e)
            times.append(t)
        results[setup] = {"errors": np.array(errs), "seconds": np.array(times)}  # (seeds, method, 4)
    return results


def table(title: str, results: dict[str, dict]) -> str:
    lines = [title]
    for setup, r in results.items():
        e, t = r["errors"], r["seconds"]
        lines.append(f"{setup} ({len(e)} seeds): median / 90th percentile; X rot deg, X trans mm, Y rot deg, "
                     "Y trans mm; ms per solve")
        for k, name in enumerate(METHODS):
            med, p90 = np.median(e[:, k], axis=0), np.percentile(e[:, k], 90, axis=0)
            cells = "  ".join(f"{a:.4f}/{b:.4f}" for a, b in zip(med, p90))
            lines.append(f"  {name:<24} {cells}   {1e3 * np.median(t[:, k]):7.1f} ms")
        ratio_truth = np.median(e[:, 1], axis=0) / np.median(e[:, 2], axis=0)
        ratio_auto = np.median(e[:, 1], axis=0) / np.median(e[:, 0], axis=0)
        lines.append("  reprojection / from truth (medians): " + " ".join(f"{x:.3f}" for x in ratio_truth)
                     + f"   target <= 1.2: {'met' if np.all(ratio_truth <= 1.2) else 'MISSED'}")
        lines.append("  reprojection / auto (medians):       " + " ".join(f"{x:.3f}" for x in ratio_auto)
                     + f"   target <= 1: {'met' if np.all(ratio_auto <= 1.0) else 'MISSED'}")
    return "\n".join(lines)


def figure(results: dict[str, dict], folder: str) -> str:
    import matplotlib

    matplotlib.use("Agg")
    from pathlib import Path

    import matplotlib.pyplot as plt

    labels = ("X rotation [deg]", "X translation [mm]", "Y rotation [deg]", "Y translation [mm]")
    fig, axes = plt.subplots(len(results), 4, figsize=(14, 3.2 * len(results)), squeeze=False)
    for row, (setup, r) in enumerate(results.items()):
        for col in range(4):
            ax = axes[row, col]
            ax.boxplot([r["errors"][:, k, col] for k in range(3)], showfliers=False)
            ax.set_xticks([1, 2, 3], ["auto\n(poses)", "reprojection", "from\ntruth"])
            ax.set_title(f"{setup}: {labels[col]}", fontsize=9)
    fig.tight_layout()
    Path(folder).mkdir(parents=True, exist_ok=True)
    path = Path(folder) / "reprojection.png"
    fig.savefig(path, dpi=110)
    return str(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--rendered", type=int, default=0, metavar="K", help="also K seeds of rendered images")
    parser.add_argument("--figure", metavar="DIR")
    args = parser.parse_args()
    results = study(simulated, range(args.seeds))
    print(table(f"projected corners, {PIXEL_NOISE} px noise, {STATIONS} stations", results))
    if args.rendered:
        print(table(f"rendered images (blur 0.7 px, noise 2 grey levels) -> detection + {PIXEL_NOISE} px -> PnP",
                    study(rendered, range(1000, 1000 + args.rendered))))
    if args.figure:
        print("wrote", figure(results, args.figure))


if __name__ == "__main__":
    main()
