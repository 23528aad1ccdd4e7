"""`so3-sdp`: the Kronecker cost of eq. 8 minimised under exact SO(3) constraints, with a
certificate of global optimality (a Shor relaxation of a QCQP, solved as an SDP).

Formulation (docs/solvers/so3-sdp.md has the details and the measurements):

1. Cost. eq. 8 reduced by QR (eqs. 10-12): |H beta - w|^2 = |R1 beta - q1|^2 + rest with
   beta = [r; t], r = [vec R_X; vec R_Y] (18), t = [t_X; t_Y] (6). A second QR of the 24 x 25
   matrix [R1_t | R1_r | q1] (translation columns first) gives
   |R1 beta - q1|^2 = |T t + U r - u|^2 + |S r - s|^2, so the translations are eliminated in
   closed form, t(r) = T^-1 (u - U r) (for given rotations these are exactly the least squares of
   eq. 4, i.e. eqs. 20-21), and the cost is |S r - s|^2 + rest = y^T M y + rest with y = [r; 1].
2. QCQP / relaxation. Constraints, for R = R_X and R = R_Y, written homogeneously in y (h = y_19):
   R^T R = h^2 I, R R^T = h^2 I (redundant), c_i x c_j = h c_k for the columns (cyclic; fixes
   det = +1), and h^2 = 1. The Shor relaxation: minimise <M, Z> over Z (19 x 19) PSD with
   <A_k, Z> = b_k. `redundant=False` keeps only R^T R = I and h^2 = 1 (a weaker relaxation, for
   studying tightness). Backends: `cvxpy` (Clarabel, or option ``cvxpy_solver``) poses its
   Lagrangian dual, max b^T nu with M - sum_k nu_k A_k PSD (41 unknowns, one PSD cone; Z is the
   cone's dual), built once per cvxpy solver with M a Parameter and cached; `picos` (cvxopt) the
   primal. Neither depends on m.
3. Extraction: the dominant eigenvector of Z scaled to h = 1, rotations projected onto SO(3), then
   (`polish=True`) Gauss-Newton on SO(3) x SO(3) for the same cost: this only removes the SDP
   solver's tolerance (~1e-7) from a point already in the basin of the global minimum.
4. Certificate: the SDP's dual multipliers nu are corrected (least squares) so that the
   stationarity condition S(nu) y = 0, S(nu) = M - sum_k nu_k A_k, holds exactly at the returned y;
   then for every feasible Z (trace Z = 7 for all of them) <M, Z> >= b^T nu + 7 min(0, lambda_min(S)),
   a lower bound on the global minimum that does not rely on the SDP solver's accuracy. The answer
   is `optimal` only when the eigenvalue ratio lambda_2 / lambda_1 of Z and the relative gap
   between the answer's cost and that bound are both below the thresholds below; otherwise it is
   `uncertified`, with the same numbers. Whichever SDP solver ran (a less accurate one such as
   SCS included), the status is decided by these numbers, never by the solver's own claim.

Normalisation (`normalize=True`, default): translations are divided by the data's RMS translation
first, which balances rotation and translation rows and makes the answer independent of the unit.
"""

from __future__ import annotations

import dataclasses
import functools
import threading
import time
import types
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import InputError, SolverError
from handeye.plugins._cvxpy_solvers import check_backend_options, compile_seconds, resolve_cvxpy_solver
from handeye.problems.axyb import AXYBData, KroneckerSystem
from handeye.se3 import make_pose, project_to_so3, rotation_angle, skew, so3_exp

#: Size of the homogenised variable y = [vec R_X; vec R_Y; 1] and the index of its last entry.
DIM = 19
HOM = 18
#: trace(Z) of every feasible Z (3 unit columns per rotation, plus Z_hh = 1).
TRACE_Z = 7.0

