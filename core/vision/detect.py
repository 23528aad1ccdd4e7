"""Find a calibration board in an image: which of its points are seen, where (sub-pixel) and which
board-frame coordinates they have.

`detect(image, board)` returns a `Detection` (ids into ``board.object_points()``, pixels, board
points) or raises `BoardNotFound` with a one-line reason. Where a kind has several detectors or
flag sets, all are run and the detection carries the others as `Detection.alternatives`, the first
in the order below; with `camera` the one fitting it best is returned, and an image set keeps per
image the one fitting its calibrated camera best (`handeye.vision.best_corners`, which says why):

- chessboard: ``cornerSubPix`` on the corners of the first flag set of
  ``cv2.findChessboardCornersSB`` that finds the board (else ``findChessboardCorners``), then SB's
  own corners with each of `SB_FLAG_SETS` that finds it (``CALIB_CB_EXHAUSTIVE`` only when none
  did). SB searches a padded crop around the board, located cheaply, and the full image when that
  fails (`handeye.vision.chessboard_region`: ACCURACY ~5x faster on 1.3 MP images, its corners
  within ~0.013 px RMS of the full image's, as near the truth). The order is OpenCV's; on a
  board with `Board.orientation_ambiguous` two images may number it 180 deg apart, which this
  module reports (the flag) but does not guess away. An image set runs only the flag sets its
  probe images kept (``flag_sets``, `handeye.vision.detection_plan`).
- charuco: ``cv2.aruco.CharucoDetector`` (ids are ChArUco corner ids; sub-pixel by OpenCV) with the
  markers refined by ``CORNER_REFINE_SUBPIX``, then by ``CORNER_REFINE_CONTOUR``, then OpenCV's
  corners refined again by ``cornerSubPix`` in a small window (`CHARUCO_WINDOW`).
- circles / circlegrid: ``cv2.findCirclesGrid`` on the blobs of a detector sized for the image, at
  most `handeye.vision.circlegrid.blob_limit` of them (more: "too cluttered"), which also orders a
  circlegrid from its big dot; the grid of each blob detector that finds one is a candidate.
- aprilgrid: ``cv2.aruco.ArucoDetector`` with tag36h11 and Kalibr's 2-bit border, corners refined
  by ``cornerSubPix`` (`handeye.vision.aprilgrid`).
"""

from __future__ import annotations

import cv2
import numpy as np

from handeye.base.errors import InputError
from handeye.vision.boards import Board, parse_board
from handeye.vision.chessboard_region import Region
from handeye.vision.detection import BoardNotFound, Detection
from handeye.vision.observations import Camera

#: fewest ChArUco corners a detection may have unless the caller says otherwise (a homography and
#: a pose need 4; 6 leaves a margin against a wrong interpolation)
CHARUCO_MIN_CORNERS = 6
#: fewest aprilgrid corners by default (two tags)
APRILGRID_MIN_CORNERS = 8
#: findChessboardCornersSB flag sets, in order: on 2 x 18 real 640 x 480 images (OpenCV 4.14) alone
#: ACCURACY calibrated best (0.114 / 0.110 px RMS), NORMALIZE | ACCURACY 0.137, none 0.141, NORMALIZE
#: 0.166-0.173; ACCURACY costs ~250 ms an image there, the others ~60 ms. Any of them can fail where
#: another finds the board.
_N, _A = cv2.CALIB_CB_NORMALIZE_IMAGE, cv2.CALIB_CB_ACCURACY
SB_FLAG_SETS = (("SB accuracy", _A), ("SB normalize accuracy", _N | _A), ("SB", 0), ("SB normalize", _N))
#: tried only when no flag set of SB_FLAG_SETS finds the board (it searches harder and, on real
#: images, once numbered a board wrongly)
SB_EXHAUSTIVE = ("SB exhaustive", _N | _A | cv2.CALIB_CB_EXHAUSTIVE)
#: cornerSubPix half window on ChArUco corners, as a fraction of a square's side in the image (2 px
#: at least): the square's corner must stay outside the marker. On the real ChArUco set 0.1 gave
#: 0.516 px calibration RMS against OpenCV's 0.525, 0.2 0.533, 0.3 0.655
CHARUCO_WINDOW = 0.1


