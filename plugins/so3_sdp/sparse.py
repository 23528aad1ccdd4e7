"""The Shor relaxation of `so3-sdp` for many rotations, solved by a primal-dual interior-point
method that exploits the sparsity of its constraints (the fallback of ``axyb-multi`` above
`handeye.plugins.so3_sdp.multi.SDP_MAX_ROTATIONS`; docs/solvers/so3-sdp.md).

Why. The relaxation (`handeye.estimation.so3_relaxation`: minimise <M, Z> over Z (n = 9k + 1 square) PSD
with <A_j, Z> = b_j, K = 20k + 1 constraints) has one dense cone, M being dense once the
translations are eliminated. Clarabel factors a KKT system in which the cone's scaling is a
dense block of size n(n + 1)/2 (23653 for k = 24): memory ~k^4, time ~k^6. But every A_j
touches only one rotation's 9 entries and h (the last entry of y), so the classical
Schur-complement interior-point method (as SDPT3 / SDPA / CSDP) is cheap here: its linear system
is K x K (481 for k = 24), with entries tr(A_i X A_j Z^-1) that only read the 10 x 10 blocks of X
and Z^-1 of the two rotations involved, and each iteration costs a few dense operations of size n.

Method: infeasible-start primal-dual path following with the HKM direction and Mehrotra's
predictor-corrector (Helmberg, Rendl, Vanderbei & Wolkowicz, SIAM J. Optim. 1996; Kojima,
Shindoh & Hara 1997; Monteiro 1997; Todd, Toh & Tutuncu 1998), our own code:

    primal  min <C, X>  s.t. <A_i, X> = b_i, X PSD   (X: the relaxation's Z, the moment matrix)
    dual    max b^T y   s.t. S = C - sum_i y_i A_i PSD  (y: the multipliers nu)

The answer is then treated exactly as the dense SDP's (`handeye.plugins.so3_sdp.single`):
extraction from the dominant eigenvector of X, polish, and the certificate recomputed in float64
from the multipliers (made exactly stationary at the polished point): the status never rests on
this solver's own convergence claim.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np
from scipy.linalg import cho_solve, solve_triangular

from handeye import Status
from handeye.base.errors import SolverError
from handeye.estimation.rotation_cost import RotationCost, rotations_vector
from handeye.estimation.so3_relaxation import (
    constraint_matrices,
    dimension,
    extract_rotations,
    polish,
    trace_z,
)
from handeye.framework.threads import one_blas_thread
from handeye.geometry.linalg import frobenius_norm
from handeye.geometry.se3 import rotation_angle
from handeye.plugins.so3_sdp.single import (
    _certificate_figures,  # the dense SDP's figures, shared
)

#: stop when the relative primal and dual infeasibilities and the relative duality gap are all
#: below this (the certificate is recomputed afterwards, so this only sets how close to the
#: optimum the multipliers start)
TOLERANCE = 1e-8
#: at most this many iterations (measured: 11-15 on calibration data, up to 74 on data no
#: calibration explains, where the relaxation is not tight)
MAX_ITERATIONS = 100
#: fraction of the step to the boundary of the PSD cone taken
STEP_FRACTION = 0.98
#: stop ("stalled") when both step lengths fall below this
MIN_STEP = 1e-8

# Constraint layout: per rotation g the 20 constraints of constraint_matrices(1) on the local
# indices (its 9 entries, h), in the order of constraint_matrices(k); then h^2 = 1 (K = 20k + 1).
_PER_ROTATION = 20


@functools.cache
def _local_matrices() -> np.ndarray:
    """(21, 10, 10): the 20 per-rotation constraint matrices of one rotation and h^2 = 1 on the
    local indices (9 entries of the rotation, then h). Read-only."""
    A1, _ = constraint_matrices(1, redundant=True)
    L = np.array(A1)
    L.flags.writeable = False
    return L


class Constraints:
    """The K = 20k + 1 constraint matrices of `constraint_matrices(k)` (same order), held as one
    10 x 10 local stack and an index map: A(X), A^T(y) and the Schur matrix without forming the
    (K, n, n) stack (181 MB for k = 24)."""

    def __init__(self, rotations: int) -> None:
        self.k = k = rotations
        self.n = dimension(k)
        self.L = _local_matrices()  # (21, 10, 10)
        self.index = np.array([[*range(9 * g, 9 * g + 9), 9 * k] for g in range(k)])  # (k, 10)
        # positions, in the padded (k, 21) layout, of the K constraints
        self.select = np.array([g * 21 + c for g in range(k) for c in range(_PER_ROTATION)] + [20])
        self.b = np.zeros(len(self.select))
        self.b[-1] = 1.0

    def blocks(self, X: np.ndarray) -> np.ndarray:
        """(k, k, 10, 10): X[index_g][:, index_f]."""
        i = self.index
        return X[i[:, None, :, None], i[None, :, None, :]]

    def apply(self, X: np.ndarray) -> np.ndarray:
        """A(X)_i = <A_i, X>: (K,)."""
        i = self.index
        diag = X[i[:, :, None], i[:, None, :]]  # (k, 10, 10)
        full = np.einsum("cpq,gpq->gc", self.L, diag)  # (k, 21)
        return full.reshape(-1)[self.select]

    def adjoint(self, y: np.ndarray) -> np.ndarray:
        """A^T(y) = sum_i y_i A_i: (n, n)."""
        k, n = self.k, self.n
        padded = np.zeros(21 * k)
        padded[self.select] = y
        G = np.einsum("gc,cpq->gpq", padded.reshape(k, 21), self.L)  # (k, 10, 10)
        out = np.zeros((n, n))
        for g in range(k):  # each rotation's own 9 x 9 block, its column and row of h
            s = slice(9 * g, 9 * g + 9)
            out[s, s] = G[g, :9, :9]
            out[s, -1] = G[g, :9, 9]
            out[-1, s] = G[g, 9, :9]
        out[-1, -1] = G[:, 9, 9].sum()
        return out

    def schur(self, X: np.ndarray, Zinv: np.ndarray) -> np.ndarray:
        """H_ij = tr(A_i X A_j Z^-1): (K, K), from the 10 x 10 blocks only."""
        k, L = self.k, self.L
        Xb, Zb = self.blocks(X), self.blocks(Zinv)  # [g, f, q, r], [g, f, p, s]
        # one product each over all blocks (a batch of k^2 x 21 products of 10 x 10 is 1.5x slower)
        T1 = np.tensordot(L, Xb, axes=([2], [2]))  # [c, p, g, f, r] = sum_q L[c,p,q] X[g,f,q,r]
        T1 = T1.transpose(2, 3, 0, 1, 4).reshape(k, k, 21, 100)
        T2 = np.tensordot(L, Zb, axes=([2], [3]))  # [d, r, g, f, p] = sum_s L[d,r,s] Zi[g,f,p,s]
        T2 = T2.transpose(2, 3, 0, 4, 1).reshape(k, k, 21, 100)  # [g, f, d, p, r]
        H = np.matmul(T1, T2.transpose(0, 1, 3, 2))  # [g, f, c, d]
        H = H.transpose(0, 2, 1, 3).reshape(21 * k, 21 * k)
        H = H[np.ix_(self.select, self.select)]
        return 0.5 * (H + H.T)


def _solver(H: np.ndarray) -> Any:
    """r -> H^-1 r for the Schur matrix H (symmetric positive definite in exact arithmetic):
    Cholesky, or, when rounding makes it fail (X nearly rank one near a tight optimum), the
    pseudo-inverse from its eigenvalues."""
    try:
        factor = (np.linalg.cholesky(H), True)
        return lambda r: cho_solve(factor, r, check_finite=False)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(H)
        inv = np.divide(1.0, w, out=np.zeros_like(w), where=w > 1e-14 * w[-1])
        return lambda r: V @ (inv * (V.T @ r))


def _direction(A: Constraints, X: np.ndarray, Rd: np.ndarray, Zinv: np.ndarray, schur_solve: Any,
               sigma_mu: float, G: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The HKM direction (dX, dy, dZ): dX = sigma mu Z^-1 - X - G - X dZ Z^-1 (then symmetrised),
    dZ = Rd - A^T dy, A(dX) = rp, i.e. H dy = b - sigma mu A(Z^-1) + A(X Rd Z^-1) + A(G); G the
    corrector's second-order term dX_aff dZ_aff Z^-1 (None for the predictor)."""
    rhs = A.b + A.apply(X @ Rd @ Zinv)
    if sigma_mu:
        rhs -= sigma_mu * A.apply(Zinv)
    if G is not None:
        rhs += A.apply(0.5 * (G + G.T))
    dy = schur_solve(rhs)
    dZ = Rd - A.adjoint(dy)
    dX = sigma_mu * Zinv - X - X @ dZ @ Zinv
    if G is not None:
        dX -= G
    return 0.5 * (dX + dX.T), dy, dZ


