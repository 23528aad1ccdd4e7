"""``handeye solve``: calibrate from a data file (or a bundled example) and report the answer.

Prints the unknowns with the frames they are in your cell (from the setup: eye-in-hand or
eye-to-hand, docs/conventions.md), the residuals of the problem's equation over the pairs
(``axyb``, A_i X = Y B_i: the rotation angle of (A_i X)(Y B_i)^-1 and the translation distance
between A_i X and Y B_i; ``axxb``, A_i X = X B_i: the same with X B_i, per motion), their summary
and the largest of them, status, solver time, warnings and, when the data come with a truth, the
errors against it (rotation angle and translation distance). ``--json`` prints the same as one
JSON object, with every residual.

Besides A, B (pairs for ``axyb``, relative motions for ``axxb``), a file may hold the absolute
poses the cell recorded (robot_poses = T_base_flange, camera_poses = T_cam_target as solvePnP
gives them), which are turned into the problem's data with the file's (or ``--setup``'s) setup,
and for ``axxb`` its (or ``--pairing``'s) pairing (docs/formats.md): the same file of stations
solves as AX=YB and as AX=XB. ``--problem axxb --example`` solves the bundled example's stations.

Exit code 0 for status optimal, optimal_inaccurate and uncertified (a valid answer that the
solver could not certify globally optimal; the output says so). Exit code 1 for not_converged
and failed, and for unreliable: the answer is still printed, for inspection, with a warning and
one line on stderr, but it must not be used. Every answer is checked against the data it came
from (residuals against the noise the data show, distance from the best fit, gross pairs): an
answer that fails is unreliable, whichever solver gave it. A file of absolute poses (robot and camera) is
checked for plausibility as handeye calibrate does (docs/calibrate.md; --no-checks skips it):
residuals no calibrated cell gives, or a usual setup mistake that explains the data far better,
make the status unreliable.
"""

# The docstring above is this command's --help: it speaks of the user's data and names no
# equation numbers (the paper's eqs. 30-33 are cited in handeye.framework.problem.Problem.residuals/errors).

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.cli import _facts
from handeye.cli._common import (
    add_force_flag,
    add_time_limit_flag,
    check_outputs_apart,
    dump_json,
    format_pose,
    in_cli_words,
    parse_key_values,
    spread_note,
    time_limit,
)
from handeye.framework.reported import Reported
from handeye.framework.solution import Status, standard_deviations
from handeye.geometry.se3 import inverse
from handeye.host.api import solve
from handeye.host.registry import get_registry
from handeye.io.data_files import (
    DEFAULT_PAIRING,
    PAIRINGS,
    SETUPS,
    PoseFile,
    from_poses,
    load_file,
    station_readers,
    supported_extensions,
)
from handeye.io.examples import (
    DEFAULT_EXAMPLE,
    EXAMPLE_PROBLEM,
    list_examples,
    load_example,
)
from handeye.workflow.frames import equation_of, frame_names, single_poses, unknown_of
from handeye.workflow.plausibility import Streams, check
from handeye.workflow.quality_report import (
    check_new_report,
    collect,
    report_files,
    write_report,
)
from handeye.workflow.solving import (  # noqa: F401
    UNUSABLE,
    default_solver,
    measured_data,
)

