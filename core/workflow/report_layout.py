"""The quality report's content, as a list of blocks built once from the report's data
(`handeye.workflow.quality_report.collect`) and rendered as HTML or markdown (`handeye.workflow.report_render`).

What a section says lives here only, so that the two formats cannot drift apart: the answer, the
warnings with what to do (every warning of the run is a row: a curated action where one is
known, else the warning's own advice), the residuals, the images of an image run (board,
intrinsics, each image's reprojection error, corner overlays of the worst images), the data
diagnostics with the plausibility hypotheses beside the data as given, the poses plot, and the
run with its full command line. A table has a header only where its columns need names, and a
column only where some row has something in it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: fewer stations than this: a warning advising to record at least this many
RECOMMENDED_STATIONS = 10


@dataclasses.dataclass(frozen=True)
class Heading:
    text: str
    level: int = 2


@dataclasses.dataclass(frozen=True)
class Text:
    """A paragraph; `css`: its HTML class ("status ok", "status bad")."""

    text: str
    css: str = ""


@dataclasses.dataclass(frozen=True)
class Pre:
    text: str


@dataclasses.dataclass(frozen=True)
class Table:
    """header: column names, or None for a table of (name, value) rows; left: how many leading
    columns are text (left-aligned); marked: rows to show as outliers."""

    header: tuple[str, ...] | None
    rows: tuple[tuple[str, ...], ...]
    left: int = 1
    marked: tuple[bool, ...] = ()


@dataclasses.dataclass(frozen=True)
class Figure:
    """A plot or an image by name (`handeye.workflow.report_plots.draw_all`), with its alternative text."""

    name: str
    alt: str


Block = Heading | Text | Pre | Table | Figure


def table(header: Sequence[str] | None, rows: Sequence[Sequence[Any]], left: int = 1,
          marked: Sequence[bool] = ()) -> Table:
    """A Table without the columns that are empty in every row (and their header)."""
    rows = [tuple(str(c) for c in row) for row in rows]
    width = max((len(r) for r in rows), default=len(header or ()))
    keep = [k for k in range(width) if any(k < len(r) and r[k] for r in rows)]
    head = None if header is None else tuple(header[k] for k in keep)
    return Table(head, tuple(tuple(r[k] for k in keep) for r in rows), sum(k < left for k in keep), tuple(marked))


def blocks(r: Mapping[str, Any]) -> list[Block]:
    """Every block of the report of `r`, in order."""
    bad = r["status"] in ("not_converged", "failed", "unreliable")
    out: list[Block] = [Heading("Hand-eye calibration report", 1), Text(status_line(r), f"status {'bad' if bad else 'ok'}")]
    out += _answer(r) + _advice(r) + _residuals(r) + _pairs(r) + _images(r) + _diagnostics(r)
    if r.get("robot_poses") is not None:
        out += [Heading("Poses and solved frames"), Figure("poses", "robot flange positions and the solved frames")]
    out += [Heading("Run"), table(None, run_rows(r), left=2)]
    return out


# ----------------------------------------------------------------------------- sections

def _answer(r: Mapping[str, Any]) -> list[Block]:
    unit = r["unit"] or "data units"
    out: list[Block] = [Heading("Answer")]
    if r["unit"]:
        out.append(Text(f"Lengths in {unit}, rotations in degrees; quaternion (x, y, z, w), w >= 0."))
    for name, T in r["unknowns"].items():
        frame, what = r["frames"].get(name, ("", ""))
        out.append(Heading(f"{name} = {frame}" if frame else name, 3))
        if what:
            out.append(Text(what))
        out.append(Pre("\n".join("".join(f"{v:14.6f}" for v in row) for row in T)))
        xq = xyz_quat(T)
        out.append(table(["x", "y", "z", "qx", "qy", "qz", "qw"],
                         [[f"{v:.6g}" for v in xq[:3]] + [f"{v:.8f}" for v in xq[3:]]], left=0))
        std = (r["std"] or {}).get(name)
        out.append(Text(f"1-sigma: rotation {std['rotation_deg']:.3g} deg, translation {std['translation']:.3g} {unit}"
                        if std else f"1-sigma: not reported by solver {r['solver']} (auto or refine report it)"))
    return out


def _advice(r: Mapping[str, Any]) -> list[Block]:
    rows = advice(r)
    return [Heading("Warnings and what to do"),
            table(["found", "what to do"], rows, left=2) if rows else Text("Nothing to act on.")]


def _residuals(r: Mapping[str, Any]) -> list[Block]:
    item, unit = r["item"], r["unit"] or "data units"
    rot, trans = r["residuals"]["rotation_deg"], r["residuals"]["translation"]
    out: list[Block] = [
        Heading(f"Residuals per {item}"),
        Text(f"Angle and distance between the two sides of the problem's equation ({r['equation']})."),
        table(["", "median", "RMS", "max"], [["rotation [deg]", *(f"{v:.4g}" for v in stats(rot))],
                                             [f"translation [{unit}]", *(f"{v:.4g}" for v in stats(trans))]]),
        Figure("residuals", f"residuals per {item}"),
    ]
    outliers = set(r.get("outliers") or [])
    labels = r.get("labels")
    if r.get("outliers") is not None:
        named = [observation_name(r, k) for k in sorted(outliers)]
        out.append(Text(f"Outliers (auto: {r.get('outlier_test') or ''}): "
                        f"{', '.join(named) or 'none'}; marked in red."))
    marked = [k in outliers for k in range(len(rot))]
    if labels and len(labels) == len(rot):  # several cameras and targets: each row by what it observes
        rows = [[*labels[k], f"{rot[k]:.4g}", f"{trans[k]:.4g}", "outlier" if k in outliers else ""]
                for k in range(len(rot))]
        out.append(table(["station", "camera", "target", "rotation [deg]", f"translation [{unit}]", ""], rows,
                         left=3, marked=marked))
        return out
    rows = [[str(k), pair_label(r, k), f"{rot[k]:.4g}", f"{trans[k]:.4g}", "outlier" if k in outliers else ""]
            for k in range(len(rot))]
    out.append(table([item, "file rows" if r.get("joined") else "file row", "rotation [deg]",
                      f"translation [{unit}]", ""], rows, left=2, marked=marked))
    return out


def _pairs(r: Mapping[str, Any]) -> list[Block]:
    """A cell of several cameras and targets: the residuals per pair of poses (which camera saw
    which target) as a table, and their graph with each edge's RMS residuals."""
    rows = r.get("pair_table")
    if not rows:
        return []
    unit = r["unit"] or "data units"
    keys = [k for k in rows[0] if k in ("X", "Y")]
    frames = r.get("frames", {})
    header = [f"{k} ({frames_word(frames, k)})" for k in keys]
    body = [[*(str(row[k]) for k in keys), str(row["observations"]), f"{row['rotation_rms_deg']:.4g}",
             f"{row['rotation_max_deg']:.4g}", f"{row['translation_rms']:.4g}", f"{row['translation_max']:.4g}"]
            for row in rows]
    return [Heading("Residuals per pair"),
            Text("Each pair of poses the observations tie (a camera and a target), with the RMS and largest "
                 "residuals over its observations: a pair far above the others points at that camera's or "
                 "target's detections."),
            table([*header, "observations", "rotation RMS [deg]", "rotation max [deg]", f"translation RMS [{unit}]",
                   f"translation max [{unit}]"], body, left=len(keys)),
            Figure("graph", "the graph of cameras and targets, each edge with its RMS residuals")]


