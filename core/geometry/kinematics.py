"""Forward kinematics of serial arms (standard Denavit-Hartenberg), for simulating robot poses.

`LR_MATE_200ID` approximates a FANUC LR Mate 200iD (the robot of the seed paper, Sec. IV):
J1-J2 offset 50 mm, base height 330 mm, upper arm 330 mm, elbow offset 35 mm, forearm 335 mm,
flange 80 mm. The joint box `LR_MATE_SIM_JOINTS` is the range the simulator samples from: a
workspace in front of the robot, wrist away from its singularity, wide enough to excite every
rotation axis.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np

from handeye.geometry.se3 import Array, inverse, make_pose, project_to_so3

#: Ground truth of the paper's simulation (Sec. IV-A), projected onto SO(3): the printed 4-digit
#: rotation blocks are not exactly orthonormal. Translations in mm.
PAPER_X = make_pose(
    project_to_so3([[0.0162, 0.9995, 0.0289], [-0.9996, 0.0168, -0.0207], [-0.0211, -0.0285, 0.9994]]),
    [22.0, -3.0, -60.0],
)
PAPER_Y = make_pose(
    project_to_so3([[-0.9990, -0.0327, 0.0279], [0.0274, 0.0155, 0.9995], [-0.0331, 0.9994, -0.0146]]),
    [165.0, 300.0, -962.0],
)


@dataclasses.dataclass(frozen=True)
class DHArm:
    """Standard DH parameters per joint: a (length), alpha (rad), d (length), theta offset (rad)."""

    a: tuple[float, ...]
    alpha: tuple[float, ...]
    d: tuple[float, ...]
    offset: tuple[float, ...]

    #: the columns of `table`, in the order of the fields
    COLUMNS: ClassVar[tuple[str, ...]] = ("a", "alpha", "d", "offset")

    @property
    def joints(self) -> int:
        return len(self.a)

    @property
    def table(self) -> Array:
        """The DH table, one row per joint, columns `COLUMNS` (a, alpha, d, offset): (joints, 4)."""
        return np.array([self.a, self.alpha, self.d, self.offset], dtype=float).T

    def __array__(self, dtype: Any = None, copy: Any = None) -> Array:
        """``np.array(arm)`` is its `table` (so that an arm passes wherever an array of numbers does)."""
        return self.table if dtype is None else self.table.astype(dtype)

    @classmethod
    def from_table(cls, table: Any) -> DHArm:
        """The arm of a (joints, 4) table with columns `COLUMNS` (a, alpha, d, offset)."""
        T = np.asarray(table, dtype=float)
        return cls(*(tuple(float(v) for v in T[:, k]) for k in range(4)))

    def scaled(self, s: float) -> DHArm:
        """The same arm with its lengths (a, d) divided by s (a change of length unit)."""
        return dataclasses.replace(self, a=tuple(v / s for v in self.a), d=tuple(v / s for v in self.d))

    def links(self) -> Array:
        """The constant part of each joint's transform, C_j = Rz(offset_j) Tz(d_j) Tx(a_j) Rx(alpha_j),
        so that `forward` is the product over the joints of Rz(q_j) C_j: (joints, 4, 4)."""
        th, alpha = np.asarray(self.offset, dtype=float), np.asarray(self.alpha, dtype=float)
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(alpha), np.sin(alpha)
        a = np.asarray(self.a, dtype=float)
        C = np.zeros((self.joints, 4, 4))
        C[:, 0, 0], C[:, 0, 1], C[:, 0, 2], C[:, 0, 3] = ct, -st * ca, st * sa, a * ct
        C[:, 1, 0], C[:, 1, 1], C[:, 1, 2], C[:, 1, 3] = st, ct * ca, -ct * sa, a * st
        C[:, 2, 1], C[:, 2, 2], C[:, 2, 3] = sa, ca, self.d
        C[:, 3, 3] = 1.0
        return C

    def forward(self, q: np.ndarray) -> Array:
        """Flange poses T_base_flange for joint vectors q: (n, joints) rad -> (n, 4, 4)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        for j, (a, alpha, d, off) in enumerate(zip(self.a, self.alpha, self.d, self.offset)):
            th = q[:, j] + off
            ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(alpha), np.sin(alpha)
            L = np.zeros((len(q), 4, 4))
            L[:, 0, 0], L[:, 0, 1], L[:, 0, 2], L[:, 0, 3] = ct, -st * ca, st * sa, a * ct
            L[:, 1, 0], L[:, 1, 1], L[:, 1, 2], L[:, 1, 3] = st, ct * ca, -ct * sa, a * st
            L[:, 2, 1], L[:, 2, 2], L[:, 2, 3] = sa, ca, d
            L[:, 3, 3] = 1.0
            T = T @ L
        return T


_deg = np.pi / 180.0
LR_MATE_200ID = DHArm(
    a=(50.0, 330.0, 35.0, 0.0, 0.0, 0.0),
    alpha=(-np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0),
    d=(330.0, 0.0, 0.0, 335.0, 0.0, 80.0),
    offset=(0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0),
)
#: (low, high) per joint, radians
LR_MATE_SIM_JOINTS = np.array(
    [(-45, 45), (-30, 40), (-30, 30), (-90, 90), (-100, -20), (-90, 90)], dtype=float
) * _deg


def random_flange_poses(n: int, rng: np.random.Generator, arm: DHArm = LR_MATE_200ID,
                        joints: np.ndarray = LR_MATE_SIM_JOINTS) -> Array:
    """n flange poses from joint values drawn uniformly in the box `joints`: (n, 4, 4)."""
    q = rng.uniform(joints[:, 0], joints[:, 1], size=(n, len(joints)))
    return arm.forward(q)


def simulate_stations(stations: int, *, seed: int | None = None, noise: Any = None, X: Array | None = None,
                      Y: Array | None = None) -> tuple[dict[str, Array], dict[str, Array]]:
    """The paper's simulated eye-in-hand cell (Sec. IV-A), `stations` stations: ({"A": T_base_flange,
    "B": T_target_cam}, {"X": T_flange_cam, "Y": T_base_target}), so that A_k X = Y B_k.

    A_k: forward kinematics of the LR Mate 200iD-like arm at random joints (mm); B_k = Y^-1 A_k X;
    then `noise` (a `handeye.estimation.noise.NoiseModel`, or None: none), "A" on the robot poses
    and "B" on the camera's. X, Y default to `PAPER_X`, `PAPER_Y`. The random stream is drawn in a
    fixed order (poses, then noise on A, then on B), so a seed gives the same poses at every noise
    level. Every problem read from a cell's stations simulates from these."""
    rng = np.random.default_rng(seed)
    X = PAPER_X if X is None else np.asarray(X, dtype=float)
    Y = PAPER_Y if Y is None else np.asarray(Y, dtype=float)
    A = random_flange_poses(stations, rng)
    B = inverse(Y) @ A @ X
    if noise is not None:
        pose_rng = np.random.default_rng(rng.integers(2**63))
        A = noise.apply("A", A, pose_rng)
        B = noise.apply("B", B, pose_rng)
    return {"A": A, "B": B}, {"X": np.array(X), "Y": np.array(Y)}
