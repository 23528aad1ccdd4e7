"""The problem axyb: its `Problem` (validation, residuals, checks, simulator) and its registration.

The data and their algebra are in `handeye.problems.axyb.data`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from operator import itemgetter
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation import camera_scale
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import Problem, pose_discrepancy
from handeye.framework.problem_cell import Frame, Published, StationReader
from handeye.framework.problem_studies import BenchSettings, BenchTarget
from handeye.geometry.kinematics import simulate_stations
from handeye.geometry.validation import (
    check_motion_beyond_noise,
    pose_stack,
)
from handeye.problems import opencv_reference
from handeye.problems import planar as planar_mode
from handeye.problems.axyb.data import (
    DEGENERATE_EXCITATION,
    PAPER_X,
    PAPER_Y,
    SETUPS,
    AXYBData,
    pairs_from_stations,
)

#: the direct OpenCV row the speed targets against OpenCV divide by
DIRECT_SHAH = "cv2 direct SHAH"


class AXYB(Problem):
    """A_i X = Y B_i: simultaneous hand-eye (X) and robot-world (Y) calibration."""

    name = "axyb"
    summary = "robot-world and hand-eye calibration, A_i X = Y B_i"
    unknowns = ("X", "Y")
    data_fields = ("A", "B")
    min_pairs = 3
    #: a planar robot's translation along its rotation axis (one of them; `AXYBData.planar`), and
    #: the board's image observations behind B (`AXYBData.images`)
    optional_fields = ("tz_X", "tz_Y", "images", "camera_scale")
    station_reader = StationReader(pairs_from_stations)
    data_type = AXYBData
    default = True
    equation = "A_i X = Y B_i"
    item = "pair"
    setups = SETUPS
    #: so3-sdp certifies its answer; kron-lstsq is the closed form (also the plausibility's fits)
    starts = ("so3-sdp", "kron-lstsq")
    certifiable_starts = ("so3-sdp",)
    quick_solver = "kron-lstsq"
    #: the accuracy study's noise: the camera (B) ten times noisier than the robot (A), rad and mm
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}
    #: ``handeye bench``: OpenCV's SHAH and LI through the ``opencv`` solver (SHAH the reference:
    #: the same path through handeye.solve, so the ratio compares methods, not wrappers) and
    #: cv2.calibrateRobotWorldHandEye called directly on prebuilt lists, A as world2cam and B as
    #: base2gripper (docs/conventions.md): the difference is handeye's wrapper cost
    bench = BenchSettings(
        pairs=(10, 16, 100, 1000, 10000),
        reference="opencv [method=shah]",
        reference_name="OpenCV SHAH",
        solver_rows=(("opencv", (("method", "shah"),)), ("opencv", (("method", "li"),))),
        direct_rows=opencv_reference.direct_rows("calibrateRobotWorldHandEye", "CALIB_ROBOT_WORLD_HAND_EYE_",
                                                 ("SHAH", "LI"), itemgetter("A", "B")),
        targets=(
            BenchTarget("lmi-sdp", 16, seconds=5e-3, backend="cvxpy"),
            BenchTarget("kron-lstsq", 10000, seconds=20e-3),
            BenchTarget("iterative", 100, ratio=5.0),
            BenchTarget("dual-quaternion", 100, ratio=5.0),
            BenchTarget("so3-sdp", 16, seconds=20e-3),
            # refine's own cost: started from the closed form (~1 ms); its default start, so3-sdp,
            # is judged on its own line and inside auto's
            BenchTarget("refine", 16, seconds=5e-3, options=(("init", "kron-lstsq"),)),
            BenchTarget("auto", 16, seconds=30e-3),
            BenchTarget("refine", 10000, seconds=200e-3),
            # auto (validation, the checks and all) against OpenCV as its users call it
            BenchTarget("auto", 16, ratio=13.0, against=DIRECT_SHAH),
            BenchTarget("auto", 100000, ratio=1.0, against=DIRECT_SHAH),
            BenchTarget("auto", 100000, ratio=0.3, options=(("noise", "groups"),), against=DIRECT_SHAH),
        ),
    )

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """Eye-in-hand X = T_flange_cam, Y = T_base_target; eye-to-hand X = T_flange_target,
        Y = T_base_cam (docs/conventions.md)."""
        if setup == "eye-to-hand":
            return {"X": Frame("flange", "target", "target in the flange frame"),
                    "Y": Frame("base", "cam", "camera in the robot base frame")}
        if setup == "eye-in-hand":
            return {"X": Frame("flange", "cam", "camera in the flange frame"),
                    "Y": Frame("base", "target", "target in the robot base frame")}
        return {}

    def published(self, setup: str | None = None) -> Published | None:
        """The camera's pose: X eye-in-hand (parent flange), Y eye-to-hand (parent base), child
        the camera's optical frame (solvePnP's: z forward, x right, y down)."""
        if setup not in SETUPS:
            return None
        return Published("X", "flange", "camera_optical_frame") if setup == "eye-in-hand" else \
            Published("Y", "base", "camera_optical_frame")

    def validate(self, **data: Any) -> AXYBData:
        """The validated data; ``tz_X`` or ``tz_Y`` (data units) for a robot whose rotations share
        one axis (`handeye.problems.planar`: required then, refused otherwise)."""
        images = data.pop("images", None)
        facts = planar_mode.take_facts(data, ("tz_X", "tz_Y"))
        unknown_scale = camera_scale.take(data)
        out = AXYBData.validated(self.name, data, self.min_pairs)
        if images is not None:
            from handeye.vision.observations import checked

            out = dataclasses.replace(out, images=checked(images, out.m))
        planar = planar_mode.for_axyb(out.A, out.translation_scale, facts)
        if planar is not None and unknown_scale:
            raise InputError("camera_scale='unknown' is not supported for a robot that rotates about one axis: "
                             "record poses that rotate about at least two axes, or give the camera's scale")
        if planar is not None:  # rotations about one axis: the translations fix their gauge
            return dataclasses.replace(out, planar=planar)
        if unknown_scale:
            out = dataclasses.replace(out, camera_scale_unknown=True)
        excitation = out.rotation_excitation
        if excitation < DEGENERATE_EXCITATION:
            raise DegenerateDataError(
                f"the robot poses rotate about fewer than two different axes (or not at all), so "
                f"the rotations of X and Y cannot be determined (rotation excitation {excitation:.1e} "
                f"< {DEGENERATE_EXCITATION:g}). Record poses that rotate about at least two different axes"
            )
        check_motion_beyond_noise(*out.station_angles(), "stations")
        return out

    def diagnose(self, data: AXYBData) -> dict[str, Any]:
        return {"pairs": data.m, "rotation_excitation": data.rotation_excitation, "warnings": []}

    def residuals(self, data: AXYBData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per pair: rotation angle of (A_i X)(Y B_i)^-1 (eq. 32), |t(A_i X) - t(Y B_i)| (eq. 33)."""
        return pose_discrepancy(data.A @ np.asarray(unknowns["X"], dtype=float),
                                np.asarray(unknowns["Y"], dtype=float) @ data.B)

    def check_model(self, data: AXYBData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]]:
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.check_model(data, unknowns)

    def expected_rotation_residual(self, data: AXYBData) -> float | None:
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.expected_rotation_residual(data)

    def rotation_axes(self, data: AXYBData) -> dict[str, np.ndarray]:
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.rotation_axes(data)

    def station_information(self, A: np.ndarray, B: np.ndarray, unknowns: Mapping[str, np.ndarray],
                            robot_sigma: tuple[float, float], camera_cov: np.ndarray,
                            setup: str) -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]]:
        from handeye.problems.axyb import planning

        return planning.station_information(A, B, dict(unknowns), robot_sigma, camera_cov), ("X", "Y"), ("X", "Y")

    def configurations(self, data: AXYBData) -> np.ndarray:
        """The robot's flange poses A_i, one per row of `check_model`'s model (its pairs)."""
        return data.A

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None,
                 **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Sec. IV-A: A_i = forward kinematics of an LR Mate 200iD-like arm at random joints (mm),
        B_i = Y^-1 A_i X, then noise (`handeye.estimation.noise.NoiseModel`) on A and/or B.

        images: a mapping (``setup``, ``pixel_noise``) to simulate board images instead
        (`handeye.problems.axyb.images`): data A, B and ``images``, B the PnP poses of the corners.

        X, Y default to the paper's `PAPER_X`, `PAPER_Y`. The random stream is drawn in a fixed
        order (poses, then noise on A, then on B), so a seed gives the same poses at every noise
        level.
        """
        images = options.pop("images", None)
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, images")
        if pairs < 1:
            raise InputError(f"pairs must be >= 1, got {pairs}")
        rng = np.random.default_rng(seed)
        X = PAPER_X if X is None else pose_stack(np.asarray(X)[None], "X")[0]
        Y = PAPER_Y if Y is None else pose_stack(np.asarray(Y)[None], "Y")[0]
        noise = noise or NoiseModel()
        if images is not None:  # stations seen in board images (problems/axyb_images.py)
            from handeye.problems.axyb import images as axyb_images

            return axyb_images.simulate(pairs, rng, noise, X, Y, images), {"X": np.array(X), "Y": np.array(Y)}
        return simulate_stations(pairs, seed=seed, noise=noise, X=X, Y=Y)


PROBLEM = AXYB()


@hookimpl
def register_problems(register):
    register(PROBLEM)


def random_truth(rng: np.random.Generator, translation_scale: float = 500.0) -> dict[str, np.ndarray]:
    """Random X, Y: uniform rotations, translations N(0, scale^2) per axis (data units)."""
    return PROBLEM.random_unknowns(rng, translation_scale)
