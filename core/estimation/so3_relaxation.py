"""A quadratic cost over k rotations minimised under exact SO(3) constraints: the QCQP, its Shor
relaxation's constraints, the extraction of rotations, the Gauss-Newton polish on SO(3)^k and the
certificate of global optimality. Shared by `so3-sdp` for every problem (k = 1 for ``axxb``,
2 for ``axyb``, 3 for AX B = Y C Z); the SDP solvers themselves are the plugin's.

Variable y = [vec R_1; ...; vec R_k; h] (9k + 1, column-major vec), cost y^T M y
(`handeye.estimation.rotation_cost.RotationCost.matrix`). Constraints y^T A_j y = b_j, per rotation
(cf. Heller et al., ICRA 2014, and Giamou et al., RA-L 2019, for one rotation; Briales &
Gonzalez-Jimenez, CVPR 2017, for the redundant ones):

- columns orthonormal, c_i . c_j = delta_ij h^2 (6);
- rows orthonormal (redundant), rho_i . rho_j = delta_ij h^2 without |rho_3|^2, which the others
  imply (5);
- handedness (redundant), c_i x c_j = h c_k for (i, j, k) cyclic (9): excludes det = -1;

and h^2 = 1 once: 20k + 1 constraints (6k + 1 without the redundant ones), linearly independent.
The relaxation: minimise <M, Z> over Z PSD with <A_j, Z> = b_j; every feasible Z has
trace Z = 3k + 1.

Certificate (`certificate`): the SDP's multipliers nu, corrected by least squares so that
S(nu) y = 0 holds exactly at the returned y (S(nu) = M - sum_j nu_j A_j), give
<M, Z> >= b^T nu + (3k + 1) min(0, lambda_min(S)) for every feasible Z: a lower bound on the
global minimum computed in float64, independent of the SDP solver's accuracy. `is_certified`:
eigenvalue ratio lambda_2 / lambda_1 of Z below RATIO_THRESHOLD and relative gap below
GAP_THRESHOLD (their basis: docs/solvers/so3-sdp.md).
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import lapack

from handeye.base.errors import SolverError
from handeye.estimation.rotation_cost import (
    RotationCost,
    rotation_blocks,
    rotations_vector,
    signed_rotations,
    sphere_least_squares,
)
from handeye.geometry import so3_fast
from handeye.geometry.linalg import eigvalsh, lstsq, vector_norm
from handeye.geometry.se3 import project_to_so3, skew

#: Certificate thresholds (docs/solvers/so3-sdp.md: 1400 solves of ``axyb`` at m = 3, simulated
#: with noise 1x, 10x, 100x the accuracy study's and unrelated A, B; checked on ``axxb``).
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

_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0
_GENERATORS = skew(np.eye(3))  # (3, 3, 3): [e_j]_x


def dimension(rotations: int) -> int:
    """Size of y = [vec R_1; ...; vec R_k; h]: 9k + 1 (h is its last entry, index 9k)."""
    return 9 * rotations + 1


def trace_z(rotations: int) -> float:
    """trace Z of every feasible Z: 3 unit columns per rotation, plus Z_hh = 1."""
    return 3.0 * rotations + 1.0


def _entry(offset: int, row: int, col: int) -> int:
    """Index in y of R[row, col] for the rotation stored at y[offset: offset + 9]."""
    return offset + 3 * col + row


@functools.cache
def constraint_terms(rotations: int, redundant: bool = True) -> tuple[np.ndarray, ...]:
    """The constraints y^T A_j y = b_j of the module docstring, sparse: (j, p, q, c, b), each A_j
    holding c / 2 at (p, q) and at (q, p) for every term of it (j, p, q, c: (T,) arrays), b: (K,).
    K = 20k + 1 with the redundant constraints, 6k + 1 without; linearly independent. A handful of
    terms per constraint, where the dense matrices take K (9k + 1)^2 numbers: 1.1 GB at 44
    rotations (a cell of 40 cameras), 4.4 GB at 104. Read-only arrays."""
    if isinstance(rotations, bool) or not isinstance(rotations, int) or rotations < 1:
        raise ValueError(f"rotations must be an integer >= 1, got {rotations!r}")
    hom = dimension(rotations) - 1
    terms: list[tuple[int, int, int, float]] = []
    count = 0

    def quadratic(pairs: list[tuple[int, int, float]]) -> None:
        nonlocal count
        terms.extend((count, p, q, c) for p, q, c in pairs)
        count += 1

    for off in range(0, 9 * rotations, 9):
        for i in range(3):  # columns orthonormal: c_i . c_j = delta_ij h^2
            for j in range(i, 3):
                quadratic([(_entry(off, a, i), _entry(off, a, j), 1.0) for a in range(3)]
                          + ([(hom, hom, -1.0)] if i == j else []))
        if not redundant:
            continue
        for i in range(3):  # rows orthonormal: rho_i . rho_j = delta_ij h^2, except |rho_3|^2
            for j in range(i, 3):  # = h^2, which is implied (trace R^T R = trace R R^T)
                if i == j == 2:
                    continue
                quadratic([(_entry(off, i, a), _entry(off, j, a), 1.0) for a in range(3)]
                          + ([(hom, hom, -1.0)] if i == j else []))
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # handedness: c_i x c_j = h c_k
            for row in range(3):
                pairs = [(_entry(off, a, i), _entry(off, b, j), _LEVI_CIVITA[row, a, b])
                         for a in range(3) for b in range(3) if _LEVI_CIVITA[row, a, b]]
                quadratic(pairs + [(_entry(off, row, k), hom, -1.0)])
    quadratic([(hom, hom, 1.0)])  # h^2 = 1
    j, p, q, c = (np.array(column, dtype=dtype) for column, dtype in
                  zip(zip(*terms), (np.intp, np.intp, np.intp, float)))
    b = np.zeros(count)
    b[-1] = 1.0
    for array in (j, p, q, c, b):
        array.flags.writeable = False
    return j, p, q, c, b


@functools.cache
def constraint_matrices(rotations: int, redundant: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A: (K, 9k+1, 9k+1) symmetric and b: (K,) with y^T A_j y = b_j for y = [vec R_1; ...;
    vec R_k; 1], every R_i in SO(3): `constraint_terms` as dense matrices, for the SDP solvers
    (a few rotations). Read-only arrays."""
    j, p, q, c, b = constraint_terms(rotations, redundant)
    dim = dimension(rotations)
    A = np.zeros((len(b), dim, dim))
    np.add.at(A, (j, p, q), 0.5 * c)
    np.add.at(A, (j, q, p), 0.5 * c)
    A.flags.writeable = False
    return A, b


