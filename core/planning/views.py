"""The camera's view of the board at a planned station: can the board be used there (wholly in the
image, in the distance range, not too oblique, its printed face toward the camera), and how sure
is the pose that PnP will give of it (the covariance of T_cam_target from pixel noise)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.se3 import inverse
from handeye.vision.boards import Board
from handeye.vision.observations import Camera
from handeye.vision.render import printed_normal


@dataclasses.dataclass(frozen=True)
class ViewLimits:
    """What makes a view of the board usable: distance of the camera from the board's centre
    (board.unit), largest angle between the optical axis and the board's normal (deg), and the
    margin of every board point from the image border (pixels)."""

    distance: tuple[float, float]
    max_angle_deg: float = 45.0
    margin_px: float = 20.0
    #: (rad, length): the margin also grows by the pixels that a rotation of this much and a
    #: shift of this much at the board's distance move it (`tightened`)
    slack: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        near, far = (float(v) for v in self.distance)
        if not 0.0 < near < far:
            raise InputError(f"the viewing distance range must be two increasing positive numbers, got {self.distance}")
        if not 0.0 < self.max_angle_deg < 90.0:
            raise InputError(f"the largest viewing angle must lie between 0 and 90 deg, got {self.max_angle_deg}")
        if self.margin_px < 0:
            raise InputError(f"the image margin must not be negative, got {self.margin_px}")


def tightened(limits: ViewLimits, rough_rad: float, rough_length: float) -> ViewLimits:
    """The limits a planned view must meet so that the real one still shows the whole board when X
    and Y are each off by up to rough_rad (any axis) and rough_length: the image margin grows by
    the pixels a rotation of 2 rough_rad and a shift of 2 rough_length at the board's distance
    move it (`ViewLimits.slack`). The angle and distance limits are kept as given: the real view
    may pass them by 2 rough_rad and 2 rough_length, which costs a little precision, where a
    board partly out of the image costs the station. (A plan sits on the limits: D-optimal
    stations are as oblique and as far apart as allowed.)"""
    return dataclasses.replace(limits, slack=(2.0 * rough_rad, 2.0 * rough_length))


def board_centre(board: Board) -> np.ndarray:
    """The centre of the board's printed pattern in its frame (z = 0)."""
    x0, y0, x1, y1 = board.extent()
    return np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0, 0.0])


def printed_outline(board: Board) -> np.ndarray:
    """(8, 3) the printed pattern's corners and edge midpoints in its frame (`Board.extent`): a
    view that keeps them in the image keeps the whole pattern (its image is a quadrilateral,
    convex; the midpoints for a lens's slight bend of the edges), the outer squares too, which the
    points a detector finds (`Board.object_points`) stop short of."""
    x0, y0, x1, y1 = board.extent()
    xm, ym = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    xy = [(x0, y0), (xm, y0), (x1, y0), (x1, ym), (x1, y1), (xm, y1), (x0, y1), (x0, ym)]
    return np.array([(x, y, 0.0) for x, y in xy])


def project(points: np.ndarray, camera: Camera, T_cam_target: np.ndarray) -> np.ndarray:
    """(..., n, 2) pixels of board points (n, 3) at poses T_cam_target (..., 4, 4) (pinhole, no
    distortion: the planner's views keep away from the image border). NaN behind the camera."""
    p = np.einsum("...ij,nj->...ni", T_cam_target[..., :3, :3], points) + T_cam_target[..., None, :3, 3]
    z = np.where(p[..., 2] > 0, p[..., 2], np.nan)
    K = camera.K
    return np.stack([K[0, 0] * p[..., 0] / z + K[0, 1] * p[..., 1] / z + K[0, 2],
                     K[1, 1] * p[..., 1] / z + K[1, 2]], axis=-1)


