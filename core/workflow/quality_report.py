"""The quality report of one calibration (``handeye calibrate / solve --report FILE``).

One self-contained file that a user can keep with the cell's calibration: the answer (each
unknown with its frame, as a 4x4 and as xyz + quaternion, with its 1-sigma when the solver
reports one), the per-pair residuals of the problem's equation (eqs. 32-33 of the paper: the
rotation angle and translation distance between the two sides) as a table and a bar plot with the
outliers marked, the data diagnostics (pairs / stations, rotation excitation or axis spread,
largest rotation, likely mismatched motions), the plausibility checks (handeye.workflow.plausibility),
a 3D plot of the flange positions and the solved frames, the warnings with what to do about
them, and the run (status, solver, time, version, inputs).

Three steps, so both commands share everything after the solve:

- `collect` turns a solve (the `Solution`, its per-pair residuals, the checks, the inputs) into a
  plain, JSON-ready dict (the report's data: nothing else is read afterwards);
- `build_html` / `build_markdown` are pure functions of that dict (HTML with the plots as base64
  PNG ``data:`` URIs, no external asset; markdown referencing PNG files named next to it);
- `write_report` chooses by the extension (``.html`` / ``.htm`` / ``.md``) and writes.

matplotlib is imported only when a plot is drawn (handeye.workflow.report_plots), never by ``import
handeye`` or a solve.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.framework.reported import Reported
from handeye.framework.solution import jsonable, standard_deviations
from handeye.geometry.se3 import largest_relative_angle
from handeye.io.output_files import write_bytes, write_text
from handeye.workflow.report_layout import advice, blocks  # noqa: F401 (advice: the report's rows, for callers)
from handeye.workflow.report_render import html_page, markdown

#: extension -> report format
FORMATS = {".html": "html", ".htm": "html", ".md": "markdown"}
#: the plots a markdown report writes next to it, as <stem>_<plot>.png (`handeye.workflow.report_plots.draw_all`)
PLOTS = ("residuals", "poses", "graph", "overlay1", "overlay2", "overlay3")


# ----------------------------------------------------------------------------- the report's data


def check_report_path(path: str | Path) -> str:
    """The format of report `path` ("html" or "markdown"); raises InputError, before anything is
    solved, for an unknown extension or a folder that does not exist."""
    p = Path(path)
    fmt = FORMATS.get(p.suffix.lower())
    if fmt is None:
        raise InputError(f"--report {str(path)!r}: unknown extension {p.suffix or '(none)'!r}; use .html (one "
                         "self-contained file) or .md (markdown, with its PNG plots written next to it)")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"--report {str(path)!r}: the folder {str(parent)!r} does not exist; create it or "
                         "name another file")
    if p.is_dir():
        raise InputError(f"--report {str(path)!r} is a folder; name a file")
    return fmt


def report_files(path: str | Path) -> list[Path]:
    """Every file a report at `path` may write: the report, and for markdown its PNG plots next
    to it (``<stem>_residuals.png``, ``<stem>_poses.png``)."""
    path = Path(path)
    if check_report_path(path) == "html":
        return [path]
    return [path, *(path.with_name(f"{path.stem}_{name}.png") for name in PLOTS)]


def check_new_report(path: str | Path, force: bool) -> None:
    """InputError, before anything is solved, for a report path `check_report_path` refuses or,
    without `force`, when the report or one of its plots exists."""
    if force:
        check_report_path(path)
        return
    for target in report_files(path):
        if target.exists():
            raise InputError(f"--report {str(path)!r}: {str(target)!r} exists; pass --force to overwrite it, or "
                             "name another report")


def _std_of(diagnostics: Mapping[str, Any]) -> dict[str, dict[str, float]] | None:
    """1-sigma per unknown (rotation deg, translation) from the solver's diagnostics, or None."""
    std = standard_deviations(diagnostics)
    return {name: {"rotation_deg": math.degrees(s["rotation"]), "translation": s["translation"]}
            for name, s in std.items()} or None


