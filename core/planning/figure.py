"""A picture of a plan (`Plan`): the robot's base, the planned flange poses numbered in the order
to drive them, where the camera is at each (eye in hand) or where it stands (eye to hand), and
the board; the predicted 1-sigma in the title. matplotlib's Agg backend, imported lazily."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from handeye.vision.boards import Board


def _triad(ax: Any, T: np.ndarray, size: float, lw: float = 1.2) -> None:
    for k, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
        end = T[:3, 3] + size * T[:3, k]
        ax.plot(*zip(T[:3, 3], end), color=colour, lw=lw)


def draw(plan: Any, board: Board, X: np.ndarray, Y: np.ndarray, path: str | Path, unit: str) -> Path:
    """Write the picture of `plan` to `path` (PNG); X, Y the rough poses it was made from."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    A = plan.A
    eye_in_hand = plan.setup == "eye-in-hand"
    cameras = A @ X if eye_in_hand else np.repeat(Y[None], len(A), axis=0)
    boards = np.repeat(Y[None], len(A), axis=0) if eye_in_hand else A @ X
    points = np.concatenate([A[:, :3, 3], cameras[:, :3, 3], boards[:, :3, 3], np.zeros((1, 3))])
    size = 0.06 * float(np.ptp(points, axis=0).max() or 1.0)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    _triad(ax, np.eye(4), 2 * size, lw=2.5)
    ax.text(0, 0, 0, " base")
    for i, T in enumerate(A):
        _triad(ax, T, size)
        ax.text(*T[:3, 3], f" {i + 1}", fontsize=8)
    if eye_in_hand:
        ax.scatter(*cameras[:, :3, 3].T, marker="^", color="k", s=12, label="camera at each station")
        corners = _board_outline(board, Y)
        ax.plot(*corners.T, color="k", lw=2, label="board")
    else:
        ax.scatter(*Y[:3, 3], marker="^", color="k", s=40, label="camera")
        ax.scatter(*boards[:, :3, 3].T, marker="s", color="k", s=10, label="board at each station")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_zlabel(f"z ({unit})")
    ax.legend(loc="upper left", fontsize=8)
    sigma = "; ".join(f"{name} {s['rotation_deg']:.3g} deg / {s['translation']:.3g} {unit}" for name, s in plan.std.items())
    ax.set_title(f"{len(A)} planned stations ({plan.setup}); predicted 1-sigma: {sigma}", fontsize=9)
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _board_outline(board: Board, T: np.ndarray) -> np.ndarray:
    """(5, 3) the board's printed outline in the base frame (closed)."""
    x0, y0, x1, y1 = board.extent()
    local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]], dtype=float)
    return local @ T[:3, :3].T + T[:3, 3]
