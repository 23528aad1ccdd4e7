"""`so3-sdp` for one pose per unknown: a Kronecker cost minimised under exact SO(3) constraints,
with a certificate of global optimality (a Shor relaxation of a QCQP, solved as an SDP). Problems
``axyb`` (eq. 8, two rotations) and ``axxb`` (A_i X = X B_i, one rotation); one spec per problem,
one pipeline (`solve_relaxation`, also used by `handeye.plugins.so3_sdp.multi`).

Formulation (docs/solvers/so3-sdp.md has the details and the measurements):

1. Cost (`handeye.estimation.rotation_cost`): the translations are minimised out in closed form,
   |H beta - w|^2 = |T t + U r - u|^2 + |S r - s|^2 + rest with r = [vec R_1; ...; vec R_k], so
   for given rotations t(r) = T^-1 (u - U r) are the translations' least squares (for ``axyb``
   eqs. 20-21) and the cost is y^T M y + rest with y = [r; 1]. ``axyb``: from the reduced system
   of eqs. 10-12 (`eliminate_translations`, a QR of [R1_t | R1_r | q1]), or from the normal
   equations when eq. 8 is rank deficient, which it is for translations all zero (its rotation
   rows are homogeneous) although the SO(3) problem is not; ``axxb``: from the normal
   equations (`RotationCost.from_normal_equations`), since its H may be rank deficient (a camera
   rotating about its own centre: docs/solvers/kron-lstsq.md) while the SO(3) problem is not.
2. QCQP / relaxation (`handeye.estimation.so3_relaxation`, shared for any number k of rotations):
   R^T R = h^2 I, R R^T = h^2 I (redundant), c_i x c_j = h c_k for the columns (cyclic; fixes
   det = +1), h^2 = 1. The Shor relaxation: minimise <M, Z> over Z (9k+1 square) PSD with
   <A_j, Z> = b_j. `redundant=False` keeps only R^T R = I and h^2 = 1 (a weaker relaxation, for
   studying tightness). Backends: `clarabel` (default) and `cvxpy` (Clarabel, or option
   ``cvxpy_solver``) pose its Lagrangian dual, max b^T nu with M - sum_j nu_j A_j PSD (20k + 1
   unknowns, one PSD cone; Z is the cone's dual). `clarabel` states it in Clarabel's own API
   (`handeye.plugins._sdp_backends.DualSDP`: the constant data built once per (constraint set,
   k) and cached, a solve only forms svec M), the same conic program cvxpy hands Clarabel without
   cvxpy's per-solve overhead (~3-4 ms a call); `cvxpy` builds it once per (constraint
   set, cvxpy solver, k) with M a Parameter; `picos` (cvxopt) the primal. None depends on m.
3. Extraction: the dominant eigenvector of Z scaled to h = 1, rotations projected onto SO(3), then
   (`polish=True`) Gauss-Newton on SO(3)^k for the same cost: this only removes the SDP solver's
   tolerance (~1e-7) from a point already in the basin of the global minimum.
4. Certificate: the SDP's dual multipliers nu are corrected (least squares) so that the
   stationarity condition S(nu) y = 0, S(nu) = M - sum_j nu_j A_j, holds exactly at the returned
   y; then for every feasible Z (trace Z = 3k + 1 for all of them)
   <M, Z> >= b^T nu + (3k + 1) min(0, lambda_min(S)), a lower bound on the global minimum that
   does not rely on the SDP solver's accuracy. The answer is `optimal` only when the eigenvalue
   ratio lambda_2 / lambda_1 of Z and the relative gap between the answer's cost and that bound
   are both below the thresholds of `handeye.estimation.so3_relaxation`; otherwise it is `uncertified`, with
   the same numbers. Whichever SDP solver ran (a less accurate one such as SCS included), the
   status is decided by these numbers, never by the solver's own claim.

Normalisation (`normalize=True`, default): translations are divided by the data's RMS translation
first, which balances rotation and translation rows and makes the answer independent of the unit.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status
from handeye.base.errors import DegenerateDataError, InputError, SolverError, shown
from handeye.estimation import camera_scale
from handeye.estimation.rotation_cost import (
    RotationCost,
    eliminate_translations,
    rotations_vector,
)
from handeye.estimation.so3_relaxation import (
    COST_FLOOR,
    GAP_THRESHOLD,
    RATIO_THRESHOLD,
    certificate,
    constraint_matrices,
    dimension,
    extract_rotations,
    is_certified,
    local_certificate,
    local_minimum,
    polish,
)
from handeye.geometry.linalg import frobenius_norm
from handeye.geometry.se3 import make_pose, rotation_angle
from handeye.plugins._sdp_backends import (
    SCS_TIGHT,
    CvxpyProblem,
    DualSDP,
    ProblemCache,
    check_backend_options,
    check_dpp,
    resolve_cvxpy_solver,
    solve_cvxpy,
    solve_picos,
)
from handeye.problems.axxb import AXXBData
from handeye.problems.axyb import AXYBData

#: Clarabel settings (backend clarabel, and backend cvxpy with its default solver): a tiny dense
#: problem, so no chordal decomposition, presolve or threads;
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
    "SCS": SCS_TIGHT,
})
#: option -> the backends it applies to (given with another backend it is an InputError)
BACKEND_ONLY_OPTIONS: dict[str, tuple[str, ...]] = {"cvxpy_solver": ("cvxpy",)}


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by their RMS first (unit invariance);
    redundant: add the redundant constraints (R R^T = I, column cross products) that make the
    relaxation tight; polish: Gauss-Newton on SO(3) after extraction to remove the SDP tolerance;
    cvxpy_solver: backend cvxpy only, an installed cvxpy solver that handles PSD cones (default
    Clarabel); local_first: solve the QCQP locally and certify that answer from its first-order
    conditions, solving the SDP only when the certificate fails (False: always the SDP)."""

    normalize: bool = True
    redundant: bool = True
    polish: bool = True
    cvxpy_solver: str | None = None
    local_first: bool = True

    def __post_init__(self) -> None:
        if self.cvxpy_solver is not None and not isinstance(self.cvxpy_solver, str):
            raise InputError(f"option cvxpy_solver={shown(self.cvxpy_solver)} must be a cvxpy solver name (str)")


