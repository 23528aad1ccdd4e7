"""The image run's part of the quality report: its data (`image_entries`, JSON-ready, for
`handeye.workflow.quality_report.collect`) and its corner overlays (`overlay_png`).

Each kept image's reprojection error is stated twice: at the board pose of the image alone (the
corners' own fit: detection and intrinsics) and through the robot's pose and the answer, i.e.
where the calibrated cell predicts the board (A X = Y B: the board in the camera is
``board_in_camera(setup, A_i, X, Y)``). The images the answer predicts worst get an overlay: the
detected corners (green circles), the corners at the image's own pose (blue +) and as predicted
(red x), so that a user sees whether a bad station is the image (blur, a wrong detection) or the
robot's pose.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

#: how many of the worst-predicted images get an overlay
OVERLAYS = 3
#: overlays show the board's region (the detected corners' box and this share of it around),
#: scaled to this width (px), so that offsets of a few pixels show
OVERLAY_MARGIN = 0.15
OVERLAY_WIDTH = 720


def image_entries(image_set: Any, board: str, setup: str, robot_poses: np.ndarray | None,
                  unknowns: Mapping[str, np.ndarray], intrinsics: str) -> dict[str, Any]:
    """The report's ``images`` entry of an image run.

    image_set: `handeye.vision.image_set.ImageSet` of the kept stations; board: the board as the
    user gave it; setup; robot_poses: (m, 4, 4) T_base_flange of those stations, in the image set's
    unit (None: no prediction); unknowns: the answer ({"X", "Y"} of A X = Y B; without Y no
    prediction); intrinsics: where the intrinsics came from (a file, or "calibrated")."""
    from handeye.vision.observations import board_in_camera
    from handeye.vision.projection import project

    obs, cam = image_set.observations, image_set.camera
    predicted = None
    if robot_poses is not None and "Y" in unknowns and "X" in unknowns:
        predicted = board_in_camera(setup, robot_poses, unknowns["X"], unknowns["Y"])
    stations, overlays = [], []
    for k, (u, p) in enumerate(zip(obs.image_points, obs.object_points)):
        own = _pixels(p, image_set.T_cam_target[k], cam, project)
        through = None if predicted is None else _pixels(p, predicted[k], cam, project)
        stations.append({"image": image_set.names[k], "file": image_set.files[k],
                         "robot_pose": None if image_set.pose_names is None else image_set.pose_names[k],
                         "points": len(u), "pnp_rms_px": _rms(own - u),
                         "calibrated_rms_px": None if through is None else _rms(through - u)})
        overlays.append((k, u, own, through))
    order = sorted(range(len(stations)), key=lambda k: -(stations[k]["calibrated_rms_px"] or stations[k]["pnp_rms_px"]))
    worst = [{"image": stations[k]["image"], "file": stations[k]["file"], "detected": overlays[k][1].tolist(),
              "own": overlays[k][2].tolist(), "predicted": None if overlays[k][3] is None else overlays[k][3].tolist()}
             for k in order[:OVERLAYS]]
    camera: dict[str, Any] = {"source": intrinsics, "K": cam.K.tolist(), "dist": cam.dist.tolist(),
                              "image_size": None if cam.size is None else list(cam.size)}
    if image_set.calibration is not None:
        camera.update({"rms_px": float(image_set.calibration.rms), "images": len(image_set.calibration.per_image_rms)})
    return {"board": board, "camera": camera, "stations": stations, "overlays": worst}


def _pixels(points: np.ndarray, T_cam_target: np.ndarray, cam: Any, project: Any) -> np.ndarray:
    T = np.asarray(T_cam_target, dtype=float)
    return project(points @ T[:3, :3].T + T[:3, 3], cam)[0]


def _rms(e: np.ndarray) -> float:
    e = np.asarray(e, dtype=float)
    return float(math.sqrt(np.nanmean(np.sum(e * e, axis=1)))) if len(e) else float("nan")


def overlay_png(entry: Mapping[str, Any]) -> bytes | None:
    """The overlay of one image (an ``overlays`` entry of `image_entries`) as PNG bytes, or None
    when the image cannot be read any more."""
    import cv2

    from handeye.vision.image_set import read_image, to_8bit

    try:
        gray = to_8bit(read_image(entry["file"]), str(entry["file"]))
    except Exception:  # noqa: BLE001 - the report is written without the overlay of an image gone since
        return None
    detected = np.asarray(entry["detected"], dtype=float)
    lo, hi = detected.min(axis=0), detected.max(axis=0)
    pad = OVERLAY_MARGIN * (hi - lo) + 10
    x0, y0 = np.maximum(np.floor(lo - pad), 0).astype(int)
    x1, y1 = np.minimum(np.ceil(hi + pad), [gray.shape[1], gray.shape[0]]).astype(int)
    origin = np.array([x0, y0], dtype=float)
    scale = OVERLAY_WIDTH / max(x1 - x0, 1)
    image = cv2.resize(cv2.cvtColor(gray[y0:y1, x0:x1], cv2.COLOR_GRAY2BGR), None, fx=scale, fy=scale,
                       interpolation=cv2.INTER_CUBIC if scale > 1 else cv2.INTER_AREA)
    size = max(4, round(OVERLAY_WIDTH / 120))

    def at(points: Any) -> list[tuple[int, int]]:
        q = (np.asarray(points, dtype=float) - origin) * scale
        return [(int(round(u)), int(round(v))) for u, v in q if np.isfinite(u) and np.isfinite(v)]

    for p in at(detected):
        cv2.circle(image, p, size, (60, 180, 60), 2, cv2.LINE_AA)
    for p in at(entry["own"]):
        cv2.drawMarker(image, p, (220, 120, 30), cv2.MARKER_CROSS, 2 * size, 2)
    if entry.get("predicted") is not None:
        for p in at(entry["predicted"]):
            cv2.drawMarker(image, p, (40, 40, 220), cv2.MARKER_TILTED_CROSS, 2 * size, 2)
    ok, png = cv2.imencode(".png", image)
    return png.tobytes() if ok else None
