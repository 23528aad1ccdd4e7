"""The settings of a cell (`handeye.workflow.cell.Cell`, as its YAML file spells them) and the
``handeye calibrate`` flags that set them, both ways:

- `cell_words`: a library message naming settings in backticks (```robot.unit```,
  ```matching.method: time```, ```checks: false```) in this command line's words (``--robot-unit``,
  ``--match time``, ``--no-checks``), for `handeye.cli._common.in_cli_words`;
- `flag_settings`: the flags given on a ``handeye calibrate`` command line as the cell file's
  nested mapping (flags not given are left out, so a ``--config`` file's values stand).
"""

from __future__ import annotations

import argparse
import os
import re
from typing import Any

from handeye.io.data_files import station_readers

#: setting (as the cell file writes it) -> flag; a section's name alone is its file / folder flag
FIELD_FLAGS = {
    **{f"{which}{key}": flag for which in ("robot", "camera")
       for key, flag in (("", f"--{which}"), (".file", f"--{which}"), (".format", f"--{which}-format"),
                         (".unit", f"--{which}-unit"), (".columns", f"--{which}-columns"),
                         (".topic", f"--{which}-topic"))},
    "camera.poses": "--camera-poses",
    "images": "--images", "images.folder": "--images", "images.board": "--board", "images.intrinsics": "--intrinsics",
    "matching.method": "--match", "matching.max_dt": "--max-dt", "matching.time_offset": "--time-offset",
    "matching.max_offset": "--max-offset", "matching.max_gap": "--max-gap", "matching.min_speed": "--min-speed",
    "matching.max_pairs": "--max-pairs",
    "setup": "--setup", "problem": "--problem", "pairing": "--pairing", "solver": "--solver", "backend": "--backend",
    "options": "--option", "tz_X": "--tz-X", "tz_Y": "--tz-Y", "camera_scale": "--camera-scale",
    "orthonormalize": "--orthonormalize", "checks": "--no-checks", "frame_ids": "--frame-ids",
    "time_limit": "--time-limit", "outputs.json": "-o", "outputs.yaml": "--yaml", "outputs.report": "--report",
    "joints": "--joints", "joints.file": "--joints", "joints.unit": "--joints-unit", "joints.topic": "--joints-topic",
    "arm": "--arm", "outputs.arm": "--arm-out",
}
#: settings whose flag is the value itself (a switch): (setting, value) -> flag
SWITCHES = {("orthonormalize", "true"): "--orthonormalize", ("checks", "false"): "--no-checks"}
#: a setting named in a library message: `name` or `name: value`
_SETTING = re.compile(r"`([A-Za-z_][A-Za-z0-9_.]*)(?:: ([^`]*))?`")


def _flag(match: re.Match[str]) -> str:
    name, value = match.group(1), match.group(2)
    if (name, value) in SWITCHES:
        return SWITCHES[(name, value)]
    if name.startswith("options.") and name != "options.":
        return f"--option {name[len('options.'):]}={'VALUE' if value is None else value}"
    flag = FIELD_FLAGS.get(name)
    if flag is None:
        return match.group(0)
    return flag if value is None or name in ("orthonormalize", "checks") else f"{flag} {value}"


def cell_words(text: str) -> str:
    """`text` with every cell setting in backticks replaced by its flag (module docstring)."""
    return _SETTING.sub(_flag, text)


def flag_settings(args: argparse.Namespace, options: dict[str, Any] | None) -> dict[str, Any]:
    """The settings the flags of `args` give, as the cell file's nested mapping (`options`: the
    parsed ``--option`` items, or None when none was given)."""
    def given(**values: Any) -> dict[str, Any]:
        return {k: v for k, v in values.items() if v is not None}

    out: dict[str, Any] = given(setup=args.setup, problem=args.problem, pairing=args.pairing, solver=args.solver,
                                backend=args.backend, options=options, tz_X=args.tz_X, tz_Y=args.tz_Y,
                                camera_scale=args.camera_scale, frame_ids=args.frame_ids, time_limit=args.time_limit,
                                orthonormalize=True if args.orthonormalize else None,
                                checks=False if args.no_checks else None, arm=getattr(args, "arm", None))
    sections = {
        "robot": given(file=args.robot, format=args.robot_format, unit=args.robot_unit, columns=args.robot_columns,
                       topic=args.robot_topic),
        "camera": given(file=args.camera, format=args.camera_format, unit=args.camera_unit,
                        columns=args.camera_columns, topic=args.camera_topic, poses=args.camera_poses),
        "images": given(folder=args.images, board=args.board, intrinsics=args.intrinsics),
        "matching": given(method=args.match, max_dt=args.max_dt, time_offset=args.time_offset,
                          max_offset=args.max_offset, max_gap=args.max_gap, min_speed=args.min_speed,
                          max_pairs=args.max_pairs),
        "outputs": given(json=args.output, yaml=args.yaml, report=args.report, arm=getattr(args, "arm_out", None)),
        "joints": given(file=getattr(args, "joints", None), unit=getattr(args, "joints_unit", None),
                        topic=getattr(args, "joints_topic", None)),
    }
    tables = getattr(args, "observations", None)
    if tables:  # several cameras and targets: the --camera-* flags describe every table
        common = given(format=args.camera_format, unit=args.camera_unit, columns=args.camera_columns,
                       poses=args.camera_poses)
        out["observations"] = [{**_table(item), **common} for item in tables]
        sections["camera"] = given(file=args.camera, topic=args.camera_topic)  # left for the cell to refuse
    out.update({name: section for name, section in sections.items() if section})
    return out


def _table(item: str) -> dict[str, str]:
    """``--observations [CAMERA=]FILE``: the file, and the camera whose poses it holds if named."""
    camera, sep, file = item.partition("=")
    if sep and camera and not os.path.exists(item) and "/" not in camera and os.sep not in camera:
        return {"camera": camera, "file": file}
    return {"file": item}


def merged(base: dict[str, Any], flags: dict[str, Any]) -> dict[str, Any]:
    """A cell file's mapping `base` with the settings `flags` gives in place of its own: a section
    key by key, options key by key; what the flags make inapplicable is dropped from `base` (its
    camera file when the flags give images and the other way round, matching settings of
    another method, axxb's pairing when the flags solve axyb)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    if "images" in flags and "folder" in flags["images"]:
        out.pop("camera", None)
    if "camera" in flags and "file" in flags["camera"]:
        out.pop("images", None)
        out.pop("observations", None)
    if "joints" in flags and "file" in flags["joints"]:  # joint readings replace the file's robot poses
        out.pop("robot", None)
    if "robot" in flags and "file" in flags["robot"]:
        out.pop("joints", None)
        out.pop("arm", None)
    if "observations" in flags:  # the tables replace the file's camera side
        out.pop("camera", None)
        out.pop("images", None)
    method = flags.get("matching", {}).get("method")
    if method is not None and "matching" in out:
        keep = {"time": ("max_dt",), "interpolate": ("time_offset", "max_offset", "max_gap", "min_speed",
                                                      "max_pairs")}.get(method, ())
        out["matching"] = {k: v for k, v in out["matching"].items() if k in keep}
    reader = station_readers().get(flags.get("problem"))
    if reader is not None and not reader.pairing:  # the flags solve a problem without motions
        out.pop("pairing", None)
    for key, value in flags.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out