def detect(image: np.ndarray, board: Board | str, *, min_corners: int | None = None,
           camera: Camera | None = None, flag_sets: tuple[str, ...] | None = None) -> Detection:
    """The points of `board` (a Board or a spec for parse_board) in `image` (uint8, gray or BGR/BGRA).
    `min_corners`: fewest points accepted (default: all of them for chessboard and circle boards,
    CHARUCO_MIN_CORNERS for charuco, APRILGRID_MIN_CORNERS for aprilgrid). `camera`: intrinsics to
    judge the candidates with (`handeye.vision.best_corners.pick`); without, the first candidate,
    the others as its `alternatives`. `flag_sets` (chessboard only): the names of the `SB_FLAG_SETS`
    to run (an image set's plan, `handeye.vision.detection_plan`); when none of them finds the
    board every other one runs, so the candidates are then those of a full run. Raises
    BoardNotFound when the board is absent, too little of it is seen or its orientation cannot be
    told."""
    board = parse_board(board) if isinstance(board, str) else board
    if not isinstance(board, Board):
        raise InputError(f"board must be a handeye.vision.boards.Board or a spec text, got {type(board).__name__}")
    gray = grayscale(image)
    needed = _needed(board, min_corners)
    if board.kind == "chessboard":
        found = _chessboard(gray, board, _planned(flag_sets))
    elif board.kind == "charuco":
        found = _charuco(gray, board)
    elif board.kind in ("circles", "circlegrid"):
        from handeye.vision.circlegrid import find_circles

        found = find_circles(gray, board)
    else:
        from handeye.vision.aprilgrid import find_aprilgrid

        found = find_aprilgrid(gray, board)
    if len(found) < needed:
        raise BoardNotFound(f"only {len(found)} {_point_name(board)} found, need {needed} ({board.describe()})")
    found = found.with_alternatives(tuple(a for a in found.alternatives if len(a) >= needed))
    if camera is not None:
        from handeye.vision.best_corners import pick

        return pick(found, camera)
    return found


def grayscale(image: np.ndarray) -> np.ndarray:
    """`image` as a 2-D uint8 array (BGR / BGRA converted, gray passed through, never modified)."""
    if not isinstance(image, np.ndarray):
        raise InputError(f"image must be a numpy array (e.g. from cv2.imread), got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise InputError(f"image must be 8-bit (uint8), got {image.dtype}; convert it, e.g. with "
                         "cv2.normalize(..., dtype=cv2.CV_8U)")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim == 2:
        gray = image
    elif image.ndim == 3 and image.shape[2] in (3, 4):
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    else:
        raise InputError(f"image must be gray (h, w) or colour (h, w, 3|4), got shape {image.shape}")
    if min(gray.shape) < 16:
        raise InputError(f"image of {gray.shape[1]}x{gray.shape[0]} pixels is too small to hold a board")
    return np.ascontiguousarray(gray)


def _needed(board: Board, min_corners: int | None) -> int:
    if min_corners is None:
        return {"charuco": CHARUCO_MIN_CORNERS, "aprilgrid": APRILGRID_MIN_CORNERS}.get(board.kind, board.point_count)
    if isinstance(min_corners, bool) or not isinstance(min_corners, (int, np.integer)) or min_corners < 4:
        raise InputError(f"min_corners must be a whole number >= 4 (a pose needs 4 points), got {min_corners!r}")
    if min_corners > board.point_count:
        raise InputError(f"min_corners {min_corners} exceeds the {board.point_count} points of the "
                         f"{board.describe()}")
    return int(min_corners)


def _point_name(board: Board) -> str:
    return {"chessboard": "chessboard corners", "charuco": "ChArUco corners", "circles": "circles",
            "circlegrid": "circles", "aprilgrid": "AprilGrid corners"}[board.kind]


