"""``handeye calibrate``: from a cell's two pose files to the hand-eye transform, exported.

Reads the robot's flange poses (``--robot``, T_base_flange, e.g. a FANUC export ``x,y,z,w,p,r``)
and the camera's board poses (``--camera``, T_cam_target: the pose of the calibration board in
the camera frame, as cv2.solvePnP gives it, in any pose format; ``--camera-poses camera-in-board``
for T_target_cam, inverted on reading), pairs them into stations (``--match row``, default: row k
of both files is station k; ``name``: equal name columns; ``time``: each camera pose with the robot
pose at the nearest time stamp within ``--max-dt``, no interpolation; ``interpolate``: the robot
stream interpolated at each camera stamp + the clock offset, estimated or given, docs/streams.md), solves, and prints the unknowns with their frames, 1-sigma uncertainties,
residuals and a ROS 2 static_transform_publisher line; ``-o`` / ``--yaml`` write the same as
JSON / YAML (the output says "wrote FILE"; an existing file is kept, and nothing solved, unless
``--force`` is given).

Board images instead of a camera file: ``--images DIR --board SPEC [--intrinsics FILE]`` detects
the board in each image, calibrates the camera from the same images without ``--intrinsics``,
solves the board poses and pairs them with the robot poses (``--match index|name|time``); an
image that fails is dropped with its robot pose (docs/images.md). ``--robot`` may also be a
folder of one pose file per station (ROS-Industrial's ``poses/N.yaml``).

What is solved (docs/conventions.md): ``--problem axyb`` (default) finds both unknowns from the
stations, eye-in-hand X = T_flange_cam and Y = T_base_target, eye-to-hand X = T_flange_target and
Y = T_base_cam; ``--problem axxb`` finds only the camera, X = T_flange_cam (eye-in-hand) or
T_base_cam (eye-to-hand), from the motions between stations (``--pairing``).

Units: each file's translations are in its ``--robot-unit`` / ``--camera-unit``, else in the
unit the file states (JSON / YAML / NPZ ``units``), else the robot maker's (FANUC, KUKA, ABB,
Staubli, Yaskawa: mm; UR: m); generic formats (matrix, quaternion, rotation vector, opencv-rvec)
need the flag. The camera's translations are converted to the robot's unit, and every answer is
in the robot's unit (the ROS line in metres). Formats and their conventions: docs/formats.md
("Pose files of robots and cameras"); this command: docs/calibrate.md.

ROS: the line publishes the camera's pose (eye-in-hand X = T_flange_cam, parent ``flange``;
eye-to-hand T_base_cam, parent ``base``) with child ``camera_optical_frame``: the camera frame
of solvePnP is the optical frame (z forward, x right, y down), not a driver's ``camera_link``.
``--frame-ids PARENT,CHILD`` names your frames (e.g. ``tool0,camera_color_optical_frame``).

Plausibility checks (always, unless ``--no-checks``; handeye.plausibility): residuals beyond
what a calibrated cell's noise allows, or a usual setup mistake (Euler order, inverted camera
or robot poses, the other setup, pairs shifted by one, camera unit x1000) that explains the data
far better, give status ``unreliable``, a warning naming the mistake and its flag, and exit 1;
duplicated stations and fewer than 5 stations give warnings.

Exit codes as handeye solve: 0 success; 2 bad input (file, format, unit, counts); 1 the solver
failed or ended not_converged / failed, or the checks found the fit unreliable: these file
checks, or the self-check every solve runs (residuals against the noise the data show, distance
from the best fit; docs/reliability.md; not skipped by --no-checks). The answer is then printed
for inspection, no -o / --yaml file is written; a --report is, to see why.

``--report FILE`` writes a quality report: .html (one self-contained page, plots embedded) or .md
(its PNG plots next to it): the answer with 1-sigma, the residual per station with the outliers
marked, the data diagnostics and checks, a 3D plot of the poses and solved frames, and the
warnings with what to do (handeye.quality_report; docs/calibrate.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import shlex
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.checks.plausibility import Streams, check
from handeye.cli import _facts, _images, _matching, _streams
from handeye.cli._common import (
    _plain,
    add_force_flag,
    add_time_limit_flag,
    check_new_file,
    check_outputs_apart,
    dump_json,
    format_pose,
    in_cli_words,
    parse_key_values,
    time_limit,
)
from handeye.cli.solve_cmd import (
    EQUATIONS,
    FRAMES,
    UNUSABLE,
    _setup_note,
    default_solver,
    noise_lines,
)
from handeye.framework.api import solve
from handeye.framework.errors import InputError
from handeye.framework.registry import get_registry
from handeye.framework.solution import Status, standard_deviations
from handeye.geometry.se3 import inverse
from handeye.io.data_files import PAIRINGS, SETUPS, from_poses
from handeye.io.output_files import write_text
from handeye.io.pose_formats import format_names, parse_format
from handeye.io.pose_readers import UNITS, PoseStack, read_pose_dir, read_poses
from handeye.streams.station_matching import MATCHES
from handeye.workflow.quality_report import (
    check_new_report,
    collect,
    report_files,
    write_report,
)
from handeye.workflow.report_images import image_entries

NAME = "calibrate"
#: what the camera file holds: board-in-camera = T_cam_target (as solvePnP), camera-in-board = T_target_cam
CAMERA_POSES = ("board-in-camera", "camera-in-board")
#: a ROS frame id as --frame-ids takes it: ROS graph resource names (letters, digits, underscores,
#: starting with a letter; '/' separating namespaces), which a shell never interprets
ROS_FRAME_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*")
#: metres per unit
METRES = {"mm": 1e-3, "m": 1.0}
#: (problem, setup) -> (unknown published on ROS, default parent frame id, default child frame id):
#: always the camera's pose (the camera frame is solvePnP's optical frame: z forward, x right, y down)
ROS_FRAMES: dict[tuple[str, str], tuple[str, str, str]] = {
    ("axyb", "eye-in-hand"): ("X", "flange", "camera_optical_frame"),
    ("axyb", "eye-to-hand"): ("Y", "base", "camera_optical_frame"),
    ("axxb", "eye-in-hand"): ("X", "flange", "camera_optical_frame"),
    ("axxb", "eye-to-hand"): ("X", "base", "camera_optical_frame"),
}


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="calibrate from a robot pose file and a camera pose file, and export",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    formats = ", ".join(format_names())
    parser.add_argument("--robot", required=True, metavar="FILE",
                        help="robot flange poses T_base_flange, one per station (.csv .tsv .txt .json .yaml .npz)")
    parser.add_argument("--robot-format", metavar="FORMAT", help=f"format of --robot (not for ROS bags): {formats}")
    parser.add_argument("--camera", metavar="FILE",
                        help="board poses in the camera frame T_cam_target (solvePnP's rvec, tvec), one per "
                             "station, in the robot file's order (see --camera-poses, --match)")
    parser.add_argument("--camera-format", metavar="FORMAT",
                        help="format of --camera, not for ROS bags (opencv-rvec for solvePnP's rvec then tvec, or any of the above)")
    for which in ("robot", "camera"):
        parser.add_argument(f"--{which}-columns", metavar="LAYOUT",
                            help=f"what each column of --{which} holds, in file order, comma separated: the format's "
                                 "fields (e.g. qw,qx,qy,qz,x,y,z for a quaternion-first file read as xyz-quat-xyzw), "
                                 "t for time stamps, name, - to skip a column; default: by header, else by position")
    parser.add_argument("--camera-poses", choices=CAMERA_POSES, default="board-in-camera",
                        help="board-in-camera (default): the camera file holds T_cam_target; camera-in-board: it "
                             "holds T_target_cam (the camera's pose in the board frame), inverted on reading")
    _images.add_flags(parser)  # --images, --board, --intrinsics: board images instead of --camera
    parser.add_argument("--match", choices=(*MATCHES, "index", _streams.INTERPOLATE), default="row",
                        help="how robot and camera poses are paired into stations: row (default): row k of both "
                             "files; name: equal name/index columns; time: each camera pose with the robot pose "
                             "at the nearest time stamp within --max-dt (no interpolation), others dropped; "
                             "interpolate: the robot stream interpolated at each camera stamp + the clock offset "
                             "(--time-offset, estimated by default; docs/streams.md)")
    parser.add_argument("--max-dt", type=float, metavar="SECONDS",
                        help="--match time: largest |camera stamp - robot stamp| paired (default: half the median "
                             "interval between robot stamps, or 0.02 s with fewer than two robot stamps)")
    _streams.add_flags(parser)
    parser.add_argument("--setup", required=True, choices=SETUPS,
                        help="eye-in-hand: camera on the flange, board fixed; eye-to-hand: camera fixed, board "
                             "on the flange")
    parser.add_argument("--problem", default="axyb", choices=("axyb", "axxb"),
                        help="axyb (default): hand-eye and robot-world from the stations; axxb: hand-eye only, "
                             "from the motions between stations")
    parser.add_argument("--robot-unit", choices=UNITS, help="length unit of --robot (default: the file's or the "
                                                            "robot maker's); the answer is in this unit")
    parser.add_argument("--camera-unit", choices=UNITS, help="length unit of --camera (default: the file's); "
                                                             "converted to the robot's")
    parser.add_argument("--orthonormalize", action="store_true",
                        help="re-orthonormalise rotation matrices / normalise quaternions exported with few "
                             "decimals (both files)")
    parser.add_argument("--pairing", choices=PAIRINGS,
                        help="axxb: motions between all pairs of stations (default) or consecutive ones")
    parser.add_argument("--solver", help="solver (default: 'auto' if installed, else 'kron-lstsq'); see handeye list")
    parser.add_argument("--backend", help="backend of the solver (default: the solver's default)")
    parser.add_argument("--option", action="append", metavar="KEY=VALUE", help="solver option, repeatable")
    _facts.add_flags(parser, "the robot file's length unit")
    parser.add_argument("-o", "--output", metavar="FILE", help="write the result as JSON (an existing file is kept "
                                                              "unless --force)")
    parser.add_argument("--yaml", metavar="FILE", help="write the result as YAML (an existing file is kept unless --force)")
    parser.add_argument("--report", metavar="FILE",
                        help="write a quality report: .html (one self-contained page with plots) or .md (markdown, "
                             "its PNG plots next to it); written also when the answer is unusable, to see why")
    parser.add_argument("--frame-ids", metavar="PARENT,CHILD",
                        help="frame ids of the ROS line (default flange,camera_optical_frame eye-in-hand; "
                             "base,camera_optical_frame eye-to-hand)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON instead of text")
    parser.add_argument("--no-checks", action="store_true",
                        help="skip the plausibility checks (residuals against the cell's noise, the usual setup "
                             "mistakes, duplicated stations, too few stations; docs/calibrate.md)")
    add_force_flag(parser)
    add_time_limit_flag(parser)
    parser.set_defaults(run=run)
    return parser


# ----------------------------------------------------------------------------- reading


def _read(path: str, fmt: str, unit: str | None, orthonormalize: bool, which: str,
          layout: str | None = None) -> PoseStack:
    """One stream, with the messages' API names replaced by this command's flags; `layout`: its
    --robot-columns / --camera-columns text (the file's columns in order, comma separated)."""
    try:
        if Path(path).is_dir():  # a folder: one pose file per station
            if layout is not None:
                raise InputError(f"--{which}-columns applies to a pose file, not to a folder of them")
            return read_pose_dir(path, fmt, unit=unit, orthonormalize=orthonormalize)
        columns = None if layout is None else [c.strip() for c in layout.split(",")]
        return read_poses(path, fmt, unit=unit, orthonormalize=orthonormalize, layout=columns)
    except InputError as exc:
        text = (str(exc).replace("pass unit='mm' or unit='m' (CLI --unit)", f"pass --{which}-unit mm or m")
                .replace("with orthonormalize=True (CLI --orthonormalize)", "with --orthonormalize")
                .replace("or pass degrees=True/False (CLI --degrees/--radians)", "")
                .replace("but unit=", f"but --{which}-unit ").replace(" was passed", " was given"))
        text = re.sub(r"layout=\[[^\]]*\] \(CLI --robot-columns / --camera-columns ([^)]*)\)",
                      rf"--{which}-columns \1", text)
        raise InputError(f"--{which}: {text}") from None


def _rereader(path: str, stack: PoseStack, unit: str, orthonormalize: bool, rows: np.ndarray | None = None,
              invert: bool = False):
    """For an Euler format: seq -> the same file read with that Euler sequence (same columns,
    angle unit and length unit), translations in `unit`, the paired `rows` only (default all),
    inverted if `invert`; None for other formats."""
    fmt = parse_format(stack.format)
    if fmt.kind != "euler":
        return None

    def reread(seq: str) -> np.ndarray:
        other = dataclasses.replace(fmt, seq=seq, name=f"euler:{seq}")
        poses = read_poses(path, other, unit=stack.unit, orthonormalize=orthonormalize).in_unit(unit).poses
        poses = poses if rows is None else poses[rows]
        return inverse(poses) if invert else poses

    return reread


# ----------------------------------------------------------------------------- the result


def pose_entry(T: np.ndarray, robot_format: str, std: dict[str, float] | None) -> dict[str, Any]:
    """One unknown as a 4x4, as [x, y, z, qx, qy, qz, qw] (w >= 0), as a row of the robot's
    format (not for matrix formats) and its 1-sigma (rotation deg, translation robot unit)."""
    T = np.asarray(T, dtype=float)
    q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
    entry: dict[str, Any] = {"matrix": T.tolist(), "xyz_quat": [*T[:3, 3].tolist(), *q.tolist()]}
    fmt = parse_format(robot_format)
    if fmt.kind != "matrix":
        entry["robot_format"] = dict(zip(fmt.fields, fmt.to_rows(T[None])[0].tolist()))
    entry["std"] = None if std is None else {"rotation_deg": math.degrees(std["rotation"]),
                                             "translation": std["translation"]}
    return entry


def ros_line(T: np.ndarray, unit: str, parent: str, child: str) -> str:
    """``ros2 run tf2_ros static_transform_publisher`` publishing T = T_parent_child (the child
    frame's pose in the parent's), translation converted from `unit` to metres."""
    t = np.asarray(T, dtype=float)[:3, 3] * METRES[unit]
    q = Rotation.from_matrix(np.asarray(T, dtype=float)[:3, :3]).as_quat(canonical=True)
    values = " ".join(f"--{k} {v:.9g}" for k, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), [*t, *q]))
    return (f"ros2 run tf2_ros static_transform_publisher {values} --frame-id {shlex.quote(parent)} "
            f"--child-frame-id {shlex.quote(child)}")  # valid ids need no quotes: quoted all the same


