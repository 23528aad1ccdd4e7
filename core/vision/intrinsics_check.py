"""Intrinsics given in a file are taken as exact: do the images say the same focal length?

A focal length a little off scales every board's distance, and the hand-eye answer moves with it
(on the real ChArUco set, 1.27 m from the board, a focal length 0.1% off moves Y by ~0.5 mm,
2.7x its 1-sigma): the fit's residuals barely change (PnP absorbs it into the distance), so a
wrong file gives a confident wrong answer. The images can check the file: calibrated from the
same corners (`handeye.vision.intrinsics.calibrate_camera`, ~30-60 ms), they give their own
focal length, and the file's is compared with it in units of its uncertainty.

That uncertainty is not OpenCV's 1-sigma: on real images the corners' errors are not independent
pixel noise, and OpenCV's figure is too small. Measured by a delete-one jackknife over the
images, fx's 1-sigma is 2.0x OpenCV's on the real ChArUco set (15 images, 10.2 px against 5.2 px)
and 4.5x on the real circle-grid set (15 images, 4.8 against 1.05 px); on simulated corners with
independent noise the two agree. The check uses the larger of the two, the jackknife over at
most `GROUPS` groups of the images (`focal_check`).

The jackknife does not recalibrate without each group (12 calibrations, 0.2-0.3 s on 15-30
images: a quarter of the pipeline after detection): it linearises the full calibration, one
Gauss-Newton step per group from the full set's intrinsics and board poses, each view's pose
eliminated (`jackknife_std`; ~2 ms). Against recalibrating, its 1-sigma of fx, fy, cx, cy: real
ChArUco 0.99, 0.99, 0.98, 0.97; real circle grid 1.01, 1.00, 1.09, 0.95; 30 rendered 1.3 MP
chessboards 1.00 for all four; 80 simulated sets of 15 images (both setups) fx, fy 0.98-1.01,
cx, cy 0.91-1.08. The circle grid's first images move cx, cy by up to 10 px when left out, where
one step is 1.7 px short; Gauss-Newton iterated per group oscillates there (two steps: cy 0.89,
three: 0.99, at 10-15x the cost), so one step it is.

Measured (bench/intrinsics_uncertainty.py --detect 40, docs/images.md): on simulated sets of 15
images (own focal length to ~0.14%) the true intrinsics warn in 0 of 40, a file 0.3% / 0.5% / 1%
/ 2% off in 7 / 20 / 38 / 40 of 40; the real sets' files (their own calibration, and their
cal_data.yaml) are quiet, and so is every error up to 2% there (own focal length to 0.75% and
0.88%: 2.6 and 2.3 sigmas at 2%). The check finds a file as far off as `FOCAL_SIGMAS` times the
images' own uncertainty and no closer; below that, the answer's 1-sigma carries the file's own
uncertainty where it states one, else the images' own (`given_std`): a file 1% off on the real
ChArUco set is 1.3 of those 1-sigmas from the images' focal length, and moves Y by 5.0 mm, within
its widened 1-sigma.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.vision.observations import Camera

#: the file's focal length this many of the images' 1-sigma from theirs: a warning. Simulated
#: sets with the true intrinsics given: largest |z| 2.2 in 40, RMS 0.82 (Gaussian |z| > 3: 0.3%)
FOCAL_SIGMAS = 3.0
#: `given_intrinsics_check`: fewest images, and how much worse (ratio and pixels) given intrinsics
#: may fit them than intrinsics calibrated from them (the calibration's extra parameters alone
#: lower its RMS by a few per cent only)
INTRINSICS_CHECK_VIEWS = 6
INTRINSICS_MISFIT = 1.25
INTRINSICS_MISFIT_PX = 0.1
#: the jackknife deletes one of at most this many groups of the images at a time (cost: one
#: Gauss-Newton step each from the full calibration, ~2 ms in all on 15-30 images)
GROUPS = 12


@dataclasses.dataclass(frozen=True)
class FocalCheck:
    """The file's focal length (fx, fy) against the images' own calibration: theirs (fx, fy),
    its 1-sigma used (the larger of OpenCV's and the jackknife's, px) and OpenCV's own, the
    difference in those 1-sigmas (focal length: the mean of fx and fy) and in per cent, the
    number of images calibrated from (``views``), and the 1-sigma of their own cx, cy (px)."""

    given: tuple[float, float]
    own: tuple[float, float]
    std: tuple[float, float]
    opencv_std: tuple[float, float]
    sigmas: float
    percent: float
    views: int
    centre_std: tuple[float, float] = (0.0, 0.0)

    @property
    def off(self) -> bool:
        return abs(self.sigmas) > FOCAL_SIGMAS


def jackknife_std(views: Sequence[Any], size: tuple[int, int], fix_k3: bool, groups: int = GROUPS,
                  images: Sequence[str] | None = None, *, calibration: Any = None) -> np.ndarray:
    """The grouped delete-one jackknife 1-sigma of (fx, fy, cx, cy) of `calibrate_camera` over
    the views: sqrt((g - 1) / g * sum_i (theta_i - mean)^2), theta_i the intrinsics without group
    i. The groups are of images: `images` names each view's image (None: one view per image), and
    the views of one image (several boards in it) leave together, as their corners' errors are
    not independent either.

    theta_i is not recalibrated: it is one Gauss-Newton step from `calibration` (the views' own,
    `handeye.vision.intrinsics.CameraCalibration`; None: calibrated here) on the views outside
    group i (`_without_group`), 12 recalibrations' ~0.3 s becoming a few ms; against them
    (module docstring) fx's 1-sigma agrees to 1-2%, cx's and cy's to 10%. Raises InputError
    where a group's removal leaves the intrinsics undetermined (fewer than `MIN_VIEWS` views)."""
    from handeye.vision.intrinsics import MIN_VIEWS, calibrate_camera

    if calibration is None:
        calibration = calibrate_camera(views, size, fix_k3=fix_k3)
    keys = list(range(len(views))) if images is None else list(images)
    units = list(dict.fromkeys(keys))
    g = min(len(units), groups)
    S, G = _reduced_terms(calibration, views, fix_k3)
    steps = []
    for part in np.array_split(np.arange(len(units)), g):
        gone = {units[i] for i in part.tolist()}
        kept = np.array([key not in gone for key in keys])
        if kept.sum() < MIN_VIEWS:
            raise InputError(f"a jackknife over {len(units)} images leaves {int(kept.sum())} board views in a group")
        steps.append(_without_group(S[kept].sum(axis=0), G[kept].sum(axis=0))[:4])
    theta = np.array(steps)  # theta_i - theta_hat: the full calibration's theta_hat cancels in the spread
    return np.sqrt((g - 1) / g * np.sum((theta - theta.mean(axis=0)) ** 2, axis=0))


