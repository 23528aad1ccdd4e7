"""The order to drive planned stations in: a short path for the flange.

A plan picks its stations for what they tell (`handeye.planning.design.greedy`: most informative
first), which sends the flange back and forth across the workspace and flips the tool between
far-apart orientations from one station to the next. What the stations tell together does not
depend on their order, so they are driven in the order that keeps the flange's motion short: a
move costs its translation plus its rotation angle times `LEVER` (the flange's orientation turns
a tool of that length by that much), the path is built nearest station first from the one
nearest the stations' centre, then shortened by 2-opt (reversing any stretch of it where that
shortens the whole) until no reversal does (`driving_order`). `path_length` gives the
translation and rotation of the path, for the time a robot needs at a stated speed.
"""

from __future__ import annotations

import numpy as np

from handeye.geometry.se3 import rotation_angle

#: the length (mm) a rotation of the flange counts as per radian: a tool and camera reaching
#: about this far from the flange sweep that much when it turns
LEVER_MM = 300.0
#: at most this many 2-opt passes (each tries every reversal; a dozen stations settle in two or three)
MAX_PASSES = 50


def move_costs(A: np.ndarray, lever: float) -> np.ndarray:
    """(n, n) cost of moving the flange between stations A (n, 4, 4): translation distance plus
    the rotation angle times `lever` (the data's length unit per radian)."""
    t = A[:, :3, 3]
    distance = np.linalg.norm(t[:, None, :] - t[None, :, :], axis=2)
    turn = rotation_angle(np.swapaxes(A[:, None, :3, :3], -1, -2) @ A[None, :, :3, :3])
    return distance + lever * turn


def driving_order(A: np.ndarray, lever: float) -> np.ndarray:
    """The order (indices into A) to drive the stations in (module docstring)."""
    n = len(A)
    if n <= 2:
        return np.arange(n)
    cost = move_costs(A, lever)
    centre = A[:, :3, 3].mean(axis=0)
    order = [int(np.argmin(np.linalg.norm(A[:, :3, 3] - centre, axis=1)))]
    left = set(range(n)) - set(order)
    while left:
        last = order[-1]
        order.append(min(left, key=lambda k: cost[last, k]))
        left.remove(order[-1])
    for _ in range(MAX_PASSES):  # 2-opt on the open path: reverse order[i:j] where that is shorter
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                before = cost[order[i - 1], order[i]] + (cost[order[j], order[j + 1]] if j + 1 < n else 0.0)
                after = cost[order[i - 1], order[j]] + (cost[order[i], order[j + 1]] if j + 1 < n else 0.0)
                if after < before - 1e-9:
                    order[i:j + 1] = order[i:j + 1][::-1]
                    improved = True
        if not improved:
            break
    return np.array(order)


def path_length(A: np.ndarray) -> tuple[float, float]:
    """(the flange's translation along the path, data units; its rotation, rad) through stations A
    in their order."""
    if len(A) < 2:
        return 0.0, 0.0
    steps = np.linalg.norm(np.diff(A[:, :3, 3], axis=0), axis=1)
    turns = rotation_angle(np.swapaxes(A[:-1, :3, :3], -1, -2) @ A[1:, :3, :3])
    return float(steps.sum()), float(np.sum(turns))


def path_seconds(A: np.ndarray, speed: float, turn_speed: float) -> float:
    """Seconds a robot needs to drive through stations A in their order, each move at `speed`
    (data units / s) or `turn_speed` (rad / s), whichever takes longer (no stops counted)."""
    if len(A) < 2:
        return 0.0
    steps = np.linalg.norm(np.diff(A[:, :3, 3], axis=0), axis=1)
    turns = rotation_angle(np.swapaxes(A[:-1, :3, :3], -1, -2) @ A[1:, :3, :3])
    return float(np.sum(np.maximum(steps / speed, turns / turn_speed)))
