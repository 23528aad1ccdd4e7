"""`kinematic-lm` and `auto` of problem axyb-kinematic: X, Y and the arm's identifiable DH
errors by Levenberg-Marquardt, from the pose-only answer.

1. Start: problem axyb's solver `Options.start` (default ``auto``) on the pose pairs (A, B), A the
   controller's nominal forward kinematics: the answer that cannot see the arm's errors.
2. Fit (X, Y, delta) to the stations, delta the corrections of the identifiable DH parameters
   (`handeye.problems.axyb_kinematic.model`), with the residuals of problem axyb's least squares
   per station, r_i = log(R_Ai R_X R_Bi^T R_Y^T), t_i = t(A_i X) - t(Y B_i), A_i = FK(q_i; DH +
   delta), X, Y perturbed on the right as in `handeye.nlls` and delta through the base-frame
   twists of the parameters: d r = Jl^-1(r) omega_k, d t = v_k - [t(A_i X)]_x omega_k.
   Weights as the shared engine estimates them: the RMS of each residual group (rotation rad,
   translation), re-estimated at every iteration (a stationary point of the profile likelihood
   over the two variances, `handeye.whitening.estimate_sigmas`). Lengths are in units of the
   data's RMS translation throughout, so the answer does not depend on the length unit.
3. Covariance: the inverse information matrix at the answer, with the variance factor of the
   estimated weights (6m / (6m - unknowns)); the standard deviations of X, Y (as refine's
   ``diagnostics["std"]``) and of every identified parameter (``diagnostics["kinematics"]``).
4. Does it pay? The same objective fitted over (X, Y) alone with the nominal arm, and `compare`:
   an F test of the identified parameters, and the predicted error of each answer (the pose-only
   one's bias estimated from the difference of the two). Where fitting the arm is predicted to
   cost more precision than it removes bias (small DH errors, noisy camera, few stations),
   ``kinematic-lm`` says so in a warning and ``auto`` returns the pose-only fit with the nominal
   arm as ``links`` (``diagnostics["answer"]``), with a warning that says why.

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
from handeye.estimation.whitening import SIGMA_FLOOR
from handeye.framework.errors import DegenerateDataError
from handeye.framework.options import check_choice, check_int
from handeye.framework.solution import standard_deviations
from handeye.geometry import so3_fast
from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import make_pose
from handeye.problems.axyb_kinematic import PROBLEM as KINEMATIC
from handeye.problems.axyb_kinematic import model

#: solvers of problem axyb that may give the start
STARTS = ("auto", "refine", "kron-lstsq", "so3-sdp")
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


@dataclasses.dataclass(frozen=True)
class Options:
    """start: problem axyb's solver for the pose-only start; max_iterations: of the fit."""

    start: str = "auto"
    max_iterations: int = 100

    def __post_init__(self) -> None:
        check_choice("start", self.start, STARTS)
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


def fit(data: Any, X0: np.ndarray, Y0: np.ndarray, max_iterations: int = 100, kinematic: bool = True
        ) -> dict[str, Any]:
    """Levenberg-Marquardt over (X, Y, delta) from (X0, Y0, 0), or over (X, Y) alone with the
    nominal arm (`kinematic` False: the pose-only fit of the same objective): {"X", "Y", "table"
    (the fitted DH table, data units), "cov" (of the normalised parameters), "weights",
    "iterations", "converged", "residuals" (m, 6, normalised), "jacobian" (m, 6, unknowns),
    "state" (normalised X, Y, delta)}."""
    f = _Fit(data, kinematic)

    def scaled(T: np.ndarray) -> np.ndarray:
        T = np.array(T, dtype=float)
        T[:3, 3] /= f.scale
        return T

    state = _State(scaled(X0), scaled(Y0), np.zeros(len(f.chosen)))
    e, J = f.residuals(state)
    lam, converged, iterations = 0.0, False, 0
    for iterations in range(1, max_iterations + 1):
        w = _weights(e)
        Jw = (J * w[None, :, None]).reshape(-1, f.size)
        ew = (e * w).ravel()
        H, g = Jw.T @ Jw, Jw.T @ ew
        diag = np.maximum(np.diag(H), 1e-300)
        cost = float(ew @ ew)
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
            if float(((e_new * w) ** 2).sum()) <= cost or np.max(np.abs(d)) < STEP_TOL:
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
    w = _weights(e)
    Jw = (J * w[None, :, None]).reshape(-1, f.size)
    dof = 6 * len(e) - f.size
    try:
        cov = np.linalg.inv(Jw.T @ Jw) * (6 * len(e) / max(dof, 1))
    except np.linalg.LinAlgError:
        raise DegenerateDataError("the stations do not determine X, Y and the kinematic parameters at the fitted "
                                  "answer: record more stations that move every joint over a wide range") from None
    X, Y = state.X.copy(), state.Y.copy()
    X[:3, 3] *= f.scale
    Y[:3, 3] *= f.scale
    table = f.table(state.delta) * f.unit.reshape(-1, 4)
    return {"X": X, "Y": Y, "table": table, "cov": cov, "unit": f.unit, "chosen": f.chosen, "weights": w,
            "iterations": iterations, "converged": converged, "residuals": e, "scale": f.scale, "jacobian": J,
            "state": state}


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


def solve(data: Any, options: Options, choose: bool) -> SolverOutput:
    """The fit of the module docstring; with `choose` (``auto``) the pose-only answer (the start)
    instead when fitting the arm's errors is predicted to cost more precision than it gains
    (`compare`)."""
    start = run_registered(options.start, data.pairs, problem="axyb")
    full = fit(data, start.X, start.Y, options.max_iterations)
    pose = fit(data, start.X, start.Y, options.max_iterations, kinematic=False)
    comparison = compare(full, pose)
    parameters, weak = _parameters(data, full)
    predicted = comparison["predicted_error"]
    use_pose = choose and not comparison["kinematic_better"]
    warnings = []
    if not comparison["kinematic_better"]:
        then = (f"the answer is axyb's {options.start} on the poses with the nominal arm (links); use solver kinematic-lm to fit the "
                "arm anyway" if use_pose else "solver auto returns the pose-only answer for such data")
        warnings.append(f"the {data.m} stations do not show the arm's kinematic errors beyond what fitting them costs "
                        f"(predicted 1-sigma errors with the fit: {_shown(predicted['kinematic'])}; with the nominal "
                        f"arm: {_shown(predicted['pose_only'])}): {then}; record more stations that move every joint "
                        "over a wide range for a kinematic calibration")
    elif weak:
        warnings.append(f"the {data.m} stations determine some kinematic parameters poorly (1 sigma): "
                        f"{', '.join(weak)}; record more stations that move every joint over a wide range")
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
