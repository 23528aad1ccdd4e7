"""The problem axyb-multi: its `Problem` (validation, observability, residuals, simulator) and its
registration.

A_i X_{x_i} = Y_{y_i} B_i: a cell with several cameras and several targets solved in one go. The
data and their graph are in `handeye.problems.axyb_multi.data`, the least-squares model in
`geometry`, what the observations determine (the rule, its refusals and warnings) in
`observability`; docs/conventions.md ("Several cameras and targets") says what X, Y and B are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.checks.validation import pose_stack
from handeye.estimation.noise import NoiseModel
from handeye.estimation.robust import OUTLIER_CHI2
from handeye.estimation.whitening import estimate_sigmas
from handeye.framework.errors import InputError
from handeye.framework.problem import (
    BenchSettings,
    BenchTarget,
    ErrorTable,
    Frame,
    Problem,
    pose_discrepancy,
)
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import (
    inverse,
    make_pose,
    random_rotations,
    rotation_angle,
    so3_exp,
)
from handeye.problems.axyb_multi import observability
from handeye.problems.axyb_multi.data import AXYBMultiData, validated

SETUPS = ("eye-in-hand", "eye-to-hand")
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


class AXYBMulti(Problem):
    """A_i X_{x_i} = Y_{y_i} B_i: several cameras and several targets of one robot cell."""

    name = "axyb-multi"
    summary = "a cell of several cameras and targets, A_i X_{x_i} = Y_{y_i} B_i (stacks of X's and Y's)"
    unknowns = ("X", "Y")
    data_fields = ("A", "B")
    #: x_index and y_index are required (`validate` says so when missing); the host passes only the
    #: data fields and the optional fields given, hence their place here
    optional_fields = ("x_index", "y_index", "x_names", "y_names", "camera_scale")
    #: observations in all: one pair needs three stations; what the graph needs is `validate`'s rule
    min_pairs = 3
    data_type = AXYBMultiData
    equation = "A_i X_{x_i} = Y_{y_i} B_i"
    item = "observation"
    setups = SETUPS
    starts = ("so3-sdp", "kron-lstsq")
    certifiable_starts = ("so3-sdp",)
    quick_solver = "kron-lstsq"
    #: no station reader (a cell's file of stations holds one camera): no setup mistakes to try
    mistakes = ()
    #: the robot (A) ten times less noisy than the cameras (B), rad and mm, as for axyb
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}
    #: pairs are stations: 83 stations of the default cell (8 cameras, 16 markers, 3-6 seen per
    #: camera) make ~3000 observations of 24 unknowns, where auto should take at most 2 s
    bench = BenchSettings(pairs=(5, 20, 83), targets=(BenchTarget("auto", 83, seconds=2.0),),
                          data_note="the simulated cell of axyb-multi (8 fixed cameras, 16 flange markers), seed "
                                    "{seed}, noise {rot} rad / {trans} mm on the camera poses B")

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """Eye-to-hand (fixed cameras watching markers on the flange): X_j = T_flange_marker,
        Y_k = T_base_cam; eye-in-hand (cameras on the wrist watching boards in the cell):
        X_j = T_flange_cam, Y_k = T_base_target (docs/conventions.md)."""
        if setup == "eye-to-hand":
            return {"X": Frame("flange", "marker", "the markers on the flange, one pose per marker"),
                    "Y": Frame("base", "cam", "the fixed cameras in the robot base frame, one pose per camera")}
        if setup == "eye-in-hand":
            return {"X": Frame("flange", "cam", "the cameras on the wrist, one pose per camera"),
                    "Y": Frame("base", "target", "the boards in the robot base frame, one pose per board")}
        return {}

    def stack_sizes(self, data: AXYBMultiData) -> Mapping[str, int]:
        return {"X": data.nX, "Y": data.nY}

    def from_observations(self, observations: Any, setup: str) -> Any:
        """A cell's table of observations as these data (`cell_files.from_observations`)."""
        from handeye.problems.axyb_multi import cell_files

        return cell_files.from_observations(observations, setup)

    def validate(self, **data: Any) -> AXYBMultiData:
        """The validated data (`data.validated`: the stacks, the indices, the names), refused when
        a component of the observation graph cannot determine its X's and Y's
        (`observability.check_determined`: one station, rotations about one axis, motions within
        the noise), naming them and what to record."""
        out = validated(self.name, data, self.min_pairs)
        observability.check_determined(out)
        return out

    def diagnose(self, data: AXYBMultiData) -> dict[str, Any]:
        """Observations, stations, per component and per unknown the figures of `observability`,
        and its warnings (separate components solved separately, weakly determined ones,
        unknowns resting on one observation)."""
        components, unknowns = data.observability
        return {"pairs": data.m, "observations": data.m, "stations": data.station_count,
                "components": components, "unknowns": unknowns,
                "warnings": observability.warnings(data, components, unknowns)}

    def residuals(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per observation: rotation angle of (A_i X_j)(Y_k B_i)^-1 and |t(A_i X_j) - t(Y_k B_i)|."""
        X, Y = _stacks(unknowns)
        return pose_discrepancy(data.A @ X[data.x_index], Y[data.y_index] @ data.B)

    def residual_table(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """Per observed (X, Y) pair (`AXYBMultiData.pair_index`): the names, the observations, the
        RMS and largest rotation (deg) and translation residuals, and the observation of the largest."""
        res = self.residuals(data, unknowns)
        rot, trans = np.degrees(res["rotation"]), res["translation"]
        pairs, of = data.pair_index
        rows = []
        for p, (j, k) in enumerate(pairs.tolist()):
            obs = np.flatnonzero(of == p)
            worst = obs[np.argmax(rot[obs] / max(float(np.median(rot)), 1e-300)
                                  + trans[obs] / max(float(np.median(trans)), 1e-300))]
            rows.append({"X": data.x_names[j], "Y": data.y_names[k], "x": j, "y": k, "observations": int(len(obs)),
                         "rotation_rms_deg": float(np.sqrt(np.mean(rot[obs] ** 2))),
                         "translation_rms": float(np.sqrt(np.mean(trans[obs] ** 2))),
                         "rotation_max_deg": float(rot[obs].max()), "translation_max": float(trans[obs].max()),
                         "worst": int(worst)})
        return rows

    def outliers(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """The observations far off the others at these unknowns (whitened by median-based scales
        beyond OUTLIER_CHI2, as the host's self-check and auto find them), each named by its index,
        station and (X, Y) pair, with its residuals (deg, data units); worst first."""
        e = data.pose_model.residuals(_stacks_flat(unknowns))
        ew = estimate_sigmas(e, data.translation_scale, robust=True).residual(e)
        s = np.einsum("ni,ni->n", ew, ew)
        far = np.flatnonzero(s > OUTLIER_CHI2)
        station = data.station_index
        return [{"index": int(i), "station": int(station[i]), "X": data.x_names[data.x_index[i]],
                 "Y": data.y_names[data.y_index[i]], "rotation_deg": float(np.degrees(np.linalg.norm(e[i, :3]))),
                 "translation": float(np.linalg.norm(e[i, 3:])), "whitened": float(math.sqrt(s[i]))}
                for i in far[np.argsort(-s[far])]]

    def errors(self, unknowns: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray]) -> ErrorTable:
        """Per unknown the worst of its poses' errors (`handeye.problem.pose_errors`); pose by pose
        in `errors_per_pose`."""
        return super().errors(unknowns, truth)

    def check_model(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]]:
        from handeye.problems.axyb_multi import geometry

        return geometry.check_model(data, unknowns)

    def expected_rotation_residual(self, data: AXYBMultiData) -> float | None:
        from handeye.problems.axyb_multi import geometry

        return geometry.expected_rotation_residual(data)

    def rotation_axes(self, data: AXYBMultiData) -> dict[str, np.ndarray]:
        from handeye.problems.axyb_multi import geometry

        return geometry.rotation_axes(data)

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None, setup: str = "eye-to-hand",
                 cameras: int | None = None, markers: int | None = None, visible: tuple[int, int] | None = None,
                 gross: float = 0.0, camera_scales: Mapping[str, float] | None = None,
                 **options: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """A simulated cell (`simulate_cell`): `pairs` stations of the robot, each camera seeing
        some of the targets at each; data A, B, x_index, y_index, x_names, y_names (and
        camera_scale with `camera_scales`), truth {"X": (nX, 4, 4), "Y": (nY, 4, 4)} (and
        "camera_scales")."""
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, setup, "
                             "cameras, markers, visible, gross, camera_scales")
        cell = simulate_cell(pairs, seed=seed, noise=noise, X=X, Y=Y, setup=setup, cameras=cameras, markers=markers,
                             visible=visible, gross=gross, camera_scales=camera_scales)
        return cell.data, cell.truth


class SimulatedCell:
    """What `simulate_cell` made: data (the fields of `AXYBMulti.validate`), truth, and which
    observations are gross (`gross`: indices into the observations) and which station each is."""

    def __init__(self, data: dict[str, Any], truth: dict[str, np.ndarray], gross: np.ndarray, station: np.ndarray) -> None:
        self.data, self.truth, self.gross, self.station = data, truth, gross, station


def simulate_cell(stations: int, *, seed: int | None = None, noise: NoiseModel | None = None,
                  X: np.ndarray | None = None, Y: np.ndarray | None = None, setup: str = "eye-to-hand",
                  cameras: int | None = None, markers: int | None = None, visible: tuple[int, int] | None = None,
                  gross: float = 0.0, camera_scales: Mapping[str, float] | None = None) -> SimulatedCell:
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
    B = noise.apply("B", B, noise_rng)
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


def _scales(value: Any, cameras: list[str]) -> dict[str, float]:
    """camera_scales checked: {name of a camera: factor > 0}."""
    if not isinstance(value, Mapping):
        raise InputError(f"camera_scales must map camera names to factors, e.g. {{'cam0': 0.5}}, got {value!r}")
    for name, s in value.items():
        if name not in cameras:
            raise InputError(f"camera_scales names {name!r}, which is not a camera of this cell: {', '.join(cameras)}")
        if isinstance(s, bool) or not isinstance(s, (int, float, np.floating, np.integer)) or not 0 < s < math.inf:
            raise InputError(f"camera_scales[{name!r}] must be a factor > 0, got {s!r}")
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
    x = _unit(np.cross(z, [0.0, 0.0, 1.0]) + 1e-9 * np.array([1.0, 0.0, 0.0]))
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


def _stacks(unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    return (np.asarray(unknowns["X"], dtype=float).reshape(-1, 4, 4),
            np.asarray(unknowns["Y"], dtype=float).reshape(-1, 4, 4))


def _stacks_flat(unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    X, Y = _stacks(unknowns)
    return tuple(X) + tuple(Y)


def errors_per_pose(unknowns: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Each pose's errors against the truth, keyed X[0], ..., Y[nY-1]: rotation angle of
    R_cal R_true^T (rad) and translation distance (data units)."""
    out = {}
    for name in ("X", "Y"):
        cal = np.asarray(unknowns[name], dtype=float).reshape(-1, 4, 4)
        true = np.asarray(truth[name], dtype=float).reshape(-1, 4, 4)
        if cal.shape != true.shape:
            raise ValueError(f"unknown {name} has shape {cal.shape}, its truth {true.shape}")
        rot = rotation_angle(cal[:, :3, :3] @ np.swapaxes(true[:, :3, :3], 1, 2))
        trans = np.linalg.norm(cal[:, :3, 3] - true[:, :3, 3], axis=1)
        out.update({f"{name}[{j}]": {"rotation": float(rot[j]), "translation": float(trans[j])} for j in range(len(cal))})
    return out


PROBLEM = AXYBMulti()


@hookimpl
def register_problems(register):
    register(PROBLEM)
