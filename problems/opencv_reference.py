"""OpenCV's calibration functions called directly, as rows of ``handeye bench`` (`BenchRow`).

Shared by the built-in problems that OpenCV also solves (``cv2.calibrateRobotWorldHandEye``,
``cv2.calibrateHandEye``): `direct_rows` makes one row per method flag, which calls the function
on rotation and translation lists built before the timing starts (`pose_lists`), so that the row
times OpenCV alone; handeye's `opencv` solver timed beside it shows what the wrapper costs.

cv2 is imported only when a row is asked whether it can run or is prepared, never on import:
problems are imported whenever the registry is built. opencv-python-headless 5.x has none of
these functions in Python; the rows then say so (`missing`) and are not timed.

It lives beside the problems (as `handeye.problems.planar`) because only problems need it: the
harness sees `BenchRow` only, and importing it costs nothing when a problem is loaded.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from handeye.framework.problem_studies import BenchRow

#: what `direct_rows` calls the function with: the inputs -> the two pose stacks (m, 4, 4) whose
#: rotation and translation lists are its four positional arguments
Arguments = Callable[[Mapping[str, Any]], tuple[np.ndarray, np.ndarray]]


def missing(function: str, flag: str) -> str | None:
    """Why ``cv2.<function>(..., method=cv2.<flag>)`` cannot be called here (cv2 fails to
    import, or lacks the function or the flag), or None."""
    try:
        import cv2
    except ImportError as exc:
        return f"importing cv2 failed ({exc}); pip install opencv-python-headless"
    for name in (function, flag):
        if not hasattr(cv2, name):
            return f"this OpenCV ({getattr(cv2, '__version__', '?')}) has no cv2.{name}"
    return None


def pose_lists(P: np.ndarray, Q: np.ndarray) -> tuple[list[np.ndarray], ...]:
    """(R_P, t_P, R_Q, t_Q): the rotation (3, 3) and translation (3, 1) lists of the pose stacks
    P, Q (m, 4, 4), as OpenCV's calibration functions take them."""
    return ([R for R in np.ascontiguousarray(P[:, :3, :3])], [t for t in np.ascontiguousarray(P[:, :3, 3:])],
            [R for R in np.ascontiguousarray(Q[:, :3, :3])], [t for t in np.ascontiguousarray(Q[:, :3, 3:])])


def direct_rows(function: str, flag_prefix: str, methods: Sequence[str], arguments: Arguments) -> tuple[BenchRow, ...]:
    """One `BenchRow` per method, labelled ``cv2 direct METHOD``: ``cv2.<function>(R_P, t_P, R_Q,
    t_Q, method=cv2.<flag_prefix><METHOD>)`` on the stacks P, Q = ``arguments(inputs)``; the
    registered solver named like the method in lower case (``tsai``) is its same method."""
    return tuple(BenchRow(f"cv2 direct {method}", _caller(function, flag_prefix + method, arguments),
                          _checker(function, flag_prefix + method), same_method=method.lower())
                 for method in methods)


def _caller(function: str, flag: str, arguments: Arguments) -> Callable[[Mapping[str, Any]], Callable[[], Any]]:
    def call(inputs: Mapping[str, Any]) -> Callable[[], Any]:
        import cv2

        run, method, lists = getattr(cv2, function), getattr(cv2, flag), pose_lists(*arguments(inputs))
        return lambda: run(*lists, method=method)

    return call


def _checker(function: str, flag: str) -> Callable[[], str | None]:
    return lambda: missing(function, flag)
