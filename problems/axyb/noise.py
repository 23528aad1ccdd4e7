"""Where the noise of A_i X = Y B_i lives: the noise sources of `handeye.estimation.noise_sources` for one
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


#: the columns of each source in `factors`' side-by-side array (rotations 3, translations 1)
WIDTHS = (3, 3, 3, 3, 1, 1, 1, 1)


def factors(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """The G_k of every source of `SOURCES` (module docstring), in that order, side by side:
    (m, 6, 16), `WIDTHS` columns each. Written into one array, with each product by the constant
    R_Y, R_X or t_X as one BLAS product over the stacked poses (batched 3 x 3 products and one
    array per source took 3x the time at m = 1e5)."""
    m = len(A)
    RA, tA, RB, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3]
    tX, RY = X[:3, 3], Y[:3, :3]
    RA9 = np.ascontiguousarray(RA).reshape(3 * m, 3)
    H = np.zeros((m, 6, 16))
    H[:, :3, 0:3] = -RY  # rotation of B, reference frame: [-R_Y; R_Y [t_B]x] = [-R_Y; [R_Y t_B]x R_Y]
    H[:, 3:, 0:3] = (skew(tB @ RY.T).reshape(3 * m, 3) @ RY).reshape(m, 3, 3)
    camera_axes = (RY @ np.ascontiguousarray(np.swapaxes(RB, 0, 1)).reshape(3, 3 * m)).reshape(3, m, 3).swapaxes(0, 1)
    H[:, :3, 3:6] = -camera_axes  # rotation of B, own frame: [-R_Y R_B; 0]
    H[:, :3, 6:9] = RA  # rotation of A, own frame: [R_A; -R_A [t_X]x]
    H[:, 3:, 6:9] = (RA9 @ -skew(tX)).reshape(m, 3, 3)
    H[:, [0, 1, 2], [9, 10, 11]] = 1.0  # rotation of A, reference frame: [I; -[R_A t_X + t_A]x]
    H[:, 3:, 9:12] = -skew((RA9 @ tX).reshape(m, 3) + tA)
    H[:, 3:, 12:15] = camera_axes  # translation of B along its own x, y, z: [0; R_Y R_B e_j]
    H[:, 3:, 15] = RY[:, 2]  # translation of B along its reference frame's z: [0; R_Y e_3]
    return H


def sources(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray) -> Sources:
    """The noise sources of A_i X = Y B_i at (X, Y) (`SOURCES`), for `handeye.estimation.noise_sources`."""
    return Sources.side_by_side(factors(A, B, X, Y), WIDTHS, SOURCES, translation=[False] * 4 + [True] * 4)