NAME = "solve"
#: the residuals are listed one by one up to this many pairs; beyond, the LISTED_LARGEST largest
LIST_ALL_UP_TO = 20
LISTED_LARGEST = 10


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="solve a data file or a bundled example", description=__doc__)
    parser.add_argument("file", nargs="?", help=f"data file ({', '.join(supported_extensions())}; docs/formats.md)")
    parser.add_argument("--example", nargs="?", const=DEFAULT_EXAMPLE, metavar="NAME",
                        help=f"solve a bundled example instead of a file: {', '.join(list_examples())} "
                             f"(default {DEFAULT_EXAMPLE})")
    parser.add_argument("--problem", default=None,
                        help="registered problem (handeye list shows them): the default, axyb (A_i X = Y B_i), axxb "
                             "(A_i X = X B_i, relative motions), ...")
    parser.add_argument("--setup", choices=SETUPS,
                        help="file of absolute poses: eye-in-hand (camera on the flange) or eye-to-hand (camera "
                             "fixed); decides what X (and Y) are, docs/conventions.md; overrides the file's setup")
    parser.add_argument("--pairing", choices=PAIRINGS,
                        help=f"axxb, file of absolute poses: motions between consecutive stations or between "
                             f"all pairs i < j (as OpenCV); overrides the file's (default {DEFAULT_PAIRING})")
    parser.add_argument("--solver", help="solver (default: 'auto' if installed, else 'kron-lstsq'); see handeye list")
    parser.add_argument("--backend", help="backend of the solver (default: the solver's default)")
    parser.add_argument("--option", action="append", metavar="KEY=VALUE",
                        help="solver option, repeatable; VALUE true/false (any case) is a bool, else it is "
                             "read as JSON when it parses (1e-8, \"x\"), else as text")
    _facts.add_flags(parser, "the data's length unit")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("--report", metavar="FILE",
                        help="write a quality report: .html (one self-contained page with plots) or .md (markdown, "
                             "its PNG plots next to it); docs/calibrate.md; an existing file is kept unless --force")
    add_force_flag(parser)
    add_time_limit_flag(parser)
    parser.add_argument("--no-checks", action="store_true",
                        help="files of absolute poses: skip the plausibility checks (docs/calibrate.md)")
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace) -> int:
    args.problem = args.problem or get_registry().default_problem()
    if (args.file is None) == (args.example is None):
        raise InputError("give either a data FILE or --example [NAME] (not both, not neither)")
    if args.report:
        check_new_report(args.report, args.force)
        check_outputs_apart([("--report", p) for p in report_files(args.report)], [args.file])
    if args.example is not None:
        pose_file = example_file(args.example, args.problem, setup=args.setup, pairing=args.pairing)
        source = f"example {args.example!r}"
    else:
        pose_file = load_file(args.file, problem=args.problem, setup=args.setup, pairing=args.pairing)
        source = args.file
    data, truth, metadata = pose_file.data, pose_file.truth, pose_file.metadata
    options = parse_key_values(args.option)
    facts = _facts.take(args, options)
    clash = sorted(set(options) & set(data))
    if clash:
        raise InputError(f"--option {clash} clashes with the data field(s) of problem {args.problem!r}")
    solver = args.solver or default_solver(args.problem)

    solution = solve(args.problem, solver=solver, backend=args.backend, time_limit=time_limit(args, args.problem, solver),
                     **data, **facts, **options)
    problem = get_registry().problem(args.problem)
    residuals = problem.residuals(measured_data(problem, solution, data, facts), solution.unknowns)
    errors = problem.errors(solution.unknowns, truth) if truth is not None else None
    checks = None
    if pose_file.poses is not None and not args.no_checks and solution.status not in UNUSABLE:
        checks = check(Streams(pose_file.poses["robot_poses"], pose_file.poses["camera_poses"],
                               metadata.get("units") or "length units", metadata["setup"], args.problem,
                               metadata.get("pairing"), facts=facts), residuals)
        if not checks.plausible:
            solution = dataclasses.replace(solution, status=Status.UNRELIABLE)
    frames = frame_names(args.problem, metadata.get("setup"))
    report = {
        "source": source,
        "problem": args.problem,
        "units": metadata.get("units"),
        "setup": metadata.get("setup"),
        "pairs": len(next(iter(data.values()))),
        **_stations(pose_file, args.problem),
        "options": options,
        **solution.to_dict(),
        "frames": {name: frames[unknown_of(name)][0] for name in single_poses(solution.unknowns)
                   if unknown_of(name) in frames},
        "residuals": {k: _summary(v) for k, v in residuals.items()},
        "residuals_per_pair": {k: np.asarray(v).tolist() for k, v in residuals.items()},
        "errors": errors,
        "warnings": [*solution.warnings, *(checks.warnings if checks else ())],
        "checks": None if checks is None else checks.to_dict(),
    }
    print(dump_json(report) if args.json else in_cli_words(_text(report, frames)))
    if args.report:
        robot_poses = (pose_file.poses["robot_poses"] if pose_file.poses is not None  # the stations' T_base_flange
                       else data["A"] if args.problem == get_registry().cell_problem() else None)
        units = metadata.get("units")
        written = write_report(args.report, force=args.force, r=collect(
            problem=args.problem, setup=metadata.get("setup"), unit=units, solution=solution, residuals=residuals,
            frames=frames, checks=report["checks"], warnings=[in_cli_words(w) for w in report["warnings"]],
            inputs={"data": source + (f" ({units})" if units else "")}, robot_poses=robot_poses,
            stations=report.get("stations"), pairing=report.get("pairing"),
            command=getattr(args, "command_line", "handeye solve")))
        print(f"wrote {written[0]}", file=sys.stderr if args.json else sys.stdout)
    if solution.status is Status.UNRELIABLE:
        why = checks.warnings[0] if checks and not checks.plausible else solution.warnings[0]
        skip = " (--no-checks skips the file checks)" if checks and not checks.plausible else ""
        print(in_cli_words(f"handeye: error: status unreliable: {why}{skip}"), file=sys.stderr)
        return 1
    if solution.status in UNUSABLE:
        print(f"handeye: error: solver {solver!r} ended with status {solution.status}: its "
              f"{', '.join(solution.unknowns)} (printed above) are not an answer; try another solver or init",
              file=sys.stderr)
        return 1
    return 0


