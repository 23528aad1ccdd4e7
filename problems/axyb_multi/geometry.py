"""The geometric model of A_i X_{x_i} = Y_{y_i} B_i for the least-squares engine (`handeye.estimation.nlls`):
residuals, Jacobians and normal equations on SE(3)^(nX + nY), and what the host's self-check
needs (its model, the noise the data show, the robot's rotation axes).

One 6-vector per observation i, with j = x_i and k = y_i: the residual of A_i X = Y B_i
(`handeye.problems.axyb.geometry.AXYBModel`, the paper's eqs. 32-33 as vectors) on the pair
(X_j, Y_k) it observes,

    r_i = log(R_Ai R_Xj R_Bi^T R_Yk^T)              rotation vector of the discrepancy [rad]
    t_i = R_Ai t_Xj + t_Ai - R_Yk t_Bi - t_Yk        t(A_i X_j) - t(Y_k B_i)          [data units]

The unknowns are the poses X[0], ..., X[nX-1], Y[0], ..., Y[nY-1] (the order of
`handeye.framework.problem_engine.flat_names`), each perturbed on the right, T <- T exp(xi), xi = (omega, v). An
observation depends on two of them only; its 6 x 12 block on (xi_Xj, xi_Yk) is AXYBModel's
(derivation in docs/solvers/refine.md):

    d r / d omega_Xj = Jl^-1(r) R_A R_Xj      d r / d omega_Yk = -Jr^-1(r) R_Yk
    d t / d v_Xj     = R_A R_Xj               d t / d omega_Yk = R_Yk [t_B]_x
    d t / d v_Yk     = -R_Yk                  (other blocks zero)

The Jacobian (m, 6, 6(nX + nY)) is those blocks put in their columns (`AXYBMultiModel.jacobian`).
From SUMS_WORK / (nX + nY) observations on, the normal equations are summed from the blocks instead
(`AXYBMultiModel.normal_equations`): each observation adds its 12 x 12 block J_i^T W J_i to the
four 6 x 6 blocks of its pair, summed per observed (X, Y) pair first, so that the cost grows as
m * 12^2 rather than m * (6(nX + nY))^2.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.estimation import camera_scale
from handeye.estimation.nlls import PoseModel, Poses
from handeye.geometry import so3_fast

#: the normal equations are summed from the per-observation blocks (`AXYBMultiModel.normal_equations`)
#: instead of from the (m, 6, 6n) Jacobian from SUMS_WORK / n observations on (n = nX + nY): the
#: Jacobian route costs ~m (6n)^2, the sums ~m 12^2 plus a fixed ~0.2 ms. Measured (one evaluation
#: of g and H): break-even near m = 240 for n = 5, 130 for n = 9, 50 for n = 24; at m = 3000,
#: n = 24: 3 ms against 30 ms (tests/problems/axyb_multi/test_axyb_multi_problem.py checks that both agree to rounding).
SUMS_WORK = 1200


class AXYBMultiModel(PoseModel):
    """A_i X_{x_i} = Y_{y_i} B_i on (X[0], ..., Y[nY-1]), with the data arranged for batched
    evaluation: RA (m, 3, 3), tA (m, 3), RBt (m, 3, 3) = R_B^T, tB (m, 3), TBx (m, 3, 3) =
    [t_B]_x; x, y the indices of each observation's X and Y; the observed (X, Y) pairs and each
    observation's pair (for the closed-form sums)."""

    noise_sources = True  # a noise level per camera and per target: `handeye.problems.axyb_multi.noise`

    #: how the data say that cameras are known only up to scale (the host's check 5 names it)
    scale_hint = "camera_scale=[the names of the monocular cameras]"

    def __init__(self, data: Any) -> None:
        m, nX, nY = data.m, data.nX, data.nY
        self.m, self.nX, self.nY, self.n = m, nX, nY, nX + nY
        self.sums_min_pairs = math.ceil(SUMS_WORK / max(self.n, 1))
        self.scale = data.translation_scale
        self.unknowns = tuple(f"X[{j}]" for j in range(nX)) + tuple(f"Y[{k}]" for k in range(nY))
        #: the names the data give the unknowns (x_names, then y_names), for messages
        self.names = tuple(data.x_names) + tuple(data.y_names)
        # The translation residuals (3m numbers) depend on t_X, t_Y and R_Y (3 nX + 6 nY
        # parameters): with fewer observations they can be fitted exactly, and the profile
        # likelihood with an unknown translation variance is unbounded there (as AXYBModel's m = 3).
        self.profile_min_pairs = nX + 2 * nY + 1
        self.x, self.y = np.asarray(data.x_index), np.asarray(data.y_index)
        self.RA = np.ascontiguousarray(data.A[:, :3, :3])
        self.tA = np.ascontiguousarray(data.A[:, :3, 3])
        self.RBt = np.ascontiguousarray(np.swapaxes(data.B[:, :3, :3], 1, 2))
        self.tB = np.ascontiguousarray(data.B[:, :3, 3])
        self.TBx = so3_fast.skew(self.tB)
        pairs, of = data.pair_index
        self.pairs = pairs
        self._order = np.argsort(of, kind="stable")  # observations grouped by pair, for np.add.reduceat
        self._starts = np.flatnonzero(np.r_[True, np.diff(of[self._order]) != 0])

    # ------------------------------------------------------------------ poses

    def _split(self, poses: Poses) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(R_X (nX, 3, 3), t_X (nX, 3), R_Y (nY, 3, 3), t_Y (nY, 3)) of the poses."""
        P = np.stack(poses)
        if len(P) != self.n:
            raise ValueError(f"{len(P)} poses for the model's {self.n} unknowns")
        return P[:self.nX, :3, :3], P[:self.nX, :3, 3], P[self.nX:, :3, :3], P[self.nX:, :3, 3]

    def residuals(self, poses: Poses) -> np.ndarray:
        """Unwhitened residuals e: (m, 6) = [r_i; t_i] (module docstring)."""
        RX, tX, RY, tY = self._split(poses)
        RYi = RY[self.y]
        RAX = self.RA @ RX[self.x]
        e = np.empty((self.m, 6))
        e[:, :3] = so3_fast.log(RAX @ (self.RBt @ np.swapaxes(RYi, 1, 2)))
        e[:, 3:] = (np.einsum("nij,nj->ni", self.RA, tX[self.x]) + self.tA
                    - np.einsum("nij,nj->ni", RYi, self.tB) - tY[self.y])
        return e

    def blocks(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """L: (m, 6, 12) = d e_i / d (omega_Xj, v_Xj, omega_Yk, v_Yk), each observation's block on
        its own X and Y (module docstring), e from `residuals`."""
        RX, _, RY, _ = self._split(poses)
        RYi = RY[self.y]
        RAX = self.RA @ RX[self.x]
        Jl_inv, Jr_inv = so3_fast.inverse_jacobians(e[:, :3])
        L = np.zeros((self.m, 6, 12))
        np.matmul(Jl_inv, RAX, out=L[:, :3, 0:3])
        L[:, :3, 6:9] = -(Jr_inv @ RYi)
        L[:, 3:, 3:6] = RAX
        np.matmul(RYi, self.TBx, out=L[:, 3:, 6:9])
        L[:, 3:, 9:12] = -RYi
        return L

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        """J: (m, 6, 6(nX + nY)): each observation's `blocks` in the columns of its X and its Y."""
        L = self.blocks(poses, e)
        J = np.zeros((self.m, 6, self.n, 6))
        rows = np.arange(self.m)
        J[rows, :, self.x, :] = L[:, :, :6]
        J[rows, :, self.nX + self.y, :] = L[:, :, 6:]
        return J.reshape(self.m, 6, 6 * self.n)

    def normal_equations(self, poses: Poses, e: np.ndarray, wr: float, wt: float,
                         d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """g_rot, g_trans (6n) and Hw (6n, 6n) of the engine's contract (`PoseModel.normal_equations`)
        without forming J: per observation d_i L_i^T W L_i (12 x 12) and d_i L_i^T W e_i, summed per
        observed (X, Y) pair, then added into the blocks of that pair's X and Y."""
        L = self.blocks(poses, e)
        w = np.array([wr, wr, wr, wt, wt, wt])
        LW = L * (d[:, None] * w)[:, :, None]  # rows weighted: W d_i L_i
        order, starts = self._order, self._starts
        H_pair = np.add.reduceat((np.swapaxes(LW, 1, 2) @ L)[order], starts, axis=0)  # (P, 12, 12)
        g_rot_pair = np.add.reduceat(np.einsum("nai,na->ni", LW[:, :3], e[:, :3])[order], starts, axis=0)
        g_trans_pair = np.add.reduceat(np.einsum("nai,na->ni", LW[:, 3:], e[:, 3:])[order], starts, axis=0)
        xs, ys = self.pairs[:, 0], self.nX + self.pairs[:, 1]
        H = np.zeros((self.n, self.n, 6, 6))
        for (a, b), (ra, rb) in (((xs, xs), (0, 0)), ((xs, ys), (0, 6)), ((ys, xs), (6, 0)), ((ys, ys), (6, 6))):
            np.add.at(H, (a, b), H_pair[:, ra:ra + 6, rb:rb + 6])
        Hw = H.transpose(0, 2, 1, 3).reshape(6 * self.n, 6 * self.n)
        Hw = 0.5 * (Hw + Hw.T)
        return self._gather(g_rot_pair, xs, ys), self._gather(g_trans_pair, xs, ys), Hw

    def _gather(self, per_pair: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """(6n,) from per-pair 12-vectors (P, 12): the first 6 added to the pair's X, the last to its Y."""
        g = np.zeros((self.n, 6))
        np.add.at(g, xs, per_pair[:, :6])
        np.add.at(g, ys, per_pair[:, 6:])
        return g.reshape(-1)

    def noise_factors(self, data: Any, poses: Poses) -> Any:
        """The noise sources of every X and Y and the robot's (`handeye.problems.axyb_multi.noise`)."""
        from handeye.problems.axyb_multi.noise import sources

        return sources(data, poses)

    # ------------------------------------------------------------------ the camera's scale

    def camera_direction(self, poses: Poses) -> np.ndarray:
        """d e / d s when every camera translation is s t_B (`handeye.estimation.camera_scale`, the host's
        check of the length units): (m, 6) = [0; -R_Yk t_B]; e is linear in s, so this is exact."""
        _, _, RY, _ = self._split(poses)
        g = np.zeros((self.m, 6))
        g[:, 3:] = -np.einsum("nij,nj->ni", RY[self.y], self.tB)
        return g

    def translation_gradient(self, poses: Poses, t: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
        """sum_i J_t,i^T t_i: (6n,) for vectors t: (m, 3) on the translation rows (which do not
        depend on the residual), without forming J. q is not used (AXYBModel's signature)."""
        RX, _, RY, _ = self._split(poses)
        RYi = RY[self.y]
        RAX = self.RA @ RX[self.x]
        u = np.einsum("nji,nj->ni", RYi, t)  # R_Y^T t
        g = np.zeros((self.n, 6))
        np.add.at(g[:, 3:], self.x, np.einsum("nji,nj->ni", RAX, t))
        np.add.at(g[:, :3], self.nX + self.y, np.cross(u, self.tB))  # (R_Y [t_B]_x)^T t = [t_B]_x^T u = u x t_B
        np.add.at(g[:, 3:], self.nX + self.y, -u)
        return g.reshape(-1)

    @property
    def scale_groups(self) -> tuple[tuple[str, np.ndarray], ...]:
        """The observations of each X and each Y by name (X's first): the groups in which the
        host's check 5 looks for a camera whose translations fit only at another scale (which
        of them are cameras the data do not say)."""
        return (tuple((self.names[j], np.flatnonzero(self.x == j)) for j in range(self.nX))
                + tuple((self.names[self.nX + k], np.flatnonzero(self.y == k)) for k in range(self.nY)))

    def with_camera_scale(self, s: float | np.ndarray) -> AXYBMultiModel:
        """This model with the camera translations t_B multiplied by s (the rest shared): one
        factor, or (m,) one per observation (each camera's own, `handeye.estimation.camera_scales`)."""
        out = copy.copy(self)
        s = np.asarray(s, dtype=float)
        if s.ndim:
            out.tB, out.TBx = s[:, None] * self.tB, s[:, None, None] * self.TBx
        else:
            out.tB, out.TBx = float(s) * self.tB, float(s) * self.TBx
        return out


# --------------------------------------------------------------------------- the host's self-check

def poses_of(unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    """The unknowns {"X": (nX, 4, 4), "Y": (nY, 4, 4)} as the model's poses X[0], ..., Y[nY-1]."""
    return (tuple(np.asarray(unknowns["X"], dtype=float).reshape(-1, 4, 4))
            + tuple(np.asarray(unknowns["Y"], dtype=float).reshape(-1, 4, 4)))


def check_model(data: Any, unknowns: Mapping[str, np.ndarray]) -> tuple[PoseModel, tuple[np.ndarray, ...], tuple[str, ...]]:
    """`Problem.check_model`: the model at the answer; every pose of both stacks is the answer's."""
    model = camera_scale.model_for(data, data.pose_model)
    return model, poses_of(unknowns), tuple(model.unknowns)


def pair_motions(data: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The motions between consecutive observations of the same (X, Y) pair (in the order of the
    data), which must agree as A X = X B does: A_l^-1 A_i X_j = X_j B_l^-1 B_i. Rotation vectors
    and translations of the robot's (in the flange frame) and of the camera's, each (n, 3)."""
    _, of = data.pair_index
    order = np.argsort(of, kind="stable")
    same = of[order][1:] == of[order][:-1]
    first, then = order[:-1][same], order[1:][same]
    A, B = data.A, data.B

    def motion(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Rt = np.swapaxes(T[first, :3, :3], 1, 2)
        return (so3_fast.log(Rt @ T[then, :3, :3]) if len(first) else np.zeros((0, 3)),
                np.einsum("nij,nj->ni", Rt, T[then, :3, 3] - T[first, :3, 3]))

    (phi_A, t_A), (phi_B, t_B) = motion(A), motion(B)
    return phi_A, t_A, phi_B, t_B


def expected_rotation_residual(data: Any) -> float | None:
    """`Problem.expected_rotation_residual`: from the angle and pitch differences of the motions
    between observations of the same pair (`pair_motions`), as for A_i X = Y B_i."""
    from handeye.checks.self_check import (
        angle_noise,
        expected_from_invariants,
        pitch_noise,
    )

    phi_A, t_A, phi_B, t_B = pair_motions(data)
    if len(phi_A) < 3:
        return None
    sigma = angle_noise(np.linalg.norm(phi_A, axis=1), np.linalg.norm(phi_B, axis=1))
    pitch = None if data.camera_scale_unknown else pitch_noise(phi_A, t_A, phi_B, t_B)
    return expected_from_invariants(sigma, pitch, data.translation_scale, 1.0)


def rotation_axes(data: Any) -> dict[str, np.ndarray]:
    """`Problem.rotation_axes`: per component of the observation graph, the robot's main
    rotation axis over its stations, in the flange frame for its X's and in the base frame for its
    Y's (named X[j], Y[k] as the model's unknowns), where the rotations are mostly about one."""
    from handeye.checks.self_check import main_axes

    out: dict[str, np.ndarray] = {}
    station = data.station_index
    for c in data.components:
        first = np.unique(station[c.observations], return_index=True)[1]
        A = data.A[np.sort(c.observations[first])]  # one pose per station, in the data's order
        if len(A) < 2:
            continue
        axis_X, axis_Y = main_axes(so3_fast.consecutive_logs(A), so3_fast.consecutive_logs(A, moving=False))
        out.update({f"X[{j}]": axis_X for j in c.x if axis_X is not None})
        out.update({f"Y[{k}]": axis_Y for k in c.y if axis_Y is not None})
    return out
