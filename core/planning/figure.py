"""A picture of a cell in 3D (`draw_cell`): the robot's base, the flange poses numbered in order,
where the camera is at each (eye in hand) or where it stands (eye to hand) with its field of
view, the board, and the next poses to record; of a plan (`draw`: the path through its stations,
the predicted 1-sigma in the title) and of a recording (``handeye watch --figure``: the stations
left out greyed). matplotlib's Agg backend, imported lazily."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

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

    eye_in_hand = setup == "eye-in-hand"
    cameras = A @ X if eye_in_hand else np.repeat(Y[None], len(A), axis=0)
    boards = np.repeat(Y[None], len(A), axis=0) if eye_in_hand else A @ X
    extra = [] if following is None or not len(following) else [np.asarray(following)[:, :3, 3]]
    points = np.concatenate([A[:, :3, 3], cameras[:, :3, 3], boards[:, :3, 3], np.zeros((1, 3)), *extra])
    size = 0.06 * float(np.ptp(points, axis=0).max() or 1.0)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    _triad(ax, np.eye(4), 2 * size, lw=2.5)
    ax.text(0, 0, 0, " robot base")
    out = set() if left_out is None else {int(i) for i in np.flatnonzero(left_out)}
    for i, T in enumerate(A):
        if i in out:
            ax.scatter(*T[:3, 3], color="0.6", marker="x", s=30)
        else:
            _triad(ax, T, size)
        ax.text(*T[:3, 3], f" {i + 1}", fontsize=8, color="0.5" if i in out else "k")
    if path_line and len(A) > 1:
        ax.plot(*A[:, :3, 3].T, color="0.5", lw=0.8, ls="--", label="path through the stations")
    if following is not None and len(following):
        nxt = np.asarray(following)
        ax.scatter(*nxt[:, :3, 3].T, color="tab:orange", marker="*", s=120, label="next to record")
        for T in nxt:
            _triad(ax, T, size, lw=2.0)
    distance = float(np.median(np.linalg.norm(boards[:, :3, 3] - cameras[:, :3, 3], axis=1)))
    if eye_in_hand:
        ax.scatter(*cameras[:, :3, 3].T, marker="^", color="k", s=12, label="camera at each station")
        if board is not None:
            ax.plot(*_board_outline(board, Y).T, color="k", lw=2, label="board")
        else:
            ax.scatter(*Y[:3, 3], marker="s", color="k", s=40, label="board")
    else:
        ax.scatter(*Y[:3, 3], marker="^", color="k", s=40, label="camera")
        ax.scatter(*boards[:, :3, 3].T, marker="s", color="k", s=10, label="board at each station")
    if camera is not None and getattr(camera, "size", None):
        for k, C in enumerate(cameras if eye_in_hand else cameras[:1]):
            for edge in _frustum(C, camera, distance):
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


def _frustum(C: np.ndarray, camera: Any, depth: float) -> list[np.ndarray]:
    """The four edges and the far rectangle of the camera's field of view (pose C = T_base_cam),
    out to `depth`, in the base frame."""
    width, height = camera.size
    K_inv = np.linalg.inv(camera.K)
    corners = np.array([[0, 0, 1], [width, 0, 1], [width, height, 1], [0, height, 1]], dtype=float) @ K_inv.T
    far = corners * depth / corners[:, 2:3]
    world = far @ C[:3, :3].T + C[:3, 3]
    edges = [np.array([C[:3, 3], p]) for p in world]
    edges.append(np.vstack([world, world[:1]]))
    return edges


def _board_outline(board: Board, T: np.ndarray) -> np.ndarray:
    """(5, 3) the board's printed outline in the base frame (closed)."""
    x0, y0, x1, y1 = board.extent()
    local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]], dtype=float)
    return local @ T[:3, :3].T + T[:3, 3]
