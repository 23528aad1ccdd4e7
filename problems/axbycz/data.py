"""The dual-robot problem A_i X B_i = Y C_i Z (hand-eye, robot-robot and tool-flange at once).

Data: A, B, C: (m, 4, 4). Unknowns: X, Y, Z (4x4). In the dual-arm cell of Wu et al. (IEEE T-RO
32(2), 2016), robot 1 carries a camera and robot 2 a marker (a target or a tool):

    A_i = T_base1_flange1   robot 1's flange pose (its controller)
    X   = T_flange1_cam     hand-eye of robot 1
    B_i = T_cam_marker      the marker's pose in the camera (solvePnP)
    Y   = T_base1_base2     robot-robot
    C_i = T_base2_flange2   robot 2's flange pose (its controller)
    Z   = T_flange2_marker  tool-flange of robot 2

and both sides are T_base1_marker (docs/conventions.md, with the single-robot cell).

Residuals per triple: the rotation angle and translation distance between A_i X B_i and
Y C_i Z (`handeye.framework.problem.pose_discrepancy`), as eqs. 32-33 are for A X = Y B.

What the data determine (docs/conventions.md, "Problem axbycz"). Each data stack ties two
unknowns together: the same data are also solved by (X', Y', Z') with, for a pose G,

    A (robot 1):  X' = G X,      Y' = G' Y    G commuting with robot 1's motions A_j^-1 A_i
    B (camera):   X' = X G,      Z' = Z G'    G commuting with the camera's motions B_j B_i^-1
    C (robot 2):  Z' = G^-1 Z,   Y' = Y G'    G commuting with robot 2's motions C_j^-1 C_i

(G' = A_0 G A_0^-1, B_0^-1 G B_0, C_0 G C_0^-1). Motions that rotate about at least two
different axes commute with the identity only; a stack that does not move leaves a whole pose
free (C the same in every triple: only the product Y C Z is determined, not Y and Z; A the same:
only Y^-1 A X), and one that rotates about one axis (or not at all, translating only) leaves at
least the translations along it free. `AXBYCZ.validate` refuses such data
(`DegenerateDataError`, naming the stack and what to record). With every stack rotating about
two axes or more, the 18-parameter Jacobian at the truth had full rank in every simulated data
set, free motion from m = 3 triples (18 equations for 18 unknowns), phases from m = 5 (tested);
the check does not exclude a coupled degeneracy of special data, which the engine's singular
normal matrix would then report. The phase protocol meets this with at least 3 poses of each
robot while the other holds still (m >= 5): robot 2 still, (A_j^-1 A_i) X = X (B_j B_i^-1)
gives X (AX=XB); robot 1 still, (C_j^-1 C_i) Z = Z (B_j^-1 B_i) gives Z; then any triple gives
Y. `AXBYCZData.still_groups` finds those phases (`handeye.problems.axbycz.geometry` uses their conjugate motions, whose
rotation angles must agree, for the host's self-check), `diagnose` reports the figures.

The simulator (`AXBYCZ.simulate`) puts two arms of the paper's kind (`handeye.geometry.kinematics`)
facing each other, noise (`handeye.estimation.noise.NoiseModel`) on A, B and C, and either free motion
(both arms move at every triple) or the phase protocol of the two-step methods (the first half
of the triples with robot 2 holding still, the second half with robot 1 holding still).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.estimation.kronecker import (
    scaled_stacks,
    translation_rms,
    validated_stacks,
)
from handeye.geometry.se3 import make_pose, project_to_so3, so3_exp

FIELDS = ("A", "B", "C")
PROTOCOLS = ("free", "phases")
#: a relative rotation below this (rad) does not count as a rotation (its axis is undefined)
MIN_MOTION_ANGLE = 1e-6
#: axis spread (rad, `AXBYCZData.rotation_spread`) below which a stack's rotations count as one axis
DEGENERATE_AXIS_SPREAD = 1e-6
#: a robot "holds still" between two triples whose poses differ by at most this rotation (rad)
#: and this share of the data's RMS translation: simulated noise of 0.002 rad / 0.2 mm moves a
#: still pose by ~0.005 rad / 0.5 mm, a robot that moves at all moves far more (the phase
#: detection of solver fu-dq uses the same defaults)
STILL_ROTATION = 0.05
STILL_TRANSLATION = 0.01
#: the stacks in the order they are checked: (what they are, the unknowns they separate, what to record)
STACKS = {
    "A": ("robot 1's flange poses (A)", "X and Y", "only Y^-1 A X is determined",
          "record robot 1 at poses rotated about at least two different axes"),
    "C": ("robot 2's flange poses (C)", "Y and Z", "only Y C Z is determined",
          "record robot 2 at poses rotated about at least two different axes"),
    "B": ("the marker's poses in the camera (B)", "X and Z", "only X B Z^-1 is determined",
          ("record poses where the marker turns in the camera about at least two different axes "
           "(the robots must not move in lockstep)")),
}

#: The simulated cell's truth: the camera 100 mm off robot 1's flange, looking along it; robot 2's
#: base 1.2 m from robot 1's, facing it; the marker 80 mm off robot 2's flange.
DEFAULT_X = make_pose(project_to_so3(so3_exp([0.1, -0.2, 1.5])), [40.0, -30.0, 100.0])
DEFAULT_Y = make_pose(so3_exp([0.0, 0.0, np.pi]), [1200.0, 50.0, 20.0])
DEFAULT_Z = make_pose(project_to_so3(so3_exp([np.pi - 0.2, 0.1, 0.3])), [10.0, 20.0, 80.0])


@dataclasses.dataclass(frozen=True)
class AXBYCZData:
    """Validated data of A_i X B_i = Y C_i Z: read-only float64 stacks A, B, C of shape (m, 4, 4)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    @classmethod
    def validated(cls, problem: str, data: Mapping[str, Any], min_pairs: int) -> AXBYCZData:
        """The data object from the raw fields {"A", "B", "C"} (`handeye.estimation.kronecker.validated_stacks`);
        `AXBYCZ.validate` adds the degeneracy checks."""
        return cls(*validated_stacks(problem, data, FIELDS, min_pairs))

    @property
    def m(self) -> int:
        return len(self.A)

    @functools.cached_property
    def translation_scale(self) -> float:
        """RMS norm of all translations of A, B and C: the data's length unit, for normalisation."""
        return translation_rms(self.A, self.B, self.C)

    @functools.cached_property
    def rotation_spread(self) -> dict[str, tuple[int, float]]:
        """Per stack ("A", "B", "C"): how many poses are rotated from the first (by more than
        MIN_MOTION_ANGLE) and the spread of those rotations' axes (rad, in [0, pi/2]): with the
        unit axes n_k of R_0^T R_k and lambda_1 >= lambda_2 the two largest eigenvalues of
        sum n_k n_k^T, 2 atan(sqrt(lambda_2 / lambda_1)), 0 when every rotation is about one axis
        (conjugating by R_0 or inverting does not change it, so it holds for the motions in
        either frame)."""
        from handeye.geometry import so3_fast

        out = {}
        for name in FIELDS:
            R = getattr(self, name)[:, :3, :3]
            phi = so3_fast.log(R[0].T @ R)
            angle = np.linalg.norm(phi, axis=1)
            moving = angle > MIN_MOTION_ANGLE
            spread = 0.0
            if moving.sum() >= 2:
                n = phi[moving] / angle[moving, None]
                lam = np.linalg.eigvalsh(n.T @ n)
                spread = float(2.0 * np.arctan(np.sqrt(max(lam[1], 0.0) / lam[2])))
            out[name] = (int(moving.sum()), spread)
        return out

    def still_groups(self, stack: str) -> list[np.ndarray]:
        """The groups (sorted indices, 2 or more each) of triples between which the robot of
        `stack` ("A": robot 1, "C": robot 2) holds still: poses within STILL_ROTATION and
        STILL_TRANSLATION x `translation_scale` (per axis) of another of the group."""
        return self._still_groups[stack]

    @functools.cached_property
    def _still_groups(self) -> dict[str, list[np.ndarray]]:
        """`still_groups` of A and C in O(m log m): each pose is compared with the first pose of
        its cell in 8 grids of cells 2 tol wide, shifted by 0 or tol along each axis (two poses
        within tol per axis share a cell in one of them), and the close pairs are joined
        (connected components)."""
        m, tol = self.m, STILL_TRANSLATION * self.translation_scale
        trace_min = 1.0 + 2.0 * np.cos(STILL_ROTATION)  # tr(R_i^T R_j) >= this: angle <= STILL_ROTATION
        out = {}
        for name in ("A", "C"):
            T = getattr(self, name)
            t, R = T[:, :3, 3], T[:, :3, :3].reshape(m, 9)
            label = np.arange(m)
            edges = []
            for shift in np.array(np.meshgrid([0, 1], [0, 1], [0, 1])).reshape(3, 8).T:
                cell = np.floor((t + shift * tol) / (2.0 * tol)).astype(np.int64)
                key = cell @ np.array([73856093, 19349663, 83492791], dtype=np.int64)  # a hash: a collision only hides a pair
                _, first, inverse_ = np.unique(key, return_index=True, return_inverse=True)
                rep = first[inverse_.ravel()]  # the first pose of each pose's cell
                close = ((np.abs(t - t[rep]) <= tol).all(axis=1)
                         & (np.einsum("ij,ij->i", R, R[rep]) >= trace_min) & (rep != label))
                edges.append((rep[close], np.flatnonzero(close)))
            i, j = np.concatenate([e[0] for e in edges]), np.concatenate([e[1] for e in edges])
            while len(i):  # connected components: propagate the smallest index along the edges
                low = np.minimum(label[i], label[j])
                if np.array_equal(low, label[i]) and np.array_equal(low, label[j]):
                    break
                np.minimum.at(label, i, low)
                np.minimum.at(label, j, low)
                label = label[label]  # follow the links (pointer jumping)
            counts = np.bincount(label, minlength=m)
            out[name] = [np.flatnonzero(label == g) for g in np.flatnonzero(counts >= 2)]
        return out

    def scaled(self, s: float) -> AXBYCZData:
        """The same data with every translation divided by s."""
        return type(self)(*scaled_stacks((self.A, self.B, self.C), s))
