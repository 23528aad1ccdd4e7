"""The raw content of a pose file before its poses are made (`Table`): text tables (CSV, TSV,
whitespace), JSON and YAML documents, NPZ arrays; numbers read strictly (`number`). The first
half of `handeye.io.pose_readers`, which turns a table into poses."""

from __future__ import annotations

import dataclasses
import math
import numbers
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError, shown
from handeye.io.input_files import TEXT_NUMBER, load_json, load_yaml
from handeye.io.npz import load_npz

#: the key of the pose list in a JSON / YAML object or an NPZ of several arrays
POSES_KEY = "poses"
#: the delimiters a text table may use, by name
DELIMITERS = {",": ",", ";": ";", "\t": "\t", "tab": "\t", " ": None, "whitespace": None}
#: the matrix shapes a pose may be written as
MATRIX_SHAPES = ((4, 4), (3, 4))


@dataclasses.dataclass
class Table:
    """A file's content before conversion: header (or None), rows of cells, row locations."""

    header: tuple[str, ...] | None
    rows: list[list[Any]]
    where: list[str]
    unit: str | None = None
    names: tuple[str, ...] | None = None
    stamps: Any = None
    #: cells are the strings of a text file (parsed by `TEXT_NUMBER`), not typed values
    text: bool = False


def number(cell: Any, text: bool) -> float | None:
    """`cell` as a float, or None when it is not a number: a string of a text file (`text`) must
    match `TEXT_NUMBER`; a typed value (JSON / YAML / NPZ / memory) must be a real number, not a
    bool and not text."""
    if text and isinstance(cell, str):
        return float(cell) if TEXT_NUMBER.fullmatch(cell) else None
    if isinstance(cell, (bool, np.bool_)) or not isinstance(cell, numbers.Real):
        return None
    try:
        return float(cell)
    except OverflowError:  # an integer of hundreds of digits: refused as not finite
        return math.inf if cell > 0 else -math.inf


def looks_numeric(cell: Any) -> bool:
    """A number, or text that is one (a JSON "1.5", refused later with a hint, not taken as a header)."""
    return number(cell, text=isinstance(cell, str)) is not None


def not_a_number(cell: Any) -> str:
    """Why `cell` is no number, with a hint when it is one written the wrong way."""
    if isinstance(cell, str) and TEXT_NUMBER.fullmatch(cell.strip()):
        return f"{shown(cell)} is text, not a number; write numbers without quotes"
    try:
        float(cell)
    except (TypeError, ValueError, OverflowError):
        return f"{shown(cell)} is not a number"
    if isinstance(cell, str):  # Python's float() takes it: 1_000, full-width digits, ...
        return (f"{shown(cell)} is not a number as written: use ASCII digits 0-9 with an optional sign, decimal "
                "point and exponent, without digit separators")
    return f"{shown(cell)} is not a number"


def read_text(path: Path, src: str, delimiter: str | None) -> Table:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{src}: not a UTF-8 text file ({exc.reason} at byte {exc.start}); export it as CSV text") from None
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{src}: no poses (the file is empty or holds only comments)")
    if delimiter is not None and delimiter not in DELIMITERS:
        raise InputError(f"delimiter must be one of {list(DELIMITERS)}, got {delimiter!r}")
    first = lines[0][1]
    sep = DELIMITERS[delimiter] if delimiter is not None else (";" if ";" in first else "," if "," in first else None)
    cells = [[c.strip() for c in line.split(sep)] if sep else line.split() for _, line in lines]
    header = None
    if not any(looks_numeric(c) for c in cells[0]):
        header = tuple(cells[0])
        cells, lines = cells[1:], lines[1:]
        if not cells:
            raise InputError(f"{src}: a header line ({', '.join(header)}) but no poses; "
                             "if that line is a pose, check the delimiter (delimiter=...)")
    width = len(header) if header else len(cells[0])
    for (n, _), row in zip(lines, cells):
        if len(row) != width:
            what = "the header has" if header else f"line {lines[0][0]} has"
            raise InputError(f"{src}: line {n} has {len(row)} cells, {what} {width}; "
                             "check the delimiter (delimiter=...) and missing values")
    return Table(header, cells, [f"line {n}" for n, _ in lines], text=True)


def yaml_module():
    try:
        import yaml
    except ImportError:  # pragma: no cover - PyYAML is a dependency
        raise InputError("reading YAML pose files needs PyYAML: pip install pyyaml") from None
    return yaml


def load_structured(path: Path, src: str, ext: str) -> Any:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{src}: not UTF-8 text ({exc.reason} at byte {exc.start}); "
                         f"a {ext} pose file is text") from None
    if not text.strip():
        raise InputError(f"{src}: no poses (the file is empty)")
    return load_json(text, src) if ext == ".json" else load_yaml(text, src)


