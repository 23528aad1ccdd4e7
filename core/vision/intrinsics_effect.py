"""How intrinsics a little off move a hand-eye answer, and the uncertainty that adds to it.

Intrinsics calibrated from the same images are uncertain, and a focal length a little off scales
every board's distance alike: the answer moves systematically, which the 1-sigma of a fit holding
the intrinsics exact does not contain (on the real ChArUco set fx, fy +- 0.79% move Y by 3.8 mm
against 0.18 mm with them exact). To first order the answer moves by S dk for intrinsics off by
dk = (dfx, dfy, dcx, dcy), and its covariance gains S C S^T with C the calibration's covariance,
fx and fy taken as fully correlated (one focal length, square pixels: the larger, safer share),
cx and cy independent. With C = L L^T (`one_sigma_moves`), S C S^T = D D^T for D = S L: the
answer's moves for each independent 1-sigma change of the intrinsics (`widened`).

- A fit to the corners has S from its own Jacobian (`handeye.plugins.reprojection`).
- A pose-based answer (PnP board poses -> a pose solver) gets D by re-solving: each board pose
  moved as PnP would move it for the intrinsics 1-sigma off (`pose_sensitivity`: one
  Gauss-Newton step of PnP at its answer, which depends on the board's points and pose only, not
  on the detected pixels), the answer's change measured in its own tangent (`answer_moves`).
- `with_moves` adds D D^T to a solution's reported covariance and 1-sigma, and `growth_note`
  names where that at least doubles a translation's 1-sigma, in the user's words.

Generic over problems: the unknowns are named poses (or stacks of them, `flat_poses`); the
caller re-solves its own data. Measured (bench/intrinsics_uncertainty.py, docs/images.md): on
simulated sets with intrinsics calibrated from the same corners, |error| / 1-sigma has an RMS
of 0.8-1.2 with this share, up to 2.5 without; on the real ChArUco set the re-solve's
focal-length move of Y and that of a file with the focal length 1-sigma longer agree to 0.01%.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from handeye.geometry.se3 import inverse, skew, so3_log
from handeye.vision.observations import Camera

#: the intrinsics' share of the uncertainty is named in a warning where a translation's 1-sigma
#: grows by this factor with it
INTRINSICS_GROWTH = 2.0
#: the focal-length change the answer's sensitivity is stated for: 0.1% (a permille), as the
#: camera-scale self-check states its own (`handeye.checks.scale_checks`)
PERMILLE = 1e-3


def one_sigma_moves(std: Sequence[float]) -> np.ndarray:
    """(4, 3) L with C = L L^T for the 1-sigma (fx, fy, cx, cy) of a calibration: the columns are
    its independent 1-sigma changes (focal length, fx and fy together; cx; cy)."""
    sx, sy, scx, scy = (float(v) for v in std)
    return np.array([[sx, 0.0, 0.0], [sy, 0.0, 0.0], [0.0, scx, 0.0], [0.0, 0.0, scy]])


def focal_percent(std: Sequence[float], camera: Camera) -> float:
    """The focal length's 1-sigma in per cent (the larger of fx's and fy's)."""
    return 100.0 * max(float(std[0]) / camera.K[0, 0], float(std[1]) / camera.K[1, 1])


def pose_sensitivity(T_cam_target: np.ndarray, object_points: np.ndarray, camera: Camera) -> np.ndarray:
    """(6, 4) d xi / d (fx, fy, cx, cy) of the PnP pose of a board with points `object_points`
    (n, 3) seen at `T_cam_target`, xi = (omega, v) the pose's right perturbation T <- T exp(xi)
    (`handeye.estimation.nlls.retract`): the Gauss-Newton step -(Jp^T Jp)^-1 Jp^T Jk of PnP's least squares."""
    from handeye.vision.projection import project

    T = np.asarray(T_cam_target, dtype=float)
    P = np.asarray(object_points, dtype=float)
    q = P @ T[:3, :3].T + T[:3, 3]
    _, Jq, Ji = project(q, camera)
    dq = np.empty((len(P), 3, 6))
    dq[:, :, :3] = -T[:3, :3] @ skew(P)
    dq[:, :, 3:] = T[:3, :3]
    Jp = (Jq @ dq).reshape(-1, 6)
    Jk = Ji[:, :, :4].reshape(-1, 4)
    return -np.linalg.lstsq(Jp, Jk, rcond=None)[0]


