"""`wang`: the iterative method of Wang et al. for A_i X B_i = Y C_i Z (the paper's [22]).

J. Wang, L. Wu, M. Q.-H. Meng, H. Ren, "Towards simultaneous coordinate calibrations for
cooperative multiple robots", IROS 2014. Rotations first, by repeated linearisation
(Gauss-Newton on SO(3)^3, the paper's eqs. 15-19 with a third unknown), then translations by
linear least squares (eqs. 20-21 with a third unknown). Any data protocol (both robots moving,
or phases); the rotations need >= 4 triples (3 triples give 9 equations for 9 unknowns, solved
by several rotation triples in general).

Rotations. Around the iterate write R_X = exp([d_X]) R_X0, R_Y = exp([d_Y]) R_Y0,
R_Z = exp([d_Z]) R_Z0 and drop second-order terms of R_A R_X R_B = R_Y R_C R_Z:

    R_A [d_X] R_X0 R_B - [d_Y] R_Y0 R_C R_Z0 - R_Y0 R_C [d_Z] R_Z0 = R_Y0 R_C R_Z0 - R_A R_X0 R_B =: E.

Column k, with p_k, n_k, z_k the columns of R_X0 R_B, R_Y0 R_C R_Z0 and R_Z0 ([a] b = -[b] a):

    -R_A [p_k] d_X + [n_k] d_Y + R_Y0 R_C [z_k] d_Z = E[:, k],      k = 1, 2, 3,

9 rows and 9 unknowns per triple (`linearised_system`). Each step is the least-squares solution
over all triples, and R <- exp([d]) R keeps the iterates in SO(3) exactly. It is Gauss-Newton on

    C(R_X, R_Y, R_Z) = sum_i |R_Ai R_X R_Bi - R_Y R_Ci R_Z|_F^2,

and stops when the step |delta| = |(d_X, d_Y, d_Z)| falls below ``tol`` (status ``optimal``); after
``max_iter`` steps without that, or on a non-finite step, the status is ``not_converged`` with a
warning (the answer is the last iterate; do not use it).

Translations. Given the rotations, the translation part of A X B = Y C Z is linear:

    R_Ai t_X - t_Y - R_Y R_Ci t_Z = R_Y t_Ci - t_Ai - R_Ai R_X t_Bi      (3 rows per triple),

solved by least squares (Wu et al.'s eq. 38, `handeye.problems.axbycz.kronecker.solve_translations`,
shared with the other axbycz solvers).

Start (``init``). Gauss-Newton needs one, and from far away it stalls or stops in a local minimum
of C. ``"grid"`` (default, our own; no other solver is involved): R_Y is eliminated in closed
form, because for fixed R_X, R_Z the best R_Y is the rotation nearest to
M(R_X, R_Z) = sum_i R_Ai R_X R_Bi R_Z^T R_Ci^T, and C = 6m - 2 max_R tr(R^T M). M is a
contraction of the 3^6 tensor sum_i R_Ai (x) R_Bi (x) R_Ci (made once, O(m)) with R_X and R_Z, so
every pair (R_X, R_Z) of the 60 rotations of the icosahedral group (no rotation is more than
0.77 rad from one of them) is scored by two matrix products: first by |M|_F, then exactly
(max tr(R^T M) = sum of M's singular values, the last signed by det) for the `SCREEN` best.
Gauss-Newton runs from the `STARTS` best of those at once (stacked, in lockstep); a start that
comes within `JOIN_ANGLE` of another's iterate stops there, and the converged end point with the
lowest C is the answer. Measured on the two-arm simulator (1300 data sets, 4 to 30 triples, free
and phases, noise 0 to 0.05 rad on A, B, C): no run ended in a local minimum, where one start
alone does in 35 of 400 runs with 4 to 6 triples. Alternatively ``init`` names a registered
``axbycz`` solver (e.g. ``"fu-dq"`` on phase data) whose rotations start one run.

Data that do not determine the rotations (e.g. 2 + 2 triples of phases: each phase gives one
relative motion) raise `DegenerateDataError` when the linearised system is singular
(sigma_min / sigma_max < `SINGULAR_RATIO`); with noise they end ``not_converged`` or with a small
``sigma_ratio`` in the diagnostics (~1e-3, against ~0.07 on 30 triples).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import (
    DegenerateDataError,
    HandEyeError,
    InputError,
    shown,
)
from handeye.framework.options import check_int, check_positive
from handeye.geometry.se3 import make_pose, project_to_so3, skew, so3_exp, vee
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axbycz.kronecker import solve_translations

#: the start of ``init="grid"``: the 60 rotations of the icosahedral group
GRID = Rotation.create_group("I").as_matrix()
GRID.setflags(write=False)
#: candidates (R_X, R_Z) of the grid kept by |M|_F for the exact score, and Gauss-Newton starts
SCREEN = 32
STARTS = 8
#: fewest triples: 3 give as many rotation equations as unknowns (several solutions in general)
MIN_TRIPLES = 4
#: sigma_min / sigma_max of the last linearised system below which the rotations are not
#: determined by the data (DegenerateDataError)
SINGULAR_RATIO = 1e-8
#: a start whose three rotations come this close (rad) to those of a start that has converged,
#: or of a better-ranked one still running, stops ("joined"): both are in one basin of attraction
JOIN_ANGLE = 1e-3
GRID_INIT = "grid"
_UNDETERMINED = ("wang: these triples do not determine the rotations of X, Y and Z (smallest/largest singular "
                 "value of the linearised system {ratio:.1e}): each robot must rotate about at least two "
                 "different axes while the other moves. Record more poses")


@dataclasses.dataclass(frozen=True)
class Options:
    init: str = GRID_INIT
    tol: float = 1e-12
    max_iter: int = 100

    def __post_init__(self) -> None:
        check_positive("tol", self.tol)
        check_int("max_iter", self.max_iter, minimum=1)
        if not (isinstance(self.init, str) and self.init == GRID_INIT):
            from handeye.host.registry import get_registry

            names = [n for n in get_registry().solver_names("axbycz") if n != "wang"]
            if not isinstance(self.init, str) or self.init not in names:
                raise InputError(f"option init={shown(self.init)} is not {GRID_INIT!r} or a registered axbycz "
                                 f"solver; use one of {', '.join([GRID_INIT, *names])}")


def rotation_tensor(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray) -> np.ndarray:
    """T: (3, 3, 3, 3, 3, 3), T[a, b, c, d, e, f] = sum_i R_Ai[a, b] R_Bi[c, d] R_Ci[f, e]; then
    sum_i R_Ai R_X R_Bi R_Z^T R_Ci^T = T contracted with R_X over (b, c) and R_Z over (e, d)."""
    m = len(RA)
    AB = (RA.reshape(m, 9, 1) * RB.reshape(m, 1, 9)).reshape(m, 81)
    return (AB.T @ np.swapaxes(RC, 1, 2).reshape(m, 9)).reshape((3,) * 6)


def grid_starts(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray,
                starts: int = STARTS) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The `starts` best (R_X, R_Y, R_Z) over R_X, R_Z in `GRID`, R_Y the best rotation for them
    (module docstring), best first; RA, RB, RC: (m, 3, 3)."""
    n = len(GRID)
    T = rotation_tensor(RA, RB, RC)
    # U[n, a, d, e, f] = sum_bc X_n[b, c] T[a, b, c, d, e, f]: one (n, 9) x (9, 81) product
    U = (GRID.reshape(n, 9) @ T.transpose(1, 2, 0, 3, 4, 5).reshape(9, 81)).reshape(n, 3, 3, 3, 3)
    # M[n, k, a, f] = sum_de U[n, a, d, e, f] Z_k[e, d]: one (9n, 9) x (9, n) product
    Zt = np.swapaxes(GRID, 1, 2).reshape(n, 9)  # Z_k[e, d] at (d, e)
    M = (U.transpose(0, 1, 4, 2, 3).reshape(9 * n, 9) @ Zt.T).reshape(n, 3, 3, n)
    M = M.transpose(0, 3, 1, 2).reshape(n * n, 3, 3)
    frob = np.einsum("kij,kij->k", M, M)
    screen = np.argpartition(-frob, SCREEN)[:SCREEN]
    U_, s, Vt = np.linalg.svd(M[screen])
    d = np.sign(np.linalg.det(U_ @ Vt))
    score = s[:, 0] + s[:, 1] + d * s[:, 2]
    best = screen[np.argsort(-score)[:starts]]
    return [(GRID[k // n], project_to_so3(M[k]), GRID[k % n]) for k in best]


def linearised_system(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                      RZ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stacked F: (9m, 9) and E: (9m,) of the linearisation at (RX, RY, RZ), rows ordered
    (triple, column k, row), unknowns (d_X, d_Y, d_Z) (module docstring)."""
    m = len(RA)
    P = RX @ RB  # columns p_k
    YC = RY @ RC
    N = YC @ RZ  # columns n_k
    F = np.empty((m, 3, 3, 9))
    F[..., 0:3] = -np.einsum("nij,nkjl->nkil", RA, skew(np.swapaxes(P, 1, 2)))  # -R_A [p_k]
    F[..., 3:6] = skew(np.swapaxes(N, 1, 2))  # [n_k]
    F[..., 6:9] = np.einsum("nij,kjl->nkil", YC, skew(RZ.T))  # R_Y R_C [z_k]
    E = np.swapaxes(N - RA @ P, 1, 2)  # E[:, k] as rows (n, k, i)
    return F.reshape(9 * m, 9), E.reshape(9 * m)


def rotation_cost(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                  RZ: np.ndarray) -> np.ndarray:
    """C = sum_i |R_Ai R_X R_Bi - R_Y R_Ci R_Z|_F^2 for RA, RB, RC: (m, 3, 3) and one or a stack
    of iterates RX, RY, RZ: (..., 3, 3) -> (...)."""
    L, N = _sides(*_contiguous(RA, RB, RC), RX, RY, RZ)
    return np.sum((L - N) ** 2, axis=(-3, -2, -1))


def _contiguous(*stacks: np.ndarray) -> tuple[np.ndarray, ...]:
    """The stacks as contiguous float arrays (the rotation blocks of (m, 4, 4) poses are views
    whose products are several times slower)."""
    return tuple(np.ascontiguousarray(R, dtype=float) for R in stacks)


def _sides(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
           RZ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L = R_A R_X R_B and N = R_Y R_C R_Z: (..., m, 3, 3) for one or a stack of iterates (RA,
    RB, RC contiguous). R_A R_X, R_Y R_C and (R_Y R_C) R_Z are BLAS products per iterate over the
    stacked triples (R_C side by side for the product from the left): a batched product of the
    (m, 3, 3) stack with each iterate took 4x longer."""
    RX, RY, RZ = (np.asarray(R, dtype=float) for R in (RX, RY, RZ))
    m = RA.shape[0]
    lead = RX.shape[:-2]
    L = (RA.reshape(3 * m, 3) @ RX).reshape(lead + (m, 3, 3)) @ RB
    W = RY @ RC.transpose(1, 0, 2).reshape(3, 3 * m)  # [a, (i, b)] = (R_Y R_Ci)[a, b]
    N = (W.reshape(lead + (3 * m, 3)) @ RZ).reshape(lead + (3, m, 3))
    return L, np.ascontiguousarray(np.swapaxes(N, -3, -2))


def normal_equations(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                     RZ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """F^T F: (..., 9, 9) and F^T E: (..., 9) of `linearised_system` for one or a stack of
    iterates RX, RY, RZ: (..., 3, 3), from 3x3 products per triple (RA, RB, RC: (m, 3, 3)).

    With L = R_A R_X R_B, N = R_Y R_C R_Z, W = R_Y R_C (columns l_k, n_k) the rows of column k are
    [-[l_k] R_A, [n_k], [n_k] W] (R [p] = [R p] R) and E[:, k] = n_k - l_k, so with
    G(P, Q) = sum_k [p_k]^T [q_k] = tr(P^T Q) I - Q P^T and s = sum_k l_k x n_k = 2 vee(N L^T):

        F^T F = sum_i [[R_A^T G(L, L) R_A, -R_A^T G(L, N), -R_A^T G(L, N) W],
                       [.,                 G(N, N),        G(N, N) W       ],
                       [.,                 .,              W^T G(N, N) W   ]]   (symmetric),
        F^T E = sum_i [R_A^T s; -s; -W^T s].

    L and N are rotations, so G(L, L) = G(N, N) = 2 I and those blocks are 2 sum R_A^T R_A, 2m I,
    2 R_Y sum R_C and 2 sum R_C^T R_C; per triple and iterate only Q = N L^T (tr(L^T N) = tr Q,
    G(L, N) = tr(Q) I - Q) and R_A^T G(L, N) are formed, and the sums over the triples are BLAS
    products (`_linearisation`). Measured (m = 1000, 8 starts, one thread): the linearisation
    and C in 3.5 ms instead of 12.5, `wang` in 16 ms instead of 43. The data's rotations are
    orthonormal to `handeye.geometry.se3.ORTHONORMALITY_TOL`, which makes the constant blocks exact to
    that order; F^T E, which decides where Gauss-Newton stops, is exact.
    """
    return _linearisation(*_contiguous(RA, RB, RC), RX, RY, RZ)[:2]


def _linearisation(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                   RZ: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`normal_equations` and the rotation cost C at the iterates (`rotation_cost`), which shares
    its products L and N (`_sides`); RA, RB, RC contiguous."""
    RY = np.asarray(RY, dtype=float)
    L, N = _sides(RA, RB, RC, RX, RY, RZ)
    m, lead = RA.shape[0], L.shape[:-3]
    cost = np.sum((L - N) ** 2, axis=(-3, -2, -1))
    Q = N @ np.ascontiguousarray(np.swapaxes(L, -1, -2))
    RAt = np.ascontiguousarray(np.swapaxes(RA, -1, -2))
    D = np.einsum("...ii->...", Q)[..., None, None] * RAt - RAt @ Q  # R_A^T G(L, N)
    DY = (D.reshape(lead + (3 * m, 3)) @ RY).reshape(lead + (m, 3, 3))  # R_A^T G(L, N) R_Y
    C3 = RC.reshape(3 * m, 3)
    H = np.empty(lead + (9, 9))
    H[..., :3, :3] = 2.0 * np.einsum("nki,nkj->ij", RA, RA)
    H[..., :3, 3:6] = -D.sum(axis=-3)
    H[..., :3, 6:] = -(np.ascontiguousarray(np.swapaxes(DY, -3, -2)).reshape(lead + (3, 3 * m)) @ C3)
    H[..., 3:6, 3:6] = 2.0 * m * np.eye(3)
    H[..., 3:6, 6:] = 2.0 * (RY @ RC.sum(axis=0))
    H[..., 6:, 6:] = 2.0 * np.einsum("nki,nkj->ij", RC, RC)
    H[..., 3:, :3] = np.swapaxes(H[..., :3, 3:], -1, -2)
    H[..., 6:, 3:6] = np.swapaxes(H[..., 3:6, 6:], -1, -2)
    s = 2.0 * vee(Q)  # (..., m, 3)
    g = np.concatenate([s.reshape(lead + (3 * m,)) @ RA.reshape(3 * m, 3), -s.sum(axis=-2),
                        -((s @ RY).reshape(lead + (3 * m,)) @ C3)], axis=-1)
    return H, g, cost


def iterate_rotations(RA: np.ndarray, RB: np.ndarray, RC: np.ndarray, RX: np.ndarray, RY: np.ndarray,
                      RZ: np.ndarray, tol: float, max_iter: int) -> list[dict]:
    """Gauss-Newton (module docstring) from S starts RX, RY, RZ: (S, 3, 3) at once, in lockstep.

    Returns one record per start: its last iterate "R" (R_X, R_Y, R_Z), "costs" (C at the start
    and after each step), "step" (the last |delta|), "iterations", "converged" (|delta| < tol),
    "diverged" (a non-finite step), "joined" (stopped because each of its rotations came within
    `JOIN_ANGLE` of those of a start that has converged, or of a better-ranked start still
    running: the two are in one basin and would end at one point) and "sigma_ratio"
    (sigma_min / sigma_max of the stacked F at its last linearisation). C at an iterate comes
    with its linearisation (`_linearisation`); only the end points' C is evaluated apart.
    """
    RA, RB, RC = _contiguous(RA, RB, RC)
    R = np.stack([RX, RY, RZ], axis=1).astype(float)  # (S, 3, 3, 3)
    S = len(R)
    records = [{"costs": [], "step": float("nan"), "iterations": 0, "converged": False,
                "diverged": False, "joined": False, "H": None} for _ in range(S)]
    active = np.ones(S, dtype=bool)
    finished = np.zeros(S, dtype=bool)  # converged: others may join it
    cos_join = np.cos(JOIN_ANGLE)
    for iteration in range(1, max_iter + 1):
        idx = np.flatnonzero(active)
        if not len(idx):
            break
        H, g, cost = _linearisation(RA, RB, RC, R[idx, 0], R[idx, 1], R[idx, 2])
        for k, j in enumerate(idx):
            records[j]["costs"].append(float(cost[k]))  # C where this step starts
        with np.errstate(invalid="ignore", over="ignore"):
            try:
                delta = np.linalg.solve(H, g[..., None])[..., 0]
            except np.linalg.LinAlgError:  # a singular H: least squares, one start at a time
                delta = np.stack([np.linalg.lstsq(h, v, rcond=None)[0] if np.all(np.isfinite(h)) else
                                  np.full(9, np.nan) for h, v in zip(H, g)])
            step = np.linalg.norm(delta, axis=1)
        ok = np.isfinite(step)
        R[idx[ok]] = so3_exp(delta[ok].reshape(-1, 3, 3)) @ R[idx[ok]]
        for k, j in enumerate(idx):
            rec = records[j]
            rec.update(iterations=iteration, step=float(step[k]), H=H[k])
            if not ok[k]:
                rec["diverged"] = True
                active[j] = False
                continue
            if step[k] < tol:
                rec["converged"] = True
                active[j], finished[j] = False, True
        # join: cos of the angle of R_j R_i^T for each unknown, every running j against every i
        running = np.flatnonzero(active)
        if len(running):
            cos = (np.einsum("juab,iuab->jiu", R[running], R) - 1.0) / 2.0
            near = np.all(cos >= cos_join, axis=2)
            near &= finished[None, :] | (active[None, :] & (np.arange(S)[None, :] < running[:, None]))
            for j in running[near.any(axis=1)]:
                records[j]["joined"] = True
                active[j] = False
    stepped = [j for j, rec in enumerate(records) if not rec["diverged"]]  # C after their last step
    for j, c in zip(stepped, rotation_cost(RA, RB, RC, R[stepped, 0], R[stepped, 1], R[stepped, 2])):
        records[j]["costs"].append(float(c))
    for j, rec in enumerate(records):
        rec["R"] = tuple(R[j])
        H = rec.pop("H")
        lam = np.linalg.eigvalsh(H) if H is not None and np.all(np.isfinite(H)) else np.array([0.0, 0.0])
        rec["sigma_ratio"] = float(np.sqrt(max(lam[0], 0.0) / lam[-1])) if lam[-1] > 0 else 0.0
    return records


def _start_from_solver(data: AXBYCZData, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from handeye import run_registered

    try:
        out = run_registered(name, data, problem="axbycz")
    except HandEyeError as exc:
        raise type(exc)(f"wang: the start (init={name!r}) failed: {exc}") from None
    return tuple(np.asarray(out.unknowns[k], dtype=float)[:3, :3] for k in ("X", "Y", "Z"))


def run(data: AXBYCZData, options: Options, backend: str) -> SolverOutput:
    if data.m < MIN_TRIPLES:
        raise DegenerateDataError(
            f"wang needs >= {MIN_TRIPLES} triples, got {data.m}: with 3 the rotation equations have "
            "several solutions in general. Record more poses"
        )
    RA, RB, RC = data.A[:, :3, :3], data.B[:, :3, :3], data.C[:, :3, :3]
    tol, max_iter = float(options.tol), int(options.max_iter)
    if options.init == GRID_INIT:
        starts = grid_starts(RA, RB, RC, STARTS)
    else:
        starts = [_start_from_solver(data, options.init)]
    runs = iterate_rotations(RA, RB, RC, *(np.stack(R) for R in zip(*starts)), tol, max_iter)
    ended = [r for r in runs if not r["joined"]]
    it = min(ended, key=lambda r: (not r["converged"], r["costs"][-1] if np.isfinite(r["costs"][-1]) else np.inf))
    if it["diverged"]:
        reason = "diverged"
    elif it["sigma_ratio"] < SINGULAR_RATIO:
        raise DegenerateDataError(_UNDETERMINED.format(ratio=it["sigma_ratio"]))
    elif not it["converged"]:
        reason = "max_iter"
    else:
        reason = "converged"
    RX, RY, RZ = it["R"]
    try:
        tX, tY, tZ = solve_translations(data, RX, RY)
    except DegenerateDataError as exc:
        raise DegenerateDataError(f"wang: {exc}") from None
    warnings = []
    if reason != "converged":
        warnings.append(f"wang: no convergence from init={options.init!r} ({reason}: {it['iterations']} "
                        f"iterations, last step {it['step']:.2e}); the result is the last iterate, do not use it")
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY), "Z": make_pose(RZ, tZ)},
        status=Status.OPTIMAL if reason == "converged" else Status.NOT_CONVERGED,
        diagnostics={
            "init": options.init,
            "starts": len(starts),
            "starts_converged": sum(r["converged"] for r in runs),
            "starts_joined": sum(r["joined"] for r in runs),
            "iterations": it["iterations"],
            "iterations_all_starts": sum(r["iterations"] for r in runs),
            "step_norm": it["step"],
            "converged": it["converged"],
            "reason": reason,
            "sigma_ratio": it["sigma_ratio"],
            "rotation_cost_initial": it["costs"][0],
            "rotation_cost_final": it["costs"][-1],
            "end_costs_of_starts": [r["costs"][-1] for r in ended],
            "cost_history": it["costs"],
            "warnings": warnings,
        },
    )


SPEC = SolverSpec(
    name="wang",
    problems=("axbycz",),
    run=run,
    options=Options,
    summary="Wang et al.'s iteration: Gauss-Newton on the three rotations (grid start), then translations by least squares",
    citation="J. Wang, L. Wu, M. Q.-H. Meng, H. Ren, IROS 2014 (the paper's [22]); Pan et al., IEEE T-ASE 2022, Sec. III.B",
    unit_invariant=True,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