#: Certificate thresholds (chosen from the measurements in docs/solvers/so3-sdp.md: 1400 solves
#: at m = 3, simulated with noise 1x, 10x, 100x the accuracy study's and unrelated A, B).
#: lambda_2 / lambda_1 of the SDP solution: <= 1.3e-6 in every certified case, >= 0.18 when the
#: default (redundant) relaxation is not tight.
RATIO_THRESHOLD = 1e-3
#: (cost - certified lower bound) / max(cost, COST_FLOOR * |M|) must be below this: <= 3.1e-8
#: when certified, >= 8.9e-4 when not (also without the redundant constraints, where Z can be
#: rank one at a reflection: ratio ~1e-9, so only the gap shows it).
GAP_THRESHOLD = 1e-6
#: Costs below COST_FLOOR * |M|_F count as zero for the relative gap (noise-free data), where the
#: gap is only the float64 rounding of the eigenvalues of M (~1e-15 |M|).
COST_FLOOR = 1e-7

#: Gauss-Newton polish: stop when the step is below this (rad), or after POLISH_MAX_ITER steps.
POLISH_STEP_TOL = 1e-14
POLISH_MAX_ITER = 30
#: polish steps below this (rad) change the cost by less than its rounding: they are taken
#: without the cost test, which could only judge the rounding (and would make the answer depend
#: on it: unit invariance to ~1e-10 instead of ~1e-14).
POLISH_SMALL_STEP = 1e-9