#: columns of cv2.projectPoints' Jacobian: rvec, tvec (the view's pose), then fx, fy, cx, cy, k1,
#: k2, p1, p2, k3 (the intrinsics `calibrate_camera` frees; k3 last, left out where it is fixed)
_POSE_COLUMNS = 6
_INTRINSIC_COLUMNS = 9


def _reduced_terms(calibration: Any, views: Sequence[Any], fix_k3: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per view, its share of the calibration's normal equations in the intrinsics alone, at the
    calibration: (S_v, g_v), the view's pose eliminated (Schur complement: the pose re-fits to
    any change of the intrinsics). Stacked, (n, p, p) and (n, p), p = 9 (8 with k3 fixed);
    sum_v g_v is the gradient of 1/2 * sum of squared residuals, ~0 at the calibration."""
    import cv2  # not on import: a closed-form solve loads no OpenCV

    camera = calibration.camera
    dist = np.zeros(5)
    dist[:min(5, camera.dist.size)] = camera.dist[:5]
    poses = _board_poses(calibration, views, dist)
    free = slice(_POSE_COLUMNS, _POSE_COLUMNS + _INTRINSIC_COLUMNS - int(fix_k3))
    S, G = [], []
    for view, pose in zip(views, poses):
        obj, img = _as_calibrated(view)
        projected, J = cv2.projectPoints(obj, pose[:3], pose[3:], camera.K, dist)
        r = (projected.reshape(-1, 2) - img).ravel()
        Jp, Ji = J[:, :_POSE_COLUMNS], J[:, free]
        B = Ji.T @ Jp
        eliminate = B @ np.linalg.inv(Jp.T @ Jp)
        S.append(Ji.T @ Ji - eliminate @ B.T)
        G.append(Ji.T @ r - eliminate @ (Jp.T @ r))
    return np.array(S), np.array(G)


def _as_calibrated(view: Any) -> tuple[np.ndarray, np.ndarray]:
    """A view's board and image points as `calibrate_camera` hands them to OpenCV (float32),
    then in float64: the residuals are the ones the calibration minimised."""
    obj = np.asarray(view.object_points, dtype=np.float32).reshape(-1, 3).astype(float)
    img = np.asarray(view.image_points, dtype=np.float32).reshape(-1, 2).astype(float)
    return obj, img


def _board_poses(calibration: Any, views: Sequence[Any], dist: np.ndarray) -> np.ndarray:
    """Each view's board pose (rvec, tvec) at the calibration: the ones it solved with the
    intrinsics (``board_poses``), else (a calibration without them, or of a different number of
    views) each view's own PnP pose with its intrinsics (`handeye.vision.camera_poses.board_pose`),
    the same per-view optimum (the jackknife agrees to 1e-3 either way; 2-4 ms more on 15-30
    images)."""
    import cv2

    from handeye.vision.camera_poses import board_pose
    from handeye.vision.observations import Camera

    poses = getattr(calibration, "board_poses", None)
    if poses is not None and len(poses) == len(views):
        return np.asarray(poses, dtype=float)
    camera = Camera(calibration.camera.K, dist, calibration.camera.size)
    out = []
    for view in views:
        T = board_pose(*_as_calibrated(view), camera).T_cam_target
        out.append(np.r_[cv2.Rodrigues(T[:3, :3])[0].ravel(), T[:3, 3]])
    return np.array(out)


def _without_group(S: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The move of the intrinsics from the full calibration to the calibration without a group:
    one Gauss-Newton step -S^-1 G of the remaining views' reduced normal equations (S, G their
    sums of `_reduced_terms`; G is minus the group's own gradient, as the full set's is zero),
    solved on unit-diagonal scaling (fx ~ 1000 px, k3 ~ 0.1)."""
    d = np.sqrt(np.diag(S))
    if not np.all(np.isfinite(d) & (d > 0)):
        raise InputError("the views left in a jackknife group do not determine the intrinsics")
    scaled = S / np.outer(d, d)
    if np.linalg.cond(scaled) > 1e12:
        raise InputError("the views left in a jackknife group do not determine the intrinsics")
    return -np.linalg.solve(scaled, G / d) / d


