"""Reading and writing calibration data files (pose stacks, optional truth, metadata).

One file holds the data stacks of one problem (for ``axyb``: ``A``, ``B``, each (m, 4, 4),
with A_i X = Y B_i; for ``axxb``: the relative motions ``A``, ``B`` with A_i X = X B_i),
optionally the true unknowns (for simulated data) and a little metadata (``units``, ``setup``,
``pairing``, ``description``, ``source``, ``license``). docs/formats.md describes each format;
docs/conventions.md says what A, B, X, Y are.

Instead of its data fields, the file of a problem that declares a `StationReader` (``axyb``,
``axxb``: `station_readers`) may hold the absolute poses a robot cell records, one per station: ``robot_poses`` (T_base_flange)
and ``camera_poses`` (T_cam_target, the board pose solvePnP gives), with ``setup`` (and for
``axxb`` ``pairing``) in the file or passed to `load_file`. They are turned into the problem's
data fields on reading by the problem's reader (``axyb``: one pair per station; ``axxb``: the
motions, `handeye.problems.axxb.motions`), so one file of stations can be solved as AX=YB and as AX=XB; `PoseFile.poses` keeps them as read.

Formats are chosen by file extension through `FORMATS`: each entry is a reader
``(path) -> RawFile`` and a writer ``(binary file object, PoseFile) -> None`` (`save_data` opens
the file with `handeye.io.output_files.new_file`: written whole or not at all). A new format (CSV, YAML,
xyz + quaternion, Fanuc WPR, ...) is one reader (and optionally one writer) plus one line in
`FORMATS`; key checking, pose validation and error messages are shared (`_finish`).

Every problem in the file is validated only as far as a file can be: the expected keys are
present, nothing unexpected is there, every stack is a finite (m, 4, 4) array of rigid motions
(`handeye.geometry.validation.pose_stack`). The problem's own checks (lengths, degeneracy) run when the
data are solved. Files are not trusted: NPZ through `handeye.io.npz.load_npz` (size limits, no
pickles), JSON through `handeye.io.input_files.load_json` (duplicate keys refused), and a JSON pose
holds JSON numbers only (``"303.5"`` or ``true`` is refused, not converted).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from handeye.base.errors import HandEyeError, InputError, shown
from handeye.base.vocabulary import METRES_PER, SETUPS
from handeye.framework.problem_cell import StationReader
from handeye.geometry.motions import PAIRINGS
from handeye.geometry.validation import float_array, pose_stack
from handeye.host.registry import get_registry
from handeye.io.input_files import check_not_looping, load_json
from handeye.io.npz import load_npz
from handeye.io.output_files import new_file

#: metadata keys a file may carry (all optional, all strings)
METADATA_KEYS = ("units", "setup", "pairing", "description", "source", "license")
#: accepted values of the ``units`` metadata (length unit of every translation in the file)
UNITS = tuple(METRES_PER)
#: accepted values of the ``setup`` metadata (see docs/conventions.md)
#: the accepted values of the ``pairing`` metadata, which stations' absolute poses form a motion
#: (``consecutive``: station i with i + 1; ``all``: every i < j, as OpenCV's calibrateHandEye),
#: are `handeye.geometry.motions.PAIRINGS`; the pairing used for absolute poses when neither the
#: file nor the caller names one
DEFAULT_PAIRING = "all"
#: the absolute poses of the stations, the alternative to a problem's data fields (docs/formats.md):
#: robot_poses = T_base_flange, camera_poses = T_cam_target (the board pose solvePnP gives)
POSE_FIELDS = ("robot_poses", "camera_poses")


#: a file of absolute poses may carry the truth of the whole cell as the unknowns of AX=YB
#: (eye-in-hand: X = T_flange_cam, Y = T_base_target; eye-to-hand: X = T_flange_target,
#: Y = T_base_cam), whatever problem reads it
CELL_UNKNOWNS = ("X", "Y")


def station_readers() -> dict[str, StationReader]:
    """Problem name -> its `StationReader`, for every registered problem that reads absolute
    poses (``axyb``, ``axxb``, and any plugin problem that declares one)."""
    return {name: p.station_reader for name, p in get_registry().problems.items() if p.station_reader is not None}


#: suffix of truth keys in flat formats (NPZ): ``X_true``, ``Y_true``
TRUTH_SUFFIX = "_true"


@dataclasses.dataclass(frozen=True)
class PoseFile:
    """The content of a data file.

    data: data field -> (m, 4, 4) float64 (e.g. ``{"A": ..., "B": ...}``); for a file of
        absolute poses, the data fields made from them (``axyb``: one pair per station; ``axxb``:
        the m motions).
    truth: unknown -> (4, 4) float64, or None when the file has no truth.
    metadata: str -> str, a subset of `METADATA_KEYS`; for a file of absolute poses ``setup``
        (and for ``axxb`` ``pairing``) are the ones used (the caller's when given, else the
        file's, else the default pairing).
    poses: for a file of absolute poses, ``{"robot_poses": (n, 4, 4), "camera_poses": (n, 4, 4)}``
        as read (n stations); None for a file of data fields.
    """

    data: dict[str, np.ndarray]
    truth: dict[str, np.ndarray] | None
    metadata: dict[str, str]
    poses: dict[str, np.ndarray] | None = None


@dataclasses.dataclass(frozen=True)
class RawFile:
    """What a reader extracts before the shared checks: values as parsed, keys unchecked."""

    data: dict[str, Any]
    truth: dict[str, Any] | None
    metadata: dict[str, Any]
    #: keys the file held that the reader did not recognise (reported by `_finish`, unless they
    #: are data fields or absolute pose stacks: their values are in `data`, reported as bad values)
    unexpected: tuple[str, ...] = ()


# ----------------------------------------------------------------------------- public API


def load_data(path: str | Path, problem: str | None = None, *, setup: str | None = None,
              pairing: str | None = None) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None]:
    """Read a data file: ``(data, truth)``; truth is None when the file holds none.

    data: e.g. ``{"A": (m, 4, 4), "B": (m, 4, 4)}`` for problem ``"axyb"``;
    truth: e.g. ``{"X": (4, 4), "Y": (4, 4)}``.
    setup, pairing: for a file of absolute poses (``robot_poses``, ``camera_poses``), override
    the file's ``setup`` / ``pairing`` (pairing: ``axxb`` only); refused for a file of data fields.

    Raises InputError for a missing file, an unsupported extension (lists the supported ones),
    unparsable content, missing or unexpected keys, or poses that are not rigid motions.
    """
    pose_file = load_file(path, problem, setup=setup, pairing=pairing)
    return pose_file.data, pose_file.truth


def load_file(path: str | Path, problem: str | None = None, *, setup: str | None = None,
              pairing: str | None = None) -> PoseFile:
    """Like `load_data`, also returning the file's metadata (units, setup, ...) and, for a file
    of absolute poses, the poses as read (`PoseFile.poses`)."""
    path = Path(path)
    reader, _ = _format(path)
    check_not_looping(path, "data file")
    if not path.is_file():
        raise InputError(f"data file not found: {str(path)!r}")
    return _finish(reader(path), path, problem, setup=setup, pairing=pairing)


def save_data(path: str | Path, data: Mapping[str, Any], truth: Mapping[str, Any] | None = None, *,
              metadata: Mapping[str, str] | None = None, problem: str | None = None, force: bool = True) -> Path:
    """Write data (and optionally truth and metadata) in the format given by the extension.

    data: data field -> (m, 4, 4), or for a problem of `station_readers` the absolute poses
    ``{"robot_poses": (n, 4, 4), "camera_poses": (n, 4, 4)}`` (then metadata must name the
    ``setup``; for ``axxb`` ``pairing`` defaults to `DEFAULT_PAIRING`); truth: unknown -> (4, 4); metadata:
    keys of `METADATA_KEYS`. Everything is validated as `load_data` would, so a file written here
    always reads back (floats are written with full precision: the round trip is exact). The
    file appears complete or not at all (`handeye.io.output_files`); force=False refuses to replace
    an existing file (InputError), atomically. Returns the path written.
    """
    path = Path(path)
    _, writer = _format(path)
    raw = RawFile(dict(data), None if truth is None else dict(truth), dict(metadata or {}))
    pose_file = _finish(raw, path, problem, writing=True)
    with new_file(path, force=force, flag="-o", binary=True) as fh:
        writer(fh, pose_file)
    return path


def from_poses(robot_poses: Any, camera_poses: Any, problem: str | None = None, *, setup: str | None = None,
               pairing: str | None = None, truth: Mapping[str, Any] | None = None,
               metadata: Mapping[str, str] | None = None, source: str = "absolute poses") -> PoseFile:
    """A `PoseFile` of `problem` (one of `station_readers`) made from absolute poses, as reading a file
    holding them would make it: robot_poses (n, 4, 4) T_base_flange, camera_poses (n, 4, 4)
    T_cam_target; setup and pairing override the metadata's (setup is required in one of them).
    `source` names the data in error messages."""
    readers = station_readers()
    problem = problem or get_registry().default_problem()
    if problem not in readers:
        raise InputError(f"problem {problem!r} does not read absolute poses; problems that do: {sorted(readers)}")
    raw = RawFile({"robot_poses": robot_poses, "camera_poses": camera_poses},
                  None if truth is None else dict(truth), dict(metadata or {}))
    return _finish(raw, Path(source), problem, setup=setup, pairing=pairing)


def supported_extensions() -> list[str]:
    """File extensions with a reader, e.g. ``[".json", ".npz"]``."""
    return sorted(FORMATS)


# ----------------------------------------------------------------------------- shared checks


def _format(path: Path) -> tuple[Callable[[Path], RawFile], Callable[[BinaryIO, PoseFile], None]]:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(
            f"{str(path)!r}: unsupported file extension {ext or '(none)'!r}; supported: "
            f"{', '.join(supported_extensions())} (see docs/formats.md)"
        )
    return FORMATS[ext]


def _finish(raw: RawFile, path: Path, problem: str, writing: bool = False, *,
            setup: str | None = None, pairing: str | None = None) -> PoseFile:
    """Check keys against the problem's fields and unknowns, validate poses and metadata, and
    turn absolute poses into the problem's data fields."""
    problem = problem or get_registry().default_problem()
    spec = get_registry().problem(problem)
    fields, unknowns = tuple(spec.data_fields), tuple(spec.unknowns)
    where = f"{str(path)!r}"
    optional = [f for f in spec.optional_fields if f in raw.data]  # facts a file may carry (e.g. labels)
    unexpected = [k for k in raw.unexpected if k not in fields and k not in POSE_FIELDS and k not in optional]
    if unexpected:
        raise InputError(
            f"{where}: unexpected key(s) {sorted(unexpected)}; a {problem!r} file holds "
            f"{_key_listing(path, problem, fields, unknowns)}"
        )
    metadata = _metadata(raw.metadata, where)
    readers = station_readers()
    if any(f in raw.data for f in POSE_FIELDS) and problem in readers:
        data, poses, metadata = _from_poses(raw.data, metadata, where, problem, fields, setup, pairing)
    else:
        for name, value in (("setup", setup), ("pairing", pairing)):
            if value is not None:
                raise InputError(
                    f"{where}: {name} applies to a file of absolute poses ({', '.join(POSE_FIELDS)}), "
                    f"but this file holds the data fields {list(fields)}; drop the {name}"
                )
        missing = [f for f in fields if f not in raw.data]
        if missing:
            raise InputError(
                f"{where}: missing data key(s) {missing} for problem {problem!r}; found "
                f"{sorted(raw.data) or 'none'}; expected {_key_listing(path, problem, fields, unknowns)}"
            )
        extra = sorted(set(raw.data) - set(fields) - set(optional))
        if extra:
            hint = ""
            if set(extra) & set(POSE_FIELDS):
                hint = (f"; absolute poses ({', '.join(POSE_FIELDS)}) are read for problem(s) "
                        f"{sorted(readers)} only")
            raise InputError(f"{where}: unexpected data key(s) {extra}; problem {problem!r} has data {list(fields)}{hint}")
        data, poses = {f: _poses(raw.data[f], f, where) for f in fields}, None
        data.update({f: np.asarray(raw.data[f]) for f in optional})  # the problem's validation checks them

    truth = None
    if raw.truth is not None:
        if not isinstance(raw.truth, Mapping):
            raise InputError(f"{where}: truth must map unknown names {list(unknowns)} to 4x4 poses")
        cell = readers[problem].cell_truth if poses is not None else None
        if cell and set(raw.truth) == set(CELL_UNKNOWNS) and set(raw.truth) != set(unknowns):
            # the cell's truth (AX=YB's X, Y) in a file of stations: this problem's unknowns from it
            _poses(raw.truth[CELL_UNKNOWNS[0]], "truth X", where, single=True)  # validate both
            _poses(raw.truth[CELL_UNKNOWNS[1]], "truth Y", where, single=True)
            raw = dataclasses.replace(raw, truth={u: raw.truth[c] for u, c in cell[metadata["setup"]].items()})
        missing = [u for u in unknowns if u not in raw.truth]
        extra = sorted(set(raw.truth) - set(unknowns))
        if missing or extra:
            raise InputError(
                f"{where}: truth must hold exactly the unknowns {list(unknowns)} of problem "
                f"{problem!r}; missing {missing}, unexpected {extra}"
            )
        truth = {u: _truth_pose(raw.truth[u], f"truth {u}", where) for u in unknowns}
    return PoseFile(data, truth, metadata, poses)


def _metadata(raw: Mapping[str, Any], where: str) -> dict[str, str]:
    """The metadata, checked: known keys, string values, allowed units / setup / pairing."""
    metadata = {}
    for key, value in raw.items():
        if key not in METADATA_KEYS:
            raise InputError(f"{where}: unknown metadata key {key!r}; known: {list(METADATA_KEYS)}")
        if not isinstance(value, str):
            raise InputError(f"{where}: metadata {key!r} must be a string, got {shown(value)}")
        metadata[key] = value
    for key, allowed in (("units", UNITS), ("setup", SETUPS), ("pairing", PAIRINGS)):
        if key in metadata and metadata[key] not in allowed:
            raise InputError(f"{where}: {key} must be one of {list(allowed)}, got {metadata[key]!r}")
    return metadata


def _from_poses(values: Mapping[str, Any], metadata: dict[str, str], where: str, problem: str,
                fields: tuple[str, ...], setup: str | None, pairing: str | None,
                ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, str]]:
    """(data fields, absolute poses, metadata with the setup and pairing used) of a file of
    absolute poses of problem `problem` (one of `station_readers`)."""
    both = [f for f in fields if f in values]
    if both:
        raise InputError(
            f"{where}: the file holds both data field(s) {both} and absolute poses "
            f"({', '.join(f for f in POSE_FIELDS if f in values)}); keep one or the other"
        )
    missing = [f for f in POSE_FIELDS if f not in values]
    if missing:
        raise InputError(
            f"{where}: absolute poses need both {' and '.join(POSE_FIELDS)}; missing {missing}"
        )
    extra = sorted(set(values) - set(POSE_FIELDS))
    if extra:
        raise InputError(f"{where}: unexpected data key(s) {extra} beside the absolute poses {list(POSE_FIELDS)}")
    readers = station_readers()
    conversion = readers[problem]
    for name, value, allowed in (("setup", setup, SETUPS), ("pairing", pairing, PAIRINGS)):
        if value is not None and value not in allowed:
            raise InputError(f"{name} must be one of {list(allowed)}, got {value!r}")
    if pairing is not None and not conversion.pairing:
        raise InputError(f"pairing applies to problems that form motions between stations "
                         f"({sorted(p for p, c in readers.items() if c.pairing)}), not to {problem!r}, "
                         "where every station is one pair; drop it")
    setup = setup or metadata.get("setup")
    if setup is None:
        raise InputError(
            f"{where}: absolute poses need the setup ({' or '.join(SETUPS)}), which decides what "
            "X is (docs/conventions.md); put \"setup\" in the file or pass it (handeye solve --setup)"
        )
    if conversion.pairing:
        pairing = pairing or metadata.get("pairing") or DEFAULT_PAIRING
        metadata = {**metadata, "pairing": pairing}
    poses = {f: _poses(values[f], f, where) for f in POSE_FIELDS}
    try:
        data = conversion.convert(poses["robot_poses"], poses["camera_poses"], setup=setup, pairing=pairing)
    except HandEyeError as exc:
        raise type(exc)(f"{where}: {exc}") from None
    data = {f: np.array(data[f]) for f in fields}
    return data, poses, {**metadata, "setup": setup}


