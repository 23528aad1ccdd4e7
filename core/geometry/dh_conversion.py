"""A serial chain of revolute joints given by their axes (lines in space at the zero position, as a
URDF gives them) as an exact standard Denavit-Hartenberg table with a constant base and tool
transform: T_base_tip(q) = base @ FK_DH(q) @ tool, for every q (`dh_from_axes`).

Frame 0 has its z axis on joint 1's axis, its origin at the point of that axis nearest the base
origin and its x axis the base x projected onto the plane normal to z (base y when x is along the
axis). Frame i (i = 1 .. n-1) has its z axis on joint i+1's axis and its x axis along the common
normal from axis i to axis i+1 (z_{i-1} x z_i for intersecting axes; for parallel axes the normal
through the origin of frame i-1, so d_i = 0; for coincident axes x_i = x_{i-1}). Row i is then
(a_i, alpha_i, d_i, theta_i) with joint i's offset theta_i the angle from x_{i-1} to x_i about z_{i-1}
at q = 0. The last row is zero (frame n is frame n-1 turned by q_n); the tool transform takes frame
n to the tip. Positive q turns about the axis's direction, as in URDF (right-hand rule), so no
joint sign is needed. (Denavit & Hartenberg 1955; the construction of Craig, "Introduction to
Robotics", Sec. 3.4, in the standard convention.)
"""

from __future__ import annotations

import math

import numpy as np

from handeye.geometry.kinematics import DHArm
from handeye.geometry.se3 import Array, inverse

#: directions whose cross product is below this (sine of their angle) count as parallel
PARALLEL = 1e-9


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _angle(u: np.ndarray, v: np.ndarray, axis: np.ndarray) -> float:
    """The angle turning unit vector u to v about `axis` (both normal to it)."""
    return math.atan2(float(np.cross(u, v) @ axis), float(u @ v))


def dh_from_axes(points: Array, directions: Array, tip: Array) -> tuple[DHArm, Array, Array]:
    """(arm, base, tool) with T_base_tip(q) = base @ arm.forward(q) @ tool exactly.

    points, directions: (n, 3), a point on each joint's axis and its direction (turning positive
    about it), in the base frame at q = 0; tip: (4, 4) T_base_tip at q = 0. base, tool: (4, 4).
    """
    P, Z = np.asarray(points, dtype=float), np.array([_unit(z) for z in np.asarray(directions, dtype=float)])
    n = len(P)
    z0 = Z[0]
    o = P[0] - (P[0] @ z0) * z0
    x = np.array([1.0, 0.0, 0.0]) - z0[0] * z0
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - z0[1] * z0
    x = _unit(x)
    base = np.eye(4)
    base[:3, :3] = np.column_stack([x, np.cross(z0, x), z0])
    base[:3, 3] = o
    rows, z = [], z0
    for i in range(1, n):
        p, zi = P[i], Z[i]
        cross = np.cross(z, zi)
        if np.linalg.norm(cross) < PARALLEL:  # parallel: the normal through the origin of frame i-1
            d = 0.0
            oi = p + ((o - p) @ zi) * zi
            v = oi - o
            xi = _unit(v) if np.linalg.norm(v) > 1e-12 * max(1.0, np.abs(P).max()) else x
        else:  # the common normal: the nearest points of the two axes
            w = o - p
            b, dd, e = float(z @ zi), float(z @ w), float(zi @ w)
            den = 1.0 - b * b
            d = (b * e - dd) / den
            oi = p + ((e - b * dd) / den) * zi
            xi = _unit(cross)
        foot = o + d * z
        a = float((oi - foot) @ xi)
        rows.append((a, _angle(z, zi, xi), d, _angle(x, xi, z)))
        o, x, z = oi, xi, zi
    rows.append((0.0, 0.0, 0.0, 0.0))
    arm = DHArm.from_table(np.array(rows))
    tool = inverse(base @ arm.forward(np.zeros((1, n)))[0]) @ np.asarray(tip, dtype=float)
    return arm, base, tool


__all__ = ["dh_from_axes"]