# --------------------------------------------------------------------------------------------
# SDP backends: each returns (Z, nu, info) with nu such that S(nu) = M - sum_j nu_j A_j is the
# dual slack (PSD at the dual optimum) and b^T nu the dual objective.

def clarabel_problem(redundant: bool, rotations: int = 2) -> DualSDP:
    """The relaxation's Lagrangian dual for `rotations` rotations (2: ``axyb``, 1: ``axxb``) in
    Clarabel's form (`handeye.plugins._sdp_backends.DualSDP`): everything but M, built once per
    (constraint set, rotations) and cached (`CLARABEL_CACHE`). Immutable, so solves need no lock."""
    return CLARABEL_CACHE.get(redundant, rotations)


def _build_clarabel_problem(redundant: bool, rotations: int) -> DualSDP:
    return DualSDP.build(*constraint_matrices(rotations, redundant))


#: One Clarabel problem per (constraint set, number of rotations) in this process.
CLARABEL_CACHE = ProblemCache(_build_clarabel_problem)


def _solve_clarabel(M: np.ndarray, redundant: bool,
                    rotations: int) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The cvxpy backend's conic program, stated directly: the same Z and nu (bit-identical with
    Clarabel 0.11 and cvxpy 1.9), the same statuses (Solved: "optimal", AlmostSolved:
    "optimal_inaccurate", anything else a SolverError), the same settings."""
    sdp = clarabel_problem(redundant, rotations).solve(0.5 * (M + M.T), CLARABEL_SETTINGS, "so3-sdp")
    info = {"sdp_solver": "CLARABEL", "sdp_status": sdp.status, "sdp_objective": sdp.objective,
            "sdp_iterations": sdp.iterations,
            # nothing is compiled: building the constant data once takes < 1 ms
            "compile_seconds": 0.0}
    return sdp.Z, sdp.nu, info


@dataclasses.dataclass
class _CvxpyProblem(CvxpyProblem):
    M: Any  # cvxpy Parameter (9k+1, 9k+1), symmetric
    nu: Any  # cvxpy Variable (K,): the multipliers
    slack: Any  # the constraint M - sum_j nu_j A_j >> 0; its dual value is Z


def cvxpy_problem(redundant: bool, solver: str, rotations: int = 2) -> _CvxpyProblem:
    """The relaxation for `rotations` rotations (2: ``axyb``, 1: ``axxb``) as a cvxpy problem
    with M a Parameter (DPP), built once per cvxpy `solver` and cached (cvxpy keeps one compiled
    program per problem, so a problem shared by two solvers would be recompiled at every switch).

    Posed in its dual (Lagrangian) form, max b^T nu s.t. M - sum_j nu_j A_j >= 0 (PSD), whose
    conic form has K = 20k + 1 variables and one PSD cone instead of the entries of Z plus K
    equalities: about half the time per interior-point iteration. The Shor relaxation's Z is
    the dual variable of the PSD constraint (Clarabel and SCS are primal-dual: both come out of
    one solve).
    """
    return CVXPY_CACHE.get(redundant, solver, rotations)


def _build_cvxpy_problem(redundant: bool, solver: str, rotations: int) -> _CvxpyProblem:
    import cvxpy as cp

    A, b = constraint_matrices(rotations, redundant)
    dim = dimension(rotations)
    nu = cp.Variable(len(A))
    M = cp.Parameter((dim, dim), symmetric=True)
    A_cols = A.reshape(len(A), dim * dim).T  # (dim^2, K); A_j symmetric: any vec order
    slack = M - cp.reshape(A_cols @ nu, (dim, dim), order="F") >> 0
    problem = cp.Problem(cp.Maximize(b @ nu), [slack])
    return _CvxpyProblem(M, nu, slack, problem=check_dpp(problem, "so3-sdp", "the relaxation"))


#: One problem per (constraint set, cvxpy solver, number of rotations) in this process.
CVXPY_CACHE = ProblemCache(_build_cvxpy_problem)


def _solve_cvxpy(M: np.ndarray, redundant: bool, solver: str,
                 rotations: int) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The relaxation on cvxpy `solver` with its `CVXPY_SETTINGS` (an older Clarabel without faer:
    retried without it, `handeye.plugins._sdp_backends.solve_cvxpy`); "solution may be
    inaccurate" is reported as sdp_status, and the certificate decides."""
    import cvxpy as cp

    def read(cached: _CvxpyProblem) -> tuple[Any, np.ndarray | None, np.ndarray | None, Any]:
        Z, nu = cached.slack.dual_value, cached.nu.value
        return (cached.problem.status, None if Z is None else np.array(Z, dtype=float),
                None if nu is None else np.array(nu, dtype=float), cached.problem.value)

    (status, Z, nu, value), record = solve_cvxpy(
        cvxpy_problem(redundant, solver, rotations), solver, CVXPY_SETTINGS.get(solver, {}), {"M": 0.5 * (M + M.T)},
        read, "so3-sdp", "the relaxation", chain=True)
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or Z is None or nu is None:
        raise SolverError(f"so3-sdp: cvxpy/{solver} returned status {status!r} for the relaxation")
    info = {"sdp_solver": solver, "sdp_status": status, "sdp_objective": float(value),
            "sdp_iterations": record.iterations, "compile_seconds": record.compile_seconds}
    return Z, nu, info


