"""`lmi-sdp`: the paper's method (Pan et al., IEEE T-ASE 2022, Sec. III.A, eqs. 5-14).

Method, as the paper has it:

1. Eqs. 5-8: A_i X = Y B_i written per pair as H_i beta = w_i (Kronecker product, column-major
   vec), stacked into H beta = w with beta = [vec R_X; vec R_Y; t_X; t_Y] (24,).
2. Eqs. 9-12: with the QR factorisation H = [Q1 Q2] [R1; 0] (eq. 10) the error of eq. 9 is
   |eps|^2 = |R1 beta - q1|^2 + rest, q1 = Q1^T w, rest = |Q2^T w|^2 (eq. 12). R1: (24, 24)
   upper triangular, computed once per data set in O(m) by `AXYBData.kronecker_system` (as the
   Cholesky factor of H^T H, equal to the R of the QR up to row signs: the same eq. 12).
3. Eqs. 13-14: with the bound u >= |eps|^2 (the paper writes u >= |eps|, but eq. 13 bounds the
   SQUARED norm, so u is the squared error), the Schur complement turns eq. 13 into the LMI

       minimise u  over (u, beta)  subject to  [[u - rest, (R1 beta - q1)^T],
                                                [R1 beta - q1,   I_24     ]]  >= 0      (eq. 14)

   a 25 x 25 linear matrix inequality. `rest` enters only as the constant subtracted from u in
   the top-left entry: it shifts the optimal u (u* = rest + |R1 beta* - q1|^2) and does not
   affect beta.
4. After eq. 14, the rotation blocks M_X = unvec beta[0:9], M_Y = unvec beta[9:18] are made
   rotations by Schmidt orthogonalisation (`handeye.se3.gram_schmidt`, columns in order).
   Translations are taken from beta (beta[18:24]) as they are: the paper re-solves them
   (eqs. 20-21) only in its iterative method (Sec. III.B), not in this one.

What the SDP computes: eq. 14 has no constraint beyond the Schur complement, which is exactly
u - rest >= |R1 beta - q1|^2. Its optimum is therefore u* = rest and beta* = R1^-1 q1, the
ordinary least-squares solution of eq. 8 (the same beta as `kron-lstsq`, and as OpenCV's
CALIB_ROBOT_WORLD_HAND_EYE_LI before its rotation normalisation). The SDP adds no information;
the method differs from `kron-lstsq` only in the Gram-Schmidt step and in keeping the
translations of beta. tests/test_lmi_sdp.py checks beta of every SDP backend against
`KroneckerSystem.least_squares`.

Numerics (the feasible set and the optimum are unchanged; docs/solvers/lmi-sdp.md has numbers):
- beta = D gamma with D = diag(1 / column norms of R1) (a change of variables), and the LMI
  multiplied by diag(1/c, I) on both sides (a congruence, which preserves >= 0) with
  c = max(sqrt(rest), 1e-6 |q1|), so that the optimal scaled u is 1 (or 0 for noise-free data);
  u is multiplied back by c^2. For Clarabel (both backends) c is capped at 1 (small problems are
  enlarged, large ones left alone: its criteria are absolute below 1 and relative above).
  Measured with every translation multiplied by 1e-6 ... 1e6, noisy and noise-free: beta equals
  the least squares to <= 3e-14 relative on clarabel, 6e-12 on cvxpy/Clarabel, 4e-15 on CVXOPT
  (picos). Without the cap Clarabel lost up to 1e-7 at 1e6; with the cap CVXOPT (picos) failed
  (status unknown) at 1e3; dividing by |q1| instead lost up to 8e-4 on Clarabel; no scaling
  (c = 1) lost 9e-6 at 1e-6.
- On the central path of an interior-point method, min u - mu log det(LMI) =
  u - mu log(u - rest - |R1 beta - q1|^2) is minimised in beta at R1 beta = q1 for every mu, so
  interior-point solvers return beta to ~1e-15 relative even though u is only as accurate as
  their tolerance (Clarabel: gap tolerances tightened to 1e-12, still 7-8 iterations).

Backends:
- ``clarabel`` (default): eq. 14 as above in Clarabel's own API, its constant structure built once
  per n (`handeye.plugins.lmi_sdp_clarabel`): ~0.8 ms per solve at n = 24, 2-3x faster than
  ``cvxpy`` with the same Clarabel and the same answer (docs/solvers/lmi-sdp.md).
- ``cvxpy``: solver ``cvxpy_solver`` (default Clarabel; any installed cvxpy solver that
  handles PSD constraints). The problem is built ONCE per cvxpy solver with R, q, rest as
  Parameters (DPP: after the first solve cvxpy skips canonicalisation and only re-applies the
  parameters) and cached at module level; a lock per cached problem serialises its solves.
- ``picos``: the same LMI through PICOS and CVXOPT. PICOS has no parameters for general
  constants, so its problem is rebuilt per call (13-20 ms per solve, ~10 ms of it CVXOPT).
- ``casadi``: NOT this LMI, the issue-4 extension: the eq. 8 cost under exact SO(3)
  constraints, solved by IPOPT (`handeye.plugins.lmi_sdp_casadi.solve_casadi`); its options
  ``multistart``, ``seed``, ``ipopt_options`` apply to it alone, ``cvxpy_solver`` to cvxpy alone
  (InputError otherwise). Its rotations are exactly in SO(3), so ``orthogonalize`` leaves them
  unchanged, and its translations are already the least squares given its rotations, so
  ``translations="resolve"`` gives the same.

Options: ``orthogonalize="gram-schmidt"`` (the paper's) or ``"svd"`` (nearest rotation,
`project_to_so3`); ``translations="beta"`` (the paper's) or ``"resolve"`` (eqs. 20-21 given the
orthogonalised rotations); ``normalize=False`` (the paper works in the data's units; the answer
then depends on the length unit, so `unit_invariant` says False for it). With
``normalize=True`` translations are divided by the data's RMS translation before eq. 8 is built
and multiplied back afterwards: the answer is unit invariant (tested to 1e-9). With
``normalize=True`` the translations in beta are poorly determined (the rotation rows dominate);
combine it with ``translations="resolve"``.

Problem ``axxb`` (A_i X = X B_i): a second spec, `SPEC_AXXB`, runs `handeye.plugins.lmi_sdp_axxb`:
the same cost with the scale constraint |vec R_X|^2 = 3 that AX = XB needs (its rotation rows are
homogeneous), as a tight SDP over a 10 x 10 Z; same backends and options, plus ``polish``
(docs/solvers/lmi-sdp.md, section AX = XB).

Problem ``axbycz`` (A_i X B_i = Y C_i Z): a third spec, `SPEC_AXBYCZ`, runs
`handeye.plugins.lmi_sdp_axbycz` on the lifted Kronecker system of
`handeye.problems.axbycz.kronecker`: the scale of the lifted rotations fixed by |r|^2 = 12 as a
tight SDP (default, from 10 triples) or eq. 14 as it is (``scale="translations"``, from 15
triples); its options and spec live there (`AXBYCZOptions`: defaults normalize=True,
translations="resolve").

Statuses: solver optimal -> optimal; optimal_inaccurate (Clarabel's AlmostSolved) ->
optimal_inaccurate; anything else (infeasible, unbounded, iteration limit, solver error) raises
`SolverError` naming the status.
On data whose translations are (near) zero eq. 8 cannot fix the scale of the rotations (its
rotation rows are homogeneous): a failure there raises `SolverError` saying so and naming
solver ``auto`` (`small_translations`), never a matrix of NaN.
"""