def with_jackknife(calibration: Any, views: Sequence[Any], size: tuple[int, int],
                   images: Sequence[str] | None = None) -> Any:
    """`calibration` (a `handeye.vision.intrinsics.CameraCalibration` of `views`) with its 1-sigma
    of fx, fy, cx, cy the larger of OpenCV's and the jackknife's over the views' images
    (`jackknife_std`), OpenCV's kept in ``opencv_std``; as it is when already widened or the
    jackknife fails."""
    if calibration.opencv_std is not None:
        return calibration
    try:
        jack = jackknife_std(views, size, calibration.model.endswith("(k3 fixed at 0)"), images=images,
                             calibration=calibration)
    except (InputError, np.linalg.LinAlgError):
        return calibration
    opencv = np.asarray(calibration.std_fx_fy_cx_cy, dtype=float)
    return dataclasses.replace(calibration, std_fx_fy_cx_cy=np.maximum(opencv, jack), opencv_std=opencv)


def focal_check(views: Sequence[Any], camera: Camera, size: tuple[int, int], own: Any = None,
                images: Sequence[str] | None = None) -> FocalCheck | None:
    """The file's focal length (`camera`) against the images' own calibration from `views` (per
    view ``image_points``, ``object_points``), `own` when already calibrated; `images`: each
    view's image, where an image shows several boards (`jackknife_std`; None: a view per image);
    None when the images cannot be calibrated."""
    from handeye.vision.intrinsics import calibrate_camera

    try:
        own = with_jackknife(own or calibrate_camera(views, size), views, size, images)
    except InputError:
        return None
    std, centre = np.asarray(own.std_fx_fy_cx_cy, dtype=float)[:2], np.asarray(own.std_fx_fy_cx_cy, dtype=float)[2:4]
    opencv = std if own.opencv_std is None else np.asarray(own.opencv_std, dtype=float)[:2]
    given = np.array([camera.K[0, 0], camera.K[1, 1]])
    mine = np.array([own.camera.K[0, 0], own.camera.K[1, 1]])
    # fx and fy move together (one focal length): their mean, with the mean 1-sigma (fully correlated)
    sigmas = float(np.mean(given - mine) / np.mean(std))
    percent = float(100.0 * np.mean(given - mine) / np.mean(mine))
    return FocalCheck(tuple(given.tolist()), tuple(mine.tolist()), tuple(std.tolist()), tuple(opencv.tolist()),
                      sigmas, percent, len(views) if images is None else len(set(images)), tuple(centre.tolist()))


