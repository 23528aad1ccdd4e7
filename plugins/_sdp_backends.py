"""The SDP backend scaffolding of `lmi-sdp` and `so3-sdp`, written once. Each solver keeps its own
formulations, its status policy and its diagnostics keys; what they share is here:

- option ``cvxpy_solver`` (`sdp_cvxpy_solvers`, `resolve_cvxpy_solver`: both solvers accept the
  same names and give the same error) and options given with a backend they do not belong to
  (`check_backend_options`);
- solver settings more than one formulation uses (`CLARABEL_TIGHT`, `SCS_TIGHT`, `CVXOPT_TIGHT`);
- problems built once per key and shared by every solve and thread (`ProblemCache`: the cvxpy
  problems, so3-sdp's Clarabel data);
- backend ``cvxpy``: a cached DPP problem (`CvxpyProblem`: the problem, the lock that serialises
  its solves, whether cvxpy compiled it yet) solved with new parameter values (`solve_cvxpy`:
  warnings, settings and their fallback, errors, status, iterations, `compile_seconds`);
- backend ``picos`` (CVXOPT): `solve_picos` (errors, status, CVXOPT's iteration count);
- backend ``clarabel`` (Clarabel's own API, no modelling layer): `solve_conic` (the one place that
  creates and runs a `clarabel.DefaultSolver`), Clarabel's statuses (`STATUSES`), its svec
  convention (`svec`, `unsvec`) and a dual-form SDP with constant constraints (`DualSDP`).

What a solve reports (`SolveRecord`: the solver's status, the solver that ran, its iterations,
the compile time) is the same for every backend; each solver names it in its own diagnostics.

cvxpy, picos and clarabel are imported only when a function here needs them, never at import time.

Clarabel's dual-form SDP (`DualSDP`): max b^T nu s.t. C - sum_k nu_k A_k PSD, with C (n, n) given
per solve and the A_k, b fixed. Used by `so3-sdp` (backend ``clarabel``) for the Lagrangian dual
of its Shor relaxation (handeye.estimation.so3_relaxation) and by `lmi-sdp` for its AX = XB SDP. Clarabel
solves min 1/2 x^T P x + q^T x s.t. A x + s = b, s in K. Here (P = 0):

    x = nu (K),   q = -b,   A = [svec A_1 ... svec A_K],   b_clarabel = svec C,
    s = svec(C - sum_k nu_k A_k) in the PSD cone (`clarabel.PSDTriangleConeT(n)`).

Clarabel's dual, max -b_clarabel^T z s.t. A^T z = -q, z in K* (the PSD cone is self-dual), is then
min <C, Z> s.t. <A_k, Z> = b_k, Z PSD with Z = unsvec(z): the primal SDP (for so3-sdp, the Shor
relaxation). A primal-dual interior-point method returns both from one solve.

svec (Clarabel's convention, `PSDTriangleConeT`): the upper triangle stacked column by column,
(0,0), (0,1), (1,1), (0,2), (1,2), (2,2), ..., off-diagonal entries multiplied by sqrt(2), so that
svec(X) . svec(Y) = <X, Y> = trace(X Y) for symmetric X, Y. `unsvec` inverts it. Tested against
an SDP with a known answer (tests/plugins/test_so3_sdp.py).

Everything that does not depend on C (A as a CSC matrix, q, the cone, the svec indices) is built
once (`DualSDP.build`); a solve forms svec C and one `clarabel.DefaultSolver`. A `DualSDP` is
immutable and a solve creates its own solver and settings, so one instance may serve several
threads at once.
"""

from __future__ import annotations

import dataclasses
import functools
import threading
import time
import types
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

from handeye.base.errors import InputError, SolverError

T = TypeVar("T")

# --------------------------------------------------------------------------------------------
# options


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


# --------------------------------------------------------------------------------------------
# settings shared by several formulations (each solver documents why it uses them)

