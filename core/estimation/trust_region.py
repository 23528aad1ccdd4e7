"""The trust-region subproblem with an equality constraint, solved exactly.

    minimise  f(x) = x^T P x - 2 p^T x   subject to  |x| = rho,      P: (n, n) symmetric, p: (n,)

x is a global minimiser if and only if, for some multiplier lambda (Gay 1981; Moré & Sorensen
1983, with the constraint an equality: no sign condition on lambda),

    (P - lambda I) x = p,   |x| = rho,   P - lambda I positive semidefinite (lambda <= d_1),

d_1 <= ... <= d_n the eigenvalues of P, v_i its eigenvectors, q = V^T p. Then
x(lambda) = sum_i q_i / (d_i - lambda) v_i, and |x(lambda)| increases monotonically from 0 to
infinity on (-infinity, d_1) when q has a component in the eigenspace of d_1: the secular equation
|x(lambda)| = rho has exactly one root there, found by a safeguarded Newton iteration on
1 / |x| - 1 / rho (concave and increasing in mu = d_1 - lambda, so Newton from the left converges
monotonically; Moré & Sorensen's choice). "Hard case": q has no component along the eigenspace of
d_1 (to `HARD_CASE_RTOL`) and |x(d_1)| (the other components) <= rho; then lambda = d_1 and
x = x(d_1) + tau v_1 with tau >= 0 completing the norm; -tau is as good (the minimiser is not
unique), which callers resolve with their own criterion.

`refine_trust_region` polishes an approximate minimiser (e.g. from an SDP solver, accurate to its
tolerance) by Newton's method on the optimality system (P - lambda I) x = p, |x|^2 = rho^2, and
says whether the point it reaches satisfies the global conditions above.

Used by the ``axxb`` Kronecker solvers (`kron-lstsq`, `lmi-sdp`): the rotation rows of A X = X B
are homogeneous, and |vec R_X|^2 = 3 fixes the scale (docs/solvers/kron-lstsq.md).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.linalg import eigh, vector_norm

#: Eigenvalues within this (relative to the largest |eigenvalue|, or to |p| / rho when larger)
#: of the smallest count as equal to it, and components of q below this (relative to |q|) in
#: that eigenspace count as zero: the test for the hard case.
HARD_CASE_RTOL = 1e-13
#: The secular iteration stops when mu changes by less than this (relative), or after MAX_ITER.
STEP_RTOL = 4 * np.finfo(float).eps
#: the smallest normal float (a floor of the spread below)
_TINY = np.finfo(float).tiny
MAX_ITER = 100
#: `refine_trust_region`: at most this many Newton steps (it converges quadratically: 2-3 from
#: an SDP solver's ~1e-7), and the tolerances of its global-optimality test: lambda <= d_1 +
#: HARD_CASE_RTOL * spread, |(P - lambda I) x - p| <= KKT_RTOL * (|P| rho + |p|).
MAX_NEWTON = 20
KKT_RTOL = 1e-10


@dataclasses.dataclass(frozen=True)
class TrustRegionSolution:
    """x: (n,) the minimiser (|x| = rho); multiplier: lambda with (P - lambda I) x = p;
    value: f(x) = x^T P x - 2 p^T x; hard_case: lambda = d_1 and x is not unique (x - 2 tau v_1
    is another minimiser); eigenvalues: (n,) of P, ascending; iterations: of the secular equation
    (0 in the hard case)."""

    x: np.ndarray
    multiplier: float
    value: float
    hard_case: bool
    eigenvalues: np.ndarray
    iterations: int
    #: |(P - lambda I) x - p| / (|P| rho + |p|): 0 up to rounding for `solve_trust_region`
    kkt_residual: float = 0.0
    #: the conditions of the module docstring hold (always for `solve_trust_region`)
    global_optimum: bool = True


def solve_trust_region(P: np.ndarray, p: np.ndarray, rho: float) -> TrustRegionSolution:
    """The global minimiser of x^T P x - 2 p^T x on the sphere |x| = rho (module docstring).

    P: (n, n) symmetric (its symmetric part is used), p: (n,), rho > 0. Cost: one symmetric
    eigendecomposition of P and a few O(n) iterations.
    """
    P = np.asarray(P, dtype=float)
    p = np.asarray(p, dtype=float).ravel()
    n = len(p)
    if P.shape != (n, n) or not (np.isfinite(P).all() and np.isfinite(p).all()):
        raise InputError(f"trust region: expected a finite P of shape ({n}, {n}) and p of shape ({n},), "
                         f"got {P.shape} and {p.shape}")
    if not (np.isfinite(rho) and rho > 0):
        raise InputError(f"trust region: rho must be a finite number > 0, got {rho!r}")
    d, V = eigh(0.5 * (P + P.T))  # LAPACK directly (`handeye.geometry.linalg.eigh`)
    q = V.T @ p
    q_norm = vector_norm(q)
    spread = max(float(np.abs(d).max()), q_norm / rho, _TINY)
    first = d - d[0] <= HARD_CASE_RTOL * spread  # the eigenspace of d_1
    q_first = vector_norm(q[first])

    if q_first <= HARD_CASE_RTOL * q_norm:
        q = np.where(first, 0.0, q)
        x_rest = _x_of(d - d[0], q, 0.0)
        if np.linalg.norm(x_rest) <= rho:
            tau = np.sqrt(max(rho**2 - float(x_rest @ x_rest), 0.0))
            coords = x_rest.copy()
            coords[0] += tau
            return _solution(V, coords, d, p, float(d[0]), True, 0)

    # mu = d_1 - lambda > 0: |x| < rho at mu = |q| / rho; |x| >= rho at the lower bound
    delta = d - d[0]
    lo = max(0.0, q_norm / rho - float(delta[-1]), q_first / rho)
    hi = q_norm / rho
    mu = lo
    iterations = 0
    # the same arithmetic as `_x_of` and np.linalg.norm (sqrt of x . x), in fewer numpy calls:
    # the mask, q^2 and the buffers are made once (3 iterations: ~45 -> ~25 us)
    nonzero, qq = q != 0, q * q
    x, terms = np.zeros_like(q), np.zeros_like(q)
    for iterations in range(1, MAX_ITER + 1):
        den = delta + mu
        np.divide(q, den, out=x, where=nonzero)
        norm = math.sqrt(float(x.dot(x)))
        if norm == 0.0 or not math.isfinite(norm):  # mu = 0 on a zero denominator: step right
            new = 0.5 * (lo + hi) if hi > lo else hi
        else:
            f = 1.0 / norm - 1.0 / rho
            if f < 0:
                lo = mu
            elif f > 0:
                hi = mu
            else:
                break
            slope = float(np.divide(qq, den**3, out=terms, where=nonzero).sum()) / norm**3
            new = mu - f / slope if slope > 0 else 0.5 * (lo + hi)
            if not (lo <= new <= hi):
                new = 0.5 * (lo + hi)
        if abs(new - mu) <= STEP_RTOL * max(mu, new):
            mu = new
            break
        mu = new
    coords = _x_of(delta, q, mu)
    return _solution(V, coords, d, p, float(d[0] - mu), False, iterations)


def refine_trust_region(P: np.ndarray, p: np.ndarray, rho: float, x0: np.ndarray) -> TrustRegionSolution:
    """Newton's method on (P - lambda I) x = p, |x|^2 = rho^2 from x0: (n,) (scaled to |x0| = rho;
    lambda starts at its least-squares estimate x0^T (P x0 - p) / rho^2).

    Converges quadratically from a point near a minimiser whose bordered Jacobian
    [[P - lambda I, -x], [x^T, 0]] is nonsingular (every non-hard case, and the hard case with
    a single smallest eigenvalue). The result's ``global_optimum`` says whether the point reached
    satisfies the global conditions (module docstring) to the tolerances `KKT_RTOL` and
    `HARD_CASE_RTOL`; ``iterations`` counts the Newton steps; ``hard_case`` is False (not tested
    here)."""
    P = 0.5 * (np.asarray(P, dtype=float) + np.asarray(P, dtype=float).T)
    p = np.asarray(p, dtype=float).ravel()
    n = len(p)
    x = np.asarray(x0, dtype=float).ravel()
    x = x * (rho / np.linalg.norm(x))
    lam = float(x @ (P @ x - p)) / rho**2
    iterations = 0
    for iterations in range(1, MAX_NEWTON + 1):
        F = np.append(P @ x - lam * x - p, 0.5 * (x @ x - rho**2))
        J = np.zeros((n + 1, n + 1))
        J[:n, :n] = P - lam * np.eye(n)
        J[:n, n] = -x
        J[n, :n] = x
        step = np.linalg.lstsq(J, -F, rcond=None)[0]
        x, lam = x + step[:n], lam + float(step[n])
        if np.linalg.norm(step[:n]) <= 4 * STEP_RTOL * rho:  # x at rounding (lambda: ~eps |P|)
            break
    d = np.linalg.eigvalsh(P)
    spread = max(float(np.max(np.abs(d))), float(np.linalg.norm(p)) / rho, np.finfo(float).tiny)
    residual = float(np.linalg.norm(P @ x - lam * x - p)) / (np.linalg.norm(P, 2) * rho + np.linalg.norm(p) or 1.0)
    optimal = bool(lam <= d[0] + HARD_CASE_RTOL * spread and residual <= KKT_RTOL
                   and abs(x @ x - rho**2) <= KKT_RTOL * rho**2)
    return TrustRegionSolution(x=x, multiplier=lam, value=float(x @ P @ x - 2.0 * p @ x), hard_case=False,
                               eigenvalues=d, iterations=iterations, kkt_residual=residual,
                               global_optimum=optimal)


def _x_of(delta: np.ndarray, q: np.ndarray, mu: float) -> np.ndarray:
    """Coordinates of x(lambda) in the eigenbasis: q_i / (d_i - d_1 + mu), 0 where q_i = 0."""
    return np.divide(q, delta + mu, out=np.zeros_like(q), where=q != 0)


def _solution(V: np.ndarray, coords: np.ndarray, d: np.ndarray, p: np.ndarray, multiplier: float,
              hard_case: bool, iterations: int) -> TrustRegionSolution:
    x = V @ coords
    value = float(coords @ (d * coords) - 2.0 * p @ x)
    return TrustRegionSolution(x=x, multiplier=multiplier, value=value, hard_case=hard_case,
                               eigenvalues=d, iterations=iterations)