def extract_rotations(Z: np.ndarray, rotations: int) -> tuple[list[np.ndarray], np.ndarray]:
    """The k rotations of the dominant eigenvector of Z: (9k+1, 9k+1), scaled to h = 1 and
    projected onto SO(3); and the eigenvalues of Z in descending order."""
    eigenvalues, vectors = np.linalg.eigh(Z)
    v = vectors[:, -1]
    hom = dimension(rotations) - 1
    if abs(v[hom]) < 1e-6 * np.max(np.abs(v)):
        raise SolverError("so3-sdp: the dominant eigenvector of the SDP solution has no "
                          "homogeneous component; the relaxation gives no rotation estimate")
    y = v / v[hom]
    return [project_to_so3(M) for M in rotation_blocks(y[:hom])], eigenvalues[::-1]


def polish(cost: RotationCost, rotations: list[np.ndarray]) -> tuple[list[np.ndarray], int]:
    """Gauss-Newton on SO(3)^k for |S r(R_1, ..., R_k) - s|^2, R_i <- R_i exp([d_i]_x).

    Returns the rotations and the number of accepted steps. A step is kept only if it does not
    increase the cost (or is below POLISH_SMALL_STEP, where the cost cannot tell), so the result
    is never worse than the start beyond rounding.

    The residual S r - s of an accepted step is the next step's (the cost is its squared norm
    plus `rest`, as `RotationCost.value`), and the derivative of r along the steps (`_tangent`)
    is formed block by block from the rotations, exactly.
    """
    Rs = list(rotations)
    S, s, rest = cost.S, cost.s, cost.rest
    r = rotations_vector(*Rs)
    e = S @ r - s
    current = float(e @ e + rest)
    steps = 0
    for _ in range(POLISH_MAX_ITER):
        D = _tangent(Rs)  # vec(R_j [e_a]_x) in column 3j + a
        delta = _gauss_newton_step(S @ D, e)
        new_Rs = [R @ so3_fast.exp(delta[3 * j:3 * j + 3]) for j, R in enumerate(Rs)]
        r_new = rotations_vector(*new_Rs)
        e_new = S @ r_new - s
        new = float(e_new @ e_new + rest)
        size = float(np.abs(delta).max())
        if new > current and size > POLISH_SMALL_STEP:
            break
        Rs, current, e, r = new_Rs, new, e_new, r_new
        steps += 1
        if size < POLISH_STEP_TOL:
            break
    return Rs, steps


def _tangent(rotations: list[np.ndarray]) -> np.ndarray:
    """D: (9k, 3k), block diagonal, D[9j:9j+9, 3j+a] = vec(R_j [e_a]_x) (column-major vec): the
    derivative of r along R_j <- R_j exp([d]_x). Each entry of R [e_a]_x is one entry of R,
    signed (a product with 0 or +-1, summed with zeros), so D is exact. Formed block by block:
    the map from r to D as one matrix held (9k)^2 3k numbers, 2.2 GB at 104 rotations."""
    k = len(rotations)
    blocks = np.asarray(rotations, dtype=float)[:, None] @ _GENERATORS[None]  # (k, 3, 3, 3): R_j [e_a]_x
    D = np.zeros((9 * k, 3 * k))
    for j in range(k):
        D[9 * j:9 * j + 9, 3 * j:3 * j + 3] = blocks[j].transpose(0, 2, 1).reshape(3, 9).T
    return D


