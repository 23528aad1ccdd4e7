"""The five classic AX=XB hand-eye methods that OpenCV's ``cv2.calibrateHandEye`` offers, as our
own NumPy code: `tsai`, `park`, `horaud`, `andreff`, `daniilidis`.

Each takes relative motions A, B: (m, 4, 4) with A_i X = X B_i (problem ``axxb``; built from
absolute poses by `handeye.problems.axxb.motions`) and returns X: (4, 4), exactly in SE(3). Each
follows its paper's equations and, where the paper leaves a choice open, the choice OpenCV 4.14
makes (read in modules/calib3d/src/calibration_handeye.cpp), so that on the same motions our X
equals OpenCV's to ~1e-13 (tests/plugins/test_classic_handeye.py checks 1e-9). OpenCV itself does not take motions: it takes n absolute poses G_k = T_base_gripper,
C_k = T_cam_target and forms EVERY pair i < j (i outer, j inner), A = inv(G_j) G_i,
B = C_j inv(C_i), the motions of ``motions(..., pairing="all")``. The steps OpenCV adds to the
papers, reproduced here:

- Tsai: only motions whose modified Rodrigues vectors P = 2 sin(theta/2) n have norm in
  [0.3, 1.7] in both A and B (rotation angle 17.3 to 116.4 deg) are used, for the rotation and
  for the translation (``select_motions=False`` uses all).
- Horaud, Daniilidis (and Tsai): every motion's (dual) quaternion is taken with scalar part >= 0,
  so that q_A and q_B of a motion have the same sign.
- Andreff: the 3x3 block of the least-squares solution is scaled to determinant +1 and replaced
  by its orthogonal polar factor (eq. 15).

Unit invariance (translations scaled by s): Tsai, Park and Horaud find R_X from the rotations
alone and t_X by linear least squares, so X scales exactly. Andreff (one least-squares system
mixing unitless rotation rows with translation rows) and Daniilidis (one SVD of rotation and
dual-part rows) weigh the two kinds of rows by the length unit: on noisy data their answer
changes with the unit (measured with 0.01 rad / 1 mm pose noise: median 2e-2 rad between mm and m);
on exact data it does not. docs/solvers/{tsai,park,horaud,andreff,daniilidis}.md give details.

A linear system that does not determine X (all rotation axes parallel, no rotation) raises
`DegenerateDataError`; a relative singular value below `SINGULAR_RATIO` counts as singular.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import DegenerateDataError, InputError
from handeye.checks.self_check import rotation_block_figures
from handeye.framework.options import check_bool
from handeye.geometry.dualquat import (
    pose_from_dual_quat,
    q_left,
    q_right,
    rotation_from_quat,
)
from handeye.geometry.linalg import triangular_factor
from handeye.geometry.se3 import make_pose, project_to_so3, skew
from handeye.problems.axxb import AXXBData, regression_blocks, solve_translation

#: Tsai as OpenCV: keep a motion when |P_A| and |P_B| (P = 2 sin(theta/2) n) both lie in this range.
TSAI_RANGE = (0.3, 1.7)
#: sigma_min / sigma_max (or eigenvalue gap / largest eigenvalue) at or below which a system is singular.
SINGULAR_RATIO = 1e-10
_PARALLEL = ("the robot motions rotate about fewer than two different axes (their rotation axes are "
             "parallel, or they do not rotate), so X cannot be determined. Record motions that rotate "
             "about at least two different axes")


def _data(A: Any, B: Any) -> AXXBData:
    """A, B (`_motions`) as AXXBData: the quaternions and rotation vectors the methods use are
    its cached properties (one vectorised pass over both stacks), shared with `axxb`'s validation
    when a method runs through `handeye.solve`."""
    return AXXBData(*_motions(A, B))


def _linear_map(build, inputs: int) -> np.ndarray:
    """The constant matrix L: (inputs, size) with build(x).reshape(-1) = x @ L for the linear
    `build` of one motion's rows from its input vector x: (inputs,), found by applying build to
    the unit vectors. A stack of blocks is then built by ONE product, X: (m, inputs) @ L, instead
    of a dozen strided assignments."""
    L = np.stack([np.asarray(build(e), dtype=float).reshape(-1) for e in np.eye(inputs)])
    L.setflags(write=False)
    return L


def _tsai_block(x: np.ndarray) -> np.ndarray:
    """[skew(P_A + P_B) | P_B - P_A]: (3, 4) of eq. 12 for x = (P_A, P_B)."""
    pa, pb = x[:3], x[3:]
    return np.concatenate([skew(pa + pb), (pb - pa)[:, None]], axis=1)


def _daniilidis_block(x: np.ndarray) -> np.ndarray:
    """The 6x8 block of eq. 31 for x = (a, b, a', b'), its columns ordered (q'_X, q_X): the
    leading 4x4 block of the stack's triangular factor is then that of the rotation rows alone
    (the first 3 rows of a block are zero in the q'_X columns)."""
    a, b, a_, b_ = x[:3], x[3:6], x[6:9], x[9:]
    T = np.zeros((6, 8))
    T[:3, 4], T[:3, 5:] = a - b, skew(a + b)
    T[3:, 4], T[3:, 5:] = a_ - b_, skew(a_ + b_)
    T[3:, 0], T[3:, 1:4] = a - b, skew(a + b)
    return T


_TSAI_MAP = _linear_map(_tsai_block, 6)
_DANIILIDIS_MAP = _linear_map(_daniilidis_block, 12)
#: cross products u x v of (k, 3) stacks by gathered components (np.cross costs ~10 numpy calls)
_C1, _C2 = np.array([1, 2, 0]), np.array([2, 0, 1])
#: the columns (q'_X, q_X) of `_daniilidis_block` reordered as (q_X, q'_X)
_Q_FIRST = np.array([4, 5, 6, 7, 0, 1, 2, 3])


def _motions(A: Any, B: Any) -> tuple[np.ndarray, np.ndarray]:
    """A, B as float64 (m, 4, 4) arrays (not copied when they already are), m >= 2."""
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    for name, T in (("A", A), ("B", B)):
        if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) < 2:
            raise InputError(f"expected `{name}` to have shape (m, 4, 4) with m >= 2, got {T.shape}")
    if len(A) != len(B):
        raise InputError(f"A and B must hold the same number of motions, got {len(A)} and {len(B)}")
    return A, B


def _lstsq(M: np.ndarray, rhs: np.ndarray | None, what: str, hint: str = _PARALLEL) -> tuple[np.ndarray, float]:
    """Least squares min |M x - rhs| for the blocks M: (k, r, c), rhs: (k, r) stacked, and
    sigma_min / sigma_max of the stack; DegenerateDataError when it is singular. As OpenCV's
    DECOMP_SVD up to rounding: the stack [M | rhs] is first reduced to its triangular factor
    (`handeye.geometry.linalg.triangular_factor`, a QR of small chunks), then solved by SVD. rhs None:
    M is already [M | rhs] (k, r, c + 1)."""
    if rhs is not None:
        M = np.concatenate([M, rhs[..., None]], axis=-1)
    c = M.shape[-1] - 1
    R = triangular_factor(M)
    U, s, Vt = np.linalg.svd(R[:c, :c])
    ratio = float(s[-1] / s[0]) if s[0] > 0 else 0.0
    if ratio <= SINGULAR_RATIO:
        raise DegenerateDataError(f"{what} is singular (smallest/largest singular value {ratio:.1e}): {hint}")
    return Vt.T @ ((U.T @ R[:c, c]) / s), ratio


def _tsai(data: AXXBData, select_motions: bool = True) -> tuple[np.ndarray, dict[str, Any]]:
    """`tsai` and its diagnostics."""
    m = data.m
    P = 2.0 * data._quaternions[:, 1:]  # 2 sin(theta/2) n of A_1 .. A_m, B_1 .. B_m, scalar part >= 0
    used = m
    if select_motions:
        lo, hi = TSAI_RANGE
        n = np.sqrt((P * P).sum(axis=1))
        inside = (n >= lo) & (n <= hi)
        keep = inside[:m] & inside[m:]
        used = int(keep.sum())
    if used < 2:
        raise DegenerateDataError(
            f"tsai: only {used} of {m} motions rotate by 17.3 to 116.4 deg (|2 sin(theta/2)| in "
            f"{list(TSAI_RANGE)}, OpenCV's selection) and 2 are needed: record motions with larger "
            "rotations, or pass select_motions=False to use every motion"
        )
    PAB = np.concatenate([P[:m], P[m:]], axis=1)  # (P_A, P_B) per motion
    if used < m:
        PAB = PAB[keep]
        data = AXXBData(data.A[keep], data.B[keep])
    # eq. 12: skew(P_A + P_B) P' = P_B - P_A, 3 rows per motion, built as [skew | rhs] by one product
    x, ratio = _lstsq((PAB @ _TSAI_MAP).reshape(-1, 3, 4), None, "tsai: the rotation system",
                      "either the robot motions rotate about fewer than two different axes, or X rotates by "
                      "180 deg, which Tsai's method cannot represent. Record motions that rotate about at "
                      "least two different axes, or use another method such as 'park'")
    # eq. 14: P_X = 2 P' / sqrt(1 + |P'|^2), i.e. the unit quaternion (1, P') / |(1, P')|
    RX = rotation_from_quat(np.concatenate([[1.0], x]))
    tX = solve_translation(data, RX)  # eq. 15 on the selected motions
    return make_pose(RX, tX), {"motions_used": used, "rotation_sigma_ratio": ratio}


def tsai(A: Any, B: Any, select_motions: bool = True) -> np.ndarray:
    """X: (4, 4) from motions A, B: (m, 4, 4) by Tsai and Lenz's method.

    R. Y. Tsai, R. K. Lenz, "A new technique for fully autonomous and efficient 3D robotics
    hand/eye calibration", IEEE Trans. Robotics and Automation 5(3), 345-358, 1989.
    With the modified Rodrigues vectors P = 2 sin(theta/2) n of R_Ai and R_Bi (P_A = R_X P_B),
    eq. 12, skew(P_Ai + P_Bi) P' = P_Bi - P_Ai, is solved for P' by least squares; then eq. 14,
    P_X = 2 P' / sqrt(1 + |P'|^2), gives R_X (P' = tan(theta_X/2) n_X: X may not rotate by 180
    deg) and eq. 15, (R_Ai - I) t_X = R_X t_Bi - t_Ai, gives t_X by least squares.

    select_motions: use only the motions OpenCV uses (module docstring); False: all. Unit
    invariant. DegenerateDataError when fewer than 2 motions are selected or eq. 12 is singular.
    """
    return _tsai(_data(A, B), select_motions)[0]


def _park(data: AXXBData) -> tuple[np.ndarray, dict[str, Any]]:
    """`park` and its diagnostics."""
    alpha, beta = data.rotation_vectors  # alpha_i = R_X beta_i
    M = beta.T @ alpha  # sum_i beta_i alpha_i^T
    sigma = np.linalg.svd(M, compute_uv=False)
    if sigma[1] <= SINGULAR_RATIO * sigma[0]:
        raise DegenerateDataError(f"park: the rotation axes of the motions span fewer than two directions: {_PARALLEL}")
    RX = project_to_so3(M.T)  # = (M^T M)^(-1/2) M^T when M is invertible with det > 0
    return make_pose(RX, solve_translation(data, RX)), {"M_singular_values": sigma.tolist()}


def park(A: Any, B: Any) -> np.ndarray:
    """X: (4, 4) from motions A, B: (m, 4, 4) by Park and Martin's method.

    F. C. Park, B. J. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean
    group", IEEE Trans. Robotics and Automation 10(5), 717-721, 1994.
    With the rotation vectors (matrix logarithms) alpha_i of R_Ai and beta_i of R_Bi, which
    satisfy alpha_i = R_X beta_i, R_X = (M^T M)^(-1/2) M^T with M = sum_i beta_i alpha_i^T (the
    least-squares rotation), computed as the orthogonal polar factor of M^T by SVD with det +1
    (the same matrix whenever M^T M is invertible and det M > 0, and still defined for two
    motions, where M has rank 2). Then t_X by least squares, (I - R_Ai) t_X = t_Ai - R_X t_Bi.
    Unit invariant. DegenerateDataError when M has rank < 2 (parallel axes).
    """
    return _park(_data(A, B))[0]


def _horaud(data: AXXBData) -> tuple[np.ndarray, dict[str, Any]]:
    """`horaud` and its diagnostics."""
    q_A, q_B = data.quaternions  # scalar >= 0
    D = (q_left(q_A) - q_right(q_B)).reshape(-1, 4)  # (Q(q_Ai) - W(q_Bi)) q_X = 0
    N = D.T @ D
    lam, V = np.linalg.eigh(N)  # ascending
    if lam[1] - lam[0] <= SINGULAR_RATIO * lam[3]:
        raise DegenerateDataError(f"horaud: the rotation of X is not unique: {_PARALLEL}")
    RX = rotation_from_quat(V[:, 0])
    return make_pose(RX, solve_translation(data, RX)), {"eigenvalues": lam.tolist()}


def horaud(A: Any, B: Any) -> np.ndarray:
    """X: (4, 4) from motions A, B: (m, 4, 4) by Horaud and Dornaika's linear method.

    R. Horaud, F. Dornaika, "Hand-eye calibration", Int. J. Robotics Research 14(3), 195-210,
    1995 (Sec. 5, Appendix A). q_Ai q_X = q_X q_Bi is linear in the unit quaternion q_X,
    (Q(q_Ai) - W(q_Bi)) q_X = 0, with Q, W the matrices of left and right multiplication; q_X is
    the eigenvector of the smallest eigenvalue of sum_i A_i^T A_i, A_i = Q(q_Ai) - W(q_Bi). Both
    quaternions of a motion are taken with scalar part >= 0 (as OpenCV does; otherwise A_i q_X = 0
    fails for motions whose signs differ). Then t_X by least squares as in `park`.
    Unit invariant. DegenerateDataError when that eigenvalue is not simple (parallel axes).
    """
    return _horaud(_data(A, B))[0]


def _andreff(data: AXXBData) -> tuple[np.ndarray, dict[str, Any]]:
    """`andreff` and its diagnostics."""
    H, w = regression_blocks(data.A, data.B)  # (R_B kron R_A - I) vec R_X = 0, (t_B^T kron I) vec R_X + (I - R_A) t_X = t_A
    beta, ratio = _lstsq(H, w, "andreff: the linear system")
    M = beta[:9].reshape(3, 3, order="F")
    det = float(np.linalg.det(M))
    if abs(det) < np.finfo(np.float32).eps:  # OpenCV's test
        raise DegenerateDataError(f"andreff: the estimated rotation block is singular (det {det:.1e}): {_PARALLEL}")
    RX = project_to_so3(np.sign(det) * M)  # eq. 15: scaled to det +1, then the orthogonal polar factor
    return make_pose(RX, beta[9:]), {"sigma_ratio": ratio, "det_rotation_block": det,
                                     "rotation_blocks": {"X": rotation_block_figures(M)}}


def andreff(A: Any, B: Any) -> np.ndarray:
    """X: (4, 4) from motions A, B: (m, 4, 4) by Andreff, Horaud and Espiau's linear method.

    N. Andreff, R. Horaud, B. Espiau, "On-line hand-eye calibration", Proc. 2nd Int. Conf. on 3-D
    Digital Imaging and Modeling (3DIM'99), 430-436, 1999 (also IJRR 20(3), 2001). Rotation and
    translation in one linear least-squares system (eq. 10), per motion
    (I_9 - R_Ai kron R_Bi) vec(R_X) = 0 and (I_3 kron t_Bi^T) vec(R_X) + (I - R_Ai) t_X = t_Ai
    (row-major vec; `handeye.problems.axxb.regression_blocks` writes the same equations with
    column-major vec, a permutation of the unknowns). The 3x3 block is then scaled to
    determinant +1 and replaced by its orthogonal polar factor (eq. 15), t_X is taken as solved.
    NOT unit invariant on noisy data: the unitless rotation rows and the translation rows are
    weighed by the length unit (exact data are recovered in any unit). DegenerateDataError when
    the system is singular or the rotation block has determinant ~0.
    """
    return _andreff(_data(A, B))[0]


def _daniilidis(data: AXXBData) -> tuple[np.ndarray, dict[str, Any]]:
    """`daniilidis` and its diagnostics."""
    m, q = data.m, data._quaternions  # q of A_1 .. A_m, B_1 .. B_m, scalar part >= 0
    t = np.concatenate([data.A[:, :3, 3], data.B[:, :3, 3]])
    v = q[:, 1:]
    # vector part of the dual part q' = 1/2 (0, t) q: (q0 t + t x v) / 2
    dual = 0.5 * (q[:, :1] * t + (t[:, _C1] * v[:, _C2] - t[:, _C2] * v[:, _C1]))
    ab = np.concatenate([v[:m], v[m:], dual[:m], dual[m:]], axis=1)  # (a, b, a', b') per motion
    T = (ab @ _DANIILIDIS_MAP).reshape(m, 6, 8)  # eq. 31 per motion, columns (q'_X, q_X)
    R = triangular_factor(T)
    rot = np.linalg.svd(R[:4, :4], compute_uv=False)  # the rotation rows alone (_daniilidis_block)
    if rot[2] <= SINGULAR_RATIO * rot[0]:
        raise DegenerateDataError(f"daniilidis: the rotation of X is not unique: {_PARALLEL}")
    _, sigma, Vt = np.linalg.svd(R)  # the right singular vectors of the stack
    v7, v8 = Vt[6:, _Q_FIRST]  # of the two smallest singular values, as (q_X, q'_X)
    u1, v1, u2, v2 = v7[:4], v7[4:], v8[:4], v8[4:]
    # eqs. 34-35: q = l1 u1 + l2 u2 with q . q' = 0 and |q| = 1; s = l1 / l2 solves a s^2 + b s + c = 0
    qa, qb, qc = u1 @ v1, u1 @ v2 + u2 @ v1, u2 @ v2
    disc = qb * qb - 4.0 * qa * qc
    root = np.sqrt(max(disc, 0.0))  # < 0 only for data no rigid X fits: the nearest, double root
    roots = ((-qb + root) / (2.0 * qa), (-qb - root) / (2.0 * qa)) if qa != 0 else (-qc / qb,)
    norms = [s * s * (u1 @ u1) + 2.0 * s * (u1 @ u2) + u2 @ u2 for s in roots]  # |s u1 + u2|^2
    k = int(np.argmax(norms))  # OpenCV's choice: the larger |s u1 + u2|
    l2 = np.sqrt(1.0 / norms[k])
    dq = roots[k] * l2 * v7 + l2 * v8
    X = pose_from_dual_quat(dq[:4], dq[4:])
    diagnostics: dict[str, Any] = {"singular_values": sigma[-3:].tolist(), "discriminant": float(disc)}
    if disc < 0:
        diagnostics["warnings"] = [(
            "daniilidis: the motions are too noisy for the dual-quaternion constraints to have an "
            "exact solution; the answer uses the nearest one and is less accurate. Use 'auto' instead"
        )]
    return X, diagnostics


def daniilidis(A: Any, B: Any) -> np.ndarray:
    """X: (4, 4) from motions A, B: (m, 4, 4) by Daniilidis' dual-quaternion method.

    K. Daniilidis, "Hand-eye calibration using dual quaternions", Int. J. Robotics Research
    18(3), 286-298, 1999. With the dual quaternions (q, q') of A_i and B_i (scalar part of q >= 0
    for both, as OpenCV), their vector parts a, a', b, b' give per motion the 6x8 block of eq. 31,
    [[a - b, [a + b]_x, 0, 0], [a' - b', [a' + b']_x, a - b, [a + b]_x]] (q_X; q'_X) = 0. The
    solution lies in the span of the right singular vectors v7, v8 of the two smallest singular
    values of the stacked matrix; the constraints |q_X| = 1 and q_X . q'_X = 0 (eqs. 34-35) give a
    quadratic for the combination, whose root with the larger |q| is taken (as OpenCV). NOT unit
    invariant on noisy data (the SVD weighs rotation rows against dual-part rows, which carry the
    length unit). DegenerateDataError when the rotation rows leave q_X undetermined.
    """
    return _daniilidis(_data(A, B))[0]


@dataclasses.dataclass(frozen=True)
class TsaiOptions:
    select_motions: bool = True  # OpenCV's selection by rotation angle (module docstring)

    def __post_init__(self) -> None:
        check_bool("select_motions", self.select_motions)


def _run(method):
    """run(data, options, backend) of a spec: `method` (one of _tsai, ...) on data.A, data.B."""

    def run(data: AXXBData, options: Any, backend: str) -> SolverOutput:
        X, diagnostics = method(data, **dataclasses.asdict(options))
        status = Status.OPTIMAL_INACCURATE if diagnostics.get("warnings") else Status.OPTIMAL
        return SolverOutput(unknowns={"X": X}, status=status, diagnostics=diagnostics)

    return run


SPECS = (
    SolverSpec(
        name="tsai", problems=("axxb",), run=_run(_tsai), options=TsaiOptions,
        summary="Tsai-Lenz: rotation from modified Rodrigues vectors (OpenCV's motion selection), then translation",
        citation="R. Y. Tsai, R. K. Lenz, IEEE Trans. Robotics and Automation 5(3), 345-358, 1989",
        unit_invariant=True,
    ),
    SolverSpec(
        name="park", problems=("axxb",), run=_run(_park),
        summary="Park-Martin: rotation (M^T M)^-1/2 M^T from the rotation logarithms, then translation",
        citation="F. C. Park, B. J. Martin, IEEE Trans. Robotics and Automation 10(5), 717-721, 1994",
        unit_invariant=True,
    ),
    SolverSpec(
        name="horaud", problems=("axxb",), run=_run(_horaud),
        summary="Horaud-Dornaika: rotation quaternion as an eigenvector, then translation",
        citation="R. Horaud, F. Dornaika, Int. J. Robotics Research 14(3), 195-210, 1995",
        unit_invariant=True,
    ),
    SolverSpec(
        name="andreff", problems=("axxb",), run=_run(_andreff),
        summary="Andreff-Horaud-Espiau: rotation and translation in one Kronecker least squares",
        citation="N. Andreff, R. Horaud, B. Espiau, 3DIM'99, 430-436, 1999",
        unit_invariant=False,  # rotation and translation rows weighed by the length unit
    ),
    SolverSpec(
        name="daniilidis", problems=("axxb",), run=_run(_daniilidis),
        summary="Daniilidis: rotation and translation at once from an SVD on dual quaternions",
        citation="K. Daniilidis, Int. J. Robotics Research 18(3), 286-298, 1999",
        unit_invariant=False,  # the SVD weighs rotation against dual-part rows
    ),
)


@hookimpl
def register_solvers(register):
    for spec in SPECS:
        register(spec)
