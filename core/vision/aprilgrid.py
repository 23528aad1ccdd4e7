"""AprilGrid detection (Kalibr's target): tag36h11 tags found by ``cv2.aruco.ArucoDetector`` with
Kalibr's 2-bit black tag border, their corners refined by ``cornerSubPix`` on the X-junctions that
the grid's corner squares make, and numbered 4 * tag_id + k with k = 0..3 the tag's bottom-left,
bottom-right, top-right and top-left corner on the print (Kalibr's order; tag 0 bottom-left, ids
row-major upward; a grid whose `first_id` is N carries tags N, N + 1, ...). Tags whose id is not
on the board are ignored (another grid, stray tags)."""

from __future__ import annotations

import cv2
import numpy as np

from handeye.vision.boards import Board
from handeye.vision.detection import BoardNotFound, Detection

#: Kalibr draws its tags with a 2-bit black border (kalibr_create_target_pdf, borderBits=2)
BORDER_BITS = 2
#: OpenCV returns a marker's corners as top-left, top-right, bottom-right, bottom-left of the marker
#: as ``cv2.aruco.generateImageMarker`` draws it. Kalibr prints each tag36h11 tag turned 180 deg from
#: that drawing (kalibr_create_target_pdf: bit 6i + j of the code, rot90 twice, i.e. the code read
#: most significant bit first from the top-left, white where a bit is set), so those corners lie at
#: the printed tag's bottom-right, bottom-left, top-left, top-right: Kalibr's k = 1, 0, 3, 2
#: (k = 0..3 bottom-left, bottom-right, top-right, top-left).
_KALIBR_FROM_OPENCV = np.array([1, 0, 3, 2])


def find_aprilgrid(gray: np.ndarray, board: Board) -> Detection:
    """Detection of an aprilgrid board in a grayscale image (the tags seen, or BoardNotFound)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = BORDER_BITS
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(gray)
    if ids is None or len(ids) == 0:
        raise BoardNotFound(f"no AprilTag (tag36h11 with a 2-bit border) in the image ({board.describe()}); check "
                            "focus, lighting and that the board is Kalibr's AprilGrid")
    ids = ids.ravel()
    first, last = board.marker_ids.start, board.marker_ids.stop - 1
    keep = (ids >= first) & (ids <= last)
    if not np.any(keep):
        raise BoardNotFound(f"AprilTags found (ids {sorted(set(ids.tolist()))[:6]}) but none with an id of this "
                            f"{board.cols}x{board.rows} grid ({first}..{last}); check the grid size and first id")
    tags = ids[keep] - first
    if len(np.unique(tags)) != len(tags):
        raise BoardNotFound("the same AprilTag id is seen twice; hide other AprilGrids or tags from the camera")
    quads = np.asarray([corners[i] for i in np.flatnonzero(keep)], dtype=np.float32).reshape(-1, 4, 2)
    refined = _refine(gray, quads, board)
    point_ids = 4 * tags[:, None] + _KALIBR_FROM_OPENCV[None, :]
    return Detection.of(board, point_ids.ravel(), refined.reshape(-1, 2))


def _refine(gray: np.ndarray, quads: np.ndarray, board: Board) -> np.ndarray:
    """Sub-pixel corners: cornerSubPix on each tag corner with a window inside the tag's border and
    the neighbouring corner square (at most 0.15 tag sides, at least 2 px)."""
    side = np.linalg.norm(np.roll(quads, -1, axis=1) - quads, axis=2).min(axis=1)  # shortest tag edge, px
    reach = min(0.2, board.tag_spacing)  # border: 2 of 10 bits
    refined = quads.copy()
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    for half in np.unique(np.clip((0.75 * reach * side).astype(int), 2, 12)):
        chosen = np.clip((0.75 * reach * side).astype(int), 2, 12) == half
        points = quads[chosen].reshape(-1, 1, 2).copy()
        refined[chosen] = cv2.cornerSubPix(gray, points, (int(half), int(half)), (-1, -1),
                                           criteria).reshape(-1, 4, 2)
    return refined.astype(np.float64)
