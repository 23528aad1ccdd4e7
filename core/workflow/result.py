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
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from handeye.framework.errors import InputError
from handeye.framework.solution import Solution, Status, standard_deviations
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import Cell
from handeye.workflow.exports import (
    dump_json,
    plain,
    pose_entry,
    ros_line,
    urdf_joint,
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
from handeye.workflow.stations import Dropped, Stations


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

    def _published_pose(self) -> np.ndarray:
        if self.published is None:
            raise InputError(f"problem {self.cell.problem!r} names no camera pose to publish; export the unknowns "
                             "with to_json or to_yaml")
        return self.unknowns[self.published]

    # ------------------------------------------------------------------------- exports

    def ros2_static_transform(self) -> str:
        """``ros2 run tf2_ros static_transform_publisher ...`` publishing the camera's pose
        (metres) under `ros_frame_ids`."""
        return ros_line(self._published_pose(), self.unit, *self.ros_frame_ids)

    def urdf_joint(self) -> str:
        """The camera's pose as a URDF fixed joint from parent to child link (`ros_frame_ids`)."""
        return urdf_joint(self._published_pose(), self.unit, *self.ros_frame_ids)

    def xacro(self) -> str:
        """A xacro file with macro ``handeye_calibration`` adding that joint (params parent, child)."""
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
        if images is not None:  # where the board poses came from, the intrinsics, the images' stations
            from handeye.workflow.image_stations import inputs_entry, result_entries

            result["inputs"]["camera"] = inputs_entry(cell, images)
            result.update(result_entries(cell, images))
        return result

    @property
    def _inverted(self) -> bool:
        return self.cell.camera is not None and self.cell.camera.poses == "camera-in-board"

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
                       inputs={"robot file": f"{cell.robot.file} ({robot_file.format}, {robot_file.unit})",
                               "camera " + ("images" if images is not None else "file"): camera_input},
                       robot_poses=robot.poses, stations=len(robot), pairing=self.pairing, command=command,
                       images=None if images is None else image_entries(
                           images, cell.images.board, cell.setup, robot.poses, self.solution.unknowns,
                           intrinsics_source(cell)))

    def write_report(self, path: str | Path, *, force: bool = False, command: str = "handeye.calibrate(cell)",
                     words: Callable[[str], str] | None = None) -> list[Path]:
        """Write the quality report to `path` (.html: one self-contained page; .md: markdown with
        its PNG plots next to it); an existing file is replaced only with `force`. Written also
        for an unusable answer: it shows why. Returns the files written."""
        from handeye.workflow.quality_report import write_report

        return write_report(path, self.report_data(command=command, words=words), force=force)
