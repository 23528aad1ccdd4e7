"""``handeye compare``: run a comparison study of registered solvers on simulated data and write
a tidy CSV, a JSON summary, PNG figures and markdown tables of times and errors.

The study comes from flags (``--solvers``, ``--noise-levels``, ``--pairs``, ...), from a study
file (``--study FILE.toml``, docs/harness.md), or is one of the built-in studies: without grid
flags, ``-o OUTDIR`` runs a noise sweep (m = 16) and a pair-count sweep (level 0.05) of every
registered solver of ``--problem``; ``--paper OUTDIR`` is the paper's Sec. IV-A (Fig. 3, Fig. 4,
Table I; docs/reproducing-the-paper.md); ``--accuracy OUTDIR`` the accuracy study (realistic
noise on A and B, m = 8, 16, 50, every solver against a refinement started at the truth when
``refine`` is installed). ``--trials``, ``--seed``, ``--solvers``, ``--units`` and ``--truth``
override what the study says. A folder that already holds the results of a study of the same
name is left alone unless ``--force`` is given.

Every finished trial is appended to ``OUTDIR/NAME.journal.jsonl`` at once. Ctrl-C or SIGTERM
stops the study cleanly (exit 130 / 143) and keeps the finished trials; running the same command
again resumes from the journal (a journal of another study definition is refused; ``--force``
starts afresh). The journal is removed once the final outputs are written.

``--data FILE -o OUTDIR`` (or ``--example NAME``) compares the solvers on your own data, which have
no truth, by held-out residuals: k-fold cross-validation (``--folds``, default 5, seeded by
``--seed``) over the pairs, or over the stations of a file of absolute poses read as AX=XB
(docs/harness.md, "Held-out residuals on your own data"). ``--cell FILE -o OUTDIR`` ranks every
solver on a cell's board images by the corners of held-out images they predict (with what
``handeye calibrate`` answers, and OpenCV's methods), and ``--real -o OUTDIR`` does so for every
real recording handeye bundles (docs/harness.md, "Held-out corners on your own images").

``--problem axxb`` (A_i X = X B_i) compares the AX=XB solvers the same way: the simulator puts
the noise on the robot poses (A) and the camera poses (B) of the stations (``--pairs``: how many),
then forms the motions (``--pairing all``, the default, or ``consecutive``); OpenCV's five methods
are five contenders.

``--problem axbycz`` (A_i X B_i = Y C_i Z, two robots) compares every axbycz solver with noise on
A, B and C; the built-in studies run each sweep twice, on free motion (both robots move at every
triple) and on the phase protocol (one robot holds still at a time: sweeps named ``...-phases``),
since the two-step solvers need the latter; ``--protocol free`` or ``phases`` runs one of them
(and sets the simulator's protocol of ``--study`` / grid studies). A solver given data of the
wrong protocol is recorded as failed, with its reason.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError
from handeye.base.vocabulary import SETUPS
from handeye.cli._common import (
    add_force_flag,
    check_new_results,
    finite_number,
    seed_number,
    whole_number,
)
from handeye.estimation.noise import NoiseModel
from handeye.host.registry import get_registry

NAME = "compare"
#: the noise levels (sigma_N, paper reading: rad and mm on A and B) when neither levels nor a
#: base noise are given
DEFAULT_LEVELS = "0,0.02,0.05,0.1"
#: what a study writes to its folder besides its figures, after the study's name
#: (`handeye.harness.write_report`): an earlier run's files of that name are not overwritten
#: without --force
STUDY_FILES = (".csv", "_summary.json", "_times.md", "_errors.md")


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(NAME, help="compare solvers on simulated data (harness)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--paper", metavar="OUTDIR", help="run the paper's study (Fig. 3, Fig. 4, Table I) into OUTDIR")
    which.add_argument("--accuracy", metavar="OUTDIR",
                       help="run the accuracy study (every solver against the oracle) into OUTDIR")
    which.add_argument("--study", metavar="FILE", help="study file (TOML, docs/harness.md)")
    which.add_argument("--data", metavar="FILE",
                       help="your own data file: held-out residuals of every solver by k-fold cross-validation "
                            "(needs -o OUTDIR; docs/harness.md)")
    which.add_argument("--example", metavar="NAME", help="as --data, on a bundled example (eth-robot-arm, simulated)")
    which.add_argument("--cell", metavar="FILE",
                       help="a cell file of one camera (as calibrate --config): board images ranked by held-out "
                            "board corners, pose files by held-out residuals (needs -o OUTDIR; docs/harness.md)")
    which.add_argument("--real", action="store_true",
                       help="every real recording handeye bundles, each as --cell / --example (needs -o OUTDIR)")
    parser.add_argument("--folds", type=whole_number, default=None, metavar="K",
                        help="--data/--example: number of cross-validation folds (default 5)")
    parser.add_argument("--setup", choices=SETUPS, default=None,
                        help="--data/--example: setup of a file of absolute poses (overrides the file's)")
    parser.add_argument("-o", "--output", metavar="OUTDIR", help="output directory (not with --paper/--accuracy)")
    parser.add_argument("--problem", default=None,
                        help="registered problem (handeye list shows them; default: the default problem, A_i X = Y B_i)")
    parser.add_argument("--pairing", choices=("consecutive", "all"),
                        help="a problem solved from motions between stations (A_i X = X B_i): motions between all "
                             "pairs of stations i < j (default, as OpenCV) or consecutive ones")
    parser.add_argument("--protocol", metavar="PROTOCOL",
                        help="a problem with data protocols (A_i X B_i = Y C_i Z: free, both robots moving at every "
                             "triple, or phases, one robot still at a time): the one to run (default: the built-in "
                             "studies run each)")
    parser.add_argument("--solvers", metavar="LIST",
                        help="comma-separated: name, name/backend, name/* (every backend) or all "
                             "(default: every registered solver, every lmi-sdp backend; with --paper: "
                             "lmi-sdp (every backend), iterative, dual-quaternion (normalize=false), then "
                             "every other registered solver)")
    parser.add_argument("--noise-levels", metavar="LEVELS",
                        help=f"multipliers of the base noise, '0,0.01' or start:stop:step (default "
                             f"{DEFAULT_LEVELS} with the paper's base noise, 1 with --noise-rot/--noise-trans)")
    parser.add_argument("--noise-rot", type=finite_number, metavar="RAD", help="base rotation noise std (rad)")
    parser.add_argument("--noise-trans", type=finite_number, metavar="MM", help="base translation noise std (mm)")
    parser.add_argument("--noise-on", default=None, metavar="B|A|both",
                        help="data stack(s) the base noise goes on (default both for the paper's reading, "
                             "B with --noise-rot/--noise-trans)")
    parser.add_argument("--pairs", metavar="LIST",
                        help="pair counts, '10,20' or start:stop:step (default: a noise sweep at 16 and a "
                             "pair-count sweep 8, 16, 32, 64; with other grid flags 16)")
    parser.add_argument("--paper-pairs", type=whole_number, default=None, metavar="M",
                        help="m of the paper's noise sweep (Fig. 3; default 16)")
    parser.add_argument("--trials", type=whole_number, help="trials per cell (default 5; --accuracy 20)")
    parser.add_argument("--seed", type=seed_number, help="master seed (default 0)")
    parser.add_argument("--units", choices=("mm", "m"), help="length unit the solvers get (default mm)")
    parser.add_argument("--truth", choices=("paper", "random"), help="X, Y: the paper's or random per trial")
    parser.add_argument("--name", help="study name (file prefix; default study)")
    parser.add_argument("--jobs", type=whole_number, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--timeout", type=finite_number, metavar="SECONDS",
                        help="stop a solve after this long and record it as failed (default 30, --paper 10; "
                             "0: no limit)")
    parser.add_argument("--executor", choices=("process", "dask"), default="process",
                        help="process pool (default) or a dask.distributed cluster (pip install handeye[dask])")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="dask scheduler address, e.g. tcp://host:8786 (default: a local cluster)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_force_flag(parser)
    parser.set_defaults(run=run)
    return parser


def build_study(args: argparse.Namespace) -> tuple[Any, Path]:
    """The study and the output directory the arguments describe."""
    from handeye.harness import (
        Study,
        Sweep,
        accuracy_study,
        load_study,
        missing_paper_methods,
        paper_noise,
        paper_study,
        parse_floats,
        parse_ints,
        parse_specs,
        sweep_study,
    )

    registry = get_registry()
    given_problem = args.problem
    args.problem = args.problem or registry.default_problem()
    grid_flags = [f for f in ("noise_levels", "pairs", "noise_rot", "noise_trans", "noise_on") if getattr(args, f) is not None]
    builtin = args.paper or args.accuracy or args.study
    if builtin and grid_flags:
        raise InputError(f"--{grid_flags[0].replace('_', '-')} defines a grid; it cannot be combined with "
                         "--paper, --accuracy or --study (edit a study file instead)")
    if (args.paper or args.accuracy) and args.output:
        raise InputError("--paper and --accuracy take the output directory themselves; drop -o")
    if args.paper_pairs is not None and not args.paper:
        raise InputError("--paper-pairs only applies to --paper")
    if not (args.paper or args.accuracy) and not args.output:
        raise InputError("give an output directory with -o OUTDIR (or use --paper/--accuracy OUTDIR)")
    specs = parse_specs(args.solvers, args.problem) if args.solvers else ()
    _protocols(args)  # --protocol for a problem without protocols: the error here
    if args.paper and args.problem != registry.default_problem():
        raise InputError(f"--paper is the paper's study of problem {registry.default_problem()!r}, not "
                         f"{args.problem!r}; use --accuracy or -o OUTDIR for it")

    if args.paper:
        study = paper_study(specs=specs, **({"pairs": args.paper_pairs} if args.paper_pairs else {}))
        outdir = args.paper
        missing = missing_paper_methods(args.problem) if not specs else []
        if missing:
            print(f"note: the paper's method(s) {', '.join(missing)} are not registered here; "
                  "the study runs without them", file=sys.stderr)
    elif args.accuracy:
        study = accuracy_study(problem=args.problem, specs=specs, protocols=_protocols(args))
        outdir = args.accuracy
    elif args.study:
        study = load_study(args.study)
        outdir = args.output
    elif not grid_flags:
        study = sweep_study(args.problem, name=args.name or "study", protocols=_protocols(args))
        outdir = args.output
    else:
        if args.noise_rot is None and args.noise_trans is None:
            fields = tuple(registry.problem(args.problem).data_fields)
            noise = paper_noise(1.0, stacks=_stacks(args, default=fields))
            levels = parse_floats(args.noise_levels or DEFAULT_LEVELS, "--noise-levels")
        else:
            noise = NoiseModel.on(_stacks(args, default=("B",)), args.noise_rot or 0.0, args.noise_trans or 0.0)
            levels = parse_floats(args.noise_levels or "1", "--noise-levels")
        pairs = parse_ints(args.pairs or "16", "--pairs")
        study = Study(name=args.name or "study", problem=args.problem, noise=noise,
                      sweeps=(Sweep("grid", levels, pairs),))
        outdir = args.output
    changes: dict[str, Any] = {}
    if specs and not args.accuracy:  # accuracy_study got them already (and adds the oracle)
        changes["specs"] = specs
    for name in ("trials", "seed", "units", "truth", "name"):
        if getattr(args, name) is not None:
            changes[name] = getattr(args, name)
    if args.timeout is not None:
        changes["timeout"] = args.timeout if args.timeout > 0 else None
    if given_problem is not None and args.study:
        changes["problem"] = args.problem
    if args.pairing is not None:
        problem = changes.get("problem", study.problem)
        reader = registry.problem(problem).station_reader
        if reader is None or not reader.pairing:
            paired = sorted(n for n, p in registry.problems.items() if p.station_reader and p.station_reader.pairing)
            raise InputError(f"--pairing applies to problems solved from motions between stations ({', '.join(paired)}), "
                             f"not {problem!r}")
        changes["simulation"] = {**study.simulation, "pairing": args.pairing}
    if args.protocol is not None and (args.study or grid_flags):
        changes["simulation"] = {**changes.get("simulation", study.simulation), "protocol": args.protocol}
    return (study.replace(**changes) if changes else study), Path(outdir)


def _protocols(args: argparse.Namespace) -> tuple[str, ...] | None:
    """The data protocols a built-in study runs (None: all of the problem's); --protocol applies
    to problems with protocols only (`Problem.protocols`)."""
    if args.protocol is None:
        return None
    registry = get_registry()
    known = registry.problem(args.problem).protocols
    if not known:
        having = sorted(n for n, p in registry.problems.items() if p.protocols)
        raise InputError(f"--protocol applies to problems with data protocols ({', '.join(having)}), "
                         f"not {args.problem!r}")
    if args.protocol not in known:
        raise InputError(f"--protocol {args.protocol!r} is not one of {', '.join(known)} (problem {args.problem!r})")
    return (args.protocol,)


def _stacks(args: argparse.Namespace, default: tuple[str, ...]) -> tuple[str, ...]:
    fields = tuple(get_registry().problem(args.problem).data_fields)
    if args.noise_on is None:
        return default
    if args.noise_on in ("both", "all"):
        return fields
    stacks = tuple(s.strip() for s in args.noise_on.split(",") if s.strip())
    unknown = [s for s in stacks if s not in fields]
    if unknown or not stacks:
        raise InputError(f"--noise-on {args.noise_on!r}: use data fields of {args.problem!r} {list(fields)} or 'both'")
    return stacks


def open_journal(args: argparse.Namespace, study: Any, outdir: Path) -> Any:
    """The run's `StudyJournal` in `outdir`: an unfinished run of the same study there is resumed
    (its final files, if the report was being written when it stopped, are then rewritten);
    otherwise, as for every command, earlier results are not overwritten without --force, which
    also discards the journal and starts afresh. A journal of another study definition: exit 2."""
    from handeye.harness.result import StudyJournal, journal_path

    path = journal_path(outdir, study.name)
    if args.force or not path.exists():
        flag = "--paper" if args.paper else "--accuracy" if args.accuracy else "-o"
        check_new_results(flag, outdir, [study.name + suffix for suffix in STUDY_FILES], args.force)
    return StudyJournal.open(path, study, fresh=args.force,
                             hint="pass --force to discard it and start afresh (or use another folder or --name)")


def run(args: argparse.Namespace) -> int:
    from handeye.harness import run_study, time_table, write_report
    from handeye.harness.interrupts import (
        Interrupted,
        StudyInterrupted,
        interruptible,
        stop_on_signals,
    )

    if args.cell or args.real:
        from handeye.cli import compare_cell

        args.problem = args.problem or get_registry().default_problem()
        return compare_cell.run(args)
    if args.data or args.example:
        from handeye.cli import compare_data

        args.problem = args.problem or get_registry().default_problem()
        return compare_data.run(args)
    for flag in ("folds", "setup"):
        if getattr(args, flag) is not None:
            raise InputError(f"--{flag} applies to --data FILE / --example NAME / --cell FILE / --real only")
    study, outdir = build_study(args)
    if args.scheduler and args.executor != "dask":
        raise InputError("--scheduler needs --executor dask")
    journal = open_journal(args, study, outdir)
    if journal.resumed:
        print(f"resumed {journal.resumed:,} of {journal.total:,} trials from {journal.path}")
        sys.stdout.flush()
    try:
        with stop_on_signals():
            result = run_study(study, jobs=args.jobs, progress=not args.no_progress,
                               executor=args.executor, scheduler=args.scheduler, journal=journal)
            with interruptible():  # the report is written whole or not at all
                paths = write_report(result, outdir)
    except StudyInterrupted as stop:
        print(f"handeye: {stop}; run the same command again to resume", file=sys.stderr)
        return stop.exit_code
    except Interrupted as stop:
        print(f"handeye: stopped by {stop.signal_name} while writing the report; every trial is saved in "
              f"{journal.path}: run the same command again to write it", file=sys.stderr)
        return stop.exit_code
    journal.remove()
    failed = sum(r["status"] == "failed" for r in result.records)
    print(f"study {study.name!r}: {len(result.records)} runs ({failed} failed) of {len(result.specs)} "
          f"solver(s) in {result.seconds:.1f} s (CPU {result.cpu_seconds:.1f} s) with {result.jobs} job(s) "
          f"[{result.executor}]")
    print()
    print(time_table(result), end="")
    print()
    for key in ("csv", "json", "times", "errors"):
        print(f"{key:>7}: {paths[key]}")
    for path in paths["figures"]:
        print(f" figure: {path}")
    sys.stdout.flush()
    return 0
