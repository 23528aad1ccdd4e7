"""The problem axxb: its `Problem` (validation, residuals, checks, simulator) and its registration.

The data and their algebra are in `handeye.problems.axxb.data`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from operator import itemgetter
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import DegenerateDataError, InputError
from handeye.base.vocabulary import SETUPS
from handeye.estimation import camera_scale
from handeye.estimation.noise import NoiseModel
from handeye.estimation.robust import MAD_TO_SIGMA
from handeye.framework.problem import Problem, pose_discrepancy
from handeye.framework.problem_cell import Frame, Published, StationReader
from handeye.framework.problem_studies import BenchSettings
from handeye.geometry.motions import PAIRINGS
from handeye.geometry.se3 import inverse
from handeye.geometry.validation import (
    check_motion_beyond_noise,
)
from handeye.problems import opencv_reference
from handeye.problems import planar as planar_mode
from handeye.problems.axxb.data import (
    DEGENERATE_AXIS_SPREAD,
    MIN_MOTION_ANGLE,
    MISMATCH_ANGLE_FLOOR,
    MISMATCH_SIGMAS,
    WEAK_ROTATION,
    AXXBData,
    motions,
    relative_motions,
)


def bench_stations(*, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                   **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``handeye bench``'s data at m = `pairs`: the fewest stations n with n (n - 1) / 2 >= m
    (`simulate_stations`, noise "A" on the robot poses, "B" on the camera poses); the solvers get
    the motions of every pair i < j, cv2.calibrateHandEye the n stations, which forms the same
    pairs itself: ({"A", "B"} motions, {"robot": T_base_flange, "camera": T_cam_target}, each
    (n, 4, 4))."""
    n = int(np.ceil((1 + np.sqrt(1 + 8 * pairs)) / 2))
    stations, _ = simulate_stations(n, seed=seed, noise=noise, **options)
    A, B = relative_motions(stations["A"], stations["B"], "all")
    return {"A": A, "B": B}, {"robot": stations["A"], "camera": inverse(stations["B"])}


