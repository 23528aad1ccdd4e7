"""The board corners of a hand-eye cell as the reprojection solver models them: the chain from the
unknowns to the pixels, its Jacobians, and the fit with the robot's poses taken as exact.

The board in the camera at station i is T_cam_target,i = Y^-1 A_i X (eye-to-hand) or
X^-1 A_i^-1 Y (eye-in-hand) (`handeye.vision.observations`), written p = L^-1 M_i R P with L, R
the unknowns in that order, and corner j projects to pi(K, dist; p) (OpenCV's camera model,
`handeye.vision.projection`). Where the robot's pose at station i is itself in error, A_i
becomes A_i exp(delta_i) (delta_i = (omega, v) in the flange frame): M_i exp(delta_i)
eye-to-hand and exp(-delta_i) M_i eye-in-hand (`residuals` with ``robot``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from handeye.base.errors import SolverError
from handeye.estimation.nlls import retract
from handeye.estimation.robust import loss_terms
from handeye.framework.caching import cached_property
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.problems.axyb import AXYBData

#: relative decrease of the cost, and step size relative to the parameters' scale, below which
#: Levenberg-Marquardt has converged
TOL = 1e-14
#: RMS pixel error of exact data after rounding (pixels are ~1e3, doubles ~1e-16 relative)
ROUNDING_PX = 1e-9


@dataclasses.dataclass(frozen=True)
class StationChains:
    """What the projection of station i needs: the chain p = L^-1 M_i R P (L, R the unknowns in
    that order, `left`/`right` their names), the corners, and each corner's station."""

    left: str
    right: str
    M: np.ndarray
    points: tuple[np.ndarray, ...]
    pixels: tuple[np.ndarray, ...]
    eye_in_hand: bool

    @classmethod
    def of(cls, data: AXYBData) -> StationChains:
        images = data.images
        if images.setup == "eye-to-hand":  # T_cam_target = Y^-1 A X
            return cls("Y", "X", np.asarray(data.A), images.object_points, images.image_points, False)
        return cls("X", "Y", inverse(data.A), images.object_points, images.image_points, True)  # X^-1 A^-1 Y

    @property
    def counts(self) -> np.ndarray:
        """The corners of each station."""
        return np.array([len(u) for u in self.pixels])

    @cached_property
    def station(self) -> np.ndarray:
        """(n,) each corner's station."""
        return np.repeat(np.arange(len(self.pixels)), self.counts)

    @cached_property
    def object_points(self) -> np.ndarray:
        """(n, 3) every station's board points, stacked."""
        return np.concatenate(self.points).astype(float, copy=False).reshape(-1, 3)

    @cached_property
    def image_points(self) -> np.ndarray:
        """(n, 2) every station's detected corners, stacked."""
        return np.concatenate(self.pixels).astype(float, copy=False).reshape(-1, 2)


def robot_poses(delta: np.ndarray) -> np.ndarray:
    """(m, 4, 4) exp(delta_i) to first order (`handeye.estimation.nlls.retract` of the identity)
    of the robot-pose corrections delta (m, 6) = (omega, v)."""
    return make_pose(so3_exp(delta[:, :3]), delta[:, 3:])


