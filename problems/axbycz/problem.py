"""The problem axbycz: its `Problem` (validation, residuals, checks, simulator) and its registration.

The data and their algebra are in `handeye.problems.axbycz.data`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import Problem, pose_discrepancy
from handeye.framework.problem_studies import BenchSettings
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import inverse
from handeye.geometry.validation import pose_stack
from handeye.problems.axbycz.data import (
    DEFAULT_X,
    DEFAULT_Y,
    DEFAULT_Z,
    DEGENERATE_AXIS_SPREAD,
    FIELDS,
    PROTOCOLS,
    STACKS,
    AXBYCZData,
)


class AXBYCZ(Problem):
    """A_i X B_i = Y C_i Z: two robots, or hand-eye with tool-flange and robot-robot at once."""

    name = "axbycz"
    summary = "A_i X B_i = Y C_i Z: dual-robot calibration (hand-eye X, robot-robot Y, tool-flange Z)"
    unknowns = ("X", "Y", "Z")
    data_fields = FIELDS
    min_pairs = 3
    data_type = AXBYCZData
    equation = "A_i X B_i = Y C_i Z"
    item = "triple"
    #: no certifiable method: wang first, the one start that takes every data protocol, then
    #: fu-dq (robot 2 still in a phase), the Kronecker least squares, wu; a start that refuses the
    #: data's protocol (InputError) gives way to the next
    starts = ("wang", "fu-dq", "kron-lstsq", "wu")
    start_refusals = (InputError,)
    quick_solver = "kron-lstsq"
    #: the accuracy study's noise: C is robot 2's flange pose, as precise as robot 1's (A)
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5), "C": (0.0002, 0.05)}
    protocols = PROTOCOLS
    #: ``handeye bench``: no OpenCV function solves A X B = Y C Z, so no reference rows; the ratio
    #: column divides by the closed form wu. A solver asking for the phase protocol
    #: (`SolverSpec.simulate_options`) is timed on phase data of the same seed
    bench = BenchSettings(
        pairs=(8, 16, 100, 1000),
        reference="wu/numpy",
        reference_name="wu",
        data_note="two facing arms (PROBLEM.simulate, free motion; solvers that need the phase protocol get "
                  "phase data of the same seed), noise on A, B and C: {rot:g} rad, {trans:g} mm (seed {seed})",
    )

    def pose_model(self, data: AXBYCZData) -> Any:
        """The engine's model of the triples (`handeye.problems.axbycz.geometry.AXBYCZModel`)."""
        from handeye.problems.axbycz.geometry import AXBYCZModel

        return AXBYCZModel(data)

    def validate(self, **data: Any) -> AXBYCZData:
        """The validated data; `DegenerateDataError` when a stack's rotations are about fewer than
        two axes, so that the data cannot separate the two unknowns it ties (module docstring)."""
        out = AXBYCZData.validated(self.name, data, self.min_pairs)
        for name, (what, pair, product, advice) in STACKS.items():
            moving, spread = out.rotation_spread[name]
            if moving >= 2 and spread >= DEGENERATE_AXIS_SPREAD:
                continue
            T = getattr(out, name)
            if np.abs(T - T[0]).max() <= 1e-12 * max(out.translation_scale, 1.0):
                how = f"are the same pose in all {out.m} triples, so {product}"
                what_not = f"the rotations and translations of {pair} separately"
            elif moving == 0:
                how, what_not = "do not rotate (they only translate)", f"the translations of {pair} separately"
            else:
                how = (f"rotate about one axis only ({moving} of {out.m} poses rotated from the first, "
                       f"axis spread {np.rad2deg(spread):.2g} deg)")
                what_not = f"the translations of {pair} along that axis separately"
            raise DegenerateDataError(f"{what} {how}: these triples do not determine {what_not}. "
                                      f"{advice[0].upper()}{advice[1:]}")
        return out

    def diagnose(self, data: AXBYCZData) -> dict[str, Any]:
        """Figures: which unknowns each stack's motions separate, per stack the poses rotated from
        the first and their axis spread (deg), and the triples where robot 1 / robot 2 hold still (the phases; how well the data determine the
        unknowns at their noise is the host's self-check, not a threshold here)."""
        still = {name: [g.tolist() for g in data.still_groups(name)] for name in ("A", "C")}
        return {
            "pairs": data.m,
            "separates": {name: pair for name, (_, pair, _, _) in STACKS.items()},  # what each stack's motions excite
            "rotated_poses": {k: v[0] for k, v in data.rotation_spread.items()},
            "axis_spread_deg": {k: float(np.rad2deg(v[1])) for k, v in data.rotation_spread.items()},
            "robot1_still_triples": still["A"],
            "robot2_still_triples": still["C"],
            "protocol": ("phases" if still["A"] and still["C"] else
                         "robot 2 still in part" if still["C"] else "robot 1 still in part" if still["A"] else "free"),
            "warnings": [],
        }

    def residuals(self, data: AXBYCZData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per triple: rotation angle of (A_i X B_i)(Y C_i Z)^-1, |t(A_i X B_i) - t(Y C_i Z)|."""
        X, Y, Z = (np.asarray(unknowns[n], dtype=float) for n in self.unknowns)
        return pose_discrepancy(data.A @ X @ data.B, Y @ data.C @ Z)

    def check_model(self, data: AXBYCZData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]]:
        from handeye.problems.axbycz import geometry as axbycz_geometry

        return axbycz_geometry.check_model(data, unknowns)

    def expected_rotation_residual(self, data: AXBYCZData) -> float | None:
        from handeye.problems.axbycz import geometry as axbycz_geometry

        return axbycz_geometry.expected_rotation_residual(data)

    def rotation_axes(self, data: AXBYCZData) -> dict[str, np.ndarray]:
        from handeye.problems.axbycz import geometry as axbycz_geometry

        return axbycz_geometry.rotation_axes(data)

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
        X, Y, Z = (default if given is None else pose_stack(np.asarray(given)[None], name)[0]
                   for name, given, default in (("X", X, DEFAULT_X), ("Y", Y, DEFAULT_Y), ("Z", Z, DEFAULT_Z)))
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
