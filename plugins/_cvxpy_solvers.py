"""Choosing the cvxpy solver of an SDP plugin (option ``cvxpy_solver`` of `lmi-sdp` and `so3-sdp`).

Shared so that both solvers accept the same names and give the same error: a name that is not an
installed cvxpy solver able to handle PSD constraints raises `InputError` listing the ones that
are. cvxpy is imported only when a function here is called, never at import time.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from handeye.framework.errors import InputError

#: The cvxpy solver used when ``cvxpy_solver`` is not given.
DEFAULT_CVXPY_SOLVER = "CLARABEL"


@functools.cache
def sdp_cvxpy_solvers() -> tuple[str, ...]:
    """Installed cvxpy solvers that accept PSD constraints (the possible ``cvxpy_solver``).

    Cached: `cvxpy.installed_solvers` looks every solver module up (~5 ms, as long as a solve)."""
    import cvxpy as cp
    from cvxpy.constraints import PSD
    from cvxpy.constraints.psd import SvecPSD
    from cvxpy.reductions.solvers.defines import SOLVER_MAP_CONIC

    return tuple(sorted(name for name in cp.installed_solvers()
                  if name in SOLVER_MAP_CONIC
                  and any(c in (PSD, SvecPSD) for c in SOLVER_MAP_CONIC[name].SUPPORTED_CONSTRAINTS)))


def resolve_cvxpy_solver(name: str | None) -> str:
    """The cvxpy solver name for option ``cvxpy_solver`` (case-insensitive; None: Clarabel);
    InputError listing the installed SDP-capable solvers when it is unknown, not installed or
    cannot do SDPs."""
    if name is None:
        name = DEFAULT_CVXPY_SOLVER
    usable = sdp_cvxpy_solvers()
    if name.upper() in usable:
        return name.upper()
    import cvxpy as cp

    if name.upper() in cp.installed_solvers():
        why = "is installed but cannot solve semidefinite programs"
    else:
        why = "is not an installed cvxpy solver"
    raise InputError(f"option cvxpy_solver={name!r} {why}; installed cvxpy solvers that can "
                     f"solve semidefinite programs: {', '.join(usable) or '(none)'}")


def check_backend_options(solver: str, options: Any, backend: str,
                          backend_only: Mapping[str, tuple[str, ...]]) -> None:
    """Raise InputError when an option of solver `solver` that belongs to other backends (option
    name -> its backends, in `backend_only`) is given (not None) with `backend`."""
    for name, backends in backend_only.items():
        if getattr(options, name) is not None and backend not in backends:
            raise InputError(
                f"{solver}: option {name} applies only to backend(s) {', '.join(backends)}, "
                f"not to backend {backend!r}; drop it or choose backend={backends[0]!r}"
            )


def compile_seconds(cached: Any, start: float) -> float:
    """Seconds the solve just made of a cached problem spent compiling it, and mark it compiled.

    `cached` holds the cvxpy problem (``.problem``) and a ``.compiled`` flag; `start` is a
    `time.perf_counter()` reading taken just before the solve. cvxpy compiles a problem on its
    first solve (20-50 ms here; later solves only re-apply the parameters): that solve's time
    not spent in the numerical solver. 0.0 for every later solve. Loading cvxpy itself (~1 s,
    once per process) happens earlier and is not counted.
    """
    if cached.compiled:
        return 0.0
    cached.compiled = True
    solve_time = getattr(cached.problem.solver_stats, "solve_time", None) or 0.0
    return max(time.perf_counter() - start - solve_time, 0.0)


class ProblemCache:
    """cvxpy problems built once per key and then shared by every solve (and thread).

    cvxpy compiles a problem on its first solve (20-50 ms; later solves only re-apply the
    Parameters, DPP) and keeps one compiled program per problem, so an SDP plugin keeps one
    problem per cvxpy solver and per whatever else changes the problem's shape. `build(*key)`
    makes the problem of a key; `problems` maps key -> problem and `builds` counts the builds in
    this process (tests clear or replace entries of `problems`).
    """

    def __init__(self, build: Callable[..., Any]) -> None:
        self._build = build
        self._lock = threading.Lock()
        self.problems: dict[tuple[Any, ...], Any] = {}
        self.builds = 0

    def get(self, *key: Any) -> Any:
        """The problem of `key`, built on the first request."""
        with self._lock:
            cached = self.problems.get(key)
            if cached is None:
                cached = self.problems[key] = self._build(*key)
                self.builds += 1
            return cached
