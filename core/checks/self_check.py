"""The host's self-check of every answer, and how precisely the data determine it.

A solver's status says it solved *its* problem. Under heavy noise, with few pairs, tiny
translations or gross pairs, a closed form can solve its problem and still return a rotation
tens of degrees off, with status ``optimal``. `handeye.solve` therefore checks every answer, any
solver's (third parties' too), against the data it was computed from:

1. **Residuals against the noise the data show.** The rotation angle and the screw pitch of a
   motion are the same for the robot and the camera (A = X B X^-1 conjugates), so their
   differences measure the noise without knowing X (`angle_noise`, `pitch_noise`). The median
   residual rotation of a correct answer is about CHI3_MEDIAN times the angle noise, plus what a
   fit trades for the translation noise (`expected_from_invariants`); an answer whose median
   residual rotation exceeds `ROTATION_RESIDUAL_FACTOR` times that is broken.
2. **Distance from the best fit.** From the answer, a local maximum-likelihood fit of the same
   data (`handeye.estimation.nlls`, the engine of ``refine``; Cauchy loss when some pairs are far off the
   others) gives the best answer near it and its covariance. The answer's distance from it in
   standard deviations, d = sqrt(delta^T Sigma^-1 delta), is ~0-3 for a good estimator; beyond
   `DISTANCE_WARN` a warning says how far and that ``auto`` fits better (and the host makes the
   status ``suboptimal``: an ``optimal`` answer beside that warning would contradict it); beyond `DISTANCE_FAIL`
   the answer is unreliable. (Sigma gets a floor of NUMERICAL_FLOOR so that noise-free data, where
   every numerical solver is "infinitely many sigmas" from the exact answer at 1e-8, pass.)
3. **Gross pairs.** Pairs whose whitened residual exceeds OUTLIER_CHI2 (`handeye.estimation.robust`) at the
   least-squares fit, or pairs outside the data's largest group that agree with each other
   (check 7), make the best fit of check 2 a robust (Cauchy) one, from the least-squares fit and
   from the answer, the lower Cauchy cost kept (`handeye.checks.best_fit.robust_fit`); the pairs still far off
   at it, unless the solver reports having left them out (``diagnostics["outliers"]``, as
   ``auto`` does), are named in check 2's message, as the reason its answer is pulled away.
4. **Signs a solver reports of a broken estimate** (``diagnostics["rotation_blocks"]``: the
   determinant and singular values of each rotation block before projection onto SO(3), see
   `rotation_block_figures`): det <= 0 or singular values further apart than BLOCK_SPREAD.

5. **Camera scale** (A X = Y B, A X = X B): the factor s the camera's translations need to fit
   the robot's (`handeye.estimation.camera_scale`), from the best fit (`handeye.checks.scale_checks.camera_scale_check`): beyond a factor
   SCALE_FAIL either way a failure (a unit mix-up, or a monocular camera: give
   camera_scale="unknown"), beyond SCALE_WARN a warning; both only SCALE_SIGMAS standard
   deviations from 1. A cell of several cameras (``axyb-multi``) first per camera
   (`camera_scales_check`: each X's and each Y's observations), naming the cameras to give in
   camera_scale=[names].
6. **Camera scale fitted** (the data's camera_scale unknown, or fitted by ``auto``): noise in the
   camera's translations biases the fitted scale toward zero (errors in variables), by up to
   kappa (`handeye.estimation.camera_scale.noise_bias`), which its stated uncertainty leaves out
   (`camera_scale_noise`): beyond NOISE_BIAS_FAIL a failure (the data do not determine the
   scale), beyond SCALE_WARN a warning; both only NOISE_BIAS_SIGMAS standard deviations of s.

7. **A consistent majority** (A X = Y B, A X = X B): the largest group of pairs that agree with
   each other, without X or Y (robot and camera rotation angles between them equal to
   `handeye.geometry.validation.AGREEMENT_ANGLE`), must hold more than half the pairs (`MAJORITY`); else
   at least half are gross and no fit can be trusted (a failure, named first).

8. **Systematic robot errors** (`handeye.checks.systematic`): residuals at the best fit that
   follow the arm's configuration (an F test of their regression on the flange's position, the
   stations given by ``Problem.configurations``) get a warning naming the robot's kinematics.

Then **observability**: the covariance of the best fit, at the noise the data show, says how
precisely the data determine each unknown; where the 1-sigma of a rotation exceeds
`PRECISION_ROTATION_DEG` or of a translation exceeds `PRECISION_TRANSLATION` of the data's lever
arm (their RMS translation), a warning gives the figures and the worst direction, named when it
is the robot's main rotation axis (few or nearly parallel rotation axes).

A problem takes part through four optional methods of `handeye.framework.problem.Problem`:
``check_model`` (the least-squares model of check 2, with nuisance unknowns fitted),
``expected_rotation_residual`` (check 1) and ``rotation_axes`` (for naming directions), and
``configurations`` (check 8).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError
from handeye.checks import systematic
from handeye.checks.best_fit import best_fit
from handeye.checks.scale_checks import (
    camera_scale_check,
    camera_scale_noise,
    camera_scales_check,
)
from handeye.estimation.robust import MAD_TO_SIGMA
from handeye.estimation.whitening import CHI3_MEDIAN
from handeye.framework.problem import item_listing
from handeye.framework.reported import Reported
from handeye.geometry import so3_fast
from handeye.geometry.linalg import eigh_stack, einsum, median, row_norms, solve
from handeye.geometry.validation import AGREEMENT_ANGLE

#: check 1: median residual rotation beyond this many times what the data's noise gives
ROTATION_RESIDUAL_FACTOR = 10.0
#: check 2: distance from the best fit (standard deviations) beyond which a warning is given ...
DISTANCE_WARN = 5.0
#: ... and beyond which the answer is unreliable. Between the two the answer is wrong beyond the
#: data's uncertainty but not broken: the paper's lmi-sdp and li, whose Kronecker cost is not the
#: likelihood, land at 20-70 sigma on ordinary data (0.01-0.1 deg, 1-5 mm from the best fit);
#: the broken answers of the reliability campaign (docs/reliability.md) at 100-20000.
DISTANCE_FAIL = 100.0
#: rotation (rad), and translation relative to the data's lever arm, below which differences are
#: exact for every practical purpose (numerical solvers stop at ~1e-8 on noise-free data, where
#: the best fit's sigma is ~1e-13 and every such answer would otherwise be "many sigmas" off)
NUMERICAL_FLOOR = 1e-6
#: check 4: largest ratio of the singular values of a rotation block before projection
BLOCK_SPREAD = 2.0
#: motions rotating less than this (rad) give no usable angle difference (check 1)
MIN_ANGLE = 0.1
#: fewest usable motions for check 1
MIN_MOTIONS = 3
#: check 7: the largest group of pairs that agree with each other must hold more than this share
MAJORITY = 0.5
#: observability: 1-sigma beyond which the data do not determine an unknown well enough
PRECISION_ROTATION_DEG = 0.25
PRECISION_TRANSLATION = 0.01
#: ... and beyond which the answer is not to be used (a failure: status unreliable): no cell is
#: calibrated to 2 deg, and a translation known to 10% of the lever arm moves what the camera sees
#: by as much. Half the pairs gross gave answers 5-52 deg off with a 1-sigma of 4-10 deg, which
#: is what this catches (docs/reliability.md)
UNRELIABLE_ROTATION_DEG = 2.0
UNRELIABLE_TRANSLATION = 0.10
#: the rotations are "mostly about one axis" when the second eigenvalue of sum phi phi^T is below
#: this share of the first (axes within ~35 deg of each other)
AXIS_SHARE = 0.1
#: a direction within this angle (deg) of the robot's main rotation axis is named as that axis
AXIS_NAMING_DEG = 25.0



@dataclasses.dataclass(frozen=True)
class Assessment:
    """What the self-check found: reliable (all checks passed), failures (why not, for the
    user), warnings (weaker findings and precision), figures (JSON-ready, for diagnostics)."""

    reliable: bool
    failures: tuple[str, ...]
    warnings: tuple[str, ...]
    figures: Mapping[str, Any]


def angle_noise(angle_A: np.ndarray, angle_B: np.ndarray) -> float | None:
    """Robust standard deviation (rad) of the differences of the rotation angles of paired
    motions (MAD_TO_SIGMA x their median absolute value), over the motions that rotate by more than
    MIN_ANGLE on both sides; None with fewer than MIN_MOTIONS such motions."""
    use = (angle_A > MIN_ANGLE) & (angle_B > MIN_ANGLE)
    if use.sum() < MIN_MOTIONS:
        return None
    return MAD_TO_SIGMA * median(np.abs(angle_A[use] - angle_B[use]))


def pitch_noise(phi_A: np.ndarray, t_A: np.ndarray, phi_B: np.ndarray, t_B: np.ndarray,
                angles: tuple[np.ndarray, np.ndarray] | None = None) -> float | None:
    """Robust standard deviation (data units) of the differences of the screw pitches n . t
    (translation along the rotation axis, invariant like the angle under A = X B X^-1, and under
    inverting a pose) of paired motions, over those that rotate by more than MIN_ANGLE on both
    sides; None with fewer than MIN_MOTIONS such motions. Motions given by rotation vectors phi
    and translations t, (n, 3) each; `angles`: their norms (the rotation angles) when the caller
    has them."""
    angle_A, angle_B = (row_norms(phi_A), row_norms(phi_B)) if angles is None else angles
    use = (angle_A > MIN_ANGLE) & (angle_B > MIN_ANGLE)
    if use.sum() < MIN_MOTIONS:
        return None
    pitch_A = einsum("ij,ij->i", phi_A[use], t_A[use]) / angle_A[use]
    pitch_B = einsum("ij,ij->i", phi_B[use], t_B[use]) / angle_B[use]
    return MAD_TO_SIGMA * median(np.abs(pitch_A - pitch_B))


def expected_from_invariants(angle_sigma: float | None, pitch_sigma: float | None, lever: float,
                             stations_per_pair: float) -> float | None:
    """Check 1's expected median rotation residual: `chi3_expected` of the angle noise, and of
    the rotation a fit trades for translation noise (the pitch noise over the data's lever arm:
    with exact rotations and noisy translations a good answer still leaves rotation residuals,
    which the angles alone cannot show). None when the angles give nothing."""
    if angle_sigma is None:
        return None
    coupled = (pitch_sigma or 0.0) / lever if lever > 0 else 0.0
    return chi3_expected(math.hypot(angle_sigma, coupled), stations_per_pair)


def main_axis(rotation_vectors: np.ndarray) -> np.ndarray | None:
    """The unit axis the rotations (rotation vectors, (n, 3)) turn mostly about: the principal
    eigenvector of sum phi phi^T (sign free), when its eigenvalue is at least 1 / AXIS_SHARE times
    the next one (the rotations are mostly about one axis); else None."""
    return main_axes(rotation_vectors)[0]


def main_axes(*rotation_vectors: np.ndarray) -> list[np.ndarray | None]:
    """`main_axis` of each set of rotation vectors (each (n, 3), the same n), in one call."""
    phi = np.stack(rotation_vectors)
    w, V = np.linalg.eigh(np.swapaxes(phi, 1, 2) @ phi)
    return [V[b, :, 2] if w[b, 2] > MIN_ANGLE**2 and w[b, 1] < AXIS_SHARE * w[b, 2] else None
            for b in range(len(phi))]


def rotation_block_figures(M: np.ndarray) -> dict[str, Any]:
    """What a solver reports of a 3x3 rotation block before projecting it onto SO(3): its
    determinant and singular values, after scaling to |det| = 1 (check 4)."""
    M = np.asarray(M, dtype=float)
    det = float(np.linalg.det(M))
    s = np.linalg.svd(M, compute_uv=False)
    scale = abs(det) ** (1.0 / 3.0) if det != 0 and math.isfinite(det) else float(s.max() or 1.0)
    return {"det": float(np.sign(det)), "singular_values": (s / scale).tolist()}


def assess(problem: Any, data: Any, unknowns: Mapping[str, np.ndarray], diagnostics: Mapping[str, Any],
           solver: str | None = None) -> Assessment:
    """Run the checks of the module docstring on `unknowns`, the answer a solver (named `solver`,
    for the advice its messages give) gave for the validated `data` of `problem` (with its
    `diagnostics`)."""
    failures: list[str] = []
    warnings: list[str] = []
    figures: dict[str, Any] = {}
    reported = Reported.of(diagnostics)
    spec = problem.check_model(data, unknowns)
    rotation = None
    if spec is not None:
        rotation = _local_fit(problem, data, spec, reported, failures, warnings, figures, solver)
    _rotation_residual(problem, data, unknowns, failures, figures, rotation, reported.held_out_best, warnings)
    _rotation_blocks(reported, failures, figures)
    failures.sort(key=lambda f: not f.startswith("the answer leaves"))  # check 1 first: it says the most
    _majority(data, failures, figures)  # first of all when it fails: no answer can be right
    return Assessment(not failures, tuple(failures), tuple(warnings), figures)


def _majority(data: Any, failures: list[str], figures: dict[str, Any]) -> None:
    """Check 7: the data's largest group of mutually agreeing pairs (`data.agreeing_share`, where
    the problem's data have it: `handeye.geometry.validation.agreeing_share`) must be a majority."""
    share = getattr(data, "agreeing_share", None)
    if share is None:
        return
    figures["agreeing_share"] = share
    if share <= MAJORITY:
        failures.insert(0, f"no majority of consistent pairs exists: the largest group of pairs that agree with each "
                           f"other (the robot's and the camera's rotations between them, to "
                           f"{math.degrees(AGREEMENT_ANGLE):g} deg) holds {share:.0%} of them, so at least half are "
                           "gross errors (failed detections, mismatched poses) and no fit can tell the right answer "
                           "from a wrong one: check the pairing and the detections, and record more stations")


