"""A third-party solver for handeye's problems "axyb" (A_i X = Y B_i) and "axxb" (A_i X = X B_i),
in one module: one solver name serving two problems.

``example-kron`` follows Shah (2013): with column-major vec, R_Ai R_X = R_Y R_Bi gives
(R_Bi kron R_Ai) vec(R_X) = vec(R_Y), so vec(R_X) and vec(R_Y) are the top right and left
singular vectors of S = sum_i R_Bi kron R_Ai (singular value m on exact data). Each is rescaled
to a rotation (sign from the determinant, then the nearest rotation by SVD); the translations
follow by linear least squares from R_Ai t_X - t_Y = R_Y t_Bi - t_Ai. For AX=XB the same S has
vec(R_X) as both singular vectors (R_Y = R_X), and t_X follows from (I - R_Ai) t_X = t_Ai - R_X t_Bi.

The registry keeps one spec per (solver name, problem): this module registers two specs under
the same name, one per problem, each with its own run function (and, if they differed, its own
options and backends). `handeye list` shows one row, "example-kron [axyb, axxb]".

handeye finds this module through the entry point in pyproject.toml:

    [project.entry-points.handeye]
    example-solver = "handeye_example_solver"

and calls its `register_solvers` hook. The host validates the data (shapes, SE(3), at least 3
pairs), parses options, times the solve and checks that X and Y are in SE(3).
"""

from __future__ import annotations

import numpy as np

import handeye


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    """Rotation closest to M: (3, 3) in Frobenius norm, det +1 (Procrustes by SVD)."""
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def _as_rotation(v: np.ndarray) -> np.ndarray:
    """The rotation whose column-major vec is parallel to the unit vector v: (9,)."""
    M = v.reshape(3, 3, order="F")
    return _nearest_rotation(np.sign(np.linalg.det(M)) * M)  # v is defined up to sign


def _kron_svd(data):
    """SVD of S = sum_n kron(R_Bn, R_An): S[(i, k), (j, l)] = sum_n RB[n, i, j] * RA[n, k, l]."""
    S = np.einsum("nij,nkl->ikjl", data.B[:, :3, :3], data.A[:, :3, :3]).reshape(9, 9)
    return np.linalg.svd(S)


def run(data, options, backend: str) -> handeye.SolverOutput:
    """A_i X = Y B_i. data.A, data.B: read-only (m, 4, 4) float64 stacks, validated by handeye."""
    RA, tA = data.A[:, :3, :3], data.A[:, :3, 3]
    tB = data.B[:, :3, 3]
    m = len(RA)
    U, sigma, Vt = _kron_svd(data)
    RX, RY = _as_rotation(Vt[0]), _as_rotation(U[:, 0])
    # R_Ai t_X - t_Y = R_Y t_Bi - t_Ai, stacked over the pairs: (3m, 6) [t_X; t_Y] = (3m,)
    J = np.concatenate([RA, np.broadcast_to(-np.eye(3), RA.shape)], axis=2).reshape(-1, 6)
    t, *_ = np.linalg.lstsq(J, (tB @ RY.T - tA).reshape(-1), rcond=None)
    X, Y = np.eye(4), np.eye(4)
    X[:3, :3], X[:3, 3] = RX, t[:3]
    Y[:3, :3], Y[:3, 3] = RY, t[3:]
    return handeye.SolverOutput(
        unknowns={"X": X, "Y": Y},
        status=handeye.Status.OPTIMAL,
        # sigma[0] = m on exact data; sigma[1] / m near 1 means the rotations are undetermined
        diagnostics={"singular_values_over_m": (sigma[:2] / m).tolist()},
    )


def run_axxb(data, options, backend: str) -> handeye.SolverOutput:
    """A_i X = X B_i (relative motions). data.A, data.B as for `run`."""
    RA, tA, tB = data.A[:, :3, :3], data.A[:, :3, 3], data.B[:, :3, 3]
    m = len(RA)
    U, sigma, Vt = _kron_svd(data)
    RX = _as_rotation(Vt[0])
    # (I - R_Ai) t_X = t_Ai - R_X t_Bi, stacked over the motions: (3m, 3) t_X = (3m,)
    t, *_ = np.linalg.lstsq((np.eye(3) - RA).reshape(-1, 3), (tA - tB @ RX.T).reshape(-1), rcond=None)
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = RX, t
    return handeye.SolverOutput(unknowns={"X": X}, status=handeye.Status.OPTIMAL,
                                diagnostics={"singular_values_over_m": (sigma[:2] / m).tolist()})


SUMMARY = "example third-party plugin: SVD of sum R_B kron R_A, then translations by least squares"
CITATION = "M. Shah, J. Mech. Robot. 5(3), 2013 (Kronecker product method)"
SPEC = handeye.SolverSpec(name="example-kron", problems=("axyb",), run=run, summary=SUMMARY,
                          citation=CITATION, unit_invariant=True)
SPEC_AXXB = handeye.SolverSpec(name="example-kron", problems=("axxb",), run=run_axxb, summary=SUMMARY,
                               citation=CITATION, unit_invariant=True)


@handeye.hookimpl
def register_solvers(register):
    register(SPEC)
    register(SPEC_AXXB)
