"""Where the noise of A_i X = Y B_i lives, estimated by maximum likelihood with the unknowns.

The least squares of `handeye.nlls` with estimated weights assumes one noise level per residual
group (rotation, translation), the same for every pair. Real noise enters through the measured
poses: a camera's rotation error in the target frame moves the translation residual by the
camera-target distance (a lever of 0.3-1 m), a robot's rotation error in the base frame by the
camera's distance from the base; the residual's covariance then differs from pair to pair and
couples its rotation and translation. Each source k of noise (a rotation error w ~ N(0, s_k^2 I3)
of one pose, in one frame) maps to pair i's residual e_i = [r_i; t_i] of `AXYBModel` through a
6 x 3 matrix G_ik, so

    Cov(e_i) = Sigma_i(theta) = sum_k theta_k G_ik G_ik^T + theta_t diag(0, I3),   theta = s^2 >= 0,

with the sources (`SOURCES`; each map is the first-order change of `AXYBModel`'s residual when
that pose is perturbed in that frame):

- camera rotation in the target frame (B <- exp(w) B):    [-R_Y; R_Y [t_B]x]
- camera rotation in the camera frame (B <- B exp(w)):    [-R_Y R_B; 0]
- robot rotation in the flange frame (A <- A exp(w)):      [R_A; -R_A [t_X]x]
- robot rotation in the base frame (A <- exp(w) A):        [I; -[R_A t_X + t_A]x]
- translations (either pose, any frame): isotropic in t_i, one variance theta_t (their maps are
  rotations, which no residual can tell apart).

`fit` alternates: the variances by maximum likelihood at the current residuals (`variances`: the
fixed point of the EM update for variance components, which keeps them >= 0 and never lowers
the likelihood), then the unknowns by `handeye.nlls` with every pair whitened by its Sigma_i,
until the unknowns stop moving. Measured on the KinHEC small tier (docs/kinhec.md, against the
default noise model): median X translation with PnP noise 0.37 -> 0.14 mm, Gaussian noise 2.15 ->
1.90 mm, clock offsets 0.92 -> 0.85 mm; every track within 2% of the best reference solver or
below; 30-150 ms a sequence, hence opt-in (docs/solvers/auto.md, "Noise sources").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import nlls
from .so3_fast import skew
from .whitening import Whitening

#: the noise sources, in the order of the variances
SOURCES = ("camera rotation (target frame)", "camera rotation (camera frame)", "robot rotation (flange frame)",
           "robot rotation (base frame)", "translations")
#: the alternation stops when no unknown moves by more than this (rad, and relative to the data's
#: length scale) between two rounds, or after MAX_ROUNDS (measured at m = 16: 1e-8 and 1e-10 give
#: the same answers to 1e-4 of their errors, in 4-8 rounds)
ROUND_TOL = 1e-8
MAX_ROUNDS = 8
#: EM iterations of the variances per round, and their relative tolerance (each round starts from
#: the previous round's variances)
EM_ITER = 200
EM_TOL = 1e-6


def maps(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """G: (4, m, 6, 3), the rotation sources' maps to each pair's residual (module docstring)."""
    RA, tA, RB, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3]
    tX, RY = X[:3, 3], Y[:3, :3]
    m = len(A)
    G = np.zeros((4, m, 6, 3))
    G[0, :, :3] = -RY
    G[0, :, 3:] = RY @ skew(tB)
    G[1, :, :3] = -(RY @ RB)
    G[2, :, :3] = RA
    G[2, :, 3:] = -RA @ skew(tX)
    G[3, :, :3] = np.eye(3)
    G[3, :, 3:] = -skew(RA @ tX + tA)
    return G


def covariances(G: np.ndarray) -> np.ndarray:
    """C: (5, m, 6, 6): G_k G_k^T per rotation source, and diag(0, I3) for the translations."""
    C = np.zeros((5,) + G.shape[1:3] + (6,))
    C[:4] = G @ np.swapaxes(G, 2, 3)
    C[4, :, 3:, 3:] = np.eye(3)
    return C


def variances(C: np.ndarray, e: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The maximum-likelihood variances theta >= 0 of Sigma_i = sum_k theta_k C_ik for residuals
    e: (m, 6), from `theta` (all > 0), by the EM update theta_k <- theta_k (u_i^T C_ik u_i summed) /
    (trace(Sigma_i^-1 C_ik) summed), u_i = Sigma_i^-1 e_i: its fixed points are the likelihood's
    stationary points, and a variance a source does not need goes to zero."""
    floor = 1e-12 * float(np.max(theta))
    for _ in range(EM_ITER):
        S = np.einsum("k,kmij->mij", theta, C)
        S[:, range(6), range(6)] += floor
        Si = np.linalg.inv(S)
        u = np.einsum("mij,mj->mi", Si, e)
        num = np.einsum("mi,kmij,mj->k", u, C, u)
        den = np.einsum("mij,kmji->k", Si, C)
        new = theta * num / np.maximum(den, 1e-300)
        done = np.max(np.abs(new - theta)) <= EM_TOL * np.max(new)
        theta = new
        if done:
            break
    return theta


def whitening(C: np.ndarray, theta: np.ndarray) -> Whitening:
    """The per-pair Cholesky factors of Sigma_i(theta) (a relative floor keeps them positive
    definite where a variance went to zero)."""
    S = np.einsum("k,kmij->mij", theta, C)
    S[:, range(6), range(6)] += 1e-12 * float(np.mean(np.trace(S, axis1=1, axis2=2)))
    return Whitening(L=np.linalg.cholesky(S))


def fit(model: Any, data: Any, poses: tuple[np.ndarray, ...], settings: nlls.Settings
        ) -> tuple[tuple[np.ndarray, ...], Any, dict[str, Any]]:
    """The unknowns (X, Y) and the noise sources' variances of A_i X = Y B_i by maximum
    likelihood from `poses`, alternating (module docstring); `settings` give the loss, tol and
    max_iter of each refinement. Returns (poses, status, diagnostics of the last refinement with
    ``noise_sources``: each source's standard deviation, rad or data units, and ``rounds``)."""
    e = model.residuals(poses)
    m = len(e)
    sr2 = float(np.sum(e[:, :3] ** 2)) / (3 * m)
    st2 = float(np.sum(e[:, 3:] ** 2)) / (3 * m)
    floor = 1e-24 * max(sr2, st2 / max(model.scale, 1e-300) ** 2, 1e-300)
    theta = np.array([max(sr2, floor) / 4] * 4 + [max(st2, floor * model.scale**2) / 2])
    status, diag, rounds = None, {}, 0
    for rounds in range(1, MAX_ROUNDS + 1):
        C = covariances(maps(data.A, data.B, poses[0], poses[1]))
        theta = variances(C, e, theta)
        stated = nlls.Settings(W=whitening(C, theta), weights="covariance", loss=settings.loss,
                               loss_scale=settings.loss_scale, max_iter=settings.max_iter, tol=settings.tol)
        new, status, diag = nlls.refine(model, poses, stated)
        moved = max(max(float(np.max(np.abs(a[:3, :3] - b[:3, :3]))),
                        float(np.max(np.abs(a[:3, 3] - b[:3, 3]))) / model.scale) for a, b in zip(new, poses))
        poses, e = new, model.residuals(new)
        if moved <= ROUND_TOL:
            break
    diag = {**diag, "weights": "estimated", "noise_model": "sources", "rounds": rounds,
            "noise_sources": {name: math.sqrt(max(float(t), 0.0)) for name, t in zip(SOURCES, theta)}}
    return poses, status, diag
