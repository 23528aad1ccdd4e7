"""The geometric model of A_i X B_i = Y C_i Z for the least-squares engine (`handeye.estimation.nlls`):
residuals and analytic Jacobians on SE(3) x SE(3) x SE(3), and the hooks of the host's
self-check (`handeye.checks.self_check`).

One 6-vector per triple (the per-triple quantities of `AXBYCZ.residuals`, as vectors):

    r_i = log(R_Ai R_X R_Bi R_Z^T R_Ci^T R_Y^T)                 rotation of (A X B)(Y C Z)^-1 [rad]
    t_i = R_Ai R_X t_Bi + R_Ai t_X + t_Ai - R_Y R_Ci t_Z - R_Y t_Ci - t_Y
                                                               t(A X B) - t(Y C Z)  [data units]

Unknowns are perturbed on the right, T <- T exp(xi), xi = (omega, v) (the engine's `retract`:
R <- R exp([omega]_x), t <- t + R v). With Q_i = exp([r_i]_x) the rotation discrepancy:

- X exp(omega_X): R_A R_X exp(omega_X) R_B ... = exp([R_A R_X omega_X]_x) Q, a left perturbation
  of Q, so d r / d omega_X = Jl^-1(r) R_A R_X;
- Y exp(omega_Y): ... R_Y^T becomes exp(-[omega_Y]_x) R_Y^T, Q <- Q exp(-[R_Y omega_Y]_x), a
  right perturbation: d r / d omega_Y = -Jr^-1(r) R_Y;
- Z exp(omega_Z): R_Z^T becomes exp(-[omega_Z]_x) R_Z^T, Q <- Q (R_Y R_C R_Z) exp(-[omega_Z]_x)
  (R_Y R_C R_Z)^T = Q exp(-[R_Y R_C R_Z omega_Z]_x): d r / d omega_Z = -Jr^-1(r) R_Y R_C R_Z;

and the translation discrepancy, with R exp([w]_x) p = R p + R (w x p) to first order:

    d t / d omega_X = -R_A R_X [t_B]_x          d t / d v_X = R_A R_X
    d t / d omega_Y = R_Y [R_C t_Z + t_C]_x     d t / d v_Y = -R_Y
    d t / d omega_Z = 0                         d t / d v_Z = -R_Y R_C R_Z

(Jl^-1, Jr^-1 = (Jl^-1)^T: the inverse left / right Jacobians of SO(3), `handeye.geometry.so3_fast`).
Checked against central differences in tests/problems/axbycz/test_axbycz_problem.py. From `SUMS_MIN_PAIRS`
triples on, the normal equations for per-group sigmas are summed in closed form
(`AXBYCZModel.normal_equations`, equal to the Jacobian's to rounding: tests/problems/axbycz/test_axbycz_speed.py)
instead of from the (m, 6, 18) Jacobian.
"""

from __future__ import annotations

import math

import numpy as np

from handeye.estimation.nlls import PoseModel, Poses
from handeye.geometry import so3_fast
from handeye.problems.axbycz.data import AXBYCZData

#: fewest triples for the profile likelihood. The translation residuals (3m numbers) depend on 15
#: parameters (R_X, t_X, R_Y, t_Y, t_Z; R_Z does not enter them), so up to m = 5 they can in
#: general be fitted exactly, and the likelihood with an unknown translation variance is then
#: unbounded (sigma_trans -> 0); from m = 6 on, 18 > 15 equations. (The rotation residuals, 3m
#: numbers in 9 parameters, fit exactly only at m = 3.) Below it the engine uses the start's
#: residuals for the weights ("initial").
PROFILE_MIN_PAIRS = 6
#: from this many triples on, the normal equations are summed in closed form (`normal_equations`)
#: instead of from the (m, 6, 18) Jacobian: measured (the engine's `local_model`, one thread, the
#: fastest of 40) 0.28 vs 0.07 ms at m = 16, 0.32 vs 0.13 at 100, 0.51 vs 0.44 at 500, 0.62 vs
#: 0.61 at 700, 0.79 vs 0.82 at 1000, 6.1 vs 11.5 ms at 10000 (the sums' ~60 small numpy
#: calls cost a fixed ~0.25 ms)
SUMS_MIN_PAIRS = 700