def frames_word(frames: Mapping[str, Any], unknown: str) -> str:
    """What the poses of `unknown` are, from a frame name of one of them (``T_base_cam0`` ->
    ``in base``), else the unknown's name."""
    symbol = next((v[0] if isinstance(v, (list, tuple)) else v for k, v in frames.items()
                   if k.split("[", 1)[0] == unknown), None)
    return f"in {symbol.split('_')[1]}" if symbol and symbol.count("_") >= 2 else unknown


def _images(r: Mapping[str, Any]) -> list[Block]:
    """The image run: board, intrinsics with their calibration RMS, each image's error, overlays."""
    images = r.get("images")
    if not images:
        return []
    cam = images["camera"]
    K = np.asarray(cam["K"], dtype=float)
    intrinsics = [("board", images["board"]), ("intrinsics", cam["source"]),
                  ("fx, fy [px]", f"{K[0, 0]:.2f}, {K[1, 1]:.2f}"), ("cx, cy [px]", f"{K[0, 2]:.2f}, {K[1, 2]:.2f}"),
                  ("distortion", ", ".join(f"{v:.4g}" for v in cam["dist"]) or "none"),
                  ("image size [px]", "" if cam.get("image_size") is None else "x".join(map(str, cam["image_size"])))]
    if cam.get("rms_px") is not None:
        intrinsics.append(("calibration RMS [px]", f"{cam['rms_px']:.3g} over {cam.get('images', '?')} images"))
    through = any(s.get("calibrated_rms_px") is not None for s in images["stations"])
    rows = [[s["image"], s["robot_pose"] or "", str(s["points"]), f"{s['pnp_rms_px']:.3g}",
             "" if s.get("calibrated_rms_px") is None else f"{s['calibrated_rms_px']:.3g}"] for s in images["stations"]]
    out: list[Block] = [Heading("Images"), table(None, intrinsics, left=2),
                        Text("Each image's reprojection error (RMS over its corners): at the board pose of the image "
                             "alone, and through the robot's pose and the answer"
                             + (" (what the calibration predicts)." if through else ".")),
                        table(["image", "robot pose", "corners", "own pose [px]", "through the robot [px]"], rows,
                              left=2)]
    if images.get("overlays"):
        out.append(Text(f"The {len(images['overlays'])} images the answer predicts worst, around the board: detected "
                        "corners (green circles), reprojected at the image's own board pose (blue +) and predicted "
                        "through the robot's pose and the answer (red x)."))
    by_name = {s["image"]: s for s in images["stations"]}
    for k, overlay in enumerate(images.get("overlays", [])):
        s = by_name.get(overlay["image"], {})
        through = s.get("calibrated_rms_px")
        out.append(Text(f"image {overlay['image']}" + (f" (robot pose {s['robot_pose']})" if s.get("robot_pose") else "")
                        + f": {s.get('pnp_rms_px', float('nan')):.3g} px at its own pose"
                        + ("" if through is None else f", {through:.3g} px predicted")))
        out.append(Figure(f"overlay{k + 1}", f"image {overlay['image']}: detected corners (green circles), at "
                                             "its own pose (blue +), predicted through the robot (red x)"))
    return out


