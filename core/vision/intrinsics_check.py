"""Intrinsics given in a file are taken as exact: do the images say the same focal length?

A focal length a little off scales every board's distance, and the hand-eye answer moves with it
(on the real ChArUco set, 1.27 m from the board, a focal length 0.1% off moves Y by ~0.5 mm,
2.7x its 1-sigma): the fit's residuals barely change (PnP absorbs it into the distance), so a
wrong file gives a confident wrong answer. The images can check the file: calibrated from the
same corners (`handeye.vision.intrinsics.calibrate_camera`, ~30-60 ms), they give their own
focal length, and the file's is compared with it in units of its uncertainty.

That uncertainty is not OpenCV's 1-sigma: on real images the corners' errors are not independent
pixel noise, and OpenCV's figure is too small. Measured by a delete-one jackknife over the
images, fx's 1-sigma is 1.9x OpenCV's on the real ChArUco set (16 images, 9.9 px against 5.2 px)
and 4.6x on the real circle-grid set (15 images); on simulated corners with independent noise
the two agree. The check uses the larger of the two, the jackknife over at most `GROUPS` groups
of the images (`focal_check`).

Measured (bench/intrinsics_uncertainty.py --detect 40, docs/images.md): on simulated sets of 15
images (own focal length to ~0.14%) the true intrinsics warn in 0 of 40, a file 0.3% / 0.5% / 1%
/ 2% off in 7 / 21 / 38 / 40 of 40; the real sets' files (their own calibration, and their
cal_data.yaml) are quiet, and so is every error up to 2% there (own focal length to 0.76% and
0.87%: 2.6 and 2.3 sigmas at 2%). The check finds a file as far off as `FOCAL_SIGMAS` times the
images' own uncertainty and no closer; below that, `exactness_note` says what holding the file
exact is worth.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.framework.errors import InputError
from handeye.vision.observations import Camera

#: the file's focal length this many of the images' 1-sigma from theirs: a warning. Simulated
#: sets with the true intrinsics given: largest |z| 2.2 in 40, RMS 0.82 (Gaussian |z| > 3: 0.3%)
FOCAL_SIGMAS = 3.0
#: a focal length 0.1% off moving an unknown's translation by more than this many of its 1-sigma
#: makes the answer state that it takes the given intrinsics as exact (`exactness_note`): a 0.1%
#: focal length is a good calibration's precision (the real ChArUco set's own: 0.76%)
EXACT_GROWTH = 1.0
#: the jackknife deletes one of at most this many groups of the images at a time (cost: GROUPS
#: calibrations of the camera, 0.12 s on the real ChArUco set's 15 images of 1600 x 1200)
GROUPS = 12


@dataclasses.dataclass(frozen=True)
class FocalCheck:
    """The file's focal length (fx, fy) against the images' own calibration: theirs (fx, fy),
    its 1-sigma used (the larger of OpenCV's and the jackknife's, px) and OpenCV's own, the
    difference in those 1-sigmas (focal length: the mean of fx and fy) and in per cent, and the
    number of images calibrated from (``views``)."""

    given: tuple[float, float]
    own: tuple[float, float]
    std: tuple[float, float]
    opencv_std: tuple[float, float]
    sigmas: float
    percent: float
    views: int

    @property
    def off(self) -> bool:
        return abs(self.sigmas) > FOCAL_SIGMAS


def jackknife_std(views: Sequence[Any], size: tuple[int, int], fix_k3: bool, groups: int = GROUPS,
                  images: Sequence[str] | None = None) -> np.ndarray:
    """The grouped delete-one jackknife 1-sigma of (fx, fy, cx, cy) of `calibrate_camera` over
    the views: sqrt((g - 1) / g * sum_i (theta_i - mean)^2), theta_i calibrated without group i.
    The groups are of images: `images` names each view's image (None: one view per image), and
    the views of one image (several boards in it) leave together, as their corners' errors are
    not independent either."""
    from handeye.vision.intrinsics import calibrate_camera

    keys = list(range(len(views))) if images is None else list(images)
    units = list(dict.fromkeys(keys))
    g = min(len(units), groups)
    theta = []
    for part in np.array_split(np.arange(len(units)), g):
        gone = {units[i] for i in part.tolist()}
        kept = [v for v, key in zip(views, keys) if key not in gone]
        K = calibrate_camera(kept, size, fix_k3=fix_k3).camera.K
        theta.append([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    theta = np.array(theta)
    return np.sqrt((g - 1) / g * np.sum((theta - theta.mean(axis=0)) ** 2, axis=0))


def with_jackknife(calibration: Any, views: Sequence[Any], size: tuple[int, int],
                   images: Sequence[str] | None = None) -> Any:
    """`calibration` (a `handeye.vision.intrinsics.CameraCalibration` of `views`) with its 1-sigma
    of fx, fy, cx, cy the larger of OpenCV's and the jackknife's over the views' images
    (`jackknife_std`), OpenCV's kept in ``opencv_std``; as it is when already widened or the
    jackknife fails."""
    if calibration.opencv_std is not None:
        return calibration
    try:
        jack = jackknife_std(views, size, calibration.model.endswith("(k3 fixed at 0)"), images=images)
    except InputError:
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
    std = np.asarray(own.std_fx_fy_cx_cy, dtype=float)[:2]
    opencv = std if own.opencv_std is None else np.asarray(own.opencv_std, dtype=float)[:2]
    given = np.array([camera.K[0, 0], camera.K[1, 1]])
    mine = np.array([own.camera.K[0, 0], own.camera.K[1, 1]])
    # fx and fy move together (one focal length): their mean, with the mean 1-sigma (fully correlated)
    sigmas = float(np.mean(given - mine) / np.mean(std))
    percent = float(100.0 * np.mean(given - mine) / np.mean(mine))
    return FocalCheck(tuple(given.tolist()), tuple(mine.tolist()), tuple(std.tolist()), tuple(opencv.tolist()),
                      sigmas, percent, len(views) if images is None else len(set(images)))


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
            "moves the answer with it, which its 1-sigma (the file taken as exact) does not contain: check that the "
            "file is this camera's, at this resolution, zoom and focus, or leave out the intrinsics file to "
            "calibrate the camera from these images")


def exactness_note(per_permille: Mapping[str, float], std: Mapping[str, Mapping[str, float]],
                   check: FocalCheck | None, labels: Mapping[str, str] | None = None) -> str | None:
    """The statement where intrinsics given apart are taken as exact and that matters: a focal
    length 0.1% off (`per_permille`: how far it moves each unknown's translation) moves some
    unknown by more than its translation 1-sigma (`std`, as `handeye.standard_deviations` gives
    it), with how well these images alone know the focal length (`check`). None where no unknown
    moves that far, where `check` already warns (its own warning says more), or without a check
    (intrinsics passed to the library with the images, e.g. a simulation's true ones: nothing
    says they are less than exact; ``focal_per_permille`` in the diagnostics still says what
    0.1% would do)."""
    if check is None or check.off:
        return None
    moved = [(name, shift, std[name]["translation"]) for name, shift in per_permille.items()
             if name in std and shift > EXACT_GROWTH * std[name]["translation"] > 0]
    if not moved:
        return None
    which = " and ".join(f"{(labels or {}).get(n, n)} by {shift:.3g} ({shift / s:.2g}x its 1-sigma)"
                         for n, shift, s in moved)
    percent = 100.0 * float(np.mean(check.std)) / float(np.mean(check.own))
    return (f"the answer's 1-sigma takes the intrinsics given as exact, yet a focal length 0.1% off would move "
            f"{which}, in the data's length unit; these {check.views} images alone know the focal length only to "
            f"{percent:.2g}% (fx {check.own[0]:.1f} +- {check.std[0]:.2g} px against the {check.given[0]:.1f} given), "
            "so they cannot confirm it to better: the answer is as good as the intrinsics' focal length; give "
            "intrinsics calibrated from many images at several distances and tilts")