def example_file(name: str, problem: str, *, setup: str | None = None, pairing: str | None = None) -> PoseFile:
    """A bundled example (`EXAMPLE_PROBLEM` data, one pair per station) as data of `problem`: as
    it is for that problem; for another problem that reads absolute poses (``axxb``), its stations:
    robot_poses = A_i, camera_poses = T_cam_target (B_i^-1 eye-in-hand, B_i eye-to-hand;
    docs/conventions.md), with the truth of its unknowns taken from the cell's
    (`StationReader.cell_truth`: ``axxb``'s X is the example's X eye-in-hand, its Y eye-to-hand)."""
    data, truth, metadata = load_example(name)
    if problem == EXAMPLE_PROBLEM:
        if setup is not None or pairing is not None:
            raise InputError("--setup and --pairing apply to files of absolute poses (robot_poses, camera_poses); "
                             f"the bundled examples hold {EXAMPLE_PROBLEM!r} pairs A, B")
        return PoseFile(data, truth, metadata)
    readers = station_readers()
    if problem not in readers:
        raise InputError(f"the bundled examples are {EXAMPLE_PROBLEM!r} data (or stations for {sorted(readers)}), "
                         f"not {problem!r}")
    own_setup = metadata.get("setup", "eye-in-hand")
    camera = inverse(data["B"]) if own_setup == "eye-in-hand" else data["B"]
    cell = readers[problem].cell_truth
    if truth is not None and setup in (None, own_setup):
        truth = {u: truth[c] for u, c in cell[own_setup].items()} if cell else truth
    else:
        truth = None  # another setup than the recording's: its X has no known truth
    return from_poses(data["A"], camera, problem, setup=setup, pairing=pairing, truth=truth,
                      metadata=metadata, source=f"example {name}")


