"""Planned stations (`handeye.planning.plan`) against random ones and a fixed pattern, and how
well a plan predicts its own 1-sigma (docs/planning.md).

    python bench/planning.py [--trials 40] [--sizes 8,12,20] [--setup eye-in-hand]

The cell: a 1280 x 960 camera (f = 1000 px), a 9 x 6 chessboard of 30 mm squares; eye in hand the
camera 100 mm off the flange, the board on the table 600 mm ahead of the base; eye to hand the
camera 1.2 m from the base looking down at the workspace, the board 120 mm off the flange. The
flange stays in a box of 0.8 x 1 x 0.95 m, its tool axis within 70 deg of straight down. Noise: 0.3 px per corner coordinate (B the PnP pose of the noisy corners,
cv2.solvePnP), robot 0.0002 rad / 0.05 mm per axis (the accuracy study's). The plan is made from
a rough X and Y (the truth off by 2 deg and 10 mm) and recorded with the truth.

Compared at N stations, RMS over trials of the errors of `auto`'s answer (X and Y, rotation deg
and translation mm):
- ``planned``: the plan's N stations (fixed; the noise drawn anew per trial);
- ``random 2N``: 2N stations drawn per trial from the stations the plan chooses from (usable
  with the rough X and Y under the plan's constraints, in the same box), and usable with the
  true X and Y;
- ``pattern``: N stations of an easy_handeye-like pattern about a start pose looking straight at
  the board (rotations of the camera about its own x, y, z by +-20, +-20, +-40 deg, moves of +-80
  mm along them, then the same at half and 1.5x those), the usable ones in order.
And the plan's z-scores: the errors whitened by its predicted covariance, RMS over all
components and trials (1 when the prediction is right).
"""

from __future__ import annotations

import argparse
import math
import time

import cv2
import numpy as np

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, so3_exp, so3_log
from handeye.planning import stations, views
from handeye.planning.plan import Noise, plan
from handeye.planning.stations import Workspace
from handeye.planning.views import ViewLimits
from handeye.vision.boards import Board
from handeye.vision.observations import Camera
from handeye.vision.render import view_pose

CAMERA = Camera(np.array([[1000.0, 0, 640], [0, 1000, 480], [0, 0, 1]]), np.zeros(5), (1280, 960))
BOARD = Board(kind="chessboard", cols=9, rows=6, spacing=30.0)
NOISE = Noise(pixel=0.3, robot=(0.0002, 0.05))
LIMITS = ViewLimits(distance=(300.0, 900.0), max_angle_deg=45.0)
#: how far off the rough X and Y are (deg, mm): `rough` draws them so, and the plan is told
ROUGH = (2.0, 10.0)


def cell(setup: str) -> tuple[np.ndarray, np.ndarray, Workspace]:
    """The true X, Y and the workspace of the module docstring."""
    if setup == "eye-in-hand":
        X = make_pose(so3_exp([0.0, 0.0, 0.3]), [60.0, -20.0, 100.0])
        Y = make_pose(so3_exp([math.pi, 0.0, 0.0]), [600.0, 0.0, 0.0])
        return X, Y, Workspace(low=(200, -500, 50), high=(1000, 500, 1000), max_tilt_deg=70)
    X = make_pose(np.eye(3), [0.0, 30.0, 120.0])  # the board's printed face (its -z) against the tool axis: up
    Y = make_pose(so3_exp([math.pi - 0.3, 0.0, 0.0]), [600.0, -300.0, 1200.0])
    return X, Y, Workspace(low=(200, -500, 50), high=(1000, 500, 1000), max_tilt_deg=70)


