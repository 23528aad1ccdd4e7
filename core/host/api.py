"""`handeye.solve`: look up problem and solver, validate, run, check, and wrap the answer."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
import time
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from handeye.base.errors import (
    BackendUnavailableError,
    HandEyeError,
    InputError,
    SolverError,
    UnknownPluginError,
    shown,
)
from handeye.checks.self_check import assess
from handeye.framework.isolation import call_with_time_limit
from handeye.framework.options import parse_options
from handeye.framework.reported import Reported
from handeye.framework.solution import (
    USABLE,
    Solution,
    SolverOutput,
    Status,
    with_spread,
)
from handeye.framework.threads import one_blas_thread
from handeye.geometry.se3 import orthonormality_error
from handeye.host.registry import get_registry

DEFAULT_SOLVER = "auto"
#: largest |R^T R - I|, and largest deviation of the last row from [0, 0, 0, 1], accepted in an
#: unknown a solver returns (the last row is then set exactly; rotations must already be rotations)
OUTPUT_ORTHONORMALITY_TOL = 1e-9


def solve(problem: str, *, solver: str | None = None, backend: str | None = None, time_limit: float | None = None,
          **data_and_options: Any) -> Solution:
    """Solve a calibration problem with one registered solver.

    Parameters
    ----------
    problem : registered problem name, ``"axyb"`` (A_i X = Y B_i) or ``"axxb"`` (A_i X = X B_i),
        or a plugin's (see `handeye.list_problems`).
    solver : registered solver name (see `handeye.list_solvers`); default ``"auto"`` where
        registered.
    backend : one of the solver's backends; default the solver's own default.
    time_limit : seconds the solver may take, or None (default: no limit). The solver then runs
        in a forked worker process that is killed at the limit (`handeye.framework.isolation`), which a
        plugin cannot catch or outlast; the fork costs a few milliseconds. POSIX only.
    **data_and_options : the problem's data fields (for ``axyb``: absolute poses ``A``, ``B``;
        for ``axxb``: relative motions ``A``, ``B``, e.g. from `handeye.problems.axxb.motions`;
        each as (m, 4, 4) arrays or sequences of 4x4) and the solver's options.

    Returns
    -------
    Solution with the unknowns as exact SE(3) (4, 4) arrays, status, timing and diagnostics, and
    the validated data it was solved from (``Solution.data``, for the residuals).

    Raises
    ------
    InputError, DegenerateDataError : bad or insufficient data (nothing is modified).
    UnknownPluginError : unknown problem, solver, backend or option (lists the known ones).
    BackendUnavailableError : the backend's package is missing (names it).
    SolverError : the solver failed numerically, or gave no answer within `time_limit`
        (`SolverTimeoutError`); also any fault of a third-party solver (an exception that is not
        handeye's, an answer that is not one), named with its plugin.
    """
    for what, name in (("problem", problem), ("solver", solver), ("backend", backend)):
        if name is not None and not isinstance(name, str):
            raise InputError(f"{what} must be a name (str), got {type(name).__name__} {name!r}")
    registry = get_registry()
    spec_problem = registry.problem(problem)
    if solver is None:
        if DEFAULT_SOLVER not in registry.solver_names(problem):
            raise InputError(
                f"no solver given and problem {problem!r} has no {DEFAULT_SOLVER!r} solver; pass "
                f"solver= one of {registry.solver_names(problem)}"
            )
        solver = DEFAULT_SOLVER
    spec, backend = _spec(registry, problem, solver, backend)
    _check_time_limit(time_limit)
    fields = spec_problem.data_fields
    missing = [f for f in fields if f not in data_and_options]
    if missing:
        raise InputError(f"problem {problem!r} needs data {list(fields)}; missing {missing}")
    given = tuple(fields) + tuple(f for f in spec_problem.optional_fields if f in data_and_options)
    with _one_blas_thread():  # small matrices: threads only wait for each other (`handeye.framework.threads`)
        with _problem_faults(registry, problem):
            data = spec_problem.validate(**{f: data_and_options[f] for f in given})
        options = {k: v for k, v in data_and_options.items() if k not in given}
        return _host(registry, problem, solver, spec, backend, data, options, time_limit, self_check=True)


def run_registered(solver: str, data: Any, *, problem: str, backend: str | None = None,
                   options: Mapping[str, Any] | None = None, self_check: bool = False,
                   time_limit: float | None = None) -> Solution:
    """Run registered solver `solver` on `data` already validated by `problem` (the object its
    ``validate`` returned): the way for one solver to use another (a start, a fallback), with the
    host's checks that `solve` applies: the solver's capabilities against the data (planar mode,
    unknown camera scale), its options parsed, its faults and answer checked (one-line errors, a
    third party's named, an answer that is not SE(3) refused). `self_check`: also the self-check
    of every answer (`handeye.checks.self_check`), as `solve` runs it; off by default, since the caller
    checks its own final answer and a start's check would cost as much as the start.

    Returns a `Solution`; raises as `solve` does."""
    registry = get_registry()
    registry.problem(problem)
    spec, backend = _spec(registry, problem, solver, backend)
    _check_time_limit(time_limit)
    with _one_blas_thread():
        return _host(registry, problem, solver, spec, backend, data, dict(options or {}), time_limit, self_check)


#: per thread: how many `_one_blas_thread` blocks are open (the limit is the process's BLAS setting)
_limited = threading.local()


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[None]:
    """`one_blas_thread`, unless this thread is already inside one (a start solver run through
    `run_registered` within `solve`): the limit is then in force until the outer block ends, and
    setting and restoring it again cost ~10 us a solve."""
    depth = getattr(_limited, "depth", 0)
    _limited.depth = depth + 1
    try:
        if depth:
            yield
        else:
            with one_blas_thread():
                yield
    finally:
        _limited.depth = depth


def _spec(registry: Any, problem: str, solver: str, backend: str | None) -> tuple[Any, str]:
    """The solver's spec for `problem` and the backend to run, checked available."""
    spec = registry.solver(solver, problem)
    backend = spec.default_backend if backend is None else backend
    if backend not in spec.backends:
        raise UnknownPluginError("backend", backend, spec.backends, owner=f"of solver {solver!r}")
    reason = spec.unavailable_reason(backend)
    if reason:
        raise BackendUnavailableError(reason)
    return spec, backend


#: the longest time limit a solve takes, seconds (a year; beyond, the clocks the limit is kept by
#: overflow)
MAX_TIME_LIMIT = 3.2e7


def _check_time_limit(time_limit: Any) -> None:
    if time_limit is not None and (isinstance(time_limit, bool) or not isinstance(time_limit, (int, float))
                                   or not 0 < time_limit <= MAX_TIME_LIMIT):
        raise InputError(f"time_limit must be a number of seconds > 0 and at most {MAX_TIME_LIMIT:.2g} (a year), or "
                         f"None for no limit; got {time_limit!r}")


def _problem_faults(registry: Any, problem: str) -> contextlib.AbstractContextManager[None]:
    if registry.problem_is_builtin(problem):  # `plugin_faults` re-raises everything of handeye's own
        return contextlib.nullcontext()
    return plugin_faults(f"problem {problem!r}", False, registry.problem_provider(problem))


def _host(registry: Any, problem: str, solver: str, spec: Any, backend: str, data: Any, raw_options: dict[str, Any],
          time_limit: float | None, self_check: bool) -> Solution:
    """The host's part of every solve on validated `data`: capabilities, options, the run (within
    the time limit, faults wrapped), the answer checked, the problem's diagnosis and, with
    `self_check`, the self-check (a failure makes a usable status `unreliable`)."""
    spec_problem = registry.problem(problem)
    reason = spec.cannot_solve(data)
    if reason:
        able = [n for n in registry.solver_names(problem) if registry.solver(n, problem).cannot_solve(data) is None]
        raise InputError(f"solver {solver!r} {reason}; use one of {', '.join(able) or '(none registered)'}")
    options = parse_options(spec.options, raw_options, solver)

    builtin = registry.is_builtin(solver, problem)
    start = time.perf_counter()
    output = _run(spec, data, options, backend, time_limit, builtin, _who(registry, solver, problem, builtin))
    seconds = time.perf_counter() - start
    with _problem_faults(registry, problem):
        sizes = dict(spec_problem.stack_sizes(data))
    unknowns, status, diagnostics = _checked_output(output, spec_problem.unknowns, solver, sizes)
    if not self_check:
        return Solution(unknowns=unknowns, problem=problem, solver=solver, backend=backend, status=status,
                        seconds=seconds, diagnostics=diagnostics, data=data)
    with _problem_faults(registry, problem):
        weak = spec_problem.diagnose(data)
    warnings = list(weak.pop("warnings", [])) + list(diagnostics.get("warnings", []))
    # an answer that comes with the camera's scale (auto estimates it where the data demand it)
    # is judged with that scale free, as its solver fitted it (handeye.estimation.camera_scale)
    check_data = data
    reported = Reported.of(diagnostics)
    if reported.camera_scale is not None and getattr(data, "camera_scale_unknown", True) is False:
        check_data = dataclasses.replace(data, camera_scale_unknown=True)
    elif reported.camera_scales and getattr(data, "camera_scale_unknown", True) is False:
        check_data = data.with_scales_unknown(list(reported.camera_scales))  # a cell: some cameras' own
    with _problem_faults(registry, problem):
        check = assess(spec_problem, check_data, unknowns, diagnostics, solver)
    diagnostics["self_check"] = {"reliable": check.reliable, "failures": list(check.failures), **check.figures}
    spread = (check.figures.get("systematic") or {}).get("spread")
    if spread:  # systematic errors: the stated 1-sigma widened to the spread over groups of stations
        with_spread(diagnostics, spread)
    warnings += list(check.warnings)
    if not check.reliable:
        instead = ("use solver 'auto'" if solver != DEFAULT_SOLVER else
                   "check the data (handeye calibrate checks files for the usual setup mistakes)")
        message = f"self-check failed, do not use this answer: {'; '.join(check.failures)}; {instead}"
        if status in USABLE:
            diagnostics["status_before_checks"] = status.value  # the solver's own, kept for the record
            status = Status.UNRELIABLE
            warnings.insert(0, message)  # the reason for the status comes first
        else:
            warnings.append(message)  # the solver's own reason for its status comes first
    elif check.figures.get("better_fit") and status is Status.OPTIMAL:  # never `optimal` beside that warning
        diagnostics["status_before_checks"] = status.value
        status = Status.SUBOPTIMAL
    diagnostics["warnings"] = warnings
    diagnostics.setdefault("data", weak)
    return Solution(unknowns=unknowns, problem=problem, solver=solver, backend=backend, status=status,
                    seconds=seconds, diagnostics=diagnostics, data=data)


def _who(registry: Any, solver: str, problem: str, builtin: bool) -> str:
    """How messages name a solver: with its plugin and distribution when it is a third party's."""
    return f"solver {solver!r}" if builtin else f"solver {solver!r} ({_plugin(registry.provider(solver, problem))})"


def _plugin(info: Any) -> str:
    source = f"from {info.distribution} {info.version}" if info.version else info.distribution.strip("()")
    return f"plugin {info.name!r}, {source}"


@contextlib.contextmanager
def plugin_faults(what: str, builtin: bool, provider: Any) -> Iterator[None]:
    """Code of a plugin's problem (`what`, e.g. "problem 'p'") run by the host: an exception of
    a third party's that is not a HandEyeError (a bug in the plugin) becomes a one-line
    SolverError naming the plugin, not an "internal error" of handeye's."""
    try:
        yield
    except HandEyeError:
        raise
    except (Exception, SystemExit) as exc:
        if builtin:
            raise
        message = " ".join(str(exc).split()) or "(no message)"
        raise SolverError(f"{what} ({_plugin(provider)}) failed: {type(exc).__name__}: {message}") from exc


def _run(spec: Any, data: Any, options: Any, backend: str, time_limit: float | None, builtin: bool,
         who: str) -> Any:
    """spec.run, within `time_limit` if given. A handeye error keeps its type, on one line; any
    other way out of a third-party plugin (an exception of its own, SystemExit) becomes a
    `SolverError` naming the plugin. A built-in's other exceptions are handeye's bugs: raised."""
    try:
        if time_limit is not None:
            return call_with_time_limit(lambda: spec.run(data, options, backend), float(time_limit), who)
        return spec.run(data, options, backend)
    except HandEyeError as exc:
        message = " ".join(str(exc).split())
        if message == str(exc):
            raise
        try:
            flat = type(exc)(message)
        except Exception:  # noqa: BLE001 - a subclass with another constructor
            flat = SolverError(message)
        raise flat from exc
    except (Exception, SystemExit) as exc:
        if builtin and not isinstance(exc, SystemExit):
            raise
        message = " ".join(str(exc).split()) or "(no message)"
        raise SolverError(f"{who} failed: {type(exc).__name__}: {message}") from exc


def _checked_output(output: Any, names: tuple[str, ...], solver: str, sizes: Mapping[str, int] | None = None
                    ) -> tuple[dict[str, np.ndarray], Status, dict[str, Any]]:
    """(unknowns, status, diagnostics) of what a solver returned, or SolverError when it is not
    an answer: not a SolverOutput, an unknown that is not a pose (or, for a stack of `sizes`,
    not that many poses), an unknown status."""
    if not isinstance(output, SolverOutput):
        raise SolverError(f"solver {solver!r} returned {type(output).__name__}, not SolverOutput")
    if not isinstance(output.unknowns, Mapping):
        raise SolverError(f"solver {solver!r} returned unknowns as a {type(output.unknowns).__name__}, not a "
                          "mapping from names to poses")
    unknowns = {name: _checked_pose(output.unknowns, name, solver, (sizes or {}).get(name)) for name in names}
    try:
        status = Status(output.status)
    except ValueError:
        raise SolverError(f"solver {solver!r} returned status {shown(output.status)}, which is not one of "
                          f"{', '.join(s.value for s in Status)}") from None
    if not isinstance(output.diagnostics, Mapping):
        raise SolverError(f"solver {solver!r} returned diagnostics as a {type(output.diagnostics).__name__}, not a "
                          "mapping")
    diagnostics = dict(output.diagnostics)
    found = diagnostics.get("warnings", [])
    if isinstance(found, str) or not isinstance(found, (list, tuple)):
        raise SolverError(f"solver {solver!r} returned diagnostics['warnings'] as a {type(found).__name__}, not a "
                          "list of strings")
    diagnostics["warnings"] = [" ".join(str(w).split()) for w in found]
    return unknowns, status, diagnostics


def _checked_pose(unknowns: Any, name: str, solver: str, stack: int | None = None) -> np.ndarray:
    """A read-only float64 copy of unknown `name`; raise if it is not a 4x4 pose in SE(3) (a
    complex array, a last row other than [0, 0, 0, 1], a rotation off SO(3)), or for a stack of
    `stack` poses not a (stack, 4, 4) array of such poses (each checked as a single one)."""
    if name not in unknowns:
        raise SolverError(f"solver {solver!r} did not return unknown {name!r}")
    try:
        raw = np.asarray(unknowns[name])
        if raw.dtype.kind == "c":  # np.iscomplexobj's test on an array, without its wrapper
            raise SolverError(f"solver {solver!r} returned {name} with complex entries; a pose is real")
        T = np.array(raw, dtype=float)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, SolverError):
            raise
        raise SolverError(f"solver {solver!r} returned {name} as a {type(unknowns[name]).__name__} that is "
                          "not an array of numbers") from None
    expected = (4, 4) if stack is None else (stack, 4, 4)
    if T.shape != expected:
        what = "a 4x4 pose" if stack is None else f"a stack of {stack} 4x4 poses"
        raise SolverError(f"solver {solver!r} returned {name} of shape {T.shape}, not {what}")
    if stack is None:
        _check_pose(T, name, solver)
    else:
        for k, pose in enumerate(T.reshape(-1, 4, 4)):
            _check_pose(pose, f"{name}[{k}]", solver)
    T[..., 3, :] = _LAST_ROW
    T.setflags(write=False)
    return T


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_LAST_ROW.setflags(write=False)


def _check_pose(T: np.ndarray, name: str, solver: str) -> None:
    """Raise SolverError naming `name` unless T (4, 4) is finite with R in SO(3) and last row
    [0, 0, 0, 1] (to `OUTPUT_ORTHONORMALITY_TOL`)."""
    v = T.ravel().tolist()  # scalar arithmetic: 5x faster than numpy calls on one 4x4
    if not all(map(math.isfinite, v)):
        raise SolverError(f"solver {solver!r} returned {name} with {int(np.sum(~np.isfinite(T)))} non-finite "
                          "entries (NaN or inf)")
    if not _is_rotation(v[0:3], v[4:7], v[8:11]):
        R = T[:3, :3]
        raise SolverError(
            f"solver {solver!r} returned {name} whose rotation is not in SO(3) "
            f"(|R^T R - I| = {orthonormality_error(R):.2e}, det = {np.linalg.det(R):+.6f})"
        )
    if max(abs(v[12]), abs(v[13]), abs(v[14]), abs(v[15] - 1.0)) > OUTPUT_ORTHONORMALITY_TOL:
        raise SolverError(f"solver {solver!r} returned {name} whose last row {np.round(T[3], 9).tolist()} is not "
                          "[0, 0, 0, 1]")


def _is_rotation(r0: list[float], r1: list[float], r2: list[float]) -> bool:
    """Whether the 3x3 matrix of rows r0, r1, r2 is in SO(3): |R^T R - I| (max entry) within
    OUTPUT_ORTHONORMALITY_TOL and det R > 0, as `orthonormality_error` and ``np.linalg.det`` say.
    Written out entry by entry (the column products summed in order, as ``sum`` would): 1 us
    against 6 for generator expressions, four times a solve."""
    a0, a1, a2 = r0
    b0, b1, b2 = r1
    c0, c1, c2 = r2
    worst = max(abs(a0 * a0 + b0 * b0 + c0 * c0 - 1.0), abs(a1 * a1 + b1 * b1 + c1 * c1 - 1.0),
                abs(a2 * a2 + b2 * b2 + c2 * c2 - 1.0), abs(a0 * a1 + b0 * b1 + c0 * c1),
                abs(a0 * a2 + b0 * b2 + c0 * c2), abs(a1 * a2 + b1 * b2 + c1 * c2))
    det = a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)
    return worst <= OUTPUT_ORTHONORMALITY_TOL and det >= 0
