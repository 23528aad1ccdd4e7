"""``handeye watch``: live feedback while a cell records its stations.

Follows the robot's pose file (``--robot``, T_base_flange) and the camera's (``--camera``, the
board's pose in the camera, T_cam_target; ``--camera-poses camera-in-board`` for T_target_cam),
the same files and flags as ``handeye calibrate``, reading them again every ``--interval``
seconds, and prints one line per new station: its name, how many stations are in the answer, the
1-sigma of each unknown (rotation deg, translation in the robot's unit; the noise estimated from
the residuals from 8 stations on, before that the expected noise), ``enough`` once every 1-sigma
is within ``--target``, a station that disagrees with the others (left out of the answer), and,
with ``--intrinsics`` and ``--board``, the next robot poses to record, in the robot file's
format (``--next-out FILE`` also writes them as a pose file for the robot program).

Stations pair by row (row k of both files, as far as both go) or by name (``--match name``).
``--once`` reads the files once (finished files), prints every station and the final answer, and
exits; otherwise the command runs until Ctrl-C (or ``--idle SECONDS`` without a new station) and
then prints the final answer: the full, self-checked solve of the stations kept (as ``handeye
calibrate`` gives it). Exit codes: 0 done; 2 bad input (flags, files that cannot be read: a line
being written is read again at the next poll); 1 the final solve failed.

docs/planning-live.md.
"""

# The docstring above is this command's --help. This module is argparse and printing only: the
# files are followed by handeye.workflow.watch_source, the session is handeye.planning.session.

from __future__ import annotations

import argparse
import json
import math
import re
import time
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.cli._common import (
    add_force_flag,
    add_workspace_flags,
    check_outputs,
    finite_number,
    in_cli_words,
    whole_number,
    workspace_of,
)
from handeye.framework.solution import USABLE, standard_deviations
from handeye.io.pose_formats import format_names, parse_format
from handeye.planning.live_view import DEFAULT_PORT
from handeye.planning.plan import Noise, planners
from handeye.planning.session import MIN_STATIONS, Session, Tolerance, Update
from handeye.workflow.cell_parts import (
    CAMERA_POSES,
    SETUPS,
    UNITS,
    CameraStream,
    PoseStream,
)
from handeye.workflow.watch_source import (
    MATCHES,
    PoseFilePair,
    RecordingRewritten,
    Station,
)

