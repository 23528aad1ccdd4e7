"""Backend ``casadi`` of `lmi-sdp`: the Kronecker cost under EXACT SO(3) constraints, as a
CasADi NLP solved by IPOPT, for k rotations: ``axyb`` (eq. 8, k = 2,
`solve_casadi`) and ``axxb`` (k = 1, `solve_casadi_axxb`); and the lifted cost of ``axbycz`` under
exact SO(3) on R_X, R_Y, R_Z (`solve_casadi_axbycz`, section "AXB = YCZ" below). The `lmi-sdp`
modules of the three problems call these for ``backend="casadi"``.

Formulation (measurements: docs/solvers/lmi-sdp.md, backend casadi):

1. Cost. |H beta - w|^2 with beta = [r; t], r = [vec R_1; ...; vec R_k] (9k, column-major vec),
   t the k translations, is split (`handeye.estimation.rotation_cost`) into
   |T t + U r - u|^2 + |S r - s|^2 + rest, so for any rotations the optimal translations are
   t(r) = T^-1 (u - U r) (for ``axyb`` exactly the least squares of eqs. 20-21) and the NLP is
   over r only: minimise |S r - s|^2 (S: 9k x 9k). ``axyb``: S from a QR of
   [R1_t | R1_r | q1] of the reduced eq. 8 (eqs. 10-12); ``axxb``: from its normal equations
   (its H may be rank deficient, docs/solvers/kron-lstsq.md). The reduction is O(m) and done in
   numpy; the NLP never sees m, so ONE CasADi `nlpsol` per k (S, s passed as its parameters p)
   serves every problem size and is built once per IPOPT option set (`nlp_solver`, cached at
   module level).
2. Constraints, per rotation with columns c1, c2, c3 (= entries 0-2, 3-5, 6-8 of its vec):
   |c1|^2 = 1, |c2|^2 = 1, c1.c2 = 0, c3 = c1 x c2 (6 equations per rotation). Together they are
   exactly SO(3): c3 is then a unit vector orthogonal to c1, c2 and det R = c3.(c1 x c2) = +1.
   They are polynomial (smooth, exact Hessians by AD) and independent everywhere on SO(3) (the
   Jacobian has rank 6: the c3 rows are the identity in c3, the other three are 2c1, 2c2 and
   (c2, c1) in (c1, c2), independent for orthonormal c1, c2), so IPOPT's LICQ assumption holds.
   The full set R^T R = I (6) plus c3 = c1 x c2 (3) would be 9 equations of rank 6: redundant,
   which violates LICQ and makes IPOPT regularise its KKT matrix. A local exp-map chart
   R = R0 exp([w]) would be unconstrained but is only a chart (singular at |w| = pi) and would
   need re-centring for the random starts; the constraints need none of that.
3. IPOPT from the `kron-lstsq` point (``axyb``: least squares beta, SVD projection onto SO(3);
   ``axxb``: least squares on the sphere |r|^2 = 3, projected), plus
   ``multistart`` seeded random starts (uniform rotations); the lowest cost of the converged
   starts wins. The cost is divided by sigma_max(S)^2 (Hessian of order 1), so IPOPT's absolute
   tolerances mean the same at every m and unit. The iterate is finally projected onto SO(3) by
   SVD (it moves by the constraint violation, ~1e-15) and translations come from t(r).
4. Status: ``Solve_Succeeded`` -> optimal; ``Solved_To_Acceptable_Level`` -> optimal_inaccurate;
   IPOPT stopping without convergence (iteration / time limit, tiny steps, failed restoration,
   diverging) -> not_converged (last iterate, projected, with a warning); anything else
   (infeasible, invalid number or option, internal error) is a hard failure of that start, and
   when every start failed that way `solve_casadi` raises `SolverError` naming the statuses.

Normalisation (``normalize=True``): translations are divided by the data's RMS translation
before the system is built and the answer's translations multiplied back, so the normalised NLP is the
same for data in mm or m and the answer is unit invariant. ``normalize=False`` is the system in
the data's own units, as the paper has it.

AXB = YCZ (``axbycz``, `solve_casadi_axbycz`):

1. Cost. |H beta(v) - w|^2 of the lifted system (`handeye.problems.axbycz.kronecker`) at the
   structured beta(v) of v = [vec R_X; vec R_Y; vec R_Z; t_X; t_Y; t_Z] (36): beta's lifted
   entries are the products vec R_Y vec R_Z^T, vec R_Y t_Z^T of v. At such a beta the cost is
   sum_i |top(A_i X B_i - Y C_i Z)|_F^2, the algebraic error of the equation over its 3 x 4 top
   rows (translations in the units of ``normalize``). It is quartic in v, given to the NLP as
   beta^T N beta - 2 g^T beta with N: (132, 132), g the normal equations (O(m) sums, passed as
   the NLP's parameters): one `nlpsol` serves every m and data set and is built once per IPOPT
   option set (cached). The translations are the NLP's variables in units of the data's RMS
   translation whatever ``normalize`` says (a change of variables, N -> D N D: the minimiser is
   unchanged and the variables are of order 1).
2. Constraints per rotation, columns c1, c2, c3: |c1|^2 = |c2|^2 = 1, c1.c2 = 0, c3 = c1 x c2 (6
   equations, exactly SO(3), independent on it: point 2 above).
3. IPOPT from the `kron-lstsq` answer (|r|^2 = 12 least squares, rank-one extraction, SVD
   projection, translations of eq. 38) plus ``multistart`` seeded random rotations (translations
   by eq. 38 for them); the lowest cost of the converged starts wins. The cost is divided by the
   largest eigenvalue of D N D (Hessian of order 1). Statuses as point 4 above.

One cache (`_CACHE`) holds every NLP built: one per (NLP, IPOPT option set), each serving every
m and data set.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from handeye import SolverOutput, Status
from handeye.base.errors import InputError, SolverError
from handeye.estimation.rotation_cost import (
    RotationCost,
    eliminate_translations,
    rotation_blocks,
    rotations_vector,
    signed_rotations,
    sphere_least_squares,
)
from handeye.framework.options import check_int
from handeye.geometry.se3 import (
    make_pose,
    orthonormality_error,
    project_to_so3,
    random_rotations,
)
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axbycz import kronecker as lifted
from handeye.problems.axxb import AXXBData
from handeye.problems.axyb import AXYBData, split_beta

#: IPOPT settings of every solve (ipopt_options may override or extend them). tol 1e-12 on the
#: scaled cost (Hessian of order 1): noise-free data are recovered to ~1e-12 rad.
IPOPT_DEFAULTS: dict[str, Any] = {
    "print_level": 0,
    "sb": "yes",
    "tol": 1e-12,
    "constr_viol_tol": 1e-12,
    "max_iter": 200,
}

SUCCESS = {"Solve_Succeeded": Status.OPTIMAL, "Solved_To_Acceptable_Level": Status.OPTIMAL_INACCURATE}
#: Largest ``multistart``: each start is one IPOPT solve of 5-10 ms (m-independent: the NLP is
#: over the rotations only), so 1000 starts take 5-10 s; more would only repeat minima already
#: found, and a mistyped count (10**10) would otherwise allocate its starts (~600 GB) first.
MAX_MULTISTART = 1000
#: Relative cost difference below which two starts count as the same minimum (rounding of the
#: cost at a converged point is ~1e-14 relative).
TIE_RTOL = 1e-10
#: IPOPT stopped without convergence but has an iterate: reported as not_converged.
NOT_CONVERGED = {
    "Maximum_Iterations_Exceeded", "Maximum_CpuTime_Exceeded", "Maximum_WallTime_Exceeded",
    "Search_Direction_Becomes_Too_Small", "Restoration_Failed", "Diverging_Iterates",
    "Feasible_Point_Found", "User_Requested_Stop",
}

#: (NLP: the number of rotations or "axbycz", merged IPOPT options as a sorted tuple) -> nlpsol;
#: every m and every data set of a problem share one entry.
_CACHE: dict[tuple, Any] = {}
_LOCK = threading.Lock()
#: A cached nlpsol is shared: its call and the stats() read after it must not interleave.
_CALL_LOCK = threading.Lock()


def _option_key(ipopt_options: Mapping[str, Any] | None) -> tuple[tuple, dict[str, Any]]:
    """(hashable cache key, merged option dict) of IPOPT_DEFAULTS updated by ipopt_options."""
    options = dict(IPOPT_DEFAULTS)
    for key, value in (ipopt_options or {}).items():
        if not isinstance(key, str):
            raise InputError(f"ipopt_options keys must be IPOPT option names (str), got {key!r}")
        options[key.removeprefix("ipopt.")] = value
    return tuple(sorted((k, repr(v)) for k, v in options.items())), options


def nlp_solver(ipopt_options: Mapping[str, Any] | None = None, rotations: int = 2):
    """The CasADi IPOPT `nlpsol` of the reduced problem over `rotations` rotations (2: ``axyb``,
    1: ``axxb``), built once per (rotations, option set) and cached.

    x: (9k,) = [vec R_1; ...; vec R_k]; p: (81k^2 + 9k,) = [vec S (column-major); s], the cost
    |S x - s|^2 scaled as the caller wishes; g: (6k,) the SO(3) equations, all = 0.
    `ipopt_options` (names with or without the "ipopt." prefix) override `IPOPT_DEFAULTS`.
    """
    return _cached(rotations, lambda options: _build(options, rotations), ipopt_options)


def _cached(nlp: int | str, build: Any, ipopt_options: Mapping[str, Any] | None):
    """The nlpsol of `nlp` (a number of rotations or "axbycz") for `ipopt_options` from `_CACHE`,
    made by `build(merged options)` on the first request."""
    option_key, options = _option_key(ipopt_options)
    key = (nlp, option_key)
    with _LOCK:
        solver = _CACHE.get(key)
        if solver is None:
            solver = build(options)
            _CACHE[key] = solver
    return solver


def _nlpsol(name: str, nlp: Mapping[str, Any], options: Mapping[str, Any]):
    """CasADi's IPOPT nlpsol `name` of `nlp` with the merged IPOPT `options`, nothing IPOPT prints
    reaching the terminal. IPOPT validates its options when the solver is created: an option it
    rejects is an InputError naming the options given and IPOPT's first line of complaint
    (without CasADi's source location)."""
    import casadi as ca

    # no CasADi text either: NaN/inf warnings of the evaluations (the status says it) and the
    # multipliers of the parameters, which are not used (their failure printed a warning)
    opts = {"print_time": False, "error_on_fail": False, "show_eval_warnings": False, "calc_lam_p": False}
    opts.update({f"ipopt.{k}": v for k, v in options.items()})
    with _captured_stdout() as printed:
        try:
            return ca.nlpsol(name, "ipopt", nlp, opts)
        except RuntimeError as exc:
            error = exc
    lines = [line.strip() for line in printed[0].splitlines() if line.strip()] or [str(error).strip().splitlines()[-1]]
    given = {k: v for k, v in options.items() if IPOPT_DEFAULTS.get(k, object()) != v}
    reason = re.sub(r"^.*?\.cpp:\d+:\s*", "", lines[0])  # CasADi's source location first
    raise InputError(f"lmi-sdp/casadi: IPOPT rejected ipopt_options {given}: {reason}")


def _build(options: Mapping[str, Any], rotations: int):
    import casadi as ca

    n = 9 * rotations
    x = ca.SX.sym("r", n)
    p = ca.SX.sym("p", n * n + n)
    S = ca.reshape(p[: n * n], n, n)
    e = ca.mtimes(S, x) - p[n * n:]
    g = []
    for k in range(0, n, 9):  # each rotation; columns of the column-major vec
        c1, c2, c3 = x[k:k + 3], x[k + 3:k + 6], x[k + 6:k + 9]
        g += [ca.dot(c1, c1) - 1, ca.dot(c2, c2) - 1, ca.dot(c1, c2), c3 - ca.cross(c1, c2)]
    return _nlpsol("lmi_sdp_casadi", {"x": x, "p": p, "f": ca.dot(e, e), "g": ca.vertcat(*g)}, options)


@contextlib.contextmanager
def _captured_stdout() -> Iterator[list[str]]:
    """Capture what is printed while the block runs, through Python's sys.stdout (where CasADi's
    bindings send its output) and to file descriptor 1 (C code): IPOPT prints an invalid option
    value and its documentation, whatever print_level says. The text is the yielded list's one
    item once the block has ended. Used only while a solver is built (once per option set, under
    `_LOCK`), so that no IPOPT text reaches the user's terminal."""
    printed: list[str] = []
    sys.stdout.flush()
    _flush_c_stdout()
    saved = os.dup(1)
    python_text = io.StringIO()  # CasADi's Python bindings route its (and IPOPT's) output to sys.stdout
    with tempfile.TemporaryFile() as sink, contextlib.redirect_stdout(python_text):
        os.dup2(sink.fileno(), 1)
        try:
            yield printed
        finally:
            _flush_c_stdout()  # C's stdout buffers when it is not a terminal: empty it into the sink
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            printed.append(python_text.getvalue() + sink.read().decode("utf-8", "replace"))


def _flush_c_stdout() -> None:
    """fflush(NULL) of the C library (every C stdio stream), where ctypes can reach it."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library by that name (e.g. Windows): nothing buffered to lose
        pass


def _constraint_violation(r: np.ndarray) -> float:
    out = []
    for k in range(0, len(r), 9):
        c1, c2, c3 = r[k:k + 3], r[k + 3:k + 6], r[k + 6:k + 9]
        out += [c1 @ c1 - 1, c2 @ c2 - 1, c1 @ c2, *(c3 - np.cross(c1, c2))]
    return float(np.max(np.abs(out)))


def check_starts(multistart: Any, seed: Any) -> None:
    """InputError unless ``multistart`` is an integer from 0 to `MAX_MULTISTART` and ``seed`` is
    None or an integer >= 0 (``numpy.random.default_rng`` refuses negative seeds)."""
    check_int("multistart", multistart, minimum=0, maximum=MAX_MULTISTART)
    if seed is not None:
        check_int("seed", seed, minimum=0)


def solve_casadi(data: AXYBData, *, normalize: bool, multistart: int = 0, seed: int | None = None,
                 ipopt_options: Mapping[str, Any] | None = None) -> SolverOutput:
    """Minimise eq. 8 over SE(3) x SE(3) with IPOPT, from the kron-lstsq point (+ random starts).

    data: validated `AXYBData` (A, B: (m, 4, 4)). normalize: divide translations by the data's
    RMS translation first (unit invariance). multistart: number of extra random starts (0 to
    `MAX_MULTISTART`), drawn from ``numpy.random.default_rng(seed)`` (seed None or >= 0).
    ipopt_options: extra IPOPT options.

    Returns a `SolverOutput` with X, Y (4, 4) exactly in SE(3), the status of the chosen start
    (module docstring, item 4) and diagnostics: ``ipopt_status`` (= ``solver_status``), ``success``
    (True only for Solve_Succeeded), ``iterations`` (of the chosen start), ``iterations_total``,
    ``cost`` (eq. 8, |H beta - w|^2 of the normalised data when normalize), ``start_cost`` (the
    same cost at the kron-lstsq point), ``starts_tried``, ``best_start`` (0 = kron-lstsq),
    ``start_statuses``, ``start_costs``, ``constraint_violation`` (before the final projection),
    ``translation_scale``, ``sigma_min_R1`` (of R1 of eq. 10, normalised data when normalize),
    ``warnings``. Raises SolverError when no start gave an iterate.
    """
    check_starts(multistart, seed)
    scale = data.translation_scale if normalize else 1.0
    system = data.kronecker(scale)
    cost = eliminate_translations(system)
    MX, MY, _, _ = split_beta(system.least_squares())
    (RX, RY), (tX, tY), status, diagnostics = solve_rotations(
        cost, [project_to_so3(MX), project_to_so3(MY)], multistart=multistart, seed=seed,
        ipopt_options=ipopt_options)
    diagnostics.update(translation_scale=scale, sigma_min_R1=system.smallest_singular_value(),
                       normalized=bool(normalize))
    return SolverOutput(unknowns={"X": make_pose(RX, tX * scale), "Y": make_pose(RY, tY * scale)},
                        status=status, diagnostics=diagnostics)


def solve_casadi_axxb(data: AXXBData, *, normalize: bool, multistart: int = 0, seed: int | None = None,
                      ipopt_options: Mapping[str, Any] | None = None) -> SolverOutput:
    """``axxb``: minimise |H beta - w|^2 of A_i X = X B_i over SE(3) with IPOPT, from the
    kron-lstsq point (least squares on |vec R_X|^2 = 3, projected) plus ``multistart`` random
    starts. Arguments, result and diagnostics as `solve_casadi` (``cost`` is |H beta - w|^2 of
    the ``axxb`` system; no ``sigma_min_R1``: this H may be rank deficient)."""
    check_starts(multistart, seed)
    scale = data.translation_scale if normalize else 1.0
    cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)
    start, _ = signed_rotations(cost, sphere_least_squares(cost).x)
    (RX,), (tX,), status, diagnostics = solve_rotations(cost, start, multistart=multistart, seed=seed,
                                                       ipopt_options=ipopt_options)
    diagnostics.update(translation_scale=scale, normalized=bool(normalize))
    return SolverOutput(unknowns={"X": make_pose(RX, tX * scale)}, status=status, diagnostics=diagnostics)


def run_starts(solver: Any, starts: list[np.ndarray], params: np.ndarray,
               value: Any) -> tuple[np.ndarray, Status, dict[str, Any]]:
    """Run the IPOPT `solver` (with parameters `params`) from every start and choose: the lowest
    `value` among the runs that succeeded (or, if none did, among those that stopped without
    converging), ties (within TIE_RTOL) going to the earliest start, so the first start is
    reported whenever a random start only reproduces its optimum. Returns the chosen iterate
    (not yet projected), its status and the diagnostics of the runs, with the warnings the status
    needs. A crash inside CasADi / IPOPT fails that start only; SolverError when no start gave
    a usable iterate."""
    runs = []
    for x0 in starts:
        try:
            with _CALL_LOCK:
                result = solver(x0=x0, p=params, lbg=0.0, ubg=0.0)
                stats = solver.stats()
        except RuntimeError as exc:
            detail = str(exc).strip().splitlines()[-1]
            runs.append({"status": f"exception: {detail}", "iterations": 0, "x": np.full(len(x0), np.nan),
                         "finite": False})
            continue
        x = np.asarray(result["x"], dtype=float).ravel()
        runs.append({"status": str(stats["return_status"]), "iterations": int(stats.get("iter_count", 0)),
                     "x": x, "finite": bool(np.all(np.isfinite(x)))})
    candidates = [i for i, run in enumerate(runs) if run["finite"] and run["status"] in SUCCESS]
    if not candidates:
        candidates = [i for i, run in enumerate(runs) if run["finite"] and run["status"] in NOT_CONVERGED]
    if not candidates:
        raise SolverError(
            "lmi-sdp/casadi: IPOPT gave no usable iterate from any of the "
            f"{len(runs)} start(s); return statuses {[run['status'] for run in runs]} "
            "(check ipopt_options, or the data: see diagnose)"
        )
    costs = [value(run["x"]) if run["finite"] else float("nan") for run in runs]
    lowest = min(costs[i] for i in candidates)
    best = min(i for i in candidates if costs[i] <= lowest + TIE_RTOL * abs(lowest))
    chosen = runs[best]
    status = SUCCESS.get(chosen["status"], Status.NOT_CONVERGED)
    warnings = []
    if status is Status.NOT_CONVERGED:
        warnings.append(f"lmi-sdp/casadi: IPOPT did not converge ({chosen['status']}); the answer "
                        "is its last iterate projected onto SO(3)")
    elif status is Status.OPTIMAL_INACCURATE:
        warnings.append("lmi-sdp/casadi: IPOPT stopped at its acceptable (looser) tolerance")
    return chosen["x"], status, {
        "backend_solver": "ipopt",
        "ipopt_status": chosen["status"],
        "solver_status": chosen["status"],
        "success": chosen["status"] == "Solve_Succeeded",
        "iterations": chosen["iterations"],
        "iterations_total": sum(run["iterations"] for run in runs),
        "start_cost": value(starts[0]),
        "starts_tried": len(runs),
        "best_start": best,
        "start_statuses": [run["status"] for run in runs],
        "start_costs": costs,
        "warnings": warnings,
    }


def solve_rotations(cost: RotationCost, start: list[np.ndarray], *, multistart: int = 0,
                    seed: int | None = None, ipopt_options: Mapping[str, Any] | None = None
                    ) -> tuple[list[np.ndarray], tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """Minimise |S r - s|^2 + rest of `cost` over k rotations (exactly SO(3)) with IPOPT from the
    rotations `start` (k of them) and ``multistart`` random starts: (rotations, their optimal
    translations t(r) in the units of `cost`, status, diagnostics as listed in `solve_casadi`
    without the problem's own entries). Raises SolverError when no start gave an iterate."""
    k = cost.rotations
    S, s = cost.S, cost.s
    weight = float(np.linalg.norm(S, 2)) ** 2  # sigma_max(S)^2: the NLP's Hessian is of order 1
    weight = weight if weight > 0 else 1.0
    p = np.concatenate([S.reshape(-1, order="F"), s]) / np.sqrt(weight)

    starts = [rotations_vector(*start)]
    if multistart:
        R = random_rotations(k * int(multistart), np.random.default_rng(seed))
        starts += [rotations_vector(*R[k * j:k * j + k]) for j in range(int(multistart))]

    solver = nlp_solver(ipopt_options, rotations=k)
    r_raw, status, diagnostics = run_starts(solver, starts, p, cost.value)
    Rs = [project_to_so3(M) for M in rotation_blocks(r_raw)]
    r = rotations_vector(*Rs)
    diagnostics.update(cost=cost.value(r), constraint_violation=_constraint_violation(r_raw),
                       orthonormality_error=float(max(orthonormality_error(R) for R in Rs)))
    return Rs, cost.translations(r), status, diagnostics


# --------------------------------------------------------------------------------------------
# AXB = YCZ: the lifted cost under exact SO(3) on R_X, R_Y, R_Z

N_BETA = lifted.N_BETA


def nlp_solver_axbycz(ipopt_options: Mapping[str, Any] | None = None):
    """The CasADi IPOPT `nlpsol` of ``axbycz`` (module docstring, AXB = YCZ point 1; x: v (36,);
    p: [vec N (column-major); g]; g: the 18 SO(3) equations), built once per IPOPT option set and
    cached."""
    return _cached("axbycz", _build_axbycz, ipopt_options)


def _build_axbycz(options: Mapping[str, Any]):
    import casadi as ca

    v = ca.MX.sym("v", 36)
    p = ca.MX.sym("p", N_BETA * N_BETA + N_BETA)
    N = ca.reshape(p[:N_BETA * N_BETA], N_BETA, N_BETA)
    g_vec = p[N_BETA * N_BETA:]
    x, y, z, tX, tY, tZ = v[0:9], v[9:18], v[18:27], v[27:30], v[30:33], v[33:36]
    beta = ca.vertcat(x, ca.reshape(ca.mtimes(y, z.T), 81, 1), tX, ca.reshape(ca.mtimes(y, tZ.T), 27, 1), y, tY)
    f = ca.dot(beta, ca.mtimes(N, beta)) - 2 * ca.dot(g_vec, beta)
    g = []
    for k in range(0, 27, 9):
        c1, c2, c3 = v[k:k + 3], v[k + 3:k + 6], v[k + 6:k + 9]
        g += [ca.dot(c1, c1) - 1, ca.dot(c2, c2) - 1, ca.dot(c1, c2), c3 - ca.cross(c1, c2)]
    return _nlpsol("lmi_sdp_axbycz_casadi", {"x": v, "p": p, "f": f, "g": ca.vertcat(*g)}, options)


def _lifted_beta(v: np.ndarray) -> np.ndarray:
    y = v[9:18]
    return np.concatenate([v[:9], np.outer(y, v[18:27]).ravel(order="F"), v[27:30],
                           np.outer(y, v[33:36]).ravel(order="F"), y, v[30:33]])


def _axbycz_start(data: AXBYCZData, rotations: tuple[np.ndarray, ...], unit: float) -> np.ndarray:
    t = lifted.solve_translations(data, *rotations)
    return np.concatenate([R.ravel(order="F") for R in rotations] + [t[0] / unit, t[1] / unit, t[2] / unit])


def solve_casadi_axbycz(data: AXBYCZData, *, normalize: bool, multistart: int = 0, seed: int | None = None,
                        ipopt_options: Mapping[str, Any] | None = None) -> SolverOutput:
    """Minimise the lifted cost of ``axbycz`` over SE(3)^3 with IPOPT (module docstring).

    data: validated `AXBYCZData` (at least 10 triples, rotations determined: the caller checks).
    normalize: the cost with translations divided by the data's RMS translation (unit invariant)
    or in the data's units. multistart (0 to 1000), seed (None or >= 0): extra random starts.
    Returns X, Y, Z exactly in SE(3), the chosen start's status and diagnostics as
    `solve_casadi` (``cost``: the lifted cost at the answer, normalised units when
    normalize). SolverError when no start gave an iterate.
    """
    check_starts(multistart, seed)
    unit = data.translation_scale
    scale = unit if normalize else 1.0
    N, g, ww = lifted.normal_equations(data, scale)
    D = np.ones(N_BETA)
    for block in (lifted.T_X, lifted.Q_YZ, lifted.T_Y):
        D[block] = unit / scale  # the NLP's translations in units of the RMS translation
    N, g = N * np.outer(D, D), g * D
    weight = float(np.linalg.eigvalsh(N)[-1]) or 1.0
    params = np.concatenate([N.ravel(order="F"), g]) / weight

    cost = lifted.LiftedCost.from_normal_equations(*lifted.normal_equations(data, scale))
    estimate = lifted.extract_rotations(lifted.sphere_least_squares(cost).x, cost)
    starts = [_axbycz_start(data, estimate.rotations, unit)]
    if multistart:
        R = random_rotations(3 * int(multistart), np.random.default_rng(seed))
        starts += [_axbycz_start(data, tuple(R[3 * j:3 * j + 3]), unit) for j in range(int(multistart))]

    def value(v: np.ndarray) -> float:
        b = _lifted_beta(v)
        return float(b @ N @ b - 2 * g @ b + ww)

    v_raw, status, diagnostics = run_starts(nlp_solver_axbycz(ipopt_options), starts, params, value)
    Rs = [project_to_so3(v_raw[k:k + 9].reshape(3, 3, order="F")) for k in (0, 9, 18)]
    v = np.concatenate([R.ravel(order="F") for R in Rs] + [v_raw[27:]])
    t = v[27:] * unit
    return SolverOutput(
        unknowns={"X": make_pose(Rs[0], t[:3]), "Y": make_pose(Rs[1], t[3:6]), "Z": make_pose(Rs[2], t[6:])},
        status=status,
        diagnostics={
            **diagnostics,
            "cost": value(v),
            "constraint_violation": _constraint_violation(v_raw[:27]),
            "orthonormality_error": float(max(orthonormality_error(R) for R in Rs)),
            "translation_scale": scale,
            "normalized": bool(normalize),
        },
    )
