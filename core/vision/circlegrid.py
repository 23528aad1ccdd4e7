"""Circle-grid detection: OpenCV's asymmetric grid (`circles`) and the symmetric grid with a big
origin dot (`circlegrid`, ROS-Industrial's "modified circle grid").

Both go through ``cv2.findCirclesGrid`` with a ``SimpleBlobDetector`` whose area limits follow the
image size. OpenCV's order of a symmetric grid is one of its 8 (square) or 4 symmetries, so a
circlegrid is renumbered from the blob sizes: id 0 is the corner circle clearly larger than its
neighbours, x runs along its row of `cols` circles and y along its column so that z = x cross y
points out of the printed face, toward the camera (ROS-Industrial's frame: big dot bottom-left, x
right, y up, z out of the page). An asymmetric grid is renumbered only if OpenCV reports it mirrored
(z must point into the board, as OpenCV's y-down board frame has it).
"""

from __future__ import annotations

import cv2
import numpy as np

from .boards import BIG_DOT_RATIO, Board
from .detect import BoardNotFound, Detection

#: the big dot must look at least this much larger (diameter ratio to its two neighbours, relative
#: to the other corners') to name the origin
BIG_DOT_MARGIN = 1.3
#: points traced along each circle's outline to find its imaged centroid
_OUTLINE = 64


def find_circles(gray: np.ndarray, board: Board) -> Detection:
    """Detection of a `circles` or `circlegrid` board in a grayscale image (all points or BoardNotFound).
    Blob detectors are tried from strict to permissive (`_blob_detectors`); a grid counts only if its
    centres are distinct and its blobs alike in size (OpenCV can return a grid with a point twice or a
    speck in it)."""
    reason = ""
    for detector in _blob_detectors(gray.shape):
        grid = _grid(gray, board, detector)
        if grid is None:
            continue
        sizes = _blob_sizes(gray, grid, detector)
        reason = _implausible(grid, sizes, board)
        if reason:
            continue
        if board.kind == "circles":
            if _handedness(grid) < 0:  # mirrored numbering: same point set, rows reversed
                grid = grid[::-1]
        else:
            try:
                grid = _from_big_dot(grid, sizes, board)
            except BoardNotFound as error:  # another blob detector may measure the dots better
                reason = str(error)
                continue
        points = _without_perspective_bias(grid.reshape(-1, 2), board)
        return Detection.of(board, np.arange(board.point_count), points)
    if reason.startswith(("circle grid found", "the big dot")):
        raise BoardNotFound(reason)
    what = "asymmetric circle grid" if board.kind == "circles" else "circle grid"
    raise BoardNotFound(f"no {board.cols}x{board.rows} {what} in the image{' (' + reason + ')' if reason else ''}; "
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


def _grid(gray: np.ndarray, board: Board, detector: cv2.SimpleBlobDetector) -> np.ndarray | None:
    """(rows, cols, 2) centres in OpenCV's order or None; a symmetric grid is also tried as
    (rows, cols) and transposed back."""
    if board.kind == "circles":
        found, centers = cv2.findCirclesGrid(gray, (board.cols, board.rows), None, cv2.CALIB_CB_ASYMMETRIC_GRID,
                                             detector)
        return centers.reshape(board.rows, board.cols, 2).astype(np.float64) if found else None
    sizes = [((board.cols, board.rows), False)] + ([((board.rows, board.cols), True)] if board.cols != board.rows
                                                    else [])
    for size, transpose in sizes:
        found, centers = cv2.findCirclesGrid(gray, size, None, cv2.CALIB_CB_SYMMETRIC_GRID, detector)
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


def _blob_sizes(gray: np.ndarray, grid: np.ndarray, detector: cv2.SimpleBlobDetector) -> np.ndarray:
    """(rows, cols) blob diameter at each grid centre (the nearest blob, NaN if none within a
    quarter of the local spacing)."""
    keypoints = detector.detect(gray)
    if not keypoints:
        return np.full(grid.shape[:2], np.nan)
    positions = np.array([k.pt for k in keypoints])
    diameters = np.array([k.size for k in keypoints])
    spacing = np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2))
    flat = grid.reshape(-1, 2)
    distance = np.linalg.norm(flat[:, None, :] - positions[None, :, :], axis=2)
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
