"""The problem axyb-kinematic: hand-eye and robot-world calibration together with the arm's own
kinematic (DH) errors, from joint readings. Its `Problem` (validation, residuals, simulator,
diagnostics) and its registration.

The equation is axyb's, A_i X = Y B_i (docs/conventions.md), with the robot's pose now a model
of its joint readings: A_i = FK(q_i) = prod_j Rz(q_ij) C_j, where C_j = Rz(offset_j) Tz(d_j)
Tx(a_j) Rx(alpha_j) is joint j's constant transform (`DHArm.links`). The unknowns are X, Y and
``links``, the stack of the n true C_j: kinematic errors are unknowns that are poses, so every
shared tool (the host's SE(3) checks, errors against a truth, studies) serves them unchanged.
The parameters behind them (the identified DH corrections with their standard deviations, and
which parameters the data cannot determine) are in the solver's ``diagnostics["kinematics"]``.

Hand-eye data cannot see every DH parameter (`model.structural`): those that move the base frame
are absorbed in Y, those of the last joint in X, and the d of a joint parallel to the one before
is redundant. Such parameters stay at their nominal values, ``links`` is the arm with the
identifiable corrections (the truth of the simulator is expressed the same way), and the
diagnosis names them in a warning.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import hookimpl
from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.framework.problem import Problem, pose_discrepancy
from handeye.framework.problem_cell import Frame, JointStations, Published
from handeye.framework.problem_studies import BenchSettings
from handeye.geometry.kinematics import LR_MATE_200ID, LR_MATE_SIM_JOINTS, DHArm
from handeye.geometry.se3 import inverse, make_pose
from handeye.geometry.validation import pose_stack
from handeye.problems.axyb import PAPER_X, PAPER_Y, SETUPS
from handeye.problems.axyb import problem as axyb_problem
from handeye.problems.axyb_kinematic import model
from handeye.problems.axyb_kinematic.data import (
    KinematicData,
    check_determined,
    check_forward_kinematics,
    dh_table,
    joint_readings,
)

#: the simulator's DH errors (magnitudes uniform in these ranges, random signs): joint offsets and
#: twists in rad, lengths a, d in the data's unit (mm for the default arm)
OFFSET_ERRORS = (math.radians(0.1), math.radians(0.5))
LENGTH_ERRORS = (0.2, 1.0)
#: the joint box of an arm other than the default one (rad)
DEFAULT_JOINT_BOX = math.radians(90.0)


def chain(q: np.ndarray, links: np.ndarray) -> np.ndarray:
    """Flange poses prod_j Rz(q_j) C_j for joint readings q: (m, n) and constant link transforms
    links: (n, 4, 4) -> (m, 4, 4)."""
    q = np.asarray(q, dtype=float)
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    for j, C in enumerate(np.asarray(links, dtype=float)):
        c, s = np.cos(q[:, j]), np.sin(q[:, j])
        Rz = np.zeros((len(q), 4, 4))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2], Rz[:, 3, 3] = c, -s, s, c, 1.0, 1.0
        T = T @ Rz @ C
    return T


def random_errors(table: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """DH errors (n, 4) on the identifiable parameters of the arm `table` (zero on the others):
    magnitudes uniform in `OFFSET_ERRORS` (angles) and `LENGTH_ERRORS` (lengths), random signs."""
    n = len(table)
    low = np.where(model.length_mask(n), LENGTH_ERRORS[0], OFFSET_ERRORS[0])
    high = np.where(model.length_mask(n), LENGTH_ERRORS[1], OFFSET_ERRORS[1])
    draw = rng.uniform(low, high) * rng.choice((-1.0, 1.0), size=4 * n)
    errors = np.zeros(4 * n)
    keep = list(model.structural(table).identifiable)
    errors[keep] = draw[keep]
    return errors.reshape(n, 4)


def canonical(nominal: np.ndarray, true: np.ndarray, X: np.ndarray, Y: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth as the data can see it: (links, X, Y) of an arm with DH table `true`, its first
    joint's offset and d and its last joint's four parameters moved into Y and X (exactly: they
    commute with the joints' rotations), so that those parameters are at their `nominal` values."""
    table = np.array(true, dtype=float)
    base = make_pose(_rz(table[0, 3] - nominal[0, 3]), [0.0, 0.0, table[0, 2] - nominal[0, 2]])
    table[0, 2:] = nominal[0, 2:]
    tool = inverse(DHArm.from_table(nominal[-1:]).links()[0]) @ DHArm.from_table(true[-1:]).links()[0]
    table[-1] = nominal[-1]
    return DHArm.from_table(table).links(), tool @ X, inverse(base) @ Y


