"""Build the bundled example data files in core/data/ (run from the repository root).

    python tools/make_example_data.py [--eth DIR] [--pairs 50]

eth_robot_arm.json -- REAL data: the ``robot_arm`` set of the ETH Zurich ASL hand-eye datasets
(Furrer et al., FSR 2017; BSD-3-Clause, Copyright (c) 2017 ETHZ ASL). Two asynchronous streams,
CSV rows ``t [s], x, y, z [m], qx, qy, qz, qw``:

- ``..._base_link_sr300_hinge.csv``: A = T_B_H, the robot's hand (flange) in its base, 50 Hz;
- ``..._target_ir.csv``: B = T_W_E, the SR300 IR camera in the target (world) frame, ~30 Hz.

This is our eye-in-hand convention (docs/conventions.md): A_i X = Y B_i with X = T_H_E
(flange -> camera) and Y = T_B_W (base -> target). Steps:

1. Pairing: the 50 Hz robot stream is interpolated at each camera time stamp shifted by a
   constant clock offset (rotation by slerp, translation linearly). A camera sample is kept only
   if its two neighbouring robot samples are at most 30 ms apart (no gaps bridged), so the
   interpolation spans at most one robot period (20 ms).
2. Clock offset: the streams have an unknown constant offset (the subject of the FSR paper). We
   pick it on a grid (-100 ms .. +100 ms, 5 ms steps) as the offset minimising the median
   rotation residual (eq. 32) of the closed-form ``kron-lstsq`` solution on ALL pairs. The
   offset found is written into the file's description.
3. Selection: ``--pairs`` well-spread pairs by greedy farthest-point sampling on the rotation
   angle between robot orientations (start: the pair farthest from the mean orientation), so
   the small example is as well conditioned as the whole recording allows. No outlier removal.

simulated_paper.json -- the paper's simulation (Sec. IV-A, X and Y of the paper, mm):
``PROBLEM.simulate(pairs=16, seed=1, noise=NoiseModel.on("B", 0.002, 0.2))`` with the truth.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import make_pose, rotation_angle
from handeye.io.data_files import save_data
from handeye.problems.axyb import PROBLEM

ROOT = Path(__file__).resolve().parents[1]
ETH_DIR = Path("/work/shared/data/ethz_asl_handeye_2017/robot_arm")
ROBOT_CSV = "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv"
CAMERA_CSV = "robot_arm_complete_bag_color_and_ir_target_ir.csv"
MAX_ROBOT_GAP = 0.030  # s: largest robot sample spacing an interpolation may bridge
OFFSETS = np.round(np.arange(-0.100, 0.1001, 0.005), 3)  # s: clock offsets tried
ETH_SOURCE = (
    "ETH Zurich ASL hand-eye calibration datasets, robot_arm (github.com/ethz-asl/"
    "hand_eye_calibration, datasets/robot_arm_w_color_camera_real.zip, commit 966cd92); "
    "Furrer et al., 'Evaluation of Combined Time-Offset Estimation and Hand-Eye Calibration on "
    "Robotic Datasets', FSR 2017"
)
ETH_LICENSE = "BSD-3-Clause, Copyright (c) 2017, ETHZ ASL (see core/data/README.md)"


def read_stream(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Time stamps (n,) and poses (n, 4, 4) from a CSV of t, x, y, z, qx, qy, qz, qw."""
    rows = np.loadtxt(path, delimiter=",")
    order = np.argsort(rows[:, 0], kind="stable")
    rows = rows[order]
    return rows[:, 0], make_pose(Rotation.from_quat(rows[:, 4:8]).as_matrix(), rows[:, 1:4])


