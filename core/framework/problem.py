"""The contract every calibration problem plugin fulfils (AX=YB, AX=XB, AXB=YCZ, ...).

The required core (`Problem`): a problem knows its data fields and unknowns, validates raw input
into an immutable data object, computes per-pair residuals and errors against a known truth,
and simulates data with a truth. Solvers receive the validated data object, never raw user input.

Optional parts, each in its own module with defaults that switch the shared tool off, tell the
shared machinery what else the problem offers, so that a problem added as a plugin gets every
shared tool with no edit to handeye (docs/plugins.md, "A problem plugin"):

- `handeye.framework.problem_engine`: the engine's least-squares model (`EnginePart.pose_model`),
  with which ``refine`` and ``auto`` serve the problem from its `EnginePart.starts`; the
  self-check's model, the noise it expects and the robot's pose at each row (`SelfCheckPart`);
- `handeye.framework.problem_cell`: how a cell's recordings become its data (a file of
  stations, a table of observations, joint readings), what its unknowns are in the cell (frames,
  exports) and the setup mistakes the plausibility check may try (`CellPart`);
- `handeye.framework.problem_planning`: the information a planned station gives (`PlanningPart`);
- `handeye.framework.problem_studies`: the settings of studies and benchmarks (`StudyPart`).

Unknowns that are stacks of poses (`Problem.stack_sizes`) are checked by the host pose by pose.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from handeye.base.moved import moved_names
from handeye.framework.problem_cell import CellPart
from handeye.framework.problem_engine import EnginePart, NamedPoses, SelfCheckPart
from handeye.framework.problem_planning import PlanningPart
from handeye.framework.problem_studies import StudyPart
from handeye.geometry.se3 import make_pose, random_rotations, rotation_angle

#: names that moved to the modules of the contract's optional parts (`handeye.base.moved`)
__getattr__ = moved_names(__name__, {
    **dict.fromkeys(("BenchRow", "BenchTarget", "BenchSettings"), "handeye.framework.problem_studies"),
    **dict.fromkeys(("Frame", "Published", "StationReader", "Observations", "ObservationData", "JointStations",
                     "MISTAKES"), "handeye.framework.problem_cell"),
    **dict.fromkeys(("flat_names", "flatten", "unflatten"), "handeye.framework.problem_engine"),
})
#: errors per unknown: {"X": {"rotation": rad, "translation": data units}, ...}
ErrorTable = dict[str, dict[str, float]]


class Problem(EnginePart, SelfCheckPart, CellPart, PlanningPart, StudyPart, ABC):
    """Base class of problem plugins: the required core below, and the optional parts it
    inherits (each part's defaults switch its shared tool off). Subclasses set the class
    variables and methods."""

    name: ClassVar[str]
    summary: ClassVar[str]
    #: names of the unknown poses, e.g. ("X", "Y"); each a 4x4 pose, or a stack (`stack_sizes`)
    unknowns: ClassVar[tuple[str, ...]]
    #: names of the data stacks, e.g. ("A", "B"), each (m, 4, 4)
    data_fields: ClassVar[tuple[str, ...]]
    min_pairs: ClassVar[int]
    #: facts about the cell the data may carry besides the stacks, passed to `validate` when given
    #: (e.g. ``tz_X``, the translation a planar robot's motions cannot determine)
    optional_fields: ClassVar[tuple[str, ...]] = ()
    #: the class of the validated data `validate` returns (how a solver serving several problems,
    #: e.g. ``refine``, tells whose data it holds: `Registry.problem_of`)
    data_type: ClassVar[type | None] = None
    #: the problem the library and the CLI solve when none is named (one registered problem sets it)
    default: ClassVar[bool] = False
    #: the equation as printed, e.g. "A_i X = Y B_i", and what one row of the data is ("pair",
    #: "motion", "triple"): the words of the printout and the report
    equation: ClassVar[str] = ""
    item: ClassVar[str] = "pair"
    #: the setups whose frames `frames` names (e.g. eye-in-hand, eye-to-hand); empty: no setup
    setups: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def validate(self, **data: Any) -> Any:
        """Check raw data and return an immutable, validated data object (float64 copies).

        Raises `InputError` / `DegenerateDataError` naming what is wrong.
        """

    @abstractmethod
    def residuals(self, data: Any, unknowns: NamedPoses) -> dict[str, np.ndarray]:
        """Per-pair residuals of the problem's equation: {"rotation": (m,), "translation": (m,)}."""

    def errors(self, unknowns: NamedPoses, truth: NamedPoses) -> ErrorTable:
        """Errors of estimated unknowns against the truth: for each unknown the angle of
        R_cal R_true^-1 (the paper's eq. 30) and |t_cal - t_true| (eq. 31)."""
        return pose_errors(unknowns, truth, self.unknowns)

    @abstractmethod
    def simulate(self, *, pairs: int, seed: int | None = None, **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Simulated data and the truth it was made from: (data fields, unknowns)."""

    def diagnose(self, data: Any) -> dict[str, Any]:
        """Figures describing how well the data determine the unknowns, and ``warnings``."""
        return {"warnings": []}

    def stack_sizes(self, data: Any) -> Mapping[str, int]:
        """Unknowns that are stacks of poses, with the number of poses of each on these data
        (e.g. one camera pose per camera of the cell): such an unknown is a (k, 4, 4) array,
        each pose checked by the host as a single one. Default: none, every unknown one pose."""
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
    """Rotation angle of R_cal R_true^T and translation distance for each named unknown; for a
    stack of poses (`Problem.stack_sizes`) the largest of its poses' errors."""
    table: ErrorTable = {}
    for name in names:
        cal, true = np.asarray(unknowns[name], dtype=float), np.asarray(truth[name], dtype=float)
        if cal.shape != true.shape:
            raise ValueError(f"unknown {name} has shape {cal.shape}, its truth {true.shape}")
        cal, true = cal.reshape(-1, 4, 4), true.reshape(-1, 4, 4)
        table[name] = {
            "rotation": float(np.max(rotation_angle(cal[:, :3, :3] @ np.swapaxes(true[:, :3, :3], 1, 2)))),
            "translation": float(np.max(np.linalg.norm(cal[:, :3, 3] - true[:, :3, 3], axis=1))),
        }
    return table


#: items an `item_listing` names before "and N more"
LISTED_ITEMS = 8


def item_listing(indices: Any, data: Any = None) -> str:
    """Rows of a problem's data as the user counts them: from 1 (row k of a file), with the 0-based
    index beside them, e.g. "no. 4 (index 3)", and what the row is where the data can say (their
    ``item_label``, e.g. the multi-camera cell's "marker3 with cam5 at station 4"); at most
    LISTED_ITEMS, then "and N more"."""
    idx = [int(i) for i in np.asarray(indices).ravel()]
    label = getattr(data, "item_label", None)
    items = [f"no. {i + 1} (index {i}{': ' + label(i) if label else ''})" for i in idx[:LISTED_ITEMS]]
    return ", ".join(items) + (f" and {len(idx) - LISTED_ITEMS} more" if len(idx) > LISTED_ITEMS else "")