def pose_row(value: list | tuple, where: str, src: str) -> list[Any]:
    """The numbers of one pose of a JSON / YAML list: a row as is, a 4x4 / 3x4 matrix (a list of
    rows of 4) flattened row by row; any other nesting is refused, not flattened."""
    if not any(isinstance(v, (list, tuple)) for v in value):
        return list(value)
    shape = (len(value), len(value[0])) if all(isinstance(v, (list, tuple)) for v in value) else None
    if (shape in MATRIX_SHAPES and all(len(v) == shape[1] for v in value)
            and not any(isinstance(x, (list, tuple)) for v in value for x in v)):
        return [x for v in value for x in v]
    raise InputError(f"{src}: {where} is a list of lists that is not a 4x4 or 3x4 matrix; a pose is a row of "
                     "numbers or a matrix of 4 (or 3) rows of 4 numbers")


def structure(obj: Any, src: str) -> Table:
    """A JSON / YAML document: a list of rows, of 4x4 (3x4) matrices, or of objects (keys as
    header), or an object holding such a list under `POSES_KEY` (and optionally ``units``)."""
    unit = None
    if (isinstance(obj, dict) and POSES_KEY not in obj and any(looks_numeric(v) for v in obj.values())
            and not any(isinstance(v, (dict, list)) for v in obj.values())):
        obj = [obj]  # one pose as an object of numbers (ROS-Industrial's poses/N.yaml: x, y, z, qx, ...)
    if isinstance(obj, dict):
        if POSES_KEY not in obj:
            raise InputError(f"{src}: an object must hold the pose list under the key {POSES_KEY!r}; "
                             f"found keys {sorted(map(str, obj))}")
        unit = obj.get("units", obj.get("unit"))
        obj = obj[POSES_KEY]
    if not isinstance(obj, list):
        raise InputError(f"{src}: expected a list of poses (rows, matrices or objects), got {type(obj).__name__}")
    if not obj:
        raise InputError(f"{src}: no poses (the pose list is empty)")
    where = [f"pose {i + 1}" for i in range(len(obj))]
    if all(isinstance(r, dict) for r in obj):
        header = tuple(str(k) for k in obj[0])
        for w, r in zip(where, obj):
            if tuple(str(k) for k in r) != header:
                raise InputError(f"{src}: {w} has keys {list(map(str, r))}, pose 1 has {list(header)}; "
                                 "every pose needs the same keys")
        return Table(header, [list(r.values()) for r in obj], where, unit=unit)
    rows = []
    for w, r in zip(where, obj):
        if not isinstance(r, (list, tuple)):
            raise InputError(f"{src}: {w} is {shown(r)}, expected a list of numbers or a matrix")
        rows.append(pose_row(r, w, src))
    width = len(rows[0])
    for w, r in zip(where, rows):
        if len(r) != width:
            raise InputError(f"{src}: {w} has {len(r)} numbers, pose 1 has {width}; every pose needs the same")
    return Table(None, rows, where, unit=unit)


def read_npz(path: Path, src: str) -> Table:
    arrays = load_npz(path, src)
    if POSES_KEY in arrays:
        rows = arrays[POSES_KEY]
    elif len(arrays) == 1:
        rows = next(iter(arrays.values()))
    else:
        raise InputError(f"{src}: an NPZ of several arrays must hold the poses under {POSES_KEY!r}; found {sorted(arrays)}")
    check_pose_shape(rows.shape, src)
    if rows.dtype.kind not in "iuf":
        raise InputError(f"{src}: the pose array holds {rows.dtype} values, expected numbers")
    unit = names = stamps = None
    if "units" in arrays:
        if arrays["units"].size != 1:
            raise InputError(f"{src}: 'units' must be one string, 'mm' or 'm'; got {shown(arrays['units'].tolist())}")
        unit = str(arrays["units"].item())
    if "names" in arrays:
        if arrays["names"].ndim != 1:
            raise InputError(f"{src}: 'names' must be a 1-D array of one name per pose, got shape {arrays['names'].shape}")
        names = tuple(str(s) for s in arrays["names"])
    if "stamps" in arrays:
        value = arrays["stamps"]
        if value.ndim != 1 or value.dtype.kind not in "biuf" or not np.all(np.isfinite(value)):
            raise InputError(f"{src}: 'stamps' must be a 1-D array of finite numbers (seconds), one per pose")
        stamps = value
    for key, value in (("names", names), ("stamps", stamps)):
        if value is not None and len(value) != len(rows):
            raise InputError(f"{src}: {key!r} has {len(value)} entries for {len(rows)} poses")
    return Table(None, rows.reshape(len(rows), -1).tolist(), [f"pose {i + 1}" for i in range(len(rows))],
                  unit=unit, names=names, stamps=stamps)


def check_pose_shape(shape: tuple[int, ...], src: str) -> None:
    """InputError unless `shape` is rows (n, k) or matrices (n, 4, 4) / (n, 3, 4), n >= 1: other
    shapes, e.g. (n, 2, 3), would fit a format only by flattening, which guesses the layout."""
    if len(shape) == 2 and shape[0] > 0 or len(shape) == 3 and shape[0] > 0 and shape[1:] in MATRIX_SHAPES:
        return
    raise InputError(f"{src}: poses of shape {shape}; expected rows (n, k) of the format's numbers or matrices "
                     "(n, 4, 4) / (n, 3, 4); other shapes are not flattened: reshape the array to one of these")
