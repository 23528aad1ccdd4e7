"""Linear least squares of the Kronecker-product methods, shared by every problem.

The rotation equations of hand-eye problems are linear in the entries of the unknown rotations
once written with Kronecker products (vec(P R Q) = (Q^T kron P) vec(R), column-major vec, as in
the paper's eqs. 5-8); the translation equations are linear in those entries and the unknown
translations. Each problem (``axyb``: eq. 8; ``axxb``: its analogue) states its system H beta = w
through sums over the pairs, taken once here in O(m) (`kron_sum`, `TranslationSums`), and reduces
it to the 24x24 (or smaller) triangular form of eqs. 10-12 (`reduce_normal_equations`,
`KroneckerSystem`), so that no solver's cost grows with m beyond that reduction.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.framework.caching import cached_property
from handeye.geometry.linalg import cholesky_upper, solve_triangular
from handeye.geometry.se3 import gram


def overflow_error(where: str) -> InputError:
    """The error for data whose sums over the pairs overflow float64 (huge translations)."""
    return InputError(
        f"the translations of the poses are too large: {where} overflow float64 (translations of "
        "order 1e150 or more). Express the translations in a larger unit (e.g. m instead of um) "
        "and solve again"
    )


#: Smallest accepted largest translation entry max |t| (data units) of data whose translations
#: are not all exactly zero. Below it the least squares under- and overflow float64: the solvers square
#: translations and weigh residuals by 1 / sigma^2, with sigma floored at 1e-12 times the RMS
#: translation s (`handeye.estimation.whitening.SIGMA_FLOOR`), so they form numbers of order s^2 and
#: 1 / (1e-12 s)^2, which leave float64's normal range (2e-308 .. 2e308) from s ~ 1e-142 on
#: (measured with every solver: overflow warnings from max |t| ~ 2e-142 on, a ZeroDivisionError
#: at ~2e-152).
#: 1e-100 keeps a margin of 1e40 in the squares; no measurement is that small in any length
#: unit (a proton is 1e-15 m), so such data are a unit mix-up or rounding noise, and an error
#: saying so serves better than solving them through a rescaling of every solver's input.
MIN_TRANSLATION = 1e-100


def underflow_error(largest: float) -> InputError:
    """The error for data whose translations are too small to compute with (`MIN_TRANSLATION`)."""
    return InputError(
        f"the translations of the poses are too small to compute with: the largest is {largest:.1e} in the "
        f"data's unit (at least {MIN_TRANSLATION:g} is needed, or all exactly 0). Express them in a smaller "
        "unit (e.g. mm instead of km), or set them to 0 if they are rounding noise, and solve again"
    )


@dataclasses.dataclass(frozen=True)
class KroneckerSystem:
    """H beta = w reduced by QR (eq. 10): |H beta - w|^2 = |R1 beta - q1|^2 + rest.

    R1: (n, n) upper triangular; q1 = Q1^T w: (n,); rest = |Q2^T w|^2 (eq. 12). What beta holds
    is the problem's: for ``axyb`` [vec(R_X); vec(R_Y); t_X; t_Y] (n = 24), for ``axxb``
    [vec(R_X); t_X] (n = 12), column-major vec as in the paper.
    """

    R1: np.ndarray
    q1: np.ndarray
    rest: float

    def least_squares(self) -> np.ndarray:
        """beta minimising |H beta - w| (the optimum of eq. 14), by back substitution."""
        from scipy.linalg import solve_triangular

        return solve_triangular(self.R1, self.q1, lower=False)

    def smallest_singular_value(self) -> float:
        """sigma_min(H) = sigma_min(R1): how well the system determines beta."""
        return float(np.linalg.svd(self.R1, compute_uv=False)[-1])


def reduce_normal_equations(N: np.ndarray, g: np.ndarray, ww: float) -> KroneckerSystem:
    """Normal equations N = H^T H, g = H^T w, ww = w^T w -> the triangular form of eqs. 10-12.

    R1 is the Cholesky factor of the column-equilibrated normal matrix (R1^T R1 = H^T H; equal to
    the R of H = QR up to row signs), q1 = R1^-T H^T w and rest = w^T w - |q1|^2. Equilibration
    (scaling columns to unit norm before factorising) keeps the accuracy close to a QR of H even
    when translations in mm make the columns differ by orders of magnitude: on noise-free data
    beta is recovered to ~1e-11 relative, against 1e-13 for a dense QR that is ~5x slower.
    Raises InputError when N, g or ww are not finite (translations so large their sums
    overflow), DegenerateDataError when N is singular.
    """
    if not (np.isfinite(N).all() and np.isfinite(g).all() and np.isfinite(ww)):
        raise overflow_error("the sums of the linear system")
    d = np.sqrt(np.diag(N))
    try:  # LAPACK directly (`handeye.geometry.linalg`: scipy's numbers without its checks, ~30 us at 24 x 24)
        R1 = cholesky_upper(N / np.outer(d, d)) * d[None, :]
    except np.linalg.LinAlgError:
        raise DegenerateDataError(
            "the linear system of the data is rank deficient: the poses rotate too little, or about "
            "too few axes, so the unknowns cannot be determined. Record poses that rotate about at "
            "least two different axes"
        ) from None
    q1 = solve_triangular(R1, g, trans=1)
    return KroneckerSystem(R1=R1, q1=q1, rest=max(ww - float(q1 @ q1), 0.0))


def kron_sum(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """sum_i kron(P_i, Q_i) for stacks P, Q: (m, 3, 3) -> (9, 9), as one BLAS product."""
    M = P.reshape(-1, 9).T @ Q.reshape(-1, 9)  # M[(i, j), (k, l)] = sum P_ij Q_kl
    return M.reshape(3, 3, 3, 3).transpose(0, 2, 1, 3).reshape(9, 9)


@dataclasses.dataclass(frozen=True)
class TranslationSums:
    """Sums over the pairs (all O(m), each one BLAS product) that the translation rows of the
    Kronecker systems and the translation least squares need: G_A = sum R_A^T R_A, sum R_A,
    C = sum t_B kron R_A (as (3, 3, 3): C[j, a, b] = sum t_Bj R_A,ab), sum t_B, sum R_A^T t_A,
    sum t_A, sum t_B t_A^T, sum |t_A|^2, T_B = sum t_B t_B^T, and m."""

    GA: np.ndarray
    sum_RA: np.ndarray
    C: np.ndarray
    sum_tB: np.ndarray
    RAt_tA: np.ndarray
    sum_tA: np.ndarray
    tB_tA: np.ndarray
    tA_tA: float
    TB: np.ndarray
    m: int

    @classmethod
    def of(cls, A: np.ndarray, B: np.ndarray) -> TranslationSums:
        m = len(A)
        RA = np.ascontiguousarray(A[:, :3, :3])
        tA, tB = np.ascontiguousarray(A[:, :3, 3]), np.ascontiguousarray(B[:, :3, 3])
        RA3 = RA.reshape(3 * m, 3)
        return cls(GA=RA3.T @ RA3, sum_RA=RA.sum(axis=0), C=(tB.T @ RA.reshape(m, 9)).reshape(3, 3, 3),
                   sum_tB=tB.sum(axis=0), RAt_tA=RA3.T @ tA.reshape(3 * m),
                   sum_tA=tA.sum(axis=0), tB_tA=tB.T @ tA, tA_tA=float((tA * tA).sum()), TB=tB.T @ tB, m=m)

    def RAt_R_tB(self, R: np.ndarray) -> np.ndarray:
        """sum_i R_Ai^T R t_Bi for a 3x3 R: (3,), from C without a pass over the pairs."""
        return np.einsum("aj,jab->b", R, self.C)


def validated_stacks(problem: str, data: Mapping[str, Any], fields: tuple[str, ...], min_pairs: int) -> list[np.ndarray]:
    """The stacks `fields` of `problem` from its raw data: no other key and all present, every pose
    checked (`handeye.geometry.validation.pose_stacks`: shapes, SE(3), the same length >= min_pairs), and
    translations whose sums of squares neither overflow nor underflow (`MIN_TRANSLATION`; every
    solver needs them: the linear systems, the unit normalisation, the weights of the least
    squares). Raises InputError / DegenerateDataError naming what is wrong."""
    return _validated_stacks(problem, data, fields, min_pairs)[0]


def _validated_stacks(problem: str, data: Mapping[str, Any], fields: tuple[str, ...],
                      min_pairs: int) -> tuple[list[np.ndarray], float]:
    """`validated_stacks` and the stacks' `translation_rms`, which it checks (the data's length
    unit: `PosePairs.validated` keeps it rather than computing it again)."""
    from handeye.geometry.validation import pose_stacks

    unexpected = set(data) - set(fields)
    if unexpected:
        raise InputError(f"problem {problem!r} takes data {list(fields)}, not {sorted(unexpected)}")
    missing = [f for f in fields if f not in data]
    if missing:
        raise InputError(f"problem {problem!r} needs data {list(fields)}; missing {missing}")
    stacks = list(pose_stacks({f: data[f] for f in fields}, min_pairs).values())
    with np.errstate(over="ignore", invalid="ignore"):
        scale = translation_rms(*stacks)
        if not np.isfinite(scale):
            raise overflow_error("the sums of squared translations")
    largest = max(float(np.abs(T[:, :3, 3]).max()) for T in stacks)
    if 0.0 < largest < MIN_TRANSLATION:
        raise underflow_error(largest)
    return stacks, scale


def translation_rms(*stacks: np.ndarray) -> float:
    """RMS norm of every translation of the pose stacks (1 when all are zero): the data's length
    unit, for normalisation."""
    t = np.concatenate([T[:, :3, 3] for T in stacks])
    scale = math.sqrt(float((t * t).sum(axis=1).sum()) / len(t)) if len(t) else math.nan  # np.mean's arithmetic
    return scale if scale > 0 else 1.0


def scaled_stacks(stacks: tuple[np.ndarray, ...], s: float) -> list[np.ndarray]:
    """Read-only copies of the pose stacks with every translation divided by s."""
    out = []
    for T in stacks:
        T = T.copy()
        T[:, :3, 3] /= s
        T.setflags(write=False)
        out.append(T)
    return out


@dataclasses.dataclass(frozen=True)
class PosePairs:
    """Validated data of a two-stack problem: read-only float64 stacks A, B of shape (m, 4, 4),
    with the sums over the pairs that the Kronecker systems need, each taken once (cached).

    Subclasses (``AXYBData``, ``AXXBData``) state their linear system in `normal_equations`;
    `kronecker(scale)` reduces it, once per scale.
    """

    A: np.ndarray
    B: np.ndarray

    @classmethod
    def validated(cls, problem: str, data: Mapping[str, Any], min_pairs: int):
        """The data object of `problem` from its raw fields {"A", "B"} (`validated_stacks`); the
        problem adds its own degeneracy checks."""
        stacks, scale = _validated_stacks(problem, data, ("A", "B"), min_pairs)
        out = cls(*stacks)
        out.__dict__["translation_scale"] = scale  # `translation_scale`'s value, computed once
        return out

    @property
    def m(self) -> int:
        return len(self.A)

    @cached_property
    def translation_scale(self) -> float:
        """RMS norm of all translations of A and B: the data's length unit, for normalisation."""
        return translation_rms(self.A, self.B)

    def scaled(self, s: float):
        """The same data (same class, the same facts) with every translation divided by s."""
        A, B = scaled_stacks((self.A, self.B), s)
        return dataclasses.replace(self, A=A, B=B)

    @cached_property
    def rotation_sum(self) -> np.ndarray:
        """S = sum_i R_Bi kron R_Ai: (9, 9), the rotation block of the normal matrices (computed
        once; shared by the excitation checks, the normal equations and Shah's method)."""
        return kron_sum(np.ascontiguousarray(self.B[:, :3, :3]), np.ascontiguousarray(self.A[:, :3, :3]))

    @cached_property
    def rotation_gram_sum(self) -> np.ndarray:
        """sum_i (R_Bi^T R_Bi) kron (R_Ai^T R_Ai): (9, 9), the K^T K block of the normal matrices
        (the identity times m for exact rotations)."""
        return kron_sum(gram(self.B[:, :3, :3]), gram(self.A[:, :3, :3]))

    @cached_property
    def translation_sums(self) -> TranslationSums:
        """The O(m) sums behind the translation rows (computed once)."""
        return TranslationSums.of(self.A, self.B)

    def normal_equations(self, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
        """N = H^T H, g = H^T w, w^T w of the problem's linear system, translations divided by scale."""
        raise NotImplementedError

    @cached_property
    def kronecker_system(self) -> KroneckerSystem:
        """The reduced linear system in the data's units (computed once)."""
        return self.kronecker(1.0)

    def kronecker(self, scale: float) -> KroneckerSystem:
        """The reduced linear system with every translation divided by `scale` (cached per
        scale), from the sums taken once: a solver normalising the units (scale =
        `translation_scale`) copies no data and repeats no O(m) work."""
        systems = self._kronecker_systems
        if scale not in systems:
            systems[scale] = reduce_normal_equations(*self.normal_equations(scale))
        return systems[scale]

    @cached_property
    def _kronecker_systems(self) -> dict[float, KroneckerSystem]:
        return {}