#: Clarabel settings: a tiny dense problem, so no chordal decomposition, presolve or threads;
#: iterative refinement off and the dense "faer" factorisation (Clarabel >= 0.10; dropped
#: automatically when the installed Clarabel rejects it) each cut the time by about a third
#: (docs/solvers/so3-sdp.md) and cost nothing here, since the answer is polished and the
#: certificate is recomputed from the multipliers in float64. Read-only: a solve copies what it
#: passes, so no solve changes what the next one does.
CLARABEL_SETTINGS: Mapping[str, Any] = types.MappingProxyType({
    "chordal_decomposition_enable": False,
    "presolve_enable": False,
    "max_threads": 1,
    "iterative_refinement_enable": False,
    "direct_solve_method": "faer",
})
#: Settings per cvxpy solver (others run with their defaults). SCS (first order): at its default
#: eps 1e-4 only the polished answer is certified; at 1e-9 its own answer is too, for about twice
#: Clarabel's time (docs/solvers/so3-sdp.md, "Other cvxpy solvers").
CVXPY_SETTINGS: Mapping[str, Mapping[str, Any]] = types.MappingProxyType({
    "CLARABEL": CLARABEL_SETTINGS,
    "SCS": types.MappingProxyType({"eps_abs": 1e-9, "eps_rel": 1e-9, "max_iters": 100_000}),
})
#: option -> the backends it applies to (given with another backend it is an InputError)
BACKEND_ONLY_OPTIONS: dict[str, tuple[str, ...]] = {"cvxpy_solver": ("cvxpy",)}


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by their RMS first (unit invariance);
    redundant: add the redundant constraints (R R^T = I, column cross products) that make the
    relaxation tight; polish: Gauss-Newton on SO(3) after extraction to remove the SDP tolerance;
    cvxpy_solver: backend cvxpy only, an installed cvxpy solver that handles PSD cones (default
    Clarabel)."""

    normalize: bool = True
    redundant: bool = True
    polish: bool = True
    cvxpy_solver: str | None = None

    def __post_init__(self) -> None:
        if self.cvxpy_solver is not None and not isinstance(self.cvxpy_solver, str):
            raise InputError(f"option cvxpy_solver={self.cvxpy_solver!r} must be a cvxpy solver name (str)")


# --------------------------------------------------------------------------------------------
# 1. cost with translations eliminated


@dataclasses.dataclass(frozen=True)
class RotationCost:
    """eq. 8 with translations minimised out: |S r - s|^2 + rest, t(r) = T^-1 (u - U r).

    S: (18, 18) upper triangular, s: (18,), T: (6, 6) upper triangular, U: (6, 18), u: (6,),
    r = [vec R_X; vec R_Y] (column-major vec, as `split_beta`), t = [t_X; t_Y].
    """

    S: np.ndarray
    s: np.ndarray
    T: np.ndarray
    U: np.ndarray
    u: np.ndarray
    rest: float

    @functools.cached_property
    def matrix(self) -> np.ndarray:
        """M: (19, 19) PSD with y^T M y = |S r - s|^2 for y = [r; 1]."""
        G = np.concatenate([self.S, -self.s[:, None]], axis=1)
        return G.T @ G

    def value(self, r: np.ndarray) -> float:
        """The eq. 8 cost (translations at their optimum) of the rotations r: (18,)."""
        e = self.S @ r - self.s
        return float(e @ e + self.rest)

    def translations(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """t_X, t_Y minimising eq. 8 for the rotations r: (18,)."""
        from scipy.linalg import solve_triangular

        t = solve_triangular(self.T, self.u - self.U @ r, lower=False)
        return t[:3], t[3:]


def eliminate_translations(system: KroneckerSystem) -> RotationCost:
    """QR of [R1_t | R1_r | q1] (24 x 25): translations first, so they drop out in closed form."""
    R1, q1 = system.R1, system.q1
    R = np.linalg.qr(np.concatenate([R1[:, 18:], R1[:, :18], q1[:, None]], axis=1), mode="r")
    return RotationCost(S=R[6:24, 6:24].copy(), s=R[6:24, 24].copy(), T=R[:6, :6].copy(),
                        U=R[:6, 6:24].copy(), u=R[:6, 24].copy(), rest=system.rest)


def rotations_vector(RX: np.ndarray, RY: np.ndarray) -> np.ndarray:
    """r = [vec R_X; vec R_Y]: (18,), column-major vec."""
    return np.concatenate([RX.ravel(order="F"), RY.ravel(order="F")])


# --------------------------------------------------------------------------------------------
# 2. constraints of the QCQP and its relaxation

_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0


def _entry(offset: int, row: int, col: int) -> int:
    """Index in y of R[row, col] for the rotation stored at y[offset: offset + 9]."""
    return offset + 3 * col + row


@functools.cache
def constraint_matrices(redundant: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A: (K, 19, 19) symmetric and b: (K,) with y^T A_k y = b_k for y = [vec R_X; vec R_Y; 1],
    R_X, R_Y in SO(3). K = 41 with the redundant constraints, 13 without; linearly independent
    (interior-point solvers need that). Read-only arrays."""
    mats: list[np.ndarray] = []

    def quadratic(pairs: list[tuple[int, int, float]]) -> None:
        A = np.zeros((DIM, DIM))
        for p, q, c in pairs:
            A[p, q] += 0.5 * c
            A[q, p] += 0.5 * c
        mats.append(A)

    for off in (0, 9):
        for i in range(3):  # columns orthonormal: c_i . c_j = delta_ij h^2
            for j in range(i, 3):
                quadratic([(_entry(off, a, i), _entry(off, a, j), 1.0) for a in range(3)]
                          + ([(HOM, HOM, -1.0)] if i == j else []))
        if not redundant:
            continue
        for i in range(3):  # rows orthonormal: rho_i . rho_j = delta_ij h^2, except |rho_3|^2
            for j in range(i, 3):  # = h^2, which is implied (trace R^T R = trace R R^T)
                if i == j == 2:
                    continue
                quadratic([(_entry(off, i, a), _entry(off, j, a), 1.0) for a in range(3)]
                          + ([(HOM, HOM, -1.0)] if i == j else []))
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # handedness: c_i x c_j = h c_k
            for row in range(3):
                terms = [(_entry(off, a, i), _entry(off, b, j), _LEVI_CIVITA[row, a, b])
                         for a in range(3) for b in range(3) if _LEVI_CIVITA[row, a, b]]
                quadratic(terms + [(_entry(off, row, k), HOM, -1.0)])
    quadratic([(HOM, HOM, 1.0)])  # h^2 = 1
    A = np.stack(mats)
    b = np.zeros(len(mats))
    b[-1] = 1.0
    A.flags.writeable = False
    b.flags.writeable = False
    return A, b


# --------------------------------------------------------------------------------------------
# SDP backends: each returns (Z, nu, info) with nu such that S(nu) = M - sum_k nu_k A_k is the
# dual slack (PSD at the dual optimum) and b^T nu the dual objective.


@dataclasses.dataclass
class _CvxpyProblem:
    problem: Any
    M: Any  # cvxpy Parameter (19, 19), symmetric
    nu: Any  # cvxpy Variable (K,): the multipliers
    slack: Any  # the constraint M - sum_k nu_k A_k >> 0; its dual value is Z
    lock: threading.Lock
    compiled: bool = False  # cvxpy compiles the problem on its first solve


