"""The pinhole camera's projection of points in the camera frame, with its Jacobians.

`project(points, camera)` returns the pixels of (n, 3) camera-frame points under OpenCV's model
(K, distortion k1, k2, p1, p2[, k3, ...]) and, from ``cv2.projectPoints`` itself (so the model is
exactly OpenCV's), d pixel / d point (n, 2, 3) and d pixel / d intrinsics (n, 2, 4 + len(dist)) in
the order fx, fy, cx, cy, dist. With the rotation and translation passed to OpenCV set to zero,
its derivative by the translation is the derivative by the point itself.

`point_jacobians(...)` chains d pixel / d point to right perturbations of two poses L, R of
p = L^-1 M R P (the board point P seen through the chain of a hand-eye cell), the form of
`handeye.vision.observations.board_in_camera` in both setups.
"""

from __future__ import annotations

import cv2
import numpy as np

from handeye.geometry.se3 import skew
from handeye.vision.observations import Camera

#: camera-frame depth below which a point counts as behind the camera
MIN_DEPTH = 1e-12


def project(points: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pixels (n, 2), d pixel / d point (n, 2, 3), d pixel / d intrinsics (n, 2, 4 + nd)) of
    camera-frame points (n, 3). Points at depth <= MIN_DEPTH give NaN pixels."""
    points = np.asarray(points, dtype=float)
    n = len(points)
    pixels, J = cv2.projectPoints(points.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), camera.K, camera.dist)
    pixels = pixels.reshape(n, 2)
    J = J.reshape(n, 2, -1)
    behind = points[:, 2] <= MIN_DEPTH
    if behind.any():
        pixels = pixels.copy()
        pixels[behind] = np.nan
    nd = len(camera.dist)
    return pixels, J[:, :, 3:6], J[:, :, 6:10 + nd]


def point_jacobians(q: np.ndarray, G: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d p / d xi_L and d p / d xi_R, each (n, 3, 6), of p = exp(xi_L)^-1 L^-1 M R exp(xi_R) P at
    xi = 0, for perturbations xi = (omega, v) applied as T <- T exp(xi) (`handeye.estimation.nlls.retract`).

    q: (n, 3) the points p at xi = 0; G: (3, 3) the rotation of L^-1 M R; P: (n, 3) the points in
    the frame of R. To first order exp(xi) x = x + omega x x + v, so
    d p / d xi_R = G [-[P]_x | I] and d p / d xi_L = [[q]_x | -I].
    """
    n = len(q)
    dR = np.empty((n, 3, 6))
    dR[:, :, :3] = -G @ skew(P)
    dR[:, :, 3:] = G
    dL = np.empty((n, 3, 6))
    dL[:, :, :3] = skew(q)
    dL[:, :, 3:] = -np.eye(3)
    return dL, dR
