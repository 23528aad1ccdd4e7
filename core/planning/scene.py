"""A cell's geometry as it is drawn, computed once for every picture of it: the matplotlib figure
of ``plan --figure`` / ``watch --figure`` (`handeye.planning.figure`) and the live view in the
browser of ``watch --live`` (`handeye.planning.live_view`).

`cell_scene` places, in the robot's base frame and the data's length unit: the flange poses of the
stations (those left out marked), where the camera is at each station (eye in hand) or where it
stands (eye to hand), where the board is, the camera's field of view toward the board (with its
intrinsics), the board's printed outline (with its layout), and the next poses to record.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye.vision.boards import Board


@dataclasses.dataclass(frozen=True)
class CellScene:
    """What a picture of a cell shows (module docstring); poses (·, 4, 4), lines (·, k, 3) polylines.

    stations: the flange poses T_base_flange; kept: (m,) bool, False for a station left out;
    cameras, boards: T_base_cam and T_base_board at each station (eye to hand: the one camera
    repeated; eye in hand: the one board repeated); eye_in_hand; board_outline: (5, 3) closed, of the
    board standing in the cell (eye in hand, with its layout), else None; views: the camera's field of view, each a
    polyline (the four edges from the centre and the far rectangle), empty without intrinsics;
    following: the next poses to record, (k, 4, 4), possibly empty; size: a length that reads at
    the cell's scale (6% of its extent), for axes and markers."""

    stations: np.ndarray
    kept: np.ndarray
    cameras: np.ndarray
    boards: np.ndarray
    eye_in_hand: bool
    board_outline: np.ndarray | None
    views: tuple[np.ndarray, ...]
    following: np.ndarray
    size: float


def cell_scene(A: np.ndarray, X: np.ndarray, Y: np.ndarray, setup: str, board: Board | None = None,
               camera: Any = None, left_out: np.ndarray | None = None,
               following: np.ndarray | None = None) -> CellScene:
    """The scene of a cell with flange poses A (m, 4, 4) and the answer X, Y in `setup`'s
    convention (docs/conventions.md): eye in hand X = T_flange_cam, Y = T_base_board; eye to hand
    X = T_flange_board, Y = T_base_cam. `board` in the data's unit; `camera` with `K` and `size`
    for the field of view; `left_out` (m,) bool; `following` the next poses to record."""
    A = np.asarray(A, dtype=float)
    eye_in_hand = setup == "eye-in-hand"
    cameras = A @ X if eye_in_hand else np.repeat(np.asarray(Y, dtype=float)[None], len(A), axis=0)
    boards = np.repeat(np.asarray(Y, dtype=float)[None], len(A), axis=0) if eye_in_hand else A @ X
    nxt = np.zeros((0, 4, 4)) if following is None else np.asarray(following, dtype=float).reshape(-1, 4, 4)
    points = np.concatenate([A[:, :3, 3], cameras[:, :3, 3], boards[:, :3, 3], np.zeros((1, 3)), nxt[:, :3, 3]])
    size = 0.06 * float(np.ptp(points, axis=0).max() or 1.0)
    kept = np.ones(len(A), dtype=bool) if left_out is None else ~np.asarray(left_out, dtype=bool)
    views: list[np.ndarray] = []
    if camera is not None and getattr(camera, "size", None) and len(A):
        distance = float(np.median(np.linalg.norm(boards[:, :3, 3] - cameras[:, :3, 3], axis=1)))
        for C in cameras if eye_in_hand else cameras[:1]:
            views += frustum_edges(C, camera, distance)
    outline = board_outline(board, np.asarray(Y, dtype=float)) if board is not None and eye_in_hand else None
    return CellScene(A, kept, cameras, boards, eye_in_hand, outline, tuple(views), nxt, size)


def frustum_edges(C: np.ndarray, camera: Any, depth: float) -> list[np.ndarray]:
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


def board_outline(board: Board, T: np.ndarray) -> np.ndarray:
    """(5, 3) the board's printed outline in the base frame (closed), the board at pose T."""
    x0, y0, x1, y1 = board.extent()
    local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]], dtype=float)
    return local @ T[:3, :3].T + T[:3, 3]
