"""The Kronecker system of A_i X B_i = Y C_i Z (problem ``axbycz``), lifted to linear form.

Shared by the linear and convex solvers of ``axbycz`` (`kron-lstsq`, `lmi-sdp`): the linear
system, its O(m) normal equations, the scale constraint that makes it solvable from 10 triples,
the extraction of R_Y, R_Z from the lifted products, and the translations given the rotations.
docs/solvers/kron-lstsq.md (section ``axbycz``) has the derivation and the measurements.

**The lifting.** Write the top three rows of each side as 3x4 matrices, X_34 = [R_X | t_X]:

    top(A X B) = R_A X_34 B + t_A e4^T,        top(Y C Z) = R_Y C_34 Z + t_Y e4^T,

so vec(R_A X_34 B) = (B^T kron R_A) vec X_34 is linear in R_X, t_X (the paper's eq. 5), and
R_Y C_34 Z is linear in the products of the entries of R_Y with those of Z (column-major vec,
Z 4x4 with its constant last row): (R_Y C_34 Z)_ab = sum_jk C_jk (R_Y)_aj Z_kb. Of those products
the ones with Z's constant row are R_Y itself (Z_44 = 1) or zero, so the unknowns are

    beta = [r; tau]  (132),  r = [vec R_X (9); vec P (81)],  tau = [t_X (3); vec Q (27); vec R_Y (9); t_Y (3)],
    P = vec(R_Y) vec(R_Z)^T  (9 x 9),   Q = vec(R_Y) t_Z^T  (9 x 3),

which is the lifting of Wu et al. (IEEE T-RO 32(2), 2016, Sec. III) written with rotation matrices
instead of their quaternions: X enters linearly, Y and Z through their products (their
q_Y kron q_Z, here vec R_Y vec R_Z^T). Rotation matrices carry no sign ambiguity, so no sign has to
be guessed per triple (Wu's closed form enumerates them, `handeye.plugins.axbycz_wu`). Per triple
12 rows H_i beta = w_i: 9 rotation rows that involve r only (homogeneous: R_A R_X R_B = R_Y R_C R_Z)
and 3 translation rows with right-hand side -t_A (`regression_blocks`).

**Sums.** H^T H (132 x 132), H^T w and |w|^2 are sums over the triples of Kronecker products of
(B B^T, R_A^T R_A), (B, vec C_34, R_A^T), (vec C_34 vec C_34^T, I) ... (`normal_equations`): a few
BLAS products, O(m), no (12m x 132) matrix.

**How many triples.** The rotation rows determine r up to its scale from 10 triples (90 unknowns,
9 rows each, null space {a r*} when both robots move). The scale, as for A X = Y B (paper eq. 8),
could only come from the translation rows, and those see 42 unknowns of their own (tau) besides
the scale: 3 rows per triple determine them from 15 triples on. With 10 to 14 triples the paper's
unconstrained least squares (its eq. 14) has no unique solution; so, as for A X = X B
(docs/solvers/kron-lstsq.md), the cost is kept and the scale fixed by the norm every rotation
has: |r|^2 = |vec R_X|^2 + |vec R_Y|^2 |vec R_Z|^2 = 3 + 9 = 12 (`LiftedCost`,
`sphere_least_squares`). tau is minimised out in closed form (with a pseudo-inverse: below 14
triples tau is not determined given r, and then the translation rows do not inform the
rotations at all).

**Extraction.** R_X from vec R_X; R_Y and R_Z from the nearest rank-one matrix to P (its leading
singular pair: the nearest Kronecker product R_Z^T kron R_Y in Van Loan's sense); the common sign
of r (the sphere allows -r) and the sign of the pair (y, z) (P = y z^T = (-y)(-z)^T) are chosen
as the lower cost after orthogonalising (`extract_rotations`). Translations: least squares given
the rotations (Wu et al.'s eq. 38, `solve_translations`), or from tau (`tau_translations`).

**Units.** Translations are divided by `scale` (the data's RMS translation when a solver
normalises) before the sums are taken, which balances the rotation and translation rows and makes
the answer independent of the length unit.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from handeye.base.errors import DegenerateDataError, SolverError
from handeye.estimation.kronecker import overflow_error
from handeye.estimation.trust_region import TrustRegionSolution, solve_trust_region
from handeye.geometry.se3 import project_to_so3
from handeye.problems.axbycz.data import AXBYCZData

#: beta = [r; tau]: where each unknown sits
R_X, P_YZ = slice(0, 9), slice(9, 90)
T_X, Q_YZ, R_Y, T_Y = slice(90, 93), slice(93, 120), slice(120, 129), slice(129, 132)
N_R, N_BETA = 90, 132
#: |r|^2 of exact rotations: |vec R_X|^2 + |vec R_Y|^2 |vec R_Z|^2
SPHERE = 12.0
#: fewest triples with which the rotation rows can determine r (90 unknowns, 9 rows a triple)
MIN_TRIPLES = 10
#: fewest triples with which the translation rows determine tau given r (42 unknowns, 3 rows each)
MIN_TRIPLES_TAU = 14
#: ... and tau together with the scale of r (43 unknowns): the unconstrained system has full rank
MIN_TRIPLES_UNCONSTRAINED = 15
#: eigenvalues of the (equilibrated) tau block below this, relative to its largest, count as zero
RANK_RTOL = 1e-12
#: the rotations are undetermined (a second null direction of the rotation rows) when the second
#: smallest eigenvalue of their Gram matrix is below this, relative to its largest
UNDETERMINED_RTOL = 1e-10
#: `check_rotations` gap (second / first eigenvalue of the rotation rows' Gram matrix) below which
#: a warning says the rotations are barely determined. Measured with 0.002 rad / 0.2 mm noise, 10
#: seeds: 1.0 ... 8.6 on structurally undetermined data (one robot still for half of 12 or 14
#: triples), >= 12 with 10 triples of free motion, >= 370 with 12, >= 4500 with 30.
WEAK_GAP = 10.0


def _selection() -> np.ndarray:
    """index (132,): beta[j] = beta'[index[j]], beta' = [vec X_34 (12); vec(vec R_Y vec(Z)^T) (144);
    t_Y (3)] the unknowns of the 3x4 form (Z: 4x4 with its constant row; each entry of beta
    appears once in beta', and the entries (vec R_Y)_p Z[3, :3] = 0 of beta' are none of beta's)."""
    index = np.zeros(N_BETA, dtype=int)
    index[R_X] = np.arange(9)
    index[T_X] = np.arange(9, 12)
    index[T_Y] = np.arange(156, 159)
    for row in range(4):
        for col in range(4):
            for p in range(9):
                i = 12 + p + 9 * (row + 4 * col)  # (vec R_Y)_p Z[row, col]
                if row < 3 and col < 3:
                    index[P_YZ.start + p + 9 * (row + 3 * col)] = i
                elif row < 3:
                    index[Q_YZ.start + p + 9 * row] = i
                elif col == 3:
                    index[R_Y.start + p] = i
    return index


SELECTION = _selection()
SELECTION.setflags(write=False)


def lift(X: np.ndarray, Y: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """beta (132,) of the poses X, Y, Z (4x4): the lifted unknowns they stand for."""
    y = Y[:3, :3].ravel(order="F")
    beta = np.zeros(N_BETA)
    beta[R_X] = X[:3, :3].ravel(order="F")
    beta[P_YZ] = np.outer(y, Z[:3, :3].ravel(order="F")).ravel(order="F")
    beta[T_X] = X[:3, 3]
    beta[Q_YZ] = np.outer(y, Z[:3, 3]).ravel(order="F")
    beta[R_Y] = y
    beta[T_Y] = Y[:3, 3]
    return beta


def rotations_vector(RX: np.ndarray, RY: np.ndarray, RZ: np.ndarray) -> np.ndarray:
    """r (90,) of three rotations: [vec R_X; vec(vec R_Y vec R_Z^T)]."""
    return np.concatenate([RX.ravel(order="F"),
                           np.outer(RY.ravel(order="F"), RZ.ravel(order="F")).ravel(order="F")])


def _stacks(data: AXBYCZData, scale: float) -> tuple[np.ndarray, ...]:
    A, B, C = data.A, data.B, data.C
    RA, tA = A[:, :3, :3], A[:, :3, 3] / scale
    B4 = B.copy()
    B4[:, :3, 3] /= scale
    C34 = C[:, :3, :4].copy()
    C34[:, :, 3] /= scale
    c = C34.transpose(0, 2, 1).reshape(len(C), 12)  # vec C_34, column-major
    return RA, tA, B4, c


def regression_blocks(data: AXBYCZData, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The per-triple blocks H_i: (m, 12, 132) and w_i: (m, 12) (translations divided by scale),
    for tests and checks; solvers use `normal_equations`."""
    RA, tA, B4, c = _stacks(data, scale)
    m = data.m
    Hp = np.zeros((m, 12, 159))
    Hp[:, :, :12] = np.einsum("ivu,iab->iuavb", B4, RA).reshape(m, 12, 12)  # B^T kron R_A
    Hp[:, :, 12:156] = -np.einsum("bd,in,ae->ibadne", np.eye(4), c, np.eye(3)).reshape(m, 12, 144)
    Hp[:, 9:, 156:] = -np.eye(3)
    w = np.zeros((m, 12))
    w[:, 9:] = -tA
    return Hp[:, :, SELECTION], w


def normal_equations(data: AXBYCZData, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """N = H^T H (132, 132), g = H^T w (132,), w^T w of the lifted system with every translation
    divided by `scale`, from sums over the triples (module docstring). InputError when they
    overflow."""
    RA, tA, B4, c = _stacks(data, scale)
    m = data.m
    with np.errstate(over="ignore", invalid="ignore"):
        n = np.zeros((159, 159))
        BBt = B4 @ B4.transpose(0, 2, 1)
        AtA = RA.transpose(0, 2, 1) @ RA
        n[:12, :12] = (BBt.reshape(m, 16).T @ AtA.reshape(m, 9)).reshape(4, 4, 3, 3).transpose(0, 2, 1, 3).reshape(12, 12)
        # K^T Phi = B kron c^T kron R_A^T; K^T T = (B e4) kron R_A^T; Phi^T T = e4 kron c kron I
        BA = np.einsum("iuv,its->iusvt", B4, RA).reshape(m, 144)  # B[u, v] R_A[t, s]
        KtPhi = (BA.T @ c).reshape(4, 3, 4, 3, 12).transpose(0, 1, 2, 4, 3).reshape(12, 144)
        n[:12, 12:156] = -KtPhi
        n[:12, 156:] = -np.einsum("iu,its->ust", B4[:, :, 3], RA).reshape(12, 3)
        Gc = c.T @ c
        n[12:156, 12:156] = np.kron(np.eye(4), np.kron(Gc, np.eye(3)))
        n[12 + 108:156, 156:] = np.kron(c.sum(axis=0)[:, None], np.eye(3))  # block b = 3 of e4 kron ...
        n[156:, 156:] = m * np.eye(3)
        n = np.triu(n) + np.triu(n, 1).T
        gp = np.zeros(159)
        RAt_tA = np.einsum("ias,ia->is", RA, tA)
        gp[:12] = -(B4[:, :, 3].T @ RAt_tA).reshape(12)
        gp[12 + 108:156] = (c.T @ tA).reshape(36)
        gp[156:] = tA.sum(axis=0)
        ww = float(np.sum(tA * tA))
        N = n[np.ix_(SELECTION, SELECTION)]
        g = gp[SELECTION]
    if not (np.all(np.isfinite(N)) and np.all(np.isfinite(g)) and np.isfinite(ww)):
        raise overflow_error("the sums of the lifted linear system")
    return N, g, ww


@dataclasses.dataclass(frozen=True)
class LiftedCost:
    """|H beta - w|^2 with tau minimised out: r^T P r - 2 p^T r + c for r (90,), P: (90, 90)
    PSD, p: (90,), c >= 0; `tau(r)` the minimiser (the one of least equilibrated norm when tau
    is not determined: `translation_rank` < 42, fewer than 14 triples)."""

    P: np.ndarray
    p: np.ndarray
    c: float
    d_r: np.ndarray  # equilibration of r and of tau (beta_s = D beta)
    d_t: np.ndarray
    pinv: np.ndarray  # pseudo-inverse of the equilibrated tau block
    N_tr: np.ndarray  # equilibrated tau-r block
    g_t: np.ndarray
    translation_rank: int

    @classmethod
    def from_normal_equations(cls, N: np.ndarray, g: np.ndarray, ww: float) -> LiftedCost:
        d = np.sqrt(np.diag(N))
        d = np.where(d > 0, d, 1.0)
        Ns, gs = N / np.outer(d, d), g / d
        lam, V = np.linalg.eigh(Ns[N_R:, N_R:])
        keep = lam > RANK_RTOL * max(float(lam[-1]), 0.0)
        Vk = V[:, keep]
        pinv = (Vk / lam[keep]) @ Vk.T
        N_tr, g_t = Ns[N_R:, :N_R], gs[N_R:]
        d_r = d[:N_R]
        P = (Ns[:N_R, :N_R] - N_tr.T @ pinv @ N_tr) * np.outer(d_r, d_r)
        p = (gs[:N_R] - N_tr.T @ pinv @ g_t) * d_r
        c = float(ww - g_t @ pinv @ g_t)
        return cls(P=0.5 * (P + P.T), p=p, c=max(c, 0.0), d_r=d_r, d_t=d[N_R:], pinv=pinv, N_tr=N_tr,
                   g_t=g_t, translation_rank=int(keep.sum()))

    @property
    def translations_determined(self) -> bool:
        return self.translation_rank == N_BETA - N_R

    def value(self, r: np.ndarray) -> float:
        """The cost |H beta - w|^2 at r with tau at its optimum."""
        return float(r @ self.P @ r - 2.0 * self.p @ r + self.c)

    def tau(self, r: np.ndarray) -> np.ndarray:
        """The tau (42,) minimising the cost for r."""
        return (self.pinv @ (self.g_t - self.N_tr @ (self.d_r * r))) / self.d_t


def lifted_cost(data: AXBYCZData, scale: float = 1.0) -> LiftedCost:
    """`LiftedCost` of the data with translations divided by `scale`."""
    return LiftedCost.from_normal_equations(*normal_equations(data, scale))


def check_triples(data: AXBYCZData, solver: str, needed: int = MIN_TRIPLES, why: str = "") -> None:
    """DegenerateDataError unless the data have at least `needed` triples."""
    if data.m < needed:
        reason = why or (f"its lifted rotation system has 90 unknowns and 9 equations per triple, "
                         f"so it needs at least {needed} triples")
        raise DegenerateDataError(f"{solver} for axbycz: {reason}; got {data.m}. Record more triples "
                                  "(both robots moving), or use solver 'wang' or 'wu', which need fewer")


def rotation_gram(data: AXBYCZData) -> np.ndarray:
    """G: (90, 90), sum_i H_rot,i^T H_rot,i of the rotation rows (which do not see translations):
    its null space is {a r*} when the data determine the rotations."""
    return normal_equations(data, np.inf)[0][:N_R, :N_R]


def check_rotations(data: AXBYCZData, solver: str) -> float:
    """DegenerateDataError when the rotation rows leave more than the scale of r free (second
    smallest eigenvalue of `rotation_gram` <= UNDETERMINED_RTOL of the largest: robot 2 not moving,
    too few distinct poses, rotations about one axis only); else lambda_2 / lambda_1 of it (inf
    for exact data), how far the null direction stands out."""
    lam = np.linalg.eigvalsh(rotation_gram(data))
    if lam[1] <= UNDETERMINED_RTOL * lam[-1]:
        raise DegenerateDataError(
            f"{solver} for axbycz: the triples do not determine the rotations of X, Y and Z (the lifted "
            "rotation system has more than one null direction). Both robots must move between the triples, "
            "each rotating about at least two different axes, through at least 10 different poses")
    return float(lam[1] / lam[0]) if lam[0] > 0 else float("inf")


def weak_rotations(gap: float, solver: str) -> list[str]:
    """The warning for a `check_rotations` gap below WEAK_GAP (empty list otherwise)."""
    if gap >= WEAK_GAP:
        return []
    return [(f"{solver}: the triples barely determine the rotations of X, Y and Z: the null direction of the "
             f"lifted rotation system stands out by a factor {gap:.2g} only (< {WEAK_GAP:g}); record triples in "
             "which both robots move, each about several axes")]


def sphere_least_squares(cost: LiftedCost) -> TrustRegionSolution:
    """The r minimising the cost on |r|^2 = 12, exactly (`handeye.estimation.trust_region`)."""
    return solve_trust_region(cost.P, cost.p, float(np.sqrt(SPHERE)))


@dataclasses.dataclass(frozen=True)
class RotationEstimate:
    """Rotations from r with the blocks before orthogonalisation (`extract_rotations`)."""

    rotations: tuple[np.ndarray, np.ndarray, np.ndarray]  # R_X, R_Y, R_Z
    blocks: tuple[np.ndarray, np.ndarray, np.ndarray]  # M_X, M_Y, M_Z (signed)
    rank_one_ratio: float  # sigma_2 / sigma_1 of P: 0 for exact products
    flipped: bool  # -r was taken


def extract_rotations(r: np.ndarray, cost: LiftedCost,
                      orthogonalize: Callable[[np.ndarray], np.ndarray] = project_to_so3) -> RotationEstimate:
    """R_X, R_Y, R_Z of r (90,): M_X = unvec r[:9]; P = unvec r[9:] ~ s1 u v^T (leading singular
    pair), M_Y = sqrt(s1) unvec u, M_Z = sqrt(s1) unvec v, each made a rotation by `orthogonalize`.
    The sign of r and of (u, v) is free: of the candidates (r or -r; (u, v) signed so that det M_Y
    > 0) the one of lower `cost` after orthogonalising is returned."""
    M_X = r[R_X].reshape(3, 3, order="F")
    U, s, Vt = np.linalg.svd(r[P_YZ].reshape(9, 9, order="F"))
    root = np.sqrt(s[0])
    u, v = root * U[:, 0], root * Vt[0]
    if np.linalg.det(u.reshape(3, 3, order="F")) < 0:
        u, v = -u, -v
    best = None
    for sign in (1.0, -1.0):
        blocks = (sign * M_X, u.reshape(3, 3, order="F"), sign * v.reshape(3, 3, order="F"))
        with np.errstate(divide="ignore", invalid="ignore"):
            rotations = tuple(orthogonalize(M) for M in blocks)
        if not all(np.all(np.isfinite(R)) for R in rotations):
            continue
        value = cost.value(rotations_vector(*rotations))
        if best is None or value < best[0]:
            best = (value, rotations, blocks, sign < 0)
    if best is None:
        raise SolverError("the lifted solution has a zero rotation block, which cannot be made a rotation; "
                          "use solver 'auto'")
    ratio = float(s[1] / s[0]) if s[0] > 0 else float("inf")
    return RotationEstimate(rotations=best[1], blocks=best[2], rank_one_ratio=ratio, flipped=best[3])


def tau_translations(tau: np.ndarray, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t_X, t_Y, t_Z (data units) from tau: t_X, t_Y as they are, t_Z = Q^T y / |y|^2 (the least
    squares of Q = y t_Z^T for the lifted y = vec R_Y)."""
    Q = tau[Q_YZ.start - N_R:Q_YZ.stop - N_R].reshape(9, 3, order="F")
    y = tau[R_Y.start - N_R:R_Y.stop - N_R]
    tZ = Q.T @ y / float(y @ y) if float(y @ y) > 0 else np.zeros(3)
    return tau[:3] * scale, tau[T_Y.start - N_R:] * scale, tZ * scale


def solve_translations(data: AXBYCZData, RX: np.ndarray, RY: np.ndarray,
                       RZ: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t_X, t_Y, t_Z by least squares given the rotations (Wu et al. 2016, eq. 38):

        R_Ai t_X - t_Y - R_Y R_Ci t_Z = R_Y t_Ci - t_Ai - R_Ai R_X t_Bi    (3 rows per triple),

    through its 9x9 normal equations (one pass over the triples). R_Z does not enter (accepted for
    symmetry). DegenerateDataError when they are singular."""
    RA, tA, tB, tC = data.A[:, :3, :3], data.A[:, :3, 3], data.B[:, :3, 3], data.C[:, :3, 3]
    m = data.m
    J = np.empty((m, 3, 9))
    J[:, :, :3] = RA
    J[:, :, 3:6] = -np.eye(3)
    J[:, :, 6:] = -RY @ data.C[:, :3, :3]
    rhs = tC @ RY.T - tA - np.einsum("iab,ib->ia", RA, tB @ RX.T)
    JtJ = np.einsum("iak,ial->kl", J, J)
    Jtp = np.einsum("iak,ia->k", J, rhs)
    lam = np.linalg.eigvalsh(JtJ)
    if not lam[0] > 1e-12 * lam[-1]:
        raise DegenerateDataError(
            "the translations of X, Y and Z cannot be determined from these triples: robot 1's poses (A) and "
            "robot 2's (C) must each rotate about at least two different axes")
    t = np.linalg.solve(JtJ, Jtp)
    return t[:3], t[3:6], t[6:]
