"""The ``handeye`` command line: ``handeye list | simulate | solve | calibrate | plan | watch`` (see ``handeye --help``).

Each subcommand is one module of this package with ``add_parser(subparsers)`` (which registers
the subcommand and its arguments) and ``run(args) -> int`` (the exit code). `COMMANDS` lists
them; a new subcommand is one module plus one entry there.

Exit codes: 0 success; 2 bad input (unknown name, bad file, bad option, bad data: every
`handeye.HandEyeError` except `SolverError`, and unreadable files); 1 the solver failed
(`SolverError`, or ``handeye solve`` got a solution of status ``not_converged`` / ``failed``,
which it still prints), or an internal error (a bug in handeye or a plugin). Errors are one line
on stderr, ``handeye: error: ...`` (``handeye: internal error: ... (please report)`` for a bug),
without a traceback; Ctrl-C exits 130; running out of memory on the data is bad input (2). The
``handeye`` command is `console_main`, which also ends the process when a plugin left a thread
running.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import threading
from collections.abc import Sequence

from handeye import __version__
from handeye.base.errors import HandEyeError, SolverError
from handeye.cli import (
    bench_cmd,
    calibrate_cmd,
    compare,
    list_cmd,
    plan_cmd,
    simulate_cmd,
    solve_cmd,
    watch_cmd,
)
from handeye.cli._common import in_cli_words

#: the subcommand modules, in the order ``handeye --help`` shows them
COMMANDS = [list_cmd, simulate_cmd, solve_cmd, calibrate_cmd, plan_cmd, watch_cmd, compare, bench_cmd]

EXIT_OK, EXIT_SOLVER_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="handeye",
        description="Robot hand-eye / robot-world calibration: A_i X = Y B_i (problem axyb) and A_i X = X B_i "
                    "(problem axxb); docs/conventions.md.",
        epilog="exit codes: 0 success; 2 bad input (file, data, unknown name or option); 1 solver "
               "failure (including a solve whose status is not_converged or failed: the result is "
               "printed, do not use it) or internal error. Errors are one line on stderr.",
    )
    parser.add_argument("--version", action="version", version=f"handeye {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with `argv` (default ``sys.argv[1:]``); return the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or an argparse usage error (code 2)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_BAD_INPUT
    args.command_line = shlex.join(["handeye", *(sys.argv[1:] if argv is None else map(str, argv))])
    try:
        return int(args.run(args))
    except SolverError as exc:
        return _fail(exc, EXIT_SOLVER_FAILED)
    except HandEyeError as exc:
        return _fail(exc, EXIT_BAD_INPUT)
    except OSError as exc:  # unreadable / unwritable files
        return _fail(exc, EXIT_BAD_INPUT)
    except MemoryError:  # data larger than this machine's memory: the input, not a bug
        return _fail("not enough memory for these data; use a smaller file (fewer stations or pairs) or a machine "
                     "with more memory", EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        return _fail("interrupted", 130)
    except Exception as exc:  # noqa: BLE001 - a bug (ours or a plugin's): one line, no traceback, exit 1
        message = " ".join(str(exc).split())
        print(f"handeye: internal error: {type(exc).__name__}: {message} (please report)", file=sys.stderr)
        return EXIT_SOLVER_FAILED


def console_main() -> None:
    """The ``handeye`` command: `main`, then exit with its code. A thread that a plugin left
    running (not a daemon) would keep the process alive after the command is done: the output
    is flushed and the process ends at once instead."""
    code = main()
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _fail(exc: BaseException | str, code: int) -> int:
    message = in_cli_words(" ".join(str(exc).split())) or type(exc).__name__
    print(f"handeye: error: {message}", file=sys.stderr)
    return code