def _poses(value: Any, name: str, where: str, single: bool = False) -> np.ndarray:
    """Validated writable float64 copy: (m, 4, 4), or (4, 4) when `single`."""
    if single:
        value = _as_float(value, name, where)
        if value.shape != (4, 4):
            raise InputError(f"{where}: expected {name} to be one 4x4 pose, got shape {value.shape}")
        value = value[None]
    try:
        stack = pose_stack(value, name)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    return np.array(stack[0] if single else stack)


def _truth_pose(value: Any, name: str, where: str) -> np.ndarray:
    """The truth of one unknown, validated: a 4x4 pose, or a (k, 4, 4) stack of poses for an
    unknown that is one (`Problem.stack_sizes`)."""
    array = _as_float(value, name, where)
    return _poses(array, name, where) if array.ndim == 3 else _poses(array, name, where, single=True)


def _as_float(value: Any, name: str, where: str) -> np.ndarray:
    try:
        return float_array(value, name, "a 4x4 array of numbers")
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _key_listing(path: Path, problem: str, fields: tuple[str, ...], unknowns: tuple[str, ...]) -> str:
    alternative = ""
    readers = station_readers()
    if problem in readers:
        alternative = (f" (or the absolute poses {', '.join(POSE_FIELDS)} with setup"
                       + (" and pairing)" if readers[problem].pairing else ")"))
    if path.suffix.lower() == ".npz":
        truth = ", ".join(u + TRUTH_SUFFIX for u in unknowns)
        return f"arrays {', '.join(fields)}{alternative}; optionally {truth} and {', '.join(METADATA_KEYS)}"
    return (f"keys {', '.join(repr(f) for f in fields)}{alternative}; optionally 'truth' "
            f"({{{', '.join(repr(u) for u in unknowns)}}}) and {', '.join(repr(k) for k in METADATA_KEYS)}")