_CVXPY_PROBLEMS: dict[tuple[bool, str], _CvxpyProblem] = {}
_CVXPY_BUILD_LOCK = threading.Lock()
#: How many times a cvxpy problem was built (once per constraint set and cvxpy solver per process).
cvxpy_builds = 0


def cvxpy_problem(redundant: bool, solver: str) -> _CvxpyProblem:
    """The relaxation as a cvxpy problem with M a Parameter (DPP), built once per cvxpy `solver`
    and cached (cvxpy keeps one compiled program per problem, so a problem shared by two solvers
    would be recompiled at every switch).

    Posed in its dual (Lagrangian) form, max b^T nu s.t. M - sum_k nu_k A_k >= 0 (PSD), whose
    conic form has K = 41 variables and one 19 x 19 PSD cone instead of the 190 entries of Z plus
    41 equalities: about half the time per interior-point iteration. The Shor relaxation's Z is
    the dual variable of the PSD constraint (Clarabel and SCS are primal-dual: both come out of
    one solve).
    """
    global cvxpy_builds
    with _CVXPY_BUILD_LOCK:
        cached = _CVXPY_PROBLEMS.get((redundant, solver))
        if cached is not None:
            return cached
        import cvxpy as cp

        A, b = constraint_matrices(redundant)
        nu = cp.Variable(len(A))
        M = cp.Parameter((DIM, DIM), symmetric=True)
        A_cols = A.reshape(len(A), DIM * DIM).T  # (361, K); A_k symmetric: any vec order
        slack = M - cp.reshape(A_cols @ nu, (DIM, DIM), order="F") >> 0
        problem = cp.Problem(cp.Maximize(b @ nu), [slack])
        assert problem.is_dpp()
        cached = _CvxpyProblem(problem, M, nu, slack, threading.Lock())
        _CVXPY_PROBLEMS[(redundant, solver)] = cached
        cvxpy_builds += 1
        return cached


def _solve_with_settings(problem: Any, solver: str) -> None:
    """problem.solve with `solver` and a copy of its CVXPY_SETTINGS made for this call. An older
    Clarabel without the faer factorisation rejects the settings ("Bad settings: ...
    direct_solve_method"); this call then retries without that one setting. Nothing is
    remembered: every solve starts from the same settings, and without a warm start (cvxpy's
    default would start SCS from the previous solve's point, making an answer depend on what
    was solved before)."""
    settings = dict(CVXPY_SETTINGS.get(solver, {}))
    try:
        problem.solve(solver=solver, warm_start=False, **settings)
    except Exception as exc:
        if "direct_solve_method" not in str(exc) or settings.pop("direct_solve_method", None) is None:
            raise
        problem.solve(solver=solver, warm_start=False, **settings)


def _solve_cvxpy(M: np.ndarray, redundant: bool,
                 solver: str) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    import cvxpy as cp

    cached = cvxpy_problem(redundant, solver)
    with cached.lock, warnings.catch_warnings():
        # "solution may be inaccurate" is reported as sdp_status; the certificate decides
        warnings.simplefilter("ignore", UserWarning)
        cached.M.value = 0.5 * (M + M.T)
        start = time.perf_counter()
        try:
            _solve_with_settings(cached.problem, solver)
        except cp.error.SolverError as exc:
            raise SolverError(f"so3-sdp: cvxpy/{solver} failed on the relaxation: {exc}") from exc
        status = cached.problem.status
        Z = cached.slack.dual_value
        if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or Z is None or cached.nu.value is None:
            raise SolverError(f"so3-sdp: cvxpy/{solver} returned status {status!r} for the relaxation")
        Z = np.array(Z, dtype=float)
        nu = np.array(cached.nu.value, dtype=float)
        info = {"sdp_solver": solver, "sdp_status": status, "sdp_objective": float(cached.problem.value),
                "sdp_iterations": cached.problem.solver_stats.num_iters,
                "compile_seconds": compile_seconds(cached, start)}
    return Z, nu, info


