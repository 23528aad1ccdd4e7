"""Running a solver in a worker process with a time limit it cannot escape.

A signal-based limit (SIGALRM raising an exception in the solver) is defeated by a plugin that
catches the exception, by a C call that never returns, and by a thread the plugin leaves running.
`call_with_time_limit` instead runs the call in a forked child process: the parent waits for the
answer at most `seconds` and then kills the child (SIGKILL), whatever it is doing; threads the
call started end with the child, and so do processes it started: the child leads a process group
of its own, which is killed whole when the call ends, answered or not (a solver's helper process
left running held a pipe open for 10 minutes after the time limit). Forking copies the parent, so run-time plugins, the registry and
the data need no pickling on the way in; the answer (or the exception) comes back pickled.

Used by `handeye.solve(..., time_limit=...)`: off by default for the library (a fork costs
milliseconds); the command line and studies turn it on for third-party plugins.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import warnings
from collections.abc import Callable, Iterator
from typing import Any

from handeye.base.errors import SolverError, SolverTimeoutError
from handeye.framework.processes import set_parent_death_signal


def fork_available() -> bool:
    """Whether this platform can fork (POSIX); elsewhere a time limit cannot be enforced."""
    return "fork" in multiprocessing.get_all_start_methods()


def call_with_time_limit(call: Callable[[], Any], seconds: float, who: str) -> Any:
    """call() run in a forked child process, its result (or exception) returned (raised) here;
    after `seconds` the child is killed and `SolverTimeoutError` raised. `who` names the solver
    in messages ("solver 'x' (plugin 'y' from z 1.0)")."""
    if not fork_available():
        raise SolverError(f"a time limit needs a platform that can fork a process; run {who} without one")
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    with warnings.catch_warnings(), _signals_held():  # Python >= 3.12 warns about fork with threads (BLAS pools)
        warnings.simplefilter("ignore", DeprecationWarning)
        child = context.Process(target=_child, args=(send, call), daemon=True)
        child.start()
    send.close()
    try:
        if not receive.poll(seconds):
            raise SolverTimeoutError(f"{who} gave no answer within {seconds:g} s and was stopped; raise the time "
                                     "limit, or use another solver")
        try:
            kind, payload = receive.recv()
        except (EOFError, OSError):
            child.join(1.0)
            raise SolverError(f"{who} ended its process without an answer (exit code {child.exitcode}); it may "
                              "have crashed") from None
        except Exception as exc:  # noqa: BLE001 - an answer or exception that does not unpickle
            raise SolverError(f"{who}'s answer could not be read back from its worker process: "
                              f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None
    finally:
        receive.close()
        _end_group(child)
        child.join()
    if kind == "error":
        raise payload
    return payload


def _end_group(child: Any) -> None:
    """Kill the child and every process in its process group (those the call started). The group
    is the child's own (`_child` makes it): its id is the child's pid, never this process's group;
    where the child had not made it yet, there is no such group and the child alone is killed."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except OSError:  # no such group (the child ended, with no process left in it, or made none)
        pass
    if child.is_alive():
        child.kill()


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM held back during the fork (delivered right after it): a handler that
    raises (a study's stop request) must not raise inside the interpreter's at-fork hooks, where
    the exception would be lost and a lock left held."""
    held = {signal.SIGINT, signal.SIGTERM}
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _child(send: Any, call: Callable[[], Any]) -> None:
    """The child's side: run, send ("ok", result) or ("error", exception), and exit at once
    (no atexit handlers, no waiting for threads the call left running)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # the parent's stop handler is not the child's
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})  # held during the fork
    set_parent_death_signal(signal.SIGKILL)  # a parent killed outright (a study's worker) takes this along
    with contextlib.suppress(OSError):
        os.setpgid(0, 0)  # a process group of its own: what the call starts is killed with it (`_end_group`)
    try:
        try:
            message: tuple[str, Any] = ("ok", call())
        except BaseException as exc:  # noqa: BLE001 - every way out of the call goes back to the parent
            message = ("error", exc)
        try:
            send.send(message)
        except Exception as exc:  # noqa: BLE001 - an answer or exception that does not pickle
            text = " ".join(str(exc).split())
            what = "answer" if message[0] == "ok" else f"error ({type(message[1]).__name__}: {message[1]})"
            send.send(("error", SolverError(f"the solver's {what} could not be sent back from its worker "
                                            f"process: {text}")))
    finally:
        send.close()
        os._exit(0)
