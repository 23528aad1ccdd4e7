"""The contract every calibration problem plugin fulfils (AX=YB, AX=XB, AXB=YCZ, ...).

A problem knows its data fields and unknowns, validates raw input into an immutable data object,
computes per-pair residuals and errors against a known truth, and simulates data with a truth.
Solvers receive the validated data object, never raw user input.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from handeye.geometry.se3 import make_pose, random_rotations, rotation_angle

Poses = Mapping[str, np.ndarray]
#: errors per unknown: {"X": {"rotation": rad, "translation": data units}, ...}
ErrorTable = dict[str, dict[str, float]]


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


class Problem(ABC):
    """Base class of problem plugins.  Subclasses set the class variables and methods below."""

    name: ClassVar[str]
    summary: ClassVar[str]
    #: names of the unknown poses, e.g. ("X", "Y")
    unknowns: ClassVar[tuple[str, ...]]
    #: names of the data stacks, e.g. ("A", "B"), each (m, 4, 4)
    data_fields: ClassVar[tuple[str, ...]]
    min_pairs: ClassVar[int]
    #: facts about the cell the data may carry besides the stacks, passed to `validate` when given
    #: (e.g. ``tz_X``, the translation a planar robot's motions cannot determine)
    optional_fields: ClassVar[tuple[str, ...]] = ()
    #: how the data are made from a cell's absolute poses, or None when they cannot be
    station_reader: ClassVar[StationReader | None] = None

    @abstractmethod
    def validate(self, **data: Any) -> Any:
        """Check raw data and return an immutable, validated data object (float64 copies).

        Raises `InputError` / `DegenerateDataError` naming what is wrong.
        """

    @abstractmethod
    def residuals(self, data: Any, unknowns: Poses) -> dict[str, np.ndarray]:
        """Per-pair residuals of the problem's equation: {"rotation": (m,), "translation": (m,)}."""

    def errors(self, unknowns: Poses, truth: Poses) -> ErrorTable:
        """Errors of estimated unknowns against the truth: for each unknown the angle of
        R_cal R_true^-1 (the paper's eq. 30) and |t_cal - t_true| (eq. 31)."""
        return pose_errors(unknowns, truth, self.unknowns)

    @abstractmethod
    def simulate(self, *, pairs: int, seed: int | None = None, **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Simulated data and the truth it was made from: (data fields, unknowns)."""

    def diagnose(self, data: Any) -> dict[str, Any]:
        """Figures describing how well the data determine the unknowns, and ``warnings``."""
        return {"warnings": []}

    def check_model(self, data: Any, unknowns: Poses) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]] | None:
        """For the host's self-check (`handeye.self_check`): a least-squares model of the data
        (`handeye.nlls.PoseModel`), the poses to start it from (the answer's, with any nuisance
        unknown of the model fitted to it) and the names among the model's unknowns that are
        the answer's; None: the problem offers no such check."""
        return None

    def expected_rotation_residual(self, data: Any) -> float | None:
        """The median rotation residual (rad, of `residuals`) a correct answer leaves at the
        noise these data show, measured without the unknowns (e.g. from the rotation angles of
        paired motions, which must agree); None when the data cannot tell."""
        return None

    def rotation_axes(self, data: Any) -> dict[str, np.ndarray]:
        """Per unknown, the robot's main rotation axis (unit) in the frame the unknown is
        expressed in, for naming a poorly determined direction; empty when not known."""
        return {}

    def random_unknowns(self, rng: np.random.Generator, translation_scale: float = 500.0) -> dict[str, np.ndarray]:
        """Random unknowns for tests and studies: uniform rotations, translations
        N(0, translation_scale^2) per axis (data units), one pose per name in `unknowns`."""
        R = random_rotations(len(self.unknowns), rng)
        t = translation_scale * rng.standard_normal((len(self.unknowns), 3))
        return {name: make_pose(R[k], t[k]) for k, name in enumerate(self.unknowns)}


def pose_discrepancy(P: np.ndarray, Q: np.ndarray) -> dict[str, np.ndarray]:
    """How far the poses P_i are from Q_i, both (m, 4, 4): {"rotation": angle of R_P R_Q^T (rad),
    "translation": |t_P - t_Q|}, each (m,). The per-pair residuals of every problem are this for
    the two sides of its equation (e.g. eqs. 32-33 for A_i X = Y B_i)."""
    return {
        "rotation": rotation_angle(P[:, :3, :3] @ np.swapaxes(Q[:, :3, :3], 1, 2)),
        "translation": np.linalg.norm(P[:, :3, 3] - Q[:, :3, 3], axis=1),
    }


def pose_errors(unknowns: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray],
                names: tuple[str, ...]) -> ErrorTable:
    """Rotation angle of R_cal R_true^T and translation distance for each named unknown."""
    table: ErrorTable = {}
    for name in names:
        cal, true = np.asarray(unknowns[name], dtype=float), np.asarray(truth[name], dtype=float)
        table[name] = {
            "rotation": float(rotation_angle(cal[:3, :3] @ true[:3, :3].T)),
            "translation": float(np.linalg.norm(cal[:3, 3] - true[:3, 3])),
        }
    return table
