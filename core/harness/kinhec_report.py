"""handeye's tables of a ``handeye bench --kinhec`` run, written beside KinHEC's own outputs.

KinHEC's leaderboard ranks solvers but neither pairs ``handeye:auto`` with KinHEC's best AX=YB
method sequence by sequence nor knows handeye's statuses. From the rows KinHEC's
``run_benchmark`` returns (one per sequence, synchronisation mode and solver, with the
``handeye_*`` columns that handeye.harness.kinhec adds), this module makes (docs/kinhec.md):

- `head_to_head`: ``handeye:auto`` against ``shah+lm`` per sequence, with auto's status;
- `track_summary`: every solver per track: success rate (KinHEC's: a finite answer), share of
  *usable* answers (handeye solvers: a status in `USABLE`), median errors and runtime;
- `auto_vs_best`: per track, auto beside the best KinHEC reference there and beside shah+lm
  (the table the command prints, `auto_vs_best_table`);
- `write_outputs`: the above as markdown and CSV (`HANDEYE_FILES`), headed by the
  `machine_line` the run took when it started.

Plain Python, so that KinHEC's pandas is not needed for them. The KinHEC names of handeye's
solvers (`AXYB_PREFIX`, `AXXB_PREFIX`, `AUTO`) and of the reference (`REFERENCE`) live here, the
module with no dependency on its siblings; handeye.harness.kinhec registers the solvers under them.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
import platform
import statistics
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from handeye.framework.solution import USABLE
from handeye.io.output_files import new_file, write_text


@dataclasses.dataclass
class KinhecRun:
    """What `run_kinhec` produced: KinHEC's rows (with the ``handeye_*`` columns), handeye's
    tables, the output folder and the notes (solvers left out)."""

    rows: list[dict[str, Any]]
    head_to_head: list[dict[str, Any]]
    tracks: list[dict[str, Any]]
    auto_vs_best: list[dict[str, Any]]
    out_dir: Path
    solvers: list[str]
    references: list[str]
    skipped: list[str]
    seconds: float
    kinhec_version: str
    #: `machine_line` taken when the run started (the code a long run uses is the code at its start)
    machine: str


#: KinHEC names of handeye's solvers: ``handeye:<solver>`` for the default problem (AX=YB, on the
#: absolute keyframe poses), ``handeye-<problem>:<solver>`` for another (``handeye-axxb:park``,
#: on the consecutive motions); every such name starts with HANDEYE
HANDEYE = "handeye"
AXYB_PREFIX = HANDEYE + ":"
#: the suffix of a solver's scale-aware variant (camera_scale="unknown"), e.g. handeye:auto+scale
SCALE_SUFFIX = "+scale"
AUTO = AXYB_PREFIX + "auto"
#: KinHEC's best AX=YB method (Shah's closed form + joint LM refinement), the head-to-head reference
REFERENCE = "shah+lm"
#: what this module adds to the output folder of KinHEC's run_benchmark
HANDEYE_FILES = ("handeye_head_to_head.csv", "handeye_head_to_head.md", "handeye_tracks.csv", "handeye_tracks.md")
#: head-to-head: auto's X translation error above this multiple of shah+lm's is counted as worse
WORSE_FACTOR = 1.05


def _num(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _text(value: Any) -> str:
    return value if isinstance(value, str) else ""


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return statistics.median(finite) if finite else math.nan


def _ratio(a: float, b: float) -> float:
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan


def _ok(row: Mapping[str, Any]) -> bool:
    return bool(row.get("ok")) and math.isfinite(_num(row.get("X_rot_err_deg")))


def _groups(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> dict[tuple[Any, ...], list[Mapping[str, Any]]]:
    out: dict[tuple[Any, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        out.setdefault(tuple(row.get(k) for k in keys), []).append(row)
    return dict(sorted(out.items(), key=lambda kv: tuple(str(k) for k in kv[0])))


def head_to_head(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """One row per (sequence, synchronisation mode): `AUTO` against `REFERENCE` (X errors in
    degrees and millimetres, their ratios auto / shah+lm, the runtime ratio) with auto's status."""
    out = []
    for (sequence, sync), group in _groups(rows, ("sequence_id", "eval_sync")).items():
        by = {r.get("solver"): r for r in group}
        auto, ref = by.get(AUTO), by.get(REFERENCE)
        if auto is None or ref is None:
            continue
        a_rot, a_trans = (_num(auto.get(k)) if _ok(auto) else math.nan for k in ("X_rot_err_deg", "X_trans_err_mm"))
        r_rot, r_trans = (_num(ref.get(k)) if _ok(ref) else math.nan for k in ("X_rot_err_deg", "X_trans_err_mm"))
        a_ms, r_ms = _num(auto.get("runtime_ms")), _num(ref.get("runtime_ms"))
        note = _text(auto.get("error")) or _text(auto.get("handeye_note"))
        out.append({
            "sequence_id": sequence, "track": auto.get("track"), "level": auto.get("level"),
            "robot": auto.get("robot"), "configuration": auto.get("configuration"), "eval_sync": sync,
            "n_keyframes": int(_num(auto.get("n_motions"))) + 1 if math.isfinite(_num(auto.get("n_motions"))) else "",
            "auto_ok": _ok(auto), "auto_status": _text(auto.get("handeye_status")) or ("raised" if not _ok(auto) else ""),
            "auto_X_rot_deg": a_rot, "auto_X_trans_mm": a_trans,
            "shah_lm_ok": _ok(ref), "shah_lm_X_rot_deg": r_rot, "shah_lm_X_trans_mm": r_trans,
            "rot_ratio": _ratio(a_rot, r_rot), "trans_ratio": _ratio(a_trans, r_trans),
            "auto_ms": a_ms, "shah_lm_ms": r_ms, "time_ratio": _ratio(a_ms, r_ms),
            "auto_note": note,
        })
    return out


