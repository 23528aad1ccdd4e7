"""`plan`: which stations to record for a hand-eye calibration, and how sure the answer will be.

Given the setup, a rough X and Y (CAD, or a first answer), the camera (intrinsics with its image
size) and the board, where the flange may go (`Workspace`) and what makes a view usable
(`ViewLimits`), it draws candidate stations (`stations.candidates`), asks the problem what each
would tell at the expected noise (`Problem.station_information`: pixel noise on the board's
corners through PnP, `views.pose_covariance`, and the robot's own) and picks the `count` that
make the maximum-likelihood answer sharpest (`design.greedy`, D-optimal). Stations already
recorded (`recorded`, their robot and camera poses) count as given: the plan is then the next
`count` that add the most. The predicted 1-sigma of each unknown is that of the fit of recorded
plus planned stations at the stated noise.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.validation import pose_stack
from handeye.host.registry import get_registry
from handeye.planning import design, route, stations, views
from handeye.planning.reach import Reach
from handeye.planning.stations import Workspace
from handeye.planning.views import ViewLimits
from handeye.vision.boards import UNITS, Board
from handeye.vision.observations import SETUPS, Camera

#: candidate stations drawn per plan
POOL = 3000
#: the robot's pose noise per axis a plan expects by default: rad, mm. Not a repeatability
#: spec (0.02-0.05 mm): what real arms show in hand-eye recordings, where their systematic errors
#: act as noise on each station. Chosen so that the plan's prediction for the stations of real
#: recordings matches the 1-sigma their calibration states (which split halves confirm): X's
#: translation 0.98 / 0.96 / 0.86 mm predicted against 0.97 / 0.92 / 0.48 mm on two real KUKA
#: cells and industrial_calibration's ChArUco cell (0.07, 0.03, 0.07 mm at the former 0.0002 rad /
#: 0.05 mm: 10-27x too optimistic); rotation 0.051 / 0.087 / 0.090 deg against 0.037 / 0.17 / 0.115
ROBOT_NOISE = (0.003, 1.5)
#: how far the rough X and Y may be off by default: rotation (deg), translation (share of the
#: farthest viewing distance)
ROUGH_DEG = 1.0
ROUGH_SHARE = 0.01


#: the largest pixel noise a plan takes (a board's corners found to 100 px are no detection)
MAX_PIXEL_NOISE = 100.0


@dataclasses.dataclass(frozen=True)
class Noise:
    """The noise a plan expects: pixel noise of the board's corners (px per coordinate) and the
    robot's pose noise per axis (rotation rad, translation in the data's length unit; None: the
    default `ROBOT_NOISE` in the board's unit)."""

    pixel: float = 0.3
    robot: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not 0 < self.pixel <= MAX_PIXEL_NOISE or (self.robot is not None and not (
                min(self.robot) >= 0 and all(math.isfinite(v) for v in self.robot))):
            raise InputError(f"the expected pixel noise must be above 0 and at most {MAX_PIXEL_NOISE:g} px, the robot's "
                             f"finite and not negative, got {self}")

    def robot_sigma(self, unit: str) -> tuple[float, float]:
        """The robot's noise (rad, length in `unit`): as given, else ROBOT_NOISE (0.003 rad,
        1.5 mm per axis, what real arms show in hand-eye recordings) in `unit`."""
        if self.robot is not None:
            return float(self.robot[0]), float(self.robot[1])
        return ROBOT_NOISE[0], ROBOT_NOISE[1] * {"mm": 1.0, "m": 1e-3}[unit]


