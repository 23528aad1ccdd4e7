"""The --kinhec flags of ``handeye bench`` and its printing: the benchmark itself is
`handeye.harness.kinhec` (docs/kinhec.md)."""

from __future__ import annotations

import argparse

from handeye.base.errors import InputError
from handeye.cli._common import whole_number
from handeye.harness.kinhec import KINHEC_FILES, register_solvers, run_kinhec  # noqa: F401 (register_solvers: its old place)
from handeye.harness.kinhec_report import AUTO, HANDEYE_FILES, auto_vs_best_table

#: flags that apply to --kinhec only (dest, flag)
_ONLY_KINHEC = (("kinhec_out", "--kinhec-out"), ("tracks", "--tracks"), ("max_sequences", "--max-sequences"),
                ("workers", "--workers"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The --kinhec flags of ``handeye bench``."""
    group = parser.add_argument_group("KinHEC benchmark (docs/kinhec.md; needs pip install \"handeye[kinhec]\")")
    group.add_argument("--kinhec", metavar="DATA_DIR",
                       help="run KinHEC's own protocol on the dataset DATA_DIR (made by kinhec generate) with every "
                            "handeye solver registered beside KinHEC's references (handeye:NAME: AX=YB; "
                            "handeye-axxb:NAME: AX=XB); --solvers then takes KinHEC names or the groups handeye, "
                            "handeye-axxb, kinhec (handeye:auto and shah+lm always run)")
    group.add_argument("--kinhec-out", metavar="DIR",
                       help="where KinHEC's results and handeye's head-to-head go (default DATA_DIR/benchmarks; "
                            "results there are kept unless --force)")
    group.add_argument("--tracks", metavar="LIST", help="comma-separated KinHEC tracks (default: all)")
    group.add_argument("--max-sequences", type=whole_number, metavar="N",
                       help="a random subset of N sequences (KinHEC's sampling, seed 0)")
    group.add_argument("--workers", type=whole_number, metavar="N", help="KinHEC's worker processes (default 1)")


def requested(args: argparse.Namespace) -> bool:
    """Whether ``handeye bench`` runs KinHEC (``--kinhec``); InputError for a flag of the other
    mode (a --kinhec flag without it, or --pairs / --json / --problem with it)."""
    if args.kinhec is None:
        given = [flag for dest, flag in _ONLY_KINHEC if getattr(args, dest, None) is not None]
        if given:
            raise InputError(f"{given[0]} applies to handeye bench --kinhec DATA_DIR only")
        return False
    for dest, flag in (("pairs", "--pairs"), ("json", "--json")):
        if getattr(args, dest, None) is not None:
            raise InputError(f"{flag} does not apply to --kinhec: KinHEC's protocol makes the data, and the results "
                             "go to --kinhec-out")
    from handeye.host.registry import get_registry

    if getattr(args, "problem", None) not in (None, get_registry().default_problem()):
        raise InputError("--problem does not apply to --kinhec: the solvers of every problem KinHEC's data serve are "
                         "registered")
    return True


def run(args: argparse.Namespace) -> int:
    """``handeye bench --kinhec DATA_DIR ...``: `run_kinhec`, then the per-track table on stdout."""
    tracks = [t.strip() for t in args.tracks.split(",") if t.strip()] if args.tracks else None
    result = run_kinhec(args.kinhec, args.kinhec_out, tracks=tracks, max_sequences=args.max_sequences,
                        solvers=args.solvers, workers=args.workers or 1, progress=not args.no_progress,
                        force=args.force)
    n_seq = len({r.get("sequence_id") for r in result.rows})
    print(f"handeye bench --kinhec {args.kinhec}: {n_seq} sequences, {len(result.solvers)} solvers "
          f"({len(result.references)} KinHEC references), {result.seconds:.0f} s; started {result.machine}")
    print()
    print(f"{AUTO} against the best KinHEC reference of each track (medians; X rot [deg], X trans [mm]):")
    print(auto_vs_best_table(result.auto_vs_best))
    if result.skipped:
        print()
        print("handeye solvers not registered:")
        for note in result.skipped:
            print(f"  {note}")
    print()
    print(f"written to {result.out_dir}: " + ", ".join(KINHEC_FILES + HANDEYE_FILES))
    return 0
