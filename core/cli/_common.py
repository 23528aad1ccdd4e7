"""Helpers shared by the subcommands: option parsing, text/JSON output, and the rule for output
files: a command never writes over an existing file unless given ``--force`` (`add_force_flag`,
`check_new_file`, `check_new_results`), checked before any work is done."""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.cli._cell_flags import cell_words
from handeye.io.output_files import check_writable
from handeye.workflow.exports import dump_json  # noqa: F401 (the commands' JSON text)
from handeye.workflow.exports import plain as _plain  # noqa: F401
from handeye.workflow.solving import PLUGIN_TIME_LIMIT
from handeye.workflow.solving import time_limit as _time_limit

#: how the library's messages spell a fact or an option (as a Python keyword) -> how this command
#: line spells it (`in_cli_words`); the library's own "(CLI --flag)" asides are dropped
CLI_WORDS: tuple[tuple[re.Pattern[str], Any], ...] = (
    (re.compile(r"; --tz-X on the command line"), ""),
    (re.compile(r"tz_([XY])=<[^>]*>"), r"--tz-\1 VALUE"),
    (re.compile(r"\btz_([XY])=([-+0-9.eE]+)"), r"--tz-\1 \2"),
    (re.compile(r"(?<!')\btz_([XY])\b(?!')"), r"--tz-\1"),  # not a quoted key ('tz_X' of a cell file)
    (re.compile(r"camera_scale='(known|unknown)'"), r"--camera-scale \1"),
    (re.compile(r"(?:camera_scale=|--camera-scale )\[([^\]]*)\]"),  # a cell's cameras: cam0,cam2
     lambda m: "--camera-scale " + ",".join(n.strip(" '\"") for n in m.group(1).split(","))),
    (re.compile(r"\b(noise|loss|outliers|init|estimate)='([^']*)'"), r"--option \1=\2"),
)
#: option values read as bools, whatever their case (JSON knows only lower-case true/false)
BOOLEANS = {"true": True, "false": False}


def in_cli_words(text: str) -> str:
    """`text` (an error, a warning, a printed result) with the library's keyword spellings of
    facts and options replaced by this command line's flags (`CLI_WORDS`): a user of the CLI is
    told ``--tz-X VALUE``, not ``tz_X=<...>``; the settings of a cell, which the library names in
    backticks (```robot.unit```), by the calibrate command's flags (``--robot-unit``;
    `handeye.cli._cell_flags`)."""
    text = cell_words(text)
    for pattern, words in CLI_WORDS:
        text = pattern.sub(words, text)
    return text


#: a 1-sigma widened by at least this factor to the stations' spread says so where printed
SPREAD_SHOWN = 1.05


def spread_note(diagnostics: dict[str, Any], name: str) -> str:
    """", widened 1.5x in rotation and 1.3x in translation to the answer's spread over groups of
    stations" where the host widened the 1-sigma of `name` (``diagnostics["station_spread"]``,
    `handeye.checks.systematic.station_spread`) by at least `SPREAD_SHOWN`, else ""."""
    factors = (diagnostics.get("station_spread") or {}).get(name) or {}
    parts = [f"{float(factors[kind]):.2g}x in {kind}" for kind in ("rotation", "translation")
             if float(factors.get(kind, 1.0)) >= SPREAD_SHOWN]
    return f", widened {' and '.join(parts)} to the answer's spread over groups of stations" if parts else ""


#: largest whole number a flag takes (counts, stations, folds, workers; seeds are below 2^63)
MAX_WHOLE = 10**9


def finite_number(text: str) -> float:
    """argparse type of a number flag: a finite float (nan, inf and 1e400 are refused by argparse
    with the flag's name, exit 2)."""
    value = _parsed(float, text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def whole_number(text: str) -> int:
    """argparse type of a count flag: an integer of at most `MAX_WHOLE` in size."""
    value = _parsed(int, text)
    if abs(value) > MAX_WHOLE:
        raise argparse.ArgumentTypeError(f"{text} is out of range (at most {MAX_WHOLE:.0e} in size)")
    return value


def seed_number(text: str) -> int:
    """argparse type of a --seed: a whole number 0 <= seed < 2^63."""
    value = _parsed(int, text)
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"{text} is no seed: give a whole number from 0 to 2^63 - 1")
    return value


