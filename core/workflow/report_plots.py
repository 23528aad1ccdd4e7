"""The plots of the quality report (handeye.workflow.quality_report), as PNG bytes, drawn with matplotlib's
Agg backend (imported here, lazily: ``import handeye`` and the solvers never import matplotlib).

- ``residuals``: the per-pair residuals of the problem's equation (eqs. 32-33: rotation angle in
  deg, translation distance in the data unit) as bars, the outliers auto left out in red; in a
  cell of several cameras and targets each tick named by its station, camera and target;
- ``poses``: a 3D view, in the robot's base frame and unit, of the flange positions (the robot
  poses' translations), the base frame and the solved frames as axis triads (x red, y green,
  z blue): the frames A_i X at each station (eye-in-hand: the camera; eye-to-hand axyb: the
  target) and the fixed unknown (Y, or X = T_base_cam for axxb eye-to-hand).

Long recordings are drawn in bounded time and memory: dots instead of bars beyond `BARS_UP_TO`
pairs, the solved frame's axes at `TRIADS_UP_TO` evenly spread stations.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

INLIER_COLOUR = "#4c72b0"
OUTLIER_COLOUR = "#d62728"
AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")
DPI = 100
#: the stations are numbered (file rows) in the 3D plot up to this many
LABELS_UP_TO = 25
#: residuals are bars up to this many pairs, dots beyond (a bar per pair of a 12,000-station
#: recording took minutes and gigabytes to draw)
BARS_UP_TO = 200
#: the 3D plot draws the solved frame's axes at this many stations at most, evenly spread
TRIADS_UP_TO = 100


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    _pyplot().close(fig)
    return buf.getvalue()


def draw_all(r: Mapping[str, Any]) -> dict[str, bytes]:
    """name -> PNG bytes of every plot the report's data `r` allows: the residuals, the poses,
    and for an image run the corner overlays of its worst images (``overlay1``, ...;
    `handeye.workflow.report_images.overlay_png`)."""
    images = {"residuals": residual_plot(r)}
    if r.get("robot_poses") is not None:
        images["poses"] = pose_plot(r)
    if r.get("pair_table"):
        images["graph"] = graph_plot(r)
    if r.get("images"):
        from handeye.workflow.report_images import overlay_png

        for k, entry in enumerate(r["images"].get("overlays", [])):
            png = overlay_png(entry)
            if png is not None:
                images[f"overlay{k + 1}"] = png
    return images


def observation_ticks(labels: Sequence[Sequence[str]], outliers: set[int], step: int) -> tuple[list[int], list[str]]:
    """The residual plot's ticks of a cell of several cameras and targets and their texts
    (``s03 cam1 marker2``): every `step`-th observation and every outlier, the ticks next to an
    outlier left out so that its name stays readable."""
    m = len(labels)
    marked = {k for k in outliers if 0 <= k < m}
    ticks = sorted(marked | {k for k in range(0, m, step) if not marked & {k - 1, k + 1}})
    return ticks, [" ".join(map(str, labels[k])) for k in ticks]


def residual_plot(r: Mapping[str, Any]) -> bytes:
    plt = _pyplot()
    rot = np.asarray(r["residuals"]["rotation_deg"], dtype=float)
    trans = np.asarray(r["residuals"]["translation"], dtype=float)
    m = len(rot)
    outliers = set(r.get("outliers") or [])
    colours = [OUTLIER_COLOUR if k in outliers else INLIER_COLOUR for k in range(m)]
    fig, axes = plt.subplots(2, 1, figsize=(max(6.0, min(14.0, 0.25 * m + 3)), 5.0), sharex=True)
    unit = r.get("unit") or "data units"
    index = np.arange(m)
    flagged = np.zeros(m, dtype=bool)
    flagged[[k for k in outliers if 0 <= k < m]] = True
    for ax, values, label in ((axes[0], rot, "rotation [deg]"), (axes[1], trans, f"translation [{unit}]")):
        if m <= BARS_UP_TO:
            ax.bar(index, values, color=colours, width=0.8)
        else:
            ax.plot(index[~flagged], values[~flagged], ".", ms=2, color=INLIER_COLOUR)
            ax.plot(index[flagged], values[flagged], ".", ms=4, color=OUTLIER_COLOUR)
        ax.axhline(float(np.median(values)), color="#555", lw=0.8, ls="--", label="median")
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    step = max(1, int(np.ceil(m / 40)))
    axes[1].set_xticks(np.arange(0, m, step))
    axes[1].set_xlabel(r["item"])
    labels = r.get("labels")
    if labels and len(labels) == m:  # several cameras and targets: each tick by station, camera and target
        ticks, texts = observation_ticks(labels, outliers, step)
        axes[1].set_xticks(ticks, texts, rotation=90, fontsize="x-small")
        axes[1].set_xlabel(f"{r['item']} (station camera target)")
    from matplotlib.patches import Patch

    handles = [Patch(color=INLIER_COLOUR, label=r["item"])]
    if outliers:
        handles.append(Patch(color=OUTLIER_COLOUR, label="outlier (left out)"))
    handles.append(next(line for line in axes[0].get_lines() if line.get_label() == "median"))
    axes[0].legend(handles=handles, loc="upper right", fontsize="small")
    axes[0].set_title(f"residuals per {r['item']} ({r['equation']})")
    fig.tight_layout()
    return _png(fig)


#: a cell with more observed pairs than this is drawn as a table of cameras and targets
#: (`pair_matrix`): a real rig's 73 edges were unreadable as a graph
GRAPH_MAX_EDGES = 24


def graph_plot(r: Mapping[str, Any]) -> bytes:
    """The observation graph of a cell of several cameras and targets (`r["pair_table"]`): the
    poses of one unknown in a column on the left, the other's on the right, an edge per pair
    observed, its width growing with its observations and its colour with its RMS rotation
    residual, labelled with its RMS residuals (deg, data unit). More than `GRAPH_MAX_EDGES`
    pairs: `pair_matrix` instead."""
    rows = r["pair_table"]
    if len(rows) > GRAPH_MAX_EDGES:
        return pair_matrix(r)
    plt = _pyplot()
    keys = [k for k in rows[0] if k in ("X", "Y")][:2]
    left = list(dict.fromkeys(row[keys[0]] for row in rows))
    right = list(dict.fromkeys(row[keys[1]] for row in rows))
    y_of = lambda names: {n: (len(names) - 1) / 2 - k for k, n in enumerate(names)}  # noqa: E731
    yl, yr = y_of(left), y_of(right)
    rot = np.array([row["rotation_rms_deg"] for row in rows])
    top = float(rot.max()) or 1.0
    most = max(row["observations"] for row in rows)
    cmap = plt.get_cmap("viridis")
    height = max(len(left), len(right))
    fig, ax = plt.subplots(figsize=(7.5, max(3.0, 0.9 * height + 1.0)))
    unit = r.get("unit") or "data units"
    for row, value in zip(rows, rot):
        a, b = (0.0, yl[row[keys[0]]]), (1.0, yr[row[keys[1]]])
        ax.plot([a[0], b[0]], [a[1], b[1]], color=cmap(value / top), lw=1.0 + 3.0 * row["observations"] / most,
                alpha=0.85, zorder=1)
        # labels spread along the edges by their right end, so that a node's edges do not stack them
        t = 0.22 + 0.56 * (right.index(row[keys[1]]) / max(1, len(right) - 1)) if len(right) > 1 else 0.5
        ax.text(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]),
                f"{value:.3g}° {row['translation_rms']:.3g} {unit}", fontsize=7, ha="center",
                va="center", bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8}, zorder=2)
    for x, names, ys, colour in ((0.0, left, yl, "#4c72b0"), (1.0, right, yr, "#dd8452")):
        for n in names:
            ax.scatter([x], [ys[n]], s=420, color=colour, zorder=3)
            ax.text(x + (-0.06 if x == 0 else 0.06), ys[n], n, ha="right" if x == 0 else "left", va="center",
                    fontsize=9, zorder=4)
    frames = r.get("frames", {})
    for x, key in ((0.0, keys[0]), (1.0, keys[1])):
        symbol = next((v[0] if isinstance(v, (list, tuple)) else v for k, v in frames.items()
                       if k.split("[", 1)[0] == key), None)
        ax.text(x, (height - 1) / 2 + 0.8, key + (f" ({symbol.split('_')[1]} frame)" if symbol else ""),
                ha="center", fontsize=10, weight="bold")
    ax.set_xlim(-0.6, 1.6)
    ax.set_ylim(-(height - 1) / 2 - 0.8, (height - 1) / 2 + 1.2)
    ax.axis("off")
    ax.set_title("which camera saw which target: edges labelled with their RMS residuals\n"
                 "(rotation, translation; width: observations, colour: RMS rotation)", fontsize=10)
    return _png(fig)


def pair_matrix(r: Mapping[str, Any]) -> bytes:
    """The pairs of a large cell as a table: one unknown's poses in rows, the other's in columns,
    each observed pair a cell coloured by its RMS rotation residual and labelled with it and its
    observations; pairs never observed left blank."""
    plt = _pyplot()
    rows = r["pair_table"]
    keys = [k for k in rows[0] if k in ("X", "Y")][:2]
    down = list(dict.fromkeys(row[keys[0]] for row in rows))
    across = list(dict.fromkeys(row[keys[1]] for row in rows))
    rot = np.full((len(down), len(across)), np.nan)
    for row in rows:
        rot[down.index(row[keys[0]]), across.index(row[keys[1]])] = row["rotation_rms_deg"]
    fig, ax = plt.subplots(figsize=(1.0 + 0.9 * len(across), 1.2 + 0.45 * len(down)))
    image = ax.imshow(rot, cmap="viridis", aspect="auto")
    for row in rows:
        i, j = down.index(row[keys[0]]), across.index(row[keys[1]])
        ax.text(j, i, f"{row['rotation_rms_deg']:.2g}°\n{row['observations']}", ha="center", va="center", fontsize=6,
                color="white" if row["rotation_rms_deg"] < 0.6 * np.nanmax(rot) else "black")
    ax.set_xticks(range(len(across)), across, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(down)), down, fontsize=7)
    ax.set_xlabel(keys[1])
    ax.set_ylabel(keys[0])
    fig.colorbar(image, ax=ax, label="RMS rotation residual (deg)")
    ax.set_title(f"which {keys[0]} was seen with which {keys[1]}: {len(rows)} pairs\n(cell: RMS rotation residual, "
                 "observations; blank: never seen together)", fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _parent(frame: str | None) -> str | None:
    """'T_flange_cam' -> 'flange' (None: no frame name)."""
    if not frame or not frame.startswith("T_") or frame.count("_") < 2:
        return None
    return frame.split("_", 2)[1]


def _child(frame: str | None, default: str) -> str:
    """'T_flange_cam' -> 'cam'."""
    if not frame or not frame.startswith("T_") or frame.count("_") < 2:
        return default
    return frame.split("_", 2)[2]


def _triad(ax: Any, T: np.ndarray, size: float, label: str | None = None, lw: float = 1.5) -> None:
    o = T[:3, 3]
    for k in range(3):
        e = o + size * T[:3, k]
        ax.plot([o[0], e[0]], [o[1], e[1]], [o[2], e[2]], color=AXIS_COLOURS[k], lw=lw)
    if label:
        ax.text(o[0], o[1], o[2], " " + label, fontsize=8)


def pose_plot(r: Mapping[str, Any]) -> bytes:
    plt = _pyplot()
    A = np.asarray(r["robot_poses"], dtype=float)
    U = {k: np.asarray(v, dtype=float) for k, v in r["unknowns"].items()}
    frames = {k: v[0] for k, v in r.get("frames", {}).items()}
    per_station, fixed = {}, {}
    for name, T in U.items():  # a pose in the flange frame moves with each station, one in the base stays
        parent = _parent(frames.get(name)) or {"X": "flange", "Y": "base"}.get(name)  # no setup: as AX=YB's
        if parent == "flange":
            per_station[_child(frames.get(name), f"A_i {name}")] = A @ T
        elif parent == "base":
            fixed[_child(frames.get(name), name)] = T
    points = [A[:, :3, 3], np.zeros((1, 3)), *(T[:, :3, 3] for T in per_station.values()),
              *(T[None, :3, 3] for T in fixed.values())]
    allp = np.concatenate(points)
    span = float(np.max(np.ptp(allp, axis=0))) or 1.0
    size = 0.08 * span
    fig = plt.figure(figsize=(7.0, 6.0))
    ax = fig.add_subplot(projection="3d")
    ax.plot(*A[:, :3, 3].T, color="#888", lw=0.6, alpha=0.6)
    ax.scatter(*A[:, :3, 3].T, color="k", s=14, label="flange positions (robot poses)", depthshade=False)
    if len(A) <= LABELS_UP_TO:
        for k, p in enumerate(A[:, :3, 3]):
            ax.text(*p, f" {k + 1}", fontsize=7, color="#444")
    _triad(ax, np.eye(4), 1.5 * size, "base", lw=2.5)
    shown = np.unique(np.linspace(0, len(A) - 1, min(len(A), TRIADS_UP_TO)).round().astype(int))
    for name, stack in per_station.items():
        for T in stack[shown]:
            _triad(ax, T, 0.6 * size, lw=1.0)
        ax.scatter(*stack[:, :3, 3].T, color="#9467bd", s=8, label=f"{name} at each station (A_i X)",
                   depthshade=False)
    for name, T in fixed.items():
        _triad(ax, T, 1.5 * size, name, lw=2.5)
    centre = 0.5 * (allp.max(axis=0) + allp.min(axis=0))
    half = 0.55 * span
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    unit = r.get("unit") or "data units"
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.set_zlabel(f"z [{unit}]")
    ax.set_title("robot base frame: flange positions and the solved frames\n(axes: x red, y green, z blue)",
                 fontsize=10)
    ax.legend(loc="upper left", fontsize="small")
    return _png(fig)
