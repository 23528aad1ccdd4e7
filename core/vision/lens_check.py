"""Intrinsics that no real lens gives: the sign of a board described wrongly, refused.

When the corners given to the camera calibration are not the board's (a sub-board found where
the printed one is larger, a circle grid's rows counted wrong), OpenCV still returns intrinsics:
on a real 24x17 chessboard given as 17x12 they fit the corners to 12.9 px RMS with fx 8639
against fy 1829. Every hand-eye answer built on them is garbage. Two figures tell: the RMS
reprojection error of the calibration (a real camera and board: 0.07-0.5 px; `RMS_LIMIT`), and
the ratio of the focal lengths fx / fy (square pixels: 1 to a fraction of a percent; industrial
cameras have square pixels, `ASPECT_LIMIT` allows far more). Either beyond its limit, the images'
calibration is refused with the board named (`lens_problem`): the survey of the board's size
(`handeye.vision.board_survey`) catches a wrong chessboard first, this catches the rest.
"""

from __future__ import annotations

from collections.abc import Mapping

from handeye.vision.boards import Board
from handeye.vision.intrinsics import CameraCalibration

#: RMS reprojection error (pixels) of a calibration from the images beyond which no real board and
#: lens explain the corners (measured on the real sets: two KUKA chessboard sets 0.074 and 0.077 px,
#: industrial_calibration's circle grid 0.19 px and ChArUco 0.52 px; a wrong board: 5-13 px)
RMS_LIMIT = 2.0
#: fx / fy (or fy / fx) beyond which the pixels would not be square to 10%
ASPECT_LIMIT = 1.1


def lens_problem(calibration: CameraCalibration, board: Board | Mapping[str, Board]) -> str | None:
    """Why the intrinsics calibrated from the images of `board` (or of several boards, by name)
    are no real lens's, or None."""
    fx, fy = float(calibration.camera.K[0, 0]), float(calibration.camera.K[1, 1])
    aspect = max(fx / fy, fy / fx) if fx > 0 and fy > 0 else float("inf")
    if calibration.rms <= RMS_LIMIT and aspect <= ASPECT_LIMIT:
        return None
    return (f"the camera calibrated from the images fits the board's points to {calibration.rms:.3g} px RMS with "
            f"fx {fx:.6g} px against fy {fy:.6g} px, which no real lens gives (a real camera: below {RMS_LIMIT:g} px, "
            f"fx / fy within {ASPECT_LIMIT - 1:.0%} of 1): {_named(board)} probably not the one in the images; "
            "check its kind, counts (inner corners for a chessboard) and sizes, or give the intrinsics")


def _named(board: Board | Mapping[str, Board]) -> str:
    if isinstance(board, Board):
        return f"the board ({board.describe()}) is"
    boards = "; ".join(f"{name}: {b.describe()}" for name, b in board.items())
    return f"the board ({boards}) is" if len(board) == 1 else f"one of the boards ({boards}) is"
