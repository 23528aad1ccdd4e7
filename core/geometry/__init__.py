"""Geometry on arrays only: SE(3) / SO(3) helpers (`se3`, `so3_fast`), dual quaternions
(`dualquat`), robot forward kinematics (`kinematics`) and small linear-algebra helpers (`linalg`).
Depends on nothing else of handeye but its error types.
"""