NAME = "watch"
#: a target or noise text: NUMBER UNIT, comma separated
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(deg|rad|mm|m)\s*$")
_METRES = {"mm": 1e-3, "m": 1.0}


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="live feedback while recording: 1-sigma so far, enough?, disagreeing "
                                              "stations, what to record next",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    formats = ", ".join(format_names())
    parser.add_argument("--robot", metavar="FILE", required=True,
                        help="robot flange poses T_base_flange, one per station, as they are recorded")
    parser.add_argument("--robot-format", metavar="FORMAT", help=f"format of --robot: {formats}")
    parser.add_argument("--robot-unit", choices=UNITS, help="length unit of --robot (default: the file's or the "
                                                            "robot maker's); every length printed is in it")
    parser.add_argument("--robot-columns", metavar="LAYOUT", help="what each column of --robot holds (as calibrate)")
    parser.add_argument("--robot-topic", metavar="TOPIC", help="--robot is a ROS bag (finished, with --once): its "
                                                               "pose topic")
    parser.add_argument("--camera", metavar="FILE", required=True,
                        help="board poses in the camera frame T_cam_target, one per station")
    parser.add_argument("--camera-format", metavar="FORMAT", help="format of --camera")
    parser.add_argument("--camera-unit", choices=UNITS, help="length unit of --camera; converted to the robot's")
    parser.add_argument("--camera-columns", metavar="LAYOUT", help="what each column of --camera holds")
    parser.add_argument("--camera-topic", metavar="TOPIC", help="--camera is a ROS bag: its pose topic")
    parser.add_argument("--camera-poses", choices=CAMERA_POSES, default="board-in-camera",
                        help="board-in-camera (default): the camera file holds T_cam_target; camera-in-board: "
                             "T_target_cam, inverted on reading")
    parser.add_argument("--setup", choices=SETUPS, required=True,
                        help="eye-in-hand: camera on the flange; eye-to-hand: camera fixed, board on the flange")
    parser.add_argument("--problem", default=None, metavar="NAME",
                        help="a registered problem that can plan stations (default: A X = Y B, hand-eye and "
                             "robot-world; the A X = X B problem reports the camera's pose only)")
    parser.add_argument("--match", choices=MATCHES, default="row",
                        help="row (default): row k of both files is station k; name: equal name columns")
    parser.add_argument("--orthonormalize", action="store_true",
                        help="re-orthonormalise rotations exported with few decimals (both files)")
    parser.add_argument("--target", metavar="ROT,TRANS",
                        help="the 1-sigma to reach, e.g. 0.1deg,0.5mm: the line says 'enough' once every unknown is "
                             "within it")
    parser.add_argument("--intrinsics", "--camera-intrinsics", dest="camera_intrinsics", metavar="FILE",
                        help="camera intrinsics with the image size (OpenCV YAML/XML/JSON, ROS camera_info), as "
                             "plan and calibrate take them: with --board, the camera's expected noise and the next "
                             "poses to record")
    parser.add_argument("--board", metavar="SPEC", help="the calibration board, e.g. chessboard:9x6:25mm "
                                                        "(docs/boards.md)")
    parser.add_argument("--pixel-noise", type=finite_number, default=Noise().pixel, metavar="PX",
                        help=f"expected noise of the board's corners, pixels (default {Noise().pixel:g})")
    parser.add_argument("--camera-noise", metavar="ROT,TRANS",
                        help="without --intrinsics and --board: the expected noise of a camera pose per axis, "
                             "e.g. 0.05deg,0.3mm (else the 1-sigma is printed from 8 stations on)")
    parser.add_argument("--suggest", type=whole_number, default=3, metavar="K",
                        help="how many next poses to suggest (default 3; 0: none)")
    add_workspace_flags(parser, "the robot's unit; the poses suggested")
    parser.add_argument("--figure", metavar="PNG",
                        help="at the end, draw the cell in 3D: the robot base, the stations (those left out grey), "
                             "the camera and its view (with --intrinsics), the board and the next poses suggested")
    parser.add_argument("--live", nargs="?", type=whole_number, const=DEFAULT_PORT, metavar="PORT",
                        help="show the cell in a browser while it records, redrawn at every answer "
                             f"(http://localhost:PORT, default {DEFAULT_PORT}; needs pip install \"handeye[live]\")")
    parser.add_argument("--next-out", metavar="FILE",
                        help="write the suggested poses to this pose file (the robot's format and unit), rewritten "
                             "after every station (an existing file is kept unless --force)")
    parser.add_argument("--once", action="store_true", help="read the files once (finished), then exit")
    parser.add_argument("--interval", type=finite_number, default=1.0, metavar="SECONDS",
                        help="seconds between reads of the files (default 1)")
    parser.add_argument("--idle", type=finite_number, metavar="SECONDS",
                        help="stop after SECONDS without a new station (default: run until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="print one JSON object per line instead of text")
    add_force_flag(parser)
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace) -> int:
    if not args.interval > 0 or (args.idle is not None and not args.idle > 0):
        raise InputError("--interval and --idle take a positive number of seconds")
    if args.suggest < 0:
        raise InputError(f"--suggest takes a number of poses >= 0, got {args.suggest}")
    if args.problem is not None and args.problem not in planners():
        raise InputError(f"--problem {args.problem!r} cannot plan stations; problems that can: {', '.join(planners())}")
    if (args.camera_intrinsics is None) != (args.board is None):
        raise InputError("--intrinsics and --board go together (the expected noise of the camera poses and "
                         "the next poses need both)")
    target = None if args.target is None else parse_pair(args.target, "--target")
    camera_noise = None if args.camera_noise is None else parse_pair(args.camera_noise, "--camera-noise")
    check_outputs([("--next-out", args.next_out), ("--figure", args.figure)],
                  [args.robot, args.camera, args.camera_intrinsics, args.board], args.force)
    if args.figure:
        from handeye.io.output_files import check_figure_format

        check_figure_format("--figure", args.figure)
    camera = board = None
    if args.camera_intrinsics is not None:
        from handeye.vision.boards import parse_board
        from handeye.vision.intrinsics import load_camera

        camera, board = load_camera(args.camera_intrinsics), parse_board(args.board)
        if camera.size is None:
            raise InputError(f"--intrinsics {args.camera_intrinsics!r} has no image size (width, height): the "
                             "next poses must keep the board inside the image")
    source = PoseFilePair(
        PoseStream(args.robot, args.robot_format, args.robot_unit, args.robot_columns, args.robot_topic),
        CameraStream(args.camera, args.camera_format, args.camera_unit, args.camera_columns, args.camera_topic,
                     poses=args.camera_poses),
        args.setup, args.match, args.orthonormalize)
    session: Session | None = None
    failed_at = None
    idle_since = time.monotonic()
    live = None
    if args.live is not None:
        from handeye.planning.live_view import LiveView

        live = LiveView(args.robot_unit or "mm", args.live)  # the unit is set again with the first station
        _say(args, f"live view: {live.url} (open it in a browser)")
    try:
        while True:
            try:
                stations = source.poll()
                failed_at = None
            except RecordingRewritten:  # a recorder restarted: follow the new recording from its start
                time.sleep(args.interval)  # unless it was a file rewritten in place, cut short for a moment
                try:
                    stations = source.poll()
                    failed_at = None
                except RecordingRewritten as exc:
                    if session is not None:
                        _say(args, f"{exc}: starting over with the new recording ({int(sum(session.kept))} "
                                   "stations of the old one dropped)")
                    source.restart()
                    session, stations = None, source.poll()
            except InputError as exc:
                signature = source.signature()
                waiting = "no poses" in str(exc) or (-1, -1) in signature  # not recording yet
                if args.once or (not waiting and signature == failed_at):  # the same error on unchanged files
                    raise
                failed_at, stations = signature, []
            for station in stations:
                if session is None:
                    session = _session(args, station.unit, camera, board, target, camera_noise)
                update = session.add(station.A, station.B, station.name)
                _show(args, update, station, source, session)
            if live is not None and stations and session is not None:
                _live(args, live, session, board, camera, source.unit)
            if args.once:
                break
            now = time.monotonic()
            if stations:
                idle_since = now
            elif args.idle is not None and now - idle_since > args.idle:
                break
            time.sleep(args.interval)
    except KeyboardInterrupt:  # Ctrl-C: the usual end of a recording
        pass
    finally:
        if live is not None:
            live.close()
    code = _final(args, session, source.unit)
    if args.figure and session is not None:
        _figure(args, session, board, camera, source.unit)
    return code