def kinhec_prefix(problem: str, default_problem: str) -> str:
    """The KinHEC name prefix of handeye's solvers of `problem` (see `AXYB_PREFIX`)."""
    return AXYB_PREFIX if problem == default_problem else f"{HANDEYE}-{problem}:"


def is_handeye(name: Any) -> bool:
    """Whether KinHEC solver `name` is one of handeye's (`prefix`)."""
    return isinstance(name, str) and name.startswith(HANDEYE) and ":" in name


def _kind(name: str) -> str:
    if not is_handeye(name):
        return "KinHEC reference"
    group = name.split(":", 1)[0]
    return "handeye" if group == HANDEYE else f"handeye {group[len(HANDEYE) + 1:]}"


def track_summary(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (track, synchronisation mode, solver): sequences, success rate (KinHEC's: a finite
    answer), usable rate (handeye solvers: success with a `USABLE` status), median X and Y errors
    over the successes, median runtime and its ratio to shah+lm's; sorted by median X translation
    error within a track, as KinHEC's leaderboard."""
    out = []
    for (track, sync), group in _groups(rows, ("track", "eval_sync")).items():
        per_solver = _groups(group, ("solver",))
        ref_ms = _median([_num(r.get("runtime_ms")) for r in per_solver.get((REFERENCE,), []) if _ok(r)])
        block = []
        for (solver,), runs in per_solver.items():
            ok = [r for r in runs if _ok(r)]
            handeye = is_handeye(solver)
            usable = sum(1 for r in ok if _text(r.get("handeye_status")) in USABLE) / len(runs) if handeye else math.nan
            ms = _median([_num(r.get("runtime_ms")) for r in ok])
            block.append({
                "track": track, "eval_sync": sync, "solver": solver, "kind": _kind(str(solver)), "n": len(runs),
                "success_rate": len(ok) / len(runs), "usable_rate": usable,
                **{f"{k}_median": _median([_num(r.get(k)) for r in ok])
                   for k in ("X_rot_err_deg", "X_trans_err_mm", "Y_rot_err_deg", "Y_trans_err_mm")},
                "runtime_ms_median": ms, "time_ratio_to_shah_lm": _ratio(ms, ref_ms),
            })
        block.sort(key=lambda s: (not math.isfinite(s["X_trans_err_mm_median"]), s["X_trans_err_mm_median"]))
        out += block
    return out


def auto_vs_best(rows: Sequence[Mapping[str, Any]], references: Sequence[str]) -> list[dict[str, Any]]:
    """Per (track, synchronisation mode), and over every sequence (track "all", oracle
    synchronisation): `AUTO`'s medians beside those of the KinHEC reference with the lowest median
    X translation error there, and of shah+lm; auto's success and usable rates, the median X
    translation errors of auto and shah+lm over the sequences both answered ("paired": each
    solver's own medians leave out the sequences it refused, which are the hardest), the median of
    auto's per-sequence runtime ratio to shah+lm, and the sequences where its X translation error
    exceeds `WORSE_FACTOR` times shah+lm's."""
    pairs = head_to_head(rows)
    summary = track_summary(rows)
    cells = list(dict.fromkeys((r["track"], r["eval_sync"]) for r in summary))
    out = []
    for track, sync in [*cells, ("all", "oracle")]:
        if track == "all":
            pooled = [r for r in rows if r.get("eval_sync") == "oracle"]
            stats = {r["solver"]: r for r in track_summary([{**r, "track": "all"} for r in pooled])}
            seqs = [p for p in pairs if p["eval_sync"] == "oracle"]
        else:
            stats = {r["solver"]: r for r in summary if r["track"] == track and r["eval_sync"] == sync}
            seqs = [p for p in pairs if p["track"] == track and p["eval_sync"] == sync]
        auto = stats.get(AUTO)
        if auto is None:
            continue
        refs = [stats[n] for n in references if n in stats and math.isfinite(stats[n]["X_trans_err_mm_median"])]
        best = min(refs, key=lambda s: s["X_trans_err_mm_median"]) if refs else None
        shah = stats.get(REFERENCE, {})
        both = [p for p in seqs if p["auto_ok"] and p["shah_lm_ok"]]
        worse = sum(1 for p in seqs if math.isfinite(p["trans_ratio"]) and p["trans_ratio"] > WORSE_FACTOR)
        flagged = sum(1 for p in seqs if p["auto_status"] != "optimal")
        out.append({
            "track": track, "eval_sync": sync, "n": auto["n"],
            "auto_success_rate": auto["success_rate"], "auto_usable_rate": auto["usable_rate"],
            "auto_X_rot_deg": auto["X_rot_err_deg_median"], "auto_X_trans_mm": auto["X_trans_err_mm_median"],
            "best_reference": best["solver"] if best else "",
            "best_X_rot_deg": best["X_rot_err_deg_median"] if best else math.nan,
            "best_X_trans_mm": best["X_trans_err_mm_median"] if best else math.nan,
            "shah_lm_X_rot_deg": shah.get("X_rot_err_deg_median", math.nan),
            "shah_lm_X_trans_mm": shah.get("X_trans_err_mm_median", math.nan),
            "paired_n": len(both),
            "paired_auto_X_trans_mm": _median([p["auto_X_trans_mm"] for p in both]),
            "paired_shah_lm_X_trans_mm": _median([p["shah_lm_X_trans_mm"] for p in both]),
            "time_ratio_to_shah_lm": _median([p["time_ratio"] for p in seqs]),
            "auto_worse_than_shah_lm": worse, "auto_not_optimal": flagged,
        })
    return out


def _fmt(value: float, digits: int = 3) -> str:
    return "-" if not math.isfinite(value) else f"{value:.{digits}f}"


def _pct(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{100 * value:.0f}%"


def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("|", "/") for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def auto_vs_best_table(summary: Sequence[Mapping[str, Any]]) -> str:
    """`auto_vs_best` as a markdown table (also what the command prints)."""
    header = ["track", "sync", "n", "auto succ.", "auto usable", "auto X rot [deg]", "auto X trans [mm]",
              "best reference", "best X rot [deg]", "best X trans [mm]", "shah+lm X rot [deg]",
              "shah+lm X trans [mm]", "paired X trans: auto / shah+lm (n)", "time / shah+lm",
              f"auto > {WORSE_FACTOR:g}x shah+lm", "auto not optimal"]
    body = [[str(r["track"]), str(r["eval_sync"]), str(r["n"]), _pct(r["auto_success_rate"]),
             _pct(r["auto_usable_rate"]), _fmt(r["auto_X_rot_deg"]), _fmt(r["auto_X_trans_mm"]),
             r["best_reference"] or "-", _fmt(r["best_X_rot_deg"]), _fmt(r["best_X_trans_mm"]),
             _fmt(r["shah_lm_X_rot_deg"]), _fmt(r["shah_lm_X_trans_mm"]),
             f"{_fmt(r['paired_auto_X_trans_mm'])} / {_fmt(r['paired_shah_lm_X_trans_mm'])} ({r['paired_n']})",
             _fmt(r["time_ratio_to_shah_lm"], 2),
             str(r["auto_worse_than_shah_lm"]), str(r["auto_not_optimal"])] for r in summary]
    return _md_table(header, body)


def _write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with new_file(path, force=True, newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()})


def machine_line(kinhec_version: str) -> str:
    """When and where: date, machine, load, versions (handeye's with its git commit when it runs
    from a checkout, ``+dirty`` with uncommitted changes: the figures belong to that code)."""
    from handeye import __version__

    load = " ".join(f"{v:.2f}" for v in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {platform.machine()}, {os.cpu_count()} cores, "
            f"load average {load}; python {platform.python_version()}, handeye {__version__}{_git_commit()}, "
            f"kinhec {kinhec_version}")


def _git_commit() -> str:
    """`` (git abc1234)`` / `` (git abc1234+dirty)`` for a checkout, else ``""``."""
    import subprocess

    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(here), "rev-parse", "--short", "HEAD"], check=False,
                              capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return ""
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
                               check=False, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return ""
    return f" (git {head.stdout.strip()}{'+dirty' if dirty.stdout.strip() else ''})"