def _rotation_residual(problem: Any, data: Any, unknowns: Mapping[str, np.ndarray], failures: list[str],
                       figures: dict[str, Any], rotation: np.ndarray | None = None,
                       best: Mapping[str, Any] | None = None, warnings: list[str] | None = None) -> None:
    """Check 1 (`expected_from_invariants`); `rotation`: the pairs' rotation residuals at the
    answer when the local fit already has them (the angle of the rotation residual of its model
    is the problem's residual rotation), else they are computed. With `best` (`Reported.held_out_best`:
    the answer predicts held-out stations at least as well as every alternative compared) the
    residuals above the noise are systematic (a real robot's kinematics), not a broken answer:
    a warning in `warnings`, not a failure; the solver widens the 1-sigma for them."""
    expected = problem.expected_rotation_residual(data)
    if expected is None:
        return
    typical = median(rotation if rotation is not None else problem.residuals(data, unknowns)["rotation"])
    ratio = typical / max(expected, NUMERICAL_FLOOR)
    figures["rotation_residual"] = {"median_deg": math.degrees(typical), "expected_deg": math.degrees(expected),
                                    "ratio": ratio}
    if typical > NUMERICAL_FLOOR and ratio > ROTATION_RESIDUAL_FACTOR:
        found = (f"the answer leaves a median rotation residual of {math.degrees(typical):.3g} deg per pair, "
                 f"{ratio:.3g} times what the noise of these data gives ({math.degrees(expected):.2g} deg, from the "
                 "rotation angles of robot and camera motions, which must agree)")
        if best is None or warnings is None:
            failures.append(found)
            return
        others = ", ".join(f"{name} {px:.3g}" for name, px in best.get("others_px", {}).items()
                           if px is not None)
        figures["rotation_residual"]["systematic"] = True
        warnings.append(f"self-check: {found}. Yet it predicts stations it was not fitted to best of the fits "
                        f"compared ({best.get('measure', 'held-out prediction')}: {best.get('answer_px', float('nan')):.3g}"
                        f"; {others or 'no other'}): the excess is systematic error (usually the robot's "
                        "kinematics), not a broken answer, and it is in the stated 1-sigma")


