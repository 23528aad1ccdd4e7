"""A cell: what a calibration cell recorded and how to read it, as one frozen value (`Cell`).

A `Cell` says where the robot's flange poses are (`PoseStream`: a pose file, a folder of one
pose file per station, or a ROS bag; format, length unit, column layout, bag topic) or, for a
kinematic calibration, its joint readings and nominal DH table (`JointStream`, ``arm``), where the
camera's side is (`CameraStream`, the board's pose per station, or `Images`, board images with
the board and optionally the intrinsics; or, for a cell of several cameras and targets, its
tables of observations or its cameras' image folders, `ObservationStream`, with the boards the
images show by name, ``targets``), the setup, how robot and camera poses pair into
stations (`Matching`), what is solved and by whom (problem, solver, backend, options, the facts
``tz_X`` / ``tz_Y`` / ``camera_scale``), whether the plausibility checks run, the ROS frame ids,
and where the command line writes its results (`Outputs`). ``handeye.calibrate(cell)`` runs it;
``handeye calibrate`` builds one from its flags (or ``--config`` file) and calls the same.

Every default of the calibrate workflow is defined here (and in its parts, `cell_parts`), once:
the library and the command line read them from these classes.

A `Cell` is checked when it is built: a wrong value or combination raises `InputError` (a
ValueError) with one line that names the setting in backticks as the cell file spells it
(```robot.unit```, ```matching.method: time```), what was expected and what to do; the command
line shows the same messages with its flags (``--robot-unit``, ``--match time``). What needs the
files (their existence, whether a path is a ROS bag or a folder) is checked when they are read.

The YAML form (`Cell.from_file`, `Cell.to_file`) is `handeye.workflow.cell_file`.
"""

from __future__ import annotations

import dataclasses
import os
import types
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError, shown
from handeye.io.data_files import station_readers
from handeye.workflow import cell_file
from handeye.workflow.cell_parts import (  # noqa: F401 (the parts and their names, as handeye.workflow.cell's)
    CAMERA_POSES,
    FACTS,
    IMAGE_MATCHES,
    INTERPOLATE_ONLY,
    MATCH_METHODS,
    PAIRINGS,
    SETUPS,
    UNITS,
    CameraStream,
    Images,
    JointStream,
    Matching,
    ObservationStream,
    Outputs,
    PoseStream,
    check_choice,
    check_flag,
    check_number,
    check_path,
    check_text,
)
from handeye.workflow.frames import frame_ids as _frame_ids


def _reader_problem(problem: str | None, key: str, what: str) -> str:
    """`problem`, checked to be a registered problem made from the cell's `key` entry (``reads_`` +
    `key`: `Problem.from_observations`, `Problem.from_joints`; `what` says what that is); None:
    the one registered problem that is, if exactly one."""
    from handeye.host.registry import get_registry

    readers = sorted(name for name, spec in get_registry().problems.items() if getattr(spec, f"reads_{key}"))
    if problem is None and len(readers) == 1:
        return readers[0]
    if problem not in readers:
        raise InputError(f"`{key}` need `problem` to be one of {', '.join(readers) or '(none registered)'} (the "
                         f"registered problems made from {what}), got {shown(problem)}")
    return problem


def _observation_streams(value: Any) -> tuple[ObservationStream, ...] | None:
    """`observations` as a tuple of `ObservationStream` (one given alone becomes a tuple of one)."""
    if value is None:
        return None
    items = (value,) if isinstance(value, ObservationStream) else value
    if not isinstance(items, (list, tuple)) or not items or not all(isinstance(v, ObservationStream) for v in items):
        raise InputError("`observations` must be a handeye.workflow.cell.ObservationStream or a non-empty list of "
                         f"them (a mapping: build the cell with Cell.from_dict), got {shown(value)}")
    return tuple(items)


