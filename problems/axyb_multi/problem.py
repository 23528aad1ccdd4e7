"""The problem axyb-multi: its `Problem` (validation, observability, residuals, simulator) and its
registration.

A_i X_{x_i} = Y_{y_i} B_i: a cell with several cameras and several targets solved in one go. The
data and their graph are in `handeye.problems.axyb_multi.data`, the least-squares model in
`geometry`, what the observations determine (the rule, its refusals and warnings) in
`observability`; docs/conventions.md ("Several cameras and targets") says what X, Y and B are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.estimation.robust import OUTLIER_CHI2
from handeye.estimation.whitening import estimate_sigmas
from handeye.framework.problem import ErrorTable, Problem, pose_discrepancy
from handeye.framework.problem_cell import Frame
from handeye.framework.problem_studies import BenchSettings, BenchTarget
from handeye.geometry.se3 import (
    rotation_angle,
)
from handeye.problems.axyb_multi import observability
from handeye.problems.axyb_multi.data import AXYBMultiData, validated
from handeye.problems.axyb_multi.simulation import SETUPS, simulate_cell


class AXYBMulti(Problem):
    """A_i X_{x_i} = Y_{y_i} B_i: several cameras and several targets of one robot cell."""

    name = "axyb-multi"
    summary = "a cell of several cameras and targets, A_i X_{x_i} = Y_{y_i} B_i (stacks of X's and Y's)"
    unknowns = ("X", "Y")
    data_fields = ("A", "B")
    #: x_index and y_index are required (`validate` says so when missing); the host passes only the
    #: data fields and the optional fields given, hence their place here
    optional_fields = ("x_index", "y_index", "x_names", "y_names", "camera_scale")
    #: observations in all: one pair needs three stations; what the graph needs is `validate`'s rule
    min_pairs = 3
    data_type = AXYBMultiData
    equation = "A_i X_{x_i} = Y_{y_i} B_i"
    item = "observation"
    setups = SETUPS
    starts = ("so3-sdp", "kron-lstsq")
    certifiable_starts = ("so3-sdp",)
    quick_solver = "kron-lstsq"
    #: no station reader (a cell's file of stations holds one camera): no setup mistakes to try
    mistakes = ()
    #: the robot (A) ten times less noisy than the cameras (B), rad and mm, as for axyb
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}
    #: pairs are stations: 83 stations of the default cell (8 cameras, 16 markers, 3-6 seen per
    #: camera) make ~3000 observations of 24 unknowns, where auto should take at most 2 s
    bench = BenchSettings(pairs=(5, 20, 83), targets=(BenchTarget("auto", 83, seconds=2.0),),
                          data_note="the simulated cell of axyb-multi (8 fixed cameras, 16 flange markers), seed "
                                    "{seed}, noise {rot} rad / {trans} mm on the camera poses B")

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """Eye-to-hand (fixed cameras watching markers on the flange): X_j = T_flange_marker,
        Y_k = T_base_cam; eye-in-hand (cameras on the wrist watching boards in the cell):
        X_j = T_flange_cam, Y_k = T_base_target (docs/conventions.md)."""
        if setup == "eye-to-hand":
            return {"X": Frame("flange", "marker", "the markers on the flange, one pose per marker"),
                    "Y": Frame("base", "cam", "the fixed cameras in the robot base frame, one pose per camera")}
        if setup == "eye-in-hand":
            return {"X": Frame("flange", "cam", "the cameras on the wrist, one pose per camera"),
                    "Y": Frame("base", "target", "the boards in the robot base frame, one pose per board")}
        return {}

    def stack_sizes(self, data: AXYBMultiData) -> Mapping[str, int]:
        return {"X": data.nX, "Y": data.nY}

    def from_observations(self, observations: Any, setup: str) -> Any:
        """A cell's table of observations as these data (`cell_files.from_observations`)."""
        from handeye.problems.axyb_multi import cell_files

        return cell_files.from_observations(observations, setup)

    def validate(self, **data: Any) -> AXYBMultiData:
        """The validated data (`data.validated`: the stacks, the indices, the names), refused when
        a component of the observation graph cannot determine its X's and Y's
        (`observability.check_determined`: one station, rotations about one axis, motions within
        the noise), naming them and what to record."""
        out = validated(self.name, data, self.min_pairs)
        observability.check_determined(out)
        return out

    def diagnose(self, data: AXYBMultiData) -> dict[str, Any]:
        """Observations, stations, per component and per unknown the figures of `observability`,
        and its warnings (separate components solved separately, weakly determined ones,
        unknowns resting on one observation)."""
        components, unknowns = data.observability
        return {"pairs": data.m, "observations": data.m, "stations": data.station_count,
                "components": components, "unknowns": unknowns,
                "warnings": observability.warnings(data, components, unknowns)}

    def residuals(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per observation: rotation angle of (A_i X_j)(Y_k B_i)^-1 and |t(A_i X_j) - t(Y_k B_i)|."""
        X, Y = _stacks(unknowns)
        return pose_discrepancy(data.A @ X[data.x_index], Y[data.y_index] @ data.B)

    def residual_table(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """Per observed (X, Y) pair (`AXYBMultiData.pair_index`): the names, the observations, the
        RMS and largest rotation (deg) and translation residuals, and the observation of the largest."""
        res = self.residuals(data, unknowns)
        rot, trans = np.degrees(res["rotation"]), res["translation"]
        pairs, of = data.pair_index
        rows = []
        for p, (j, k) in enumerate(pairs.tolist()):
            obs = np.flatnonzero(of == p)
            worst = obs[np.argmax(rot[obs] / max(float(np.median(rot)), 1e-300)
                                  + trans[obs] / max(float(np.median(trans)), 1e-300))]
            rows.append({"X": data.x_names[j], "Y": data.y_names[k], "x": j, "y": k, "observations": int(len(obs)),
                         "rotation_rms_deg": float(np.sqrt(np.mean(rot[obs] ** 2))),
                         "translation_rms": float(np.sqrt(np.mean(trans[obs] ** 2))),
                         "rotation_max_deg": float(rot[obs].max()), "translation_max": float(trans[obs].max()),
                         "worst": int(worst)})
        return rows

    def outliers(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """The observations far off the others at these unknowns (whitened by median-based scales
        beyond OUTLIER_CHI2, as the host's self-check and auto find them), each named by its index,
        station and (X, Y) pair, with its residuals (deg, data units); worst first."""
        e = data.pose_model.residuals(_stacks_flat(unknowns))
        ew = estimate_sigmas(e, data.translation_scale, robust=True).residual(e)
        s = np.einsum("ni,ni->n", ew, ew)
        far = np.flatnonzero(s > OUTLIER_CHI2)
        station = data.station_index
        return [{"index": int(i), "station": int(station[i]), "X": data.x_names[data.x_index[i]],
                 "Y": data.y_names[data.y_index[i]], "rotation_deg": float(np.degrees(np.linalg.norm(e[i, :3]))),
                 "translation": float(np.linalg.norm(e[i, 3:])), "whitened": float(math.sqrt(s[i]))}
                for i in far[np.argsort(-s[far])]]

    def errors(self, unknowns: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray]) -> ErrorTable:
        """Per unknown the worst of its poses' errors (`handeye.framework.problem.pose_errors`); pose by pose
        in `errors_per_pose`."""
        return super().errors(unknowns, truth)

    def check_model(self, data: AXYBMultiData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]]:
        from handeye.problems.axyb_multi import geometry

        return geometry.check_model(data, unknowns)

    def expected_rotation_residual(self, data: AXYBMultiData) -> float | None:
        from handeye.problems.axyb_multi import geometry

        return geometry.expected_rotation_residual(data)

    def rotation_axes(self, data: AXYBMultiData) -> dict[str, np.ndarray]:
        from handeye.problems.axyb_multi import geometry

        return geometry.rotation_axes(data)

    def configurations(self, data: AXYBMultiData) -> np.ndarray:
        """The robot's flange pose at each observation (a station's repeated for each of its
        observations, which the self-check's test of systematic robot errors counts once)."""
        return data.A

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None, setup: str = "eye-to-hand",
                 cameras: int | None = None, markers: int | None = None, visible: tuple[int, int] | None = None,
                 gross: float = 0.0, camera_scales: Mapping[str, float] | None = None,
                 camera_noise: Mapping[str, float] | None = None,
                 **options: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """A simulated cell (`simulate_cell`): `pairs` stations of the robot, each camera seeing
        some of the targets at each; data A, B, x_index, y_index, x_names, y_names (and
        camera_scale with `camera_scales`), truth {"X": (nX, 4, 4), "Y": (nY, 4, 4)} (and
        "camera_scales")."""
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, setup, "
                             "cameras, markers, visible, gross, camera_scales, camera_noise")
        cell = simulate_cell(pairs, seed=seed, noise=noise, X=X, Y=Y, setup=setup, cameras=cameras, markers=markers,
                             visible=visible, gross=gross, camera_scales=camera_scales, camera_noise=camera_noise)
        return cell.data, cell.truth


def _stacks(unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    return (np.asarray(unknowns["X"], dtype=float).reshape(-1, 4, 4),
            np.asarray(unknowns["Y"], dtype=float).reshape(-1, 4, 4))


def _stacks_flat(unknowns: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    X, Y = _stacks(unknowns)
    return tuple(X) + tuple(Y)


def errors_per_pose(unknowns: Mapping[str, np.ndarray], truth: Mapping[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Each pose's errors against the truth, keyed X[0], ..., Y[nY-1]: rotation angle of
    R_cal R_true^T (rad) and translation distance (data units)."""
    out = {}
    for name in ("X", "Y"):
        cal = np.asarray(unknowns[name], dtype=float).reshape(-1, 4, 4)
        true = np.asarray(truth[name], dtype=float).reshape(-1, 4, 4)
        if cal.shape != true.shape:
            raise ValueError(f"unknown {name} has shape {cal.shape}, its truth {true.shape}")
        rot = rotation_angle(cal[:, :3, :3] @ np.swapaxes(true[:, :3, :3], 1, 2))
        trans = np.linalg.norm(cal[:, :3, 3] - true[:, :3, 3], axis=1)
        out.update({f"{name}[{j}]": {"rotation": float(rot[j]), "translation": float(trans[j])} for j in range(len(cal))})
    return out


PROBLEM = AXYBMulti()


@hookimpl
def register_problems(register):
    register(PROBLEM)
