"""`kron-lstsq`: closed-form least squares on a Kronecker system. Problems ``axyb`` and ``axxb``.

``axyb`` (eq. 8): beta = argmin |H beta - w| (the optimum of the paper's eq. 14, without an SDP
solver), R_X and R_Y projected onto SO(3) by SVD (det +1), then t_X, t_Y re-solved by least
squares given the rotations (eqs. 20-21).

``axxb`` (A_i X = X B_i, docs/solvers/kron-lstsq.md): the rotation rows (R_B kron R_A - I) r = 0
are homogeneous, so plain least squares gets the scale of r = vec R_X from the translation rows
alone, and is singular when all motions rotate about one common point (t_Ai = (I - R_Ai) u: a
camera rotating about its own centre). Instead: minimise |H beta - w|^2 subject to |r|^2 = 3
(the squared Frobenius norm of every rotation), with t_X minimised out in closed form
(`handeye.rotation_cost`), a trust-region subproblem on the sphere solved exactly
(`handeye.trust_region`); then R_X = the SVD projection of r or of -r, whichever costs less (the
sign is free where the translations carry no scale), and t_X re-solved given R_X
(`solve_translation`).

With ``normalize=True`` (default) translations are divided by the data's RMS translation before
the system is built, which balances the rotation and translation rows and makes the answer
independent of the length unit.
"""

from __future__ import annotations

import dataclasses

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.problems.axxb import AXXBData, solve_translation
from handeye.problems.axyb import AXYBData, solve_translations, split_beta
from handeye.rotation_cost import RotationCost, signed_rotations, sphere_least_squares
from handeye.se3 import make_pose, project_to_so3


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by the data's RMS translation first (see module docstring)."""

    normalize: bool = True


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    system = data.kronecker(data.translation_scale if options.normalize else 1.0)
    MX, MY, _, _ = split_beta(system.least_squares())
    RX, RY = project_to_so3(MX), project_to_so3(MY)
    tX, tY = solve_translations(data, RX, RY)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=Status.OPTIMAL,
        diagnostics={"residual_eq8": system.rest, "sigma_min_R1": system.smallest_singular_value()},
    )


def run_axxb(data: AXXBData, options: Options, backend: str) -> SolverOutput:
    """``axxb``: least squares on the sphere |vec R_X|^2 = 3 (module docstring)."""
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


SPEC = SolverSpec(
    name="kron-lstsq",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="closed-form linear least squares on all pose pairs (Kronecker form), SVD projection",
    citation="Pan et al., IEEE T-ASE 2022, eq. 8; cf. Li, Wang, Wu, Int. J. Phys. Sci. 2010",
    unit_invariant=lambda options: options.normalize,  # not with normalize=False (module docstring)
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


@hookimpl
def register_solvers(register):
    register(SPEC)
    register(SPEC_AXXB)
