"""`so3-sdp` for ``axyb-multi`` (A_i X_{x_i} = Y_{y_i} B_i: several cameras and targets): the
stacked Kronecker cost minimised under exact SO(3) constraints, with a certificate of global
optimality, one connected component of the observation graph at a time
(`AXYBMultiData.components`: nothing ties two components, so each is its own QCQP).

Cost. Per observation i (X j, Y l) the rows of eq. 8 (Pan et al., T-ASE 2022), stacked as
kron-lstsq does for axyb-multi (`handeye.plugins.kron_lstsq.multi`), with column-major vec:

    rotation (9):    (I kron R_Ai) vec R_Xj - (R_Bi^T kron I) vec R_Yl = 0
    translation (3): R_Ai t_Xj - (t_Bi^T kron I) vec R_Yl - t_Yl = -t_Ai

(R_Y t_B = (t_B^T kron I) vec R_Y: the translation rows are linear in vec R_Y and in the
translations). beta = [r; t], r = [vec R_X0; ...; vec R_Y0; ...] (9k, k = nX + nY of the
component), t the k translations (3k). The normal equations N = H^T H, g = H^T w are summed per
observation (rotation block: `kron_lstsq.multi.rotation_normal_matrix`), per X, per Y and per
observed (X, Y) pair, without forming H (12m x 12k); the translations are eliminated in closed
form by `RotationCost.from_normal_equations` (Cholesky of N_tt, Schur complement for r), which
leaves y^T M y + rest with y = [r; 1], M (9k + 1)-square (217 for 8 cameras and 16 markers).
Translations are divided by the data's RMS translation first (``normalize``, as for ``axyb``):
the answer does not depend on the length unit.

Solve (`handeye.plugins.so3_sdp.single.solve_relaxation`, the pipeline of ``axyb``/``axxb``
for k rotations): with ``local_first`` (default) a local minimum of the QCQP (sphere least
squares, signs, Gauss-Newton on SO(3)^k) certified by `local_certificate`, one symmetric
eigenproblem of size 9k + 1; only when that certificate fails, the Shor relaxation as an SDP,
and that only up to SDP_MAX_ROTATIONS rotations: its time grows as k^6 and its memory as k^4
(~45 min and ~30 GB by extrapolation for 8 cameras and 16 markers; docs/solvers/so3-sdp.md,
"Several cameras and targets"), so a larger component whose local certificate fails gets the
same relaxation from the sparse interior-point solver of `handeye.plugins.so3_sdp.sparse`
(Schur complement of size 20k + 1; ~1 s for 24 rotations), certified as the dense SDP's, or
keeps the cheaper answer ``uncertified``. A component is
``optimal`` only when certified, the whole answer only when every component is; otherwise
``uncertified`` with the figures.

Diagnostics: ``components`` (per component its X's and Y's, observations, status and the
certificate's figures: ``certificate_path`` local / sdp, cost, lower bound, relative gap, ...),
``certified`` (every component), ``certificate_path`` (the paths taken), for the whole cell
``cost``, ``lower_bound``, ``duality_gap`` (sums over the components), ``relative_gap``,
``eigenvalue_ratio`` (their largest) and ``thresholds``; ``translation_scale``.

Cameras known only up to their own scales (``camera_scale=[names]``, `handeye.estimation.camera_scales`):
the rotations from the data with every translation zero (certified as above: the rotation rows
do not see the scales), then the translations and every camera's scale by one linear least
squares; ``camera_scales`` and ``camera_scales_std`` (from that fit's residual, the rotations
held) in the diagnostics, a warning for a camera whose scale it barely determines, and a
DegenerateDataError naming a camera whose scale it does not determine.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from handeye import DegenerateDataError, InputError, SolverOutput, Status
from handeye.estimation import camera_scale, camera_scales
from handeye.estimation.rotation_cost import RotationCost
from handeye.geometry.se3 import gram, make_pose
from handeye.plugins.kron_lstsq.multi import group_sums, rotation_normal_matrix
from handeye.plugins.so3_sdp.single import SPEC as SPEC_SINGLE
from handeye.plugins.so3_sdp.single import Options, solve_relaxation
from handeye.plugins.so3_sdp.sparse import fallback as sparse_fallback

if TYPE_CHECKING:
    from handeye.problems.axyb_multi.data import AXYBMultiData

#: the problem this module solves
PROBLEM = "axyb-multi"
#: the most rotations of a component whose SDP is solved when the local certificate fails. The
#: SDP's PSD cone of size 9k + 1 makes Clarabel's KKT system dense of size (9k + 1)(9k + 2) / 2:
#: memory grows as k^4 and time as k^6 (backend clarabel on random costs, 2 busy cores: k = 4
#: 0.2 s, 6 1.8 s, 8 4.4 s, 10 13.6 s, 12 43 s and 1.9 GB; k = 24, 8 cameras and 16 markers: a
#: 2.2 GB allocation failed under a 12 GB limit, ~30 GB and ~45 min by those rates). Beyond it
#: a failed local certificate goes to the sparse solver of the same relaxation (`sparse.fallback`)
SDP_MAX_ROTATIONS = 4


def normal_equations(A: np.ndarray, B: np.ndarray, x: np.ndarray, y: np.ndarray,  # noqa: N803
                     nX: int, nY: int) -> tuple[np.ndarray, np.ndarray, float]:  # noqa: N803
    """(N, g, w^T w) of the stacked rows of one component (module docstring), N = H^T H:
    (12k, 12k), g = H^T w: (12k,), k = nX + nY, beta = [vec R_X0; ...; vec R_Y0; ...; t_X0; ...;
    t_Y0; ...]. A, B: (m, 4, 4) in the units wanted; x, y: (m,) indices 0..nX-1, 0..nY-1."""
    k, m = nX + nY, len(A)
    RA, tA, tB = A[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    N = np.zeros((12 * k, 12 * k))
    g = np.zeros(12 * k)
    N[:9 * k, :9 * k] = rotation_normal_matrix(RA, B[:, :3, :3], x, y, nX, nY)

    def rot(u: int) -> slice:
        return slice(9 * u, 9 * u + 9)

    def tra(u: int) -> slice:
        return slice(9 * k + 3 * u, 9 * k + 3 * u + 3)

    eye = np.eye(3)
    # per X: sum R_A^T R_A, sum R_A^T t_A
    GA = group_sums(gram(RA).reshape(m, 9), x, nX).reshape(nX, 3, 3)
    At = group_sums(np.einsum("mba,mb->ma", RA, tA), x, nX)
    # per Y: sum t_B t_B^T, sum t_B, sum t_B (x) t_A, sum t_A, count
    TT = group_sums((tB[:, :, None] * tB[:, None, :]).reshape(m, 9), y, nY).reshape(nY, 3, 3)
    sB = group_sums(tB, y, nY)
    BA = group_sums((tB[:, :, None] * tA[:, None, :]).reshape(m, 9), y, nY)
    sA = group_sums(tA, y, nY)
    count = np.bincount(y, minlength=nY)
    # per observed (X, Y) pair: sum R_A^T, sum t_B kron R_A
    keys, pair = np.unique(x * nY + y, return_inverse=True)
    pair = pair.ravel()
    SA = group_sums(np.swapaxes(RA, 1, 2).reshape(m, 9), pair, len(keys)).reshape(-1, 3, 3)
    TR = group_sums((tB[:, :, None, None] * RA[:, None, :, :]).reshape(m, 27), pair, len(keys)).reshape(-1, 9, 3)
    for j in range(nX):
        N[tra(j), tra(j)] = GA[j]
        g[tra(j)] = -At[j]
    for l in range(nY):  # noqa: E741
        u = nX + l
        N[rot(u), rot(u)] += np.kron(TT[l], eye)
        N[rot(u), tra(u)] = np.kron(sB[l][:, None], eye)  # sum t_B kron I
        N[tra(u), rot(u)] = N[rot(u), tra(u)].T
        N[tra(u), tra(u)] = count[l] * eye
        g[rot(u)] = BA[l]
        g[tra(u)] = sA[l]
    for p, key in enumerate(keys.tolist()):
        j, u = key // nY, nX + key % nY
        N[tra(j), tra(u)] = -SA[p]
        N[tra(u), tra(j)] = -SA[p].T
        N[rot(u), tra(j)] = -TR[p]
        N[tra(j), rot(u)] = -TR[p].T
    return N, g, float(np.einsum("mi,mi->", tA, tA))


def component_cost(data: AXYBMultiData, observations: np.ndarray, xs: tuple[int, ...], ys: tuple[int, ...],
                   scale: float) -> RotationCost:
    """The cost of one component's observations over its X's `xs` and Y's `ys` (indices of the
    data's stacks), translations divided by `scale` and minimised out: y^T M y + rest."""
    alone = data.subset(observations).scaled(scale)  # its X's and Y's numbered from 0, in the order of xs, ys
    N, g, ww = normal_equations(alone.A, alone.B, alone.x_index, alone.y_index, len(xs), len(ys))
    return RotationCost.from_normal_equations(N, g, ww, rotations=len(xs) + len(ys))