def _joined(n: int, pairing: str | None) -> list[tuple[int, int]] | None:
    if pairing == "consecutive":
        return [(i, i + 1) for i in range(n - 1)]
    if pairing == "all":
        return [(int(i), int(j)) for i, j in zip(*np.triu_indices(n, k=1))]
    return None


def collect(*, problem: str, setup: str | None, unit: str | None, solution: Any, residuals: Mapping[str, Any],
            frames: Mapping[str, tuple[str, str]], checks: Mapping[str, Any] | None, warnings: Sequence[str],
            inputs: Mapping[str, str], robot_poses: np.ndarray | None = None, stations: int | None = None,
            pairing: str | None = None, command: str = "", images: Mapping[str, Any] | None = None,
            pair_table: Sequence[Mapping[str, Any]] | None = None,
            labels: Sequence[Sequence[str]] | None = None) -> dict[str, Any]:
    """The report's data, JSON-ready.

    solution: the `Solution` as reported (status possibly set to unreliable by the checks);
    residuals: per pair {"rotation": (m,) rad, "translation": (m,) data unit}; frames: unknown ->
    (frame name, what it is); checks: `plausibility.Report.to_dict()` or None; warnings: every
    warning the command printed; inputs: label -> text (files, formats, units); robot_poses:
    (n, 4, 4) T_base_flange of the stations (for the 3D plot; None without absolute poses);
    stations, pairing: for data made of stations (a problem of motions: which stations each motion
    joins);
    command: the command line as given; images: an image run's entry
    (`handeye.workflow.report_images.image_entries`), or None; pair_table: the residuals per pair of
    poses of a cell of several cameras and targets (`Problem.residual_table`: the table and the
    graph of the report), or None; labels: such a cell's (station, camera, target) of each
    observation, which label the per-observation rows instead of their index, or None.
    """
    from handeye import __version__
    from handeye.host.registry import get_registry
    from handeye.workflow.frames import single_poses, unknown_of

    rot = np.degrees(np.asarray(residuals["rotation"], dtype=float))
    trans = np.asarray(residuals["translation"], dtype=float)
    diagnostics = dict(solution.diagnostics)
    spec = get_registry().problem(problem)
    motions = spec.station_reader is not None and spec.station_reader.pairing
    joined = _joined(stations, pairing) if stations is not None and motions else None
    # auto's outliers: indices of pairs, or of stations when it solved axxb on the stations
    reported = Reported.of(diagnostics)
    outlier_list = reported.outliers
    on_stations = reported.on_stations and joined is not None
    outliers = None
    outlier_stations = None
    if outlier_list is not None:
        idx = sorted(int(o["index"]) for o in outlier_list)
        if on_stations:
            outlier_stations = idx
            outliers = [k for k, (i, j) in enumerate(joined) if i in idx or j in idx]
        else:
            outliers = idx
    data = dict(diagnostics.get("data") or {})
    if robot_poses is not None and len(robot_poses) > 1:  # where the problem's own figures lack it
        data.setdefault("largest_rotation", largest_relative_angle(np.asarray(robot_poses, dtype=float)[:, :3, :3]))
    return jsonable({
        "command": command,
        "version": __version__,
        "problem": problem,
        "setup": setup,
        "unit": unit,
        "solver": solution.solver,
        "backend": solution.backend,
        "status": str(getattr(solution.status, "value", solution.status)),
        "seconds": float(solution.seconds),
        "unknowns": {name: T.tolist() for name, T in single_poses(solution.unknowns).items()},
        "frames": {name: list(frames[unknown_of(name)]) for name in single_poses(solution.unknowns)
                   if unknown_of(name) in frames},
        "std": _std_of(diagnostics),
        "item": spec.item,
        "equation": spec.equation or f"the equations of problem {problem!r}",
        # one data pair per station (the stations as recorded), not motions between them
        "one_per_station": spec.station_reader is not None and not spec.station_reader.pairing,
        "residuals": {"rotation_deg": rot.tolist(), "translation": trans.tolist()},
        "joined": joined,
        "outliers": outliers,
        "outlier_stations": outlier_stations,
        "outlier_test": reported.outlier_test,
        "stations": stations,
        "pairing": pairing,
        "data": data,
        "checks": checks,
        "warnings": list(dict.fromkeys(warnings)),
        "inputs": dict(inputs),
        "robot_poses": None if robot_poses is None else np.asarray(robot_poses, dtype=float).tolist(),
        "images": None if images is None else dict(images),
        "pair_table": None if not pair_table else [dict(row) for row in pair_table],
        "labels": None if labels is None else [list(map(str, label)) for label in labels],
        # a cell's monocular cameras: each one's scale and 1-sigma (the residuals above use them)
        "camera_scales": {name: [s, reported.camera_scales_std.get(name)]
                          for name, s in reported.camera_scales.items()} or None,
    })


