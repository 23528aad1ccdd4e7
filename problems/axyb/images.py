"""A_i X = Y B_i simulated from board images: corners projected by a camera, with pixel noise, and
B_i the PnP pose of the noisy corners, as real image data give it (`AXYB.simulate(images=...)`).

The stations are camera poses looking at a 9 x 6 board (30 mm spacing, scaled with the data's
unit) from 350-750 mm, tilted up to 40 deg from its normal, at a random roll; A_i follows from X,
Y: A_i = Y B_i X^-1. The camera: 1280 x 960, fx = fy = 1000 px, mild barrel distortion. Noise on
B in the noise model means pixel noise on the corners (``pixel_noise``, default 0.3 px); noise on
A stays the robot's pose noise.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import SETUPS
from handeye.estimation.noise import NoiseModel
from handeye.framework.options import check_choice, check_positive
from handeye.geometry.se3 import inverse, make_pose, so3_exp

#: board corners (cols x rows) and spacing (mm), camera distance range (mm), largest tilt (rad)
BOARD = (9, 6, 30.0)
DISTANCE = (350.0, 750.0)
MAX_TILT = np.radians(40.0)
#: the simulated camera (K, distortion k1, k2, p1, p2, k3, image size)
K = np.array([[1000.0, 0.0, 640.0], [0.0, 1000.0, 480.0], [0.0, 0.0, 1.0]])
DIST = np.array([-0.08, 0.05, 0.0, 0.0, 0.0])
SIZE = (1280, 960)
KEYS = ("setup", "pixel_noise")


def board_points(unit_scale: float = 1.0) -> np.ndarray:
    """(n, 3) corners of the simulated board in its frame (z = 0), lengths times unit_scale."""
    cols, rows, spacing = BOARD
    grid = np.stack(np.meshgrid(np.arange(cols), np.arange(rows)), axis=-1).reshape(-1, 2) * spacing
    return np.column_stack([grid, np.zeros(len(grid))]) * unit_scale


def views(pairs: int, rng: np.random.Generator, unit_scale: float = 1.0, points: np.ndarray | None = None) -> np.ndarray:
    """(pairs, 4, 4) T_cam_target: the camera looking at the centre of the board (its `points`,
    default `board_points`) from the -z side."""
    P = board_points(unit_scale) if points is None else np.asarray(points, dtype=float)
    centre = (P.min(axis=0) + P.max(axis=0)) / 2
    out = np.empty((pairs, 4, 4))
    for i in range(pairs):
        tilt, azimuth = MAX_TILT * np.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * np.pi)
        direction = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)])
        position = centre + rng.uniform(*DISTANCE) * unit_scale * direction
        z = -direction
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z]) @ so3_exp(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)]))
        out[i] = inverse(make_pose(R, position))
    return out


def simulate(pairs: int, rng: np.random.Generator, noise: NoiseModel, X: np.ndarray, Y: np.ndarray,
             options: Mapping[str, Any], unit_scale: float = 1.0) -> dict[str, Any]:
    """The data {A, B, images} of `pairs` stations (module docstring)."""
    import cv2

    from handeye.vision.observations import BoardObservations, Camera

    unknown = sorted(set(options) - set(KEYS))
    if unknown:
        raise InputError(f"unknown images option(s) {unknown}; known: {', '.join(KEYS)}")
    setup = options.get("setup", "eye-in-hand")
    check_choice("images setup", setup, SETUPS)
    pixel_noise = options.get("pixel_noise", 0.3)
    check_positive("images pixel_noise", pixel_noise, allow_zero=True)
    pixel_noise = float(pixel_noise)
    T_cam_target = views(pairs, rng, unit_scale)
    B_true = inverse(T_cam_target) if setup == "eye-in-hand" else T_cam_target
    A = Y @ B_true @ inverse(X)
    P = board_points(unit_scale)
    camera = Camera(K, DIST, SIZE)
    noisy = "B" in noise.sigmas and max(noise.sigmas["B"]) > 0
    pose_rng = np.random.default_rng(rng.integers(2**63))
    pixels, B = [], np.array(B_true)
    for i, T in enumerate(T_cam_target):
        rvec, _ = cv2.Rodrigues(T[:3, :3])
        u = cv2.projectPoints(P, rvec, T[:3, 3], K, DIST)[0].reshape(-1, 2)
        if noisy:
            u = u + pixel_noise * pose_rng.standard_normal(u.shape)
            _, r, t = cv2.solvePnP(P, u, K, DIST, rvec=rvec.copy(), tvec=T[:3, 3].copy(), useExtrinsicGuess=True,
                                    flags=cv2.SOLVEPNP_ITERATIVE)
            T_pnp = make_pose(cv2.Rodrigues(r)[0], t.ravel())
            B[i] = inverse(T_pnp) if setup == "eye-in-hand" else T_pnp
        pixels.append(u)
    A_noisy = NoiseModel({k: v for k, v in noise.sigmas.items() if k == "A"}).apply("A", A, pose_rng)
    images = BoardObservations(tuple(pixels), tuple(P for _ in range(pairs)), camera, setup)
    return {"A": A_noisy, "B": B, "images": images}