def _stations(pose_file: PoseFile, problem: str) -> dict[str, Any]:
    """For absolute poses: the number of stations, the pairing and which stations (i, j) each
    motion joins (pairing consecutive: (i, i + 1); all: every i < j, i outer)."""
    if pose_file.poses is None:
        return {}
    n = len(pose_file.poses["robot_poses"])
    if not station_readers()[problem].pairing:  # one pair per station (axyb)
        return {"stations": n}
    pairing = pose_file.metadata["pairing"]
    if pairing == "consecutive":
        joined = [(i, i + 1) for i in range(n - 1)]
    else:
        joined = [(int(i), int(j)) for i, j in zip(*np.triu_indices(n, k=1))]
    return {"stations": n, "pairing": pairing, "motions": joined}


def _summary(values: np.ndarray) -> dict[str, float]:
    values = np.asarray(values, dtype=float)
    return {"median": float(np.median(values)), "rms": float(np.sqrt(np.mean(values**2))),
            "max": float(np.max(values))}


def _text(r: dict[str, Any], frames: dict[str, tuple[str, str]]) -> str:
    unit = r["units"] or "data units"
    equation, item = equation_of(r["problem"])
    head = f"{r['source']}: {r['pairs']} {item}s"
    if "pairing" in r:
        head += f" from {r['stations']} stations"
    pairing = f"{r['pairing']} pairs" if "pairing" in r else None
    extras = ", ".join(x for x in (pairing, r["setup"], f"lengths in {unit}" if r["units"] else None) if x)
    lines = [head + (f" ({extras})" if extras else ""),
             f"solver {r['solver']} (backend {r['backend']}): status {r['status']}, "
             f"solver time {_ms(r['seconds'])}" + _setup_note(r["diagnostics"])]
    diagnostics = r["diagnostics"]
    std_all = standard_deviations(diagnostics)
    for name, T in single_poses(r["unknowns"]).items():
        known = frames.get(unknown_of(name))
        frame = f" = {known[0]} ({known[1]})" if known else ""
        lines += ["", f"{name}{frame} =", format_pose(np.array(T))]
        std = std_all.get(name)
        if std is not None:
            lines.append(f"  1-sigma: rotation {_value('rotation', std['rotation'], unit)}   "
                         f"translation {_value('translation', std['translation'], unit)}")
            if note := spread_note(diagnostics, name):
                lines[-1] += f" ({note.removeprefix(', ')})"
    reported = Reported.of(diagnostics)
    if reported.camera_scale is not None:
        std = reported.camera_scale_std
        sigma = "" if std is None else f" (1-sigma {std:.2g})"
        lines += ["", (f"camera scale s = {reported.camera_scale:.6g}{sigma}: the camera's translations times s "
                       "are in the robot's unit (the residuals below use them)")]
    if reported.camera_scales:  # a cell's monocular cameras, each its own scale
        stds = reported.camera_scales_std
        lines += ["", "camera scales (each monocular camera's translations times its s are in the robot's unit; the "
                      "residuals below use them):"]
        lines += [f"  {name:<14} s = {s:.6g}" + ("" if stds.get(name) is None else f" (1-sigma {stds[name]:.2g})")
                  for name, s in reported.camera_scales.items()]
    if not frames:
        lines += ["", ("(no setup given: docs/conventions.md says which frames the unknowns are for "
                       "eye-in-hand and eye-to-hand data)")]
    lines += ["", f"residuals of {equation} over the {item}s (angle and distance between the two sides):"]
    for kind, s in r["residuals"].items():
        lines.append(f"  {kind:<12}" + "   ".join(f"{stat} {_value(kind, s[stat], unit)}" for stat in ("median", "rms", "max")))
    lines += _per_pair(r, item, unit)
    lines += noise_lines(r["diagnostics"], unit)
    if r["errors"]:
        lines += ["", "errors against the file's truth (angle and distance):"]
        for name, e in r["errors"].items():
            lines.append(f"  {name}: rotation {_value('rotation', e['rotation'], unit)}   "
                         f"translation {_value('translation', e['translation'], unit)}")
    scalars = {k: v for k, v in r["diagnostics"].items()
               if k not in ("warnings", "data") and isinstance(v, (int, float, str, bool)) and not isinstance(v, bool)}
    if scalars:
        lines += ["", "diagnostics: " + ", ".join(f"{k}={_short(v)}" for k, v in scalars.items())]
    names = ", ".join(r["unknowns"])
    if r["status"] in UNUSABLE:
        lines.append(f"warning: status {r['status']}: the solver did not reach its answer; do not use {names}")
    elif r["status"] == Status.UNRELIABLE:
        lines.append(f"warning: status unreliable: the data do not support this answer; do not use "
                     f"{names} (the first warning below says why)")
    elif r["status"] == Status.UNCERTIFIED:
        lines.append("note: status uncertified: a valid answer, but the solver could not prove it "
                     "globally optimal")
    elif r["status"] == Status.SUBOPTIMAL:
        lines.append("note: status suboptimal: a usable answer, but the data support another fit far better "
                     "(the self-check's warning below says how far; solver auto returns that fit)")
    for w in r["warnings"]:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def _per_pair(r: dict[str, Any], item: str, unit: str) -> list[str]:
    """The residual of every pair (motion), or of the `LISTED_LARGEST` largest when there are
    more than `LIST_ALL_UP_TO` (largest: the sum of each residual relative to its median)."""
    rot = np.asarray(r["residuals_per_pair"]["rotation"], dtype=float)
    trans = np.asarray(r["residuals_per_pair"]["translation"], dtype=float)
    m = len(rot)
    if m <= LIST_ALL_UP_TO:
        shown, title = np.arange(m), f"per {item}:"
    else:
        score = rot / max(float(np.median(rot)), 1e-300) + trans / max(float(np.median(trans)), 1e-300)
        shown = np.sort(np.argsort(-score, kind="stable")[:LISTED_LARGEST])
        title = f"the {LISTED_LARGEST} largest of the {m} {item}s (--json lists every one):"
    joined = r.get("motions")
    lines = [f"  {title}", f"  {item:>14}   {'rotation [deg]':>14}   {'translation [' + unit + ']':>18}"]
    for i in shown:
        name = f"{i}" + (f" ({joined[i][0]}->{joined[i][1]})" if joined else "")
        lines.append(f"  {name:>14}   {np.degrees(rot[i]):14.4g}   {trans[i]:18.4g}")
    return lines


