"""Circle-grid detection: OpenCV's asymmetric grid (`circles`) and the symmetric grid with a big
origin dot (`circlegrid`, ROS-Industrial's "modified circle grid").

Both go through ``cv2.findCirclesGrid`` on blob candidates found here by a ``SimpleBlobDetector``
whose area limits follow the image size. The search's time grows steeply with the number of
candidates (one call on 640x480: 0.01 s for 200 candidates, ~0.1-0.3 s for 500, ~0.4-2 s for
1,000, 88 s for the 7,429 blobs of a random-noise image), so a candidate set larger than
`blob_limit` is not searched: the image is "too cluttered" (`BLOBS_PER_CIRCLE`). OpenCV's order of
a symmetric grid is one of its 8 (square) or 4 symmetries, so a
circlegrid is renumbered from the blob sizes: id 0 is the corner circle clearly larger than its
neighbours, x runs along its row of `cols` circles and y along its column so that z = x cross y
points out of the printed face, toward the camera (ROS-Industrial's frame: big dot bottom-left, x
right, y up, z out of the page). An asymmetric grid is renumbered only if OpenCV reports it mirrored
(z must point into the board, as OpenCV's y-down board frame has it).
"""

from __future__ import annotations

import cv2
import numpy as np

from handeye.vision.boards import BIG_DOT_RATIO, Board
from handeye.vision.detection import BoardNotFound, Detection

#: the big dot must look at least this much larger (diameter ratio to its two neighbours, relative
#: to the other corners') to name the origin
BIG_DOT_MARGIN = 1.3
#: points traced along each circle's outline to find its imaged centroid
_OUTLINE = 64
#: most blob candidates one grid search gets, per circle of the board, and the clip of that count
#: (`blob_limit`). findCirclesGrid stops finding a grid long before 5 x: on renders with dark clutter
#: discs around the board a 10x10 grid was found among up to 191 blobs (1.9 x) and once 338 (3.4 x),
#: lost from 219; a 5x4 grid among 107 (5.3 x), lost at 164; a 4x11 asymmetric grid among 102 (2.3 x),
#: lost at 133. The bundled real 10x10 set gives 100-103 blobs (1.6 x with the permissive detector).
#: MIN_BLOBS keeps small boards searchable where a search costs nothing (200 candidates: <= 20 ms);
#: MAX_BLOBS bounds one search on large boards (1,000 candidates: <= 2 s).
BLOBS_PER_CIRCLE = 5
MIN_BLOBS = 200
MAX_BLOBS = 1000


def find_circles(gray: np.ndarray, board: Board) -> Detection:
    """Detection of a `circles` or `circlegrid` board in a grayscale image (all points or BoardNotFound).
    Blob detectors are tried from strict to permissive (`_blob_detectors`), each candidate set
    searched once at most (`_candidates`: too few or too many blobs are not searched, a set equal
    to one already searched neither), so an image costs at most 2 x 2 findCirclesGrid calls (two
    detectors, a non-square grid in both orientations) on at most `blob_limit` candidates. A grid
    counts only if its centres are distinct and its blobs alike in size (OpenCV can return a grid
    with a point twice or a speck in it). Each detector's grid is a candidate (the first returned,
    a second one as its `Detection.alternatives`): their blob centroids differ by hundredths of a
    pixel, and `handeye.vision.best_corners` keeps the one fitting the camera best."""
    reasons: list[str] = []
    searched: list[np.ndarray] = []
    grids: list[Detection] = []
    for permissive, detector in enumerate(_blob_detectors(gray.shape)):
        if permissive and reasons and reasons[-1].startswith("too cluttered"):
            break  # the permissive detector finds at least the strict one's blobs: more clutter
        blobs = _candidates(gray, board, detector, probe=bool(permissive))
        if isinstance(blobs, str):
            reasons.append(blobs)
            continue
        positions, diameters = blobs
        key = positions[np.lexsort((positions[:, 0], positions[:, 1]))]
        if any(np.array_equal(key, done) for done in searched):  # the same search again
            continue
        searched.append(key)
        grid = _grid(positions, board)
        if grid is None:
            continue
        sizes = _blob_sizes(grid, positions, diameters)
        reason = _implausible(grid, sizes, board)
        if reason:
            reasons.append(reason)
            continue
        if board.kind == "circles":
            if _handedness(grid) < 0:  # mirrored numbering: same point set, rows reversed
                grid = grid[::-1]
        else:
            try:
                grid = _from_big_dot(grid, sizes, board)
            except BoardNotFound as error:  # another blob detector may measure the dots better
                reasons.append(str(error))
                continue
        points = _without_perspective_bias(grid.reshape(-1, 2), board)
        grids.append(Detection.of(board, np.arange(board.point_count), points,
                                  ("strict", "permissive")[permissive] + " blobs"))
    if grids:
        return grids[0].with_alternatives(tuple(grids[1:]))
    raise BoardNotFound(_not_found(board, reasons))


