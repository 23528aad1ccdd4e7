"""The board's pose in the camera, T_cam_target, from one image's detected points (PnP).

Planar boards (every board point at z = 0) are solved with ``cv2.solvePnPGeneric(...,
SOLVEPNP_IPPE)``, which returns both poses a plane admits; the one with the smaller reprojection
error is refined with ``cv2.solvePnPRefineLM`` (Levenberg-Marquardt on the reprojection error).
Other point sets start from ``SOLVEPNP_SQPNP``. Translations come out in the unit of the board
points passed in: give them in the robot's unit (`handeye.vision.image_set` converts).

`flag_outliers` names the images whose RMS reprojection error is far above the others'
(> `OUTLIER_FACTOR` x the median and > `OUTLIER_MIN_PX`): a wrong detection, motion blur or a
board that moved; such an image must not be used silently.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import cv2
import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import make_pose
from handeye.vision.observations import Camera

#: an image is an outlier when its RMS exceeds this many times the median RMS ...
OUTLIER_FACTOR = 5.0
#: ... and this many pixels
OUTLIER_MIN_PX = 2.0
#: |z| / board size below which the board points count as planar
PLANAR_TOL = 1e-9


@dataclasses.dataclass(frozen=True)
class BoardPose:
    """T_cam_target (4x4, translation in the board points' unit) and the RMS reprojection error
    (pixels) of the image's points at that pose."""

    T_cam_target: np.ndarray
    rms: float


def board_pose(object_points: np.ndarray, image_points: np.ndarray, camera: Camera, *, name: str = "image") -> BoardPose:
    """The board pose that best reprojects `object_points` (n, 3) onto `image_points` (n, 2 pixels)."""
    obj = np.ascontiguousarray(object_points, dtype=np.float64).reshape(-1, 3)
    img = np.ascontiguousarray(image_points, dtype=np.float64).reshape(-1, 2)
    if len(obj) != len(img) or len(obj) < 4:
        raise InputError(f"{name}: a board pose needs at least 4 points with both pixels and board coordinates, "
                         f"got {len(img)} and {len(obj)}")
    size = float(np.ptp(obj, axis=0).max()) or 1.0
    planar = bool(np.all(np.abs(obj[:, 2]) <= PLANAR_TOL * size))
    K, dist = camera.K, camera.dist
    try:
        if planar:
            _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        else:
            _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, dist, flags=cv2.SOLVEPNP_SQPNP)
        if not rvecs:
            raise InputError(f"{name}: OpenCV found no board pose for its {len(obj)} points")
        errors = [_rms(obj, img, r, t, camera) for r, t in zip(rvecs, tvecs)]
        best = int(np.argmin(errors))
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvecs[best].copy(), tvecs[best].copy(),
                                          criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    except cv2.error as exc:
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
        raise InputError(f"{name}: the board pose could not be computed ({reason})") from None
    rms = _rms(obj, img, rvec, tvec, camera)
    T = make_pose(cv2.Rodrigues(rvec)[0], np.ravel(tvec))
    if T[2, 3] <= 0:
        raise InputError(f"{name}: the board pose puts the board behind the camera; check the intrinsics and board")
    T.setflags(write=False)
    return BoardPose(T, rms)


def _rms(obj: np.ndarray, img: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, camera: Camera) -> float:
    projected, _ = cv2.projectPoints(obj, rvec, tvec, camera.K, camera.dist)
    return float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))


def flag_outliers(rms: Sequence[float], names: Sequence[str]) -> list[tuple[int, str]]:
    """(index, reason) of each image whose RMS exceeds `OUTLIER_FACTOR` x the median of all and
    `OUTLIER_MIN_PX` pixels."""
    values = np.asarray(rms, dtype=float)
    if len(values) < 3:
        return []
    median = float(np.median(values))
    limit = max(OUTLIER_FACTOR * median, OUTLIER_MIN_PX)
    return [(i, (f"reprojection error {v:.3g} px is far above the others' (median {median:.3g} px, limit "
                 f"{limit:.3g} px): a wrong detection, blur or a moved board"))
            for i, v in enumerate(values) if v > limit]
