"""A third-party *problem* for handeye: ``registration``, A_i X_b(i) = B_i.

A camera rides on the flange (eye-in-hand) and sees a board whose frame is the robot's base frame
(a board surveyed into the base). Each station gives the flange pose A_i = T_base_flange from the
robot and the camera's pose B_i = T_base_cam = inv(T_cam_target) from solvePnP, so A_i X = B_i
with X = T_flange_cam: hand-eye calibration when the board's pose is known. With several cameras
on the flange, each station labelled with the camera that saw it (``body``, 0 .. k-1), the
unknown X is a *stack* of k poses, X_b = T_flange_cam_b: handeye checks each like a single pose.

This module is all there is to it. It registers, through one entry point (pyproject.toml):

- the problem `Registration`: its data (`RegistrationData`), validation, residuals, simulator,
  the frames of its unknown, how a cell's stations become its data (`station_reader`), and the
  least-squares model of the shared engine (`RegistrationModel`);
- the solver ``registration-mean``, the closed form: per body, the chordal mean of A_i^-1 B_i.

handeye's shared tools serve it through the `handeye.Problem` contract, with no change to
handeye: ``refine`` and ``auto`` register for every problem that gives a pose model (started
from ``starts``), the host's self-check fits the model, ``handeye compare`` and ``handeye bench``
use the simulator, and ``handeye calibrate`` reads a cell's stations through the station reader.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np

import handeye
from handeye import Frame, PoseModel, StationReader, pose_discrepancy
from handeye.geometry import inverse, make_pose, pose_stack, random_flange_poses, so3_fast

NAME = "registration"
SOLVER = "registration-mean"
#: the default camera pose on the flange, mm (a camera 80 mm off the flange axis, looking down it)
DEFAULT_X = make_pose(so3_fast.exp(np.array([0.1, -0.2, 1.4])), [80.0, -20.0, 60.0])


@dataclasses.dataclass(frozen=True)
class RegistrationData:
    """Validated data: A, B (m, 4, 4) read-only, body (m,) the body (camera) of each station."""

    A: np.ndarray
    B: np.ndarray
    body: np.ndarray

    @property
    def m(self) -> int:
        return len(self.A)

    @property
    def k(self) -> int:
        """The number of bodies: X is a stack of k poses."""
        return int(self.body.max()) + 1

    @functools.cached_property
    def translation_scale(self) -> float:
        """RMS norm of the translations: the data's length unit."""
        t = np.concatenate([self.A[:, :3, 3], self.B[:, :3, 3]])
        return float(np.sqrt(np.mean(np.sum(t * t, axis=1)))) or 1.0

    @functools.cached_property
    def pose_model(self) -> RegistrationModel:
        return RegistrationModel(self)