def blob_limit(board: Board) -> int:
    """Most blob candidates one findCirclesGrid search of `board` gets: `BLOBS_PER_CIRCLE` per circle,
    clipped to `MIN_BLOBS`..`MAX_BLOBS` (the constants say why)."""
    return int(np.clip(BLOBS_PER_CIRCLE * board.point_count, MIN_BLOBS, MAX_BLOBS))


def _candidates(gray: np.ndarray, board: Board, detector: cv2.SimpleBlobDetector,
                probe: bool) -> tuple[np.ndarray, np.ndarray] | str:
    """The blobs `detector` finds, as (positions (n, 2) float32, diameters (n,)) in its order, or
    the reason they are not worth a search: fewer than the board's circles, or more than
    `blob_limit` (noise, texture). `probe`: count the central quarter first (`_central_blob_count`)
    and give up at once when it alone holds too many, sparing the permissive detector's full run,
    which is what costs on noise (0.55 s on 640x480, 4x the strict detector's)."""
    limit = blob_limit(board)
    if probe:
        central = _central_blob_count(gray, detector)
        if central > limit:
            return _cluttered(f"at least {central}", board, limit)
    keypoints = detector.detect(gray)
    if len(keypoints) > limit:
        return _cluttered(str(len(keypoints)), board, limit)
    if len(keypoints) < board.point_count:
        return f"only {len(keypoints)} round dark blobs, fewer than the {board.point_count} circles"
    positions = np.array([k.pt for k in keypoints], dtype=np.float32).reshape(-1, 2)
    return positions, np.array([k.size for k in keypoints], dtype=np.float64)


def _cluttered(count: str, board: Board, limit: int) -> str:
    return (f"too cluttered ({count} round dark blobs for its {board.point_count} circles; a search takes at "
            f"most {limit})")


