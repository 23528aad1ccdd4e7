"""`auto`'s steps after its pipeline, which choose the model the data demand (plugins/auto.py,
docs/solvers/auto.md, steps 6 and 7): the camera's scale, where the camera's translations fit
the robot's only at another scale (`estimate_scale_if_needed`), and the formulation, where the
camera's poses drift (`drift`). Each runs auto's pipeline again (`solve`) on the data as they
then are.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from handeye import SolverOutput
from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.whitening import Whitening
from handeye.framework.solution import jsonable
from handeye.plugins import refine as _refine

#: camera poses that drift (`drift`): lag-1 autocorrelation of the A X = Y B translation
#: residuals beyond this (and beyond 3 / sqrt(m)), from DRIFT_MIN_PAIRS stations on. Measured
#: (kinhec smoke tier, docs/solvers/auto.md): drifting (visual-odometry) camera poses 0.79-0.98,
#: every other noise model of the tier -0.40..0.20
DRIFT_AUTOCORRELATION = 0.6
DRIFT_MIN_PAIRS = 20
#: ... and the switch is taken only where held-out prediction does not contradict it
#: (`drift_held_out`): over DRIFT_FOLDS contiguous blocks of stations, the consecutive motions'
#: answer predicts the held-out stations' camera translations at most DRIFT_TOLERANCE times as far
#: off as the A X = Y B answer. Held-out absolute poses cannot favour drift much (neither answer
#: predicts drifting poses), hence a tolerance. Measured ratios: 87 simulated drifting cameras (40
#: stations, three drift rates) 0.90-1.19, the switch paying in X every time; KinHEC's 29 fixture
#: sequences past the autocorrelation test (monocular and mixed tracks) 0.86-6.0, where the gate
#: at 1.5 keeps the median X error at 16.0 mm against 17.8 mm always switching (rotation 0.19 against
#: 0.17 deg), and rejects the switch where it cost most (6.0: 48 against 4.5 mm); a real rig of fixed
#: cameras (Wise et al. 2025, 33 pair recordings), whose residuals correlate because neighbouring
#: stations share the arm's configuration, 0.71-2.48, 13 of 33 beyond 1.5 (at 2.4 the switch would
#: have more than doubled the held-out error)
DRIFT_FOLDS = 5
DRIFT_TOLERANCE = 1.5
#: auto's pipeline: (problem, data, options, backend) -> SolverOutput
Solve = Callable[[Any, Any, Any, str], SolverOutput]


def residuals_at(problem: Any, data: Any, output: SolverOutput) -> tuple[Any, np.ndarray] | None:
    """(model, residuals) of A X = Y B at auto's answer, or None for other problems."""
    if problem.name != "axyb" or _refine.is_planar(data):
        return None
    model = _refine.model_of(problem, data)
    return model, model.residuals((output.unknowns["X"], output.unknowns["Y"]))


def estimate_scale_if_needed(problem: Any, data: Any, options: Any, backend: str, output: SolverOutput,
                             at: tuple[Any, np.ndarray] | None, solve: Solve) -> tuple[Any, SolverOutput]:
    """(data, output) as they are, or with the camera's scale unknown and solved again when check
    5 fails on `output` (auto's `run`)."""
    from handeye.checks.scale_checks import (
        camera_scale_screen,
        camera_scale_verdict,
        scale_suspect,
    )
    fitted = output.diagnostics.get("refine", {})
    if at is not None and "formulation" not in output.diagnostics and "covariance_XY" in fitted \
            and not fitted.get("outliers_left_out") and "sigma_rot" in fitted:
        # screened from refine's own fit (one residual evaluation): most data end here
        model, residuals = at
        screen = camera_scale_screen(model, (output.unknowns["X"], output.unknowns["Y"]), residuals,
                                     Whitening(fitted["sigma_rot"], fitted["sigma_trans"]),
                                     np.asarray(fitted["covariance_XY"], dtype=float))
        if screen is None or not scale_suspect(*screen):
            return data, output
    verdict = camera_scale_verdict(problem, data, output.unknowns)
    if verdict is None or verdict["verdict"] != "fail":
        return data, output
    data = dataclasses.replace(data, camera_scale_unknown=True)
    scaled = solve(problem, data, dataclasses.replace(options, noise="groups"), backend)  # the scale is fitted per group
    s, std = scaled.diagnostics.get("camera_scale", verdict["scale"]), scaled.diagnostics.get("camera_scale_std")
    sigma = "" if std is None else f" (1-sigma {std:.2g})"
    note = (f"auto: the camera's translations fit the robot's only when multiplied by {verdict['scale']:.4g} (the "
            f"translation residuals {verdict['translation_fit_gain']:.3g} times smaller), so auto estimated that "
            f"factor, as camera_scale='unknown' does: {s:.6g}{sigma}. A monocular camera, or the two in "
            "different length units: if they should be in one, fix the data; camera_scale='known' would keep the "
            "scale at 1 (and the answer would be unreliable)")
    diagnostics = {**scaled.diagnostics, "camera_scale_test": jsonable(verdict),
                   "warnings": [note, *scaled.diagnostics.get("warnings", [])]}
    return data, SolverOutput(unknowns=scaled.unknowns, status=scaled.status, diagnostics=diagnostics)


