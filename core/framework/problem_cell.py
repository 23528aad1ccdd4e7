"""The cell's part of the problem contract (`CellPart`): how a cell's recordings become the
problem's data (a file of stations: `StationReader`; a table of several cameras and targets:
`Observations` -> `ObservationData`; joint readings: `JointStations`), what its unknowns are in
the cell (`Frame`, `Published`) for printouts, exports and the report, its residuals per pair
of unknowns, and which setup mistakes the plausibility check may try (`MISTAKES`). Optional: a
problem without it is solved from its data fields (``handeye.solve``, ``handeye solve FILE``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from handeye.framework.problem_engine import NamedPoses


@dataclasses.dataclass(frozen=True)
class Frame:
    """What an unknown is in a cell: the pose of frame `child` in frame `parent`, T_parent_child
    (e.g. ``Frame("flange", "cam", "camera in the flange frame")``: X = T_flange_cam)."""

    parent: str
    child: str
    meaning: str

    @property
    def symbol(self) -> str:
        return f"T_{self.parent}_{self.child}"


@dataclasses.dataclass(frozen=True)
class Published:
    """The unknown a cell's exports publish (the camera's pose: a ROS static transform, a URDF
    joint) and the frame ids they give it by default (the user may rename them)."""

    unknown: str
    parent: str
    child: str


@dataclasses.dataclass(frozen=True)
class StationReader:
    """How a problem's data are made from the absolute poses a cell records, one robot pose
    (T_base_flange) and one camera pose (T_cam_target, as solvePnP gives it) per station, so that
    one file of stations serves every problem that declares a reader (`handeye.io`).

    convert: ``convert(robot_poses, camera_poses, setup=..., pairing=...) -> data fields``
        (``pairing`` is None for a problem whose data are not motions).
    pairing: whether the problem forms motions between stations (then a pairing applies).
    cell_truth: setup -> {unknown of the problem: the unknown X or Y of AX=YB it is}, so that a
        file of stations carrying the cell's truth (AX=YB's X and Y) gives this problem's truth.
    """

    convert: Callable[..., dict[str, np.ndarray]]
    pairing: bool = False
    cell_truth: Mapping[str, Mapping[str, str]] | None = None


@dataclasses.dataclass(frozen=True)
class Observations:
    """A cell's observations as recorded, one row per (station, camera, target): which camera
    saw which target at which station, the robot's pose there and the camera's pose of the
    target, so that a problem of several cameras and targets makes its data from them
    (`Problem.from_observations`).

    station, camera, target: (m,) names (text); robot: (m, 4, 4) T_base_flange of each row's
    station; camera_poses: (m, 4, 4) T_cam_target, the target's pose in the camera frame as
    ``cv2.solvePnP`` gives it, in the robot's length unit.
    """

    station: tuple[str, ...]
    camera: tuple[str, ...]
    target: tuple[str, ...]
    robot: np.ndarray
    camera_poses: np.ndarray

    def __len__(self) -> int:
        return len(self.station)


@dataclasses.dataclass(frozen=True)
class ObservationData:
    """What `Problem.from_observations` makes: `fields`, the keyword arguments of
    `handeye.solve` for the problem (its data fields and optional fields), and `names`, per
    stacked unknown the user's name of each of its poses (e.g. ``{"Y": ("cam0", "cam1")}``), so
    that printouts and exports name the poses as the cell does."""

    fields: Mapping[str, Any]
    names: Mapping[str, tuple[str, ...]]


@dataclasses.dataclass(frozen=True)
class JointStations:
    """A cell's stations with the robot's joint readings, so that a problem of the arm's
    kinematics makes its data from them (`Problem.from_joints`).

    robot: (m, 4, 4) T_base_flange, the nominal forward kinematics of `q` (as the controller
    reports it); camera_poses: (m, 4, 4) T_cam_target as ``cv2.solvePnP`` gives it, in the arm's
    length unit; q: (m, n) joint readings, rad, in the order of `dh`; dh: (n, 4) the arm's nominal
    standard DH table, columns a, alpha, d, offset (lengths in the arm's unit, angles in rad).
    """

    robot: np.ndarray
    camera_poses: np.ndarray
    q: np.ndarray
    dh: np.ndarray

    def __len__(self) -> int:
        return len(self.q)


#: the setup mistakes `handeye.workflow.plausibility` knows how to undo and try (`Problem.mistakes`)
MISTAKES = ("camera-inverted", "robot-inverted", "other-setup", "shifted", "camera-unit", "euler")


class CellPart:
    """What calibrating a cell (`handeye.workflow`), its exports and the plausibility check
    (`handeye.workflow.plausibility`) ask of a problem."""

    #: how the data are made from a cell's absolute poses, or None when they cannot be
    station_reader: ClassVar[StationReader | None] = None
    #: a fast closed-form solver for the plausibility check's many fits (None: the first start)
    quick_solver: ClassVar[str | None] = None
    #: the setup mistakes of `MISTAKES` the plausibility check may try on this problem's stations
    mistakes: ClassVar[tuple[str, ...]] = MISTAKES

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """Per unknown, what it is in a cell of `setup` (one of `setups`); empty when the problem
        does not say (the printout then names the unknowns only)."""
        return {}

    def published(self, setup: str | None = None) -> Published | None:
        """The unknown a cell's exports publish with its default frame ids, or None (nothing to
        publish: the answer is exported as the unknowns)."""
        return None

    def from_observations(self, observations: Observations, setup: str) -> ObservationData | None:
        """The problem's data made from a cell's table of observations (several cameras and
        targets) in `setup`, with the names of its stacked unknowns' poses; None (the default):
        the problem is not made from such a table. Raises `InputError` naming what is wrong."""
        return None

    @property
    def reads_observations(self) -> bool:
        """Whether the problem is made from a table of observations (`from_observations`)."""
        return type(self).from_observations is not CellPart.from_observations

    def from_joints(self, stations: JointStations, setup: str) -> dict[str, Any] | None:
        """The problem's data (the keyword arguments of `handeye.solve`) made from a cell's
        stations with the robot's joint readings and nominal DH table (`JointStations`) in
        `setup`; None (the default): the problem is not made from joint readings."""
        return None

    @property
    def reads_joints(self) -> bool:
        """Whether the problem is made from joint readings (`from_joints`)."""
        return type(self).from_joints is not CellPart.from_joints

    def residual_table(self, data: Any, unknowns: NamedPoses) -> list[dict[str, Any]]:
        """Residuals per pair of poses the observations tie (e.g. one camera and one marker): rows
        naming the poses by unknown (``{"X": "marker0", "Y": "cam1", "observations": 12,
        "rotation_rms_deg": ..., "translation_rms": ..., "rotation_max_deg": ...,
        "translation_max": ...}``), for the report's table and graph; empty (the default): the
        problem has no such pairs."""
        return []
