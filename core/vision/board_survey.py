"""Which chessboard the images show, whatever size was given: a wrong board size named in seconds.

A chessboard spec with the wrong counts fails slowly or, worse, quietly. A smaller board than the
printed one (17x12 given for a 24x17 board) is found as a sub-board in most images, wherever the
detector happens to lock on, and the camera calibrated from such corners fits them to many pixels
with an impossible focal length; a larger one (28x17) is found in none, after the detector has
searched every image with every flag set (minutes on 30 images of 2 MP).

`check_chessboard_size` looks first, on a few probe images (those of
`handeye.vision.detection_plan.probe_indices`), at what is printed: OpenCV's ``findChessboardCornersSBWithMeta`` with
``CALIB_CB_LARGER`` grows a small seed pattern (`SEED`) to the whole board it sits in, on the image
shrunk to `SURVEY_SIDE` pixels (~0.1-0.2 s an image; ``CALIB_CB_EXHAUSTIVE`` is needed for it to
grow beyond the seed). When most probe images with a board show one size, none shows the size
given, and that size is not the one given, `BoardSizeError` names it ("the images show a 24x17
chessboard ..."). A probe image where nothing is found, or only a part of the board (a view cut by
the image's edge), casts no vote against the given size; fewer than `MIN_VOTES` agreeing images
give no verdict (the detection then runs as it always did).
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import Board

#: the seed pattern (inner corners) the survey grows from, at most this many each way: large
#: enough that image noise or texture never forms it (a 3x3 seed is found in pure noise)
SEED = 5
#: the long side (pixels) the probe images are shrunk to before the survey
SURVEY_SIDE = 1000
#: fewest probe images that must agree on another size for a verdict
MIN_VOTES = 2
_FLAGS = cv2.CALIB_CB_LARGER | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_NORMALIZE_IMAGE


class BoardSizeError(InputError):
    """The images show another chessboard than the one given (its counts named)."""


@dataclasses.dataclass(frozen=True)
class Survey:
    """What the probe images show: per image (name) the chessboard grid found, (cols, rows) inner
    corners as OpenCV's patternSize counts them, or None."""

    grids: tuple[tuple[str, tuple[int, int] | None], ...]

    def verdict(self, board: Board) -> tuple[tuple[int, int], int] | None:
        """(the size most probe images show, how many show it) when it is not `board`'s and the
        module docstring's rule names it; else None."""
        given = _key((board.cols, board.rows))
        seen = [_key(g) for _, g in self.grids if g is not None]
        if not seen or given in seen:
            return None
        size, votes = Counter(seen).most_common(1)[0]
        if votes < min(MIN_VOTES, len(self.grids)) or 2 * votes <= len(seen):
            return None
        return next(g for _, g in self.grids if g is not None and _key(g) == size), votes

    def voters(self, size: tuple[int, int]) -> list[str]:
        """The probe images that show a board of `size`."""
        return [name for name, g in self.grids if g is not None and _key(g) == _key(size)]


def chessboard_grid(gray: np.ndarray, board: Board) -> tuple[int, int] | None:
    """The whole chessboard (cols, rows of inner corners) around a `SEED`-sized part of one in the
    8-bit image `gray`, or None when there is none (module docstring)."""
    seed = (min(board.cols, SEED), min(board.rows, SEED))
    if min(seed) < 3:
        return None
    found, _, meta = cv2.findChessboardCornersSBWithMeta(_shrunk(gray), seed, flags=_FLAGS)
    if not found or meta is None:
        return None
    rows, cols = meta.shape[:2]
    return int(cols), int(rows)


def shows_given(gray: np.ndarray, board: Board) -> bool:
    """Whether the given chessboard itself is found in the 8-bit image `gray` at the survey's scale:
    the check before naming a size smaller than the given one (the survey may stop growing short of
    a steeply seen board's far rows)."""
    found, _ = cv2.findChessboardCornersSB(_shrunk(gray), (board.cols, board.rows),
                                           flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_NORMALIZE_IMAGE)
    return bool(found)


def survey(files: Sequence[Path], board: Board, workers: int | None = None) -> Survey:
    """The chessboard grid each of `files` shows (unreadable files: None), over `workers` threads."""
    from handeye.vision.detection_pool import map_in_order

    return Survey(tuple(zip((Path(f).name for f in files),
                            map_in_order(lambda f: _on_image(f, chessboard_grid, board), list(files), workers))))


def check_chessboard_size(probes: Sequence[Path], board: Board, workers: int | None = None) -> Survey | None:
    """`BoardSizeError` when the probe images `probes` (a few spread over the set) show another
    chessboard than `board` (module docstring); the survey otherwise (None for boards of other
    kinds)."""
    if board.kind != "chessboard":
        return None
    found = survey(probes, board, workers)
    verdict = found.verdict(board)
    if verdict is not None and any(a < b for a, b in zip(_key(verdict[0]), _key((board.cols, board.rows)))):  # confirm
        from handeye.vision.detection_pool import map_in_order

        named = set(found.voters(verdict[0]))
        if any(map_in_order(lambda f: _on_image(f, shows_given, board), [f for f in probes if Path(f).name in named],
                            workers)):
            verdict = None
    if verdict is not None:
        (cols, rows), votes = verdict
        if (cols >= rows) != (board.cols >= board.rows):  # counted the way the given board is
            cols, rows = rows, cols
        square = f"{board.spacing:g}{board.unit}"
        raise BoardSizeError(
            f"the images show a {cols}x{rows} chessboard (inner corners), not the {board.cols}x{board.rows} given: "
            f"found in {votes} of the {len(probes)} images looked at first ({', '.join(n for n, _ in found.grids)}); "
            f"give the board as chessboard:{cols}x{rows}:{square} (and check the square size)")
    return found


def _shrunk(gray: np.ndarray) -> np.ndarray:
    """`gray` with its long side at most `SURVEY_SIDE` pixels (area-averaged)."""
    scale = min(1.0, SURVEY_SIDE / max(gray.shape[:2]))
    return gray if scale == 1.0 else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)


def _on_image(path: Path, look, board: Board):
    """`look(gray, board)` on the image file `path` (None when it cannot be read)."""
    from handeye.vision.detect import grayscale
    from handeye.vision.image_files import read_any, to_8bit

    path = Path(path)
    try:
        gray = grayscale(to_8bit(read_any(path), path.name))
    except InputError:
        return None
    return look(gray, board)


def _key(grid: tuple[int, int]) -> tuple[int, int]:
    """A grid's size whichever way round it is counted (a 24x17 board given as 17x24 is the same)."""
    return tuple(sorted(grid))  # type: ignore[return-value]
