"""``handeye.calibrate(cell)`` for a kinematic calibration: a cell that recorded the robot's joint
readings (`Cell.joints`) with the arm's nominal DH table (`Cell.arm`) instead of flange poses,
solved by the problem made from joint readings (`Problem.from_joints`, ``axyb-kinematic``).

1. read the arm file (`handeye.io.arm_files`: its length unit is the answer's) and the joint
   readings (`handeye.io.joint_files`), put the joints in the arm's order (by name when the file
   names them as the arm does, else by position);
2. the robot's stream is the arm's nominal forward kinematics of the readings, with the joint
   file's names and stamps, so that the camera's poses or board images are paired with it as with
   a robot pose file (`handeye.workflow.stations`, `handeye.workflow.image_stations`: row, name or
   time; each station keeps its readings);
3. the problem makes its data from the stations (`JointStations`: flange poses, camera poses
   T_cam_target in the arm's unit, readings in rad, the nominal table) and the cell's solver, or
   the default, solves; the residuals per station;
4. `kinematics_entry`: the DH corrections with their 1-sigma in the arm file's units, the
   parameters hand-eye data cannot determine in words, and the corrected table as an arm file
   (`CalibrationResult.arm_yaml`) for the controller.

The plausibility checks of pose files (Euler order, inverted poses, ...) do not apply: the solve's
self-check and the problem's own validation (readings against the table, enough motion) do.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from handeye.framework.api import solve
from handeye.framework.errors import InputError
from handeye.framework.problem import JointStations
from handeye.framework.registry import get_registry
from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import inverse
from handeye.io.arm_files import ANGLE_UNITS, ArmModel, arm_yaml, read_arm
from handeye.io.joint_files import JointStack, read_joints
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import Cell
from handeye.workflow.image_stations import image_stations
from handeye.workflow.result import CalibrationResult
from handeye.workflow.solving import default_solver, time_limit
from handeye.workflow.stations import Log, pose_stations, take

#: how the inputs name joint readings; the robot stream made from them holds matrices
JOINTS_FORMAT = "joints"


def read_inputs(cell: Cell) -> tuple[ArmModel, JointStack]:
    """The cell's arm model and joint readings (joints in the arm's order); InputError naming the
    setting (```arm```, ```joints```)."""
    try:
        arm = read_arm(cell.arm)
    except InputError as exc:
        raise InputError(f"`arm`: {exc}") from None
    try:
        joints = read_joints(cell.joints.file, cell.joints.unit, topic=cell.joints.topic).ordered(arm.names)
    except InputError as exc:
        text = str(exc).replace("the joint unit must be", "`joints.unit` must be")
        text = text.replace("the unit of the joint readings is required (deg or rad)",
                            "`joints.unit` is required (deg or rad)")
        text = text.replace("give the unit deg", "give `joints.unit: deg`")
        text = re.sub(r"drop the unit (\w+)", r"drop `joints.unit: \1`", text)
        text = text.replace("name its sensor_msgs/JointState topic", "name its sensor_msgs/JointState topic with "
                            "`joints.topic`")
        raise InputError(f"`joints`: {text}") from None
    return arm, joints


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


def calibrate_joints(cell: Cell, log: Log | None = None, *, workers: int | None = None,
                     cache: Any = None) -> CalibrationResult:
    """Calibrate a cell of joint readings (module docstring); `log`, `workers` and `cache` (how
    board images are detected) as `handeye.calibrate`'s."""
    arm, joints = read_inputs(cell)
    unit = arm.unit
    robot_file = PoseStack(_frozen(arm.forward(joints.q)), unit, "matrix", joints.names, joints.stamps,
                           None, str(cell.joints.file))
    try:
        stations = (image_stations(cell, log, robot=robot_file, workers=workers, cache=cache)
                    if cell.images is not None else pose_stations(cell, log, robot_file=robot_file))
    except InputError as exc:
        raise InputError(str(exc).replace("`robot` ", "`joints` ")) from None
    q = joints.q[stations.robot_rows]
    invert = cell.camera is not None and cell.camera.poses == "camera-in-board"
    camera_read = take(stations.camera_file, stations.camera_rows)
    if invert:
        camera_read = dataclasses.replace(camera_read, poses=_frozen(inverse(camera_read.poses)))
    camera = camera_read.in_unit(unit)
    problem = get_registry().problem(cell.problem)
    fields = problem.from_joints(JointStations(arm.dh.forward(q), np.array(camera.poses), q, arm.dh.table),
                                 cell.setup)
    options = cell.solver_options()
    clash = sorted(set(options) & set(fields))
    if clash:
        raise InputError(f"`options` {clash} clash with the data field(s) of problem {cell.problem!r}")
    solver = cell.solver or default_solver(cell.problem)
    solution = solve(cell.problem, solver=solver, backend=cell.backend,
                     time_limit=time_limit(cell.time_limit, cell.problem, solver), **fields, **options)
    residuals = problem.residuals(problem.validate(**fields), solution.unknowns)
    solution = in_arm_frames(solution, arm)
    kinematics = kinematics_entry(cell, arm, joints, solution.diagnostics)
    return CalibrationResult(cell=cell, solution=solution, solver=solver, unit=unit, stations=stations,
                             camera=camera, camera_read=camera_read, residuals=residuals, checks=None, pairing=None,
                             facts={}, warnings=(*stations.warnings, *solution.warnings), kinematics=kinematics)


