"""The arm's nominal kinematic model as a file: a standard Denavit-Hartenberg table in YAML
(`read_arm`, `arm_yaml`), the input of a kinematic calibration (problem ``axyb-kinematic``) and
the form its corrected table is exported in, so that the user can enter it in the controller.

The file (docs/formats.md, "Arm models"):

    convention: standard-dh          # joint j: Rz(q_j + offset_j) Tz(d_j) Tx(a_j) Rx(alpha_j)
    length_unit: mm                  # mm or m: a and d
    angle_unit: deg                  # deg or rad: alpha and offset
    joints:                          # base to flange, one mapping per revolute joint
      - {name: J1, a: 50, alpha: -90, d: 330, offset: 0}
      - ...

``name`` is optional (default J1, J2, ...): a joint file whose columns carry the same names is
read in the table's order whatever its column order. Optional ``base`` and ``tool``, each
``{xyz: [x, y, z], rpy: [roll, pitch, yaw]}`` (length and angle units as above; rpy as in URDF,
R = Rz(yaw) Ry(pitch) Rx(roll)), are constant transforms before the first DH frame and after the
last: the flange pose is T_base_flange(q) = base FK_DH(q) tool. A URDF (``.urdf``) is read as
such an arm, its revolute chain converted exactly (`handeye.io.urdf_arm`). Modified (Craig) DH and
prismatic joints are not read (docs/kinematic.md, "Left for later").

Errors are one-line `InputError`s naming the file, the joint and the key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base import vocabulary
from handeye.base.errors import InputError, shown
from handeye.base.vocabulary import METRES_PER, RADIANS_PER
from handeye.geometry.kinematics import DHArm
from handeye.io.input_files import check_not_looping, load_yaml, number

#: the conventions read (standard DH only, for now)
CONVENTIONS = ("standard-dh",)
LENGTH_UNITS = {unit: METRES_PER[unit] for unit in vocabulary.LENGTH_UNITS}
ANGLE_UNITS = RADIANS_PER
#: the keys of the file and of each joint
KEYS = ("convention", "length_unit", "angle_unit", "joints", "base", "tool", "description")
JOINT_KEYS = ("name", "a", "alpha", "d", "offset")
#: an arm file holds a few dozen numbers
MAX_ARM_FILE_BYTES = 1_000_000


@dataclasses.dataclass(frozen=True)
class ArmModel:
    """A nominal arm as read: `dh` (lengths in `unit`, angles in rad), `unit` (``mm`` or ``m``),
    `names` (one per joint), `angle_unit` (the file's, for writing it back), `source`, and the
    constant `base` and `tool` transforms ((4, 4), `unit`; None: identity) with the names of the
    frames they reach (`frames`: base and tip link of a URDF, else None)."""

    dh: DHArm
    unit: str
    names: tuple[str, ...]
    angle_unit: str = "deg"
    source: str = ""
    base: np.ndarray | None = None
    tool: np.ndarray | None = None
    frames: tuple[str, str] | None = None

    def forward(self, q: np.ndarray) -> np.ndarray:
        """T_base_flange = base FK_DH(q) tool for joint vectors q (m, n) rad: (m, 4, 4)."""
        T = self.dh.forward(q)
        if self.base is not None:
            T = self.base @ T
        if self.tool is not None:
            T = T @ self.tool
        return T

    @property
    def joints(self) -> int:
        return self.dh.joints

    def in_unit(self, unit: str) -> ArmModel:
        """The same arm with its lengths in `unit` (``mm`` or ``m``)."""
        s = LENGTH_UNITS[unit] / LENGTH_UNITS[self.unit]

        def scaled(T: np.ndarray | None) -> np.ndarray | None:
            if T is None:
                return None
            T = np.array(T, dtype=float)
            T[:3, 3] /= s
            return T

        return dataclasses.replace(self, dh=self.dh.scaled(s), unit=unit, base=scaled(self.base),
                                   tool=scaled(self.tool))


def read_arm(path: str | Path) -> ArmModel:
    """The arm model of DH YAML file `path` (module docstring); InputError for anything else."""
    path = Path(path)
    where = f"arm file {str(path)!r}"
    check_not_looping(path, "arm file")
    if not path.is_file():
        raise InputError(f"{where} not found" + ("; it is a folder, name the YAML file" if path.is_dir() else ""))
    if path.suffix.lower() == ".urdf":
        from handeye.io.urdf_arm import read_urdf_arm

        return ArmModel(**read_urdf_arm(path))
    if path.stat().st_size > MAX_ARM_FILE_BYTES:
        raise InputError(f"{where} is {path.stat().st_size} bytes long; an arm file is a DH table of a few lines")
    try:
        data = load_yaml(path.read_text(encoding="utf-8-sig"), where)
    except UnicodeDecodeError:
        raise InputError(f"{where} is not text (UTF-8); an arm file is YAML") from None
    return arm_from_dict(data, where, source=str(path))


def arm_from_dict(data: Any, where: str = "arm", source: str = "") -> ArmModel:
    """The arm model of a mapping as the arm file holds it (module docstring)."""
    if not isinstance(data, dict):
        raise InputError(f"{where}: expected a mapping with keys convention, length_unit, angle_unit, joints (a "
                         f"standard DH table; docs/formats.md), got {shown(data)}")
    unknown = [k for k in data if k not in KEYS]
    if unknown:
        raise InputError(f"{where}: unknown key {str(unknown[0])!r}; the keys of an arm file are "
                         f"{', '.join(map(repr, KEYS))}")
    convention = data.get("convention")
    if convention not in CONVENTIONS:
        hint = (": modified (Craig) DH tables are not read yet" if isinstance(convention, str)
                and "modified" in convention.lower() else "")
        raise InputError(f"{where}: 'convention' must be standard-dh (joint j is Rz(q + offset) Tz(d) Tx(a) Rx(alpha)), "
                         f"got {shown(convention)}{hint}")
    for key, units in (("length_unit", LENGTH_UNITS), ("angle_unit", ANGLE_UNITS)):
        if not isinstance(data.get(key), str) or data[key] not in units:
            raise InputError(f"{where}: '{key}' must be one of {', '.join(units)} (the unit of "
                             f"{'a and d' if key == 'length_unit' else 'alpha and offset'}), got {shown(data.get(key))}")
    joints = data.get("joints")
    if not isinstance(joints, list) or len(joints) < 2:
        raise InputError(f"{where}: 'joints' must list at least 2 joints, base to flange, each a mapping of a, alpha, "
                         f"d, offset (and optionally name), got {shown(joints)}")
    angle = ANGLE_UNITS[data["angle_unit"]]
    rows, names = [], []
    for j, joint in enumerate(joints):
        at = f"{where}: joints[{j}]"
        if not isinstance(joint, dict):
            raise InputError(f"{at} must be a mapping of a, alpha, d, offset, got {shown(joint)}")
        odd = [k for k in joint if k not in JOINT_KEYS]
        missing = [k for k in JOINT_KEYS[1:] if k not in joint]
        if odd or missing:
            what = f"unknown key {str(odd[0])!r}" if odd else f"no {missing[0]!r}"
            raise InputError(f"{at} has {what}; a joint has {', '.join(JOINT_KEYS[1:])} (and optionally name)")
        values = []
        for key in JOINT_KEYS[1:]:
            v = number(joint[key])
            if v is None or not math.isfinite(v):
                raise InputError(f"{at}.{key} must be a finite number, got {shown(joint[key])}")
            values.append(v * angle if key in ("alpha", "offset") else v)
        rows.append(values)
        name = joint.get("name", f"J{j + 1}")
        if not isinstance(name, str) or not name.strip():
            raise InputError(f"{at}.name must be a non-empty text, got {shown(name)}")
        names.append(name.strip())
    if len(set(names)) < len(names):
        raise InputError(f"{where}: joint names repeat ({', '.join(names)}); name each joint once")
    base, tool = (_transform(data.get(key), f"{where}: '{key}'", angle) for key in ("base", "tool"))
    return ArmModel(DHArm.from_table(np.array(rows)), data["length_unit"], tuple(names), data["angle_unit"], source,
                    base=base, tool=tool)


def _transform(value: Any, where: str, angle: float) -> np.ndarray | None:
    """A ``{xyz: [3], rpy: [3]}`` mapping as a 4x4 (rpy in the unit `angle` rad, URDF's order)."""
    from scipy.spatial.transform import Rotation

    if value is None:
        return None
    if not isinstance(value, dict) or set(value) - {"xyz", "rpy"}:
        raise InputError(f"{where} must be a mapping of xyz (3 lengths) and rpy (3 angles), got {shown(value)}")
    T = np.eye(4)
    for key in ("xyz", "rpy"):
        v = value.get(key, [0, 0, 0])
        numbers = [number(x) for x in v] if isinstance(v, list) and len(v) == 3 else [None]
        if any(x is None or not math.isfinite(x) for x in numbers):
            raise InputError(f"{where}.{key} must be a list of 3 finite numbers, got {shown(v)}")
        if key == "xyz":
            T[:3, 3] = numbers
        else:
            T[:3, :3] = Rotation.from_euler("xyz", np.array(numbers) * angle).as_matrix()
    return T


def arm_yaml(arm: ArmModel, *, header: str = "", digits: int = 15) -> str:
    """The arm file's text of `arm` (module docstring), angles in its `angle_unit`, numbers with
    `digits` significant digits; `header`: comment lines put first (without ``#``)."""
    angle = ANGLE_UNITS[arm.angle_unit]

    def fmt(v: float) -> str:  # rounding below 1e-13 (of a metre, a degree) away: a conversion's dust
        text = f"{0.0 if abs(v) < 1e-13 else v:.{digits}g}"
        return "0" if text in ("0", "-0") else text

    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    lines += ["convention: standard-dh", f"length_unit: {arm.unit}", f"angle_unit: {arm.angle_unit}", "joints:"]
    for name, (a, alpha, d, offset) in zip(arm.names, arm.dh.table):
        shown_name = name if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name) else json.dumps(name)
        lines.append(f"  - {{name: {shown_name}, a: {fmt(a)}, alpha: {fmt(alpha / angle)}, d: {fmt(d)}, "
                     f"offset: {fmt(offset / angle)}}}")
    for key in ("base", "tool"):
        T = getattr(arm, key)
        if T is not None:
            from scipy.spatial.transform import Rotation

            rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz") / angle
            lines.append(f"{key}: {{xyz: [{', '.join(fmt(v) for v in T[:3, 3])}], "
                         f"rpy: [{', '.join(fmt(v) for v in rpy)}]}}")
    return "\n".join(lines) + "\n"


__all__ = ["ANGLE_UNITS", "ArmModel", "LENGTH_UNITS", "arm_from_dict", "arm_yaml", "read_arm"]