def _central_blob_count(gray: np.ndarray, detector: cv2.SimpleBlobDetector) -> int:
    """Blobs `detector` finds in the central quarter of the image (half its width and height) that
    stay a diameter clear of the crop's edges: a dark region enclosed by the crop is the same region
    in the whole image, so these are (up to the merging of blobs across thresholds) blobs of the
    whole image too -- a lower bound of its count at a quarter of the cost."""
    height, width = gray.shape[:2]
    crop = gray[height // 4:height // 4 + height // 2, width // 4:width // 4 + width // 2]
    if crop.size == 0:
        return 0
    h, w = crop.shape
    clear = [k for k in detector.detect(crop)
             if k.size <= k.pt[0] < w - 1 - k.size and k.size <= k.pt[1] < h - 1 - k.size]
    return len(clear)


def _not_found(board: Board, reasons: list[str]) -> str:
    """The one-line BoardNotFound message: a grid found but unusable says so itself; otherwise the
    most telling reason the searches failed (clutter, an implausible grid, too few blobs)."""
    what = f"{board.cols}x{board.rows} {'asymmetric circle grid' if board.kind == 'circles' else 'circle grid'}"
    for reason in reasons:
        if reason.startswith(("circle grid found", "the big dot")):
            return reason
    for reason in reasons:
        if reason.startswith("too cluttered"):
            return (f"no {what} in the image: {reason}; if the board is in it, crop or mask the background "
                    "(noise, texture or many small dark spots)")
    reason = min(reasons, key=lambda r: r.startswith("only")) if reasons else ""
    return (f"no {what} in the image{' (' + reason + ')' if reason else ''}; "
            "check cols (circles per row) and rows, focus and that every circle is visible")


def _without_perspective_bias(centres: np.ndarray, board: Board, iterations: int = 2) -> np.ndarray:
    """Blob centroids moved to the images of the circles' centres. A tilted circle images as an
    ellipse whose centroid is not the image of the centre (the near half looks larger): with the
    homography board -> image fitted to the centres, trace each circle's image (`_OUTLINE` points),
    take its area centroid and subtract its offset from the projected centre. Lens distortion is
    locally negligible over one circle."""
    board_xy = board.object_points()[:, :2]
    radii = np.full(len(board_xy), float(board.diameter) / 2)
    if board.kind == "circlegrid":
        radii[0] *= BIG_DOT_RATIO
    angles = np.linspace(0.0, 2 * np.pi, _OUTLINE, endpoint=False)
    outline = board_xy[:, None, :] + radii[:, None, None] * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    corrected = centres.copy()
    for _ in range(iterations):
        H, _ = cv2.findHomography(board_xy, corrected, 0)
        if H is None:
            return centres
        imaged = _apply(H, outline.reshape(-1, 2)).reshape(outline.shape)
        corrected = centres - (_polygon_centroids(imaged) - _apply(H, board_xy))
    return corrected


def _apply(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    p = np.column_stack([xy, np.ones(len(xy))]) @ H.T
    return p[:, :2] / p[:, 2:]


def _polygon_centroids(polygons: np.ndarray) -> np.ndarray:
    """Area centroids (n, 2) of closed polygons (n, k, 2) (shoelace formula)."""
    x, y = polygons[..., 0], polygons[..., 1]
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * yn - xn * y
    area = cross.sum(axis=1) / 2
    return np.column_stack([((x + xn) * cross).sum(axis=1), ((y + yn) * cross).sum(axis=1)]) / (6 * area[:, None])


def _blob_detectors(shape: tuple[int, ...]) -> list[cv2.SimpleBlobDetector]:
    """Dark round blobs: OpenCV's default blob detector (area up to a tenth of the image), then a
    permissive one for low contrast (lower threshold, smaller and less convex blobs)."""
    strict = cv2.SimpleBlobDetector_Params()
    strict.maxArea = max(5000.0, float(shape[0] * shape[1]) / 10)
    loose = cv2.SimpleBlobDetector_Params()
    loose.minThreshold, loose.maxThreshold, loose.thresholdStep = 20, 230, 10
    loose.minArea, loose.maxArea = 8.0, strict.maxArea
    loose.minInertiaRatio, loose.minConvexity, loose.minDistBetweenBlobs = 0.05, 0.85, 3.0
    return [cv2.SimpleBlobDetector_create(strict), cv2.SimpleBlobDetector_create(loose)]


def _grid(positions: np.ndarray, board: Board) -> np.ndarray | None:
    """(rows, cols, 2) centres in OpenCV's order or None, searched among the candidate `positions`
    (findCirclesGrid without a blob detector takes them as they are); a symmetric grid is also tried
    as (rows, cols) and transposed back."""
    candidates = positions.reshape(-1, 1, 2)
    parameters = cv2.CirclesGridFinderParameters()
    if board.kind == "circles":
        found, centers = cv2.findCirclesGrid(candidates, (board.cols, board.rows), cv2.CALIB_CB_ASYMMETRIC_GRID,
                                             None, parameters)
        return centers.reshape(board.rows, board.cols, 2).astype(np.float64) if found else None
    sizes = [((board.cols, board.rows), False)] + ([((board.rows, board.cols), True)] if board.cols != board.rows
                                                    else [])
    for size, transpose in sizes:
        found, centers = cv2.findCirclesGrid(candidates, size, cv2.CALIB_CB_SYMMETRIC_GRID, None, parameters)
        if found:
            grid = centers.reshape(size[1], size[0], 2).astype(np.float64)
            return grid.transpose(1, 0, 2) if transpose else grid
    return None


def _implausible(grid: np.ndarray, sizes: np.ndarray, board: Board) -> str:
    """Why `grid` is not a real detection ("" if it is): a centre twice, a blob missing, or blobs
    (apart from the corners, where the big dot is) unlike the others in size."""
    flat = grid.reshape(-1, 2)
    gaps = np.linalg.norm(flat[:, None] - flat[None], axis=2) + np.eye(len(flat)) * 1e9
    spacing = np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2))
    if gaps.min() < 0.3 * spacing:
        return "a circle was counted twice"
    if not np.all(np.isfinite(sizes)):
        return "a grid point has no blob under it"
    inner = sizes.copy()
    for corner in ((0, 0), (0, -1), (-1, 0), (-1, -1)):
        inner[corner] = np.nan
    ratio = inner / np.nanmedian(inner)
    if np.nanmin(ratio) < 0.6 or np.nanmax(ratio) > 1.6:
        return "circles of unequal size"
    return ""


