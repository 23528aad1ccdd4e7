"""`reprojection`: A_i X = Y B_i fitted to the board's corners in the images, not to PnP poses.

For image data the maximum-likelihood answer minimises the reprojection error of the detected
board corners (Tabb & Ahmad Yousef, Machine Vision and Applications 2017; what camera
calibration itself minimises): pixel noise on the corners is isotropic and independent, while
the PnP poses B_i that every pose-based solver fits have a noise that is neither (depth and the
rotation about the image axes are poorly determined, and differently at every station).

Model (`handeye.vision.observations`): the board in the camera at station i is
T_cam_target,i = Y^-1 A_i X (eye-to-hand) or X^-1 A_i^-1 Y (eye-in-hand), with A_i the robot's
poses taken as exact (robot noise is not modelled), and corner j projects to
pi(K, dist; T_cam_target,i P_j) (OpenCV's camera model, `handeye.vision.projection`). The solver
minimises 1/2 sum_ij rho(|u_ij - pi(...)|^2) over X, Y (right perturbations on SE(3) x SE(3), as
`handeye.nlls`) and, with ``refine_intrinsics``, fx, fy, cx, cy and the distortion coefficients
given, by Levenberg-Marquardt with Marquardt's scaling; rho is a robust loss of
`handeye.robust` with its scale in pixels (``loss``, ``loss_scale``), applied per corner by
iteratively reweighted Gauss-Newton steps.

Start: solver `auto` on the data's poses (the PnP poses B), or ``init_X`` / ``init_Y``. The
covariance of X, Y is sigma^2 (J^T W J)^-1 with sigma^2 the weighted residual variance per
pixel coordinate (2n - p degrees of freedom), reported as refine reports it (``std``,
``covariance``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.checks.validation import float_array, pose_stack
from handeye.estimation.nlls import retract
from handeye.estimation.robust import LOSSES, loss_terms
from handeye.framework.errors import InputError, SolverError
from handeye.framework.options import check_choice, check_int, check_positive
from handeye.framework.solution import Status, jsonable
from handeye.framework.solver import SolverOutput, SolverSpec
from handeye.geometry.se3 import inverse, rotation_angle
from handeye.problems.axyb import AXYBData

#: the start solver (pose-based maximum likelihood)
START = "auto"
#: relative decrease of the cost, and step size relative to the parameters' scale, below which
#: Levenberg-Marquardt has converged
TOL = 1e-14
#: RMS pixel error of exact data after rounding (pixels are ~1e3, doubles ~1e-16 relative)
ROUNDING_PX = 1e-9
#: a corner this many robust sigmas (loss_scale) off counts as an outlier in the diagnostics
OUTLIER_SIGMAS = 3.0
#: `robot_misfit` (the corners' RMS error with the robot's poses / with each image's own PnP pose)
#: above which the robot's pose errors, not the pixel noise, dominate: a warning. Exact robot
#: poses give ~1.03 (6 fewer free parameters per image); the RCT real sets give 2.3 and 9.3.
MISFIT_LIMIT = 1.5
#: ... and only when the robot adds more than this to the corners' RMS error (px, in quadrature:
#: sqrt(rms^2 - pnp_rms^2)): below it the corners are placed to a tenth of a pixel either way, as
#: well as a detector finds them on real images, and a rendered set with exact robot poses
#: (0.063 px RMS) is no sign of robot errors
MISFIT_FLOOR_PX = 0.1
#: the shared suite's simulation: board images, corners with 0.3 px noise where B is noisy
SIMULATE_OPTIONS = {"images": {"pixel_noise": 0.3}}


@dataclasses.dataclass(frozen=True)
class Options:
    """refine_intrinsics: also refine fx, fy, cx, cy and the distortion coefficients given.
    loss / loss_scale: robust loss on each corner's squared pixel error, scale in pixels.
    init_X / init_Y: start poses (both), else solver `auto` on the poses.
    max_iter: Levenberg-Marquardt iterations."""

    refine_intrinsics: bool = False
    loss: str = "linear"
    loss_scale: float = 1.0
    init_X: Any = None
    init_Y: Any = None
    max_iter: int = 100

    def __post_init__(self) -> None:
        if not isinstance(self.refine_intrinsics, bool):
            raise InputError(f"option refine_intrinsics must be True or False, got {self.refine_intrinsics!r}")
        check_choice("loss", self.loss, LOSSES)
        check_positive("loss_scale", self.loss_scale)
        check_int("max_iter", self.max_iter, minimum=1)
        if (self.init_X is None) != (self.init_Y is None):
            raise InputError("options init_X and init_Y must be given together (4x4 poses)")
        if self.init_X is not None:
            for name in ("init_X", "init_Y"):
                T = float_array(getattr(self, name), f"option {name}", "a 4x4 pose")
                object.__setattr__(self, name, pose_stack(T[None], f"option {name}")[0])


@dataclasses.dataclass(frozen=True)
class _Cell:
    """What the projection of station i needs: the chain p = L^-1 M_i R P (L, R the unknowns in
    that order, `left`/`right` their names) and the corners."""

    left: str
    right: str
    M: np.ndarray
    points: tuple[np.ndarray, ...]
    pixels: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, data: AXYBData) -> _Cell:
        images = data.images
        if images.setup == "eye-to-hand":  # T_cam_target = Y^-1 A X
            return cls("Y", "X", np.asarray(data.A), images.object_points, images.image_points)
        return cls("X", "Y", inverse(data.A), images.object_points, images.image_points)  # X^-1 A^-1 Y


def _residuals(cell: _Cell, poses: dict[str, np.ndarray], camera: Any, jacobian: bool):
    """Stacked pixel residuals (n, 2) (prediction - detection) and, if asked, their Jacobian
    (n, 2, 12 + ni) by right perturbations of X, Y (in that order) and the intrinsics."""
    from handeye.vision.projection import point_jacobians, project

    L, R = poses[cell.left], poses[cell.right]
    Linv = inverse(L)
    res, jac = [], []
    for M, P, u in zip(cell.M, cell.points, cell.pixels):
        T = Linv @ M @ R
        q = P @ T[:3, :3].T + T[:3, 3]
        pixels, Jp, Ji = project(q, camera)
        res.append(pixels - u)
        if jacobian:
            dL, dR = point_jacobians(q, T[:3, :3], P)
            dpose = {cell.left: Jp @ dL, cell.right: Jp @ dR}
            jac.append(np.concatenate([dpose["X"], dpose["Y"], Ji], axis=2))
    r = np.concatenate(res)
    if not np.all(np.isfinite(r)):
        raise SolverError("reprojection: a board corner fell behind the camera at the start poses; give "
                          "better init_X / init_Y or check the setup (eye-in-hand / eye-to-hand)")
    return r, (np.concatenate(jac) if jacobian else None)


def _camera_with(camera: Any, theta: np.ndarray) -> Any:
    """The camera with fx, fy, cx, cy, dist replaced by theta."""
    from handeye.vision.observations import Camera

    K = np.array([[theta[0], camera.K[0, 1], theta[2]], [0.0, theta[1], theta[3]], [0.0, 0.0, 1.0]])
    return Camera(K, theta[4:], camera.size)


def _intrinsics(camera: Any) -> np.ndarray:
    return np.concatenate([[camera.K[0, 0], camera.K[1, 1], camera.K[0, 2], camera.K[1, 2]], camera.dist])


def _cost(r: np.ndarray, loss: str, c: float) -> tuple[float, np.ndarray]:
    """(1/2 sum rho(s_j), the weights rho'(s_j)) of the corners' squared pixel errors s_j."""
    rho, w = loss_terms(np.sum(r * r, axis=1), loss, c)
    return 0.5 * float(np.sum(rho)), w


@dataclasses.dataclass
class _Fit:
    poses: dict[str, np.ndarray]
    theta: np.ndarray
    r: np.ndarray
    J: np.ndarray
    cost: float
    weights: np.ndarray
    iterations: int
    converged: bool


def _at_rounding(cost: float, corners: int) -> bool:
    """The corners' RMS error is at rounding level (exact data): below ROUNDING_PX."""
    return cost <= 0.5 * ROUNDING_PX**2 * corners


def _levenberg_marquardt(cell: _Cell, poses: dict[str, np.ndarray], camera: Any, options: Options) -> _Fit:
    """Levenberg-Marquardt (Marquardt's diagonal scaling, IRLS weights of the loss) over X, Y and,
    with refine_intrinsics, the intrinsics."""
    theta = _intrinsics(camera)
    free = 12 + (len(theta) if options.refine_intrinsics else 0)
    cam = camera
    r, J = _residuals(cell, poses, cam, True)
    cost, w = _cost(r, options.loss, options.loss_scale)
    lam, converged, iterations = 1e-3, False, 0
    for iterations in range(1, options.max_iter + 1):
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
            trial_cam = _camera_with(camera, trial_theta) if options.refine_intrinsics else cam
            try:
                r_new, _ = _residuals(cell, trial, trial_cam, False)
                new_cost, _ = _cost(r_new, options.loss, options.loss_scale)
            except SolverError:
                new_cost = math.inf
            predicted = -(g @ step) - 0.5 * step @ (H @ step)
            if new_cost <= cost or predicted <= TOL * cost:
                break
            lam *= 10.0
            if lam > 1e16:  # no step lowers the cost: a minimum, or rounding on exact data
                done = predicted <= TOL * max(cost, 1e-300) or _at_rounding(cost, len(r))
                return _Fit(poses, theta, r, J, cost, w, iterations, converged=done)
        decrease = cost - new_cost
        poses, theta, cam = trial, trial_theta, trial_cam
        r, J = _residuals(cell, poses, cam, True)
        cost, w = _cost(r, options.loss, options.loss_scale)
        lam = max(lam / 10.0, 1e-12)
        if decrease <= TOL * max(cost, 1e-300) or _at_rounding(cost, len(r)):
            converged = True
            break
    return _Fit(poses, theta, r, J, cost, w, iterations, converged)


def _start(data: AXYBData, options: Options) -> tuple[dict[str, np.ndarray], str, list[str]]:
    if options.init_X is not None:
        return {"X": options.init_X, "Y": options.init_Y}, "given", []
    from handeye import run_registered

    output = run_registered(START, data, problem="axyb")
    if Status(output.status) not in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.UNCERTIFIED):
        raise SolverError(f"reprojection: its start, solver {START!r} on the board poses, ended {output.status}")
    warnings = [w for w in output.diagnostics.get("warnings", []) if "left out" not in w]
    return {k: np.asarray(output.unknowns[k], dtype=float) for k in ("X", "Y")}, START, warnings