def _targets(value: Any) -> dict[str, Any] | None:
    """`targets` as a dict of target name -> board spec, board file or `handeye.vision.boards.Board`."""
    if value is None:
        return None
    if not isinstance(value, Mapping) or not value:
        raise InputError("`targets` must map each target's name to its board (a spec such as "
                         f"charuco:5x7:30mm:22mm:DICT_4X4_50, or a board file), got {shown(value)}")
    for name, board in value.items():
        if not isinstance(name, str) or not name.strip():
            raise InputError(f"`targets` must be named by non-empty texts, got {shown(name)}")
        if isinstance(board, os.PathLike):
            continue
        if not (isinstance(board, str) and board.strip()) and type(board).__name__ != "Board":
            raise InputError(f"`targets.{name}` must be a board spec or board file (docs/boards.md), got {shown(board)}")
    return {name: os.fspath(b) if isinstance(b, os.PathLike) else b for name, b in value.items()}


def _check_camera_names(value: Any) -> None:
    """`camera_scale` of a cell of several cameras: None, ``known``, or the names of its monocular
    cameras (distinct non-empty texts; whether they are the tables' cameras is checked on reading)."""
    if value is None or value == "known":
        return
    if value == "unknown":
        raise InputError("`camera_scale: unknown` does not say which of the cell's cameras are monocular: name them, "
                         "e.g. `camera_scale: [cam0, cam2]`, each gets its own scale (docs/camera-scale.md)")
    if not isinstance(value, tuple) or not value or not all(isinstance(v, str) and v.strip() for v in value):
        raise InputError("`camera_scale` of a cell of several cameras must be `known` or a list of the names of its "
                         f"monocular cameras (e.g. [cam0, cam2]), got {shown(value)}")
    twice = sorted({v for v in value if value.count(v) > 1})
    if twice:
        raise InputError(f"`camera_scale` names {twice[0]!r} twice; name each monocular camera once")


def _stations_problem(problem: str | None) -> str:
    """`problem` (None: the default problem), checked to be a registered problem that a cell's
    stations make data for (`Problem.station_reader`)."""
    from handeye.host.registry import get_registry

    problem = get_registry().default_problem() if problem is None else problem
    if problem in get_registry().problems and get_registry().problem(problem).reads_joints:
        raise InputError(f"`problem: {problem}` is made from the robot's joint readings: give `joints.file: FILE` "
                         "(with `joints.unit`) and `arm: FILE` (the nominal DH table) instead of `robot.file`")
    readers = station_readers()
    if problem not in readers:
        raise InputError(f"`problem` must be one of {', '.join(sorted(readers))} (the registered problems a cell's "
                         f"stations make data for), got {shown(problem)}")
    return problem