# ----------------------------------------------------------------------------- building


def build_html(r: Mapping[str, Any], images: Mapping[str, bytes] | None = None) -> str:
    """The report of `r` as one HTML page; `images` (figure name -> PNG bytes, default: drawn here
    with handeye.workflow.report_plots) are embedded as base64 ``data:`` URIs."""
    if images is None:
        from handeye.workflow.report_plots import draw_all

        images = draw_all(r)
    return html_page(blocks(r), images)


def build_markdown(r: Mapping[str, Any], image_names: Mapping[str, str]) -> str:
    """The report of `r` as markdown; `image_names` (figure name -> file name relative to the
    report) are the PNGs written next to it."""
    return markdown(blocks(r), image_names)


# ----------------------------------------------------------------------------- writing


def write_report(path: str | Path, r: Mapping[str, Any], force: bool = False) -> list[Path]:
    """Write the report of `r` (from `collect`) to `path`, HTML or markdown by its extension
    (markdown: its PNGs as ``<stem>_<plot>.png`` next to it); return the files written. Each
    file appears complete or not at all, and an existing one is replaced only with `force`
    (`handeye.io.output_files`)."""
    from handeye.workflow.report_plots import draw_all

    fmt = check_report_path(path)
    path = Path(path)
    images = draw_all(r)
    if fmt == "html":
        return [write_text(path, build_html(r, images), force=force, flag="--report")]
    names = {name: f"{path.stem}_{name}.png" for name in images}
    written = [write_bytes(path.with_name(names[name]), png, force=force, flag="--report")
               for name, png in images.items()]
    return [write_text(path, build_markdown(r, names), force=force, flag="--report"), *written]


def write_failure_report(path: str | Path, error: str, lines: Sequence[str], command: str,
                         force: bool = False) -> Path:
    """The report of a calibration that ended without an answer (bad input found while reading or
    detecting, a solver that failed): the command, the error in the user's words, and what was
    found before it (`lines`: the images' summary), so that the report the user asked for says
    why (HTML or markdown by `path`'s extension; replaced only with `force`)."""
    import html

    fmt = check_report_path(path)
    title = "handeye calibration report: no answer"
    if fmt == "html":
        found = "".join(f"<pre>{html.escape(text)}</pre>" for text in lines)
        body = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{title}</title></head><body>"
                f"<h1>{title}</h1><p><b>error:</b> {html.escape(error)}</p><p><b>command:</b> "
                f"<code>{html.escape(command)}</code></p>" + (f"<h2>What was found before</h2>{found}" if found else "")
                + "</body></html>\n")
    else:
        found = "".join(f"```\n{text}\n```\n\n" for text in lines)
        body = (f"# {title}\n\n**error:** {error}\n\n**command:** `{command}`\n\n"
                + (f"## What was found before\n\n{found}" if found else ""))
    return write_text(path, body, force=force, flag="--report")
