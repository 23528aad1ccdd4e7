"""Pairing a robot pose stream with a camera pose stream into stations (``handeye calibrate --match``).

Three ways, each returning the row indices (robot_rows, camera_rows) of the pairs, in the camera
stream's order for ``time`` and the robot's for ``name``:

- ``row``: row k of both files (equal counts; checked by the caller);
- ``name``: rows whose name / index columns are equal (each name once per file; every name needs
  a partner, else an InputError listing the unmatched ones);
- ``time``: each camera pose with the robot pose at the nearest robot time stamp, if that stamp is
  at most ``max_dt`` seconds away (else the camera pose is dropped). No interpolation and no clock
  offset estimation: the robot pose nearest in time is taken as it is.

Nothing passed in is modified; bad input raises `handeye.base.errors.InputError`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from handeye.base.errors import InputError

MATCHES = ("row", "name", "time")
#: default --max-dt when the robot stream has fewer than two stamps (seconds)
FALLBACK_MAX_DT = 0.02


def default_max_dt(robot_stamps: ArrayLike) -> float:
    """Half the median interval between consecutive (sorted, distinct) robot stamps: a regular
    robot stream then matches every camera stamp inside it, and none across a gap. `FALLBACK_MAX_DT`
    when there are fewer than two distinct stamps."""
    t = np.unique(np.asarray(robot_stamps, dtype=float))
    if len(t) < 2:
        return FALLBACK_MAX_DT
    return 0.5 * float(np.median(np.diff(t)))


def match_by_time(robot_stamps: ArrayLike, camera_stamps: ArrayLike,
                  max_dt: float) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """For each camera stamp the robot row of the nearest robot stamp (ties: the earlier one),
    kept when |dt| <= max_dt. Returns (robot_rows, camera_rows, dt = camera - robot stamp) of the
    kept pairs, in camera row order. A robot row may serve several camera rows."""
    r = np.asarray(robot_stamps, dtype=float).ravel()
    c = np.asarray(camera_stamps, dtype=float).ravel()
    if not (np.isfinite(max_dt) and max_dt >= 0):
        raise InputError(f"--max-dt must be a finite number of seconds >= 0, got {max_dt}")
    if len(r) == 0 or len(c) == 0:
        return np.empty(0, np.intp), np.empty(0, np.intp), np.empty(0)
    order = np.argsort(r, kind="stable")
    rs = r[order]
    k = np.searchsorted(rs, c)  # rs[k-1] < c <= rs[k]
    lo = np.clip(k - 1, 0, len(rs) - 1)
    hi = np.clip(k, 0, len(rs) - 1)
    take_hi = np.abs(rs[hi] - c) < np.abs(c - rs[lo])
    nearest = np.where(take_hi, hi, lo)
    dt = c - rs[nearest]
    keep = np.abs(dt) <= max_dt
    return order[nearest[keep]].astype(np.intp), np.flatnonzero(keep).astype(np.intp), dt[keep]


def match_by_name(robot_names: Sequence[str], camera_names: Sequence[str]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Rows with equal names, in the robot file's order. Raises InputError when a name occurs
    twice in one file or some name has no partner (listing them)."""
    for which, names in (("robot", robot_names), ("camera", camera_names)):
        seen: set[str] = set()
        dup = [n for n in names if n in seen or seen.add(n)]
        if dup:
            raise InputError(f"--match name: the {which} file names {sorted(set(dup))[:5]!r} more than once; "
                             "each station's name must be unique")
    where = {n: i for i, n in enumerate(camera_names)}
    only_r = [n for n in robot_names if n not in where]
    only_c = [n for n in camera_names if n not in set(robot_names)]
    if only_r or only_c:
        def listed(names: list[str]) -> str:
            return (", ".join(map(repr, names[:10])) + (f" and {len(names) - 10} more" if len(names) > 10 else "")
                    if names else "none")
        raise InputError(f"--match name: {len(only_r) + len(only_c)} names have no partner: only in the robot "
                         f"file: {listed(only_r)}; only in the camera file: {listed(only_c)}")
    ri = np.arange(len(robot_names), dtype=np.intp)
    ci = np.array([where[n] for n in robot_names], dtype=np.intp)
    return ri, ci