_I3 = so3_fast.I3
#: [e_l]_x for the unit vectors e_l: [v]_x = sum_l v_l _E[l]
_E = so3_fast.skew(np.eye(3))


class AXBYCZModel(PoseModel):
    """A_i X B_i = Y C_i Z on (X, Y, Z), parameters (omega_X, v_X, omega_Y, v_Y, omega_Z, v_Z)."""

    unknowns = ("X", "Y", "Z")
    profile_min_pairs = PROFILE_MIN_PAIRS
    sums_min_pairs = SUMS_MIN_PAIRS

    def __init__(self, data: AXBYCZData) -> None:
        self.m, self.scale = data.m, data.translation_scale
        self.RA = np.ascontiguousarray(data.A[:, :3, :3])
        self.RB = np.ascontiguousarray(data.B[:, :3, :3])
        self.RC = np.ascontiguousarray(data.C[:, :3, :3])
        self.tA = np.ascontiguousarray(data.A[:, :3, 3])
        self.tB = np.ascontiguousarray(data.B[:, :3, 3])
        self.tC = np.ascontiguousarray(data.C[:, :3, 3])
        self.TBx = so3_fast.skew(self.tB)  # [t_B]_x: (m, 3, 3)
        self.RC_side = np.ascontiguousarray(self.RC.transpose(1, 0, 2)).reshape(3, 3 * self.m)  # R_C side by side

    def _sides(self, poses: Poses) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """R_A R_X, rotations of A X B and of Y C Z, and R_C t_Z + t_C (t(C Z)): the products the
        residuals and the Jacobian share. Products of the stacks with one pose are BLAS products
        of the stacked (3m, 3) or side-by-side (3, 3m) matrices (a batched product with each
        pose took several times longer)."""
        X, Y, Z = poses
        m = self.m
        RAX = (self.RA.reshape(3 * m, 3) @ X[:3, :3]).reshape(m, 3, 3)
        YC = (Y[:3, :3] @ self.RC_side).reshape(3 * m, 3)  # rows (a, i): (R_Y R_Ci)[a, :]
        right = np.ascontiguousarray((YC @ Z[:3, :3]).reshape(3, m, 3).transpose(1, 0, 2))
        CZ_t = (self.RC.reshape(3 * m, 3) @ Z[:3, 3]).reshape(m, 3) + self.tC
        return RAX, RAX @ self.RB, right, CZ_t, X[:3, 3]

    def residuals(self, poses: Poses) -> np.ndarray:
        """Unwhitened residuals e: (m, 6) = [r_i; t_i] at (X, Y, Z)."""
        Y = poses[1]
        RAX, left, right, CZ_t, tX = self._sides(poses)
        m = self.m
        e = np.empty((m, 6))
        e[:, :3] = so3_fast.log(left @ np.swapaxes(right, 1, 2))
        e[:, 3:] = (np.einsum("nij,nj->ni", RAX, self.tB) + (self.RA.reshape(3 * m, 3) @ tX).reshape(m, 3)
                    + self.tA - CZ_t @ Y[:3, :3].T - Y[:3, 3])
        return e

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 18) = d e_i / d (omega_X, v_X, omega_Y, v_Y, omega_Z, v_Z) at the poses (module
        docstring), e from `residuals`."""
        _, Y, _ = poses
        RY = Y[:3, :3]
        RAX, _, right, CZ_t, _ = self._sides(poses)
        Jl_inv, Jr_inv = so3_fast.inverse_jacobians(e[:, :3])
        J = np.zeros((self.m, 6, 18))
        J[:, :3, 0:3] = Jl_inv @ RAX
        J[:, :3, 6:9] = -(Jr_inv @ RY)
        J[:, :3, 12:15] = -(Jr_inv @ right)  # right = R_Y R_C R_Z
        J[:, 3:, 0:3] = -(RAX @ self.TBx)
        J[:, 3:, 3:6] = RAX
        J[:, 3:, 6:9] = RY @ so3_fast.skew(CZ_t)
        J[:, 3:, 9:12] = -RY
        J[:, 3:, 15:18] = -right
        return J

    def normal_equations(self, poses: Poses, e: np.ndarray, wr: float, wt: float,
                         d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """g_rot, g_trans (18) and Hw (18, 18) of the engine's contract (`PoseModel.normal_equations`)
        without forming J: the blocks of sum_i d_i J_i^T C^-1 J_i and J_i^T C^-1 e_i are sums over the
        triples of small products in which the rotations cancel (R^T R = I), each one BLAS
        contraction over the triples.

        Rotation rows: with M = Jl^-1(r), M^T r = r, M M^T = M^T M = I + beta [r]_x^2 and
        M^T M^T = I + gamma [r]_x + delta [r]_x^2 (`_rotation_terms`), the blocks of (omega_X,
        omega_Y, omega_Z) are R_AX^T (..) R_AX, R_Y^T (..) R_Y, N^T (..) N and the cross terms, with
        N = R_Y R_C R_Z. Translation rows (F = -R_AX [t_B]_x, R_AX, R_Y [p]_x, -R_Y, -N on omega_X,
        v_X, omega_Y, v_Y, v_Z; p = R_C t_Z + t_C): F_a^T F_b reduce to [t_B]_x^T [t_B]_x, [t_B]_x,
        G = R_AX^T R_Y and their products with [p]_x and R_C R_Z (`_translation_terms`). Equal to
        the Jacobian's to rounding for rotations orthonormal to rounding (tests/problems/axbycz/test_axbycz_speed.py;
        the data's are orthonormal to `handeye.geometry.se3.ORTHONORMALITY_TOL`, and Hw to that order, while
        the gradient uses no orthonormality); faster from `SUMS_MIN_PAIRS` on.
        """
        X, Y, Z = poses
        RX, RY, RZ = X[:3, :3], Y[:3, :3], Z[:3, :3]
        H = np.zeros((18, 18))
        g_rot = _rotation_terms(self, RX, RY, RZ, e[:, :3], d, wr, H)
        g_trans = _translation_terms(self, RX, RY, RZ, Z[:3, 3], e[:, 3:], d, wt, H)
        return g_rot, g_trans, np.triu(H) + np.triu(H, 1).T  # mirror the upper blocks filled


def _cross_sum(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sum_i a_i x b_i for a, b: (m, 3), from one (3, m) x (m, 3) product."""
    M = a.T @ b
    return np.array([M[1, 2] - M[2, 1], M[2, 0] - M[0, 2], M[0, 1] - M[1, 0]])


