"""Pose representations of robot controllers and vision tools, and their conversion to 4x4 poses.

A *format* says what the numbers of one pose (one row of a file) are: a flattened matrix, a
translation + quaternion, a translation + rotation vector, or a translation + three angles of a
vendor's (or any scipy) Euler sequence. `parse_format` turns a format name (``"fanuc-wpr"``,
``"euler:ZYX:deg"``, ...) into a `PoseFormat`, which converts rows to rotations and translations
(`PoseFormat.to_rotations`) and back (`PoseFormat.to_rows`). Every rotation conversion goes through
`scipy.spatial.transform.Rotation` (no hand-written Euler code), so a vendor preset is nothing but
a scipy sequence, an angle unit and column names; docs/formats.md ("Pose files of robots and
cameras") states each preset's convention and the source it was checked against.

Why a table of formats: the conventions differ in one letter case (``'xyz'`` extrinsic vs
``'XYZ'`` intrinsic) and mixing them up gives rotations that look plausible and are wrong, so
each convention is written once, here, and tested against an explicit product of elementary
rotations (tests/io/test_pose_readers.py).

Reading files (CSV, JSON, YAML, NPZ), column selection, units and orthonormalisation live in
`handeye.io.pose_readers`.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from handeye.base.errors import InputError

Array = NDArray[np.float64]

#: accepted header spellings of the translation columns (after `normalise_header`)
_T_ALIASES = {
    "x": ("x", "tx", "px", "t_x", "pos_x", "position_x", "trans_x", "tvec_x"),
    "y": ("y", "ty", "py", "t_y", "pos_y", "position_y", "trans_y", "tvec_y"),
    "z": ("z", "tz", "pz", "t_z", "pos_z", "position_z", "trans_z", "tvec_z"),
}
_RV_ALIASES = {  # rotation-vector components
    "rx": ("rx", "r_x", "rot_x", "rvec_x", "ax"),
    "ry": ("ry", "r_y", "rot_y", "rvec_y", "ay"),
    "rz": ("rz", "r_z", "rot_z", "rvec_z", "az"),
}
_Q_ALIASES = {f"q{c}": (f"q{c}", f"q_{c}", f"quat_{c}", f"orientation_{c}") for c in "wxyz"}


@dataclasses.dataclass(frozen=True)
class PoseFormat:
    """One pose representation: its columns, and how they become a rotation and a translation.

    name: canonical name, as `parse_format` accepts it (``"kuka-abc"``, ``"euler:ZYX:deg"``).
    fields: column names of one pose, in file order (``("x", "y", "z", "a", "b", "c")``).
    aliases: field -> accepted header names (lower case, unit suffix removed).
    kind: ``"matrix"``, ``"quat"``, ``"rotvec"`` or ``"euler"``.
    seq: scipy Euler sequence (kind ``"euler"``): lower case extrinsic, upper case intrinsic.
    degrees: angle unit of the format (True / False), None where angles do not apply
        (matrix, quaternion) or where the name leaves it open (``euler:SEQ``: pass ``degrees``).
    unit: the length unit the format's vendor documents (``"mm"``, ``"m"``), None for generic
        formats whose files do not say (then the reader needs ``unit=``).
    scalar_first: quaternion order (kind ``"quat"``): (w, x, y, z) when True.
    rotation_first: the rotation columns precede the translation (OpenCV's rvec, tvec).
    """

    name: str
    fields: tuple[str, ...]
    aliases: dict[str, tuple[str, ...]]
    kind: str
    seq: str | None = None
    degrees: bool | None = None
    unit: str | None = None
    scalar_first: bool = False
    rotation_first: bool = False

    @property
    def width(self) -> int:
        """Numbers a pose: 16, 12, 7 or 6."""
        return len(self.fields)

    def _split(self, rows: Array) -> tuple[Array, Array]:
        """(rotation part, translation) columns of rows: (n, width)."""
        if self.kind == "matrix":
            M = rows.reshape(len(rows), -1, 4)
            return M[:, :3, :3], M[:, :3, 3]
        if self.rotation_first:
            return rows[:, :3], rows[:, 3:6]
        return rows[:, 3:], rows[:, :3]

    def quaternions(self, rows: ArrayLike) -> Array:
        """The quaternions of rows (n, width) of a quaternion format, as written, in (x, y, z, w)
        order (for checking their norms before conversion)."""
        rot, _ = self._split(np.asarray(rows, dtype=float))
        return rot[:, [1, 2, 3, 0]] if self.scalar_first else np.array(rot)

    def to_rotations(self, rows: ArrayLike, degrees: bool | None = None) -> tuple[Array, Array, Array | None]:
        """``(R, t, raw)`` of rows: (n, width): R (n, 3, 3) exact rotations (matrix formats:
        the rotation blocks as written, NOT projected), t (n, 3), and ``raw``: the rotation
        blocks as written (matrix), the quaternions as written (n, 4) in (x, y, z, w) order, or
        None for angle formats (always exact). `degrees` overrides the format's angle unit."""
        rows = np.asarray(rows, dtype=float)
        rot, t = self._split(rows)
        t = np.array(t)
        if self.kind == "matrix":
            return np.array(rot), t, np.array(rot)
        if self.kind == "quat":
            q = self.quaternions(rows)
            return Rotation.from_quat(q).as_matrix(), t, q
        deg = self._angle_unit(degrees)
        if self.kind == "rotvec":
            return Rotation.from_rotvec(rot, degrees=deg).as_matrix(), t, None
        return Rotation.from_euler(self.seq, rot, degrees=deg).as_matrix(), t, None

    def to_rows(self, poses: ArrayLike, degrees: bool | None = None) -> Array:
        """Rows (n, width) of poses (n, 4, 4) in this format (the inverse of `to_rotations`).
        Euler angles come back in scipy's canonical range; quaternions with w >= 0."""
        T = np.asarray(poses, dtype=float)
        if self.kind == "matrix":
            return T[:, : self.width // 4, :].reshape(len(T), -1).copy()
        rot = Rotation.from_matrix(T[:, :3, :3])
        if self.kind == "quat":
            q = rot.as_quat(canonical=True)
            r = q[:, [3, 0, 1, 2]] if self.scalar_first else q
        elif self.kind == "rotvec":
            r = rot.as_rotvec(degrees=self._angle_unit(degrees))
        else:
            r = rot.as_euler(self.seq, degrees=self._angle_unit(degrees))
        t = T[:, :3, 3]
        return np.hstack([r, t] if self.rotation_first else [t, r])

    def _angle_unit(self, degrees: bool | None) -> bool:
        if degrees is not None:
            return bool(degrees)
        if self.degrees is None:
            raise InputError(f"format {self.name!r} does not say its angle unit; write "
                             f"{self.name}:deg or {self.name}:rad, or pass degrees=True/False (CLI --degrees/--radians)")
        return self.degrees


def _preset(name: str, kind: str, rot_fields: dict[str, tuple[str, ...]], **kw) -> PoseFormat:
    first = kw.get("rotation_first", False)
    parts = [rot_fields, _T_ALIASES] if first else [_T_ALIASES, rot_fields]
    aliases = {k: v for part in parts for k, v in part.items()}
    return PoseFormat(name, tuple(aliases), aliases, kind, **kw)


def _angles(*names: str) -> dict[str, tuple[str, ...]]:
    return {n: (n,) for n in names}


def _matrix(rows: int) -> PoseFormat:
    fields = tuple(f"m{i}{j}" for i in range(rows) for j in range(4))
    aliases = {f: (f,) for f in fields}
    return PoseFormat("matrix" if rows == 4 else "matrix34", fields, aliases, "matrix")


#: the named formats (docs/formats.md, "Pose files of robots and cameras"); ``euler:SEQ[:deg|rad]``
#: is parsed by `parse_format`
PRESETS: dict[str, PoseFormat] = {f.name: f for f in (
    _matrix(4),
    _matrix(3),
    _preset("xyz-quat-wxyz", "quat", {k: _Q_ALIASES[k] for k in ("qw", "qx", "qy", "qz")}, scalar_first=True),
    _preset("xyz-quat-xyzw", "quat", {k: _Q_ALIASES[k] for k in ("qx", "qy", "qz", "qw")}),
    _preset("xyz-rotvec", "rotvec", _RV_ALIASES, degrees=False),
    # Universal Robots: p[x, y, z, rx, ry, rz], metres and radians (URScript)
    _preset("ur-rotvec", "rotvec", _RV_ALIASES, degrees=False, unit="m"),
    # FANUC: W, P, R about the fixed x, y, z axes: R = Rz(r) Ry(p) Rx(w)
    _preset("fanuc-wpr", "euler", _angles("w", "p", "r"), seq="xyz", degrees=True, unit="mm"),
    # KUKA: A, B, C about z, y', x'' (intrinsic): R = Rz(a) Ry(b) Rx(c)
    _preset("kuka-abc", "euler", _angles("a", "b", "c"), seq="ZYX", degrees=True, unit="mm"),
    # ABB RAPID orient: q1 (scalar), q2, q3, q4
    _preset("abb-quat", "quat", {f"q{i}": (f"q{i}",) for i in range(1, 5)}, scalar_first=True, unit="mm"),
    # Staubli: Rx, Ry', Rz'' (intrinsic): R = Rx(rx) Ry(ry) Rz(rz)
    _preset("staubli", "euler", _RV_ALIASES, seq="XYZ", degrees=True, unit="mm"),
    # Yaskawa / Motoman: Rx, Ry, Rz about the fixed axes, as FANUC's: R = Rz(rz) Ry(ry) Rx(rx)
    _preset("yaskawa", "euler", _RV_ALIASES, seq="xyz", degrees=True, unit="mm"),
    # OpenCV solvePnP: rvec then tvec, the board (object) pose in the camera, T_cam_target
    _preset("opencv-rvec", "rotvec", _RV_ALIASES, degrees=False, rotation_first=True),
)}

_EULER = re.compile(r"^euler:([xyzXYZ]{3})(?::(deg|rad))?$")


def format_names() -> list[str]:
    """The accepted format names, ``euler:SEQ[:deg|rad]`` last."""
    return [*PRESETS, "euler:SEQ[:deg|rad]"]


def parse_format(text: str | PoseFormat) -> PoseFormat:
    """The `PoseFormat` named `text` (case-insensitive for presets; ``euler:SEQ`` keeps the case
    of SEQ, which decides extrinsic (``xyz``) or intrinsic (``XYZ``)). A `PoseFormat` is returned
    as is. Raises InputError listing the known names."""
    if isinstance(text, PoseFormat):
        return text
    if not isinstance(text, str):
        raise InputError(f"format must be a string such as 'fanuc-wpr', got {type(text).__name__}")
    name = text.strip()
    if name.lower() in PRESETS:
        return PRESETS[name.lower()]
    m = _EULER.match(name)
    if name.lower().startswith("euler:") and m is None:
        raise InputError(f"format {text!r}: expected euler:SEQ or euler:SEQ:deg|rad with SEQ three of "
                         "x, y, z (lower case: extrinsic, fixed axes; upper case: intrinsic), e.g. euler:ZYX:deg")
    if m is None:
        raise InputError(f"unknown pose format {text!r}; known: {', '.join(format_names())}")
    seq, unit = m.groups()
    if not (seq.islower() or seq.isupper()):
        raise InputError(f"format {text!r}: SEQ {seq!r} mixes cases; all lower case (extrinsic) or all "
                         "upper case (intrinsic), as scipy's Rotation.from_euler")
    if seq[0] == seq[1] or seq[1] == seq[2]:
        raise InputError(f"format {text!r}: SEQ {seq!r} repeats an axis in a row; consecutive axes must differ")
    names = ("angle1", "angle2", "angle3")
    aliases = dict(_T_ALIASES)
    for i, (n, axis) in enumerate(zip(names, seq)):
        aliases[n] = (n, f"a{i + 1}") + ((f"r{axis.lower()}", f"rot_{axis.lower()}") if len(set(seq.lower())) == 3 else ())
    degrees = None if unit is None else unit == "deg"
    return PoseFormat(f"euler:{seq}" + (f":{unit}" if unit else ""), tuple(aliases), aliases, "euler",
                      seq=seq, degrees=degrees)


_UNIT_SUFFIX = re.compile(r"(?:[\s_]+|\s*[\[(])(?:mm|m|cm|deg|degs|degrees|rad|rads|radians|s|sec)[\])]?$")


def normalise_header(name: str) -> str:
    """A header cell as compared with field aliases: stripped, lower case, a unit suffix removed
    (``"X_mm"``, ``"w [deg]"``, ``"t (s)"`` -> ``"x"``, ``"w"``, ``"t"``)."""
    key = str(name).strip().strip('"').strip().lower()
    return _UNIT_SUFFIX.sub("", key) or key
