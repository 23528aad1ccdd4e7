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
Y C_i Z (`handeye.problem.pose_discrepancy`), as eqs. 32-33 are for A X = Y B.

The simulator (`AXBYCZ.simulate`) puts two arms of the paper's kind (`handeye.kinematics`)
facing each other, noise (`handeye.noise.NoiseModel`) on A, B and C, and either free motion
(both arms move at every triple) or the phase protocol of the two-step methods (the first half
of the triples with robot 2 holding still, the second half with robot 1 holding still).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
from handeye import hookimpl
from handeye.errors import InputError
from handeye.kinematics import random_flange_poses
from handeye.kronecker import MIN_TRANSLATION, overflow_error, underflow_error
from handeye.noise import NoiseModel
from handeye.problem import Problem, pose_discrepancy
from handeye.se3 import inverse, make_pose, project_to_so3, so3_exp

FIELDS = ("A", "B", "C")
PROTOCOLS = ("free", "phases")

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
        """The data object from the raw fields {"A", "B", "C"}: no other key and all present, every
        pose checked (`handeye.validation.pose_stacks`: shapes, SE(3), the same length >=
        min_pairs), sums of squared translations that neither overflow nor underflow."""
        from handeye.validation import pose_stacks

        unexpected = set(data) - set(FIELDS)
        if unexpected:
            raise InputError(f"problem {problem!r} takes data {list(FIELDS)}, not {sorted(unexpected)}")
        missing = [f for f in FIELDS if f not in data]
        if missing:
            raise InputError(f"problem {problem!r} needs data {list(FIELDS)}; missing {missing}")
        out = cls(*pose_stacks({f: data[f] for f in FIELDS}, min_pairs).values())
        with np.errstate(over="ignore", invalid="ignore"):
            if not np.isfinite(out.translation_scale):
                raise overflow_error("the sums of squared translations")
        largest = max(float(np.max(np.abs(T[:, :3, 3]))) for T in (out.A, out.B, out.C))
        if 0.0 < largest < MIN_TRANSLATION:
            raise underflow_error(largest)
        return out

    @property
    def m(self) -> int:
        return len(self.A)

    @functools.cached_property
    def translation_scale(self) -> float:
        """RMS norm of all translations of A, B and C: the data's length unit, for normalisation."""
        t = np.concatenate([self.A[:, :3, 3], self.B[:, :3, 3], self.C[:, :3, 3]])
        scale = float(np.sqrt(np.mean(np.sum(t * t, axis=1))))
        return scale if scale > 0 else 1.0

    def scaled(self, s: float) -> AXBYCZData:
        """The same data with every translation divided by s."""
        stacks = []
        for T in (self.A, self.B, self.C):
            T = T.copy()
            T[:, :3, 3] /= s
            T.setflags(write=False)
            stacks.append(T)
        return type(self)(*stacks)


class AXBYCZ(Problem):
    """A_i X B_i = Y C_i Z: two robots, or hand-eye with tool-flange and robot-robot at once."""

    name = "axbycz"
    summary = "A_i X B_i = Y C_i Z: dual-robot calibration (hand-eye X, robot-robot Y, tool-flange Z)"
    unknowns = ("X", "Y", "Z")
    data_fields = FIELDS
    min_pairs = 3

    def validate(self, **data: Any) -> AXBYCZData:
        return AXBYCZData.validated(self.name, data, self.min_pairs)

    def residuals(self, data: AXBYCZData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per triple: rotation angle of (A_i X B_i)(Y C_i Z)^-1, |t(A_i X B_i) - t(Y C_i Z)|."""
        X, Y, Z = (np.asarray(unknowns[n], dtype=float) for n in self.unknowns)
        return pose_discrepancy(data.A @ X @ data.B, Y @ data.C @ Z)

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None, Z: np.ndarray | None = None,
                 protocol: str = "free", **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """`pairs` triples of two facing arms: A_i, C_i flange poses at random joints (mm),
        B_i = X^-1 A_i^-1 Y C_i Z, then noise on A, B, C (`NoiseModel`, drawn in that order).

        protocol "free": both arms move at every triple; "phases": the first ceil(pairs / 2)
        triples keep robot 2 at one pose (C constant) while robot 1 moves, the others keep robot 1
        at one pose (A constant) while robot 2 moves (what the two-step methods need).
        """
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, Z, protocol")
        if pairs < 1:
            raise InputError(f"pairs must be >= 1, got {pairs}")
        if protocol not in PROTOCOLS:
            raise InputError(f"protocol={protocol!r} is not one of {', '.join(PROTOCOLS)}")
        rng = np.random.default_rng(seed)
        X, Y, Z = (default if given is None else np.asarray(given, dtype=float)
                   for given, default in ((X, DEFAULT_X), (Y, DEFAULT_Y), (Z, DEFAULT_Z)))
        A = random_flange_poses(pairs, rng)
        C = random_flange_poses(pairs, rng)
        if protocol == "phases":
            half = (pairs + 1) // 2
            C[:half] = C[0]
            A[half:] = A[0]
        B = inverse(X) @ inverse(A) @ Y @ C @ Z
        noise = noise or NoiseModel()
        noise_rng = np.random.default_rng(rng.integers(2**63))
        noisy = {name: noise.apply(name, T, noise_rng) for name, T in (("A", A), ("B", B), ("C", C))}
        return noisy, {"X": X.copy(), "Y": Y.copy(), "Z": Z.copy()}


PROBLEM = AXBYCZ()


@hookimpl
def register_problems(register):
    register(PROBLEM)