def parse_pair(text: str, flag: str) -> tuple[float, float, str]:
    """``0.1deg,0.5mm`` -> (rotation deg, translation, its unit). InputError for anything else."""
    rotation = translation = None
    for part in text.split(","):
        match = _QUANTITY.match(part)
        if match is None:
            raise InputError(f"{flag} expects a rotation and a translation with their units, e.g. 0.1deg,0.5mm; got "
                             f"{text!r}")
        value, unit = float(match.group(1)), match.group(2)
        if not 0 < value < math.inf:
            raise InputError(f"{flag}: {part.strip()!r} must be positive")
        if unit in ("deg", "rad"):
            if rotation is not None:
                raise InputError(f"{flag} {text!r} gives the rotation twice")
            rotation = value if unit == "deg" else math.degrees(value)
        else:
            if translation is not None:
                raise InputError(f"{flag} {text!r} gives the translation twice")
            translation = (value, unit)
    if rotation is None or translation is None:
        raise InputError(f"{flag} needs a rotation and a translation, e.g. 0.1deg,0.5mm; got {text!r}")
    return rotation, translation[0], translation[1]


def _in_unit(value: float, unit: str, to: str) -> float:
    return value * _METRES[unit] / _METRES[to]


def _session(args: argparse.Namespace, unit: str, camera: Any, board: Any, target: Any, camera_noise: Any) -> Session:
    """The session, once the robot's unit is known (every length in it)."""
    tolerance = None if target is None else Tolerance(target[0], _in_unit(target[1], target[2], unit))
    sigma = None if camera_noise is None else (math.radians(camera_noise[0]),
                                              _in_unit(camera_noise[1], camera_noise[2], unit))
    workspace = workspace_of(args.workspace, args.max_tilt, args.tool_axis, args.max_roll)
    return Session(args.problem, setup=args.setup, target=tolerance, camera=camera,
                   board=None if board is None else board.in_unit(unit), unit=unit, workspace=workspace,
                   noise=Noise(args.pixel_noise), camera_sigma=sigma, suggest=args.suggest)


