"""What a board detector returns: the points of a board found in one image (`Detection`), or
why the board was not found (`BoardNotFound`). Shared by the detectors of every board kind
(`handeye.vision.detect`, `circlegrid`, `aprilgrid`), which import it and not each other.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import Board


class BoardNotFound(InputError):
    """The board is not in the image (or not enough of it, or not unambiguously): the message
    says why in one line."""


@dataclasses.dataclass(frozen=True)
class Detection:
    """Points of `board` found in one image: ids (n,) into board.object_points(), image_points
    (n, 2) float64 sub-pixel pixels, object_points (n, 3) = board.object_points()[ids]. Read-only.

    method: which detector / flag set found these points ("" when not said). alternatives: the
    other detections of the same board in the same image (other detectors or flag sets), in the
    detector's order of preference, each without alternatives of its own; a caller that can judge
    them (`handeye.vision.best_corners`, with intrinsics) keeps the one that fits best."""

    ids: np.ndarray
    image_points: np.ndarray
    object_points: np.ndarray
    method: str = dataclasses.field(default="", compare=False)
    alternatives: tuple[Detection, ...] = dataclasses.field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).ravel()
        image_points = np.asarray(self.image_points, dtype=np.float64).reshape(-1, 2)
        object_points = np.asarray(self.object_points, dtype=np.float64).reshape(-1, 3)
        if not len(ids) == len(image_points) == len(object_points):
            raise InputError(f"Detection needs as many ids, image points and board points, got {len(ids)}, "
                             f"{len(image_points)} and {len(object_points)}")
        for name, value in (("ids", ids), ("image_points", image_points), ("object_points", object_points)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return len(self.ids)

    @classmethod
    def of(cls, board: Board, ids: np.ndarray, image_points: np.ndarray, method: str = "") -> Detection:
        """The detection of `board` with these ids and pixels, sorted by id."""
        ids = np.asarray(ids, dtype=np.int64).ravel()
        order = np.argsort(ids, kind="stable")
        points = np.asarray(image_points, dtype=np.float64).reshape(-1, 2)[order]
        return cls(ids[order], points, board.object_points()[ids[order]], method)

    def candidates(self) -> tuple[Detection, ...]:
        """This detection and its alternatives, in the detector's order of preference (each
        without alternatives)."""
        return (dataclasses.replace(self, alternatives=()), *self.alternatives)

    def with_alternatives(self, others: tuple[Detection, ...]) -> Detection:
        """This detection carrying `others` (their own alternatives dropped) as its alternatives."""
        return dataclasses.replace(self, alternatives=tuple(dataclasses.replace(o, alternatives=()) for o in others))
