"""Where does the board appear in an image the calibration was not fitted to? Held-out corner
prediction by k-fold cross-validation over the stations: the measure a user judges a hand-eye
answer by, and the one that decides between the corner fit and the pose-based answer.

The stations are split into k folds (shuffled with a fixed seed, `handeye.harness.crossval.make_folds`);
each contender is fitted on the other folds' stations (their robot poses, board poses and
corners), and the corners of the held-out stations are predicted through the fitted X, Y and the
held-out stations' robot poses, as measured (a held-out station's robot error was not fitted:
it is part of what the prediction must live with). The figure is the RMS pixel distance between
predicted and detected corners over every held-out corner of every fold. Every contender sees the
same corners, intrinsics and folds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError
from handeye.plugins.reprojection.corners import StationChains, residuals
from handeye.problems.axyb import AXYBData
from handeye.vision.observations import Camera

#: a contender: validated training data -> {"X": 4x4, "Y": 4x4}
Fitter = Callable[[AXYBData], Mapping[str, np.ndarray]]
#: focal lengths (per cent from the given one, fx and fy together) at which `focal_scan` predicts
#: the held-out corners, beside the given one
FOCAL_SCAN = (-1.0, -0.5, 0.5, 1.0)


def stations(data: AXYBData, which: np.ndarray) -> AXYBData:
    """The data of the stations `which` only (poses and their images)."""
    images = data.images
    kept = dataclasses.replace(images, image_points=tuple(images.image_points[i] for i in which),
                               object_points=tuple(images.object_points[i] for i in which),
                               names=None if images.names is None else tuple(images.names[i] for i in which))
    return dataclasses.replace(data, A=data.A[which], B=data.B[which], images=kept)


def predicted_rms(data: AXYBData, unknowns: Mapping[str, np.ndarray]) -> tuple[float, int]:
    """(sum of squared pixel errors, corners) of the data's corners predicted through X, Y and
    the robot's poses."""
    poses = {k: np.asarray(unknowns[k], dtype=float) for k in ("X", "Y")}
    r, _ = residuals(StationChains.of(data), poses, data.images.camera, False)
    return float(np.sum(r * r)), len(r)


def held_out(data: AXYBData, fitters: Mapping[str, Fitter], folds: int, seed: int = 0) -> dict[str, float | None]:
    """{name: held-out corner RMS (px)} of each contender over `folds` folds of the stations
    (module docstring); None for a contender that failed on some fold."""
    from handeye.estimation.folds import make_folds

    m = len(data.A)
    parts = make_folds(m, folds, seed)
    sums = {name: [0.0, 0] for name in fitters}
    for test in parts:
        train = np.setdiff1d(np.arange(m), test)
        train_data, test_data = stations(data, train), stations(data, test)
        for name, fitter in fitters.items():
            if sums[name] is None:
                continue
            try:
                squared, corners = predicted_rms(test_data, fitter(train_data))
            except (HandEyeError, np.linalg.LinAlgError):
                sums[name] = None
                continue
            sums[name][0] += squared
            sums[name][1] += corners
    return {name: None if s is None else float(np.sqrt(s[0] / max(s[1], 1))) for name, s in sums.items()}


def focal_scan(data: AXYBData, fitter: Fitter, folds: int, at_given: float | None, seed: int = 0) -> dict[str, Any]:
    """Held-out corner prediction (`held_out`, the same folds) of `fitter` with the camera's focal
    length (fx and fy together) moved by each of `FOCAL_SCAN` per cent, beside `at_given` (its
    figure at the given focal length): ``percent`` and ``px`` (None where a fit failed), the
    ``best_percent`` and ``gain``, the given focal length's figure over the best's.

    Why: intrinsics given apart may be off, and the images alone know the focal length only to
    0.75-0.9% on the real sets, while the hand-eye chain ties each board's distance to the robot's
    poses: a focal length off shows in held-out images. Measured on the real ChArUco set (exact-
    robot corner fit, 3 folds): 1.47 px at the images' own focal length, 1.37 at -0.5%, 1.48 at
    -1%, 1.74 at +0.5%, 2.10 at +1%, 2.98 at +2%; on the real circle grid, whose robot errors
    dominate, 2.07-2.23 px from -2% to +2% (flat: no information)."""
    camera = data.images.camera
    found = {0.0: at_given}
    for percent in FOCAL_SCAN:
        K = camera.K.copy()
        K[0, 0] *= 1.0 + percent / 100.0
        K[1, 1] *= 1.0 + percent / 100.0
        moved = dataclasses.replace(data, images=dataclasses.replace(data.images, camera=Camera(K, camera.dist,
                                                                                                 camera.size)))
        found[percent] = held_out(moved, {"fit": fitter}, folds, seed)["fit"]
    usable = {p: px for p, px in found.items() if px is not None}
    best = min(usable, key=usable.get) if usable else 0.0
    given = found[0.0]
    return {"percent": sorted(found), "px": [found[p] for p in sorted(found)], "best_percent": best,
            "gain": None if given is None or not usable else given / usable[best]}
