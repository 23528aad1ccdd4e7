"""`kron-lstsq` for ``axyb-multi`` (A_i X_{x_i} = Y_{y_i} B_i: several cameras and targets): the
closed-form start from the stacked Kronecker system, one connected component of the observation
graph at a time (`AXYBMultiData.components`: nothing ties two components, so each is solved alone
and has its own scale of the null vector below).

Rotations (Pan et al., T-ASE 2022, eq. 6, for every observation; stacked as Shah 2013 does for
one X and one Y). With column-major vec, vec(R_Ai R_Xj) = (I kron R_Ai) vec R_Xj and
vec(R_Yk R_Bi) = (R_Bi^T kron I) vec R_Yk, so observation i gives the nine homogeneous rows
[I kron R_Ai, -(R_Bi^T kron I)] on r = [vec R_X0; ...; vec R_Y0; ...] (9 (nX + nY) unknowns of the
component). r is the null vector of the stack: the eigenvector of the smallest eigenvalue of its
normal matrix N = H^T H, summed per observation without forming H (9m x 9(nX + nY)):

    N_{Xj,Xj} = I kron sum_{x_i = j} R_Ai^T R_Ai            (m_j I_9 for exact rotations)
    N_{Yk,Yk} = (sum_{y_i = k} R_Bi R_Bi^T) kron I          (m_k I_9)
    N_{Xj,Yk} = -sum_{x_i = j, y_i = k} R_Bi^T kron R_Ai^T  (one 9 x 9 sum per observed (j, k))

O(81 m) work in one pass, then one dense symmetric eigenproblem of size 9 (nX + nY) (216 for 8
cameras and 16 markers). The rows are homogeneous, so r has a free scale, which the SVD projection
ignores, and a free sign, fixed by the determinants (sum over the blocks of det M > 0: a rotation
has det +1); each 3 x 3 block is projected onto SO(3) (`project_to_so3`).

Translations, the rotations fixed: R_Ai t_Xj - t_Yk = R_Yk t_Bi - t_Ai, linear least squares in the
3 (nX + nY) translations of the component through its normal equations (blocks sum R_Ai^T R_Ai,
m_k I and -sum_{(j, k)} R_Ai^T); there is no gauge: the system is regular as soon as the robot's
rotations do not all share one axis.

Conditioning. The rotation step never sees a translation and the translation step is linear in
them, so the answer scales exactly with the length unit: no normalisation is needed and none is
offered (``unit_invariant=True``, no options). The normal matrix squares the condition number of
the stack, which costs nothing here: noise-free data leave N an exact null vector, whose
eigenvector is found to ~eps * lambda_max / lambda_2 (errors <= 4e-15 measured). The
relative weight of the unknowns is the number of their observations (N's diagonal blocks
m_j I_9), the algebraic least squares of the stack; `refine` weighs them by their noise.

Degeneracy (the problem's validation refuses unobservable cells first; this is the solver's own
guard, never a guess): a second null direction of N (lambda_2 <= UNDETERMINED_RTOL times its mean
eigenvalue), or a singular translation system, raises DegenerateDataError naming the component's
unknowns; a null direction that stands out from the next by less than WEAK_GAP gives a warning.

Cameras known only up to their own scales (``camera_scale=[names]``, `handeye.estimation.camera_scales`):
the rotation step is the same (it never sees a translation); the translations and every
camera's scale then come from one linear least squares given the rotations
(`camera_scales.translations_and_scales`: a camera whose scale it does not fix is refused by
name), with ``camera_scales`` and ``camera_scales_std`` in the diagnostics.

Diagnostics: ``components`` (per component its X's and Y's, observations, ``rotation_gap``
lambda_2 / lambda_1 (inf on exact data), ``sign_flipped``, ``translation_rcond``),
``rotation_blocks`` (each block before projection, keyed ``X[j]`` / ``Y[k]``, for the self-check).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from handeye import DegenerateDataError, SolverOutput, SolverSpec, Status
from handeye.geometry.se3 import gram, make_pose, project_to_so3

if TYPE_CHECKING:
    from handeye.problems.axyb_multi.data import AXYBMultiData

#: the problem this module solves
PROBLEM = "axyb-multi"
#: a second eigenvalue of the rotation normal matrix at or below this times its mean eigenvalue
#: is a second null direction: the rotations are undetermined (rounding leaves ~1e-16 * n there);
#: likewise the smallest eigenvalue of the translation normal matrix relative to its largest
UNDETERMINED_RTOL = 1e-10
#: rotation_gap (lambda_2 / lambda_1) below which a warning says the observations barely determine
#: the rotations (as kron-lstsq for axbycz; a well observed cell with 0.005 rad of noise is > 1e3)
WEAK_GAP = 10.0


def group_sums(values: np.ndarray, groups: np.ndarray, n: int) -> np.ndarray:
    """sum of values[i] over the i with groups[i] == g, for g = 0..n-1: values (m, ...) -> (n, ...)."""
    order = np.argsort(groups, kind="stable")
    sorted_groups = groups[order]
    starts = np.flatnonzero(np.r_[True, sorted_groups[1:] != sorted_groups[:-1]])
    out = np.zeros((n,) + values.shape[1:])
    out[sorted_groups[starts]] = np.add.reduceat(values[order], starts, axis=0)
    return out


def _pairs(x: np.ndarray, y: np.ndarray, nY: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: N803
    """(pair of each observation 0..p-1, X of each pair, Y of each pair) of the observed (x, y)."""
    keys, pair = np.unique(x * nY + y, return_inverse=True)
    return pair.ravel(), keys // nY, keys % nY


def rotation_normal_matrix(RA: np.ndarray, RB: np.ndarray, x: np.ndarray, y: np.ndarray,  # noqa: N803
                           nX: int, nY: int) -> np.ndarray:
    """N = H^T H of the rotation rows of one component (module docstring): (9n, 9n), n = nX + nY,
    unknowns [vec R_X0; ...; vec R_Y0; ...] (column-major vec). RA, RB: (m, 3, 3); x, y: (m,)
    indices 0..nX-1, 0..nY-1."""
    n, m = nX + nY, len(RA)
    N = np.zeros((n, 9, n, 9))
    eye = np.eye(3)
    GA = group_sums(gram(RA).reshape(m, 9), x, nX).reshape(nX, 3, 3)  # sum R_A^T R_A per X
    GB = group_sums(gram(np.swapaxes(RB, 1, 2)).reshape(m, 9), y, nY).reshape(nY, 3, 3)  # sum R_B R_B^T per Y
    jx, ky = np.arange(nX), nX + np.arange(nY)
    N[jx, :, jx, :] = np.einsum("ab,jcd->jacbd", eye, GA).reshape(nX, 9, 9)  # I kron G_A
    N[ky, :, ky, :] = np.einsum("jab,cd->jacbd", GB, eye).reshape(nY, 9, 9)  # G_B kron I
    pair, pj, pk = _pairs(x, y, nY)
    P = np.swapaxes(RB, 1, 2).reshape(m, 9)  # R_B^T, row-major
    Q = np.swapaxes(RA, 1, 2).reshape(m, 9)  # R_A^T
    outer = group_sums((P[:, :, None] * Q[:, None, :]).reshape(m, 81), pair, len(pj))
    K = outer.reshape(-1, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(-1, 9, 9)  # sum R_B^T kron R_A^T
    N[pj, :, nX + pk, :] = -K
    N[nX + pk, :, pj, :] = -np.swapaxes(K, 1, 2)
    return N.reshape(9 * n, 9 * n)


def component_rotations(RA: np.ndarray, RB: np.ndarray, x: np.ndarray, y: np.ndarray, nX: int, nY: int,  # noqa: N803
                        what: str) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The rotations of one component from the null vector of its rotation rows: (R (n, 3, 3) in
    the order X's then Y's, the blocks before projection (n, 3, 3), figures). `what` names the
    component's unknowns in the error when they are undetermined."""
    from scipy.linalg import eigh

    N = rotation_normal_matrix(RA, RB, x, y, nX, nY)
    mean = float(np.trace(N)) / len(N)
    lam, V = eigh(N, subset_by_index=[0, 1])
    if lam[1] <= UNDETERMINED_RTOL * mean:
        raise DegenerateDataError(
            f"kron-lstsq for axyb-multi: the observations of {what} do not determine their rotations (the "
            "stacked rotation system has more than one null direction): each X and each Y needs observations "
            "at robot poses that rotate about at least two different axes, and the cell's graph of X's and "
            "Y's must tie them together")
    n = nX + nY
    blocks = V[:, 0].reshape(n, 3, 3).transpose(0, 2, 1)  # column-major vec per block
    flipped = bool(np.sum(np.linalg.det(blocks)) < 0)
    if flipped:
        blocks = -blocks
    gap = float(lam[1] / lam[0]) if lam[0] > 0 else float("inf")
    return project_to_so3(blocks), blocks, {"rotation_gap": gap, "sign_flipped": flipped}


