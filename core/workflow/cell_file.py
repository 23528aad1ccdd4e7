"""The cell file: a `handeye.workflow.cell.Cell` as YAML, so that a cell is configured once,
versioned beside its data and rerun (``handeye calibrate --config cell.yaml``,
``handeye.calibrate(handeye.Cell.from_file("cell.yaml"))``).

The file is a mapping with the `Cell`'s fields as keys and its sections (``robot``, ``camera``,
``images``, ``matching``, ``outputs``) as nested mappings; docs/calibrate.md ("Cell files and
Python") shows a full one. Rules:

- a key the cell does not know is an error naming the key and the known keys (a typo never
  falls back to a default silently);
- relative paths (stream files, the image folder, the intrinsics, a board file, the outputs) are
  relative to the cell file's folder, so the file and its data move together; `cell_to_dict`
  writes paths inside the file's folder relative to it and others absolute;
- the file is read by `handeye.io.input_files.load_yaml` (aliases bounded, duplicate keys
  refused, YAML 1.2 numbers) and at most `MAX_CELL_FILE_BYTES` long; written whole or not at
  all (`handeye.io.output_files`);
- a cell read from a file is checked as `Cell` checks any cell, its messages naming the file's
  keys in quotes.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError, shown
from handeye.io.input_files import check_not_looping, load_yaml
from handeye.workflow.cell_parts import (
    CameraStream,
    Images,
    JointStream,
    Matching,
    ObservationStream,
    Outputs,
    PoseStream,
)

#: a cell file is a few hundred bytes; anything this long is not one
MAX_CELL_FILE_BYTES = 1_000_000
#: the sections of a cell file and the classes they become
SECTIONS: dict[str, type] = {"robot": PoseStream, "camera": CameraStream, "images": Images, "matching": Matching,
                             "outputs": Outputs, "joints": JointStream}
#: the keys of each section that are paths (relative to the cell file's folder)
PATH_KEYS = {"robot": ("file",), "camera": ("file",), "images": ("folder", "intrinsics"), "observations": ("file", "images", "intrinsics"),
             "outputs": ("json", "yaml", "report", "arm"), "joints": ("file",)}
#: a board spec ending so is a board file (a path)
BOARD_FILE_SUFFIXES = (".yaml", ".yml", ".json")
#: top-level keys in the order a cell file lists them
ORDER = ("setup", "problem", "robot", "joints", "arm", "camera", "images", "observations", "targets", "matching", "pairing", "solver", "backend", "options",
         "tz_X", "tz_Y", "camera_scale", "orthonormalize", "checks", "frame_ids", "time_limit", "outputs")
HEADER = ("# handeye cell file: what this cell records and how to calibrate it (docs/calibrate.md,\n"
          "# \"Cell files and Python\").\n"
          "# Run: handeye calibrate --config THIS_FILE   or   handeye.calibrate(handeye.Cell.from_file(THIS_FILE))\n"
          "# Relative paths are relative to this file's folder.\n")


def _keys(kind: type) -> list[str]:
    return [f.name for f in dataclasses.fields(kind)]


def _is_board_file(board: Any) -> bool:
    return isinstance(board, str) and board.strip().lower().endswith(BOARD_FILE_SUFFIXES)


# ----------------------------------------------------------------------------- reading


def cell_from_dict(cls: type, data: Mapping[str, Any], *, base: str | os.PathLike | None = None,
                   where: str = "cell") -> Any:
    """The cell (of class `cls`, `Cell`) of a cell file's mapping (module docstring); relative paths are joined to
    folder `base` (None: kept as they are). InputError for unknown keys, sections that are not
    mappings, and whatever `Cell` refuses."""
    if not isinstance(data, Mapping):
        raise InputError(f"{where}: expected a mapping of settings (setup, robot, camera or images, matching, ...), "
                         f"got {shown(data)}")
    known = _keys(cls)
    unknown = [k for k in data if k not in known]
    if unknown:
        raise InputError(f"{where}: unknown key {str(unknown[0])!r}; known keys: {', '.join(map(repr, known))}")
    values: dict[str, Any] = {k: v for k, v in data.items() if k not in SECTIONS}
    for name, kind in SECTIONS.items():
        section = data.get(name)
        if section is None:
            continue
        section = _settings(section, kind, where, name, repr(name))
        if base is not None:
            for key in PATH_KEYS.get(name, ()):
                section[key] = _joined(section.get(key), base)
            if name == "images" and _is_board_file(section.get("board")):
                section["board"] = _joined(section["board"], base)
        values[name] = kind(**section)
    if data.get("observations") is not None:
        values["observations"] = _observations(data["observations"], base, where)
    if isinstance(data.get("targets"), Mapping) and base is not None:  # board files beside the cell file
        values["targets"] = {name: _joined(board, base) if _is_board_file(board) else board
                             for name, board in data["targets"].items()}
    if base is not None and "arm" in values:  # the arm file beside the cell file
        values["arm"] = _joined(values["arm"], base)
    values.setdefault("robot", None)
    values.setdefault("setup", None)
    return cls(**values)


def _settings(section: Any, kind: type, where: str, name: str, what: str) -> dict[str, Any]:
    """A section of a cell file (`name`, e.g. ``robot`` or ``observations[1]``) as a dict of the
    fields of `kind`; InputError when it is not a mapping, or has a key `kind` lacks (the keys
    of `what` listed)."""
    keys = ", ".join(map(repr, _keys(kind)))
    if not isinstance(section, Mapping):
        raise InputError(f"{where}: '{name}' must be a mapping of {keys}; got {shown(section)}")
    odd = [key for key in section if key not in _keys(kind)]
    if odd:
        raise InputError(f"{where}: unknown key '{name}.{odd[0]}'; the keys of {what} are {keys}")
    return dict(section)


def _observations(value: Any, base: str | os.PathLike | None, where: str) -> tuple[ObservationStream, ...]:
    """The `observations` of a cell file: one mapping (a table naming each row's camera) or a list
    of them (e.g. one file per camera, each with its `camera`), paths joined to `base`."""
    items = [value] if isinstance(value, Mapping) else value
    if not isinstance(items, list) or not items:
        raise InputError(f"{where}: 'observations' must be a mapping of "
                         f"{', '.join(map(repr, _keys(ObservationStream)))} or a list of them (one per file); got "
                         f"{shown(value)}")
    out = []
    for k, item in enumerate(items):
        item = _settings(item, ObservationStream, where, f"observations[{k}]", "an observations file")
        if base is not None:
            for key in PATH_KEYS["observations"]:
                item[key] = _joined(item.get(key), base)
        out.append(ObservationStream(**item))
    return tuple(out)


def _joined(value: Any, base: str | os.PathLike) -> Any:
    """`value` joined to folder `base` when it is a relative path (``~`` expanded)."""
    if not isinstance(value, str) or not value.strip():
        return value
    path = Path(value).expanduser()
    return str(path if path.is_absolute() else Path(base) / path)


def read_cell(cls: type, path: str | os.PathLike) -> Any:
    """The cell of YAML file `path`, relative paths joined to its folder. InputError (one line,
    naming the file) for a file that is missing, too long, not YAML, or not a valid cell."""
    path = Path(path)
    where = f"cell file {str(path)!r}"
    check_not_looping(path, "cell file")
    if not path.is_file():
        raise InputError(f"{where} not found" + ("; it is a folder, name the YAML file" if path.is_dir() else ""))
    if path.stat().st_size > MAX_CELL_FILE_BYTES:
        raise InputError(f"{where} is {path.stat().st_size} bytes long; a cell file holds a few settings (at most "
                         f"{MAX_CELL_FILE_BYTES} bytes): name the cell's YAML file")
    try:
        data = load_yaml(path.read_text(encoding="utf-8-sig"), where)
    except UnicodeDecodeError:
        raise InputError(f"{where} is not text (UTF-8); a cell file is YAML") from None
    folder = path.parent if str(path.parent) else Path(".")
    try:
        return cell_from_dict(cls, {} if data is None else data, base=folder, where=where)
    except InputError as exc:
        text = str(exc)
        text = text if text.startswith(where) else f"{where}: {text}"
        raise InputError(text.replace("`", "'")) from None  # the file's keys, not the command line's flags


# ----------------------------------------------------------------------------- writing


def _portable(value: str | None, folder: str | os.PathLike | None) -> str | None:
    """A path as a cell file in `folder` writes it: relative to the folder when inside it, else
    absolute; as it is when `folder` is None."""
    if value is None or folder is None:
        return value
    target, root = os.path.abspath(os.path.expanduser(value)), os.path.abspath(folder)
    try:
        inside = os.path.commonpath([target, root]) == root
    except ValueError:  # another drive (Windows)
        inside = False
    return os.path.relpath(target, root) if inside else target


def _section(value: Any, name: str, folder: str | os.PathLike | None) -> dict[str, Any]:
    """The settings of one section that differ from its defaults, paths made portable."""
    default = type(value)()
    out: dict[str, Any] = {}
    for f in dataclasses.fields(value):
        item = getattr(value, f.name)
        if item == getattr(default, f.name) and not (name == "matching" and f.name == "method"):
            continue
        if f.name in PATH_KEYS.get(name, ()) or (name == "images" and f.name == "board" and _is_board_file(item)):
            item = _portable(item, folder)
        out[f.name] = list(item) if isinstance(item, tuple) else item
    return out


def cell_to_dict(cell: Any, relative_to: str | os.PathLike | None = None) -> dict[str, Any]:
    """The cell file's mapping of `cell` (`Cell.to_dict`): `setup`, `problem`, `matching.method`
    and every setting that differs from its default, in `ORDER`."""
    out: dict[str, Any] = {}
    defaults = {f.name: f.default if f.default is not dataclasses.MISSING else f.default_factory()
                for f in dataclasses.fields(cell) if f.name not in ("robot", "setup")}
    for name in ORDER:
        value = getattr(cell, name)
        if name == "matching" and cell.observations is not None and not any(s.images for s in cell.observations):
            continue  # the tables name each row's station
        if name == "observations":
            if value is not None:
                out[name] = [_section(stream, name, relative_to) for stream in value]
        elif name == "targets":
            if value is not None:
                out[name] = {target: _portable(board, relative_to) if _is_board_file(board) else
                             board if isinstance(board, str) else board.spec() for target, board in value.items()}
        elif name in SECTIONS:
            if value is not None:
                section = _section(value, name, relative_to)
                if section:
                    out[name] = section
        elif name == "arm":
            if value is not None:
                out[name] = _portable(value, relative_to)
        elif name in ("setup", "problem") or value != defaults[name]:
            out[name] = (dict(value) if name == "options" else list(value) if isinstance(value, tuple) else value)
    return out


def cell_yaml(cell: Any, relative_to: str | os.PathLike | None = None) -> str:
    """The cell file's text: `HEADER` and the YAML of `cell_to_dict`."""
    import yaml

    from handeye.workflow.exports import plain

    class Dumper(yaml.SafeDumper):
        """Sections as blocks (one setting a line), lists (columns, frame ids) on one line."""

    Dumper.add_representer(list, lambda dumper, value: dumper.represent_sequence(
        "tag:yaml.org,2002:seq", value, flow_style=True))
    body = yaml.dump(plain(cell_to_dict(cell, relative_to)), Dumper=Dumper, sort_keys=False,
                     default_flow_style=False, allow_unicode=True, width=100)
    return HEADER + body