def given_intrinsics_check(views: Sequence[Any], errors: np.ndarray, size: tuple[int, int] | None, camera: Camera,
                           images: Sequence[str] | None = None) -> tuple[list[str], FocalCheck | None]:
    """Warnings where intrinsics given apart (`camera`) disagree with intrinsics calibrated from
    the same views (per view ``image_points``, ``object_points``; `errors`: each view's RMS
    reprojection error with `camera`, px; `images`: each view's image, as `focal_check`): they fit
    the views clearly worse (pooled RMS more than `INTRINSICS_MISFIT` x the calibration's and
    `INTRINSICS_MISFIT_PX` px above it, e.g. a lens distortion the file does not list), or their
    focal length is off by more than the images' own uncertainty allows (`focal_warning`: PnP
    absorbs a focal length off into the distance, the answer moves). Also that focal-length check
    itself; ([], None) with fewer than `INTRINSICS_CHECK_VIEWS` images or no image size."""
    from handeye.vision.intrinsics import calibrate_camera

    if size is None or len(views if images is None else set(images)) < INTRINSICS_CHECK_VIEWS:
        return [], None
    try:
        own = calibrate_camera(views, size)
    except InputError:
        return [], None
    out = []
    counts = np.array([len(v.image_points) for v in views], dtype=float)
    given = float(np.sqrt(np.sum(np.asarray(errors, dtype=float) ** 2 * counts) / np.sum(counts)))
    if given > INTRINSICS_MISFIT * own.rms and given - own.rms > INTRINSICS_MISFIT_PX:
        out.append(f"the given intrinsics fit the images worse than intrinsics calibrated from them "
                   f"({given:.2f} px against {own.rms:.2f} px RMS; calibrated distortion "
                   f"{' '.join(f'{v:.3g}' for v in own.camera.dist)}): check the intrinsics file (a lens "
                   "distortion it does not list?) or leave out its intrinsics to calibrate the camera from these "
                   "images")
    check = focal_check(views, camera, size, own, images)
    return out + [w for w in [focal_warning(check)] if w], check


def focal_warning(check: FocalCheck | None) -> str | None:
    """The warning for a file whose focal length the images contradict (`FocalCheck.off`), in the
    user's words: the file's values, the images' own with their 1-sigma, and what to do."""
    if check is None or not check.off:
        return None
    longer = "longer" if check.percent > 0 else "shorter"
    return (f"the intrinsics file's focal length (fx {check.given[0]:.1f}, fy {check.given[1]:.1f} px) is "
            f"{abs(check.percent):.2g}% {longer} than these {check.views} images give when the camera is calibrated "
            f"from them (fx {check.own[0]:.1f}, fy {check.own[1]:.1f} px, 1-sigma {check.std[0]:.2g} px): "
            f"{abs(check.sigmas):.2g} of its 1-sigma apart. A focal length off scales every board's distance and "
            "moves the answer with it, beyond its 1-sigma: check that the "
            "file is this camera's, at this resolution, zoom and focus, or leave out the intrinsics file to "
            "calibrate the camera from these images")


def given_std(camera: Camera, check: FocalCheck | None) -> tuple[tuple[float, float, float, float] | None, str]:
    """The 1-sigma (px) of fx, fy, cx, cy of intrinsics given apart, and where it comes from
    (`handeye.vision.observations.STD_SOURCES`): the file's own (`Camera.std`, "file"); for a
    file that states none, what these images know of the camera themselves (`check`: their own
    calibration's 1-sigma, the larger of OpenCV's and the jackknife's, "assumed"), since nothing
    then says the file is known better and the images cannot confirm it to better (on the real
    ChArUco set a file 1% off moved Y by 5.0 mm where the 1-sigma holding it exact was 1.1 mm);
    (None, "file") where neither is known (too few images to calibrate from): taken as exact."""
    if camera.std is not None:
        return camera.std, "file"
    if check is None:
        return None, "file"
    return (*check.std, *check.centre_std), "assumed"
