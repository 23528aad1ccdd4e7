"""The kinematic model of A_i X = Y B_i with A_i = FK(q_i; DH): forward kinematics with the
sensitivity of the flange pose to every DH parameter, and which parameters hand-eye data can
determine at all (structural identifiability) and on given stations.

Parameters, per joint j (1-based in messages), in the columns of `DHArm.table`: a, alpha, d,
offset (standard DH: the joint's transform is Rz(q_j + offset_j) Tz(d_j) Tx(a_j) Rx(alpha_j)).
A change dp of parameter k moves the flange pose on the left, in the base frame:
A(p + dp) = exp(xi_k dp) A(p) to first order, with the twist xi_k = (omega, v) (`twists`):

    offset_j: (z, p x z)    d_j: (0, z)     a_j: (0, x')    alpha_j: (x', p' x x')

z, p the axis and origin of frame j-1 (before the joint), x' the x axis of the frame after
Rz Tz, p' its origin after Tx (Hollerbach & Wampler, "The calibration index and taxonomy for
robot kinematic calibration methods", IJRR 15(6), 1996: the columns of the identification
Jacobian).

Identifiability (`structural`): with X and Y unknown, a parameter is identifiable when its
column of the linearised equation, [Ad(A_i) (X), -I (Y), xi_i (parameters)] stacked over
generic stations, is not in the span of X's, Y's and the earlier parameters' columns. That
reproduces the known rules (Everett, Driels & Mooring 1987; Zhuang & Roth 1992): the first
joint's offset and d move the base frame (absorbed in Y), the last joint's four parameters move
the flange frame (absorbed in X), and the d of a joint whose axis is parallel to the previous
one's is redundant with that one's d; for a 6R arm 4 x 6 - 6 = 18 parameters remain, 17 with one
pair of parallel axes (the LR Mate's joints 2 and 3).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from handeye.geometry.kinematics import DHArm

KINDS = DHArm.COLUMNS  # ("a", "alpha", "d", "offset")
#: which columns of the table are lengths (scaled with the unit); the others are angles (rad)
IS_LENGTH = np.array([True, False, True, False])
#: generic stations of the structural analysis, and the relative size of a column outside the
#: span of the others below which the parameter is not identifiable (exact dependencies give ~1e-15)
STRUCTURAL_STATIONS = 24
INDEPENDENT = 1e-6


def parameter_name(index: int) -> str:
    """'J3 d' for flat parameter index 4 * (3 - 1) + 2."""
    return f"J{index // 4 + 1} {KINDS[index % 4]}"


def length_mask(joints: int) -> np.ndarray:
    """Which of the 4 * joints flat parameters are lengths: (4 * joints,) bool."""
    return np.tile(IS_LENGTH, joints)


def twists(q: np.ndarray, table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flange poses and their sensitivities: A (m, 4, 4) = FK(q; table) and Xi (m, 6, 4n), the
    base-frame twist (omega, v) of each parameter (module docstring), for q (m, n) rad and a DH
    table (n, 4) (columns a, alpha, d, offset)."""
    q = np.asarray(q, dtype=float)
    m, n = q.shape
    P = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
    Xi = np.zeros((m, 6, 4 * n))
    for j in range(n):
        a, alpha, d, off = table[j]
        z, p = P[:, :3, 2], P[:, :3, 3]
        Xi[:, :3, 4 * j + 3], Xi[:, 3:, 4 * j + 3] = z, np.cross(p, z)  # offset
        Xi[:, 3:, 4 * j + 2] = z  # d
        th = q[:, j] + off
        c, s = np.cos(th), np.sin(th)
        Rz = np.zeros((m, 3, 3))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
        R = P[:, :3, :3] @ Rz
        x = R[:, :, 0]
        origin = p + d * z + a * x
        Xi[:, 3:, 4 * j] = x  # a
        Xi[:, :3, 4 * j + 1], Xi[:, 3:, 4 * j + 1] = x, np.cross(origin, x)  # alpha
        ca, sa = np.cos(alpha), np.sin(alpha)
        Rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
        P[:, :3, :3] = R @ Rx
        P[:, :3, 3] = origin
    return P, Xi