def _rotation_blocks(reported: Reported, failures: list[str], figures: dict[str, Any]) -> None:
    """Check 4."""
    blocks = reported.rotation_blocks
    for name, block in blocks.items():
        s = np.asarray(block.get("singular_values", []), dtype=float)
        det = float(block.get("det", 1.0))
        if det <= 0 or (len(s) and s.min() * BLOCK_SPREAD < s.max()):
            failures.append(
                f"the solver's rotation of {name} before projection was far from a rotation (determinant "
                f"{'<= 0' if det <= 0 else '> 0'}, singular values {', '.join(f'{v:.2g}' for v in s)} where a "
                "rotation has 1, 1, 1): its linear system does not determine the rotation with this noise")
    if blocks:
        figures["rotation_blocks"] = dict(blocks)


def _local_fit(problem: Any, data: Any, spec: tuple[Any, tuple[np.ndarray, ...], tuple[str, ...]],
               reported: Reported, failures: list[str], warnings: list[str],
               figures: dict[str, Any], solver: str | None = None) -> np.ndarray | None:
    """Checks 2, 3 and 5, and the observability warnings; returns the rotation residuals of the
    data's pairs at the answer (for check 1) when the model is on those pairs, else None."""
    model, poses, interest = spec
    try:
        fit, cov, flagged, res, at_answer, factor = best_fit(model, poses, _disagreeing(data))
    except DegenerateDataError:
        failures.append("the data do not determine the unknowns near this answer (the least-squares fit from it "
                        "is singular)")
        return None
    # a cell's cameras one by one first (a monocular camera's observations may all be far off, so
    # whether or not some are); one scale for every camera where that names none
    before = len(failures) + len(warnings)
    camera_scales_check(model, res, cov, failures, warnings, figures, reported.camera_scales_held_out)
    if not flagged.any() and len(failures) + len(warnings) == before:
        camera_scale_check(model, res, cov, failures, warnings, figures)
    camera_scale_noise(model, res, factor, failures, warnings, figures)
    configurations = getattr(problem, "configurations", None)
    systematic.assess_configuration(configurations(data) if configurations else None, model, res, flagged,
                                    warnings, figures, covered=reported.sigma_from == "stations",
                                    # the spread of this pose-level fit speaks for answers fitted to the poses;
                                    # one fitted to other measurements (corners) states its own
                                    cov=cov if reported.fitted_to == "poses" else None,
                                    stated=bool(reported.std))
    names = model.unknowns
    delta = _difference(poses, fit)
    chosen = [j for j, n in enumerate(names) if n in interest]
    # the floors' variances, once per chosen unknown (the list repeated: np.tile's numbers, ~3 us less)
    floor = np.diag(np.array(([NUMERICAL_FLOOR] * 3 + [NUMERICAL_FLOOR * model.scale] * 3) * len(chosen)) ** 2)
    if len(chosen) == len(names):  # every unknown (the usual case): cov and delta as they are
        sigma = cov + floor
    else:
        keep = np.concatenate([np.arange(6 * j, 6 * j + 6) for j in chosen])
        sigma, delta = cov[np.ix_(keep, keep)] + floor, delta[keep]
    d = math.sqrt(max(float(delta @ solve(sigma, delta)), 0.0))
    figures["distance_sigmas"] = d

    def gap_text() -> str:  # for the messages only
        return "; ".join(
            f"{names[j]} differs by {math.degrees(float(np.linalg.norm(omega))):.2g} deg / "
            f"{float(np.linalg.norm(poses[j][:3, 3] - fit[j][:3, 3])):.3g}"
            for j, omega in zip(chosen, delta.reshape(-1, 6)[:, :3])) + ", translations in the data's length unit"
    left_out = reported.left_out
    used = [int(i) for i in np.flatnonzero(flagged) if int(i) not in left_out]
    figures["far_off_pairs"] = np.flatnonzero(flagged).tolist()
    why = ""
    if used:
        on_rows = model.m == problem_pairs(data)  # the model's rows are the data's: their labels apply
        listing = item_listing(used, data if on_rows else None)
        why = (f"; {len(used)} of the {model.m} {'stations' if not on_rows else 'pairs'} "
               f"({listing}) are far off the others (gross errors: a failed detection, a mismatched pair) and "
               "this solver used them")
    if d > DISTANCE_FAIL:
        failures.append(f"the answer is {d:.3g} standard deviations from the best fit of these data ({gap_text()}){why}")
    elif d > DISTANCE_WARN and not _own_model(reported):
        figures["better_fit"] = True  # the host makes an `optimal` status `suboptimal`: they must agree
        advice = "" if solver == "auto" else "; solver 'auto' returns the best fit"
        warnings.append(f"self-check: the answer is {d:.3g} standard deviations from the best fit of these data "
                        f"({gap_text()}), so the data support it far less than that fit{why}{advice}")
    figures["std"] = _precision(problem, data, model, fit, cov, interest, warnings, figures)
    _imprecise(figures["std"], model.scale, failures)
    # the rotation residuals of the data's own pairs at the answer, when the model is on them
    return row_norms(at_answer[:, :3]) if model.m == problem_pairs(data) else None