#: Clarabel with gap and feasibility tolerances 1e-12 (its defaults: 1e-8).
CLARABEL_TIGHT: Mapping[str, Any] = types.MappingProxyType({
    "tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12, "tol_ktratio": 1e-10,
})
#: SCS (first order) at eps 1e-9 (its default: 1e-4), with room for the iterations that takes.
SCS_TIGHT: Mapping[str, Any] = types.MappingProxyType({"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 100_000})
#: CVXOPT through cvxpy with gap tolerances 1e-10.
CVXOPT_TIGHT: Mapping[str, Any] = types.MappingProxyType({"abstol": 1e-10, "reltol": 1e-10})


# --------------------------------------------------------------------------------------------
# problems built once


class ProblemCache:
    """Problems built once per key and then shared by every solve (and thread).

    cvxpy compiles a problem on its first solve (20-50 ms; later solves only re-apply the
    Parameters, DPP) and keeps one compiled program per problem, so an SDP plugin keeps one
    problem per cvxpy solver and per whatever else changes the problem's shape (the same holds
    for constant data stated in a solver's own API). `build(*key)` makes the problem of a key;
    `problems` maps key -> problem and `builds` counts the builds in this process (tests clear
    or replace entries of `problems`).
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


@dataclasses.dataclass(frozen=True)
class SolveRecord:
    """What a backend says about one solve: solver_status (the solver's or modelling layer's own
    status name), backend_solver (the numerical solver that ran, e.g. "CLARABEL", "cvxopt"),
    iterations (None when the backend does not say) and compile_seconds (cvxpy compiling its
    problem, on the first solve of a cached problem only; 0.0 otherwise)."""

    solver_status: str
    backend_solver: str
    iterations: int | None
    compile_seconds: float = 0.0


def _iterations(count: Any) -> int | None:
    return None if count is None else int(count)


# --------------------------------------------------------------------------------------------
# backend cvxpy: one DPP problem per key, compiled on its first solve, then reused


@dataclasses.dataclass(kw_only=True)
class CvxpyProblem:
    """A cached cvxpy problem; subclasses add its Parameters and Variables as fields. `lock`
    serialises the solves of the problem (parameter values, solve and reading the solution);
    `compiled`: cvxpy compiled it (on its first solve, `compile_seconds`)."""

    problem: Any
    lock: threading.Lock = dataclasses.field(default_factory=threading.Lock)
    compiled: bool = False


def check_dpp(problem: Any, who: str, what: str) -> Any:
    """`problem` when it is DPP (the cache re-applies parameters without recompiling), else a
    SolverError naming `what`."""
    if not problem.is_dpp():  # pragma: no cover - a cvxpy change would break the cache
        raise SolverError(f"{who}: the cvxpy formulation of {what} is not DPP")
    return problem


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


def _solve_with_settings(problem: Any, solver: str, settings: Mapping[str, Any]) -> None:
    """problem.solve with `solver` and a copy of `settings` made for this call. An older Clarabel
    without the faer factorisation rejects the settings ("Bad settings: ... direct_solve_method");
    this call then retries without that one setting. Nothing is remembered: every solve starts
    from the same settings, and without a warm start (cvxpy's default would start SCS from the
    previous solve's point, making an answer depend on what was solved before)."""
    settings = dict(settings)
    try:
        problem.solve(solver=solver, warm_start=False, **settings)
    except Exception as exc:
        if "direct_solve_method" not in str(exc) or settings.pop("direct_solve_method", None) is None:
            raise
        problem.solve(solver=solver, warm_start=False, **settings)


def solve_cvxpy(cached: CvxpyProblem, solver: str, settings: Mapping[str, Any], parameters: Mapping[str, Any],
                read: Callable[[Any], T], who: str, what: str, *, chain: bool = False) -> tuple[T, SolveRecord]:
    """Solve the cached problem with cvxpy solver `solver` and `settings` (`_solve_with_settings`)
    after setting its Parameters (field name of `cached` -> value), all under its lock: (what
    `read(cached)` takes from the solved problem under the lock, the solve's record).

    Any status is returned (the caller maps it): cvxpy's warning "solution may be inaccurate" is
    the status optimal_inaccurate and is silenced. A solver failure is a SolverError "{who}:
    cvxpy/{solver} failed on {what}: ..." (`chain`: with the cvxpy error as its cause).
    """
    import cvxpy as cp

    with cached.lock, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        for name, value in parameters.items():
            getattr(cached, name).value = value
        start = time.perf_counter()
        try:
            _solve_with_settings(cached.problem, solver, settings)
        except cp.error.SolverError as exc:
            raise SolverError(f"{who}: cvxpy/{solver} failed on {what}: {exc}") from (exc if chain else None)
        record = SolveRecord(str(cached.problem.status), solver, _iterations(cached.problem.solver_stats.num_iters),
                             compile_seconds(cached, start))
        return read(cached), record


# --------------------------------------------------------------------------------------------
# backend picos (CVXOPT): built per call (PICOS has no parameters for general constants)


def solve_picos(problem: Any, settings: Mapping[str, Any], who: str, what: str, *, primals: bool | None = None,
                duals: bool = False, chain: bool = False) -> tuple[Any, SolveRecord]:
    """Solve the PICOS `problem` with CVXOPT and `settings`: (PICOS's solution, the solve's
    record; any status, the caller maps it). A failure is a SolverError "{who}: picos/cvxopt
    failed on {what}: ..." (`chain`: with PICOS's error as its cause)."""
    import picos

    try:
        solution = problem.solve(solver="cvxopt", primals=primals, duals=duals, **settings)
    except picos.SolutionFailure as exc:
        raise SolverError(f"{who}: picos/cvxopt failed on {what}: {exc}") from (exc if chain else None)
    raw = solution.info.get("cvxopt_sol", {}) if isinstance(solution.info, Mapping) else {}
    return solution, SolveRecord(str(solution.claimedStatus), "cvxopt", _iterations(raw.get("iterations")))


# --------------------------------------------------------------------------------------------
# backend clarabel: Clarabel's own API

#: Clarabel's statuses with a usable solution -> the status reported (cvxpy's names, so that the
#: native and cvxpy backends report the same status); any other status is a SolverError.
STATUSES: Mapping[str, str] = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate"}


def solve_conic(P: Any, q: np.ndarray, A: Any, b: np.ndarray, cones: Sequence[Any],
                settings: Mapping[str, Any], who: str) -> Any:
    """Clarabel's min 1/2 x^T P x + q^T x s.t. A x + s = b, s in `cones` (P, A: scipy.sparse CSC;
    q: (n,); b: (m,)) with `settings` (attribute -> value; verbose off unless given): Clarabel's
    solution object, whatever its status (the caller maps it). A setting "direct_solve_method"
    that the installed Clarabel rejects (< 0.10: no "faer") is dropped for this call. SolverError
    naming `who` when Clarabel raises (bad data, unknown setting)."""
    import clarabel

    settings = {"verbose": False, **settings}

    def solver(settings: dict[str, Any]) -> Any:
        s = clarabel.DefaultSettings()
        for name, value in settings.items():
            setattr(s, name, value)
        return clarabel.DefaultSolver(P, q, A, b, list(cones), s)

    try:
        try:
            instance = solver(settings)
        except Exception as exc:
            if "direct_solve_method" not in str(exc) or settings.pop("direct_solve_method", None) is None:
                raise
            instance = solver(settings)
        return instance.solve()
    except Exception as exc:
        raise SolverError(f"{who}: Clarabel failed on the SDP: {exc}") from exc


@functools.cache
def svec_indices(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, weights): entry i of svec X is weights[i] * X[rows[i], cols[i]], rows <= cols,
    in Clarabel's order (upper triangle, column by column); weights 1 on the diagonal, sqrt(2) off.
    Cached, read-only."""
    cols, rows = np.tril_indices(n)  # row-major over the lower triangle = column-major over the upper
    weights = np.where(rows == cols, 1.0, np.sqrt(2.0))
    for a in (rows, cols, weights):
        a.flags.writeable = False
    return rows, cols, weights


def svec(X: np.ndarray) -> np.ndarray:
    """X: (n, n) symmetric (only its upper triangle is read) -> (n (n + 1) / 2,), Clarabel's svec."""
    rows, cols, weights = svec_indices(X.shape[-1])
    return X[..., rows, cols] * weights


def unsvec(x: np.ndarray, n: int) -> np.ndarray:
    """Inverse of `svec`: x (n (n + 1) / 2,) -> the symmetric (n, n) matrix."""
    rows, cols, weights = svec_indices(n)
    X = np.zeros((n, n))
    X[rows, cols] = x / weights
    X[cols, rows] = x / weights
    return X


@dataclasses.dataclass(frozen=True)
class DualSDPSolution:
    """Z: (n, n) the primal matrix (the cone's dual variable); nu: (K,) the multipliers;
    status: "optimal" or "optimal_inaccurate" (`STATUSES`); objective: b^T nu; iterations and
    solve_seconds as Clarabel reports them."""

    Z: np.ndarray
    nu: np.ndarray
    status: str
    objective: float
    iterations: int
    solve_seconds: float


@dataclasses.dataclass(frozen=True)
class DualSDP:
    """The C-independent data of max b^T nu s.t. C - sum_k nu_k A_k PSD (module docstring)."""

    n: int
    A: Any  # scipy.sparse CSC (n (n + 1) / 2, K): column k is svec A_k
    P: Any  # scipy.sparse CSC (K, K), zero
    q: np.ndarray  # (K,): -b
    cones: tuple[Any, ...]  # (clarabel.PSDTriangleConeT(n),)

    @classmethod
    def build(cls, matrices: np.ndarray, b: np.ndarray) -> DualSDP:
        """matrices: (K, n, n) symmetric A_k; b: (K,)."""
        import clarabel
        import scipy.sparse as sp

        K, n, _ = matrices.shape
        A = sp.csc_matrix(svec(matrices).T)
        q = -np.asarray(b, dtype=float)
        q.flags.writeable = False
        return cls(n, A, sp.csc_matrix((K, K)), q, (clarabel.PSDTriangleConeT(n),))

    def solve(self, C: np.ndarray, settings: Mapping[str, Any], who: str) -> DualSDPSolution:
        """Solve for C: (n, n) symmetric, with Clarabel `settings` (attribute -> value; verbose off
        unless given; see `solve_conic`). SolverError (naming `who`) when Clarabel fails or ends
        without a usable solution (`STATUSES`)."""
        solution = solve_conic(self.P, self.q, self.A, svec(C), self.cones, settings, who)
        status = STATUSES.get(str(solution.status))
        if status is None:
            raise SolverError(f"{who}: Clarabel returned status {str(solution.status)!r} for the SDP "
                              f"(after {solution.iterations} iterations); try backend='cvxpy' with "
                              "another cvxpy_solver")
        nu = np.array(solution.x, dtype=float)
        return DualSDPSolution(Z=unsvec(np.array(solution.z, dtype=float), self.n), nu=nu, status=status,
                               objective=float(-self.q @ nu), iterations=int(solution.iterations),
                               solve_seconds=float(solution.solve_time))
