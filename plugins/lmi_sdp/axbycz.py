"""`lmi-sdp` for ``axbycz`` (A_i X B_i = Y C_i Z): the paper's LMI-SDP (Pan et al., IEEE T-ASE
2022, eqs. 9-14) carried over to the lifted Kronecker system of
`handeye.problems.axbycz.kronecker` (beta = [r; tau], 132 unknowns, r = [vec R_X; vec(vec R_Y
vec R_Z^T)] the 90 rotation unknowns). `handeye.plugins.lmi_sdp` registers its ``axbycz`` spec
(`SPEC_AXBYCZ`) with `run` and the options `AXBYCZOptions` defined here. docs/solvers/lmi-sdp.md,
section AXB = YCZ.

The lifted rotation rows are homogeneous (R_A R_X R_B - R_Y R_C R_Z = 0), so, as for A X = Y B,
only the translation rows fix the scale of r, and they see 42 unknowns of their own (tau): they
fix it from 15 triples on. Option ``scale`` says what fixes it:

``scale="translations"``: the paper's eq. 14 as it is on the lifted system: minimise u subject to
  [[u - rest, (R1 beta - q1)^T], [R1 beta - q1, I_132]] >= 0 (a 133 x 133 LMI; R1, q1, rest of
  eqs. 10-12 from the O(m) normal equations, `handeye.estimation.kronecker.reduce_normal_equations`), solved
  by `handeye.plugins.lmi_sdp.axyb.solve_lmi` as for ``axyb``. Its only constraint is the Schur
  complement, so its optimum is the least squares of the lifted system (tested). Needs >= 15
  triples; with fewer the system is rank deficient and a one-line DegenerateDataError says so.

``scale="norm"`` (default; works from 10 triples): as for A X = X B (plugins/lmi_sdp/axxb.py) the
  cost is kept and the scale fixed by the norm exact rotations have, |r|^2 = 3 + 3 * 3 = 12:
  1. tau minimised out (`LiftedCost`): |H beta - w|^2 = r^T P r - 2 p^T r + c.
  2. The QCQP min r^T P r - 2 p^T r s.t. |r|^2 = 12, lifted to Z = [r; 1][r; 1]^T, is the Shor SDP
     min <M, Z> s.t. trace W = 12, Z_hh = 1, Z PSD (91 x 91), tight by the S-lemma (one
     quadratic constraint besides the homogenisation: Polyak 1998). In the eigenbasis of P
     (P = V diag(d) V^T, r = V rho) its cost and constraints touch only the diagonal w of W and
     the last column rho of Z, an arrow pattern, which is chordal: a partial matrix on it has a PSD
     completion if and only if its cliques are PSD (Grone et al. 1984). The SDP is therefore exactly

         minimise  sum_k d_k w_k - 2 (V^T p)_k rho_k  s.t.  sum_k w_k = 12,  [[w_k, rho_k], [rho_k, 1]] >= 0,

     90 LMIs of 2 x 2 (what an SDP solver's chordal decomposition makes of the 91 x 91 one; Clarabel
     took 25-40 s on the 91 x 91 cone, 20 ms on this form).
  3. Extraction: r = V rho when |rho|^2 = 12 (Z of rank one); else (the trust-region hard case:
     below 15 triples p = 0, the translation rows not informing r) the missing norm goes along the
     eigenvector k of largest w_k - rho_k^2: candidates V (rho +- tau e_k), tau^2 = 12 - |rho|^2.
  4. Polish (option ``polish``, default True): Newton on (P - lambda I) r = p, |r|^2 = 12 from the
     SDP's r (`handeye.estimation.trust_region.refine_trust_region`), as for AX = XB: the SDP places r to
     ~1e-6, the polish to rounding; when the global conditions hold the status is ``optimal``.

Both: R_X, R_Y, R_Z from r (`axbycz_kronecker.extract_rotations`: the nearest rank-one factors of
the lifted products; the sign of lower cost) made rotations by ``orthogonalize`` (Gram-Schmidt by
default, the paper's); translations by least squares given the rotations (``translations=
"resolve"``, the default here: Wu et al.'s eq. 38) or from the lifted solution (``"beta"``, the
paper's way: t_X, t_Y of tau and t_Z = Q^T y / |y|^2; tau is determined from 14 triples on).

Defaults that differ from ``axyb`` (`AXBYCZOptions`): ``normalize=True``
(in the data's units, mm, the translation rows weigh ~1e6 times the rotation rows and the normal
equations then give the rotations of exact data to ~1e-7 rad only, against ~1e-13 normalised) and
``translations="resolve"`` (tau is not determined below 14 triples). Backend ``clarabel``
(default): both SDPs in Clarabel's own API, constant data built once
(`handeye.plugins.lmi_sdp.clarabel`: `solve_axbycz` for point 2, `solve_eq14` with n = 132 for
``scale="translations"``); ``cvxpy`` and ``picos`` as for ``axyb``. Backend ``casadi``: the
lifted cost under exact SO(3) (`handeye.plugins.lmi_sdp.casadi.solve_casadi_axbycz`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import SolverOutput, Status
from handeye.base.errors import DegenerateDataError, SolverError
from handeye.checks.self_check import rotation_block_figures
from handeye.estimation.kronecker import reduce_normal_equations
from handeye.estimation.trust_region import refine_trust_region
from handeye.framework.options import check_choice
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
from handeye.plugins.lmi_sdp.axyb import solve_lmi
from handeye.plugins.lmi_sdp.casadi import solve_casadi_axbycz
from handeye.plugins.lmi_sdp.clarabel import solve_axbycz
from handeye.plugins.lmi_sdp.common import (
    BACKEND_ONLY_OPTIONS,
    CVXPY_SETTINGS,
    ORTHOGONALIZERS,
    PICOS_SETTINGS,
    POLISH_NOT_CERTIFIED,
    AXXBOptions,
    check_finite,
    map_status,
    polish_figures,
    record_figures,
    sdp_status,
)
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axbycz import kronecker as lifted

#: What the SDP is, for error messages.
WHAT = "the semidefinite program of AXB=YCZ"
#: |rho|^2 below 12 by more than this (relative): Z has rank two (the hard case of point 3)
RANK_TWO_RTOL = 1e-6
N_R = lifted.N_R
#: what fixes the scale of the lifted rotations (module docstring)
SCALES = ("norm", "translations")


@dataclasses.dataclass(frozen=True)
class AXBYCZOptions(AXXBOptions):
    """Options of `lmi-sdp` for ``axbycz``: those of `handeye.plugins.lmi_sdp.AXXBOptions`
    (``polish``: the SDP backends with scale "norm") and scale: "norm" (|r|^2 = 12, from
    10 triples) or "translations" (the paper's eq. 14 as it is, from 15 triples). Two defaults
    differ from ``axyb``'s: normalize=True and translations="resolve" (module docstring)."""

    normalize: bool = True
    translations: str = "resolve"
    scale: str = "norm"

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice("scale", self.scale, SCALES)


@dataclasses.dataclass(frozen=True)
class SDPResult:
    w: np.ndarray  # (90,) the diagonal of W in the eigenbasis
    rho: np.ndarray  # (90,) r in the eigenbasis
    value: float  # objective of the scaled problem
    status: Status | None  # None: the solver's status is "unknown" (no claim); the polish decides
    record: SolveRecord


@dataclasses.dataclass
class CvxpySDP(CvxpyProblem):
    """The cached cvxpy problem (parameters d, p (90,); variables w, rho (90,))."""

    d: Any
    p: Any
    w: Any
    rho: Any


def cvxpy_problem(solver: str) -> CvxpySDP:
    """The SDP of point 2 as a DPP cvxpy problem for cvxpy `solver`, built once (`CVXPY_CACHE`)."""
    return CVXPY_CACHE.get(solver)


def _build_cvxpy_problem(solver: str) -> CvxpySDP:
    import cvxpy as cp

    d, p = cp.Parameter(N_R, name="d"), cp.Parameter(N_R, name="p")
    w, rho = cp.Variable(N_R, name="w"), cp.Variable(N_R, name="rho")
    one = np.ones((1, 1))
    blocks = [cp.bmat([[cp.reshape(w[k], (1, 1), order="F"), cp.reshape(rho[k], (1, 1), order="F")],
                       [cp.reshape(rho[k], (1, 1), order="F"), one]]) >> 0 for k in range(N_R)]
    problem = cp.Problem(cp.Minimize(d @ w - 2 * p @ rho), [cp.sum(w) == lifted.SPHERE, *blocks])
    return CvxpySDP(d, p, w, rho, problem=check_dpp(problem, "lmi-sdp", "the AXB=YCZ SDP"))


#: One problem per cvxpy solver in this process.
CVXPY_CACHE = ProblemCache(_build_cvxpy_problem)


def _solve_cvxpy(d: np.ndarray, p: np.ndarray, solver: str) -> SDPResult:
    # "inaccurate" is a status; the polish decides
    (w, rho, value), record = solve_cvxpy(
        cvxpy_problem(solver), solver, CVXPY_SETTINGS.get(solver, {}), {"d": d, "p": p},
        lambda cached: (cached.w.value, cached.rho.value, cached.problem.value), "lmi-sdp", WHAT)
    status = sdp_status("cvxpy", record, w is not None and rho is not None, WHAT)
    return SDPResult(np.array(w, dtype=float), np.array(rho, dtype=float), float(value), status, record)


def _solve_picos(d: np.ndarray, p: np.ndarray) -> SDPResult:
    import picos

    P = picos.Problem()
    w, rho = picos.RealVariable("w", N_R), picos.RealVariable("rho", N_R)
    P.add_constraint(picos.sum(w) == lifted.SPHERE)
    for k in range(N_R):
        P.add_constraint(picos.block([[w[k], rho[k]], [rho[k], 1]]) >> 0)
    P.set_objective("min", picos.Constant("d", d).T * w - 2 * picos.Constant("p", p).T * rho)
    _, record = solve_picos(P, PICOS_SETTINGS, "lmi-sdp", WHAT)
    status = record.solver_status
    if w.value is None or rho.value is None:
        raise SolverError(f"lmi-sdp: picos/cvxopt returned status {status!r} for {WHAT} and no solution")
    # CVXOPT stops with "unknown" when it cannot reach its tolerances (ill-conditioned costs:
    # normalize=False with large translations); its point then goes to the polish, which
    # certifies it or the solve fails (run)
    unknown = status == picos.modeling.solution.SS_UNKNOWN
    result_status = None if unknown else map_status(status, {picos.modeling.solution.SS_OPTIMAL}, set(),
                                                    "picos/cvxopt", WHAT)
    return SDPResult(np.array(w.value, dtype=float).ravel(), np.array(rho.value, dtype=float).ravel(),
                     float(P.value), result_status, record)


def solve_sdp(cost: lifted.LiftedCost, backend: str, cvxpy_solver: str | None = None
              ) -> tuple[list[np.ndarray], SDPResult, float, bool]:
    """The SDP of point 2 for `cost` on backend "clarabel", "cvxpy" or "picos": (candidates for r
    (point 3), raw result, the scale the cost was divided by, rank two)."""
    d, V = np.linalg.eigh(cost.P)
    pt = V.T @ cost.p
    norm = max(float(np.max(np.abs(d))), float(np.linalg.norm(pt)) / np.sqrt(lifted.SPHERE))
    if not np.isfinite(norm) or norm == 0.0:
        raise SolverError("lmi-sdp: the cost matrix of the lifted system is zero or not finite")
    if backend == "clarabel":
        native = solve_axbycz(d / norm, pt / norm, lifted.SPHERE, WHAT)
        w, rho = native.x[:N_R], native.x[N_R:]
        result = SDPResult(w, rho, float(d @ w - 2 * pt @ rho) / norm, native.status, native.record)
    elif backend == "cvxpy":
        result = _solve_cvxpy(d / norm, pt / norm, resolve_cvxpy_solver(cvxpy_solver))
    elif backend == "picos":
        result = _solve_picos(d / norm, pt / norm)
    else:
        raise ValueError(f"lmi-sdp: {backend!r} is not an SDP backend")
    check_finite(backend, result.record, "solution", result.w, result.rho)
    rho = result.rho
    missing = lifted.SPHERE - float(rho @ rho)
    if missing <= RANK_TWO_RTOL * lifted.SPHERE:
        return [V @ rho], result, norm, False
    k = int(np.argmax(result.w - rho**2))
    tau = np.sqrt(max(missing, 0.0))
    return [V @ (rho + tau * np.eye(N_R)[k]), V @ (rho - tau * np.eye(N_R)[k])], result, norm, True


def run(data: AXBYCZData, options: AXBYCZOptions, backend: str) -> SolverOutput:
    """`lmi-sdp` on ``axbycz`` data (module docstring)."""
    check_backend_options("lmi-sdp", options, backend, BACKEND_ONLY_OPTIONS)
    if backend == "casadi":
        lifted.check_triples(data, "lmi-sdp")
        gap = lifted.check_rotations(data, "lmi-sdp")
        out = solve_casadi_axbycz(data, normalize=bool(options.normalize), multistart=options.multistart or 0,
                                  seed=options.seed, ipopt_options=options.ipopt_options)
        diagnostics = dict(out.diagnostics, orthogonalize=options.orthogonalize, translations=options.translations,
                           scale=options.scale, rotation_gap=gap)
        diagnostics["warnings"] = lifted.weak_rotations(gap, "lmi-sdp") + list(diagnostics.get("warnings", []))
        return SolverOutput(unknowns=out.unknowns, status=out.status, diagnostics=diagnostics)
    literal = options.scale == "translations"
    if literal:
        lifted.check_triples(data, "lmi-sdp", lifted.MIN_TRIPLES_UNCONSTRAINED, _LITERAL_NEEDS)
    else:
        lifted.check_triples(data, "lmi-sdp")
    gap = lifted.check_rotations(data, "lmi-sdp")
    scale = data.translation_scale if options.normalize else 1.0
    N, g, ww = lifted.normal_equations(data, scale)
    cost = lifted.LiftedCost.from_normal_equations(N, g, ww)
    if options.translations == "beta" and not (literal or cost.translations_determined):
        raise DegenerateDataError(
            f"lmi-sdp for axbycz: translations='beta' reads the translations from the lifted solution, which "
            f"{data.m} triples do not determine (at least {lifted.MIN_TRIPLES_TAU} are needed); use "
            "translations='resolve'")
    orthogonalize = ORTHOGONALIZERS[options.orthogonalize]
    notes: list[str] = lifted.weak_rotations(gap, "lmi-sdp")
    if literal:
        r, tau, status, figures = _run_literal(N, g, ww, backend, options)
        estimate = lifted.extract_rotations(r, cost, orthogonalize)
    else:
        candidates, result, norm, rank_two = solve_sdp(cost, backend, options.cvxpy_solver)
        choices = [(lifted.extract_rotations(r, cost, orthogonalize), r) for r in candidates]
        values = [cost.value(lifted.rotations_vector(*e.rotations)) for e, _ in choices]
        estimate, r_sdp = choices[int(np.argmin(values))]
        r_sdp = -r_sdp if estimate.flipped else r_sdp
        r, status, polished = r_sdp, result.status, None
        if options.polish:
            polished = refine_trust_region(cost.P, cost.p, float(np.sqrt(lifted.SPHERE)), r_sdp)
            if polished.global_optimum:
                r, status = polished.x, Status.OPTIMAL
                estimate = lifted.extract_rotations(r, cost, orthogonalize)
            elif status is not None:
                notes.append(POLISH_NOT_CERTIFIED)
        if status is None:
            raise SolverError(
                f"lmi-sdp: {backend}/{result.record.backend_solver} returned status {result.record.solver_status!r} for {WHAT}, "
                "and its point is not certified optimal (Newton polish" + ("" if options.polish else " off")
                + ("; normalize=False makes the cost ill-conditioned: use normalize=True" if not options.normalize
                   else "") + "); no solution is returned")
        tau = cost.tau(r)
        figures = {
            "sdp_objective": result.value * norm + cost.c,
            "rank_two": rank_two,
            "sdp_r": r_sdp,
            **polish_figures(polished, r_sdp),
            **record_figures(result.record, sdp_status=None if result.status is None else str(result.status)),
        }
    RX, RY, RZ = estimate.rotations
    if options.translations == "resolve":
        tX, tY, tZ = lifted.solve_translations(data, RX, RY, RZ)
    else:
        tX, tY, tZ = lifted.tau_translations(tau, scale)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY), "Z": make_pose(RZ, tZ)},
        status=status,
        diagnostics={
            **figures,
            "cost": cost.value(r),
            "sign_flipped": estimate.flipped,
            "rank_one_ratio": estimate.rank_one_ratio,
            "rotation_gap": gap,
            "translation_rank": cost.translation_rank,
            "rotation_blocks": {name: rotation_block_figures(M) for name, M in zip("XYZ", estimate.blocks)},
            "scale": options.scale,
            "orthogonalize": options.orthogonalize,
            "translations": options.translations,
            "normalized": bool(options.normalize),
            "translation_scale": scale,
            "warnings": notes,
        },
    )


