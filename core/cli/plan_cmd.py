"""``handeye plan``: which stations to record. From the setup, a rough X and Y (CAD, or a first
answer), the camera's intrinsics and the board, where the flange may go and what makes a view
usable, it proposes the stations that make the answer sharpest at the expected noise, writes them
in the robot's own pose format, and prints the 1-sigma they predict (docs/planning.md).

    handeye plan --setup eye-in-hand --x 60,-20,100,17,0,0 --y 600,0,0,0,0,180 \\
        --board chessboard:9x6:30mm --intrinsics camera.yaml --count 12 \\
        --workspace 200,-500,50,1000,500,1000 --max-tilt 70 -o stations.csv --format kuka-abc

X and Y are given as one pose each in --pose-format (default kuka-abc: x, y, z in mm, then A, B,
C in deg); eye in hand X = T_flange_cam and Y = T_base_target, eye to hand X = T_flange_target and
Y = T_base_cam (docs/conventions.md). Stations already recorded (--recorded-robot and
--recorded-camera, read as `handeye calibrate` reads --robot and --camera, row by row) count as
given: the plan is then the next --count.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.cli._common import (
    add_force_flag,
    add_workspace_flags,
    check_outputs,
    finite_number,
    seed_number,
    whole_number,
    workspace_of,
)
from handeye.geometry.se3 import make_pose
from handeye.io.arm_files import read_arm
from handeye.io.output_files import check_figure_format
from handeye.io.pose_formats import parse_format
from handeye.planning import route
from handeye.planning.plan import Noise, plan
from handeye.planning.reach import Reach
from handeye.planning.views import ViewLimits
from handeye.vision.boards import parse_board
from handeye.vision.intrinsics import load_camera
from handeye.vision.observations import SETUPS
from handeye.workflow.cell_parts import CAMERA_POSES

NAME = "plan"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="propose which stations to record", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--problem", default=None,
                        help="a registered problem that can plan (default: A X = Y B, X and Y of interest; the "
                             "A X = X B problem plans for X alone)")
    parser.add_argument("--setup", choices=SETUPS, required=True)
    parser.add_argument("--x", required=True, metavar="POSE", help="rough X as comma-separated fields of --pose-format")
    parser.add_argument("--y", required=True, metavar="POSE", help="rough Y as comma-separated fields of --pose-format")
    parser.add_argument("--pose-format", default="kuka-abc",
                        help="format of --x, --y and of the written stations unless --format (default kuka-abc)")
    parser.add_argument("--unit", choices=("mm", "m"), default="mm", help="length unit of the poses (default mm)")
    parser.add_argument("--board", required=True, metavar="SPEC", help="the board, e.g. chessboard:9x6:30mm (docs/boards.md)")
    parser.add_argument("--intrinsics", required=True, metavar="FILE",
                        help="camera intrinsics with the image size (OpenCV YAML/XML/JSON, ROS camera_info YAML)")
    parser.add_argument("--count", type=whole_number, default=12, help="stations to plan (default 12)")
    add_workspace_flags(parser, "--unit")
    parser.add_argument("--rough", metavar="DEG,LENGTH",
                        help="how far the given X and Y may be off (deg, --unit): the planned views keep the board "
                             "that far inside the image (default 1 deg and 1%% of the farthest viewing distance)")
    parser.add_argument("--distance", metavar="NEAR,FAR",
                        help="camera-board distance range, --unit (default: 0.5-2x that at which the board fills half "
                             "the image's width)")
    parser.add_argument("--max-angle", type=finite_number, default=45.0, metavar="DEG",
                        help="largest angle between the optical axis and the board's normal (default 45)")
    parser.add_argument("--pixel-noise", type=finite_number, default=0.3, metavar="PX", help="expected corner noise (default 0.3)")
    parser.add_argument("--robot-noise", metavar="RAD,LENGTH",
                        help="expected robot pose noise per axis: rad, --unit (default 0.003 rad, 1.5 mm: what real "
                             "arms show in hand-eye recordings, their systematic errors included)")
    parser.add_argument("--arm", metavar="FILE",
                        help="the arm's model (DH YAML or URDF, docs/formats.md): only stations it reaches within "
                             "--joint-limits are planned, and their joints are written with --joints-out")
    parser.add_argument("--joint-limits", metavar="LO:HI,...",
                        help="with --arm: each joint's limits in deg, e.g. --joint-limits=-170:170,-100:145,-70:200,"
                             "-190:190,-125:125,-360:360 (with '=': the value starts with '-'; default: +-180 each)")
    parser.add_argument("--joints-out", metavar="FILE", help="with --arm: the stations' joints (deg) as a table")
    parser.add_argument("--recorded-robot", metavar="FILE", help="robot poses of stations already recorded")
    parser.add_argument("--recorded-camera", metavar="FILE",
                        help="their camera poses, read as calibrate reads --camera: the board's pose in the camera "
                             "(T_cam_target), or with --camera-poses camera-in-board T_target_cam")
    parser.add_argument("--camera-poses", choices=CAMERA_POSES, default="board-in-camera",
                        help="what --recorded-camera holds (default board-in-camera: T_cam_target, as calibrate and "
                             "watch read it)")
    parser.add_argument("--robot-format", help="format of --recorded-robot (default: --pose-format)")
    parser.add_argument("--camera-format", help="format of --recorded-camera (default: --pose-format)")
    parser.add_argument("--seed", type=seed_number, default=0, help="random seed of the candidate stations (default 0)")
    parser.add_argument("-o", "--output", required=True, help="the stations file (.csv, .json, ...)")
    parser.add_argument("--format", help="pose format of the written stations (default: --pose-format)")
    parser.add_argument("--figure", metavar="PNG", help="also draw the plan")
    parser.add_argument("--speed", default="250,45", metavar="LENGTH_PER_S,DEG_PER_S",
                        help="the robot's flange speed and turning speed, for the time the driving order takes "
                             "(default 250 mm/s in --unit, 45 deg/s)")
    parser.add_argument("--json", metavar="FILE", help="also write the plan with its predicted 1-sigma as JSON")
    add_force_flag(parser)
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace) -> int:
    check_outputs([("--output", args.output), ("--figure", args.figure), ("--json", args.json),
                   ("--joints-out", args.joints_out)],
                  [args.intrinsics, args.board, args.arm, args.recorded_robot, args.recorded_camera,
                   getattr(args, "joint_limits", None)], args.force)
    if args.figure:
        check_figure_format("--figure", args.figure)
    if (args.joint_limits or args.joints_out) and not args.arm:
        raise InputError("--joint-limits and --joints-out need the arm's model (--arm FILE)")
    fmt = parse_format(args.pose_format)
    X, Y = (_pose(text, fmt, flag) for text, flag in ((args.x, "--x"), (args.y, "--y")))
    board = parse_board(args.board).in_unit(args.unit)
    camera = load_camera(args.intrinsics)
    limits = ViewLimits(distance=_numbers(args.distance, 2, "--distance"), max_angle_deg=args.max_angle) \
        if args.distance else None
    if limits is None and args.max_angle != 45.0:
        from handeye.planning.plan import default_limits

        limits = ViewLimits(distance=default_limits(board, camera).distance, max_angle_deg=args.max_angle)
    workspace = workspace_of(args.workspace, args.max_tilt, args.tool_axis, args.max_roll)
    rough = None
    if args.rough:
        rough = tuple(_numbers(args.rough, 2, "--rough"))
        if not all(0 <= v < math.inf for v in rough) or rough[0] >= 90:
            raise InputError(f"--rough takes an angle (deg, below 90) and a length >= 0, got {args.rough!r}")
    noise = Noise(pixel=args.pixel_noise, robot=_numbers(args.robot_noise, 2, "--robot-noise") if args.robot_noise else None)
    recorded = _recorded(args)
    arm = read_arm(args.arm).in_unit(args.unit) if args.arm else None
    reach = Reach(arm, *_limits(args.joint_limits, arm.joints), seed=args.seed) if arm is not None else None
    result = plan(args.problem, setup=args.setup, X=X, Y=Y, camera=camera, board=board, count=args.count,
                  workspace=workspace, limits=limits, noise=noise, recorded=recorded, rough=rough, reach=reach,
                  seed=args.seed)
    result.write(args.output, args.format or args.pose_format, args.unit)
    print(f"{len(result.A)} stations ({args.setup}) written to {args.output}, in the order to record them"
          + (f", after the {result.recorded} recorded" if result.recorded else ""))
    travel, turn = route.path_length(result.A)
    speed, turn_speed = _numbers(args.speed, 2, "--speed")
    if not (speed > 0 and turn_speed > 0):
        raise InputError(f"--speed takes two speeds > 0 (--unit per s, deg per s), got {args.speed!r}")
    seconds = route.path_seconds(result.A, speed, math.radians(turn_speed))
    print(f"driving order: the flange travels {travel:.4g} {args.unit} and turns {math.degrees(turn):.0f} deg through "
          f"them, about {seconds:.0f} s at {speed:g} {args.unit}/s and {turn_speed:g} deg/s (--speed), stops not counted")
    if reach is None:
        print("reachability not checked: the stations keep the flange in --workspace and the tool axis within "
              "--max-tilt only; give the arm's model (--arm, --joint-limits) to plan stations the arm reaches")
    rot, trans = result.robot_sigma
    print(f"predicted 1-sigma ({args.pixel_noise:g} px per corner, robot {rot:g} rad and {trans:g} {args.unit} per axis"
          + ("" if args.robot_noise else ": the default, what real arms show in hand-eye recordings; --robot-noise "
             "gives yours") + "):")
    for k, std in enumerate(result.progression, start=1):
        cells = "; ".join(f"{n} {s['rotation_deg']:.3g} deg / {s['translation']:.3g} {args.unit}" for n, s in std.items())
        print(f"  after station {k:2d}: {cells}")
    if args.joints_out:
        print(f"joints (deg): {result.write_joints(args.joints_out, arm.names)}")
    if args.figure:
        from handeye.planning.figure import draw

        print(f"figure: {draw(result, board, X, Y, args.figure, args.unit, camera)}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(result.to_dict(), f, indent=1)
        print(f"plan: {args.json}")
    return 0


def _pose(text: str, fmt: Any, flag: str) -> np.ndarray:
    row = _numbers(text, fmt.width, flag)
    R, t, _ = fmt.to_rotations(np.array([row]))
    return make_pose(R[0], t[0])


def _numbers(text: str, count: int, flag: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(np.isfinite(values)):
        raise InputError(f"{flag} needs {count} comma-separated numbers, got {text!r}")
    return values


def _limits(text: str | None, joints: int) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) rad from --joint-limits (deg, LO:HI per joint), +-180 deg each by default."""
    if text is None:
        return np.full(joints, -np.pi), np.full(joints, np.pi)
    try:
        pairs = [tuple(float(v) for v in item.split(":")) for item in text.split(",")]
    except ValueError:
        pairs = []
    if len(pairs) != joints or any(len(p) != 2 for p in pairs):
        raise InputError(f"--joint-limits needs LO:HI in deg for each of the arm's {joints} joints, got {text!r}")
    low, high = np.radians(np.array(pairs)).T
    return low, high


