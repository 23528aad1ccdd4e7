"""What a solver returns: `Status` and the frozen `Solution` record."""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from handeye.framework.reported import Reported


class Status(str, enum.Enum):
    """How far a solver stands behind its answer.

    - ``optimal``: the method solved its own problem to its tolerance (closed forms: exactly).
    - ``optimal_inaccurate``: the numerical solver stopped close to, but not at, its tolerance.
    - ``uncertified``: a certifiable method found a solution but could not prove it globally optimal.
    - ``suboptimal``: set by the host, not by a solver: the solver solved its own problem, but the
      self-check finds a fit of the same data that the data support far better (the answer beyond
      `handeye.checks.self_check.DISTANCE_WARN` standard deviations from it, with a warning); usable,
      not the best these data give (solver ``auto`` returns that fit).
    - ``not_converged``: an iterative method hit its iteration limit or diverged; the returned
      unknowns are its last iterate and must not be trusted.
    - ``failed``: no usable answer (used by the harness for solvers that raised).
    - ``unreliable``: set by the host, not by a solver: the solver solved its problem, but the
      residuals are implausible for the data (`handeye.workflow.plausibility`: most often a setup mistake
      such as inverted poses, another Euler order or a unit); the unknowns must not be used.
    """

    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"
    UNCERTIFIED = "uncertified"
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"
    UNRELIABLE = "unreliable"
    SUBOPTIMAL = "suboptimal"

    def __str__(self) -> str:
        return self.value


#: statuses whose unknowns may be used (the others: shown for inspection only)
USABLE = (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.UNCERTIFIED, Status.SUBOPTIMAL)


@dataclass(frozen=True)
class SolverOutput:
    """What a solver plugin's ``run`` returns; the host turns it into a `Solution`.

    unknowns: name -> 4x4 pose (must be in SE(3); the host checks).
    diagnostics: free-form but JSON-friendly (numbers, strings, lists), e.g. ``iterations``,
    ``cost``, ``solver_status``; ``warnings`` is a list of strings shown to the user.
    """

    unknowns: Mapping[str, np.ndarray]
    status: Status = Status.OPTIMAL
    diagnostics: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Solution:
    """The answer of `handeye.solve`.

    Attributes
    ----------
    unknowns : dict name -> (4, 4) float64 array, exactly in SE(3) (read-only arrays).
        Also reachable as attributes: ``sol.X``, ``sol.Y``.
    problem, solver, backend : names used.
    status : `Status`.
    seconds : wall time of the solver itself (validation excluded).
    diagnostics : dict of solver-specific figures (cost, iterations, certificate, ...) and
        ``warnings`` (list of str) about weak data or numerical trouble.
    data : the problem's validated data the solver ran on (what ``Problem.validate`` returned
        for the data given to `handeye.solve`, or the data given to ``run_registered``), so that
        a caller measuring residuals need not validate the data again; None where no solve made
        it. Not compared, not shown, not in `to_dict`.
    """

    unknowns: Mapping[str, np.ndarray]
    problem: str
    solver: str
    backend: str
    status: Status
    seconds: float
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    data: Any = field(default=None, compare=False, repr=False)

    def __getattr__(self, name: str) -> np.ndarray:
        unknowns = self.__dict__.get("unknowns", {})
        if name in unknowns:
            return unknowns[name]
        raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")

    @property
    def warnings(self) -> list[str]:
        """Warnings about weak data or numerical trouble (also in ``diagnostics['warnings']``)."""
        return list(self.diagnostics.get("warnings", []))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: unknowns as nested lists, status as its string."""
        return {
            "problem": self.problem,
            "solver": self.solver,
            "backend": self.backend,
            "status": self.status.value,
            "seconds": self.seconds,
            "unknowns": {k: v.tolist() for k, v in self.unknowns.items()},
            "diagnostics": jsonable(dict(self.diagnostics)),
        }


def standard_deviations(diagnostics: Mapping[str, Any]) -> dict[str, dict[str, float]]:
    """The 1-sigma of each unknown a solver reported, {name: {"rotation": rad, "translation":
    data unit}} (root of the sum of the three axes' variances), from its covariance: refine's
    ``std``, or auto's under ``refine`` (`Reported.std`); empty when it gave none."""
    std = Reported.of(diagnostics).std
    return {name: {"rotation": float(s["rotation"]), "translation": float(s["translation"])}
            for name, s in std.items()}


def with_spread(diagnostics: dict[str, Any], spread: dict[str, dict[str, float]]) -> None:
    """The answer's stated covariance and 1-sigma (``diagnostics``' own and auto's ``refine``)
    widened in place by the factors `spread` (`handeye.checks.systematic.station_spread`) of each unknown's rotation and
    translation; the factors recorded as ``diagnostics["station_spread"]``."""
    for entry in (diagnostics, diagnostics.get("refine")):
        if not isinstance(entry, dict):
            continue
        for name, std in (entry.get("std") or {}).items():
            if name in spread and isinstance(std, dict):
                for kind in ("rotation", "translation"):
                    std[kind] = float(std[kind]) * spread[name][kind]
        blocks = entry.get("covariance")
        if isinstance(blocks, dict):
            names = list(blocks)
            scale = np.concatenate([[spread.get(n, {}).get("rotation", 1.0)] * 3
                                    + [spread.get(n, {}).get("translation", 1.0)] * 3 for n in names])
            for j, name in enumerate(names):
                block = np.asarray(blocks[name], dtype=float)
                s = scale[6 * j:6 * j + 6]
                blocks[name] = (block * np.outer(s, s)).tolist()
            full_key = "covariance_" + "".join(names)
            if full_key in entry:
                entry[full_key] = (np.asarray(entry[full_key], dtype=float) * np.outer(scale, scale)).tolist()
    diagnostics["station_spread"] = spread


def jsonable(value: Any) -> Any:
    """`value` with numpy arrays, numpy scalars and enums turned into plain Python (JSON-ready);
    mappings (keys as str) and sequences converted recursively."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, enum.Enum):
        return value.value
    return value
