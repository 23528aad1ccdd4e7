"""`iterative`: the paper's iterative Lie-algebra method (Sec. III.B, eqs. 15-21, after Wang et al.).

Rotations first, by repeated linearisation (Gauss-Newton on SO(3) x SO(3)), then translations by
linear least squares (eqs. 20-21, `solve_translations`).

Linearisation (our derivation from eq. 16; the typesetting of F in eq. 17 is garbled). Write the
unknown rotations as R_X = exp([d_X]) R_X0 ~ (I + [d_X]) R_X0 and R_Y ~ (I + [d_Y]) R_Y0 around the
current iterate. Substituting into R_A R_X = R_Y R_B and dropping second-order terms gives eq. 16,

    R_A [d_X] R_X0 - [d_Y] R_Y0 R_B = R_Y0 R_B - R_A R_X0 =: E.

Column k of this 3x3 equation, with c_k = column k of R_X0 and e_k = column k of R_Y0 R_B, is
(using [a] b = -[b] a)

    -R_A [c_k] d_X + [e_k] d_Y = E[:, k],        k = 1, 2, 3,

so per pair F = [[-R_A [c_1], [e_1]], [-R_A [c_2], [e_2]], [-R_A [c_3], [e_3]]]: (9, 6) and
q = vec(E) (column-major), delta = [d_X; d_Y] (eq. 17). This matches the paper's F once its
brackets are read as skew matrices of the columns vec_k(R_X,init) and vec_k(R_Y,init R_B). The
blocks of all m pairs are stacked (9m x 6, built at once with einsum, no loop over pairs), delta
is the least-squares solution by the normal equations (eq. 18) and
the rotations are updated by the exponential map (eq. 19): R <- exp([d]) R, which keeps them
exactly in SO(3). Each step minimises the linearised rotation cost

    C(R_X, R_Y) = sum_i |R_Ai R_X - R_Y R_Bi|_F^2,

so the iteration is Gauss-Newton on C; it stops when |delta| < tol.

Initial value (`init`): ``"kron-lstsq"`` (default) starts from the closed-form least-squares
rotations of eq. 8 (normalised translations, SVD projection, as the `kron-lstsq` solver), from
which a few steps reach the minimum of C. ``"identity"`` is the paper's start R_X0 = R_Y0 = I; on
general data (large rotations) Gauss-Newton from there wanders, hits max_iter, or stops in a
local minimum of C. Such runs are reported with status ``not_converged`` (never ``optimal``):

- ``max_iter``: |delta| never fell below tol;
- ``diverged``: the iterate or cost became non-finite;
- ``local_minimum``: the steps converged but C at the end exceeds C at the kron-lstsq rotations
  (by more than 1e-6 relative): the global minimum of C is at most that value, so this point
  is not it. (C at the kron-lstsq rotations is always computed, as this reference.)

Diagnostics: iterations, step_norm (last |delta|), rotation_cost_initial / _final / _reference,
cost_history, converged, reason, init.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import InputError
from handeye.options import check_choice, check_positive
from handeye.problems.axyb import AXYBData, solve_translations, split_beta
from handeye.se3 import make_pose, project_to_so3, skew, so3_exp

INITS = ("kron-lstsq", "identity")
#: relative margin by which the final cost may exceed the kron-lstsq reference before the end
#: point is declared a local minimum
LOCAL_MINIMUM_MARGIN = 1e-6


@dataclasses.dataclass(frozen=True)
class Options:
    init: str = "kron-lstsq"
    tol: float = 1e-12
    max_iter: int = 100

    def __post_init__(self) -> None:
        check_choice("init", self.init, INITS)
        check_positive("tol", self.tol)
        check_positive("max_iter", self.max_iter)
        if int(self.max_iter) != self.max_iter:
            raise InputError(f"option max_iter={self.max_iter!r} must be a positive integer")


def kron_rotations(data: AXYBData) -> tuple[np.ndarray, np.ndarray]:
    """R_X, R_Y: (3, 3) of the closed-form least squares on eq. 8 (normalised, SVD-projected)."""
    MX, MY, _, _ = split_beta(data.scaled(data.translation_scale).kronecker_system.least_squares())
    return project_to_so3(MX), project_to_so3(MY)


def rotation_cost(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray, RY: np.ndarray) -> float:
    """C = sum_i |R_Ai R_X - R_Y R_Bi|_F^2 for RA, RB: (m, 3, 3)."""
    return float(np.sum((RA @ RX - RY @ RB) ** 2))


def linearised_system(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray,
                      RY: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stacked F: (9m, 6) and q: (9m,) of eq. 17 at the iterate (RX, RY), rows ordered (pair, column k, row)."""
    m = len(RA)
    YB = RY @ RB  # (m, 3, 3), columns e_k
    F = np.empty((m, 3, 3, 6))
    F[..., :3] = -np.einsum("nij,kjl->nkil", RA, skew(RX.T))  # -R_A [c_k]
    F[..., 3:] = skew(np.swapaxes(YB, 1, 2))  # [e_k]
    q = np.swapaxes(YB - RA @ RX, 1, 2)  # E[:, k] as rows (n, k, i)
    return F.reshape(9 * m, 6), q.reshape(9 * m)


