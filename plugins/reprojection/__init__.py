"""`reprojection`: A_i X = Y B_i fitted to the board's corners in the images, not to PnP poses.

For image data the maximum-likelihood answer minimises the reprojection error of the detected
board corners (Tabb & Ahmad Yousef, Machine Vision and Applications 2017; what camera
calibration itself minimises): pixel noise on the corners is isotropic and independent, while
the PnP poses B_i that every pose-based solver fits have a noise that is neither (depth and the
rotation about the image axes are poorly determined, and differently at every station).

Model (`handeye.vision.observations`): the board in the camera at station i is
T_cam_target,i = Y^-1 A_i X (eye-to-hand) or X^-1 A_i^-1 Y (eye-in-hand), with A_i the robot's
poses taken as exact (``robot_noise="none"``; the default corrects each and estimates the
robot's noise with the pixels': `robot_noise`, docs/solvers/reprojection.md), and corner j projects to
pi(K, dist; T_cam_target,i P_j) (OpenCV's camera model, `handeye.vision.projection`). The solver
minimises 1/2 sum_ij rho(|u_ij - pi(...)|^2) over X, Y (right perturbations on SE(3) x SE(3), as
`handeye.estimation.nlls`) and, with ``refine_intrinsics``, fx, fy, cx, cy and the distortion coefficients
given, by Levenberg-Marquardt with Marquardt's scaling; rho is a robust loss of
`handeye.estimation.robust` with its scale in pixels (``loss``, ``loss_scale``), applied per corner by
iteratively reweighted Gauss-Newton steps.

Start: solver `auto` on the data's poses (the PnP poses B), or ``init_X`` / ``init_Y``. The
covariance of X, Y is sigma^2 (J^T W J)^-1 with sigma^2 the weighted residual variance per
pixel coordinate (2n - p degrees of freedom), or with the robot's noise the inverse of the
reduced normal matrix, reported as refine reports it (``std``, ``covariance``). With
``held_out=k`` the fits are also compared by held-out corner prediction (`held_out`), which
picks the robot model from the data.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import InputError, SolverError
from handeye.estimation.robust import LOSSES
from handeye.framework.options import check_choice, check_int, check_positive
from handeye.framework.solution import USABLE, Status, jsonable
from handeye.framework.solver import SolverOutput, SolverSpec
from handeye.geometry.se3 import rotation_angle
from handeye.geometry.validation import float_array, pose_stack
from handeye.plugins.reprojection import held_out, robot_noise
from handeye.plugins.reprojection.corners import (
    StationChains,
    camera_with,
    covariance,
    levenberg_marquardt,
    pnp_rms,
    residuals,
    station_jackknife,
)
from handeye.problems.axyb import AXYBData
from handeye.vision import intrinsics_effect

#: the start solver (pose-based maximum likelihood)
START = "auto"
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
#: a focal length other than the given one predicting held-out corners this many times better
#: (`held_out.focal_scan`) makes a warning. Measured on the real ChArUco set: the images' own
#: focal length 1.07 (its best at -0.5%), a file 0.5% long 1.26, 1% long 1.43, 2% long 2.0; the
#: real circle grid's curve is flat (at most 1.02 for any file within 2%)
FOCAL_GAIN = 1.3
#: the held-out comparison's contenders in words
LABELS = {"joint": "with the robot's noise estimated", "exact_robot": "with the robot's poses as measured",
          "pose_based": "the pose-based answer"}
#: values of option `robot_noise`
ROBOT_NOISE = (None, "estimated", "none")
#: the shared suite's simulation: board images, corners with 0.3 px noise where B is noisy
SIMULATE_OPTIONS = {"images": {"pixel_noise": 0.3}}


@dataclasses.dataclass(frozen=True)
class Options:
    """refine_intrinsics: also refine fx, fy, cx, cy and the distortion coefficients given.
    loss / loss_scale: robust loss on each corner's squared pixel error, scale in pixels.
    init_X / init_Y: start poses (both), else solver `auto` on the poses.
    max_iter: Levenberg-Marquardt iterations.
    robot_noise: "estimated" (each robot pose corrected, the robot's noise estimated with the
    pixels': `robot_noise`), "none" (the robot's poses exact), or None (the default: "estimated"
    with least squares, "none" with a robust loss).
    held_out: k >= 2 folds of the stations over which the corner fits with and without the
    robot's noise and the pose-based start solver are compared by their held-out corner
    prediction (`held_out`): with robot_noise None the better corner fit is the answer, and
    ``held_out.pose_based_better`` says whether the pose-based one predicts better still
    (``handeye.calibrate`` asks for 3 folds and then answers with it); 0 (default) none."""

    refine_intrinsics: bool = False
    loss: str = "linear"
    loss_scale: float = 1.0
    init_X: Any = None
    init_Y: Any = None
    max_iter: int = 100
    robot_noise: str | None = None
    held_out: int = 0

    @property
    def robot_noise_estimated(self) -> bool:
        return self.robot_noise == "estimated" or (self.robot_noise is None and self.loss == "linear")

    def __post_init__(self) -> None:
        if not isinstance(self.refine_intrinsics, bool):
            raise InputError(f"option refine_intrinsics must be True or False, got {self.refine_intrinsics!r}")
        check_choice("loss", self.loss, LOSSES)
        check_positive("loss_scale", self.loss_scale)
        check_int("max_iter", self.max_iter, minimum=1)
        check_choice("robot_noise", self.robot_noise, ROBOT_NOISE)
        check_int("held_out", self.held_out, minimum=0)
        if self.held_out == 1:
            raise InputError("held_out must be 0 (no comparison) or a number of folds >= 2, got 1")
        if self.robot_noise == "estimated" and self.loss != "linear":
            raise InputError(f"robot_noise='estimated' fits the pixels by least squares, not loss={self.loss!r}: "
                             "use robot_noise='none' with a robust loss, or loss='linear'")
        if (self.init_X is None) != (self.init_Y is None):
            raise InputError("options init_X and init_Y must be given together (4x4 poses)")
        if self.init_X is not None:
            for name in ("init_X", "init_Y"):
                T = float_array(getattr(self, name), f"option {name}", "a 4x4 pose")
                object.__setattr__(self, name, pose_stack(T[None], f"option {name}")[0])


def _start(data: AXYBData, options: Options) -> tuple[dict[str, np.ndarray], str, list[str]]:
    if options.init_X is not None:
        return {"X": options.init_X, "Y": options.init_Y}, "given", []
    from handeye import run_registered

    output = run_registered(START, data, problem="axyb")
    if Status(output.status) not in USABLE:
        raise SolverError(f"reprojection: its start, solver {START!r} on the board poses, ended {output.status}")
    warnings = [w for w in output.diagnostics.get("warnings", []) if "left out" not in w]
    return {k: np.asarray(output.unknowns[k], dtype=float) for k in ("X", "Y")}, START, warnings


def robot_errors_dominate(diagnostics: Mapping[str, Any]) -> bool:
    """Whether the robot's poses explain the corners far worse than each image alone does: their
    ratio (`robot_misfit`) beyond MISFIT_LIMIT and the robot's share of the error beyond
    MISFIT_FLOOR_PX. Then the reprojection model (exact robot poses) does not describe the data."""
    rms, pnp = float(diagnostics["rms_px"]), float(diagnostics["pnp_rms_px"])
    return diagnostics["robot_misfit"] > MISFIT_LIMIT and math.sqrt(max(rms * rms - pnp * pnp, 0.0)) > MISFIT_FLOOR_PX


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    if data.images is None:
        raise InputError("solver 'reprojection' needs the board's image observations (images=...); "
                         "handeye calibrate --images makes them")
    started = time.perf_counter()
    poses0, start_name, warnings = _start(data, options)
    start_seconds = time.perf_counter() - started
    cell = StationChains.of(data)
    camera = data.images.camera
    r0, _ = residuals(cell, poses0, camera, False)
    fit = levenberg_marquardt(cell, poses0, camera, options.refine_intrinsics, options.loss, options.loss_scale,
                              options.max_iter)
    free = 12 + (len(fit.theta) if options.refine_intrinsics else 0)
    cov, sigma2 = covariance(fit, free)
    pnp = pnp_rms(data)
    exact_rms = float(np.sqrt(np.mean(np.sum(fit.r**2, axis=1))))
    misfit = exact_rms / max(pnp, 1e-300)
    poses, theta, r, converged, iterations = fit.poses, fit.theta, fit.r, fit.converged, fit.iterations
    compared = _compare_held_out(data, options) if options.held_out else None
    robot: dict[str, Any] = {}
    if options.robot_noise_estimated and (compared is None or options.robot_noise == "estimated"
                                          or compared["chosen"] == "joint"):
        joint = robot_noise.fit(cell, fit.poses, camera, options.refine_intrinsics, _start_sigmas(data, cell, fit, pnp))
        poses, theta, r, cov = joint.poses, joint.theta, joint.r, joint.covariance
        converged, sigma2 = converged and joint.converged, joint.sigmas[0] ** 2
        robot = {"rotation": joint.sigmas[1], "translation": joint.sigmas[2], "rounds": joint.rounds,
                 "exact_robot_rms_px": exact_rms,
                 "corrections_rms": {"rotation": float(np.sqrt(np.mean(joint.delta[:, :3] ** 2) * 3)),
                                     "translation": float(np.sqrt(np.mean(joint.delta[:, 3:] ** 2) * 3))}}
    dominate = robot_errors_dominate({"rms_px": exact_rms, "pnp_rms_px": pnp, "robot_misfit": misfit})
    widened = None
    if dominate and not robot:  # the robot's errors shared by each station's corners: the stations' jackknife
        jack = station_jackknife(fit, cell.counts, free)
        if jack is not None and np.trace(jack[:12, :12]) > np.trace(cov[:12, :12]):
            widened = math.sqrt(np.trace(jack[:12, :12]) / np.trace(cov[:12, :12]))
            cov = jack
    cov, intrinsics_note, share = _with_intrinsics(data, options, fit, cov)
    if intrinsics_note:
        warnings.append(intrinsics_note)
    var = np.diag(cov)
    errors = np.linalg.norm(r, axis=1)
    counts = [len(u) for u in data.images.image_points]
    per_station = [float(np.sqrt(np.mean(e**2))) for e in np.split(errors, np.cumsum(counts)[:-1])]
    outliers = int(np.sum(errors > OUTLIER_SIGMAS * options.loss_scale)) if options.loss != "linear" else 0
    moved = {k: {"rotation": float(rotation_angle(poses[k][:3, :3] @ poses0[k][:3, :3].T)),
                 "translation": float(np.linalg.norm(poses[k][:3, 3] - poses0[k][:3, 3]))} for k in ("X", "Y")}
    diagnostics: dict[str, Any] = {
        "iterations": iterations,
        "converged": converged,
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
        "noise_model": "reprojection with robot noise" if robot else "reprojection",
        "fitted_to": "corners",
        "covariance": {k: cov[6 * j:6 * j + 6, 6 * j:6 * j + 6].tolist() for j, k in enumerate(("X", "Y"))},
        "std": {k: {"rotation": math.sqrt(max(sum(var[6 * j:6 * j + 3]), 0.0)),
                    "translation": math.sqrt(max(sum(var[6 * j + 3:6 * j + 6]), 0.0))}
                for j, k in enumerate(("X", "Y"))},
        "warnings": warnings,
        "pnp_rms_px": pnp,
        "robot_misfit": misfit,
    }
    if robot:
        diagnostics["robot_noise"] = robot
    if not options.refine_intrinsics:  # what a focal length 0.1% off does to the answer (docs/images.md)
        diagnostics["focal_per_permille"] = _focal_per_permille(fit, camera)
    if share:
        diagnostics["intrinsics_effect"] = share
    # the verdict itself, for whoever shows the answer (handeye.calibrate gives way to the pose-based
    # one where the robot's errors dominate and this fit took the robot's poses as exact)
    diagnostics["robot_errors_dominate"] = dominate and not robot
    if widened is not None:  # the 1-sigma from the stations' spread (read by the self-check's wording)
        diagnostics["station_jackknife_factor"] = widened
        diagnostics["sigma_from"] = "stations"
    if dominate and not robot and compared is not None:
        others = ", ".join(f"{LABELS[name]} {compared[name + '_px']:.3g} px" for name in ("joint", "pose_based")
                           if compared.get(name + "_px") is not None)
        warnings.append(f"the robot's poses explain the board corners only to {exact_rms:.2g} px RMS while each "
                        f"image alone fits them to {pnp:.2g} px: the robot's pose errors dominate the pixel noise. "
                        f"Over {compared['folds']} folds of the stations, this fit (the robot's poses as measured) "
                        f"predicts the corners of images it was not fitted to best ({compared['exact_robot_px']:.3g} px "
                        f"RMS; {others}): the robot's errors look systematic (its kinematics), which no noise model "
                        "describes; the 1-sigma is "
                        + (f"from a jackknife over the stations ({widened:.2g}x what independent pixel errors give)"
                           if widened is not None else "that of independent pixel errors, likely too small"))
    elif dominate and not robot:
        warnings.append(f"the robot's poses explain the board corners only to {exact_rms:.2g} px RMS "
                        f"while each image alone fits them to {pnp:.2g} px: the robot's pose errors, which this "
                        "fit (robot_noise='none') does not model, dominate the pixel noise, so this is not the most "
                        "likely answer and its 1-sigma assumes independent pixel errors; robot_noise='estimated' or "
                        "solver 'auto' model noise on both sides")
    if compared is not None:
        diagnostics["held_out"] = compared
        note = focal_note(compared.get("focal_scan"))
        if note:
            warnings.append(note)
    if options.refine_intrinsics:
        cam = camera_with(camera, theta)
        diagnostics["camera"] = {"K": cam.K.tolist(), "dist": cam.dist.tolist(),
                                 "std": np.sqrt(np.maximum(var[12:], 0.0)).tolist()}
    if outliers:
        warnings.append(f"reprojection: {outliers} board corners are more than {OUTLIER_SIGMAS:g} x loss_scale "
                        f"({options.loss_scale:g} px) off; the {options.loss} loss down-weighted them")
    status = Status.OPTIMAL if converged else Status.NOT_CONVERGED
    if not converged:
        warnings.append(f"reprojection: the fit did not converge in {options.max_iter} iterations; "
                        "raise max_iter or check the images")
    return SolverOutput(unknowns=dict(poses), status=status, diagnostics=jsonable(diagnostics))


def _with_intrinsics(data: AXYBData, options: Options, fit: Any,
                     cov: np.ndarray) -> tuple[np.ndarray, str | None, dict[str, Any] | None]:
    """The covariance of X, Y with the intrinsics' uncertainty added (`BoardObservations.
    intrinsics_std`: calibrated from these images, or given with a 1-sigma stated or assumed), a
    warning where that at least doubles a translation's 1-sigma, and the record of that share
    (`intrinsics_effect.focal_moves`); `cov` as it is where the intrinsics are taken as exact.

    The fit holds the intrinsics exact, at the values the camera's calibration gave them, each
    uncertain by its 1-sigma there (`handeye.vision.intrinsics_effect`). To first order the
    answer moves by S dk for intrinsics off by dk (`_intrinsics_slope`), so the covariance gains
    S C S^T, C the calibration's with fx and fy fully correlated."""
    std = data.images.intrinsics_std
    if std is None or options.refine_intrinsics:
        return cov, None, None
    moves = _intrinsics_slope(fit) @ intrinsics_effect.one_sigma_moves(std)
    out = np.array(cov, dtype=float)
    out[:12, :12] = intrinsics_effect.widened(out[:12, :12], moves)
    percent, source = intrinsics_effect.focal_percent(std, data.images.camera), data.images.intrinsics_std_from
    return (out, intrinsics_effect.growth_note(cov[:12, :12], out[:12, :12], ("X", "Y"), percent, source=source),
            intrinsics_effect.focal_moves(moves, ("X", "Y"), percent, source))


def _intrinsics_slope(fit: Any) -> np.ndarray:
    """(12, 4) S = -(J_p^T W J_p)^-1 J_p^T W J_k: how X, Y move with fx, fy, cx, cy at the fit
    holding them exact, from its own Jacobian (columns for the poses p and the intrinsics k)."""
    ww = np.repeat(fit.weights, 2)[:, None]
    Jp, Jk = fit.J[:, :, :12].reshape(-1, 12), fit.J[:, :, 12:16].reshape(-1, 4)
    return -np.linalg.lstsq(Jp.T @ (Jp * ww), Jp.T @ (Jk * ww), rcond=None)[0]


def _focal_per_permille(fit: Any, camera: Any) -> dict[str, float]:
    """How far each unknown's translation moves for a focal length 0.1% off (fx, fy together):
    the 1-sigma takes given intrinsics as exact, so this says what that trust is worth."""
    return intrinsics_effect.per_permille(_intrinsics_slope(fit) @ intrinsics_effect.focal_change(camera), ("X", "Y"))


def _compare_held_out(data: AXYBData, options: Options) -> dict[str, Any]:
    """The held-out corner prediction (px RMS, `held_out.held_out`) over `options.held_out` folds
    of the stations of the corner fit with the robot's noise estimated ("joint", where the loss
    allows it), with the robot's poses exact ("exact_robot") and of the pose-based start solver;
    ``chosen``: the corner fit this solver answers with (the better of the two, unless option
    robot_noise fixes it); ``pose_based_better``: the pose-based answer predicts better than it;
    ``best``: the chosen fit predicts at least as well as every other (``answer_px``, ``others_px``),
    the evidence the host's self-check reads (`handeye.checks.self_check`, check 1)."""
    from handeye import run_registered

    k = options.held_out
    if len(data.A) < 2 * k:
        raise InputError(f"held_out={k} needs at least {2 * k} stations (2 per fold), got {len(data.A)}; "
                         "give fewer folds or record more stations")
    plain = dataclasses.replace(options, held_out=0, init_X=None, init_Y=None)
    fold: dict[str, Any] = {}  # what was fitted on the current fold's training data (`fitted`)

    def fitted(train: AXYBData, what: str, fit: Any) -> Any:
        """fit(train), once per fold: the corner fits share the fold's corner model, the pose-based
        start and the exact-robot fit (the joint fit starts from it, as in `run`)."""
        if fold.get("train") is not train:
            fold.clear()
            fold["train"] = train
        if what not in fold:
            fold[what] = fit(train)
        return fold[what]

    def pose_based(train: AXYBData) -> Any:
        return fitted(train, "pose_based", lambda t: run_registered(START, dataclasses.replace(t, images=None),
                                                                    problem="axyb"))

    def exact_fit(train: AXYBData) -> Any:
        """`run`'s corner fit with the robot's poses exact, from the pose-based start (or, where
        that ended badly, from `run`'s own start, which then refuses it as alone)."""
        start = pose_based(train)
        if Status(start.status) in USABLE:
            poses0 = {k: np.asarray(start.unknowns[k], dtype=float) for k in ("X", "Y")}
        else:
            poses0 = _start(train, plain)[0]
        return levenberg_marquardt(fitted(train, "cell", StationChains.of), poses0, train.images.camera,
                                   plain.refine_intrinsics, plain.loss, plain.loss_scale, plain.max_iter)

    def joint_fit(train: AXYBData) -> dict[str, np.ndarray]:
        """`run`'s joint fit with the robot's noise estimated, from the exact-robot fit."""
        fit = fitted(train, "exact_robot", exact_fit)
        cell = fitted(train, "cell", StationChains.of)
        sigmas = _start_sigmas(train, cell, fit, pnp_rms(train))
        return robot_noise.fit(cell, fit.poses, train.images.camera, plain.refine_intrinsics, sigmas).poses

    fitters: dict[str, held_out.Fitter] = {}
    if options.robot_noise_estimated:
        fitters["joint"] = lambda train: fitted(train, "joint", joint_fit)
    if options.robot_noise != "estimated":
        fitters["exact_robot"] = lambda train: fitted(train, "exact_robot", exact_fit).poses
    fitters["pose_based"] = lambda train: pose_based(train).unknowns
    found = held_out.held_out(data, fitters, k)
    scan = None  # intrinsics given apart: is their focal length the one held-out images agree with?
    if data.images.intrinsics_std_from != "images" and not options.refine_intrinsics and "exact_robot" in fitters:
        scan = held_out.focal_scan(data, fitters["exact_robot"], k, found["exact_robot"])
    corner_fits = {name: px for name, px in found.items() if name != "pose_based" and px is not None}
    chosen = min(corner_fits, key=corner_fits.get) if corner_fits else next(iter(fitters))
    pose = found["pose_based"]
    better = pose is not None and (chosen not in corner_fits or pose < corner_fits[chosen])
    # the answer this solver returns (the chosen corner fit) predicts held-out corners at least as
    # well as every fit compared: the self-check then takes residuals above the noise as systematic
    best = chosen in corner_fits and all(px is None or corner_fits[chosen] <= px for px in found.values())
    return {"folds": k, **{f"{name}_px": px for name, px in found.items()}, "chosen": chosen,
            "reprojection_px": corner_fits.get(chosen), "pose_based_solver": START, "pose_based_better": better,
            "best": best, "measure": "board corners of held-out stations, px RMS",
            "answer_px": corner_fits.get(chosen), "others_px": {LABELS[n]: px for n, px in found.items() if n != chosen},
            **({"focal_scan": scan} if scan is not None else {})}


def focal_note(scan: Mapping[str, Any] | None) -> str | None:
    """The warning where held-out images are predicted clearly better with another focal length
    than the one given (`held_out.focal_scan`: its ``gain`` beyond `FOCAL_GAIN`), or None."""
    if not scan or scan.get("gain") is None or scan["gain"] <= FOCAL_GAIN:
        return None
    best, edge = scan["best_percent"], max(abs(p) for p in scan["percent"])
    given = scan["px"][scan["percent"].index(0.0)]
    best_px = scan["px"][scan["percent"].index(best)]
    way = "shorter" if best < 0 else "longer"
    amount = f"{abs(best):g}% or more" if abs(best) >= edge else f"about {abs(best):g}%"
    return (f"the corners of images the fit was not given are predicted best with a focal length {amount} {way} than "
            f"the intrinsics given ({best_px:.3g} px RMS against {given:.3g} px with theirs): the given focal length is "
            "likely off by about that, which scales every board's distance and moves the answer; check the "
            "intrinsics file (this camera's, at this resolution and focus?), or leave it out to calibrate the camera "
            "from these images")


def _start_sigmas(data: AXYBData, cell: StationChains, fit: Any, pnp: float) -> tuple[float, float, float]:
    """The start of (s_px, s_r, s_t) for the joint fit: the pixels' from each image's own board
    pose (PnP, 6 parameters per image), the robot's from the board poses' misfit against the
    exact-robot fit, per axis, in the flange frame (rad, data units)."""
    from handeye.problems.axyb.geometry import AXYBModel

    corners = int(np.sum(cell.counts))
    s_px = pnp * math.sqrt(corners / max(corners - 3 * len(cell.M), 1))
    e = AXYBModel(data).residuals((fit.poses["X"], fit.poses["Y"]))
    s_r = math.sqrt(float(np.mean(e[:, :3] ** 2)))
    s_t = math.sqrt(float(np.mean(e[:, 3:] ** 2)))
    scale = float(data.translation_scale)
    return max(s_px, 1e-6), max(s_r, 1e-9), max(s_t, 1e-9 * scale)


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
    fits_images=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