def _solve_picos(M: np.ndarray, redundant: bool,
                 rotations: int) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    import picos

    A, b = constraint_matrices(rotations, redundant)
    dim = dimension(rotations)
    P = picos.Problem()
    Z = picos.SymmetricVariable("Z", (dim, dim))
    A_vec = picos.Constant("A", A.reshape(len(A), dim * dim))
    equality = P.add_constraint(A_vec * Z.vec == picos.Constant("b", b))
    P.add_constraint(Z >> 0)
    P.set_objective("min", picos.Constant("M", M) | Z)
    solution, _ = solve_picos(P, {}, "so3-sdp", "the relaxation", primals=True, duals=True, chain=True)
    if solution.claimedStatus != picos.modeling.solution.SS_OPTIMAL or Z.value is None:
        raise SolverError(f"so3-sdp: picos/cvxopt returned {solution.claimedStatus!r} for the relaxation")
    Zv = np.array(Z.value, dtype=float)
    # picos: the dual of an equality constraint is the multiplier with S = M - sum nu_j A_j
    nu = np.array(equality.dual, dtype=float).ravel()
    info = {"sdp_solver": "cvxopt", "sdp_status": str(solution.claimedStatus),
            "sdp_objective": float(P.value)}
    return Zv, nu, info


# --------------------------------------------------------------------------------------------