# ----------------------------------------------------------------------------- NPZ


def _read_npz(path: Path) -> RawFile:
    """NPZ: one array per data field (``A``, ``B``) or absolute pose stack (``robot_poses``,
    ``camera_poses``), ``<unknown>_true`` (``X_true``), and 0-d string arrays for metadata. Object arrays are refused (no pickle)."""
    arrays = load_npz(path, repr(str(path)))
    data, truth, metadata, unexpected = {}, {}, {}, []
    for key, value in arrays.items():
        if key.endswith(TRUTH_SUFFIX):
            truth[key[: -len(TRUTH_SUFFIX)]] = value
        elif key in METADATA_KEYS:
            metadata[key] = str(value) if value.ndim == 0 and value.dtype.kind in "US" else value
        else:
            data[key] = value
            if value.dtype.kind in "US":  # reported as a bad value if a data field, else as unexpected
                unexpected.append(key)
    return RawFile(data, truth or None, metadata, tuple(unexpected))


def _write_npz(fh: BinaryIO, pose_file: PoseFile) -> None:
    arrays: dict[str, np.ndarray] = dict(pose_file.poses if pose_file.poses is not None else pose_file.data)
    for name, T in (pose_file.truth or {}).items():
        arrays[name + TRUTH_SUFFIX] = T
    for key, value in pose_file.metadata.items():
        arrays[key] = np.array(value)
    np.savez(fh, **arrays)  # a file object: np.savez would append .npz to other names


