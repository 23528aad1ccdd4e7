"""Writing poses to a file that `handeye.io.pose_readers.read_poses` reads back: the robot
stations a plan proposes, the next stations `watch` suggests, test and benchmark files.
docs/formats.md ("Pose files of robots and cameras") is the reference for the formats."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from handeye.base.errors import InputError
from handeye.geometry.validation import pose_stack
from handeye.io.output_files import new_file, write_text
from handeye.io.pose_formats import PoseFormat, parse_format
from handeye.io.pose_readers import EXTENSIONS, TEXT_EXTENSIONS, PoseStack, check_unit
from handeye.io.pose_tables import POSES_KEY, yaml_module


def write_poses(path: str | Path, poses: ArrayLike | PoseStack, format: str | PoseFormat, *,
                unit: str | None = None, degrees: bool | None = None) -> Path:
    """Write poses (n, 4, 4) (or a `PoseStack`, with its names and stamps) in `format`, the file
    type chosen by extension, so that `read_poses` reads them back (floats written in full). The
    file appears complete or not at all, replacing an existing one (`handeye.io.output_files`).
    unit: required for bare arrays; a `PoseStack`'s own unit by default."""
    path = Path(path)
    fmt = parse_format(format)
    stack = poses if isinstance(poses, PoseStack) else None
    unit = unit or (stack.unit if stack else None)
    if unit is None:
        raise InputError("write_poses needs unit='mm' or unit='m' for an array of poses")
    check_unit(unit, str(path))
    if stack is not None and unit != stack.unit:
        stack = stack.in_unit(unit)
    T = pose_stack(stack.poses if stack else poses, "poses")
    rows = fmt.to_rows(T, degrees)
    names = stack.names if stack else None
    stamps = None if stack is None or stack.stamps is None else np.asarray(stack.stamps)
    ext = path.suffix.lower()
    header = (["name"] if names else []) + (["t"] if stamps is not None else []) + list(fmt.fields)
    records = [([names[i]] if names else []) + ([float(stamps[i])] if stamps is not None else []) + [float(v) for v in r]
               for i, r in enumerate(rows)]
    if ext in TEXT_EXTENSIONS:
        sep = "\t" if ext == ".tsv" else ","
        lines = [f"# handeye poses: format {fmt.name}, unit {unit}", sep.join(header)]
        lines += [sep.join(repr(v) if isinstance(v, float) else str(v) for v in rec) for rec in records]
        write_text(path, "\n".join(lines) + "\n", force=True)
    elif ext in (".json", ".yaml", ".yml"):
        doc = {"format": fmt.name, "units": unit, POSES_KEY: [dict(zip(header, rec)) for rec in records]}
        if ext == ".json":
            write_text(path, json.dumps(doc, indent=1) + "\n", force=True)
        else:
            write_text(path, yaml_module().safe_dump(doc, sort_keys=False), force=True)
    elif ext == ".npz":
        extra = {"units": np.array(unit)}
        if names:
            extra["names"] = np.array(names)
        if stamps is not None:
            extra["stamps"] = stamps
        with new_file(path, force=True, binary=True) as fh:  # a file object: np.savez would append .npz to other names
            np.savez(fh, **{POSES_KEY: rows}, **extra)
    else:
        raise InputError(f"{str(path)!r}: unsupported pose file extension {ext or '(none)'!r}; supported: {', '.join(EXTENSIONS)}")
    return path