def gauss_newton_step(F: np.ndarray, q: np.ndarray) -> np.ndarray:
    """delta = (F^T F)^-1 F^T q (eq. 18) for F: (9m, 6), q: (9m,).

    The 6x6 normal equations are summed by einsum (no threaded BLAS call on the tall F, which is
    erratic on a loaded machine); lstsq on the 6x6 system if it is singular.
    """
    N, g = np.einsum("na,nb->ab", F, F), np.einsum("na,n->a", F, q)
    try:
        return np.linalg.solve(N, g)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(N, g, rcond=None)[0]


def iterate_rotations(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                      tol: float, max_iter: int) -> dict:
    """Gauss-Newton of eqs. 17-19 from (RX, RY); returns the last iterate and its history."""
    costs = [rotation_cost(RA, RB, RX, RY)]
    step = float("nan")
    converged = diverged = False
    iterations = 0
    for iterations in range(1, max_iter + 1):
        delta = gauss_newton_step(*linearised_system(RA, RB, RX, RY))
        step = float(np.linalg.norm(delta))
        if not np.isfinite(step):
            diverged = True
            break
        RX_new, RY_new = so3_exp(delta[:3]) @ RX, so3_exp(delta[3:]) @ RY  # eq. 19
        cost = rotation_cost(RA, RB, RX_new, RY_new)
        if not np.isfinite(cost):
            diverged = True
            break
        RX, RY = RX_new, RY_new
        costs.append(cost)
        if step < tol:
            converged = True
            break
    return {"RX": RX, "RY": RY, "costs": costs, "step": step, "iterations": iterations,
            "converged": converged, "diverged": diverged}


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    RA, RB = data.A[:, :3, :3], data.B[:, :3, :3]
    RX_ref, RY_ref = kron_rotations(data)
    reference = rotation_cost(RA, RB, RX_ref, RY_ref)
    if options.init == "kron-lstsq":
        RX0, RY0 = RX_ref, RY_ref
    else:
        RX0 = RY0 = np.eye(3)
    it = iterate_rotations(RA, RB, RX0, RY0, float(options.tol), int(options.max_iter))
    final = it["costs"][-1]
    if it["diverged"]:
        reason = "diverged"
    elif not it["converged"]:
        reason = "max_iter"
    elif final > reference * (1 + LOCAL_MINIMUM_MARGIN) + 1e-12 * data.m:
        reason = "local_minimum"
    else:
        reason = "converged"
    status = Status.OPTIMAL if reason == "converged" else Status.NOT_CONVERGED
    RX, RY = it["RX"], it["RY"]
    tX, tY = solve_translations(data, RX, RY)  # eqs. 20-21
    warnings = []
    if status is Status.NOT_CONVERGED:
        warnings.append(
            f"iterative: no convergence from init={options.init!r} ({reason}: {it['iterations']} "
            f"iterations, last step {it['step']:.2e}, rotation cost {final:.3e} vs {reference:.3e} "
            "at the kron-lstsq rotations); the result is the last iterate, do not use it"
        )
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY)},
        status=status,
        diagnostics={
            "init": options.init,
            "iterations": it["iterations"],
            "step_norm": it["step"],
            "converged": it["converged"],
            "reason": reason,
            "rotation_cost_initial": it["costs"][0],
            "rotation_cost_final": final,
            "rotation_cost_reference": reference,
            "cost_history": it["costs"],
            "warnings": warnings,
        },
    )


SPEC = SolverSpec(
    name="iterative",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="Gauss-Newton on the rotations by exp-map linearisation (eqs. 15-19), then translations (eq. 21)",
    citation="Pan et al., IEEE T-ASE 2022, Sec. III.B (after Wang et al.)",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
