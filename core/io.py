"""Reading and writing calibration data files (pose stacks, optional truth, metadata).

One file holds the data stacks of one problem (for ``axyb``: ``A``, ``B``, each (m, 4, 4),
with A_i X = Y B_i), optionally the true unknowns (for simulated data) and a little metadata
(``units``, ``setup``, ``description``, ``source``, ``license``). docs/formats.md describes
each format; docs/conventions.md says what A, B, X, Y are.

Formats are chosen by file extension through `FORMATS`: each entry is a reader
``(path) -> RawFile`` and a writer ``(path, PoseFile) -> None``. A new format (CSV, YAML,
xyz + quaternion, Fanuc WPR, ...) is one reader (and optionally one writer) plus one line in
`FORMATS`; key checking, pose validation and error messages are shared (`_finish`).

Every problem in the file is validated only as far as a file can be: the expected keys are
present, nothing unexpected is there, every stack is a finite (m, 4, 4) array of rigid motions
(`handeye.validation.pose_stack`). The problem's own checks (lengths, degeneracy) run when the
data are solved.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .registry import get_registry
from .validation import pose_stack

#: metadata keys a file may carry (all optional, all strings)
METADATA_KEYS = ("units", "setup", "description", "source", "license")
#: accepted values of the ``units`` metadata (length unit of every translation in the file)
UNITS = ("m", "cm", "mm")
#: accepted values of the ``setup`` metadata (see docs/conventions.md)
SETUPS = ("eye-in-hand", "eye-to-hand")
#: suffix of truth keys in flat formats (NPZ): ``X_true``, ``Y_true``
TRUTH_SUFFIX = "_true"


@dataclasses.dataclass(frozen=True)
class PoseFile:
    """The content of a data file.

    data: data field -> (m, 4, 4) float64 (e.g. ``{"A": ..., "B": ...}``).
    truth: unknown -> (4, 4) float64, or None when the file has no truth.
    metadata: str -> str, a subset of `METADATA_KEYS`.
    """

    data: dict[str, np.ndarray]
    truth: dict[str, np.ndarray] | None
    metadata: dict[str, str]


@dataclasses.dataclass(frozen=True)
class RawFile:
    """What a reader extracts before the shared checks: values as parsed, keys unchecked."""

    data: dict[str, Any]
    truth: dict[str, Any] | None
    metadata: dict[str, Any]
    #: keys the file held that the reader did not recognise (reported by `_finish`)
    unexpected: tuple[str, ...] = ()


# ----------------------------------------------------------------------------- public API


def load_data(path: str | Path, problem: str = "axyb") -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None]:
    """Read a data file: ``(data, truth)``; truth is None when the file holds none.

    data: e.g. ``{"A": (m, 4, 4), "B": (m, 4, 4)}`` for problem ``"axyb"``;
    truth: e.g. ``{"X": (4, 4), "Y": (4, 4)}``.

    Raises InputError for a missing file, an unsupported extension (lists the supported ones),
    unparsable content, missing or unexpected keys, or poses that are not rigid motions.
    """
    pose_file = load_file(path, problem)
    return pose_file.data, pose_file.truth


def load_file(path: str | Path, problem: str = "axyb") -> PoseFile:
    """Like `load_data`, also returning the file's metadata (units, setup, ...)."""
    path = Path(path)
    reader, _ = _format(path)
    if not path.is_file():
        raise InputError(f"data file not found: {str(path)!r}")
    return _finish(reader(path), path, problem)


def save_data(path: str | Path, data: Mapping[str, Any], truth: Mapping[str, Any] | None = None, *,
              metadata: Mapping[str, str] | None = None, problem: str = "axyb") -> Path:
    """Write data (and optionally truth and metadata) in the format given by the extension.

    data: data field -> (m, 4, 4); truth: unknown -> (4, 4); metadata: keys of
    `METADATA_KEYS`. Everything is validated as `load_data` would, so a file written here always
    reads back (floats are written with full precision: the round trip is exact).
    Returns the path written.
    """
    path = Path(path)
    _, writer = _format(path)
    raw = RawFile(dict(data), None if truth is None else dict(truth), dict(metadata or {}))
    pose_file = _finish(raw, path, problem, writing=True)
    writer(path, pose_file)
    return path


def supported_extensions() -> list[str]:
    """File extensions with a reader, e.g. ``[".json", ".npz"]``."""
    return sorted(FORMATS)


# ----------------------------------------------------------------------------- shared checks


def _format(path: Path) -> tuple[Callable[[Path], RawFile], Callable[[Path, PoseFile], None]]:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(
            f"{str(path)!r}: unsupported file extension {ext or '(none)'!r}; supported: "
            f"{', '.join(supported_extensions())} (see docs/formats.md)"
        )
    return FORMATS[ext]


