"""Per-image detection work items (`handeye.vision.image_detection.read_and_detect`) run over the
machine's cores: detecting a board is nearly all of the time an image set takes, and images are
independent of each other.

`run(items, workers=...)` returns one `Outcome` per item, in the items' order whatever order they
finish in, the same to the last bit as a serial run (tests/vision/test_detection_speed.py).

Threads, not processes: OpenCV's detectors release Python's global lock while they run, so
`workers` threads detect on as many cores. Measured on 30 rendered 1.3 MP chessboard images on
the 2-core machine: 47 s serial, 22 s on two threads, 31 s on a pool of spawned processes (each
spends 1-2 s importing handeye first). Threads also need nothing of the caller: a spawned
process re-imports the user's script (without its ``if __name__ == "__main__"`` guard its
top-level code runs again), and a forked one deadlocks when the parent holds a lock of a BLAS or
OpenCV thread pool, or runs under pytest-xdist.

Serial when there is no second worker: ``workers=1`` (or `WORKERS_VARIABLE`) or a single item.
The bar while detecting: `handeye.framework.progress.progress_bar`, on a terminal only.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import TypeVar

from handeye.base.errors import InputError
from handeye.vision.boards import Board
from handeye.vision.image_detection import Outcome, read_and_detect

#: environment variable: how many threads detect (default: the cores this process may use)
WORKERS_VARIABLE = "HANDEYE_WORKERS"

Item = tuple[str, Board, "tuple[str, ...] | None"]
T = TypeVar("T")
R = TypeVar("R")


def default_workers() -> int:
    """`WORKERS_VARIABLE` if set, else the cores this process may run on."""
    text = os.environ.get(WORKERS_VARIABLE, "").strip()
    if text:
        return check_workers(int(text) if text.isdigit() else text)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def check_workers(workers: object) -> int:
    """`workers` as a whole number >= 1 (InputError otherwise)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"the number of detection workers must be a whole number >= 1, got {workers!r} "
                         f"(argument workers or {WORKERS_VARIABLE})")
    return workers


def run(items: Sequence[Item], workers: int | None = None, *,
        done: Callable[[], object] | None = None) -> list[Outcome]:
    """The outcome of each item ``(path, board, flag_sets)``, in order (module docstring); `done` is
    called once per item finished (a progress bar's update)."""
    return map_in_order(_work, items, workers, done=done)


def map_in_order(work: Callable[[T], R], items: Sequence[T], workers: int | None = None, *,
                 done: Callable[[], object] | None = None) -> list[R]:
    """[work(item) for item in items] on `workers` threads (default `default_workers`), in the
    items' order; serial for one worker or one item. `work` must hold no lock OpenCV waits on."""
    workers = default_workers() if workers is None else check_workers(workers)
    done = done or (lambda: None)
    if workers < 2 or len(items) < 2:
        out = []
        for item in items:
            out.append(work(item))
            done()
        return out
    with ThreadPoolExecutor(min(workers, len(items)), thread_name_prefix="handeye-detect") as pool:
        futures = [pool.submit(work, item) for item in items]
        for _ in as_completed(futures):
            done()
        return [f.result() for f in futures]


def _work(item: Item) -> Outcome:
    path, board, flag_sets = item
    return read_and_detect(Path(path), board, flag_sets)
