"""The self-check's checks 5 and 6, the camera's scale: do the camera's translations need a factor
to fit the robot's (a unit mix-up, a monocular camera, a board size or focal length off), for one
camera (`camera_scale_check`) or camera by camera in a cell (`camera_scales_check`), and does
noise bias a fitted scale (`camera_scale_noise`); `camera_scale_verdict` and
`camera_scale_screen` for `auto`, which asks before it solves again with the scale unknown."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.stats import norm

from handeye.base.errors import DegenerateDataError
from handeye.checks.best_fit import FIT_TOL, MAX_ITER, best_fit
from handeye.estimation import camera_scale, camera_scales, nlls
from handeye.estimation.robust import DEFAULT_LOSS_SCALE
from handeye.geometry.linalg import solve

#: check 5: the camera's translations need a factor s to fit the robot's: a failure beyond a
#: factor SCALE_FAIL either way (a unit mix-up, m against mm or inch, or a monocular camera), a
#: warning beyond SCALE_WARN (1%: a board size or focal length off, or robot errors that mimic
#: them: the bundled real circle-grid set, with robot errors dominating its pixel noise, fits
#: best at 0.94), each only when s is SCALE_SIGMAS standard deviations from 1
SCALE_FAIL = 1.5
SCALE_WARN = 0.01
SCALE_SIGMAS = 5.0
#: ... and only when the factor explains the translation misfit: the RMS translation residual
#: with s free is this many times smaller than at s = 1 (measured: a unit mix-up or a monocular
#: camera at 0.37, 150-460; a 2% factor, 5-8; correct units, 1.0-1.5; systematic robot errors
#: that a free s partly absorbs (kinhec small tier, mixed-000066, IRB 120 with DH errors, 8 deg
#: rotations), 1.54 at s = 0.37, which is no unit error)
SCALE_GAIN_FAIL = 3.0
SCALE_GAIN_WARN = 2.0
#: ... or, below those sizes, when fitting the factor would move an unknown by more than
#: EFFECT_SIGMAS of its own stated 1-sigma, the factor EFFECT_SCALE_SIGMAS standard deviations
#: from 1 and beyond SCALE_FLOOR (rounding: noise-free data fit best at 1 +- 1e-14). A factor
#: 0.3% off (a board size or focal length a little wrong) moves Y of a camera 1.5 m away by 4.5
#: mm, 8 times its 1-sigma at 30 stations, with translation residuals no smaller. Measured
#: (docs/camera-scale.md): 2 warnings in 4000 simulated answers of exact cameras (8-60 stations,
#: five kinds of noise); 0.3% off warned in 40/40 at 30 and 60 stations, 12/40 at 15
EFFECT_SIGMAS = 3.0
EFFECT_SCALE_SIGMAS = 4.0
#: ... for a cell, the same false-alarm rate over its groups (each X's and each Y's observations):
#: the two-sided tail of EFFECT_SCALE_SIGMAS shared among them (4.8 sigma for 24 groups)
EFFECT_TAIL = 2.0 * float(norm.sf(EFFECT_SCALE_SIGMAS))
SCALE_FLOOR = 1e-6
#: ... for factors within EFFECT_MAX of 1 (a larger one is judged by how much it explains, as
#: above: KinHEC's noisiest camera fits best at 0.72 with a right answer, its noise's bias)
EFFECT_MAX = 0.05
#: check 6 (the scale fitted): noise in the camera's translations biases the fitted scale toward
#: zero by a relative amount up to kappa (`handeye.estimation.camera_scale.noise_bias`); flagged when that
#: is NOISE_BIAS_SIGMAS standard deviations of the scale (and SCALE_WARN). Measured
#: (docs/camera-scale.md): genuinely monocular data at most 2.2 sigma (KinHEC's 32 monocular
#: sequences; 2.9 for its mixed monocular ones), simulated ones at most 1.0 (camera noise 5 mm)
#: and 2.4 (robot noise 10 mm, where the bound is loose); metric data given camera_scale=
#: 'unknown' with noisy camera depth 5.0-10.3 (KinHEC mixed-000015: 6.3, kappa 7.1%, the scale
#: 7.2% short). A failure beyond NOISE_BIAS_FAIL: noise could span half the translations'
#: spread, the scale is not determined (measured 0.57 to 2000 where it was meaningless; at most
#: 0.34 elsewhere, 0.013 on the monocular sequences)
NOISE_BIAS_SIGMAS = 4.0
NOISE_BIAS_FAIL = 0.5


def camera_scale_verdict(problem: Any, data: Any, unknowns: Mapping[str, np.ndarray]) -> dict[str, Any] | None:
    """Check 5 alone, for a solver that wants to know whether the data demand a camera scale
    (`auto`): the figures of `camera_scale_check` with "verdict" "fail", "warn" or None, or None when
    the check does not apply (no camera, the scale already unknown, pairs far off the others,
    the fit singular)."""
    spec = problem.check_model(data, unknowns)
    if spec is None:
        return None
    model, poses, _ = spec
    try:
        _, cov, flagged, res, _, _ = best_fit(model, poses)
    except DegenerateDataError:
        return None
    if flagged.any():
        return None
    failures: list[str] = []
    warnings: list[str] = []
    figures: dict[str, Any] = {}
    camera_scale_check(model, res, cov, failures, warnings, figures)
    if "camera_scale" not in figures:
        return None
    verdict = "fail" if failures else "warn" if warnings else None
    return {**figures["camera_scale"], "verdict": verdict}


def camera_scales_named(problem: Any, data: Any, unknowns: Mapping[str, np.ndarray]) -> tuple[str, ...]:
    """Check 5 per camera of a cell alone (`camera_scales_check`), for a solver that wants to
    know which cameras and targets may need a factor of their own (`auto`): the names of those
    its warning names, or () when it names none, does not apply (the fit singular) or fails (a
    camera in another length unit, beyond SCALE_FAIL: the data are to be fixed, not fitted)."""
    spec = problem.check_model(data, unknowns)
    if spec is None:
        return ()
    model, poses, _ = spec
    try:
        _, cov, _, res, _, _ = best_fit(model, poses)
    except DegenerateDataError:
        return ()
    failures: list[str] = []
    warnings: list[str] = []
    figures: dict[str, Any] = {}
    camera_scales_check(model, res, cov, failures, warnings, figures)
    if failures or not warnings:
        return ()
    return tuple(name for name, f in figures.get("camera_scales", {}).items() if isinstance(f, Mapping))


def camera_scale_screen(model: Any, poses: tuple[np.ndarray, ...], e: np.ndarray, W: Any,
                        cov: np.ndarray) -> tuple[float, float] | None:
    """Check 5's screen: (s, its standard deviation) for the scale of the camera's translations
    in one Gauss-Newton step from a least-squares fit (`poses`, its residuals e, per-group
    weights W, covariance cov as `handeye.estimation.nlls.covariance` gives it); exact in s, which the
    residual is linear in, with the poses stationary at the fit. None where the data do not
    determine s (the Schur complement of s is not positive)."""
    screen = _screen(model, poses, e, W, cov)
    return None if screen is None else screen[:2]


def _screen(model: Any, poses: tuple[np.ndarray, ...], e: np.ndarray, W: Any,
            cov: np.ndarray) -> tuple[float, float, np.ndarray] | None:
    """`camera_scale_screen`'s (s, std) and the slope d(poses)/ds (6k,): how far the fit moves,
    in each pose's own frame, per unit of s when s is fitted with it (-H^-1 J^T W g, H^-1 =
    cov / the variance factor)."""
    g = model.camera_direction(poses)
    gw, ew = W.residual(g).ravel(), W.residual(e).ravel()
    if model.m >= model.sums_min_pairs:  # J^T W g in closed form: g lives on the translation rows only
        b = model.translation_gradient(poses, g[:, 3:]) / W.sigma_trans ** 2
    else:
        J = W.jacobian(model.jacobian(poses, e))
        b = J.reshape(-1, J.shape[2]).T @ gw  # cov is P (P^T H P)^-1 P^T: b stays in the full 6k
    factor = float(ew @ ew) / max(ew.size - len(b), 1)  # the variance factor of cov
    slope = cov @ b / factor
    schur = float(gw @ gw) - float(b @ slope)
    if not schur > 0.0:
        return None
    return 1.0 - float(gw @ ew) / schur, math.sqrt(factor / schur), -slope


def slightly_off(s: float, std: float, residuals: int, sigmas: float = EFFECT_SCALE_SIGMAS) -> bool:
    """Whether a screened camera scale s (its standard deviation std) is a little off: within
    EFFECT_MAX of 1 but `sigmas` standard deviations beyond what exact cameras give, which is 1, or up to
    kappa = n (std / s)^2 short of it, the bias that noise in the camera's translations puts on a
    fitted scale (`handeye.estimation.camera_scale.noise_bias`; n the translation residuals less the
    unknowns': KinHEC's noisy cameras fit best at 0.65-0.9, 8-10 standard deviations short, with
    answers as right as their 1-sigma), and beyond SCALE_FLOOR."""
    if not abs(s - 1.0) < EFFECT_MAX:
        return False
    kappa = residuals * (std / s) ** 2
    low = 1.0 - kappa - sigmas * std
    return (s > 1.0 + max(sigmas * std, SCALE_FLOOR)) or s < min(low, 1.0 - SCALE_FLOOR)


def scale_effect(model: Any, cov: np.ndarray, slope: np.ndarray, s: float) -> tuple[str, float, float]:
    """How far fitting the camera's scale s would move the answer: (the unknown it moves the most
    against its own 1-sigma, that many standard deviations, its translation's shift in the data's
    length unit), the shift (s - 1) * slope to first order, measured by each unknown's
    translation covariance block."""
    worst = ("", 0.0, 0.0)
    for j, name in enumerate(model.unknowns):
        t = slope[6 * j + 3:6 * j + 6] * (s - 1.0)
        block = cov[6 * j + 3:6 * j + 6, 6 * j + 3:6 * j + 6]
        try:
            sigmas = math.sqrt(max(float(t @ solve(block, t)), 0.0))
        except np.linalg.LinAlgError:
            continue
        if sigmas > worst[1]:
            worst = (name, sigmas, float(np.linalg.norm(t)))
    return worst


def scale_suspect(s: float, std: float) -> bool:
    """Whether a screened scale needs the fit with s free (`camera_scale_check`): it moved by more
    than SCALE_WARN and two standard deviations."""
    return abs(s - 1.0) > SCALE_WARN and abs(s - 1.0) > 2.0 * std


def camera_scale_check(model: Any, res: Any, cov: np.ndarray, failures: list[str], warnings: list[str],
                  figures: dict[str, Any]) -> None:
    """Check 5: do the camera's translations fit the robot's at scale 1? Screened in one
    Gauss-Newton step from the best fit for the scale s of the camera's translations
    (`handeye.estimation.camera_scale`; the residual is linear in s and the fit stationary in the poses),
    with its standard deviation from the Schur complement of s in the information matrix; where
    s moves by more than SCALE_WARN and two standard deviations, the fit is redone with s free
    (the residuals at s = 1 carry the misfit of a wrong scale, which inflates the noise and
    would hide it) and s judged there. Models without a camera, or whose camera scale is
    already unknown, are skipped."""
    if not hasattr(model, "camera_direction") or res.W.L is not None:
        return
    screen = _screen(model, res.poses, res.e, res.W, cov)
    if screen is None:
        return
    s, std, slope = screen
    gain = 1.0
    if scale_suspect(s, std):
        try:
            free = camera_scale.ScaledCameraModel(model)
            fit = nlls.levenberg_marquardt(free, res.poses, None, "linear", DEFAULT_LOSS_SCALE, MAX_ITER, FIT_TOL)
            figures_s = camera_scale.scale_figures(free, fit.poses, fit.W.sigma_rot, fit.W.sigma_trans,
                                                   nlls.covariance(fit, "linear", DEFAULT_LOSS_SCALE, True)[1])
        except DegenerateDataError:
            return
        s, std = figures_s["camera_scale"], figures_s["camera_scale_std"]
        gain = math.sqrt(float(np.sum(res.e[:, 3:] ** 2)) / max(float(np.sum(fit.e[:, 3:] ** 2)), 1e-300))
    if not s > SCALE_SIGMAS * std:  # the robot's translations do not fix the camera's scale (e.g. none)
        return
    z = (s - 1.0) / std
    moved, effect, shift = scale_effect(model, cov, slope, s)
    # what a camera scale 0.1% off (a board size or focal length a little wrong) would do to each
    # unknown: the stated 1-sigma takes the scale as exact (docs/camera-scale.md)
    per_permille = {name: float(np.linalg.norm(1e-3 * slope[6 * j + 3:6 * j + 6])) for j, name in enumerate(model.unknowns)}
    figures["camera_scale"] = {"scale": s, "std": std, "sigmas": z, "translation_fit_gain": gain,
                               "moves": moved, "moves_sigmas": effect, "moves_by": shift,
                               "per_permille": per_permille}
    smaller = f"; the translation residuals {gain:.3g} times smaller" if gain > 1.1 else ""
    text = (f"the camera's translations fit the robot's best when multiplied by {s:.4g} (+-{std:.2g}, "
            f"{abs(z):.3g} standard deviations from 1{smaller})")
    hint = getattr(model, "scale_hint", "camera_scale='unknown'")  # how the data say so (a cell: the cameras' names)
    if abs(math.log(s)) > math.log(SCALE_FAIL) and abs(z) > SCALE_SIGMAS and gain > SCALE_GAIN_FAIL:
        failures.append(f"{text}: are both in one length unit (m against mm)? For a camera whose translations are "
                        f"known only up to scale (monocular SLAM), give {hint}")
    elif abs(s - 1.0) > SCALE_WARN and abs(z) > SCALE_SIGMAS and gain > SCALE_GAIN_WARN:
        warnings.append(f"self-check: {text}: check the board's size and the camera's focal length (a PnP pose's "
                        f"distance scales with both); {hint} fits the factor")
    elif effect > EFFECT_SIGMAS and slightly_off(s, std, 3 * (model.m - len(model.unknowns))):
        warnings.append(f"self-check: {text}; that factor would move {moved}'s translation by {shift:.3g} in the "
                        f"data's length unit, {effect:.3g} times its stated 1-sigma, so {moved} is less certain than "
                        f"stated: check the board's size and the camera's focal length (a PnP pose's distance scales "
                        f"with both), or the robot's own errors, which can mimic a scale; {hint} fits the factor")


def camera_scales_check(model: Any, res: Any, cov: np.ndarray, failures: list[str], warnings: list[str],
                        figures: dict[str, Any], held_out: Mapping[str, Any] | None = None) -> None:
    """Check 5 per camera of a cell (a model with ``scale_groups``: the observations of each X
    and each Y, whose cameras the data do not single out), before check 5 for all cameras at once:
    one monocular camera among metric ones misfits by a factor that a scale for all would average
    away. The fit with groups' scales free that explains the most
    (`handeye.estimation.camera_scales.groups_off_scale`), its scales judged as check 5 judges one camera;
    where it names none, the groups whose scale would move the answer beyond its 1-sigma
    (`_groups_moving`). `held_out`: the solver's held-out comparison of factors for some groups
    (`handeye.plugins._auto_scales.held_out`), which the advice then follows."""
    groups = getattr(model, "scale_groups", None)
    if not groups or res.W.L is not None:
        return
    screens = camera_scales.screen_groups(model, res.poses, res.e, res.W, cov, groups)
    best = camera_scales.groups_off_scale(model, res, screens, groups, scale_suspect, MAX_ITER, FIT_TOL)
    if best is None or not _groups_off(best, failures, warnings, figures, held_out):
        _groups_moving(model, res, cov, screens, warnings, figures, held_out)


def _groups_off(best: tuple[list[str], float, dict[str, Any]], failures: list[str], warnings: list[str],
                figures: dict[str, Any], held_out: Mapping[str, Any] | None = None) -> bool:
    """`camera_scales_check` for the best fit with groups' scales free: a failure or a warning
    for the groups whose scale is off by SCALE_FAIL or SCALE_WARN where that fit explains the
    misfit (as check 5 for one camera); whether it named any."""
    names, gain, f = best
    scales = {name: (f["camera_scales"][name], f["camera_scales_std"][name]) for name in names}
    figures["camera_scales"] = {"translation_fit_gain": gain, **{
        name: {"scale": s, "std": std, "sigmas": (s - 1.0) / std} for name, (s, std) in scales.items()}}
    far = [n for n, (s, std) in scales.items() if s > SCALE_SIGMAS * std and abs(s - 1.0) > SCALE_SIGMAS * std]
    fail = [n for n in far if abs(math.log(scales[n][0])) > math.log(SCALE_FAIL)]
    warn = [n for n in far if abs(scales[n][0] - 1.0) > SCALE_WARN]
    named = fail if fail and gain > SCALE_GAIN_FAIL else warn if warn and gain > SCALE_GAIN_WARN else []
    if not named:
        return False
    text = (f"the translations of the observations of {', '.join(repr(n) for n in named)} fit the robot's best when "
            f"multiplied by {', '.join(f'{scales[n][0]:.4g} (+-{scales[n][1]:.2g})' for n in named)} (the translation "
            f"residuals {gain:.3g} times smaller)")
    if named is fail:
        failures.append(f"{text}: is each camera in the cell's length unit? For cameras known only up to scale "
                        f"(monocular SLAM), give camera_scale={named!r}")
    else:
        warnings.append(f"self-check: {text}: check the printed size of those boards or markers and the focal length "
                        f"of the cameras that see them (a PnP pose's distance scales with both); "
                        f"{_scales_advice(named, held_out)}")
    return True


def _groups_moving(model: Any, res: Any, cov: np.ndarray, screens: list[camera_scales.GroupScreen],
                   warnings: list[str], figures: dict[str, Any], held_out: Mapping[str, Any] | None = None) -> None:
    """A warning for the groups (cameras or targets) whose screened scale is off beyond noise
    (`slightly_off`, at EFFECT_TAIL shared among the groups, its standard deviation the larger of
    the screen's and the one robust to cameras of unequal noise, `_robust_std`) and would move an
    unknown by more than EFFECT_SIGMAS of its 1-sigma (`scale_effect`), most standard deviations
    first, sharing no observation: a camera's board size or focal length a little off, which
    neither the residuals nor a scale for the whole cell single out."""
    gate = float(norm.isf(0.5 * EFFECT_TAIL / max(len(screens), 1)))
    parts: dict[str, np.ndarray] = {}
    named: list[tuple[camera_scales.GroupScreen, tuple[str, float, float]]] = []
    used = np.zeros(model.m, dtype=bool)
    for x in sorted(screens, key=lambda x: -abs(x.scale - 1.0) / x.std):
        if used[x.rows].any() or not slightly_off(x.scale, x.std, 3 * len(x.rows), gate):
            continue
        x = x._replace(std=max(x.std, _robust_std(model, res, x, parts)))
        effect = scale_effect(model, cov, x.slope, x.scale)
        if slightly_off(x.scale, x.std, 3 * len(x.rows), gate) and effect[1] > EFFECT_SIGMAS:
            named.append((x, effect))
            used[x.rows] = True
    if not named:
        return
    figures["camera_scales"] = {x.name: {"scale": x.scale, "std": x.std, "sigmas": (x.scale - 1.0) / x.std,
                                         "moves": moved, "moves_sigmas": sigmas, "moves_by": by}
                                for x, (moved, sigmas, by) in named}
    parts = "; ".join(f"those of {x.name!r} when multiplied by {x.scale:.4g} (+-{x.std:.2g}, "
                      f"{abs(x.scale - 1.0) / x.std:.3g} standard deviations from 1), which would move {moved}'s "
                      f"translation by {by:.3g}, {sigmas:.3g} times its stated 1-sigma" for x, (moved, sigmas, by) in named)
    names = [x.name for x, _ in named]
    warnings.append(f"self-check: the camera translations fit the robot's best at another scale: {parts} (lengths in "
                    f"the data's unit), so the answer is less certain than stated: check the printed size of those "
                    f"boards or markers and the focal length of the cameras that see them (a PnP pose's distance "
                    f"scales with both), or the robot's own errors, which can mimic a scale; "
                    f"{_scales_advice(names, held_out)}")


def _scales_advice(names: list[str], held_out: Mapping[str, Any] | None) -> str:
    """How to fit the factors of the groups `names`, or, where the solver compared factors on
    held-out stations and kept none, what that comparison found (never advice it measured as worse)."""
    if not held_out or held_out.get("chosen") != "none":
        return f"camera_scale={names!r} fits their factors"
    models = held_out["models"]
    best = min((label for label in models if label != "none"), key=lambda label: models[label]["translation"])
    return (f"auto fitted no factor: the left-out stations were predicted no better with them (median translation "
            f"residual {models[best]['translation']:.3g} with factors for {', '.join(models[best]['names'])}, "
            f"{models['none']['translation']:.3g} without, {held_out['blocks']} blocks of the stations held out in turn), "
            "which points to the robot's errors more than to a scale")


def _robust_std(model: Any, res: Any, x: camera_scales.GroupScreen, parts: dict[str, np.ndarray]) -> float:
    """The standard deviation of a group's screened scale that holds whatever each observation's
    noise (the sandwich estimate): s - 1 = -(h . e) / |h|^2 with h = (I - P) g the group's scale
    direction off the poses' Jacobian (g + J slope, whitened), so var(s) = sum_i (h_i . e_i)^2 /
    |h|^4 over the observations i, e the residuals with that scale fitted, times N / (N - p).
    The screen's sqrt(factor) / |h| takes one
    noise level for all, which makes a camera four times noisier than the rest look far off.
    `parts` caches the whitened Jacobian, camera direction and residuals between groups."""
    if not parts:
        parts["J"] = res.W.jacobian(model.jacobian(res.poses, res.e))
        parts["g"] = res.W.residual(model.camera_direction(res.poses))
        parts["e"] = res.W.residual(res.e)
    J, g, e = parts["J"], parts["g"], parts["e"]
    h = np.einsum("iak,k->ia", J, x.slope)
    h[x.rows] += g[x.rows]
    hh = float(np.sum(h * h))
    if not hh > 0.0:
        return math.inf
    e = e - (float(np.sum(h * e)) / hh) * h  # the residuals with the group's scale fitted: noise alone
    size, p = e.size, J.shape[2] + 1
    return math.sqrt(float(np.sum(np.einsum("ia,ia->i", h, e) ** 2)) * size / max(size - p, 1)) / hh


def camera_scale_noise(model: Any, res: Any, factor: float, failures: list[str], warnings: list[str],
                        figures: dict[str, Any]) -> None:
    """Check 6, where the camera's scale is unknown (fitted with the answer): could noise in the
    camera's translations have biased the fitted scale s toward zero by more than its stated
    uncertainty (`handeye.estimation.camera_scale.noise_bias`)? A failure beyond NOISE_BIAS_FAIL (the data
    do not determine s), a warning beyond SCALE_WARN; both only NOISE_BIAS_SIGMAS standard
    deviations of s. Skipped for models whose scale is known."""
    if not isinstance(model, camera_scale.ScaledCameraModel) or res.W.L is not None:
        return
    try:
        f = camera_scale.noise_bias(model, res.poses, res.W.sigma_rot, res.W.sigma_trans, factor)
    except DegenerateDataError:
        return
    s, std, bias, sigmas = f["camera_scale"], f["camera_scale_std"], f["bias"], f["bias_sigmas"]
    figures["camera_scale_noise"] = {"scale": s, "std": std, "bias": bias, "bias_sigmas": sigmas}
    whose, fitted = "the camera's scale", f"the camera's scale {s:.4g} (+-{std:.2g})"
    if "camera" in f:  # several cameras (`handeye.estimation.camera_scales`): the worst named, all in the figures
        whose = f"the scale of camera {f['camera']!r}"
        fitted = f"the scale {s:.4g} (+-{std:.2g}) of camera {f['camera']!r}"
        figures["camera_scale_noise"].update(camera=f["camera"], cameras=f["cameras"])
    if not sigmas > NOISE_BIAS_SIGMAS:
        return
    rms = float(np.sqrt(np.mean(np.sum(res.e[:, 3:] ** 2, axis=1))))
    spread = (f"the translation residuals ({rms:.3g} RMS, in the robot's length unit) are large against the spread of "
              "the camera's translations that fixes its scale, and noise in those translations pulls a fitted scale "
              "toward zero")
    advice = ("record poses whose camera-to-target distance varies more, or less noisy camera poses; if the camera's "
              "translations are metric, solve with the scale known")
    if bias > NOISE_BIAS_FAIL:
        share = "all" if bias >= 1.0 else f"{bias:.0%}"
        failures.append(f"the data do not determine {whose}: {spread}; noise as large as the residuals "
                        f"could account for {share} of that spread, so the fitted {s:.4g} (+-{std:.2g}) may be far "
                        f"too small: {advice}")
    elif bias > SCALE_WARN:
        warnings.append(f"self-check: {fitted} may be up to {bias:.1%} too small, "
                        f"{sigmas:.3g} standard deviations that its stated uncertainty (and X's and Y's) leaves out: "
                        f"{spread}; {advice}")