def in_arm_frames(solution: Any, arm: ArmModel) -> Any:
    """The solution with X and Y in the arm model's base and tip frames when it has base and tool
    transforms: the problem solves FK_DH(q) X' = Y' B, and base FK_DH(q) tool X = Y B gives
    X = tool^-1 X', Y = base Y' (their 1-sigma, of right perturbations, are unchanged)."""
    if arm.base is None and arm.tool is None:
        return solution
    unknowns = dict(solution.unknowns)
    if arm.tool is not None:
        unknowns["X"] = _frozen(inverse(arm.tool) @ unknowns["X"])
    if arm.base is not None:
        unknowns["Y"] = _frozen(arm.base @ unknowns["Y"])
    return dataclasses.replace(solution, unknowns=unknowns)


def kinematics_entry(cell: Cell, arm: ArmModel, joints: JointStack, diagnostics: dict[str, Any]) -> dict[str, Any]:
    """The result's ``kinematics`` entry: the inputs, every identified DH parameter (nominal,
    estimate, correction, 1-sigma) in the arm file's units, the parameters not identifiable (names
    and why), the table of the answer (the fitted one when the answer uses it, else the nominal)
    as rows and as an arm file's text (``arm_yaml``)."""
    fitted = diagnostics.get("kinematics") or {}
    angle = ANGLE_UNITS[arm.angle_unit]
    used = bool(fitted.get("used", False))
    table = np.array(fitted["dh"], dtype=float) if used and "dh" in fitted else arm.dh.table
    answer = dataclasses.replace(arm, dh=DHArm.from_table(table))
    parameters = []
    for p in fitted.get("parameters", ()):
        joint, kind = p["name"].split()
        j = int(joint[1:]) - 1
        s = 1.0 if p["unit"] == "length" else 1.0 / angle
        parameters.append({"name": f"{arm.names[j]} {kind}", "joint": arm.names[j], "parameter": kind,
                           "unit": arm.unit if p["unit"] == "length" else arm.angle_unit,
                           **{k: float(p[k]) * s for k in ("nominal", "estimate", "correction", "std")}})
    named = [f"{arm.names[int(n.split()[0][1:]) - 1]} {n.split()[1]}" for n in fitted.get("not_identifiable", ())]
    why = re.sub(r"\bJ(\d+) ", lambda m: f"{arm.names[int(m.group(1)) - 1]} ", fitted.get("why", ""))
    rows = [{"name": name, "a": float(r[0]), "alpha": float(r[1] / angle), "d": float(r[2]),
             "offset": float(r[3] / angle)} for name, r in zip(arm.names, table)]
    note = ("the nominal table: the answer kept the nominal arm (see the warnings)" if not used else
            f"{len(parameters)} parameters corrected; not identifiable from hand-eye data, kept nominal: "
            f"{why or ', '.join(named) or 'none'}")
    header = (f"DH table of {arm.source or 'the arm'} corrected by handeye calibrate (problem {cell.problem}, "
              f"{len(joints)} joint readings from {cell.joints.file})\n{note}")
    return {
        "inputs": {"file": str(cell.joints.file), "format": f"{JOINTS_FORMAT} ({joints.unit}) + arm {arm.source}",
                   "unit": arm.unit, "poses": len(joints), "joints": list(arm.names)},
        "arm": arm.source, "frames": None if arm.frames is None else list(arm.frames), "length_unit": arm.unit, "angle_unit": arm.angle_unit, "used": used,
        "parameters": parameters, "not_identifiable": named, "not_identifiable_why": why,
        "dh": rows, **{key: getattr(arm, key).tolist() for key in ("base", "tool") if getattr(arm, key) is not None},
        "arm_yaml": arm_yaml(answer, header=header),
    }


def kinematics_lines(k: dict[str, Any]) -> list[str]:
    """The printout of a ``kinematics`` entry (`kinematics_entry`): the corrections with their
    1-sigma, and what is not identifiable, in words."""
    lu, au = k["length_unit"], k["angle_unit"]
    chain = f", {k['frames'][0]} to {k['frames'][1]}" if k.get("frames") else ""
    head = (f"kinematics ({k['arm']}{chain}; lengths in {lu}, angles in {au}): "
            + (f"{len(k['parameters'])} DH parameters identified and used in the answer" if k["used"] else
               f"{len(k['parameters'])} DH parameters fitted, not used: the answer keeps the nominal arm"))
    width = max([14, *(len(p["name"]) + 2 for p in k["parameters"])])
    lines = ["", head, f"  {'parameter':<{width}}{'nominal':>12}{'estimate':>16}{'correction':>13}{'1-sigma':>10}"]
    for p in k["parameters"]:
        nominal = 0.0 if abs(p["nominal"]) < 1e-12 else p["nominal"]  # a converted URDF's dust
        lines.append(f"  {p['name']:<{width}}{nominal:>12.6g}{p['estimate']:>16.8g}{p['correction']:>+13.4g}"
                     f"{p['std']:>10.2g}")
    if k["not_identifiable"]:
        why = k["not_identifiable_why"] or ", ".join(k["not_identifiable"])
        lines.append(f"  not identifiable from hand-eye data, kept nominal: {why}")
    return lines


__all__ = ["JOINTS_FORMAT", "calibrate_joints", "kinematics_entry", "kinematics_lines", "read_inputs"]
