"""The quality report of one calibration (``handeye calibrate / solve --report FILE``).

One self-contained file that a user can keep with the cell's calibration: the answer (each
unknown with its frame, as a 4x4 and as xyz + quaternion, with its 1-sigma when the solver
reports one), the per-pair residuals of the problem's equation (eqs. 32-33 of the paper: the
rotation angle and translation distance between the two sides) as a table and a bar plot with the
outliers marked, the data diagnostics (pairs / stations, rotation excitation or axis spread,
largest rotation, likely mismatched motions), the plausibility checks (handeye.plausibility),
a 3D plot of the flange positions and the solved frames, the warnings with what to do about
them, and the run (status, solver, time, version, inputs).

Three steps, so both commands share everything after the solve:

- `collect` turns a solve (the `Solution`, its per-pair residuals, the checks, the inputs) into a
  plain, JSON-ready dict (the report's data: nothing else is read afterwards);
- `build_html` / `build_markdown` are pure functions of that dict (HTML with the plots as base64
  PNG ``data:`` URIs, no external asset; markdown referencing PNG files named next to it);
- `write_report` chooses by the extension (``.html`` / ``.htm`` / ``.md``) and writes.

matplotlib is imported only when a plot is drawn (handeye.report_plots), never by ``import
handeye`` or a solve.
"""

from __future__ import annotations

import base64
import html
import math
import re
import urllib.parse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .output_files import write_bytes, write_text
from .se3 import largest_relative_angle
from .solution import jsonable, standard_deviations

#: extension -> report format
FORMATS = {".html": "html", ".htm": "html", ".md": "markdown"}
#: the plots a markdown report writes next to it, as <stem>_<plot>.png (`handeye.report_plots.draw_all`)
PLOTS = ("residuals", "poses")
#: fewer stations than this: a warning advising to record at least this many
RECOMMENDED_STATIONS = 10
#: the residual table lists every pair up to this many; beyond, it still does (the file has room),
#: but the plot's tick labels are thinned
TICKS_UP_TO = 40


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
            pairing: str | None = None, command: str = "") -> dict[str, Any]:
    """The report's data, JSON-ready.

    solution: the `Solution` as reported (status possibly set to unreliable by the checks);
    residuals: per pair {"rotation": (m,) rad, "translation": (m,) data unit}; frames: unknown ->
    (frame name, what it is); checks: `plausibility.Report.to_dict()` or None; warnings: every
    warning the command printed; inputs: label -> text (files, formats, units); robot_poses:
    (n, 4, 4) T_base_flange of the stations (for the 3D plot; None without absolute poses);
    stations, pairing: for data made of stations (axxb: which stations each motion joins).
    """
    from . import __version__

    rot = np.degrees(np.asarray(residuals["rotation"], dtype=float))
    trans = np.asarray(residuals["translation"], dtype=float)
    diagnostics = dict(solution.diagnostics)
    joined = _joined(stations, pairing) if stations is not None and problem == "axxb" else None
    # auto's outliers: indices of pairs, or of stations when it solved axxb on the stations
    outlier_list = diagnostics.get("outliers")
    on_stations = "formulation" in diagnostics and joined is not None
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
    if robot_poses is not None and problem == "axyb" and len(robot_poses) > 1:
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
        "unknowns": {name: np.asarray(T, dtype=float).tolist() for name, T in solution.unknowns.items()},
        "frames": {name: list(frames[name]) for name in solution.unknowns if name in frames},
        "std": _std_of(diagnostics),
        "item": "motion" if problem == "axxb" else "pair",
        "residuals": {"rotation_deg": rot.tolist(), "translation": trans.tolist()},
        "joined": joined,
        "outliers": outliers,
        "outlier_stations": outlier_stations,
        "outlier_test": diagnostics.get("outlier_test"),
        "stations": stations,
        "pairing": pairing,
        "data": data,
        "checks": checks,
        "warnings": list(dict.fromkeys(warnings)),
        "inputs": dict(inputs),
        "robot_poses": None if robot_poses is None else np.asarray(robot_poses, dtype=float).tolist(),
    })