@dataclasses.dataclass(frozen=True)
class Plan:
    """Planned stations: A (n, 4, 4) the robot's flange poses T_base_flange to drive to, in
    order; B (n, 4, 4) the camera poses they should give (A X = Y B's convention); views (n, 4,
    4) T_cam_target; std: the predicted 1-sigma of each unknown of interest after recorded and
    planned stations (rotation_deg, translation in the data's unit), and progression: the same
    after each planned station in turn (1-sigma of inf while the stations cannot determine it);
    recorded: how many stations were given as recorded; information: the predicted Fisher
    information of the unknowns `names` after them all (`covariance`); joints: (n, joints) rad
    the arm's joints at each station when planned with its model (`reach`), else None."""

    problem: str
    setup: str
    A: np.ndarray
    B: np.ndarray
    views: np.ndarray
    std: dict[str, dict[str, float]]
    progression: tuple[dict[str, dict[str, float]], ...]
    recorded: int
    noise: Noise
    robot_sigma: tuple[float, float]
    information: np.ndarray
    names: tuple[str, ...]
    joints: np.ndarray | None = None

    def covariance(self) -> np.ndarray:
        """The predicted covariance (6k, 6k) of the unknowns `names` after recorded and planned
        stations, their parameters (omega, v) in each unknown's own frame (right perturbation)."""
        return np.linalg.inv(self.information)

    def to_dict(self) -> dict[str, Any]:
        return {"problem": self.problem, "setup": self.setup, "stations": self.A.tolist(),
                "camera_poses": self.B.tolist(), "predicted_std": self.std, "progression": list(self.progression),
                "recorded": self.recorded, "noise": {"pixel": self.noise.pixel, "robot": self.robot_sigma},
                "joints_rad": None if self.joints is None else self.joints.tolist()}

    def write_joints(self, path: str | Path, joint_names: tuple[str, ...], unit: str = "deg") -> Path:
        """The stations' joint values (planned with an arm, `reach`), named station01, ..."""
        from handeye.io.joint_files import write_joints

        if self.joints is None:
            raise InputError("this plan has no joint values: plan with the arm's model and joint limits (reach=)")
        names = tuple(f"station{i + 1:02d}" for i in range(len(self.A)))
        return write_joints(path, self.joints, joint_names, unit=unit, names=names, force=True)

    def write(self, path: str | Path, format: str, unit: str) -> Path:
        """The stations in a robot's pose format (`handeye.io.pose_formats`, e.g. "kuka-abc",
        "ur-rotvec"), named station01, ... in the order to drive them."""
        from handeye.io.pose_readers import PoseStack
        from handeye.io.pose_writers import write_poses

        names = tuple(f"station{i + 1:02d}" for i in range(len(self.A)))
        return write_poses(path, PoseStack(self.A, unit=unit, format=format, names=names), format)


def plan(problem: str | None = None, *, setup: str, X: np.ndarray, Y: np.ndarray, camera: Camera, board: Board,
         count: int, workspace: Workspace | None = None, limits: ViewLimits | None = None, noise: Noise | None = None,
         recorded: tuple[np.ndarray, np.ndarray] | None = None, rough: tuple[float, float] | None = None,
         reach: Reach | None = None, pool: int = POOL, seed: int = 0) -> Plan:
    """Plan `count` stations (module docstring) for `problem` (default: the problem of a cell's
    stations, A X = Y B; one whose unknowns are fewer plans for those). X, Y: rough poses as A X = Y B takes them
    (docs/conventions.md); board in the data's length unit (`board.unit`); limits default to
    0.5-2x the distance at which the board fills half the image's width, at most 45 deg off its
    normal; recorded: (A, B) of stations already recorded; rough: how far X and Y may be off
    (deg, length; default 1 deg and 1% of the farthest viewing distance): the planned views keep
    the board that far inside the image (`views.tightened`), so the real ones show all of it;
    reach: the arm's model and joint limits (`reach.Reach`): only stations it reaches are planned,
    and `Plan.joints` holds their joints."""
    if setup not in SETUPS:
        raise InputError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
    if count < 1:
        raise InputError(f"the number of stations to plan must be at least 1, got {count}")
    registry = get_registry()
    problem = problem or registry.cell_problem()
    spec = registry.problem(problem)
    X, Y = (_pose(T, name) for T, name in ((X, "X"), (Y, "Y")))
    _check_reach(X, Y, board.unit)
    noise = noise or Noise()
    limits = limits or default_limits(board, camera)
    rough_deg, rough_length = rough if rough is not None else (ROUGH_DEG, ROUGH_SHARE * limits.distance[1])
    planned_limits = views.tightened(limits, np.radians(rough_deg), rough_length)
    rng = np.random.default_rng(seed)
    A, seen = stations.candidates(board, camera, X, Y, setup, planned_limits, workspace, pool, rng)
    info, names, interest = _information(spec, problem, A, stations.camera_poses(seen, setup), seen, board, camera,
                                         setup, X, Y, noise)
    mask = np.array([n in interest for n in names for _ in range(6)])
    prior = None
    if recorded is not None:
        A0, B0 = (np.asarray(P, dtype=float) for P in recorded)
        new = ~_near(A, A0, np.radians(rough_deg), rough_length)  # a station again adds no new geometry
        A, seen, info = A[new], seen[new], info[new]
        prior = _information(spec, problem, A0, B0, views.views_of(B0, setup), board, camera, setup, X, Y, noise)[0].sum(0)
    if len(A) < count:  # fewer usable stations than asked: said before the design would take them all
        raise stations.PlanningError(f"only {len(A)} usable stations were found for the {count} asked (views of the "
                                     "board within the viewing distance and angle, the flange in the workspace"
                                     + (", not already recorded" if recorded is not None else "") + "); plan fewer "
                                     "stations, or widen the workspace or the viewing limits")
    admissible = None if reach is None else (lambda i: reach.joints_for(A[i], key=i) is not None)
    chosen = design.greedy(info, count, prior=prior, interest=mask, admissible=admissible)
    if len(chosen) < count:
        raise stations.PlanningError(f"the arm reaches only {len(chosen)} of the usable stations within its joint "
                                     "limits; widen the limits or the workspace, or plan fewer stations")
    # driven in the order that keeps the flange's motion short (what they tell together is the same)
    chosen = np.asarray(chosen)[route.driving_order(A[chosen], route.LEVER_MM * UNITS["mm"] / UNITS[board.unit])]
    base = np.zeros(info.shape[1:]) if prior is None else prior
    totals = base + np.cumsum(info[chosen], axis=0)
    progression = tuple(_std(T, names, interest) for T in totals)
    return Plan(problem, setup, A[chosen], stations.camera_poses(seen[chosen], setup), seen[chosen], progression[-1],
                progression, 0 if recorded is None else len(recorded[0]), noise, noise.robot_sigma(board.unit), totals[-1],
                names, None if reach is None else np.array([reach.solved[i] for i in chosen]))