def pair_streams(t_robot: np.ndarray, robot: np.ndarray, t_cam: np.ndarray, cam: np.ndarray,
                 offset: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B): robot poses interpolated at t_cam + offset, and the camera poses kept."""
    t = t_cam + offset
    inside = (t > t_robot[0]) & (t < t_robot[-1])
    hi = np.searchsorted(t_robot, t[inside])
    keep = np.flatnonzero(inside)[(t_robot[hi] - t_robot[hi - 1]) <= MAX_ROBOT_GAP]
    t = t[keep]
    slerp = Slerp(t_robot, Rotation.from_matrix(robot[:, :3, :3]))
    trans = np.stack([np.interp(t, t_robot, robot[:, k, 3]) for k in range(3)], axis=1)
    return make_pose(slerp(t).as_matrix(), trans), cam[keep]


def median_rotation_residual(A: np.ndarray, B: np.ndarray) -> float:
    sol = handeye.solve("axyb", A=A, B=B, solver="kron-lstsq")
    res = PROBLEM.residuals(PROBLEM.validate(A=A, B=B), sol.unknowns)
    return float(np.median(res["rotation"]))


def farthest_rotations(R: np.ndarray, k: int) -> np.ndarray:
    """Indices of k rotations R: (n, 3, 3) chosen greedily to maximise the smallest pairwise angle."""
    mean = Rotation.from_matrix(R).mean().as_matrix()
    chosen = [int(np.argmax(rotation_angle(np.swapaxes(R, 1, 2) @ mean)))]
    nearest = rotation_angle(np.swapaxes(R, 1, 2) @ R[chosen[0]])
    for _ in range(k - 1):
        nxt = int(np.argmax(nearest))
        chosen.append(nxt)
        nearest = np.minimum(nearest, rotation_angle(np.swapaxes(R, 1, 2) @ R[nxt]))
    return np.sort(np.array(chosen))


def make_eth(eth_dir: Path, pairs: int, out: Path) -> None:
    t_robot, robot = read_stream(eth_dir / ROBOT_CSV)
    t_cam, cam = read_stream(eth_dir / CAMERA_CSV)
    scores = [median_rotation_residual(*pair_streams(t_robot, robot, t_cam, cam, o)) for o in OFFSETS]
    offset = float(OFFSETS[int(np.argmin(scores))])
    A, B = pair_streams(t_robot, robot, t_cam, cam, offset)
    idx = farthest_rotations(A[:, :3, :3], pairs)
    description = (
        f"{pairs} of {len(A)} time-paired poses of the ETH ASL robot_arm recording (real data): "
        f"A_i = T_base_hand (robot, 50 Hz, slerp-interpolated at the camera time stamp shifted by {offset * 1000:+.0f} ms "
        f"(clock offset chosen on a grid by median rotation residual), B_i = T_target_camera (SR300 IR "
        "camera, ~30 Hz); pairs chosen by greedy farthest-point sampling of the robot orientation. "
        "Made by tools/make_example_data.py."
    )
    save_data(out, {"A": A[idx], "B": B[idx]}, metadata={
        "units": "m", "setup": "eye-in-hand", "description": description,
        "source": ETH_SOURCE, "license": ETH_LICENSE,
    })
    spread = np.degrees(rotation_angle(np.swapaxes(A[idx, :3, :3], 1, 2)[:, None] @ A[idx, :3, :3][None]).max())
    print(f"{out}: {pairs} pairs of {len(A)}, clock offset {offset * 1000:+.0f} ms "
          f"(median rotation residual {np.degrees(min(scores)):.3f} deg on all pairs), "
          f"max rotation between chosen robot poses {spread:.1f} deg, {out.stat().st_size} bytes")


def make_simulated(out: Path) -> None:
    data, truth = PROBLEM.simulate(pairs=16, seed=1, noise=NoiseModel.on("B", 0.002, 0.2))
    save_data(out, data, truth, metadata={
        "units": "mm", "setup": "eye-in-hand",
        "description": "the paper's simulation (Pan et al., T-ASE 2022, Sec. IV-A): 16 random poses "
                       "of an LR Mate 200iD-like arm, the paper's X and Y, noise on B (0.002 rad, 0.2 mm). "
                       "PROBLEM.simulate(pairs=16, seed=1, noise=NoiseModel.on('B', 0.002, 0.2)); "
                       "made by tools/make_example_data.py",
        "source": "simulated by handeye", "license": "BSD-3-Clause (handeye)",
    })
    print(f"{out}: 16 simulated pairs with truth, {out.stat().st_size} bytes")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eth", type=Path, default=ETH_DIR, help="directory of the ETH robot_arm CSVs")
    parser.add_argument("--pairs", type=int, default=50, help="pairs to keep from the ETH data")
    parser.add_argument("--out", type=Path, default=ROOT / "core" / "data")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    make_eth(args.eth, args.pairs, args.out / "eth_robot_arm.json")
    make_simulated(args.out / "simulated_paper.json")


if __name__ == "__main__":
    main()