def _outer_sums(coefficients: np.ndarray, R: np.ndarray, S: np.ndarray) -> np.ndarray:
    """sum_i c_i[j] R_i[k, a] S_i[n, b] as (J, 3, 3, 3, 3) for coefficients c: (m, J) and R, S:
    (m, 3, 3): one (9J, m) x (m, 9) product, from which the sums of products R_i^T M S_i over the
    triples follow for any constant M (a contraction of 81 numbers)."""
    m, J = coefficients.shape
    left = (coefficients[:, :, None] * R.reshape(m, 1, 9)).reshape(m, 9 * J)
    return (left.T @ S.reshape(m, 9)).reshape(J, 3, 3, 3, 3)


def _rotation_terms(model: AXBYCZModel, RX: np.ndarray, RY: np.ndarray, RZ: np.ndarray, r: np.ndarray,
                    d: np.ndarray, wr: float, H: np.ndarray) -> np.ndarray:
    """The rotation rows' part of `AXBYCZModel.normal_equations`: sets the upper blocks of H on
    (omega_X, omega_Y, omega_Z) and returns g_rot (18); r: (m, 3) rotation residuals.

    With u = R_A^T r and w = (R_Y R_C)^T r: H_XX = R_X^T (a I + sum d beta u u^T) R_X (a = sum
    d (1 - beta theta^2)), likewise H_YY with r and H_ZZ with w; H_XY = -R_X^T T_XY R_Y and H_XZ =
    -R_X^T T_XZ R_Z with T_XY = sum R_A^T (d (1 - delta theta^2) I + d gamma [r]_x) + sum d delta
    u r^T and T_XZ the same with R_Y R_C on the right (u w^T for u r^T); H_YZ = (sum d (1 - beta
    theta^2) R_C + R_Y^T sum d beta r w^T) R_Z."""
    RA, RC, m = model.RA, model.RC, model.m
    theta2 = np.einsum("ni,ni->n", r, r)
    beta, gamma, delta = so3_fast.jl_products(theta2)
    u = np.einsum("nji,nj->ni", RA, r)  # R_A^T r
    w = np.einsum("nji,nj->ni", RC, r @ RY)  # R_C^T R_Y^T r
    db, dd = (d * beta)[:, None], (d * delta)[:, None]
    bt = d * (1.0 - beta * theta2)
    a = float(np.sum(bt))
    H[0:3, 0:3] = wr * (RX.T @ (a * _I3 + (db * u).T @ u) @ RX)
    H[6:9, 6:9] = wr * (RY.T @ (a * _I3 + (db * r).T @ r) @ RY)
    H[12:15, 12:15] = wr * (RZ.T @ (a * _I3 + (db * w).T @ w) @ RZ)
    # coefficients of R_A^T (.) per triple: the identity's, then those of [e_l]_x (l = 1..3)
    c = np.concatenate([(d * (1.0 - delta * theta2))[:, None], (d * gamma)[:, None] * r], axis=1)
    sums = (c.T @ RA.reshape(m, 9)).reshape(4, 3, 3)  # sum c_j R_A
    T_XY = sums[0].T + np.einsum("lka,lkb->ab", sums[1:], _E) + (dd * u).T @ r
    outer = _outer_sums(c, RA, RC)  # [j, k, a, n, b] = sum c_j R_A[k, a] R_C[n, b]
    middle = np.concatenate([RY[None], _E @ RY])  # I R_Y and [e_l]_x R_Y
    T_XZ = np.einsum("jkanb,jkn->ab", outer, middle) + (dd * u).T @ w
    H[0:3, 6:9] = -wr * (RX.T @ T_XY @ RY)
    H[0:3, 12:15] = -wr * (RX.T @ T_XZ @ RZ)
    H[6:9, 12:15] = wr * (((bt @ RC.reshape(m, 9)).reshape(3, 3) + RY.T @ (db * r).T @ w) @ RZ)
    dr = d[:, None] * r
    g = np.zeros(18)
    g[0:3] = wr * (RX.T @ (dr.reshape(-1) @ RA.reshape(3 * m, 3)))
    g[6:9] = -wr * (RY.T @ dr.sum(axis=0))
    g[12:15] = -wr * (RZ.T @ (d @ w))
    return g


