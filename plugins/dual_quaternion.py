"""`dual-quaternion`: the paper's DQ-based method (Sec. III.C, eqs. 22-26).

A_i X = Y B_i in unit dual quaternions (eq. 22, helpers in `handeye.geometry.dualquat`, scalar-first
Hamilton quaternions) reads

    (a + eps a')(x + eps x') = (y + eps y')(b + eps b'),

i.e. (real part) a x = y b and (dual part) a x' + a' x = y b' + y' b. With q_1 q_2 = Q_L(q_1) q_2
= Q_R(q_2) q_1 (eq. 25) this is linear in Delta = [x; x'; y; y'] (16 unknowns), D_i Delta = 0
(eq. 24), with our derivation of the 8 x 16 block

    D_i = [[Q_L(a),  0,       -Q_R(b),  0      ],
           [Q_L(a'), Q_L(a),  -Q_R(b'), -Q_R(b)]].

(The paper's typeset D agrees once its second row is read as these four blocks.) The stacked
8m x 16 matrix always has a two-dimensional null space on exact data: the solution Delta* and
eps Delta* = [0; x; 0; y] (multiplying both unknowns by the dual unit eps solves eq. 22 too).
So, as in Daniilidis (1999), Delta = mu_1 v_15 + mu_2 v_16 (the last two right singular vectors,
eq. 26). The paper's inherent constraints are |x| = |y| = 1 and x . x' = y . y' = 0: four
equations for two unknowns mu, all satisfiable on exact data but not under noise, so we impose
their sums. With real part r(mu) = [x; y] and dual part d(mu) = [x'; y'] (8-vectors):

- orthogonality r . d = 0 is a quadratic form mu^T P mu = 0 (P symmetric 2x2). Its two real
  roots (P indefinite) are mu = sqrt(-l_2) e_1 +- sqrt(l_1) e_2 in the eigenbasis of P
  (l_1 >= 0 >= l_2). On exact data one root is eps Delta* (real part 0) and the other the
  solution, so we keep the root with the larger |r(mu)|^2 (Daniilidis' rule);
- unit norm: |x| = |y| = 1, i.e. |r(mu)|^2 = 2, fixes the scale.
If noise makes P definite (no real root) the eigenvector of P with the smaller |eigenvalue| is
used, and the status is ``optimal_inaccurate`` (not ``optimal``) with a warning: the answer does
not satisfy the method's own constraint. X and Y are read from (x, x') and (y, y') with t = 2 x' x*
(vector part) after normalising x, y.

Sign of each pair's dual quaternions (the paper's published code picks them with the ground
truth; here they come from the data alone). A rotation has two quaternions, q and -q, and eq. 24
holds only if, for every pair, the signs of (a_i, a'_i) and (b_i, b'_i) agree with a_i x = y b_i
for ONE fixed choice of x and y. No per-pair invariant fixes that sign (A_i and B_i are not
similar), but pairs of pairs do: from A_i X = Y B_i and A_j X = Y B_j, A_j A_i^-1 = Y (B_j B_i^-1)
Y^-1, so relative rotations have equal angles, and with a_i = s_i y b_i x* (s_i = +-1 the sign
error of pair i):

    a_i . a_j = s_i s_j (b_i . b_j)      (scalar part of a_j a_i* = that of b_j b_i*, signed).

Hence the m x m matrix C_ij = (a_i . a_j)(b_i . b_j) = s_i s_j (b_i . b_j)^2 equals S N S with
S = diag(s) and N_ij = (b_i . b_j)^2 >= 0 entrywise; by Perron-Frobenius the leading eigenvector
of N is positive, so the signs of the leading eigenvector of C are the s_i (up to one global
sign, which is harmless). C = Psi Psi^T with Psi_i = a_i kron b_i (16 numbers), so this is the
leading right singular vector u of Psi (a 16 x 16 eigenproblem, O(m), no loop over pairs):
s_i = sign(Psi_i . u). Rule: keep every (a_i, a'_i) as given (the conversion returns scalar part
>= 0, but any signs work, see below) and multiply (b_i, b'_i) by s_i.
Second pass: after solving, each pair is checked against the estimate, sign(a_i . (y b_i x*));
pairs that disagree (possible under heavy noise when a pair's rotation is ~180 deg from all the
others, so that its entry of the eigenvector is small) are flipped and the system solved once
more. Diagnostics report the sign margin (min |Psi_i . u| / max) and the flips of the second pass;
pairs still inconsistent after it make the status ``optimal_inaccurate``, with a warning.

Why the answer cannot depend on the signs the conversion gave (`solve_dual_quaternions`, tested
by flipping random input signs): flipping a_i (with a'_i) flips Psi_i, leaves Psi^T Psi and so u
bit for bit unchanged, and flips p_i and s_i, so pair i's rows of D are all negated -- same null
space, same least-squares problem. Flipping b_i (with b'_i) flips s_i too, so s_i b_i is
unchanged. The global sign of u flips every s_i b_i, i.e. y -> -y: the same rotation Y. The
consistency check of the second pass, sign(a_i . (y s_i b_i x*)), is invariant in the same way.

Option ``normalize`` (default True): translations are divided by the data's RMS translation
before the dual parts are formed (and the answer scaled back). This balances the rotation rows
against the translation rows and makes the solver independent of the length unit; the paper's
method is ``normalize=False`` (data in mm make the dual rows dominate the SVD).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import SolverError
from handeye.geometry.dualquat import (
    conjugate,
    dual_quat_from_pose,
    pose_from_dual_quat,
    q_left,
    q_right,
    quat_multiply,
)
from handeye.geometry.linalg import triangular_factor
from handeye.problems.axyb import AXYBData


@dataclasses.dataclass(frozen=True)
class Options:
    """normalize: divide translations by the data's RMS translation first (see module docstring)."""

    normalize: bool = True


