"""The contract every calibration problem plugin fulfils (AX=YB, AX=XB, AXB=YCZ, ...).

A problem knows its data fields and unknowns, validates raw input into an immutable data object,
computes per-pair residuals and errors against a known truth, and simulates data with a truth.
Solvers receive the validated data object, never raw user input.

Beyond that, it tells the shared machinery what it needs, so that a problem added as a plugin
gets every shared tool with no edit to handeye (docs/plugins.md, "A problem plugin"):

- the engine's least-squares model of its data (`Problem.pose_model`): ``refine`` and ``auto``
  serve every problem that has one, started from the problem's `Problem.starts`;
- the self-check's model (`Problem.check_model`), the noise it expects and the robot's pose at
  each of its rows (`Problem.configurations`);
- how its unknowns read in a cell (`Problem.frames`, `Problem.published`), for printing, exports
  and the report, and how a cell's recorded stations become its data (`Problem.station_reader`;
  joint readings: `Problem.from_joints`);
- the settings of studies and benchmarks (`Problem.study_noise`, `Problem.protocols`,
  `Problem.bench`) and which setup mistakes the plausibility check may try (`Problem.mistakes`);
- unknowns that are stacks of poses (`Problem.stack_sizes`), checked by the host pose by pose;
- how a cell's table of observations (several cameras and targets, `Observations`) becomes its
  data (`Problem.from_observations`), and its residuals per pair of unknowns
  (`Problem.residual_table`) for the report.
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
class BenchRow:
    """A row `handeye bench` times beside the registered solvers: one solve done outside handeye
    (e.g. OpenCV called directly), so that handeye's time reads against it.

    call: ``call(inputs)`` prepares one solve of `inputs` (the second item `BenchSettings.simulate`
        returns: the data fields unless the problem makes other inputs) and returns a function of
        no argument doing it; only that function is timed (its result is ignored). It may raise:
        the row then shows the error.
    missing: why the row cannot run here (e.g. a library missing), or None: it can. Rows giving
        the same reason are listed once, together.
    same_method: the registered solver implementing the same method (e.g. ``"tsai"`` beside
        OpenCV's TSAI), whose call time the printout divides by this row's; None: no such solver.
    """

    label: str
    call: Callable[[Mapping[str, Any]], Callable[[], Any]]
    missing: Callable[[], str | None] = lambda: None
    same_method: str | None = None


@dataclasses.dataclass(frozen=True)
class BenchTarget:
    """A speed target `handeye bench` checks and prints: `solver` (on its default backend, or
    `backend`) at `pairs` pairs within `seconds` per `handeye.solve` call, or within `ratio` times
    the call of the row labelled `against` (None: the reference row; e.g. a direct row, to compare
    with the other library called as its users call it); `options` (e.g.
    ``(("init", "kron-lstsq"),)``) make it a row of its own, timed beside the solver's plain row."""

    solver: str
    pairs: int
    seconds: float | None = None
    ratio: float | None = None
    backend: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    against: str | None = None


@dataclasses.dataclass(frozen=True)
class BenchSettings:
    """What `handeye bench` (`handeye.harness.bench`) times for a problem besides every
    registered solver, and on which data. Every field has a default: a problem that sets none is
    benchmarked as its solvers on its own simulator.

    pairs: the default numbers of pairs m (the ``--pairs`` of the command line).
    reference: the label of the row the ratio column divides by (None: the first row timed);
        reference_name: how the targets name it (None: its label).
    solver_rows: options of registered solvers timed as rows of their own, e.g.
        ``("opencv", (("method", "shah"),))``, labelled ``opencv [method=shah]``, on the solver's
        default backend; always timed (whatever ``--solvers`` selects), left out when the solver
        is not registered for the problem, and a note when its backend is unavailable. A solver
        named here is timed as these rows only.
    direct_rows: solves outside handeye (`BenchRow`), timed after the solver rows.
    targets: `BenchTarget`, judged and printed one line each.
    simulate: ``simulate(pairs=m, seed=seed, noise=noise, **options) -> (data fields, inputs)``,
        called like `Problem.simulate` (``options``: a solver's `SolverSpec.simulate_options`)
        but giving, instead of the truth, the inputs of the direct rows (`BenchRow.call`): e.g.
        the stations a function forms the motions from itself. None: the problem's simulator,
        the data fields serving as both.
    data_note: how the printout describes the data: a `str.format` template of ``{seed}``,
        ``{rot}`` and ``{trans}`` (the noise std, rad and data units). None: the problem's
        simulator with noise on every data stack.
    """

    pairs: tuple[int, ...] = (10, 100, 1000)
    reference: str | None = None
    reference_name: str | None = None
    solver_rows: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    direct_rows: tuple[BenchRow, ...] = ()
    targets: tuple[BenchTarget, ...] = ()
    simulate: Callable[..., tuple[Mapping[str, Any], Mapping[str, Any]]] | None = None
    data_note: str | None = None


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


class Problem(ABC):
    """Base class of problem plugins.  Subclasses set the class variables and methods below."""

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
    #: how the data are made from a cell's absolute poses, or None when they cannot be
    station_reader: ClassVar[StationReader | None] = None
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
    #: registered solvers that give ``refine`` and ``auto`` their start, in order of preference;
    #: those in `certifiable_starts` prove their answer globally optimal (auto then needs no
    #: second start); errors of `start_refusals` pass on to the next start besides a solver's
    #: failure (e.g. InputError of a start that serves one data protocol only)
    starts: ClassVar[tuple[str, ...]] = ()
    certifiable_starts: ClassVar[tuple[str, ...]] = ()
    start_refusals: ClassVar[tuple[type[Exception], ...]] = ()
    #: a fast closed-form solver for the plausibility check's many fits (None: the first start)
    quick_solver: ClassVar[str | None] = None
    #: the setup mistakes of `MISTAKES` the plausibility check may try on this problem's stations
    mistakes: ClassVar[tuple[str, ...]] = MISTAKES
    #: the accuracy study's realistic noise per data stack, (rad, data units); None: 0.002 rad
    #: and 0.5 units (a camera's) on every stack
    study_noise: ClassVar[Mapping[str, tuple[float, float]] | None] = None
    #: simulator protocols (values of its ``protocol`` option) studies sweep one by one; empty: none
    protocols: ClassVar[tuple[str, ...]] = ()
    #: what `handeye bench` times for this problem (default: every registered solver)
    bench: ClassVar[BenchSettings] = BenchSettings()

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
        """For the host's self-check (`handeye.checks.self_check`): a least-squares model of the data
        (`handeye.estimation.nlls.PoseModel`), the poses to start it from (the answer's, with any nuisance
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

    def configurations(self, data: Any) -> np.ndarray | None:
        """The robot's pose (T_base_flange, or its inverse) at each row of the model
        `check_model` gives, (m, 4, 4), for the self-check's test of residuals that follow the
        arm's configuration (systematic robot errors, `handeye.checks.systematic`); None (the
        default): the problem's rows are not stations of one robot, the test is skipped."""
        return None

    def station_information(self, A: np.ndarray, B: np.ndarray, unknowns: Poses, robot_sigma: tuple[float, float],
                            camera_cov: np.ndarray, setup: str) -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]] | None:
        """For planning which stations to record (`handeye.planning`): the Fisher information
        (m, 6k, 6k) that each planned station would give, its robot pose A_i (T_base_flange) and
        camera pose B_i exactly as planned, with the cell's X and Y in `unknowns` (A X = Y B's
        convention for `setup`, docs/conventions.md), the camera pose's covariance camera_cov
        (m, 6, 6) in B_i's own frame and the robot's noise robot_sigma (rad, length per axis);
        with the names of the k unknowns (6 parameters each, rotation then translation in their
        own frame) as the problem calls them, and those of interest (the others are nuisances).
        None (the default): the problem cannot plan stations yet."""
        return None

    def pose_model(self, data: Any) -> Any:
        """The shared least-squares engine's model of validated `data` (a
        `handeye.estimation.nlls.PoseModel`, its unknowns in the order `flat_unknowns` gives),
        or None: then ``refine`` and ``auto`` do not serve the problem. Default: the data's own
        ``pose_model`` attribute, when they have one."""
        return getattr(data, "pose_model", None)

    @property
    def refinable(self) -> bool:
        """Whether the problem offers the engine a model (`pose_model` overridden, or its data
        type carrying one): ``refine`` and ``auto`` register for it."""
        return type(self).pose_model is not Problem.pose_model or hasattr(self.data_type, "pose_model")

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """Per unknown, what it is in a cell of `setup` (one of `setups`); empty when the problem
        does not say (the printout then names the unknowns only)."""
        return {}

    def published(self, setup: str | None = None) -> Published | None:
        """The unknown a cell's exports publish with its default frame ids, or None (nothing to
        publish: the answer is exported as the unknowns)."""
        return None

    def stack_sizes(self, data: Any) -> Mapping[str, int]:
        """Unknowns that are stacks of poses, with the number of poses of each on these data
        (e.g. one camera pose per camera of the cell): such an unknown is a (k, 4, 4) array,
        each pose checked by the host as a single one. Default: none, every unknown one pose."""
        return {}

    def from_observations(self, observations: Observations, setup: str) -> ObservationData | None:
        """The problem's data made from a cell's table of observations (several cameras and
        targets) in `setup`, with the names of its stacked unknowns' poses; None (the default):
        the problem is not made from such a table. Raises `InputError` naming what is wrong."""
        return None

    @property
    def reads_observations(self) -> bool:
        """Whether the problem is made from a table of observations (`from_observations`)."""
        return type(self).from_observations is not Problem.from_observations

    def from_joints(self, stations: JointStations, setup: str) -> dict[str, Any] | None:
        """The problem's data (the keyword arguments of `handeye.solve`) made from a cell's
        stations with the robot's joint readings and nominal DH table (`JointStations`) in
        `setup`; None (the default): the problem is not made from joint readings."""
        return None

    @property
    def reads_joints(self) -> bool:
        """Whether the problem is made from joint readings (`from_joints`)."""
        return type(self).from_joints is not Problem.from_joints

    def residual_table(self, data: Any, unknowns: Poses) -> list[dict[str, Any]]:
        """Residuals per pair of poses the observations tie (e.g. one camera and one marker): rows
        naming the poses by unknown (``{"X": "marker0", "Y": "cam1", "observations": 12,
        "rotation_rms_deg": ..., "translation_rms": ..., "rotation_max_deg": ...,
        "translation_max": ...}``), for the report's table and graph; empty (the default): the
        problem has no such pairs."""
        return []

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


