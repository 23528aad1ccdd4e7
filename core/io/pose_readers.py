"""Reading the pose files robot cells produce (CSV/TSV/TXT, JSON, YAML, NPZ) into 4x4 pose stacks.

`read_poses(path, format, unit=...)` reads one stream of poses (the robot's flange poses, or the
camera's board poses) written in one of the representations of `handeye.io.pose_formats`
(``fanuc-wpr``, ``xyz-quat-xyzw``, ``matrix``, ...) and returns a `PoseStack`: the poses as a
read-only (n, 4, 4) float64 array, the length unit, and the index / name / time-stamp column
when the file has one. docs/formats.md ("Pose files of robots and cameras") is the reference.

The file's raw content (text table, JSON / YAML document, NPZ arrays) is read by
`handeye.io.pose_tables`; this module turns it into poses.

Why a module of its own: the files people have are vendor exports with headers such as
``index,x_mm,...,r_deg``, tab-aligned text, or JSON lists; turning them into validated poses
(columns by name or position, units stated, rotation blocks exported with few decimals
re-orthonormalised only when asked, one-line errors naming the line) is one job, separate from
`handeye.io`'s files of whole problems.

Numbers are read strictly: a text cell is a plain decimal number (ASCII digits, sign, point,
exponent; ``nan`` / ``inf`` are read and then refused as not finite), not everything Python's
float() takes (``1_000``, full-width ``１２３``); a JSON / YAML value must be a number, not text
(``"303.5"``) nor a bool; YAML is read by `handeye.io.input_files.load_yaml` (``1:30`` stays text,
duplicate keys and alias bombs are refused) and JSON by `handeye.io.input_files.load_json`
(duplicate keys refused). A pose is a row of numbers or a 4x4 / 3x4 matrix: other nestings and
NPZ shapes are refused, not flattened.

Nothing passed in is modified; every check raises `handeye.base.errors.InputError` with a one-line
message naming the file, the line (text) or pose (JSON / YAML / NPZ) and what to do.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from handeye.base.errors import InputError, shown
from handeye.base.moved import moved_names
from handeye.base.vocabulary import LENGTH_UNITS
from handeye.geometry.se3 import (
    ORTHONORMALITY_TOL,
    make_pose,
    orthonormality_error,
    project_to_so3,
)
from handeye.geometry.validation import (
    LAST_ROW_TOL,
    is_masked,
    masked_count,
    pose_stack,
)
from handeye.io.input_files import check_not_looping
from handeye.io.pose_formats import PoseFormat, normalise_header, parse_format
from handeye.io.pose_tables import (
    Table,
    check_pose_shape,
    load_structured,
    not_a_number,
    number,
    read_npz,
    read_text,
    structure,
)

Array = NDArray[np.float64]

#: names that moved to another module (`handeye.base.moved`)
__getattr__ = moved_names(__name__, {"write_poses": "handeye.io.pose_writers"})

#: accepted length units (the unit of every translation of the file, recorded in the result)
UNITS = LENGTH_UNITS
#: largest re-orthonormalisation accepted with orthonormalize=True: Frobenius norm |R - proj(R)|
#: for matrices, | |q| - 1 | for quaternions. Rounding to 3 decimals moves a rotation by ~1e-3;
#: more than 0.01 is not rounding but a wrong layout, unit or format.
MAX_CORRECTION = 0.01
#: file extensions and how they are read
TEXT_EXTENSIONS = (".csv", ".tsv", ".txt")
EXTENSIONS = (*TEXT_EXTENSIONS, ".json", ".yaml", ".yml", ".npz")
#: header names (after `normalise_header`) of an extra column kept as `PoseStack.names` / `.stamps`
NAME_COLUMNS = ("index", "idx", "i", "n", "no", "nr", "#", "id", "name", "label", "pose", "station", "point")
STAMP_COLUMNS = ("t", "time", "stamp", "timestamp", "time_stamp", "sec", "secs", "seconds")


@dataclasses.dataclass(frozen=True)
class PoseStack:
    """Poses read from a file.

    poses: (n, 4, 4) float64, read-only; translations in `unit`; rotation blocks in SO(3) to
        1e-6 (``handeye.geometry.se3.ORTHONORMALITY_TOL``), exactly (SVD projection) with orthonormalize=True,
        and always exact for angle, rotation-vector and quaternion formats.
    unit: ``"mm"`` or ``"m"``.
    format: the canonical format name (`handeye.io.pose_formats.PoseFormat.name`).
    names: the index / name column as text, one a pose, or None.
    stamps: the time-stamp column (n,) float64 read-only, or None.
    max_correction: with orthonormalize=True the largest change made to a rotation (Frobenius
        norm for matrices, | |q| - 1 | for quaternions, 0.0 for angle formats); None otherwise.
    source: the file read (for messages).
    """

    poses: Array
    unit: str
    format: str
    names: tuple[str, ...] | None = None
    stamps: Array | None = None
    max_correction: float | None = None
    source: str = ""

    def __len__(self) -> int:
        return len(self.poses)

    def in_unit(self, unit: str) -> PoseStack:
        """A copy with translations converted to `unit` (``"mm"`` or ``"m"``)."""
        check_unit(unit, self.source or "poses")
        scale = {"mm": 1e-3, "m": 1.0}[self.unit] / {"mm": 1e-3, "m": 1.0}[unit]
        T = np.array(self.poses)
        T[:, :3, 3] *= scale
        T.setflags(write=False)
        return dataclasses.replace(self, poses=T, unit=unit)


# ----------------------------------------------------------------------------- public API


def read_poses(path: str | Path, format: str | PoseFormat, *, unit: str | None = None,
               columns: Sequence[str | int] | None = None, layout: Sequence[str] | None = None,
               degrees: bool | None = None, orthonormalize: bool = False, delimiter: str | None = None) -> PoseStack:
    """Read a file of poses into a `PoseStack` (poses: (n, 4, 4)).

    format: a name of `handeye.io.pose_formats.format_names` (``"fanuc-wpr"``, ``"matrix"``,
        ``"euler:ZYX:deg"``, ...) or a `PoseFormat`.
    unit: ``"mm"`` or ``"m"``, the unit of the file's translations (kept, not converted; use
        `PoseStack.in_unit`). Default: the unit a JSON / YAML / NPZ file states (``units``), else
        the vendor's documented unit (FANUC, KUKA, ABB, Staubli, Yaskawa: mm; UR: m); generic
        formats (matrix, quaternion, rotation vector, euler, opencv-rvec) have none and need it.
    columns: the format's columns in format order, as header names (case-insensitive) or 0-based
        indices; default: found by header name, else by position.
    layout: the other way round: what each of the file's columns holds, in file order, as the
        format's field names (``("qw", "qx", "qy", "qz", "x", "y", "z")`` for a quaternion-first
        file read as ``xyz-quat-xyzw``), ``"t"`` for time stamps, ``"name"`` for names, ``"-"``
        for a column to skip (`file_layout`). Not with `columns`.
    degrees: override the format's angle unit (True: degrees, False: radians).
    orthonormalize: project matrix rotation blocks onto SO(3) (SVD) and normalise quaternions,
        reporting the largest correction; a correction above `MAX_CORRECTION` still raises.
    delimiter: for text files, ``","``, ``";"``, ``"\\t"`` or ``"whitespace"``; default sniffed
        from the first line (semicolon, else comma, else whitespace).
    """
    path = Path(path)
    fmt = parse_format(format)
    src = repr(str(path))
    ext = path.suffix.lower()
    if ext not in EXTENSIONS:
        raise InputError(f"{src}: unsupported pose file extension {ext or '(none)'!r}; supported: {', '.join(EXTENSIONS)}")
    check_not_looping(path, "pose file")
    if not path.is_file():
        raise InputError(f"pose file not found: {src}")
    if ext in TEXT_EXTENSIONS:
        table = read_text(path, src, delimiter)
    elif delimiter is not None:
        raise InputError(f"{src}: delimiter applies to text files ({', '.join(TEXT_EXTENSIONS)}); drop it")
    elif ext == ".npz":
        table = read_npz(path, src)
    else:
        table = structure(load_structured(path, src, ext), src)
    if layout is not None:
        if columns is not None:
            raise InputError(f"{src}: give columns (the format's fields in order) or layout (the file's columns in "
                             "order), not both")
        columns = file_layout(layout, fmt, _width(table), src)
    return _convert(table, fmt, src, unit=unit, columns=columns, degrees=degrees, orthonormalize=orthonormalize)


def file_layout(layout: Sequence[str], fmt: PoseFormat, width: int, src: str = "pose file") -> _Layout:
    """The columns of `fmt`'s fields, and of the stamps and names, from `layout`: the file's
    `width` columns in file order, each a field name of the format (or one of its header
    aliases), a time-stamp name (``t``, ``time``, ...), a name-column name (``name``, ``index``,
    ...) or ``-`` (skipped)."""
    if isinstance(layout, (str, bytes)) or len(layout) != width:
        raise InputError(f"{src}: the column layout names {len(layout) if not isinstance(layout, (str, bytes)) else 1} "
                         f"columns but the file has {width}; name every column in file order ({', '.join(fmt.fields)}, "
                         "t for time stamps, name, or - to skip one)")
    where: dict[str, int] = {}
    stamp = name = None
    for i, entry in enumerate(layout):
        key = normalise_header(str(entry))
        field = next((f for f in fmt.fields if key == f or key in fmt.aliases[f]), None)
        if field is not None:
            if field in where:
                raise InputError(f"{src}: the column layout names {field!r} twice")
            where[field] = i
        elif key in STAMP_COLUMNS and stamp is None:
            stamp = i
        elif key in NAME_COLUMNS and name is None:
            name = i
        elif str(entry).strip() not in ("-", "_"):
            raise InputError(f"{src}: column {i + 1} of the layout, {str(entry)!r}, is not a field of {fmt.name} "
                             f"({', '.join(fmt.fields)}), t, name or -")
    missing = [f for f in fmt.fields if f not in where]
    if missing:
        raise InputError(f"{src}: the column layout does not say where {', '.join(missing)} of {fmt.name} are")
    return _Layout(tuple(where[f] for f in fmt.fields), name, stamp)


@dataclasses.dataclass(frozen=True)
class _Layout:
    """Resolved columns: the format's fields (format order), the names and stamps columns."""

    fields: tuple[int, ...]
    name: int | None
    stamp: int | None