def pair_signs(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Signs s: (m,) making b_i -> s_i b_i consistent with a_i x = y b_i, and the sign margin.

    a, b: (m, 4) rotation quaternions of A_i and B_i. See the module docstring (Perron vector of
    C_ij = (a_i . a_j)(b_i . b_j), via the 16-column matrix Psi_i = a_i kron b_i).
    """
    psi = np.einsum("ni,nj->nij", a, b).reshape(len(a), 16)
    _, vecs = np.linalg.eigh(np.einsum("ni,nj->ij", psi, psi))
    p = psi @ vecs[:, -1]
    signs = np.where(p < 0, -1.0, 1.0)
    margin = float(np.min(np.abs(p)) / np.max(np.abs(p)))
    return signs, margin


def dq_matrix(a: np.ndarray, ad: np.ndarray, b: np.ndarray, bd: np.ndarray) -> np.ndarray:
    """Stacked D of eq. 24: (8m, 16) from dual quaternions (a, a') of A_i and (b, b') of B_i, (m, 4) each."""
    m = len(a)
    D = np.zeros((m, 8, 16))
    D[:, :4, 0:4] = q_left(a)
    D[:, :4, 8:12] = -q_right(b)
    D[:, 4:, 0:4] = q_left(ad)
    D[:, 4:, 4:8] = q_left(a)
    D[:, 4:, 8:12] = -q_right(bd)
    D[:, 4:, 12:16] = -q_right(b)
    return D.reshape(8 * m, 16)


def null_space_solution(v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, bool]:
    """Delta = mu_1 v + mu_2 w: (16,) with r . d = 0 and |r|^2 = 2 (unit x, y); flag = real root found."""
    parts = np.r_[0:4, 8:12], np.r_[4:8, 12:16]
    vr, vd, wr, wd = v[parts[0]], v[parts[1]], w[parts[0]], w[parts[1]]
    P = np.array([[vr @ vd, 0.5 * (vr @ wd + wr @ vd)], [0.5 * (vr @ wd + wr @ vd), wr @ wd]])
    G = np.array([[vr @ vr, vr @ wr], [vr @ wr, wr @ wr]])
    lam, E = np.linalg.eigh(P)  # lam[0] <= lam[1]
    if lam[0] <= 0.0 <= lam[1]:
        candidates = [np.sqrt(-lam[0]) * E[:, 1] + s * np.sqrt(lam[1]) * E[:, 0] for s in (1.0, -1.0)]
        real_root = True
    else:
        candidates = [E[:, int(np.argmin(np.abs(lam)))]]
        real_root = False
    mu = max(candidates, key=lambda c: float(c @ G @ c))
    norm2 = float(mu @ G @ mu)
    if not norm2 > 0:
        raise SolverError("dual-quaternion: the data determine no rotation (degenerate data: the poses "
                          "rotate about too few axes); record poses that rotate about at least two "
                          "different axes")
    mu = mu * np.sqrt(2.0 / norm2)
    return mu[0] * v + mu[1] * w, real_root


def solve_dq(a: np.ndarray, ad: np.ndarray, b: np.ndarray, bd: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """(Delta: (16,), singular values of D: (16,), real_root) of eqs. 24-26.

    a, ad, b, bd: (m, 4), sign-consistent. SVD of D = Q R through the 16 x 16 factor R (same
    singular values and right singular vectors); v_15, v_16 are the last two right singular vectors.
    """
    R = triangular_factor(dq_matrix(a, ad, b, bd).reshape(-1, 8, 16))
    _, sigma, Vt = np.linalg.svd(R)
    delta, real_root = null_space_solution(Vt[-2], Vt[-1])
    return delta, sigma, real_root


def solve_dual_quaternions(a: np.ndarray, ad: np.ndarray, b: np.ndarray, bd: np.ndarray) -> dict:
    """Eqs. 24-26 from the dual quaternions (a, a') of A_i and (b, b') of B_i: (m, 4) each, any signs.

    The sign of each pair is chosen from the data (`pair_signs`, then one consistency pass; module
    docstring), so the result does not depend on the sign each input quaternion came with.
    Returns x, xd, y, yd: (4,) (the dual quaternions of X and Y, |x| = |y| = 1 up to noise),
    sigma: (16,) singular values of D, real_root, signs: (m,) applied to (b, b'), margin, flips
    (pairs flipped by the second pass) and wrong (pairs still inconsistent afterwards).
    """
    signs, margin = pair_signs(a, b)
    flips = 0
    for _ in range(2):  # first pass, then at most one correction of the signs
        sb, sbd = signs[:, None] * b, signs[:, None] * bd
        delta, sigma, real_root = solve_dq(a, ad, sb, sbd)
        x, y = delta[0:4], delta[8:12]
        check = np.sum(a * quat_multiply(quat_multiply(y, sb), conjugate(x)), axis=1)
        wrong = check < 0
        if not wrong.any() or flips:
            break
        flips = int(wrong.sum())
        signs = np.where(wrong, -signs, signs)
    return {"x": delta[0:4], "xd": delta[4:8], "y": delta[8:12], "yd": delta[12:16], "sigma": sigma,
            "real_root": real_root, "signs": signs, "margin": margin, "flips": flips,
            "wrong": int(wrong.sum())}


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    scale = data.translation_scale if options.normalize else 1.0
    work = data.scaled(scale) if options.normalize else data
    a, ad = dual_quat_from_pose(work.A)
    b, bd = dual_quat_from_pose(work.B)
    sol = solve_dual_quaternions(a, ad, b, bd)
    X = pose_from_dual_quat(sol["x"], sol["xd"])
    Y = pose_from_dual_quat(sol["y"], sol["yd"])
    X[:3, 3] *= scale
    Y[:3, 3] *= scale
    warnings = []
    if sol["wrong"]:
        warnings.append(f"dual-quaternion: {sol['wrong']} pair(s) remain sign-inconsistent with "
                        "the solution (very noisy data, or mismatched robot and camera poses?)")
    if not sol["real_root"]:
        warnings.append("dual-quaternion: the rotation constraint has no real root (noise too large "
                        "for this method); used the closest approximate root. Solver 'refine' or "
                        "'auto' copes with this noise")
    sigma = sol["sigma"]
    return SolverOutput(
        unknowns={"X": X, "Y": Y},
        status=Status.OPTIMAL_INACCURATE if warnings else Status.OPTIMAL,
        diagnostics={
            "singular_values_tail": sigma[-3:].tolist(),
            "sigma_max": float(sigma[0]),
            "sign_margin": sol["margin"],
            "sign_flips_second_pass": sol["flips"],
            "sign_inconsistent_pairs": sol["wrong"],
            "orthogonality_real_root": sol["real_root"],
            "normalize": options.normalize,
            "warnings": warnings,
        },
    )


SPEC = SolverSpec(
    name="dual-quaternion",
    problems=("axyb",),
    run=run,
    options=Options,
    summary="dual quaternions: SVD of the stacked linear system (8 rows a pair), unit solution in its two-vector null space",
    citation="Pan et al., IEEE T-ASE 2022, Sec. III.C; Daniilidis, IJRR 18(3), 1999",
    unit_invariant=lambda options: options.normalize,  # not with normalize=False (module docstring)
)


@hookimpl
def register_solvers(register):
    register(SPEC)