def run(data: AXYBMultiData, options: Options, backend: str) -> SolverOutput:
    """``axyb-multi``: each connected component's QCQP, certified (module docstring)."""
    if data.camera_scale_unknown:
        return _unknown_scales(data, options, backend)
    scale = data.translation_scale if options.normalize else 1.0
    RX, RY = np.empty((data.nX, 3, 3)), np.empty((data.nY, 3, 3))
    tX, tY = np.empty((data.nX, 3)), np.empty((data.nY, 3))
    components = []
    what = data.component_names
    for c in data.components:
        nX, k = len(c.x), len(c.x) + len(c.y)
        try:
            cost = component_cost(data, c.observations, c.x, c.y, scale)
        except DegenerateDataError as error:
            raise DegenerateDataError(f"so3-sdp for axyb-multi, {what(c)}: {error}") from None
        skipped = None
        if k > SDP_MAX_ROTATIONS:
            skipped = (f"{k} rotations: the SDP (a PSD cone of size {9 * k + 1}) is too large to solve in reasonable "
                       f"time and memory beyond {SDP_MAX_ROTATIONS} rotations")
            if not options.local_first:
                raise InputError(f"so3-sdp for axyb-multi: local_first=False asks for the SDP, but a component of "
                                 f"{what(c)} has {skipped}; use local_first=True (the default)")
        Rs, ts, status, figures = solve_relaxation(cost, options, backend, sdp_skipped=skipped)
        if skipped is not None and not figures["certified"]:  # the same relaxation by the sparse solver
            Rs, ts, status, figures = sparse_fallback(cost, options, Rs, figures)  # (sparse.py)
        RX[list(c.x)], RY[list(c.y)] = Rs[:nX], Rs[nX:]
        tX[list(c.x)], tY[list(c.y)] = ts[:nX], ts[nX:]
        components.append({"X": [data.x_names[j] for j in c.x], "Y": [data.y_names[j] for j in c.y],
                           "observations": len(c.observations), "status": status.value, **figures})
    certified = all(c["certified"] for c in components)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX * scale), "Y": make_pose(RY, tY * scale)},
        status=Status.OPTIMAL if certified else Status.UNCERTIFIED,
        diagnostics={"components": components, "certified": certified,
                     "certificate_path": sorted({c["certificate_path"] for c in components}),
                     # the whole cell: costs and bounds add over the components, ratios and gaps their worst
                     **{key: float(sum(c[key] for c in components)) for key in ("cost", "lower_bound", "duality_gap")},
                     **{key: float(max(c[key] for c in components)) for key in ("relative_gap", "eigenvalue_ratio")},
                     "thresholds": components[0]["thresholds"], "translation_scale": scale},
    )


