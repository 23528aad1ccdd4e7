"""`handeye.solve`: look up problem and solver, validate, run, check, and wrap the answer."""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from .errors import BackendUnavailableError, InputError, SolverError, UnknownPluginError
from .options import parse_options
from .registry import get_registry
from .se3 import orthonormality_error
from .self_check import assess
from .solution import Solution, SolverOutput, Status

DEFAULT_SOLVER = "auto"
#: largest |R^T R - I| accepted in an unknown a solver returns (it is then re-orthonormalised
#: exactly by the host only in its last row; rotations must already be rotations).
OUTPUT_ORTHONORMALITY_TOL = 1e-9


def solve(problem: str, *, solver: str | None = None, backend: str | None = None, **data_and_options: Any) -> Solution:
    """Solve a calibration problem with one registered solver.

    Parameters
    ----------
    problem : registered problem name, ``"axyb"`` (A_i X = Y B_i) or ``"axxb"`` (A_i X = X B_i),
        or a plugin's (see `handeye.list_problems`).
    solver : registered solver name (see `handeye.list_solvers`); default ``"auto"`` where
        registered.
    backend : one of the solver's backends; default the solver's own default.
    **data_and_options : the problem's data fields (for ``axyb``: absolute poses ``A``, ``B``;
        for ``axxb``: relative motions ``A``, ``B``, e.g. from `handeye.problems.axxb.motions`;
        each as (m, 4, 4) arrays or sequences of 4x4) and the solver's options.

    Returns
    -------
    Solution with the unknowns as exact SE(3) (4, 4) arrays, status, timing and diagnostics.

    Raises
    ------
    InputError, DegenerateDataError : bad or insufficient data (nothing is modified).
    UnknownPluginError : unknown problem, solver, backend or option (lists the known ones).
    BackendUnavailableError : the backend's package is missing (names it).
    SolverError : the solver failed numerically.
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
    spec = registry.solver(solver, problem)
    backend = spec.default_backend if backend is None else backend
    if backend not in spec.backends:
        raise UnknownPluginError("backend", backend, spec.backends, owner=f"of solver {solver!r}")
    reason = spec.unavailable_reason(backend)
    if reason:
        raise BackendUnavailableError(reason)

    fields = spec_problem.data_fields
    missing = [f for f in fields if f not in data_and_options]
    if missing:
        raise InputError(f"problem {problem!r} needs data {list(fields)}; missing {missing}")
    given = tuple(fields) + tuple(f for f in spec_problem.optional_fields if f in data_and_options)
    data = spec_problem.validate(**{f: data_and_options[f] for f in given})
    if getattr(data, "planar", None) is not None and not spec.planar_mode:
        able = [n for n in registry.solver_names(problem) if registry.solver(n, problem).planar_mode]
        raise InputError(f"solver {solver!r} has no planar (4-DOF) mode for data whose robot rotates about one "
                         f"axis; use one of {', '.join(able) or '(none registered)'}")
    if getattr(data, "camera_scale_unknown", False) and not spec.camera_scale_mode:
        able = [n for n in registry.solver_names(problem) if registry.solver(n, problem).camera_scale_mode]
        raise InputError(f"solver {solver!r} takes the camera's translations as metric; for camera_scale='unknown' "
                         f"use one of {', '.join(able) or '(none registered)'}")
    options = parse_options(spec.options, {k: v for k, v in data_and_options.items() if k not in given}, solver)

    start = time.perf_counter()
    output = spec.run(data, options, backend)
    seconds = time.perf_counter() - start
    if not isinstance(output, SolverOutput):
        raise SolverError(f"solver {solver!r} returned {type(output).__name__}, not SolverOutput")

    unknowns = {name: _checked_pose(output.unknowns, name, solver) for name in spec_problem.unknowns}
    diagnostics = dict(output.diagnostics)
    weak = spec_problem.diagnose(data)
    status = Status(output.status)
    # an answer that comes with the camera's scale (auto estimates it where the data demand it)
    # is judged with that scale free, as its solver fitted it (handeye.camera_scale)
    check_data = data
    if "camera_scale" in diagnostics and getattr(data, "camera_scale_unknown", True) is False:
        check_data = dataclasses.replace(data, camera_scale_unknown=True)
    check = assess(spec_problem, check_data, unknowns, diagnostics)
    diagnostics["self_check"] = {"reliable": check.reliable, "failures": list(check.failures), **check.figures}
    warnings = list(weak.pop("warnings", [])) + list(diagnostics.get("warnings", [])) + list(check.warnings)
    if not check.reliable:
        instead = ("use solver 'auto'" if solver != DEFAULT_SOLVER else
                   "check the data (handeye calibrate checks files for the usual setup mistakes)")
        message = f"self-check failed, do not use this answer: {'; '.join(check.failures)}; {instead}"
        if status in (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.UNCERTIFIED):
            status = Status.UNRELIABLE
            warnings.insert(0, message)  # the reason for the status comes first
        else:
            warnings.append(message)  # the solver's own reason for its status comes first
    diagnostics["warnings"] = warnings
    diagnostics.setdefault("data", weak)
    return Solution(
        unknowns=unknowns,
        problem=problem,
        solver=solver,
        backend=backend,
        status=status,
        seconds=seconds,
        diagnostics=diagnostics,
    )


def _checked_pose(unknowns: Any, name: str, solver: str) -> np.ndarray:
    """A read-only float64 copy of unknown `name`, with an exact last row; raise if not SE(3)."""
    if name not in unknowns:
        raise SolverError(f"solver {solver!r} did not return unknown {name!r}")
    try:
        T = np.array(unknowns[name], dtype=float)
    except (TypeError, ValueError):
        raise SolverError(f"solver {solver!r} returned {name} as a {type(unknowns[name]).__name__} that is "
                          "not an array of numbers") from None
    if T.shape != (4, 4):
        raise SolverError(f"solver {solver!r} returned {name} of shape {T.shape}, not a 4x4 pose")
    if not np.all(np.isfinite(T)):
        raise SolverError(f"solver {solver!r} returned {name} with {int(np.sum(~np.isfinite(T)))} non-finite "
                          "entries (NaN or inf)")
    R = T[:3, :3]
    if orthonormality_error(R) > OUTPUT_ORTHONORMALITY_TOL or np.linalg.det(R) < 0:
        raise SolverError(
            f"solver {solver!r} returned {name} whose rotation is not in SO(3) "
            f"(|R^T R - I| = {orthonormality_error(R):.2e}, det = {np.linalg.det(R):+.6f})"
        )
    T[3] = (0.0, 0.0, 0.0, 1.0)
    T.setflags(write=False)
    return T
