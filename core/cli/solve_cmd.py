"""``handeye solve``: calibrate from a data file (or a bundled example) and report the answer.

Prints X and Y, the per-pair residual summary of A_i X = Y B_i (rotation angle of
(A_i X)(Y B_i)^-1, eq. 32, and translation distance, eq. 33), status, solver time, warnings
and, when the data come with a truth, the errors against it (eqs. 30-31). ``--json`` prints
the same as one JSON object.

Exit code 0 for status optimal, optimal_inaccurate and uncertified (a valid answer that the
solver could not certify globally optimal; the output says so). Exit code 1 for not_converged
and failed: the answer is still printed, for inspection, with a warning and one line on stderr,
but it must not be used.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from ..api import solve
from ..errors import InputError
from ..examples import DEFAULT_EXAMPLE, list_examples, load_example
from ..io import load_file, supported_extensions
from ..registry import get_registry
from ..solution import Status
from ._common import dump_json, format_pose, parse_key_values

NAME = "solve"
#: solvers tried, in order, when --solver is not given
DEFAULT_SOLVERS = ("auto", "kron-lstsq")
#: statuses whose unknowns must not be used: printed, but the exit code is 1 (solver failure)
UNUSABLE = (Status.NOT_CONVERGED, Status.FAILED)


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="solve a data file or a bundled example", description=__doc__)
    parser.add_argument("file", nargs="?", help=f"data file ({', '.join(supported_extensions())}; docs/formats.md)")
    parser.add_argument("--example", nargs="?", const=DEFAULT_EXAMPLE, metavar="NAME",
                        help=f"solve a bundled example instead of a file: {', '.join(list_examples())} "
                             f"(default {DEFAULT_EXAMPLE})")
    parser.add_argument("--problem", default="axyb", help="problem (default axyb)")
    parser.add_argument("--solver", help="solver (default: 'auto' if installed, else 'kron-lstsq'); see handeye list")
    parser.add_argument("--backend", help="backend of the solver (default: the solver's default)")
    parser.add_argument("--option", action="append", metavar="KEY=VALUE",
                        help="solver option, repeatable; VALUE true/false (any case) is a bool, else it is "
                             "read as JSON when it parses (1e-8, \"x\"), else as text")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)
    return parser


def default_solver(problem: str) -> str:
    names = get_registry().solver_names(problem)
    for name in DEFAULT_SOLVERS:
        if name in names:
            return name
    raise InputError(f"no default solver for problem {problem!r}; pass --solver, one of {names}")


def run(args: argparse.Namespace) -> int:
    if (args.file is None) == (args.example is None):
        raise InputError("give either a data FILE or --example [NAME] (not both, not neither)")
    if args.example is not None:
        if args.problem != "axyb":
            raise InputError(f"the bundled examples are 'axyb' data, not {args.problem!r}")
        data, truth, metadata = load_example(args.example)
        source = f"example {args.example!r}"
    else:
        pose_file = load_file(args.file, problem=args.problem)
        data, truth, metadata = pose_file.data, pose_file.truth, pose_file.metadata
        source = args.file
    options = parse_key_values(args.option)
    clash = sorted(set(options) & set(data))
    if clash:
        raise InputError(f"--option {clash} clashes with the data field(s) of problem {args.problem!r}")
    solver = args.solver or default_solver(args.problem)

    solution = solve(args.problem, solver=solver, backend=args.backend, **data, **options)
    problem = get_registry().problem(args.problem)
    residuals = problem.residuals(problem.validate(**data), solution.unknowns)
    errors = problem.errors(solution.unknowns, truth) if truth is not None else None
    report = {
        "source": source,
        "units": metadata.get("units"),
        "setup": metadata.get("setup"),
        "pairs": int(len(next(iter(data.values())))),
        "options": options,
        **solution.to_dict(),
        "residuals": {k: _summary(v) for k, v in residuals.items()},
        "residuals_per_pair": {k: np.asarray(v).tolist() for k, v in residuals.items()},
        "errors": errors,
        "warnings": solution.warnings,
    }
    print(dump_json(report) if args.json else _text(report))
    if solution.status in UNUSABLE:
        print(f"handeye: error: solver {solver!r} ended with status {solution.status}: its X, Y "
              "(printed above) are not an answer; try another solver or init", file=sys.stderr)
        return 1
    return 0


def _summary(values: np.ndarray) -> dict[str, float]:
    values = np.asarray(values, dtype=float)
    return {"median": float(np.median(values)), "rms": float(np.sqrt(np.mean(values**2))),
            "max": float(np.max(values))}


def _text(r: dict[str, Any]) -> str:
    unit = r["units"] or "data units"
    head = f"{r['source']}: {r['pairs']} pairs"
    extras = ", ".join(x for x in (r["setup"], f"lengths in {unit}" if r["units"] else None) if x)
    lines = [head + (f" ({extras})" if extras else ""),
             f"solver {r['solver']} (backend {r['backend']}): status {r['status']}, "
             f"solver time {_ms(r['seconds'])}" + _setup_note(r["diagnostics"])]
    for name, T in r["unknowns"].items():
        lines += ["", f"{name} =", format_pose(np.array(T))]
    lines += ["", "residuals of A_i X = Y B_i over the pairs (eqs. 32-33):"]
    for kind, s in r["residuals"].items():
        lines.append(f"  {kind:<12}" + "   ".join(f"{stat} {_value(kind, s[stat], unit)}" for stat in ("median", "rms", "max")))
    if r["errors"]:
        lines += ["", "errors against the file's truth (eqs. 30-31):"]
        for name, e in r["errors"].items():
            lines.append(f"  {name}: rotation {_value('rotation', e['rotation'], unit)}   "
                         f"translation {_value('translation', e['translation'], unit)}")
    scalars = {k: v for k, v in r["diagnostics"].items()
               if k not in ("warnings", "data") and isinstance(v, (int, float, str, bool)) and not isinstance(v, bool)}
    if scalars:
        lines += ["", "diagnostics: " + ", ".join(f"{k}={_short(v)}" for k, v in scalars.items())]
    if r["status"] in UNUSABLE:
        lines.append(f"warning: status {r['status']}: the solver did not reach its answer; do not use X, Y")
    elif r["status"] == Status.UNCERTIFIED:
        lines.append("note: status uncertified: a valid answer, but the solver could not prove it "
                     "globally optimal")
    for w in r["warnings"]:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


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
