"""Several named boards that one camera may see in one image (the targets of a cell of several
cameras and targets): whether they can be told apart, and each one's points in an image.

Boards are told apart by their marker ids: ChArUco boards and AprilGrids of one dictionary must
carry disjoint id ranges (`Board.first_id`; docs/boards.md). A chessboard or circle grid has no
ids, so a camera may look for at most one of them (with any number of boards that have ids):
two would be found at each other's place, or a larger grid's corners read as a smaller one's.

`detect_boards(image, boards)` runs the detector of every board on the image and returns the
detections found and, for the others, why each was not found (one line each: not in the image,
too few points, ...), so the caller can report every (image, board) left out.

`detect_board_files(files, boards, camera)` does so for one camera's folder of images as fast as
one camera's image set is detected: per board, `handeye.vision.detection_plan.detect_set` (the
images over the cores, the detection cache, and for a chessboard the flag-set plan, judged on
this camera's images only: a camera's images are alike, another camera's need not be), so that a
rerun of a cell of several cameras with other options reads every detection from the cache.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import APRILGRID_DICTIONARY, Board
from handeye.vision.observations import Camera

#: kinds without marker ids: found by their pattern alone
WITHOUT_IDS = ("chessboard", "circles", "circlegrid")

Detector = Callable[[np.ndarray, Board], Any]
#: how `handeye.vision.image_detection.Outcome.reason` begins for a board not found
_NOT_FOUND = "board not found: "


@dataclasses.dataclass(frozen=True)
class BoardsFound:
    """What one image shows of a set of named boards: `found` maps a board's name to its
    `handeye.vision.detection.Detection`; `missing` maps each other board's name to the reason."""

    found: dict[str, Any]
    missing: dict[str, str]


#: what one image of a camera's folder gave: its size (width, height) and the boards in it, or the
#: InputError that makes it unreadable
ImageBoards = tuple[tuple[int, int], BoardsFound] | InputError


def _family(board: Board) -> str:
    """The id space a board's markers live in (an aprilgrid's tags are tag36h11 ids)."""
    return APRILGRID_DICTIONARY if board.kind == "aprilgrid" else str(board.dictionary)


def check_distinct(boards: Mapping[str, Board], where: str = "targets") -> None:
    """InputError (one line, naming `where` and both boards) unless every board of `boards` can be
    told apart from the others in one image (module docstring)."""
    plain = [name for name, b in boards.items() if b.kind in WITHOUT_IDS]
    if len(plain) > 1:
        raise InputError(f"{where}: {plain[0]!r} and {plain[1]!r} are both {boards[plain[0]].kind} / "
                         f"{boards[plain[1]].kind} boards without marker ids, which one image cannot tell apart; "
                         "give each camera at most one of them (its `targets` list) or use ChArUco boards or "
                         "AprilGrids with distinct ids (first=N)")
    with_ids = [(name, b) for name, b in boards.items() if b.kind not in WITHOUT_IDS]
    for k, (name, board) in enumerate(with_ids):
        for other, theirs in with_ids[k + 1:]:
            if _family(board) != _family(theirs):
                continue
            ours, their_ids = board.marker_ids, theirs.marker_ids
            if ours.start < their_ids.stop and their_ids.start < ours.stop:
                raise InputError(f"{where}: {name!r} (ids {ours.start}..{ours.stop - 1}) and {other!r} (ids "
                                 f"{their_ids.start}..{their_ids.stop - 1}) share {_family(board)} marker ids, so "
                                 f"one image cannot tell them apart; print them with disjoint ids and give each "
                                 f"its first id (e.g. first={ours.stop})")


def detect_boards(image: np.ndarray, boards: Mapping[str, Board], detector: Detector | None = None) -> BoardsFound:
    """Each board of `boards` (name -> Board) in `image` (8-bit grey): the detections and, for a
    board not found, the detector's one-line reason. `detector`: ``(image, board) -> Detection``
    raising InputError when the board is not found (default `handeye.vision.detect.detect`)."""
    if detector is None:
        from handeye.vision.detect import detect as detector
    found: dict[str, Any] = {}
    missing: dict[str, str] = {}
    for name, board in boards.items():
        try:
            found[name] = detector(image, board)
        except InputError as exc:
            missing[name] = str(exc)
    return BoardsFound(found, missing)


def detect_board_files(files: Sequence[Path], boards: Mapping[str, Board], camera: Camera | None = None, *,
                       workers: int | None = None, cache: bool | str | Path | None = None,
                       detector: Detector | None = None) -> list[ImageBoards]:
    """Per file of one camera, in order: ``(size, BoardsFound)``, or the InputError that makes it
    unreadable (module docstring). camera: its intrinsics, if given (a chessboard's plan is judged
    with them); workers: detection threads (default: the cores, `HANDEYE_WORKERS`); cache: None /
    True the environment's detection cache, False none, a folder that one; detector: ``(image,
    board) -> Detection`` instead of the built-in ones, run one image at a time, never cached."""
    files = [Path(f) for f in files]
    if detector is not None:
        from handeye.vision.detection_pool import map_in_order

        return map_in_order(lambda path: _detect_image(path, boards, detector), files, 1)
    from handeye.vision.detection_plan import detect_set

    per_board = {name: detect_set(files, board, camera, workers=workers, cache=cache)
                 for name, board in boards.items()}
    out: list[ImageBoards] = []
    for k in range(len(files)):
        outcomes = {name: found[k] for name, found in per_board.items()}
        unreadable = next((o for o in outcomes.values() if not o.readable), None)
        if unreadable is not None:
            out.append(InputError(str(unreadable.reason)))
            continue
        size = next(iter(outcomes.values())).size
        out.append((size, BoardsFound({n: o.detection for n, o in outcomes.items() if o.detection is not None},
                                      {n: str(o.reason).removeprefix(_NOT_FOUND) for n, o in outcomes.items()
                                       if o.detection is None})))
    return out


def _detect_image(path: Path, boards: Mapping[str, Board], detector: Detector) -> ImageBoards:
    """One image's (size, boards found) with `detector`, or the InputError that makes it unreadable."""
    from handeye.vision.image_files import read_any, to_8bit

    try:
        image = to_8bit(read_any(path), path.name)
    except InputError as exc:
        return exc
    return (image.shape[1], image.shape[0]), detect_boards(image, boards, detector)