def flat_names(problem: Problem, data: Any) -> tuple[str, ...]:
    """The problem's unknowns as single poses, in order: a stack `X` of k poses (`stack_sizes`)
    as ``X[0]``, ..., ``X[k-1]`` (the order of `Problem.pose_model`'s unknowns)."""
    sizes = problem.stack_sizes(data)
    return tuple(item for name in problem.unknowns
                 for item in ([f"{name}[{k}]" for k in range(sizes[name])] if name in sizes else [name]))


def flatten(problem: Problem, data: Any, unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    """The unknowns as a tuple of single poses (`flat_names`' order)."""
    sizes = problem.stack_sizes(data)
    out: list[np.ndarray] = []
    for name in problem.unknowns:
        T = np.asarray(unknowns[name], dtype=float)
        out += list(T) if name in sizes else [T]
    return tuple(out)


def unflatten(problem: Problem, data: Any, poses: tuple[np.ndarray, ...] | list[np.ndarray]) -> dict[str, np.ndarray]:
    """The inverse of `flatten`: {unknown: 4x4, or a (k, 4, 4) stack}."""
    sizes, out, k = problem.stack_sizes(data), {}, 0
    for name in problem.unknowns:
        n = sizes.get(name)
        out[name] = np.stack(poses[k:k + n]) if n is not None else np.asarray(poses[k])
        k += 1 if n is None else n
    if k != len(poses):
        raise ValueError(f"{len(poses)} poses for unknowns {flat_names(problem, data)}")
    return out


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