def _recorded(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray] | None:
    """(A, B) of the stations already recorded: the files read as ``handeye calibrate`` reads a
    cell's --robot and --camera (row by row, in --unit; the camera's poses T_cam_target unless
    --camera-poses camera-in-board) and, from 3 stations on, checked as it checks them (the
    plausibility checks: camera poses inverted, the other setup, a unit off, ...), so that the
    plan does not rest on stations read the wrong way."""
    from handeye.workflow.calibration import calibrate, read_stations
    from handeye.workflow.cell import CameraStream, Cell, Matching, PoseStream

    if not args.recorded_robot and not args.recorded_camera:
        return None
    if not (args.recorded_robot and args.recorded_camera):
        raise InputError("stations already recorded need both --recorded-robot and --recorded-camera")
    cell = Cell(robot=PoseStream(args.recorded_robot, format=args.robot_format or args.pose_format, unit=args.unit),
                camera=CameraStream(args.recorded_camera, format=args.camera_format or args.pose_format,
                                    unit=args.unit, poses=args.camera_poses),
                setup=args.setup, matching=Matching(method="row"))
    try:
        data = read_stations(cell).pose_file.data
        checked = calibrate(cell) if len(data["A"]) >= 3 else None
    except InputError as exc:  # calibrate's words for its --robot and --camera are plan's --recorded-* files
        raise InputError(re.sub(r"`(robot|camera)`", r"--recorded-\1", str(exc))) from None
    if checked is not None and checked.checks is not None and not checked.checks.plausible:
        raise InputError("--recorded-robot / --recorded-camera: " + " ".join(checked.checks.warnings[0].split()))
    return np.asarray(data["A"], dtype=float), np.asarray(data["B"], dtype=float)