def _translation_terms(model: AXBYCZModel, RX: np.ndarray, RY: np.ndarray, RZ: np.ndarray, tZ: np.ndarray,
                       t: np.ndarray, d: np.ndarray, wt: float, H: np.ndarray) -> np.ndarray:
    """The translation rows' part of `AXBYCZModel.normal_equations`: adds it to the upper blocks of
    H and returns g_trans (18); t: (m, 3) translation residuals.

    With F = (-R_AX [t_B]_x, R_AX, R_Y [p]_x, -R_Y, -N) on (omega_X, v_X, omega_Y, v_Y, v_Z) and
    G = R_AX^T R_Y: F^T F has the blocks [t_B]_x^T [t_B]_x, [t_B]_x, [t_B]_x G [p]_x, -[t_B]_x G,
    -[t_B]_x G R_C R_Z; I, G [p]_x, -G, -G R_C R_Z; [p]_x^T [p]_x, [p]_x, [p]_x R_C R_Z; I, R_C R_Z; I.
    Writing [v]_x = sum_l v_l [e_l]_x, every sum over the triples is a sum of R_A^T or R_C (or of
    R_A^T R_Y R_C) weighted by products of d, t_B and p: one BLAS product each (`_outer_sums`)."""
    RA, RC, tB, m = model.RA, model.RC, model.tB, model.m
    p = (RC.reshape(3 * m, 3) @ tZ).reshape(m, 3) + model.tC  # t(C Z)
    sum_d = float(np.sum(d))
    dtB, dp, dt = d[:, None] * tB, d[:, None] * p, d[:, None] * t
    A9, C9 = RA.reshape(m, 9), RC.reshape(m, 9)
    # sums of d t_B[j] p[l] R_A, d t_B[j] R_A, d p[l] R_A, d R_A: R_X^T (sum R_A)^T R_Y per weight
    weights = np.concatenate([(dtB[:, :, None] * p[:, None, :]).reshape(m, 9), dtB, dp, d[:, None]], axis=1)
    G = np.einsum("ax,jka,kz->jxz", RX, (weights.T @ A9).reshape(16, 3, 3), RY)  # sum weight G
    H[0:3, 0:3] += wt * (float(np.sum(dtB * tB)) * _I3 - dtB.T @ tB)
    H[0:3, 3:6] = wt * so3_fast.skew(dtB.sum(axis=0))
    H[0:3, 6:9] += wt * np.einsum("jpx,jlxz,lzq->pq", _E, G[:9].reshape(3, 3, 3, 3), _E)
    H[0:3, 9:12] = -wt * np.einsum("jpx,jxz->pz", _E, G[9:12])
    H[3:6, 3:6] = wt * sum_d * _I3
    H[3:6, 6:9] += wt * np.einsum("lxz,lzq->xq", G[12:15], _E)
    H[3:6, 9:12] = -wt * G[15]
    # sums of d t_B[j] R_A^T R_Y R_C and d R_A^T R_Y R_C
    outer = np.einsum("jkanb,kn->jab", _outer_sums(np.concatenate([dtB, d[:, None]], axis=1), RA, RC), RY)
    H[0:3, 15:18] = -wt * (np.einsum("jpx,ax,jab->pb", _E, RX, outer[:3]) @ RZ)
    H[3:6, 15:18] = -wt * (RX.T @ outer[3] @ RZ)
    H[6:9, 6:9] += wt * (float(np.sum(dp * p)) * _I3 - dp.T @ p)
    H[6:9, 9:12] = wt * so3_fast.skew(dp.sum(axis=0))
    sums_C = (np.concatenate([dp, d[:, None]], axis=1).T @ C9).reshape(4, 3, 3)  # sum d p[l] R_C, sum d R_C
    H[6:9, 15:18] = wt * (np.einsum("lpn,lnb->pb", _E, sums_C[:3]) @ RZ)
    H[9:12, 9:12] = wt * sum_d * _I3
    H[9:12, 15:18] = wt * (sums_C[3] @ RZ)
    H[15:18, 15:18] = wt * sum_d * _I3
    At = np.einsum("nji,nj->ni", RA, dt)  # R_A^T (d t)
    Yt = dt @ RY  # R_Y^T (d t) as rows
    g = np.zeros(18)
    g[0:3] = wt * _cross_sum(tB, At @ RX)
    g[3:6] = wt * (RX.T @ At.sum(axis=0))
    g[6:9] = -wt * _cross_sum(p, Yt)
    g[9:12] = -wt * Yt.sum(axis=0)
    g[15:18] = -wt * (RZ.T @ (Yt.reshape(-1) @ RC.reshape(3 * m, 3)))
    return g