def solve_relaxation(cost: RotationCost, options: Options, backend: str, sdp_skipped: str | None = None
                     ) -> tuple[list[np.ndarray], tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """The pipeline of the module docstring for any number k of rotations: (rotations, the k
    translations t(r) in the units of `cost`, status, diagnostics). With ``local_first`` the
    local minimum is tried first and returned when its certificate holds (no SDP is solved).
    `sdp_skipped`: why the SDP is out of reach (too large to solve): the local minimum is then
    the answer, `uncertified` unless its certificate holds, with that reason in the diagnostics
    (``sdp_skipped``); None (default) solves the SDP whenever the local certificate fails."""
    check_backend_options("so3-sdp", options, backend, BACKEND_ONLY_OPTIONS)
    solver = resolve_cvxpy_solver(options.cvxpy_solver) if backend == "cvxpy" else None
    k = cost.rotations
    M = cost.matrix
    norm = frobenius_norm(M)
    if not np.isfinite(norm) or norm == 0.0:
        raise SolverError("so3-sdp: the cost matrix built from the poses is zero or not finite")

    local: dict[str, Any] = {}
    if options.local_first or sdp_skipped is not None:
        Rs, local = _local(cost, norm)
        if local["certified"]:
            return Rs, cost.translations(rotations_vector(*Rs)), Status.OPTIMAL, local
        if sdp_skipped is not None:
            if not Rs:
                raise SolverError(f"so3-sdp: the local solve failed numerically and the SDP is out of reach "
                                  f"({sdp_skipped})")
            return (Rs, cost.translations(rotations_vector(*Rs)), Status.UNCERTIFIED,
                    {**local, "sdp_skipped": sdp_skipped})

    if backend == "clarabel":
        Z, nu, info = _solve_clarabel(M / norm, options.redundant, k)
    elif solver is not None:
        Z, nu, info = _solve_cvxpy(M / norm, options.redundant, solver, k)
    else:
        Z, nu, info = _solve_picos(M / norm, options.redundant, k)
    Rs, eig = extract_rotations(Z, k)
    ratio = float(eig[1] / eig[0])
    start = Rs
    steps = 0
    if options.polish:
        Rs, steps = polish(cost, Rs)
    y = np.append(rotations_vector(*Rs), 1.0)
    cert = certificate(M, y, nu * norm, options.redundant)
    # The bound is recomputed in float64 from the multipliers, so it does not depend on how
    # accurately the SDP was solved: an "optimal_inaccurate" SDP can still certify.
    diagnostics = {
        "certificate_path": "sdp",
        **info,
        "sdp_objective": info["sdp_objective"] * norm + cost.rest,
        **_certificate_figures(cert, ratio, cost.rest, norm),
        "eigenvalues": [float(v) for v in eig[:3]],
        "polish_steps": steps,
        "polish_rotation_change": float(max(rotation_angle(R0.T @ R) for R0, R in zip(start, Rs))),
        "cost_matrix_norm": norm,
        "redundant_constraints": options.redundant,
    }
    if local:
        diagnostics["local_certificate"] = {key: local[key] for key in
                                            ("relative_gap", "dual_slack_min_eigenvalue", "cost")}
    status = Status.OPTIMAL if diagnostics["certified"] else Status.UNCERTIFIED
    return Rs, cost.translations(y[:-1]), status, diagnostics


def _local(cost: RotationCost, norm: float) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The local minimum of the QCQP and its certificate from the first-order conditions
    (`handeye.estimation.so3_relaxation.local_minimum`, `local_certificate`): (rotations, diagnostics with
    "certified"). A local solve that fails numerically is reported as not certified."""
    root = np.sqrt(norm)  # the cost divided by |M| (as the SDP's): entries of M may pass 1e154
    try:
        Rs, steps = local_minimum(RotationCost(S=cost.S / root, s=cost.s / root, T=cost.T, U=cost.U, u=cost.u,
                                               rest=cost.rest))  # as dataclasses.replace, without its ~4 us
    except (np.linalg.LinAlgError, InputError):  # the SDP decides
        return [], {"certified": False, "relative_gap": float("nan"), "dual_slack_min_eigenvalue": float("nan"),
                    "cost": float("nan")}
    y = np.append(rotations_vector(*Rs), 1.0)
    cert = local_certificate(cost.matrix / norm, y)
    cert = {key: value * norm for key, value in cert.items()}  # each scales with M
    # Z = y y^T: rank one by construction, so only the gap decides
    return Rs, {"certificate_path": "local", **_certificate_figures(cert, 0.0, cost.rest, norm),
                "polish_steps": steps, "cost_matrix_norm": norm, "redundant_constraints": False}


def _certificate_figures(cert: Mapping[str, float], ratio: float, rest: float, norm: float) -> dict[str, Any]:
    """The certificate's diagnostics (both paths): costs with `rest` added back, gaps, status."""
    gap = cert["value"] - cert["lower_bound"]
    relative_gap = gap / max(cert["value"], COST_FLOOR * norm)
    return {
        "cost": cert["value"] + rest,
        "lower_bound": cert["lower_bound"] + rest,
        "duality_gap": gap,
        "relative_gap": relative_gap,
        "eigenvalue_ratio": ratio,
        "dual_slack_min_eigenvalue": cert["dual_slack_min_eigenvalue"],
        "certificate_margin": cert["certificate_margin"],
        "stationarity_residual": cert["stationarity_residual"],
        "certified": is_certified(ratio, relative_gap),
        "thresholds": {"eigenvalue_ratio": RATIO_THRESHOLD, "relative_gap": GAP_THRESHOLD},
    }


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    """``axyb``: eq. 8 over SO(3) x SO(3) (module docstring)."""
    if data.camera_scale_unknown:
        return _unknown_scale(data, options, backend, run)
    scale = data.translation_scale if options.normalize else 1.0
    try:
        cost = eliminate_translations(data.kronecker(scale))
    except DegenerateDataError:  # e.g. translations all zero (module docstring, item 1)
        cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=2)
    (RX, RY), (tX, tY), status, diagnostics = solve_relaxation(cost, options, backend)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX * scale), "Y": make_pose(RY, tY * scale)},
        status=status,
        diagnostics={**diagnostics, "translation_scale": scale},
    )