def _rz(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class AXYBKinematic(Problem):
    """A_i X = Y B_i with A_i = FK(q_i): hand-eye, robot-world and kinematic calibration."""

    name = "axyb-kinematic"
    summary = "hand-eye and robot-world calibration with the arm's DH errors, from joint readings"
    unknowns = ("X", "Y", "links")
    #: the pose stacks (A: the controller's T_base_flange, which must be the nominal forward
    #: kinematics of q; B: the camera's, as for axyb); q and dh are required too (`validate`)
    data_fields = ("A", "B")
    optional_fields = ("q", "dh")
    min_pairs = 3
    data_type = KinematicData
    equation = "FK(q_i) X = Y B_i"
    item = "station"
    setups = SETUPS
    mistakes = ()
    #: the camera as in axyb's study; the robot's noise is on its joint readings (rad; the
    #: simulator applies the rotation sigma of "A" to q)
    study_noise = {"A": (math.radians(0.01), 0.0), "B": (0.002, 0.5)}
    bench = BenchSettings(pairs=(20, 50, 200))

    def frames(self, setup: str | None = None) -> dict[str, Frame]:
        """X and Y as axyb's; links: joint j's constant transform in the frame of joint j - 1."""
        frames = axyb_problem.PROBLEM.frames(setup)
        if frames:
            frames["links"] = Frame("joint", "next_joint", "each joint's constant DH transform (q = 0)")
        return frames

    def published(self, setup: str | None = None) -> Published | None:
        return axyb_problem.PROBLEM.published(setup)

    def validate(self, **data: Any) -> KinematicData:
        """The validated data: A, B as problem axyb validates them, q (m, n) rad and dh (a
        `DHArm` or an (n, 4) table a, alpha, d, offset) required, A the nominal forward kinematics
        of q; DegenerateDataError when the stations cannot determine the identifiable parameters."""
        q, dh = data.pop("q", None), data.pop("dh", None)
        pairs = axyb_problem.PROBLEM.validate(**data)
        table = dh_table(dh)
        q = joint_readings(q, pairs.m, len(table))
        check_forward_kinematics(pairs, q, table)
        ident = model.structural(table)
        check_determined(q, table, ident, pairs.translation_scale)
        return KinematicData(pairs, q, DHArm.from_table(table), ident)

    def from_joints(self, stations: JointStations, setup: str) -> dict[str, Any]:
        """The data of a cell's stations with joint readings (``handeye.calibrate`` of a cell with
        ``joints`` and ``arm``): A, B as problem axyb makes them from the stations' robot and
        camera poses in `setup`, with the readings q and the nominal DH table."""
        from handeye.problems.axyb.data import pairs_from_stations

        pairs = pairs_from_stations(stations.robot, stations.camera_poses, setup=setup)
        return {**pairs, "q": np.asarray(stations.q, dtype=float), "dh": DHArm.from_table(stations.dh)}

    def diagnose(self, data: KinematicData) -> dict[str, Any]:
        ident = data.identifiability
        table = data.dh.table
        return {
            "pairs": data.m, "joints": data.joints,
            "identifiable": [model.parameter_name(k) for k in ident.identifiable],
            "not_identifiable": [model.parameter_name(k) for k, _ in ident.confounded],
            "warnings": [f"not identifiable from hand-eye data, kept at their nominal values: {ident.words(table)}"]
            if ident.confounded else [],
        }

    def stack_sizes(self, data: KinematicData) -> Mapping[str, int]:
        return {"links": data.joints}

    def residuals(self, data: KinematicData, unknowns: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per station: rotation angle and translation distance between FK(q_i) X and Y B_i, FK
        from the unknowns' ``links`` (the nominal arm's when they give none)."""
        links = unknowns.get("links")
        links = data.dh.links() if links is None else np.asarray(links, dtype=float)
        return pose_discrepancy(chain(data.q, links) @ np.asarray(unknowns["X"], dtype=float),
                                np.asarray(unknowns["Y"], dtype=float) @ data.B)

    def expected_rotation_residual(self, data: KinematicData) -> float | None:
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.expected_rotation_residual(data.pairs)

    def rotation_axes(self, data: KinematicData) -> dict[str, np.ndarray]:
        from handeye.problems.axyb import geometry as axyb_geometry

        return axyb_geometry.rotation_axes(data.pairs)

    def random_unknowns(self, rng: np.random.Generator, translation_scale: float = 500.0) -> dict[str, np.ndarray]:
        """Random X, Y (`Problem.random_unknowns`) and the default arm with random DH errors on
        its identifiable parameters (`random_errors`)."""
        poses = axyb_problem.PROBLEM.random_unknowns(rng, translation_scale)
        table = LR_MATE_200ID.table
        return {**poses, "links": DHArm.from_table(table + random_errors(table, rng)).links()}

    def simulate(self, *, pairs: int, seed: int | None = None, noise: NoiseModel | None = None,
                 X: np.ndarray | None = None, Y: np.ndarray | None = None, links: np.ndarray | None = None,
                 **options: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """Stations of an arm with DH errors: joints q drawn in a box, the true flange poses
        A_true = prod Rz(q_j) C_j (`links`, or the nominal arm `dh` plus `errors`), B = Y^-1 A_true X;
        then noise: the rotation sigma of "A" on the joint readings q (rad), "B" on the camera
        poses (`NoiseModel`); A is the nominal forward kinematics of the readings, as a
        controller reports it.

        Options: dh (the nominal arm, default `LR_MATE_200ID`), errors ((n, 4) DH errors, columns
        a, alpha, d, offset; default `random_errors`; errors the data cannot see are moved into
        X and Y, `canonical`), joints ((n, 2) box, rad; default the LR Mate's, or +-90 deg).
        q: (pairs, n) the true joints themselves instead of a draw in the box (rad).
        X, Y default to axyb's `PAPER_X`, `PAPER_Y`. The random stream: joints, errors, noise.
        """
        dh, errors, box = options.pop("dh", None), options.pop("errors", None), options.pop("joints", None)
        given_q = options.pop("q", None)
        if options:
            raise InputError(f"unknown simulate option(s) {sorted(options)}; known: pairs, seed, noise, X, Y, links, "
                             "dh, errors, joints, q")
        if pairs < 1:
            raise InputError(f"pairs must be >= 1, got {pairs}")
        nominal = LR_MATE_200ID.table if dh is None else dh_table(dh)
        n = len(nominal)
        if box is None:
            default = dh is None or np.array_equal(nominal, LR_MATE_200ID.table)
            box = LR_MATE_SIM_JOINTS if default else np.tile([-DEFAULT_JOINT_BOX, DEFAULT_JOINT_BOX], (n, 1))
        box = np.asarray(box, dtype=float)
        rng = np.random.default_rng(seed)
        X = PAPER_X if X is None else pose_stack(np.asarray(X)[None], "X")[0]
        Y = PAPER_Y if Y is None else pose_stack(np.asarray(Y)[None], "Y")[0]
        q = rng.uniform(box[:, 0], box[:, 1], size=(pairs, n))
        if given_q is not None:  # the stations' joints themselves (the draw above keeps the stream's order)
            q = np.array(given_q, dtype=float).reshape(pairs, n)
        if links is None:
            errors = random_errors(nominal, rng) if errors is None else np.asarray(errors, dtype=float)
            links, X, Y = canonical(nominal, nominal + errors, X, Y)
        links = np.array(links, dtype=float)
        B = inverse(Y) @ chain(q, links) @ X
        noise = noise or NoiseModel()
        noise_rng = np.random.default_rng(rng.integers(2**63))
        sigma_q = noise.sigmas.get("A", (0.0, 0.0))[0]
        q_read = q + sigma_q * noise_rng.standard_normal(q.shape)
        B = noise.apply("B", B, noise_rng)
        nominal_arm = DHArm.from_table(nominal)
        data = {"A": nominal_arm.forward(q_read), "B": B, "q": q_read, "dh": nominal_arm}
        return data, {"X": np.array(X), "Y": np.array(Y), "links": links}


PROBLEM = AXYBKinematic()


@hookimpl
def register_problems(register):
    register(PROBLEM)
