"""`lmi-sdp` for ``axyb`` (A_i X = Y B_i): the paper's method (Pan et al., IEEE T-ASE 2022,
Sec. III.A, eqs. 5-14), eq. 14 on the SDP backends clarabel (`handeye.plugins.lmi_sdp.clarabel`),
cvxpy and picos; backend casadi is `handeye.plugins.lmi_sdp.casadi.solve_casadi`. Backends,
options and statuses: the package's docstring (`handeye.plugins.lmi_sdp`).

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
   rotations by Schmidt orthogonalisation (`handeye.geometry.se3.gram_schmidt`, columns in order).
   Translations are taken from beta (beta[18:24]) as they are: the paper re-solves them
   (eqs. 20-21) only in its iterative method (Sec. III.B), not in this one.

What the SDP computes: eq. 14 has no constraint beyond the Schur complement, which is exactly
u - rest >= |R1 beta - q1|^2. Its optimum is therefore u* = rest and beta* = R1^-1 q1, the
ordinary least-squares solution of eq. 8 (the same beta as `kron-lstsq`, and as OpenCV's
CALIB_ROBOT_WORLD_HAND_EYE_LI before its rotation normalisation). The SDP adds no information;
the method differs from `kron-lstsq` only in the Gram-Schmidt step and in keeping the
translations of beta. tests/plugins/test_lmi_sdp.py checks beta of every SDP backend against
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
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import SolverOutput, Status
from handeye.base.errors import DegenerateDataError, SolverError
from handeye.estimation.kronecker import KroneckerSystem
from handeye.estimation.rotation_cost import signed_blocks
from handeye.geometry.se3 import make_pose
from handeye.plugins._sdp_backends import (
    CLARABEL_TIGHT,
    CvxpyProblem,
    ProblemCache,
    SolveRecord,
    check_backend_options,
    check_dpp,
    resolve_cvxpy_solver,
    solve_cvxpy,
    solve_picos,
)
from handeye.plugins.lmi_sdp.casadi import solve_casadi
from handeye.plugins.lmi_sdp.clarabel import solve_eq14
from handeye.plugins.lmi_sdp.common import (
    BACKEND_ONLY_OPTIONS,
    ORTHOGONALIZERS,
    PICOS_SETTINGS,
    Options,
    check_finite,
    record_figures,
    sdp_status,
)
from handeye.plugins.lmi_sdp.common import (
    CVXPY_SETTINGS as SDP_CVXPY_SETTINGS,
)
from handeye.problems.axyb import AXYBData, solve_translations, split_beta

#: Settings per cvxpy solver of eq. 14 (others run with their defaults). Clarabel: gap and
#: feasibility tolerances 1e-12 give u to ~1e-13 relative for 2 more iterations (beta is exact
#: either way); merge_method "none" keeps the chordal decomposition of the arrow-shaped LMI into
#: 2x2 cliques (1.5 ms instead of 2.5 ms per solve at the same accuracy; without decomposition:
#: 40 ms). SCS and CVXOPT: as for the other SDPs of lmi-sdp (`common.CVXPY_SETTINGS`).
CVXPY_SETTINGS = {
    **SDP_CVXPY_SETTINGS,
    "CLARABEL": {**CLARABEL_TIGHT, "chordal_decomposition_merge_method": "none"},
}
#: cvxpy solver -> cap on the congruence scale c (`ScaledLMI.of`); others uncapped.
CVXPY_MAX_C: dict[str, float] = {"CLARABEL": 1.0}
#: RMS translation, in the units eq. 8 is built in (the data's; with normalize=True they are
#: divided by their RMS first), below which a failure of the method is put down to the
#: translations (`small_translations`). Measured on the paper's simulation (m = 10): noise-free
#: data solve on every backend down to an RMS of 1e-3; at 1e-4 Clarabel's solution is inaccurate,
#: at 1e-5 picos's fails the host's self-check, and from ~1e-10 eq. 8 is numerically rank
#: deficient; with noise and every translation 0 the SDP's rotation blocks are zero.
SMALL_TRANSLATION = 1e-3


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
    record: SolveRecord


# --------------------------------------------------------------------------------------------
# backend cvxpy: one DPP problem per (cvxpy solver, n), compiled on its first solve, then reused


@dataclasses.dataclass
class CvxpyLMI(CvxpyProblem):
    """The cached cvxpy problem of eq. 14 (parameters R, q, rest; variables gamma, u)."""

    R: Any
    q: Any
    rest: Any
    gamma: Any
    u: Any


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
    problem = check_dpp(cp.Problem(cp.Minimize(u), [lmi >> 0]), "lmi-sdp", "the semidefinite program")
    return CvxpyLMI(R, q, rest, gamma, u, problem=problem)


#: One problem per (cvxpy solver, number of unknowns) in this process.
CVXPY_CACHE = ProblemCache(_build_cvxpy_problem)


def _solve_cvxpy(lmi: ScaledLMI, solver: str) -> SDPResult:
    (gamma, u), record = solve_cvxpy(cvxpy_problem(solver, len(lmi.q)), solver, CVXPY_SETTINGS.get(solver, {}),
                                     {"R": lmi.R, "q": lmi.q, "rest": lmi.rest},
                                     lambda cached: (cached.gamma.value, cached.u.value),
                                     "lmi-sdp", "the semidefinite program")
    status = sdp_status("cvxpy", record, gamma is not None and u is not None)
    return SDPResult(np.array(gamma, dtype=float), float(u), status, record)


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
    _, record = solve_picos(P, PICOS_SETTINGS, "lmi-sdp", "the semidefinite program")
    status = sdp_status("picos", record, gamma.value is not None and u.value is not None)
    return SDPResult(np.array(gamma.value, dtype=float).ravel(), float(u.value), status, record)


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
        result = SDPResult(native.x[1:], float(native.x[0]), native.status, native.record)
    elif backend == "picos":
        lmi = ScaledLMI.of(system)
        result = _solve_picos(lmi)
    else:
        raise ValueError(f"lmi-sdp: {backend!r} is not an SDP backend")
    beta = lmi.d * result.gamma
    check_finite(backend, result.record, "beta", beta)
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
            **record_figures(result.record),
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
