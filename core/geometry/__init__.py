"""Geometry on arrays only: SE(3) / SO(3) helpers (`se3`, `so3_fast`), dual quaternions
(`dualquat`), robot forward kinematics (`kinematics`), small linear-algebra helpers (`linalg`),
validating pose stacks (`validation`) and resampling poses in time (`resample`). Depends on
nothing else of handeye but `handeye.base`.

The names a plugin author needs are here (docs/plugins.md): poses built, inverted and compared
(`make_pose`, `inverse`, `rotation_angle`), rotations from and to rotation vectors (`so3_fast`),
random flange poses of a simulated arm (`random_flange_poses`) and a user's pose stack checked
(`pose_stack`).
"""

from handeye.geometry import so3_fast
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import inverse, make_pose, rotation_angle
from handeye.geometry.validation import pose_stack

__all__ = ["inverse", "make_pose", "pose_stack", "random_flange_poses", "rotation_angle", "so3_fast"]
