"""One image's board detection as a self-contained work item: read the file, detect the board, and
say what came of it (`Outcome`). The unit a detecting thread runs (`handeye.vision.detection_pool`)
and that the detection cache stores (`handeye.vision.detection_cache`): it depends only on the
file's content, the board and the detector settings, never on the other images.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import Board
from handeye.vision.detection import Detection


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What one image gave: the detection (None when not found or unreadable), why not (None when
    found), the image size (width, height; None when unreadable) and, for an image that was not
    8-bit, its depth name and largest value (it was scaled to 8 bits to be detected)."""

    detection: Detection | None
    reason: str | None
    size: tuple[int, int] | None
    depth: tuple[str, float] | None

    @property
    def readable(self) -> bool:
        return self.size is not None


def read_and_detect(path: str | Path, board: Board, flag_sets: tuple[str, ...] | None = None) -> Outcome:
    """`Outcome` of the file `path` with the default detector (`handeye.vision.detect.detect`;
    `flag_sets`: its chessboard plan)."""
    from handeye.vision.detect import detect

    return detect_file(Path(path), board, lambda image, b: detect(image, b, flag_sets=flag_sets))


def detect_file(path: Path, board: Board, detector) -> Outcome:
    """`Outcome` of the file `path` with `detector(image, board)`: an unreadable file or a board not
    found (an InputError of the reader or the detector) is an outcome with its reason, not an error."""
    from handeye.vision.image_files import depth_name, read_any, to_8bit

    try:
        raw = read_any(path)
        image = to_8bit(raw, path.name)
    except InputError as exc:
        return Outcome(None, str(exc).removeprefix(f"{path.name}: "), None, None)
    size = (int(image.shape[1]), int(image.shape[0]))
    depth = None if raw.dtype == np.uint8 else (depth_name(raw.dtype), float(raw.max()))
    try:
        return Outcome(detector(image, board), None, size, depth)
    except InputError as exc:
        return Outcome(None, f"board not found: {exc}", size, depth)
