"""`wu`: the closed-form solution of Wu et al. for A_i X B_i = Y C_i Z (its closed-form part).

L. Wu, J. Wang, L. Qi, K. Wu, H. Ren, M. Q.-H. Meng, "Simultaneous Hand-Eye, Tool-Flange, and
Robot-Robot Calibration for Comanipulation by Solving the AXB=YCZ Problem", IEEE T-RO 32(2):
413-428, 2016. The paper solves the rotations in closed form, refines them iteratively (its eq.
29: repeated linearisation on SO(3)^3, the method of solver ``wang``) and then solves the
translations (eq. 38). This solver is the closed form followed by eq. 38, without the iterative
refinement (for that: solver ``wang`` with ``init="wu"``, or ``refine``). Equation numbers follow
the authors' MATLAB code (github.com/drliaowu/AXBYCZ), which we read to understand the method.

1. Quaternions. With unit quaternions q_A, q_B, q_C of the data and q_X, q_Y, q_Z of the
   unknowns, R_A R_X R_B = R_Y R_C R_Z reads q_A q_X q_B = s q_Y q_C q_Z with a sign s = +-1 per
   triple (a rotation has two quaternions, and those of the data are taken with no regard to the
   unknowns). Both sides are linear in q_X and in k = q_Y kron q_Z (16), so each triple gives 4
   homogeneous equations in 20 unknowns (`system_blocks`):

       Q_L(q_A) Q_R(q_B) q_X - s W(q_C) k = 0,      W(q_C) k = q_Y q_C q_Z   (the paper's eq. 9).

2. Signs. The signs s_i are unknown: the paper fixes s_1 = 1 and tries all 2^(n-1) sign patterns of
   the first n = min(m, 10) triples (``sign_triples``); for each, the eigenvector of the smallest
   eigenvalue of the 20 x 20 matrix sum_i [W_ABi, -s_i W_Ci]^T [W_ABi, -s_i W_Ci] solves the
   homogeneous system in the least-squares sense. The ``candidates`` (5) patterns of smallest
   eigenvalue are kept, their rotations extracted, and the one whose rotation residual
   sum_i |log(R_Ai R_X R_Bi (R_Y R_Ci R_Z)^T)| over those triples is smallest wins. Exact data make
   the smallest eigenvalue of the right pattern 0.
3. Extraction. q_X = the first 4 entries, normalised. q_Y, q_Z from k = q_Y kron q_Z, i.e. the 4x4
   matrix q_Y q_Z^T: the paper takes |q_Yj| and |q_Zj| as norms of its rows and columns with signs
   from its first row and column, which breaks down when q_Y0 q_Z0 = 0 (a half turn: the simulated
   cell's Y is one); we take the leading singular pair of the matrix (its nearest rank-one matrix),
   which is the same on exact data. The sign of the pair is irrelevant (q and -q are one rotation).
4. Translations: least squares given the rotations over all triples (eq. 38,
   `handeye.problems.axbycz.kronecker.solve_translations`).

``all_triples=True`` (our extension): after the paper's estimate, every triple's sign is the sign
of <q_A q_X q_B, q_Y q_C q_Z> and the 20 x 20 eigenproblem is solved again over all triples.

Data. At least 5 triples (20 unknowns up to scale, 4 equations each), and the sign triples must
determine the rotations: both robots moving between them (the paper's simulation moves both at
every triple; ``simulate_options`` protocol "free"). In the phase protocol (robot 2 still for the
first half) the first 10 triples cannot: a one-line DegenerateDataError says so. The answer does
not depend on the length unit (the rotations use rotations only; eq. 38 is linear).
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import DegenerateDataError
from handeye.framework.options import check_int
from handeye.geometry.dualquat import (
    q_left,
    q_right,
    quat_from_rotation,
    quat_multiply,
    rotation_from_quat,
)
from handeye.geometry.se3 import make_pose, rotation_angle
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axbycz.kronecker import solve_translations

#: the paper's number of sign triples and of sign patterns compared by their residual
SIGN_TRIPLES = 10
CANDIDATES = 5
#: fewest triples: 20 unknowns up to scale, 4 equations a triple
MIN_TRIPLES = 5
#: most sign triples (2^(n-1) patterns: 8192 eigenproblems of 20 x 20 at 14)
MAX_SIGN_TRIPLES = 14
#: the rotations are undetermined when the second smallest eigenvalue is below this (relative)
UNDETERMINED_RTOL = 1e-10


def _product_tensor() -> np.ndarray:
    """E: (4, 4, 4) with (p q)_k = sum_ij E[i, j, k] p_i q_j (Hamilton product, scalar first)."""
    basis = np.eye(4)
    return np.stack([[quat_multiply(basis[i], basis[j]) for j in range(4)] for i in range(4)])


PRODUCT = _product_tensor()


@dataclasses.dataclass(frozen=True)
class Options:
    """sign_triples: how many leading triples the signs are enumerated on (the paper: 10);
    candidates: sign patterns compared by their rotation residual (the paper: 5); all_triples:
    re-solve over all triples with signs from the first estimate (ours; the paper: False)."""

    sign_triples: int = SIGN_TRIPLES
    candidates: int = CANDIDATES
    all_triples: bool = False

    def __post_init__(self) -> None:
        check_int("sign_triples", self.sign_triples, minimum=MIN_TRIPLES, maximum=MAX_SIGN_TRIPLES)
        check_int("candidates", self.candidates, minimum=1, maximum=2 ** (MAX_SIGN_TRIPLES - 1))


def system_blocks(data: AXBYCZData) -> tuple[np.ndarray, np.ndarray]:
    """W_AB: (m, 4, 4) = Q_L(q_A) Q_R(q_B) and W_C: (m, 4, 16) with W_C k = q_Y q_C q_Z for
    k = q_Y kron q_Z (step 1 of the module docstring), from the data's quaternions (signs as
    `quat_from_rotation` gives them)."""
    qA, qB, qC = (quat_from_rotation(T[:, :3, :3]) for T in (data.A, data.B, data.C))
    W_AB = q_left(qA) @ q_right(qB)
    # (q_Y q_C q_Z)_k = sum E[a, c, j] E[j, b, k] qY_a qC_c qZ_b
    W_C = np.einsum("acj,jbk,ic->ikab", PRODUCT, PRODUCT, qC).reshape(len(qC), 4, 16)
    return W_AB, W_C


def _grams(W_AB: np.ndarray, W_C: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """sum_i [W_ABi, -s_i W_Ci]^T [...]: (patterns, 20, 20) for signs: (patterns, n)."""
    n = W_AB.shape[0]
    G0 = np.zeros((20, 20))
    G0[:4, :4] = np.einsum("iak,ial->kl", W_AB, W_AB)
    G0[4:, 4:] = np.einsum("iak,ial->kl", W_C, W_C)
    cross = -np.einsum("iak,ial->ikl", W_AB, W_C).reshape(n, 64)  # -W_AB^T W_C per triple
    off = (signs @ cross).reshape(-1, 4, 16)
    G = np.broadcast_to(G0, (len(signs), 20, 20)).copy()
    G[:, :4, 4:] = off
    G[:, 4:, :4] = off.transpose(0, 2, 1)
    return G


def rotations_of(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """R_X, R_Y, R_Z of an eigenvector v: (20,) (step 3), and sigma_2 / sigma_1 of q_Y q_Z^T."""
    U, s, Vt = np.linalg.svd(v[4:].reshape(4, 4))
    RX, RY, RZ = rotation_from_quat(np.stack([v[:4], U[:, 0], Vt[0]]))
    return RX, RY, RZ, float(s[1] / s[0]) if s[0] > 0 else float("inf")


def rotation_residual(data: AXBYCZData, index: slice, RX: np.ndarray, RY: np.ndarray, RZ: np.ndarray) -> float:
    """sum over the triples `index` of the angle of R_A R_X R_B (R_Y R_C R_Z)^T (the paper's choice)."""
    RA, RB, RC = data.A[index, :3, :3], data.B[index, :3, :3], data.C[index, :3, :3]
    return float(np.sum(rotation_angle(RA @ RX @ RB @ (RY @ RC @ RZ).transpose(0, 2, 1))))


def _undetermined(n: int) -> DegenerateDataError:
    return DegenerateDataError(
        f"wu: the first {n} triples, on which Wu's closed form enumerates the quaternion signs, do not "
        "determine the rotations: both robots must move between them (with one robot still, as in the "
        "phase protocol, use solver 'fu-dq' or 'wang'; or reorder the triples so that both robots move "
        "in the first ones)")


def run(data: AXBYCZData, options: Options, backend: str) -> SolverOutput:
    if data.m < MIN_TRIPLES:
        raise DegenerateDataError(f"wu: Wu's closed form needs at least {MIN_TRIPLES} triples (20 quaternion "
                                  f"unknowns up to scale, 4 equations per triple); got {data.m}")
    W_AB, W_C = system_blocks(data)
    n = min(data.m, options.sign_triples)
    signs = np.array([(1.0,) + rest for rest in itertools.product((1.0, -1.0), repeat=n - 1)])
    G = _grams(W_AB[:n], W_C[:n], signs)
    order = np.argsort(np.linalg.eigvalsh(G)[:, 0])[:options.candidates]  # values only: 3x faster
    lam, vectors = np.linalg.eigh(G[order])
    trials = []
    for k in range(len(order)):
        RX, RY, RZ, ratio = rotations_of(vectors[k, :, 0])
        trials.append((rotation_residual(data, slice(0, n), RX, RY, RZ), k, (RX, RY, RZ), ratio))
    residual, chosen, (RX, RY, RZ), rank_ratio = min(trials, key=lambda trial: trial[0])
    eig = lam[chosen]
    if eig[1] <= UNDETERMINED_RTOL * eig[-1]:
        raise _undetermined(n)
    figures = {"eigenvalue": float(eig[0]), "eigenvalue_ratio": float(eig[0] / eig[1])}
    if options.all_triples and data.m > n:
        qX, qY, qZ = quat_from_rotation(np.stack([RX, RY, RZ]))
        qA, qB, qC = (quat_from_rotation(T[:, :3, :3]) for T in (data.A, data.B, data.C))
        left = quat_multiply(quat_multiply(qA, qX), qB)
        right = quat_multiply(quat_multiply(qY, qC), qZ)
        all_signs = np.where(np.sum(left * right, axis=1) < 0, -1.0, 1.0)
        lam_all, vectors_all = np.linalg.eigh(_grams(W_AB, W_C, all_signs[None])[0])
        RX, RY, RZ, rank_ratio = rotations_of(vectors_all[:, 0])
        figures = {"eigenvalue": float(lam_all[0]), "eigenvalue_ratio": float(lam_all[0] / lam_all[1])}
    tX, tY, tZ = solve_translations(data, RX, RY, RZ)
    return SolverOutput(
        unknowns={"X": make_pose(RX, tX), "Y": make_pose(RY, tY), "Z": make_pose(RZ, tZ)},
        status=Status.OPTIMAL,
        diagnostics={
            **figures,
            "sign_triples": n,
            "sign_patterns": len(signs),
            "sign_residual": residual,
            "candidate_residuals": sorted(trial[0] for trial in trials),
            "rank_one_ratio": rank_ratio,
            "all_triples": bool(options.all_triples),
        },
    )


SPEC = SolverSpec(
    name="wu",
    problems=("axbycz",),
    run=run,
    options=Options,
    summary="Wu et al.'s closed form: quaternions, signs enumerated on the first 10 triples, "
            "q_Y kron q_Z lifted; translations by least squares (no iterative refinement)",
    citation="Wu, Wang, Qi, Wu, Ren, Meng, Simultaneous Hand-Eye, Tool-Flange, and Robot-Robot "
             "Calibration for Comanipulation by Solving the AXB=YCZ Problem, IEEE T-RO 32(2):413-428, "
             "2016 (closed-form part and eq. 38)",
    unit_invariant=True,
    simulate_options={"protocol": "free"},
)


@hookimpl
def register_solvers(register):
    register(SPEC)
