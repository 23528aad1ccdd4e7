"""The stations' own figures, before any fit: the cell's lever arm (`cell_size`), repeated
stations (`duplicate_stations`) and the warnings they give (`station_warnings`). Used by the
plausibility check of a calibration's files (`handeye.workflow.plausibility`) and by planning a
session (`handeye.planning.session`), which must agree on what a repeated station is; and the
record of a pose or image left out of the stations (`Dropped`), which the image readers and the
workflow both give."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.geometry.se3 import rotation_angle

#: two stations are duplicates when their robot poses differ by less than this angle (deg) and
#: this fraction of the cell size
DUPLICATE_DEG = 0.1
DUPLICATE_FRACTION = 1e-3
#: the duplicated stations a warning lists (then "...")
DUPLICATES_LISTED = 5
#: below this many stations the covariance-based 1-sigma is not meaningful
MIN_STATIONS_FOR_SIGMA = 5


@dataclasses.dataclass(frozen=True)
class Dropped:
    """A pose or image left out of the stations, and why.

    kind: ``"image"``, ``"camera"`` (a camera pose) or ``"robot"`` (a robot pose); name: the
    image's file stem, the pose's name, else its row in its file as ``"row N"`` (1-based); robot:
    the robot pose dropped together with an image (its name), if any; reason: in words.
    """

    kind: str
    name: str
    reason: str
    robot: str | None = None

    def describe(self) -> str:
        """One line, e.g. ``image 4 with robot pose 4: board not found: ...``."""
        what = {"image": "image", "camera": "camera pose", "robot": "robot pose"}[self.kind]
        partner = f" with robot pose {self.robot}" if self.robot is not None else ""
        return f"{what} {self.name}{partner}: {self.reason}"


def cell_size(robot: np.ndarray, camera: np.ndarray | None = None) -> float:
    """The cell's lever arm (robot unit): the largest of the RMS distance of the flange positions
    robot[:, :3, 3] from their centroid, their RMS distance from the robot base, and the RMS
    camera-to-board distance. Rotation noise turns into translation residuals through these
    arms, and which one dominates depends on the frame the residuals live in (the flange spread
    for eye-in-hand motions; the base-to-camera distance, up to base-to-flange plus
    camera-to-board, for eye-to-hand motions, whose residuals are in the base frame). The
    camera arm counts up to twice the base-to-flange one, so that a camera file in the wrong unit
    (1000x) cannot widen the limit with it."""
    t = np.asarray(robot, dtype=float)[:, :3, 3]
    arms = [np.sqrt(np.mean(np.sum((t - t.mean(axis=0)) ** 2, axis=1))), np.sqrt(np.mean(np.sum(t * t, axis=1)))]
    if camera is not None:
        c = np.asarray(camera, dtype=float)[:, :3, 3]
        arms.append(min(np.sqrt(np.mean(np.sum(c * c, axis=1))), 2.0 * arms[1]))
    return float(max(arms))


def station_warnings(robot: np.ndarray, unit: str) -> list[str]:
    """Duplicated stations (robot poses within DUPLICATE_DEG and DUPLICATE_FRACTION of the cell
    size) and too few stations for a meaningful 1-sigma."""
    robot = np.asarray(robot, dtype=float)
    n = len(robot)
    out = []
    size = cell_size(robot)
    dup = duplicate_stations(robot, DUPLICATE_FRACTION * max(size, 1e-12), math.radians(DUPLICATE_DEG),
                             limit=DUPLICATES_LISTED + 1)
    if dup:
        rows = ", ".join(f"{i + 1} and {j + 1}" for i, j in dup[:DUPLICATES_LISTED])
        more = " ..." if len(dup) > DUPLICATES_LISTED else ""
        out.append(f"duplicated stations: the robot poses of rows {rows}{more} are "
                   f"nearly the same (< {DUPLICATE_DEG:g} deg, < {DUPLICATE_FRACTION * size:.2g} {unit}); a "
                   "repeated station adds no information and makes the 1-sigma too small: move the robot "
                   "between stations")
    if n < MIN_STATIONS_FOR_SIGMA:
        out.append(f"only {n} stations: the reported 1-sigma is not meaningful (the noise is estimated from "
                   f"the residuals, which needs at least {MIN_STATIONS_FOR_SIGMA} stations; 10-20 are usual)")
    return out


def duplicate_stations(poses: np.ndarray, distance: float, angle: float, limit: int) -> list[tuple[int, int]]:
    """The first `limit` pairs (i, j), i < j in row order (i, then j), of poses (n, 4, 4) whose
    positions are within `distance` and whose rotations differ by less than `angle` (rad).

    Memory and time grow with n (not n^2, which 15,000 stations of a recording matched by time
    would make 9.8 GB): a k-d tree on the positions proposes the neighbours of each station
    within `distance`, the rotation angle decides, and the search stops at `limit` pairs."""
    from scipy.spatial import cKDTree

    n = len(poses)
    if n < 2:
        return []
    t = poses[:, :3, 3]
    tree = cKDTree(t)
    crowded = np.flatnonzero(tree.query_ball_point(t, distance, return_length=True) > 1)  # counts only: O(n) memory
    found: list[tuple[int, int]] = []
    for i in crowded:
        near = tree.query_ball_point(t[i], distance, return_sorted=True)
        near = np.asarray(near, dtype=np.intp)
        near = near[near > i]
        if not len(near):
            continue
        turn = rotation_angle(poses[i, :3, :3].T @ poses[near, :3, :3])
        for j in near[turn < angle][: limit - len(found)]:
            found.append((int(i), int(j)))
        if len(found) >= limit:
            break
    return found
