"""`refine`: geometric maximum-likelihood refinement on SE(3)^k, for A_i X = Y B_i, A_i X = X B_i and
A_i X B_i = Y C_i Z.

Beyond the paper. The Kronecker cost of eq. 8 mixes rotation entries and
translations in one algebraic residual whose relative weight depends on the length unit; this
solver instead minimises a weighted sum of squared *geometric* residuals, one 6-vector per pair
(the per-pair quantities of eqs. 32-33, as vectors):

    axyb:  r_i = log(R_Ai R_X R_Bi^T R_Y^T),  t_i = R_Ai t_X + t_Ai - R_Y t_Bi - t_Y
    axxb:  r_i = log(R_Ai R_X R_Bi^T R_X^T),  t_i = R_Ai t_X + t_Ai - R_X t_Bi - t_X
    axbycz: r_i = log(R_Ai R_X R_Bi R_Z^T R_Ci^T R_Y^T),  t_i = t(A_i X B_i) - t(Y C_i Z)

With Gaussian noise of standard deviation sigma_rot (rad, per axis) and sigma_trans (data
units, per axis), F = 1/2 sum_i rho(|e_i|^2), e_i = W^(1/2) [r_i; t_i], is the negative
log-likelihood for rho(s) = s.

This module is the plugin only: its options, the start (a registered solver per problem, or
given poses) and the registration. The machinery is shared and lives below it:
- `handeye.estimation.nlls`: Levenberg-Marquardt on SE(3)^k with its weight modes (stated weights, profile
  likelihood over the two variances, IRLS with median-based scales, "initial"), convergence
  rules, covariance with its variance factor, diagnostics; `handeye.estimation.whitening` and
  `handeye.estimation.robust`: weights and losses; `handeye.geometry.so3_fast`: the SO(3) helpers;
- `handeye.problems.axyb.geometry`, `handeye.problems.axxb.geometry`,
  `handeye.problems.axbycz.geometry`: each problem's residuals and analytic Jacobians (and, for
  A X = Y B at large m, closed-form normal equations).

refine serves every registered problem that gives the engine a model (`handeye.Problem.pose_model`,
a third party's too: it registers for them all), started from the problem's `Problem.starts`.
A_i X B_i = Y C_i Z has no certifiable start; its starts (`Problem.starts`) each serve the data
protocol they were made for: `wang` (any protocol; a grid of rotation starts, then Gauss-Newton),
`fu-dq` (two steps; a phase with robot 2 still), `kron-lstsq` (lifted linear system; >= 10
triples), `wu` (closed form; both robots moving; 3x slower than kron-lstsq at m = 16). A default
start that refuses the data (`InputError`, `DegenerateDataError`: wrong protocol, too few
triples) or fails gives way to the next, with a warning; when none is registered, or none solves the data, refine asks for the start
poses (init_X, init_Y, init_Z).

Weights: stated (``sigma_rot`` and ``sigma_trans``, or a 6x6 / (m, 6, 6) ``covariance`` of
[r_i; t_i]) or, by default, estimated: with least squares by the profile likelihood (one smooth
function, so the answer does not depend on the start within its basin and scales exactly with
the length unit); with a robust loss by robust scales re-estimated to a fixed point. See
docs/solvers/refine.md for the models, the Jacobians and measured figures.

Planar mode (a robot whose rotations share one axis, `handeye.problems.planar`, docs/planar.md):
the model keeps the translation component the user gave (`handeye.estimation.nlls.PoseModel.fixed`: the
steps stay in the 6k - 1 dimensional subspace that keeps it, and its variance is zero); the
default start is the first start solver with a planar mode (kron-lstsq), and a start given as
poses is moved onto the constraint first.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl, run_registered
from handeye.base.errors import (
    BackendUnavailableError,
    InputError,
    SolverError,
    shown,
)
from handeye.estimation import camera_scale, nlls, noise_sources
from handeye.estimation.robust import DEFAULT_LOSS_SCALE, LOSSES
from handeye.estimation.whitening import covariance_factor, stated
from handeye.framework.options import check_choice, check_int, check_positive
from handeye.framework.problem import Problem
from handeye.framework.problem_engine import flatten, unflatten
from handeye.framework.solution import jsonable
from handeye.geometry.validation import float_array, pose_stack
from handeye.host.registry import get_registry

#: values of option `noise`: "groups", one noise level per residual group (rotation,
#: translation) for every pair; "sources" (A_i X = Y B_i, noise estimated, least squares), the
#: noise of each measured pose in its own frame, pair by pair (`handeye.estimation.noise_sources`)
NOISE_MODELS = ("groups", "sources")
#: solvers that cannot serve as `init` because they call `refine` themselves.
RECURSIVE = ("refine", "auto")


@dataclasses.dataclass(frozen=True)
class Options:
    """Options of `refine`, common to every problem; `options_for(problem)` adds one start pose
    per unknown (``init_X``, ``init_Y``, ...), which UNKNOWNS and INIT_FIELDS name.

    init: name of the solver giving the starting point (default: the first registered and
        available of the problem's `Problem.starts`, e.g. so3-sdp then kron-lstsq), or a
        mapping {"X": 4x4, ...} of starting poses, one per unknown (a (k, 4, 4) stack for an
        unknown that is one; the harness's "oracle" passes the ground truth this way).
    init_X, init_Y, ...: the starting poses (all or none).
    sigma_rot, sigma_trans: stated noise of the residual, per axis (rad, data units); both or
        neither. covariance: (6, 6) or (m, 6, 6) covariance of [r_i; t_i] instead.
        Without them the weights are estimated from the residuals (see module docstring):
    estimate: how, "profile" (default: maximum likelihood over the two variances too, i.e. RMS
        of the residuals at the answer; independent of the start) or "initial" (RMS, or for a
        robust loss the median-based scale, of the start's residuals, then fixed).
    loss: "linear" (least squares, default), "huber" or "cauchy", on the norm of each pair's
        whitened residual; loss_scale: where the robust loss departs from least squares, in units
        of that norm (default sqrt(chi2_6 quantile 0.95) = 3.55).
    max_iter: total Levenberg-Marquardt iterations; tol: stop when the cost decrease predicted by a
        Gauss-Newton step is below tol * cost.
    noise: "groups" (default: one noise level per residual group, the same for every pair) or
        "sources" (the noise of each measured pose in its own frame, estimated at the per-group fit,
        pair by pair: `handeye.estimation.noise_sources`; A_i X = Y B_i with the noise estimated).
    """

    UNKNOWNS: ClassVar[tuple[str, ...]] = ()
    INIT_FIELDS: ClassVar[tuple[str, ...]] = ()

    init: str | None = None
    sigma_rot: float | None = None
    sigma_trans: float | None = None
    covariance: Any = None
    estimate: str = "profile"
    loss: str = "linear"
    loss_scale: float = DEFAULT_LOSS_SCALE
    max_iter: int = 200
    tol: float = 1e-14
    noise: str = "groups"

    def __post_init__(self) -> None:
        check_choice("loss", self.loss, LOSSES)
        check_choice("noise", self.noise, NOISE_MODELS)
        check_choice("estimate", self.estimate, nlls.ESTIMATES)
        check_positive("loss_scale", self.loss_scale)
        check_positive("tol", self.tol)
        check_int("max_iter", self.max_iter, minimum=1)
        names, fields = self.UNKNOWNS, self.INIT_FIELDS
        if isinstance(self.init, Mapping):  # {"X": 4x4, ...}: start from given poses
            if set(self.init) != set(names) or any(getattr(self, f) is not None for f in fields):
                raise InputError(f"option init as a mapping must be {self._init_listing()} (and no "
                                 f"{'/'.join(fields)}), got keys {sorted(self.init)}")
            for k, f in zip(names, fields):
                object.__setattr__(self, f, self.init[k])
            object.__setattr__(self, "init", None)
        if self.init is not None:
            if not isinstance(self.init, str):
                raise InputError(f"option init={shown(self.init)} must be a solver name (str) or a mapping {self._init_listing()}")
            if self.init in RECURSIVE:
                raise InputError(
                    f"option init={self.init!r} would make refine start from itself; use a "
                    "closed-form or certifiable solver such as 'kron-lstsq' or 'so3-sdp'"
                )
        given = [getattr(self, f) is not None for f in fields]
        if any(given) and not all(given):
            raise InputError(f"options {' and '.join(fields)} must be given together (4x4 poses)")
        if any(given):
            # numbers first (one-line InputError for text, None, complex or masked values)
            values = [float_array(getattr(self, f), f"option {f}", "a 4x4 pose") for f in fields]
            for f, T in zip(fields, _pose_options(values, fields)):
                object.__setattr__(self, f, T)
        if (self.sigma_rot is None) != (self.sigma_trans is None):
            raise InputError("options sigma_rot and sigma_trans must be given together (the ratio sets the weights)")
        if self.sigma_rot is not None:
            check_positive("sigma_rot", self.sigma_rot)
            check_positive("sigma_trans", self.sigma_trans)
            if self.covariance is not None:
                raise InputError("give either sigma_rot/sigma_trans or covariance, not both")
        if self.covariance is not None:
            object.__setattr__(self, "covariance", covariance_factor(self.covariance))  # its Cholesky factor

    def start_poses(self) -> dict[str, np.ndarray] | None:
        """The given starting poses (validated) per unknown, or None when a solver gives the start."""
        poses = {k: getattr(self, f) for k, f in zip(self.UNKNOWNS, self.INIT_FIELDS)}
        return None if not poses or any(T is None for T in poses.values()) else poses

    def _init_listing(self) -> str:
        return "{" + ", ".join(f"'{k}': 4x4" for k in self.UNKNOWNS) + "}"


_OPTIONS: dict[tuple[str, tuple[str, ...]], type[Options]] = {}


def options_for(problem: Problem) -> type[Options]:
    """refine's options class for `problem`: `Options` with a start pose ``init_<name>`` per
    unknown (made once per problem)."""
    key = (problem.name, tuple(problem.unknowns))
    if key not in _OPTIONS:
        fields = [(f"init_{name}", Any, dataclasses.field(default=None)) for name in problem.unknowns]
        cls = dataclasses.make_dataclass(
            f"{problem.name.title().replace('-', '').replace('_', '')}RefineOptions", fields, bases=(Options,),
            frozen=True, namespace={"UNKNOWNS": tuple(problem.unknowns),
                                    "INIT_FIELDS": tuple(f"init_{n}" for n in problem.unknowns),
                                    "__module__": __name__})
        cls.__doc__ = (f"Options of `refine` for {problem.equation or problem.name}: those of `Options` with "
                       f"the start poses {', '.join(f'init_{n}' for n in problem.unknowns)} (all or none).")
        _OPTIONS[key] = cls
    return _OPTIONS[key]


def _pose_options(values: list[Any], names: list[str]) -> list[np.ndarray]:
    """The init poses validated, each a 4x4 pose or a (k, 4, 4) stack. All single poses are
    checked in one `pose_stack` call, which is most of the cost of parsing the options at small
    m; when that fails, or for stacks, each is checked alone, for an error naming the bad one."""
    arrays = [np.asarray(v, dtype=float) for v in values]
    if all(T.shape == (4, 4) for T in arrays):
        try:
            return list(pose_stack(np.stack(arrays), ", ".join(names)))
        except InputError:
            pass
    out = []
    for T, name in zip(arrays, names):
        if T.shape[-2:] != (4, 4) or T.ndim not in (2, 3) or len(T) == 0:
            raise InputError(f"option {name} must be a 4x4 pose (or a stack of them), got shape {T.shape}")
        out.append(pose_stack(T[None], name)[0] if T.ndim == 2 else pose_stack(T, name))
    return out


# --------------------------------------------------------------------------- start

def model_of(problem: Problem, data: Any) -> nlls.PoseModel:
    """The engine's model of `problem` on these validated data (the camera's scale profiled out
    when the data say it is unknown, `handeye.estimation.camera_scale`)."""
    model = problem.pose_model(data)
    if model is None:
        raise InputError(f"problem {problem.name!r} gives no least-squares model of these data; refine cannot "
                         "solve them")
    return camera_scale.model_for(data, model)


def starts_of(problem: str) -> tuple[str, ...]:
    """The start solvers of `problem`, in order of preference (`Problem.starts`)."""
    return tuple(get_registry().problem(problem).starts)


def _available(name: str, problem: str, planar: bool = False) -> bool:
    spec = get_registry().solvers.get(name, {}).get(problem)
    return (spec is not None and spec.unavailable_reason(spec.default_backend) is None
            and (spec.planar_mode or not planar))


def default_init(problem: str | None = None, planar: bool = False) -> str:
    """The first of the starts of `problem` (default: the default problem) that is registered and
    available here, with a planar mode when `planar` (else the last, whose absence then raises an
    error listing the solvers)."""
    problem = problem or get_registry().default_problem()
    starts = starts_of(problem)
    return next((name for name in starts if _available(name, problem, planar)), starts[-1])


def fallback_init(problem: str, after: str, planar: bool = False) -> str | None:
    """The start to use when `after` failed (and auto's second start): the first registered and
    available start listed after it in the problem's starts (with a planar mode when `planar`); None
    when there is none."""
    starts = starts_of(problem)
    later = starts[starts.index(after) + 1:] if after in starts else ()
    return next((name for name in later if _available(name, problem, planar)), None)


def able_start(problem: str, data: Any) -> str:
    """The first of the starts of `problem` that is registered, available here and able to solve
    validated `data` (`SolverSpec.cannot_solve`); else the last of them."""
    starts = starts_of(problem)
    solvers = get_registry().solvers
    return next((name for name in starts if _available(name, problem)
                 and solvers[name][problem].cannot_solve(data) is None), starts[-1])


def is_planar(data: Any) -> bool:
    """Whether validated data are in the planar mode (`handeye.problems.planar`)."""
    return getattr(data, "planar", None) is not None


def start(problem: Problem, data: Any, requested: str | None
          ) -> tuple[str, tuple[np.ndarray, ...], Status, dict[str, Any], list[str]]:
    """The starting poses (`flat_names` order): (solver name, poses, its status, its
    diagnostics, warnings).

    `requested` None means the default start (`default_init`); when that solve fails
    (SolverError, or its backend turns out unavailable, or an error of the problem's
    `Problem.start_refusals`: e.g. a start that serves another data protocol) the next start
    (`fallback_init`) is used, and so on, each time with a warning. A start the user asked for by
    name is never replaced: its failure raises. Without any start registered and available, or
    when every start refused the data, the error asks for the start poses.
    """
    planar = is_planar(data)
    name_ = problem.name
    fields = options_for(problem).INIT_FIELDS
    poses_hint = f"give the start poses ({', '.join(fields)}) or init=<a registered solver>"
    if requested is None and not planar and not any(_available(n, name_) for n in problem.starts):
        raise BackendUnavailableError(
            f"refine has no start for problem {name_!r}: none of its start solvers "
            f"({', '.join(problem.starts) or 'none declared'}) is registered and available here; {poses_hint}")
    name, warnings = requested or (default_init(name_, planar=True) if planar else default_init(name_)), []
    failures: list[tuple[str, Exception]] = []
    passes = (SolverError, BackendUnavailableError, *problem.start_refusals)
    while True:
        try:
            return (name, *run_init(problem, name, data), warnings)
        except passes as exc:
            failures.append((name, exc))
            fallback = (None if requested is not None else
                        fallback_init(name_, name, planar=True) if planar else fallback_init(name_, name))
            if fallback is None:
                if not problem.start_refusals or requested is not None:
                    raise
                first = failures[0][1]
                reasons = "; ".join(f"{n}: {' '.join(str(e).split())}" for n, e in failures)
                raise type(first)(f"no start solver of refine solves these data ({reasons}); {poses_hint}") from None
            warnings.append(f"the start solver {name!r} failed ({exc}); started from {fallback!r}")
            name = fallback


def run_init(problem: Problem, name: str, data: Any) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """Run registered solver `name` (default backend and options) on validated data through the
    host (`handeye.run_registered`): (poses in `flat_names` order, status, diagnostics)."""
    if name in RECURSIVE:
        raise InputError(f"init solver {name!r} would call refine recursively")
    spec = get_registry().solver(name, problem.name)  # UnknownPluginError listing the solvers
    unable = spec.cannot_solve(data)
    if unable:
        raise InputError(f"init solver {name!r} {unable}; use init='{able_start(problem.name, data)}'")
    reason = spec.unavailable_reason(spec.default_backend)
    if reason:
        raise BackendUnavailableError(f"init solver {name!r} is unavailable: {reason}")
    sol = run_registered(name, data, problem=problem.name)
    return flatten(problem, data, sol.unknowns), sol.status, dict(sol.diagnostics)


# --------------------------------------------------------------------------- solver

def settings_of(options: Options, m: int) -> nlls.Settings:
    """The engine's settings from refine's (or auto's) options, for m pairs."""
    W, kind = stated(options.sigma_rot, options.sigma_trans, options.covariance, m)
    return nlls.Settings(W, kind, options.loss, float(options.loss_scale), options.estimate,
                         int(options.max_iter), options.tol)


def refine(problem: Problem, data: Any, poses0: tuple[np.ndarray, ...], options: Options
           ) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """Refine the poses poses0 (in the problem's order of unknowns) on validated `data` with
    `options` (the init options are not used here): (poses, status, diagnostics); with the
    camera's scale unknown also that scale and its standard deviation (`handeye.estimation.camera_scale`)."""
    model = model_of(problem, data)
    settings = settings_of(options, data.m)
    if isinstance(model, camera_scale.ScaledCameraModel) and settings.W is not None and settings.W.L is not None:
        raise InputError("with camera_scale='unknown' give the noise as sigma_rot/sigma_trans (or let it be estimated), "
                         "not as a covariance: the camera's scale is fitted under one sigma per residual group")
    if options.noise == "sources" and not sources_apply(problem, data, options):
        raise InputError("noise='sources' takes A_i X = Y B_i data with the camera's scale known, the noise "
                             "estimated (no sigma_rot, sigma_trans or covariance) and loss='linear'; use noise='groups'")
    return fit(model, data, poses0, settings, options.noise)


def fit(model: nlls.PoseModel, data: Any, poses0: tuple[np.ndarray, ...], settings: nlls.Settings,
        noise: str = "groups", per_group_fit: Any = None) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any]]:
    """The engine's fit of `model` (of `data`) from `poses0` with `settings`: `handeye.estimation.nlls`, or
    with noise="sources" `handeye.estimation.noise_sources` (`per_group_fit`: as there); with the camera's
    scale profiled out (`handeye.estimation.camera_scale`) that scale and its standard deviation added to the
    diagnostics. Shared by `refine` and `auto`'s refit without the pairs it leaves out."""
    if noise == "sources":
        return noise_sources.fit(model, data, poses0, settings, per_group_fit)
    poses, status, diagnostics = nlls.refine(model, poses0, settings)
    if isinstance(model, camera_scale.ScaledCameraModel):
        W = settings.W
        sigma_rot, sigma_trans = (diagnostics["sigma_rot"], diagnostics["sigma_trans"]) if W is None else (W.sigma_rot, W.sigma_trans)
        factor = diagnostics["variance_factor"] if settings.weights == "estimated" else 1.0
        diagnostics.update(camera_scale.scale_figures(model, poses, sigma_rot, sigma_trans, factor))
    return poses, status, diagnostics


def sources_apply(problem: Problem, data: Any, options: Options) -> bool:
    """Whether the noise-source model (`handeye.estimation.noise_sources`) applies: a model whose residuals
    it describes (`PoseModel.noise_sources`: A_i X = Y B_i), the camera's scale known, the noise
    estimated, least squares."""
    return (getattr(problem.pose_model(data), "noise_sources", False)
            and not getattr(data, "camera_scale_unknown", False)
            and options.sigma_rot is None and options.covariance is None and options.loss == "linear")


def run(data: Any, options: Options, backend: str, problem: Problem) -> SolverOutput:
    """refine on `problem`'s validated data (`spec_for` hands each problem's spec its problem)."""
    given = options.start_poses()
    if given is not None:
        init_name, init_status, init_diag, warnings = "given", None, {}, []
        poses0 = flatten(problem, data, _sized(problem, data, given))
        if is_planar(data):
            poses0 = data.planar.constrain(options.UNKNOWNS, poses0)
    else:
        init_name, poses0, init_status, init_diag, warnings = start(problem, data, options.init)
    poses, status, diagnostics = refine(problem, data, poses0, options)
    if is_planar(data):
        warnings.insert(0, data.planar.warning())
        diagnostics["planar"] = data.planar.figures()
    if getattr(data, "stations", None) is not None:
        warnings.append(
            f"the {data.m} motions are every pair of {len(data.stations[0])} stations and share "
            "their noise, which refine treats as independent: its uncertainty is too small (3-6x "
            "in our simulations) and its answer not the most accurate; solver 'auto' solves the "
            "stations themselves"
        )
    diagnostics["warnings"] = warnings + diagnostics.get("warnings", [])
    diagnostics["init"] = init_name
    if init_status is not None:
        diagnostics["compile_seconds"] = float(init_diag.get("compile_seconds", 0.0))
        diagnostics["init_status"] = str(init_status)
        diagnostics["init_diagnostics"] = jsonable(init_diag)
    return SolverOutput(unknowns=unflatten(problem, data, poses), status=status, diagnostics=diagnostics)


def _sized(problem: Problem, data: Any, poses: Mapping[str, np.ndarray]) -> Mapping[str, np.ndarray]:
    """The given start poses, checked against the unknowns' shapes on these data (a stack of
    `Problem.stack_sizes` poses, else one pose)."""
    sizes = problem.stack_sizes(data)
    for name, T in poses.items():
        expected = (sizes[name], 4, 4) if name in sizes else (4, 4)
        if np.shape(T) != expected:
            raise InputError(f"option init_{name} has shape {np.shape(T)}; on these data {name} is "
                             f"{'a stack of ' + str(sizes[name]) + ' poses' if name in sizes else 'one 4x4 pose'}")
    return poses


#: one citation for every problem (the registry table shows one line per solver name)
CITATION = "geometric ML refinement on SE(3); cf. Strobl & Hirzinger, IROS 2006; Pan et al., T-ASE 2022 (init)"


def spec_for(problem: Problem) -> SolverSpec:
    """refine's spec for `problem`. It honours every mode the problem's data and model express
    (a planar robot's fixed translation through `PoseModel.fixed`, the camera's unknown scale
    profiled out), so the host lets such data through."""
    return SolverSpec(
        name="refine",
        problems=(problem.name,),
        run=functools.partial(run, problem=problem),
        options=options_for(problem),
        summary=f"maximum-likelihood refinement of {problem.equation or problem.name} on SE(3)^k "
                "(Levenberg-Marquardt, robust losses)",
        citation=CITATION,
        unit_invariant=True,
        exact=True,
        planar_mode=True,
        camera_scale_mode=True,
    )


@hookimpl
def register_solvers(register, problems):
    """refine for every registered problem that gives the engine a model (`Problem.pose_model`)."""
    for problem in problems.values():
        if problem.refinable:
            register(spec_for(problem))
