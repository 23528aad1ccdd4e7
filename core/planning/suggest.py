"""What to record next during a session: a pool of usable candidate stations drawn once at a
rough answer (`Pool`, `stations.candidates`), and the few of them that add most to what the
stations so far tell (`Pool.choose`: D-optimal greedy selection, `handeye.planning.design`).

The pool's robot poses follow from the answer it was drawn at (A = Y T_cam_target^-1 X^-1 eye in
hand), so a pool is redrawn when the answer has moved enough to shift the views it promises
(`Pool.stale`). The factors of the candidates' information (`design.factors`, an eigen
decomposition of each, the cost of a selection) are computed once per pool and handed to
`design.greedy`: choosing k stations is then k evaluations of the gains, plus k per exchange pass
(one, or two when the first swaps a station), about 0.5 ms each for 1000 candidates.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.geometry import so3_fast
from handeye.planning import design, stations
from handeye.planning.stations import Workspace
from handeye.planning.views import ViewLimits
from handeye.vision.boards import Board
from handeye.vision.observations import Camera

#: candidate stations per pool
POOL = 1000
#: the answer moved this far from where the pool was drawn: redraw it (rotation deg; translation
#: as a share of the nearest viewing distance)
STALE_DEG = 0.5
STALE_SHARE = 0.01


@dataclasses.dataclass(frozen=True)
class Pool:
    """Candidate stations: A (n, 4, 4) robot poses, B (n, 4, 4) the camera poses they give (A X =
    Y B's convention), views (n, 4, 4) T_cam_target, information (n, 12, 12) of (X, Y) each would
    give at the expected noise, factors (n, 12, r) of it (`design.factors`); X, Y: the answer they
    were drawn at; limits: the views' limits."""

    A: np.ndarray
    B: np.ndarray
    views: np.ndarray
    information: np.ndarray
    factors: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    limits: ViewLimits

    def stale(self, X: np.ndarray, Y: np.ndarray) -> bool:
        """Whether X or Y moved beyond STALE_DEG / STALE_SHARE of the near viewing distance from
        where the pool was drawn."""
        shift = STALE_SHARE * self.limits.distance[0]
        for old, new in ((self.X, X), (self.Y, Y)):
            angle = math.degrees(float(np.linalg.norm(so3_fast.log(old[None, :3, :3].transpose(0, 2, 1)
                                                                     @ new[None, :3, :3])[0])))
            if angle > STALE_DEG or float(np.linalg.norm(old[:3, 3] - new[:3, 3])) > shift:
                return True
        return False

    def choose(self, count: int, prior: np.ndarray | None, interest: np.ndarray | None) -> list[int]:
        """Indices of `count` candidates that maximise the D-criterion of prior + theirs:
        `design.greedy` on the cached factors (it adds its own ridge to `prior`, the information
        of the stations so far as it is); interest: the mask of the parameters of interest."""
        return design.greedy(self.information, count, prior=prior, interest=interest,
                             candidate_factors=self.factors)


def draw(board: Board, camera: Camera, X: np.ndarray, Y: np.ndarray, setup: str, limits: ViewLimits,
         workspace: Workspace | None, information, size: int, rng: np.random.Generator) -> Pool:
    """A pool of up to `size` usable candidates at (X, Y); information: (A, B, X, Y) -> (n, 12, 12)
    at the expected noise (the session's). `stations.PlanningError` when too few are usable."""
    A, views = stations.candidates(board, camera, X, Y, setup, limits, workspace, size, rng)
    B = stations.camera_poses(views, setup)
    info = information(A, B, X, Y)
    return Pool(A, B, views, info, design.factors(info), X.copy(), Y.copy(), limits)
