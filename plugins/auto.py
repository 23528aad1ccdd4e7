"""`auto`: the default solver of A_i X = Y B_i, A_i X = X B_i and A_i X B_i = Y C_i Z -- a good
start (certified where a certifiable method exists), then maximum likelihood. One pipeline for
every problem refine serves:

Pipeline (the measurements behind it are in docs/solvers/auto.md):

1. start: the first registered and available of refine's STARTS for the problem: `so3-sdp`
   (the Kronecker cost under exact SO(3) constraints, globally optimal with a certificate), else
   `kron-lstsq` (for axxb then `park`). If the start's solve itself fails, the next one is used,
   with a warning.
2. `refine` from that start: geometric maximum likelihood on SE(3)^k (plugins/refine.py, engine
   `handeye.estimation.nlls`); by default least squares with the noise variances estimated jointly
   (profile likelihood), or the weights and robust loss the user states (the options are
   refine's).
3. safeguard: when the certifiable start (so3-sdp) is not certified, `refine` also runs from the
   next start (kron-lstsq) and the answer with the lower objective is kept.
4. outliers: pairs far off the others at a robust fit are left out and least squares refitted
   (`handeye.plugins._auto_outliers.reject_outliers`).
5. noise sources (A_i X = Y B_i with the noise estimated and least squares, from
   SOURCES_MIN_PAIRS pairs on): where the noise lives -- each measured pose's rotation in its
   two frames, the translation along the camera pose's axes -- estimated by maximum likelihood at
   the per-group answer, then X and Y refitted with it, on the pairs kept (`handeye.estimation.noise_sources`,
   `_noise_step`).

A_i X B_i = Y C_i Z (`MULTI_START`) has no certifiable method: the start is `wang` (grid of
rotation starts, any data protocol), and the safeguard always runs, from the next of refine's
STARTS["axbycz"] that solves the data (`fu-dq` when robot 2 holds still in a phase, else
`kron-lstsq` from 10 triples on, else `wu`): a closed form of the data's own protocol, whose basin
is independent of wang's grid. Measured (bench/axbycz_accuracy.py, docs/solvers/auto.md): refine from either start
lands on the oracle's optimum (refine started at the truth); a start in a wrong basin (wu on
noisy phase data) ends at a higher objective and is discarded. The outlier step's threshold
(OUTLIER_CHI2) flagged no triple in 600 clean data sets of the accuracy study.

Why (bench/accuracy.py, docs/solvers/auto.md): refinement is what buys accuracy -- for A X = Y B
the median rotation error of Y is about half that of every Kronecker-type solver (kron-lstsq,
so3-sdp, shah, OpenCV's SHAH and LI) and `auto` equals the "oracle" (refine started at the
ground truth) in every cell, so the start only has to land in the right basin. so3-sdp is the
start because it is the only one that can prove it is the global minimum of its cost, it reached
the oracle's optimum in every one of 1200 small-m / heavy-noise simulations (kron-lstsq missed
one), and it fits the time budget. Robust losses are off by default: on clean data they only
cost efficiency, so the Cauchy fit only finds the gross pairs and least squares on the others gives
the answer. For A X = X B docs/solvers/auto.md compares auto with OpenCV's five methods.

Planar mode (a robot whose rotations share one axis, `handeye.problems.planar`, docs/planar.md):
the start is kron-lstsq in planar mode (so3-sdp has none), then refine in planar mode, with the
translation component the user gave kept; the outlier step and the stations of A X = X B keep it
too. The answer carries a warning naming the value assumed.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import (
    BackendUnavailableError,
    DegenerateDataError,
    InputError,
    SolverError,
)
from handeye.estimation import lm_objective, noise_sources
from handeye.estimation.robust import DEFAULT_LOSS_SCALE, OUTLIER_CHI2
from handeye.estimation.whitening import Whitening
from handeye.framework.options import check_choice
from handeye.framework.problem import Problem
from handeye.framework.problem_engine import unflatten
from handeye.framework.solution import jsonable
from handeye.plugins import _auto_outliers as far_off
from handeye.plugins import _auto_scales as cell_scales
from handeye.plugins import _auto_steps as steps
from handeye.plugins import refine as _refine
from handeye.plugins._auto_steps import DRIFT_AUTOCORRELATION, DRIFT_MIN_PAIRS  # noqa: F401 (auto's constants)

#: keys of an init solver's diagnostics that make up its certificate
CERTIFICATE_KEYS = ("certified", "eigenvalue_ratio", "relative_gap", "duality_gap", "lower_bound", "cost", "thresholds")
#: values of option `outliers`
OUTLIER_CHOICES = ("reject", "keep")
#: the noise-source model is fitted by default where the pairs kept give this many residuals
#: per variance (axyb's 8 variances: SOURCES_MIN_PAIRS = 20 pairs, 120 residuals); below it the
#: two per-group variances. Measured on the KinHEC small tier (docs/solvers/auto.md): at 3-12
#: pairs it was 1.1x less accurate than the per-group model in X translation (geometric mean),
#: at 17-20 pairs 0.84x, from 60 pairs 0.74x; it costs 6.7 ms at 16 pairs (the per-group
#: model: 3.3 ms).
RESIDUALS_PER_VARIANCE = 15
SOURCES_MIN_PAIRS = 20
#: by default the noise sources replace the per-group model only where they explain the
#: residuals better than chance would (`handeye.estimation.noise_sources.min_gain`: for axyb's 8 variances
#: against 2 the 1% point of chi^2 with 6 degrees of freedom, halved: 8.4 nats). Where the
#: per-group model is the true one (the simulator's noise) a fit on 8 variances costs 2-5% of
#: accuracy (bench/accuracy.py, m = 50), and there the gain stayed below 8.4 in 200 of 200 data
#: sets at m = 50 (99th percentile 7.3 nats); on the KinHEC small tier it was below it on 43 of
#: 452 sequences of 20 pairs or more (median gain 24-97 nats per track).
#: values of option `noise` (None: "sources" where it applies, see `_noise_step`)
NOISE_CHOICES = (None, "groups", "sources")


@dataclasses.dataclass(frozen=True)
class Options:
    """Options of `auto`: the weighting and loss options of `refine` (see plugins/refine.py), and
    ``init`` to force the starting solver (default: the first registered and available of the
    problem's `Problem.starts`: so3-sdp, then kron-lstsq (then park for axxb); for axbycz wang,
    fu-dq, kron-lstsq, wu), and
    ``noise``: None (default: "sources" on A_i X = Y B_i data of SOURCES_MIN_PAIRS pairs or more
    with the noise estimated and least squares, else "groups"), "groups" (refine's one noise level
    per residual group) or "sources" (the noise of each measured pose in its own frame,
    estimated at the per-group answer, `handeye.estimation.noise_sources`; fitted last, on the pairs kept), and
    ``outliers``: "reject" (default; with least squares, pairs far off the others are left out
    and listed, see the module docstring) or "keep" (least squares on every pair). With a robust
    ``loss`` the loss handles outliers and nothing is left out."""

    init: str | None = None
    sigma_rot: float | None = None
    sigma_trans: float | None = None
    covariance: Any = None
    estimate: str = "profile"
    loss: str = "linear"
    loss_scale: float = DEFAULT_LOSS_SCALE
    max_iter: int = 200
    tol: float = 1e-14
    noise: str | None = None
    outliers: str = "reject"

    def __post_init__(self) -> None:
        check_choice("outliers", self.outliers, OUTLIER_CHOICES)
        check_choice("noise", self.noise, NOISE_CHOICES)
        if self.noise == "sources" and not self._noise_estimated():
            raise InputError("noise='sources' takes the noise estimated (no sigma_rot, sigma_trans or covariance) "
                             "and loss='linear'; use noise='groups'")
        if self.init is not None and not isinstance(self.init, str):
            raise InputError(
                f"option init of auto must be a solver name, got {type(self.init).__name__}; to "
                "start from given poses use solver='refine' with init_X (and init_Y)"
            )
        self.refine_options()  # validates everything
        if self.covariance is not None:  # kept as stated (refine takes its Cholesky factor each time), read-only
            covariance = np.array(self.covariance, dtype=float)
            covariance.setflags(write=False)
            object.__setattr__(self, "covariance", covariance)

    def refine_options(self, problem: Problem | None = None, **overrides: Any) -> _refine.Options:
        """refine's options for `problem` with these values; without a problem, the options
        common to every problem."""
        values = {name: getattr(self, name) for name in _passed_on(type(self))}
        values["noise"] = "groups"  # the noise sources are auto's last step (`_noise_step`)
        values.update(overrides)
        cls = _refine.Options if problem is None else _refine.options_for(problem)
        if all(type(v) in _PLAIN for v in values.values()):  # the usual case: the defaults, or plain values
            return _validated(cls, tuple((k, type(v), v) for k, v in values.items()))
        return cls(**values)

    def _noise_estimated(self) -> bool:
        return self.sigma_rot is None and self.sigma_trans is None and self.covariance is None and self.loss == "linear"


#: the types of option values `_validated` keeps the validated options for (immutable, hashable,
#: equal only to values of the same meaning once the type is part of the key)
_PLAIN = (str, int, float, bool, type(None))


@functools.lru_cache(maxsize=64)
def _validated(cls: type, items: tuple[tuple[str, type, Any], ...]) -> _refine.Options:
    """refine's options `cls` with the values `items` ((name, type, value), the type in the key so
    that True and 1, or 1 and 1.0, stay apart), validated once: they are frozen, and auto makes
    the same ones twice a solve (~8 us each; a refusal raises and is not kept)."""
    return cls(**{name: value for name, _, value in items})


@functools.cache
def _passed_on(cls: type) -> tuple[str, ...]:
    """The fields of auto's options class `cls` that are refine's (all but ``outliers``), in
    order, listed once (`Options.refine_options` runs twice a solve)."""
    return tuple(f.name for f in dataclasses.fields(cls) if f.name != "outliers")


def run(data: Any, options: Options, backend: str, problem: Problem) -> SolverOutput:
    """The pipeline of the module docstring; then, where the camera's translations fit the
    robot's only at another scale (the host's check 5, `handeye.checks.self_check`: a factor beyond 1.5
    that explains the translation misfit), the pipeline again with that scale unknown
    (`handeye.estimation.camera_scale`), with a warning; for a cell of several cameras and targets, a factor
    for some of them where held-out stations are predicted better (`_auto_scales`); then, for A X = Y B whose camera poses drift, X
    from the consecutive motions (`handeye.plugins._auto_steps`)."""
    output = _run(problem, data, options, backend)
    at = steps.residuals_at(problem, data, output)  # (model, residuals) at the answer, shared by the two steps
    if steps.scale_may_be_estimated(problem, data, options):
        data, scaled = steps.estimate_scale_if_needed(problem, data, options, backend, output, at, _run)
        at, output = (at if scaled is output else None), scaled
    elif cell_scales.applies(data, options):
        data, output = cell_scales.scales_if_held_out_agrees(problem, data, options, backend, output, _run)
    return steps.drift(problem, data, options, backend, output, at, _run)


def _run(problem: Problem, data: Any, options: Options, backend: str, stations: bool = False) -> SolverOutput:
    """The pipeline of the module docstring on `problem`'s `data` (`stations`: A X = X B's stations
    rebuilt from its motions, where step 5 does not apply)."""
    if getattr(data, "stations", None) is not None and _weights_are_estimated(options):
        return _run_on_stations(problem, data, options, backend)
    start, poses, init_status, init_diag, warnings = _refine.start(problem, data, options.init)
    warnings = [f"auto: {w}" for w in warnings]
    if _refine.is_planar(data):
        warnings.insert(0, data.planar.warning())
    certified = _certified(init_status, init_diag)
    pipeline = [start, "refine"]
    ropts = options.refine_options(problem)
    poses, status, diag = _refine.refine(problem, data, poses, ropts)
    starts = [{"init": start, "init_status": str(init_status), "final_cost": diag["final_cost"]}]

    # the safeguard applies to a certifiable start that did not certify its answer, and always
    # where the problem has no certifiable start
    second = None
    if options.init is None and (not problem.certifiable_starts
                                 or (not certified and start in problem.certifiable_starts)):
        second = _second_start(problem, start, data)
    if second is not None:
        other, poses1, status1 = second
        try:
            poses_b, status_b, diag_b = _refine.refine(problem, data, poses1, ropts)
        except DegenerateDataError:  # singular at the second start's end point: the first answer stands
            second = None
    if second is not None:
        # compare the objective refine minimises: stated weights and the profile likelihood
        # (estimated weights, least squares) do not depend on the start; robust losses with
        # estimated scales are compared under common weights (those of the first run)
        settings = _refine.settings_of(ropts, data.m)
        model = _refine.model_of(problem, data)
        if lm_objective.mode_of(settings.W, settings.loss, data.m, settings.estimate, model.profile_min_pairs) in ("irls", "initial"):
            W = Whitening(diag["sigma_rot"], diag["sigma_trans"])
            cost_a = lm_objective.cost_of(model, poses, W, settings.loss, settings.loss_scale)
            cost_b = lm_objective.cost_of(model, poses_b, W, settings.loss, settings.loss_scale)
        else:
            cost_a, cost_b = diag["final_cost"], diag_b["final_cost"]
        starts.append({"init": other, "init_status": str(status1), "final_cost": diag_b["final_cost"],
                       "compared_cost": cost_b})
        starts[0]["compared_cost"] = cost_a
        pipeline = [f"{start} | {other}", "refine", "best"]
        if cost_b < cost_a - 1e-12 * abs(cost_a):
            poses, status, diag = poses_b, status_b, diag_b
            diag["init"] = other

    what = f"{problem.item}s"
    poses, status, diag, report = _outlier_step(problem, data, poses, status, diag, ropts, options, what)
    poses, status, diag = _noise_step(problem, data, poses, status, diag, ropts, options, report, stations)
    diagnostics = _diagnostics(pipeline, start, init_status, init_diag, starts, diag, warnings)
    diagnostics.update(report)
    if _refine.is_planar(data):
        diagnostics["planar"] = data.planar.figures()
    return SolverOutput(unknowns=unflatten(problem, data, poses), status=status, diagnostics=diagnostics)


def _second_start(problem: Problem, start: str, data: Any) -> tuple[str, tuple[np.ndarray, ...], Status] | None:
    """The safeguard's start: the first of the problem's starts after `start` that is available
    and solves the data (a start that fails, or refuses them with one of the problem's
    `Problem.start_refusals`, is passed over): (name, poses, status), or None."""
    name = _refine.fallback_init(problem.name, start)
    while name is not None:
        try:
            poses, status, _ = _refine.run_init(problem, name, data)
            return name, poses, status
        except (SolverError, BackendUnavailableError, *problem.start_refusals):
            name = _refine.fallback_init(problem.name, name)
    return None


def _outlier_step(problem: Problem, data: Any, poses: tuple[np.ndarray, ...], status: Status, diag: dict[str, Any],
                  ropts: _refine.Options, options: Options, what: str) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any], dict[str, Any]]:
    """`_auto_outliers.reject_outliers` when option outliers="reject" and the loss is least squares: the
    (possibly refitted) poses, status, refine's diagnostics, and auto's diagnostics to add
    ("outliers", "outlier_test"; the warning goes into refine's)."""
    if options.outliers != "reject" or ropts.loss != "linear":
        return poses, status, diag, {}
    poses, status, diag, outliers, note = far_off.reject_outliers(problem, data, poses, status, diag, ropts, what)
    report: dict[str, Any] = {
        "outliers": outliers,
        "outlier_test": (f"whitened residual norm > {OUTLIER_CHI2 ** 0.5:.3g} at a Cauchy fit, "
                         "median-based scales (or the stated weights); least squares refitted without them"),
    }
    if note:
        diag = {**diag, "warnings": diag.get("warnings", []) + [f"auto: {note}"]}
    if note and not outliers:  # far-off pairs, but too many (or too important) to leave out
        report["outliers_left_in"] = True
    return poses, status, diag, report


def _noise_step(problem: Problem, data: Any, poses: tuple[np.ndarray, ...], status: Status, diag: dict[str, Any],
                ropts: _refine.Options, options: Options, report: dict[str, Any], stations: bool = False
                ) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """Pipeline step 5: the noise-source model (`handeye.estimation.noise_sources`) fitted from the answer
    `poses` on the pairs kept (those not in the outlier step's `report`), where the option asks
    for it (None: from SOURCES_MIN_PAIRS pairs kept on and RESIDUALS_PER_VARIANCE residuals per
    variance, and kept only where it gains `noise_sources.min_gain` nats over the per-group model) and `_sources_skipped` finds no reason
    against it. Returns the new (poses, status, refine's diagnostics), their warnings after the
    earlier ones; else the inputs, with the reason in the diagnostics (and, where the user asked
    for the sources, a warning)."""
    if options.noise == "groups":
        return poses, status, diag
    flagged = np.zeros(data.m, dtype=bool)
    flagged[[o["index"] for o in report.get("outliers", [])]] = True
    kept = far_off.kept(problem, data, ~flagged)
    if options.noise is None and kept.m < SOURCES_MIN_PAIRS:
        return poses, status, diag
    reason = _sources_skipped(problem, data, status, ropts, report, stations)
    if reason is None:
        model = _refine.model_of(problem, kept)
        factors = model.noise_factors(kept, poses)  # poses: the per-group fit of the pairs kept
        count = factors.count
        if options.noise is None and 6 * kept.m < RESIDUALS_PER_VARIANCE * count:
            return poses, status, {**diag, "noise_sources_skipped": f"{kept.m} observations are too few for {count} variances"}
        try:
            new, new_status, new_diag = _refine.fit(model, kept, poses, _refine.settings_of(ropts, kept.m), "sources",
                                                    per_group_fit=factors)
        except DegenerateDataError:
            reason = "the pairs kept do not determine the fit with the noise sources"
    if reason is not None:
        note = {"noise_sources_skipped": reason}
        if options.noise == "sources":
            note["warnings"] = diag.get("warnings", []) + [f"auto: noise='sources' was not applied: {reason}"]
        return poses, status, {**diag, **note}
    if options.noise is None and new_diag["loglik_gain"] < noise_sources.min_gain(count):  # no better than one level per group
        return poses, status, {**diag, "noise_sources_gain": new_diag["loglik_gain"]}
    carried = {k: diag[k] for k in ("outliers_left_out", "init") if k in diag}
    warnings = diag.get("warnings", []) + new_diag.get("warnings", [])
    return new, new_status, {**new_diag, **carried, **({"warnings": warnings} if warnings else {})}


def _sources_skipped(problem: Problem, data: Any, status: Status, ropts: _refine.Options, report: dict[str, Any],
                     stations: bool) -> str | None:
    """Why the noise sources do not apply here, in the user's words, or None."""
    if stations:
        # A X = X B's stations are rebuilt with the first one as the origin, which moves the
        # centre of each rotation error: the sources' lever arms would be wrong (measured: 0.41-1.64
        # mm against 0.07-0.28 mm for axyb on the same stations)
        return "the stations were rebuilt from motions (solve them as axyb to estimate the noise sources)"
    if status is not Status.OPTIMAL:
        return f"the per-group fit ended {status.value}"
    if report.get("outliers_left_in"):
        return "far-off pairs had to be kept, and no noise model describes them"
    if not _refine.sources_apply(problem, data, ropts):
        return ("they take A_i X = Y B_i data with the camera's scale known, the noise estimated and "
                "loss='linear'")
    return None


def _diagnostics(pipeline: list[str], start: str, init_status: Status, init_diag: dict[str, Any],
                 starts: list[dict[str, Any]], diag: dict[str, Any], warnings: list[str]) -> dict[str, Any]:
    """auto's diagnostics: the pipeline, the start and its certificate, refine's figures, warnings."""
    diagnostics: dict[str, Any] = {
        "pipeline": pipeline,
        "init": diag.get("init", start),
        "init_status": str(init_status),
        "init_certified": _certified(init_status, init_diag),
        "certificate": jsonable({k: init_diag[k] for k in CERTIFICATE_KEYS if k in init_diag}),
        "compile_seconds": float(init_diag.get("compile_seconds", 0.0)),
        "starts": starts,
        "refine": {k: v for k, v in diag.items() if k != "warnings"},
    }
    # the camera's scale, or the cameras' scales, when unknown (handeye.estimation.camera_scale, handeye.estimation.camera_scales)
    for key in ("camera_scale", "camera_scale_std", "camera_scales", "camera_scales_std"):
        if key in diag:
            diagnostics[key] = diag[key]
    warnings = warnings + diag.get("warnings", [])
    if warnings:
        diagnostics["warnings"] = warnings
    return diagnostics


def _certified(status: Status, diagnostics: dict[str, Any]) -> bool:
    return bool(diagnostics.get("certified", False)) and status == Status.OPTIMAL


def _weights_are_estimated(options: Options) -> bool:
    """No start, noise level or covariance stated: those describe the motions, not stations."""
    return options.init is None and options.sigma_rot is None and options.covariance is None


def _run_on_stations(problem: Problem, data: Any, options: Options, backend: str) -> SolverOutput:
    """A_i X = X B_i whose motions are every pair of n stations (`AXXBData.stations`): solved as
    A_k X = Y B_k on the stations, the maximum-likelihood answer for independent noise on each
    station. The motions share the stations' noise, which the per-motion model of `refine`
    cannot represent: on them its answer is 2-14% less accurate and its uncertainty 3-6x too
    small (docs/solvers/auto.md); on the stations both are right. Eye-in-hand the answer is that
    of ``axyb`` on the user's stations (Y, the first station's pose pair, absorbs the common
    origin; tested to 1e-9); eye-to-hand the motions were made from inverted poses, and the AX=YB
    solved here measures the translation residual in the flange frame, not the base frame as
    ``axyb`` on the recorded stations does (the two ML answers differ by a fraction of the noise).

    The start is the certified start of the motions (so3-sdp for one rotation, a 10x10 SDP):
    the first station is the origin on both sides, so A_0 X = Y B_0 gives Y = X there and
    (X0, X0) starts the AX=YB refinement. When that start is not certified, the whole AX=YB
    pipeline runs on the stations instead (its own certified start, 19x19, and safeguard).

    Planar mode: A_k X = Y B_k on the stations keeps the same component of X (X's axis in its
    parent frame is that of the motions), and the whole AX=YB pipeline runs on them (its planar
    start, kron-lstsq, is not certified)."""
    from handeye.problems.axyb import PROBLEM as AXYB
    from handeye.problems.axyb import AXYBData

    A_abs, B_abs = data.stations
    if _refine.is_planar(data):
        stations = AXYBData(A_abs, B_abs, planar=data.planar)  # exact products of validated motions
        start, poses, init_status, init_diag, warnings = None, None, None, {}, []
    else:
        stations = AXYB.validate(A=A_abs, B=B_abs, camera_scale="unknown" if data.camera_scale_unknown else "known")
        start, poses, init_status, init_diag, warnings = _refine.start(problem, data, None)
    if start is not None and _certified(init_status, init_diag):
        ropts = options.refine_options(AXYB)
        fitted, status, diag = _refine.refine(AXYB, stations, (poses[0], poses[0]), ropts)
        starts = [{"init": f"{start} (motions)", "init_status": str(init_status), "final_cost": diag["final_cost"]}]
        fitted, status, diag, report = _outlier_step(AXYB, stations, fitted, status, diag, ropts, options, "stations")
        (X, _), status, diag = _noise_step(AXYB, stations, fitted, status, diag, ropts, options, report, stations=True)
        diagnostics = _diagnostics([f"{start} (motions)", "refine"], start, init_status, init_diag, starts, diag,
                                   [f"auto: {w}" for w in warnings])
        diagnostics.update(report)
        output = SolverOutput(unknowns={"X": X}, status=status, diagnostics=diagnostics)
    else:
        output = _run(AXYB, stations, options, backend, stations=True)
    diagnostics = dict(output.diagnostics)
    diagnostics["formulation"] = (f"A_k X = Y B_k on the {len(A_abs)} stations the {data.m} motions were made "
                                  "from (maximum likelihood for independent noise on each station)")
    diagnostics["pipeline"] = ["stations", *diagnostics["pipeline"]]
    return SolverOutput(unknowns={"X": output.unknowns["X"]}, status=output.status, diagnostics=diagnostics)


def spec_for(problem: Problem) -> SolverSpec:
    """auto's spec for `problem` (every mode refine honours, auto honours)."""
    starts = " or ".join(problem.starts) or "given"
    return SolverSpec(
        name="auto",
        problems=(problem.name,),
        run=functools.partial(run, problem=problem),
        options=Options,
        summary=f"default for {problem.equation or problem.name}: {starts} start, then maximum-likelihood refine",
        citation="Pan et al., IEEE T-ASE 2022 (eq. 8); see docs/solvers/auto.md",
        unit_invariant=True,
        planar_mode=True,
        camera_scale_mode=True,
    )


@hookimpl
def register_solvers(register, problems):
    """auto for every registered problem that gives the engine a model (`Problem.pose_model`)."""
    for problem in problems.values():
        if problem.refinable:
            register(spec_for(problem))
