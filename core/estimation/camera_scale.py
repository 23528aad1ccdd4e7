"""A camera whose translations are known only up to scale (monocular SLAM or structure from
motion): the camera's translations t_B hold in their own unit, s t_B in the robot's, with s > 0
unknown. Selected with the data, ``camera_scale="unknown"`` (``"known"``, the default: the
camera's translations are in the robot's unit), like a planar robot's ``tz_X``: it is a fact of
the data, so every fit of them honours it, the solver's and the host's self-check alike.

In A_i X = Y B_i (and A_i X = X B_i) only the translation rows see s, and linearly:
t_i(s) = R_Ai t_X + t_Ai - s R_Y t_Bi - t_Y, so a pair's residual is e_i(s) = e_i(1) + (s - 1) g_i
with g_i = d e_i / d s = [0; -R_Y t_Bi] (`AXYBModel.camera_direction`), exactly. Hence:

- **Start** (`rotation_only`, `translations_and_scale`): the rotation rows alone do not see s, so
  the rotations come from the data with every translation set to zero (the certified `so3-sdp`
  solves that cost: docs/solvers/so3-sdp.md), and given them the translations and s are linear
  least squares (one Gauss-Newton step of the residual, which is affine in them).
- **Refinement** (`ScaledCameraModel`): s is profiled out, s*(X, Y) = argmin_s |e(s)|^2 in closed
  form, and the engine (`handeye.estimation.nlls`) refines the poses on e(s*) with the Jacobian projected
  orthogonally to g (variable projection: Golub & Pereyra 1973; Kaufman's Jacobian, 1975). The
  minimiser is that of the joint problem over (X, Y, s), and the covariance of the poses is the
  marginal one (the projection is the Schur complement of s). The projection is exact under the
  engine's per-group weights (one sigma for every translation residual); with a stated per-pair
  covariance s would need that metric too, which the refinement refuses.
- **Scale figures** (`scale_figures`): s and its standard deviation at the answer.
- **Noise bias** (`noise_bias`): s multiplies the camera's measured translations, so noise in them
  is noise in a regressor and biases the fitted s toward zero (errors in variables: regression
  dilution), by a relative amount up to kappa = n (std / s)^2 (n the translation residuals'
  degrees of freedom), reached when all the translation misfit is the camera's noise. The stated
  standard deviation does not include it; the host's self-check flags it (docs/camera-scale.md).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from handeye.base.errors import DegenerateDataError, InputError
from handeye.estimation.nlls import PoseModel, Poses

#: values of the data fact ``camera_scale``
CHOICES = ("known", "unknown")


def take(data: dict[str, Any]) -> bool:
    """Pop the data fact ``camera_scale`` from raw data: True for "unknown", False for "known" or
    absent; InputError for anything else."""
    value = data.pop("camera_scale", "known")
    if not isinstance(value, str) or value not in CHOICES:
        raise InputError(f"camera_scale={value!r} must be 'known' (the camera's translations are in the robot's unit, "
                         "the default) or 'unknown' (known only up to scale, e.g. monocular SLAM)")
    return value == "unknown"


def rotation_only(data: Any) -> Any:
    """The same validated data with every translation set to zero: the rotation rows alone, which
    do not see the camera's scale (and do not need the fact any more)."""
    stacks = {}
    for name in ("A", "B"):
        T = np.array(getattr(data, name))
        T[:, :3, 3] = 0.0
        T.setflags(write=False)
        stacks[name] = T
    return dataclasses.replace(data, camera_scale_unknown=False, **stacks)


def model_for(data: Any, model: PoseModel) -> PoseModel:
    """`model` of `data`, with the camera's scale profiled out when the data say it is unknown;
    one scale per camera when the data make that model themselves (``scaled_cameras_model``, as a
    cell of several cameras does: `handeye.estimation.camera_scales.ScaledCamerasModel`)."""
    if not getattr(data, "camera_scale_unknown", False):
        return model
    several = getattr(data, "scaled_cameras_model", None)
    return several(model) if several is not None else ScaledCameraModel(model)


class ScaledCameraModel(PoseModel):
    """`model` (an `AXYBModel` or `AXXBModel`: `camera_direction`, `with_camera_scale`) with the
    camera's scale s profiled out (module docstring). `camera_scale(poses)` gives s* there."""

    sums_min_pairs = math.inf  # the closed-form sums hold for a fixed s only

    def __init__(self, model: PoseModel) -> None:
        self.model = model
        self.unknowns, self.m, self.scale = model.unknowns, model.m, model.scale
        self.profile_min_pairs = model.profile_min_pairs
        self.fixed = model.fixed
        self._last: tuple[Poses, float, np.ndarray] | None = None

    def _profile(self, poses: Poses) -> tuple[np.ndarray, float, np.ndarray]:
        """(e(1), s*, g) at the poses."""
        e1 = self.model.residuals(poses)
        g = self.model.camera_direction(poses)
        gg = float(np.sum(g[:, 3:] * g[:, 3:]))
        if not gg > 0.0:
            raise DegenerateDataError("the camera's translations are all zero, so their scale is undetermined: "
                                      "give camera_scale='known', or record poses where the camera moves")
        s = 1.0 - float(np.sum(g[:, 3:] * e1[:, 3:])) / gg
        self._last = (poses, s, g)
        return e1, s, g

    def camera_scale(self, poses: Poses) -> float:
        """s*: the factor on the camera's translations that fits the poses best."""
        return self._profile(poses)[1]

    def residuals(self, poses: Poses) -> np.ndarray:
        e1, s, g = self._profile(poses)
        return e1 + (s - 1.0) * g

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        last = self._last
        _, s, g = last if last is not None and last[0] is poses else self._profile(poses)
        J = self.model.with_camera_scale(s).jacobian(poses, e)  # read-only (the model keeps it)
        n = J.shape[2]
        Jf, gf = J.reshape(-1, n), g.reshape(-1)
        Jf = Jf - np.outer(gf, (gf @ Jf) / (gf @ gf))  # orthogonal to g: s re-profiled at every step
        return Jf.reshape(J.shape)


