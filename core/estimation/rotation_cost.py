"""The Kronecker cost |H beta - w|^2 with the translations minimised out in closed form.

Every Kronecker system here (``axyb``: eq. 8 of the paper; ``axxb``: its analogue, problems/axxb/data.py)
has beta = [r; t] with r = [vec R_1; ...; vec R_k] (9k entries, column-major vec) followed by the
k translations t (3k). For given rotations the cost is a linear least squares in t, so

    |H beta - w|^2 = |T t + U r - u|^2 + |S r - s|^2 + rest,

T (3k, 3k) invertible, and t(r) = T^-1 (u - U r) are the translations' least squares for the
rotations r (for ``axyb`` exactly eqs. 20-21). What remains is a quadratic in r alone,
y^T M y + rest with y = [r; 1] (`RotationCost.matrix`), the cost the SDP relaxations, the SO(3)
NLP and the trust-region solver minimise. Two ways to get there:

- `eliminate_translations(system)`: a QR of [R1_t | R1_r | q1] of the reduced system of eq. 10
  (`handeye.estimation.kronecker.KroneckerSystem`), translation columns first: S upper triangular. Needs R1,
  i.e. H of full column rank.
- `RotationCost.from_normal_equations(N, g, w^T w, k)`: from H^T H, H^T w directly, through the
  Cholesky factor of the translation block only (T^T T = N_tt) and the Schur complement
  P = N_rr - U^T U, p = g_r - U^T u; S = Lambda^{1/2} V^T from P = V Lambda V^T, so P may be
  singular. This is what ``axxb`` needs: its rotation rows are homogeneous and, for a camera
  rotating about its own centre, H is rank deficient (its Cholesky fails about half the time)
  while the translations stay determined (N_tt is positive definite whenever the rotation axes
  differ, which the problem's validation demands).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np
from scipy.linalg import lapack

from handeye.base.errors import DegenerateDataError
from handeye.estimation.kronecker import KroneckerSystem
from handeye.estimation.trust_region import TrustRegionSolution, solve_trust_region
from handeye.framework.caching import cached_property
from handeye.geometry.linalg import solve_triangular
from handeye.geometry.se3 import project_to_so3

#: Eigenvalues of P below this (relative to the largest) count as zero in the square root
#: S = Lambda^{1/2} V^T of `RotationCost.from_normal_equations`: their part of p is rounding.
RANK_RTOL = 1e-13


@dataclasses.dataclass(frozen=True)
class RotationCost:
    """|H beta - w|^2 = |T t + U r - u|^2 + |S r - s|^2 + rest (module docstring).

    S: (9k, 9k), s: (9k,), T: (3k, 3k) upper triangular, U: (3k, 9k), u: (3k,), rest >= 0; k
    rotations r = [vec R_1; ...; vec R_k] (column-major vec), translations t = [t_1; ...; t_k].
    """

    S: np.ndarray
    s: np.ndarray
    T: np.ndarray
    U: np.ndarray
    u: np.ndarray
    rest: float

    @property
    def rotations(self) -> int:
        """k, the number of rotations (and translations) in beta."""
        return len(self.s) // 9

    @cached_property
    def matrix(self) -> np.ndarray:
        """M: (9k+1, 9k+1) PSD with y^T M y = |S r - s|^2 for y = [r; 1]."""
        G = np.concatenate([self.S, -self.s[:, None]], axis=1)
        return G.T @ G

    @cached_property
    def quadratic(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(P, p, c) with |S r - s|^2 = r^T P r - 2 p^T r + c: P = S^T S (9k, 9k), p = S^T s."""
        return self.S.T @ self.S, self.S.T @ self.s, float(self.s @ self.s)

    def value(self, r: np.ndarray) -> float:
        """The cost |H beta - w|^2 with the translations at their optimum, for r: (9k,)."""
        e = self.S @ r - self.s
        return float(e @ e + self.rest)

    def translations(self, r: np.ndarray) -> tuple[np.ndarray, ...]:
        """The k translations (3,) minimising the cost for the rotations r: (9k,)."""
        t = solve_triangular(self.T, self.u - self.U @ r)  # LAPACK directly (`handeye.geometry.linalg`)
        return tuple(t[3 * j:3 * j + 3] for j in range(len(t) // 3))

    @classmethod
    def from_normal_equations(cls, N: np.ndarray, g: np.ndarray, ww: float, rotations: int) -> RotationCost:
        """From N = H^T H: (12k, 12k), g = H^T w, ww = w^T w, beta = [r (9k); t (3k)]: the
        translations through the Cholesky factor of N_tt, the rotations through the Schur
        complement, which may be singular (module docstring). DegenerateDataError when N_tt is
        not positive definite (the translations are then undetermined)."""
        from scipy.linalg import LinAlgError, cholesky

        n_r = 9 * rotations
        if N.shape != (12 * rotations, 12 * rotations):
            raise ValueError(f"expected N of shape {(12 * rotations,) * 2} for {rotations} rotation(s), got {N.shape}")
        try:
            T = cholesky(N[n_r:, n_r:], lower=False)
        except LinAlgError:
            raise DegenerateDataError(
                "the translations are undetermined given the rotations: the motions must rotate "
                "about at least two different axes"
            ) from None
        # numpy's solve: scipy's triangular solve with a matrix right-hand side took 2-8 ms here
        # (against 0.02 ms) once cvxpy / casadi were imported
        U = np.linalg.solve(T.T, N[n_r:, :n_r])
        u = np.linalg.solve(T.T, g[n_r:])
        P = N[:n_r, :n_r] - U.T @ U
        p = g[:n_r] - U.T @ u
        lam, V = np.linalg.eigh(0.5 * (P + P.T))
        keep = lam > RANK_RTOL * max(float(lam[-1]), 0.0)
        root = np.sqrt(np.where(keep, lam, 0.0))
        S = root[:, None] * V.T
        s = np.divide(V.T @ p, root, out=np.zeros(n_r), where=keep)
        rest = max(float(ww - u @ u - s @ s), 0.0)
        return cls(S=S, s=s, T=T, U=U, u=u, rest=rest)


def eliminate_translations(system: KroneckerSystem, rotations: int | None = None) -> RotationCost:
    """QR of [R1_t | R1_r | q1] (12k x (12k+1)): translations first, so they drop out in closed
    form. k defaults to the size of R1 / 12 (each unknown pose has 9 + 3 entries in beta)."""
    R1, q1 = system.R1, system.q1
    n = len(q1)
    k = n // 12 if rotations is None else rotations
    if n != 12 * k:
        raise ValueError(f"a system of size {n} does not hold {k} rotation(s) and translation(s)")
    n_r = 9 * k
    R = _qr_r(np.concatenate([R1[:, n_r:], R1[:, :n_r], q1[:, None]], axis=1))
    n_t = n - n_r
    return RotationCost(S=R[n_t:n, n_t:n].copy(), s=R[n_t:n, n].copy(), T=R[:n_t, :n_t].copy(),
                        U=R[:n_t, n_t:n].copy(), u=R[:n_t, n].copy(), rest=system.rest)


def _qr_r(M: np.ndarray) -> np.ndarray:
    """The R of np.linalg.qr(M, mode="r") for a finite float64 M: (rows, n): LAPACK's dgeqrf
    called directly, as numpy does (the same numbers, measured), without its wrapper (28 -> 12 us
    at 24 x 25, once a so3-sdp solve)."""
    qr, _, _, info = lapack.dgeqrf(M)
    if info != 0:
        return np.linalg.qr(M, mode="r")
    top = qr[:min(M.shape)]
    return np.where(_below_diagonal(top.shape), 0.0, top)  # np.triu's own operation, its mask kept


@functools.cache
def _below_diagonal(shape: tuple[int, int]) -> np.ndarray:
    """The mask np.triu(a) zeroes for a of `shape` (np.tri(..., k=-1)), made once per shape
    (read-only): np.triu builds it at every call (~5 of ~7 us)."""
    mask = np.tri(*shape, k=-1, dtype=bool)
    mask.setflags(write=False)
    return mask


def sphere_least_squares(cost: RotationCost) -> TrustRegionSolution:
    """The r minimising |S r - s|^2 on the sphere |r|^2 = 3k (the squared Frobenius norm of k
    rotations): a trust-region subproblem with an equality constraint, solved exactly
    (`handeye.estimation.trust_region`). Its x is r; r and -r are told apart by `signed_rotations`."""
    P, p, _ = cost.quadratic
    return solve_trust_region(P, p, float(np.sqrt(3.0 * cost.rotations)))


def rotations_vector(*rotations: np.ndarray) -> np.ndarray:
    """r = [vec R_1; ...; vec R_k]: (9k,), column-major vec."""
    # the column-major vecs, concatenated, as one copy of the transposed stack (11 times a so3-sdp solve)
    return np.array(rotations, dtype=float).transpose(0, 2, 1).ravel()


def rotation_blocks(r: np.ndarray) -> list[np.ndarray]:
    """The 3x3 matrices unvec(r[9j: 9j + 9]) of r: (9k,) (not yet rotations)."""
    return [r[9 * j:9 * j + 9].reshape(3, 3, order="F") for j in range(len(r) // 9)]


def signed_rotations(cost: RotationCost, r: np.ndarray,
                     orthogonalize: Callable[[np.ndarray], np.ndarray] = project_to_so3
                     ) -> tuple[list[np.ndarray], bool]:
    """The rotations of r or of -r, made rotations by `orthogonalize` (batched: (n, 3, 3) in, out;
    both signs in one call), whichever costs less.

    With the scale of r fixed by a norm (|r|^2 = 3k) rather than by the data, r and -r are equally
    feasible, and where the translation rows carry no scale information (a camera rotating about
    its own centre) they cost the same: the minimiser is then unique only up to sign. Only one
    sign is close to rotations (det(-R) = -det R), and the rotations of the other cost far more.
    Returns (rotations, flipped); ties keep r.
    """
    blocks = np.stack(rotation_blocks(r))
    both = orthogonalize(np.concatenate([blocks, -blocks]))  # one batched call for both signs
    candidates = [list(both[:len(blocks)]), list(both[len(blocks):])]
    costs = [cost.value(rotations_vector(*Rs)) for Rs in candidates]
    flipped = costs[1] < costs[0]
    return candidates[int(flipped)], bool(flipped)


def signed_blocks(system: KroneckerSystem, MX: np.ndarray, MY: np.ndarray,
                  orthogonalize: Callable[[np.ndarray], np.ndarray] = project_to_so3) -> tuple[tuple[np.ndarray, np.ndarray], bool]:
    """The rotations of the least-squares blocks (M_X, M_Y) of eq. 8, or of (-M_X, -M_Y), made
    rotations by `orthogonalize`, whichever leaves the smaller eq. 8 cost (translations at their
    optimum): (rotations, flipped). The rotation rows are homogeneous, so only the translation
    rows fix the blocks' sign; where they are weak against the noise (small translations, e.g.
    a wrist turning in place: kinhec small tier motion-000060, IRB 120) the least squares can
    come out near -(R_X, R_Y), and its projection ~180 deg off, while the other sign fits the
    data far better. Without a translation-eliminated cost (translations all zero) no flip."""
    try:
        cost = eliminate_translations(system)
    except DegenerateDataError:
        return (orthogonalize(MX), orthogonalize(MY)), False
    Rs, flipped = signed_rotations(cost, np.concatenate([MX.ravel(order="F"), MY.ravel(order="F")]), orthogonalize)
    return (Rs[0], Rs[1]), flipped

