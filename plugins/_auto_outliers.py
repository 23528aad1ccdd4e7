"""auto's outlier step (`handeye.plugins.auto`, pipeline step 4): pairs (observations) far off
the others found at a robust fit and left out of least squares, judged against their own group's
noise where the data come in groups (a camera, a marker), and a group struck by something
systematic named as such; and the validated data restricted to the pairs kept (`kept`), which the
noise-source step uses too."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import Status
from handeye.base.errors import DegenerateDataError, HandEyeError
from handeye.checks.self_check import MAJORITY
from handeye.estimation import lm_objective, nlls
from handeye.estimation.robust import DEFAULT_LOSS_SCALE, OUTLIER_CHI2
from handeye.estimation.whitening import Whitening, estimate_sigmas
from handeye.framework.problem import Problem, item_listing
from handeye.geometry.linalg import einsum
from handeye.plugins import refine as _refine


def kept(problem: Problem, data: Any, inliers: np.ndarray) -> Any:
    """The validated data restricted to the pairs (triples) `inliers` (keeps the planar mode)."""
    if inliers.all():  # the data themselves, whose model and factors are built already
        return data
    stacks = problem.data_fields
    return dataclasses.replace(data, **{f: getattr(data, f)[inliers] for f in stacks})


#: how much noisier (or quieter) than the rest, in standard deviation, one group of items (a
#: camera, a marker: `item_groups`) may be and still be judged against its own noise by the
#: outlier test (`_group_variances`); beyond it the group is judged against the others' and its
#: far-off items, too many to be chance, are named as something wrong with it (`_concentrated`).
#: Measured (bench/axyb_multi.py --uneven, cameras 0.25-4x the typical noise): judged against
#: the others' noise, a camera 2x noisier than most had 21 of its 243 observations flagged and
#: was named as broken; a length unit wrong by 1000x or two markers under one name are far
#: beyond 10x.
GROUP_NOISE_RANGE = 10.0


def _beyond(e: np.ndarray, W: Whitening | None, scale: float, data: Any = None) -> np.ndarray:
    """Which of the residuals e: (m, 6) are beyond OUTLIER_CHI2 under W (None: median-based
    scales of e, and with `data` whose items come in groups, each item's group's own noise:
    `_group_variances`; only at the robust fit, where a broken group cannot hide in the others'
    residuals as it does at least squares)."""
    estimated = W is None
    W = W if W is not None else estimate_sigmas(e, scale, robust=True)
    ew = W.residual(e)
    q = einsum("ni,ni->n", ew, ew)
    groups = getattr(data, "item_groups", None) if estimated else None
    return q > OUTLIER_CHI2 * (_group_variances(q, groups) if groups else 1.0)


def _group_variances(q: np.ndarray, groups: dict[str, np.ndarray]) -> np.ndarray:
    """Each item's noise variance relative to the data's, from its groups (`item_groups`: e.g.
    the observations of one camera, of one marker): a group's is the median of its items'
    whitened squared norms q over the median of all, clipped to GROUP_NOISE_RANGE (squared)
    either way; an item's the largest of its groups'. A camera twice as noisy as the rest then
    has its gross observations found against its own noise, not every fourth one flagged."""
    limit = GROUP_NOISE_RANGE**2
    typical = max(float(np.median(q)), 1e-300)
    out = np.zeros(len(q))
    for idx in groups.values():
        ratio = float(np.clip(np.median(q[idx]) / typical, 1.0 / limit, limit)) if len(idx) else 1.0
        out[idx] = np.maximum(out[idx], ratio)
    return np.where(out > 0, out, 1.0)


def reject_outliers(problem: Problem, data: Any, poses: tuple[np.ndarray, ...], status: Status, diag: dict[str, Any],
                     ropts: _refine.Options, what: str
                     ) -> tuple[tuple[np.ndarray, ...], Status, dict[str, Any], list[dict[str, Any]], str | None]:
    """Find pairs far off the others and refit least squares without them.

    1. gate: at the least-squares answer `poses`, is any pair beyond OUTLIER_CHI2 under the
       median-based scales (or the stated weights), or outside the data's largest group of pairs
       that agree with each other (`data.agreeing_group`: rotation angles, no X or Y needed)? No:
       the answer stands (clean data: today's answer, bit for bit).
    2. Cauchy refinement (IRLS, median-based scales re-estimated to a fixed point, or the stated
       weights) from that answer: gross pairs get weights ~ 1/s and stop pulling, so it lands at
       the inliers' fit (measured: from the least-squares answer poisoned by 15% gross pairs,
       bench/outliers.py); and from the agreeing group's own fit, the better of the two kept
       (`_better_robust_fit`: 40% gross pairs pull the least-squares answer too far).
    3. the pairs beyond OUTLIER_CHI2 at the Cauchy fit are the outliers; none: the least-squares
       answer stands. More than half: no majority to trust, the least-squares answer stands with
       a warning. Else least squares (the user's weights) is refitted on the others from the
       Cauchy fit.
    Returns (poses, status, refine's diagnostics, [{"index", "rotation_deg", "translation"}] at
    the final answer, warning or None).
    """
    model = _refine.model_of(problem, data)
    settings = _refine.settings_of(ropts, data.m)
    disagreeing = MAJORITY < getattr(data, "agreeing_share", 1.0) < 1.0  # pairs outside the largest agreeing majority
    if not disagreeing and not _beyond(model.residuals(poses), settings.W, model.scale).any():
        return poses, status, diag, [], None
    robust = dataclasses.replace(settings, loss="cauchy", loss_scale=DEFAULT_LOSS_SCALE, estimate="profile")
    try:
        fit, _, _ = nlls.refine(model, poses, robust)
    except DegenerateDataError:
        return poses, status, diag, [], None
    fit = _better_robust_fit(problem, data, model, fit, robust)
    flagged = _beyond(model.residuals(fit), settings.W, model.scale, data)
    k, m = int(flagged.sum()), data.m
    if k == 0:
        return poses, status, diag, [], None
    inliers = ~flagged
    if m - k < max(model.profile_min_pairs, (m + 1) // 2):
        return poses, status, diag, [], (
            f"{k} of {m} {what} are far off the others at a robust fit, too many to leave out: no majority of "
            f"consistent {what} exists, which a robust fit needs (at least half of the {what} without gross "
            "errors); least squares on every pair is returned: check the pairing and the detections, and record "
            "more stations")
    concentrated = _concentrated(data, flagged)
    if concentrated:
        name, k_g, n_g = concentrated
        return poses, status, diag, [], (
            f"{k_g} of the {n_g} {what} of {name} are far off the others at a robust fit, far more than elsewhere in "
            f"the data: that is not a few gross {what} but something wrong with {name} itself (its length unit, its "
            f"name or index in the data, or the way its poses were recorded); least squares on every {what[:-1]} is "
            f"returned: check the {what} of {name}")
    W = settings.W
    sub_settings = settings
    if W is not None and W.L is not None and W.L.ndim == 3:
        sub_settings = dataclasses.replace(settings, W=Whitening(L=W.L[inliers]))
    subset = kept(problem, data, inliers)
    try:
        # refine's fit (its noise model, the camera's scale) on the pairs that are left
        new_poses, new_status, new_diag = _refine.fit(_refine.model_of(problem, subset), subset, fit, sub_settings, ropts.noise)
    except DegenerateDataError:
        return poses, status, diag, [], (
            f"{what} {item_listing(np.flatnonzero(flagged), data)} are far off the others, but the rest do not determine "
            "the unknowns: least squares on every pair")
    e = model.residuals(new_poses)
    rot = np.rad2deg(np.linalg.norm(e[:, :3], axis=1))
    trans = np.linalg.norm(e[:, 3:], axis=1)
    idx = np.flatnonzero(flagged)
    outliers = [{"index": int(i), "rotation_deg": float(rot[i]), "translation": float(trans[i])} for i in idx]
    worst = idx[np.argmax(trans[idx] / max(float(np.median(trans[inliers])), 1e-300)
                          + rot[idx] / max(float(np.median(rot[inliers])), 1e-300))]
    label = what if k > 1 else what[:-1]  # "pairs 3, 17 are", "pair 3 is"
    whole = [f"{name} (all {len(rows)})" for name, rows in (getattr(data, "pair_groups", None) or {}).items()
             if len(rows) > 1 and flagged[rows].all()]  # a camera-marker pair off as a whole: named, not its camera
    note = ((f"every observation of {', '.join(whole)} {'is' if len(whole) == 1 else 'are'} far off the others: "
             "that pair (a marker seen edge-on or misread by that camera), not its camera or marker. In all, " if whole
             else "") + f"{label} {item_listing(idx, data)} {'is' if k == 1 else 'are'} far off the others (residual "
            f"{'up to ' if k > 1 else ''}{rot[worst]:.3g} deg / {trans[worst]:.3g} against a typical "
            f"{np.median(rot[inliers]):.2g} deg / {np.median(trans[inliers]):.2g}, translations in the data's "
            f"length unit) and {'was' if k == 1 else 'were'} left out; outliers='keep' uses every pair")
    new_diag["outliers_left_out"] = k
    return new_poses, new_status, new_diag, outliers, note


def _better_robust_fit(problem: Problem, data: Any, model: Any, fit: tuple[np.ndarray, ...], robust: nlls.Settings
                       ) -> tuple[np.ndarray, ...]:
    """The robust fit from the least-squares answer (`fit`), or the one from the data's largest
    group of pairs that agree with each other without X or Y (`data.agreeing_group`, where the
    problem's data have it), whichever has the lower Cauchy cost under the noise of that group.
    Gross pairs pull the least-squares answer, and with 40% of them the Cauchy fit from it stays
    in the wrong basin (half of 40 sets 10-45 deg off, measured); the group's own fit is a start
    they cannot pull."""
    group = getattr(data, "agreeing_group", None)
    if group is None or getattr(data, "agreeing_share", 1.0) >= 1.0 or group.sum() < max(model.profile_min_pairs, 3):
        return fit
    subset = kept(problem, data, group)
    try:
        _, start, _, _, _ = _refine.start(problem, subset, None)
        other, _, _ = nlls.refine(model, start, robust)
    except HandEyeError:
        return fit
    W = estimate_sigmas(_refine.model_of(problem, subset).residuals(other), model.scale, robust=True)
    cost = [lm_objective.cost_of(model, poses, W, "cauchy", DEFAULT_LOSS_SCALE) for poses in (fit, other)]
    return other if cost[1] < cost[0] else fit


#: a group of items (`item_groups`) whose flagged items are this improbable as random gross errors
#: is struck by something systematic (`_concentrated`): 1e-6, so that random gross items, 40% of
#: them included, are left out as before
CONCENTRATION_P = 1e-6
#: ... and whose flagged items are at least this share of its observations: a wrong unit, a wrong
#: label or two markers under one name strike most or half of a group's items, not a few. On a real
#: rig (Wise et al. 2025, 8 cameras, 16 tags, half of each recording) 12 of the 194 observations of
#: one camera were flagged, spread over 5 of its tags (one tag-camera pair 35 deg off): judged as
#: something wrong with the camera, least squares on every observation was returned, which predicts
#: held-out rows worse than leaving the 12 out (1.33 deg / 24.2 mm against 1.25 deg / 23.4 mm)
CONCENTRATION_SHARE = 0.25


def _concentrated(data: Any, flagged: np.ndarray) -> tuple[str, int, int] | None:
    """(name, flagged, observations) of the first group of the data's items (`item_groups`,
    e.g. axyb-multi's observations of one camera or one marker) whose flagged items are too many
    to be chance: a count whose binomial tail probability at the share flagged elsewhere (at
    least one item's worth) is below CONCENTRATION_P, and at least CONCENTRATION_SHARE of the
    group's items. Gross errors strike
    items at random; a wrong unit, a wrong label or a swapped setup strikes every item of one
    camera or marker, and leaving those out would answer for it from the few that are left, or
    from another marker's poses. None: no such group, or the data have no groups."""
    from scipy.stats import binom

    groups = getattr(data, "item_groups", None)
    if not groups:
        return None
    k, m = int(flagged.sum()), len(flagged)
    for name, idx in groups.items():
        k_g, n_g = int(flagged[idx].sum()), len(idx)
        if k_g == 0 or n_g == m:
            continue
        p_rest = max((k - k_g) / (m - n_g), 1.0 / m)
        if k_g >= CONCENTRATION_SHARE * n_g and binom.sf(k_g - 1, n_g, p_rest) < CONCENTRATION_P:
            return name, k_g, n_g
    return None