# -- chessboard --------------------------------------------------------------------------------
def _planned(flag_sets: tuple[str, ...] | None) -> tuple[tuple[str, int], ...]:
    """The `SB_FLAG_SETS` named in `flag_sets`, in their own order (all of them for None)."""
    if flag_sets is None:
        return SB_FLAG_SETS
    unknown = sorted(set(flag_sets) - {name for name, _ in SB_FLAG_SETS})
    if unknown:
        raise InputError(f"unknown chessboard flag sets {unknown}; use names of {[n for n, _ in SB_FLAG_SETS]}")
    return tuple(s for s in SB_FLAG_SETS if s[0] in flag_sets)


def _chessboard(gray: np.ndarray, board: Board, planned: tuple[tuple[str, int], ...] = SB_FLAG_SETS) -> Detection:
    """cornerSubPix on the first corners found, then SB's own corners of each flag set of `planned`
    that finds the board, or of every other flag set when none does (module docstring); all in the
    canonical order."""
    size, ids = (board.cols, board.rows), np.arange(board.point_count)
    region = Region(gray, size)
    sb = _sb_candidates(gray, board, planned, region)
    if not sb and len(planned) < len(SB_FLAG_SETS):
        sb = _sb_candidates(gray, board, tuple(s for s in SB_FLAG_SETS if s not in planned), region)
    if not sb:
        found, corners = cv2.findChessboardCornersSB(gray, size, flags=SB_EXHAUSTIVE[1])
        if found:
            sb.append(Detection.of(board, ids, _canonical_order(gray, corners.reshape(-1, 2), board), SB_EXHAUSTIVE[0]))
    if sb:
        start, method = sb[0].image_points, "cornerSubPix on " + sb[0].method
    else:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
        if not found:
            raise BoardNotFound(f"no {board.cols}x{board.rows} chessboard (inner corners) in the image; check the "
                                "board size (inner corners, not squares), focus and that the whole board is visible")
        start, method = _canonical_order(gray, corners.reshape(-1, 2), board), "cornerSubPix on classic"
    refined = Detection.of(board, ids, _refine_corners(gray, start, board), method)
    return refined.with_alternatives(tuple(sb))


def _sb_candidates(gray: np.ndarray, board: Board, flag_sets: tuple[tuple[str, int], ...],
                  region: Region) -> list[Detection]:
    """SB's corners of each of `flag_sets` that finds the board, in that order, searched in
    `region` (a crop around the board, else the full image)."""
    ids = np.arange(board.point_count)
    sb = []
    for method, flags in flag_sets:
        corners = region.find(flags)
        if corners is not None:
            sb.append(Detection.of(board, ids, _canonical_order(gray, corners, board), method))
    return sb


def _canonical_order(gray: np.ndarray, corners: np.ndarray, board: Board) -> np.ndarray:
    """OpenCV's corner order, made right-handed (z into the board, as OpenCV's y-down board frame)
    and, on a board without the 180 deg ambiguity, started so that the first inner square (corners
    0, 1, cols, cols + 1) is white: the order findChessboardCornersSB gives, enforced for the
    classic detector too. An ambiguous board keeps OpenCV's choice of the two."""
    grid = corners.reshape(board.rows, board.cols, 2).astype(np.float64)
    x, y = grid[0, -1] - grid[0, 0], grid[-1, 0] - grid[0, 0]
    if x[0] * y[1] - x[1] * y[0] < 0:  # mirrored: same rows, numbered bottom-up
        grid = grid[::-1]
    if not board.orientation_ambiguous:
        other = (1, 2) if board.cols >= 3 else (2, 1)  # a neighbour of the first inner square, (col, row)
        if _square_brightness(gray, grid, 1, 1) < _square_brightness(gray, grid, *other):
            grid = grid[::-1, ::-1]
    return grid.reshape(-1, 2)


def _square_brightness(gray: np.ndarray, grid: np.ndarray, col: int, row: int) -> float:
    """Mean grey level around the centre of inner square (col, row) (corners [row-1:row+1, col-1:col+1])."""
    centre = grid[row - 1:row + 1, col - 1:col + 1].reshape(-1, 2).mean(axis=0)
    patch = cv2.getRectSubPix(gray, (3, 3), (float(centre[0]), float(centre[1])))
    return float(patch.mean())


