"""Backend ``clarabel`` of `lmi-sdp`: the paper's LMI (Pan et al., IEEE T-ASE 2022, eq. 14) and its
AX = XB and AXB = YCZ variants stated in Clarabel's own API (`clarabel.DefaultSolver`), without a
modelling layer. Called by `handeye.plugins.lmi_sdp.axyb`, `handeye.plugins.lmi_sdp.axxb` and
`handeye.plugins.lmi_sdp.axbycz`.

Clarabel solves min 1/2 x^T P x + q^T x s.t. A x + s = b, s in K (P = 0 here). Everything that
does not depend on the data (the sparsity pattern of A, the cones, P, and whichever of q, b are
constant) is built once per problem size and cached (`eq14_structure`, `axxb_sdp`,
`axbycz_structure`); a solve fills in the data-dependent values only and runs one solver
(`handeye.plugins._sdp_backends.solve_conic`).

Eq. 14, scaled (`handeye.plugins.lmi_sdp.axyb.ScaledLMI`: R (n, n) upper triangular, q (n,), rest):
x = [u; gamma] (n + 1), q_clarabel = e_1 (minimise u), one cone PSDTriangleConeT(n + 1) holding

    s = svec(L),  L = [[u - rest, (R gamma - q)^T], [R gamma - q, I_n]]                 (eq. 14)

(svec: the upper triangle column by column, off-diagonal entries times sqrt(2), `svec_indices`).
Entry (0, 0) of L is u - rest, entry (0, j) is (R gamma - q)_j (j = 1..n), the diagonal of I_n is 1, the
rest of the lower block 0. With s = b - A x: b holds -rest, -sqrt(2) q and the ones of I_n; A has
-1 for u and -sqrt(2) R[i, k] in the row of L's entry (0, i + 1), column gamma_k. R is triangular
(eqs. 10-12: the Cholesky factor of the normal equations), so A's pattern is fixed per n: a solve
replaces A's data array (n (n + 1) / 2 + 1 values) and three parts of b.
Clarabel's chordal decomposition finds the arrow pattern of L (row 0, the diagonal) and splits the
(n + 1) x (n + 1) cone into n 2 x 2 cliques {0, j} (merging none: ~0.7 ms per solve at n = 24,
the default clique-graph merge ~1.5 ms, without decomposition ~25 ms), the same problem the
``cvxpy`` backend hands Clarabel.

AX = XB (`handeye.plugins.lmi_sdp.axxb`): min <M, Z> s.t. trace W = 3, Z_hh = 1, Z (10 x 10) PSD is
the primal whose Lagrangian dual max 3 lambda + mu s.t. M - lambda diag(I_9, 0) - mu e_10 e_10^T
PSD `handeye.plugins._sdp_backends.DualSDP` states (2 variables, one PSD cone); Z is Clarabel's dual
variable of that cone. Only M changes between solves.

AXB = YCZ (`handeye.plugins.lmi_sdp.axbycz`, scale "norm"): x = [w; rho] (90 + 90),
min d^T w - 2 p^T rho s.t. sum w = 12 (a ZeroConeT(1)) and [[w_k, rho_k], [rho_k, 1]] PSD (90
PSDTriangleConeT(2)); A and b are constant, only q_clarabel = [d; -2 p] changes.

Statuses: Clarabel's Solved -> optimal, AlmostSolved -> optimal_inaccurate (the names of the
``cvxpy`` backend, `handeye.plugins._sdp_backends.STATUSES`); anything else is a SolverError
naming Clarabel and its status. The cached structures are immutable and every solve creates its
own solver, so solves need no lock.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import Status
from handeye.base.errors import SolverError
from handeye.plugins._sdp_backends import (
    CLARABEL_TIGHT,
    STATUSES,
    DualSDP,
    SolveRecord,
    solve_conic,
    svec,
    svec_indices,
    unsvec,
)

#: Clarabel settings of the AX = XB and AXB = YCZ SDPs: the gap and feasibility tolerances of their
#: cvxpy backends (1e-12; the polish after them does the rest). Other settings of so3-sdp's
#: `CLARABEL_SETTINGS` (one thread, faer, no presolve) changed no time here by more than the
#: noise (measured at n = 24 and 132, on both SDPs; docs/solvers/lmi-sdp.md), so Clarabel's
#: defaults stand; iterative refinement must stay on (without it beta of eq. 14 lost up to 6e-9).
SDP_SETTINGS: Mapping[str, Any] = CLARABEL_TIGHT
#: Clarabel settings of eq. 14: the tolerances as for the cvxpy backend (u to ~1e-13 relative;
#: beta is exact either way) and the chordal decomposition into the n 2 x 2 cliques of the arrow
#: without merging (the default merge: 1.5 ms instead of 0.75 at n = 24, 300 ms instead of 13 at
#: n = 132).
CLARABEL_SETTINGS: Mapping[str, Any] = types.MappingProxyType({
    **SDP_SETTINGS, "chordal_decomposition_merge_method": "none",
})
#: The name reported as ``backend_solver`` (as the cvxpy backend and so3-sdp's native one do).
SOLVER = "CLARABEL"


@dataclasses.dataclass(frozen=True)
class NativeSolution:
    """x: (n,) Clarabel's primal variables; z: (m,) the cone duals; status: the mapped status
    (`STATUSES`); record: the solve (solver_status: the mapped status's name, backend_solver
    `SOLVER`, iterations); solve_seconds as Clarabel has it."""

    x: np.ndarray
    z: np.ndarray
    status: Status
    record: SolveRecord
    solve_seconds: float


def _run(P: Any, q: np.ndarray, A: Any, b: np.ndarray, cones: list[Any], settings: Mapping[str, Any],
         what: str) -> NativeSolution:
    """One Clarabel solve; SolverError naming Clarabel's status unless it is usable."""
    solution = solve_conic(P, q, A, b, cones, settings, "lmi-sdp")
    raw = str(solution.status)
    mapped = STATUSES.get(raw)
    if mapped is None:
        raise SolverError(f"lmi-sdp: clarabel returned status {raw!r} for {what} (after "
                          f"{solution.iterations} iterations); no solution is returned")
    return NativeSolution(np.array(solution.x, dtype=float), np.array(solution.z, dtype=float), Status(mapped),
                          SolveRecord(mapped, SOLVER, int(solution.iterations)), float(solution.solve_time))


