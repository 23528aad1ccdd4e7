"""axyb-multi from a cell's files: a table of observations (station, camera, target, the robot's
pose, the camera's pose of the target) made into the problem's data (`from_observations`, the
`Problem.from_observations` hook). The example cell's files: `example_files`.

The mapping per setup (docs/conventions.md, "Problem `axyb-multi`"): eye-to-hand, fixed cameras
watching markers on the flange, X_j = T_flange_marker (one per target name), Y_k = T_base_cam
(one per camera name), B_i = T_cam_marker as solvePnP gives it; eye-in-hand, cameras on the
wrist watching boards in the cell, X_j = T_flange_cam (one per camera name), Y_k =
T_base_board (one per target name), B_i = T_board_cam, the inverse of solvePnP's board pose.
A_i = T_base_flange in both.
"""

from __future__ import annotations

import re

import numpy as np

from handeye.base.errors import InputError
from handeye.base.vocabulary import SETUPS
from handeye.framework.problem_cell import ObservationData, Observations
from handeye.geometry.se3 import inverse


def natural_key(text: str) -> tuple:
    """``cam2`` before ``cam10``: digits compared as numbers."""
    return tuple(int(part) if part.isdigit() else part for part in re.split(r"(\d+)", text))


def from_observations(observations: Observations, setup: str) -> ObservationData:
    """The data of axyb-multi (A, B, x_index, y_index, x_names, y_names) of `observations` in
    `setup` (module docstring), the X's and Y's named by the cameras and targets in natural
    order (``cam2`` before ``cam10``)."""
    if setup not in SETUPS:
        raise InputError(f"axyb-multi from observations needs the setup, one of {', '.join(SETUPS)}; got {setup!r}")
    cameras = sorted(set(observations.camera), key=natural_key)
    targets = sorted(set(observations.target), key=natural_key)
    clash = sorted(set(cameras) & set(targets))
    if clash:
        raise InputError(f"{clash[0]!r} names both a camera and a target; give cameras and targets distinct names")
    cam_number = {c: k for k, c in enumerate(cameras)}
    target_number = {t: k for k, t in enumerate(targets)}
    cam_index = np.array([cam_number[c] for c in observations.camera], dtype=np.int64)
    target_index = np.array([target_number[t] for t in observations.target], dtype=np.int64)
    A = np.asarray(observations.robot, dtype=float)
    T_cam_target = np.asarray(observations.camera_poses, dtype=float)
    if setup == "eye-to-hand":  # X: markers on the flange, Y: fixed cameras, B = T_cam_marker
        x_index, y_index, x_names, y_names, B = target_index, cam_index, targets, cameras, T_cam_target
    else:  # X: cameras on the wrist, Y: boards in the cell, B = T_board_cam
        x_index, y_index, x_names, y_names, B = cam_index, target_index, cameras, targets, inverse(T_cam_target)
    fields = {"A": A, "B": B, "x_index": x_index, "y_index": y_index, "x_names": list(x_names),
              "y_names": list(y_names)}
    return ObservationData(fields=fields, names={"X": tuple(x_names), "Y": tuple(y_names)})