def robot_errors_dominate(diagnostics: Mapping[str, Any]) -> bool:
    """Whether the robot's poses explain the corners far worse than each image alone does: their
    ratio (`robot_misfit`) beyond MISFIT_LIMIT and the robot's share of the error beyond
    MISFIT_FLOOR_PX. Then the reprojection model (exact robot poses) does not describe the data."""
    rms, pnp = float(diagnostics["rms_px"]), float(diagnostics["pnp_rms_px"])
    return diagnostics["robot_misfit"] > MISFIT_LIMIT and math.sqrt(max(rms * rms - pnp * pnp, 0.0)) > MISFIT_FLOOR_PX


def _covariance(fit: _Fit, free: int) -> tuple[np.ndarray, float]:
    """(covariance of the free parameters, residual variance per pixel coordinate)."""
    Jf = fit.J[:, :, :free].reshape(-1, free)
    ww = np.repeat(fit.weights, 2)
    H = Jf.T @ (Jf * ww[:, None])
    dof = max(fit.r.size - free, 1)
    sigma2 = float(np.sum(ww * fit.r.ravel() ** 2)) / dof
    return sigma2 * np.linalg.pinv(H), sigma2


def _pnp_rms(data: AXYBData) -> float:
    """The corners' RMS error when each image keeps its own board pose (the PnP poses in B)."""
    from handeye.vision.projection import project

    T_cam_target = inverse(data.B) if data.images.setup == "eye-in-hand" else data.B
    squares = [np.sum((project(P @ T[:3, :3].T + T[:3, 3], data.images.camera)[0] - u) ** 2, axis=1)
               for T, P, u in zip(T_cam_target, data.images.object_points, data.images.image_points)]
    return float(np.sqrt(np.mean(np.concatenate(squares))))


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    if data.images is None:
        raise InputError("solver 'reprojection' needs the board's image observations (images=...); "
                         "handeye calibrate --images makes them")
    started = time.perf_counter()
    poses0, start_name, warnings = _start(data, options)
    start_seconds = time.perf_counter() - started
    cell = _Cell.of(data)
    camera = data.images.camera
    r0, _ = _residuals(cell, poses0, camera, False)
    fit = _levenberg_marquardt(cell, poses0, camera, options)
    free = 12 + (len(fit.theta) if options.refine_intrinsics else 0)
    cov, sigma2 = _covariance(fit, free)
    var = np.diag(cov)
    errors = np.linalg.norm(fit.r, axis=1)
    counts = [len(u) for u in data.images.image_points]
    per_station = [float(np.sqrt(np.mean(e**2))) for e in np.split(errors, np.cumsum(counts)[:-1])]
    outliers = int(np.sum(errors > OUTLIER_SIGMAS * options.loss_scale)) if options.loss != "linear" else 0
    moved = {k: {"rotation": float(rotation_angle(fit.poses[k][:3, :3] @ poses0[k][:3, :3].T)),
                 "translation": float(np.linalg.norm(fit.poses[k][:3, 3] - poses0[k][:3, 3]))} for k in ("X", "Y")}
    diagnostics: dict[str, Any] = {
        "iterations": fit.iterations,
        "converged": fit.converged,
        "start": start_name,
        "start_seconds": start_seconds,
        "moved_from_start": moved,
        "initial_rms_px": float(np.sqrt(np.mean(np.sum(r0**2, axis=1)))),
        "rms_px": float(np.sqrt(np.mean(errors**2))),
        "rms_px_per_station": per_station,
        "corners": len(errors),
        "final_cost": fit.cost,
        "loss": options.loss,
        "loss_scale": options.loss_scale,
        "outlier_corners": outliers,
        "sigma_px": math.sqrt(sigma2),
        "noise_model": "reprojection",
        "covariance": {k: cov[6 * j:6 * j + 6, 6 * j:6 * j + 6].tolist() for j, k in enumerate(("X", "Y"))},
        "std": {k: {"rotation": math.sqrt(max(sum(var[6 * j:6 * j + 3]), 0.0)),
                    "translation": math.sqrt(max(sum(var[6 * j + 3:6 * j + 6]), 0.0))}
                for j, k in enumerate(("X", "Y"))},
        "warnings": warnings,
    }
    pnp_rms = _pnp_rms(data)
    misfit = diagnostics["rms_px"] / max(pnp_rms, 1e-300)
    diagnostics["pnp_rms_px"], diagnostics["robot_misfit"] = pnp_rms, misfit
    # the verdict itself, for whoever shows the answer (handeye.calibrate gives way to the pose-based one)
    diagnostics["robot_errors_dominate"] = robot_errors_dominate(diagnostics)
    if robot_errors_dominate(diagnostics):
        warnings.append(f"the robot's poses explain the board corners only to {diagnostics['rms_px']:.2g} px RMS "
                        f"while each image alone fits them to {pnp_rms:.2g} px: the robot's pose errors, which this "
                        "solver does not model, dominate the pixel noise, so this is not the most likely answer "
                        "and its 1-sigma assumes independent pixel errors; solver 'auto' models noise on both sides")
    if options.refine_intrinsics:
        cam = _camera_with(camera, fit.theta)
        diagnostics["camera"] = {"K": cam.K.tolist(), "dist": cam.dist.tolist(),
                                 "std": np.sqrt(np.maximum(var[12:], 0.0)).tolist()}
    if outliers:
        warnings.append(f"reprojection: {outliers} board corners are more than {OUTLIER_SIGMAS:g} x loss_scale "
                        f"({options.loss_scale:g} px) off; the {options.loss} loss down-weighted them")
    status = Status.OPTIMAL if fit.converged else Status.NOT_CONVERGED
    if not fit.converged:
        warnings.append(f"reprojection: Levenberg-Marquardt did not converge in {options.max_iter} iterations; "
                        "raise max_iter or check the images")
    return SolverOutput(unknowns=dict(fit.poses), status=status, diagnostics=jsonable(diagnostics))


SPEC = SolverSpec(
    name="reprojection",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="X, Y (and optionally the intrinsics) fitted to the board corners' reprojection error (images)",
    citation="Tabb & Ahmad Yousef, Machine Vision and Applications 2017 (reprojection-error hand-eye)",
    unit_invariant=True,
    exact=True,
    simulate_options=SIMULATE_OPTIONS,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
