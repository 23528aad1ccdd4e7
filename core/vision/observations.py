"""The image observations of a calibration board at each station, as solvers see them.

`Camera` holds the pinhole intrinsics (OpenCV's model: K and distortion coefficients in
``cv2.projectPoints`` order). `BoardObservations` holds, per station, the detected corners (pixels)
and the same corners in the board frame (the data's length unit), with what the station's pose B_i
of ``A_i X = Y B_i`` means for the camera (`setup`):

- eye-in-hand: B_i = T_target_cam, so the board in the camera is T_cam_target = B_i^-1 = X^-1 A_i^-1 Y;
- eye-to-hand: B_i = T_cam_target = Y^-1 A_i X (docs/conventions.md).

`board_in_camera(A, X, Y)` gives T_cam_target for every station from the unknowns, which is what a
reprojection-error solver projects the board's corners with.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import SETUPS
from handeye.geometry.se3 import inverse
from handeye.geometry.validation import float_array

#: where the intrinsics' 1-sigma comes from: calibrated from the images themselves, stated by an
#: intrinsics file, or assumed for a file that states none (the images' own knowledge of them)
STD_SOURCES = ("images", "file", "assumed")


@dataclasses.dataclass(frozen=True)
class Camera:
    """Pinhole intrinsics: K (3x3, pixels), dist (OpenCV's k1, k2, p1, p2[, k3, ...]; may be empty),
    image size (width, height) in pixels or None, and `std`: the 1-sigma (pixels) of fx, fy, cx,
    cy where whoever calibrated the camera stated it (an intrinsics file's ``std_px``, OpenCV's
    ``stdDeviationsIntrinsics``), else None."""

    K: np.ndarray
    dist: np.ndarray
    size: tuple[int, int] | None = None
    std: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        K = float_array(self.K, "camera matrix K", "a 3x3 matrix of numbers")
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError(f"camera matrix K must be a finite 3x3 matrix with fx, fy > 0, got shape {K.shape}")
        dist = float_array(self.dist, "distortion coefficients", "a list of numbers").ravel()
        if dist.size not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
            raise InputError(f"distortion coefficients must be 0, 4, 5, 8, 12 or 14 finite numbers (OpenCV's "
                             f"order k1, k2, p1, p2, k3, ...), got {dist.size}")
        for name, value in (("K", K), ("dist", dist)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if self.size is not None:
            object.__setattr__(self, "size", (int(self.size[0]), int(self.size[1])))
        if self.std is not None:
            std = float_array(self.std, "the intrinsics' 1-sigma", "4 numbers (fx, fy, cx, cy in pixels)").ravel()
            if std.size != 4 or not np.all(np.isfinite(std)) or np.any(std < 0):
                raise InputError(f"the intrinsics' 1-sigma must be 4 finite numbers >= 0 (fx, fy, cx, cy in pixels), "
                                 f"got {std.tolist()}")
            object.__setattr__(self, "std", tuple(float(v) for v in std))


@dataclasses.dataclass(frozen=True)
class BoardObservations:
    """Per station i: image_points[i] (n_i, 2) pixels and object_points[i] (n_i, 3) in the board
    frame (the pose data's length unit), the camera, the setup, the stations' names (e.g. the
    image files) or None, and whether the intrinsics came from these images. Arrays are
    read-only copies."""

    image_points: tuple[np.ndarray, ...]
    object_points: tuple[np.ndarray, ...]
    camera: Camera
    setup: str
    names: tuple[str, ...] | None = None
    #: the 1-sigma (px) of fx, fy, cx, cy of the intrinsics (None: taken as exact), and where it
    #: comes from (`intrinsics_std_from`, one of `STD_SOURCES`): calibrated from these images
    #: (`handeye.vision.intrinsics.CameraCalibration`), stated by the intrinsics file, or, for a
    #: file that states none, what these images know of the camera themselves
    #: (`handeye.vision.intrinsics_check.given_std`). A fit to the corners owes them part of its
    #: uncertainty (the `reprojection` solver adds it)
    intrinsics_std: tuple[float, float, float, float] | None = None
    intrinsics_std_from: str = "images"
    #: where the intrinsics were given apart: the images' own focal length against theirs
    #: (`handeye.vision.intrinsics_check.FocalCheck`), or None (not checked: too few images)
    focal_check: Any = None

    def __post_init__(self) -> None:
        if self.setup not in SETUPS:
            raise InputError(f"setup must be one of {SETUPS}, got {self.setup!r}")
        if len(self.image_points) != len(self.object_points):
            raise InputError(f"image observations: {len(self.image_points)} stations of image points but "
                             f"{len(self.object_points)} of board points; give both for every station")
        img, obj = [], []
        for i, (u, p) in enumerate(zip(self.image_points, self.object_points)):
            u = float_array(u, f"image points of station {i}", "an (n, 2) array of pixels")
            p = float_array(p, f"board points of station {i}", "an (n, 3) array")
            if u.ndim != 2 or u.shape[1] != 2 or p.shape != (len(u), 3):
                raise InputError(f"station {i}: image points must be (n, 2) and board points (n, 3) with the "
                                 f"same n, got {u.shape} and {p.shape}")
            if len(u) < 4 or not (np.all(np.isfinite(u)) and np.all(np.isfinite(p))):
                raise InputError(f"station {i}: needs at least 4 finite corners, got {len(u)}")
            u.setflags(write=False)
            p.setflags(write=False)
            img.append(u)
            obj.append(p)
        object.__setattr__(self, "image_points", tuple(img))
        object.__setattr__(self, "object_points", tuple(obj))
        if self.names is not None:
            if len(self.names) != len(img):
                raise InputError(f"image observations: {len(self.names)} names for {len(img)} stations")
            object.__setattr__(self, "names", tuple(str(n) for n in self.names))

    def __len__(self) -> int:
        return len(self.image_points)

    def scaled(self, s: float) -> BoardObservations:
        """The same observations with board lengths divided by s (as the pose data's translations)."""
        return dataclasses.replace(self, object_points=tuple(p / s for p in self.object_points))

    def take(self, rows: Sequence[int]) -> BoardObservations:
        """The stations `rows`, in that order."""
        names = None if self.names is None else tuple(self.names[i] for i in rows)
        return dataclasses.replace(self, image_points=tuple(self.image_points[i] for i in rows),
                                   object_points=tuple(self.object_points[i] for i in rows), names=names)


def board_in_camera(setup: str, A: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """T_cam_target of every station (m, 4, 4) from the robot poses A and the unknowns X, Y of
    A_i X = Y B_i: Y^-1 A_i X eye-to-hand, its inverse eye-in-hand."""
    B = inverse(np.asarray(Y, dtype=float)) @ np.asarray(A, dtype=float) @ np.asarray(X, dtype=float)
    return inverse(B) if setup == "eye-in-hand" else B


def checked(value: Any, stations: int) -> BoardObservations:
    """`value` as BoardObservations for `stations` pose pairs (InputError otherwise)."""
    if not isinstance(value, BoardObservations):
        raise InputError(f"images must be handeye.vision.observations.BoardObservations, got {type(value).__name__}")
    if len(value) != stations:
        raise InputError(f"images hold {len(value)} stations but the poses {stations}; give one board "
                         "observation per pose pair, in the same order")
    return value
