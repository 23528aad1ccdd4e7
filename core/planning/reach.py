"""Whether the arm reaches a planned flange pose within its joint limits, and with which joints
(`Reach`): numerical inverse kinematics of the arm's model (a DH table with its base and tool,
`handeye.io.arm_files.ArmModel`, or any object with ``forward(q)`` and ``joints``).

For a pose T, the joints q within [low, high] that minimise the pose error
r(q) = (log(R(q)^T R_T), (t(q) - t_T) / L) (L: the arm's reach, so that both parts weigh alike)
are found by Levenberg-Marquardt with the steps clipped to the limits, from SEEDS starts at once:
the joints of the nearest station already solved (neighbouring poses have neighbouring joints)
and random joints in the limits; poses farther from the base than the flange ever gets (sampled
over the limits) are not tried. T is reached when the error is below ROTATION_TOL and
TRANSLATION_TOL of the reach. Among several solutions (elbow up or down, wrist flipped) the one
found first from the nearest start is kept, so consecutive stations tend to stay in one branch.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry import so3_fast

#: starts per pose: the nearest solved station's joints, then random joints in the limits (measured on the
#: LR Mate-like arm: 99 of 100 random reachable poses found, 3.5 ms each)
SEEDS = 12
#: the flange positions of this many random joint vectors in the limits bound where it can be
#: (their farthest from the base's origin, plus REACH_MARGIN of it): poses beyond are not tried
REACH_SAMPLES = 4000
REACH_MARGIN = 0.05
#: Levenberg-Marquardt iterations per pose, and the forward-difference step (rad)
MAX_ITERATIONS = 200
STEP = 1e-7
#: the damping beyond which a start has stalled
STALLED = 1e8
#: ... and the iterations over which some start must halve its cost, else every start has settled
#: on a pose it cannot improve (out of reach within the limits). Measured on the LR Mate-like arm:
#: reached poses converge in 5-14 iterations; unreached ones used all MAX_ITERATIONS before (the
#: damping rises and falls without stalling), 95% of a planning run's time. With 25: the same
#: plan 3.1x faster, 296 of 300 random reachable poses found as before (10: 295)
PROGRESS_WINDOW = 25
#: a pose is reached when the inverse kinematics leave less than this (rad; share of the reach)
ROTATION_TOL = 1e-8
TRANSLATION_TOL = 1e-8


@dataclasses.dataclass
class Reach:
    """An arm and its joint limits low, high (rad, one per joint); `solved` holds the joints of
    every pose reached so far (`joints_for`), by candidate index."""

    arm: Any
    low: np.ndarray
    high: np.ndarray
    seed: int = 0
    solved: dict[int, np.ndarray] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        self.low, self.high = np.asarray(self.low, dtype=float), np.asarray(self.high, dtype=float)
        n = int(self.arm.joints)
        if self.low.shape != (n,) or self.high.shape != (n,) or not np.all(self.low < self.high):
            raise InputError(f"the joint limits need a low < high pair for each of the arm's {n} joints")
        self._rng = np.random.default_rng(self.seed)
        sample = self.arm.forward(self._rng.uniform(self.low, self.high, (REACH_SAMPLES, n)))[:, :3, 3]
        self._farthest = float(np.linalg.norm(sample, axis=1).max()) * (1.0 + REACH_MARGIN)
        self._length = max(self._farthest, 1e-12)

    def joints_for(self, T: np.ndarray, key: int | None = None) -> np.ndarray | None:
        """Joints (n,) within the limits that put the flange at T, or None when none were found;
        remembered under `key`."""
        T = np.asarray(T, dtype=float)
        if np.linalg.norm(T[:3, 3]) > self._farthest:  # beyond where the flange can be
            return None
        q = self._solve(np.array(self._starts(T)), T)
        if q is not None and key is not None:
            self.solved[key] = q
        return q

    def _error(self, q: np.ndarray, T: np.ndarray) -> np.ndarray:
        """(k, 6) the pose error r(q) of joint vectors q (k, n) against T (module docstring)."""
        F = self.arm.forward(q)
        rotation = so3_fast.log(np.swapaxes(F[:, :3, :3], 1, 2) @ T[:3, :3])
        return np.concatenate([rotation, (F[:, :3, 3] - T[:3, 3]) / self._length], axis=1)

    def _solve(self, q: np.ndarray, T: np.ndarray) -> np.ndarray | None:
        """Levenberg-Marquardt on every start q (k, n) at once, each step clipped to the limits
        (a projected method: at a limit the step slides along it), the Jacobian by forward
        differences (one forward-kinematics call for all starts and joints); the first start to
        meet the tolerances, or None after MAX_ITERATIONS or once no start halves its cost over
        PROGRESS_WINDOW iterations."""
        k, n = q.shape
        damping = np.full(k, 1e-3)
        r = self._error(q, T)
        cost = np.sum(r * r, axis=1)
        eye = np.eye(n)
        window_start = cost.copy()
        for iteration in range(1, MAX_ITERATIONS + 1):
            done = (np.linalg.norm(r[:, :3], axis=1) < ROTATION_TOL) & (np.linalg.norm(r[:, 3:], axis=1) < TRANSLATION_TOL)
            if done.any():
                return q[int(np.argmax(done))]
            shifted = (q[:, None, :] + STEP * eye[None]).reshape(-1, n)
            J = (self._error(shifted, T).reshape(k, n, 6) - r[:, None, :]).transpose(0, 2, 1) / STEP
            JtJ = np.swapaxes(J, 1, 2) @ J
            A = JtJ + damping[:, None, None] * (np.diagonal(JtJ, axis1=1, axis2=2)[:, :, None] * eye + 1e-12 * eye)
            dq = -np.linalg.solve(A, np.einsum("kai,ka->ki", J, r)[..., None])[..., 0]
            trial = np.clip(q + dq, self.low, self.high)
            r_trial = self._error(trial, T)
            cost_trial = np.sum(r_trial * r_trial, axis=1)
            better = cost_trial < cost
            q = np.where(better[:, None], trial, q)
            r = np.where(better[:, None], r_trial, r)
            cost = np.where(better, cost_trial, cost)
            damping = np.where(better, damping / 3.0, damping * 4.0)
            if np.all(damping > STALLED):  # no start improves any more: a local minimum, or the limits
                break
            if iteration % PROGRESS_WINDOW == 0:
                if not np.any(cost < 0.5 * window_start):  # every start settled short of the pose
                    break
                window_start = cost.copy()
        return None

    def _starts(self, T: np.ndarray) -> list[np.ndarray]:
        """The joints of the nearest pose solved so far, then random joints in the limits."""
        starts = []
        if self.solved:
            keys = list(self.solved)
            poses = self.arm.forward(np.array([self.solved[k] for k in keys]))
            nearest = int(np.argmin(np.linalg.norm(poses[:, :3, 3] - T[:3, 3], axis=1)))
            starts.append(np.clip(self.solved[keys[nearest]], self.low, self.high))
        while len(starts) < SEEDS:
            starts.append(self._rng.uniform(self.low, self.high))
        return starts