def _width(table: Table) -> int:
    return len(table.header) if table.header else len(table.rows[0])


def poses_from_rows(rows: ArrayLike, format: str | PoseFormat, *, unit: str | None = None,
                    degrees: bool | None = None, orthonormalize: bool = False, source: str = "rows") -> PoseStack:
    """`read_poses` on numbers in memory: rows (n, width) of `format` (or (n, 4, 4) / (n, 3, 4)
    matrices for ``matrix`` / ``matrix34``). `source` names the data in messages."""
    if is_masked(rows):  # np.asarray would keep the values under the mask
        raise InputError(f"{source}: a masked array with {masked_count(rows)}, and masks are not used; "
                         "remove the rows with masked entries and pass a plain array")
    arr = np.asarray(rows, dtype=object)
    check_pose_shape(arr.shape, source)
    table = Table(None, [list(r) for r in arr.reshape(len(arr), -1)], [f"pose {i + 1}" for i in range(len(arr))])
    return _convert(table, parse_format(format), source, unit=unit, columns=None, degrees=degrees,
                    orthonormalize=orthonormalize)


# --- a directory of one pose file per station (handeye calibrate --robot DIR; added with handeye.vision.image_set)


def natural_key(text: str) -> tuple:
    """Sort key that orders digit runs as numbers: ``2.yaml`` before ``10.yaml``."""
    return tuple((0, int(part), "") if part.isdigit() else (1, 0, part.lower())
                 for part in re.split(r"(\d+)", str(text)) if part)


