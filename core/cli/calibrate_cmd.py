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

Several cameras and targets (``--problem axyb-multi``, the default with tables): ``--observations
FILE`` (a table: station, camera, target, the camera's pose of the target) or ``--observations
CAMERA=FILE`` per camera, beside ``--robot`` (one pose per station, matched by its name column);
every X and Y is printed, exported and reported by its camera's or target's name.

A kinematic calibration (``--problem axyb-kinematic``, the default with joints; docs/kinematic.md):
``--joints FILE --joints-unit deg|rad`` (a table with a header: name and/or t, one column per
joint; or a ROS bag with ``--joints-topic``) and ``--arm DH.yaml`` (the nominal standard DH table,
docs/formats.md) instead of ``--robot``: X, Y and the arm's identifiable DH corrections with their
1-sigma are printed, and ``--arm-out FILE`` writes the corrected table for the controller.

Board images instead of a camera file: ``--images DIR --board SPEC [--intrinsics FILE]`` detects
the board in each image, calibrates the camera from the same images without ``--intrinsics``,
solves the board poses and pairs them with the robot poses (``--match index|name|time``); an
image that fails is dropped with its robot pose (docs/images.md). ``--robot`` may also be a
folder of one pose file per station (ROS-Industrial's ``poses/N.yaml``). The images (one camera's
or several cameras') are detected on ``--workers`` threads (default: the cores), and detections of
images seen before are read from the detection cache (``~/.cache/handeye/detections``; not with
``--no-cache``), so a rerun with other options does not detect again.

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

Plausibility checks (always, unless ``--no-checks``; handeye.workflow.plausibility): residuals beyond
what a calibrated cell's noise allows, or a usual setup mistake (Euler order, inverted camera
or robot poses, the other setup, pairs shifted by one, camera unit x1000) that explains the data
far better, give status ``unreliable``, a warning naming the mistake and its flag, and exit 1;
duplicated stations and fewer than 5 stations give warnings.

Exit codes as handeye solve: 0 success; 2 bad input (file, format, unit, counts); 1 the solver
failed or ended not_converged / failed, or the checks found the fit unreliable: these file
checks, or the self-check every solve runs (residuals against the noise the data show, distance
from the best fit; docs/reliability.md; not skipped by --no-checks). The answer is then printed
for inspection, no -o / --yaml file is written; a --report is, to see why (also when the run ends
without an answer: the report then holds the error and what was found before it).

A cell file (YAML; docs/calibrate.md, "Cell files and Python") holds the same settings:
``--config cell.yaml`` reads them (relative paths relative to the file's folder), and flags
given beside it override the file's values; ``--write-config cell.yaml`` writes the settings the
flags (and a ``--config``) give to that file and stops: nothing is read or solved, so a cell is
set up once, versioned, and rerun with ``handeye calibrate --config cell.yaml``. The same in
Python: ``handeye.calibrate(handeye.Cell.from_file("cell.yaml"))``.

``--report FILE`` writes a quality report: .html (one self-contained page, plots embedded) or .md
(its PNG plots next to it): the answer with 1-sigma, the residual per station with the outliers
marked, the data diagnostics and checks, a 3D plot of the poses and solved frames, and the
warnings with what to do (handeye.workflow.quality_report; docs/calibrate.md).
"""

# The docstring above is this command's --help. This module is argparse and printing only: the
# flags become a handeye.Cell (handeye.workflow.cell; `_cell_flags`), handeye.calibrate does the
# work (handeye.workflow.calibration), and the result is printed and written here.

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError
from handeye.cli import _facts
from handeye.cli._cell_flags import cell_words, flag_settings, merged
from handeye.cli._common import (
    _plain,
    add_detection_flags,
    add_force_flag,
    add_time_limit_flag,
    check_outputs,
    check_outputs_apart,
    detection_options,
    dump_json,
    finite_number,
    format_pose,
    in_cli_words,
    parse_key_values,
    spread_note,
    whole_number,
)
from handeye.cli.solve_cmd import _setup_note, noise_lines
from handeye.framework.solution import Status
from handeye.io.output_files import check_writable, write_text
from handeye.io.pose_formats import format_names
from handeye.io.pose_readers import UNITS
from handeye.workflow.calibration import calibrate
from handeye.workflow.cell import (
    CAMERA_POSES,
    MATCH_METHODS,
    PAIRINGS,
    SETUPS,
    Cell,
    Matching,
)
from handeye.workflow.frames import equation_of, frame_names, unknown_of
from handeye.workflow.joint_cell import kinematics_lines
from handeye.workflow.quality_report import (
    check_new_report,
    report_files,
    write_failure_report,
)
from handeye.workflow.result import CalibrationResult
from handeye.workflow.solving import UNUSABLE

NAME = "calibrate"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """The flags; none has a default here (the cell's defaults apply, `handeye.workflow.cell`),
    so that a flag not given leaves a --config file's value."""
    parser = subparsers.add_parser(NAME, help="calibrate from a robot pose file and a camera pose file, and export",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    formats = ", ".join(format_names())
    default = Matching()
    parser.add_argument("--config", metavar="CELL.yaml",
                        help="read the cell's settings from this cell file (docs/calibrate.md, 'Cell files and "
                             "Python'); flags given beside it override its values")
    parser.add_argument("--write-config", metavar="CELL.yaml",
                        help="write the settings given (flags, and --config's) to this cell file and stop: nothing "
                             "is read or solved; rerun with --config (an existing file is kept unless --force)")
    parser.add_argument("--robot", metavar="FILE",
                        help="robot flange poses T_base_flange, one per station (.csv .tsv .txt .json .yaml .npz, a "
                             "folder of one pose file per station, or a ROS bag); required unless --config gives it")
    parser.add_argument("--robot-format", metavar="FORMAT", help=f"format of --robot (not for ROS bags): {formats}")
    parser.add_argument("--camera", metavar="FILE",
                        help="board poses in the camera frame T_cam_target (solvePnP's rvec, tvec), one per "
                             "station, in the robot file's order (see --camera-poses, --match)")
    parser.add_argument("--camera-format", metavar="FORMAT",
                        help="format of --camera, not for ROS bags (opencv-rvec for solvePnP's rvec then tvec, or any "
                             "of the above)")
    for which in ("robot", "camera"):
        parser.add_argument(f"--{which}-columns", metavar="LAYOUT",
                            help=f"what each column of --{which} holds, in file order, comma separated: the format's "
                                 "fields (e.g. qw,qx,qy,qz,x,y,z for a quaternion-first file read as xyz-quat-xyzw), "
                                 "t for time stamps, name, - to skip a column; default: by header, else by position")
    parser.add_argument("--camera-poses", choices=CAMERA_POSES,
                        help="board-in-camera (default): the camera file holds T_cam_target; camera-in-board: it "
                             "holds T_target_cam (the camera's pose in the board frame), inverted on reading")
    parser.add_argument("--observations", action="append", metavar="[CAMERA=]FILE",
                        help="a cell of several cameras and targets (--problem axyb-multi): a table of observations "
                             "(station, camera, target, the camera's pose of the target; .csv .json .npz), or with "
                             "CAMERA= one camera's file (station, target, pose); repeatable, instead of --camera; "
                             "--camera-format/-unit/-poses/-columns apply to every table (docs/calibrate.md, "
                             "'Several cameras and targets')")
    parser.add_argument("--joints", metavar="FILE",
                        help="a kinematic calibration (--problem axyb-kinematic, the default with joints; "
                             "docs/kinematic.md): the robot's joint readings, one row per station, instead of --robot: "
                             "a table with a header (name and/or t column, one column per joint; --joints-unit) or a "
                             "ROS bag (--joints-topic, sensor_msgs/JointState); needs --arm")
    parser.add_argument("--joints-unit", choices=("deg", "rad"), help="--joints: the angle unit of the table "
                                                                       "(required for a table; bags hold rad)")
    parser.add_argument("--joints-topic", metavar="TOPIC", help="--joints is a ROS bag: its JointState topic")
    parser.add_argument("--arm", metavar="DH.yaml",
                        help="--joints: the arm's nominal standard DH table as YAML (docs/formats.md, 'Arm models'), "
                             "or a URDF (.urdf, its revolute chain; pip install 'handeye[urdf]'); its length unit is "
                             "the answer's")
    parser.add_argument("--arm-out", metavar="FILE",
                        help="--joints: write the DH table of the answer (the corrected one) as an arm file, for the "
                             "robot controller (an existing file is kept unless --force)")
    parser.add_argument("--images", metavar="DIR",
                        help="a folder of board images, one per station (instead of --camera/--camera-format): the "
                             "board is detected in each and its pose solved; paired with the robot poses by --match "
                             "index (= row, the default: k-th image in natural order), name (file stem = robot pose "
                             "name) or time (stamp in the file name or a sidecar); docs/images.md")
    parser.add_argument("--board", metavar="SPEC",
                        help="--images: the calibration board, e.g. chessboard:9x6:25mm, "
                             "charuco:5x7:36.195mm:18.256mm:DICT_6X6_250, circlegrid:10x10:25.4mm (docs/boards.md)")
    parser.add_argument("--intrinsics", metavar="FILE",
                        help="--images: camera intrinsics (OpenCV YAML/XML/JSON, ROS camera_info YAML, "
                             "industrial_calibration cal_data.yaml); default: calibrated from the same images")
    parser.add_argument("--match", choices=MATCH_METHODS,
                        help=f"how robot and camera poses are paired into stations: row ({default.method}, the "
                             "default): row k of both files (index: the same); name: equal name/index columns; time: "
                             "each camera pose with the robot pose at the nearest time stamp within --max-dt (no "
                             "interpolation), others dropped; interpolate: the robot stream interpolated at each "
                             "camera stamp + the clock offset (--time-offset, estimated by default; docs/streams.md)")
    parser.add_argument("--max-dt", type=finite_number, metavar="SECONDS",
                        help="--match time: largest |camera stamp - robot stamp| paired (default: half the median "
                             "interval between robot stamps, or 0.02 s with fewer than two robot stamps)")
    parser.add_argument("--time-offset", metavar="auto|SECONDS",
                        help="--match interpolate: the clock offset, t_robot = t_camera + offset; 'auto' (default) "
                             "estimates it (cross-correlation of the angular speeds, refined on the residuals)")
    parser.add_argument("--max-offset", type=finite_number, metavar="SECONDS",
                        help=f"--match interpolate: search the offset within +-SECONDS (default "
                             f"{default.max_offset:g})")
    parser.add_argument("--max-gap", type=finite_number, metavar="SECONDS",
                        help="--match interpolate: largest spacing of robot samples interpolated across (default "
                             "3 x the robot's median interval); camera stamps in wider gaps are dropped")
    parser.add_argument("--min-speed", type=finite_number, metavar="DEG_PER_S",
                        help=f"--match interpolate: drop stations where the robot turns slower (default "
                             f"{default.min_speed:g} deg/s)")
    parser.add_argument("--max-pairs", type=whole_number, metavar="N",
                        help=f"--match interpolate: keep at most N well-spread stations (default {default.max_pairs})")
    parser.add_argument("--robot-topic", metavar="TOPIC",
                        help="--robot is a ROS bag: its pose topic (PoseStamped, TransformStamped, "
                             "PoseWithCovarianceStamped, Odometry) or /tf:PARENT,CHILD")
    parser.add_argument("--camera-topic", metavar="TOPIC", help="--camera is a ROS bag: its pose topic, as --robot-topic")
    parser.add_argument("--setup", choices=SETUPS,
                        help="eye-in-hand: camera on the flange, board fixed; eye-to-hand: camera fixed, board "
                             "on the flange; required unless --config gives it")
    parser.add_argument("--problem", metavar="PROBLEM",
                        help="a registered problem a cell's stations make data for (handeye list): the default, axyb, "
                             "finds hand-eye and robot-world from the stations; axxb hand-eye only, from the motions "
                             "between stations")
    parser.add_argument("--robot-unit", choices=UNITS, help="length unit of --robot (default: the file's or the "
                                                            "robot maker's); the answer is in this unit")
    parser.add_argument("--camera-unit", choices=UNITS, help="length unit of --camera (default: the file's); "
                                                             "converted to the robot's")
    parser.add_argument("--orthonormalize", action="store_true", default=None,
                        help="re-orthonormalise rotation matrices / normalise quaternions exported with few "
                             "decimals (both files)")
    parser.add_argument("--pairing", choices=PAIRINGS,
                        help="axxb: motions between all pairs of stations (default) or consecutive ones")
    parser.add_argument("--solver", help="solver (default: 'auto' if installed, else 'kron-lstsq'; images: "
                                         "'reprojection'); see handeye list")
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
    parser.add_argument("--no-checks", action="store_true", default=None,
                        help="skip the plausibility checks (residuals against the cell's noise, the usual setup "
                             "mistakes, duplicated stations, too few stations; docs/calibrate.md)")
    add_detection_flags(parser)
    add_force_flag(parser)
    add_time_limit_flag(parser)
    parser.set_defaults(run=run)
    return parser


def cell_of(args: argparse.Namespace) -> Cell:
    """The cell the flags describe: --config's file with the flags given in place of its values,
    or the flags alone (paths relative to the working folder)."""
    flags = flag_settings(args, parse_key_values(args.option) if args.option else None)
    if args.config is None:
        if ("robot" not in flags and "observations" not in flags and "joints" not in flags) or "setup" not in flags:
            missing = " and ".join(f for f, k in (("--robot FILE", "robot"), ("--setup", "setup"))
                                   if k not in flags and not (k == "robot" and ("observations" in flags
                                                                                or "joints" in flags)))
            raise InputError(f"{missing} {'are' if ' and ' in missing else 'is'} required (or --config CELL.yaml, a "
                             "cell file that gives them)")
        return Cell.from_dict(flags)
    base = Cell.from_file(args.config)
    return Cell.from_dict(merged(base.to_dict(), flags))


def run(args: argparse.Namespace) -> int:
    detecting = detection_options(args)
    cell = cell_of(args)
    if cell.observations is not None:  # several cameras and targets: the tables of observations
        inputs = [cell.robot.file, *(p for s in cell.observations for p in (s.file, s.images, s.intrinsics)),
                  *(b for b in (cell.targets or {}).values() if isinstance(b, str))]
    else:
        inputs = [cell.robot.file, cell.images.folder if cell.images else cell.camera.file,
                  cell.images.intrinsics if cell.images else None, cell.images.board if cell.images else None,
                  *((cell.joints.file, cell.arm) if cell.joints is not None else ())]
    inputs.append(args.config)
    if args.write_config:
        check_outputs([("--write-config", args.write_config)], inputs, args.force)
        check_writable("--write-config", args.write_config)
        print(f"wrote {cell.to_file(args.write_config, force=args.force)}")
        return 0
    out = cell.outputs
    outputs = [("-o", out.json), ("--yaml", out.yaml), ("--arm-out", out.arm)]
    if out.report:
        check_new_report(out.report, args.force)
        outputs += [("--report", p) for p in report_files(out.report)]
    check_outputs(outputs[:3], inputs, args.force)  # the report's files: check_new_report, above
    check_outputs_apart(outputs, inputs)

    log_to = sys.stderr if args.json else sys.stdout
    logged: list[str] = []

    def log(stage: str, text: str) -> None:  # the images' summary as soon as it is known; matching: --json only
        logged.append(text)
        if stage == "images" or args.json:
            print(text, file=log_to)

    try:
        result = calibrate(cell, log=log, **detecting)
    except HandEyeError as exc:  # no answer: a --report still says why (the error is then raised as usual)
        if out.report:
            written = write_failure_report(out.report, in_cli_words(str(exc)), logged,
                                           getattr(args, "command_line", "handeye calibrate"), force=args.force)
            print(f"wrote {written}", file=sys.stderr)
        raise
    r = result.to_dict()
    r["warnings"] = [cell_words(w) for w in r["warnings"]]  # the cell's settings as flags; else as the library says
    written = [] if not result.usable else _write(r, out.json, out.yaml, args.force)
    if result.usable and out.arm:  # a kinematic calibration's corrected DH table
        written.append(str(write_text(out.arm, result.arm_yaml(), force=args.force, flag="--arm-out")))
    if out.report:
        written.append(str(result.write_report(out.report, force=args.force, words=in_cli_words,
                                               command=getattr(args, "command_line", "handeye calibrate"))[0]))
    if args.json:
        print(dump_json(r))
    else:
        print(in_cli_words(_text(r, frame_names(result.cell.problem, cell.setup), result.solution.diagnostics)))
    for path in written:
        print(f"wrote {path}", file=log_to)
    if result.status is Status.UNRELIABLE:
        print(in_cli_words(f"handeye: error: status unreliable: {_why(result)}; no result file was written "
                           "(--no-checks skips the checks)"), file=sys.stderr)
        return 1
    if result.status in UNUSABLE:
        print(f"handeye: error: solver {result.solver!r} ended with status {result.status}: its "
              f"{', '.join(result.unknowns)} (printed above) are not an answer and no result file was written; "
              "try another solver", file=sys.stderr)
        return 1
    return 0


def _why(result: CalibrationResult) -> str:
    """The warning that says why the answer is unreliable: the implausible fit's, else the first
    of the pairing's (an untrusted clock offset), else the first at all."""
    if result.checks is not None and not result.checks.plausible:
        return result.checks.warnings[0]
    return next(iter(result.stations.warnings or result.warnings), "")


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


def _scale_sensitivity(diagnostics: dict[str, Any], name: str, sigma: float, unit: str) -> list[str]:
    """Lines saying how far a camera scale 0.1% off (a board size or focal length a little wrong),
    and a given focal length 0.1% off, would move the unknown `name`, where that exceeds its
    1-sigma `sigma`, which takes them as exact (self-check 5, docs/camera-scale.md; docs/images.md)."""
    lines = []
    shift = ((diagnostics.get("self_check") or {}).get("camera_scale") or {}).get("per_permille", {}).get(name)
    if shift is not None and shift > sigma:
        lines.append(f"  a camera scale 0.1% off (board size, focal length) would move it by {shift:.3g} {unit}, "
                     f"{shift / sigma:.2g}x its 1-sigma, which takes the scale as exact")
    # intrinsics given (not calibrated here, where their uncertainty is in the 1-sigma already)
    focal = (diagnostics.get("focal_per_permille") or {}).get(name)
    if focal is not None and focal > sigma and "intrinsics_effect" not in diagnostics:
        lines.append(f"  a focal length 0.1% off would move it by {focal:.3g} {unit}, {focal / sigma:.2g}x its "
                     "1-sigma, which takes the given intrinsics as exact")
    return lines


def _text(r: dict[str, Any], frames: dict[str, tuple[str, str]], diagnostics: dict[str, Any]) -> str:
    unit = r["units"]["translation"]
    inp = r["inputs"]
    cam_unit = inp["camera"]["unit"] + (f", converted to {unit}" if inp["camera"]["unit"] != unit else "")
    camera_file = inp["camera"]["file"] if "files" not in inp["camera"] else ", ".join(inp["camera"]["files"])
    if inp["camera"].get("holds") == "T_target_cam":
        cam_unit += ", T_target_cam inverted"
    equation, item = equation_of(r["problem"])
    lines = [(f"{r['stations']} stations: robot {inp['robot']['file']} ({inp['robot']['format']}, {unit}), "
              f"{'observations' if 'files' in inp['camera'] else 'camera'} {camera_file} ({inp['camera']['format']}, "
              f"{cam_unit})"),
             # the image path prints its pairing with the images' summary, before this
             *([r["matching"]["message"]] if "message" in r["matching"] and not inp["camera"]["format"].startswith("images")
               else []),
             f"{r['setup']}, problem {r['problem']} ({equation})"
             + (f", {r['residuals']['count']} motions ({r['pairing']} pairs of stations)" if "pairing" in r else ""),
             f"solver {r['solver']} (backend {r['backend']}): status {r['status']}, {r['seconds'] * 1e3:.1f} ms"
             + _setup_note(diagnostics)]
    for name, p in r["poses"].items():
        frame = frames.get(unknown_of(name))
        symbol = r["frames"].get(name) or (frame[0] if frame else None)
        named = f" = {symbol}" + (f" ({frame[1]})" if frame else "") if symbol else ""
        label = f"{name} {r['names'][name]}" if name in r.get("names", {}) else name
        lines += ["", f"{label}{named}, lengths in {unit}:", format_pose(np.array(r[name]))]
        x = p["xyz_quat"]
        lines.append(f"  xyz  {x[0]:.6g} {x[1]:.6g} {x[2]:.6g}   quaternion (x, y, z, w)  "
                     + " ".join(f"{v:.8f}" for v in x[3:]))
        if "robot_format" in p:
            lines.append(f"  {inp['robot']['format']}  " + "  ".join(f"{k}={v:.6g}" for k, v in p["robot_format"].items()))
        if p["std"] is not None:
            lines.append(f"  1-sigma  rotation {p['std']['rotation_deg']:.3g} deg, translation "
                         f"{p['std']['translation']:.3g} {unit} (root of the 3 axes' variances"
                         + spread_note(diagnostics, name) + ")")
            lines += _scale_sensitivity(diagnostics, name, p["std"]["translation"], unit)
        else:
            lines.append(f"  1-sigma  not reported by solver {r['solver']} (solver auto or refine reports it)")
    res = r["residuals"]
    per_pair = (r.get("observations") or {}).get("per_pair") or []
    lines += ["", (f"residuals over the {res['count']} {item}s (angle and distance between the two sides "
                   f"of {equation}):"),
              "  " + " " * 18 + "".join(f"{s:>12}" for s in ("median", "rms", "max"))]
    for label, key in (("rotation [deg]", "rotation_deg"), (f"translation [{unit}]", "translation")):
        lines.append(f"  {label:<18}" + "".join(f"{res[key][s]:12.4g}" for s in ("median", "rms", "max")))
    if per_pair:
        lines += ["", "residuals per pair (RMS and max over its observations):",
                  f"  {'X':<14}{'Y':<14}{'obs':>5}{'rot rms [deg]':>15}{'rot max':>10}"
                  f"{f'trans rms [{unit}]':>18}{'trans max':>11}"]
        lines += [f"  {row['X']:<14}{row['Y']:<14}{row['observations']:>5}{row['rotation_rms_deg']:>15.4g}"
                  f"{row['rotation_max_deg']:>10.4g}{row['translation_rms']:>18.4g}{row['translation_max']:>11.4g}"
                  for row in per_pair]
    lines += _scale_lines(r, unit)
    lines += noise_lines(diagnostics, unit)
    if "kinematics" in r:  # joint readings and the arm's DH table: the corrections
        lines += kinematics_lines(r["kinematics"])
    ros = r["ros"]
    if ros is not None and "transforms" in ros:
        lines += ["", "ROS 2 (every pose by name, metres):", *(f"  {t['command']}" for t in ros["transforms"])]
    elif ros is not None:
        lines += ["", f"ROS 2 ({ros['unknown']}: {ros['child_frame_id']} in {ros['frame_id']}, metres):",
                  "  " + ros["command"]]
    if r["status"] in ("not_converged", "failed"):
        lines.append(f"warning: status {r['status']}: the solver did not reach its answer; do not use it")
    elif r["status"] == "unreliable":
        lines.append("warning: status unreliable: the checks found this answer unusable; do not use it (the first "
                     "warning below says why)")
    elif r["status"] == "suboptimal":
        lines.append("note: status suboptimal: a usable answer, but the data support another fit far better "
                     "(the self-check's warning below says how far)")
    elif r["status"] == "uncertified":
        lines.append("note: status uncertified: a valid answer, but the solver could not prove it globally optimal")
    lines += [f"warning: {w}" for w in r["warnings"]]
    return "\n".join(lines)


def _scale_lines(r: dict[str, Any], unit: str) -> list[str]:
    """The camera scales estimated (``camera_scale``: one camera's; ``camera_scales``: each
    monocular camera's of a cell), with their 1-sigma."""
    sigma = lambda std: "" if std is None else f" (1-sigma {std:.2g})"  # noqa: E731
    if "camera_scale" in r:
        s = r["camera_scale"]
        return ["", f"camera scale s = {s['scale']:.6g}{sigma(s['std'])}: the camera's translations times s are in "
                    f"{unit} (the residuals above use them)"]
    if "camera_scales" not in r:
        return []
    return ["", f"camera scales (each monocular camera's translations times its s are in {unit}; the residuals "
                "above use them):",
            *(f"  {name:<14} s = {s['scale']:.6g}{sigma(s['std'])}" for name, s in r["camera_scales"].items())]
