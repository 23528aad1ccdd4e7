"""A picture of a cell in 3D (`draw_cell`): the robot's base, the flange poses numbered in order,
where the camera is at each (eye in hand) or where it stands (eye to hand) with its field of
view, the board, and the next poses to record; of a plan (`draw`: the path through its stations,
the predicted 1-sigma in the title) and of a recording (``handeye watch --figure``: the stations
left out greyed). matplotlib's Agg backend, imported lazily."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from handeye.planning.scene import cell_scene
from handeye.vision.boards import Board


def _triad(ax: Any, T: np.ndarray, size: float, lw: float = 1.2) -> None:
    for k, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
        end = T[:3, 3] + size * T[:3, k]
        ax.plot(*zip(T[:3, 3], end), color=colour, lw=lw)


def draw(plan: Any, board: Board, X: np.ndarray, Y: np.ndarray, path: str | Path, unit: str,
         camera: Any = None) -> Path:
    """Write the picture of `plan` to `path` (PNG); X, Y the rough poses it was made from; the
    camera's frustum drawn where its intrinsics (`camera`) are given."""
    sigma = "; ".join(f"{name} {s['rotation_deg']:.3g} deg / {s['translation']:.3g} {unit}" for name, s in plan.std.items())
    return draw_cell(plan.A, X, Y, plan.setup, board, path, unit,
                     f"{len(plan.A)} planned stations ({plan.setup}), numbered in the order to drive them; "
                     f"predicted 1-sigma: {sigma}", camera=camera, path_line=True)


def draw_cell(A: np.ndarray, X: np.ndarray, Y: np.ndarray, setup: str, board: Board | None, path: str | Path, unit: str,
              title: str, *, camera: Any = None, left_out: np.ndarray | None = None, following: np.ndarray | None = None,
              path_line: bool = False) -> Path:
    """A cell in 3D, written to `path`: the robot's base, the flange poses A (numbered; those in
    `left_out` grey), where the camera is at each (eye in hand) or where it stands (eye to hand),
    with its field of view toward the board where the intrinsics `camera` are given, the board
    (its outline, or its origin where `board` is None),
    the path through the stations (`path_line`) and the next poses to record (`following`)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    scene = cell_scene(A, X, Y, setup, board, camera, left_out, following)
    size, eye_in_hand, cameras, boards = scene.size, scene.eye_in_hand, scene.cameras, scene.boards
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    _triad(ax, np.eye(4), 2 * size, lw=2.5)
    ax.text(0, 0, 0, " robot base")
    out = {int(i) for i in np.flatnonzero(~scene.kept)}
    for i, T in enumerate(A):
        if i in out:
            ax.scatter(*T[:3, 3], color="0.6", marker="x", s=30)
        else:
            _triad(ax, T, size)
        ax.text(*T[:3, 3], f" {i + 1}", fontsize=8, color="0.5" if i in out else "k")
    if path_line and len(A) > 1:
        ax.plot(*A[:, :3, 3].T, color="0.5", lw=0.8, ls="--", label="path through the stations")
    if len(scene.following):
        nxt = scene.following
        ax.scatter(*nxt[:, :3, 3].T, color="tab:orange", marker="*", s=120, label="next to record")
        for T in nxt:
            _triad(ax, T, size, lw=2.0)
    if eye_in_hand:
        ax.scatter(*cameras[:, :3, 3].T, marker="^", color="k", s=12, label="camera at each station")
        if scene.board_outline is not None:
            ax.plot(*scene.board_outline.T, color="k", lw=2, label="board")
        else:
            ax.scatter(*Y[:3, 3], marker="s", color="k", s=40, label="board")
    else:
        ax.scatter(*Y[:3, 3], marker="^", color="k", s=40, label="camera")
        ax.scatter(*boards[:, :3, 3].T, marker="s", color="k", s=10, label="board at each station")
    for k, edge in enumerate(scene.views):
        ax.plot(*edge.T, color="tab:purple", lw=0.6, alpha=0.6, label="camera's view" if k == 0 else None)
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_zlabel(f"z ({unit})")
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    ax.legend(unique.values(), unique.keys(), loc="upper left", fontsize=8)
    ax.set_title(title, fontsize=9)
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
