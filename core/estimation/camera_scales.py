"""Several cameras, each known only up to its own scale (monocular SLAM or structure from motion
per camera): `handeye.estimation.camera_scale` for q scales s_1, ..., s_q whose directions act on disjoint
sets of observations. Camera c's scale multiplies the translations t_Bi of its own observations
(``groups[i] == c``; -1: a metric camera's observation, scale 1), so with g_i = d e_i / d s =
[0; -R_Y t_Bi] (`camera_direction`, exact: e is affine in every s_c)

    e_i(s) = e_i(1) + (s_{c_i} - 1) g_i,        G = [g^(1), ..., g^(q)],  g^(c) = g on c's rows only.

The columns of G have disjoint supports, so G^T G is diagonal and everything of the single scale
holds column by column:

- **Profile** (`ScaledCamerasModel`): s_c* = 1 - <g^(c), e(1)> / |g^(c)|^2, each in closed form.
- **Variable projection**: the Jacobian of the poses projected orthogonally to span(G), i.e. off
  each g^(c) on its own rows (Kaufman 1975); the engine's covariance of the poses is then the
  marginal one (the Schur complement of the scales).
- **Start** (`translations_and_scales`): given the rotations, the translations and the q scales
  by one linear least squares; a camera whose scale that system does not fix (its column of G
  inside the span of the others: its t_B constant over its observations, e.g. a wrist camera
  turned about its own centre, with its target seen by no other camera) is refused by name.
- **Figures** (`ScaledCamerasModel.scale_figures`): s_c and the marginal standard deviation
  from the inverse of the Schur complement S = G_w^T (I - P) G_w (q x q), P the projector onto
  the whitened Jacobian of the poses; `noise_bias`: the regression-dilution bound per camera,
  kappa_c = n_c (std_c / s_c)^2 with n_c the translation residuals of camera c less their
  leverage on the poses (3 m_c - trace of the hat matrix on c's translation rows).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from handeye.base.errors import DegenerateDataError
from handeye.estimation.camera_scale import ScaledCameraModel, with_translations
from handeye.estimation.nlls import PoseModel, Poses

#: a camera's scale column of the translation system whose share outside the span of the other
#: columns (sin^2 of the angle to it) is below this is not determined by the data (noise-free
#: degenerate data leave ~1e-30; the weakest camera of the tests' cells, ~1e-3)
UNDETERMINED_RATIO = 1e-10
#: a camera's scale fitted fewer than this many of its standard deviations above zero (the start's
#: linear least squares, the rotations held) is refused: the data do not fix it (a camera turned
#: about its own centre fits best at 0, its translations unused)
POSITIVE_SIGMAS = 3.0
#: a camera's scale fitted fewer than this many of its standard deviations from zero (the start's
#: linear least squares) is weakly determined: a warning names it
WEAK_SIGMAS = 10.0


class GroupScreen(NamedTuple):
    """One group's screened scale (`screen_groups`): its name and rows, the scale its camera
    translations would need with its standard deviation, and d(poses)/d(scale) (6k,)."""
    name: str
    rows: np.ndarray
    scale: float
    std: float
    slope: np.ndarray


class ScaledCamerasModel(ScaledCameraModel):
    """`model` (camera_direction, with_camera_scale accepting an (m,) factor per observation)
    with q camera scales profiled out: groups (m,) the camera of each observation (0..q-1; -1:
    metric), names (q,) the cameras' names for messages and figures."""

    def __init__(self, model: PoseModel, groups: np.ndarray, names: tuple[str, ...]) -> None:
        super().__init__(model)
        self.groups = np.asarray(groups, dtype=np.int64)
        self.camera_names = tuple(names)
        self.q = len(self.camera_names)
        self._scaled = self.groups >= 0
        self._last_many: tuple[Poses, np.ndarray, np.ndarray, np.ndarray] | None = None

    def _sums(self, values: np.ndarray) -> np.ndarray:
        """Per camera sums of values (m,) over its observations: (q,)."""
        return np.bincount(self.groups[self._scaled], weights=values[self._scaled], minlength=self.q)

    def _profile_many(self, poses: Poses) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(e(1), s* (q,), G's rows g (m, 6), zero on metric rows, |g^(c)|^2 (q,)) at the poses."""
        e1 = self.model.residuals(poses)
        g = self.model.camera_direction(poses)
        g[~self._scaled] = 0.0
        gg = self._sums(np.einsum("ni,ni->n", g[:, 3:], g[:, 3:]))
        if not np.all(gg > 0.0):
            c = int(np.flatnonzero(~(gg > 0.0))[0])
            raise DegenerateDataError(f"the translations of camera {self.camera_names[c]!r} are all zero, so its scale "
                                      "is undetermined: record poses where it sees its targets from different places, "
                                      "or leave it out of camera_scale")
        s = 1.0 - self._sums(np.einsum("ni,ni->n", g[:, 3:], e1[:, 3:])) / gg
        self._last_many = (poses, s, g, gg)
        return e1, s, g, gg

    def _factors(self, s: np.ndarray) -> np.ndarray:
        """(m,) the scale of each observation's camera (1 for a metric one)."""
        return np.where(self._scaled, s[np.maximum(self.groups, 0)], 1.0)

    def camera_scale(self, poses: Poses) -> np.ndarray:  # type: ignore[override]
        """s*: (q,) the factors on the cameras' translations that fit the poses best."""
        return self._profile_many(poses)[1]

    def residuals(self, poses: Poses) -> np.ndarray:
        e1, s, g, _ = self._profile_many(poses)
        return e1 + (self._factors(s) - 1.0)[:, None] * g

    def jacobian(self, poses: Poses, e: np.ndarray) -> np.ndarray:
        last = self._last_many
        _, s, g, gg = last if last is not None and last[0] is poses else self._profile_many(poses)
        J = self.model.with_camera_scale(self._factors(s)).jacobian(poses, e)
        n = J.shape[2]
        gJ = np.einsum("ia,ian->in", g, J)  # (m, n): each row's g_i^T J_i
        per = np.zeros((self.q, n))
        np.add.at(per, self.groups[self._scaled], gJ[self._scaled])
        coef = per / gg[:, None]
        J[self._scaled] -= g[self._scaled][:, :, None] * coef[self.groups[self._scaled]][:, None, :]
        return J

    # ------------------------------------------------------------------ figures

    def _whitened(self, poses: Poses, sigma_rot: float,
                  sigma_trans: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s (q,), Jf (6m, n) the whitened Jacobian of the poses at s, Gf (6m, q) the whitened G)."""
        e1, s, g, _ = self._profile_many(poses)
        factors = self._factors(s)
        J = self.model.with_camera_scale(factors).jacobian(poses, e1 + (factors - 1.0)[:, None] * g)
        w = np.repeat([1.0 / sigma_rot, 1.0 / sigma_trans], 3)
        G = np.zeros((self.model.m, 6, self.q))
        rows = np.flatnonzero(self._scaled)
        G[rows, :, self.groups[rows]] = g[rows] * w
        return s, (J * w[:, None]).reshape(-1, J.shape[2]), G.reshape(-1, self.q)

    def scale_figures(self, poses: Poses, sigma_rot: float, sigma_trans: float,
                      variance_factor: float = 1.0) -> dict[str, Any]:
        """{"camera_scales": {name: s_c}, "camera_scales_std": {name: its marginal 1-sigma}}
        (module docstring); std inf for a camera the poses leave its scale free."""
        s, std, _ = self._marginal(poses, sigma_rot, sigma_trans, variance_factor)
        return {"camera_scales": dict(zip(self.camera_names, s.tolist())),
                "camera_scales_std": dict(zip(self.camera_names, std.tolist()))}

    def _marginal(self, poses: Poses, sigma_rot: float, sigma_trans: float,
                  variance_factor: float) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        s, Jf, Gf = self._whitened(poses, sigma_rot, sigma_trans)
        coef, *_ = np.linalg.lstsq(Jf, Gf, rcond=None)
        S = Gf.T @ (Gf - Jf @ coef)
        S = 0.5 * (S + S.T)
        lam = np.linalg.eigvalsh(S)
        if lam[0] > 1e-12 * max(lam[-1], 1e-300):
            std = np.sqrt(variance_factor * np.diag(np.linalg.inv(S)))
        else:
            std = np.full(self.q, math.inf)
        return s, std, (Jf, Gf)

    def noise_bias(self, poses: Poses, sigma_rot: float, sigma_trans: float,
                   variance_factor: float = 1.0) -> dict[str, Any]:
        """`handeye.estimation.camera_scale.noise_bias` per camera: "cameras" {name: {"camera_scale",
        "camera_scale_std", "bias", "bias_sigmas", "dof"}}, and at the top the figures of the camera
        with the largest "bias_sigmas" with its name ("camera")."""
        s, std, (Jf, _) = self._marginal(poses, sigma_rot, sigma_trans, variance_factor)
        Q, R = np.linalg.qr(Jf)
        keep = np.abs(np.diag(R)) > 1e-12 * max(float(np.abs(np.diag(R)).max()), 1e-300)
        leverage = np.einsum("ij,ij->i", Q[:, keep], Q[:, keep]).reshape(-1, 6)[:, 3:].sum(axis=1)  # per observation
        count = np.bincount(self.groups[self._scaled], minlength=self.q)
        dof = np.maximum(3.0 * count - self._sums(leverage), 0.0)
        cameras = {}
        for c, name in enumerate(self.camera_names):
            rel = std[c] / s[c] if s[c] > 0 else math.inf
            cameras[name] = {"camera_scale": float(s[c]), "camera_scale_std": float(std[c]),
                             "bias": float(dof[c] * rel * rel), "bias_sigmas": float(dof[c] * rel),
                             "dof": float(dof[c])}
        worst = max(cameras, key=lambda name: cameras[name]["bias_sigmas"])
        return {**{k: cameras[worst][k] for k in ("camera_scale", "camera_scale_std", "bias", "bias_sigmas")},
                "camera": worst, "cameras": cameras}


def translations_and_scales(model: PoseModel, rotations: Poses, groups: np.ndarray, names: tuple[str, ...]
                            ) -> tuple[Poses, np.ndarray, dict[str, Any]]:
    """The translations of the unknowns and the q cameras' scales that fit `model`'s data best
    for the given poses' rotations (their translations are not used), by one linear least
    squares (the residual is affine in them: `handeye.estimation.camera_scale.translations_and_scale`):
    (poses, s (q,), figures {"camera_scales", "camera_scales_std" (from the residual's RMS,
    the rotations held fixed), "weak": names of cameras fitted fewer than WEAK_SIGMAS standard
    deviations from zero}). DegenerateDataError naming a camera whose scale the system does not
    fix, or the unknowns' translations when they are not fixed, or a scale fitted <= 0."""
    groups = np.asarray(groups, dtype=np.int64)
    q, scaled = len(names), groups >= 0
    poses = tuple(_without_translation(T) for T in rotations)
    e = model.residuals(poses)
    J = model.jacobian(poses, e)[:, 3:, :]
    cols = [6 * j + c for j in range(len(poses)) for c in (3, 4, 5)]
    g = model.camera_direction(poses)[:, 3:]
    G = np.zeros((len(g), 3, q))
    rows = np.flatnonzero(scaled)
    G[rows, :, groups[rows]] = g[rows]
    T, Gm, w = J[:, :, cols].reshape(-1, len(cols)), G.reshape(-1, q), -e[:, 3:].reshape(-1)
    Qt, Rt = np.linalg.qr(T)
    if np.abs(np.diag(Rt)).min() <= 1e-10 * np.abs(np.diag(Rt)).max():
        raise DegenerateDataError("the translations are undetermined by these poses: record poses that rotate about "
                                  "at least two different axes")
    Gp = Gm - Qt @ (Qt.T @ Gm)  # the scales' columns off the translations'
    norms = np.einsum("ij,ij->j", Gm, Gm)
    S = Gp.T @ Gp
    for c in range(q):  # each camera given the translations (and the other scales fixed)
        if not S[c, c] > UNDETERMINED_RATIO * norms[c]:
            raise DegenerateDataError(_undetermined([names[c]]))
    Sn = S / np.sqrt(np.outer(np.diag(S), np.diag(S)))
    lam, V = np.linalg.eigh(Sn)
    if lam[0] <= UNDETERMINED_RATIO:
        raise DegenerateDataError(_undetermined([names[c] for c in np.flatnonzero(np.abs(V[:, 0]) > 0.1)]))
    wp = w - Qt @ (Qt.T @ w)
    Sinv = np.linalg.inv(S)
    x_s = Sinv @ (Gp.T @ wp)
    x_t = np.linalg.solve(Rt, Qt.T @ (w - Gm @ x_s))
    s = 1.0 + x_s
    r = w - T @ x_t - Gm @ x_s
    dof = max(len(w) - len(cols) - q, 1)
    std = np.sqrt(max(float(r @ r) / dof, 0.0) * np.diag(Sinv))
    bad = np.flatnonzero(~(s > POSITIVE_SIGMAS * std) | ~(s > 0.0))
    if len(bad):
        c = int(bad[0])
        raise DegenerateDataError(f"the scale of camera {names[c]!r} fitted to these poses is {s[c]:.3g} "
                                  f"(+-{std[c]:.2g}), not positive beyond its noise: "
                                  "its translations do not follow the robot's motion (it turns about its own centre or "
                                  "sees its targets from one place: record stations where it moves toward and around "
                                  "them; or its observations are mispaired: check their pairing, its index and the "
                                  "setup)")
    weak = [names[c] for c in range(q) if not s[c] > WEAK_SIGMAS * std[c]]
    return with_translations(poses, x_t), s, {"camera_scales": dict(zip(names, s.tolist())),
                           "camera_scales_std": dict(zip(names, std.tolist())), "weak": weak}


def screen_groups(model: PoseModel, poses: Poses, e: np.ndarray, W: Any, cov: np.ndarray,
                  groups: tuple[tuple[str, np.ndarray], ...]) -> list[GroupScreen]:
    """The host's check 5 per camera of a cell whose every camera is taken as metric: for each
    group of observations (name, rows: each X's and each Y's, since which are cameras the data
    do not say), the scale s its t_B would need and its standard deviation, in one Gauss-Newton
    step from a least-squares fit (`poses`, residuals e, per-group weights W, covariance cov), as
    `handeye.checks.scale_checks.camera_scale_screen` does for one camera, and how the fit would
    move per unit of that scale (-H^-1 J^T W g over the group's rows, H^-1 = cov / the variance
    factor). For the groups the data determine (a positive Schur complement)."""
    g = model.camera_direction(poses)
    gw, ew = W.residual(g), W.residual(e)
    Jw = W.jacobian(model.jacobian(poses, e))
    C = np.einsum("iak,ia->ik", Jw, gw)  # (m, 6n): each observation's J_i^T W g_i
    gg, ge = np.einsum("ia,ia->i", gw, gw), np.einsum("ia,ia->i", gw, ew)
    factor = float(np.sum(ew * ew)) / max(ew.size - Jw.shape[2], 1)
    out = []
    for name, rows in groups:
        b = C[rows].sum(axis=0)
        slope = cov @ b / factor
        schur = float(gg[rows].sum()) - float(b @ slope)
        if schur > 0.0:
            out.append(GroupScreen(name, rows, 1.0 - float(ge[rows].sum()) / schur, math.sqrt(factor / schur), -slope))
    return out


def groups_off_scale(model: PoseModel, res: Any, screens: list[GroupScreen], groups: tuple[tuple[str, np.ndarray], ...],
                     suspect: Any, max_iter: int, tol: float) -> tuple[list[str], float, dict[str, Any]] | None:
    """For the host's check 5 on a cell: the groups of observations (each X's, each Y's) whose
    t_B fit best at another scale, from the least-squares fit `res` (an `nlls` result) and its
    groups' `screens` (`screen_groups`). Where any is `suspect(s, std)`, the
    fits with scales free (`ScaledCamerasModel`, least squares, estimated weights) of every X's
    group, every Y's, and the suspects' (most standard deviations first, sharing no
    observation): the one whose translation residuals shrink the most, as (names, that factor,
    `scale_figures`), or None."""
    from handeye.estimation import nlls
    from handeye.estimation.robust import DEFAULT_LOSS_SCALE

    suspects = [x for x in screens if suspect(x.scale, x.std)]
    greedy: list[tuple[str, np.ndarray]] = []
    used = np.zeros(model.m, dtype=bool)
    for x in sorted(suspects, key=lambda x: -abs(x.scale - 1.0) / x.std):
        if not used[x.rows].any():
            greedy.append((x.name, x.rows))
            used[x.rows] = True
    if not greedy:
        return None
    nX = getattr(model, "nX", 0)
    best = None
    for chosen in (list(groups[:nX]), list(groups[nX:]), greedy):  # wrist cameras, fixed ones, some of each
        names = [name for name, _ in chosen]
        if not chosen or (best is not None and names == best[0]):
            continue
        group_of = np.full(model.m, -1, dtype=np.int64)
        for c, (_, rows) in enumerate(chosen):
            group_of[rows] = c
        try:
            free = ScaledCamerasModel(model, group_of, tuple(names))
            fit = nlls.levenberg_marquardt(free, res.poses, None, "linear", DEFAULT_LOSS_SCALE, max_iter, tol)
            figures = free.scale_figures(fit.poses, fit.W.sigma_rot, fit.W.sigma_trans,
                                         nlls.covariance(fit, "linear", DEFAULT_LOSS_SCALE, True)[1])
        except DegenerateDataError:
            continue
        gain = math.sqrt(float(np.sum(res.e[:, 3:] ** 2)) / max(float(np.sum(fit.e[:, 3:] ** 2)), 1e-300))
        if best is None or gain > best[1]:
            best = (names, gain, figures)
    return best


def weak_warning(figures: dict[str, Any]) -> list[str]:
    """The warnings for the cameras `translations_and_scales` found weakly determined."""
    return [f"the scale of camera {name!r} is weakly determined: {figures['camera_scales'][name]:.4g} "
            f"(+-{figures['camera_scales_std'][name]:.2g}); record stations where camera {name!r} sees its targets "
            "from different distances and places" for name in figures.get("weak", [])]


def _undetermined(cameras: list[str]) -> str:
    """The refusal of cameras whose scales the data do not fix, named."""
    listed = " and ".join(repr(name) for name in cameras)
    what = f"camera {listed}" if len(cameras) == 1 else f"cameras {listed}"
    return (f"the data do not determine the scale of {what}: its translations t_B barely change over its "
            "observations beyond what the X's and Y's explain (it turns about its own centre, or sees its targets "
            f"from one place); record stations where {what} moves toward and around its targets, or give its scale "
            "(leave it out of camera_scale)")


def _without_translation(T: np.ndarray) -> np.ndarray:
    out = np.array(T, dtype=float)
    out[:3, 3] = 0.0
    return out