_LITERAL_NEEDS = (f"scale='translations' (the paper's unconstrained LMI as it is) takes the scale of the lifted "
                  f"rotations from the translation rows, which determine it with at least "
                  f"{lifted.MIN_TRIPLES_UNCONSTRAINED} triples (use scale='norm' with fewer)")


def _run_literal(N: np.ndarray, g: np.ndarray, ww: float, backend: str, options: AXBYCZOptions
                 ) -> tuple[np.ndarray, np.ndarray, Status, dict[str, Any]]:
    """scale="translations": eq. 14 on the lifted system; (r, tau, status, diagnostics)."""
    try:
        system = reduce_normal_equations(N, g, ww)
    except DegenerateDataError:
        raise DegenerateDataError(f"lmi-sdp for axbycz: the lifted system is rank deficient, so {_LITERAL_NEEDS}; "
                                  "both robots must move between the triples") from None
    beta, u, result = solve_lmi(system, backend, options)
    e = system.R1 @ beta - system.q1
    figures = {
        "u": u,
        "rest": system.rest,
        "schur_complement": float(u - system.rest - e @ e),
        "sigma_min_R1": system.smallest_singular_value(),
        "beta": beta,
        **record_figures(result.record),
    }
    return beta[:N_R], beta[N_R:], result.status, figures
