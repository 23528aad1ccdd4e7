"""Where the noise of a multi-camera cell lives: a noise level for every camera and every target
(`handeye.estimation.noise_sources`, the sources of `handeye.problems.axyb.noise` per pose).

The cameras of a cell differ: one has a longer lens or a lower resolution, one target is smaller
or seen from farther. With one noise level for every observation, least squares weighs a noisy
camera's poses as much as a sharp one's; with a level per camera and per target, maximum
likelihood weighs each observation by the noise of the two things it ties. Observation i (its
X_j and Y_k) is reached by the sources of its camera pose B_i, in three kinds, once for X_j and
once for Y_k (each X and each Y has its own three variances, which add up on the observations
they share), and by the robot's two:

- "NAME: rotation of B, own frame" (B <- B exp(w)):          G = [-R_Y R_B; 0]
- "NAME: rotation of B, reference frame" (B <- exp(w) B):    G = [-R_Y; R_Y [t_B]x]
- "NAME: translation of B" (isotropic):                      G = [0; I]
- "rotation of A, own frame", "rotation of A, reference frame" (the robot's, as for axyb).

In the eye-to-hand setup (B = T_cam_marker) a marker's pose error from PnP is a rotation about
the marker (own frame), a camera's calibration error one about the camera (reference frame);
eye in hand (B = T_board_cam) the other way round: both kinds for every pose keep the model
right in both setups and in a mix. The robot's translation noise is isotropic too and joins the
translation sources. 3 (nX + nY) + 2 variances: 74 for 8 cameras and 16 markers, estimated from
the observations (auto fits them where there are RESIDUALS_PER_VARIANCE residuals per variance).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from handeye.estimation.noise_sources import Sources
from handeye.geometry.so3_fast import skew
from handeye.problems.axyb.noise import robot_factors, rotation_factor

#: the kinds of source of each X and each Y, in the order of their variances
KINDS = ("rotation of B, own frame", "rotation of B, reference frame", "translation of B")
#: the robot's sources, after every X's and Y's
ROBOT = ("rotation of A, own frame", "rotation of A, reference frame")


def sources(data: Any, poses: tuple[np.ndarray, ...]) -> Sources:
    """The noise sources of the cell's observations at the poses X[0], ..., Y[nY-1] (module
    docstring): H (m, 6, 24) = [X_j's 9 columns, Y_k's 9, the robot's 6] per observation."""
    P = np.stack(poses)
    nX, n = data.nX, data.nX + data.nY
    x, y = np.asarray(data.x_index), np.asarray(data.y_index)
    RA, tA, RB, tB = data.A[:, :3, :3], data.A[:, :3, 3], data.B[:, :3, :3], data.B[:, :3, 3]
    RY, tX = P[nX:, :3, :3][y], P[:nX, :3, 3][x]
    m = len(RA)
    translation = np.zeros((m, 6, 3))
    translation[:, 3:] = np.eye(3)
    pose = np.concatenate([rotation_factor(-(RY @ RB)), rotation_factor(-RY, RY @ skew(tB)), translation], axis=2)
    H = np.concatenate([pose, pose, *robot_factors(RA, tA, tX)], axis=2)
    kind = np.repeat(np.arange(3), 3)
    column_source = np.concatenate([3 * x[:, None] + kind, 3 * (nX + y)[:, None] + kind,
                                    np.broadcast_to(3 * n + np.repeat(np.arange(2), 3), (m, 6))], axis=1)
    names = tuple(f"{name}: {k}" for name in (*data.x_names, *data.y_names) for k in KINDS) + ROBOT
    return Sources(H, column_source, names, np.array([False, False, True] * n + [False, False]))
