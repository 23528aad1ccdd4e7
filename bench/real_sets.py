"""Real recordings as the judge: each real image set through the default path of `handeye
calibrate`, its status and stated 1-sigma checked against what held-out data say.

For every set found (the bundled industrial_calibration circle grid, the shared ChArUco set, and
any set given with --set NAME=FOLDER:BOARD:ROBOTFILE:FORMAT:UNIT:SETUP:MATCH):

1. the default calibration (`handeye.calibrate` on a `Cell`): status, the answer's model, X, Y
   and their stated 1-sigma;
2. held-out corner prediction over 3 folds of the stations (the same folds for every contender,
   `handeye.plugins.reprojection.held_out`): the default path refitted on each fold (the corner fit
   choosing its robot model by its own inner folds, or the pose-based answer where that predicts
   better), against OpenCV's methods on the same board poses (calibrateRobotWorldHandEye SHAH and
   LI; calibrateHandEye TSAI, PARK, HORAUD on every pair of stations, Y then fitted);
3. split halves: the even and the odd stations calibrated apart (intrinsics calibrated from each
   half's own images where the set has none), z = |difference| / root of the two stated variances
   for each unknown's rotation and translation: about 1 in RMS where the 1-sigma is honest.

Usage:
    python bench/real_sets.py
    python bench/real_sets.py --set kuka_2=/data/kuka_2:chessboard:24x17:15mm:/data/kuka_2/RobotPosesVec.txt:matrix:m:eye-in-hand:index
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

import handeye
from handeye.framework.solution import standard_deviations
from handeye.geometry.motions import relative_motions
from handeye.geometry.se3 import rotation_angle
from handeye.host.api import run_registered
from handeye.host.registry import get_registry
from handeye.io.pose_writers import write_poses
from handeye.plugins.reprojection import held_out
from handeye.problems.axyb.geometry import fitted_Y
from handeye.workflow.cell import Cell, Images, Matching, PoseStream
from handeye.workflow.solving import HELD_OUT_FOLDS as FOLDS

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "industrial_calibration_rct"


@dataclasses.dataclass(frozen=True)
class RealSet:
    name: str
    folder: Path
    board: str
    robot: Path
    format: str
    unit: str
    setup: str
    match: str

    def cell(self, folder: Path | None = None, robot: Path | None = None, match: str | None = None,
             robot_format: str | None = None) -> Cell:
        return Cell(robot=PoseStream(robot or self.robot, format=robot_format or self.format, unit=self.unit),
                    images=Images(folder or self.folder, board=self.board), setup=self.setup,
                    matching=Matching(method=match or self.match))


def known_sets() -> list[RealSet]:
    rct = ROOT / "core" / "data" / "rct_circle_grid"
    return [RealSet("rct circle grid", rct / "images", "circlegrid:10x10:25.4mm", rct / "poses", "xyz-quat-xyzw", "m",
                    "eye-in-hand", "name"),
            RealSet("rct charuco", SHARED / "test_set_charuco" / "images", "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250",
                    SHARED / "test_set_charuco" / "poses", "xyz-quat-xyzw", "m", "eye-to-hand", "name")]


def parse_set(text: str) -> RealSet:
    name, rest = text.split("=", 1)
    parts = rest.split(":")
    folder, board_parts, (robot, robot_format, unit, setup, match) = parts[0], parts[1:-5], parts[-5:]
    return RealSet(name, Path(folder), ":".join(board_parts), Path(robot), robot_format, unit, setup, match)


def opencv_fitters() -> dict[str, held_out.Fitter]:
    def axyb(method: str) -> held_out.Fitter:
        return lambda train: run_registered("opencv", dataclasses.replace(train, images=None), problem="axyb",
                                            options={"method": method}).unknowns

    def axxb(method: str) -> held_out.Fitter:
        def fit(train):
            Am, Bm = relative_motions(train.A, train.B, "all")
            motions = get_registry().problem("axxb").validate(A=Am, B=Bm)
            X = run_registered("opencv", motions, problem="axxb", options={"method": method}).unknowns["X"]
            return {"X": X, "Y": fitted_Y(train.A, train.B, X)}
        return fit

    return {**{f"opencv {m}": axyb(m) for m in ("shah", "li")},
            **{f"opencv {m}": axxb(m) for m in ("tsai", "park", "horaud")}}


def default_fitter(train):
    """The default path of calibrate on a fold: the corner fit with its own held-out choice of the
    robot model, giving way to the pose-based answer where that predicts its inner folds better."""
    sol = run_registered("reprojection", train, problem="axyb", options={"held_out": FOLDS}
                         if len(train.A) >= 2 * FOLDS else {})
    if (sol.diagnostics.get("held_out") or {}).get("pose_based_better"):
        return run_registered("auto", dataclasses.replace(train, images=None), problem="axyb").unknowns
    return sol.unknowns


def halves(real: RealSet, result, work: Path) -> list[Cell]:
    """Two cells of the even and the odd stations of `result` (symlinked images, named in
    station order, paired with their robot poses by index)."""
    images = result.stations.images
    robot = result.stations.robot
    cells = []
    for parity in (0, 1):
        folder = work / f"half{parity}"
        folder.mkdir()
        rows = list(range(parity, len(images.files), 2))
        for k, i in enumerate(rows):
            source = Path(images.files[i])
            (folder / f"{k:04d}{source.suffix}").symlink_to(source.resolve())
        poses = robot.poses[rows]  # the stations' robot poses, in station order
        robot_file = write_poses(work / f"robot{parity}.csv", poses, "matrix", unit=robot.unit)
        cells.append(real.cell(folder, robot_file, "index", "matrix"))
    return cells


def z_scores(a, b) -> dict[str, float]:
    out = {}
    for name in ("X", "Y"):
        Ta, Tb = np.asarray(a.solution.unknowns[name]), np.asarray(b.solution.unknowns[name])
        sa, sb = standard_deviations(a.solution.diagnostics), standard_deviations(b.solution.diagnostics)
        rot = float(rotation_angle(Ta[:3, :3].T @ Tb[:3, :3]))
        trans = float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]))
        out[f"{name} rot"] = rot / math.hypot(sa[name]["rotation"], sb[name]["rotation"])
        out[f"{name} trans"] = trans / math.hypot(sa[name]["translation"], sb[name]["translation"])
    return out


def study(real: RealSet) -> dict:
    started = time.perf_counter()
    result = handeye.calibrate(real.cell())
    data = result.solution.data
    row = {"set": real.name, "stations": len(data.A), "status": result.status.value, "solver": result.solver,
           "std": standard_deviations(result.solution.diagnostics)}
    if data.images is not None:
        row["held_out_px"] = held_out.held_out(data, {"handeye default": default_fitter, **opencv_fitters()}, FOLDS)
    with tempfile.TemporaryDirectory() as work:
        a, b = (handeye.calibrate(c) for c in halves(real, result, Path(work)))
        row["halves"] = (a.status.value, b.status.value)
        row["z"] = z_scores(a, b)
    row["seconds"] = time.perf_counter() - started
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", action="append", default=[], help="NAME=FOLDER:BOARD:ROBOT:FORMAT:UNIT:SETUP:MATCH")
    args = parser.parse_args()
    os.environ.setdefault("HANDEYE_WORKERS", "2")
    sets = known_sets() + [parse_set(s) for s in args.set]
    zs = []
    for real in sets:
        if not real.folder.is_dir():
            print(f"{real.name}: {real.folder} not found, skipped")
            continue
        row = study(real)
        zs += list(row["z"].values())
        ho = row.get("held_out_px") or {}
        best_cv = min((v for k, v in ho.items() if k.startswith("opencv") and v is not None), default=float("nan"))
        print(f"{row['set']}: {row['stations']} stations, status {row['status']} ({row['solver']}), "
              f"halves {'/'.join(row['halves'])}, {row['seconds']:.0f} s")
        print("  1-sigma  " + "; ".join(f"{k} {math.degrees(v['rotation']):.3g} deg / {v['translation']:.3g}"
                                         for k, v in row["std"].items()))
        print("  held-out corners px  " + ", ".join(f"{k} {v:.3g}" if v is not None else f"{k} failed"
                                                    for k, v in ho.items())
              + (f"  (default / OpenCV's best {ho['handeye default'] / best_cv:.2f})" if ho.get("handeye default") else ""))
        print("  split-half z  " + ", ".join(f"{k} {v:.2f}" for k, v in row["z"].items()))
    if zs:
        print(f"split-half z over every set and unknown: RMS {math.sqrt(np.mean(np.square(zs))):.2f}, "
              f"median {np.median(zs):.2f}, max {max(zs):.2f} ({len(zs)} values)")


if __name__ == "__main__":
    main()
