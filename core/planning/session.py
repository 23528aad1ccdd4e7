"""Live feedback while recording stations: after each station, the answer so far, how sure it is,
whether the target precision is reached, whether the station disagrees with the others, and
which stations to record next (`Session`; docs/planning-live.md).

One `Session.add` per recorded station (robot pose A_i = T_base_flange and camera pose B_i as
A X = Y B takes it, docs/conventions.md) returns an `Update`:

- the answer: the first from ``handeye.solve`` once three stations determine it, then a warm
  started Gauss-Newton fit (`live_fit`; ~1 ms instead of ~20 ms), with a full ``handeye.solve``
  every `solve_every` stations (stations it finds far off are left out, as they arrive; stations
  left out before that agree with its answer under the noise estimated since are taken back);
- the 1-sigma of each unknown of interest (its worst direction, as the self-check reports it)
  from the information at the answer: with the noise estimated from the residuals from
  `MIN_NOISE_STATIONS` stations on, before that with the expected noise (pixel noise through
  the camera and board, or a stated camera pose noise, and the robot's): no 1-sigma when neither
  is known;
- ``enough``: every 1-sigma of interest within the target tolerance;
- a disagreement: the new station's residual at the answer of the others, whitened by its
  noise and the answer's uncertainty, beyond the chi-square value of p = `P_VALUE` on 6 degrees
  of freedom. Such a station is left out of the answer (and of `final`) but kept listed;
- with camera and board, the next `suggest` robot poses: D-optimal additions
  (`handeye.planning.suggest.Pool`) to the information of the 1-sigma reported, each candidate's
  at the expected noise, from a pool of usable views in the workspace drawn at the first answer
  and redrawn when the answer moves.

A session serves the problems that plan stations (`plan.planners`: they implement
`Problem.station_information`), its own fits being always those of the cell problem on the
stations (`Registry.cell_problem`, A X = Y B), whose (X, Y) the problem's station information is
on: the problem names them and says which are of interest (A X = X B: its X, the camera's pose,
the other a nuisance). `Session.final` is the full ``handeye.solve`` of the stations kept
(self-checked) for the session's problem: of the stations themselves for the cell problem, else
of the data the problem makes of them (`from_poses`; A X = X B: the motions between every pair).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from handeye.base.errors import HandEyeError, InputError, SolverError
from handeye.checks.stations import DUPLICATE_DEG, DUPLICATE_FRACTION, cell_size
from handeye.framework.reported import Reported
from handeye.framework.solution import Solution, Status
from handeye.geometry.se3 import inverse, rotation_angle
from handeye.geometry.validation import pose_stack
from handeye.host.registry import get_registry
from handeye.planning import design, live_fit, views
from handeye.planning.plan import Noise, default_limits, planners
from handeye.planning.session_types import (
    Disagreement,
    SessionError,
    Suggestions,
    Tolerance,
    Update,
)
from handeye.planning.stations import PlanningError, Workspace
from handeye.planning.suggest import POOL, Pool, draw
from handeye.planning.views import ViewLimits
from handeye.vision.boards import UNITS, Board
from handeye.vision.observations import SETUPS, Camera

#: fewest stations kept that determine X and Y
MIN_STATIONS = 3
#: from this many stations kept on, the noise is estimated from the residuals (6m - 12 degrees
#: of freedom: 36 at 8 stations, the two noise levels then known to ~15%)
MIN_NOISE_STATIONS = 8
#: a full handeye.solve every this many stations kept
SOLVE_EVERY = 10
#: a station whose whitened residual is this unlikely disagrees with the others
P_VALUE = 1e-4
#: a station farther than this (metres) from its frame's origin is no robot cell's: a unit or a
#: number is off, refused before it spoils the fit (a translation of 1e300 made every later
#: station untestable)
MAX_CELL_M = 1000.0
#: statuses whose answer a session does not take
_UNUSABLE = (Status.NOT_CONVERGED, Status.FAILED, Status.UNRELIABLE)


class Session:
    """A recording session (module docstring).

    problem: a problem that plans stations (`plan.planners`; default: the cell problem, A X = Y
    B); setup: "eye-in-hand" or "eye-to-hand"; target: the `Tolerance` (None: ``enough`` is never
    reached). camera, board: for the expected noise of the camera poses and for suggestions;
    unit: the data's length unit, "mm" or "m" (default: the board's, else mm; a board in another
    unit is converted to it); workspace, limits: where suggested stations may be (default limits:
    `plan.default_limits`); noise: the expected pixel and robot noise (`plan.Noise`; the robot's
    by default 0.0002 rad and 0.05 mm per axis, in `unit`); camera_sigma: without camera and
    board, the expected noise of a camera pose per axis (rad, the data's unit), in its own frame.
    suggest: how many stations to suggest (0: none); pool: candidates drawn; seed: their random
    stream. solve_every: a full handeye.solve every this many stations kept (0: only the first);
    p_value: the disagreement test's.
    """

    def __init__(self, problem: str | None = None, *, setup: str, target: Tolerance | None = None,
                 camera: Camera | None = None, board: Board | None = None, unit: str | None = None,
                 workspace: Workspace | None = None, limits: ViewLimits | None = None, noise: Noise | None = None,
                 camera_sigma: tuple[float, float] | None = None, suggest: int = 3, pool: int = POOL,
                 seed: int = 0, solve_every: int = SOLVE_EVERY, p_value: float = P_VALUE) -> None:
        registry = get_registry()
        cell = registry.cell_problem()
        served = planners()
        problem = cell if problem is None else problem
        if problem not in served:
            raise SessionError(f"a recording session serves problems {', '.join(served)}, got {problem!r}")
        if setup not in SETUPS:
            raise SessionError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
        if target is not None and not isinstance(target, Tolerance):
            raise SessionError(f"target must be a Tolerance(rotation_deg, translation), got {type(target).__name__}")
        if (camera is None) != (board is None):
            raise SessionError("give the camera and the board together (both are needed for the camera's noise and "
                               "for suggestions), or neither")
        if camera_sigma is not None and (len(camera_sigma) != 2 or not all(0 < float(s) < math.inf
                                                                           for s in camera_sigma)):
            raise SessionError(f"camera_sigma must be two positive numbers (rad, length), got {camera_sigma!r}")
        if not 0 < p_value < 1:
            raise SessionError(f"p_value must lie between 0 and 1, got {p_value!r}")
        if suggest < 0 or solve_every < 0 or pool < 1:
            raise SessionError("suggest and solve_every must not be negative, and pool must be positive")
        unit = unit if unit is not None else board.unit if board is not None else "mm"
        if unit not in UNITS:
            raise SessionError(f"unit must be one of {', '.join(UNITS)}, got {unit!r}")
        if board is not None and board.unit != unit:
            board = board.in_unit(unit)
        self.problem, self.setup, self.target, self.unit = problem, setup, target, unit
        self.camera, self.board, self.workspace = camera, board, workspace
        self.noise = noise or Noise()
        self.robot_sigma = self.noise.robot_sigma(unit)
        self.limits = limits if limits is not None or camera is None else default_limits(board, camera)
        self.camera_sigma = None if camera_sigma is None else (float(camera_sigma[0]), float(camera_sigma[1]))
        self.count, self.pool_size, self.solve_every = (int(suggest) if camera is not None else 0), int(pool), \
            int(solve_every)
        self.threshold = live_fit.chi2_threshold(p_value)
        self._rng = np.random.default_rng(seed)
        self._cell = cell  # the problem of the stations: the session's fits and full solves
        self._cell_spec = registry.problem(cell)
        self._spec = registry.problem(problem)
        # the problem's names of the cell's (X, Y) and those of interest (the others nuisances)
        self._blocks, self._interest = self._layout()
        mask = np.repeat([name in self._interest for name in self._blocks], 6)
        self._mask = None if mask.all() else mask
        self._model: tuple[tuple[int, ...], Any] | None = None  # the last fit model, by its stations
        self._A: list[np.ndarray] = []
        self._B: list[np.ndarray] = []
        self._names: list[str] = []
        self._kept: list[bool] = []
        self._left_out: list[Disagreement] = []
        self._fit: live_fit.Fit | None = None
        self._pool: Pool | None = None
        self._last_solved = 0
        self._readmitted: tuple[str, ...] = ()
        self._last_suggestions: Suggestions | None = None

    # ------------------------------------------------------------------ public

    @property
    def stations(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) of every station recorded, (n, 4, 4) each, in order."""
        return _stack(self._A), _stack(self._B)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._names)

    @property
    def kept(self) -> np.ndarray:
        """(n,) whether each station is in the answer."""
        return np.array(self._kept, dtype=bool)

    @property
    def left_out(self) -> tuple[Disagreement, ...]:
        """The stations left out, with why."""
        return tuple(self._left_out)

    @property
    def last_suggestions(self) -> Suggestions | None:
        """The poses suggested after the last station (`Update.suggestions`), or None."""
        return self._last_suggestions

    @property
    def unknowns(self) -> dict[str, np.ndarray] | None:
        """The current answer (`Update.unknowns`)."""
        if self._fit is None:
            return None
        XY = (self._fit.X, self._fit.Y)
        return {name: XY[self._blocks.index(name)].copy() for name in self._interest}

    def add(self, A: Any, B: Any, name: str | None = None) -> Update:
        """Add one station: robot pose A (4, 4) T_base_flange and camera pose B (4, 4) as A X = Y B
        takes it (eye in hand T_target_cam, eye to hand T_cam_target); name: how it is reported
        (default ``station N``, N from 1). The `Update` after it."""
        start = time.perf_counter()
        A_i, B_i = (_pose(P, which) for P, which in ((A, "the robot pose A"), (B, "the camera pose B")))
        for T, which in ((A_i, "robot pose A"), (B_i, "camera pose B")):
            reach = float(np.max(np.abs(T[:3, 3])))  # the largest coordinate: no overflow where a norm would
            if reach * UNITS[self.unit] > MAX_CELL_M:
                raise SessionError(f"the {which} of {name or f'station {len(self._names) + 1}'} is {reach:.3g} "
                                   f"{self.unit} from its origin, beyond any robot cell ({MAX_CELL_M:g} m): a unit or a "
                                   "number is off")
        index = len(self._names)
        self._A.append(A_i)
        self._B.append(B_i)
        self._names.append(str(name) if name is not None else f"station {index + 1}")
        repeated = self._repeated(index)
        self._kept.append(repeated is None)
        warnings: list[str] = []
        disagreement, solved, self._readmitted = None, False, ()
        if repeated is not None:  # the same robot pose again: no information about X and Y, a 1-sigma too small
            warnings.append(f"{self._names[index]} repeats {self._names[repeated]} (the robot pose within "
                            f"{DUPLICATE_DEG:g} deg and {DUPLICATE_FRACTION:.0%} of the cell's size): left out, since the "
                            "robot's error there is the same and would count twice; move the robot between stations")
        elif self._fit is None:
            if sum(self._kept) >= MIN_STATIONS:
                solved = self._solve(warnings)
        else:
            disagreement = self._test(index, warnings)
            if disagreement is not None:
                self._kept[index] = False
                self._left_out.append(disagreement)
            elif self.solve_every and sum(self._kept) - self._last_solved >= self.solve_every:
                solved = self._solve(warnings)
            else:
                self._refit(warnings)
        noise, information = self._noise() if self._fit is not None else ("unknown", None)
        std = self._std(information)
        enough = bool(self.target is not None and std is not None and self.target.met(std))
        suggestions = self._suggest(information, warnings) if self._fit is not None and self.count else None
        self._last_suggestions = suggestions
        return Update(index, self._names[index], len(self._names), int(sum(self._kept)), self.unknowns, std, noise,
                      enough, disagreement, suggestions, solved, self._readmitted, tuple(warnings),
                      time.perf_counter() - start)

    def _repeated(self, index: int) -> int | None:
        """The kept station whose robot pose the new one `index` repeats (`handeye.workflow.plausibility`'s
        duplicated stations: within DUPLICATE_DEG and DUPLICATE_FRACTION of the cell's size), or None."""
        kept = [k for k in range(index) if self._kept[k]]
        if not kept:
            return None
        A = np.stack([self._A[k] for k in kept] + [self._A[index]])
        size = cell_size(A)
        near = np.linalg.norm(A[:-1, :3, 3] - A[-1, :3, 3], axis=1) <= DUPLICATE_FRACTION * size
        turn = rotation_angle(np.swapaxes(A[:-1, :3, :3], 1, 2) @ A[-1, :3, :3])
        same = np.flatnonzero(near & (turn < math.radians(DUPLICATE_DEG)))
        return kept[int(same[0])] if len(same) else None

    def final(self, **options: Any) -> Solution:
        """The full ``handeye.solve`` of the stations kept (`options` passed on: solver, ...): the
        self-checked answer. A problem other than the cell problem: of the data it makes of the
        stations (A X = X B: the motions between every pair)."""
        from handeye.host.api import solve
        from handeye.io.data_files import from_poses

        A, B = self._kept_stations()
        if len(A) < MIN_STATIONS:
            raise SessionError(f"{len(A)} station(s) kept; the answer needs at least {MIN_STATIONS}")
        if self.problem == self._cell:
            return solve(self.problem, A=A, B=B, **options)
        camera = inverse(B) if self.setup == "eye-in-hand" else B  # T_cam_target, as a cell records it
        return solve(self.problem, **from_poses(A, camera, self.problem, setup=self.setup).data, **options)

    # ------------------------------------------------------------------ the answer

    def _layout(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """The names the problem gives the cell's (X, Y) (the blocks of its station information)
        and those of interest, asked once of `Problem.station_information`."""
        eye = np.eye(4)
        info, names, interest = self._spec.station_information(eye[None], eye[None], {"X": eye, "Y": eye},
                                                               self.robot_sigma, np.eye(6)[None], self.setup)
        names, interest = tuple(names), tuple(interest)
        if np.shape(info) != (1, 12, 12) or len(names) != 2 or not interest or not set(interest) <= set(names):
            raise SessionError(f"problem {self.problem!r} plans for unknowns other than X and Y of A X = Y B on a "
                               "cell's stations; a recording session cannot follow it")
        return names, interest

    def _kept_stations(self) -> tuple[np.ndarray, np.ndarray]:
        keep = self.kept
        return _stack(self._A)[keep], _stack(self._B)[keep]

    def _model_of(self, rows: np.ndarray) -> Any:
        """The cell problem's model of the stations `rows` (`live_fit.model_of`), kept for the next
        call on the same stations (a station's test and the fit after it share it)."""
        key = tuple(int(r) for r in rows)
        if self._model is None or self._model[0] != key:
            self._model = (key, live_fit.model_of(self._cell_spec, _stack(self._A)[rows], _stack(self._B)[rows]))
        return self._model[1]

    def _solve(self, warnings: list[str]) -> bool:
        """A full handeye.solve of the stations kept; the stations it finds far off are left out.
        Whether it gave an answer (else the previous one stands, or none)."""
        from handeye.host.api import solve

        A, B = self._kept_stations()
        rows = np.flatnonzero(self.kept)
        try:
            solution = solve(self._cell, A=A, B=B)
        except (HandEyeError, SolverError) as exc:
            if self._fit is not None:
                warnings.append(f"the full solve failed ({exc}); the quick fit stands")
                self._refit(warnings)
            else:  # why there is no answer yet, and what the next station should do about it
                warnings.append(f"no answer from the {len(A)} stations yet: {exc}")
            return False
        if solution.status in _UNUSABLE:
            if self._fit is not None:
                self._refit(warnings)
            else:
                reason = (solution.warnings or [f"the answer is {solution.status.value}"])[0]
                warnings.append(f"no answer from the {len(A)} stations yet: {reason}")
            return False
        self._last_solved = int(sum(self._kept))
        for outlier in Reported.of(solution.diagnostics).outliers or ():
            row = int(rows[int(outlier["index"])])
            self._kept[row] = False
            self._left_out.append(Disagreement(row, self._names[row], math.inf, 0.0, float(outlier["rotation_deg"]),
                                               float(outlier["translation"])))
        X, Y = (np.asarray(solution.unknowns[k], dtype=float) for k in self._cell_spec.unknowns)
        self._fit = None
        self._refit(warnings, (X, Y))
        self._readmitted = self._readmit(warnings)
        return True

    def _refit(self, warnings: list[str], start: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """The quick fit of the stations kept from `start` (default: the current answer)."""
        if start is None:
            start = (self._fit.X, self._fit.Y)
        try:
            self._fit = live_fit.fit(self._model_of(np.flatnonzero(self.kept)), *start)
        except HandEyeError as exc:
            warnings.append(f"the quick fit failed ({exc}); the previous answer stands")

    # ------------------------------------------------------------------ noise and precision

    def _expected_information(self, A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray | None:
        """(m, 12, 12) information of (X, Y) from stations (A, B) at the expected noise (the
        problem's `station_information`), or None when the camera's noise is not known."""
        cov = self._camera_covariance(B)
        if cov is None:
            return None
        return self._spec.station_information(A, B, {"X": X, "Y": Y}, self.robot_sigma, cov, self.setup)[0]

    def _camera_covariance(self, B: np.ndarray) -> np.ndarray | None:
        """(m, 6, 6) expected covariance of camera poses B in their own frame, or None."""
        if self.camera is not None:
            seen = views.views_of(B, self.setup)
            cov = views.pose_covariance(self.board, self.camera, seen, self.noise.pixel)
            return views.target_to_camera_frame(seen, cov) if self.setup == "eye-in-hand" else cov
        if self.camera_sigma is not None:
            rot, trans = self.camera_sigma
            return np.broadcast_to(np.diag([rot**2] * 3 + [trans**2] * 3), (len(B), 6, 6))
        return None

    def _noise(self, without: int | None = None) -> tuple[str, np.ndarray | None]:
        """Where the noise comes from, and the answer's information under it (None: unknown):
        that of the stations kept but `without` (a station being tested, not yet in the fit)."""
        fit = self._fit
        keep = self.kept
        if without is not None:
            keep[without] = False
        if int(keep.sum()) >= MIN_NOISE_STATIONS and math.isfinite(fit.factor):
            return "estimated", fit.information / fit.factor
        info = self._expected_information(_stack(self._A)[keep], _stack(self._B)[keep], fit.X, fit.Y)
        return ("unknown", None) if info is None else ("expected", info.sum(axis=0))

    def _std(self, information: np.ndarray | None) -> dict[str, dict[str, float]] | None:
        """The 1-sigma of the unknowns of interest under the answer's `information` (`_noise`)."""
        if information is None:
            return None
        if not _full_rank(information):
            return {name: {"rotation_deg": math.inf, "translation": math.inf} for name in self._interest}
        std = design.predicted_std(information, self._blocks)
        return {name: std[name] for name in self._interest}

    def _test(self, index: int, warnings: list[str]) -> Disagreement | None:
        """Station `index` (not in the answer) against the answer of the others
        (`live_fit.disagreement`): a `Disagreement` beyond the threshold, else None (also when
        the noise is not known)."""
        fit = self._fit
        noise, information = self._noise(without=index)
        if information is None or not _full_rank(information):
            return None
        rows = np.flatnonzero(self.kept | (np.arange(len(self._names)) == index))
        try:
            e, J = live_fit.residual(self._model_of(rows), fit.X, fit.Y)
        except HandEyeError as exc:
            warnings.append(f"{self._names[index]} could not be tested ({exc})")
            return None
        row = int(np.searchsorted(rows, index))
        e, J = e[row], J[row]
        if noise == "estimated":
            s_rot, s_trans = fit.sigmas
            station = np.diag([s_rot**2] * 3 + [s_trans**2] * 3) * fit.factor
        else:
            A_i, B_i = self._A[index][None], self._B[index][None]
            station = live_fit.residual_covariance(J, self._expected_information(A_i, B_i, fit.X, fit.Y)[0])
        chi2 = live_fit.disagreement(e, J, station, np.linalg.inv(information))
        if chi2 <= self.threshold:
            return None
        return Disagreement(index, self._names[index], chi2, live_fit.chi2_p_value(chi2),
                            math.degrees(float(np.linalg.norm(e[:3]))), float(np.linalg.norm(e[3:])))

    def _readmit(self, warnings: list[str]) -> tuple[str, ...]:
        """Stations left out earlier that agree with the answer now (tested with the noise
        estimated from the stations kept, which an early test under the expected noise did not
        have) are taken back; their names."""
        if self._fit is None or not self._left_out or sum(self._kept) < MIN_NOISE_STATIONS:
            return ()
        back = [d for d in self._left_out if self._test(d.station, warnings) is None]
        if not back:
            return ()
        for d in back:
            self._kept[d.station] = True
            self._left_out.remove(d)
        self._refit(warnings)
        return tuple(d.name for d in back)

    # ------------------------------------------------------------------ suggestions

    def _suggest(self, prior: np.ndarray | None, warnings: list[str]) -> Suggestions | None:
        """The next stations: D-optimal additions to the current information `prior` (that of the
        1-sigma reported, `_noise`) from the pool, redrawn when the answer moved."""
        fit = self._fit
        if self._pool is None or self._pool.stale(fit.X, fit.Y):
            try:
                self._pool = draw(self.board, self.camera, fit.X, fit.Y, self.setup, self.limits, self.workspace,
                                  self._expected_information, self.pool_size, self._rng)
            except PlanningError as exc:
                warnings.append(f"no suggestions: {exc}")
                return None
        pool = self._pool
        chosen = pool.choose(self.count, prior, self._mask)
        total = pool.information[chosen].sum(axis=0) + (0.0 if prior is None else prior)
        return Suggestions(pool.A[chosen], pool.B[chosen], pool.views[chosen], self._std(total))


def _pose(P: Any, which: str) -> np.ndarray:
    try:
        T = np.asarray(P, dtype=float)
    except (TypeError, ValueError):
        raise SessionError(f"{which} must be a 4x4 pose, got {type(P).__name__}") from None
    if T.shape != (4, 4):
        raise SessionError(f"{which} must be a 4x4 pose, got shape {T.shape}")
    try:
        return np.array(pose_stack(T[None], which)[0])
    except InputError as exc:
        raise SessionError(str(exc)) from None


def _stack(poses: list[np.ndarray]) -> np.ndarray:
    return np.stack(poses) if poses else np.zeros((0, 4, 4))


def _full_rank(information: np.ndarray) -> bool:
    """Whether the information determines every parameter (Cholesky succeeds after scaling)."""
    d = np.sqrt(np.maximum(np.diag(information), 1e-300))
    try:
        w = np.linalg.eigvalsh(information / np.outer(d, d))
    except np.linalg.LinAlgError:
        return False
    return bool(w[0] > 1e-10 * w[-1])