def component_translations(A: np.ndarray, B: np.ndarray, RX: np.ndarray, RY: np.ndarray, x: np.ndarray,  # noqa: N803
                           y: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray, float]:
    """t_X (nX, 3), t_Y (nY, 3) of one component by least squares given RX (nX, 3, 3), RY (nY, 3, 3):
    R_Ai t_Xj - t_Yk = R_Yk t_Bi - t_Ai; and the reciprocal condition number of its normal matrix."""
    nX, nY, m = len(RX), len(RY), len(A)
    n = nX + nY
    RA, tA, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    p = np.einsum("mab,mb->ma", RY[y], tB) - tA
    N = np.zeros((n, 3, n, 3))
    g = np.zeros((n, 3))
    jx, ky = np.arange(nX), nX + np.arange(nY)
    N[jx, :, jx, :] = group_sums(gram(RA).reshape(m, 9), x, nX).reshape(nX, 3, 3)
    N[ky, :, ky, :] = np.bincount(y, minlength=nY)[:, None, None] * np.eye(3)
    pair, pj, pk = _pairs(x, y, nY)
    S = group_sums(np.swapaxes(RA, 1, 2).reshape(m, 9), pair, len(pj)).reshape(-1, 3, 3)  # sum R_A^T
    N[pj, :, nX + pk, :] = -S
    N[nX + pk, :, pj, :] = -np.swapaxes(S, 1, 2)
    g[:nX] = group_sums(np.einsum("mba,mb->ma", RA, p), x, nX)
    g[nX:] = -group_sums(p, y, nY)
    lam, V = np.linalg.eigh(N.reshape(3 * n, 3 * n))
    if not lam[0] > UNDETERMINED_RTOL * lam[-1]:
        raise DegenerateDataError(
            f"kron-lstsq for axyb-multi: the observations of {what} do not determine their translations: the "
            "robot poses rotate about fewer than two different axes. Record poses that rotate about at least "
            "two different axes")
    t = V @ ((V.T @ g.reshape(3 * n)) / lam)
    t = t.reshape(n, 3)
    return t[:nX], t[nX:], float(lam[0] / lam[-1])


