"""Joint readings of a robot, one row per station: the input of a kinematic calibration (problem
``axyb-kinematic``) beside the camera's poses and the arm's DH table (`handeye.io.arm_files`).

`read_joints(path, unit)` reads

- a text table (.csv .tsv .txt; comma, semicolon, tab or whitespace separated) with a header:
  an optional name column (``name``, ``station``, ``index``, ...) and an optional time-stamp
  column (``t``, ``time``, ``stamp``, ...; seconds), as pose files have them, and one column per
  joint (any other header, e.g. ``J1 ... J6`` or a URDF's joint names), in `unit` (``deg`` or
  ``rad``; required, since a joint angle does not say which it is);
- a ROS bag's ``sensor_msgs/JointState`` topic (`handeye.io.bag_readers.read_bag_joints`):
  radians, the messages' header stamps, joints named by the messages.

`JointStack.ordered(names)` puts the joints in the arm's order when the file names them as the
arm file does. Errors are one-line `InputError`s naming the file, line and column.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from handeye.base.errors import InputError, shown
from handeye.base.vocabulary import RADIANS_PER
from handeye.io.input_files import check_not_looping

#: the angle units of joint readings and their size in radians
JOINT_UNITS = RADIANS_PER
#: joint readings in radians beyond this are degrees written as radians (no revolute joint turns
#: more than two turns either way)
MAX_RADIANS = 4.0 * math.pi
TEXT_EXTENSIONS = (".csv", ".tsv", ".txt")


@dataclasses.dataclass(frozen=True)
class JointStack:
    """Joint readings as read: q (m, n) rad read-only; joints: the n joint names (the header's, the
    messages'); names: per row the name column's text, or None; stamps: (m,) seconds, or None;
    unit: the file's angle unit; source: the file (for messages)."""

    q: np.ndarray
    joints: tuple[str, ...]
    names: tuple[str, ...] | None = None
    stamps: np.ndarray | None = None
    unit: str = "rad"
    source: str = ""

    def __len__(self) -> int:
        return len(self.q)

    def ordered(self, names: Sequence[str]) -> JointStack:
        """The readings with their joints in the order of `names` (the arm's): by name when the
        file names every one of them, else in file order when the counts agree; InputError
        otherwise."""
        names = tuple(names)
        if set(names) <= set(self.joints):
            q = np.array(self.q[:, [self.joints.index(n) for n in names]])
            q.setflags(write=False)
            return dataclasses.replace(self, q=q, joints=names)
        if len(self.joints) != len(names):
            raise InputError(f"{self.source}: {len(self.joints)} joint columns ({', '.join(self.joints)}) but the arm "
                             f"has {len(names)} joints ({', '.join(names)}); give one column per joint of the arm")
        return self


def read_joints(path: str | Path, unit: str | None = None, *, topic: str | None = None) -> JointStack:
    """The joint readings of `path` (module docstring): a text table in `unit` (``deg`` or
    ``rad``, required), or a ROS bag's JointState `topic` (radians: `unit` None or ``rad``)."""
    from handeye.io.bag_readers import is_bag, read_bag_joints

    if unit is not None and unit not in JOINT_UNITS:
        raise InputError(f"the joint unit must be deg or rad, got {shown(unit)}")
    path = Path(path)
    src = f"joint file {str(path)!r}"
    if is_bag(path):
        if topic is None:
            raise InputError(f"{src} is a ROS bag: name its sensor_msgs/JointState topic (e.g. /joint_states)")
        if unit not in (None, "rad"):
            raise InputError(f"{src} is a ROS bag, whose JointState messages hold radians; drop the unit {unit}")
        q, joints, stamps = read_bag_joints(path, topic)
        return JointStack(q, joints, None, stamps, "rad", f"{str(path)!r} {str(topic).strip()}")
    if topic is not None:
        raise InputError(f"a topic applies to ROS bags (.bag, .db3, .mcap, or a bag directory), and {src} is none")
    check_not_looping(path, "joint file")
    if not path.is_file():
        raise InputError(f"{src} not found" + ("; it is a folder, name the table" if path.is_dir() else ""))
    if path.suffix.lower() not in TEXT_EXTENSIONS:
        raise InputError(f"{src}: expected a text table ({', '.join(TEXT_EXTENSIONS)}) or a ROS bag, got "
                         f"{path.suffix or 'no extension'!r}")
    if unit is None:
        raise InputError(f"{src}: the unit of the joint readings is required (deg or rad): a joint angle does not "
                         "say which it is")
    return _read_table(path, src, unit)


def _read_table(path: Path, src: str, unit: str) -> JointStack:
    from handeye.io.pose_readers import NAME_COLUMNS, STAMP_COLUMNS
    from handeye.io.pose_tables import number, read_text

    table = read_text(path, src, None)
    if table.header is None:
        raise InputError(f"{src}: the first line must be a header naming each column (name or t, then one column "
                         "per joint, e.g. name,J1,J2,J3,J4,J5,J6)")
    header = [h.strip() for h in table.header]
    kinds = ["name" if h.lower() in NAME_COLUMNS else "t" if h.lower() in STAMP_COLUMNS else "joint" for h in header]
    for kind in ("name", "t"):
        if kinds.count(kind) > 1:
            twice = [h for h, k in zip(header, kinds) if k == kind]
            raise InputError(f"{src}: two {'name' if kind == 'name' else 'time-stamp'} columns ({', '.join(twice)}); "
                             "keep one")
    joint_cols = [i for i, k in enumerate(kinds) if k == "joint"]
    joints = tuple(header[i] for i in joint_cols)
    if len(joint_cols) < 2:
        raise InputError(f"{src}: {len(joint_cols)} joint column(s) in the header ({', '.join(header)}); give one "
                         "column per joint")
    if any(not h for h in joints) or len(set(joints)) < len(joints):
        raise InputError(f"{src}: every joint column needs its own name in the header, got {', '.join(header)}")
    q = np.empty((len(table.rows), len(joint_cols)))
    stamps = np.empty(len(table.rows)) if "t" in kinds else None
    for r, (row, where) in enumerate(zip(table.rows, table.where)):
        for c, i in enumerate(joint_cols):
            v = number(row[i], text=True)
            if v is None or not math.isfinite(v):
                raise InputError(f"{src} {where}, column {header[i]!r}: {shown(row[i])} is not a finite number")
            q[r, c] = v
        if stamps is not None:
            t = number(row[kinds.index("t")], text=True)
            if t is None or not math.isfinite(t):
                raise InputError(f"{src} {where}, column {header[kinds.index('t')]!r}: {shown(row[kinds.index('t')])} "
                                 "is not a time stamp in seconds")
            stamps[r] = t
    names = tuple(row[kinds.index("name")] for row in table.rows) if "name" in kinds else None
    if names is not None and len(set(names)) < len(names):
        repeated = sorted({n for n in names if names.count(n) > 1})
        raise InputError(f"{src}: station name {repeated[0]!r} repeats; name each station once")
    if unit == "rad" and np.abs(q).max() > MAX_RADIANS:
        r, c = np.unravel_index(np.argmax(np.abs(q)), q.shape)
        raise InputError(f"{src} {table.where[r]}, column {joints[c]!r}: {q[r, c]:g} rad is beyond any revolute joint "
                         "(the readings look like degrees): give the unit deg")
    q = q * JOINT_UNITS[unit]
    q.setflags(write=False)
    if stamps is not None:
        stamps.setflags(write=False)
    return JointStack(q, joints, names, stamps, unit, src)


__all__ = ["JOINT_UNITS", "JointStack", "read_joints"]


def write_joints(path: str | Path, q: np.ndarray, joints: Sequence[str], *, unit: str = "deg",
                 names: Sequence[str] | None = None, force: bool = False) -> Path:
    """Joint values q (m, n) rad as a table `read_joints` reads back (a name column when `names`
    are given, one column per joint named `joints`, in `unit`; floats in full)."""
    from handeye.io.output_files import write_text

    if unit not in JOINT_UNITS:
        raise InputError(f"joint unit must be one of {', '.join(JOINT_UNITS)}, got {unit!r}")
    q = np.asarray(q, dtype=float) / JOINT_UNITS[unit]
    header = (["name"] if names is not None else []) + list(joints)
    lines = [f"# joints in {unit}", ",".join(header)]
    for i, row in enumerate(q):
        lines.append(",".join(([str(names[i])] if names is not None else []) + [repr(float(v)) for v in row]))
    return write_text(path, "\n".join(lines) + "\n", force=force, flag="joints output")
