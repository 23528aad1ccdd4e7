"""`auto`: the default solver of A_i X = Y B_i -- a certified start, then maximum likelihood.

Pipeline (issue 4, item 4; the measurements behind it are in docs/solvers/auto.md):

1. start: `so3-sdp` (the Kronecker cost of eq. 8 under exact SO(3) constraints, globally optimal
   with a certificate) when it is registered and its backend is available, else `kron-lstsq`
   (eq. 8 by least squares, SVD projection). Both are unit invariant (normalize=True). If the
   so3-sdp solve itself fails, `kron-lstsq` is used, with a warning.
2. `refine` from that start: geometric maximum likelihood on SE(3) x SE(3); by default least
   squares with the noise variances estimated jointly (profile likelihood), or the weights and
   robust loss the user states (the options are refine's).
3. safeguard: when so3-sdp's start is not certified, `refine` also runs from the kron-lstsq start
   and the answer with the lower objective is kept.

Why (bench/accuracy.py, docs/solvers/auto.md): refinement is what buys accuracy -- the median
rotation error of Y is about half that of every Kronecker-type solver (kron-lstsq, so3-sdp, shah,
OpenCV's SHAH and LI) and `auto` equals the "oracle" (refine started at the ground truth) in every
cell, so the start only has to land in the right basin. so3-sdp is the start because it is the
only one that can prove it is the global minimum of its cost, it reached the oracle's optimum in
every one of 1200 small-m / heavy-noise simulations (kron-lstsq missed one), and it fits the time
budget (about 10 ms of auto's ~15 ms at m = 16). Robust losses are off by default: on clean data
they only cost efficiency.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import InputError
from handeye.plugins import refine as _refine
from handeye.solution import jsonable
from handeye.problems.axyb import AXYBData

#: the start when so3-sdp is unavailable or fails, and the second start when it is not certified
FALLBACK = _refine.FALLBACK_INIT
#: keys of an init solver's diagnostics that make up its certificate
CERTIFICATE_KEYS = ("certified", "eigenvalue_ratio", "relative_gap", "duality_gap", "lower_bound", "cost", "thresholds")


@dataclasses.dataclass(frozen=True)
class Options:
    """Options of `auto`: the weighting and loss options of `refine` (see plugins/refine.py), and
    ``init`` to force the starting solver (default: so3-sdp when available, else kron-lstsq)."""

    init: str | None = None
    sigma_rot: float | None = None
    sigma_trans: float | None = None
    covariance: Any = None
    estimate: str = "profile"
    loss: str = "linear"
    loss_scale: float = _refine.DEFAULT_LOSS_SCALE
    max_iter: int = 200
    tol: float = 1e-14

    def __post_init__(self) -> None:
        if self.init is not None and not isinstance(self.init, str):
            raise InputError(
                f"option init of auto must be a solver name, got {type(self.init).__name__}; to "
                "start from given poses use solver='refine' with init_X/init_Y"
            )
        refine_options = self.refine_options()  # validates everything
        object.__setattr__(self, "covariance", refine_options.covariance)

    def refine_options(self, **overrides: Any) -> _refine.Options:
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        values.update(overrides)
        return _refine.Options(**values)


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    start, X0, Y0, init_status, init_diag, warnings = _refine.start(data, options.init)
    warnings = [f"auto: {w}" for w in warnings]
    certificate = {k: init_diag[k] for k in CERTIFICATE_KEYS if k in init_diag}
    certified = bool(init_diag.get("certified", False)) and init_status == Status.OPTIMAL
    pipeline = [start, "refine"]
    ropts = options.refine_options()
    X, Y, status, diag = _refine.refine(data, X0, Y0, ropts)
    starts = [{"init": start, "init_status": str(init_status), "final_cost": diag["final_cost"]}]

    other = FALLBACK if start != FALLBACK else None
    if not certified and other is not None and options.init is None:
        X1, Y1, status1, _ = _refine.run_init(other, data)
        Xb, Yb, status_b, diag_b = _refine.refine(data, X1, Y1, ropts)
        # compare the objective refine minimises: stated weights and the profile likelihood
        # (estimated weights, least squares) do not depend on the start; robust losses with
        # estimated scales are compared under common weights (those of the first run)
        W0 = _refine.weights_of(ropts, data.m)[0]
        if _refine.mode_of(W0, ropts.loss, data.m, ropts.estimate) in ("irls", "initial"):
            W = _refine.Whitening(diag["sigma_rot"], diag["sigma_trans"])
            P = _refine.Pairs.of(data)
            cost_a = _refine.cost_of(P, X, Y, W, ropts.loss, float(ropts.loss_scale))
            cost_b = _refine.cost_of(P, Xb, Yb, W, ropts.loss, float(ropts.loss_scale))
        else:
            cost_a, cost_b = diag["final_cost"], diag_b["final_cost"]
        starts.append({"init": other, "init_status": str(status1), "final_cost": diag_b["final_cost"],
                       "compared_cost": cost_b})
        starts[0]["compared_cost"] = cost_a
        pipeline = [f"{start} | {other}", "refine", "best"]
        if cost_b < cost_a - 1e-12 * abs(cost_a):
            X, Y, status, diag = Xb, Yb, status_b, diag_b
            diag["init"] = other

    diagnostics: dict[str, Any] = {
        "pipeline": pipeline,
        "init": diag.get("init", start),
        "init_status": str(init_status),
        "init_certified": certified,
        "certificate": jsonable(certificate),
        "compile_seconds": float(init_diag.get("compile_seconds", 0.0)),
        "starts": starts,
        "refine": {k: v for k, v in diag.items() if k != "warnings"},
    }
    warnings += diag.get("warnings", [])
    if warnings:
        diagnostics["warnings"] = warnings
    return SolverOutput(unknowns={"X": X, "Y": Y}, status=status, diagnostics=diagnostics)


SPEC = SolverSpec(
    name="auto",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="default: so3-sdp (certified) or kron-lstsq start, then maximum-likelihood refine",
    citation="Pan et al., IEEE T-ASE 2022 (eq. 8); see docs/solvers/auto.md",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
