"""One progress bar for every long job (a study's trials, held-out comparisons, benchmark solves,
board detection): tqdm on stderr."""

from __future__ import annotations

import sys
from typing import Any


def progress_bar(total: int, description: str | None, unit: str, show: bool = True, *, in_logs: bool = False,
                 initial: int = 0) -> Any:
    """A tqdm bar on stderr counting `total` `unit`s (`initial` already done, e.g. resumed), a
    context manager with ``update()``. Shown when `show`: on a terminal only (tqdm's
    ``disable=None``: not in a log, a pipe or a test), and cleared when done; with `in_logs` also
    where stderr is a file, and kept, so that a long study's log records its rate and time left.
    Without tqdm's monitor thread: no thread may run when a process pool forks its workers."""
    from tqdm import tqdm

    class Bar(tqdm):
        monitor_interval = 0

    disable = True if not show else (False if in_logs else None)
    return Bar(total=total, initial=initial, desc=description, unit=unit, disable=disable, leave=in_logs,
               dynamic_ncols=True, file=sys.stderr)