# --------------------------------------------------------------------------- the host's self-check

def check_model(data: AXBYCZData, unknowns: dict[str, np.ndarray]) -> tuple[AXBYCZModel, tuple[np.ndarray, ...], tuple[str, ...]]:
    """`Problem.check_model` for A_i X B_i = Y C_i Z: this model at the answer (X, Y, Z)."""
    poses = tuple(np.asarray(unknowns[n], dtype=float) for n in AXBYCZModel.unknowns)
    return AXBYCZModel(data), poses, AXBYCZModel.unknowns


def motion_invariants(data: AXBYCZData, still: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Rotation vectors and translations of paired motions that must be conjugate, between
    consecutive triples i < j of each group where one robot holds still (`AXBYCZData.still_groups`):

    still "C" (robot 2 still): A_i X B_i = A_j X B_j, so (A_j^-1 A_i) X = X (B_j B_i^-1);
    still "A" (robot 1 still): (C_j^-1 C_i) Z = Z (B_j^-1 B_i).

    Returns (phi_robot, t_robot, phi_camera, t_camera), each (n, 3), or None without such pairs.
    """
    i, j = [], []
    for group in data.still_groups(still):
        i.extend(group[:-1])
        j.extend(group[1:])
    if not i:
        return None
    i, j = np.asarray(i), np.asarray(j)
    from handeye.geometry.se3 import inverse

    if still == "C":
        robot = inverse(data.A[j]) @ data.A[i]
        camera = data.B[j] @ inverse(data.B[i])
    else:
        robot = inverse(data.C[j]) @ data.C[i]
        camera = inverse(data.B[j]) @ data.B[i]
    return (so3_fast.log(robot[:, :3, :3]), robot[:, :3, 3], so3_fast.log(camera[:, :3, :3]), camera[:, :3, 3])


def expected_rotation_residual(data: AXBYCZData) -> float | None:
    """`Problem.expected_rotation_residual` for A_i X B_i = Y C_i Z, from the invariants of the
    phase protocol (`motion_invariants`); None unless the data hold both kinds of phases.

    With per-axis rotation noise s_A, s_B, s_C on a pose of A, B, C, the angle difference of a
    robot-1 motion and its camera motion (robot 2 still) has variance s1^2 = 2 s_A^2 + 2 s_B^2,
    that of robot 2's (robot 1 still) s2^2 = 2 s_C^2 + 2 s_B^2, and a triple's residual per-axis
    variance s_A^2 + s_B^2 + s_C^2 = (s1^2 + s2^2) / 2 - s_B^2: at most (s1^2 + s2^2) / 2, which
    is what this returns (the check flags answers ten times over it; the noise of B cannot be
    told from that of A and C). Free motion has no such invariant: robot 1 and robot 2 move
    together, and no motion of one robot alone is conjugate to one of the camera."""
    from handeye.checks.self_check import (
        angle_noise,
        expected_from_invariants,
        pitch_noise,
    )

    sigmas, pitches = [], []
    for still in ("C", "A"):
        found = motion_invariants(data, still)
        if found is None:
            return None
        phi_r, t_r, phi_c, t_c = found
        sigma = angle_noise(np.linalg.norm(phi_r, axis=1), np.linalg.norm(phi_c, axis=1))
        if sigma is None:
            return None
        sigmas.append(sigma)
        pitches.append(pitch_noise(phi_r, t_r, phi_c, t_c) or 0.0)
    return expected_from_invariants(math.hypot(*sigmas), math.hypot(*pitches), data.translation_scale, 1.0)


def rotation_axes(data: AXBYCZData) -> dict[str, np.ndarray]:
    """The main rotation axis of robot 1 in X's frame (its flange: A_k^-1 A_k+1) and in Y's (its
    base: A_k+1 A_k^-1), and of robot 2 in Z's frame (its flange: C_k^-1 C_k+1)."""
    from handeye.checks.self_check import main_axis

    if data.m < 2:
        return {}
    axes = {"X": main_axis(so3_fast.consecutive_logs(data.A)),
            "Y": main_axis(so3_fast.consecutive_logs(data.A, moving=False)),
            "Z": main_axis(so3_fast.consecutive_logs(data.C))}
    return {k: v for k, v in axes.items() if v is not None}