def visible_points(points: np.ndarray, T_cam_target: np.ndarray, camera: Camera) -> np.ndarray:
    """The board points (n, 3) in front of the camera that project into its image (all of them
    when the image size is unknown): the corners a detector can have found, where only their
    count was kept."""
    from handeye.vision.projection import project

    P = np.asarray(points, dtype=float)
    q = P @ T_cam_target[:3, :3].T + T_cam_target[:3, 3]
    pixels = project(q, camera)[0]
    inside = np.all(np.isfinite(pixels), axis=1)
    if camera.size is not None:
        inside &= (pixels[:, 0] >= 0) & (pixels[:, 0] < camera.size[0])
        inside &= (pixels[:, 1] >= 0) & (pixels[:, 1] < camera.size[1])
    return P[inside] if inside.sum() >= 4 else P


def shifted_poses(T_cam_target: np.ndarray, sensitivities: Sequence[np.ndarray], dk: np.ndarray) -> np.ndarray:
    """(m, 4, 4) the board poses as PnP would give them with the intrinsics changed by dk
    (fx, fy, cx, cy), to first order."""
    from handeye.estimation.nlls import retract

    return np.array([retract(np.asarray(T, dtype=float), S @ dk) for T, S in zip(T_cam_target, sensitivities)])


def tangent(T0: np.ndarray, T1: np.ndarray) -> np.ndarray:
    """(omega, v) with T1 = T0 exp(omega, v) to first order: the right perturbation the solvers'
    covariances are expressed in (rotation, then the translation change in T0's frame)."""
    d = inverse(T0) @ T1
    return np.concatenate([so3_log(d[:3, :3]), d[:3, 3]])


def flat_poses(unknowns: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The answer's poses by the labels its covariance uses: ``X`` for a pose, ``Y[k]`` for pose
    k of a stack (a cell of several cameras and targets)."""
    out = {}
    for name, value in unknowns.items():
        T = np.asarray(value, dtype=float)
        if T.shape == (4, 4):
            out[name] = T
        elif T.ndim == 3 and T.shape[1:] == (4, 4):
            out.update({f"{name}[{k}]": pose for k, pose in enumerate(T)})
    return out


def answer_moves(resolve: Callable[[np.ndarray], Mapping[str, np.ndarray]], answer: Mapping[str, np.ndarray],
                 names: Sequence[str], T_cam_target: np.ndarray, sensitivities: Sequence[np.ndarray],
                 changes: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """(6k, c) the answer's move (`tangent` of each pose in `names`, labelled as `flat_poses`
    labels them) for each change of the
    intrinsics (fx, fy, cx, cy) in the columns of `changes` (4, c), e.g. `one_sigma_moves`, of the
    camera whose board poses are `T_cam_target[rows]` (all rows: None), by re-solving:
    `resolve(poses)` answers for the board poses (m, 4, 4) with those rows moved as PnP would move
    them (`sensitivities`, one per row of `rows`). Forward differences at the change itself: the
    answer is smooth in the intrinsics, and 0.4% of a focal length is well inside its linear range."""
    T0 = np.asarray(T_cam_target, dtype=float)
    rows = np.arange(len(T0)) if rows is None else np.asarray(rows)
    changes = np.asarray(changes, dtype=float).reshape(4, -1)
    out = np.zeros((6 * len(names), changes.shape[1]))
    start = flat_poses(answer)
    for c, dk in enumerate(changes.T):
        moved = T0.copy()
        moved[rows] = shifted_poses(T0[rows], sensitivities, dk)
        unknowns = flat_poses(resolve(moved))
        out[:, c] = np.concatenate([tangent(start[n], unknowns[n]) for n in names])
    return out


def focal_change(camera: Camera) -> np.ndarray:
    """(4, 1) the change of (fx, fy, cx, cy) of a focal length 0.1% (`PERMILLE`) longer."""
    return np.array([[PERMILLE * camera.K[0, 0]], [PERMILLE * camera.K[1, 1]], [0.0], [0.0]])


def focal_moves(moves: np.ndarray, names: Sequence[str], percent: float, source: str = "images") -> dict[str, Any]:
    """The result's record of one camera's share: its focal length's 1-sigma (per cent), where
    that comes from (`handeye.vision.observations.STD_SOURCES`) and how far it moves each pose's
    translation (the first column of `moves`, `one_sigma_moves`)."""
    return {"focal_percent": percent, "std_from": source, "focal_moves": per_permille(np.asarray(moves)[:, 0], names)}


def per_permille(moves: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """{name: how far its translation moves} for the moves (6k,) or (6k, 1) of one change."""
    m = np.asarray(moves, dtype=float).ravel()
    return {n: float(np.linalg.norm(m[6 * j + 3:6 * j + 6])) for j, n in enumerate(names)}


def widened(cov: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """cov + D D^T for the answer's moves D (6k, c) of independent 1-sigma changes."""
    moves = np.asarray(moves, dtype=float)
    return np.asarray(cov, dtype=float) + moves @ moves.T


