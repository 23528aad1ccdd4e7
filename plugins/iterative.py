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
brackets are read as skew matrices of the columns vec_k(R_X,init) and vec_k(R_Y,init R_B)
(`linearised_system` builds it, for the tests). Each step is the least-squares solution of the
stacked system, delta = (F~^T F~)^-1 F~^T q~ (eq. 18), and the rotations are updated by the
exponential map (eq. 19): R <- exp([d]) R, which keeps them exactly in SO(3). Each step minimises
the linearised rotation cost

    C(R_X, R_Y) = sum_i |R_Ai R_X - R_Y R_Bi|_F^2,

so the iteration is Gauss-Newton on C; it stops when |delta| < tol.

Cost per iteration. F~^T F~ (6x6) and F~^T q~ (6) are not formed from the 9m x 6 matrix: they are
exact closed forms in three sums over the pairs computed once (`RotationSums`, O(m)),

    K = sum_i R_Ai kron R_Bi  (9x9; row-major vec: vec(sum_i R_Ai M R_Bi^T) = K vec(M)),
    G_A = sum_i R_Ai^T R_Ai,   G_B = sum_i R_Bi R_Bi^T,

with K(M) = sum R_Ai M R_Bi^T, L(M) = sum R_Ai^T M R_Bi (= K^T vec M), vee(P) the axial vector of
the skew part of P, and tr([w] P) = -2 w . vee(P), [a]^T G [b] traced = a^T (tr G I - G) b:

    F~^T F~ = [[tr(G_A) I - G_A,             N_XY                              ],
               [N_XY^T,                      R_Y0 (tr(G_B) I - G_B) R_Y0^T     ]],
    N_XY[k, l] = -2 vee(L([e_l] R_Y0) R_X0^T)_k,
    F~^T q~ = [2 vee(L(R_Y0) R_X0^T); 2 vee(K(R_X0) R_Y0^T)].