def _blob_sizes(grid: np.ndarray, positions: np.ndarray, diameters: np.ndarray) -> np.ndarray:
    """(rows, cols) blob diameter at each grid centre (the nearest candidate blob, NaN if none
    within a quarter of the local spacing)."""
    spacing = np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2))
    flat = grid.reshape(-1, 2)
    distance = np.linalg.norm(flat[:, None, :] - positions[None, :, :].astype(np.float64), axis=2)
    nearest = distance.argmin(axis=1)
    sizes = np.where(distance[np.arange(len(flat)), nearest] < spacing / 4, diameters[nearest], np.nan)
    return sizes.reshape(grid.shape[:2])


def _from_big_dot(grid: np.ndarray, sizes: np.ndarray, board: Board) -> np.ndarray:
    """`grid` renumbered so that [0, 0] is the big dot, [0, :] its row of cols circles and z toward the
    camera. BoardNotFound when no corner is clearly the big dot or the board's counts contradict it."""
    rows, cols = grid.shape[:2]
    corners = {(0, 0): ((0, 1), (1, 0)), (0, cols - 1): ((0, cols - 2), (1, cols - 1)),
               (rows - 1, 0): ((rows - 1, 1), (rows - 2, 0)), (rows - 1, cols - 1): ((rows - 1, cols - 2),
                                                                                      (rows - 2, cols - 1))}
    ratios = {corner: sizes[corner] / np.mean([sizes[n] for n in neighbours])
              for corner, neighbours in corners.items()}
    if any(not np.isfinite(r) for r in ratios.values()):
        raise BoardNotFound("circle grid found but the size of a corner circle could not be measured, so its "
                            "origin (the big dot) is unknown; improve focus or lighting")
    ranked = sorted(ratios, key=ratios.get, reverse=True)
    best, second = ratios[ranked[0]], ratios[ranked[1]]
    if best < BIG_DOT_MARGIN * max(second, 1.0):
        raise BoardNotFound(f"circle grid found but no corner circle is clearly the big origin dot (largest size "
                            f"ratio {best:.2f}, next {second:.2f}); ambiguous orientation")
    r0, c0 = ranked[0]
    for candidate in _symmetries(grid):
        index, transformed = candidate
        if transformed.shape[:2] != (board.rows, board.cols) or tuple(index[0, 0]) != (r0, c0):
            continue
        if _handedness(transformed) < 0:  # x right, y up on the print: z out of it, toward the camera
            return transformed
    raise BoardNotFound(f"the big dot's corner makes a {board.cols}x{board.rows} circle grid left-handed; the board "
                        f"is {board.rows}x{board.cols} (swap cols and rows)")


def _symmetries(grid: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The grid under the 8 symmetries of a rectangle (transposes change its shape): pairs of
    (original (row, col) of each new cell, renumbered grid)."""
    rows, cols = grid.shape[:2]
    index = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), axis=-1)
    out = []
    for transpose in (False, True):
        g, i = (grid.transpose(1, 0, 2), index.transpose(1, 0, 2)) if transpose else (grid, index)
        for flip_rows in (False, True):
            for flip_cols in (False, True):
                gg, ii = g, i
                if flip_rows:
                    gg, ii = gg[::-1], ii[::-1]
                if flip_cols:
                    gg, ii = gg[:, ::-1], ii[:, ::-1]
                out.append((ii, gg))
    return out


def _handedness(grid: np.ndarray) -> float:
    """Sign of the image cross product of the board's x axis (along row 0) and y axis (down column 0):
    > 0 when the board's z points away from the camera (y-down print seen from the front)."""
    x = grid[0, -1] - grid[0, 0]
    y = grid[-1, 0] - grid[0, 0]
    return float(np.sign(x[0] * y[1] - x[1] * y[0]))