def _own_model(reported: Reported) -> bool:
    """Whether the answer was fitted under another model than this check's best fit (one noise
    level per residual group, on the poses): to other observations (the board's corners,
    ``fitted_to``) or with the noise of each pose, camera and marker estimated (``noise_model``
    "sources"). Its distance from that fit is then a figure, not a warning (a gross disagreement,
    beyond DISTANCE_FAIL, still fails it): a camera four times noisier than the rest moves the
    weighted answer several of the one-level fit's sigmas, rightly."""
    # drift_agrees: auto's X from the consecutive motions, held-out stations agreeing
    return (reported.fitted_to != "poses" or reported.noise_model == "sources"
            or (reported.drift_agrees and reported.on_stations))


def _disagreeing(data: Any) -> bool:
    """Whether some pairs lie outside the data's largest group of pairs that agree with each
    other (`data.agreeing_share`, where the problem's data have it), which is a majority (else
    check 7 fails the answer whatever the fit, and a robust fit of such data is slow and moot)."""
    return MAJORITY < getattr(data, "agreeing_share", 1.0) < 1.0


def problem_pairs(data: Any) -> int | None:
    """The number of pairs of the problem's own data (to tell when the check's model is on
    stations rather than pairs), None if the data do not say."""
    return getattr(data, "m", None)