from __future__ import annotations

import dataclasses
import threading
import time
import warnings
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.estimation.kronecker import KroneckerSystem
from handeye.estimation.rotation_cost import signed_blocks
from handeye.framework.errors import DegenerateDataError, InputError, SolverError, shown
from handeye.framework.options import check_choice
from handeye.geometry.se3 import gram_schmidt, make_pose, project_to_so3
from handeye.plugins._cvxpy_solvers import (  # noqa: F401 (sdp_cvxpy_solvers re-exported)
    ProblemCache,
    check_backend_options,
    compile_seconds,
    resolve_cvxpy_solver,
    sdp_cvxpy_solvers,
)
from handeye.plugins.lmi_sdp_casadi import check_starts
from handeye.plugins.lmi_sdp_clarabel import SOLVER as CLARABEL
from handeye.plugins.lmi_sdp_clarabel import solve_eq14
from handeye.problems.axyb import AXYBData, solve_translations, split_beta

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
#: Settings per cvxpy solver (others run with their defaults). Clarabel: gap and feasibility
#: tolerances 1e-12 give u to ~1e-13 relative for 2 more iterations (beta is exact either way);
#: merge_method "none" keeps the chordal decomposition of the arrow-shaped LMI into 2x2 cliques
#: (1.5 ms instead of 2.5 ms per solve at the same accuracy; without decomposition: 40 ms).
CVXPY_SETTINGS: dict[str, dict[str, Any]] = {
    "CLARABEL": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12,
                 "tol_ktratio": 1e-10, "chordal_decomposition_merge_method": "none"},
    "SCS": {"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 100_000},
    "CVXOPT": {"abstol": 1e-10, "reltol": 1e-10},
}
#: cvxpy solver -> cap on the congruence scale c (`ScaledLMI.of`); others uncapped.
CVXPY_MAX_C: dict[str, float] = {"CLARABEL": 1.0}
#: CVXOPT through PICOS: gap tolerances 1e-10 (6 iterations); feasibility tolerances at their
#: defaults (at 1e-11 the dual residual stalls near 1e-9 and CVXOPT wanders). The iteration
#: limit matters: PICOS runs CVXOPT with its "chol" KKT solver and, when that ends with status
#: unknown, again with "ldl". On noise-free data in km (translations * 1e-6) "chol" never
#: converges, and with PICOS's default limit (10^6 iterations) it ran for minutes; with 50 the
#: "ldl" retry solves it in 6. Forcing "ldl" throughout fails on data in micrometres.
PICOS_SETTINGS: dict[str, Any] = {"abs_ipm_opt_tol": 1e-10, "rel_ipm_opt_tol": 1e-10,
                                  "max_iterations": 50}
