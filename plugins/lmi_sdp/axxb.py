"""`lmi-sdp` for ``axxb`` (A_i X = X B_i): the paper's LMI-SDP carried over to AX = XB.
`handeye.plugins.lmi_sdp` registers its ``axxb`` spec with `run`.

The paper's eq. 14 minimises |H beta - w|^2 with no constraint: for ``axyb`` its optimum is the
least squares of eq. 8. For ``axxb`` the rotation rows (R_B kron R_A - I) vec R_X = 0 are
homogeneous, so the same SDP would return beta = 0 plus whatever scale the translation rows
give, and nothing when all motions rotate about one point (docs/solvers/kron-lstsq.md). The cost
is therefore kept and the scale fixed as `kron-lstsq` fixes it, |r|^2 = 3 (r = vec R_X):

1. Translations minimised out in closed form (`handeye.estimation.rotation_cost`, from the normal equations
   of problems/axxb/data.py): |H beta - w|^2 = |T t + U r - u|^2 + y^T M y + rest, y = [r; 1],
   M = [[P, -p], [-p^T, c]] (10 x 10, PSD), t(r) = T^-1 (u - U r).
2. The QCQP min y^T M y s.t. |r|^2 = 3, h^2 = 1 lifted to Z = y y^T: the SDP

       minimise <M, Z>  over Z = [[W, r], [r^T, h]] PSD (10 x 10)
       subject to  trace W = 3,  Z_hh = 1,

   a Shor relaxation with one quadratic constraint besides the homogenisation, which the S-lemma
   makes tight (equality-constrained trust region: Polyak 1998; Ye & Zhang 2003): its optimum
   equals the QCQP's, attained by a rank-one Z = [r*; 1][r*; 1]^T, r* the trust-region solution
   of `kron-lstsq` (measured on noisy data: eigenvalue ratio <= 1e-9, the SDP's r within 6e-7
   (Clarabel) / 5e-6 (CVXOPT) of r*; docs/solvers/lmi-sdp.md).
3. Extraction: the dominant eigenvector of Z scaled to h = 1. When Z has rank two (eigenvalue
   ratio >= `RANK_TWO_RATIO`), the trust-region hard case: both r0 +- tau v are optimal, with
   r0 = Z[:9, 9], v the dominant eigenvector of W - r0 r0^T and tau^2 = 3 - |r0|^2
   (Z = (Z_+ + Z_-) / 2, both rank one and optimal). In every case r and -r are told apart by
   `signed_rotations` (the lower cost after orthogonalisation).
4. Polish (option ``polish``, default True): the SDP solvers return r only to ~1e-7 (Clarabel)
   or ~1e-6 (CVXOPT): r lies on the boundary of the PSD cone, where the objective is flat to
   second order, so an objective accurate to epsilon places r to ~sqrt(epsilon) (measured in
   docs/solvers/lmi-sdp.md). A few Newton steps on the optimality system (P - lambda I) r = p,
   |r|^2 = 3 from the SDP's r (`handeye.estimation.trust_region.refine_trust_region`) take it to the
   minimiser to rounding, and check the global conditions (lambda <= lambda_min(P)): when they
   hold the status is ``optimal`` whatever the SDP solver's own claim (Clarabel often says
   "optimal_inaccurate" at the tolerances used); otherwise the SDP solver's status stands and
   the unpolished r is kept. ``polish=False`` returns the SDP's own r.
5. Then as the paper does for ``axyb``: R_X = ``orthogonalize``(unvec r) (Gram-Schmidt by
   default), t_X = t(r) of r (``translations="beta"``, the paper's: the translation part of the
   optimal beta) or re-solved given R_X (``"resolve"``).

Backends: ``clarabel`` (default; the SDP in Clarabel's own API, its constant data built once:
`handeye.plugins.lmi_sdp.clarabel.solve_axxb`), ``cvxpy`` (the SDP built once per cvxpy solver
with M a Parameter, DPP, cached here), ``picos`` (CVXOPT, built per call); ``casadi`` is
`handeye.plugins.lmi_sdp.casadi.solve_casadi_axxb` (exact SO(3), IPOPT; ``polish`` does not
apply). Options: those of `lmi-sdp` (`handeye.plugins.lmi_sdp.Options`) plus ``polish``
(`handeye.plugins.lmi_sdp.AXXBOptions`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import SolverOutput, Status
from handeye.base.errors import SolverError
from handeye.estimation.rotation_cost import RotationCost, signed_rotations
from handeye.estimation.trust_region import refine_trust_region
from handeye.geometry.linalg import frobenius_norm
from handeye.geometry.se3 import make_pose
from handeye.plugins._sdp_backends import (
    CvxpyProblem,
    ProblemCache,
    SolveRecord,
    check_backend_options,
    check_dpp,
    resolve_cvxpy_solver,
    solve_cvxpy,
    solve_picos,
)
from handeye.plugins.lmi_sdp.casadi import solve_casadi_axxb
from handeye.plugins.lmi_sdp.clarabel import solve_axxb
from handeye.plugins.lmi_sdp.common import (
    BACKEND_ONLY_OPTIONS,
    CVXPY_SETTINGS,
    ORTHOGONALIZERS,
    PICOS_SETTINGS,
    POLISH_NOT_CERTIFIED,
    AXXBOptions,
    check_finite,
    polish_figures,
    record_figures,
    sdp_status,
)
from handeye.problems.axxb import AXXBData, solve_translation

#: Eigenvalue ratio lambda_2 / lambda_1 of Z above which Z counts as rank two (the trust-region
#: hard case, point 3 of the module docstring). Measured: <= 1e-9 on simulated data with
#: Clarabel and CVXOPT, 1/3 in the hard case (W = 3 v v^T, r0 = 0).
RANK_TWO_RATIO = 1e-3
#: What the SDP is, for error messages (`FAILED_ON`: when its solver fails).
WHAT = "the semidefinite program of AX=XB"
FAILED_ON = "the SDP of AX=XB"


@dataclasses.dataclass(frozen=True)
class SDPResult:
    Z: np.ndarray  # (10, 10)
    value: float  # <M, Z> of the scaled M
    status: Status
    record: SolveRecord


# --------------------------------------------------------------------------------------------
# backend cvxpy: one DPP problem per cvxpy solver, compiled on its first solve, then reused


@dataclasses.dataclass
class CvxpySDP(CvxpyProblem):
    """The cached cvxpy problem (parameter M (10, 10); variable Z (10, 10) PSD)."""

    M: Any
    Z: Any


def cvxpy_problem(solver: str) -> CvxpySDP:
    """The SDP of the module docstring as a DPP cvxpy problem for cvxpy `solver`, built once
    (`CVXPY_CACHE`)."""
    return CVXPY_CACHE.get(solver)


def _build_cvxpy_problem(solver: str) -> CvxpySDP:
    import cvxpy as cp

    M = cp.Parameter((10, 10), symmetric=True, name="M")
    Z = cp.Variable((10, 10), PSD=True, name="Z")
    problem = cp.Problem(cp.Minimize(cp.trace(M @ Z)), [cp.trace(Z[:9, :9]) == 3, Z[9, 9] == 1])
    return CvxpySDP(M, Z, problem=check_dpp(problem, "lmi-sdp", "the AX=XB SDP"))


#: One problem per cvxpy solver in this process.
CVXPY_CACHE = ProblemCache(_build_cvxpy_problem)


def _solve_cvxpy(M: np.ndarray, solver: str) -> SDPResult:
    # "solution may be inaccurate" is the status optimal_inaccurate; the polish decides
    (Z, value), record = solve_cvxpy(cvxpy_problem(solver), solver, CVXPY_SETTINGS.get(solver, {}),
                                     {"M": 0.5 * (M + M.T)}, lambda cached: (cached.Z.value, cached.problem.value),
                                     "lmi-sdp", FAILED_ON)
    status = sdp_status("cvxpy", record, Z is not None, WHAT)
    return SDPResult(np.array(Z, dtype=float), float(value), status, record)


# --------------------------------------------------------------------------------------------
# backend picos (CVXOPT): built per call


def _solve_picos(M: np.ndarray) -> SDPResult:
    import picos

    P = picos.Problem()
    Z = picos.SymmetricVariable("Z", (10, 10))
    P.add_constraint(Z >> 0)
    P.add_constraint(picos.trace(Z[:9, :9]) == 3)
    P.add_constraint(Z[9, 9] == 1)
    P.set_objective("min", picos.Constant("M", 0.5 * (M + M.T)) | Z)
    _, record = solve_picos(P, PICOS_SETTINGS, "lmi-sdp", FAILED_ON)
    status = sdp_status("picos", record, Z.value is not None, WHAT)
    return SDPResult(np.array(Z.value, dtype=float), float(P.value), status, record)


# --------------------------------------------------------------------------------------------


def solve_sdp(cost: RotationCost, backend: str, cvxpy_solver: str | None = None) -> tuple[np.ndarray, SDPResult, float]:
    """The SDP for `cost` (one rotation) on backend "clarabel", "cvxpy" or "picos": (Z (10, 10), raw
    result, |M|_F, the scale M was divided by for the solver)."""
    M = cost.matrix
    norm = frobenius_norm(M)
    if not np.isfinite(norm) or norm == 0.0:
        raise SolverError("lmi-sdp: the cost matrix built from the motions is zero or not finite")
    if backend == "cvxpy":
        result = _solve_cvxpy(M / norm, resolve_cvxpy_solver(cvxpy_solver))
    elif backend == "clarabel":
        Z, value, native = solve_axxb(0.5 * (M + M.T) / norm, WHAT)
        result = SDPResult(Z, value, native.status, native.record)
    elif backend == "picos":
        result = _solve_picos(M / norm)
    else:
        raise ValueError(f"lmi-sdp: {backend!r} is not an SDP backend")
    check_finite(backend, result.record, "Z", result.Z)
    return result.Z, result, norm


def extract(Z: np.ndarray) -> tuple[list[np.ndarray], float]:
    """Candidates for r (9,) from the SDP solution Z (module docstring, point 3): one (the
    dominant eigenvector scaled to h = 1) when Z is rank one, else the two r0 +- tau v; and the
    eigenvalue ratio lambda_2 / lambda_1 of Z."""
    eigenvalues, vectors = np.linalg.eigh(0.5 * (Z + Z.T))
    ratio = float(eigenvalues[-2] / eigenvalues[-1]) if eigenvalues[-1] > 0 else np.inf
    if ratio < RANK_TWO_RATIO:
        v = vectors[:, -1]
        if abs(v[9]) < 1e-6 * np.max(np.abs(v)):
            raise SolverError("lmi-sdp: the dominant eigenvector of the SDP solution has no "
                              "homogeneous component; the SDP gives no rotation estimate")
        return [v[:9] / v[9]], ratio
    r0 = Z[:9, 9] / Z[9, 9]
    E = Z[:9, :9] - np.outer(r0, r0)
    v = np.linalg.eigh(0.5 * (E + E.T))[1][:, -1]
    tau = np.sqrt(max(3.0 - float(r0 @ r0), 0.0))
    return [r0 + tau * v, r0 - tau * v], ratio


def run(data: AXXBData, options: AXXBOptions, backend: str) -> SolverOutput:
    """`lmi-sdp` on ``axxb`` data (module docstring)."""
    check_backend_options("lmi-sdp", options, backend, BACKEND_ONLY_OPTIONS)
    if backend == "casadi":
        return _run_casadi(data, options)
    scale = data.translation_scale if options.normalize else 1.0
    cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)
    Z, result, norm = solve_sdp(cost, backend, options.cvxpy_solver)
    candidates, ratio = extract(Z)
    orthogonalize = ORTHOGONALIZERS[options.orthogonalize]
    # each candidate and its negative (signed_rotations); the lowest cost after orthogonalising
    choices = []
    for r in candidates:
        (R,), flipped = signed_rotations(cost, r, orthogonalize)
        choices.append((cost.value(R.ravel(order="F")), -r if flipped else r, flipped))
    _, r_sdp, flipped = min(choices, key=lambda choice: choice[0])
    r, status, polished = r_sdp, result.status, None
    if options.polish:
        P, p, _ = cost.quadratic
        polished = refine_trust_region(P, p, np.sqrt(3.0), r_sdp)
        if polished.global_optimum:
            r, status = polished.x, Status.OPTIMAL
    RX = orthogonalize(r.reshape(3, 3, order="F"))
    (t_r,) = cost.translations(r)
    tX = t_r * scale if options.translations == "beta" else solve_translation(data, RX)
    beta = np.concatenate([r, t_r * scale])
    beta.flags.writeable = False
    notes = []
    if polished is not None and not polished.global_optimum:
        notes.append(POLISH_NOT_CERTIFIED)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX)},
        status=status,
        diagnostics={
            "sdp_objective": result.value * norm + cost.rest,
            "cost": cost.value(r),
            "eigenvalue_ratio": ratio,
            "rank_two": len(candidates) == 2,
            "sign_flipped": flipped,
            "sdp_r": r_sdp,
            **polish_figures(polished, r_sdp),
            **record_figures(result.record, sdp_status=str(result.status)),
            "beta": beta,
            "orthogonalize": options.orthogonalize,
            "translations": options.translations,
            "normalized": bool(options.normalize),
            "translation_scale": scale,
            "warnings": notes,
        },
    )


def _run_casadi(data: AXXBData, options: AXXBOptions) -> SolverOutput:
    out = solve_casadi_axxb(data, normalize=bool(options.normalize), multistart=options.multistart or 0,
                            seed=options.seed, ipopt_options=options.ipopt_options)
    diagnostics = dict(out.diagnostics)
    diagnostics.update(orthogonalize=options.orthogonalize, translations=options.translations)
    return SolverOutput(unknowns=out.unknowns, status=out.status, diagnostics=diagnostics)
