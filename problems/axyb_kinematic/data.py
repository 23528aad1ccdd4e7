"""Validated data of the kinematic hand-eye problem: the stations' pose pairs (A, B, validated as
problem axyb's), the joint readings q and the arm's nominal DH table, with which DH parameters
hand-eye data can determine (`handeye.problems.axyb_kinematic.model.structural`) and whether these
stations determine them.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import rotation_angle
from handeye.geometry.validation import float_array
from handeye.problems.axyb import AXYBData
from handeye.problems.axyb_kinematic import model

#: largest difference between the robot poses A and the nominal forward kinematics of q accepted
#: (rad, and relative to the data's RMS translation): a controller's printed poses (0.001 mm,
#: 0.001 deg) pass; joints in degrees, in another order, or another DH table do not
FK_ROTATION_TOL = 1e-3
FK_TRANSLATION_TOL = 1e-3
#: smallest singular value, relative to the largest, of the stations' linearised equation (columns
#: scaled to unit norm) with which X, Y and the identifiable parameters count as determined
DETERMINED = 1e-7
#: stations needed per unknown: the fit needs twice as many residuals as unknowns, so that the
#: noise (whose level the fit estimates from the residuals) is not fitted away
REDUNDANCY = 2.0
#: a joint that moved less than this over the stations (rad) is named when the data fall short
SMALL_MOTION = math.radians(5.0)


@dataclasses.dataclass(frozen=True)
class KinematicData:
    """Validated data of A_i X = Y B_i with A_i = FK(q_i): `pairs` (A, B: (m, 4, 4) as problem
    axyb validates them), `q` (m, n) joint readings (rad, read-only), `dh` the nominal arm
    (`DHArm`), `identifiability` (which of its 4n parameters the data can determine)."""

    pairs: AXYBData
    q: np.ndarray
    dh: DHArm
    identifiability: model.Identifiability

    @property
    def A(self) -> np.ndarray:
        return self.pairs.A

    @property
    def B(self) -> np.ndarray:
        return self.pairs.B

    @property
    def m(self) -> int:
        return self.pairs.m

    @property
    def joints(self) -> int:
        return self.dh.joints

    @property
    def translation_scale(self) -> float:
        """RMS translation of A and B: the data's length unit."""
        return self.pairs.translation_scale


def dh_table(value: Any) -> np.ndarray:
    """A nominal DH table from a `DHArm` or a (joints, 4) array of numbers, columns a, alpha, d,
    offset (lengths in the unit of A and B, angles in rad); InputError naming what is wrong."""
    if value is None:
        raise InputError("problem 'axyb-kinematic' needs dh, the arm's nominal DH table (a DHArm, or one row "
                         "per joint: a, alpha, d, offset)")
    table = float_array(value, "dh", "the nominal DH table: one row per joint, columns a, alpha, d, offset")
    if table.ndim != 2 or table.shape[1] != 4 or len(table) < 2:
        raise InputError(f"dh must have shape (joints, 4) with at least 2 joints (columns a, alpha, d, offset), "
                         f"got {table.shape}")
    if not np.all(np.isfinite(table)):
        raise InputError("dh holds NaN or inf; every DH parameter must be a finite number")
    return table


def joint_readings(value: Any, m: int, joints: int) -> np.ndarray:
    """The joint readings q: (m, joints) rad, finite and read-only; InputError otherwise."""
    if value is None:
        raise InputError("problem 'axyb-kinematic' needs q, the joint readings of every station ((m, joints) "
                         "array, radians)")
    q = float_array(value, "q", "the joint readings: an (m, joints) array of angles in radians")
    if q.ndim != 2:
        raise InputError(f"q must have shape (m, joints), one row of joint angles per station, got {q.shape}")
    if len(q) != m:
        raise InputError(f"q and A must have the same length: q has {len(q)} rows of joint readings and A "
                         f"{m} poses; give one reading per station")
    if q.shape[1] != joints:
        raise InputError(f"q has {q.shape[1]} joints per station but the DH table dh has {joints}; give the "
                         "joints in the table's order")
    if not np.all(np.isfinite(q)):
        raise InputError("q holds NaN or inf; every joint reading must be a finite angle (rad)")
    if np.abs(q).max(initial=0.0) > 100.0:
        raise InputError(f"q holds joint angles up to {np.abs(q).max():.3g}, beyond any revolute joint in "
                         "radians: give q in radians (np.radians of degrees)")
    q.setflags(write=False)
    return q


def check_forward_kinematics(pairs: AXYBData, q: np.ndarray, table: np.ndarray) -> None:
    """InputError unless the robot poses A are the nominal forward kinematics of q (to
    FK_ROTATION_TOL and FK_TRANSLATION_TOL): what the controller reports, so a mismatch is a
    unit, an order or a DH table that is not the controller's."""
    with np.errstate(all="ignore"):
        F = DHArm.from_table(table).forward(q)
        angle = rotation_angle(F[:, :3, :3] @ np.swapaxes(pairs.A[:, :3, :3], 1, 2))
        dist = np.linalg.norm(F[:, :3, 3] - pairs.A[:, :3, 3], axis=1)
    bad = ~((angle <= FK_ROTATION_TOL) & (dist <= FK_TRANSLATION_TOL * pairs.translation_scale))
    if bad.any():
        i = int(np.flatnonzero(bad)[np.argmax(np.nan_to_num(dist[bad], nan=np.inf))])
        raise InputError(
            f"the robot poses A are not the nominal forward kinematics of the joint readings q ({int(bad.sum())} of "
            f"{len(q)} stations; station {i}: {math.degrees(angle[i]):.3g} deg, {dist[i]:.3g} length units apart): "
            "give q in radians in the joint order of the DH table dh, dh as the controller's model (columns a, "
            "alpha, d, offset; lengths in the unit of A and B), and A as the controller reports it")


def check_determined(q: np.ndarray, table: np.ndarray, ident: model.Identifiability, scale: float) -> None:
    """DegenerateDataError, naming what to record, when the stations q do not determine X, Y and
    the identifiable parameters: too few stations, or too little motion of some joints."""
    m, n = q.shape
    unknowns = 12 + len(ident.identifiable)
    needed = math.ceil(REDUNDANCY * unknowns / 6)
    ranges = np.ptp(q, axis=0)
    still = [f"J{j + 1}" for j in range(n) if ranges[j] < SMALL_MOTION]
    advice = (f"; joints that moved less than {math.degrees(SMALL_MOTION):g} deg: {', '.join(still)}" if still else "")
    if m < needed:
        raise DegenerateDataError(
            f"{m} stations cannot determine X, Y and the {len(ident.identifiable)} identifiable kinematic parameters "
            f"of this arm with noise to spare: record at least {needed} stations (30 or more for a useful "
            f"correction) that move every joint over a wide range{advice}")
    M = model.design(q, table, scale)
    M = M[:, list(range(12)) + [12 + k for k in ident.identifiable]]
    M = M / np.maximum(np.linalg.norm(M, axis=0), 1e-300)
    _, s, Vt = np.linalg.svd(M, full_matrices=False)
    if s[-1] < DETERMINED * s[0]:
        v = np.abs(Vt[-1, 12:])
        worst = [model.parameter_name(ident.identifiable[k]) for k in np.argsort(-v)[:3] if v[k] > 0.1]
        raise DegenerateDataError(
            f"the {m} stations do not determine the kinematic parameters {', '.join(worst) or '(X and Y)'} apart from "
            f"X, Y and each other: record stations that move every joint over a wide range{advice}, or solve "
            "problem axyb (poses only)")