def drift(problem: Any, data: Any, options: Any, backend: str, output: SolverOutput,
          at: tuple[Any, np.ndarray] | None, solve: Solve) -> SolverOutput:
    """A X = Y B whose camera poses drift (visual odometry, SLAM: each pose's error carries the
    earlier ones'): the residuals of A_k X = Y B_k at the answer are correlated from one station
    to the next (lag-1 autocorrelation of the translation residuals, in the order of the data,
    above DRIFT_AUTOCORRELATION and 3 / sqrt(m), from DRIFT_MIN_PAIRS stations on), while the
    errors of consecutive motions do not accumulate. X then comes from A_k+1^-1 A_k X =
    X B_k+1^-1 B_k (`relative_motions`, consecutive; `auto` for A X = X B on those motions) and
    Y is the fit of the stations to it (`fitted_Y`: the average over the drift), with a warning; the A X = Y B answer is kept in
    the diagnostics. Anything else: `output` as it is, with the autocorrelation reported."""
    if (problem.name != "axyb" or data.m < DRIFT_MIN_PAIRS or _refine.is_planar(data)
            or options.init is not None or options.covariance is not None):
        return output
    from handeye.problems.axxb import PROBLEM as AXXB
    from handeye.problems.axxb import relative_motions
    from handeye.problems.axyb.geometry import fitted_Y

    scale_unknown = bool(data.camera_scale_unknown)
    e = (at or residuals_at(problem, data, output))[1][:, 3:]
    e = e - e.mean(axis=0)
    acf = float(np.sum(e[1:] * e[:-1]) / max(float(np.sum(e * e)), 1e-300))
    if acf <= max(DRIFT_AUTOCORRELATION, 3.0 / np.sqrt(data.m)):
        return SolverOutput(output.unknowns, output.status, {**output.diagnostics, "drift_autocorrelation": acf})
    A, B = data.A, data.B
    try:
        Am, Bm = relative_motions(A, B, "consecutive")
        motions = AXXB.validate(A=Am, B=Bm,
                                camera_scale="unknown" if scale_unknown else "known")
        sub = solve(AXXB, motions, options, backend)
    except (DegenerateDataError, InputError):
        return SolverOutput(output.unknowns, output.status, {**output.diagnostics, "drift_autocorrelation": acf})
    X = sub.unknowns["X"]
    held_out = drift_held_out(problem, data, output, X)
    if held_out is not None and not held_out["drift_agrees"]:
        kept = {**output.diagnostics, "drift_autocorrelation": acf, "drift_held_out": held_out}
        kept["warnings"] = [*output.diagnostics.get("warnings", []), (
            f"auto: the residuals of A_k X = Y B_k are correlated from one station to the next (lag-1 autocorrelation "
            f"{acf:.2f}), as a camera's drifting poses make them, but X from the consecutive motions predicts "
            f"held-out stations worse ({held_out['drift_translation']:.3g} against {held_out['axyb_translation']:.3g} "
            f"in the data's length unit, median translation over {held_out['folds']} blocks of stations): neighbouring stations "
            "share the arm's configuration, and its systematic errors correlate them; the A X = Y B answer is kept")]
        return SolverOutput(output.unknowns, output.status, kept)
    metric_B = np.array(B)
    metric_B[:, :3, 3] *= sub.diagnostics.get("camera_scale", 1.0)
    note = (f"auto: the camera's poses drift over the recording (the residuals of A_k X = Y B_k are correlated from "
            f"one station to the next: lag-1 autocorrelation {acf:.2f}), as visual odometry's do; X comes from the "
            f"{motions.m} consecutive motions (A X = X B), whose errors do not accumulate, and Y is the stations' "
            "average fit to it")
    earlier = [w for w in output.diagnostics.get("warnings", []) if w.startswith("auto: the camera's translations")]
    diagnostics = {**sub.diagnostics, "drift_autocorrelation": acf,
                   "formulation": f"A_k X = X B_k on the {motions.m} consecutive motions (the camera's poses drift)",
                   "axyb_answer": jsonable(output.unknowns),
                   "warnings": [*earlier, note, *sub.diagnostics.get("warnings", [])]}
    if "camera_scale_test" in output.diagnostics:
        diagnostics["camera_scale_test"] = output.diagnostics["camera_scale_test"]
    if held_out is not None:
        diagnostics["drift_held_out"] = held_out
    return SolverOutput({"X": X, "Y": fitted_Y(A, metric_B, X)}, sub.status, diagnostics)