# ----------------------------------------------------------------------------- advice


def advice(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(what was found, what to do) in the user's words, most important first."""
    out: list[tuple[str, str]] = []
    status, item, unit = r["status"], r["item"], r["unit"] or "data units"
    checks = r.get("checks") or {}
    if status in ("not_converged", "failed"):
        out.append((f"the solver ended with status {status}: the answer is not usable",
                    "try another solver (handeye list), or check the data"))
    if status == "unreliable" or (checks and not checks.get("plausible", True)):
        expl = checks.get("explanation")
        if expl:
            out.append(((f"implausible fit: the residuals drop to {expl['rotation_deg']:.3g} deg / "
                        f"{expl['translation']:.3g} {unit} if {expl['description']}"),
                        f"{expl['suggestion']}, then calibrate again; do not use this answer"))
        else:
            out.append((("implausible fit: the residuals are larger than a calibrated cell gives, and none of "
                        "the usual mistakes explains them"),
                        "check the pairing of the two files, their formats and units; do not use this answer"))
    if r.get("outliers"):
        if r.get("outlier_stations"):
            rows = ", ".join(str(i + 1) for i in r["outlier_stations"])
            many = len(r["outlier_stations"]) > 1
            what = f"station{'s' if many else ''} (file row{'s' if many else ''}) {rows}"
        else:
            what = f"{item}{'s' if len(r['outliers']) > 1 else ''} " + ", ".join(str(i) for i in r["outliers"])
            if r.get("stations") and r["problem"] == "axyb":
                what += (f" (file row{'s' if len(r['outliers']) > 1 else ''} "
                         + ", ".join(str(i + 1) for i in r["outliers"]) + ")")
        many = len(r.get("outlier_stations") or r["outliers"]) > 1
        out.append(((f"{what} {'are' if many else 'is'} far off the others and left out of "
                    "the answer"),
                     ("check those stations' images (board detection, blur, reflections) and robot poses; "
                     "re-record them or remove them")))
    data = r.get("data") or {}
    precision = [w for w in r["warnings"] if w.startswith("the data determine")]
    if any("main rotation axis" in w for w in precision):
        out.append(("the robot rotates mostly about one axis, so the data determine part of the answer poorly",
                    "add poses that rotate about other axes (tilt the flange about x and y, not only z)"))
    elif precision:
        out.append(("the data determine part of the answer poorly at their noise (see the 1-sigma)",
                    "add stations with larger rotations (20-40 deg) about different axes, or reduce the noise"))
    if data.get("likely_mismatched"):
        out.append(((f"{item}s {', '.join(str(i) for i in data['likely_mismatched'])} rotate by a different angle "
                    "for the robot than for the camera"),
                    "check that row k of the robot file and of the camera file are the same station"))
    n = r.get("stations") or (len(r["residuals"]["rotation_deg"]) if r["problem"] == "axyb" else None)
    if n is not None and n < RECOMMENDED_STATIONS:
        out.append((f"only {n} stations", (f"record at least {RECOMMENDED_STATIONS} stations (10-20 are usual), "
                                          "spread over the workspace, with varied orientations")))
    if any("duplicated stations" in w for w in r["warnings"]):
        out.append(("some stations repeat the same robot pose", "move the robot between stations"))
    if any("time stamps" in w or "row names differ" in w for w in r["warnings"]):
        out.append(("the two files' rows may not be the same stations",
                    "check that row k of both files is the same station"))
    if r["std"] is None:
        out.append((f"no 1-sigma: solver {r['solver']} does not report uncertainties",
                    "use solver auto (default) or refine to get the 1-sigma of the answer"))
    if status == "uncertified":
        out.append(("status uncertified: a valid answer that the solver could not prove globally optimal",
                    "nothing to do if the residuals are small; solver auto certifies its start"))
    return out


# ----------------------------------------------------------------------------- pieces of text


def _xyz_quat(T: Sequence[Sequence[float]]) -> list[float]:
    from scipy.spatial.transform import Rotation

    M = np.asarray(T, dtype=float)
    return [*M[:3, 3].tolist(), *Rotation.from_matrix(M[:3, :3]).as_quat(canonical=True).tolist()]


def _stats(values: Sequence[float]) -> tuple[float, float, float]:
    v = np.asarray(values, dtype=float)
    return float(np.median(v)), float(np.sqrt(np.mean(v**2))), float(np.max(v))


def _diag_rows(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(name, value) rows of the data diagnostics and the plausibility check."""
    data, unit = r.get("data") or {}, r["unit"] or "data units"
    rows = []
    m = len(r["residuals"]["rotation_deg"])
    if r.get("stations"):
        rows.append(("stations", str(r["stations"])))
    rows.append((f"{r['item']}s", str(m) + (f" ({r['pairing']} pairs of stations)" if r.get("pairing") else "")))
    if "rotation_excitation" in data:
        rows.append(("rotation excitation", f"{data['rotation_excitation']:.3g} (weak below 1e-4)"))
    if "axis_spread" in data:
        rows.append(("rotation axis spread", f"{math.degrees(data['axis_spread']):.3g} deg (weak below 5.7 deg)"))
    if "largest_rotation" in data:
        between = " between two stations" if r["problem"] == "axyb" else " of a motion"
        rows.append(("largest rotation" + between, f"{math.degrees(data['largest_rotation']):.3g} deg"))
    if "angle_difference_max" in data:
        rows.append(("largest robot/camera angle difference", f"{math.degrees(data['angle_difference_max']):.3g} deg"))
    if "likely_mismatched" in data:
        mis = data["likely_mismatched"]
        rows.append(("likely mismatched motions", ", ".join(map(str, mis)) if mis else "none"))
    if r.get("outliers") is not None:
        rows.append((f"outlying {r['item']}s (left out)", ", ".join(map(str, r["outliers"])) or "none"))
    checks = r.get("checks")
    if checks:
        res, lim = checks["residual_rms"], checks["limits"]
        rows.append(("plausibility check", "plausible" if checks["plausible"] else "IMPLAUSIBLE"))
        rows.append(("residual RMS vs limits", (f"{res['rotation_deg']:.3g} deg / {res['translation']:.3g} {unit} "
                                               f"(limits {lim['rotation_deg']:.3g} deg / {lim['translation']:.3g} "
                                               f"{unit})")))
        rows.append(("cell size (RMS spread of the flange positions)", f"{checks['cell_size']:.4g} {unit}"))
        if checks.get("explanation"):
            e = checks["explanation"]
            rows.append(("best explanation", f"{e['description']} ({e['suggestion']})"))
    else:
        rows.append(("plausibility check", "not run (needs absolute robot and camera poses; off with --no-checks)"))
    return rows


def _hypothesis_rows(r: Mapping[str, Any]) -> list[tuple[str, str, str, str]]:
    checks = r.get("checks") or {}
    return [(h["description"], f"{h['rotation_deg']:.3g}", f"{h['translation']:.3g}", f"{h['score']:.3g}")
            for h in checks.get("hypotheses", [])[:6]]


def _run_rows(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    rows = [("status", r["status"]), ("solver", f"{r['solver']} (backend {r['backend']})"),
            ("solver time", f"{r['seconds'] * 1e3:.3g} ms" if r["seconds"] < 10 else f"{r['seconds']:.1f} s"),
            ("problem", r["problem"] + (f", {r['setup']}" if r["setup"] else "")),
            ("length unit", r["unit"] or "not stated"), ("handeye version", r["version"])]
    if r.get("command"):
        rows.append(("command", r["command"]))
    return rows + [(k, v) for k, v in r["inputs"].items()]


def _status_line(r: Mapping[str, Any]) -> str:
    s = r["status"]
    if s in ("not_converged", "failed"):
        return f"status {s}: the solver did not reach its answer; do not use it"
    if s == "unreliable":
        return "status unreliable: the residuals are implausible for a calibrated cell; do not use this answer"
    if s == "uncertified":
        return "status uncertified: a valid answer, not proven globally optimal"
    return f"status {s}"


def _pair_label(r: Mapping[str, Any], k: int) -> str:
    if r.get("joined"):
        i, j = r["joined"][k]
        return f"rows {i + 1}-{j + 1}"
    if r.get("stations") and r["problem"] == "axyb":
        return f"row {k + 1}"
    return ""


# ----------------------------------------------------------------------------- HTML

CSS = """body{font-family:system-ui,sans-serif;max-width:62em;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.2em .6em;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}tr.outlier td{background:#fde2e2;color:#a00}
pre{background:#f7f7f7;padding:.5em}.status{font-size:1.2em;font-weight:bold}.bad{color:#b00}.ok{color:#070}
img{max-width:100%}"""


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], left: int = 1,
           row_class: Sequence[str] | None = None) -> str:
    e = html.escape
    head = "".join(f"<th class='l'>{e(h)}</th>" if k < left else f"<th>{e(h)}</th>" for k, h in enumerate(header))
    body = []
    for n, row in enumerate(rows):
        cls = f" class='{row_class[n]}'" if row_class and row_class[n] else ""
        cells = "".join(f"<td class='l'>{e(str(c))}</td>" if k < left else f"<td>{e(str(c))}</td>"
                        for k, c in enumerate(row))
        body.append(f"<tr{cls}>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _unknown_blocks(r: Mapping[str, Any]) -> list[tuple[str, str, list[list[float]], list[float], str]]:
    """(name + frame, description, 4x4, xyz+quat, 1-sigma text) per unknown."""
    unit = r["unit"] or "data units"
    out = []
    for name, T in r["unknowns"].items():
        frame, what = r["frames"].get(name, ("", ""))
        title = f"{name} = {frame}" if frame else name
        std = (r["std"] or {}).get(name)
        sigma = (f"1-sigma: rotation {std['rotation_deg']:.3g} deg, translation {std['translation']:.3g} {unit}"
                 if std else f"1-sigma: not reported by solver {r['solver']} (auto or refine report it)")
        out.append((title, what, T, _xyz_quat(T), sigma))
    return out


def build_html(r: Mapping[str, Any], images: Mapping[str, bytes] | None = None) -> str:
    """The report as one HTML page; `images` (name -> PNG bytes, default: drawn here with
    handeye.report_plots) are embedded as base64 ``data:`` URIs."""
    if images is None:
        from .report_plots import draw_all

        images = draw_all(r)
    e = html.escape
    unit = r["unit"] or "data units"
    item = r["item"]
    bad = r["status"] in ("not_converged", "failed", "unreliable")
    parts = [(f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>handeye calibration report</title>"
             f"<style>{CSS}</style></head><body>"),
             "<h1>Hand-eye calibration report</h1>",
             f"<p class='status {'bad' if bad else 'ok'}'>{e(_status_line(r))}</p>",
             "<h2>Answer</h2>"]
    if r["unit"]:
        parts.append(f"<p>Lengths in {e(unit)}, rotations in degrees; quaternion (x, y, z, w), w &ge; 0.</p>")
    for title, what, T, xq, sigma in _unknown_blocks(r):
        parts.append(f"<h3>{e(title)}</h3>" + (f"<p>{e(what)}</p>" if what else ""))
        parts.append("<pre>" + "\n".join("".join(f"{v:14.6f}" for v in row) for row in T) + "</pre>")
        parts.append(_table(["x", "y", "z", "qx", "qy", "qz", "qw"], [[f"{v:.6g}" for v in xq[:3]]
                                                                     + [f"{v:.8f}" for v in xq[3:]]], left=0))
        parts.append(f"<p class='sigma'>{e(sigma)}</p>")
    advice_rows = advice(r)
    parts.append("<h2>Warnings and what to do</h2>")
    if advice_rows:
        parts.append(_table(["found", "what to do"], advice_rows, left=2))
    else:
        parts.append("<p>Nothing to act on.</p>")
    if r["warnings"]:
        parts.append("<p>Messages of the run:</p><ul>" + "".join(f"<li>{e(w)}</li>" for w in r["warnings"]) + "</ul>")
    parts.append(f"<h2>Residuals per {item}</h2>")
    rot, trans = r["residuals"]["rotation_deg"], r["residuals"]["translation"]
    parts.append("<p>Angle and distance between the two sides of the problem's equation "
                 f"({'A_i X = X B_i' if r['problem'] == 'axxb' else 'A_i X = Y B_i'}).</p>")
    parts.append(_table(["", "median", "RMS", "max"],
                        [["rotation [deg]", *(f"{v:.4g}" for v in _stats(rot))],
                         [f"translation [{unit}]", *(f"{v:.4g}" for v in _stats(trans))]]))
    if "residuals" in images:
        parts.append(_img(images["residuals"], f"residuals per {item}"))
    outliers = set(r.get("outliers") or [])
    if r.get("outliers") is not None:
        parts.append(f"<p>Outliers (auto: {e(r.get('outlier_test') or '')}): "
                     f"{', '.join(map(str, sorted(outliers))) or 'none'}; marked in red.</p>")
    rows, classes = [], []
    for k in range(len(rot)):
        rows.append([str(k), _pair_label(r, k), f"{rot[k]:.4g}", f"{trans[k]:.4g}", "outlier" if k in outliers else ""])
        classes.append("outlier" if k in outliers else "")
    parts.append(_table([item, "file rows" if r.get("joined") else "file row", "rotation [deg]",
                         f"translation [{unit}]", ""], rows, left=2, row_class=classes))
    parts.append("<h2>Data diagnostics</h2>")
    parts.append(_table(["", "value"], _diag_rows(r), left=2))
    hyps = _hypothesis_rows(r)
    if hyps:
        parts.append("<p>Usual setup mistakes tried by the plausibility check (residual RMS of a closed-form fit "
                     "with the mistake undone; score below 1 is plausible):</p>")
        parts.append(_table(["hypothesis", "rotation [deg]", f"translation [{unit}]", "score"], hyps))
    if "poses" in images:
        parts.append("<h2>Poses and solved frames</h2>")
        parts.append(_img(images["poses"], "robot flange positions and the solved frames"))
    parts.append("<h2>Run</h2>")
    parts.append(_table(["", ""], _run_rows(r), left=2))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _img(png: bytes, alt: str) -> str:
    return f"<p><img alt='{html.escape(alt)}' src='data:image/png;base64,{base64.b64encode(png).decode('ascii')}'></p>"


# ----------------------------------------------------------------------------- markdown


def _md_text(text: Any) -> str:
    """`text` (a file name, a warning, the command line: anything from the user's data) as
    markdown that renders as that text: no HTML tag, entity, link, image or code span can form
    (``<img src=x onerror=...>`` in a file name stays text), and on one line."""
    text = html.escape(" ".join(str(text).split()), quote=False)  # < > & as entities
    return re.sub(r"([\\`\[\]|])", r"\\\1", text)


def _md_link(name: str) -> str:
    """A file name as a markdown link target (percent-encoded: spaces, parentheses)."""
    return urllib.parse.quote(name)


def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    def cell(c: Any) -> str:
        return _md_text(c)

    lines = ["| " + " | ".join(cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def build_markdown(r: Mapping[str, Any], image_names: Mapping[str, str]) -> str:
    """The report as markdown; `image_names` (plot name -> file name relative to the report)
    are the PNGs written next to it."""
    unit = r["unit"] or "data units"
    item = r["item"]
    out = ["# Hand-eye calibration report", "", f"**{_md_text(_status_line(r))}**", "", "## Answer", ""]
    if r["unit"]:
        out += [f"Lengths in {unit}, rotations in degrees; quaternion (x, y, z, w), w >= 0.", ""]
    for title, what, T, xq, sigma in _unknown_blocks(r):
        out += [f"### {_md_text(title)}", ""] + ([_md_text(what), ""] if what else [])
        out += ["```", *("".join(f"{v:14.6f}" for v in row) for row in T), "```", ""]
        out += [_md_table(["x", "y", "z", "qx", "qy", "qz", "qw"],
                          [[f"{v:.6g}" for v in xq[:3]] + [f"{v:.8f}" for v in xq[3:]]]), "", _md_text(sigma), ""]
    out += ["## Warnings and what to do", ""]
    rows = advice(r)
    out += [_md_table(["found", "what to do"], rows) if rows else "Nothing to act on.", ""]
    if r["warnings"]:
        out += ["Messages of the run:", "", *(f"- {_md_text(w)}" for w in r["warnings"]), ""]
    rot, trans = r["residuals"]["rotation_deg"], r["residuals"]["translation"]
    out += [f"## Residuals per {item}", "",
            _md_table(["", "median", "RMS", "max"],
                      [["rotation [deg]", *(f"{v:.4g}" for v in _stats(rot))],
                       [f"translation [{unit}]", *(f"{v:.4g}" for v in _stats(trans))]]), ""]
    if "residuals" in image_names:
        out += [f"![residuals per {item}]({_md_link(image_names['residuals'])})", ""]
    outliers = set(r.get("outliers") or [])
    if r.get("outliers") is not None:
        out += [f"Outliers (auto: {_md_text(r.get('outlier_test') or '')}): "
                f"{', '.join(map(str, sorted(outliers))) or 'none'}.",
                ""]
    out += [_md_table([item, "file rows" if r.get("joined") else "file row", "rotation [deg]",
                       f"translation [{unit}]", ""],
                      [[str(k), _pair_label(r, k), f"{rot[k]:.4g}", f"{trans[k]:.4g}",
                        "**outlier**" if k in outliers else ""] for k in range(len(rot))]), ""]
    out += ["## Data diagnostics", "", _md_table(["", "value"], _diag_rows(r)), ""]
    hyps = _hypothesis_rows(r)
    if hyps:
        out += ["Usual setup mistakes tried by the plausibility check (score below 1 is plausible):", "",
                _md_table(["hypothesis", "rotation [deg]", f"translation [{unit}]", "score"], hyps), ""]
    if "poses" in image_names:
        out += ["## Poses and solved frames", "", f"![poses and solved frames]({_md_link(image_names['poses'])})", ""]
    out += ["## Run", "", _md_table(["", ""], _run_rows(r)), ""]
    return "\n".join(out)


# ----------------------------------------------------------------------------- writing


def write_report(path: str | Path, r: Mapping[str, Any], force: bool = False) -> list[Path]:
    """Write the report of `r` (from `collect`) to `path`, HTML or markdown by its extension
    (markdown: its PNGs as ``<stem>_<plot>.png`` next to it); return the files written. Each
    file appears complete or not at all, and an existing one is replaced only with `force`
    (`handeye.output_files`)."""
    from .report_plots import draw_all

    fmt = check_report_path(path)
    path = Path(path)
    images = draw_all(r)
    if fmt == "html":
        return [write_text(path, build_html(r, images), force=force, flag="--report")]
    names = {name: f"{path.stem}_{name}.png" for name in images}
    written = [write_bytes(path.with_name(names[name]), png, force=force, flag="--report")
               for name, png in images.items()]
    return [write_text(path, build_markdown(r, names), force=force, flag="--report"), *written]
