"""`kron-lstsq` for the problems of one pose per unknown: closed-form least squares on a Kronecker
system. Problems ``axyb``, ``axxb``, ``axbycz`` (``axyb-multi``: `handeye.plugins.kron_lstsq.multi`).

``axyb`` (eq. 8): beta = argmin |H beta - w| (the optimum of the paper's eq. 14, without an SDP
solver), R_X and R_Y projected onto SO(3) by SVD (det +1), then t_X, t_Y re-solved by least
squares given the rotations (eqs. 20-21).

``axxb`` (A_i X = X B_i, docs/solvers/kron-lstsq.md): the rotation rows (R_B kron R_A - I) r = 0
are homogeneous, so plain least squares gets the scale of r = vec R_X from the translation rows
alone, and is singular when all motions rotate about one common point (t_Ai = (I - R_Ai) u: a
camera rotating about its own centre). Instead: minimise |H beta - w|^2 subject to |r|^2 = 3
(the squared Frobenius norm of every rotation), with t_X minimised out in closed form
(`handeye.estimation.rotation_cost`), a trust-region subproblem on the sphere solved exactly
(`handeye.estimation.trust_region`); then R_X = the SVD projection of r or of -r, whichever costs less (the
sign is free where the translations carry no scale), and t_X re-solved given R_X
(`solve_translation`).

``axbycz`` (A_i X B_i = Y C_i Z, docs/solvers/kron-lstsq.md): the lifted Kronecker system of
`handeye.problems.axbycz.kronecker` (X linear, Y and Z through their products), whose rotation
rows are homogeneous like those of AX = XB: minimise |H beta - w|^2 subject to |r|^2 = 12 (r the
lifted rotation unknowns; the translation-side unknowns minimised out), exactly as a trust-region
subproblem; R_X from r, R_Y and R_Z from the nearest rank-one factors of the lifted products, SVD
projection, then the translations by least squares given the rotations (Wu et al. 2016, eq. 38).
Needs at least 10 triples with both robots moving (``simulate_options`` protocol "free").

With ``normalize=True`` (default) translations are divided by the data's RMS translation before
the system is built, which balances the rotation and translation rows and makes the answer
independent of the length unit.

Planar mode (a robot whose rotations share one axis; `handeye.problems.planar`, docs/planar.md):
the translation component the user gave (t_X . b = tz_X, or t_Y . a = tz_Y) is substituted into
the linear system exactly (beta = z0 + T y, `planar.fixed_substitution`), and each rotation block
gets the rows M c = b (weight sqrt(m), as many as the pairs): R_X maps the camera's rotation axis
c to the robot's b, which holds exactly for the true rotation and fixes what the rotation rows
cannot when all rotations share one axis (the scale of M along the axis, and for AX=XB the
overall scale, so no sphere constraint is needed). Then the SVD projection as usual, and the
translations by least squares given the rotations with the same component fixed.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status
from handeye.estimation.kronecker import reduce_normal_equations
from handeye.estimation.rotation_cost import (
    RotationCost,
    signed_blocks,
    signed_rotations,
    sphere_least_squares,
)
from handeye.geometry import so3_fast
from handeye.geometry.se3 import make_pose, project_to_so3
from handeye.problems import planar as planar_mode
from handeye.problems.axxb import AXXBData, solve_translation
from handeye.problems.axyb import AXYBData, solve_translations, split_beta


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by the data's RMS translation first (see module docstring)."""

    normalize: bool = True


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    if data.planar is not None:
        return _run_planar(data, options)
    system = data.kronecker(data.translation_scale if options.normalize else 1.0)
    MX, MY, _, _ = split_beta(system.least_squares())
    (RX, RY), flipped = signed_blocks(system, MX, MY)
    tX, tY = solve_translations(data, RX, RY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=Status.OPTIMAL,
        diagnostics={"residual_eq8": system.rest, "sigma_min_R1": system.smallest_singular_value(),
                     "sign_flipped": flipped},
    )


def run_axxb(data: AXXBData, options: Options, backend: str) -> SolverOutput:
    """``axxb``: least squares on the sphere |vec R_X|^2 = 3 (module docstring)."""
    if data.planar is not None:
        return _run_planar(data, options)
    scale = data.translation_scale if options.normalize else 1.0
    cost = RotationCost.from_normal_equations(*data.normal_equations(scale), rotations=1)
    trs = sphere_least_squares(cost)
    (RX,), flipped = signed_rotations(cost, trs.x)
    d = trs.eigenvalues
    return SolverOutput(
        unknowns={"X": make_pose(RX, solve_translation(data, RX))},
        status=Status.OPTIMAL,
        diagnostics={
            "cost": trs.value + cost.quadratic[2] + cost.rest,  # |H beta - w|^2 at r (normalised units)
            "multiplier": trs.multiplier,
            "hard_case": trs.hard_case,
            "sign_flipped": flipped,
            # smallest / largest eigenvalue of the reduced normal matrix of r: ~1e-16 when plain
            # least squares is singular (all motions about one point)
            "relative_lambda_min": float(d[0] / d[-1]) if d[-1] > 0 else 0.0,
            "translation_scale": scale,
        },
    )