# --------------------------------------------------------------------------------------------
# eq. 14


@dataclasses.dataclass(frozen=True)
class Eq14Structure:
    """The data-independent part of eq. 14 for n unknowns (module docstring): A's CSC pattern,
    the svec positions of the data in b, P, q and the cone."""

    n: int
    indptr: np.ndarray  # (n + 2,)
    indices: np.ndarray  # (n (n + 1) / 2 + 1,) rows of A's nonzeros, column by column
    R_rows: np.ndarray  # (n (n + 1) / 2,) R[R_rows, R_cols]: A's gamma entries in CSC order
    R_cols: np.ndarray
    first_row: np.ndarray  # (n,) svec positions of L's entries (0, 1..n)
    b_constant: np.ndarray  # ((n + 1) (n + 2) / 2,) b without the data: the ones of I_n
    P: Any
    q: np.ndarray
    cones: tuple[Any, ...]

    @classmethod
    def build(cls, n: int) -> Eq14Structure:
        import clarabel
        import scipy.sparse as sp

        j = np.arange(1, n + 1)
        first_row = j * (j + 1) // 2  # svec position of (0, j): column j starts there
        diagonal = first_row + j  # of (j, j)
        R_rows, R_cols, _ = svec_indices(n)  # upper triangle of R, column by column: CSC order
        indices = np.concatenate([[0], first_row[R_rows]]).astype(np.int64)
        indptr = np.concatenate([[0], 1 + j * (j - 1) // 2, [1 + n * (n + 1) // 2]]).astype(np.int64)
        size = (n + 1) * (n + 2) // 2
        b = np.zeros(size)
        b[diagonal] = 1.0
        q = np.zeros(n + 1)
        q[0] = 1.0
        for a in (indptr, indices, first_row, b, q):
            a.flags.writeable = False
        return cls(n, indptr, indices, R_rows, R_cols, first_row, b, sp.csc_matrix((n + 1, n + 1)), q,
                   (clarabel.PSDTriangleConeT(n + 1),))

    def data(self, R: np.ndarray, q: np.ndarray, rest: float) -> tuple[Any, np.ndarray]:
        """A (CSC, the cached pattern) and b for R: (n, n) upper triangular, q: (n,), rest."""
        import scipy.sparse as sp

        values = np.empty(len(self.indices))
        values[0] = -1.0
        np.multiply(R[self.R_rows, self.R_cols], -np.sqrt(2.0), out=values[1:])
        A = sp.csc_matrix((values, self.indices, self.indptr), shape=(len(self.b_constant), self.n + 1))
        b = self.b_constant.copy()
        b[0] = -rest
        b[self.first_row] = -np.sqrt(2.0) * q
        return A, b


@functools.cache
def eq14_structure(n: int) -> Eq14Structure:
    """`Eq14Structure` for n unknowns (24: ``axyb``; 132: the lifted system of ``axbycz``), built
    once per n in this process (`eq14_structure.cache_info()` counts the builds)."""
    return Eq14Structure.build(n)


def solve_eq14(R: np.ndarray, q: np.ndarray, rest: float) -> NativeSolution:
    """Eq. 14 scaled (`handeye.plugins.lmi_sdp.axyb.ScaledLMI`: R (n, n) upper triangular, q (n,),
    rest): x = [u; gamma]. ValueError when R is not upper triangular (the cached pattern holds
    only that triangle)."""
    n = len(q)
    if np.any(np.tril(R, -1)):
        raise ValueError("lmi-sdp: the clarabel backend of eq. 14 needs an upper triangular R")
    structure = eq14_structure(n)
    A, b = structure.data(R, q, rest)
    return _run(structure.P, structure.q, A, b, list(structure.cones), CLARABEL_SETTINGS,
                "the semidefinite program")


# --------------------------------------------------------------------------------------------
# AX = XB: min <M, Z> s.t. trace W = 3, Z_hh = 1, Z PSD, as the dual of a DualSDP


@functools.cache
def axxb_sdp() -> DualSDP:
    """The AX = XB SDP's constant data (`DualSDP` with A_1 = diag(I_9, 0), b_1 = 3 and A_2 =
    e_10 e_10^T, b_2 = 1), built once."""
    A1 = np.diag(np.r_[np.ones(9), 0.0])
    A2 = np.zeros((10, 10))
    A2[9, 9] = 1.0
    return DualSDP.build(np.stack([A1, A2]), np.array([3.0, 1.0]))


def solve_axxb(M: np.ndarray, what: str) -> tuple[np.ndarray, float, NativeSolution]:
    """min <M, Z> s.t. trace Z[:9, :9] = 3, Z[9, 9] = 1, Z PSD for M: (10, 10) symmetric:
    (Z (10, 10), the optimal value 3 lambda + mu, the raw solution)."""
    sdp = axxb_sdp()
    solution = _run(sdp.P, sdp.q, sdp.A, svec(M), list(sdp.cones), SDP_SETTINGS, what)
    return unsvec(solution.z, 10), float(-sdp.q @ solution.x), solution


# --------------------------------------------------------------------------------------------
# AXB = YCZ, scale "norm": 90 2 x 2 LMIs and sum w = 12


@dataclasses.dataclass(frozen=True)
class ArrowStructure:
    """The constant A, b, P and cones of min d^T w - 2 p^T rho s.t. sum w = sphere,
    [[w_i, rho_i], [rho_i, 1]] PSD (i < k): x = [w; rho] (2 k)."""

    k: int
    A: Any
    b: np.ndarray
    P: Any
    cones: tuple[Any, ...]

    @classmethod
    def build(cls, k: int, sphere: float) -> ArrowStructure:
        import clarabel
        import scipy.sparse as sp

        ks = np.arange(k)
        # row 0: sum w; rows 1 + 3i, 2 + 3i, 3 + 3i: svec [[w_i, rho_i], [rho_i, 1]] = b - A x
        rows = np.concatenate([np.zeros(k, dtype=np.int64), 1 + 3 * ks, 2 + 3 * ks])
        cols = np.concatenate([ks, ks, k + ks])
        values = np.concatenate([np.ones(k), -np.ones(k), -np.sqrt(2.0) * np.ones(k)])
        A = sp.csc_matrix((values, (rows, cols)), shape=(1 + 3 * k, 2 * k))
        b = np.zeros(1 + 3 * k)
        b[0] = sphere
        b[3 + 3 * ks] = 1.0
        b.flags.writeable = False
        cones = (clarabel.ZeroConeT(1), *[clarabel.PSDTriangleConeT(2)] * k)
        return cls(k, A, b, sp.csc_matrix((2 * k, 2 * k)), cones)


@functools.cache
def axbycz_structure(k: int, sphere: float) -> ArrowStructure:
    """`ArrowStructure` for k lifted rotation unknowns (90) and |r|^2 = sphere (12), built once."""
    return ArrowStructure.build(k, sphere)


def solve_axbycz(d: np.ndarray, p: np.ndarray, sphere: float, what: str) -> NativeSolution:
    """min d^T w - 2 p^T rho s.t. sum w = sphere, [[w_k, rho_k], [rho_k, 1]] PSD, for d, p: (k,):
    x = [w; rho]."""
    structure = axbycz_structure(len(d), sphere)
    return _run(structure.P, np.concatenate([d, -2.0 * p]), structure.A, structure.b.copy(),
                list(structure.cones), SDP_SETTINGS, what)
