"""What the problems of `lmi-sdp` share: the options (`Options`; `AXXBOptions` adds ``polish``),
the orthogonalisers, the backend settings of the SDPs of ``axxb`` and ``axbycz`` and of PICOS, and
how a backend's solve becomes a `Status` and diagnostics (`sdp_status`, `record_figures`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Mapping
from typing import Any

import numpy as np

from handeye import Status
from handeye.base.errors import InputError, SolverError, shown
from handeye.framework.options import check_choice
from handeye.geometry.se3 import gram_schmidt, project_to_so3
from handeye.plugins._sdp_backends import (
    CLARABEL_TIGHT,
    CVXOPT_TIGHT,
    SCS_TIGHT,
    SolveRecord,
)
from handeye.plugins.lmi_sdp.casadi import check_starts

ORTHOGONALIZERS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "gram-schmidt": gram_schmidt,
    "svd": project_to_so3,
}
TRANSLATIONS = ("beta", "resolve")
#: option -> the backends it applies to (given with another backend it is an InputError)
BACKEND_ONLY_OPTIONS: dict[str, tuple[str, ...]] = {
    "cvxpy_solver": ("cvxpy",),
    "multistart": ("casadi",),
    "seed": ("casadi",),
    "ipopt_options": ("casadi",),
}
#: Settings per cvxpy solver of the AX = XB and AXB = YCZ SDPs (others: their defaults; eq. 14's
#: are `handeye.plugins.lmi_sdp.axyb.CVXPY_SETTINGS`). Clarabel: gap and feasibility tolerances
#: 1e-12, as for eq. 14: the SDP's r within 6e-7 of the trust-region solution on the noisy study
#: (docs/solvers/lmi-sdp.md; at its default tolerances up to 6e-5), reported mostly as
#: "optimal_inaccurate"; the polish then takes it to rounding and decides the status.
CVXPY_SETTINGS: Mapping[str, Mapping[str, Any]] = {
    "CLARABEL": CLARABEL_TIGHT,
    "SCS": SCS_TIGHT,
    "CVXOPT": CVXOPT_TIGHT,
}
#: CVXOPT through PICOS: gap tolerances 1e-10 (6 iterations); feasibility tolerances at their
#: defaults (at 1e-11 the dual residual stalls near 1e-9 and CVXOPT wanders). The iteration
#: limit matters: PICOS runs CVXOPT with its "chol" KKT solver and, when that ends with status
#: unknown, again with "ldl". On noise-free data in km (translations * 1e-6) "chol" never
#: converges, and with PICOS's default limit (10^6 iterations) it ran for minutes; with 50 the
#: "ldl" retry solves it in 6. Forcing "ldl" throughout fails on data in micrometres.
PICOS_SETTINGS: dict[str, Any] = {"abs_ipm_opt_tol": 1e-10, "rel_ipm_opt_tol": 1e-10,
                                  "max_iterations": 50}


@dataclasses.dataclass(frozen=True)
class Options:
    """orthogonalize: "gram-schmidt" | "svd"; translations: "beta" | "resolve";
    normalize: divide translations by the RMS translation first (unit invariance);
    cvxpy_solver: cvxpy only (default Clarabel); multistart (0 to 1000), seed (>= 0),
    ipopt_options: casadi only (see `handeye.plugins.lmi_sdp.casadi.solve_casadi`)."""

    orthogonalize: str = "gram-schmidt"
    normalize: bool = False
    translations: str = "beta"
    cvxpy_solver: str | None = None
    multistart: int | None = None
    seed: int | None = None
    ipopt_options: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        check_choice("orthogonalize", self.orthogonalize, tuple(ORTHOGONALIZERS))
        check_choice("translations", self.translations, TRANSLATIONS)
        if self.cvxpy_solver is not None and not isinstance(self.cvxpy_solver, str):
            raise InputError(f"option cvxpy_solver={shown(self.cvxpy_solver)} must be a cvxpy solver name (str)")
        check_starts(0 if self.multistart is None else self.multistart, self.seed)
        if self.ipopt_options is not None and not isinstance(self.ipopt_options, Mapping):
            raise InputError(f"option ipopt_options={shown(self.ipopt_options)} must be a dict of IPOPT options")


@dataclasses.dataclass(frozen=True)
class AXXBOptions(Options):
    """Options of `lmi-sdp` for ``axxb``: those of `Options` and polish: Newton steps on the
    optimality conditions after the SDP (the SDP backends; handeye.plugins.lmi_sdp.axxb)."""

    polish: bool = True


def map_status(solver_status: str, optimal: Collection[str], inaccurate: Collection[str], where: str,
               what: str = "the semidefinite program") -> Status:
    """The `Status` of an SDP solver's status; SolverError naming it for anything but optimal or
    inaccurate (`where`: backend/solver; `what`: the problem solved, for the message)."""
    if solver_status in optimal:
        return Status.OPTIMAL
    if solver_status in inaccurate:
        return Status.OPTIMAL_INACCURATE
    raise SolverError(f"lmi-sdp: {where} returned status {solver_status!r} for {what}; "
                      "no solution is returned")


def sdp_status(backend: str, record: SolveRecord, solved: bool, what: str = "the semidefinite program") -> Status:
    """The `Status` of a solve on backend "cvxpy" or "picos" (`map_status`: optimal, and for cvxpy
    optimal_inaccurate; anything else a SolverError), and a SolverError when the solver gave no
    solution (`solved` False) although its status says it did."""
    if backend == "cvxpy":
        import cvxpy as cp

        optimal, inaccurate = {cp.OPTIMAL}, {cp.OPTIMAL_INACCURATE}
    else:
        import picos

        optimal, inaccurate = {picos.modeling.solution.SS_OPTIMAL}, set()
    where = f"{backend}/{record.backend_solver}"
    status = map_status(record.solver_status, optimal, inaccurate, where, what)
    if not solved:
        raise SolverError(f"lmi-sdp: {where} reported {record.solver_status!r} but gave no solution")
    return status


def record_figures(record: SolveRecord, **after_status: Any) -> dict[str, Any]:
    """The diagnostics of a backend's solve: solver_status, the entries `after_status`,
    backend_solver, iterations, compile_seconds."""
    return {"solver_status": record.solver_status, **after_status, "backend_solver": record.backend_solver,
            "iterations": record.iterations, "compile_seconds": record.compile_seconds}


#: The warning when the Newton polish after an SDP (``axxb``, ``axbycz``) does not certify its point.
POLISH_NOT_CERTIFIED = ("lmi-sdp: the Newton polish after the SDP did not reach a point satisfying "
                        "the global optimality conditions; the SDP's own r is returned")


def polish_figures(polished: Any, r_sdp: np.ndarray) -> dict[str, Any]:
    """The diagnostics of the Newton polish (`handeye.estimation.trust_region.refine_trust_region`'s result)
    that started from the SDP's r `r_sdp`; all None when there was none (polish=False)."""
    if polished is None:
        return dict.fromkeys(("polish_change", "polish_steps", "multiplier", "kkt_residual"))
    return {"polish_change": float(np.abs(polished.x - r_sdp).max()), "polish_steps": polished.iterations,
            "multiplier": polished.multiplier, "kkt_residual": polished.kkt_residual}


def check_finite(backend: str, record: SolveRecord, what: str, *arrays: np.ndarray) -> None:
    """SolverError when a backend returned non-finite numbers (`what`: "beta", "Z", ...)."""
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise SolverError(f"lmi-sdp: {backend}/{record.backend_solver} returned a non-finite {what} "
                          f"(status {record.solver_status!r})")
