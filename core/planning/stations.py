"""Candidate stations for a plan: views of the board the camera can use (`views.usable`), turned
into robot poses through the rough X and Y, kept where the flange may go (`Workspace`).

A view is T_cam_target, the board's pose in the camera. It is drawn the way a person would point
the camera: a direction from the board's centre within the largest viewing angle of its printed
normal (uniform over that cap), a distance in the range, an aim point within a quarter of the
board's size of its centre (so that the board also sits off the image centre), and a roll about
the optical axis. The robot pose follows from A X = Y B (docs/conventions.md): eye in hand
(X = T_flange_cam, Y = T_base_target, B = T_target_cam) A = Y T_cam_target^-1 X^-1; eye to hand
(X = T_flange_target, Y = T_base_cam, B = T_cam_target) A = Y T_cam_target X^-1.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import inverse, make_pose
from handeye.planning.views import ViewLimits, board_centre, usable
from handeye.vision.boards import Board
from handeye.vision.observations import Camera
from handeye.vision.render import printed_normal

#: draws per batch, and the most batches before giving up on filling the pool
BATCH = 4000
MAX_BATCHES = 50


class PlanningError(InputError):
    """The constraints leave too few usable stations to plan from."""


@dataclasses.dataclass(frozen=True)
class Workspace:
    """Where the flange may go: its origin inside the box low..high (base frame, the data's length
    unit) and, where max_tilt_deg is given, its z axis (the tool axis) within that angle of
    `axis` (base frame; default straight down)."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]
    axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    max_tilt_deg: float | None = None
    #: the flange's roll about its tool axis within this angle of "x forward" (`roll`): a person
    #: drives the wrist within a half turn, not from -178 to +178 deg between stations; None: any
    max_roll_deg: float | None = None

    def __post_init__(self) -> None:
        low, high = np.asarray(self.low, dtype=float), np.asarray(self.high, dtype=float)
        if low.shape != (3,) or high.shape != (3,) or not np.all(low < high):
            raise InputError(f"the workspace box needs low < high in x, y and z, got low {self.low}, high {self.high}")
        if np.linalg.norm(self.axis) == 0:
            raise InputError("the workspace's tool axis must not be zero")
        if self.max_tilt_deg is not None and not 0 < self.max_tilt_deg <= 180:
            raise InputError(f"the tool axis' largest tilt must lie in (0, 180] deg, got {self.max_tilt_deg}")
        if self.max_roll_deg is not None and not 0 < self.max_roll_deg <= 180:
            raise InputError(f"the flange's largest roll must lie in (0, 180] deg, got {self.max_roll_deg}")

    def holds(self, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(inside the box, tool axis within its tilt and roll limits) for flange poses A (m, 4, 4)."""
        t = A[:, :3, 3]
        box = np.all((t >= self.low) & (t <= self.high), axis=1)
        ok = np.ones(len(A), dtype=bool)
        if self.max_tilt_deg is not None:
            axis = np.asarray(self.axis, dtype=float) / np.linalg.norm(self.axis)
            ok &= A[:, :3, 2] @ axis >= math.cos(math.radians(self.max_tilt_deg))
        if self.max_roll_deg is not None:
            ok &= np.abs(roll(A)) <= math.radians(self.max_roll_deg)
        return box, ok


def roll(A: np.ndarray) -> np.ndarray:
    """(m,) the flange's roll about its own z axis (rad, -pi..pi): the angle from "x forward" (the
    base's x axis, or its y where the tool axis lies along x, projected on the plane across the
    tool axis) to the flange's x axis, about the tool axis."""
    z, x = A[:, :3, 2], A[:, :3, 0]
    forward = np.where((np.abs(z[:, 0]) > 0.95)[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    forward = forward - np.einsum("mi,mi->m", forward, z)[:, None] * z
    forward /= np.linalg.norm(forward, axis=1)[:, None]
    return np.arctan2(np.einsum("mi,mi->m", np.cross(forward, x), z), np.einsum("mi,mi->m", forward, x))


def random_views(board: Board, limits: ViewLimits, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 4, 4) T_cam_target drawn as the module docstring says."""
    normal = printed_normal(board)
    x0, y0, x1, y1 = board.extent()
    aim = board_centre(board) + np.column_stack([rng.uniform(-0.25, 0.25, count) * (x1 - x0),
                                                 rng.uniform(-0.25, 0.25, count) * (y1 - y0), np.zeros(count)])
    cos_tilt = rng.uniform(math.cos(math.radians(limits.max_angle_deg)), 1.0, count)
    sin_tilt, azimuth = np.sqrt(1.0 - cos_tilt**2), rng.uniform(0.0, 2.0 * np.pi, count)
    # directions about the printed normal (+-z of the board frame)
    direction = np.column_stack([sin_tilt * np.cos(azimuth), sin_tilt * np.sin(azimuth), cos_tilt * normal[2]])
    position = aim + rng.uniform(*limits.distance, count)[:, None] * direction
    z = -direction
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    roll = rng.uniform(-np.pi, np.pi, count)[:, None]
    x, y = np.cos(roll) * x + np.sin(roll) * y, -np.sin(roll) * x + np.cos(roll) * y
    return inverse(make_pose(np.stack([x, y, z], axis=2), position))


def robot_poses(views: np.ndarray, X: np.ndarray, Y: np.ndarray, setup: str) -> np.ndarray:
    """A for views T_cam_target (module docstring)."""
    inner = inverse(views) if setup == "eye-in-hand" else views
    return Y @ inner @ inverse(X)


def camera_poses(views: np.ndarray, setup: str) -> np.ndarray:
    """B as A X = Y B takes it for views T_cam_target."""
    return inverse(views) if setup == "eye-in-hand" else np.array(views)


def candidates(board: Board, camera: Camera, X: np.ndarray, Y: np.ndarray, setup: str, limits: ViewLimits,
               workspace: Workspace | None, pool: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(A, views): up to `pool` usable stations in the workspace; PlanningError naming the
    constraint that rejected most when fewer than a tenth of the pool are found."""
    found_A, found_views = [], []
    rejected: Counter[str] = Counter()
    total = 0
    for _ in range(MAX_BATCHES):
        views = random_views(board, limits, BATCH, rng)
        A = robot_poses(views, X, Y, setup)
        ok = usable(board, camera, views, limits)
        rejected["the board not wholly in the image"] += int(np.sum(~ok))
        if workspace is not None:
            box, tilt = workspace.holds(A)
            rejected["the flange outside the workspace box"] += int(np.sum(ok & ~box))
            rejected["the tool axis beyond its tilt or roll limit"] += int(np.sum(ok & box & ~tilt))
            ok &= box & tilt
        found_A.append(A[ok])
        found_views.append(views[ok])
        total += int(np.sum(ok))
        if total >= pool:
            break
    if total < max(pool // 10, 1):
        reason, count = rejected.most_common(1)[0]
        raise PlanningError(f"only {total} of {MAX_BATCHES * BATCH} drawn views are usable ({count} rejected for "
                            f"{reason}): widen the workspace box, the viewing distance or angle, or check the rough "
                            f"X and Y and the setup")
    return np.concatenate(found_A)[:pool], np.concatenate(found_views)[:pool]