(No orthogonality of the data's R_A, R_B is assumed, only of the iterate.) So an iteration costs
O(1) whatever m; only the rotation cost C reported in the diagnostics is evaluated pair by pair.
tests/plugins/test_iterative.py checks these forms against the explicit stacked F~ of eq. 17.

Initial value (`init`): ``"kron-lstsq"`` (default) starts from the closed-form least-squares
rotations of eq. 8 (normalised translations, SVD projection, as the `kron-lstsq` solver), from
which a few steps reach the minimum of C. ``"identity"`` is the paper's start R_X0 = R_Y0 = I; on
general data (large rotations) Gauss-Newton from there wanders, hits max_iter, or stops in a
local minimum of C. Such runs are reported with status ``not_converged`` (never ``optimal``):

- ``max_iter``: |delta| never fell below tol;
- ``diverged``: the iterate or cost became non-finite;
- ``local_minimum``: the steps converged but C at the end exceeds the reference cost by more than
  1e-6 relative (+ 1e-12 m absolute). The reference is the cost of the minimum reached from the
  kron-lstsq start (with init="identity" that run is made too; it costs O(1) per iteration), or
  the cost at the kron-lstsq rotations themselves if that run does not converge; the global
  minimum of C is at most either, so a higher end point is not it.

Diagnostics: init, iterations, step_norm (last |delta|), converged, reason,
rotation_cost_initial / _final / _reference, cost_history (C after each iteration).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.framework.options import check_choice, check_int, check_positive
from handeye.geometry.se3 import make_pose, project_to_so3, skew, vee
from handeye.problems.axyb import AXYBData, solve_translations, split_beta

INITS = ("kron-lstsq", "identity")
#: relative margin by which the final cost may exceed the reference before the end point is
#: declared a local minimum (plus LOCAL_MINIMUM_ABS per pair, for noise-free data where C ~ 0)
LOCAL_MINIMUM_MARGIN = 1e-6
LOCAL_MINIMUM_ABS = 1e-12
_E = np.eye(3)


@dataclasses.dataclass(frozen=True)
class Options:
    init: str = "kron-lstsq"
    tol: float = 1e-12
    max_iter: int = 100

    def __post_init__(self) -> None:
        check_choice("init", self.init, INITS)
        check_positive("tol", self.tol)
        check_int("max_iter", self.max_iter, minimum=1)


@dataclasses.dataclass(frozen=True)
class RotationSums:
    """The O(m) sums that give eq. 18's normal equations in closed form (module docstring).

    K: (9, 9) = sum_i R_Ai kron R_Bi; NXX: (3, 3) = tr(G_A) I - G_A; NB: (3, 3) = tr(G_B) I - G_B.
    """

    K: np.ndarray
    NXX: np.ndarray
    NB: np.ndarray

    @classmethod
    def of(cls, RA: np.ndarray, RB: np.ndarray) -> RotationSums:
        """From RA, RB: (m, 3, 3)."""
        RA, RB = np.ascontiguousarray(RA), np.ascontiguousarray(RB)
        K = (RA.reshape(-1, 9).T @ RB.reshape(-1, 9)).reshape(3, 3, 3, 3).transpose(0, 2, 1, 3).reshape(9, 9)
        RA2, RBt2 = RA.reshape(-1, 3), np.swapaxes(RB, 1, 2).reshape(-1, 3)
        GA, GB = RA2.T @ RA2, RBt2.T @ RBt2  # sum R_A^T R_A, sum R_B R_B^T
        return cls(K=K, NXX=np.trace(GA) * _E - GA, NB=np.trace(GB) * _E - GB)


def kron_rotations(data: AXYBData) -> tuple[np.ndarray, np.ndarray]:
    """R_X, R_Y: (3, 3) of the closed-form least squares on eq. 8 (normalised, SVD-projected)."""
    MX, MY, _, _ = split_beta(data.kronecker(data.translation_scale).least_squares())
    RX, RY = project_to_so3(np.stack([MX, MY]))
    return RX, RY


def rotation_cost(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray, RY: np.ndarray) -> float:
    """C = sum_i |R_Ai R_X - R_Y R_Bi|_F^2 for RA, RB: (m, 3, 3), evaluated pair by pair."""
    return float(np.sum((RA @ RX - RY @ RB) ** 2))


def linearised_system(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray,
                      RY: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stacked F: (9m, 6) and q: (9m,) of eq. 17 at (RX, RY), rows ordered (pair, column k, row).

    The explicit system (the solver uses its closed-form normal equations, `normal_equations`).
    """
    m = len(RA)
    YB = RY @ RB  # (m, 3, 3), columns e_k
    F = np.empty((m, 3, 3, 6))
    F[..., :3] = -np.einsum("nij,kjl->nkil", RA, skew(RX.T))  # -R_A [c_k]
    F[..., 3:] = skew(np.swapaxes(YB, 1, 2))  # [e_k]
    q = np.swapaxes(YB - RA @ RX, 1, 2)  # E[:, k] as rows (n, k, i)
    return F.reshape(9 * m, 6), q.reshape(9 * m)


_SKEW_E = skew(_E)  # [e_l], l = 1..3: (3, 3, 3)


def normal_equations(sums: RotationSums, RX: np.ndarray, RY: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """F~^T F~: (6, 6) and F~^T q~: (6,) of eq. 18 at the iterate (RX, RY), in O(1) (module docstring)."""
    K = sums.K
    Z = np.concatenate([RY[None], _SKEW_E @ RY])  # R_Y, [e_l] R_Y: (4, 3, 3)
    L = (Z.reshape(4, 9) @ K).reshape(4, 3, 3)  # L(.) = sum R_A^T (.) R_B of each
    KX = (K @ RX.ravel()).reshape(3, 3)  # sum R_A R_X R_B^T
    v = vee(np.concatenate([L @ RX.T, (KX @ RY.T)[None]]))  # (5, 3)
    N = np.empty((6, 6))
    N[:3, :3] = sums.NXX
    N[:3, 3:] = -2.0 * v[1:4].T  # column l: -2 vee(L([e_l] R_Y) R_X^T)
    N[3:, :3] = N[:3, 3:].T
    N[3:, 3:] = RY @ sums.NB @ RY.T
    return N, 2.0 * np.concatenate([v[0], v[4]])


def exp_so3(w: np.ndarray) -> np.ndarray:
    """exp([w]): (3, 3) for one rotation vector w: (3,) (Rodrigues, Taylor terms for tiny angles)."""
    theta2 = float(w @ w)
    W = skew(w)
    if theta2 < 1e-12:
        a, b = 1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0
    else:
        theta = np.sqrt(theta2)
        a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / theta2
    return _E + a * W + b * (W @ W)


def step(N: np.ndarray, g: np.ndarray) -> np.ndarray:
    """delta = N^-1 g (eq. 18); least squares if N is singular."""
    try:
        return np.linalg.solve(N, g)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(N, g, rcond=None)[0]


def iterate_rotations(RA: np.ndarray, RB: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                      tol: float, max_iter: int, sums: RotationSums | None = None) -> dict:
    """Gauss-Newton of eqs. 17-19 from (RX, RY); returns the last iterate and its history."""
    sums = RotationSums.of(RA, RB) if sums is None else sums
    costs = [rotation_cost(RA, RB, RX, RY)]
    step_norm = float("nan")
    converged = diverged = False
    iterations = 0
    for iterations in range(1, max_iter + 1):
        delta = step(*normal_equations(sums, RX, RY))
        step_norm = float(np.linalg.norm(delta))
        if not np.isfinite(step_norm):
            diverged = True
            break
        RX, RY = exp_so3(delta[:3]) @ RX, exp_so3(delta[3:]) @ RY  # eq. 19
        costs.append(rotation_cost(RA, RB, RX, RY))
        if step_norm < tol:
            converged = True
            break
    return {"RX": RX, "RY": RY, "costs": costs, "step": step_norm, "iterations": iterations,
            "converged": converged, "diverged": diverged}


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    RA, RB = data.A[:, :3, :3], data.B[:, :3, :3]
    sums = RotationSums.of(RA, RB)
    tol, max_iter = float(options.tol), int(options.max_iter)
    RX_ref, RY_ref = kron_rotations(data)
    from_kron = iterate_rotations(RA, RB, RX_ref, RY_ref, tol, max_iter, sums)
    reference = from_kron["costs"][-1] if from_kron["converged"] else from_kron["costs"][0]
    if options.init == "kron-lstsq":
        it = from_kron
    else:
        it = iterate_rotations(RA, RB, np.eye(3), np.eye(3), tol, max_iter, sums)
    final = it["costs"][-1]
    if it["diverged"]:
        reason = "diverged"
    elif not it["converged"]:
        reason = "max_iter"
    elif final > reference * (1 + LOCAL_MINIMUM_MARGIN) + LOCAL_MINIMUM_ABS * data.m:
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
            f"iterations, last step {it['step']:.2e}, rotation cost {final:.3e} vs reference "
            f"{reference:.3e}); the result is the last iterate, do not use it"
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
    summary="Gauss-Newton on the rotations by exp-map linearisation, then translations by least squares",
    citation="Pan et al., IEEE T-ASE 2022, Sec. III.B (after Wang et al.)",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
