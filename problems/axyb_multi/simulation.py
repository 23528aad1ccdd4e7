"""The simulated multi-camera cell (`simulate_cell`): fixed cameras around the workspace watching
markers on the flange, or cameras on the wrist watching boards in the cell, each camera seeing a
random subset of the targets at each station of the simulated arm, with noise on the robot's
and the cameras' poses (per camera where they differ), gross observations and monocular scales."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import SETUPS
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import inverse, make_pose, random_rotations, so3_exp
from handeye.geometry.validation import pose_stack

#: the simulated cell per setup: (cameras, markers, visible markers per camera per station). Eye
#: to hand, fixed cameras (the Y's) watch markers on the flange (the X's); eye in hand, cameras
#: on the wrist (the X's) watch boards in the cell (the Y's, "markers" in the options)
SIMULATED_CELL = {"eye-to-hand": (8, 16, (3, 6)), "eye-in-hand": (2, 6, (1, 3))}
#: mean flange position of the simulated arm (`random_flange_poses`, mm): what the cameras look at
WORKSPACE_CENTER = np.array([370.0, 0.0, 680.0])
#: fixed cameras' distance from the workspace centre (mm) and elevation above it (rad)
CAMERA_DISTANCE = (1000.0, 2000.0)
CAMERA_ELEVATION = (math.radians(20.0), math.radians(60.0))
#: markers (eye to hand) and wrist cameras (eye in hand): distance from the flange origin, mm
FLANGE_OFFSET = (50.0, 150.0)
#: boards (eye in hand): distance from the workspace centre (mm), at or below its height
BOARD_DISTANCE = (400.0, 800.0)
#: a gross observation's camera pose is off by a rotation of this many degrees (a random axis)
#: and a translation of this many mm (a random direction): a marker mistaken for another, a
#: detection of the wrong corner order
GROSS_ROTATION_DEG = (10.0, 60.0)
GROSS_TRANSLATION = (50.0, 200.0)
#: the seed of the simulated cell's default layout (fixed: the same cell at every data seed)
CELL_SEED = 2025



class SimulatedCell:
    """What `simulate_cell` made: data (the fields of `AXYBMulti.validate`), truth, and which
    observations are gross (`gross`: indices into the observations) and which station each is."""

    def __init__(self, data: dict[str, Any], truth: dict[str, np.ndarray], gross: np.ndarray, station: np.ndarray) -> None:
        self.data, self.truth, self.gross, self.station = data, truth, gross, station


def simulate_cell(stations: int, *, seed: int | None = None, noise: NoiseModel | None = None,
                  X: np.ndarray | None = None, Y: np.ndarray | None = None, setup: str = "eye-to-hand",
                  cameras: int | None = None, markers: int | None = None, visible: tuple[int, int] | None = None,
                  gross: float = 0.0, camera_scales: Mapping[str, float] | None = None,
                  camera_noise: Mapping[str, float] | None = None) -> SimulatedCell:
    """A simulated multi-camera cell.

    setup "eye-to-hand": `cameras` fixed cameras (the Y's, T_base_cam) 1-2 m from the workspace,
    looking at its centre from around it and 20-60 deg above, watch `markers` markers on the
    flange (the X's, T_flange_marker, 50-150 mm from the flange origin, facing outward); B_i =
    T_cam_marker. "eye-in-hand": `cameras` cameras on the wrist (the X's, T_flange_cam, 50-150 mm
    off the flange, looking along its axis within 30 deg) watch `markers` boards in the cell
    (the Y's, T_base_target, 0.4-0.8 m from the workspace centre at or below it, facing it);
    B_i = T_target_cam. Defaults per setup: `SIMULATED_CELL` (8 cameras and 16 markers, each
    camera seeing 3-6 of them at a station; 2 cameras and 6 boards, 1-3).

    Stations: `stations` flange poses of the simulated LR Mate 200iD-like arm at random joints
    (`random_flange_poses`, mm). Visibility: at each station each camera sees a random subset of
    the targets, of a size drawn uniformly from `visible` = (fewest, most) (clipped to the
    targets); a target no camera saw at any station is then given one observation (a random
    camera at a random station), so that every X and Y is observed. Observations are ordered by
    station, then camera, then target.

    X, Y: None (the default cell's, fixed whatever the seed: `CELL_SEED`), a stack of poses (its
    length then sets the number of X's or Y's), or one 4x4 pose (the harness's random truth): the
    first of the stack, the others it turned about the z axis of its parent frame (the flange's for
    X, the base's for Y) in equal steps of 360 deg / count.

    noise: `NoiseModel`, "A" on each station's robot pose (shared by that station's observations,
    as one reading of the robot is) and "B" on each observation's camera pose. gross: the share
    of observations (rounded) whose camera pose is off by GROSS_ROTATION_DEG and
    GROSS_TRANSLATION (`SimulatedCell.gross` lists them). The random stream is drawn in a fixed
    order (stations, visibility, then the noise and gross streams), so a seed gives the same
    stations and visibility at every noise level and share of gross observations.

    camera_noise: {camera name: f}: the "B" noise of that camera's observations times f (others
    1), for cells whose cameras differ (a longer lens, a lower resolution); the same draws scaled,
    so a seed gives the same stations, visibility and gross observations with or without it.

    camera_scales: {camera name: s} for monocular cameras (names as made here: ``cam0``, ...):
    each named camera's translations t_B are its metric ones (noise and gross errors included)
    divided by its s, so that s t_B is metric (docs/camera-scale.md); the data then carry
    ``camera_scale`` = those names and the truth ``"camera_scales"`` = {name: s}.
    """
    if setup not in SETUPS:
        raise InputError(f"setup={setup!r} is not one of {', '.join(SETUPS)}")
    _count("pairs (stations)", stations, 1)
    default_cameras, default_markers, default_visible = SIMULATED_CELL[setup]
    eye_to_hand = setup == "eye-to-hand"
    # X's are the markers eye to hand, the wrist cameras eye in hand; Y's the other
    x_count = markers if eye_to_hand else cameras
    y_count = cameras if eye_to_hand else markers
    x_default = default_markers if eye_to_hand else default_cameras
    y_default = default_cameras if eye_to_hand else default_markers
    x_option, y_option = ("markers", "cameras") if eye_to_hand else ("cameras", "markers")
    X = _truth_stack(X, "X", x_count, x_option, x_default)
    Y = _truth_stack(Y, "Y", y_count, y_option, y_default)
    nX = len(X) if X.ndim == 3 else (_count(x_option, x_count, 1) if x_count is not None else x_default)
    nY = len(Y) if Y.ndim == 3 else (_count(y_option, y_count, 1) if y_count is not None else y_default)
    n_cam, n_target = (nY, nX) if eye_to_hand else (nX, nY)
    lo, hi = _visible(default_visible if visible is None else visible)
    gross = _share(gross)
    layout = np.random.default_rng(CELL_SEED)
    default_X, default_Y = (_markers(nX, layout), _fixed_cameras(nY, layout)) if eye_to_hand else \
        (_wrist_cameras(nX, layout), _boards(nY, layout))
    X = default_X if X.ndim == 0 else (_turned(X, nX) if X.ndim == 2 else X)
    Y = default_Y if Y.ndim == 0 else (_turned(Y, nY) if Y.ndim == 2 else Y)

    rng = np.random.default_rng(seed)
    A_station = random_flange_poses(stations, rng)
    seen = []  # (station, camera, target)
    for s in range(stations):
        for c in range(n_cam):
            size = int(rng.integers(min(lo, n_target), min(hi, n_target) + 1))
            seen += [(s, c, int(t)) for t in np.sort(rng.choice(n_target, size=size, replace=False))]
    unseen = sorted(set(range(n_target)) - {t for _, _, t in seen})
    seen += [(int(rng.integers(stations)), int(rng.integers(n_cam)), t) for t in unseen]
    seen.sort()
    obs = np.array(seen, dtype=np.int64).reshape(-1, 3)
    station, camera, target = obs[:, 0], obs[:, 1], obs[:, 2]
    x_index, y_index = (target, camera) if eye_to_hand else (camera, target)
    noise_rng = np.random.default_rng(rng.integers(2**63))
    gross_rng = np.random.default_rng(rng.integers(2**63))

    noise = noise or NoiseModel()
    A_noisy = noise.apply("A", A_station, noise_rng)
    B = inverse(Y)[y_index] @ A_station[station] @ X[x_index]  # exact: B_i = Y_k^-1 A_i X_j
    factors = _scales(camera_noise, [f"cam{c}" for c in range(n_cam)], "camera_noise") if camera_noise else None
    B = noise.apply("B", B, noise_rng, None if factors is None else
                    np.array([factors.get(f"cam{c}", 1.0) for c in range(n_cam)])[camera])
    m = len(B)
    bad = np.sort(gross_rng.choice(m, size=int(round(gross * m)), replace=False)) if gross > 0 else np.zeros(0, dtype=np.int64)
    if len(bad):
        angle = np.radians(gross_rng.uniform(*GROSS_ROTATION_DEG, size=len(bad)))
        axis = _unit(gross_rng.standard_normal((len(bad), 3)))
        shift = gross_rng.uniform(*GROSS_TRANSLATION, size=len(bad))[:, None] * _unit(gross_rng.standard_normal((len(bad), 3)))
        B[bad, :3, :3] = B[bad, :3, :3] @ so3_exp(angle[:, None] * axis)
        B[bad, :3, 3] += shift
    x_names, y_names = ((f"marker{j}" for j in range(nX)), (f"cam{k}" for k in range(nY))) if eye_to_hand else \
        ((f"cam{j}" for j in range(nX)), (f"target{k}" for k in range(nY)))
    x_names, y_names = list(x_names), list(y_names)
    truth = {"X": np.array(X), "Y": np.array(Y)}
    data = {"A": A_noisy[station], "B": B, "x_index": np.array(x_index), "y_index": np.array(y_index),
            "x_names": x_names, "y_names": y_names}
    if camera_scales:
        names = y_names if eye_to_hand else x_names
        of_camera = y_index if eye_to_hand else x_index
        for name, s in _scales(camera_scales, names).items():
            B[of_camera == names.index(name), :3, 3] /= s
        data["camera_scale"] = list(camera_scales)
        truth["camera_scales"] = {name: float(s) for name, s in camera_scales.items()}
    return SimulatedCell(data, truth, bad, station)


# --------------------------------------------------------------------------- the simulated cell

def _count(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _visible(value: Any) -> tuple[int, int]:
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise InputError(f"visible must be (fewest, most) targets a camera sees at a station, got {value!r}") from None
    lo, hi = _count("visible[0]", lo, 1), _count("visible[1]", hi, 1)
    if lo > hi:
        raise InputError(f"visible must be (fewest, most) with fewest <= most, got {value!r}")
    return lo, hi


def _scales(value: Any, cameras: list[str], option: str = "camera_scales") -> dict[str, float]:
    """`option` (camera_scales, camera_noise) checked: {name of a camera: factor > 0}."""
    if not isinstance(value, Mapping):
        raise InputError(f"{option} must map camera names to factors, e.g. {{'cam0': 0.5}}, got {value!r}")
    for name, s in value.items():
        if name not in cameras:
            raise InputError(f"{option} names {name!r}, which is not a camera of this cell: {', '.join(cameras)}")
        if isinstance(s, bool) or not isinstance(s, (int, float, np.floating, np.integer)) or not 0 < s < math.inf:
            raise InputError(f"{option}[{name!r}] must be a factor > 0, got {s!r}")
    return {name: float(s) for name, s in value.items()}


def _share(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not 0 <= value < 1:
        raise InputError(f"gross must be the share of gross observations, in [0, 1), got {value!r}")
    return float(value)


def _truth_stack(T: Any, name: str, count: int | None, option: str, default: int) -> np.ndarray:
    """T checked: np.array(None) (not given), a 4x4 pose, or a stack of poses (as many as
    `count` when given)."""
    if T is None:
        return np.array(None)
    array = np.asarray(T, dtype=float)
    if array.shape == (4, 4):
        return pose_stack(array[None], name)[0]
    stack = pose_stack(array, name)
    if count is not None and len(stack) != count:
        raise InputError(f"{name} holds {len(stack)} poses but {option}={count}")
    return stack


def _turned(T: np.ndarray, count: int) -> np.ndarray:
    """T turned about the z axis of its parent frame by 2 pi j / count, j = 0 .. count-1."""
    angles = 2.0 * np.pi * np.arange(count) / count
    Rz = so3_exp(np.stack([np.zeros(count), np.zeros(count), angles], axis=1))
    out = np.repeat(T[None], count, axis=0)
    out[:, :3, :] = Rz @ T[:3, :]
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _looking(z: np.ndarray, rng: np.random.Generator, roll: bool = False) -> np.ndarray:
    """Rotations whose z axis is z: (n, 3) (unit), x horizontal (right of the view, y down), turned
    about z by a random angle when `roll`."""
    x = np.cross(z, [0.0, 0.0, 1.0]) + 1e-9 * np.array([1.0, 0.0, 0.0])  # the nudge: z never vertical
    x = _unit(x - np.sum(x * z, axis=1, keepdims=True) * z)  # orthogonal to z again, to rounding
    R = np.stack([x, np.cross(z, x), z], axis=2)
    if roll:
        angle = rng.uniform(-np.pi, np.pi, size=len(z))
        R = R @ so3_exp(np.stack([np.zeros(len(z)), np.zeros(len(z)), angle], axis=1))
    return R


def _fixed_cameras(n: int, rng: np.random.Generator) -> np.ndarray:
    """T_base_cam of n cameras around the workspace (CAMERA_DISTANCE, CAMERA_ELEVATION), spread
    in azimuth, each looking at its centre."""
    azimuth = 2.0 * np.pi * np.arange(n) / n + rng.uniform(-0.3, 0.3, size=n)
    elevation = rng.uniform(*CAMERA_ELEVATION, size=n)
    distance = rng.uniform(*CAMERA_DISTANCE, size=n)
    direction = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                          np.sin(elevation)], axis=1)
    position = WORKSPACE_CENTER + distance[:, None] * direction
    return np.stack([make_pose(R, t) for R, t in zip(_looking(-direction, rng), position)])


def _boards(n: int, rng: np.random.Generator) -> np.ndarray:
    """T_base_target of n boards around the workspace (BOARD_DISTANCE, at or below its centre),
    each facing it."""
    azimuth = 2.0 * np.pi * np.arange(n) / n + rng.uniform(-0.3, 0.3, size=n)
    elevation = rng.uniform(-np.pi / 3, 0.0, size=n)
    distance = rng.uniform(*BOARD_DISTANCE, size=n)
    direction = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                          np.sin(elevation)], axis=1)
    position = WORKSPACE_CENTER + distance[:, None] * direction
    return np.stack([make_pose(R, t) for R, t in zip(_looking(-direction, rng, roll=True), position)])


def _flange_offsets(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points 50-150 mm (FLANGE_OFFSET) from the flange origin, on the tool side (z >= -0.2 of
    their distance)."""
    u = _unit(rng.standard_normal((n, 3)))
    u[:, 2] = np.maximum(u[:, 2], -0.2)
    return _unit(u) * rng.uniform(*FLANGE_OFFSET, size=n)[:, None]


def _markers(n: int, rng: np.random.Generator) -> np.ndarray:
    """T_flange_marker of n markers on the flange, each facing outward (its z along its offset)."""
    t = _flange_offsets(n, rng)
    return np.stack([make_pose(R, p) for R, p in zip(_looking(_unit(t), rng, roll=True), t)])


def _wrist_cameras(n: int, rng: np.random.Generator) -> np.ndarray:
    """T_flange_cam of n cameras on the wrist, looking along the flange's z axis within 30 deg."""
    t = _flange_offsets(n, rng)
    tilt = rng.uniform(0.0, np.radians(30.0), size=n)
    turn = rng.uniform(-np.pi, np.pi, size=n)
    z = np.stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)], axis=1)
    R = random_rotations(n, rng)  # any roll: the x axis from a random rotation, made normal to z
    x = _unit(R[:, :, 0] - np.einsum("ni,ni->n", R[:, :, 0], z)[:, None] * z)
    R = np.stack([x, np.cross(z, x), z], axis=2)
    return np.stack([make_pose(Ri, p) for Ri, p in zip(R, t)])