def _frame_ids(text: str | None, default: tuple[str, str]) -> tuple[str, str]:
    """(parent, child) of --frame-ids PARENT,CHILD, each a ROS name (`ROS_FRAME_ID`)."""
    if text is None:
        return default
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise InputError(f"--frame-ids expects PARENT,CHILD (two frame ids), got {text!r}")
    for part in parts:
        if not ROS_FRAME_ID.fullmatch(part):
            raise InputError(f"--frame-ids: {part!r} is not a ROS frame id (letters, digits and underscores, "
                             "starting with a letter, '/' between namespaces: e.g. tool0, camera_link, "
                             "robot1/base_link)")
    return parts[0], parts[1]


def _summary(values: np.ndarray) -> dict[str, float]:
    values = np.asarray(values, dtype=float)
    return {"median": float(np.median(values)), "rms": float(np.sqrt(np.mean(values**2))),
            "max": float(np.max(values))}


def run(args: argparse.Namespace) -> int:
    _streams.check_flags(args)
    from_images = _images.check_flags(args)  # --images instead of --camera (one of them, checked)
    for flag, fmt, path in (("--robot-format", args.robot_format, args.robot),
                            ("--camera-format", args.camera_format, args.camera)):
        if path is None:  # --images
            continue
        if not _streams.check_format(flag, fmt, path):
            continue
        try:
            parse_format(fmt)
        except InputError as exc:
            raise InputError(f"{flag}: {exc}") from None
    outputs = [("-o", args.output), ("--yaml", args.yaml)]
    if args.report:
        check_new_report(args.report, args.force)
        outputs += [("--report", p) for p in report_files(args.report)]
    check_outputs_apart(outputs, [args.robot, args.images if from_images else args.camera,
                                  getattr(args, "intrinsics", None), getattr(args, "board", None)])
    for flag, path in (("-o", args.output), ("--yaml", args.yaml)):
        check_new_file(flag, path, args.force)
    if args.pairing is not None and args.problem != "axxb":
        raise InputError("--pairing applies to --problem axxb (motions between stations); with axyb every "
                         "station is one pair: drop it")
    parent, child = _frame_ids(args.frame_ids, ROS_FRAMES[(args.problem, args.setup)][1:])
    options = parse_key_values(args.option)
    facts = _facts.take(args, options)
    if from_images and facts.get("camera_scale") == "unknown":
        raise InputError("--camera-scale unknown does not apply to --images: the board's size gives the camera's "
                         "translations in the board's unit; drop it")

    images, robot_file, camera_file, robot, robot_rows, camera_rows, matching, warnings = _matching.stations(
        args, from_images, _read)
    invert = args.camera_poses == "camera-in-board"
    camera_read = _matching.take(camera_file, camera_rows)
    if invert:
        inverted = inverse(camera_read.poses)
        inverted.setflags(write=False)
        camera_read = dataclasses.replace(camera_read, poses=inverted)
    camera = camera_read.in_unit(robot.unit)
    if args.json and "message" in matching and not from_images:  # the image path printed it with its summary
        print(matching["message"], file=sys.stderr)
    pose_file = from_poses(robot.poses, camera.poses, args.problem, setup=args.setup, pairing=args.pairing,
                           metadata={"units": robot.unit}, source=f"{args.robot} + {args.camera or args.images}")
    clash = sorted(set(options) & set(pose_file.data))
    if clash:
        raise InputError(f"--option {clash} clashes with the data field(s) of problem {args.problem!r}")
    solver = args.solver or (images and _images.default_solver(args.problem)) or default_solver(args.problem)
    solution = solve(args.problem, solver=solver, backend=args.backend, time_limit=time_limit(args, args.problem, solver),
                     **pose_file.data, **facts, **options,
                     **_images.solver_data(images, solver, args.problem))
    instead = _images.pose_based_instead(solution, defaulted=args.solver is None)
    if instead:
        solver = default_solver(args.problem)
        solution = solve(args.problem, solver=solver, **pose_file.data, **facts, **options)
        warnings.append(instead)

    problem = get_registry().problem(args.problem)
    measured = _facts.in_robot_unit(pose_file.data, facts, solution.diagnostics)
    residuals = problem.residuals(problem.validate(**measured, **facts), solution.unknowns)
    report = None
    if not args.no_checks and solution.status not in UNUSABLE:
        report = check(Streams(robot.poses, camera.poses, robot.unit, args.setup, args.problem,
                               pose_file.metadata.get("pairing"), facts=facts, robot_format=robot.format,
                               camera_format=camera_read.format, camera_unit=camera_read.unit,
                               reread_robot=None if robot_rows is None else _rereader(
                                   args.robot, robot, robot.unit, args.orthonormalize, robot_rows),
                               reread_camera=_rereader(args.camera, camera_read, robot.unit, args.orthonormalize,
                                                       camera_rows, invert)),
                       residuals)
        warnings += list(report.warnings)
        if not report.plausible:
            solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    if not _streams.reliable(matching) and solution.status not in UNUSABLE:  # the clock offset is not trusted
        solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    diagnostics = solution.diagnostics
    std_all = standard_deviations(diagnostics)
    frames = FRAMES[(args.problem, args.setup)]
    unit = robot.unit
    unknowns = {name: pose_entry(T, robot.format, std_all.get(name)) for name, T in solution.unknowns.items()}
    published, _, _ = ROS_FRAMES[(args.problem, args.setup)]
    ros = ros_line(solution.unknowns[published], unit, parent, child)
    item = EQUATIONS[args.problem][1]
    result: dict[str, Any] = {
        **{name: e["matrix"] for name, e in unknowns.items()},
        "frames": {name: frames[name][0] for name in solution.unknowns},
        "units": {"translation": unit, "rotation": "deg"},
        "setup": args.setup,
        "problem": args.problem,
        "solver": solution.solver,
        "backend": solution.backend,
        "status": str(solution.status),
        "seconds": solution.seconds,
        "stations": len(robot),
        "matching": matching,
        **({"pairing": pose_file.metadata["pairing"]} if "pairing" in pose_file.metadata else {}),
        "poses": {name: {k: v for k, v in e.items() if k != "matrix"} for name, e in unknowns.items()},
        "std": {name: e["std"] for name, e in unknowns.items()} if std_all else None,
        "residuals": {
            "per": item, "count": len(residuals["rotation"]),
            "rotation_deg": _summary(np.degrees(residuals["rotation"])),
            "translation": _summary(residuals["translation"]),
            "per_" + item: {"rotation_deg": np.degrees(residuals["rotation"]).tolist(),
                            "translation": np.asarray(residuals["translation"]).tolist()},
        },
        "warnings": [*warnings, *solution.warnings],
        "checks": None if report is None else report.to_dict(),
        "inputs": {
            "robot": {"file": args.robot, "format": robot.format, "unit": robot.unit, "poses": len(robot_file)},
            "camera": {"file": args.camera, "format": camera_read.format, "unit": camera_read.unit,
                       "poses": len(camera_file), "holds": "T_target_cam" if invert else "T_cam_target"},
            "orthonormalize": bool(args.orthonormalize),
        },
        "ros": {"command": ros, "unknown": published, "frame_id": parent, "child_frame_id": child,
                "translation_unit": "m"},
    }
    if images is not None:  # where the board poses came from, the intrinsics, the images' stations
        result["inputs"]["camera"] = _images.inputs_entry(args, images)
        result.update(_images.result_entries(args, images))
    unusable = solution.status in UNUSABLE or solution.status is Status.UNRELIABLE
    written = [] if unusable else _write(result, args.output, args.yaml, args.force)
    if args.report:
        camera_input = (f"{args.images} (images, board {args.board})" if images is not None
                        else f"{args.camera} ({camera_read.format}, {camera_read.unit})")
        data = collect(problem=args.problem, setup=args.setup, unit=unit, solution=solution, residuals=residuals,
                       frames=frames, checks=result["checks"], warnings=[in_cli_words(w) for w in result["warnings"]],
                       inputs={"robot file": f"{args.robot} ({robot.format}, {robot.unit})",
                               "camera " + ("images" if images is not None else "file"): camera_input},
                       robot_poses=robot.poses, stations=len(robot), pairing=pose_file.metadata.get("pairing"),
                       command=getattr(args, "command_line", "handeye calibrate"),
                       images=None if images is None else image_entries(
                           images.image_set, args.board, args.setup, robot.poses, solution.unknowns,
                           args.intrinsics or "calibrated from the images"))
        written.append(str(write_report(args.report, data, force=args.force)[0]))
    if args.json:
        print(dump_json(result))
    else:
        print(in_cli_words(_text(result, frames, solution.diagnostics)))
    for path in written:
        print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout)
    if solution.status is Status.UNRELIABLE:
        why = report.warnings[0] if report and not report.plausible else next(iter(warnings), "")
        print(in_cli_words(f"handeye: error: status unreliable: {why}; no result file was written "
                           "(--no-checks skips the checks)"), file=sys.stderr)
        return 1
    if unusable:
        print(f"handeye: error: solver {solver!r} ended with status {solution.status}: its "
              f"{', '.join(solution.unknowns)} (printed above) are not an answer and no result file was written; "
              "try another solver", file=sys.stderr)
        return 1
    return 0