class AXXB(Problem):
    """A_i X = X B_i: hand-eye calibration from relative motions."""

    name = "axxb"
    summary = "hand-eye calibration from relative motions, A_i X = X B_i"
    unknowns = ("X",)
    data_fields = ("A", "B")
    min_pairs = 2
    #: X is the camera's pose: AX=YB's X eye-in-hand (T_flange_cam), its Y eye-to-hand (T_base_cam)
    station_reader = StationReader(motions, pairing=True,
                                   cell_truth={"eye-in-hand": {"X": "X"}, "eye-to-hand": {"X": "Y"}})

    #: a planar robot's translation of X along its rotation axis (`AXXBData.planar`)
    optional_fields = ("tz_X", "camera_scale")
    data_type = AXXBData
    equation = "A_i X = X B_i"
    item = "motion"
    setups = SETUPS
    #: so3-sdp certifies its answer; kron-lstsq and park are closed forms
    starts = ("so3-sdp", "kron-lstsq", "park")
    certifiable_starts = ("so3-sdp",)
    quick_solver = "kron-lstsq"
    #: the accuracy study's noise on the absolute poses the motions are made of: "A" the robot's,
    #: "B" the camera's (ten times the robot's), rad and mm
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}
    #: ``handeye bench``: the ``opencv`` solver with each of OpenCV's five methods, and
    #: cv2.calibrateHandEye called directly on the stations' prebuilt lists (gripper2base = the
    #: robot poses, target2cam = the camera poses: `bench_stations`), each method beside
    #: handeye's solver of that name; the ratio column divides by OpenCV's default, TSAI
    bench = BenchSettings(
        pairs=(16, 100, 1000),
        reference="cv2 direct TSAI",
        reference_name="cv2 TSAI",
        solver_rows=tuple(("opencv", (("method", method),)) for method in ("tsai", "park", "horaud", "andreff",
                                                                          "daniilidis")),
        direct_rows=opencv_reference.direct_rows("calibrateHandEye", "CALIB_HAND_EYE_",
                                                 ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"),
                                                 itemgetter("robot", "camera")),
        simulate=bench_stations,
        data_note="simulate_stations(seed={seed}), noise on the robot and camera poses: {rot:g} rad, {trans:g} mm; "
                  "solvers: the motions of all pairs of the fewest stations giving at least m; cv2 direct: those "
                  "stations (it forms the same pairs)",
    )

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """X is the camera's pose: T_flange_cam eye-in-hand, T_base_cam eye-to-hand."""
        if setup == "eye-to-hand":
            return {"X": Frame("base", "cam", "camera in the robot base frame")}
        if setup == "eye-in-hand":
            return {"X": Frame("flange", "cam", "camera in the flange frame")}
        return {}

    def published(self, setup: str | None = None) -> Published | None:
        """X, the camera's pose, child the camera's optical frame (parent flange eye-in-hand,
        base eye-to-hand)."""
        if setup not in self.setups:
            return None
        return Published("X", "flange" if setup == "eye-in-hand" else "base", "camera_optical_frame")

    def validate(self, **data: Any) -> AXXBData:
        """The validated motions; ``tz_X`` (data units) for motions that all rotate about one axis
        (`handeye.problems.planar`: required then, refused otherwise); ``camera_scale="unknown"``
        for camera translations known only up to scale (`handeye.estimation.camera_scale`)."""
        facts = planar_mode.take_facts(data, ("tz_X",))
        unknown_scale = camera_scale.take(data)
        out = AXXBData.validated(self.name, data, self.min_pairs)
        planar = planar_mode.for_axxb(out.A, out.rotation_vectors[0], out.translation_scale, facts)
        if planar is not None and unknown_scale:
            raise InputError("camera_scale='unknown' is not supported for motions that rotate about one axis: "
                             "record motions that rotate about at least two axes, or give the camera's scale")
        if planar is not None:
            return dataclasses.replace(out, planar=planar)
        if unknown_scale:
            out = dataclasses.replace(out, camera_scale_unknown=True)
        moving = int(np.sum(out.angles[0] > MIN_MOTION_ANGLE))
        if moving < 2 or out.axis_spread < DEGENERATE_AXIS_SPREAD:
            raise DegenerateDataError(
                f"the robot motions do not determine X: {moving} of {out.m} motions rotate, and "
                f"their rotation axes are {'parallel' if moving >= 2 else 'undefined'} (spread "
                f"{np.rad2deg(out.axis_spread):.2g} deg). Record motions that rotate about at "
                "least two different axes"
            )
        check_motion_beyond_noise(*out.angles, "motions")
        return out

    def diagnose(self, data: AXXBData) -> dict[str, Any]:
        """Spread of the rotations and axes (figures; how well they determine X at the data's noise
        is the host's self-check), and the motions whose rotation angles differ between A and B
        (invariant under A = X B X^-1, so a difference is noise or a mismatched pair)."""
        angle_A, angle_B = data.angles
        spread, largest = data.axis_spread, float(angle_A.max())
        warnings = []
        angle_gap = np.abs(angle_A - angle_B)
        pitch = _pitch(data)
        pitch_gap = np.abs(pitch[:data.m] - pitch[data.m:])
        pitch_gap[(angle_A < WEAK_ROTATION) | (angle_B < WEAK_ROTATION)] = 0.0  # axis too uncertain
        mismatched = _outlying(angle_gap, MISMATCH_ANGLE_FLOOR)
        if mismatched:
            listing = ", ".join(
                f"{i} (angle {np.rad2deg(angle_A[i]):.3g} vs {np.rad2deg(angle_B[i]):.3g} deg)" for i in mismatched[:5]
            ) + (" ..." if len(mismatched) > 5 else "")
            warnings.append(
                f"{len(mismatched)} motion(s) rotate by a different angle for the robot (A) than "
                f"for the camera (B), which a true pair cannot: {listing}. Check that the robot "
                "and camera poses are paired in the same order"
            )
        return {
            "pairs": data.m,
            "axis_spread": spread,
            "largest_rotation": largest,
            "angle_difference_max": float(angle_gap.max()),
            "pitch_difference_max": float(pitch_gap.max()),
            "likely_mismatched": mismatched,
            "warnings": warnings,
        }

    def residuals(self, data: AXXBData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per motion: rotation angle of (A_i X)(X B_i)^-1, |t(A_i X) - t(X B_i)|."""
        X = np.asarray(unknowns["X"], dtype=float)
        return pose_discrepancy(data.A @ X, X @ data.B)

    def check_model(self, data: AXXBData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]]:
        from handeye.problems.axxb import geometry as axxb_geometry

        return axxb_geometry.check_model(data, unknowns)

    def expected_rotation_residual(self, data: AXXBData) -> float | None:
        from handeye.problems.axxb import geometry as axxb_geometry

        return axxb_geometry.expected_rotation_residual(data)

    def rotation_axes(self, data: AXXBData) -> dict[str, np.ndarray]:
        from handeye.problems.axxb import geometry as axxb_geometry

        return axxb_geometry.rotation_axes(data)

    def station_information(self, A: np.ndarray, B: np.ndarray, unknowns: Mapping[str, np.ndarray],
                            robot_sigma: tuple[float, float], camera_cov: np.ndarray,
                            setup: str) -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]]:
        """The stations of A X = X B are those of A X = Y B (any pairing of them into motions
        carries no more: the motions are functions of them), the same information, with X the
        camera's pose: eye in hand A X = Y B's X (T_flange_cam; its Y, the board's pose, a
        nuisance), eye to hand its Y (T_base_cam; its X, the board on the flange, a nuisance)."""
        from handeye.problems.axyb import planning

        names = ("X", "target") if setup == "eye-in-hand" else ("target", "X")
        return planning.station_information(A, B, dict(unknowns), robot_sigma, camera_cov), names, ("X",)

    def configurations(self, data: AXXBData) -> np.ndarray | None:
        """The stations' robot poses when `check_model`'s model is on the stations (the motions
        are every pair of them); None for independent motions (rows that are not stations)."""
        stations = data.stations
        return None if stations is None else stations[0]

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None, pairing: str = "all",
                 **options: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """The motions of an eye-in-hand cell that records `pairs` robot/camera pose pairs
        (stations, as ``axyb``'s `pairs`), with the noise on those absolute poses.

        Absolute poses as the ``axyb`` simulator makes them (`simulate_stations`, the same seed
        gives the same stations): robot poses A_k of the paper's arm at random joints (mm),
        B_k = Y^-1 A_k X, noise (`NoiseModel`: "A" on the robot poses, "B" on the camera poses)
        applied to them, then differenced (`relative_motions`), so motions that share a station
        share its noise: pairs (pairs - 1) / 2 motions with pairing "all" (default), pairs - 1
        with "consecutive". X, Y default to the paper's (Sec. IV-A).
        """
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, pairing")
        if pairs < 2:
            raise InputError(f"pairs must be >= 2 (stations; motions are made between them), got {pairs}")
        if pairing not in PAIRINGS:
            raise InputError(f"pairing={pairing!r} is not one of {', '.join(PAIRINGS)}")
        stations, truth = simulate_stations(pairs, seed=seed, noise=noise, X=X, Y=Y)
        A, B = relative_motions(stations["A"], stations["B"], pairing)
        return {"A": A, "B": B}, {"X": truth["X"]}


def simulate_stations(stations: int, *, seed: int | None = None, noise: NoiseModel | None = None,
                      X: np.ndarray | None = None, Y: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Noisy absolute poses {"A": robot, "B": camera} of `stations` stations and the truth {"X",
    "Y"}: exactly the ``axyb`` simulator's data, so AX=YB and AX=XB can be compared on the same
    recordings (A_k X = Y B_k)."""
    from handeye.geometry import kinematics

    if stations < 1:
        raise InputError(f"stations must be >= 1, got {stations}")
    return kinematics.simulate_stations(stations, seed=seed, noise=noise, X=X, Y=Y)


def _pitch(data: AXXBData) -> np.ndarray:
    """Translation along the rotation axis, n . t, of each motion of A then B: (2m,) (0 where it
    barely rotates)."""
    rotvec, angle = data._logs
    t = np.concatenate([data.A[:, :3, 3], data.B[:, :3, 3]])
    pitch = (rotvec * t).sum(axis=1) / np.maximum(angle, MIN_MOTION_ANGLE)
    pitch[angle <= MIN_MOTION_ANGLE] = 0.0
    return pitch


#: the six (row, column) pairs, as flat indices of a 3x3 block, of R^T R's distinct entries, and I's
_GRAM_I, _GRAM_J = np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2])
_GRAM_EYE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])


def _outlying(gap: np.ndarray, floor: float) -> list[int]:
    """Indices whose gap exceeds both `floor` and MISMATCH_SIGMAS robust sigmas (MAD about 0)."""
    g = np.sort(gap)  # its median, as np.median computes it, with 1 numpy call instead of ~12
    sigma = MAD_TO_SIGMA * float((g[(len(g) - 1) // 2] + g[len(g) // 2]) / 2)
    return np.flatnonzero(gap > max(floor, MISMATCH_SIGMAS * sigma)).tolist()


PROBLEM = AXXB()


@hookimpl
def register_problems(register):
    register(PROBLEM)
