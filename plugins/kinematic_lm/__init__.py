"""`kinematic-lm` and `auto` of problem axyb-kinematic: X, Y and the arm's identifiable DH
errors by Levenberg-Marquardt, from the pose-only answer.

1. Start: problem axyb's solver `Options.start` (default ``auto``) on the pose pairs (A, B), A the
   controller's nominal forward kinematics: the answer that cannot see the arm's errors.
2. Fit (X, Y, delta) to the stations, delta the corrections of the identifiable DH parameters
   (`handeye.problems.axyb_kinematic.model`), with the residuals of problem axyb's least squares
   per station, r_i = log(R_Ai R_X R_Bi^T R_Y^T), t_i = t(A_i X) - t(Y B_i), A_i = FK(q_i; DH +
   delta), X, Y perturbed on the right as in `handeye.estimation.nlls` and delta through the base-frame
   twists of the parameters: d r = Jl^-1(r) omega_k, d t = v_k - [t(A_i X)]_x omega_k.
   Weights as the shared engine estimates them: the RMS of each residual group (rotation rad,
   translation), re-estimated at every iteration (a stationary point of the profile likelihood
   over the two variances, `handeye.estimation.whitening.estimate_sigmas`). Lengths are in units of the
   data's RMS translation throughout, so the answer does not depend on the length unit.
3. The corrections' prior (``prior="estimated"``, the default: `prior`): delta ~
   N(0, diag(tau^2)), one tau for the angles and one for the lengths, tau and the two noise
   sigmas by type-II maximum likelihood (the stations' marginal likelihood with delta, X and Y
   integrated out, linearised at the fit), alternated with the MAP fit until they settle. It
   shrinks the corrections to zero where the stations cannot see the arm's errors (tau -> 0:
   the pose-only fit) and leaves them free where they can; ``prior="none"``: the free fit.
4. Covariance: the posterior covariance at the answer (regularised), or the inverse information
   matrix with the variance factor of the estimated weights (6m / (6m - unknowns)) (free); the
   standard deviations of X, Y (as refine's ``diagnostics["std"]``) and of every identified
   parameter (``diagnostics["kinematics"]``).
5. Does it pay? The same objective fitted over (X, Y) alone with the nominal arm. ``auto``
   returns axyb's answer (the start) with the nominal arm as ``links`` where the arm's errors
   are not seen: the restricted likelihood ratio of the estimated prior against none has p >=
   `SEEN_P` (``diagnostics["prior"]``); without the prior, where `compare` (an F test of the
   identified parameters and the predicted error of each answer) says fitting them costs more
   precision than it removes. ``kinematic-lm`` fits anyway and says so in a warning.

Status: ``optimal`` when the steps vanish, ``not_converged`` at the iteration limit. Parameters the
stations determine poorly (1-sigma beyond `WEAK_ANGLE` or `WEAK_LENGTH` of the data's scale) are
named in a warning, with what to record; stations that cannot determine them at all are refused
by the problem's validation (DegenerateDataError).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl, run_registered
from handeye.base.errors import DegenerateDataError
from handeye.estimation.whitening import SIGMA_FLOOR
from handeye.framework.options import check_choice, check_int
from handeye.framework.solution import standard_deviations
from handeye.geometry import so3_fast
from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import make_pose
from handeye.plugins.kinematic_lm import prior
from handeye.problems.axyb_kinematic import PROBLEM as KINEMATIC
from handeye.problems.axyb_kinematic import model

#: solvers of problem axyb that may give the start
STARTS = ("auto", "refine", "kron-lstsq", "so3-sdp")
#: the corrections' prior: estimated from the stations (the regularised fit) or none (free)
PRIORS = ("estimated", "none")
#: a step below this (largest parameter change: rad, and lengths in units of the data's RMS
#: translation) ends the iterations
STEP_TOL = 1e-12
#: a parameter whose 1-sigma exceeds these is named as poorly determined (rad; relative to the
#: data's RMS translation: 1 mm at 1 m)
WEAK_ANGLE = math.radians(0.1)
WEAK_LENGTH = 1e-3
#: the arm's errors count as seen in the stations when the F test of the identified parameters
#: gives p below this (`compare`)
SEEN_P = 0.01
#: the regularised fit: at most this many rounds of (hyperparameters, MAP fit), ended when the
#: hyperparameters' logarithms change by less than this
HYPER_ROUNDS = 20
#: why a fit's covariance does not exist
UNDETERMINED = ("the stations do not determine X, Y and the kinematic parameters at the fitted answer: record more "
                "stations that move every joint over a wide range")
HYPER_TOL = 1e-4


@dataclasses.dataclass(frozen=True)
class Options:
    """start: problem axyb's solver for the pose-only start; max_iterations: of the fit; prior:
    ``estimated`` (the corrections' Gaussian prior, its spreads estimated from the stations:
    `prior`) or ``none`` (the free fit)."""

    start: str = "auto"
    max_iterations: int = 100
    prior: str = "estimated"

    def __post_init__(self) -> None:
        check_choice("start", self.start, STARTS)
        check_choice("prior", self.prior, PRIORS)
        check_int("max_iterations", self.max_iterations, minimum=1, maximum=10000)


@dataclasses.dataclass
class _State:
    X: np.ndarray
    Y: np.ndarray
    delta: np.ndarray


class _Fit:
    """The least-squares problem of the module docstring, lengths in units of `scale`."""

    def __init__(self, data: Any, kinematic: bool = True) -> None:
        self.scale = data.translation_scale
        self.q = data.q
        n = data.joints
        self.unit = np.where(model.length_mask(n), self.scale, 1.0)
        self.nominal = data.dh.table.ravel() / self.unit
        self.chosen = np.array(data.identifiability.identifiable if kinematic else (), dtype=int)
        self.B = np.array(data.B)
        self.B[:, :3, 3] /= self.scale
        self.size = 12 + len(self.chosen)

    def table(self, delta: np.ndarray) -> np.ndarray:
        flat = self.nominal.copy()
        flat[self.chosen] += delta
        return flat.reshape(-1, 4)

    def residuals(self, s: _State, jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        A, Xi = model.twists(self.q, self.table(s.delta))
        AX = A @ s.X
        YB = s.Y @ self.B
        r = so3_fast.log(AX[:, :3, :3] @ np.swapaxes(YB[:, :3, :3], 1, 2))
        e = np.concatenate([r, AX[:, :3, 3] - YB[:, :3, 3]], axis=1)
        if not jacobian:
            return e, None
        m = len(e)
        Jl, Jr = so3_fast.inverse_jacobians(r)
        J = np.zeros((m, 6, self.size))
        RAX = AX[:, :3, :3]
        J[:, :3, 0:3] = Jl @ RAX
        J[:, 3:, 3:6] = RAX
        RY = s.Y[:3, :3]
        J[:, :3, 6:9] = -Jr @ RY
        J[:, 3:, 6:9] = RY @ so3_fast.skew(self.B[:, :3, 3])
        J[:, 3:, 9:12] = -RY
        omega, v = Xi[:, :3, self.chosen], Xi[:, 3:, self.chosen]
        J[:, :3, 12:] = Jl @ omega
        J[:, 3:, 12:] = v - so3_fast.skew(AX[:, :3, 3]) @ omega
        return e, J

    def step(self, s: _State, d: np.ndarray) -> _State:
        def right(T: np.ndarray, xi: np.ndarray) -> np.ndarray:
            return make_pose(T[:3, :3] @ so3_fast.exp(xi[:3]), T[:3, 3] + T[:3, :3] @ xi[3:])

        return _State(right(s.X, d[:6]), right(s.Y, d[6:12]), s.delta + d[12:])


def _weights(e: np.ndarray) -> np.ndarray:
    """Per-component inverse sigmas: the RMS of each residual group, floored (`estimate_sigmas`)."""
    m = len(e)
    s_rot = max(math.sqrt(float((e[:, :3] ** 2).sum()) / (3 * m)), SIGMA_FLOOR)
    s_trans = max(math.sqrt(float((e[:, 3:] ** 2).sum()) / (3 * m)), SIGMA_FLOOR)
    return np.array([1 / s_rot] * 3 + [1 / s_trans] * 3)


def _minimise(f: _Fit, state: _State, weights: Any, prior_std: np.ndarray | None, max_iterations: int
              ) -> tuple[_State, np.ndarray, np.ndarray, int, bool]:
    """Levenberg-Marquardt from `state` on the whitened sum of squares, weights(e) -> (6,) the
    inverse sigmas (re-estimated every iteration), plus sum (delta / prior_std)^2 when a prior is
    given: (state, residuals, Jacobian, iterations, converged)."""
    e, J = f.residuals(state)
    precision = np.zeros(f.size)
    if prior_std is not None:
        precision[12:] = prior_std ** -2.0
    lam, converged, iterations = 0.0, False, 0
    for iterations in range(1, max_iterations + 1):
        w = weights(e)
        Jw = (J * w[None, :, None]).reshape(-1, f.size)
        ew = (e * w).ravel()
        theta = np.concatenate([np.zeros(12), state.delta])
        H, g = Jw.T @ Jw + np.diag(precision), Jw.T @ ew + precision * theta
        diag = np.maximum(np.diag(H), 1e-300)
        cost = float(ew @ ew) + float(precision @ theta ** 2)
        for _ in range(30):
            try:
                d = np.linalg.solve(H + lam * np.diag(diag), -g)
            except np.linalg.LinAlgError:
                d = np.full(f.size, np.nan)
            if not np.all(np.isfinite(d)):
                lam = max(10 * lam, 1e-3)
                continue
            trial = f.step(state, d)
            e_new, _ = f.residuals(trial, jacobian=False)
            new_cost = float(((e_new * w) ** 2).sum()) + float(precision[12:] @ trial.delta ** 2)
            if new_cost <= cost or np.max(np.abs(d)) < STEP_TOL:
                state, lam = trial, (0.0 if lam <= 1e-6 else lam / 10)
                break
            lam = max(10 * lam, 1e-3)
        else:
            converged = True  # no step improves the cost: stationary to working precision
            break
        e, J = f.residuals(state)
        if np.max(np.abs(d)) < STEP_TOL:
            converged = True
            break
    return state, e, J, iterations, converged


def _regularised(f: _Fit, state: _State, max_iterations: int) -> tuple[_State, np.ndarray, np.ndarray, int, bool,
                                                                        prior.Hyper]:
    """The fit with the corrections' prior, its spreads and the noise estimated from the stations
    (`prior`): alternately the hyperparameters at the current linearisation and the
    MAP fit at fixed hyperparameters, until the hyperparameters settle (`HYPER_TOL` in their
    logarithms), from the pose-only `state`."""
    is_length = model.length_mask(len(f.nominal) // 4)[f.chosen]
    e, J = f.residuals(state)
    h = prior.estimate(J, e, state.delta, is_length)
    total, converged = 0, False
    for _ in range(HYPER_ROUNDS):
        state, e, J, iterations, converged = _minimise(f, state, lambda _e, h=h: 1.0 / h.noise(),
                                                       h.spreads(is_length), max_iterations)
        total += iterations
        new = prior.estimate(J, e, state.delta, is_length, start=h)
        settled = np.max(np.abs(new.as_log() - h.as_log())) < HYPER_TOL
        h = new
        if settled:
            break
    state, e, J, iterations, converged = _minimise(f, state, lambda _e: 1.0 / h.noise(), h.spreads(is_length),
                                                   max_iterations)
    return state, e, J, total + iterations, converged, h


def fit(data: Any, X0: np.ndarray, Y0: np.ndarray, max_iterations: int = 100, kinematic: bool = True,
        regularised: bool = False) -> dict[str, Any]:
    """Levenberg-Marquardt over (X, Y, delta) from (X0, Y0, 0), or over (X, Y) alone with the
    nominal arm (`kinematic` False: the pose-only fit of the same objective), or with the
    corrections' prior estimated from the stations (`regularised`, `_regularised`): {"X", "Y",
    "table" (the fitted DH table, data units), "cov" (of the normalised parameters), "weights",
    "iterations", "converged", "residuals" (m, 6, normalised), "jacobian" (m, 6, unknowns),
    "state" (normalised X, Y, delta), "hyper" (the prior's `Hyper` or None), "gamma" (how much
    of each correction the stations determine, 1 without a prior), "seen" (the likelihood ratio
    of the prior against none and its p, `prior.without_errors`; None without)}."""
    f = _Fit(data, kinematic)

    def scaled(T: np.ndarray) -> np.ndarray:
        T = np.array(T, dtype=float)
        T[:3, 3] /= f.scale
        return T

    state = _State(scaled(X0), scaled(Y0), np.zeros(len(f.chosen)))
    h = None
    if regularised and len(f.chosen):
        state, e, J, iterations, converged, h = _regularised(f, state, max_iterations)
        is_length = model.length_mask(data.joints)[f.chosen]
        w = 1.0 / h.noise()
        try:
            cov = prior.posterior_covariance(J, h, is_length)
        except np.linalg.LinAlgError:
            raise DegenerateDataError(UNDETERMINED) from None
        gamma = prior.effective_parameters(cov, h, is_length)
        seen = prior.without_errors(J, e, state.delta, is_length, h)
    else:
        state, e, J, iterations, converged = _minimise(f, state, _weights, None, max_iterations)
        w = _weights(e)
        Jw = (J * w[None, :, None]).reshape(-1, f.size)
        dof = 6 * len(e) - f.size
        try:
            cov = np.linalg.inv(Jw.T @ Jw) * (6 * len(e) / max(dof, 1))
        except np.linalg.LinAlgError:
            raise DegenerateDataError(UNDETERMINED) from None
        gamma, seen = np.ones(len(f.chosen)), None
    X, Y = state.X.copy(), state.Y.copy()
    X[:3, 3] *= f.scale
    Y[:3, 3] *= f.scale
    table = f.table(state.delta) * f.unit.reshape(-1, 4)
    return {"X": X, "Y": Y, "table": table, "cov": cov, "unit": f.unit, "chosen": f.chosen, "weights": w,
            "iterations": iterations, "converged": converged, "residuals": e, "scale": f.scale, "jacobian": J,
            "state": state, "hyper": h, "gamma": gamma, "seen": seen}


def _rms(e: np.ndarray) -> dict[str, float]:
    return {"rotation_rms_deg": math.degrees(math.sqrt(float((e[:, :3] ** 2).sum(axis=1).mean()))),
            "translation_rms": math.sqrt(float((e[:, 3:] ** 2).sum(axis=1).mean()))}


def _difference(a: _State, b: _State) -> np.ndarray:
    """(12,): b's X and Y as right perturbations of a's (normalised units)."""
    out = []
    for Ta, Tb in ((a.X, b.X), (a.Y, b.Y)):
        out += [so3_fast.log((Ta[:3, :3].T @ Tb[:3, :3])[None])[0], Ta[:3, :3].T @ (Tb[:3, 3] - Ta[:3, 3])]
    return np.concatenate(out)


def compare(full: dict[str, Any], pose: dict[str, Any]) -> dict[str, Any]:
    """Whether fitting the arm's errors pays, from the kinematic fit and the pose-only fit of the
    same objective, both whitened by the kinematic fit's weights:

    - seen: the F test of the identified parameters, F = ((S_pose - S_kin) / p) / (S_kin / (6m -
      12 - p)) with S the whitened sums of squares (F(p, 6m - 12 - p) when the arm has no
      errors; a likelihood ratio's chi-square is too optimistic at 30 stations);
    - worth it: per group (X, Y; rotation, translation) the predicted 1-sigma error of each
      answer: the kinematic fit's from its covariance, the pose-only fit's from its covariance
      plus its bias, estimated from the difference d of the two answers as |d|^2 - (tr
      Sigma_kin - tr Sigma_pose) (Hausman's argument: d has that covariance when the pose-only
      answer is unbiased).

    ``kinematic_better``: the errors are seen (F test p < `SEEN_P`) and the geometric mean over
    the four groups of the ratio of predicted errors (pose-only over kinematic) exceeds 1."""
    from scipy.stats import f as f_distribution

    e0, e1, scale = pose["residuals"], full["residuals"], full["scale"]
    m, p = len(e1), full["jacobian"].shape[2] - 12
    w = full["weights"]
    s0, s1 = float(((e0 * w) ** 2).sum()), float(((e1 * w) ** 2).sum())
    rest = 6 * m - 12 - p
    F = ((s0 - s1) / p) / max(s1 / rest, 1e-300) if p and rest > 0 else 0.0
    seen_p = float(f_distribution.sf(F, p, rest)) if p and rest > 0 else 1.0
    J0 = (pose["jacobian"] * w[None, :, None]).reshape(-1, 12)
    J1 = (full["jacobian"] * w[None, :, None]).reshape(-1, full["jacobian"].shape[2])
    S1, S0 = np.linalg.pinv(J1.T @ J1)[:12, :12], np.linalg.pinv(J0.T @ J0)
    d = _difference(full["state"], pose["state"])
    predicted: dict[str, dict[str, dict[str, float]]] = {"kinematic": {}, "pose_only": {}}
    logs = []
    for name, o in (("X", 0), ("Y", 6)):
        for kind, g, unit in (("rotation", slice(o, o + 3), 1.0), ("translation", slice(o + 3, o + 6), scale)):
            kin, only = max(float(S1[g, g].trace()), 0.0), max(float(S0[g, g].trace()), 0.0)  # rounding
            biased = only + max(float(d[g] @ d[g]) - (kin - only), 0.0)
            predicted["kinematic"].setdefault(name, {})[kind] = math.sqrt(kin) * unit
            predicted["pose_only"].setdefault(name, {})[kind] = math.sqrt(biased) * unit
            logs.append(0.5 * math.log(max(biased, 1e-300) / max(kin, 1e-300)))
    return {"F": F, "F_p": seen_p, "parameters": p, "predicted_error": predicted,
            "kinematic_better": bool(seen_p < SEEN_P and np.mean(logs) > 0.0)}


def _parameters(data: Any, result: dict[str, Any]) -> tuple[list[dict[str, Any]], list[str]]:
    """The identified DH parameters with their standard deviations, and the poorly determined."""
    std = np.sqrt(np.maximum(np.diag(result["cov"]), 0.0))
    nominal, table, unit = data.dh.table.ravel(), result["table"].ravel(), result["unit"]
    parameters, weak = [], []
    for k, index in enumerate(result["chosen"]):
        length = bool(model.length_mask(data.joints)[index])
        sigma = float(std[12 + k] * unit[index])
        parameters.append({"name": model.parameter_name(int(index)), "unit": "length" if length else "rad",
                           "nominal": float(nominal[index]), "estimate": float(table[index]),
                           "correction": float(table[index] - nominal[index]), "std": sigma})
        if (sigma > WEAK_LENGTH * result["scale"]) if length else (sigma > WEAK_ANGLE):
            shown = f"{sigma:.2g} length units" if length else f"{math.degrees(sigma):.2g} deg"
            weak.append(f"{model.parameter_name(int(index))} to +-{shown}")
    return parameters, weak


def _pose_std(result: dict[str, Any]) -> dict[str, dict[str, float]]:
    cov, scale = result["cov"], result["scale"]
    return {name: {"rotation": float(math.sqrt(cov[o:o + 3, o:o + 3].trace())),
                   "translation": float(math.sqrt(cov[o + 3:o + 6, o + 3:o + 6].trace()) * scale)}
            for name, o in (("X", 0), ("Y", 6))}


def _shown(error: dict[str, dict[str, float]]) -> str:
    return (f"X {math.degrees(error['X']['rotation']):.2g} deg / {error['X']['translation']:.2g}, "
            f"Y {math.degrees(error['Y']['rotation']):.2g} deg / {error['Y']['translation']:.2g}")


def _pose_only_warning(data: Any, comparison: dict[str, Any], full: dict[str, Any], use_pose: bool,
                       options: Options) -> str:
    """Why the pose-only answer is as good (`auto` returns it; kinematic-lm fits anyway)."""
    then = (f"the answer is axyb's {options.start} on the poses with the nominal arm (links); use solver "
            "kinematic-lm to fit the arm anyway" if use_pose else "solver auto returns the pose-only answer for "
            "such data")
    predicted = comparison["predicted_error"]
    if full["hyper"] is not None:
        why = (f"the {data.m} stations do not show the arm's kinematic errors (likelihood ratio test of the "
               f"estimated prior against none: p = {full['seen'][1]:.2g}; the regularised fit determines "
               f"{float(full['gamma'].sum()):.2g} of {len(full['gamma'])} corrections' worth)")
    else:
        why = f"the {data.m} stations do not show the arm's kinematic errors beyond what fitting them costs"
    return (f"{why} (predicted 1-sigma errors with the free fit: {_shown(predicted['kinematic'])}; with the "
            f"nominal arm: {_shown(predicted['pose_only'])}): {then}; record more stations that move every joint "
            "over a wide range for a kinematic calibration")


def _fits(data: Any, options: Options, start: Any) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(the answer's fit: regularised or free per `options.prior`; the free fit; the pose-only fit)."""
    free = fit(data, start.X, start.Y, options.max_iterations)
    pose = fit(data, start.X, start.Y, options.max_iterations, kinematic=False)
    full = free if options.prior == "none" else fit(data, start.X, start.Y, options.max_iterations, regularised=True)
    return full, free, pose


def _pose_only_pays(full: dict[str, Any], comparison: dict[str, Any]) -> bool:
    """Whether `auto` should return the pose-only answer: with the estimated prior when the
    restricted likelihood ratio does not show the arm's errors (p >= `SEEN_P`,
    `prior.without_errors`); without, `compare`'s verdict."""
    if full["hyper"] is not None:
        return full["seen"][1] >= SEEN_P
    return not comparison["kinematic_better"]


def solve(data: Any, options: Options, choose: bool) -> SolverOutput:
    """The fit of the module docstring (regularised by default); with `choose` (``auto``) the
    pose-only answer (the start) instead where the stations do not show the arm's errors
    (`_pose_only_pays`)."""
    start = run_registered(options.start, data.pairs, problem="axyb")
    full, free, pose = _fits(data, options, start)
    comparison = compare(free, pose)
    parameters, weak = _parameters(data, full)
    pose_pays = _pose_only_pays(full, comparison)
    use_pose = choose and pose_pays
    warnings = []
    if pose_pays:
        warnings.append(_pose_only_warning(data, comparison, full, use_pose, options))
    elif weak and full["hyper"] is None:
        warnings.append(f"the {data.m} stations determine some kinematic parameters poorly (1 sigma): "
                        f"{', '.join(weak)}; record more stations that move every joint over a wide range")
    elif weak:
        warnings.append(f"the {data.m} stations determine some kinematic parameters poorly (1 sigma): "
                        f"{', '.join(weak)}; the estimated prior holds them near nominal; record more stations "
                        "that move every joint over a wide range")
    result = pose if use_pose else full
    start_e = KINEMATIC.residuals(data, {"X": start.X, "Y": start.Y})
    residuals = result["residuals"].copy()
    residuals[:, 3:] *= result["scale"]
    std = _pose_std(result)
    if use_pose:  # the start itself: axyb's answer, whose noise model may be richer than this fit's
        std = standard_deviations(start.diagnostics) or std
        residuals = None
    diagnostics = {
        "answer": f"pose-only ({options.start} of axyb)" if use_pose else "kinematic",
        "iterations": full["iterations"],
        "start": {"solver": options.start, "status": start.status.value,
                  "rotation_rms_deg": math.degrees(float(np.sqrt(np.mean(start_e["rotation"] ** 2)))),
                  "translation_rms": float(np.sqrt(np.mean(start_e["translation"] ** 2)))},
        "fit": _rms(residuals) if residuals is not None else {
            "rotation_rms_deg": math.degrees(float(np.sqrt(np.mean(start_e["rotation"] ** 2)))),
            "translation_rms": float(np.sqrt(np.mean(start_e["translation"] ** 2)))},
        "sigmas": {"rotation": float(1 / result["weights"][0]),
                   "translation": float(result["scale"] / result["weights"][3])},
        "std": std,
        "comparison": comparison,
        "prior": _prior_diagnostics(full),
        "kinematics": {"used": not use_pose, "parameters": parameters,
                       "not_identifiable": [model.parameter_name(k) for k, _ in data.identifiability.confounded],
                       "why": data.identifiability.words(data.dh.table),
                       "dh": full["table"].tolist()},
        "warnings": warnings,
    }
    status = start.status if use_pose else (Status.OPTIMAL if full["converged"] else Status.NOT_CONVERGED)
    links = DHArm.from_table(result["table"]).links()
    X, Y = (start.X, start.Y) if use_pose else (result["X"], result["Y"])
    return SolverOutput({"X": X, "Y": Y, "links": links},
                        status, diagnostics)


def _prior_diagnostics(full: dict[str, Any]) -> dict[str, Any] | None:
    """The estimated prior: its spreads (angle rad, length in data units), the noise it found and
    how many corrections' worth the stations determine (None for the free fit)."""
    h = full["hyper"]
    if h is None:
        return None
    return {"tau_angle": h.tau[0], "tau_length": h.tau[1] * full["scale"], "sigma_rotation": h.sigma[0],
            "sigma_translation": h.sigma[1] * full["scale"], "effective_parameters": float(full["gamma"].sum()),
            "likelihood_ratio": full["seen"][0], "p": full["seen"][1]}


def run(data: Any, options: Options, backend: str) -> SolverOutput:
    """kinematic-lm: always the kinematic fit (with a warning when it is predicted not to pay)."""
    return solve(data, options, choose=False)


def run_auto(data: Any, options: Options, backend: str) -> SolverOutput:
    """auto: the kinematic fit, or the pose-only fit where the stations cannot show the arm's errors."""
    return solve(data, options, choose=True)


SUMMARY = "X, Y and the arm's identifiable DH errors by Levenberg-Marquardt from the pose-only answer"
CITATION = ("Zhuang, Roth & Sudhakar, IEEE T-RA 10(4), 1994 (simultaneous robot/world and tool/flange "
            "calibration with kinematic parameters); Hollerbach & Wampler, IJRR 15(6), 1996")
SPEC = SolverSpec(name="kinematic-lm", problems=(KINEMATIC.name,), run=run, options=Options, summary=SUMMARY,
                  citation=CITATION, unit_invariant=True, exact=True)
#: the problem's default: the same fit, or the pose-only one where it does not pay (`compare`); cited as the other problems' auto (its start is axyb's auto), so
#: that `handeye list --markdown` keeps one row for the name
AUTO = dataclasses.replace(SPEC, name="auto", run=run_auto,
                           summary="kinematic-lm from axyb's auto, or the pose-only fit where the arm's errors do not "
                                   "show: the default of axyb-kinematic",
                           citation="Pan et al., IEEE T-ASE 2022 (eq. 8); see docs/solvers/auto.md")


@hookimpl
def register_solvers(register: Any) -> None:
    register(SPEC)
    register(AUTO)
