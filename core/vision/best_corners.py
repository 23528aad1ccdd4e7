"""The best corners the images hold: of the detections a detector offers for one image (its
`Detection.candidates()`: several OpenCV detectors or flag sets, `handeye.vision.detect`), keep
the one that fits the camera best.

Why a fit and not a fixed order: no single detector is best everywhere. On renders (sharp,
ideal edges) ``cornerSubPix`` halves the error of ``findChessboardCornersSB``; on real chessboard
images (OpenCV 4.14, 2 x 18 images of a 6x5 board, 640 x 480) SB with ``CALIB_CB_ACCURACY``
alone calibrates to 0.114 / 0.110 px RMS where ``cornerSubPix`` gives 0.149 / 0.148 px and SB
with ``NORMALIZE_IMAGE | ACCURACY`` 0.137 / 0.136 px; and any flag set may fail, or number a board
wrongly, on an image where another succeeds. The image itself says which fits: the board is
planar and the camera is one pinhole with lens distortion, so the corners that are right leave
the smallest residual of that model.

The rule (`choose`, `pick`):

1. `plausible`: of an image's candidates, those with the most points (more of the board seen is
   more information) that agree with the largest group of the others (median distance on their
   common points below `AGREE_PX`): a wrong numbering (a board turned, a row shifted) disagrees
   with the others by a square and is left out before it can spoil a calibration;
2. each candidate's board pose is solved (PnP, `handeye.vision.camera_poses.board_pose`) and its
   RMS reprojection error taken; the detectors are ranked over the whole set by their mean log
   ratio to each image's least error (`rank_methods`), and each image keeps its best-ranked
   candidate unless another leaves a `SWITCH` (20 %) smaller error -- one image's few dozen points
   cannot tell detectors 10 % apart (on renders a per-image minimum picked worse corners than a
   fixed detector), a whole set can, and an image where the set's detector fails or goes astray
   still gets the one that fits;
3. without intrinsics they are calibrated from each image's first plausible candidate, every
   image picks by step 2 with them, and the camera is recalibrated from the picks, until the
   picks repeat (at most `ROUNDS`): the intrinsics are shared by all images, so one image's pick
   hardly moves them. A single image with intrinsics (`pick`) keeps the detector's first
   candidate unless another's error is `SWITCH` smaller.

What the residual cannot see: an error a pose change absorbs. On renders of a 6x5 chessboard,
blurred, noisy and distorted, SB with ACCURACY left the smaller residual but lay 0.004 px further
from the truth than cornerSubPix (0.023 against 0.019 px); docs/boards.md has the figures.

Everything is deterministic (OpenCV's calibration on one thread, PnP, stable ordering).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from handeye.base.errors import InputError
from handeye.vision.camera_poses import board_pose
from handeye.vision.detection import Detection
from handeye.vision.intrinsics import CameraCalibration, calibrate_camera
from handeye.vision.observations import Camera

#: two candidates agree when the median distance of their common points is below this (pixels):
#: right detections of one image differ by hundredths of a pixel, a wrong numbering by a square
AGREE_PX = 1.0
#: most calibrate-pick rounds without intrinsics (the picks repeat after 1-2 on the real sets)
ROUNDS = 3
#: an image leaves the set's preferred detector for another only when that one's residual is this
#: much (fraction) smaller: the RMS of one image's few dozen points scatters by ~10 %, so smaller
#: differences are noise (measured: tests/vision/test_vision_best_corners.py, docs/boards.md)
SWITCH = 0.2


@dataclasses.dataclass(frozen=True)
class Choice:
    """What `choose` kept: per image the detection (None where the board was not found), the
    detector / flag set of each kept one, the camera calibration of the last round (None when
    intrinsics were given or too few images), and how many rounds it took. calibrated_kept: the
    calibration is that of exactly the detections kept (the picks repeated), so a caller
    calibrating from them can take it instead of calibrating again."""

    detections: tuple[Detection | None, ...]
    methods: tuple[str, ...]
    calibration: CameraCalibration | None
    rounds: int
    calibrated_kept: bool = False


def plausible(candidates: Sequence[Detection]) -> list[Detection]:
    """The candidates worth judging (rule 1 in the module docstring), in their given order."""
    most = max(len(c) for c in candidates)
    full = [c for c in candidates if len(c) == most]
    agree = np.array([[_distance(a, b) < AGREE_PX for b in full] for a in full])
    leader = int(np.argmax(agree.sum(axis=1)))  # first of the largest group on a tie
    return [c for c, ok in zip(full, agree[leader]) if ok]


def _distance(a: Detection, b: Detection) -> float:
    """Median distance (px) between the points of `a` and `b` with the same id (inf if none)."""
    common, ia, ib = np.intersect1d(a.ids, b.ids, assume_unique=True, return_indices=True)
    if len(common) == 0:
        return float("inf")
    return float(np.median(np.linalg.norm(a.image_points[ia] - b.image_points[ib], axis=1)))


def fit_rms(detection: Detection, camera: Camera) -> float:
    """RMS reprojection error (px) of `detection` at its PnP board pose with `camera` (inf when
    no pose can be solved)."""
    try:
        return board_pose(detection.object_points, detection.image_points, camera).rms
    except InputError:
        return float("inf")


def pick(detection: Detection, camera: Camera) -> Detection:
    """Of `detection` and its alternatives, the plausible one that fits `camera` best (module
    docstring); it carries the other plausible ones as its alternatives."""
    candidates = plausible(detection.candidates())
    if len(candidates) == 1:
        return candidates[0]
    best = _pick(candidates, [fit_rms(c, camera) for c in candidates], 0)
    return candidates[best].with_alternatives(tuple(c for k, c in enumerate(candidates) if k != best))


def _pick(candidates: Sequence[Detection], errors: Sequence[float], preferred: int) -> int:
    """The candidate kept: `preferred`, unless another's residual is `SWITCH` smaller (the least)."""
    best = int(np.argmin(errors))
    return best if errors[best] < (1 - SWITCH) * errors[preferred] else preferred