def default_limits(board: Board, camera: Camera) -> ViewLimits:
    """Views from half to twice the distance at which the board's width fills half the image's."""
    if camera.size is None:
        raise InputError("planning needs the camera's image size (width, height) in pixels with its intrinsics")
    x0, _, x1, _ = board.extent()
    fill = camera.K[0, 0] * (x1 - x0) / (0.5 * camera.size[0])
    return ViewLimits(distance=(0.5 * fill, 2.0 * fill))


def _information(spec: Any, problem: str, A: np.ndarray, B: np.ndarray, seen: np.ndarray, board: Board, camera: Camera,
                 setup: str, X: np.ndarray, Y: np.ndarray, noise: Noise) -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]]:
    cov = views.pose_covariance(board, camera, seen, noise.pixel)
    if setup == "eye-in-hand":  # B = T_target_cam: the covariance in the camera's frame
        cov = views.target_to_camera_frame(seen, cov)
    out = spec.station_information(A, B, {"X": X, "Y": Y}, noise.robot_sigma(board.unit), cov, setup)
    if out is None:
        raise InputError(f"problem {problem!r} cannot plan stations yet (problems that can: {', '.join(planners())})")
    return out


def planners() -> list[str]:
    """The registered problems that can plan stations (their planning part: `PlanningPart.plans`)."""
    return [name for name, p in get_registry().problems.items() if p.plans]


def _std(information: np.ndarray, names: tuple[str, ...], interest: tuple[str, ...]) -> dict[str, dict[str, float]]:
    """`design.predicted_std` of the unknowns of interest, inf while the information is singular."""
    if np.linalg.matrix_rank(information, tol=1e-9 * np.max(np.abs(np.diag(information)))) < len(information):
        return {n: {"rotation_deg": float("inf"), "translation": float("inf")} for n in interest}
    std = design.predicted_std(information, names)
    return {n: std[n] for n in interest}


def _near(A: np.ndarray, recorded: np.ndarray, angle: float, length: float) -> np.ndarray:
    """(n,) whether each pose of A lies within `angle` (rad) and `length` of a recorded one."""
    near = np.zeros(len(A), dtype=bool)
    for T in recorded:
        cos = (np.einsum("nij,ij->n", A[:, :3, :3], T[:3, :3]) - 1.0) / 2.0
        near |= (cos > np.cos(angle)) & (np.linalg.norm(A[:, :3, 3] - T[:3, 3], axis=1) < length)
    return near


#: farthest a rough X (from the flange) and Y (from the base) can be, metres: beyond, they are in
#: another length unit than the board
MAX_X_METRES, MAX_Y_METRES = 3.0, 20.0


def _check_reach(X: np.ndarray, Y: np.ndarray, unit: str) -> None:
    """InputError when X or Y lies farther than any cell puts them (MAX_X_METRES, MAX_Y_METRES)."""
    metres = {"mm": 1e-3, "m": 1.0}[unit]
    for name, T, limit in (("X", X, MAX_X_METRES), ("Y", Y, MAX_Y_METRES)):
        distance = float(np.linalg.norm(T[:3, 3])) * metres
        if distance > limit:
            raise InputError(f"the rough {name} is {distance:.3g} m from its parent frame (lengths read in {unit}, the "
                             f"board's unit); no cell is that large: give X, Y and the board in one length unit")


def _pose(T: Any, name: str) -> np.ndarray:
    return pose_stack(np.asarray(T, dtype=float)[None], name)[0]