def _solve_picos(M: np.ndarray, redundant: bool) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    import picos

    A, b = constraint_matrices(redundant)
    P = picos.Problem()
    Z = picos.SymmetricVariable("Z", (DIM, DIM))
    A_vec = picos.Constant("A", A.reshape(len(A), DIM * DIM))
    equality = P.add_constraint(A_vec * Z.vec == picos.Constant("b", b))
    P.add_constraint(Z >> 0)
    P.set_objective("min", picos.Constant("M", M) | Z)
    try:
        solution = P.solve(solver="cvxopt", primals=True, duals=True)
    except picos.SolutionFailure as exc:
        raise SolverError(f"so3-sdp: picos/cvxopt failed on the relaxation: {exc}") from exc
    if solution.claimedStatus != picos.modeling.solution.SS_OPTIMAL or Z.value is None:
        raise SolverError(f"so3-sdp: picos/cvxopt returned {solution.claimedStatus!r} for the relaxation")
    Zv = np.array(Z.value, dtype=float)
    # picos: the dual of an equality constraint is the multiplier with S = M - sum nu_k A_k
    nu = np.array(equality.dual, dtype=float).ravel()
    info = {"sdp_solver": "cvxopt", "sdp_status": str(solution.claimedStatus),
            "sdp_objective": float(P.value)}
    return Zv, nu, info


# --------------------------------------------------------------------------------------------
# 3. extraction and polish


def extract_rotations(Z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R_X, R_Y) from the dominant eigenvector of Z: (19, 19), projected onto SO(3); and the
    eigenvalues of Z in descending order."""
    eigenvalues, vectors = np.linalg.eigh(Z)
    v = vectors[:, -1]
    if abs(v[HOM]) < 1e-6 * np.max(np.abs(v)):
        raise SolverError("so3-sdp: the dominant eigenvector of the SDP solution has no "
                          "homogeneous component; the relaxation gives no rotation estimate")
    y = v / v[HOM]
    RX = project_to_so3(y[:9].reshape(3, 3, order="F"))
    RY = project_to_so3(y[9:18].reshape(3, 3, order="F"))
    return RX, RY, eigenvalues[::-1]


_GENERATORS = skew(np.eye(3))  # (3, 3, 3): [e_k]_x


def polish(cost: RotationCost, RX: np.ndarray, RY: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Gauss-Newton on SO(3) x SO(3) for |S r(R_X, R_Y) - s|^2, R <- R exp([d]_x).

    Returns the rotations and the number of accepted steps. A step is kept only if it does not
    increase the cost (or is below POLISH_SMALL_STEP, where the cost cannot tell), so the result
    is never worse than the start beyond rounding.
    """
    current = cost.value(rotations_vector(RX, RY))
    steps = 0
    for _ in range(POLISH_MAX_ITER):
        e = cost.S @ rotations_vector(RX, RY) - cost.s
        D = np.zeros((18, 6))
        D[:9, :3] = (RX @ _GENERATORS).transpose(0, 2, 1).reshape(3, 9).T  # vec(R [e_k]_x)
        D[9:, 3:] = (RY @ _GENERATORS).transpose(0, 2, 1).reshape(3, 9).T
        delta, *_ = np.linalg.lstsq(cost.S @ D, -e, rcond=None)
        RX_new, RY_new = RX @ so3_exp(delta[:3]), RY @ so3_exp(delta[3:])
        new = cost.value(rotations_vector(RX_new, RY_new))
        if new > current and np.max(np.abs(delta)) > POLISH_SMALL_STEP:
            break
        RX, RY, current = RX_new, RY_new, new
        steps += 1
        if np.max(np.abs(delta)) < POLISH_STEP_TOL:
            break
    return RX, RY, steps


# --------------------------------------------------------------------------------------------
# 4. certificate


def certificate(M: np.ndarray, y: np.ndarray, nu: np.ndarray, redundant: bool) -> dict[str, float]:
    """Lower bound on the global minimum of y^T M y from multipliers nu, made exact at y.

    M: (19, 19); y: (19,) feasible (rotations in SO(3), y_h = 1); nu: (K,) from the SDP's dual.
    nu is moved by the least-norm correction that makes S(nu) y = 0 (first-order optimality at y);
    then y'^T M y' = b^T nu + y'^T S y' >= b^T nu + 7 min(0, lambda_min(S)) for every feasible
    y' (indeed every feasible Z of the relaxation), while y^T M y = b^T nu + y^T S y.
    """
    A, b = constraint_matrices(redundant)
    L = np.einsum("kij,j->ik", A, y)  # (19, K): columns A_k y
    correction, *_ = np.linalg.lstsq(L, M @ y - L @ nu, rcond=None)
    nu = nu + correction
    S = M - np.einsum("k,kij->ij", nu, A)
    lam_min = float(np.linalg.eigvalsh(S)[0])
    value = float(y @ M @ y)
    lower = float(nu @ b + TRACE_Z * min(0.0, lam_min))
    # y is feasible, so the global minimum is <= value: a bound above it is rounding (~1e-15 |M|)
    return {"value": value, "lower_bound": min(lower, value), "dual_slack_min_eigenvalue": lam_min,
            "stationarity_residual": float(np.linalg.norm(S @ y))}