def _gauss_newton_step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The least-squares step d minimising |J d + e|: by Cholesky on the normal equations (LAPACK
    directly: a fifth of ``lstsq``'s time on these 18 x 6 systems, run at every solve), by
    ``lstsq`` where J^T J is not positive definite."""
    _, d, info = lapack.dposv(J.T @ J, -(J.T @ e))
    if info != 0:
        d = np.linalg.lstsq(J, -e, rcond=None)[0]
    return d


def certificate(M: np.ndarray, y: np.ndarray, nu: np.ndarray, redundant: bool) -> dict[str, float]:
    """Lower bound on the global minimum of y^T M y from multipliers nu, made exact at y.

    M: (9k+1, 9k+1); y: (9k+1,) feasible (rotations in SO(3), y_h = 1); nu: (K,) from the SDP's
    dual. nu is moved by the least-norm correction that makes S(nu) y = 0 (first-order optimality
    at y); then y'^T M y' = b^T nu + y'^T S y' >= b^T nu + (3k + 1) min(0, lambda_min(S)) for every
    feasible y' (indeed every feasible Z of the relaxation), while y^T M y = b^T nu + y^T S y.
    """
    rotations = (len(y) - 1) // 9
    j, p, q, c, b = constraint_terms(rotations, redundant)
    # (9k+1, K): the columns A_j y, summed from the constraints' terms (no dense A_j: K (9k+1)^2
    # numbers, 1.1 GB for a cell of 40 cameras)
    L = np.zeros((len(y), len(b)))
    np.add.at(L, (p, j), 0.5 * c * y[q])
    np.add.at(L, (q, j), 0.5 * c * y[p])
    correction = lstsq(L, M @ y - L @ nu)  # LAPACK directly (`handeye.geometry.linalg.lstsq`: numpy's numbers)
    nu = nu + correction
    S = np.array(M, dtype=float)
    np.subtract.at(S, (p, q), 0.5 * c * nu[j])
    np.subtract.at(S, (q, p), 0.5 * c * nu[j])
    lam = eigvalsh(S)
    lam_min = float(lam[0])
    value = float(y @ M @ y)
    lower = float(nu @ b + trace_z(rotations) * min(0.0, lam_min))
    # y is feasible, so the global minimum is <= value: a bound above it is rounding (~1e-15 |M|)
    return {"value": value, "lower_bound": min(lower, value), "dual_slack_min_eigenvalue": lam_min,
            "certificate_margin": float(lam[1]), "stationarity_residual": vector_norm(S @ y)}


def local_minimum(cost: RotationCost) -> tuple[list[np.ndarray], int]:
    """A local minimum of the QCQP without the SDP: the minimiser of |S r - s|^2 on the sphere
    |r|^2 = 3k (`sphere_least_squares`, exact), its blocks projected onto SO(3) with the sign
    that costs less (`signed_rotations`), then `polish`. Returns (rotations, polish steps).
    Whether it is the global minimum is for `local_certificate` to say."""
    start, _ = signed_rotations(cost, sphere_least_squares(cost).x)
    return polish(cost, start)


def local_certificate(M: np.ndarray, y: np.ndarray) -> dict[str, float]:
    """`certificate` of y (a local minimum, feasible) with the multipliers of the first-order
    conditions: the SDP is not solved. Only the non-redundant constraints (columns orthonormal,
    h^2 = 1) are used: their 6k + 1 multipliers are unique, the least squares of M y = sum_j
    nu_j A_j y (9k + 1 equations), where the redundant set's 20k + 1 would leave a family to
    search (an SDP again). The bound then holds over the columns-orthonormal set, which
    contains SO(3)^k, so a certified y is the global minimum over rotations as well; it is
    certified less often than the SDP's answer (docs/solvers/so3-sdp.md, "Local certificate":
    where a reflection of the answer costs less, this relaxation is not tight). Adds
    "certificate_margin": the second smallest eigenvalue of the dual slack S (its smallest is
    0, along y), the room the certificate has."""
    rotations = (len(y) - 1) // 9
    K = len(constraint_terms(rotations, redundant=False)[4])
    return certificate(M, y, np.zeros(K), redundant=False)


def is_certified(eigenvalue_ratio: float, relative_gap: float) -> bool:
    """Z rank one (ratio) and the answer's cost within GAP_THRESHOLD of the certified bound."""
    return eigenvalue_ratio < RATIO_THRESHOLD and relative_gap < GAP_THRESHOLD