def adjoint(T: np.ndarray) -> np.ndarray:
    """Ad(T) acting on twists (omega, v): (m, 4, 4) -> (m, 6, 6), [[R, 0], [[t]_x R, R]]."""
    R, t = T[:, :3, :3], T[:, :3, 3]
    out = np.zeros((len(T), 6, 6))
    out[:, :3, :3] = out[:, 3:, 3:] = R
    tx = np.zeros((len(T), 3, 3))
    tx[:, 0, 1], tx[:, 0, 2], tx[:, 1, 2] = -t[:, 2], t[:, 1], -t[:, 0]
    out[:, 3:, :3] = (tx - np.swapaxes(tx, 1, 2)) @ R
    return out


def design(q: np.ndarray, table: np.ndarray, scale: float) -> np.ndarray:
    """The linearised equation on stations q: (6m, 12 + 4n) columns [X (6), Y (6), parameters],
    lengths in units of `scale` (so that rotation and translation rows and columns compare)."""
    A, Xi = twists(q, table / np.where(IS_LENGTH, scale, 1.0))
    m = len(q)
    M = np.concatenate([adjoint(A), np.broadcast_to(-np.eye(6), (m, 6, 6)), Xi], axis=2)
    return M.reshape(6 * m, -1)


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """Which DH parameters hand-eye data determine (flat indices 4 (j - 1) + column), and for the
    others what they are confounded with (words: "Y", "X", "J2 d")."""

    identifiable: tuple[int, ...]
    confounded: tuple[tuple[int, tuple[str, ...]], ...]

    def words(self, table: np.ndarray) -> str:
        """The non-identifiable parameters in the user's words, grouped by reason."""
        groups: dict[str, list[str]] = {}
        for index, partners in self.confounded:
            if partners == ("Y",):
                reason = "they move the robot's base frame: absorbed in Y"
            elif partners == ("X",):
                reason = "they move the flange frame: absorbed in X"
            else:
                reason = f"confounded with {', '.join(partners)}"
                j = index // 4
                if KINDS[index % 4] == "d" and j > 0 and abs(np.sin(table[j - 1, 1])) < 1e-9:
                    reason = f"joints {j} and {j + 1} have parallel axes: only J{j} d + J{j + 1} d is determined"
            groups.setdefault(reason, []).append(parameter_name(index))
        return "; ".join(f"{', '.join(names)} ({reason})" for reason, names in groups.items())


@functools.lru_cache(maxsize=32)
def _structural(table_bytes: bytes, joints: int) -> Identifiability:
    table = np.frombuffer(table_bytes).reshape(joints, 4)
    q = np.random.default_rng(12345).uniform(-np.pi, np.pi, (STRUCTURAL_STATIONS, joints))
    A = DHArm.from_table(table).forward(q)
    scale = float(np.sqrt(np.mean(np.sum(A[:, :3, 3] ** 2, axis=1)))) or 1.0
    M = design(q, table, scale)
    basis = np.linalg.qr(M[:, :12])[0]
    chosen: list[int] = []
    confounded: list[tuple[int, tuple[str, ...]]] = []
    for k in range(4 * joints):
        c = M[:, 12 + k]
        size = np.linalg.norm(c)
        rest = c - basis @ (basis.T @ c)
        if size > 0 and np.linalg.norm(rest) > INDEPENDENT * size:
            chosen.append(k)
            basis = np.column_stack([basis, rest / np.linalg.norm(rest)])
            continue
        others = np.column_stack([M[:, :12], M[:, [12 + i for i in chosen]]])
        beta = np.linalg.lstsq(others, c, rcond=None)[0]
        parts = np.linalg.norm(others * beta, axis=0) > 1e-3 * max(size, 1e-300)
        names = (["X"] if parts[:6].any() else []) + (["Y"] if parts[6:12].any() else []) + \
            [parameter_name(chosen[i]) for i in np.flatnonzero(parts[12:])]
        confounded.append((k, tuple(names) or ("nothing: the parameter does not move the flange",)))
    return Identifiability(tuple(chosen), tuple(confounded))


def structural(table: np.ndarray) -> Identifiability:
    """The identifiable parameters of an arm with nominal DH `table` (n, 4) from hand-eye data
    with X and Y unknown, chosen in table order (module docstring); cached per table."""
    table = np.ascontiguousarray(table, dtype=float)
    return _structural(table.tobytes(), len(table))
