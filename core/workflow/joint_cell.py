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

A kinematic fit absorbs what it is given: readings in the wrong unit or order, an arm file's
angles in radians under ``angle_unit: deg``, camera poses in m given as mm or a board 2% off
became DH "corrections" (J2's a by +330 m) beside an answer metres off, ``optimal``. So the cell
gets the checks every pose cell gets (`pose_checks`), on the nominal arm's flange poses: the
plausibility checks of the A X = Y B fit (`handeye.workflow.plausibility`: the usual setup
mistakes, residuals beyond any calibrated cell's) and its camera scale (self-check 5, with what
a kinematic fit would make of it), and the corrections are bounded by what a real arm can be off
its model (`MAX_LENGTH_CORRECTION_MM`, `MAX_ANGLE_CORRECTION_DEG`): beyond, named, and the
status ``unreliable``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError
from handeye.framework.problem_cell import JointStations
from handeye.framework.reported import Reported
from handeye.framework.solution import Status
from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import inverse
from handeye.host.api import solve
from handeye.host.registry import get_registry
from handeye.io.arm_files import ANGLE_UNITS, ArmModel, arm_yaml, read_arm
from handeye.io.joint_files import JointStack, read_joints
from handeye.io.pose_readers import PoseStack
from handeye.workflow.cell import Cell
from handeye.workflow.image_stations import image_stations
from handeye.workflow.result import CalibrationResult
from handeye.workflow.solving import UNUSABLE, default_solver, time_limit
from handeye.workflow.stations import Log, pose_stations, take

#: how the inputs name joint readings; the robot stream made from them holds matrices
JOINTS_FORMAT = "joints"
#: a DH correction beyond these is no real arm's deviation from its model (a manufacturer's
#: calibration corrects tenths of a millimetre and of a degree): a unit or an order is wrong
MAX_LENGTH_CORRECTION_MM = 10.0
MAX_ANGLE_CORRECTION_DEG = 2.0


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
    report, notes = (pose_checks(cell, stations, camera, camera_read, invert) if cell.checks else (None, []))
    notes += beyond_a_real_arm(kinematics)
    if (notes or (report is not None and not report.plausible)) and solution.status not in UNUSABLE:
        solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    found = [*(report.warnings if report is not None else ()), *notes]
    return CalibrationResult(cell=cell, solution=solution, solver=solver, unit=unit, stations=stations,
                             camera=camera, camera_read=camera_read, residuals=residuals, checks=report, pairing=None,
                             facts={}, warnings=(*stations.warnings, *found, *solution.warnings), kinematics=kinematics)


def pose_checks(cell: Cell, stations: Any, camera: PoseStack, camera_read: PoseStack,
                invert: bool) -> tuple[Any, list[str]]:
    """The checks of a pose cell on the A X = Y B fit of the nominal arm's flange poses (the robot
    stream made from the readings) and the camera's: the plausibility report
    (`handeye.workflow.plausibility.check`: camera poses inverted or in another unit, the other
    setup, pairs shifted, residuals beyond any calibrated cell's) and, where the camera's
    translations fit the robot's at another scale (self-check 5), what a kinematic fit makes of
    that: it scales the arm's links instead. Errors of the arm's kinematics, which the kinematic
    fit is for, stay within what a calibrated cell shows."""
    from handeye.checks.scale_checks import (
        SCALE_SIGMAS,
        SCALE_WARN,
        camera_scale_verdict,
    )
    from handeye.io.data_files import from_poses
    from handeye.workflow.plausibility import Streams, check
    from handeye.workflow.reading import rereader

    robot = stations.robot
    cell_problem = get_registry().cell_problem()  # A X = Y B on the stations' poses
    pose_file = from_poses(robot.poses, camera.poses, cell_problem, setup=cell.setup)
    try:
        pose = solve(cell_problem, **pose_file.data)
    except HandEyeError:  # the kinematic fit's own checks speak for it
        return None, []
    problem = get_registry().problem(cell_problem)
    data = problem.validate(**pose_file.data)
    report = check(Streams(robot.poses, camera.poses, robot.unit, cell.setup, cell_problem, None, robot_format="matrix",
                           camera_format=camera_read.format, camera_unit=camera_read.unit,
                           reread_camera=None if cell.images is not None else rereader(
                               cell.camera, camera_read, robot.unit, cell.orthonormalize, stations.camera_rows, invert)),
                   problem.residuals(data, pose.unknowns))
    notes = []
    scale = camera_scale_verdict(problem, data, pose.unknowns)
    # a scale error, not what the kinematics' own errors mimic (tenths of a per mille: the arm's links)
    if scale is not None and abs(scale["scale"] - 1.0) > SCALE_WARN and abs(scale["sigmas"]) > SCALE_SIGMAS:
        notes.append(f"the camera's translations fit the arm's nominal flange poses best when multiplied by "
                     f"{scale['scale']:.4g} (+-{scale['std']:.2g}, {abs(scale['sigmas']):.3g} standard deviations from 1): "
                     "a kinematic fit makes the arm's links that much longer or shorter instead, and the answer is off "
                     "by it; check the camera poses' unit, the board's size and the camera's focal length")
    return report, notes


def beyond_a_real_arm(kinematics: dict[str, Any]) -> list[str]:
    """The warning naming the DH corrections beyond what a real arm is off its model
    (`MAX_LENGTH_CORRECTION_MM`, `MAX_ANGLE_CORRECTION_DEG`), in the arm file's units; [] where
    none is, or the answer keeps the nominal arm."""
    if not kinematics.get("used"):
        return []
    unit, angle_unit = kinematics["length_unit"], kinematics["angle_unit"]
    to_mm = {"mm": 1.0, "m": 1000.0}.get(unit, 1.0)
    to_deg = 1.0 if angle_unit == "deg" else math.degrees(1.0)
    far = [f"{p['name']} by {p['correction']:+.4g} {p['unit']}" for p in kinematics["parameters"]
           if (abs(p["correction"]) * to_mm > MAX_LENGTH_CORRECTION_MM if p["unit"] == unit
               else abs(p["correction"]) * to_deg > MAX_ANGLE_CORRECTION_DEG)]
    if not far:
        return []
    return [f"the kinematic fit corrects {', '.join(far[:4])}{' and more' if len(far) > 4 else ''}: beyond what a real "
            f"arm is off its model ({MAX_LENGTH_CORRECTION_MM:g} mm, {MAX_ANGLE_CORRECTION_DEG:g} deg), so the "
            "corrections stand for a mistake in the inputs: check the joint readings' unit and order against the arm "
            "file's joints, the arm file's units, and the camera poses' unit"]


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
    fitted = Reported.of(diagnostics).kinematics
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
    # corrections of lengths in m are tenths of a millimetre: shown in mm, as an arm's are read
    small = 1000.0 if lu == "m" else 1.0
    fix = "correction" + (" (mm)" if small != 1.0 else "")
    lines = ["", head, f"  {'parameter':<{width}}{'nominal':>12}{'estimate':>16}{fix:>18}{'1-sigma':>10}"]
    for p in k["parameters"]:
        nominal = 0.0 if abs(p["nominal"]) < 1e-12 else p["nominal"]  # a converted URDF's dust
        scale = small if p["unit"] == lu else 1.0
        lines.append(f"  {p['name']:<{width}}{nominal:>12.6g}{p['estimate']:>16.8g}{p['correction'] * scale:>+18.4g}"
                     f"{p['std'] * scale:>10.2g}")
    if small != 1.0:
        lines.append("  (the corrections of lengths and their 1-sigma in mm; nominal and estimate in m, the arm file's unit)")
    if k["not_identifiable"]:
        why = k["not_identifiable_why"] or ", ".join(k["not_identifiable"])
        lines.append(f"  not identifiable from hand-eye data, kept nominal: {why}")
    return lines


__all__ = ["JOINTS_FORMAT", "calibrate_joints", "kinematics_entry", "kinematics_lines", "read_inputs"]
