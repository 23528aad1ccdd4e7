"""Where a study's work units run: in this process, on a pool of worker processes, or on a
dask.distributed cluster (`execute`), and how they stop.

The pool uses the fork start method where available, so run-time plugins registered with
`handeye.host.registry.register_plugin` are inherited (elsewhere workers re-register them). On a
stop (SIGINT, SIGTERM: `handeye.harness.interrupts`) no more units start, queued ones are
cancelled, and the workers are terminated; the workers also end when the process running the
study is killed outright (SIGKILL): `handeye.framework.processes.die_with_parent`.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from handeye.base.errors import InputError
from handeye.framework.processes import die_with_parent
from handeye.harness.interrupts import POLL, check_stop, interruptible
from handeye.host.registry import (
    _extra as _runtime_plugins,  # run-time plugins, re-registered in workers
)
from handeye.host.registry import register_plugin

#: where units run: worker processes of this machine, or a dask.distributed cluster
EXECUTORS = ("process", "dask")
#: seconds terminated workers get to exit before they are killed (SIGKILL)
STOP_TIMEOUT = 2.0


#: the work on one unit: work(unit) -> (unit index, records, pid of the process that ran it)
Work = Callable[[Any], tuple[int, list[dict[str, Any]], int]]
#: what an executor does with a finished unit: finish(unit index, records, pid of the process that ran it)
Finish = Callable[[int, list[dict[str, Any]], int], None]


def _init_worker(plugins: list[tuple[str, Any]], parent: int | None = None) -> None:
    """Prepare a process-pool worker: make it end with `parent` (the process running the study,
    `handeye.framework.processes.die_with_parent`), leave Ctrl-C to the parent (which stops the workers itself) and let
    SIGTERM end it at once, and make it see the run-time plugins of its parent (a no-op after
    fork)."""
    if parent is not None:
        die_with_parent(parent)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    known = {name for name, _ in _runtime_plugins}
    for name, plugin in plugins:
        if name not in known:
            register_plugin(plugin, name)


def _process_context() -> multiprocessing.context.BaseContext:
    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context()


def _run_serial(units: list[Any], work: Work, finish: Finish) -> None:
    """Run `units` in this process, each `interruptible` (a signal stops its solve)."""
    for unit in units:
        with interruptible():
            done = work(unit)
        finish(*done)


def _run_processes(units: list[Any], work: Work, jobs: int, finish: Finish) -> None:
    """Run `units` on a pool of `jobs` worker processes. On any way out but the end (a signal,
    an error) the units finished but not yet handed over are handed over (`_harvest`) and the
    pool is stopped at once (`_stop_pool`)."""
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=_process_context(), initializer=_init_worker,
                               initargs=(list(_runtime_plugins), os.getpid()))
    futures: list[Future[Any]] = []
    try:
        futures = [pool.submit(work, unit) for unit in units]
        pending = set(futures)
        while pending:
            check_stop()
            done, pending = wait(pending, timeout=POLL, return_when=FIRST_COMPLETED)
            for future in done:
                finish(*future.result())
    except BaseException:
        try:
            _harvest(futures, finish)
        finally:
            _stop_pool(pool, before)
        raise
    pool.shutdown(wait=True)


def _harvest(futures: Sequence[Future[Any]], finish: Finish) -> None:
    """Hand over every unit that finished without being handed over yet (`finish` ignores the
    ones it has), so that a stop keeps every finished row."""
    for future in futures:
        if future.done() and not future.cancelled() and future.exception() is None:
            finish(*future.result())


def _stop_pool(pool: ProcessPoolExecutor, before: set[Any]) -> None:
    """Stop `pool` now: cancel its queued units and terminate its workers (SIGTERM; SIGKILL
    after `STOP_TIMEOUT` s). ``shutdown`` alone would let the workers run every queued unit
    first (wait=True) or leave them running (wait=False). The workers are this process's
    multiprocessing children that were not there before the pool (`before`; the pool's own
    list is private)."""
    pool.shutdown(wait=False, cancel_futures=True)
    workers = [p for p in multiprocessing.active_children() if p not in before]
    for process in workers:
        process.terminate()
    deadline = time.monotonic() + STOP_TIMEOUT
    for process in workers:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.kill()
            process.join(STOP_TIMEOUT)
    pool.shutdown(wait=True)  # the pool's manager thread sees its workers gone and ends


def _run_dask(units: list[Any], work: Work, scheduler: Any, jobs: int, finish: Finish) -> None:
    """Run `units` on a dask.distributed cluster. On any way out but the end (a signal, an
    error), the units not yet done are cancelled on the cluster and a cluster this function
    started (no `scheduler`) is closed with its workers; a cluster given by address or Client
    keeps running."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise InputError('executor "dask" needs dask.distributed: pip install "handeye[dask]"') from None
    own = not isinstance(scheduler, Client)
    if own:
        client = Client(scheduler) if scheduler else Client(n_workers=jobs, threads_per_worker=1)
    else:
        client = scheduler
    futures: list[Any] = []
    try:
        futures = client.map(work, units, pure=False)
        arriving = dask_completed(futures)
        while not arriving.is_empty():
            check_stop()
            ready = arriving.next_batch(block=False)
            for future in ready:
                finish(*future.result())
            if not ready:
                time.sleep(POLL)
    except BaseException:
        if futures and not own:  # closing our own cluster below ends its work anyway
            client.cancel(futures)
        raise
    finally:
        if own:
            client.close()


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and of its finished child processes, i.e. the
    process-pool workers once the pool is shut down; the time of dask workers is not in it."""
    try:
        import resource
    except ImportError:  # not POSIX
        return time.process_time()
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        usage = resource.getrusage(who)
        total += usage.ru_utime + usage.ru_stime
    return total


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells it, else the count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def execute(units: list[Any], work: Work, executor: str, scheduler: Any, jobs: int, finish: Finish) -> None:
    """Run `work` on every one of `units` on the chosen executor (`EXECUTORS`; in this process
    when `jobs` is 1 or there is one unit), handing each result to `finish`. `work` must be a
    module-level function (the workers import it by name)."""
    if units:
        if executor == "dask":
            _run_dask(units, work, scheduler, jobs, finish)
        elif jobs == 1 or len(units) == 1:
            _run_serial(units, work, finish)
        else:
            _run_processes(units, work, min(jobs, len(units)), finish)
    check_stop()  # a request that came at the very end
