"""``handeye compare --data FILE`` / ``--example NAME``: held-out residuals of every solver on the
user's own data (k-fold cross-validation, `handeye.harness.crossval`).

The data file is read as for ``handeye solve`` (`handeye.io.load_file`: the problem's data
fields, or the absolute poses of stations with ``--setup`` / ``--pairing``). A bundled example
(pairs of AX=YB) is read as the stations' absolute poses when ``--problem`` forms motions
(``axxb``), so it is folded by station.

The folds run in this process, in one go, and the files are written at the end, whole or not at
all: Ctrl-C or SIGTERM (exit 130 / 143) leaves no file of the run behind; run it again.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError
from handeye.base.vocabulary import METRES_PER, millimetres_per
from handeye.cli._common import check_new_results, check_outputs_apart
from handeye.geometry.se3 import inverse
from handeye.host.registry import get_registry
from handeye.io.data_files import PoseFile, from_poses, load_file, station_readers

#: flags of the simulated studies that make no sense with --data / --example
SIMULATION_FLAGS = ("paper", "accuracy", "study", "noise_levels", "noise_rot", "noise_trans", "noise_on",
                    "pairs", "paper_pairs", "trials", "units", "truth", "jobs", "scheduler")
#: length unit of a file -> factor to mm
TO_MM = {unit: millimetres_per(unit) for unit in METRES_PER}
DEFAULT_FOLDS = 5
#: what a cross-validation writes to its folder, after its name (`write_crossval`); an earlier
#: run's files of that name are not overwritten without --force
CROSSVAL_FILES = ("_heldout.md", "_summary.json", "_folds.csv", "_pairs.csv", "_heldout.png")


def read(args: argparse.Namespace) -> tuple[Any, str]:
    """(`CrossValData`, a description of the source) from --data or --example."""
    from handeye.harness.crossval import CrossValData
    from handeye.io.examples import EXAMPLE_PROBLEM, load_example

    problem = args.problem
    get_registry().problem(problem)  # unknown problem: exit 2 listing the known ones
    if args.example:
        data, truth, metadata = load_example(args.example)
        source = f"example {args.example!r}"
        reader = station_readers().get(problem)
        if problem != EXAMPLE_PROBLEM:
            if reader is None or not reader.pairing:
                raise InputError(f"the examples hold {EXAMPLE_PROBLEM} pairs (one per station); problem {problem!r} "
                                 "cannot read them")
            setup = args.setup or metadata.get("setup", "eye-in-hand")
            camera = inverse(data["B"]) if setup == "eye-in-hand" else data["B"]  # B = T_target_cam eye-in-hand
            pose_file = from_poses(data["A"], camera, problem, setup=setup, pairing=args.pairing,
                                   metadata={k: v for k, v in metadata.items() if k in ("units",)}, source=source)
        else:
            if args.setup or args.pairing:
                raise InputError(f"--setup and --pairing do not apply to example {args.example!r} with problem "
                                 f"{EXAMPLE_PROBLEM!r}")
            pose_file = PoseFile(data, truth, metadata)
    else:
        pose_file = load_file(args.data, problem, setup=args.setup, pairing=args.pairing)
        source = f"file {str(args.data)!r}"
    metadata = pose_file.metadata
    return CrossValData(problem, pose_file.data, pose_file.truth, pose_file.poses, metadata.get("setup"),
                        metadata.get("pairing"), station_readers().get(problem),
                        TO_MM.get(metadata.get("units", ""))), source


def run(args: argparse.Namespace) -> int:
    check_flags(args)
    if args.data and args.example:
        raise InputError("give either --data FILE or --example NAME, not both")
    cv, source = read(args)
    return report(args, cv, source, args.name or (args.example or Path(args.data).stem), args.problem)


def check_flags(args: argparse.Namespace) -> None:
    """InputError for a flag of the simulated studies, or no output directory."""
    given = [f.replace("_", "-") for f in SIMULATION_FLAGS if getattr(args, f, None) not in (None, False)]
    if args.executor != "process":
        given.append("executor")
    if given:
        raise InputError(f"--{given[0]} belongs to the simulated studies (the folds run in this process); "
                         "with --data/--example/--cell/--real use --problem, --setup, --pairing, --solvers, --folds, "
                         "--seed, --timeout, --name, -o")
    if not args.output:
        raise InputError("give an output directory with -o OUTDIR")


def report(args: argparse.Namespace, cv: Any, source: str, name: str, problem: str) -> int:
    """Cross-validate `cv` (`handeye.harness.crossval.CrossValData`, read from `source`) with the
    solvers `args` names, write the files as `name` into ``-o`` and print the table."""
    from handeye.harness import default_specs, parse_specs
    from handeye.harness.crossval import run_crossval
    from handeye.harness.crossval_report import heldout_table, write_crossval
    from handeye.harness.interrupts import Interrupted, interruptible, stop_on_signals

    files = [name + suffix for suffix in CROSSVAL_FILES]
    check_outputs_apart([("-o", Path(args.output) / f) for f in files], [args.data, getattr(args, "cell", None)])
    check_new_results("-o", args.output, files, args.force)
    folds = DEFAULT_FOLDS if args.folds is None else args.folds
    specs = parse_specs(args.solvers, problem) if args.solvers else default_specs(problem)
    timeout = 30.0 if args.timeout is None else (args.timeout if args.timeout > 0 else None)
    try:
        with stop_on_signals(), interruptible():  # in memory, in one go; the files are written whole or not at all
            result = run_crossval(cv, specs, folds=folds, seed=0 if args.seed is None else args.seed,
                                  timeout=timeout, progress=not args.no_progress)
            paths = write_crossval(result, Path(args.output), name=name, source=source)
    except Interrupted as stop:
        print(f"handeye: stopped by {stop.signal_name} before the cross-validation was written (nothing of it is in "
              f"{args.output}); run the command again", file=sys.stderr)
        return stop.exit_code
    failed = sum(r["status"] == "failed" for r in result.folds)
    print(f"held-out residuals of {len(specs)} solver(s) on {source} ({problem}): {folds}-fold "
          f"cross-validation over {cv.count} {cv.item}s, seed {result.seed}; {failed} failed fit(s); "
          f"{result.seconds:.1f} s")
    print()
    print(heldout_table(result), end="")
    print()
    print("Lower is better only relative to the other solvers on the same folds: a held-out residual is the "
          "answer's error plus that pair's own noise (docs/harness.md).")
    for key in ("table", "folds", "pairs", "json", "figure"):
        print(f"{key:>7}: {paths[key]}")
    sys.stdout.flush()
    return 0