# ----------------------------------------------------------------------------- JSON


def _read_json(path: Path) -> RawFile:
    """JSON object: ``{"A": [4x4, ...], "B": [...], "truth": {"X": 4x4, "Y": 4x4}, "units": "m",
    "setup": "eye-in-hand", ...}``; 4x4 poses are row-major nested lists."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{str(path)!r}: not UTF-8 text ({exc})") from None
    obj = load_json(text, repr(str(path)))
    if not isinstance(obj, dict):
        raise InputError(f"{str(path)!r}: expected a JSON object with keys such as 'A' and 'B', got {type(obj).__name__}")
    truth = obj.pop("truth", None)
    metadata = {k: obj.pop(k) for k in METADATA_KEYS if k in obj}
    for key, value in obj.items():
        _json_numbers(value, key, repr(str(path)))
    if isinstance(truth, dict):
        for key, value in truth.items():
            _json_numbers(value, f"truth {key}", repr(str(path)))
    # every other key is data; one whose value is not a list is unexpected unless it names a data
    # field (then `_finish` reports its value, e.g. "A": null, as bad)
    unexpected = tuple(k for k, v in obj.items() if not isinstance(v, list))
    return RawFile(obj, truth, metadata, unexpected)


def _json_numbers(value: Any, name: str, where: str) -> None:
    """InputError at the first entry of the nested lists `value` (a JSON pose stack or pose) that is
    text or a bool: np.array(..., dtype=float) would take "303.5" and true as numbers. Values that
    are not lists (``"A": null``) are left to the shared checks, which say what a value must be."""
    if not isinstance(value, list):
        return
    if set(map(type, np.array(value, dtype=object).ravel())) <= {int, float}:
        return  # the usual case, checked at C speed: a regular nest of JSON numbers
    stack: list[tuple[list, int, tuple[int, ...]]] = [(value, 0, ())]
    while stack:  # in document order, without recursion (json reads any depth its parser can)
        items, start, at = stack.pop()
        for i in range(start, len(items)):
            item = items[i]
            if isinstance(item, list):
                stack += [(items, i + 1, at), (item, 0, (*at, i))]
                break
            if isinstance(item, (str, bool)):
                index = "".join(f"[{k}]" for k in (*at, i))
                written = json.dumps(item)  # as the file spells it: true, "303.5"
                written = written if len(written) <= 60 else written[:57] + "..."
                raise InputError(f"{where}: {name}{index} is {written}, not a number{_quoted_hint(item)}")


def _quoted_hint(item: Any) -> str:
    """A hint for a JSON string that holds a number (``"303.5"``)."""
    try:
        float(item)
    except (TypeError, ValueError):
        return ""
    return "; write numbers without quotes" if isinstance(item, str) else ""


def _write_json(fh: BinaryIO, pose_file: PoseFile) -> None:
    """One pose per line; floats as Python's shortest round-trip repr (exact read-back)."""

    def pose(T: np.ndarray) -> str:
        return json.dumps(np.asarray(T, dtype=float).tolist())

    parts = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in pose_file.metadata.items()]
    stacks = pose_file.poses if pose_file.poses is not None else pose_file.data
    for name, stack in stacks.items():
        if np.ndim(stack) != 3:  # a fact the problem's data carry besides its stacks (labels, a length)
            parts.append(f"  {json.dumps(name)}: {json.dumps(np.asarray(stack).tolist())}")
            continue
        rows = ",\n".join("    " + pose(T) for T in stack)
        parts.append(f"  {json.dumps(name)}: [\n{rows}\n  ]")
    if pose_file.truth is not None:
        rows = ",\n".join(f"    {json.dumps(k)}: {pose(T)}" for k, T in pose_file.truth.items())
        parts.append(f'  "truth": {{\n{rows}\n  }}')
    fh.write(("{\n" + ",\n".join(parts) + "\n}\n").encode("utf-8"))


#: extension -> (reader, writer). Add a format here (one line) after writing its two functions.
FORMATS: dict[str, tuple[Callable[[Path], RawFile], Callable[[BinaryIO, PoseFile], None]]] = {
    ".npz": (_read_npz, _write_npz),
    ".json": (_read_json, _write_json),
}