def write_outputs(run: KinhecRun, data_dir: Path) -> list[Path]:
    """Write `HANDEYE_FILES` to ``run.out_dir``; return their paths."""
    out = run.out_dir
    out.mkdir(parents=True, exist_ok=True)
    head = (f"KinHEC protocol (kinhec.benchmark.run_benchmark) on {data_dir}: "
            f"{len({r.get('sequence_id') for r in run.rows})} sequences, {len(run.solvers)} solvers, "
            f"{run.seconds:.0f} s; started {run.machine}.")
    _write_csv(out / "handeye_head_to_head.csv", run.head_to_head)
    _write_csv(out / "handeye_tracks.csv", run.tracks)
    per_seq = [[str(p["sequence_id"]), str(p["track"]), str(p["eval_sync"]), str(p["robot"]), str(p["n_keyframes"]),
                p["auto_status"], _fmt(p["auto_X_rot_deg"]), _fmt(p["auto_X_trans_mm"]), _fmt(p["shah_lm_X_rot_deg"]),
                _fmt(p["shah_lm_X_trans_mm"]), _fmt(p["rot_ratio"], 2), _fmt(p["trans_ratio"], 2),
                _fmt(p["time_ratio"], 2), p["auto_note"][:120]] for p in run.head_to_head]
    text = [
        "# handeye:auto against KinHEC's shah+lm", "", head, "",
        (f"X errors: rotation [deg], translation [mm], medians over the sequences a solver answered. `usable`: "
         f"answered with status {', '.join(USABLE)}. `best reference`: the KinHEC reference solver with the lowest "
         f"median X translation error on the track. `paired`: medians over the sequences both auto and shah+lm "
         f"answered. `time / shah+lm`: median over the sequences of auto's "
         f"runtime over shah+lm's (KinHEC's timing: the whole handeye.solve call)."), "",
        "## Per track", "", auto_vs_best_table(run.auto_vs_best), "",
        "## Per sequence", "",
        _md_table(["sequence", "track", "sync", "robot", "keyframes", "auto status", "auto X rot", "auto X trans",
                   "shah+lm X rot", "shah+lm X trans", "rot ratio", "trans ratio", "time ratio", "note"], per_seq),
        "",
    ]
    write_text(out / "handeye_head_to_head.md", "\n".join(text), force=True)
    blocks = ["# Every solver per KinHEC track", "", head, "",
              "Medians over the sequences a solver answered (`succ.`: KinHEC's success, a finite answer; `usable`: "
              "handeye solvers only, answered with status " + ", ".join(USABLE) + "); sorted by median X "
              "translation error. Runtime: KinHEC's timing of the solver callable.", ""]
    for (track, sync), group in _groups(run.tracks, ("track", "eval_sync")).items():
        blocks += [f"## {track} ({sync} synchronisation)", "", _md_table(
            ["solver", "kind", "n", "succ.", "usable", "X rot [deg]", "X trans [mm]", "Y rot [deg]", "Y trans [mm]",
             "runtime [ms]", "time / shah+lm"],
            [[str(s["solver"]), s["kind"], str(s["n"]), _pct(s["success_rate"]), _pct(s["usable_rate"]),
              _fmt(s["X_rot_err_deg_median"]), _fmt(s["X_trans_err_mm_median"]), _fmt(s["Y_rot_err_deg_median"]),
              _fmt(s["Y_trans_err_mm_median"]), _fmt(s["runtime_ms_median"], 1), _fmt(s["time_ratio_to_shah_lm"], 2)]
             for s in sorted(group, key=lambda s: (not math.isfinite(s["X_trans_err_mm_median"]),
                                                   s["X_trans_err_mm_median"]))]), ""]
    write_text(out / "handeye_tracks.md", "\n".join(blocks), force=True)
    return [out / name for name in HANDEYE_FILES]
