"""The cell in a browser while it records (``handeye watch --live``): the robot's base, the
stations (those left out grey), the camera and its field of view, the board, and the next poses
to record, redrawn at every answer. The scene is the figure's (`handeye.planning.scene`); viser
(an optional dependency, ``pip install "handeye[live]"``) serves it as a three.js page over a
websocket, so any browser on the network can follow the recording.

viser's scene is in metres: the data's lengths are scaled from their unit, which the page's
title states.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterator
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.base.errors import InputError
from handeye.base.vocabulary import METRES_PER
from handeye.planning.scene import CellScene

#: the port ``watch --live`` serves on when none is given
DEFAULT_PORT = 8080
#: colours (RGB 0-255): stations, those left out, the next poses, the board, the field of view
KEPT, LEFT_OUT, NEXT, BOARD, VIEW = (40, 40, 40), (170, 170, 170), (255, 140, 0), (0, 0, 0), (148, 103, 189)


class LiveView:
    """A viser server showing one `CellScene` at a time (`show`); `url` is where to look.
    InputError when viser is not installed or the port cannot be served."""

    def __init__(self, unit: str, port: int = DEFAULT_PORT, host: str = "localhost") -> None:
        try:
            import viser
        except ImportError:
            raise InputError('--live needs the package viser: pip install "handeye[live]"') from None
        try:
            with _quiet():  # viser prints a banner and its stop; the command's output is the user's
                self.server = viser.ViserServer(host=host, port=int(port), verbose=False)
        except OSError as exc:
            raise InputError(f"--live: cannot serve on {host}:{port} ({exc.strerror or exc}); give another port") from None
        self.host, self.unit = host, unit
        self.nodes: dict[str, Any] = {}
        self._title = self.server.gui.add_markdown("waiting for an answer")

    @property
    def scale(self) -> float:
        """Metres per unit of the data (viser's scene is in metres)."""
        return METRES_PER[self.unit]

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.server.get_port()}"

    def show(self, scene: CellScene, title: str) -> None:
        """Draw `scene` in place of the one shown (nodes no longer in it are removed)."""
        size = scene.size * self.scale
        drawn: dict[str, Any] = {}
        add = self.server.scene
        drawn["/base"] = add.add_frame("/base", axes_length=2 * size, axes_radius=0.05 * size)
        for i, (T, kept) in enumerate(zip(scene.stations, scene.kept)):
            name = f"/stations/{i + 1}"
            if kept:
                drawn[name] = add.add_frame(name, axes_length=size, axes_radius=0.03 * size, **self._pose(T))
            else:
                drawn[name] = add.add_point_cloud(name, self._points(T[None, :3, 3]), LEFT_OUT, point_size=0.3 * size)
            drawn[f"{name}/label"] = add.add_label(f"{name}/label", str(i + 1))
        for k, T in enumerate(scene.following):
            name = f"/next/{k + 1}"
            drawn[name] = add.add_frame(name, axes_length=1.5 * size, axes_radius=0.06 * size,
                                        origin_color=NEXT, **self._pose(T))
        cameras = scene.cameras[scene.kept] if scene.eye_in_hand else scene.cameras[:1]
        drawn["/cameras"] = add.add_point_cloud("/cameras", self._points(cameras[:, :3, 3]), KEPT,
                                                point_size=0.25 * size, point_shape="diamond")
        if scene.board_outline is not None:
            drawn["/board"] = add.add_line_segments("/board", self._segments(scene.board_outline), BOARD,
                                                    thickness=0.04 * size)
        else:
            boards = scene.boards[:1] if scene.eye_in_hand else scene.boards[scene.kept]
            drawn["/board"] = add.add_point_cloud("/board", self._points(boards[:, :3, 3]), BOARD,
                                                  point_size=0.25 * size)
        if scene.views:
            segments = np.concatenate([self._segments(line) for line in scene.views])
            drawn["/views"] = add.add_line_segments("/views", segments, VIEW, thickness=0.015 * size)
        self._aim(scene)
        for name in sorted(set(self.nodes) - set(drawn), key=lambda n: -n.count("/")):  # children first
            self.nodes[name].remove()
        self.nodes = drawn
        self._title.content = f"{title} (lengths in m; the data are in {self.unit})"

    def _aim(self, scene: CellScene) -> None:
        """Where a browser opening the page looks: at the middle of the cell (stations, cameras,
        boards, the robot's base), from above and aside, far enough to see all of it (z up)."""
        points = np.concatenate([scene.stations[:, :3, 3], scene.cameras[:, :3, 3], scene.boards[:, :3, 3],
                                 np.zeros((1, 3))]) * self.scale
        low, high = points.min(axis=0), points.max(axis=0)
        centre, extent = (low + high) / 2, max(float(np.max(high - low)), 1e-3)
        camera = self.server.initial_camera
        camera.up = (0.0, 0.0, 1.0)
        camera.look_at = tuple(centre)
        camera.position = tuple(centre + extent * np.array([1.0, -1.0, 0.8]))

    def close(self) -> None:
        with _quiet():
            self.server.stop()

    def _pose(self, T: np.ndarray) -> dict[str, np.ndarray]:
        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        return {"wxyz": np.array([w, x, y, z]), "position": T[:3, 3] * self.scale}

    def _points(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points, dtype=np.float32).reshape(-1, 3) * np.float32(self.scale)

    def _segments(self, polyline: np.ndarray) -> np.ndarray:
        """(k - 1, 2, 3) the segments of a polyline (k, 3), in metres."""
        p = np.asarray(polyline, dtype=float) * self.scale
        return np.stack([p[:-1], p[1:]], axis=1)


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        yield
