"""Estimating the constant offset between a robot's clock and a camera's.

Sign convention (the one of the whole `handeye.streams` package and of docs/streams.md):

    t_robot = t_camera + offset

the camera pose stamped t (camera clock) was taken when the robot's clock read t + offset. So a
camera whose stamps lag behind the robot's (images stamped late, e.g. after processing) has a
negative offset. `tools/make_example_data.py` uses the same sign (robot interpolated at
t_camera + offset).

Two steps, as in Furrer et al. (FSR 2017):

1. `coarse_offset`: both streams' angular speed on one uniform grid (the speed does not depend on
   the unknown X, Y: `resample.angular_speed`), normalised cross-correlation over the lags of the
   search range, the peak refined by a parabola. Needs no calibration, finds the offset to a few
   milliseconds, and says so when the peak is at the edge of the range or hardly stands out.
2. `refine_offset`: minimise over the offset, in a bounded window around the coarse value
   (`scipy.optimize.minimize_scalar`, bounded Brent), the profile cost

       S(o) = min over X, Y of sum_i |log(R_AiX R_YBi^T)|^2 + |t_AiX - t_YBi|^2 / L^2

   with A_i the robot interpolated at t_i + o and B_i the camera poses, L the spread of the
   robot's positions (so one radian weighs like one workspace size). X and Y are re-solved at
   every offset (closed form ``kron-lstsq``, ~10 ms for 300 pairs) rather than held fixed: X, Y
   fitted at a wrong offset absorb part of its error and would pull the minimum back towards the
   value they were fitted at. A_i X = Y B_i is used whatever is finally solved (axyb or axxb):
   each station's residual depends on its own synchronisation only, where AX = XB motions mix two.
   1-sigma from the curvature of S at the minimum (Gauss-Newton: var = 2 s^2 / S'', s^2 = S / (6m - 13)).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from handeye.base.errors import DegenerateDataError, InputError, SolverError
from handeye.geometry.resample import angular_speed, resample_poses

#: a correlation peak below this does not identify the offset clearly (warning)
WEAK_CORRELATION = 0.5
#: angular speed (rad/s) the robot must exceed somewhere for an offset to be estimated
MIN_MOTION = math.radians(2.0)
#: grid points a cross-correlation may use at most (keeps long recordings fast)
MAX_GRID = 40_000
#: lags one side of zero a cross-correlation scores at most (a wide --max-offset coarsens the grid)
MAX_LAGS = 2000
#: smallest overlap of the two speed signals a lag is scored on, as a fraction of the shorter span
MIN_OVERLAP = 0.5


@dataclasses.dataclass(frozen=True)
class CoarseOffset:
    """Cross-correlation result: offset (s), its peak correlation, the lags searched (s), the
    grid step (s) and the correlation at each lag (NaN where the overlap was too short)."""

    offset: float
    correlation: float
    lags: NDArray[np.float64]
    scores: NDArray[np.float64]
    step: float


@dataclasses.dataclass(frozen=True)
class OffsetEstimate:
    """The clock offset, t_robot = t_camera + offset (seconds).

    offset: the refined value; std: its 1-sigma from the curvature of the profile cost (s), None
    when the curvature is not positive; coarse: the cross-correlation value and correlation: its
    peak; window: the bounds of the refinement; pairs: stations the cost was computed on;
    rms_rotation (rad) / rms_translation (data unit): the fit's RMS residuals at the offset;
    reliable: False when the value is not to be trusted (at the edge of the window, or no curvature);
    warnings: why, and a weak correlation peak (a warning only: the refinement decides).
    """

    offset: float
    std: float | None
    coarse: float
    correlation: float
    window: tuple[float, float]
    pairs: int
    rms_rotation: float
    rms_translation: float
    reliable: bool
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready fields (seconds, radians)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}


def coarse_offset(robot_t: NDArray, robot_T: NDArray, camera_t: NDArray, camera_T: NDArray, *,
                  max_offset: float, robot_gap: float, camera_gap: float) -> CoarseOffset:
    """Offset maximising the normalised cross-correlation of the two angular speeds, searched in
    [-max_offset, +max_offset]. Raises InputError when the streams do not overlap for any lag, or
    when the best lag is the edge of the range (the offset may lie beyond); DegenerateDataError
    when the robot hardly rotates."""
    dt_r, dt_c = float(np.median(np.diff(robot_t))), float(np.median(np.diff(camera_t)))
    start = min(robot_t[0], camera_t[0])
    stop = max(robot_t[-1], camera_t[-1])
    step = max(0.5 * min(dt_r, dt_c), (stop - start) / MAX_GRID, max_offset / MAX_LAGS, 1e-4)
    step = min(step, max_offset / 10.0)
    grid = start + step * np.arange(int((stop - start) / step) + 1)
    half = max(dt_r, dt_c)  # central difference over about two samples of the slower stream
    w_r = angular_speed(robot_t, robot_T, grid, half, robot_gap)
    w_c = angular_speed(camera_t, camera_T, grid, half, camera_gap)
    if not np.nanmax(w_r, initial=0.0) > MIN_MOTION:
        raise DegenerateDataError(
            f"the robot stream hardly rotates (largest angular speed {math.degrees(np.nanmax(w_r, initial=0.0)):.2g} "
            f"deg/s < {math.degrees(MIN_MOTION):.2g}): the time offset cannot be estimated; give it with --time-offset "
            "SECONDS (time_offset=...), or record a moving robot")
    n_lag = math.floor(max_offset / step)
    lags = step * np.arange(-n_lag, n_lag + 1)
    scores = np.full(len(lags), np.nan)
    need = MIN_OVERLAP * min(robot_t[-1] - robot_t[0], camera_t[-1] - camera_t[0]) / step
    for j, k in enumerate(range(-n_lag, n_lag + 1)):
        # camera at grid[i] (camera clock) against robot at grid[i + k] = grid[i] + offset
        c = w_c[max(0, -k): len(grid) - max(0, k)]
        r = w_r[max(0, k): len(grid) - max(0, -k)]
        ok = np.isfinite(c) & np.isfinite(r)
        if ok.sum() < max(need, 10):
            continue
        c, r = c[ok] - c[ok].mean(), r[ok] - r[ok].mean()
        denom = math.sqrt(float(c @ c) * float(r @ r))
        scores[j] = float(c @ r) / denom if denom > 0 else np.nan
    if not np.any(np.isfinite(scores)):
        raise InputError(
            f"the robot stream ({robot_t[0]:.6f}..{robot_t[-1]:.6f} s) and the camera stream ({camera_t[0]:.6f}.."
            f"{camera_t[-1]:.6f} s) do not overlap in time for any offset within +-{max_offset:g} s; check that "
            "both use the same clock and seconds, or give the offset with --time-offset SECONDS")
    j = int(np.nanargmax(scores))
    valid = np.flatnonzero(np.isfinite(scores))
    if j in (valid[0], valid[-1]):
        raise InputError(
            f"the angular speeds correlate best at the edge of the offset search range ({lags[j] * 1e3:+.1f} ms of "
            f"+-{max_offset * 1e3:.0f} ms): the clock offset may lie outside it; widen --max-offset (max_offset=), "
            "or give the offset with --time-offset SECONDS")
    offset = float(lags[j])
    y0, y1, y2 = scores[j - 1], scores[j], scores[j + 1]
    curv = y0 - 2 * y1 + y2
    if np.isfinite(curv) and curv < 0:
        offset += step * 0.5 * (y0 - y2) / curv
    return CoarseOffset(offset, float(scores[j]), lags, scores, step)


def profile_cost(robot_t: NDArray, robot_T: NDArray, camera_t: NDArray, B: NDArray, offset: float,
                 max_gap: float, length: float) -> tuple[float, int, float, float]:
    """S(offset) of the module docstring on the camera samples `camera_t` (all must be
    interpolable; B: the camera side at them): (S, pairs, rms rotation rad, rms translation)."""
    from handeye.host.api import solve
    from handeye.host.registry import get_registry

    name = get_registry().cell_problem()
    problem = get_registry().problem(name)
    res = resample_poses(robot_t, robot_T, camera_t + offset, max_gap)
    if len(res.kept) != len(camera_t):
        raise SolverError(f"internal: {len(camera_t) - len(res.kept)} stations could not be interpolated at offset "
                          f"{offset:.6f} s")
    A = res.poses
    sol = solve(name, solver=problem.quick_solver or problem.starts[0], A=A, B=B)  # a closed form
    r = problem.residuals(problem.validate(A=A, B=B), sol.unknowns)
    rot, tr = np.asarray(r["rotation"]), np.asarray(r["translation"])
    S = float(np.sum(rot**2) + np.sum((tr / length) ** 2))
    return S, len(A), float(np.sqrt(np.mean(rot**2))), float(np.sqrt(np.mean(tr**2)))


def refine_offset(robot_t: NDArray, robot_T: NDArray, camera_t: NDArray, B: NDArray, *, coarse: CoarseOffset,
                  window: tuple[float, float], max_gap: float, length: float, tol: float = 1e-7) -> OffsetEstimate:
    """Minimise the profile cost over the offset within `window` (camera samples `camera_t`
    must be interpolable over the whole window plus a curvature step, 10 % of its width); B: the
    camera side B_i of A_i X = Y B_i at those samples (it does not move with the offset)."""
    lo, hi = window

    def cost(o: float) -> float:
        return profile_cost(robot_t, robot_T, camera_t, B, o, max_gap, length)[0]

    found = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": tol})
    best = float(found.x)
    S, m, rms_r, rms_t = profile_cost(robot_t, robot_T, camera_t, B, best, max_gap, length)
    h = 0.05 * (hi - lo)
    curvature = (cost(best + h) - 2 * S + cost(best - h)) / h**2
    dof = max(6 * m - 13, 1)
    std = math.sqrt(2 * (S / dof) / curvature) if curvature > 0 else None
    warnings = []
    edge = 0.02 * (hi - lo)
    at_edge = best - lo < edge or hi - best < edge
    if at_edge:
        warnings.append(
            f"the refined time offset {best * 1e3:+.2f} ms is at the edge of its window {lo * 1e3:+.1f}..{hi * 1e3:+.1f} "
            f"ms around the cross-correlation estimate {coarse.offset * 1e3:+.1f} ms: the two disagree, so neither is "
            "trusted; check the data, or give the offset with --time-offset SECONDS")
    if coarse.correlation < WEAK_CORRELATION:
        warnings.append(
            f"the angular speeds of the two streams correlate weakly (peak {coarse.correlation:.2f} < "
            f"{WEAK_CORRELATION}): the time offset is poorly determined; record faster, more varied rotations")
    if std is None:
        warnings.append("the residuals do not grow away from the time offset found (no curvature): it is not "
                        "determined by the data")
    return OffsetEstimate(best, std, coarse.offset, coarse.correlation, (lo, hi), m, rms_r, rms_t,
                          reliable=not at_edge and std is not None, warnings=tuple(warnings))