def _finish(raw: RawFile, path: Path, problem: str, writing: bool = False) -> PoseFile:
    """Check keys against the problem's fields and unknowns, validate poses and metadata."""
    spec = get_registry().problem(problem)
    fields, unknowns = tuple(spec.data_fields), tuple(spec.unknowns)
    where = f"{str(path)!r}"
    if raw.unexpected:
        raise InputError(
            f"{where}: unexpected key(s) {sorted(raw.unexpected)}; a {problem!r} file holds "
            f"{_key_listing(path, fields, unknowns)}"
        )
    missing = [f for f in fields if f not in raw.data]
    if missing:
        raise InputError(
            f"{where}: missing data key(s) {missing} for problem {problem!r}; found "
            f"{sorted(raw.data) or 'none'}; expected {_key_listing(path, fields, unknowns)}"
        )
    extra = sorted(set(raw.data) - set(fields))
    if extra:
        raise InputError(f"{where}: unexpected data key(s) {extra}; problem {problem!r} has data {list(fields)}")
    data = {f: _poses(raw.data[f], f, where) for f in fields}

    truth = None
    if raw.truth is not None:
        if not isinstance(raw.truth, Mapping):
            raise InputError(f"{where}: truth must map unknown names {list(unknowns)} to 4x4 poses")
        missing = [u for u in unknowns if u not in raw.truth]
        extra = sorted(set(raw.truth) - set(unknowns))
        if missing or extra:
            raise InputError(
                f"{where}: truth must hold exactly the unknowns {list(unknowns)} of problem "
                f"{problem!r}; missing {missing}, unexpected {extra}"
            )
        truth = {u: _poses(raw.truth[u], f"truth {u}", where, single=True) for u in unknowns}

    metadata = {}
    for key, value in raw.metadata.items():
        if key not in METADATA_KEYS:
            raise InputError(f"{where}: unknown metadata key {key!r}; known: {list(METADATA_KEYS)}")
        if not isinstance(value, str):
            raise InputError(f"{where}: metadata {key!r} must be a string, got {value!r}")
        metadata[key] = value
    for key, allowed in (("units", UNITS), ("setup", SETUPS)):
        if key in metadata and metadata[key] not in allowed:
            raise InputError(f"{where}: {key} must be one of {list(allowed)}, got {metadata[key]!r}")
    return PoseFile(data, truth, metadata)


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


def _as_float(value: Any, name: str, where: str) -> np.ndarray:
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: {name} must be a 4x4 array of numbers ({exc})") from None


def _key_listing(path: Path, fields: tuple[str, ...], unknowns: tuple[str, ...]) -> str:
    if path.suffix.lower() == ".npz":
        truth = ", ".join(u + TRUTH_SUFFIX for u in unknowns)
        return f"arrays {', '.join(fields)}; optionally {truth} and {', '.join(METADATA_KEYS)}"
    return (f"keys {', '.join(repr(f) for f in fields)}; optionally 'truth' "
            f"({{{', '.join(repr(u) for u in unknowns)}}}) and {', '.join(repr(k) for k in METADATA_KEYS)}")


# ----------------------------------------------------------------------------- NPZ


def _read_npz(path: Path) -> RawFile:
    """NPZ: one array per data field (``A``, ``B``), ``<unknown>_true`` (``X_true``), and
    0-d string arrays for metadata. Object arrays are refused (no pickle)."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"{str(path)!r}: not a readable NPZ file ({exc})") from None
    data, truth, metadata, unexpected = {}, {}, {}, []
    for key, value in arrays.items():
        if key.endswith(TRUTH_SUFFIX):
            truth[key[: -len(TRUTH_SUFFIX)]] = value
        elif key in METADATA_KEYS:
            metadata[key] = str(value) if value.ndim == 0 and value.dtype.kind in "US" else value
        elif value.dtype.kind in "US":
            unexpected.append(key)
        else:
            data[key] = value
    return RawFile(data, truth or None, metadata, tuple(unexpected))


def _write_npz(path: Path, pose_file: PoseFile) -> None:
    arrays: dict[str, np.ndarray] = dict(pose_file.data)
    for name, T in (pose_file.truth or {}).items():
        arrays[name + TRUTH_SUFFIX] = T
    for key, value in pose_file.metadata.items():
        arrays[key] = np.array(value)
    with open(path, "wb") as fh:  # a file object: np.savez would append .npz to other names
        np.savez(fh, **arrays)


# ----------------------------------------------------------------------------- JSON


def _read_json(path: Path) -> RawFile:
    """JSON object: ``{"A": [4x4, ...], "B": [...], "truth": {"X": 4x4, "Y": 4x4}, "units": "m",
    "setup": "eye-in-hand", ...}``; 4x4 poses are row-major nested lists."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{str(path)!r}: not UTF-8 text ({exc})") from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{str(path)!r}: invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    if not isinstance(obj, dict):
        raise InputError(f"{str(path)!r}: expected a JSON object with keys such as 'A' and 'B', got {type(obj).__name__}")
    truth = obj.pop("truth", None)
    metadata = {k: obj.pop(k) for k in METADATA_KEYS if k in obj}
    unexpected = tuple(k for k, v in obj.items() if not isinstance(v, list))
    data = {k: v for k, v in obj.items() if isinstance(v, list)}
    return RawFile(data, truth, metadata, unexpected)


def _write_json(path: Path, pose_file: PoseFile) -> None:
    """One pose per line; floats as Python's shortest round-trip repr (exact read-back)."""

    def pose(T: np.ndarray) -> str:
        return json.dumps(np.asarray(T, dtype=float).tolist())

    parts = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in pose_file.metadata.items()]
    for name, stack in pose_file.data.items():
        rows = ",\n".join("    " + pose(T) for T in stack)
        parts.append(f"  {json.dumps(name)}: [\n{rows}\n  ]")
    if pose_file.truth is not None:
        rows = ",\n".join(f"    {json.dumps(k)}: {pose(T)}" for k, T in pose_file.truth.items())
        parts.append(f'  "truth": {{\n{rows}\n  }}')
    path.write_text("{\n" + ",\n".join(parts) + "\n}\n", encoding="utf-8")


#: extension -> (reader, writer). Add a format here (one line) after writing its two functions.
FORMATS: dict[str, tuple[Callable[[Path], RawFile], Callable[[Path, PoseFile], None]]] = {
    ".npz": (_read_npz, _write_npz),
    ".json": (_read_json, _write_json),
}