def _write(result: dict[str, Any], json_path: str | None, yaml_path: str | None, force: bool) -> list[str]:
    written = []
    if json_path:
        write_text(json_path, dump_json(result) + "\n", force=force, flag="-o")
        written.append(json_path)
    if yaml_path:
        import yaml

        write_text(yaml_path, yaml.safe_dump(_plain(result), sort_keys=False, default_flow_style=None),
                   force=force, flag="--yaml")
        written.append(yaml_path)
    return written


def _text(r: dict[str, Any], frames: dict[str, tuple[str, str]], diagnostics: dict[str, Any]) -> str:
    unit = r["units"]["translation"]
    inp = r["inputs"]
    cam_unit = inp["camera"]["unit"] + (f", converted to {unit}" if inp["camera"]["unit"] != unit else "")
    if inp["camera"].get("holds") == "T_target_cam":
        cam_unit += ", T_target_cam inverted"
    equation, item = EQUATIONS[r["problem"]]
    lines = [(f"{r['stations']} stations: robot {inp['robot']['file']} ({inp['robot']['format']}, {unit}), "
              f"camera {inp['camera']['file']} ({inp['camera']['format']}, {cam_unit})"),
             # the image path prints its pairing with the images' summary, before this
             *([r["matching"]["message"]] if "message" in r["matching"] and not inp["camera"]["format"].startswith("images")
               else []),
             f"{r['setup']}, problem {r['problem']} ({equation})"
             + (f", {r['residuals']['count']} motions ({r['pairing']} pairs of stations)" if "pairing" in r else ""),
             f"solver {r['solver']} (backend {r['backend']}): status {r['status']}, {r['seconds'] * 1e3:.1f} ms"
             + _setup_note(diagnostics)]
    for name in frames:
        if name not in r["poses"]:
            continue
        p = r["poses"][name]
        lines += ["", f"{name} = {frames[name][0]} ({frames[name][1]}), lengths in {unit}:", format_pose(np.array(r[name]))]
        x = p["xyz_quat"]
        lines.append(f"  xyz  {x[0]:.6g} {x[1]:.6g} {x[2]:.6g}   quaternion (x, y, z, w)  "
                     + " ".join(f"{v:.8f}" for v in x[3:]))
        if "robot_format" in p:
            lines.append(f"  {inp['robot']['format']}  " + "  ".join(f"{k}={v:.6g}" for k, v in p["robot_format"].items()))
        if p["std"] is not None:
            lines.append(f"  1-sigma  rotation {p['std']['rotation_deg']:.3g} deg, translation "
                         f"{p['std']['translation']:.3g} {unit} (root of the 3 axes' variances)")
        else:
            lines.append(f"  1-sigma  not reported by solver {r['solver']} (solver auto or refine reports it)")
    res = r["residuals"]
    lines += ["", (f"residuals over the {res['count']} {item}s (angle and distance between the two sides "
                   f"of {equation}):"),
              "  " + " " * 18 + "".join(f"{s:>12}" for s in ("median", "rms", "max"))]
    for label, key in (("rotation [deg]", "rotation_deg"), (f"translation [{unit}]", "translation")):
        lines.append(f"  {label:<18}" + "".join(f"{res[key][s]:12.4g}" for s in ("median", "rms", "max")))
    lines += noise_lines(diagnostics, unit)
    ros = r["ros"]
    lines += ["", f"ROS 2 ({ros['unknown']}: {ros['child_frame_id']} in {ros['frame_id']}, metres):",
              "  " + ros["command"]]
    if r["status"] in ("not_converged", "failed"):
        lines.append(f"warning: status {r['status']}: the solver did not reach its answer; do not use it")
    elif r["status"] == "unreliable":
        lines.append("warning: status unreliable: the residuals are implausible for a calibrated cell; do not use "
                     "this answer (the first warning below says why)")
    elif r["status"] == "uncertified":
        lines.append("note: status uncertified: a valid answer, but the solver could not prove it globally optimal")
    lines += [f"warning: {w}" for w in r["warnings"]]
    return "\n".join(lines)
