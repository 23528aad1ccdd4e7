"""auto's step for a cell of several cameras and targets (A_i X_j = Y_k B_i, ``axyb-multi``,
docs/solvers/auto.md, step 6): a length factor for each marker or camera whose translations fit
the robot's only at another scale, fitted where held-out stations say it predicts better.

A marker printed at another size than the one stated, or a camera's focal length off, scales the
distances of its PnP poses (docs/camera-scale.md, "Several cameras"). The host's check 5 per group
(`handeye.checks.scale_checks.camera_scales_named`) screens auto's answer in-sample; the arm's
systematic errors can mimic a scale there, so where it names any group, held-out prediction
decides between four models: no factor, a factor for each group it named, one for every X, one
for every Y. Over HELD_OUT_BLOCKS contiguous blocks of the stations (numbered in the order the data
give them, so that a recording's neighbours leave together), `refine` is fitted from auto's answer
on the other stations' observations (those auto kept) and predicts every left-out observation:
A_i X_j against Y_k B_i, the camera's translation times the fit's factor. Of the models whose
median translation residual is lower than no factor's by HELD_OUT_GAIN, with a rotation median no
more than ROTATION_TOLERANCE times no factor's, the one with the fewest factors, unless one with
more is lower again by HELD_OUT_GAIN, is fitted by auto's pipeline
(``camera_scale=[names]``); the figures are in ``diagnostics["camera_scales_held_out"]``, and the
self-check's advice follows them.

Measured on the real 8-camera / 16-marker rig (Wise et al. 2025, 3230 observations, 5 contiguous
blocks of the recording): held-out median translation residual 30.5 mm with no factor, 25.8 with
the two markers the screen names most, 22.6 with one for every marker (the factors 0.88-1.07,
stable across the blocks to +-0.01), 29.8 with one for every camera; rotation 1.38-1.40 deg in all.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from handeye import SolverOutput
from handeye.base.errors import HandEyeError

#: contiguous blocks of the stations held out in turn
HELD_OUT_BLOCKS = 5
#: a model with factors is taken where its held-out median translation residual is at most this
#: fraction of no factor's (a smaller gain is within what the blocks' choice moves)
HELD_OUT_GAIN = 0.97
#: ... and its rotation median at most this many times no factor's
ROTATION_TOLERANCE = 1.05
#: a cell of fewer stations is not split (each block's fit would be too weak to judge)
MIN_STATIONS = 25


def applies(data: Any, options: Any) -> bool:
    """Whether auto may fit factors for some groups of a cell: data of several cameras and
    targets (`camera_scale_groups`) whose scales the user left known, no start and no covariance
    stated."""
    return (hasattr(data, "camera_scale_groups") and not data.camera_scale_unknown
            and options.init is None and options.covariance is None and data.station_count >= MIN_STATIONS)


def scales_if_held_out_agrees(problem: Any, data: Any, options: Any, backend: str, output: SolverOutput,
                              solve: Any) -> tuple[Any, SolverOutput]:
    """(data, output) as they are, with the held-out figures in the diagnostics where they were
    computed, or with the chosen groups' scales unknown and auto's pipeline run again (`solve`:
    (problem, data, options, backend) -> SolverOutput), with a warning naming the factors and the gain."""
    from handeye.checks.scale_checks import camera_scales_named

    named = camera_scales_named(problem, data, output.unknowns)
    if not named:
        return data, output
    candidates = {"named": tuple(named), "every_x": data.x_names, "every_y": data.y_names}
    figures = held_out(problem, data, output, candidates)
    if figures is None:
        return data, output
    chosen = figures["chosen"]
    if chosen == "none":
        return data, _with(output, {"camera_scales_held_out": figures})
    scaled = data.with_scales_unknown(candidates[chosen])
    again = solve(problem, scaled, options, backend)
    factors = again.diagnostics.get("camera_scales", {})
    best, plain = figures["models"][chosen], figures["models"]["none"]
    listed = ", ".join(f"{name!r} {s:.4g}" for name, s in factors.items())
    note = (f"auto: the camera translations of these data fit the robot's at a factor of their own for "
            f"{_which(chosen)}{listed}: with those factors the left-out stations are predicted "
            f"better (median translation residual {best['translation']:.3g} against {plain['translation']:.3g} in the "
            f"data's length unit, {figures['blocks']} blocks of the stations held out in turn), so auto fitted them, as "
            f"camera_scale={list(candidates[chosen])!r} does. A marker printed at another size than stated, or a "
            "camera's focal length off, does this: with the right sizes the factors are 1")
    diagnostics = {**again.diagnostics, "camera_scales_held_out": figures,
                   "warnings": [note, *again.diagnostics.get("warnings", [])]}
    return scaled, SolverOutput(unknowns=again.unknowns, status=again.status, diagnostics=diagnostics)


def held_out(problem: Any, data: Any, output: SolverOutput, candidates: Mapping[str, Sequence[str]]) -> dict[str, Any] | None:
    """The held-out figures of no factor and of each of `candidates` ({label: names of the X's and
    Y's given a factor}): {"blocks", "observations", "models": {label: {"names", "translation",
    "rotation_deg"}}, "chosen"}, the medians over every left-out observation a fit can predict
    (its marker and camera seen at other stations). None where the cell has too few stations or a
    block's fit fails (the screen's warning then stands alone)."""
    from handeye.host.api import run_registered

    if data.station_count < MIN_STATIONS:
        return None
    left_out = [int(o["index"]) for o in output.diagnostics.get("outliers", []) if isinstance(o, Mapping)]
    kept = np.ones(data.m, dtype=bool)
    kept[left_out] = False
    station = np.asarray(data.station_index)
    blocks = np.array_split(np.arange(data.station_count), HELD_OUT_BLOCKS)
    start = {name: pose for name, pose in zip(data.x_names + data.y_names, _poses(output))}
    models = {"none": ()} | {label: tuple(names) for label, names in candidates.items()}
    errors: dict[str, list[np.ndarray]] = {label: [] for label in models}
    for block in blocks:
        test = np.isin(station, block)
        train = np.flatnonzero(kept & ~test)
        for label, names in models.items():
            sub = data.with_scales_unknown(names).subset(train)
            init = {"init_X": np.stack([start[n] for n in sub.x_names]),
                    "init_Y": np.stack([start[n] for n in sub.y_names])}
            try:
                fit = run_registered("refine", sub, problem=problem.name, options=init)
            except (HandEyeError, np.linalg.LinAlgError, ValueError):
                return None
            errors[label].append(_prediction(data, np.flatnonzero(test), sub, fit))
    medians = {label: np.median(np.concatenate(e), axis=0) for label, e in errors.items()}
    figures = {label: {"names": list(models[label]), "rotation_deg": float(np.degrees(med[0])),
                       "translation": float(med[1])} for label, med in medians.items()}
    plain = figures["none"]
    fits = [label for label in candidates
            if figures[label]["translation"] <= HELD_OUT_GAIN * plain["translation"]
            and figures[label]["rotation_deg"] <= ROTATION_TOLERANCE * plain["rotation_deg"]]
    # the fewest factors, unless more predict better by HELD_OUT_GAIN again
    chosen = "none"
    for label in sorted(fits, key=lambda label: len(models[label])):
        if chosen == "none" or figures[label]["translation"] <= HELD_OUT_GAIN * figures[chosen]["translation"]:
            chosen = label
    return {"blocks": HELD_OUT_BLOCKS, "observations": int(sum(len(e) for e in errors["none"])),
            "models": figures, "chosen": chosen}


def _prediction(data: Any, rows: np.ndarray, sub: Any, fit: Any) -> np.ndarray:
    """(n, 2) rotation (rad) and translation residuals of the observations `rows` of `data` that
    the fit of `sub` predicts: A_i X_j against Y_k B_i, t_B times the fit's factor."""
    from handeye.geometry.se3 import inverse, rotation_angle

    X = np.asarray(fit.unknowns["X"]).reshape(-1, 4, 4)
    Y = np.asarray(fit.unknowns["Y"]).reshape(-1, 4, 4)
    x_of = {n: j for j, n in enumerate(sub.x_names)}
    y_of = {n: k for k, n in enumerate(sub.y_names)}
    factors = fit.diagnostics.get("camera_scales", {})
    x_names = [data.x_names[j] for j in data.x_index[rows]]
    y_names = [data.y_names[k] for k in data.y_index[rows]]
    seen = np.array([x in x_of and y in y_of for x, y in zip(x_names, y_names)], dtype=bool)
    if not seen.any():
        return np.zeros((0, 2))
    rows = rows[seen]
    x_names = [n for n, s in zip(x_names, seen) if s]
    y_names = [n for n, s in zip(y_names, seen) if s]
    B = np.array(data.B[rows])
    # an observation's factor: its X's where that is scaled, else its Y's (`camera_scale_groups`)
    B[:, :3, 3] *= np.array([factors.get(y, factors.get(x, 1.0)) for x, y in zip(x_names, y_names)])[:, None]
    left = np.asarray(data.A[rows]) @ X[[x_of[n] for n in x_names]]
    right = Y[[y_of[n] for n in y_names]] @ B
    gap = inverse(right) @ left
    return np.stack([rotation_angle(gap[:, :3, :3]), np.linalg.norm(gap[:, :3, 3], axis=1)], axis=1)


def _poses(output: SolverOutput) -> list[np.ndarray]:
    """auto's X's then Y's, in the data's order."""
    return [*np.asarray(output.unknowns["X"]).reshape(-1, 4, 4), *np.asarray(output.unknowns["Y"]).reshape(-1, 4, 4)]


def _which(label: str) -> str:
    """The start of the listing of a candidate's groups, in the user's words."""
    return {"every_x": "every X: ", "every_y": "every Y: "}.get(label, "")


def _with(output: SolverOutput, extra: Mapping[str, Any]) -> SolverOutput:
    return SolverOutput(unknowns=output.unknowns, status=output.status, diagnostics={**output.diagnostics, **extra})