class RegistrationModel(PoseModel):
    """e_i = [log(R_Ai R_Xb R_Bi^T); R_Ai t_Xb + t_Ai - t_Bi] on the poses X[0], ..., X[k-1].

    With the retraction X exp(omega, v): R_A R_X exp(omega) R_B^T = exp(R_A R_X omega) Q, so the
    rotation rows are Jl^-1(r) R_A R_X on omega_b and the translation rows R_A R_X on v_b."""

    def __init__(self, data: RegistrationData) -> None:
        self.k, self.m, self.scale = data.k, data.m, data.translation_scale
        self.unknowns = tuple(f"X[{b}]" for b in range(self.k))
        self.profile_min_pairs = self.k + 1
        self.body = data.body
        self.RA, self.tA = data.A[:, :3, :3], data.A[:, :3, 3]
        self.RBt, self.tB = np.swapaxes(data.B[:, :3, :3], 1, 2), data.B[:, :3, 3]

    def _RAX(self, poses: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        X = np.stack(poses)[self.body]
        return self.RA @ X[:, :3, :3], np.einsum("mij,mj->mi", self.RA, X[:, :3, 3])

    def residuals(self, poses: tuple[np.ndarray, ...]) -> np.ndarray:
        RAX, RAtX = self._RAX(poses)
        e = np.empty((self.m, 6))
        e[:, :3] = so3_fast.log(RAX @ self.RBt)
        e[:, 3:] = RAtX + self.tA - self.tB
        return e

    def jacobian(self, poses: tuple[np.ndarray, ...], e: np.ndarray) -> np.ndarray:
        RAX, _ = self._RAX(poses)
        Jl_inv, _ = so3_fast.inverse_jacobians(e[:, :3])
        J = np.zeros((self.m, 6, 6 * self.k))
        for b in range(self.k):
            rows = self.body == b
            J[rows, :3, 6 * b:6 * b + 3] = Jl_inv[rows] @ RAX[rows]
            J[rows, 3:, 6 * b + 3:6 * b + 6] = RAX[rows]
        return J


def stations_to_data(robot_poses: Any, camera_poses: Any, setup: str = "eye-in-hand",
                     pairing: str | None = None) -> dict[str, np.ndarray]:
    """A cell's stations as registration data: A = T_base_flange, B = inv(T_cam_target), the
    board's frame being the base's; eye-in-hand only, one camera."""
    if setup != "eye-in-hand":
        raise handeye.InputError(f"registration takes an eye-in-hand cell (a camera on the flange), not {setup!r}")
    return {"A": np.array(pose_stack(robot_poses, "robot_poses")),
            "B": inverse(pose_stack(camera_poses, "camera_poses"))}


class Registration(handeye.Problem):
    """A_i X_b(i) = B_i: the camera(s) on the flange, against a board at a known pose."""

    name = NAME
    summary = "hand-eye registration against a known board, A_i X_b(i) = B_i (example plugin)"
    unknowns = ("X",)
    data_fields = ("A", "B")
    optional_fields = ("body",)
    min_pairs = 2
    data_type = RegistrationData
    equation = "A_i X_b(i) = B_i"
    setups = ("eye-in-hand",)
    starts = (SOLVER,)
    station_reader = StationReader(stations_to_data)
    study_noise = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}

    def validate(self, **data: Any) -> RegistrationData:
        A = pose_stack(data["A"], "A")
        B = pose_stack(data["B"], "B")
        if len(A) != len(B):
            raise handeye.InputError(f"A and B must hold as many poses, got {len(A)} and {len(B)}")
        body = np.zeros(len(A), dtype=int) if data.get("body") is None else np.asarray(data["body"])
        if body.shape != (len(A),) or body.dtype.kind not in "iu" or (len(body) and body.min() < 0):
            raise handeye.InputError(f"body must hold one integer >= 0 per pose pair ({len(A)}), got shape {body.shape}")
        counts = np.bincount(body)
        if np.any(counts < self.min_pairs):
            raise handeye.InputError(f"every body 0..{len(counts) - 1} needs at least {self.min_pairs} pose pairs, "
                                     f"got {counts.tolist()}")
        body = body.astype(int)
        body.setflags(write=False)
        return RegistrationData(A, B, body)

    def residuals(self, data: RegistrationData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        X = np.asarray(unknowns["X"], dtype=float).reshape(-1, 4, 4)
        return pose_discrepancy(data.A @ X[data.body], data.B)

    def stack_sizes(self, data: RegistrationData) -> Mapping[str, int]:
        return {"X": data.k}

    def check_model(self, data: RegistrationData, unknowns: Mapping[str, np.ndarray]) -> tuple[Any, tuple, tuple]:
        model = data.pose_model
        return model, tuple(np.asarray(unknowns["X"], dtype=float).reshape(-1, 4, 4)), model.unknowns

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        return {"X": Frame("flange", "cam", "camera(s) in the flange frame")}

    def simulate(self, *, pairs: int, seed: int | None = None, noise: Any = None, X: Any = None,
                 bodies: int = 1) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """`pairs` stations of the paper's arm at random joints (mm), station i seen by body
        i mod `bodies`; B_i = A_i X_b(i), then `noise` ("A" on the robot, "B" on the camera).
        X: a 4x4 pose or a stack of `bodies` poses (default `DEFAULT_X` turned about the flange
        axis for each body)."""
        rng = np.random.default_rng(seed)
        if X is None:
            turn = [make_pose(so3_exp_z(2 * np.pi * b / bodies), np.zeros(3)) for b in range(bodies)]
            X = np.stack([T @ DEFAULT_X for T in turn])
        X = np.asarray(X, dtype=float).reshape(-1, 4, 4)
        if len(X) != bodies:
            raise handeye.InputError(f"X holds {len(X)} poses for {bodies} bodies")
        body = np.arange(pairs) % bodies
        A = random_flange_poses(pairs, rng)
        B = A @ X[body]
        if noise is not None:
            pose_rng = np.random.default_rng(rng.integers(2**63))
            A, B = noise.apply("A", A, pose_rng), noise.apply("B", B, pose_rng)
        data = {"A": A, "B": B, **({"body": body} if bodies > 1 else {})}
        return data, {"X": X}


def so3_exp_z(angle: float) -> np.ndarray:
    return so3_fast.exp(np.array([0.0, 0.0, angle]))


def _chordal_mean(R: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(R.sum(axis=0))
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def run(data: RegistrationData, options: Any, backend: str) -> handeye.SolverOutput:
    """Per body b: R_Xb the chordal mean of R_Ai^T R_Bi, t_Xb the mean of R_Ai^T (t_Bi - t_Ai)."""
    D = inverse(data.A) @ data.B  # each A_i^-1 B_i is X_b(i) measured once
    X = np.stack([make_pose(_chordal_mean(D[data.body == b, :3, :3]), D[data.body == b, :3, 3].mean(axis=0))
                  for b in range(data.k)])
    return handeye.SolverOutput({"X": X})


SPEC = handeye.SolverSpec(
    name=SOLVER,
    problems=(NAME,),
    run=run,
    summary="closed form: per body, the chordal mean of A_i^-1 B_i (example plugin)",
    citation="example",
    unit_invariant=True,
    exact=True,
)
PROBLEM = Registration()


@handeye.hookimpl
def register_problems(register):
    register(PROBLEM)


@handeye.hookimpl
def register_solvers(register):
    register(SPEC)