def _difference(poses: Any, fit: Any) -> np.ndarray:
    """xi_j with T_j = F_j exp(xi_j) (to first order in the translation) for every answer T_j and
    fit F_j (k of each, or one pose each), stacked (6k,): (omega, v) in F_j's frame (one batched
    log for all of them)."""
    T, F = np.array(poses).reshape(-1, 4, 4), np.array(fit).reshape(-1, 4, 4)  # np.reshape's arrays, ~2 us less
    RFt = np.swapaxes(F[:, :3, :3], 1, 2)
    omega = so3_fast.log(RFt @ T[:, :3, :3])
    v = einsum("kij,kj->ki", RFt, T[:, :3, 3] - F[:, :3, 3])
    return np.concatenate([omega, v], axis=1).ravel()


def _precision(problem: Any, data: Any, model: Any, fit: tuple[np.ndarray, ...], cov: np.ndarray,
               interest: tuple[str, ...], warnings: list[str], figures: dict[str, Any]) -> dict[str, Any]:
    """1-sigma per unknown (rotation deg, translation; the worst direction in the frame the
    unknown is expressed in: R v for the principal eigenvector v of its 3x3 covariance block in
    its own frame) from the covariance of the best fit; warnings beyond the precision."""
    axes: dict[str, np.ndarray] = {}
    out: dict[str, Any] = {}
    chosen = [j for j, name in enumerate(model.unknowns) if name in interest]
    blocks = np.stack([cov[i:i + 3, i:i + 3] for j in chosen for i in (6 * j, 6 * j + 3)])
    w, V = eigh_stack(0.5 * (blocks + np.swapaxes(blocks, 1, 2)))  # one call for every block
    for n, j in enumerate(chosen):
        name, R = model.unknowns[j], fit[j][:3, :3]
        rot_deg = math.degrees(math.sqrt(max(float(w[2 * n, 2]), 0.0)))
        trans = math.sqrt(max(float(w[2 * n + 1, 2]), 0.0))
        rot_dir, trans_dir = R @ V[2 * n, :, 2], R @ V[2 * n + 1, :, 2]
        out[name] = {"rotation_deg": rot_deg, "rotation_axis": rot_dir.tolist(),
                     "translation": trans, "translation_direction": trans_dir.tolist()}
        limit = PRECISION_TRANSLATION * model.scale
        if (rot_deg > PRECISION_ROTATION_DEG or trans > limit) and not axes:
            axes = problem.rotation_axes(data)  # only a warning names them
        if rot_deg > PRECISION_ROTATION_DEG:
            warnings.append(f"the data determine the rotation of {name} only to {rot_deg:.2g} deg (1-sigma, about "
                            f"{_direction(rot_dir, axes.get(name))} in the frame {name} is expressed in); "
                            f"{_advice(rot_dir, axes.get(name))}")
        if trans > limit:
            warnings.append(f"the data determine the translation of {name} only to {trans:.3g} in their length unit (1-sigma, along "
                            f"{_direction(trans_dir, axes.get(name))} in the frame {name} is expressed in; "
                            f"{PRECISION_TRANSLATION:.0%} of the data's lever arm is {limit:.3g}); "
                            f"{_advice(trans_dir, axes.get(name))}")
    return out