def usable(board: Board, camera: Camera, T_cam_target: np.ndarray, limits: ViewLimits) -> np.ndarray:
    """(m,) whether each view T_cam_target (m, 4, 4) is usable (`ViewLimits`, printed face toward
    the camera): every board point and the whole printed pattern (`printed_outline`) inside the
    image by the margin; the image size is the camera's (required)."""
    if camera.size is None:
        raise InputError("planning needs the camera's image size (width, height) in pixels with its intrinsics")
    T = np.asarray(T_cam_target, dtype=float).reshape(-1, 4, 4)
    centre = board_centre(board)
    centre_cam = np.einsum("mij,j->mi", T[:, :3, :3], centre) + T[:, :3, 3]
    distance = np.linalg.norm(centre_cam, axis=1)
    normal_cam = T[:, :3, :3] @ printed_normal(board)  # points out of the printed face
    facing = np.einsum("mi,mi->m", normal_cam, -centre_cam) / np.maximum(distance, 1e-300)
    uv = project(np.concatenate([board.object_points(), printed_outline(board)]), camera, T)
    width, height = camera.size
    f = float(max(camera.K[0, 0], camera.K[1, 1]))
    margin = (limits.margin_px + f * limits.slack[0] + f * limits.slack[1] / np.maximum(distance, 1e-300))[:, None]
    inside = np.all((uv[..., 0] >= margin) & (uv[..., 0] <= width - margin) & (uv[..., 1] >= margin)
                    & (uv[..., 1] <= height - margin), axis=1)
    near, far = limits.distance
    return (inside & (distance >= near) & (distance <= far)
            & (facing >= math.cos(math.radians(limits.max_angle_deg))))


def pose_covariance(board: Board, camera: Camera, T_cam_target: np.ndarray, pixel_sigma: float) -> np.ndarray:
    """(m, 6, 6) covariance of the PnP pose T_cam_target from pixel noise pixel_sigma (px, each
    coordinate of every board point), as the perturbation xi = (omega, v) of T exp(xi) in the
    board's own frame: pixel_sigma^2 (J^T J)^-1 with J the projections' Jacobian (Gauss-Newton:
    the first-order covariance of the least-squares pose). Depth is typically 3-10x less sure
    than the sideways position, and more so far away and face-on."""
    T = np.asarray(T_cam_target, dtype=float).reshape(-1, 4, 4)
    P = board.object_points()
    R, t = T[:, :3, :3], T[:, :3, 3]
    p = np.einsum("mij,nj->mni", R, P) + t[:, None, :]  # (m, n, 3) in the camera frame
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    fx, fy = camera.K[0, 0], camera.K[1, 1]
    d_uv = np.zeros(p.shape[:2] + (2, 3))  # d(u, v) / d p_cam
    d_uv[..., 0, 0], d_uv[..., 0, 2] = fx / z, -fx * x / z**2
    d_uv[..., 1, 1], d_uv[..., 1, 2] = fy / z, -fy * y / z**2
    # p_cam = R (P + omega x P + v) + t: d p / d(omega, v) = R [-[P]x, I]
    d_p = np.zeros(p.shape[:2] + (3, 6))
    skew = np.zeros((len(P), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -P[:, 2], P[:, 1], -P[:, 0]
    skew -= np.swapaxes(skew, 1, 2)
    d_p[..., :3] = -np.einsum("mij,njk->mnik", R, skew)
    d_p[..., 3:] = R[:, None]
    J = np.einsum("mnab,mnbc->mnac", d_uv, d_p).reshape(len(T), -1, 6)
    return pixel_sigma**2 * np.linalg.inv(np.einsum("mki,mkj->mij", J, J))


def target_to_camera_frame(T_cam_target: np.ndarray, cov_target: np.ndarray) -> np.ndarray:
    """The covariance of T_target_cam = T_cam_target^-1 in its own (camera) frame from that of
    T_cam_target in its own (board) frame: inverse(T exp(xi)) = exp(-xi) T^-1 = T^-1 exp(-Ad(T) xi),
    so Ad(T) cov Ad(T)^T, Ad(T) = [[R, 0], [[t]x R, R]] for xi = (omega, v)."""
    T = np.asarray(T_cam_target, dtype=float).reshape(-1, 4, 4)
    R, t = T[:, :3, :3], T[:, :3, 3]
    tx = np.zeros_like(R)
    tx[:, 0, 1], tx[:, 0, 2], tx[:, 1, 2] = -t[:, 2], t[:, 1], -t[:, 0]
    tx -= np.swapaxes(tx, 1, 2)
    Ad = np.zeros((len(T), 6, 6))
    Ad[:, :3, :3] = R
    Ad[:, 3:, 3:] = R
    Ad[:, 3:, :3] = tx @ R
    return Ad @ cov_target @ np.swapaxes(Ad, 1, 2)


def views_of(B: np.ndarray, setup: str) -> np.ndarray:
    """T_cam_target of the camera poses B as axyb takes them (eye in hand T_target_cam, eye to
    hand T_cam_target; docs/conventions.md)."""
    return inverse(B) if setup == "eye-in-hand" else np.asarray(B, dtype=float)