def read_pose_dir(directory: str | Path, format: str | PoseFormat, *, unit: str | None = None,
                  orthonormalize: bool = False) -> PoseStack:
    """The poses of a directory holding one pose file per station (e.g. ROS-Industrial's
    ``poses/N.yaml``: x, y, z, qx, qy, qz, qw), each read with `read_poses`, in natural order of the
    file names (`natural_key`); names = the file stems."""
    folder = Path(directory)
    files = sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in EXTENSIONS),
                   key=lambda p: natural_key(p.name))
    if not files:
        raise InputError(f"no pose files in the folder {str(folder)!r} (looked for {', '.join(EXTENSIONS)})")
    stacks = [read_poses(p, format, unit=unit, orthonormalize=orthonormalize) for p in files]
    many = next(((p.name, len(s)) for p, s in zip(files, stacks) if len(s) != 1), None)
    if many:
        raise InputError(f"{str(folder)!r}: a folder of poses holds one pose per file, but {many[0]} holds "
                         f"{many[1]}; give that file instead of the folder")
    units = sorted({s.unit for s in stacks})
    if len(units) > 1:
        raise InputError(f"{str(folder)!r}: the pose files state different units {units}; use one unit")
    poses = np.concatenate([s.poses for s in stacks])
    poses.setflags(write=False)
    corrections = [s.max_correction for s in stacks if s.max_correction is not None]
    return PoseStack(poses, stacks[0].unit, stacks[0].format, tuple(p.stem for p in files), None,
                     max(corrections) if corrections else None, repr(str(folder)))