def run(data: AXYBMultiData, options: Any, backend: str) -> SolverOutput:
    """``axyb-multi``: each connected component from its null vector and its translation least
    squares (module docstring)."""
    from handeye.checks.self_check import rotation_block_figures

    if data.camera_scale_unknown:
        return _unknown_scales(data, options, backend)
    RX, RY = np.empty((data.nX, 3, 3)), np.empty((data.nY, 3, 3))
    tX, tY = np.empty((data.nX, 3)), np.empty((data.nY, 3))
    components, blocks_figures, warnings = [], {}, []
    for c in data.components:
        xs, ys = np.asarray(c.x), np.asarray(c.y)
        alone = data.subset(c.observations)  # its X's and Y's numbered from 0, in the order of c.x, c.y
        A, B, x, y = alone.A, alone.B, alone.x_index, alone.y_index
        what = data.component_names(c)
        R, M, figures = component_rotations(A[:, :3, :3], B[:, :3, :3], x, y, len(xs), len(ys), what)
        RX[xs], RY[ys] = R[:len(xs)], R[len(xs):]
        tX[xs], tY[ys], rcond = component_translations(A, B, RX[xs], RY[ys], x, y, what)
        for kind, ids, Ms in (("X", c.x, M[:len(xs)]), ("Y", c.y, M[len(xs):])):
            blocks_figures.update({f"{kind}[{k}]": rotation_block_figures(Mk) for k, Mk in zip(ids, Ms)})
        components.append({"X": [data.x_names[k] for k in c.x], "Y": [data.y_names[k] for k in c.y],
                           "observations": len(c.observations), **figures, "translation_rcond": rcond})
        if figures["rotation_gap"] < WEAK_GAP:
            warnings.append(
                f"kron-lstsq: the observations barely determine the rotations of {what}: the null direction of "
                f"their stacked rotation system stands out by a factor {figures['rotation_gap']:.2g} only "
                f"(< {WEAK_GAP:g}); record robot poses that rotate about several axes for every camera and target")
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=Status.OPTIMAL,
        diagnostics={"components": components, "rotation_blocks": blocks_figures, "warnings": warnings},
    )


def _unknown_scales(data: AXYBMultiData, options: Any, backend: str) -> SolverOutput:
    """Cameras known only up to their own scales (`handeye.estimation.camera_scales`): the rotations from
    the rotation rows, which do not see the scales (the data with every translation zero), then
    the translations and the cameras' scales by one linear least squares given them."""
    from handeye.estimation import camera_scale, camera_scales

    rotations = run(camera_scale.rotation_only(data), options, backend)
    groups, names = data.camera_scale_groups
    poses, _, figures = camera_scales.translations_and_scales(
        data.pose_model, (*rotations.unknowns["X"], *rotations.unknowns["Y"]), groups, names)
    warnings = list(rotations.diagnostics.get("warnings", [])) + camera_scales.weak_warning(figures)
    return SolverOutput(unknowns={"X": np.stack(poses[:data.nX]), "Y": np.stack(poses[data.nX:])},
                        status=rotations.status,
                        diagnostics={**rotations.diagnostics, "camera_scales": figures["camera_scales"],
                                     "camera_scales_std": figures["camera_scales_std"], "warnings": warnings})


SPEC = SolverSpec(
    name="kron-lstsq",
    problems=(PROBLEM,),
    run=run,
    summary="closed form per connected component: rotations from the null vector of the stacked Kronecker "
            "rotation rows, SVD projection, then translations by linear least squares",
    citation="Pan et al., IEEE T-ASE 2022, eq. 6, stacked over cameras and targets as Shah, J. Mech. Robot. "
             "5(3), 2013; docs/solvers/kron-lstsq.md",
    unit_invariant=True,  # rotations from rotations only, translations linear (module docstring)
    exact=True,
    camera_scale_mode=True,
)
