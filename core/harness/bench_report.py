"""The speed benchmark's results as text (`handeye.harness.bench`): the tables of call and run
times with the ratio to the reference row, one verdict line per speed target, the rows of a
registered solver beside the same method called directly, the line describing the data, and the
JSON payload of ``handeye bench --json``. Everything is read from a `BenchRun` and the problem's
`BenchSettings`; nothing here names a problem.
"""

from __future__ import annotations

from typing import Any

from handeye.harness.bench import BenchRun, reference_name, row_label
from handeye.host.registry import get_registry

#: width of a table's time column
COLUMN = 20


def fmt_seconds(seconds: float | None) -> str:
    """"1.23 ms" below a second, "1.23 s" above; "-" for no value."""
    if seconds is None:
        return "-"
    ms = seconds * 1e3
    return f"{ms:.3g} ms" if ms < 1000 else f"{seconds:.3g} s"


def data_line(run: BenchRun) -> str:
    """What the data were (the problem's `BenchSettings.data_note`, filled with the seed and the
    noise); by default its simulator with the noise on every data stack."""
    problem = get_registry().problem(run.problem)
    note = problem.bench.data_note
    if note is None:
        fields = list(problem.data_fields)
        stacks = " and ".join([", ".join(fields[:-1]), fields[-1]]) if len(fields) > 1 else fields[0]
        note = f"PROBLEM.simulate(seed={{seed}}), noise on {stacks}: {{rot:g}} rad, {{trans:g}} mm"
    return note.format(seed=run.seed, rot=run.noise_rot, trans=run.noise_trans)


def table(run: BenchRun, which: str) -> str:
    """Rows x m: median `which` ("call" or "run") time and, for "call", the ratio to the
    reference row at the same m; "*" marks a single solve over the budget."""
    rows, cells, reference = run.rows, run.cells, run.reference
    width = max(len(r.label) for r in rows) + 2
    lines = [f"{'solver/backend [options]':<{width}}" + "".join(f"{'m=' + str(m):>{COLUMN}}" for m in run.pairs)]
    for row in rows:
        text = f"{row.label:<{width}}"
        for m in run.pairs:
            cell = cells[(row.label, m)]
            value = getattr(cell, which)
            if cell.note and value is None:
                text += f"{cell.note[:COLUMN - 2]:>{COLUMN}}"
                continue
            entry = fmt_seconds(value)
            ref = cells.get((reference, m))
            if which == "call" and ref is not None and ref.call and value is not None:
                entry += f" {value / ref.call:6.2f}x"
            if cell.note.startswith("single"):
                entry += "*"
            text += f"{entry:>{COLUMN}}"
        lines.append(text.rstrip())
    return "\n".join(lines)


def target_lines(run: BenchRun) -> list[str]:
    """One line per target of the problem: what it is, the measured value and PASS / MISS (or
    why it could not be judged). A ratio target also gives the ratio to the first direct row
    when that is not the reference."""
    registry = get_registry()
    settings = run.settings
    name = reference_name(settings, run.rows)
    direct_label = next((row.label for row in run.rows if row.direct is not None), None)
    lines = []
    for t in settings.targets:
        spec = registry.solvers.get(t.solver, {}).get(run.problem)
        backend = t.backend or (spec.default_backend if spec else "?")
        label = row_label(t.solver, backend, t.options)
        by = t.against or name
        limit = f"< {t.seconds * 1e3:g} ms" if t.seconds is not None else f"< {t.ratio:g}x {by}"
        head = f"  target: {label:<34} m={t.pairs:<6} {limit:<22}"
        cell = run.cells.get((label, t.pairs))
        ref = run.cells.get((t.against or run.reference, t.pairs))
        direct = run.cells.get((direct_label, t.pairs)) if direct_label else None
        if spec is None:
            lines.append(f"{head} n/a: solver {t.solver!r} is not registered")
        elif backend not in spec.backends:
            lines.append(f"{head} n/a: {t.solver!r} has no backend {backend!r}")
        elif t.pairs not in run.pairs:
            lines.append(f"{head} n/a: m={t.pairs} not measured (add it to --pairs)")
        elif cell is None:
            lines.append(f"{head} n/a: not measured ({spec.unavailable_reason(backend) or 'not selected'})")
        elif cell.call is None:
            lines.append(f"{head} MISS: {(cell.error or cell.note)[:80]}")
        elif t.seconds is not None:
            verdict = "PASS" if cell.call < t.seconds else "MISS"
            if verdict == "MISS" and cell.run is not None and cell.run < t.seconds:
                verdict += " (solver run alone would pass)"
            lines.append(f"{head} {fmt_seconds(cell.call)} (run {fmt_seconds(cell.run)})  {verdict}")
        elif ref is None or not ref.call:
            lines.append(f"{head} n/a: {by} not measured")
        else:
            ratio = cell.call / ref.call
            verdict = "PASS" if ratio < t.ratio else "MISS"
            vs_direct = (f", {cell.call / direct.call:.2f}x {direct_label}"
                         if direct and direct.call and direct is not ref else "")
            lines.append(f"{head} {ratio:.2f}x ({fmt_seconds(cell.call)} vs {fmt_seconds(ref.call)}"
                         f"{vs_direct})  {verdict}")
    return lines


def same_method_lines(run: BenchRun) -> list[str]:
    """For every direct row naming its `BenchRow.same_method` whose solver was timed (its plain
    row): that solver's call time over the direct row's, per m."""
    lines = []
    for direct in run.settings.direct_rows:
        if direct.same_method is None:
            continue
        row = next((r for r in run.rows if r.solver == direct.same_method and not r.options), None)
        if row is None:
            continue
        ratios = []
        for m in run.pairs:
            ours, theirs = run.cells.get((row.label, m)), run.cells.get((direct.label, m))
            if ours and theirs and ours.call and theirs.call:
                ratios.append(f"m={m}: {ours.call / theirs.call:.2f}x ({fmt_seconds(ours.call)} vs {fmt_seconds(theirs.call)})")
            else:
                ratios.append(f"m={m}: -")
        lines.append(f"  {row.label:<20} vs {direct.label:<22} " + ", ".join(ratios))
    return lines


def errors(run: BenchRun) -> dict[tuple[str, int], str]:
    """(row label, m) -> the exception of each cell whose solve raised."""
    return {(label, m): c.error for (label, m), c in run.cells.items() if c.error}


def payload(run: BenchRun) -> dict[str, Any]:
    """Every timing of the run with its settings, targets and notes (``handeye bench --json``)."""
    return {
        "machine": run.machine, "problem": run.problem, "pairs": run.pairs, "repeats": run.repeats,
        "seed": run.seed, "noise": {"rot": run.noise_rot, "trans": run.noise_trans}, "reference": run.reference,
        "cells": [{"row": label, "m": m, "warmup": c.warmup, "calls": c.calls, "runs": c.runs,
                   "median_call": c.call, "median_run": c.run, "note": c.note, "error": c.error}
                  for (label, m), c in run.cells.items()],
        "targets": target_lines(run), "same_method": same_method_lines(run), "unavailable": run.unavailable,
    }