def _diagnostics(r: Mapping[str, Any]) -> list[Block]:
    out: list[Block] = [Heading("Data diagnostics"), table(None, diag_rows(r), left=2)]
    checks = r.get("checks") or {}
    if checks.get("hypotheses"):
        unit = r["unit"] or "data units"
        out.append(Text("Usual setup mistakes tried by the plausibility check (residual RMS of a closed-form fit "
                        "with the mistake undone; score below 1 is plausible), beside the data as given:"))
        rows = []
        base = checks.get("baseline")
        if base:
            rows.append(("the data as given", f"{base['rotation_deg']:.3g}", f"{base['translation']:.3g}",
                         f"{base['score']:.3g}"))
        rows += [(h["description"], f"{h['rotation_deg']:.3g}", f"{h['translation']:.3g}", f"{h['score']:.3g}")
                 for h in checks["hypotheses"][:6]]
        out.append(table(["hypothesis", "rotation [deg]", f"translation [{unit}]", "score"], rows))
    return out


# ----------------------------------------------------------------------------- advice

def advice(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(what was found, what to do) in the user's words, most important first: a curated row for
    what the report's figures show, then every warning of the run that no row covers, with its
    own advice (`own_advice`)."""
    out: list[tuple[str, str]] = []
    covered: set[str] = set()
    warnings = list(r["warnings"])

    def cover(pred: Any) -> list[str]:
        hits = [w for w in warnings if pred(w)]
        covered.update(hits)
        return hits

    status, item, unit = r["status"], r["item"], r["unit"] or "data units"
    checks = r.get("checks") or {}
    if status in ("not_converged", "failed"):
        out.append((f"the solver ended with status {status}: the answer is not usable",
                    "try another solver (handeye list), or check the data"))
    if status == "unreliable" or (checks and not checks.get("plausible", True)):
        expl = checks.get("explanation")
        if expl:
            cover(lambda w: w.startswith("implausible fit"))
            out.append(((f"implausible fit: the residuals drop to {expl['rotation_deg']:.3g} deg / "
                        f"{expl['translation']:.3g} {unit} if {expl['description']}"),
                        f"{expl['suggestion']}, then calibrate again; do not use this answer"))
        elif checks and not checks.get("plausible", True):
            cover(lambda w: w.startswith("implausible fit"))
            out.append((("implausible fit: the residuals are larger than a calibrated cell gives, and none of "
                        "the usual mistakes explains them"),
                        "check the pairing of the two files, their formats and units; do not use this answer"))
    if r.get("outliers"):
        cover(lambda w: "far off the others" in w and "left out" in w)
        if r.get("outlier_stations"):
            rows = ", ".join(str(i + 1) for i in r["outlier_stations"])
            many = len(r["outlier_stations"]) > 1
            what = f"station{'s' if many else ''} (file row{'s' if many else ''}) {rows}"
        elif r.get("labels"):  # several cameras and targets: by station, camera and target
            what = f"{item}{'s' if len(r['outliers']) > 1 else ''} of " + ", ".join(
                observation_name(r, i) for i in r["outliers"])
        else:
            what = f"{item}{'s' if len(r['outliers']) > 1 else ''} " + ", ".join(str(i) for i in r["outliers"])
            if r.get("stations") and r.get("one_per_station"):
                what += (f" (file row{'s' if len(r['outliers']) > 1 else ''} "
                         + ", ".join(str(i + 1) for i in r["outliers"]) + ")")
        many = len(r.get("outlier_stations") or r["outliers"]) > 1
        out.append(((f"{what} {'are' if many else 'is'} far off the others and left out of the answer"),
                    ("check those stations' images (board detection, blur, reflections) and robot poses; "
                     "re-record them or remove them")))
    data = r.get("data") or {}
    precision = cover(lambda w: w.startswith("the data determine the"))
    if any("main rotation axis" in w for w in precision):
        out.append(("the robot rotates mostly about one axis, so the data determine part of the answer poorly",
                    "add poses that rotate about other axes (tilt the flange about x and y, not only z)"))
    elif precision:
        out.append(("the data determine part of the answer poorly at their noise (see the 1-sigma)",
                    "add stations with larger rotations (20-40 deg) about different axes, or reduce the noise"))
    if data.get("likely_mismatched"):
        cover(lambda w: "rotate by a different angle" in w)
        out.append(((f"{item}s {', '.join(str(i) for i in data['likely_mismatched'])} rotate by a different angle "
                    "for the robot than for the camera"),
                    "check that row k of the robot file and of the camera file are the same station"))
    n = r.get("stations") or (len(r["residuals"]["rotation_deg"]) if r.get("one_per_station") else None)
    if n is not None and n < RECOMMENDED_STATIONS:
        cover(lambda w: w.startswith(f"only {n} stations"))
        out.append((f"only {n} stations", (f"record at least {RECOMMENDED_STATIONS} stations (10-20 are usual), "
                                          "spread over the workspace, with varied orientations")))
    if cover(lambda w: "duplicated stations" in w):
        out.append(("some stations repeat the same robot pose", "move the robot between stations"))
    if cover(lambda w: "time stamps" in w or "row names differ" in w):
        out.append(("the two files' rows may not be the same stations",
                    "check that row k of both files is the same station"))
    if r["std"] is None:
        out.append((f"no 1-sigma: solver {r['solver']} does not report uncertainties",
                    "use solver auto (default) or refine to get the 1-sigma of the answer"))
    if status == "uncertified":
        out.append(("status uncertified: a valid answer that the solver could not prove globally optimal",
                    "nothing to do if the residuals are small; solver auto certifies its start"))
    out += [(w, own_advice(w)) for w in warnings if w not in covered]
    return out


def own_advice(warning: str) -> str:
    """What a warning itself says to do: its last clause after "; " outside parentheses when there
    is one (handeye's warnings end with the action), else to read it."""
    depth, cut = 0, -1
    for k, ch in enumerate(warning):
        depth += {"(": 1, ")": -1}.get(ch, 0)
        if depth == 0 and warning.startswith("; ", k):
            cut = k
    return warning[cut + 2:] if cut > 0 else "see the message"


# ----------------------------------------------------------------------------- rows and figures

def xyz_quat(T: Sequence[Sequence[float]]) -> list[float]:
    from scipy.spatial.transform import Rotation

    M = np.asarray(T, dtype=float)
    return [*M[:3, 3].tolist(), *Rotation.from_matrix(M[:3, :3]).as_quat(canonical=True).tolist()]


def stats(values: Sequence[float]) -> tuple[float, float, float]:
    v = np.asarray(values, dtype=float)
    return float(np.median(v)), float(np.sqrt(np.mean(v**2))), float(np.max(v))


def diag_rows(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(name, value) rows of the data diagnostics and the plausibility check."""
    data, unit = r.get("data") or {}, r["unit"] or "data units"
    rows = []
    m = len(r["residuals"]["rotation_deg"])
    if r.get("stations"):
        rows.append(("stations", str(r["stations"])))
    rows.append((f"{r['item']}s", str(m) + (f" ({r['pairing']} pairs of stations)" if r.get("pairing") else "")))
    for name, (s, std) in (r.get("camera_scales") or {}).items():  # a cell's monocular cameras
        rows.append((f"camera scale of {name}", f"{s:.6g}" + ("" if std is None else f" (1-sigma {std:.2g})")
                     + f": its translations times this are in {unit}"))
    if "rotation_excitation" in data:
        rows.append(("rotation excitation", f"{data['rotation_excitation']:.3g} (weak below 1e-4)"))
    if "axis_spread" in data:
        rows.append(("rotation axis spread", f"{math.degrees(data['axis_spread']):.3g} deg (weak below 5.7 deg)"))
    if "largest_rotation" in data:
        between = " between two stations" if r.get("one_per_station") else f" of a {r['item']}"
        rows.append(("largest rotation" + between, f"{math.degrees(data['largest_rotation']):.3g} deg"))
    if "angle_difference_max" in data:
        rows.append(("largest robot/camera angle difference", f"{math.degrees(data['angle_difference_max']):.3g} deg"))
    if "likely_mismatched" in data:
        mis = data["likely_mismatched"]
        rows.append(("likely mismatched motions", ", ".join(map(str, mis)) if mis else "none"))
    if r.get("outliers") is not None:
        rows.append((f"outlying {r['item']}s (left out)",
                     ", ".join(observation_name(r, k) for k in r["outliers"]) or "none"))
    checks = r.get("checks")
    if checks:
        res, lim = checks["residual_rms"], checks["limits"]
        rows.append(("plausibility check", "plausible" if checks["plausible"] else "IMPLAUSIBLE"))
        rows.append(("residual RMS vs limits", (f"{res['rotation_deg']:.3g} deg / {res['translation']:.3g} {unit} "
                                               f"(limits {lim['rotation_deg']:.3g} deg / {lim['translation']:.3g} "
                                               f"{unit})")))
        rows.append(("cell size (lever arm: the largest RMS distance of the flange from its stations' centre or "
                     "from the base, or of the board from the camera)", f"{checks['cell_size']:.4g} {unit}"))
        if checks.get("explanation"):
            e = checks["explanation"]
            rows.append(("best explanation", f"{e['description']} ({e['suggestion']})"))
    else:
        rows.append(("plausibility check", "not run (needs absolute robot and camera poses; off with --no-checks)"))
    return rows


def run_rows(r: Mapping[str, Any]) -> list[tuple[str, str]]:
    rows = [("status", r["status"]), ("solver", f"{r['solver']} (backend {r['backend']})"),
            ("solver time", f"{r['seconds'] * 1e3:.3g} ms" if r["seconds"] < 10 else f"{r['seconds']:.1f} s"),
            ("problem", r["problem"] + (f", {r['setup']}" if r["setup"] else "")),
            ("length unit", r["unit"] or "not stated"), ("handeye version", r["version"])]
    if r.get("command"):
        rows.append(("command", r["command"]))
    return rows + [(k, v) for k, v in r["inputs"].items()]


def status_line(r: Mapping[str, Any]) -> str:
    s = r["status"]
    if s in ("not_converged", "failed"):
        return f"status {s}: the solver did not reach its answer; do not use it"
    if s == "unreliable":
        return "status unreliable: the checks found this answer unusable; do not use it"
    if s == "suboptimal":
        return "status suboptimal: usable, but the data support another fit far better (see the warnings)"
    if s == "uncertified":
        return "status uncertified: a valid answer, not proven globally optimal"
    return f"status {s}"


def pair_label(r: Mapping[str, Any], k: int) -> str:
    if r.get("joined"):
        i, j = r["joined"][k]
        return f"rows {i + 1}-{j + 1}"
    if r.get("stations") and r.get("one_per_station"):
        return f"row {k + 1}"
    return ""


def observation_name(r: Mapping[str, Any], k: int) -> str:
    """Item k in words: in a cell of several cameras and targets its station, camera and target
    (``station s03 (cam1, marker2)``, from ``r["labels"]``), else its index."""
    labels = r.get("labels")
    return "station {} ({}, {})".format(*labels[k]) if labels and 0 <= k < len(labels) else str(k)
