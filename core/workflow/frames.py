"""What the unknowns of a calibration are in the cell, read from the problem (`handeye.Problem`:
`frames`, `published`, `equation`, `item`), in the forms the printouts, the exports and the report
use; and the ROS frame ids the exports take.

For the built-in problems (docs/conventions.md): eye-in-hand (camera on the flange, board fixed)
AX=YB X = T_flange_cam, Y = T_base_target, AX=XB X = T_flange_cam; eye-to-hand (camera fixed,
board on the flange) AX=YB X = T_flange_target, Y = T_base_cam, AX=XB X = T_base_cam.

``T_parent_child`` is the child frame's pose in the parent frame. The camera frame is the optical
frame of ``cv2.solvePnP`` (z forward, x right, y down), hence the default ROS child id
``camera_optical_frame``, not a driver's ``camera_link`` (x forward).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.framework.problem_cell import Published
from handeye.host.registry import get_registry

#: the short names of frames in T_parent_child -> the frame's name in words
FRAME_WORDS = {"flange": "flange", "base": "base", "cam": "camera", "target": "target"}
#: a ROS frame id: graph resource names (letters, digits, underscores, starting with a letter; '/'
#: separating namespaces), which a shell never interprets and an XML attribute takes as they are
ROS_FRAME_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*")


@dataclasses.dataclass(frozen=True)
class CellFrame:
    """One unknown as a frame of the cell: ``T_parent_child``, the child's pose in the parent.

    unknown: ``"X"`` or ``"Y"``; name: e.g. ``"T_flange_cam"``; parent, child: the frames in words
    (``"flange"``, ``"camera"``); description: e.g. ``"camera in the flange frame"``.
    """

    unknown: str
    name: str
    parent: str
    child: str
    description: str


def frame_names(problem: str, setup: str | None) -> dict[str, tuple[str, str]]:
    """Per unknown of `problem` in `setup`: (its frame name T_parent_child, what it is); empty
    when the problem does not say (`Problem.frames`)."""
    frames = get_registry().problem(problem).frames(setup)
    return {unknown: (f.symbol, f.meaning) for unknown, f in frames.items()}


def frames_of(problem: str, setup: str | None) -> dict[str, CellFrame]:
    """The unknowns of `problem` in `setup` as `CellFrame`s, in the problem's order."""
    frames = get_registry().problem(problem).frames(setup)
    return {unknown: CellFrame(unknown, f.symbol, FRAME_WORDS.get(f.parent, f.parent),
                               FRAME_WORDS.get(f.child, f.child), f.meaning)
            for unknown, f in frames.items()}


def equation_of(problem: str) -> tuple[str, str]:
    """(the problem's equation as printed, what one row of its data is: "pair", "motion", ...)."""
    spec = get_registry().problem(problem)
    return spec.equation or f"the equations of problem {problem!r}", spec.item


def published_of(problem: str, setup: str | None) -> Published | None:
    """The unknown the exports publish (the camera's pose) with its default frame ids, or None
    when `problem` publishes none (`Problem.published`)."""
    return get_registry().problem(problem).published(setup)


def single_poses(unknowns: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The unknowns as named single 4x4 poses, for printing and exports: a stack of k poses
    (`Problem.stack_sizes`) as ``X[0]``, ..., ``X[k-1]`` (the names of its 1-sigma entries)."""
    out: dict[str, np.ndarray] = {}
    for name, T in unknowns.items():
        T = np.asarray(T, dtype=float)
        if T.ndim == 3:
            out.update({f"{name}[{k}]": pose for k, pose in enumerate(T)})
        else:
            out[name] = T
    return out


def unknown_of(name: str) -> str:
    """The unknown a name of `single_poses` belongs to (``X[2]`` -> ``X``)."""
    return name.split("[", 1)[0]


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