def _refine_corners(gray: np.ndarray, corners: np.ndarray, board: Board) -> np.ndarray:
    """cornerSubPix on chessboard corners (n, 2) with a window of 0.4 of the smallest square seen
    (2..11 px): on renders it halves findChessboardCornersSB's own error (docs/boards.md)."""
    grid = corners.reshape(board.rows, board.cols, 2).astype(np.float64)
    square = min(np.min(np.linalg.norm(np.diff(grid, axis=1), axis=2)),
                 np.min(np.linalg.norm(np.diff(grid, axis=0), axis=2)))
    half = int(np.clip(square * 0.4, 2, 11))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    refined = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2).astype(np.float32), (half, half), (-1, -1), criteria)
    return refined.reshape(-1, 2).astype(np.float64)


# -- charuco -----------------------------------------------------------------------------------
def charuco_board(board: Board) -> cv2.aruco.CharucoBoard:
    """OpenCV's CharucoBoard for `board` (lengths in board.unit; its marker ids from
    `Board.first_id`; the legacy pattern if asked)."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary))
    ids = np.arange(board.marker_ids.start, board.marker_ids.stop, dtype=np.int32)
    cv_board = cv2.aruco.CharucoBoard((board.cols, board.rows), float(board.spacing), float(board.marker), dictionary,
                                      ids)
    cv_board.setLegacyPattern(bool(board.legacy))
    return cv_board


def _charuco(gray: np.ndarray, board: Board) -> Detection:
    cv_board = charuco_board(board)
    charuco_parameters = cv2.aruco.CharucoParameters()  # minMarkers 2: a corner needs both its markers
    detector_parameters = cv2.aruco.DetectorParameters()
    detector_parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.CharucoDetector(cv_board, charuco_parameters, detector_parameters)
    corners, ids, _, marker_ids = detector.detectBoard(gray)
    if marker_ids is not None:  # markers of other boards in the image do not count
        marker_ids = [m for m in np.ravel(marker_ids) if m in board.marker_ids]
    if marker_ids is None or len(marker_ids) == 0:
        raise BoardNotFound(f"no {board.dictionary} ArUco marker of the board in the image, so no ChArUco board "
                            f"({board.describe()}); check the dictionary, focus and lighting")
    if ids is None or len(ids) == 0:
        raise BoardNotFound(f"{len(marker_ids)} ArUco markers but no ChArUco corner found ({board.describe()}); "
                            "check the board size and marker size, or the legacy flag")
    first = Detection.of(board, ids.ravel(), corners.reshape(-1, 2), "CharucoDetector, markers SUBPIX")
    others = []
    detector_parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_CONTOUR
    corners, ids, _, _ = cv2.aruco.CharucoDetector(cv_board, charuco_parameters, detector_parameters).detectBoard(gray)
    if ids is not None and len(ids) > 0:
        others.append(Detection.of(board, ids.ravel(), corners.reshape(-1, 2), "CharucoDetector, markers CONTOUR"))
    if len(first) >= 4:
        others.append(_charuco_subpix(gray, first, board))
    return first.with_alternatives(tuple(others))


def _charuco_subpix(gray: np.ndarray, found: Detection, board: Board) -> Detection:
    """`found` refined by cornerSubPix with a half window of `CHARUCO_WINDOW` of the smallest
    square side the homography of its points gives (2 px at least)."""
    H, _ = cv2.findHomography(found.object_points[:, :2], found.image_points, 0)
    half = 2
    if H is not None:
        xy = found.object_points[:, :2]
        here = _homography(H, xy)
        sides = [np.linalg.norm(_homography(H, xy + step) - here, axis=1)
                 for step in ([board.spacing, 0.0], [0.0, board.spacing])]
        half = int(np.clip(CHARUCO_WINDOW * min(s.min() for s in sides), 2, 11))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    refined = cv2.cornerSubPix(gray, found.image_points.astype(np.float32).reshape(-1, 1, 2), (half, half), (-1, -1),
                               criteria)
    return Detection.of(board, found.ids, refined.reshape(-1, 2), "CharucoDetector + cornerSubPix")


def _homography(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    p = np.column_stack([xy, np.ones(len(xy))]) @ H.T
    return p[:, :2] / p[:, 2:]