# --- end of the pose directory reader


# ----------------------------------------------------------------------------- conversion


def check_unit(unit: Any, src: str) -> None:
    """InputError naming `src` unless `unit` is one of `UNITS`."""
    if unit not in UNITS:
        raise InputError(f"{src}: unit must be one of {list(UNITS)}, got {unit!r}")


def _columns(table: Table, fmt: PoseFormat, columns: Sequence[str | int] | None,
             src: str) -> tuple[list[int], int | None, int | None]:
    """(indices of the format's fields, index of the names column, index of the stamps column)."""
    header, width = table.header, _width(table)
    norm = [normalise_header(h) for h in header] if header else None
    if isinstance(columns, _Layout):
        return list(columns.fields), columns.name, columns.stamp
    if columns is not None:
        if isinstance(columns, (str, bytes)) or len(columns) != fmt.width:
            raise InputError(f"{src}: columns must list the {fmt.width} columns of {fmt.name} "
                             f"({', '.join(fmt.fields)}) in that order, got {columns!r}")
        idx = []
        for c in columns:
            if isinstance(c, numbers.Integral) and not isinstance(c, bool):
                if not 0 <= c < width:
                    raise InputError(f"{src}: column index {c} is out of range; the file has {width} columns (0-based)")
                idx.append(int(c))
            elif isinstance(c, str) and norm is not None:
                hits = [i for i, (h, n) in enumerate(zip(header, norm)) if c.strip().lower() in (h.strip().lower(), n)]
                if not hits:
                    raise InputError(f"{src}: no column named {c!r}; the header has {', '.join(header)}")
                idx.append(hits[0])
            else:
                raise InputError(f"{src}: column {c!r}: give 0-based indices (the file has no header line) "
                                 "or names of header columns")
    elif norm is not None and any(n in fmt.aliases[f] for f in fmt.fields for n in norm):
        found = {f: next((i for i, n in enumerate(norm) if n in fmt.aliases[f]), None) for f in fmt.fields}
        missing = [f for f, i in found.items() if i is None]
        if missing:
            raise InputError(f"{src}: the header names some columns of {fmt.name} but not {', '.join(missing)} "
                             f"(header: {', '.join(header)}); pass columns=[...] to choose them")
        idx = list(found.values())
    elif width == fmt.width:
        idx = list(range(width))
    elif width == fmt.width + 1:
        idx = list(range(1, width))
    else:
        raise InputError(f"{src}: {width} columns, but format {fmt.name} has {fmt.width} numbers a pose "
                         f"({', '.join(fmt.fields)}), optionally after one index/name/time column; "
                         "check the format name, or pass columns=[...]")
    if len(set(idx)) != len(idx):
        raise InputError(f"{src}: a column is used twice for {fmt.name}: {idx}")
    rest = [i for i in range(width) if i not in idx]
    name_i = stamp_i = None
    for i in rest:
        label = norm[i] if norm else None
        if label in STAMP_COLUMNS and stamp_i is None:
            stamp_i = i
        elif (label in NAME_COLUMNS or label == "" or (norm is None and len(rest) == 1)) and name_i is None:
            name_i = i
    if norm is None and name_i is not None:  # headerless extra column: non-integer numbers are time stamps
        values = [number(r[name_i], table.text) for r in table.rows]
        if all(v is not None for v in values) and not all(v.is_integer() for v in values):
            name_i, stamp_i = None, name_i
    return idx, name_i, stamp_i