def residuals(cell: StationChains, poses: dict[str, np.ndarray], camera: Any, jacobian: bool,
              robot: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Stacked pixel residuals (n, 2) (prediction - detection) and, if asked, their Jacobian
    (n, 2, 12 + ni [+ 6]) by right perturbations of X, Y (in that order), the intrinsics and,
    with `robot` (m, 6) corrections delta_i of the robot's poses (module docstring), by each
    corner's own station's delta. Every corner of every station at once: one projection, and
    each corner's station's transforms gathered by `StationChains.station`."""
    from handeye.vision.projection import project

    L, R = poses[cell.left], poses[cell.right]
    Linv = inverse(L)
    M = cell.M
    if robot is not None:
        E = robot_poses(robot)
        M = inverse(E) @ M if cell.eye_in_hand else M @ E  # exp(-delta) M, M exp(delta)
    T = Linv @ M @ R                                           # (m, 4, 4): board to camera
    at = cell.station
    G = T[at, :3, :3]                                          # each corner's station's rotation
    P = cell.object_points
    q = np.einsum("nij,nj->ni", G, P) + T[at, :3, 3]
    pixels, Jp, Ji = project(q, camera)
    r = pixels - cell.image_points
    if not np.all(np.isfinite(r)):
        raise SolverError("reprojection: a board corner fell behind the camera at the start poses; give "
                          "better init_X / init_Y or check the setup (eye-in-hand / eye-to-hand)")
    if not jacobian:
        return r, None
    # d p / d xi_L = [[q]_x | -I], d p / d xi_R = G [-[P]_x | I] (`handeye.vision.projection.
    # point_jacobians`); a row j^T [v]_x is (j x v)^T, so each product by Jp is a cross product
    JpG = Jp @ G
    parts = {cell.left: np.concatenate([np.cross(Jp, q[:, None, :]), -Jp], axis=2),
             cell.right: np.concatenate([-np.cross(JpG, P[:, None, :]), JpG], axis=2)}
    columns = [parts["X"], parts["Y"], Ji]
    if robot is not None:
        columns.append(_robot_jacobian(cell, Linv, M, R, Jp))
    return r, np.concatenate(columns, axis=2)


def _robot_jacobian(cell: StationChains, Linv: np.ndarray, M: np.ndarray, R: np.ndarray, Jp: np.ndarray) -> np.ndarray:
    """d pixel / d delta: (n, 2, 6) at the current corrections (M: the stations' corrected robot
    chains), Jp = d pixel / d p. Eye-to-hand p = L^-1 M exp(delta) R P: d p / d delta =
    G [-[w]_x | I] with G the rotation of L^-1 M and w = R P (the points in the flange frame);
    eye-in-hand p = L^-1 exp(-delta) M R P: R_L^T [[w]_x | -I] with w = M R P (the points in
    the flange frame)."""
    at, P = cell.station, cell.object_points
    w = P @ R[:3, :3].T + R[:3, 3]
    if cell.eye_in_hand:
        Mw = M[at]
        w = np.einsum("nij,nj->ni", Mw[:, :3, :3], w) + Mw[:, :3, 3]
        JpG = Jp @ Linv[:3, :3]
        return np.concatenate([np.cross(JpG, w[:, None, :]), -JpG], axis=2)
    JpG = Jp @ (Linv[:3, :3] @ M[:, :3, :3])[at]
    return np.concatenate([-np.cross(JpG, w[:, None, :]), JpG], axis=2)


def station_grams(columns: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(m, k, k): each station's sum of C^T C over its corners' rows of `columns` (n, 2, k),
    `counts` corners a station in order; one BLAS product a station (~6x an einsum over every
    corner's outer product and a reduceat, at 30 stations of 54 corners)."""
    k = columns.shape[2]
    out = np.empty((len(counts), k, k))
    start = 0
    for i, count in enumerate(counts.tolist()):
        rows = columns[start:start + count].reshape(-1, k)
        out[i] = rows.T @ rows
        start += count
    return out


def camera_with(camera: Any, theta: np.ndarray) -> Any:
    """The camera with fx, fy, cx, cy, dist replaced by theta."""
    from handeye.vision.observations import Camera

    K = np.array([[theta[0], camera.K[0, 1], theta[2]], [0.0, theta[1], theta[3]], [0.0, 0.0, 1.0]])
    return Camera(K, theta[4:], camera.size)


def intrinsics(camera: Any) -> np.ndarray:
    return np.concatenate([[camera.K[0, 0], camera.K[1, 1], camera.K[0, 2], camera.K[1, 2]], camera.dist])


def cost(r: np.ndarray, loss: str, c: float) -> tuple[float, np.ndarray]:
    """(1/2 sum rho(s_j), the weights rho'(s_j)) of the corners' squared pixel errors s_j."""
    rho, w = loss_terms(np.sum(r * r, axis=1), loss, c)
    return 0.5 * float(np.sum(rho)), w


@dataclasses.dataclass
class Fit:
    poses: dict[str, np.ndarray]
    theta: np.ndarray
    r: np.ndarray
    J: np.ndarray
    cost: float
    weights: np.ndarray
    iterations: int
    converged: bool


def at_rounding(cost: float, corners: int) -> bool:
    """The corners' RMS error is at rounding level (exact data): below ROUNDING_PX."""
    return cost <= 0.5 * ROUNDING_PX**2 * corners


def levenberg_marquardt(cell: StationChains, poses: dict[str, np.ndarray], camera: Any, refine_intrinsics: bool,
                        loss: str, loss_scale: float, max_iter: int) -> Fit:
    """Levenberg-Marquardt (Marquardt's diagonal scaling, IRLS weights of the loss) over X, Y and,
    with refine_intrinsics, the intrinsics; the robot's poses exact."""
    theta = intrinsics(camera)
    free = 12 + (len(theta) if refine_intrinsics else 0)
    cam = camera
    r, J = residuals(cell, poses, cam, True)
    value, w = cost(r, loss, loss_scale)
    lam, converged, iterations = 1e-3, False, 0
    for iterations in range(1, max_iter + 1):
        Jf = J[:, :, :free].reshape(-1, free)
        ww = np.repeat(w, 2)
        H = Jf.T @ (Jf * ww[:, None])
        g = Jf.T @ (r.ravel() * ww)
        D = np.maximum(np.diag(H), 1e-300)
        while True:
            try:
                step = -np.linalg.solve(H + lam * np.diag(D), g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial = {"X": retract(poses["X"], step[:6]), "Y": retract(poses["Y"], step[6:12])}
            trial_theta = theta + np.concatenate([step[12:], np.zeros(len(theta) - (free - 12))])
            trial_cam = camera_with(camera, trial_theta) if refine_intrinsics else cam
            try:
                r_new, _ = residuals(cell, trial, trial_cam, False)
                new_value, _ = cost(r_new, loss, loss_scale)
            except SolverError:
                new_value = math.inf
            predicted = -(g @ step) - 0.5 * step @ (H @ step)
            if new_value <= value or predicted <= TOL * value:
                break
            lam *= 10.0
            if lam > 1e16:  # no step lowers the cost: a minimum, or rounding on exact data
                done = predicted <= TOL * max(value, 1e-300) or at_rounding(value, len(r))
                return Fit(poses, theta, r, J, value, w, iterations, converged=done)
        decrease = value - new_value
        poses, theta, cam = trial, trial_theta, trial_cam
        r, J = residuals(cell, poses, cam, True)
        value, w = cost(r, loss, loss_scale)
        lam = max(lam / 10.0, 1e-12)
        if decrease <= TOL * max(value, 1e-300) or at_rounding(value, len(r)):
            converged = True
            break
    return Fit(poses, theta, r, J, value, w, iterations, converged)


def covariance(fit: Fit, free: int) -> tuple[np.ndarray, float]:
    """(covariance of the free parameters, residual variance per pixel coordinate)."""
    Jf = fit.J[:, :, :free].reshape(-1, free)
    ww = np.repeat(fit.weights, 2)
    H = Jf.T @ (Jf * ww[:, None])
    dof = max(fit.r.size - free, 1)
    sigma2 = float(np.sum(ww * fit.r.ravel() ** 2)) / dof
    return sigma2 * np.linalg.pinv(H), sigma2


def station_jackknife(fit: Fit, counts: np.ndarray, free: int) -> np.ndarray | None:
    """Covariance of the first `free` parameters of `fit` by a delete-one-station jackknife,
    linearised (one Gauss-Newton step from the full fit per station left out: theta_(-i) - theta =
    (H - H_i)^-1 g_i, H_i and g_i station i's share of J^T W J and J^T W r), `counts`: the corners
    of each station, in order. Where the robot's poses are off systematically every corner of a
    station shares the error, and sigma^2 (J^T W J)^-1, which counts each corner as independent,
    is several times too small; the jackknife treats the stations as the independent units (a
    cluster-robust, CR3-type estimate). None when a station cannot be left out (the rest do not
    determine the parameters)."""
    if len(counts) < 3:
        return None
    J = fit.J[:, :, :free]
    H_i = station_grams(J * np.sqrt(fit.weights)[:, None, None], counts)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    g_i = np.add.reduceat(np.einsum("nki,nk->ni", J * fit.weights[:, None, None], fit.r), starts, axis=0)
    try:
        steps = np.linalg.solve(H_i.sum(axis=0) - H_i, g_i[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return None
    steps -= steps.mean(axis=0)
    m = len(counts)
    return (m - 1) / m * steps.T @ steps


def pnp_rms(data: AXYBData) -> float:
    """The corners' RMS error when each image keeps its own board pose (the PnP poses in B)."""
    from handeye.vision.projection import project

    T_cam_target = inverse(data.B) if data.images.setup == "eye-in-hand" else data.B
    squares = [np.sum((project(P @ T[:3, :3].T + T[:3, 3], data.images.camera)[0] - u) ** 2, axis=1)
               for T, P, u in zip(T_cam_target, data.images.object_points, data.images.image_points)]
    return float(np.sqrt(np.mean(np.concatenate(squares))))