def translation_std(cov: np.ndarray, j: int) -> float:
    """The translation 1-sigma of unknown j (root of the trace of its translation block)."""
    block = np.asarray(cov)[6 * j + 3:6 * j + 6, 6 * j + 3:6 * j + 6]
    return math.sqrt(max(float(np.trace(block)), 0.0))


def growth_note(before: np.ndarray, after: np.ndarray, names: Sequence[str], percent: float,
                whose: str = "the camera's intrinsics", labels: Mapping[str, str] | None = None,
                source: str = "images") -> str | None:
    """The warning where the intrinsics at least double (`INTRINSICS_GROWTH`) a translation's
    1-sigma (covariances `before` / `after` of the unknowns `names`); `percent`: the focal
    length's 1-sigma in per cent (the largest, of several cameras); `whose`: the intrinsics in
    words (a cell's cameras by name); `labels`: the user's name of a pose (``Y[0]``: ``cam0``);
    `source`: where their 1-sigma comes from (`handeye.vision.observations.STD_SOURCES`)."""
    grown = []
    for j, name in enumerate(names):
        b, a = translation_std(before, j), translation_std(after, j)
        if a > INTRINSICS_GROWTH * b:
            grown.append(f"{(labels or {}).get(name, name)} to {a:.3g} (from {b:.3g} with them exact)")
    if not grown:
        return None
    known = {"images": f"{whose}, calibrated from these same images, are known to {percent:.2g}% in focal length",
             "file": f"{whose}, as the intrinsics file states their 1-sigma, are known to {percent:.2g}% in focal "
                     "length",
             "assumed": f"{whose} come from a file that states no 1-sigma for them, so they are taken as known as "
                        f"these images know them, {percent:.2g}% in focal length"}[source]
    advice = {"images": "Images at more distances and tilts fix the intrinsics better, or calibrate the camera apart "
                        "and give its intrinsics",
              "file": "A camera calibration from more images at several distances and tilts narrows it",
              "assumed": "Where the file's intrinsics are known better, state their 1-sigma in it (std_px: {fx, fy, "
                         "cx, cy} in pixels, or OpenCV's stdDeviationsIntrinsics)"}[source]
    return (f"{known}, and they leave the translation of {' and '.join(grown)} (1-sigma, the data's length unit; the "
            f"1-sigma reported includes them): a focal length a little off scales the board's distance. {advice}")


def covariance_of(diagnostics: Mapping[str, Any], names: Sequence[str]) -> tuple[np.ndarray, str | None] | None:
    """(the joint covariance (6k, 6k) of the unknowns `names`, where it is: None for the top level
    (refine, reprojection), ``"refine"`` for auto's), block diagonal where only each unknown's own
    block was reported; None where the solver reported none."""
    for key in (None, "refine"):
        entry = diagnostics if key is None else diagnostics.get(key) or {}
        blocks = entry.get("covariance")
        if not isinstance(blocks, Mapping) or not all(n in blocks for n in names):
            continue
        full = entry.get("covariance_" + "".join(names))
        if full is not None:
            return np.array(full, dtype=float), key
        cov = np.zeros((6 * len(names), 6 * len(names)))
        for j, n in enumerate(names):
            cov[6 * j:6 * j + 6, 6 * j:6 * j + 6] = np.array(blocks[n], dtype=float)
        return cov, key
    return None


def with_moves(diagnostics: Mapping[str, Any], names: Sequence[str], moves: np.ndarray,
               note: Callable[[np.ndarray, np.ndarray], str | None]) -> tuple[dict[str, Any], str | None]:
    """(a copy of a solution's `diagnostics` whose covariance and 1-sigma of the unknowns `names`
    include D D^T for the moves D (`answer_moves`), the warning `note(before, after)`); the
    diagnostics unchanged and no warning where the solver reported no covariance."""
    out = copy.deepcopy(dict(diagnostics))
    found = covariance_of(out, names)
    if found is None:
        return out, None
    before, key = found
    entry = out if key is None else out[key]
    after = widened(before, moves)
    var = np.diag(after)
    entry["covariance"] = {**entry["covariance"],
                           **{n: after[6 * j:6 * j + 6, 6 * j:6 * j + 6].tolist() for j, n in enumerate(names)}}
    if "covariance_" + "".join(names) in entry:
        entry["covariance_" + "".join(names)] = after.tolist()
    entry["std"] = {**(entry.get("std") or {}),
                    **{n: {"rotation": math.sqrt(max(float(sum(var[6 * j:6 * j + 3])), 0.0)),
                           "translation": math.sqrt(max(float(sum(var[6 * j + 3:6 * j + 6])), 0.0))}
                       for j, n in enumerate(names)}}
    return out, note(before, after)