def noise_lines(diagnostics: dict[str, Any], unit: str) -> list[str]:
    """Where the answer's fit found the noise (`handeye.estimation.noise_sources`), when it weighed the pairs
    by it: each source's 1-sigma that did not vanish."""
    fit = diagnostics.get("refine", diagnostics)
    if fit.get("noise_model") != "sources":
        return []
    found = ", ".join(f"{name} {v:.2g} {'rad' if name.startswith('rotation') else unit}"
                      for name, v in fit["noise_sources"].items() if v > 0)
    return ["", (f"noise per source, 1-sigma ({fit['loglik_gain']:.0f} nats of log-likelihood better than one level "
                 f"per residual group; docs/solvers/auto.md): {found}")]


def _value(kind: str, v: float, unit: str) -> str:
    if kind == "rotation":
        return f"{v:.3g} rad ({math.degrees(v):.3g} deg)"
    return f"{v:.3g} {unit}"


def _short(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _setup_note(diagnostics: dict[str, Any]) -> str:
    """A note when the solve compiled an SDP (`compile_seconds` > 0): the first solve of an SDP
    solver in a process also loads cvxpy (~1 s) and compiles its problem, which a one-shot command
    always pays and a program solving repeatedly pays once."""
    if not float(diagnostics.get("compile_seconds") or 0.0) > 0.0:
        return ""
    return ("\n  (first SDP solve in this process: includes loading cvxpy and compiling the problem; "
            "repeated solves are much faster, see `handeye bench`)")


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.2f} ms" if seconds < 10 else f"{seconds:.1f} s"