# --------------------------------------------------------------------------------------------


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    check_backend_options("so3-sdp", options, backend, BACKEND_ONLY_OPTIONS)
    solver = resolve_cvxpy_solver(options.cvxpy_solver) if backend == "cvxpy" else None
    scale = data.translation_scale if options.normalize else 1.0
    cost = eliminate_translations(data.kronecker(scale))
    M = cost.matrix
    norm = float(np.linalg.norm(M))
    if not np.isfinite(norm) or norm == 0.0:
        raise SolverError("so3-sdp: the cost matrix of eq. 8 is zero or not finite")

    if solver is not None:
        Z, nu, info = _solve_cvxpy(M / norm, options.redundant, solver)
    else:
        Z, nu, info = _solve_picos(M / norm, options.redundant)
    RX, RY, eig = extract_rotations(Z)
    ratio = float(eig[1] / eig[0])
    RX0, RY0 = RX, RY
    steps = 0
    if options.polish:
        RX, RY, steps = polish(cost, RX, RY)
    r = rotations_vector(RX, RY)
    y = np.append(r, 1.0)
    cert = certificate(M, y, nu * norm, options.redundant)

    total = cert["value"] + cost.rest
    gap = cert["value"] - cert["lower_bound"]
    relative_gap = gap / max(cert["value"], COST_FLOOR * norm)
    # The bound is recomputed in float64 from the multipliers, so it does not depend on how
    # accurately the SDP was solved: an "optimal_inaccurate" SDP can still certify.
    certified = ratio < RATIO_THRESHOLD and relative_gap < GAP_THRESHOLD
    status = Status.OPTIMAL if certified else Status.UNCERTIFIED

    tX, tY = cost.translations(r)
    polish_change = float(max(rotation_angle(RX0.T @ RX), rotation_angle(RY0.T @ RY)))
    diagnostics = {
        **info,
        "sdp_objective": info["sdp_objective"] * norm + cost.rest,
        "cost": total,
        "lower_bound": cert["lower_bound"] + cost.rest,
        "duality_gap": gap,
        "relative_gap": relative_gap,
        "eigenvalue_ratio": ratio,
        "eigenvalues": [float(v) for v in eig[:3]],
        "dual_slack_min_eigenvalue": cert["dual_slack_min_eigenvalue"],
        "stationarity_residual": cert["stationarity_residual"],
        "certified": certified,
        "thresholds": {"eigenvalue_ratio": RATIO_THRESHOLD, "relative_gap": GAP_THRESHOLD},
        "polish_steps": steps,
        "polish_rotation_change": polish_change,
        "cost_matrix_norm": norm,
        "translation_scale": scale,
        "redundant_constraints": options.redundant,
    }
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX * scale), "Y": make_pose(RY, tY * scale)},
        status=status,
        diagnostics=diagnostics,
    )


SPEC = SolverSpec(
    name="so3-sdp",
    problems=("axyb",),
    run=run,
    backends={"cvxpy": ("cvxpy", "clarabel"), "picos": ("picos", "cvxopt")},
    default_backend="cvxpy",
    options=Options,
    summary="eq. 8 under exact SO(3) constraints: tight SDP relaxation with optimality certificate",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8; relaxation and certificate as in Briales & "
             "Gonzalez-Jimenez, CVPR 2017, and Rosen et al., IJRR 2019",
    unit_invariant=lambda options: options.normalize,  # "Units" in docs/solvers/so3-sdp.md
)


@hookimpl
def register_solvers(register):
    register(SPEC)