def _parsed(kind: type, text: str) -> Any:
    """kind(text), or argparse's own message for a value that is no number of that kind."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid {kind.__name__} value: {text!r}") from None


def parse_key_values(items: Sequence[str] | None, what: str = "--option") -> dict[str, Any]:
    """``["k=v", ...]`` -> dict; v is a bool when it is ``true``/``false`` in any case (``False``
    as Python prints it), else parsed as a JSON literal when it is one (``1e-6``, ``"x"``,
    ``[1, 2]``), else kept as the string. Raises InputError on a malformed item."""
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"{what} expects key=value, got {item!r}")
        if key in out:
            raise InputError(f"{what} {key!r} given twice")
        word = text.strip().lower()
        if word in BOOLEANS:
            out[key] = BOOLEANS[word]
            continue
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out


def format_pose(T: np.ndarray, indent: str = "  ") -> str:
    """A 4x4 pose as aligned rows, rotation to 6 decimals, translation to 6 significant-ish digits."""
    T = np.asarray(T, dtype=float)
    width = max(10, max(len(f"{v:.6f}") for v in T.ravel()) + 1)
    return "\n".join(indent + "".join(f"{v:{width}.6f}" for v in row) for row in T)


def add_force_flag(parser: argparse.ArgumentParser) -> None:
    """The ``--force`` flag of every subcommand that writes files."""
    parser.add_argument("--force", action="store_true",
                        help="overwrite output files that exist (without it they are kept and the command stops)")


def add_time_limit_flag(parser: argparse.ArgumentParser) -> None:
    """The ``--time-limit`` flag of the commands that run one solver."""
    parser.add_argument("--time-limit", type=finite_number, metavar="SECONDS",
                        help="stop the solver after SECONDS (it runs in a worker process that is killed then); "
                             f"default: none for handeye's own solvers, {PLUGIN_TIME_LIMIT:g} s for a third-party "
                             "plugin's; 0: no limit")


def add_detection_flags(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` and ``--no-cache``: how the commands that detect boards in images do it
    (`detection_options`; the library's ``workers=`` and ``cache=``, docs/images.md "Speed")."""
    parser.add_argument("--workers", type=whole_number, metavar="N",
                        help="images: detect the boards on N threads (default: the cores, or HANDEYE_WORKERS); 1 "
                             "detects one image at a time")
    parser.add_argument("--no-cache", action="store_true", default=None,  # None when not given, as every flag
                        help="images: detect every board afresh, neither reading nor writing the detection cache "
                             "(default: detections of images seen before are read from it; HANDEYE_CACHE_DIR, "
                             "HANDEYE_NO_CACHE=1)")


def detection_options(args: argparse.Namespace) -> dict[str, Any]:
    """The library's ``workers`` and ``cache`` arguments of ``--workers`` and ``--no-cache``
    (None: the environment's defaults). InputError for ``--workers`` below 1."""
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise InputError(f"--workers takes the number of detection threads, at least 1; got {workers}")
    return {"workers": workers, "cache": False if getattr(args, "no_cache", False) else None}


def time_limit(args: argparse.Namespace, problem: str, solver: str) -> float | None:
    """The time limit of a solve, in seconds or None, from ``--time-limit`` and who provides the
    solver (`PLUGIN_TIME_LIMIT` for a third party's, so that a hanging plugin cannot hang the
    command; `handeye.workflow.solving.time_limit`). InputError for a negative or non-finite value."""
    return _time_limit(getattr(args, "time_limit", None), problem, solver)


def check_new_file(flag: str, path: str | Path | None, force: bool) -> None:
    """InputError when output file `path` (given with `flag`, e.g. ``-o``) exists and `force` is
    False; nothing when path is None. Called before any work, so a refused run computes nothing."""
    if path is not None and not force and Path(path).exists():
        raise InputError(f"{flag} {str(path)!r}: the file exists; pass --force to overwrite it, or name another file")


def check_outputs(outputs: Sequence[tuple[str, str | Path | None]], inputs: Iterable[str | Path | None],
                  force: bool) -> None:
    """The one rule every command's output files follow, checked before any work: none is an input
    of the same run (a file it reads, a folder of images it reads) or another of its outputs,
    whatever the flags (`check_outputs_apart`), none exists already unless `force`
    (`check_new_file`), and each can be written (`check_writable`: its folder exists and takes
    a file). `outputs`: (flag, path) pairs, None where not given; `inputs`: every
    file or folder the run reads (a spec that names no file never matches one)."""
    check_outputs_apart(outputs, inputs)
    for flag, path in outputs:
        check_new_file(flag, path, force)
        if path is not None:
            check_writable(flag, path)


