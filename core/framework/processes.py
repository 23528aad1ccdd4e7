"""Child processes that end with the process that started them.

A worker process (a study's process-pool worker, a solve run under a time limit) must not outlive
its parent: killed outright (SIGKILL), a parent has no chance to stop its children, and an
orphaned worker would go on computing, or wait for work forever, holding the parent's output
pipes open. `die_with_parent` makes the calling process end with its parent: on Linux by
PR_SET_PDEATHSIG (the kernel sends the signal when the parent thread that forked it ends),
elsewhere by a daemon thread that watches os.getppid().
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

#: seconds between two looks of a worker at its parent where PR_SET_PDEATHSIG is not available
PARENT_POLL = 0.5
#: prctl(2) option: the signal a process gets when its parent dies (Linux)
PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int, poll: float = PARENT_POLL) -> None:
    """End this process when process `parent` ends, even by SIGKILL, which gives the parent no
    chance to stop it (an orphaned pool worker would wait for work forever, holding the
    parent's output pipes open). Linux: PR_SET_PDEATHSIG (the kernel sends SIGKILL when the
    thread that forked this process ends; the pool forks its workers from the thread that
    submits the units, which lives until the pool is stopped). Elsewhere: a daemon thread that
    looks at os.getppid() every `poll` seconds. Either way, a parent already gone ends it now."""
    if not set_parent_death_signal(signal.SIGKILL):
        threading.Thread(target=_watch_parent, args=(parent, poll), name="handeye-parent-watch", daemon=True).start()
    if os.getppid() != parent:
        os._exit(1)


def set_parent_death_signal(signum: int) -> bool:
    """prctl(PR_SET_PDEATHSIG, signum) through ctypes; False where it is not available."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(parent: int, poll: float) -> None:
    """Exit this process as soon as its parent is no longer `parent` (it died; the orphan was
    given to init or a subreaper)."""
    while os.getppid() == parent:
        time.sleep(poll)
    os._exit(1)