def rank_methods(candidates: Sequence[Sequence[Detection]], errors: Sequence[Sequence[float]]) -> dict[str, float]:
    """Each detector's (`Detection.method`) mean log ratio of its residual to the image's least,
    over the images where it found the board: 0 for one always best. Pooled over a set, this
    ranks detectors far more surely than one image's residuals can (`SWITCH`)."""
    ratios: dict[str, list[float]] = {}
    for cands, errs in zip(candidates, errors):
        least = max(min(errs), 1e-12)
        for c, e in zip(cands, errs):
            ratios.setdefault(c.method, []).append(float(np.log(max(e, 1e-12) / least)) if np.isfinite(e) else 1e3)
    return {m: float(np.mean(r)) for m, r in ratios.items()}


def choose(detections: Sequence[Detection | None], camera: Camera | None,
           image_size: tuple[int, int] | None) -> Choice:
    """Per image, the detection that fits best (module docstring, rule 2 as refined there).
    `detections`: one per image
    (None: board not found), each carrying its alternatives; `camera`: the intrinsics, or None to
    calibrate them here from the images (`image_size`: (width, height))."""
    candidates = [None if d is None else plausible(d.candidates()) for d in detections]
    kept = [None if c is None else c[0] for c in candidates]
    calibration, rounds, changed = None, 0, True
    judged = [k for k, c in enumerate(candidates) if c is not None and len(c) > 1]
    for rounds in range(1, ROUNDS + 1):
        if not judged:
            break
        if camera is None:
            try:
                calibration = calibrate_camera([d for d in kept if d is not None], image_size)
            except InputError:  # too few images: keep the detector's preference
                break
        fit_camera = camera or calibration.camera
        errors = {k: [fit_rms(c, fit_camera) for c in candidates[k]] for k in judged}
        rank = rank_methods([candidates[k] for k in judged], [errors[k] for k in judged])
        picks = {}
        for k in judged:
            preferred = min(range(len(candidates[k])), key=lambda i: (rank[candidates[k][i].method], i))
            picks[k] = _pick(candidates[k], errors[k], preferred)
        new = [kept[k] if k not in picks else candidates[k][picks[k]] for k in range(len(kept))]
        changed = any(a is not b for a, b in zip(new, kept))
        kept = new
        if camera is not None or not changed:
            break
    current = calibration is not None and not changed
    return Choice(tuple(kept), tuple(d.method for d in kept if d is not None), calibration, rounds, current)
