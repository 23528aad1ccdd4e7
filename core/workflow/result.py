"""What ``handeye.calibrate(cell)`` returns: `CalibrationResult`, the answer with everything a
user needs to trust it, and its exports.

It carries the `Solution` (its status as finally decided: ``unreliable`` when the plausibility
checks or an untrusted clock offset say so), the unknowns as frames of the cell (`Frame`: parent
and child per setup), the stations (which robot pose went with which camera pose or image) and
every pose or image dropped with its reason, the residuals, the plausibility verdict, and every
warning. Its exports: `to_dict` / `to_json` / `to_yaml` (the same data ``handeye calibrate -o`` /
``--yaml`` writes), `ros2_static_transform` (the ``static_transform_publisher`` line),
`urdf_joint` and `xacro` (the camera's pose as a fixed joint) and `write_report` (the quality
report, HTML or markdown; `handeye.workflow.quality_report`).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.checks.stations import Dropped
from handeye.framework.reported import Reported
from handeye.framework.solution import Solution, Status, standard_deviations
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import Cell
from handeye.workflow.exports import (
    dump_json,
    plain,
    pose_entry,
    ros_line,
    urdf_joint,
    xacro_joints,
    xacro_macro,
)
from handeye.workflow.frames import (
    CellFrame,
    equation_of,
    frame_names,
    frames_of,
    published_of,
    single_poses,
    unknown_of,
)
from handeye.workflow.solving import UNUSABLE
from handeye.workflow.stations import Stations


@dataclasses.dataclass(frozen=True)
class NamedPose:
    """One pose of a stacked unknown by its user's name: label (``Y[1]``), name (``cam1``),
    the ROS frame ids parent (the unknown's parent frame, ``base``) and child (the name), and
    T = T_parent_child (4, 4) in the cell's unit."""

    label: str
    name: str
    parent: str
    child: str
    T: np.ndarray


def _frame_id(name: str) -> str:
    """`name` as a ROS frame id: characters other than letters, digits, '_' and '/' as '_', a
    leading non-letter prefixed by 'f'."""
    text = re.sub(r"[^A-Za-z0-9_/]", "_", name.strip()) or "frame"
    return text if text[0].isalpha() else f"f{text}"


def frame_ids(names: Sequence[str]) -> tuple[list[str], str | None]:
    """ROS frame ids of several poses' `names` (`_frame_id`), kept apart where different names
    become one id ("cam 0", "cam-0" and "cam_0" are ``cam_0``, ``cam_0_2``, ``cam_0_3``: one
    frame and one URDF link each), and the warning naming them, or None."""
    ids, owner, groups = [], {}, {}
    for name in names:
        base = _frame_id(name)
        frame, k = base, 1
        while owner.get(frame, name) != name:
            k += 1
            frame = f"{base}_{k}"
        owner.setdefault(frame, name)
        ids.append(frame)
        group = groups.setdefault(base, {})
        group.setdefault(name, frame)
    merged = [group for group in groups.values() if len(group) > 1]
    if not merged:
        return ids, None
    said = "; ".join(", ".join(f"{name!r} as {frame}" for name, frame in group.items()) for group in merged)
    return ids, (f"names that differ only in characters a ROS frame id cannot hold would share one frame; published "
                 f"apart: {said} (rename them to tell the frames apart)")


def _number(value: Any) -> float | None:
    return None if value is None else float(value)


def _summary(values: np.ndarray) -> dict[str, float]:
    values = np.asarray(values, dtype=float)
    return {"median": float(np.median(values)), "rms": float(np.sqrt(np.mean(values**2))),
            "max": float(np.max(values))}


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """A calibrated cell (module docstring).

    cell: the `Cell` calibrated. solution: the solve, its status as decided here. solver: the
    solver name run (the pose-based default when the reprojection fit gave way). unit: the robot's
    length unit, every translation's. stations: the pairing (`Stations`: robot and camera streams,
    rows, the ``matching`` entry, the dropped ones). camera: the stations' camera poses as solved
    (T_cam_target, robot unit); camera_read: the same as read (its format and unit). residuals:
    per pair (axxb: per motion) {"rotation": rad, "translation": unit}. checks: the plausibility
    `Report`, or None (``checks: false``, or an unusable solve). pairing: axxb's pairing. facts:
    the facts given (``tz_X``, ``camera_scale``). warnings: every warning, pairing first.
    """

    cell: Cell
    solution: Solution
    solver: str
    unit: str
    stations: Stations
    camera: PoseStack
    camera_read: PoseStack
    residuals: Mapping[str, np.ndarray]
    checks: Any
    pairing: str | None
    facts: Mapping[str, Any]
    warnings: tuple[str, ...]
    #: a cell of several cameras and targets (`Cell.observations`): per stacked unknown the names
    #: of its poses (``{"X": ("marker0", ...), "Y": ("cam0", ...)}``), else None
    names: Mapping[str, tuple[str, ...]] | None = None
    #: such a cell's residuals per pair of poses (`Problem.residual_table`), else None
    pair_table: tuple[dict[str, Any], ...] | None = None
    #: such a cell's (station, camera, target) of each observation, in the residuals' order, else None
    observation_labels: tuple[tuple[str, str, str], ...] | None = None
    #: such a cell's cameras of images: per camera name its intrinsics, as one camera's result
    #: writes its ``camera`` entry (`handeye.workflow.observation_images.intrinsics_entries`), else None
    cameras: Mapping[str, dict[str, Any]] | None = None
    #: a kinematic calibration (`Cell.joints`): the DH corrections, what is not identifiable and
    #: the corrected table (`handeye.workflow.joint_cell.kinematics_entry`), else None
    kinematics: Mapping[str, Any] | None = None

    # ------------------------------------------------------------------------- the answer

    @property
    def status(self) -> Status:
        """The final status (``unreliable`` when the checks found the fit implausible)."""
        return self.solution.status

    @property
    def usable(self) -> bool:
        """Whether the answer may be used: not not_converged, failed or unreliable."""
        return self.status not in UNUSABLE and self.status is not Status.UNRELIABLE

    @property
    def unknowns(self) -> Mapping[str, np.ndarray]:
        """name -> (4, 4) pose, translations in `unit`."""
        return self.solution.unknowns

    @property
    def X(self) -> np.ndarray:  # noqa: N802 - the paper's name
        return self.solution.unknowns["X"]

    @property
    def Y(self) -> np.ndarray | None:  # noqa: N802
        """Y, or None for axxb."""
        return self.solution.unknowns.get("Y")

    @property
    def frames(self) -> dict[str, CellFrame]:
        """Each unknown as a frame of the cell (``X`` -> T_flange_cam eye-in-hand, ...)."""
        return frames_of(self.cell.problem, self.cell.setup)

    @property
    def dropped(self) -> tuple[Dropped, ...]:
        """Every pose or image left out of the stations, with why."""
        return self.stations.dropped

    @property
    def plausible(self) -> bool | None:
        """The plausibility verdict: True, False, or None when the checks did not run."""
        return None if self.checks is None else bool(self.checks.plausible)

    @property
    def ros_frame_ids(self) -> tuple[str, str] | None:
        """(parent, child) of the camera's pose in the ROS, URDF and xacro exports (None: the
        problem publishes none, `Problem.published`)."""
        published = published_of(self.cell.problem, self.cell.setup)
        return None if published is None else self.cell.frame_ids or (published.parent, published.child)

    @property
    def published(self) -> str | None:
        """The unknown that is the camera's pose (X eye-in-hand; eye-to-hand axyb Y, axxb X), or
        None when the problem publishes none."""
        published = published_of(self.cell.problem, self.cell.setup)
        return None if published is None else published.unknown

    def named_poses(self) -> list[NamedPose]:
        """A cell of several cameras and targets: every pose of the stacked unknowns by its name,
        with ROS frame ids (the unknown's parent frame, e.g. ``base``, and the name), in the
        problem's order; empty for a cell of one camera."""
        if not self.names:
            return []
        frames = frames_of(self.cell.problem, self.cell.setup)
        found = []
        for label, T in single_poses(self.solution.unknowns).items():
            unknown = unknown_of(label)
            names = self.names.get(unknown)
            if names is None:
                continue
            frame = frames.get(unknown)
            found.append((label, names[int(label[len(unknown) + 1:-1])],
                          _frame_id(frame.parent if frame is not None else unknown), T))
        children, _ = frame_ids([name for _, name, _, _ in found])
        return [NamedPose(label, name, parent, child, T) for (label, name, parent, T), child in zip(found, children)]

    def _published_pose(self) -> np.ndarray:
        if self.published is None:
            raise InputError(f"problem {self.cell.problem!r} names no camera pose to publish; export the unknowns "
                             "with to_json or to_yaml")
        return self.unknowns[self.published]

    # ------------------------------------------------------------------------- exports

    def ros2_static_transform(self) -> str:
        """``ros2 run tf2_ros static_transform_publisher ...`` publishing the camera's pose
        (metres) under `ros_frame_ids`; for a cell of several cameras and targets one line per
        named pose (`named_poses`, e.g. ``base`` -> ``cam0``)."""
        if self.names:
            return "\n".join(ros_line(p.T, self.unit, p.parent, p.child) for p in self.named_poses())
        return ros_line(self._published_pose(), self.unit, *self.ros_frame_ids)

    def urdf_joint(self) -> str:
        """The camera's pose as a URDF fixed joint from parent to child link (`ros_frame_ids`);
        for a cell of several cameras and targets a joint per named pose."""
        if self.names:
            return "\n".join(urdf_joint(p.T, self.unit, p.parent, p.child) for p in self.named_poses())
        return urdf_joint(self._published_pose(), self.unit, *self.ros_frame_ids)

    def xacro(self) -> str:
        """A xacro file with macro ``handeye_calibration`` adding that joint (params parent, child);
        for a cell of several cameras and targets the macro adds a joint per named pose
        (`handeye.workflow.exports.xacro_joints`, no params)."""
        if self.names:
            return xacro_joints([(p.T, p.parent, p.child) for p in self.named_poses()], self.unit)
        return xacro_macro(self._published_pose(), self.unit, *self.ros_frame_ids)

    def to_dict(self) -> dict[str, Any]:
        """The result as ``handeye calibrate -o`` writes it (docs/calibrate.md lists the keys)."""
        cell, solution, robot = self.cell, self.solution, self.stations.robot
        std_all = standard_deviations(solution.diagnostics)
        frames = frame_names(cell.problem, cell.setup)
        unknowns = {name: pose_entry(T, robot.format, std_all.get(name))
                    for name, T in single_poses(solution.unknowns).items()}
        item = equation_of(cell.problem)[1]
        rot, trans = np.degrees(self.residuals["rotation"]), np.asarray(self.residuals["translation"])
        images = self.stations.images
        result: dict[str, Any] = {
            **{name: e["matrix"] for name, e in unknowns.items()},
            "frames": {name: frames[unknown_of(name)][0] for name in unknowns if unknown_of(name) in frames},
            "units": {"translation": self.unit, "rotation": "deg"},
            "setup": cell.setup,
            "problem": cell.problem,
            "solver": solution.solver,
            "backend": solution.backend,
            "status": str(solution.status),
            "seconds": solution.seconds,
            "stations": len(robot),
            "matching": self.stations.matching,
            **({"pairing": self.pairing} if self.pairing is not None else {}),
            "poses": {name: {k: v for k, v in e.items() if k != "matrix"} for name, e in unknowns.items()},
            "std": {name: e["std"] for name, e in unknowns.items()} if std_all else None,
            "residuals": {
                "per": item, "count": len(rot),
                "rotation_deg": _summary(rot),
                "translation": _summary(trans),
                "per_" + item: {"rotation_deg": rot.tolist(), "translation": trans.tolist()},
            },
            "warnings": list(self.warnings),
            "checks": None if self.checks is None else self.checks.to_dict(),
            "inputs": {
                "robot": {"file": cell.robot.file, "format": self.stations.robot_file.format,
                          "unit": self.stations.robot_file.unit, "poses": len(self.stations.robot_file)},
                "camera": {"file": None if cell.camera is None else cell.camera.file, "format": self.camera_read.format,
                           "unit": self.camera_read.unit, "poses": len(self.stations.camera_file),
                           "holds": "T_target_cam" if self._inverted else "T_cam_target"},
                "orthonormalize": bool(cell.orthonormalize),
            },
            "ros": None if self.published is None else {
                "command": self.ros2_static_transform(), "unknown": self.published, "frame_id": self.ros_frame_ids[0],
                "child_frame_id": self.ros_frame_ids[1], "translation_unit": "m"},
        }
        if self.names:  # several cameras and targets: every pose by name, the residuals per pair
            result.update(self._named_entries(unknowns))
        if self.kinematics is not None:  # joint readings and the arm's DH table: the corrections
            result["inputs"]["robot"] = dict(self.kinematics["inputs"])
            for name in [n for n in unknowns if unknown_of(n) == "links"]:  # the DH table says it
                for entry in (result, result["poses"], result["frames"], result["std"] or {}):
                    entry.pop(name, None)
            result["kinematics"] = {k: v for k, v in self.kinematics.items() if k not in ("inputs", "arm_yaml")}
        result.update(self._scale_entries())
        if images is not None:  # where the board poses came from, the intrinsics, the images' stations
            from handeye.workflow.image_stations import inputs_entry, result_entries

            result["inputs"]["camera"] = inputs_entry(cell, images)
            result.update(result_entries(cell, images))
        return result

    def _named_entries(self, unknowns: Mapping[str, dict[str, Any]]) -> dict[str, Any]:
        """The entries of a cell of several cameras and targets (`to_dict`): names, frames per
        pose, transforms by name, ROS lines per pose, the observations and residuals per pair."""
        named = self.named_poses()
        cell, stations = self.cell, self.stations
        camera = {"files": [s.source for s in cell.observations], "format": self.camera_read.format,
                  "unit": self.camera_read.unit, "poses": len(self.camera_read),
                  "holds": "T_target_cam" if any(s.poses == "camera-in-board" for s in cell.observations)
                  else "T_cam_target"}
        return {
            "names": {p.label: p.name for p in named},
            "frames": {p.label: f"T_{p.parent}_{p.child}" for p in named},
            "transforms": {p.name: {"unknown": p.label, "parent": p.parent, "child": p.child,
                                    "matrix": unknowns[p.label]["matrix"], "xyz_quat": unknowns[p.label]["xyz_quat"]}
                           for p in named},
            "stations": int(stations.matching["stations"]),
            "observations": {"count": len(self.camera_read), "cameras": self._camera_names(),
                             "per_pair": [dict(row) for row in self.pair_table or ()]},
            **({"cameras": {name: dict(entry) for name, entry in self.cameras.items()}} if self.cameras else {}),
            "inputs": {"robot": {"file": cell.robot.file or stations.robot_file.source,
                                 "format": stations.robot_file.format,
                                 "unit": stations.robot_file.unit, "poses": len(stations.robot_file)},
                       "camera": camera, "orthonormalize": bool(cell.orthonormalize)},
            "ros": {"transforms": [{"unknown": p.label, "frame_id": p.parent, "child_frame_id": p.child,
                                    "command": ros_line(p.T, self.unit, p.parent, p.child)} for p in named],
                    "translation_unit": "m"},
        }

    def _scale_entries(self) -> dict[str, Any]:
        """The camera scales the solve estimated, when the cell says they are unknown: one
        camera's ``camera_scale`` {"scale", "std"}; a cell's monocular cameras' ``camera_scales``
        {name: {"scale", "std"}} (their translations times the scale are in the robot's unit,
        as the residuals are measured)."""
        d, given = Reported.of(self.solution.diagnostics), self.facts.get("camera_scale")
        if given == "unknown" and d.camera_scale is not None:
            return {"camera_scale": {"scale": d.camera_scale, "std": _number(d.camera_scale_std)}}
        if given is None or isinstance(given, str) or not d.camera_scales:
            return {}
        return {"camera_scales": {name: {"scale": float(s), "std": _number(d.camera_scales_std.get(name))}
                                  for name, s in d.camera_scales.items()}}

    def _camera_names(self) -> list[str]:
        """The names of the poses that are cameras: those of the unknown whose frame's child is
        the camera (`Problem.frames`: the Y's of fixed cameras, the X's of wrist cameras)."""
        frames = frames_of(self.cell.problem, self.cell.setup)
        return [name for unknown, names in (self.names or {}).items()
                if unknown in frames and frames[unknown].child == "camera" for name in names]

    @property
    def _inverted(self) -> bool:
        return self.cell.camera is not None and self.cell.camera.poses == "camera-in-board"

    def arm_yaml(self) -> str:
        """A kinematic calibration's DH table of the answer as an arm file (`handeye.io.arm_files`;
        the corrected table, for the robot controller); InputError for other cells."""
        if self.kinematics is None:
            raise InputError("arm_yaml applies to a kinematic calibration (a cell with `joints` and `arm`)")
        return self.kinematics["arm_yaml"]

    def to_json(self) -> str:
        """`to_dict` as JSON text (indented; NaN as null)."""
        return dump_json(self.to_dict())

    def to_yaml(self) -> str:
        """`to_dict` as YAML text (``yaml.safe_dump``)."""
        import yaml

        return yaml.safe_dump(plain(self.to_dict()), sort_keys=False, default_flow_style=None)

    # ------------------------------------------------------------------------- the report

    def report_data(self, *, command: str = "handeye.calibrate(cell)",
                    words: Callable[[str], str] | None = None) -> dict[str, Any]:
        """The quality report's data (`handeye.workflow.quality_report.collect`): `command` is
        shown as the run's command; `words` rewrites each warning (the command line names its
        flags)."""
        from handeye.workflow.image_stations import intrinsics_source
        from handeye.workflow.quality_report import collect
        from handeye.workflow.report_images import image_entries

        cell, robot, words = self.cell, self.stations.robot, words or (lambda text: text)
        robot_file = self.stations.robot_file
        if self.names:  # several cameras and targets: the tables, each pose named
            camera_input = f"{self.camera_read.source} ({self.camera_read.format}, {self.camera_read.unit})"
            return self._named_report(collect(
                problem=cell.problem, setup=cell.setup, unit=self.unit, solution=self.solution,
                residuals=self.residuals, frames=frame_names(cell.problem, cell.setup), checks=None,
                warnings=[words(w) for w in self.warnings],
                inputs={"robot file": f"{cell.robot.file or robot_file.source} ({robot_file.format}, "
                                      f"{robot_file.unit})", "observations": camera_input},
                robot_poses=robot.poses, stations=len(robot), command=command, pair_table=self.pair_table,
                labels=self.observation_labels))
        images = self.stations.images
        if images is not None:
            camera_input = f"{cell.images.folder} (images, board {cell.images.board})"
        else:
            camera_input = f"{cell.camera.file} ({self.camera_read.format}, {self.camera_read.unit})"
        robot_file = self.stations.robot_file
        return collect(problem=cell.problem, setup=cell.setup, unit=self.unit, solution=self.solution,
                       residuals=self.residuals, frames=frame_names(cell.problem, cell.setup),
                       checks=None if self.checks is None else self.checks.to_dict(),
                       warnings=[words(w) for w in self.warnings],
                       inputs={"robot file": f"{cell.robot.file} ({robot_file.format}, {robot_file.unit})"
                               if self.kinematics is None else "joints: {file} ({format}, {unit})".format(
                                   **self.kinematics["inputs"]),
                               "camera " + ("images" if images is not None else "file"): camera_input},
                       robot_poses=robot.poses, stations=len(robot), pairing=self.pairing, command=command,
                       images=None if images is None else image_entries(
                           images, cell.images.board, cell.setup, robot.poses, self.solution.unknowns,
                           intrinsics_source(cell)))

    def _named_report(self, r: dict[str, Any]) -> dict[str, Any]:
        """The report's data with each pose's frame named by its user's name (``T_base_cam0``)."""
        named = {p.label: p for p in self.named_poses()}
        frames = dict(r["frames"])
        for label, p in named.items():
            frames[label] = [f"T_{p.parent}_{p.child}", f"{p.name}: {frames.get(label, ['', ''])[1]}"]
        return {**r, "frames": frames}

    def write_report(self, path: str | Path, *, force: bool = False, command: str = "handeye.calibrate(cell)",
                     words: Callable[[str], str] | None = None) -> list[Path]:
        """Write the quality report to `path` (.html: one self-contained page; .md: markdown with
        its PNG plots next to it); an existing file is replaced only with `force`. Written also
        for an unusable answer: it shows why. Returns the files written."""
        from handeye.workflow.quality_report import write_report

        return write_report(path, self.report_data(command=command, words=words), force=force)