def _max_step(X: np.ndarray, dX: np.ndarray) -> float:
    """The largest alpha with X + alpha dX PSD (X positive definite), or inf."""
    R = np.linalg.cholesky(X)
    Ri = solve_triangular(R, dX, lower=True, check_finite=False)  # L^-1 dX
    W = solve_triangular(R, Ri.T, lower=True, check_finite=False)  # L^-1 dX L^-T (dX symmetric)
    lam = np.linalg.eigvalsh(0.5 * (W + W.T))[0]
    return np.inf if lam >= 0 else -1.0 / lam


def solve_sdp(C: np.ndarray, rotations: int, tolerance: float = TOLERANCE,
              max_iterations: int = MAX_ITERATIONS) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The relaxation with cost matrix C ((9k+1)-square, symmetric, best scaled to |C| ~ 1) and the
    redundant constraints: (X, y, info), X the moment matrix (the primal, the relaxation's Z), y
    the multipliers (S = C - sum y_i A_i), info with status ("optimal" when the tolerances were
    met, else "max_iterations" / "stalled"), iterations, objectives and residuals."""
    with one_blas_thread():  # 217-square matrices: BLAS threads only wait for each other
        return _solve_sdp(C, rotations, tolerance, max_iterations)


def _solve_sdp(C: np.ndarray, rotations: int, tolerance: float, max_iterations: int
               ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    A = Constraints(rotations)
    n, b = A.n, A.b
    C = 0.5 * (C + C.T)
    normC = max(frobenius_norm(C), 1.0)
    start = max(10.0, np.sqrt(n))
    X = start * np.eye(n)
    Z = start * np.eye(n)
    y = np.zeros(len(b))
    status = "max_iterations"
    info: dict[str, Any] = {}
    for it in range(max_iterations + 1):
        rp = b - A.apply(X)
        Rd = C - Z - A.adjoint(y)
        primal, dual = float(np.sum(C * X)), float(b @ y)
        gap = float(np.sum(X * Z))
        mu = gap / n
        pinf = float(np.linalg.norm(rp) / (1.0 + np.linalg.norm(b)))
        dinf = float(frobenius_norm(Rd) / (1.0 + normC))
        rgap = abs(primal - dual) / (1.0 + abs(primal) + abs(dual))
        info = {"sdp_iterations": it, "sdp_objective": dual, "primal_objective": primal,
                "primal_infeasibility": pinf, "dual_infeasibility": dinf, "relative_gap_sdp": rgap}
        if max(pinf, dinf, rgap) < tolerance:
            status = "optimal"
            break
        if it == max_iterations:
            break
        try:
            Zinv = np.linalg.inv(Z)
        except np.linalg.LinAlgError:
            status = "stalled"
            break
        Zinv = 0.5 * (Zinv + Zinv.T)
        schur_solve = _solver(A.schur(X, Zinv))

        try:
            dX, dy, dZ = _direction(A, X, Rd, Zinv, schur_solve, 0.0, None)  # predictor
            ap = min(1.0, STEP_FRACTION * _max_step(X, dX))
            ad = min(1.0, STEP_FRACTION * _max_step(Z, dZ))
            mu_aff = float(np.sum((X + ap * dX) * (Z + ad * dZ))) / n
            sigma = min(1.0, (mu_aff / mu) ** 3)
            dX, dy, dZ = _direction(A, X, Rd, Zinv, schur_solve, sigma * mu, dX @ dZ @ Zinv)  # corrector
            ap = min(1.0, STEP_FRACTION * _max_step(X, dX))
            ad = min(1.0, STEP_FRACTION * _max_step(Z, dZ))
        except np.linalg.LinAlgError:  # X or Z numerically singular: the iterate is as good as it gets
            status = "stalled"
            break
        if max(ap, ad) < MIN_STEP:
            status = "stalled"
            break
        X = X + ap * dX
        y = y + ad * dy
        Z = Z + ad * dZ
        X, Z = 0.5 * (X + X.T), 0.5 * (Z + Z.T)
    return X, y, {"sdp_status": status, **info}


def certificate(M: np.ndarray, y: np.ndarray, nu: np.ndarray) -> dict[str, float]:
    """`handeye.estimation.so3_relaxation.certificate` (redundant constraints) with the structured
    constraints: the same lower bound, without the (K, n, n) stack."""
    k = (len(y) - 1) // 9
    A = Constraints(k)
    # L: columns A_j y, (n, K)
    padded = np.zeros((k, 21, 9 * k + 1))
    local = np.einsum("cpq,gq->gcp", A.L, y[A.index])  # (k, 21, 10): (A_c y_local)
    for g in range(k):
        padded[g, :, A.index[g]] = local[g].T
    Lmat = padded.reshape(21 * k, -1)[A.select].T
    correction, *_ = np.linalg.lstsq(Lmat, M @ y - Lmat @ nu, rcond=None)
    nu = nu + correction
    S = M - A.adjoint(nu)
    lam = np.linalg.eigvalsh(0.5 * (S + S.T))
    value = float(y @ M @ y)
    lower = float(nu @ A.b + trace_z(k) * min(0.0, float(lam[0])))
    return {"value": value, "lower_bound": min(lower, value), "dual_slack_min_eigenvalue": float(lam[0]),
            "certificate_margin": float(lam[1]), "stationarity_residual": float(np.linalg.norm(S @ y))}


def solve(cost: RotationCost, options: Any, local: dict[str, Any] | None = None
          ) -> tuple[list[np.ndarray], tuple[np.ndarray, ...], Any, dict[str, Any]]:
    """`solve_relaxation`'s SDP path for any k with this solver (the redundant constraints always:
    the weaker set is for studying tightness): (rotations, translations, status, diagnostics),
    `certificate_path` "sdp-sparse". `local`: the local attempt's diagnostics, reported as
    ``local_certificate``."""
    k = cost.rotations
    M = cost.matrix
    norm = frobenius_norm(M)
    if not np.isfinite(norm) or norm == 0.0:
        raise SolverError("so3-sdp: the cost matrix built from the poses is zero or not finite")
    t0 = time.perf_counter()
    Z, nu, info = solve_sdp(M / norm, k)
    seconds = time.perf_counter() - t0
    Rs, eig = extract_rotations(Z, k)
    ratio = float(eig[1] / eig[0])
    start, steps = Rs, 0
    if options.polish:
        Rs, steps = polish(cost, Rs)
    y = np.append(rotations_vector(*Rs), 1.0)
    cert = certificate(M / norm, y, nu)
    cert = {key: value * norm for key, value in cert.items()}
    diagnostics = {
        "certificate_path": "sdp-sparse",
        **info,
        "sdp_solver": "so3-sdp sparse interior point",
        "sdp_seconds": seconds,
        "sdp_objective": info["sdp_objective"] * norm + cost.rest,
        "primal_objective": info["primal_objective"] * norm + cost.rest,
        **_certificate_figures(cert, ratio, cost.rest, norm),
        "eigenvalues": [float(v) for v in eig[:3]],
        "polish_steps": steps,
        "polish_rotation_change": float(max(rotation_angle(R0.T @ R) for R0, R in zip(start, Rs))),
        "cost_matrix_norm": norm,
        "redundant_constraints": True,
    }
    if local:
        diagnostics["local_certificate"] = {key: local[key] for key in
                                            ("relative_gap", "dual_slack_min_eigenvalue", "cost") if key in local}
    status = Status.OPTIMAL if diagnostics["certified"] else Status.UNCERTIFIED
    return Rs, cost.translations(y[:-1]), status, diagnostics


def fallback(cost: RotationCost, options: Any, local_rotations: list[np.ndarray], local: dict[str, Any]
             ) -> tuple[list[np.ndarray], tuple[np.ndarray, ...], Any, dict[str, Any]]:
    """The relaxation of a component too large for the dense SDP, after its local certificate
    failed (`handeye.plugins.so3_sdp.multi`): `solve`. Its answer is returned when certified;
    otherwise the cheaper of it and the local minimum (`local_rotations`, diagnostics `local`),
    `uncertified`, the other's figures under ``sparse_sdp`` / ``local_certificate``."""
    local = {key: value for key, value in local.items() if key != "sdp_skipped"}
    try:
        Rs, ts, status, figures = solve(cost, options, local)
    except SolverError as error:  # no rotation in the relaxation's answer: the local minimum stays
        if not local_rotations:
            raise
        return (local_rotations, cost.translations(rotations_vector(*local_rotations)), Status.UNCERTIFIED,
                {**local, "sparse_sdp": {"error": str(error)}})
    if figures["certified"] or not local_rotations or figures["cost"] <= local["cost"]:
        return Rs, ts, status, figures
    keep = ("sdp_status", "sdp_iterations", "sdp_seconds", "cost", "lower_bound", "relative_gap", "eigenvalue_ratio")
    return (local_rotations, cost.translations(rotations_vector(*local_rotations)), Status.UNCERTIFIED,
            {**local, "sparse_sdp": {key: figures[key] for key in keep}})