@dataclasses.dataclass(frozen=True)
class Cell:
    """What a calibration cell recorded and how to read and solve it (module docstring).

    robot: the flange poses T_base_flange (`PoseStream`).
    setup: ``eye-in-hand`` (camera on the flange) or ``eye-to-hand`` (camera fixed).
    camera: the board poses (`CameraStream`), or images: board images (`Images`): exactly one.
    matching: how they pair into stations (`Matching`; default: row k with row k).
    problem: a registered problem read from a cell's stations (`Problem.station_reader`): the
        default problem (None: ``axyb``, both unknowns from the stations), or e.g. ``axxb`` (the
        camera only, from the motions between stations); pairing: for a problem of motions,
        ``all`` (default) or ``consecutive``.
    solver, backend: default ``auto`` (``reprojection`` for images when installed, giving way to
        the pose-based answer when the robot's errors dominate); options: solver options.
    tz_X, tz_Y: a planar robot's unobservable translation (docs/planar.md); camera_scale:
        ``unknown`` for a camera known up to scale (docs/camera-scale.md); in a cell of several
        cameras (`observations`) the names of its monocular cameras instead, each with its own
        unknown scale (``[cam0, wrist1]``, docs/camera-scale.md, "Several cameras"). They may also
        be given in `options`, not both.
    orthonormalize: re-orthonormalise rotations exported with few decimals (both streams).
    checks: run the plausibility checks (default True). frame_ids: (parent, child) of the ROS,
        URDF and xacro exports (default: the problem's per setup, `Problem.published`).
    time_limit: seconds a solve may take (None: no limit for handeye's own solvers, 600 s for a
        third party's; 0: no limit). outputs: the command line's result files (`Outputs`).
    observations: a cell of several cameras and targets instead of `camera` / `images`: its tables
        of observations (`ObservationStream`: one table naming each row's camera, or one file
        per camera), solved by a problem made from them (`Problem.from_observations`; default:
        the one registered, ``axyb-multi``); `matching` applies to the cameras' images only,
        `pairing`, the facts and `frame_ids` do not apply (`handeye.workflow.observation_cell`).
    targets: with observations from images (`ObservationStream.images`), the boards the cameras
        look for, by name: a board spec or board file each (docs/boards.md); several boards in one
        image must be told apart by their marker ids (``:first=N``).
    joints: a kinematic calibration (docs/kinematic.md) instead of `robot`: the robot's joint
        readings (`JointStream`), matched with the camera's poses or images by `matching` (row,
        name or time) as robot poses are; arm: the arm's nominal DH table (an arm file,
        `handeye.io.arm_files`; its length unit is the answer's). The problem: the one registered
        problem made from joint readings (`Problem.from_joints`; ``axyb-kinematic``).
    """

    robot: PoseStream | None = None
    setup: str | None = None
    camera: CameraStream | None = None
    images: Images | None = None
    matching: Matching = dataclasses.field(default_factory=Matching)
    problem: str | None = None
    pairing: str | None = None
    solver: str | None = None
    backend: str | None = None
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    tz_X: float | None = None
    tz_Y: float | None = None
    camera_scale: str | tuple[str, ...] | None = None
    orthonormalize: bool = False
    checks: bool = True
    frame_ids: tuple[str, str] | str | None = None
    time_limit: float | None = None
    outputs: Outputs = dataclasses.field(default_factory=Outputs)
    observations: tuple[ObservationStream, ...] | None = None
    targets: Mapping[str, Any] | None = None
    joints: JointStream | None = None
    arm: str | os.PathLike | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.options, Mapping) or not all(isinstance(k, str) and k for k in self.options):
            raise InputError(f"`options` must map option names to values, got {shown(self.options)}")
        object.__setattr__(self, "options", types.MappingProxyType(dict(self.options)))
        object.__setattr__(self, "frame_ids", _frame_ids(self.frame_ids))
        for name, kind in (("robot", PoseStream), ("camera", CameraStream), ("images", Images),
                           ("matching", Matching), ("outputs", Outputs), ("joints", JointStream)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise InputError(f"`{name}` must be a handeye.workflow.cell.{kind.__name__}, got "
                                 f"{type(value).__name__} (a mapping: build the cell with Cell.from_dict)")
        if self.robot is None and (self.observations is not None or self.joints is not None):
            object.__setattr__(self, "robot", PoseStream())  # the tables may carry the robot's poses; joints give them
        if isinstance(self.arm, os.PathLike):
            object.__setattr__(self, "arm", os.fspath(self.arm))
        if self.robot is None:
            raise InputError("`robot.file: FILE` is required: the robot's flange poses (a pose file, a folder of "
                             "one pose file per station, or a ROS bag)")
        check_choice(self.setup, SETUPS, "setup")
        object.__setattr__(self, "observations", _observation_streams(self.observations))
        object.__setattr__(self, "targets", _targets(self.targets))
        if isinstance(self.camera_scale, list):  # camera names (a cell of several cameras)
            object.__setattr__(self, "camera_scale", tuple(self.camera_scale))
        if self.observations is not None:
            if self.joints is not None or self.arm is not None:
                raise InputError("`joints` and `arm` apply to one camera's stations, not to `observations`; drop them")
            self._check_observations()
            return
        if self.targets is not None:
            raise InputError("`targets` name the boards of a cell of several cameras (`observations` with `images`); "
                             "one camera's images take `images.board`: drop `targets`")
        if self.joints is not None:
            self._check_joints()
            return
        if self.arm is not None or self.outputs.arm is not None:
            raise InputError(f"`{'arm' if self.arm is not None else 'outputs.arm'}` applies to a kinematic calibration "
                             "from joint readings: give `joints.file: FILE` too, or drop it")
        object.__setattr__(self, "problem", _stations_problem(self.problem))
        self.robot.check("robot")
        if self.robot.file is None:
            raise InputError("`robot.file: FILE` is required: the robot's flange poses (a pose file, a folder of "
                             "one pose file per station, or a ROS bag)")
        self._check_camera_side()
        self.matching.check(images=self.images is not None)
        self.outputs.check()
        check_choice(self.pairing, PAIRINGS, "pairing", optional=True)
        readers = station_readers()
        if self.pairing is not None and not readers[self.problem].pairing:
            motions = " or ".join(f"`problem: {name}`" for name, reader in sorted(readers.items()) if reader.pairing)
            raise InputError(f"`pairing` applies to {motions} (motions between stations); with {self.problem} every "
                             "station is one pair: drop it")
        for name in ("solver", "backend"):
            check_text(getattr(self, name), name)
        for name in ("tz_X", "tz_Y"):
            check_number(getattr(self, name), name, what="length in the robot's unit")
        if isinstance(self.camera_scale, tuple):
            raise InputError("`camera_scale` names the monocular cameras of a cell of several cameras "
                             "(`observations`); one camera's is `known` or `unknown`")
        check_choice(self.camera_scale, ("known", "unknown"), "camera_scale", optional=True)
        for name in FACTS:
            if getattr(self, name) is not None and name in self.options:
                raise InputError(f"`{name}` is given twice: as `{name}` and in `options`; give it once")
        check_flag(self.orthonormalize, "orthonormalize")
        check_flag(self.checks, "checks")
        check_number(self.time_limit, "time_limit", low=0.0, what="number of seconds (0: no limit)")
        if self.images is not None and self.facts().get("camera_scale") == "unknown":
            raise InputError("`camera_scale: unknown` does not apply to `images`: the board's size gives the "
                             "camera's translations in the board's unit; drop it")

    def _check_observations(self) -> None:
        """A cell of several cameras and targets: tables of observations, one robot pose file of
        the stations, neither `camera` nor `images`, no settings of one camera's stations."""
        object.__setattr__(self, "problem", _reader_problem(self.problem, "observations", "a table of observations"))
        self.robot.check("robot")
        if self.robot.file is None and any(s.images is not None for s in self.observations):
            raise InputError("`robot.file: FILE` is required with a camera's `images`: the robot's flange poses, one "
                             "per station, which the images are paired with")
        if self.robot.file is None and self.robot.topic is not None:
            raise InputError("`robot.topic` applies to a ROS bag as `robot.file`; drop it")
        stray = [name for name in ("camera", "images") if getattr(self, name) is not None
                 and (name == "images" or getattr(self, name).given())]
        if stray:
            raise InputError(f"`observations` replace `{stray[0]}`: the tables give every camera's poses; drop "
                             f"`{stray[0]}`")
        object.__setattr__(self, "camera", None)
        for k, stream in enumerate(self.observations):
            stream.check(f"observations[{k}]")
        named = [s.camera for s in self.observations]
        if len(self.observations) > 1 and None in named:
            raise InputError("several `observations` files: name each file's camera (`camera: NAME`), or give one "
                             "table with a camera column")
        repeated = sorted({c for c in named if c is not None and named.count(c) > 1})
        if repeated:
            raise InputError(f"camera {repeated[0]!r} is named by two `observations` files; give each camera once")
        self._check_image_observations()
        if self.pairing is not None:
            raise InputError("`pairing` applies to problems of motions; drop it")
        if self.frame_ids is not None:
            raise InputError("`frame_ids` names one camera's frames; with `observations` every pose is published from "
                             "its unknown's frame (base, flange) to its name in the tables: drop it")
        self.outputs.check()
        for name in ("solver", "backend"):
            check_text(getattr(self, name), name)
        for name in FACTS:
            if getattr(self, name) is not None and name != "camera_scale":
                raise InputError(f"`{name}` does not apply to `observations`; drop it")
        _check_camera_names(self.camera_scale)
        check_flag(self.orthonormalize, "orthonormalize")
        check_flag(self.checks, "checks")
        check_number(self.time_limit, "time_limit", low=0.0, what="number of seconds (0: no limit)")

    def _check_joints(self) -> None:
        """A kinematic calibration: joint readings and the arm's DH table instead of the robot's
        pose file (whose poses are the table's forward kinematics), a camera pose file or board
        images, matched by row, name or time; settings of other problems refused."""
        object.__setattr__(self, "problem", _reader_problem(self.problem, "joints", "joint readings"))
        self.joints.check()
        check_path(self.arm, "arm")
        if self.arm is None:
            raise InputError("`arm: FILE` is required with `joints`: the arm's nominal DH table (docs/formats.md, "
                             "'Arm models')")
        if self.robot.given():
            raise InputError("`joints` give the robot's poses (the arm's forward kinematics of the readings): drop "
                             f"`robot.{self.robot.given()[0]}`")
        self._check_camera_side()
        self.matching.check(images=self.images is not None)
        if self.matching.method == "interpolate":
            raise InputError("`matching.method: interpolate` does not apply to `joints` (joint readings are not "
                             "interpolated yet); use row, name or time")
        self.outputs.check()
        stray = [name for name in ("pairing", *FACTS) if getattr(self, name) is not None or name in self.options]
        if stray:
            raise InputError(f"`{stray[0]}` does not apply to `joints` (problem {self.problem}); drop it")
        for name in ("solver", "backend"):
            check_text(getattr(self, name), name)
        check_flag(self.orthonormalize, "orthonormalize")
        check_flag(self.checks, "checks")
        check_number(self.time_limit, "time_limit", low=0.0, what="number of seconds (0: no limit)")

    def _check_image_observations(self) -> None:
        """The cameras' images (`observations` entries with `images`): the targets they look for
        are named in `targets`; `matching` pairs their images with the stations (row / index,
        name or time) and does not apply without images."""
        imaged = [(k, s) for k, s in enumerate(self.observations) if s.images is not None]
        if not imaged:
            if self.matching.given():
                raise InputError("`matching` applies to one camera's stations or to cameras' `images`; the tables of "
                                 "observations name each row's station (matched to the robot file's names, else its "
                                 "0-based rows): drop it")
            if self.targets is not None:
                raise InputError("`targets` name the boards the cameras' `images` show; the tables of observations "
                                 "name each row's target: drop `targets`")
            return
        if self.targets is None:
            raise InputError(f"`observations[{imaged[0][0]}].images` need `targets`: the boards in the images, by name "
                             "(e.g. `targets: {board0: charuco:5x7:30mm:22mm:DICT_4X4_50}`; docs/calibrate.md)")
        for k, stream in imaged:
            unknown = [t for t in stream.targets or () if t not in self.targets]
            if unknown:
                raise InputError(f"`observations[{k}].targets` names {unknown[0]!r}, which is not in `targets` (they "
                                 f"are {', '.join(map(repr, self.targets))})")
        self.matching.check(images=True)

    def _check_camera_side(self) -> None:
        """Exactly one of a camera pose file and board images, each complete."""
        camera, images = self.camera, self.images
        if images is not None and camera is not None and not camera.given():  # nothing said about a camera file
            object.__setattr__(self, "camera", None)
            camera = None
        if images is not None:
            images.check()
            if images.folder is None:
                stray = " and ".join(f"`images.{g}`" for g in ("board", "intrinsics") if getattr(images, g) is not None)
                if not stray:
                    raise InputError("`images` needs `images.folder: DIR`, the folder of board images")
                raise InputError(f"{stray} appl{'y' if ' and ' in stray else 'ies'} to `images.folder: DIR`; give "
                                 "it or drop them")
            given = [] if camera is None else [g for g in camera.given() if g != "poses"]
            if given:
                names = ", ".join(f"`camera.{g}`" for g in given)
                raise InputError("`images` replaces `camera` and `camera.format`: give either `images` (a folder of "
                                 "board images, with `images.board`) or `camera` (a pose file, with `camera.format`), "
                                 f"not both (drop {names})")
            if camera is not None and camera.poses != "board-in-camera":
                raise InputError("`camera.poses` applies to a camera pose file, not to `images`; drop it")
            if images.board is None:
                raise InputError("`images` needs `images.board: SPEC` (e.g. `images.board: chessboard:9x6:25mm`; "
                                 "docs/boards.md)")
            return
        if camera is None or camera.file is None:
            raise InputError("give the camera's side: `camera.file: FILE` `camera.format: FORMAT` (board poses) or "
                             "`images.folder: DIR` `images.board: SPEC` (board images)")
        camera.check("camera")

    # ------------------------------------------------------------------------- derived

    def facts(self) -> dict[str, Any]:
        """The facts given, from their fields or from `options` (``tz_X``, ``tz_Y``, ``camera_scale``)."""
        facts = {name: getattr(self, name) for name in FACTS if getattr(self, name) is not None}
        facts.update({name: self.options[name] for name in FACTS if name in self.options})
        return facts

    def solver_options(self) -> dict[str, Any]:
        """The solver options: `options` without the facts."""
        return {k: v for k, v in self.options.items() if k not in FACTS}

    def replace(self, **changes: Any) -> Cell:
        """A copy with `changes` (checked as a new cell)."""
        return dataclasses.replace(self, **changes)

    # ------------------------------------------------------------------------- files

    def to_dict(self, *, relative_to: str | os.PathLike | None = None) -> dict[str, Any]:
        """The cell as the cell file's mapping: the settings that differ from their defaults (and
        always `setup`, `problem`, `matching.method`); paths relative to folder `relative_to` when
        they lie inside it (else absolute), as given when it is None."""
        return cell_file.cell_to_dict(self, relative_to)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, base: str | os.PathLike | None = None,
                  where: str = "cell") -> Cell:
        """The cell of a mapping as a cell file holds it; relative paths are taken relative to
        folder `base` (default: as they are). Unknown keys are an InputError naming the key and
        the known ones; `where` names the source in messages."""
        return cell_file.cell_from_dict(cls, data, base=base, where=where)

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> Cell:
        """The cell of a YAML cell file; relative paths in it are relative to the file's folder."""
        return cell_file.read_cell(cls, path)

    def to_yaml(self, *, relative_to: str | os.PathLike | None = None) -> str:
        """The cell file's text (YAML with a header comment), paths as `to_dict` writes them."""
        return cell_file.cell_yaml(self, relative_to)

    def to_file(self, path: str | os.PathLike, *, force: bool = False) -> Path:
        """Write the cell file `path` (paths relative to its folder when inside it), whole or not
        at all; an existing file is replaced only with `force` (`handeye.io.output_files`)."""
        from handeye.io.output_files import write_text

        folder = Path(path).parent if str(Path(path).parent) else Path(".")
        return write_text(path, self.to_yaml(relative_to=folder), force=force, flag="cell file")
