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

import numpy as np

from handeye.framework.errors import HandEyeError
from handeye.plugins.reprojection.corners import Cell, residuals
from handeye.problems.axyb import AXYBData

#: a contender: validated training data -> {"X": 4x4, "Y": 4x4}
Fitter = Callable[[AXYBData], Mapping[str, np.ndarray]]


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
    r, _ = residuals(Cell.of(data), poses, data.images.camera, False)
    return float(np.sum(r * r)), len(r)


def held_out(data: AXYBData, fitters: Mapping[str, Fitter], folds: int, seed: int = 0) -> dict[str, float | None]:
    """{name: held-out corner RMS (px)} of each contender over `folds` folds of the stations
    (module docstring); None for a contender that failed on some fold."""
    from handeye.harness.crossval import make_folds

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
