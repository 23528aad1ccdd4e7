"""``handeye bench``: median solve time of every registered solver/backend of a problem beside the
problem's reference rows (e.g. OpenCV through handeye's ``opencv`` solver and called directly),
measured in the same run.

Every solver of ``--problem`` (default: the registry's default problem; ``handeye list`` names
them all, third-party ones included) on every available backend is timed through `handeye.solve`
on simulated noisy data at each pair count m. What else is timed, the reference of the ratio
column, the speed targets and the data come from the problem itself (`Problem.bench`), so a
problem added as a plugin is benchmarked like a built-in one. The first lines of the printout say
what the data were; bench/README.md describes the built-in problems' settings.

Per m and per row: one warm-up solve, then ``--repeats`` timed solves taken round-robin over the
rows (so that load changes on a shared machine hit every row alike), reported as the median. Two
times per solve: "call" is the wall time of the `handeye.solve` call (what a user waits for);
"run" is `Solution.seconds`, the solver's own ``run`` only (without validation and checks).
Targets are judged on the call time; the run time is printed beside it.

A row whose single solve takes longer than ``--budget`` seconds is not repeated and not run at
larger m ("skipped (>5 s)"); its repeats are also capped so that one cell stays within the budget.
This is a benchmark, not a test: numbers depend on the machine and its load. The work is done by
`handeye.harness.bench` (timing) and `handeye.harness.bench_report` (tables, verdicts); this
module parses the arguments and prints.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from handeye.base.errors import InputError
from handeye.cli import _kinhec
from handeye.cli._common import (
    add_force_flag,
    check_outputs,
    finite_number,
    seed_number,
    whole_number,
)
from handeye.harness import bench
from handeye.harness.bench_report import (
    data_line,
    errors,
    payload,
    same_method_lines,
    table,
    target_lines,
)
from handeye.host.registry import get_registry
from handeye.io.output_files import check_writable, new_file

NAME = "bench"
DEFAULT_REPEATS = bench.DEFAULT_REPEATS
DEFAULT_BUDGET = bench.DEFAULT_BUDGET


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="time every solver beside the problem's references, e.g. OpenCV (benchmark)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    parser.set_defaults(run=run)
    return parser


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--problem", default=None,
                        help="registered problem whose solvers are timed (default: the default problem)")
    parser.add_argument("--pairs", default=None, metavar="LIST",
                        help="comma-separated pair counts m (the problem's data items: pairs, motions, ...) "
                             "(default: the problem's own)")
    parser.add_argument("--repeats", type=whole_number, default=DEFAULT_REPEATS, metavar="N",
                        help=f"timed solves per cell after the warm-up; the median is shown (default {DEFAULT_REPEATS})")
    parser.add_argument("--solvers", metavar="LIST",
                        help="comma-separated solver or solver/backend names (default: all registered); "
                             "the problem's reference rows are always timed")
    parser.add_argument("--budget", type=finite_number, default=DEFAULT_BUDGET, metavar="SECONDS",
                        help=f"per-solve time budget: slower rows are not repeated nor run at larger m "
                             f"(default {DEFAULT_BUDGET:g})")
    parser.add_argument("--seed", type=seed_number, default=0, help="simulation seed (default 0)")
    parser.add_argument("--noise-rot", type=finite_number, default=0.005, metavar="RAD",
                        help="rotation noise std on the simulated poses (every data stack, unless the problem "
                             "says otherwise in the printout), rad (default 0.005)")
    parser.add_argument("--noise-trans", type=finite_number, default=0.5, metavar="MM",
                        help="translation noise std on the simulated poses, mm (default 0.5)")
    parser.add_argument("--json", metavar="FILE",
                        help="also write every timing to FILE (JSON; an existing file is kept unless --force)")
    add_force_flag(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    _kinhec.add_arguments(parser)  # --kinhec DATA_DIR: KinHEC's protocol (docs/kinhec.md)


def parse_pairs(text: str, minimum: int = 3) -> list[int]:
    try:
        pairs = [int(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise InputError(f"--pairs expects comma-separated integers, got {text!r}") from None
    if not pairs or min(pairs) < minimum:
        raise InputError(f"--pairs needs pair counts >= {minimum}, got {text!r}")
    return sorted(set(pairs))


def run(args: argparse.Namespace) -> int:
    if args.problem is None:
        args.problem = get_registry().default_problem()
    if _kinhec.requested(args):
        return _kinhec.run(args)
    pairs = parse_pairs(args.pairs, bench.min_pairs(args.problem)) if args.pairs else None
    if args.repeats < 1:
        raise InputError(f"--repeats must be >= 1, got {args.repeats}")
    if not args.budget > 0:
        raise InputError(f"--budget must be > 0 seconds, got {args.budget}")
    check_outputs([("--json", args.json)], [getattr(args, "kinhec", None)], args.force)
    if args.json:
        check_writable("--json", args.json)  # before the benchmark, not after it
    result = bench.run_bench(args.problem, pairs, repeats=args.repeats, budget=args.budget, seed=args.seed,
                             noise_rot=args.noise_rot, noise_trans=args.noise_trans, solvers=args.solvers,
                             progress=not args.no_progress)
    print_run(result)
    if args.json:
        with new_file(args.json, force=args.force, flag="--json") as f:
            json.dump(payload(result), f, indent=1)
    return 0


def print_run(result: bench.BenchRun) -> None:
    """The printout of a benchmark run: what and where, the two tables, then the notes."""
    print(f"handeye bench ({result.problem}): {result.machine}")
    print(f"data: {data_line(result)}")
    print(f"median of up to {result.repeats} solves after one warm-up, round-robin over the rows; "
          f"budget {result.budget:g} s per solve")
    print()
    print("time of the handeye.solve call (validation + solver + checks); ratio to "
          f"'{result.reference}' at the same m; * = a single solve over the budget")
    print(table(result, "call"))
    print()
    print("solver run alone (Solution.seconds; rows called directly: the call itself)")
    print(table(result, "run"))
    failed = errors(result)
    if failed:
        print()
        print("errors (the row's solve raised; first 200 characters):")
        for (label, m), text in failed.items():
            print(f"  {label} at m={m}: {text[:200]}")
    if result.unavailable:
        print()
        print("not timed (unavailable here):")
        for note in result.unavailable:
            print(f"  {note}")
    same = same_method_lines(result)
    if same:
        print()
        print("handeye's implementation of a method beside the same method called directly (call time ratio):")
        for line in same:
            print(line)
    targets = target_lines(result)
    if targets:
        print()
        print("targets (judged on the handeye.solve call time):")
        for line in targets:
            print(line)