def _std_text(std: dict[str, dict[str, float]], unit: str) -> str:
    return ", ".join(f"{name} {s['rotation_deg']:.3g} deg {s['translation']:.3g} {unit}" for name, s in std.items())


def _pose_text(T: np.ndarray, robot_format: str) -> str:
    fmt = parse_format(robot_format)
    if fmt.kind == "matrix":
        fmt = parse_format("xyz-quat-xyzw")
    return " ".join(f"{k}={v:.6g}" for k, v in zip(fmt.fields, fmt.to_rows(T[None])[0]))


def _picture(args: argparse.Namespace, session: Session, board: Any, camera: Any, unit: str | None
             ) -> dict[str, Any] | None:
    """What a picture of the recording shows at the answer so far (`handeye.planning.scene`), with
    the last poses suggested and a title; None where there is no answer yet."""
    answer = session.unknowns
    if answer is None or {"X", "Y"} - set(answer):
        return None
    A, _ = session.stations
    last = session.last_suggestions
    return {"A": A, "X": answer["X"], "Y": answer["Y"], "setup": args.setup,
            "board": None if board is None else board.in_unit(unit or board.unit), "camera": camera,
            "left_out": ~session.kept, "following": None if last is None else last.A,
            "title": f"{len(A)} stations recorded ({int(sum(session.kept))} in the answer)"
                     + ("; the next suggested" if last is not None else "")}


def _figure(args: argparse.Namespace, session: Session, board: Any, camera: Any, unit: str | None) -> None:
    """The recording drawn in 3D (`handeye.planning.figure.draw_cell`); a line saying why not
    where there is no answer."""
    from handeye.planning.figure import draw_cell

    picture = _picture(args, session, board, camera, unit)
    if picture is None:
        _say(args, "figure: no answer to draw the cell with yet")
        return
    title = picture.pop("title")
    path = draw_cell(picture.pop("A"), picture.pop("X"), picture.pop("Y"), picture.pop("setup"), picture.pop("board"),
                     args.figure, unit or "", title, **picture)
    _say(args, f"figure: {path}")


def _live(args: argparse.Namespace, live: Any, session: Session, board: Any, camera: Any, unit: str | None) -> None:
    """The live view redrawn at the answer so far (`handeye.planning.live_view`)."""
    from handeye.planning.scene import cell_scene

    picture = _picture(args, session, board, camera, unit)
    if picture is not None:
        title = picture.pop("title")
        live.unit = unit or live.unit
        live.show(cell_scene(**picture), title)


def _say(args: argparse.Namespace, message: str) -> None:
    """A line about the recording itself (not a station): text, or ``{"message": ...}`` with --json."""
    print(json.dumps({"message": message}) if args.json else message, flush=True)