def translations_and_scale(model: PoseModel, rotations: Poses) -> tuple[Poses, float]:
    """The translations of the unknowns and the camera's scale s that fit `model`'s data best for
    the given poses' rotations (their translations are not used): linear least squares, as one
    Gauss-Newton step from zero translations and s = 1, which is exact since the translation
    residual is affine in them (the retraction moves t by R v). DegenerateDataError when they
    are not determined."""
    poses = tuple(_without_translation(T) for T in rotations)
    e = model.residuals(poses)
    J = model.jacobian(poses, e)[:, 3:, :]  # translation rows
    cols = [6 * j + c for j in range(len(poses)) for c in (3, 4, 5)]
    g = model.camera_direction(poses)[:, 3:]
    M = np.concatenate([J[:, :, cols], g[:, :, None]], axis=2).reshape(-1, len(cols) + 1)
    x, _, rank, _ = np.linalg.lstsq(M, -e[:, 3:].reshape(-1), rcond=None)
    if rank < M.shape[1]:
        raise DegenerateDataError("the translations and the camera's scale are undetermined by these poses: "
                                  "record poses that rotate about at least two different axes, with the camera moving")
    return with_translations(poses, x), 1.0 + float(x[-1])


def with_translations(poses: Poses, x: np.ndarray) -> Poses:
    """The poses with the translations the linear step found: t_j = R_j x[3j:3j+3] (the step is
    on right perturbations, so in each pose's own frame)."""
    out = []
    for j, T in enumerate(poses):
        T = T.copy()
        T[:3, 3] = T[:3, :3] @ x[3 * j:3 * j + 3]
        out.append(T)
    return tuple(out)


def _without_translation(T: np.ndarray) -> np.ndarray:
    out = np.array(T, dtype=float)
    out[:3, 3] = 0.0
    return out


def scale_figures(model: ScaledCameraModel, poses: Poses, sigma_rot: float, sigma_trans: float,
                  variance_factor: float = 1.0) -> dict[str, Any]:
    """The camera's scale s at the poses and its standard deviation under per-group noise
    (sigma_rot, sigma_trans, times the variance factor of an estimated noise): the inverse of the
    Schur complement of s in the information matrix of (poses, s), g_w^T (I - P) g_w with g_w the
    whitened d e / d s and P the projector onto the span of the whitened Jacobian of the poses.
    Several cameras (`ScaledCamerasModel`): "camera_scales" and "camera_scales_std", per camera."""
    if hasattr(model, "camera_names"):
        return model.scale_figures(poses, sigma_rot, sigma_trans, variance_factor)
    e1, s, g = model._profile(poses)
    J = model.model.with_camera_scale(s).jacobian(poses, e1 + (s - 1.0) * g)
    w = np.repeat([1.0 / sigma_rot, 1.0 / sigma_trans], 3)
    Jf, gf = (J * w[:, None]).reshape(-1, J.shape[2]), (g * w).reshape(-1)
    coef, *_ = np.linalg.lstsq(Jf, gf, rcond=None)
    information = float(gf @ (gf - Jf @ coef))
    std = math.sqrt(variance_factor / information) if information > 0 else math.inf
    return {"camera_scale": s, "camera_scale_std": std}


def noise_bias(model: ScaledCameraModel, poses: Poses, sigma_rot: float, sigma_trans: float,
               variance_factor: float = 1.0) -> dict[str, float]:
    """`scale_figures` and the bias that noise in the camera's translations puts on s (module
    docstring): "bias", the relative amount kappa = n (std / s)^2 by which s falls short of the
    truth when all the translation misfit is the camera's noise, and "bias_sigmas", the same in
    standard deviations of s, n std / s (infinite when s <= 0: the data do not fix its sign).

    Why: s is fitted against the camera's translations R_Y t_Bi after the poses are fitted (the
    projection of g off the poses' Jacobian, (I - P) g). Noise of variance sigma_B^2 in each
    component of t_B adds about n sigma_B^2 to |(I - P) g|^2 and nothing to the covariance of g
    with the robot's side, so s shrinks by the factor 1 - n sigma_B^2 / |(I - P) g|^2. The
    translation residuals bound sigma_B: sigma_t^2 = sigma_A^2 + s^2 sigma_B^2 >= s^2 sigma_B^2,
    and std^2 = sigma_t^2 / |(I - P) g|^2, hence kappa. n = 3 (pairs - unknowns): the translation
    residuals less the unknowns' translations. Several cameras (`ScaledCamerasModel`): the same
    per camera ("cameras"), the camera of the largest "bias_sigmas" at the top ("camera")."""
    if hasattr(model, "camera_names"):
        return model.noise_bias(poses, sigma_rot, sigma_trans, variance_factor)
    figures = scale_figures(model, poses, sigma_rot, sigma_trans, variance_factor)
    s, std = figures["camera_scale"], figures["camera_scale_std"]
    n = 3.0 * (model.m - len(model.unknowns))
    rel = std / s if s > 0 else math.inf
    return {**figures, "bias": n * rel * rel, "bias_sigmas": n * rel}