def run_axbycz(data: Any, options: Options, backend: str) -> SolverOutput:
    """``axbycz``: least squares of the lifted system on |r|^2 = 12 (module docstring)."""
    from handeye.checks.self_check import rotation_block_figures
    from handeye.problems.axbycz import kronecker as lifted

    lifted.check_triples(data, "kron-lstsq")
    gap = lifted.check_rotations(data, "kron-lstsq")
    scale = data.translation_scale if options.normalize else 1.0
    cost = lifted.lifted_cost(data, scale)
    trs = lifted.sphere_least_squares(cost)
    estimate = lifted.extract_rotations(trs.x, cost)
    RX, RY, RZ = estimate.rotations
    tX, tY, tZ = lifted.solve_translations(data, RX, RY, RZ)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY), "Z": make_pose(RZ, tZ)},
        status=Status.OPTIMAL,
        diagnostics={
            "cost": trs.value + cost.c,  # |H beta - w|^2 at r, tau at its optimum (normalised units)
            "multiplier": trs.multiplier,
            "hard_case": trs.hard_case,
            "sign_flipped": estimate.flipped,
            "rank_one_ratio": estimate.rank_one_ratio,
            "rotation_gap": gap,
            "translation_rank": cost.translation_rank,
            "translation_scale": scale,
            "rotation_blocks": {name: rotation_block_figures(M) for name, M in zip("XYZ", estimate.blocks)},
            "warnings": lifted.weak_rotations(gap, "kron-lstsq"),
        },
    )


def _run_planar(data: AXYBData | AXXBData, options: Options) -> SolverOutput:
    """Planar mode, both problems (module docstring)."""
    planar = data.planar
    scale = data.translation_scale if options.normalize else 1.0
    N, g, ww = data.normal_equations(scale)
    n, weight = len(g), float(np.sqrt(data.m))
    if isinstance(data, AXXBData):
        blocks = [(0, planar.axis, *data.rotation_vectors)]  # (start of the block in beta, robot axis, motions)
        index = 9  # t_X in beta = [vec R_X; t_X]
    else:
        moving, fixed = so3_fast.consecutive_logs(data.A), so3_fast.consecutive_logs(data.A, moving=False)
        axis_X = planar.axis if planar.unknown == "X" else planar_mode.main_axis(moving)[0]
        axis_Y = planar.axis if planar.unknown == "Y" else planar_mode.main_axis(fixed)[0]
        blocks = [(0, axis_X, moving, so3_fast.consecutive_logs(data.B)),
                  (9, axis_Y, fixed, so3_fast.consecutive_logs(data.B, moving=False))]
        index = 18 if planar.unknown == "X" else 21  # beta = [vec R_X; vec R_Y; t_X; t_Y]
    for start, b, robot, camera in blocks:
        c = planar_mode.camera_axis(robot, camera, b)
        if c is None:
            continue  # the camera does not rotate: the rotation rows say so, this row would not help
        E, d = planar_mode.axis_rows(c, b, weight, n, start)
        N, g, ww = N + E.T @ E, g + E.T @ d, ww + float(d @ d)
    T, z0 = planar_mode.fixed_substitution(n, index, planar.axis, planar.value / scale)
    Nz0 = N @ z0
    system = reduce_normal_equations(T.T @ N @ T, T.T @ (g - Nz0), ww - 2.0 * float(g @ z0) + float(z0 @ Nz0))
    beta = z0 + T @ system.least_squares()
    diagnostics = {"residual": system.rest, "sigma_min_R1": system.smallest_singular_value(),
                   "planar": planar.figures(), "warnings": [planar.warning()]}
    if isinstance(data, AXXBData):
        RX = project_to_so3(beta[:9].reshape(3, 3, order="F"))
        unknowns = {"X": make_pose(RX, planar_mode.axxb_translation(data, RX, planar))}
    else:
        MX, MY, _, _ = split_beta(beta)
        RX, RY = project_to_so3(MX), project_to_so3(MY)
        tX, tY = planar_mode.axyb_translations(data, RX, RY, planar)
        unknowns = {"X": make_pose(RX, tX), "Y": make_pose(RY, tY)}
    return SolverOutput(unknowns=unknowns, status=Status.OPTIMAL, diagnostics=diagnostics)


SPEC = SolverSpec(
    name="kron-lstsq",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="closed-form linear least squares on all pose pairs (Kronecker form), SVD projection",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8; cf. Li, Wang, Wu, Int. J. Phys. Sci. 2010",
    unit_invariant=lambda options: options.normalize,  # not with normalize=False (module docstring)
    planar_mode=True,
)

#: ``axxb``: its own run (the sphere constraint), the same options.
SPEC_AXXB = dataclasses.replace(
    SPEC,
    problems=("axxb",),
    run=run_axxb,
    summary="least squares on the Kronecker system of AX=XB with |vec R_X|^2 = 3 (exact "
            "trust-region solution), SVD projection",
    citation="Kronecker form as Andreff, Horaud, Espiau, 3DIM 1999; the scale constraint and "
             "its trust-region solution: docs/solvers/kron-lstsq.md",
)


#: ``axbycz``: the lifted system (problems/axbycz/kronecker.py), the same options.
SPEC_AXBYCZ = dataclasses.replace(
    SPEC,
    problems=("axbycz",),
    run=run_axbycz,
    summary="least squares on the lifted Kronecker system of AXB=YCZ with |r|^2 = 12 (exact "
            "trust-region solution), rank-one extraction of R_Y, R_Z, SVD projection; >= 10 triples",
    citation="lifting as Wu et al., IEEE T-RO 32(2):413-428, 2016 (rotation matrices instead of "
             "quaternions); the scale constraint: docs/solvers/kron-lstsq.md",
    planar_mode=False,
    simulate_options={"protocol": "free"},
)