def _unknown_scales(data: AXYBMultiData, options: Options, backend: str) -> SolverOutput:
    """Cameras known only up to their own scales (`handeye.estimation.camera_scales`): the rotations
    certified on the rotation rows alone (every translation zero), then the translations and
    the cameras' scales by one linear least squares given them."""
    rotations = run(camera_scale.rotation_only(data), options, backend)
    groups, names = data.camera_scale_groups
    poses, _, figures = camera_scales.translations_and_scales(
        data.pose_model, (*rotations.unknowns["X"], *rotations.unknowns["Y"]), groups, names)
    return SolverOutput(unknowns={"X": np.stack(poses[:data.nX]), "Y": np.stack(poses[data.nX:])},
                        status=rotations.status,
                        diagnostics={**rotations.diagnostics, **{k: figures[k] for k in ("camera_scales",
                                                                                         "camera_scales_std")},
                                     "warnings": [*rotations.diagnostics.get("warnings", []),
                                                  *camera_scales.weak_warning(figures)],
                                     "formulation": "rotations from the rotation rows alone (the cameras' scales "
                                                    "unknown), then translations and scales by linear least squares"})


SPEC = dataclasses.replace(
    SPEC_SINGLE,
    problems=(PROBLEM,),
    run=run,
    summary="the stacked Kronecker cost of a cell of several cameras and targets under exact SO(3) constraints, per "
            "connected component: local minimum with optimality certificate (the tight SDP relaxation when that fails: "
            f"dense up to {SDP_MAX_ROTATIONS} rotations, a sparse interior point above)",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8, stacked over cameras and targets as Shah, J. Mech. Robot. 5(3), "
             "2013; relaxation and certificate as in Briales & Gonzalez-Jimenez, CVPR 2017, and Rosen et al., IJRR 2019",
    camera_scale_mode=True,
)
