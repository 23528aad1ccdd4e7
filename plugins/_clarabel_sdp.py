"""A dual-form SDP in Clarabel's own API: max b^T nu s.t. C - sum_k nu_k A_k PSD, with C (n, n)
given per solve and the A_k, b fixed. Used by `so3-sdp` (backend ``clarabel``) for the Lagrangian
dual of its Shor relaxation (handeye.so3_relaxation); written for any such SDP.

Clarabel solves min 1/2 x^T P x + q^T x s.t. A x + s = b, s in K. Here (P = 0):

    x = nu (K),   q = -b,   A = [svec A_1 ... svec A_K],   b_clarabel = svec C,
    s = svec(C - sum_k nu_k A_k) in the PSD cone (`clarabel.PSDTriangleConeT(n)`).

Clarabel's dual, max -b_clarabel^T z s.t. A^T z = -q, z in K* (the PSD cone is self-dual), is then
min <C, Z> s.t. <A_k, Z> = b_k, Z PSD with Z = unsvec(z): the primal SDP (for so3-sdp, the Shor
relaxation). A primal-dual interior-point method returns both from one solve.

svec (Clarabel's convention, `PSDTriangleConeT`): the upper triangle stacked column by column,
(0,0), (0,1), (1,1), (0,2), (1,2), (2,2), ..., off-diagonal entries multiplied by sqrt(2), so that
svec(X) . svec(Y) = <X, Y> = trace(X Y) for symmetric X, Y. `unsvec` inverts it. Tested against
an SDP with a known answer (tests/test_so3_sdp.py).

Everything that does not depend on C (A as a CSC matrix, q, the cone, the svec indices) is built
once (`DualSDP.build`); a solve forms svec C and one `clarabel.DefaultSolver`. A `DualSDP` is
immutable and a solve creates its own solver and settings, so one instance may serve several
threads at once.

`solve_conic` is the one place that creates and runs a `clarabel.DefaultSolver` (settings, the
fallback for an installed Clarabel without "faer", errors as SolverError); `DualSDP` and the
native backend of `lmi-sdp` (handeye.plugins.lmi_sdp_clarabel) both use it.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.framework.errors import SolverError

#: Clarabel's statuses with a usable solution -> the status reported (cvxpy's names, so that both
#: so3-sdp backends report the same ``sdp_status``); any other status is a SolverError.
STATUSES: Mapping[str, str] = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate"}


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