def _imprecise(std: Mapping[str, Any], lever: float, failures: list[str]) -> None:
    """A failure for every unknown whose 1-sigma exceeds UNRELIABLE_ROTATION_DEG or
    UNRELIABLE_TRANSLATION of the lever arm: the data do not determine it well enough to use."""
    limit = UNRELIABLE_TRANSLATION * lever
    for name, s in std.items():
        if s["rotation_deg"] > UNRELIABLE_ROTATION_DEG or s["translation"] > limit:
            failures.append(
                f"the data determine {name} only to {s['rotation_deg']:.2g} deg and {s['translation']:.3g} in their "
                f"length unit (1-sigma), beyond what can be used ({UNRELIABLE_ROTATION_DEG:g} deg, or "
                f"{UNRELIABLE_TRANSLATION:.0%} of the lever arm: {limit:.3g}): too few consistent stations, too much "
                "noise, or many gross pairs")


def _direction(v: np.ndarray, axis: np.ndarray | None) -> str:
    text = "(" + ", ".join(f"{c:+.2f}" for c in v) + ")"
    if axis is not None and abs(float(v @ axis)) > math.cos(math.radians(AXIS_NAMING_DEG)):
        text += ", the robot's main rotation axis"
    return text


def _advice(v: np.ndarray, axis: np.ndarray | None) -> str:
    if axis is not None and abs(float(v @ axis)) > math.cos(math.radians(AXIS_NAMING_DEG)):
        return "the robot rotates mostly about one axis: add stations that rotate about other axes"
    return "add stations (larger rotations about different axes), or reduce the noise"


def chi3_expected(angle_sigma: float, stations_per_pair: float) -> float:
    """Expected median norm of a pair's rotation residual (rad) when the angle differences of
    motions have robust standard deviation `angle_sigma` and each pair's residual carries the
    noise of `stations_per_pair` stations (a motion's angle difference carries two): the
    per-axis noise of a station is angle_sigma / sqrt(2) (the angle difference is the noise's
    component along the motion's axis, from two stations)."""
    return CHI3_MEDIAN * angle_sigma * math.sqrt(stations_per_pair / 2.0)
