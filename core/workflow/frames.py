"""What the unknowns of a calibration are in the cell: their frames per problem and setup
(docs/conventions.md), the equation each problem's residuals are measured on, and which unknown a
ROS graph publishes under which frame ids.

One table each, read by `handeye.calibrate` (its result's `frames`), by ``handeye solve`` and
``handeye calibrate`` (the printed frames) and by the exports (ROS line, URDF, xacro).

- eye-in-hand (camera on the flange, board fixed): axyb X = T_flange_cam, Y = T_base_target;
  axxb X = T_flange_cam;
- eye-to-hand (camera fixed, board on the flange): axyb X = T_flange_target, Y = T_base_cam;
  axxb X = T_base_cam.

``T_parent_child`` is the child frame's pose in the parent frame. The camera frame is the optical
frame of ``cv2.solvePnP`` (z forward, x right, y down), hence the default ROS child id
``camera_optical_frame``, not a driver's ``camera_link`` (x forward).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence

from handeye.framework.errors import InputError

#: (problem, setup) -> unknown -> (frame name, what it is)
FRAMES: dict[tuple[str, str], dict[str, tuple[str, str]]] = {
    ("axyb", "eye-in-hand"): {"X": ("T_flange_cam", "camera in the flange frame"),
                              "Y": ("T_base_target", "target in the robot base frame")},
    ("axyb", "eye-to-hand"): {"X": ("T_flange_target", "target in the flange frame"),
                              "Y": ("T_base_cam", "camera in the robot base frame")},
    ("axxb", "eye-in-hand"): {"X": ("T_flange_cam", "camera in the flange frame")},
    ("axxb", "eye-to-hand"): {"X": ("T_base_cam", "camera in the robot base frame")},
}
#: problem -> its equation and what one data pair is, for the residual lines
EQUATIONS = {"axyb": ("A_i X = Y B_i", "pair"), "axxb": ("A_i X = X B_i", "motion")}
#: the short names in a frame name T_parent_child -> the frame's name in words
FRAME_WORDS = {"flange": "flange", "base": "base", "cam": "camera", "target": "target"}
#: (problem, setup) -> (the unknown published on ROS: always the camera's pose, default parent
#: frame id, default child frame id)
ROS_FRAMES: dict[tuple[str, str], tuple[str, str, str]] = {
    ("axyb", "eye-in-hand"): ("X", "flange", "camera_optical_frame"),
    ("axyb", "eye-to-hand"): ("Y", "base", "camera_optical_frame"),
    ("axxb", "eye-in-hand"): ("X", "flange", "camera_optical_frame"),
    ("axxb", "eye-to-hand"): ("X", "base", "camera_optical_frame"),
}
#: a ROS frame id: graph resource names (letters, digits, underscores, starting with a letter; '/'
#: separating namespaces), which a shell never interprets and an XML attribute takes as they are
ROS_FRAME_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*")


@dataclasses.dataclass(frozen=True)
class Frame:
    """One unknown as a frame of the cell: ``T_parent_child``, the child's pose in the parent.

    unknown: ``"X"`` or ``"Y"``; name: e.g. ``"T_flange_cam"``; parent, child: the frames in words
    (``"flange"``, ``"camera"``); description: e.g. ``"camera in the flange frame"``.
    """

    unknown: str
    name: str
    parent: str
    child: str
    description: str


def frames_of(problem: str, setup: str) -> dict[str, Frame]:
    """The unknowns of `problem` in `setup` as `Frame`s, X first."""
    out = {}
    for unknown, (name, description) in FRAMES[(problem, setup)].items():
        _, parent, child = name.split("_")
        out[unknown] = Frame(unknown, name, FRAME_WORDS[parent], FRAME_WORDS[child], description)
    return out


def frame_ids(ids: str | Sequence[str] | None, field: str = "`frame_ids`") -> tuple[str, str] | None:
    """(parent, child) of ``"PARENT,CHILD"`` or a pair, each a ROS frame id (`ROS_FRAME_ID`); None
    stays None (the default ids of the setup). `field` names the setting in messages."""
    if ids is None:
        return None
    parts = [p.strip() for p in ids.split(",")] if isinstance(ids, str) else list(ids)
    if len(parts) != 2 or not all(isinstance(p, str) and p for p in parts):
        raise InputError(f"{field} expects PARENT,CHILD (two frame ids), got {ids!r}")
    for part in parts:
        if not ROS_FRAME_ID.fullmatch(part):
            raise InputError(f"{field}: {part!r} is not a ROS frame id (letters, digits and underscores, "
                             "starting with a letter, '/' between namespaces: e.g. tool0, camera_link, "
                             "robot1/base_link)")
    return parts[0], parts[1]
