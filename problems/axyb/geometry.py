"""The geometric model of A_i X = Y B_i for the least-squares engine (`handeye.estimation.nlls`): residuals,
Jacobians and closed-form normal equations on SE(3) x SE(3).

One 6-vector per pair (the per-pair quantities of the paper's eqs. 32-33, as vectors):

    r_i = log(R_Ai R_X R_Bi^T R_Y^T)            rotation vector of the discrepancy [rad]
    t_i = R_Ai t_X + t_Ai - R_Y t_Bi - t_Y       t(A_i X) - t(Y B_i)              [data units]

Unknowns are perturbed on the right, X <- X exp(xi_X), xi = (omega, v) (engine's `retract`).
With Q_i = R_A R_X R_B^T R_Y^T = exp([r_i]_x) (derivation in docs/solvers/refine.md, checked
against central differences in tests/plugins/test_refine.py):

    d r / d omega_X = Jl^-1(r) R_A R_X        d r / d omega_Y = -Jr^-1(r) R_Y
    d t / d v_X     = R_A R_X                 d t / d omega_Y = R_Y [t_B]_x
    d t / d v_Y     = -R_Y                    (other blocks zero)

with Jl^-1, Jr^-1 = (Jl^-1)^T the inverse left / right Jacobians of SO(3). From SUMS_MIN_PAIRS
pairs on, the normal equations for per-group sigmas are summed in closed form
(`AXYBModel.normal_equations`) instead of from the (m, 6, 12) Jacobian.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from handeye.estimation import camera_scale
from handeye.estimation.kronecker import PosePairs
from handeye.estimation.nlls import PoseModel, Poses
from handeye.geometry import so3_fast
from handeye.geometry.linalg import einsum, row_norms
from handeye.problems.axyb import noise

#: from this many pairs on, the normal equations are summed in closed form (`normal_equations`)
#: instead of from the (m, 6, 12) Jacobian: measured 0.38 vs 0.08 ms at m = 16, 0.84 vs 0.52 ms
#: at 600, 0.76 vs 1.7 ms at 1000, 4.8 vs 17 ms at m = 10000.
SUMS_MIN_PAIRS = 700
#: fewest pairs for the profile likelihood. The translation residuals (3m numbers) depend on 9
#: parameters (t_X, t_Y, R_Y); with m = 3 they can be fitted exactly, and the likelihood with an
#: unknown translation variance is unbounded there (sigma_trans -> 0): measured in 6% of m = 3
#: simulations started at the truth, never from the usual starts (docs/solvers/refine.md).
PROFILE_MIN_PAIRS = 4

_I3 = so3_fast.I3
#: [e_c]_x of the unit vectors
_E = so3_fast.skew(np.eye(3))


class AXYBModel(PoseModel):
    """A_i X = Y B_i on (X, Y), with the data arranged for cheap evaluation: RA9: (3m, 3) =
    stacked R_A, RBt9: (3m, 3) = stacked R_B^T, tA, tB: (m, 3), TBx_T: (3, 3m) = [t_B]_x stacked
    side by side (so that R_Y [t_B]_x for all pairs is one product R_Y @ TBx_T)."""

    unknowns = ("X", "Y")
    profile_min_pairs = PROFILE_MIN_PAIRS
    sums_min_pairs = SUMS_MIN_PAIRS
    noise_sources = True

    def __init__(self, data: PosePairs) -> None:
        RA, RB = data.A[:, :3, :3], data.B[:, :3, :3]
        m = len(RA)
        self.m, self.scale = m, data.translation_scale
        self.RA9 = np.ascontiguousarray(RA.reshape(3 * m, 3))
        self.RBt9 = np.ascontiguousarray(np.swapaxes(RB, 1, 2)).reshape(3 * m, 3)
        self.tA = np.ascontiguousarray(data.A[:, :3, 3])
        self.tB = np.ascontiguousarray(data.B[:, :3, 3])
        self.TBx_T = np.ascontiguousarray(so3_fast.skew(self.tB).transpose(1, 0, 2)).reshape(3, 3 * m)
        planar = getattr(data, "planar", None)  # the planar mode keeps one translation component
        self.fixed = () if planar is None else planar.fixed(self.unknowns)
        self._last: tuple[bytes, np.ndarray] | None = None
        self._last_jacobian: tuple[tuple[bytes, bytes], np.ndarray] | None = None
        self._components: tuple[np.ndarray, np.ndarray] | None = None

    def residuals(self, poses: Poses) -> np.ndarray:
        """Unwhitened residuals e: (m, 6) = [r_i; t_i], r_i the rotation vector of the discrepancy
        Q_i = R_A R_X R_B^T R_Y^T (two BLAS products, one batched 3x3); read-only. The last ones
        are kept: auto's steps and the self-check ask again at the same answer (5 of 12
        evaluations at m = 1e5, 20 ms each)."""
        key = _key(poses)
        last = self._last
        if last is not None and last[0] == key:
            return last[1]
        e = self._residuals(poses)
        e.setflags(write=False)
        self._last = (key, e)
        return e

    def _residuals(self, poses: Poses) -> np.ndarray:
        X, Y = poses
        RY = Y[:3, :3]
        m = self.m
        AX = self.RA9 @ X[:3]  # (3m, 4): [R_A R_X, R_A t_X] per pair
        Q = AX[:, :3].reshape(m, 3, 3) @ (self.RBt9 @ RY.T).reshape(m, 3, 3)
        e = np.empty((m, 6))
        e[:, :3] = so3_fast.log(Q)
        e[:, 3:] = AX[:, 3].reshape(m, 3) - self.tB @ RY.T + (self.tA - Y[:3, 3])
        return e

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 12) = d e_i / d (omega_X, v_X, omega_Y, v_Y) at (X, Y), e from `residuals`;
        read-only. The last one is kept, as the residuals: the self-check's scale screen and its
        systematic test ask it at the best fit, auto's scale screen and the best fit's first step
        at the answer (2 of 9 Jacobians a solve at m = 16)."""
        key = (_key(poses), np.ascontiguousarray(e, dtype=float).tobytes())
        last = self._last_jacobian
        if last is not None and last[0] == key:
            return last[1]
        J = self._jacobian(poses, e)
        J.setflags(write=False)
        self._last_jacobian = (key, J)
        return J

    def _jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """`jacobian`, computed.

        With Q_i = R_A R_X R_B^T R_Y^T = exp([r_i]_x): X exp(omega_X) gives Q <- exp([R_A R_X omega_X]_x) Q
        and Y exp(omega_Y) gives Q <- Q exp(-[R_Y omega_Y]_x), hence
        rotation rows [Jl^-1(r) R_A R_X, 0, -Jr^-1(r) R_Y, 0];
        translation rows [0, R_A R_X, R_Y [t_B]_x, -R_Y] (R_Y [t_B]_x = [R_Y t_B]_x R_Y).
        """
        X, Y = poses
        m = self.m
        RX, minus_RY = X[:3, :3], -Y[:3, :3]
        RAX = (self.RA9 @ RX).reshape(m, 3, 3)
        Jl_inv, Jr_inv = so3_fast.inverse_jacobians(e[:, :3])
        J = np.zeros((m, 6, 12))
        np.matmul(Jl_inv, RAX, out=J[:, :3, 0:3])
        J[:, :3, 6:9] = (Jr_inv.reshape(3 * m, 3) @ minus_RY).reshape(m, 3, 3)
        J[:, 3:, 3:6] = RAX
        J[:, 3:, 6:9] = (Y[:3, :3] @ self.TBx_T).reshape(3, m, 3).transpose(1, 0, 2)
        J[:, 3:, 9:12] = minus_RY
        return J

    def noise_factors(self, data: PosePairs, poses: Poses) -> Any:
        """The noise sources of `handeye.problems.axyb.noise` at (X, Y)."""
        return noise.sources(data.A, data.B, poses[0], poses[1])

    def camera_direction(self, poses: Poses) -> np.ndarray:
        """d e / d s when the camera translations are s t_B (an unknown camera scale,
        `handeye.estimation.camera_scale`): (m, 6) = [0; -R_Y t_B]; e is linear in s, so this is exact."""
        g = np.zeros((self.m, 6))
        g[:, 3:] = -self.tB @ poses[1][:3, :3].T
        return g

    def translation_gradient(self, poses: Poses, t: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
        """sum_i J_t,i^T t_i: (12,) for vectors t: (m, 3) on the translation rows (J_t the
        translation rows of `jacobian`, which do not depend on the residual), in O(m) without
        forming J (`normal_equations` takes its translation gradient from here); q: R_Y t_B
        when the caller has it."""
        X, Y = poses
        RX, RY = X[:3, :3], Y[:3, :3]
        q = self.tB @ RY.T if q is None else q
        g = np.zeros(12)
        g[3:6] = RX.T @ np.einsum("nji,nj->i", self.RA9.reshape(self.m, 3, 3), t)
        g[6:9] = RY.T @ np.cross(t, q).sum(axis=0)
        g[9:12] = -(RY.T @ t.sum(axis=0))
        return g

    def rows(self, index: np.ndarray) -> AXYBModel:
        """This model on the pairs `index` only (the same scale and fixed components): what the
        self-check's test for systematic errors needs of 2000 pairs out of 1e5."""
        out = copy.copy(self)
        out._last = out._last_jacobian = out._components = None
        index = np.asarray(index)
        m = len(index)
        out.m = m
        out.RA9 = self.RA9.reshape(self.m, 3, 3)[index].reshape(3 * m, 3)
        out.RBt9 = self.RBt9.reshape(self.m, 3, 3)[index].reshape(3 * m, 3)
        out.tA, out.tB = self.tA[index], self.tB[index]
        out.TBx_T = np.ascontiguousarray(so3_fast.skew(out.tB).transpose(1, 0, 2)).reshape(3, 3 * m)
        return out

    def with_camera_scale(self, s: float) -> AXYBModel:
        """This model with the camera translations t_B multiplied by s (the rest shared)."""
        out = copy.copy(self)
        out._last = out._last_jacobian = out._components = None
        out.tB, out.TBx_T = s * self.tB, s * self.TBx_T
        return out

    def _by_component(self) -> tuple[np.ndarray, np.ndarray]:
        """(R_A (3, 3, m), t_B (3, m)): the pairs' data component by component, each contiguous
        over the pairs, the layout in which `normal_equations`' sums run at memory speed (kept)."""
        if self._components is None:
            RA = np.ascontiguousarray(self.RA9.reshape(self.m, 9).T).reshape(3, 3, self.m)
            self._components = (RA, np.ascontiguousarray(self.tB.T))
        return self._components

    def normal_equations(self, poses: Poses, e: np.ndarray, wr: float, wt: float,
                         d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """g_rot, g_trans (12) and Hw (12, 12) of the engine's contract without forming J.

        The blocks of J^T W J and J^T W e are sums over pairs of small products (derivation in
        docs/solvers/refine.md), using Jl^-T r = Jl^-1 r = r, Jl^-T Jl^-1 = Jl^-1 Jl^-T = I + beta [r]_x^2
        and Jl^-T Jl^-T = I + gamma [r]_x + delta [r]_x^2, with beta = 2c - 1/4 - c^2 theta^2,
        gamma = 1 - c theta^2, delta = 1/4 + 2c - c^2 theta^2 (c of `so3_fast.jl_coefficient`).
        Each sum is one BLAS contraction over the pairs: this is several times faster than the
        Jacobian route at large m and equal to it to rounding (tested).
        """
        X, Y = poses
        m = self.m
        RX, RY = X[:3, :3], Y[:3, :3]
        RA, tB = self._by_component()
        eT = np.ascontiguousarray(e.T)
        r, t = eT[:3], eT[3:]
        theta2 = np.einsum("in,in->n", r, r)
        beta, gamma, delta = so3_fast.jl_products(theta2)
        u = np.einsum("jin,jn->in", RA, r)  # R_A^T r
        q = RY @ tB  # R_Y t_B
        # the sums of R_A weighted per pair by dt, dq, d, d (1 - delta theta^2), d gamma r: one product.
        # A sum of R_A^T [v]_x is sum_c S_(v_c)^T [e_c]_x, and sum R_A^T v is sum_c row c of S_(v_c)
        W = np.empty((11, m))
        np.multiply(t, d, out=W[0:3])
        np.multiply(q, d, out=W[3:6])
        W[6] = d
        W[7] = d * (1.0 - delta * theta2)
        np.multiply(r, d * gamma, out=W[8:11])
        S = (W @ RA.reshape(9, m).T).reshape(11, 3, 3)
        dt, dq = W[0:3], W[3:6]
        db = d * beta
        Brr = (r * db) @ r.T
        sum_d = float(np.sum(d))
        ones = sum_d - float(np.trace(Brr))  # sum d (1 - beta theta^2)
        tq = dt @ q.T  # sum d t q^T: its skew part is sum d t x q
        # gradient (translation rows as `translation_gradient`)
        g_rot = np.zeros(12)
        g_rot[0:3] = wr * (RX.T @ (u @ d))
        g_rot[6:9] = -wr * (RY.T @ (r @ d))
        g_trans = np.zeros(12)
        g_trans[3:6] = wt * (RX.T @ (S[0, 0] + S[1, 1] + S[2, 2]))
        g_trans[6:9] = wt * (RY.T @ np.array([tq[1, 2] - tq[2, 1], tq[2, 0] - tq[0, 2], tq[0, 1] - tq[1, 0]]))
        g_trans[9:12] = -wt * (RY.T @ (t @ d))
        # information matrix
        H = np.zeros((12, 12))
        H[0:3, 0:3] = wr * (RX.T @ (ones * _I3 + (u * db) @ u.T) @ RX)
        H[6:9, 6:9] = wr * (RY.T @ (ones * _I3 + Brr) @ RY)
        T = S[7].T + _skew_sum(S[8:11]) + (u * (d * delta)) @ r.T
        H[0:3, 6:9] = -wr * (RX.T @ T @ RY)
        H[3:6, 3:6] = wt * sum_d * _I3
        H[9:12, 9:12] = wt * sum_d * _I3
        H[3:6, 6:9] = wt * (RX.T @ _skew_sum(S[3:6]) @ RY)
        H[3:6, 9:12] = -wt * (RX.T @ S[6].T @ RY)
        qq = dq @ q.T
        H[6:9, 6:9] += wt * (RY.T @ (float(np.trace(qq)) * _I3 - qq) @ RY)
        H[6:9, 9:12] = wt * (RY.T @ so3_fast.skew(dq.sum(axis=1)) @ RY)
        Hw = np.triu(H) + np.triu(H, 1).T  # mirror the upper blocks filled above
        return g_rot, g_trans, Hw


def _skew_sum(S: np.ndarray) -> np.ndarray:
    """sum_c S_c^T [e_c]_x of three 3x3 sums S (3, 3, 3): sum_i R_A,i^T [v_i]_x when S_c is the sum
    of R_A,i weighted by v_i's component c."""
    return S[0].T @ _E[0] + S[1].T @ _E[1] + S[2].T @ _E[2]


def _key(poses: Poses) -> bytes:
    """The bits of the poses (X, Y): what `AXYBModel`'s kept residuals and Jacobian are keyed by."""
    return np.ascontiguousarray(poses[0], dtype=float).tobytes() + np.ascontiguousarray(poses[1], dtype=float).tobytes()


# --------------------------------------------------------------------------- the host's self-check

def consecutive_motions(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                               np.ndarray, np.ndarray]:
    """The consecutive motions of the stations: rotation vectors of the robot's A_k^-1 A_k+1 (in
    the flange frame) and A_k+1 A_k^-1 (in the base frame), translations of A_k^-1 A_k+1, and
    rotation vectors and translations of the camera's B_k^-1 B_k+1: (phi_right, phi_left, t_right,
    phi_cam, t_cam), each (m-1, 3), and the angles of phi_right (m-1,)."""
    RAt, RBt = np.swapaxes(A[:-1, :3, :3], 1, 2), np.swapaxes(B[:-1, :3, :3], 1, 2)
    t_right = einsum("nij,nj->ni", RAt, A[1:, :3, 3] - A[:-1, :3, 3])
    t_cam = einsum("nij,nj->ni", RBt, B[1:, :3, 3] - B[:-1, :3, 3])
    phi_right = so3_fast.consecutive_logs(A)
    return (phi_right, so3_fast.consecutive_logs(A, moving=False), t_right, so3_fast.consecutive_logs(B), t_cam,
            row_norms(phi_right))


def expected_rotation_residual(data: PosePairs) -> float | None:
    """`Problem.expected_rotation_residual` for A_i X = Y B_i: from the angle and pitch
    differences of consecutive motions (A_k^-1 A_k+1 X = X B_k^-1 B_k+1); a station's residual
    carries one station's noise."""
    from handeye.checks.self_check import (
        angle_noise,
        expected_from_invariants,
        pitch_noise,
    )

    if data.m < 4:
        return None
    phi_A, _, t_A, phi_B, t_B, angle_A = data.consecutive_motions
    angle_B = row_norms(phi_B)
    sigma = angle_noise(angle_A, angle_B)
    pitch = None if data.camera_scale_unknown else pitch_noise(phi_A, t_A, phi_B, t_B, (angle_A, angle_B))  # B's pitch in its own unit
    return expected_from_invariants(sigma, pitch, data.translation_scale, 1.0)


def rotation_axes(data: PosePairs) -> dict[str, np.ndarray]:
    """The robot's main rotation axis in X's frame (the flange: motions A_k^-1 A_k+1) and in Y's
    (the base: A_k+1 A_k^-1)."""
    from handeye.checks.self_check import main_axes

    if data.m < 2:
        return {}
    phi_right, phi_left, *_ = data.consecutive_motions
    axes = dict(zip(("X", "Y"), main_axes(phi_right, phi_left)))
    return {k: v for k, v in axes.items() if v is not None}


def check_model(data: PosePairs, unknowns: dict[str, np.ndarray]) -> tuple[AXYBModel, tuple[np.ndarray, ...], tuple[str, ...]]:
    """`Problem.check_model` for A_i X = Y B_i: this model at the answer (X, Y)."""
    return (camera_scale.model_for(data, data.pose_model),
            (np.asarray(unknowns["X"], dtype=float), np.asarray(unknowns["Y"], dtype=float)), ("X", "Y"))


def fitted_Y(A: np.ndarray, B: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The Y that best fits A_k X = Y B_k for a given X: the chordal mean rotation of
    R_A R_X R_B^T and the mean translation of t(A_k X) - R_Y t_B."""
    from handeye.geometry.se3 import make_pose, project_to_so3

    AX = A @ X
    RY = project_to_so3(np.einsum("nij,nkj->ik", AX[:, :3, :3], B[:, :3, :3]))
    tY = np.mean(AX[:, :3, 3] - B[:, :3, 3] @ RY.T, axis=0)
    return make_pose(RY, tY)