def drift_held_out(problem: Any, data: Any, output: SolverOutput, X_drift: np.ndarray) -> dict[str, Any] | None:
    """The drift switch judged by held-out prediction (DRIFT_FOLDS contiguous blocks of stations:
    drift is a matter of the order): per block left out, ``refine`` of A X = Y B on the other
    stations from auto's answer, and of A X = X B on the consecutive motions within each run of
    the other stations from `X_drift` (Y then their average fit, as `drift` makes it); each
    predicts the left-out stations, A_k X against Y B_k (a monocular camera's translations at each
    fit's own camera scale, where the data leave it unknown). ``drift_translation`` /
    ``axyb_translation``: the median translation residual over every left-out station (the
    data's length unit), ``*_rotation_deg`` the rotation's; ``drift_agrees``: drift_translation
    <= DRIFT_TOLERANCE x axyb_translation. None
    when a fold cannot be fitted (the in-sample test then decides alone)."""
    from handeye.base.errors import HandEyeError
    from handeye.geometry.motions import relative_motions
    from handeye.geometry.se3 import inverse, rotation_angle
    from handeye.host.api import run_registered
    from handeye.host.registry import get_registry
    from handeye.problems.axyb.geometry import fitted_Y

    A, B, m = np.asarray(data.A), np.asarray(data.B), data.m
    axyb, axxb = problem, get_registry().problem("axxb")
    scale = {"camera_scale": "unknown"} if data.camera_scale_unknown else {}  # a monocular camera: each fit's own

    def scaled(fit: Any) -> np.ndarray:  # the camera's poses at a fit's camera scale
        out = np.array(B)
        out[:, :3, 3] *= fit.diagnostics.get("camera_scale", 1.0)
        return out

    blocks = np.array_split(np.arange(m), DRIFT_FOLDS)
    errors: dict[str, list[np.ndarray]] = {"axyb": [], "drift": []}
    try:
        for held in blocks:
            train = np.setdiff1d(np.arange(m), held)
            fit = run_registered("refine", axyb.validate(A=A[train], B=B[train], **scale), problem="axyb",
                                 options={"init_X": output.unknowns["X"], "init_Y": output.unknowns["Y"]})
            runs = np.split(train, np.flatnonzero(np.diff(train) > 1) + 1)
            motions = [relative_motions(A[r], B[r], "consecutive") for r in runs if len(r) > 1]
            Am, Bm = np.concatenate([a for a, _ in motions]), np.concatenate([b for _, b in motions])
            sub = run_registered("refine", axxb.validate(A=Am, B=Bm, **scale), problem="axxb",
                                 options={"init_X": X_drift})
            X, B_fit, B_sub = sub.unknowns["X"], scaled(fit), scaled(sub)
            for name, (Xf, Yf, Bf) in (("axyb", (fit.unknowns["X"], fit.unknowns["Y"], B_fit)),
                                       ("drift", (X, fitted_Y(A[train], B_sub[train], X), B_sub))):
                gap = inverse(Yf @ Bf[held]) @ (A[held] @ Xf)
                errors[name].append(np.stack([rotation_angle(gap[:, :3, :3]), np.linalg.norm(gap[:, :3, 3], axis=1)], 1))
    except (HandEyeError, np.linalg.LinAlgError, ValueError):
        return None
    med = {name: np.median(np.concatenate(e), axis=0) for name, e in errors.items()}
    return {"folds": DRIFT_FOLDS, "axyb_rotation_deg": float(np.degrees(med["axyb"][0])),
            "axyb_translation": float(med["axyb"][1]), "drift_rotation_deg": float(np.degrees(med["drift"][0])),
            "drift_translation": float(med["drift"][1]),
            "drift_agrees": bool(med["drift"][1] <= DRIFT_TOLERANCE * med["axyb"][1])}


def scale_may_be_estimated(problem: Any, data: Any, options: Any) -> bool:
    """auto may estimate the camera's scale where the data demand it: a problem whose data may
    leave the camera's scale unknown (``camera_scale`` among its `Problem.optional_fields`: A X =
    Y B, A X = X B), the scale not already unknown, not planar (unsupported there), no start and
    no covariance stated (the scale is fitted under per-group weights)."""
    # a cell of several cameras (data with `camera_scale_groups`): which of them are monocular is
    # the user's to say (camera_scale=[names]); one scale fitted for all would be wrong for a mix
    # of metric and monocular cameras, so auto leaves it to the self-check's check 5 to report
    return ("camera_scale" in problem.optional_fields
            and not hasattr(data, "camera_scale_groups")
            and not getattr(data, "camera_scale_unknown", False)
            and not _refine.is_planar(data) and options.init is None and options.covariance is None)


