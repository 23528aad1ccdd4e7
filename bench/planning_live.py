"""The cost of one ``Session.add`` (`handeye.planning.session`) while a cell records: milliseconds
per station at 10, 25 and 50 stations, without and with suggestions.

Rows:

- ``fit``: the simulator's stations (``axyb``, noise A 0.0002 rad / 0.05 mm, B 0.002 rad / 0.5 mm),
  no camera: the warm-started fit, the 1-sigma, the disagreement test;
- ``fit + 3 suggestions``: planned stations of a camera on the flange (1280 x 1024, f = 1000 px,
  chessboard 9 x 6, 25 mm; noise on both poses) with the camera and board given: the same, plus
  three suggestions from a pool of 1000 candidates.

Each row: the median over the adds around that count (count - 2 .. count + 2; the full solve every
10th station is its own column, ``solve``: the median of those adds), over ``--repeats`` sessions.
The target is 10 ms per add at 50 stations. Timings on a shared machine vary with its load.

    python bench/planning_live.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from handeye.estimation.noise import NoiseModel
from handeye.geometry import so3_fast
from handeye.geometry.se3 import make_pose
from handeye.planning.plan import plan
from handeye.planning.session import Session
from handeye.planning.stations import Workspace
from handeye.problems.axyb import PROBLEM
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera

COUNTS = (10, 25, 50)
STATIONS = 53


def simulated(seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    data, _ = PROBLEM.simulate(pairs=STATIONS, seed=seed, noise=NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)}))
    return data["A"], data["B"], {}


def planned(seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    board = parse_board("chessboard:9x6:25mm")
    camera = Camera(np.array([[1000.0, 0, 640], [0, 1000, 512], [0, 0, 1]]), np.zeros(0), (1280, 1024))
    X = make_pose(np.eye(3), np.array([0.0, 50.0, 80.0]))
    Y = make_pose(np.diag([1.0, -1.0, -1.0]), np.array([600.0, 0.0, 0.0]))
    workspace = Workspace((200, -500, 100), (1000, 500, 1200), max_tilt_deg=60)
    p = plan("axyb", setup="eye-in-hand", X=X, Y=Y, camera=camera, board=board, count=STATIONS, workspace=workspace,
             pool=2000, seed=seed)
    rng = np.random.default_rng(seed)

    def noisy(T: np.ndarray, rot: float, trans: float) -> np.ndarray:
        return T @ make_pose(so3_fast.exp(rng.normal(0, rot, 3)), rng.normal(0, trans, 3))

    A = np.stack([noisy(a, 0.0002, 0.05) for a in p.A])
    B = np.stack([noisy(b, 0.0003, 0.05) for b in p.B])
    return A, B, {"camera": camera, "board": board, "workspace": workspace, "suggest": 3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"{'row':<22}" + "".join(f"{f'{n} stations':>14}" for n in COUNTS) + f"{'solve':>10}  (ms per add, median)")
    for label, make in (("fit", simulated), ("fit + 3 suggestions", planned)):
        per_count: dict[int, list[float]] = {n: [] for n in COUNTS}
        solves: list[float] = []
        for seed in range(args.repeats):
            A, B, options = make(seed)
            session = Session("axyb", setup="eye-in-hand", **options)
            for i, (a, b) in enumerate(zip(A, B)):
                update = session.add(a, b)
                if update.solved:
                    solves.append(update.seconds)
                    continue
                for n in COUNTS:
                    if abs(i + 1 - n) <= 2:
                        per_count[n].append(update.seconds)
        print(f"{label:<22}" + "".join(f"{1e3 * statistics.median(per_count[n]):14.2f}" for n in COUNTS)
              + f"{1e3 * statistics.median(solves):10.1f}")


if __name__ == "__main__":
    main()
