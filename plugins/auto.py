"""`auto`: the default solver of A_i X = Y B_i and of A_i X = X B_i -- a certified start, then
maximum likelihood. One pipeline for both problems (and any problem refine serves):

Pipeline (the measurements behind it are in docs/solvers/auto.md):

1. start: the first registered and available of refine's STARTS for the problem: `so3-sdp`
   (the Kronecker cost under exact SO(3) constraints, globally optimal with a certificate), else
   `kron-lstsq` (for axxb then `park`). If the start's solve itself fails, the next one is used,
   with a warning.
2. `refine` from that start: geometric maximum likelihood on SE(3)^k (plugins/refine.py, engine
   `handeye.nlls`); by default least squares with the noise variances estimated jointly
   (profile likelihood), or the weights and robust loss the user states (the options are
   refine's).
3. safeguard: when the certifiable start (so3-sdp) is not certified, `refine` also runs from the
   next start (kron-lstsq) and the answer with the lower objective is kept.

Why (bench/accuracy.py, docs/solvers/auto.md): refinement is what buys accuracy -- for A X = Y B
the median rotation error of Y is about half that of every Kronecker-type solver (kron-lstsq,
so3-sdp, shah, OpenCV's SHAH and LI) and `auto` equals the "oracle" (refine started at the
ground truth) in every cell, so the start only has to land in the right basin. so3-sdp is the
start because it is the only one that can prove it is the global minimum of its cost, it reached
the oracle's optimum in every one of 1200 small-m / heavy-noise simulations (kron-lstsq missed
one), and it fits the time budget. Robust losses are off by default: on clean data they only
cost efficiency. For A X = X B docs/solvers/auto.md compares auto with OpenCV's five methods.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from handeye import SolverOutput, SolverSpec, Status, hookimpl, nlls
from handeye.errors import InputError
from handeye.plugins import refine as _refine
from handeye.robust import DEFAULT_LOSS_SCALE
from handeye.solution import jsonable
from handeye.whitening import Whitening

#: keys of an init solver's diagnostics that make up its certificate
CERTIFICATE_KEYS = ("certified", "eigenvalue_ratio", "relative_gap", "duality_gap", "lower_bound", "cost", "thresholds")


@dataclasses.dataclass(frozen=True)
class Options:
    """Options of `auto`: the weighting and loss options of `refine` (see plugins/refine.py), and
    ``init`` to force the starting solver (default: the first registered and available of
    refine's STARTS for the problem: so3-sdp, then kron-lstsq (then park for axxb))."""

    init: str | None = None
    sigma_rot: float | None = None
    sigma_trans: float | None = None
    covariance: Any = None
    estimate: str = "profile"
    loss: str = "linear"
    loss_scale: float = DEFAULT_LOSS_SCALE
    max_iter: int = 200
    tol: float = 1e-14

    def __post_init__(self) -> None:
        if self.init is not None and not isinstance(self.init, str):
            raise InputError(
                f"option init of auto must be a solver name, got {type(self.init).__name__}; to "
                "start from given poses use solver='refine' with init_X (and init_Y)"
            )
        refine_options = self.refine_options()  # validates everything
        object.__setattr__(self, "covariance", refine_options.covariance)

    def refine_options(self, problem: str = "axyb", **overrides: Any) -> _refine._Options:
        """refine's options for `problem` with these values (the covariance given as its
        Cholesky factor, as refine keeps it after validation)."""
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        values.update(overrides)
        return _refine.OPTIONS[problem](**values)


def run(data: Any, options: Options, backend: str) -> SolverOutput:
    problem = _refine.problem_of(data)
    if problem == "axxb" and data.stations is not None and _weights_are_estimated(options):
        return _run_on_stations(data, options, backend)
    start, poses, init_status, init_diag, warnings = _refine.start(data, options.init)
    warnings = [f"auto: {w}" for w in warnings]
    certified = _certified(init_status, init_diag)
    pipeline = [start, "refine"]
    ropts = options.refine_options(problem)
    poses, status, diag = _refine.refine(data, poses, ropts)
    starts = [{"init": start, "init_status": str(init_status), "final_cost": diag["final_cost"]}]

    # the safeguard applies to the certifiable start (the first of refine's STARTS)
    other = _refine.fallback_init(problem, start) if start == _refine.STARTS[problem][0] else None
    if not certified and other is not None and options.init is None:
        poses1, status1, _ = _refine.run_init(other, data)
        poses_b, status_b, diag_b = _refine.refine(data, poses1, ropts)
        # compare the objective refine minimises: stated weights and the profile likelihood
        # (estimated weights, least squares) do not depend on the start; robust losses with
        # estimated scales are compared under common weights (those of the first run)
        settings = _refine.settings_of(ropts, data.m)
        model = _refine.model_of(data)
        if nlls.mode_of(settings.W, settings.loss, data.m, settings.estimate, model.profile_min_pairs) in ("irls", "initial"):
            W = Whitening(diag["sigma_rot"], diag["sigma_trans"])
            cost_a = nlls.cost_of(model, poses, W, settings.loss, settings.loss_scale)
            cost_b = nlls.cost_of(model, poses_b, W, settings.loss, settings.loss_scale)
        else:
            cost_a, cost_b = diag["final_cost"], diag_b["final_cost"]
        starts.append({"init": other, "init_status": str(status1), "final_cost": diag_b["final_cost"],
                       "compared_cost": cost_b})
        starts[0]["compared_cost"] = cost_a
        pipeline = [f"{start} | {other}", "refine", "best"]
        if cost_b < cost_a - 1e-12 * abs(cost_a):
            poses, status, diag = poses_b, status_b, diag_b
            diag["init"] = other

    diagnostics = _diagnostics(pipeline, start, init_status, init_diag, starts, diag, warnings)
    return SolverOutput(unknowns=dict(zip(ropts.UNKNOWNS, poses)), status=status, diagnostics=diagnostics)


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
    warnings = warnings + diag.get("warnings", [])
    if warnings:
        diagnostics["warnings"] = warnings
    return diagnostics


def _certified(status: Status, diagnostics: dict[str, Any]) -> bool:
    return bool(diagnostics.get("certified", False)) and status == Status.OPTIMAL


def _weights_are_estimated(options: Options) -> bool:
    """No start, noise level or covariance stated: those describe the motions, not stations."""
    return options.init is None and options.sigma_rot is None and options.covariance is None


def _run_on_stations(data: Any, options: Options, backend: str) -> SolverOutput:
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
    pipeline runs on the stations instead (its own certified start, 19x19, and safeguard)."""
    from handeye.problems.axyb import PROBLEM as AXYB

    A_abs, B_abs = data.stations
    stations = AXYB.validate(A=A_abs, B=B_abs)
    start, poses, init_status, init_diag, warnings = _refine.start(data, None)
    if _certified(init_status, init_diag):
        (X, _), status, diag = _refine.refine(stations, (poses[0], poses[0]), options.refine_options("axyb"))
        starts = [{"init": f"{start} (motions)", "init_status": str(init_status), "final_cost": diag["final_cost"]}]
        diagnostics = _diagnostics([f"{start} (motions)", "refine"], start, init_status, init_diag, starts, diag,
                                   [f"auto: {w}" for w in warnings])
        output = SolverOutput(unknowns={"X": X}, status=status, diagnostics=diagnostics)
    else:
        output = run(stations, options, backend)
    diagnostics = dict(output.diagnostics)
    diagnostics["formulation"] = (f"A_k X = Y B_k on the {len(A_abs)} stations the {data.m} motions were made "
                                  "from (maximum likelihood for independent noise on each station)")
    diagnostics["pipeline"] = ["stations", *diagnostics["pipeline"]]
    return SolverOutput(unknowns={"X": output.unknowns["X"]}, status=output.status, diagnostics=diagnostics)


SPECS = (
    SolverSpec(
        name="auto",
        problems=("axyb",),
        run=run,
        options=Options,
        summary="default: so3-sdp (certified) or kron-lstsq start, then maximum-likelihood refine",
        citation="Pan et al., IEEE T-ASE 2022 (eq. 8); see docs/solvers/auto.md",
        unit_invariant=True,
    ),
    SolverSpec(
        name="auto",
        problems=("axxb",),
        run=run,
        options=Options,
        summary="default for A_i X = X B_i: so3-sdp (certified), kron-lstsq or park start, then maximum-likelihood refine",
        citation="Pan et al., IEEE T-ASE 2022 (eq. 8); see docs/solvers/auto.md",
        unit_invariant=True,
    ),
)
#: the A_i X = Y B_i spec (kept under its old name)
SPEC = SPECS[0]


@hookimpl
def register_solvers(register):
    for spec in SPECS:
        register(spec)
