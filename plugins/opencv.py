"""`opencv`: OpenCV's robot-world / hand-eye solvers as a reference (`cv2.calibrateRobotWorldHandEye`).

OpenCV solves A X = Z B in its own naming. For handeye's A_i X = Y B_i (paper eq. 2) the data go
in these slots and the answers come back from these (docs/conventions.md):

    A_i -> R_world2cam, t_world2cam        B_i -> R_base2gripper, t_base2gripper
    X   <- R_base2world, t_base2world      Y   <- R_gripper2cam, t_gripper2cam

(checked by tests/test_opencv.py: noise-free data are recovered to ~1e-12).

Option ``method``: ``"shah"`` (default; CALIB_ROBOT_WORLD_HAND_EYE_SHAH, Shah 2013: rotations from
the SVD of sum_i R_Bi kron R_Ai, then translations by least squares) or ``"li"``
(CALIB_ROBOT_WORLD_HAND_EYE_LI, Li, Wang, Wu 2010: rotations and translations together by least
squares on the Kronecker system, which is the paper's eq. 8 without normalisation). The method is
always passed to OpenCV by keyword. handeye's own NumPy `shah` and `li` plugins implement the same
methods (tests/test_shah_li.py checks equality to 1e-9 through this plugin).

Unit invariance is declared for method "shah" only: SHAH's rotations use the rotations only and
its translations enter linearly (measured with translations scaled by 1e-3 and 1e3: rotations
identical, translations equal to ~1e-13 of the data scale). LI is *not* unit invariant: OpenCV
does not normalise the translation rows, so data in mm or in m give different rotations
(measured: ~1e-3 rad apart on the shared suite's noisy case at s = 1e-3).

Rotations: OpenCV computes in float64 and its results are orthonormal to ~1e-15 in practice. A
result is re-projected onto SO(3) by SVD (`handeye.se3.project_to_so3`) only if its
|R^T R - I| exceeds `REPROJECT_ABOVE`; the names of re-projected unknowns are reported in
``diagnostics["reprojected"]`` (normally empty), so the answer is OpenCV's own whenever possible.

Availability: backend ``"opencv"`` needs the module ``cv2`` (pip install opencv-python-headless)
*with* ``calibrateRobotWorldHandEye`` (OpenCV >= 4.5.x; opencv-python-headless 5.0.0.93's module no
longer has it). `check` reports a missing function as the reason the backend is unavailable;
this module never imports cv2 at import time, so the plugin always loads and ``handeye list``
shows the reason.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.errors import SolverError
from handeye.options import check_choice
from handeye.problems.axyb import AXYBData
from handeye.se3 import make_pose, orthonormality_error, project_to_so3

#: method option -> name of OpenCV's flag (looked up on cv2 only when solving)
METHODS = {"shah": "CALIB_ROBOT_WORLD_HAND_EYE_SHAH", "li": "CALIB_ROBOT_WORLD_HAND_EYE_LI"}
FUNCTION = "calibrateRobotWorldHandEye"
#: |R^T R - I| of an OpenCV rotation above which it is re-projected onto SO(3) by SVD
REPROJECT_ABOVE = 1e-12


@dataclasses.dataclass(frozen=True)
class Options:
    method: str = "shah"

    def __post_init__(self) -> None:
        check_choice("method", self.method, tuple(METHODS))


def check(backend: str) -> str | None:
    """Why OpenCV cannot run here (cv2 fails to import, or lacks calibrateRobotWorldHandEye)."""
    try:
        import cv2
    except ImportError as exc:  # present (find_spec found it) but broken
        return f"backend {backend!r} of solver 'opencv': importing cv2 failed: {exc}"
    missing = [name for name in (FUNCTION, *METHODS.values()) if not hasattr(cv2, name)]
    if missing:
        return (
            f"backend {backend!r} of solver 'opencv': this OpenCV ({getattr(cv2, '__version__', '?')}) "
            f"has no cv2.{', cv2.'.join(missing)}; install opencv-python-headless>=4.8,<5 "
            "(5.0.0.93 dropped calibrateRobotWorldHandEye)"
        )
    return None


def calibrate(A: np.ndarray, B: np.ndarray, method: str) -> tuple[np.ndarray, np.ndarray]:
    """X, Y: (4, 4) each, straight from cv2.calibrateRobotWorldHandEye (A, B: (m, 4, 4)).

    Rotation blocks exactly as OpenCV returns them (not re-projected).
    """
    import cv2

    try:
        R_bw, t_bw, R_gc, t_gc = cv2.calibrateRobotWorldHandEye(
            list(np.ascontiguousarray(A[:, :3, :3])), list(np.ascontiguousarray(A[:, :3, 3:])),
            list(np.ascontiguousarray(B[:, :3, :3])), list(np.ascontiguousarray(B[:, :3, 3:])),
            method=getattr(cv2, METHODS[method]),
        )
    except cv2.error as exc:
        raise SolverError(f"cv2.calibrateRobotWorldHandEye (method {method!r}) failed: {' '.join(str(exc).split())}") from exc
    return make_pose(R_bw, np.ravel(t_bw)), make_pose(R_gc, np.ravel(t_gc))


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    import cv2

    unknowns = dict(zip(("X", "Y"), calibrate(data.A, data.B, options.method)))
    reprojected = []
    for name, T in unknowns.items():
        if not np.all(np.isfinite(T)):
            raise SolverError(f"OpenCV ({options.method}) returned a non-finite {name}: the data "
                              "do not determine it")
        if orthonormality_error(T[:3, :3]) > REPROJECT_ABOVE:
            unknowns[name] = make_pose(project_to_so3(T[:3, :3]), T[:3, 3])
            reprojected.append(name)
    return SolverOutput(
        unknowns=unknowns,
        status=Status.OPTIMAL,
        diagnostics={"method": options.method, "opencv_version": cv2.__version__, "reprojected": reprojected},
    )


SPEC = SolverSpec(
    name="opencv",
    problems=("axyb",),
    run=run,
    backends={"opencv": ("cv2",)},
    default_backend="opencv",
    options=Options,
    summary="reference: OpenCV's calibrateRobotWorldHandEye, method 'shah' (default) or 'li'",
    citation="OpenCV calib3d calibrateRobotWorldHandEye; M. Shah, J. Mech. Robot. 5(3) 031007, 2013; "
             "A. Li, L. Wang, D. Wu, Int. J. Phys. Sci. 5(10) 1530-1536, 2010",
    unit_invariant=lambda options: options.method == "shah",  # "li" is not (module docstring)
    exact=True,
    check=check,
)


@hookimpl
def register_solvers(register):
    register(SPEC)