def rough(T: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """T off by 2 deg about a random axis and 10 mm in a random direction."""
    axis, shift = rng.normal(size=3), rng.normal(size=3)
    return make_pose(T[:3, :3] @ so3_exp(math.radians(2.0) * axis / np.linalg.norm(axis)),
                     T[:3, 3] + 10.0 * shift / np.linalg.norm(shift))


def record(A: np.ndarray, X: np.ndarray, Y: np.ndarray, setup: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) as recorded at flange poses A: the robot's noise on A, B the PnP pose of the board's
    corners at the true view with pixel noise."""
    inner = inverse(Y) @ A @ X  # the true B
    seen = views.views_of(inner, setup)
    P = BOARD.object_points()
    B = np.empty_like(A)
    for i, T in enumerate(seen):
        uv = views.project(P, CAMERA, T) + rng.normal(0.0, NOISE.pixel, (len(P), 2))
        rvec0, _ = cv2.Rodrigues(T[:3, :3])
        ok, rvec, tvec = cv2.solvePnP(P, uv, CAMERA.K, CAMERA.dist, rvec0.copy(), T[:3, 3].copy(),
                                      useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
        R, _ = cv2.Rodrigues(rvec)
        B[i] = make_pose(R, tvec.ravel())
    B = inverse(B) if setup == "eye-in-hand" else B
    noise = NoiseModel({"A": NOISE.robot})
    return noise.apply("A", A, rng), B


def errors(sol: handeye.Solution, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """(12,) (omega, v) of X^-1 X_est and Y^-1 Y_est, each in its own frame."""
    out = []
    for T, E in ((X, sol.X), (Y, sol.Y)):
        out += [so3_log(T[:3, :3].T @ E[:3, :3]), T[:3, :3].T @ (E[:3, 3] - T[:3, 3])]
    return np.concatenate(out)


def summary(e: np.ndarray) -> list[float]:
    """RMS of rotation (deg) and translation (mm) errors of X and Y over trials e (n, 12)."""
    return [float(np.sqrt(np.mean(np.sum(e[:, k:k + 3] ** 2, axis=1)))) * (180 / math.pi if k % 6 == 0 else 1.0)
            for k in (0, 3, 6, 9)]


def pattern(X: np.ndarray, Y: np.ndarray, setup: str, workspace: Workspace, count: int) -> np.ndarray:
    """The easy_handeye-like stations of the module docstring (their flange poses)."""
    start = view_pose(BOARD, 0.5 * sum(LIMITS.distance), tilt=(0.0, 0.0, 0.0))  # T_cam_target, straight on
    moves = []
    for amplitude in (1.0, 0.5, 1.5):
        for axis in range(3):
            angle = math.radians((20.0, 20.0, 40.0)[axis]) * amplitude
            for sign in (1, -1):
                w = np.zeros(3)
                w[axis] = sign * angle
                moves.append(make_pose(so3_exp(w), np.zeros(3)))
        for axis in range(3):
            for sign in (1, -1):
                t = np.zeros(3)
                t[axis] = sign * 80.0 * amplitude
                moves.append(make_pose(np.eye(3), t))
    seen = np.stack([start] + [inverse(M) @ start for M in moves])  # the camera moved by M in its own frame
    A = stations.robot_poses(seen, X, Y, setup)
    ok = views.usable(BOARD, CAMERA, seen, LIMITS)
    box, tilt = workspace.holds(A)
    return A[ok & box & tilt][:count]


def study(setup: str, sizes: list[int], trials: int) -> None:
    X, Y, workspace = cell(setup)
    rng = np.random.default_rng(1)
    Xr, Yr = rough(X, rng), rough(Y, rng)
    planned_limits = views.tightened(LIMITS, math.radians(ROUGH[0]), ROUGH[1])  # the plan's own constraints
    pool, _ = stations.candidates(BOARD, CAMERA, Xr, Yr, setup, planned_limits, workspace, 3000, np.random.default_rng(2))
    pool = pool[views.usable(BOARD, CAMERA, views.views_of(inverse(Y) @ pool @ X, setup), LIMITS)]  # the board seen
    print(f"\n{setup}: RMS over {trials} trials, X rot deg / X mm / Y rot deg / Y mm")
    print("| N | planned | random 2N | pattern N | planned z RMS | plan time |")
    print("|---|---|---|---|---|---|")
    for n in sizes:
        t0 = time.perf_counter()
        p = plan("axyb", setup=setup, X=Xr, Y=Yr, camera=CAMERA, board=BOARD, count=n, workspace=workspace,
                 limits=LIMITS, noise=NOISE, rough=ROUGH)
        seconds = time.perf_counter() - t0
        L = np.linalg.cholesky(p.covariance())
        fixed = pattern(X, Y, setup, workspace, n)
        rows: dict[str, list[np.ndarray]] = {"planned": [], "random": [], "pattern": []}
        z = []
        for trial in range(trials):
            r = np.random.default_rng(1000 + trial)
            for name, A in (("planned", p.A), ("random", pool[r.choice(len(pool), 2 * n, replace=False)]),
                            ("pattern", fixed)):
                Am, Bm = record(A, X, Y, setup, r)
                try:
                    e = errors(handeye.solve("axyb", A=Am, B=Bm), X, Y)
                except handeye.HandEyeError:
                    e = np.full(12, np.nan)
                rows[name].append(e)
                if name == "planned":
                    z.append(np.linalg.solve(L, e))
        cells = [" / ".join(f"{v:.3g}" for v in summary(np.array(rows[k]))) for k in ("planned", "random", "pattern")]
        print(f"| {n} | {cells[0]} | {cells[1]} | {cells[2]} ({len(fixed)} usable) | "
              f"{float(np.sqrt(np.nanmean(np.square(z)))):.2f} | {seconds:.2f} s |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--sizes", default="8,12,20")
    parser.add_argument("--setup", choices=("eye-in-hand", "eye-to-hand", "both"), default="both")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    for setup in (("eye-in-hand", "eye-to-hand") if args.setup == "both" else (args.setup,)):
        study(setup, sizes, args.trials)


if __name__ == "__main__":
    main()