def check_outputs_apart(outputs: Sequence[tuple[str, str | Path | None]], inputs: Iterable[str | Path | None]) -> None:
    """InputError when two outputs (flag, path) name the same file, or an output is one of the
    `inputs`, by name or as the same file under another name (a link)."""
    named = [(flag, Path(p)) for flag, p in outputs if p]
    sources = [Path(p) for p in inputs if p and isinstance(p, (str, Path))]
    for k, (flag, path) in enumerate(named):
        for other_flag, other in named[:k]:
            if _same_file(path, other):
                raise InputError(f"{other_flag} and {flag} name the same file {str(path)!r}; give different files")
        for source in sources:
            if _same_file(path, source):
                raise InputError(f"{flag} {str(path)!r} is the input file {str(source)!r} (or a link to it); it would be "
                                 "overwritten: name another output file")
            if _read_from(path, source):
                raise InputError(f"{flag} {str(path)!r} is a file the run reads from the input folder {str(source)!r}; "
                                 "it would be overwritten: name a file outside that folder")


#: files an input folder's readers take (images; pose files, one per station): an output that is
#: one of them, already there, would overwrite an input
FOLDER_INPUTS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp", ".csv", ".tsv", ".txt",
                 ".yaml", ".yml", ".json", ".npz")


def _read_from(path: Path, folder: Path) -> bool:
    """Whether `path` is an existing file directly in the input folder `folder` of a kind its
    readers take (`FOLDER_INPUTS`)."""
    try:
        return (folder.is_dir() and path.is_file() and path.suffix.lower() in FOLDER_INPUTS
                and path.resolve().parent == folder.resolve())
    except (OSError, RuntimeError):
        return False


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and a.samefile(b)
    except (OSError, RuntimeError):  # RuntimeError: a symbolic link loop (Python < 3.13)
        return False


def check_new_results(flag: str, outdir: str | Path, files: Iterable[str], force: bool) -> None:
    """InputError when folder `outdir` (given with `flag`) already holds one of `files` (the names
    a run writes there, e.g. a study's CSV and summary) and `force` is False."""
    if force:
        return
    existing = [name for name in files if (Path(outdir) / name).exists()]
    if existing:
        raise InputError(f"{flag} {str(outdir)!r} already holds {existing[0]!r} from an earlier run; pass --force "
                         "to overwrite its results, or name another folder (or --name)")


def add_workspace_flags(parser: argparse.ArgumentParser, unit: str) -> None:
    """The flags of where the flange may go, shared by plan and watch (`workspace_of`): the box,
    the tool axis' tilt and the wrist's roll; `unit` names the box's length unit in the help."""
    parser.add_argument("--workspace", metavar="X0,Y0,Z0,X1,Y1,Z1",
                        help=f"the box the flange's origin must stay in, base frame, {unit} (default: no limit)")
    parser.add_argument("--max-tilt", type=finite_number, metavar="DEG",
                        help="largest angle of the flange's z axis from --tool-axis (default: no limit)")
    parser.add_argument("--tool-axis", metavar="X,Y,Z",
                        help="the base-frame direction --max-tilt is measured from (default 0,0,-1: the flange "
                             "pointing down; 0,0,1 for an arm whose flange points up, e.g. toward fixed cameras above)")
    parser.add_argument("--max-roll", type=finite_number, default=90.0, metavar="DEG",
                        help="largest roll of the flange about its tool axis from x forward (default 90: the wrist "
                             "within a half turn, as a person drives it; 180: any)")


def workspace_of(box: str | None, max_tilt: float | None, tool_axis: str | None = None,
                 max_roll: float | None = None) -> Any:
    """The `handeye.planning.stations.Workspace` of ``--workspace X0,Y0,Z0,X1,Y1,Z1`` (the box's
    corners; absent: no box), ``--max-tilt DEG`` (absent: no limit), ``--tool-axis X,Y,Z`` (the
    base-frame direction the flange's z axis tilts from; default straight down, 0,0,-1: up for an
    arm whose flange points up, sideways for a wall) and ``--max-roll DEG`` (the flange's roll
    about its tool axis from "x forward"; 180: any), or None without any of them."""
    from handeye.planning.stations import Workspace

    if box is None and max_tilt is None and tool_axis is None and max_roll is None:
        return None
    axis = (0.0, 0.0, -1.0) if tool_axis is None else tuple(_finite_numbers(tool_axis, 3, "--tool-axis", "X,Y,Z"))
    limits = {"axis": axis, "max_tilt_deg": max_tilt, "max_roll_deg": max_roll}
    if box is None:
        return Workspace(low=(-np.inf,) * 3, high=(np.inf,) * 3, **limits)
    values = _finite_numbers(box, 6, "--workspace", "X0,Y0,Z0,X1,Y1,Z1 (the box's corners)")
    return Workspace(low=tuple(values[:3]), high=tuple(values[3:]), **limits)


def _finite_numbers(text: str, count: int, flag: str, form: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != count or not all(np.isfinite(values)):
        raise InputError(f"{flag} expects {'six' if count == 6 else count} numbers {form}, got {text!r}")
    return values