def run_axxb(data: AXXBData, options: Options, backend: str) -> SolverOutput:
    """``axxb``: the Kronecker cost of A_i X = X B_i over SO(3) (module docstring)."""
    if data.camera_scale_unknown:
        return _unknown_scale(data, options, backend, run_axxb)
    scale = data.translation_scale if options.normalize else 1.0
    cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)
    (RX,), (tX,), status, diagnostics = solve_relaxation(cost, options, backend)
    return SolverOutput(unknowns={"X": make_pose(RX, tX * scale)}, status=status,
                        diagnostics={**diagnostics, "translation_scale": scale})


def _unknown_scale(data: Any, options: Options, backend: str, solve: Any) -> SolverOutput:
    """Camera translations known only up to scale (`handeye.estimation.camera_scale`): the rotations
    certified on the rotation rows alone (the data with every translation zero), then the
    translations and the camera's scale by linear least squares given them."""
    rotations = solve(camera_scale.rotation_only(data), options, backend)
    poses, s = camera_scale.translations_and_scale(data.pose_model, tuple(rotations.unknowns.values()))
    if not s > 0.0:
        raise DegenerateDataError(f"the camera's scale fitted to these poses is {s:.3g}, not positive: the camera's "
                                  "translations do not match the robot's motion (check the pairing and the setup)")
    return SolverOutput(unknowns=dict(zip(rotations.unknowns, poses)), status=rotations.status,
                        diagnostics={**rotations.diagnostics, "camera_scale": s,
                                     "formulation": "rotations from the rotation rows alone (the camera's scale unknown), "
                                                    "then translations and scale by linear least squares"})


SPEC = SolverSpec(
    name="so3-sdp",
    problems=("axyb",),
    run=run,
    backends={"clarabel": ("clarabel",), "cvxpy": ("cvxpy", "clarabel"), "picos": ("picos", "cvxopt")},
    default_backend="clarabel",
    options=Options,
    summary="the linear least squares of kron-lstsq under exact SO(3) constraints: tight SDP relaxation with optimality certificate",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8; relaxation and certificate as in Briales & "
             "Gonzalez-Jimenez, CVPR 2017, and Rosen et al., IJRR 2019",
    unit_invariant=lambda options: options.normalize,  # "Units" in docs/solvers/so3-sdp.md
    camera_scale_mode=True,
)

#: The same solver for ``axxb`` (one rotation): same backends, options and certificate.
SPEC_AXXB = dataclasses.replace(
    SPEC,
    problems=("axxb",),
    run=run_axxb,
    summary="the Kronecker cost of AX=XB under exact SO(3) constraints: tight SDP relaxation "
            "with optimality certificate",
    citation="Heller, Havlena, Pajdla, ICRA 2014; Giamou et al., RA-L 2019; certificate as in "
             "Rosen et al., IJRR 2019",
)