#: RMS translation, in the units eq. 8 is built in (the data's; with normalize=True they are
#: divided by their RMS first), below which a failure of the method is put down to the
#: translations (`small_translations`). Measured on the paper's simulation (m = 10): noise-free
#: data solve on every backend down to an RMS of 1e-3; at 1e-4 Clarabel's solution is inaccurate,
#: at 1e-5 picos's fails the host's self-check, and from ~1e-10 eq. 8 is numerically rank
#: deficient; with noise and every translation 0 the SDP's rotation blocks are zero.
SMALL_TRANSLATION = 1e-3


@dataclasses.dataclass(frozen=True)
class Options:
    """orthogonalize: "gram-schmidt" | "svd"; translations: "beta" | "resolve";
    normalize: divide translations by the RMS translation first (unit invariance);
    cvxpy_solver: cvxpy only (default Clarabel); multistart (0 to 1000), seed (>= 0),
    ipopt_options: casadi only (see `handeye.plugins.lmi_sdp_casadi.solve_casadi`)."""

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
    optimality conditions after the SDP (the SDP backends; plugins/lmi_sdp_axxb.py)."""

    polish: bool = True


# --------------------------------------------------------------------------------------------
# eq. 14, scaled


@dataclasses.dataclass(frozen=True)
class ScaledLMI:
    """Eq. 14 in gamma = D^-1 beta, congruence diag(1/c, I) (module docstring, Numerics):

    [[u' - rest', (R gamma - q)^T], [R gamma - q, I]] >= 0 with R = R1 D / c: (n, n),
    q = q1 / c: (n,), rest' = rest / c^2, u = c^2 u'; d: (n,) the diagonal of D (n = 24 for
    ``axyb``, 132 for the lifted system of ``axbycz``).
    """

    R: np.ndarray
    q: np.ndarray
    rest: float
    d: np.ndarray
    c: float

    @classmethod
    def of(cls, system: KroneckerSystem, max_c: float = np.inf) -> ScaledLMI:
        """Scale eq. 14 of `system`: c = min(max_c, max(sqrt(rest), 1e-6 |q1|)) (or 1 if 0)."""
        norms = np.linalg.norm(system.R1, axis=0)
        d = 1.0 / np.where(norms > 0, norms, 1.0)
        c = min(max_c, max(float(np.sqrt(system.rest)), 1e-6 * float(np.linalg.norm(system.q1))))
        c = c if c > 0 else 1.0
        return cls(R=system.R1 * d / c, q=system.q1 / c, rest=system.rest / c**2, d=d, c=c)


@dataclasses.dataclass(frozen=True)
class SDPResult:
    gamma: np.ndarray  # (n,), scaled beta
    u: float  # scaled u
    status: Status
    solver_status: str
    backend_solver: str
    iterations: int | None
    compile_seconds: float = 0.0  # compiling the cvxpy problem (its first solve in a process)


def _status(solver_status: str, optimal: set[str], inaccurate: set[str], where: str,
            what: str = "the semidefinite program") -> Status:
    """The `Status` of an SDP solver's status; SolverError naming it for anything but optimal or
    inaccurate (`what`: the problem solved, for the message)."""
    if solver_status in optimal:
        return Status.OPTIMAL
    if solver_status in inaccurate:
        return Status.OPTIMAL_INACCURATE
    raise SolverError(f"lmi-sdp: {where} returned status {solver_status!r} for {what}; "
                      "no solution is returned")


# --------------------------------------------------------------------------------------------
# backend cvxpy: one DPP problem per cvxpy solver, compiled on its first solve, then reused


@dataclasses.dataclass
class CvxpyLMI:
    """The cached cvxpy problem of eq. 14 (parameters R, q, rest; variables gamma, u)."""

    problem: Any
    R: Any
    q: Any
    rest: Any
    gamma: Any
    u: Any
    lock: threading.Lock
    compiled: bool = False  # cvxpy compiles the problem on its first solve


def cvxpy_problem(solver: str, n: int = 24) -> CvxpyLMI:
    """Eq. 14 as a DPP cvxpy problem for cvxpy solver `solver` and n unknowns (24: ``axyb``;
    132: the lifted system of ``axbycz``), built once and cached (`CVXPY_CACHE`, key (solver, n))."""
    return CVXPY_CACHE.get(solver, n)


def _build_cvxpy_problem(solver: str, n: int) -> CvxpyLMI:
    import cvxpy as cp

    R = cp.Parameter((n, n), name="R")
    q = cp.Parameter(n, name="q")
    rest = cp.Parameter(nonneg=True, name="rest")
    gamma = cp.Variable(n, name="gamma")
    u = cp.Variable(name="u")
    e = R @ gamma - q  # R1 beta - q1, scaled
    lmi = cp.bmat([
        [cp.reshape(u - rest, (1, 1), order="F"), cp.reshape(e, (1, n), order="F")],
        [cp.reshape(e, (n, 1), order="F"), np.eye(n)],
    ])
    problem = cp.Problem(cp.Minimize(u), [lmi >> 0])
    if not problem.is_dpp():  # pragma: no cover - a cvxpy change would break the cache
        raise SolverError("lmi-sdp: the cvxpy formulation of the semidefinite program is not DPP")
    return CvxpyLMI(problem, R, q, rest, gamma, u, threading.Lock())


#: One problem per (cvxpy solver, number of unknowns) in this process.
CVXPY_CACHE = ProblemCache(_build_cvxpy_problem)


def _solve_cvxpy(lmi: ScaledLMI, solver: str) -> SDPResult:
    import cvxpy as cp

    cached = cvxpy_problem(solver, len(lmi.q))
    with cached.lock, warnings.catch_warnings():
        # "solution may be inaccurate" is the status optimal_inaccurate, reported as such
        warnings.simplefilter("ignore", UserWarning)
        cached.R.value = lmi.R
        cached.q.value = lmi.q
        cached.rest.value = lmi.rest
        start = time.perf_counter()
        try:
            cached.problem.solve(solver=solver, warm_start=False, **CVXPY_SETTINGS.get(solver, {}))
        except cp.error.SolverError as exc:
            raise SolverError(f"lmi-sdp: cvxpy/{solver} failed on the semidefinite program: {exc}") from None
        status = str(cached.problem.status)
        gamma, u = cached.gamma.value, cached.u.value
        iterations = cached.problem.solver_stats.num_iters
        setup = compile_seconds(cached, start)
    result_status = _status(status, {cp.OPTIMAL}, {cp.OPTIMAL_INACCURATE}, f"cvxpy/{solver}")
    if gamma is None or u is None:
        raise SolverError(f"lmi-sdp: cvxpy/{solver} reported {status!r} but gave no solution")
    return SDPResult(np.array(gamma, dtype=float), float(u), result_status, status, solver,
                     None if iterations is None else int(iterations), setup)


# --------------------------------------------------------------------------------------------
# backend picos (CVXOPT): built per call


def _solve_picos(lmi: ScaledLMI) -> SDPResult:
    import picos

    P = picos.Problem()
    gamma = picos.RealVariable("gamma", len(lmi.q))
    u = picos.RealVariable("u")
    e = picos.Constant("R", lmi.R) * gamma - picos.Constant("q", lmi.q)
    P.add_constraint(picos.block([[u - lmi.rest, e.T], [e, "I"]]) >> 0)
    P.set_objective("min", u)
    try:
        solution = P.solve(solver="cvxopt", primals=None, duals=False, **PICOS_SETTINGS)
    except picos.SolutionFailure as exc:
        raise SolverError(f"lmi-sdp: picos/cvxopt failed on the semidefinite program: {exc}") from None
    status = str(solution.claimedStatus)
    result_status = _status(status, {picos.modeling.solution.SS_OPTIMAL}, set(), "picos/cvxopt")
    if gamma.value is None or u.value is None:
        raise SolverError(f"lmi-sdp: picos/cvxopt reported {status!r} but gave no solution")
    raw = solution.info.get("cvxopt_sol", {}) if isinstance(solution.info, Mapping) else {}
    iterations = raw.get("iterations")
    return SDPResult(np.array(gamma.value, dtype=float).ravel(), float(u.value), result_status,
                     status, "cvxopt", None if iterations is None else int(iterations))


# --------------------------------------------------------------------------------------------


def solve_lmi(system: KroneckerSystem, backend: str, options: Options) -> tuple[np.ndarray, float, SDPResult]:
    """Solve eq. 14 for `system` on SDP backend "clarabel", "cvxpy" or "picos": (beta (n,), u, raw
    result)."""
    if backend == "cvxpy":
        solver = resolve_cvxpy_solver(options.cvxpy_solver)
        lmi = ScaledLMI.of(system, CVXPY_MAX_C.get(solver, np.inf))
        result = _solve_cvxpy(lmi, solver)
    elif backend == "clarabel":
        lmi = ScaledLMI.of(system, CVXPY_MAX_C["CLARABEL"])
        native = solve_eq14(lmi.R, lmi.q, lmi.rest)
        result = SDPResult(native.x[1:], float(native.x[0]), native.status, native.solver_status,
                           CLARABEL, native.iterations)
    elif backend == "picos":
        lmi = ScaledLMI.of(system)
        result = _solve_picos(lmi)
    else:
        raise ValueError(f"lmi-sdp: {backend!r} is not an SDP backend")
    beta = lmi.d * result.gamma
    if not np.all(np.isfinite(beta)):
        raise SolverError(f"lmi-sdp: {backend}/{result.backend_solver} returned a non-finite beta "
                          f"(status {result.solver_status!r})")
    return beta, result.u * lmi.c**2, result


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    """The paper's method on `data` (A, B: (m, 4, 4)); see the module docstring. A failure on
    data whose translations are (near) zero is reported as such (`small_translations`)."""
    check_backend_options("lmi-sdp", options, backend, BACKEND_ONLY_OPTIONS)
    if backend != "casadi" and not (np.any(data.A[:, :3, 3]) or np.any(data.B[:, :3, 3])):
        raise SolverError(small_translations(data, options.normalize))  # eq. 14's optimum is then beta = 0
    try:
        if backend == "casadi":
            return _run_casadi(data, options)
        return _run_sdp(data, options, backend)
    except (SolverError, DegenerateDataError):
        reason = small_translations(data, options.normalize)
        if reason is None:
            raise
        raise SolverError(reason) from None


def small_translations(data: AXYBData, normalize: bool) -> str | None:
    """Why the method failed, when the data's translations are (near) zero in the units eq. 8 is
    built in (RMS below `SMALL_TRANSLATION`), else None.

    Eq. 8's rotation rows are homogeneous (K_i vec R_X - vec R_Y = 0), so only its translation
    rows, through t_B, fix the scale of the rotation entries of beta, with a weight of order t^2
    in the normal equations. With translations (near) zero the least squares of eq. 8 tends to
    beta = 0 (rotation blocks that cannot be made rotations) or is rank deficient, whatever the
    rotations. A method under exact rotation constraints has no such trouble.
    """
    t = np.concatenate([data.A[:, :3, 3], data.B[:, :3, 3]])
    rms = float(np.sqrt(np.mean(np.sum(t * t, axis=1))))
    scale = data.translation_scale if normalize else 1.0
    if rms / scale >= SMALL_TRANSLATION:
        return None
    if rms == 0.0:
        seen, instead = "every translation of the data is zero", "solver 'auto'"
    else:
        seen = f"the translations of the data are all near zero (RMS {rms:.1e} in the data's unit)"
        instead = "solver 'auto'" if normalize else "solver 'auto' (or lmi-sdp with normalize=True)"
    return (f"lmi-sdp: {seen}, and the paper's method needs them to fix the scale of its rotation "
            f"estimates, so it cannot solve these data; use {instead}")


def _run_sdp(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    """Backends clarabel, cvxpy and picos: the LMI of eq. 14."""
    scale = data.translation_scale if options.normalize else 1.0
    system = data.kronecker(scale)
    beta, u, result = solve_lmi(system, backend, options)
    MX, MY, tX, tY = split_beta(beta)
    # beyond the paper: the sign of the blocks chosen by eq. 8's cost (`signed_blocks`; the
    # translations of beta belong to the other sign, so they are re-solved when it flips)
    _, flipped = signed_blocks(system, MX, MY, ORTHOGONALIZERS[options.orthogonalize])
    if flipped:
        MX, MY = -MX, -MY
    e = system.R1 @ beta - system.q1
    beta_out = beta.copy()
    beta_out[18:] *= scale
    beta_out.flags.writeable = False
    return SolverOutput(
        unknowns=_unknowns(data, dataclasses.replace(options, translations="resolve") if flipped else options,
                           MX, MY, tX * scale, tY * scale),
        status=result.status,
        diagnostics={
            "u": u,
            "rest": system.rest,
            "cost": float(e @ e + system.rest),
            "schur_complement": float(u - system.rest - e @ e),
            "solver_status": result.solver_status,
            "backend_solver": result.backend_solver,
            "iterations": result.iterations,
            "compile_seconds": result.compile_seconds,
            "sigma_min_R1": system.smallest_singular_value(),
            "beta": beta_out,
            "orthogonalize": options.orthogonalize,
            "translations": options.translations,
            "normalized": bool(options.normalize),
            "translation_scale": scale,
            "sign_flipped": flipped,
        },
    )


def _run_casadi(data: AXYBData, options: Options) -> SolverOutput:
    from handeye.plugins.lmi_sdp_casadi import solve_casadi

    out = solve_casadi(data, normalize=bool(options.normalize), multistart=options.multistart or 0,
                       seed=options.seed, ipopt_options=options.ipopt_options)
    X, Y = out.unknowns["X"], out.unknowns["Y"]
    diagnostics = dict(out.diagnostics)
    diagnostics.update(orthogonalize=options.orthogonalize, translations=options.translations)
    return SolverOutput(unknowns=_unknowns(data, options, X[:3, :3], Y[:3, :3], X[:3, 3], Y[:3, 3]),
                        status=out.status, diagnostics=diagnostics)


def _unknowns(data: AXYBData, options: Options, MX: np.ndarray, MY: np.ndarray, tX: np.ndarray,
              tY: np.ndarray) -> dict[str, np.ndarray]:
    """X, Y from rotation blocks MX, MY made rotations by ``options.orthogonalize`` and the
    translations tX, tY (data units), or with ``translations="resolve"`` translations re-solved
    given those rotations (eqs. 20-21)."""
    orthogonalize = ORTHOGONALIZERS[options.orthogonalize]
    with np.errstate(divide="ignore", invalid="ignore"):  # zero columns: NaN, refused below
        RX, RY = orthogonalize(MX), orthogonalize(MY)
    if not (np.all(np.isfinite(RX)) and np.all(np.isfinite(RY))):
        raise SolverError(f"lmi-sdp: a rotation estimate of the solution has a zero column (norms of the two "
                          f"estimates {np.linalg.norm(MX):.1e} and {np.linalg.norm(MY):.1e}), so it cannot be made a "
                          "rotation; use solver 'auto'")
    if options.translations == "resolve":
        tX, tY = solve_translations(data, RX, RY)
    return {"X": make_pose(RX, tX), "Y": make_pose(RY, tY)}


SPEC = SolverSpec(
    name="lmi-sdp",
    problems=("axyb",),
    run=run,
    backends={"clarabel": ("clarabel",), "cvxpy": ("cvxpy", "clarabel"), "picos": ("picos", "cvxopt"),
              "casadi": ("casadi",)},
    default_backend="clarabel",
    options=Options,
    summary="the paper's LMI-SDP (its optimum is the linear least squares of kron-lstsq), Gram-Schmidt; "
            "casadi: that least squares under exact SO(3)",
    citation="Pan et al., Toward Simultaneous Coordinate Calibrations of AX=YB Problem by the "
             "LMI-SDP Optimization, IEEE T-ASE 2022, eqs. 5-14",
    unit_invariant=lambda options: options.normalize,  # the paper-faithful default is not (docstring)
)


def run_axxb(data: Any, options: Options, backend: str) -> SolverOutput:
    """``axxb``: `handeye.plugins.lmi_sdp_axxb.run` (the LMI-SDP of AX=XB, |vec R_X|^2 = 3)."""
    from handeye.plugins.lmi_sdp_axxb import run as run_lmi_sdp_axxb

    return run_lmi_sdp_axxb(data, options, backend)


#: ``axxb``: the same cost, SDP lifted with the scale constraint |vec R_X|^2 = 3 (plugins/lmi_sdp_axxb.py),
#: the same options and backends.
SPEC_AXXB = dataclasses.replace(
    SPEC,
    problems=("axxb",),
    run=run_axxb,
    options=AXXBOptions,
    summary="the paper's LMI-SDP carried over to AX=XB: Kronecker cost with |vec R_X|^2 = 3 as a "
            "tight SDP (rank one), Gram-Schmidt; casadi: the cost under exact SO(3)",
    citation="Pan et al., IEEE T-ASE 2022, eqs. 5-14, carried over to AX=XB (docs/solvers/lmi-sdp.md)",
)


@hookimpl
def register_solvers(register):
    register(SPEC)
    register(SPEC_AXXB)
    from handeye.plugins.lmi_sdp_axbycz import SPEC_AXBYCZ  # it imports this module

    register(SPEC_AXBYCZ)
