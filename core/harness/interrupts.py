"""Stopping a long run cleanly on SIGINT or SIGTERM.

The default SIGTERM ends a process on the spot, leaving its workers and no message behind, and
an exception raised by a signal handler while the main thread waits on a lock (a pool's futures)
can leave that lock broken. `stop_on_signals` instead records a stop request, which the run acts
on at safe points (`check_stop`) or at once inside an `interruptible` block; `Interrupted` (a
KeyboardInterrupt) then carries the signal and the exit code a shell reports (130, 143).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: seconds after a first SIGINT / SIGTERM in which further ones are ignored (the first one's
#: clean-up is running); later ones stop the clean-up too
STOP_GRACE = 5.0
#: seconds between two looks of a run waiting for its workers at a stop request
POLL = 0.1


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped a run (raised in the main thread by `stop_on_signals`). A
    KeyboardInterrupt, so code that handles Ctrl-C handles SIGTERM the same way."""

    def __init__(self, signum: int, message: str = "") -> None:
        self.signum = int(signum)
        super().__init__(message or f"stopped by {self.signal_name}")

    @property
    def signal_name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        """The code of a process ended by the signal, as shells report it: 130 SIGINT, 143 SIGTERM."""
        return 128 + self.signum


class StudyInterrupted(Interrupted):
    """A study stopped by SIGINT or SIGTERM: `saved` of its `total` units are in `journal` (None:
    the run had no journal, nothing was kept); running the study again with it resumes."""

    def __init__(self, signum: int, saved: int, total: int, journal: Path | None) -> None:
        self.saved, self.total, self.journal = saved, total, journal
        where = f"{saved:,} of {total:,} trials saved in {journal}" if journal else "nothing saved (no journal)"
        super().__init__(signum, f"stopped by {signal.Signals(signum).name}: {where}")


@dataclasses.dataclass
class _StopRequest:
    """The state of the `stop_on_signals` block of this process."""

    installed: bool = False  # the block's handlers are in place
    signum: int | None = None  # the signal that asked to stop (None: none yet)
    at: float = 0.0  # when (time.monotonic)
    raising: bool = False  # in an `interruptible` block: the handler raises at once


_stop = _StopRequest()


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """In the block, SIGINT and SIGTERM ask the run to stop (the default SIGTERM would end the
    process on the spot, leaving its workers and no message behind). The handler only records
    the request; the run acts on it at safe points (`check_stop`: between units, every
    `POLL` s while waiting for workers), or at once inside an `interruptible` block. An
    exception raised by a handler while the main thread waits on a lock (a pool's futures) can
    leave that lock broken, hence the deferral.

    A repeated signal within `STOP_GRACE` s of the first is ignored (the first one's clean-up is
    running); a later one raises `Interrupted` at once, wherever the run is. Only handlers still
    at Python's defaults are replaced (an application's own stay), only in the main thread (the
    only one that may set them); nested blocks leave it to the outermost; a process forked in
    the block gets the default behaviour back on its first signal.
    """
    if _stop.installed or threading.current_thread() is not threading.main_thread():
        yield
        return
    owner = os.getpid()

    def handler(signum: int, frame: Any) -> None:
        if os.getpid() != owner:  # a forked worker that has not reset its handlers yet
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        now, repeated = time.monotonic(), _stop.signum is not None
        if repeated and now - _stop.at < STOP_GRACE:
            return
        if not repeated:
            _stop.signum = signum
        _stop.at = now
        if _stop.raising or repeated:
            raise Interrupted(signum)

    defaults = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    previous = {signum: signal.signal(signum, handler) for signum, default in defaults.items()
                if signal.getsignal(signum) == default}
    _stop.installed = bool(previous)
    try:
        yield
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)
        if previous:
            _stop.installed, _stop.signum, _stop.raising = False, None, False


def check_stop() -> None:
    """Raise `Interrupted` if SIGINT or SIGTERM asked the `stop_on_signals` block to stop."""
    if _stop.signum is not None:
        raise Interrupted(_stop.signum)


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """In the block, a stop request raises `Interrupted` at once instead of at the next
    `check_stop`: for work of this thread that may stop anywhere, as Ctrl-C always could stop
    it (a unit solved in this process, a report written whole or not at all)."""
    previous = _stop.raising
    _stop.raising = True
    try:
        check_stop()  # a request that came before the block
        yield
    finally:
        _stop.raising = previous
