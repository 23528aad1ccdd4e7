"""A calibrated pose in the forms a cell consumes it: a JSON-ready entry (4x4, xyz + quaternion,
the robot's own format, 1-sigma), a ROS 2 ``static_transform_publisher`` line, a URDF fixed
joint and a xacro macro of that joint, and plain JSON text of a result.

Every export takes ``T = T_parent_child`` (the child frame's pose in the parent frame) with its
translation in the cell's length unit; ROS, URDF and xacro want metres and get them. Quaternions
are Hamilton (x, y, z, w) with w >= 0; URDF's ``rpy`` is roll, pitch, yaw about the fixed x, y, z
axes (R = Rz(yaw) Ry(pitch) Rx(roll)), scipy's extrinsic ``"xyz"``.
"""

from __future__ import annotations

import json
import math
import shlex
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.io.pose_formats import parse_format

#: metres per unit
METRES = {"mm": 1e-3, "m": 1.0}


def pose_entry(T: np.ndarray, robot_format: str, std: Mapping[str, float] | None) -> dict[str, Any]:
    """One unknown as a 4x4, as [x, y, z, qx, qy, qz, qw] (w >= 0), as a row of the robot's
    format (not for matrix formats) and its 1-sigma (rotation deg, translation robot unit).
    T: (4, 4); std: {"rotation": rad, "translation": unit} or None."""
    T = np.asarray(T, dtype=float)
    q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
    entry: dict[str, Any] = {"matrix": T.tolist(), "xyz_quat": [*T[:3, 3].tolist(), *q.tolist()]}
    fmt = parse_format(robot_format)
    if fmt.kind != "matrix":
        entry["robot_format"] = dict(zip(fmt.fields, fmt.to_rows(T[None])[0].tolist()))
    entry["std"] = None if std is None else {"rotation_deg": math.degrees(std["rotation"]),
                                             "translation": std["translation"]}
    return entry


def _metres_and_quaternion(T: np.ndarray, unit: str) -> tuple[np.ndarray, np.ndarray]:
    T = np.asarray(T, dtype=float)
    return T[:3, 3] * METRES[unit], Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)


def ros_line(T: np.ndarray, unit: str, parent: str, child: str) -> str:
    """``ros2 run tf2_ros static_transform_publisher`` publishing T = T_parent_child (the child
    frame's pose in the parent's), translation converted from `unit` to metres."""
    t, q = _metres_and_quaternion(T, unit)
    values = " ".join(f"--{k} {v:.9g}" for k, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), [*t, *q]))
    return (f"ros2 run tf2_ros static_transform_publisher {values} --frame-id {shlex.quote(parent)} "
            f"--child-frame-id {shlex.quote(child)}")  # valid ids need no quotes: quoted all the same


def _origin(T: np.ndarray, unit: str) -> str:
    """URDF ``<origin xyz=... rpy=.../>`` of T (metres, radians)."""
    T = np.asarray(T, dtype=float)
    t = T[:3, 3] * METRES[unit]
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    return (f'<origin xyz="{" ".join(f"{v:.9g}" for v in t)}" '
            f'rpy="{" ".join(f"{v:.9g}" for v in rpy)}"/>')


def urdf_joint(T: np.ndarray, unit: str, parent: str, child: str, name: str | None = None) -> str:
    """A URDF fixed joint placing link `child` at T = T_parent_child in link `parent` (both links
    must exist in the robot description; frame ids are `handeye.workflow.frames.ROS_FRAME_ID`
    names, safe in XML). `name`: the joint's name (default ``<parent>_to_<child>``, '/' as '_')."""
    name = name or f"{parent}_to_{child}".replace("/", "_")
    return "\n".join([f'<joint name="{name}" type="fixed">',
                      f'  <parent link="{parent}"/>',
                      f'  <child link="{child}"/>',
                      f"  {_origin(T, unit)}",
                      "</joint>"])


def xacro_macro(T: np.ndarray, unit: str, parent: str, child: str, macro: str = "handeye_calibration") -> str:
    """A xacro file defining macro `macro` with params ``parent`` and ``child`` (defaults: the
    given ids) that adds the fixed joint of `urdf_joint`: include it in the robot's xacro and call
    ``<xacro:handeye_calibration/>`` (or with ``parent="tool0"`` etc.)."""
    origin = _origin(T, unit)
    return "\n".join(['<?xml version="1.0"?>',
                      '<robot xmlns:xacro="http://www.ros.org/wiki/xacro">',
                      f'  <xacro:macro name="{macro}" params="parent:={parent} child:={child}">',
                      '    <joint name="${parent}_to_${child}" type="fixed">',
                      '      <parent link="${parent}"/>',
                      '      <child link="${child}"/>',
                      f"      {origin}",
                      "    </joint>",
                      "  </xacro:macro>",
                      "</robot>"])


def xacro_joints(poses: list[tuple[np.ndarray, str, str]], unit: str, macro: str = "handeye_calibration") -> str:
    """A xacro file defining macro `macro` (no params) that adds a fixed joint per (T, parent,
    child) of `poses` (T = T_parent_child), e.g. every camera and marker of a cell: include it in
    the robot's xacro and call ``<xacro:handeye_calibration/>``."""
    lines = ['<?xml version="1.0"?>', '<robot xmlns:xacro="http://www.ros.org/wiki/xacro">',
             f'  <xacro:macro name="{macro}" params="">']
    for T, parent, child in poses:
        lines += ["    " + line for line in urdf_joint(T, unit, parent, child).splitlines()]
    return "\n".join([*lines, "  </xacro:macro>", "</robot>"])


def plain(value: Any) -> Any:
    """`value` as plain JSON data: mappings (keys as str), sequences, numpy arrays and scalars
    converted, enums as their value, NaN and infinities as None."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "value") and isinstance(value.value, str):  # enums
        return value.value
    return value


def dump_json(obj: Any) -> str:
    """JSON text of `obj` (`plain`), indented by 2."""
    return json.dumps(plain(obj), indent=2)
