"""Where the noise of A_i X = Y B_i lives: the noise sources of `handeye.noise_sources` for one
camera and one target.

Real noise enters through the measured poses, each in its own frame: a camera's rotation error in
the target frame moves the translation residual by the camera-target distance (a lever of 0.3-1
m); a camera's translation error is largest along its optical axis (a pose from PnP is 3-10x less
sure of its depth than of its sideways position); a robot's rotation error in the base frame
moves the translation by the camera's distance from the base. Each source k (an error w ~ N(0,
s_k^2 I) of one pose, in one frame, along one axis or all three) maps to pair i's residual e_i =
[r_i; t_i] of `AXYBModel` through a 6 x r_k matrix G_ik (its first-order change when that pose
is perturbed so).

The sources (`SOURCES`), named by the side of A or B the error multiplies: its reference frame
(left: P <- exp(w) P) or its own frame (right: P <- P exp(w)). In axyb's terms (docs/conventions.md)
A = T_base_flange in both setups (own frame: the flange; reference: the base); B = T_target_cam
eye-in-hand (own frame: the camera; reference: the target) and T_cam_target eye-to-hand (own
frame: the target; reference: the camera, whose z is the optical axis):

- rotation of B, reference frame (B <- exp(w) B):   G = [-R_Y; R_Y [t_B]x] (a lever of |t_B|)
- rotation of B, own frame (B <- B exp(w)):         G = [-R_Y R_B; 0]
- rotation of A, own frame (A <- A exp(w)):         G = [R_A; -R_A [t_X]x]
- rotation of A, reference frame (A <- exp(w) A):   G = [I; -[R_A t_X + t_A]x]
- translation of B along its own x, y and z (one source each): G = [0; R_Y R_B e_j]. Together
  they hold any isotropic translation error (either pose, any frame: the robot's too), and
  eye-in-hand the extra depth error of a camera along its optical axis z.
- translation of B along its reference frame's z: G = [0; R_Y e_3]: the optical axis eye-to-hand.

Chosen by measurement (KinHEC small tier, and the simulator's isotropic noise, where the
per-group model is the true one): per-axis translation sources in both of the camera pose's
frames (6) or a robot translation along its flange axes made the answers no better on KinHEC
and up to 9% worse on the simulator at 16 pairs; these 8 sources cost 1-3% there (geometric
mean of X's translation error, 30 data sets at 16, 30 and 60 pairs).
"""

from __future__ import annotations

import numpy as np

from handeye.estimation.noise_sources import Sources
from handeye.geometry.so3_fast import skew

#: the noise sources, in the order of the variances
SOURCES = ("rotation of B, reference frame", "rotation of B, own frame", "rotation of A, own frame",
           "rotation of A, reference frame", "translation of B, own x", "translation of B, own y",
           "translation of B, own z", "translation of B, reference z")


def rotation_factor(top: np.ndarray, bottom: np.ndarray | None = None, m: int | None = None) -> np.ndarray:
    """A rotation source's G: (m, 6, 3) = [top; bottom] (bottom None: zero)."""
    m = len(top) if m is None else m
    G = np.zeros((m, 6, 3))
    G[:, :3] = top
    if bottom is not None:
        G[:, 3:] = bottom
    return G


def robot_factors(RA: np.ndarray, tA: np.ndarray, tX: np.ndarray) -> list[np.ndarray]:
    """G of the robot's rotation in its own frame and in its reference frame (module docstring),
    for pairs whose X translations are tX: (m, 3) or (3,)."""
    tX = np.broadcast_to(tX, tA.shape)
    lever = np.einsum("nij,nj->ni", RA, tX) + tA  # where X's origin is, in the base frame
    return [rotation_factor(RA, -RA @ skew(tX)), rotation_factor(np.broadcast_to(np.eye(3), RA.shape), -skew(lever))]


def factors(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> list[np.ndarray]:
    """G_k: (m, 6, r_k) for each source of `SOURCES` (module docstring), in that order."""
    RA, tA, RB, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3]
    tX, RY = X[:3, 3], Y[:3, :3]
    m = len(A)

    def axis(frame: np.ndarray, j: int) -> np.ndarray:
        G = np.zeros((m, 6, 1))
        G[:, 3:, 0] = frame[..., j]
        return G

    camera_axes = RY @ RB
    return [rotation_factor(np.broadcast_to(-RY, (m, 3, 3)), RY @ skew(tB)), rotation_factor(-camera_axes),
            *robot_factors(RA, tA, tX),
            axis(camera_axes, 0), axis(camera_axes, 1), axis(camera_axes, 2), axis(np.broadcast_to(RY, (m, 3, 3)), 2)]


def sources(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> Sources:
    """The noise sources of A_i X = Y B_i at (X, Y) (`SOURCES`), for `handeye.noise_sources`."""
    return Sources.of(factors(A, B, X, Y), SOURCES, translation=[False] * 4 + [True] * 4)