def _numbers(table: Table, idx: list[int], src: str) -> Array:
    out = np.empty((len(table.rows), len(idx)))
    names = table.header
    for r, (row, where) in enumerate(zip(table.rows, table.where)):
        for k, j in enumerate(idx):
            cell = row[j]
            col = f"column {j + 1}" + (f" ({names[j]})" if names else "")
            v = number(cell, table.text)
            if v is None:
                raise InputError(f"{src}: {where}, {col}: {not_a_number(cell)}")
            if not math.isfinite(v):
                raise InputError(f"{src}: {where}, {col}: {shown(cell)} is not finite; poses must not hold NaN or inf")
            out[r, k] = v
    return out


def _convert(table: Table, fmt: PoseFormat, src: str, *, unit: str | None, columns: Sequence[str | int] | None,
             degrees: bool | None, orthonormalize: bool) -> PoseStack:
    if table.unit is not None:
        check_unit(table.unit, f"{src}: units in the file")
    if unit is not None:
        check_unit(unit, src)
        if table.unit is not None and table.unit != unit:
            raise InputError(f"{src}: the file says units {table.unit!r} but unit={unit!r} was passed; drop one")
    unit = unit or table.unit or fmt.unit
    if unit is None:
        raise InputError(f"{src}: format {fmt.name} does not fix a length unit; pass unit='mm' or unit='m' (CLI --unit)")
    if degrees is not None and fmt.kind in ("matrix", "quat"):
        raise InputError(f"degrees applies to formats with angles, not to {fmt.name}; drop it")
    idx, name_i, stamp_i = _columns(table, fmt, columns, src)
    values = _numbers(table, idx, src)
    correction = 0.0 if orthonormalize else None
    if fmt.kind == "quat":  # before scipy, which refuses zero quaternions without saying where
        try:
            correction = _check_quaternions(fmt.quaternions(values), table.where, src, orthonormalize)
        except InputError as exc:
            raise InputError(f"{exc}{_quaternion_hint(table, fmt, idx)}") from None
    R, t, _ = fmt.to_rotations(values, degrees)
    if fmt.kind == "matrix":
        R, correction = _matrix_rotations(values, R, fmt, table.where, src, orthonormalize)
    poses = pose_stack(make_pose(R, t), src)
    names, stamps = table.names, table.stamps
    if name_i is not None:
        names = tuple(str(r[name_i]) for r in table.rows)
    if stamp_i is not None:
        stamps = _numbers(table, [stamp_i], src)[:, 0]
    if stamps is not None:
        stamps = np.array(stamps, dtype=float)
        stamps.setflags(write=False)
    return PoseStack(poses, unit, fmt.name, names, stamps, correction, src)


def _quaternion_hint(table: Table, fmt: PoseFormat, idx: list[int]) -> str:
    """Where else the file holds unit quaternions, when four consecutive columns other than the
    format's do (a quaternion-first file read as quaternion-last, say): the layout to give."""
    columns = []
    for j in range(_width(table)):
        values = [number(r[j], table.text) for r in table.rows]
        columns.append(None if any(v is None for v in values) else np.array(values, dtype=float))
    mine = sorted(idx[k] for k, f in enumerate(fmt.fields) if f.startswith("q"))
    for s in range(len(columns) - 3):
        window = columns[s:s + 4]
        if list(range(s, s + 4)) == mine or any(c is None for c in window):
            continue
        if np.all(np.abs(np.linalg.norm(np.stack(window, axis=1), axis=1) - 1.0) < 1e-6):
            rest = [c for c in ("x", "y", "z") if c in fmt.fields]
            example = ",".join(["qw", "qx", "qy", "qz"] + rest) if s == 0 else ",".join(rest + ["qx", "qy", "qz", "qw"])
            return (f"; columns {s + 1}-{s + 4} of the file hold unit quaternions: give the file's column layout, "
                    f"e.g. layout={example.split(',')} (CLI --robot-columns / --camera-columns {example}), "
                    "scalar first or last as the file has it")
    return ""