def _show(args: argparse.Namespace, update: Update, station: Station, source: PoseFilePair, session: Session) -> None:
    unit = station.unit
    robot_format = source.robot_format
    if args.next_out and update.suggestions is not None:
        from handeye.io.pose_readers import PoseStack
        from handeye.io.pose_writers import write_poses

        names = tuple(f"next{i + 1}" for i in range(len(update.suggestions.A)))
        write_poses(args.next_out, PoseStack(update.suggestions.A, unit=unit, format=robot_format, names=names),
                    robot_format)
    if args.json:
        print(json.dumps(_record(update, unit, robot_format)), flush=True)
        return
    parts = [f"{update.name}: {update.used}/{update.stations} stations"]
    if update.unknowns is None:
        parts.append("not determined yet" + ("" if update.used >= MIN_STATIONS else
                                             f" (an answer needs {MIN_STATIONS} stations)"))
    elif update.std is None:
        parts.append("1-sigma from 8 stations on (--camera-noise gives it sooner)")
    else:
        parts.append(_std_text(update.std, unit) + ("" if update.noise == "estimated" else " (expected noise)"))
    if update.enough:
        parts.append("enough")
    if update.disagreement is not None:
        d = update.disagreement
        parts.append(f"DISAGREES: off by {d.rotation_deg:.3g} deg and {d.translation:.3g} {unit} "
                     f"(p = {d.p_value:.1e}), left out")
    if update.readmitted:
        parts.append(f"back in: {', '.join(update.readmitted)}")
    parts += [f"note: {w}" for w in update.warnings]
    line = "; ".join(parts)
    if update.suggestions is not None:
        line += " | next: " + " ; ".join(_pose_text(T, robot_format) for T in update.suggestions.A)
    print(in_cli_words(line), flush=True)


def _record(update: Update, unit: str, robot_format: str) -> dict[str, Any]:
    out: dict[str, Any] = {"station": update.name, "stations": update.stations, "used": update.used, "unit": unit,
                           "std": update.std, "noise": update.noise, "enough": update.enough,
                           "disagreement": None, "readmitted": list(update.readmitted), "warnings": list(update.warnings)}
    if update.disagreement is not None:
        d = update.disagreement
        out["disagreement"] = {"chi2": d.chi2 if math.isfinite(d.chi2) else None, "p_value": d.p_value,
                               "rotation_deg": d.rotation_deg, "translation": d.translation}
    if update.unknowns is not None:
        out["unknowns"] = {k: v.tolist() for k, v in update.unknowns.items()}
    if update.suggestions is not None:
        fmt = parse_format(robot_format)
        out["next"] = {"format": fmt.name, "poses": fmt.to_rows(update.suggestions.A).tolist(),
                       "std": update.suggestions.std}
    return out


def _final(args: argparse.Namespace, session: Session | None, unit: str | None) -> int:
    """The full solve of the stations kept, one line; exit code."""
    if session is None or sum(session.kept) < 3:
        message = "final: fewer than 3 stations kept, no answer"
        print(json.dumps({"final": None, "message": message}) if args.json else message, flush=True)
        return 0
    solution = session.final()
    # the answer's stated 1-sigma, as calibrate prints it (the root of the three axes' variances)
    std = {name: {"rotation_deg": math.degrees(s["rotation"]), "translation": s["translation"]}
           for name, s in standard_deviations(solution.diagnostics).items()}
    status = getattr(solution.status, "value", str(solution.status))
    if args.json:
        print(json.dumps({"final": {"status": status, "stations": int(sum(session.kept)), "unit": unit,
                                    "warnings": list(solution.warnings),
                                    "unknowns": {k: np.asarray(v).tolist() for k, v in solution.unknowns.items()},
                                    "std": {k: {"rotation_deg": s["rotation_deg"], "translation": s["translation"]}
                                            for k, s in std.items()}}}), flush=True)
    else:
        shown = {k: s for k, s in std.items() if k in solution.unknowns}
        print(f"final: {int(sum(session.kept))} stations, status {status}"
              + (f"; {_std_text(shown, unit)}" if shown else ""), flush=True)
        for name, T in solution.unknowns.items():
            print(f"  {name} = " + "; ".join(" ".join(f"{v:.6g}" for v in row) for row in np.asarray(T)[:3]))
        for warning in solution.warnings:  # what the answer's own checks say, as calibrate prints it
            print(f"  warning: {warning}", flush=True)
    return 0 if status in USABLE else 1