def _first(mask: np.ndarray, where: list[str]) -> str:
    i = int(np.flatnonzero(mask)[0])
    return f"pose {i + 1} ({where[i]})" if not where[i].startswith("pose") else where[i]


def _matrix_rotations(values: Array, R: Array, fmt: PoseFormat, where: list[str], src: str,
                      orthonormalize: bool) -> tuple[Array, float | None]:
    """The rotation blocks, checked (last row, reflection, orthonormality) and, when asked,
    projected onto SO(3); with the largest correction (Frobenius) or None."""
    if fmt.width == 16:
        bad = np.abs(values[:, 12:] - (0.0, 0.0, 0.0, 1.0)).max(axis=1) > LAST_ROW_TOL
        if bad.any():
            raise InputError(f"{src}: {_first(bad, where)}: last row is not 0 0 0 1; is the matrix row-major "
                             "(format matrix), or 3x4 (format matrix34)?")
    det = np.linalg.det(R)
    if (det <= 0).any():
        raise InputError(f"{src}: {_first(det <= 0, where)}: rotation block has det {det.min():.3g} <= 0 "
                         "(a reflection or a degenerate matrix); is the matrix transposed or the layout wrong?")
    err = orthonormality_error(R)
    if not orthonormalize:
        if err.max() > ORTHONORMALITY_TOL:
            raise InputError(f"{src}: rotation blocks are not orthonormal (largest |R^T R - I| = {err.max():.1e} "
                             f"> {ORTHONORMALITY_TOL:g}, first in {_first(err > ORTHONORMALITY_TOL, where)}); "
                             "re-orthonormalise with orthonormalize=True (CLI --orthonormalize)")
        return R, None
    P = project_to_so3(R)
    corr = np.linalg.norm(R - P, axis=(1, 2))
    if corr.max() > MAX_CORRECTION:
        raise InputError(f"{src}: re-orthonormalising would move a rotation by {corr.max():.2g} "
                         f"(Frobenius, in {_first(corr == corr.max(), where)}) > {MAX_CORRECTION:g}: that is not "
                         "rounding; check the format (row-major?), the columns and the units")
    return P, float(corr.max())


def _check_quaternions(q: Array, where: list[str], src: str, orthonormalize: bool) -> float | None:
    """Check quaternion norms (scipy normalises them); the largest | |q| - 1 | when orthonormalize."""
    norm = np.linalg.norm(q, axis=1)
    if (norm < 1e-9).any():
        raise InputError(f"{src}: {_first(norm < 1e-9, where)}: the quaternion is zero; it is no rotation")
    dev = np.abs(norm - 1.0)
    if not orthonormalize:
        if dev.max() > MAX_CORRECTION:  # not rounding: normalising would hide a wrong layout or format
            raise InputError(f"{src}: the quaternion columns do not hold unit quaternions (|q| = {norm[np.argmax(dev)]:.4g} "
                             f"in {_first(dev == dev.max(), where)}); check the format and the order of the columns")
        if dev.max() > ORTHONORMALITY_TOL:
            raise InputError(f"{src}: quaternions are not unit (largest ||q| - 1| = {dev.max():.1e} > "
                             f"{ORTHONORMALITY_TOL:g}, first in {_first(dev > ORTHONORMALITY_TOL, where)}); "
                             "normalise them with orthonormalize=True (CLI --orthonormalize)")
        return None
    if dev.max() > MAX_CORRECTION:
        raise InputError(f"{src}: normalising would change a quaternion's norm by {dev.max():.2g} (in "
                         f"{_first(dev == dev.max(), where)}) > {MAX_CORRECTION:g}: that is not rounding; check "
                         "the format (scalar first or last?) and the columns")
    return float(dev.max())
