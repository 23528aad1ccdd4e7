"""`opencv`: OpenCV's robot-world / hand-eye solvers as a reference (`cv2.calibrateRobotWorldHandEye`).

OpenCV solves A X = Z B in its own naming. For handeye's A_i X = Y B_i (paper eq. 2) the data go
in these slots and the answers come back from these (docs/conventions.md):

    A_i -> R_world2cam, t_world2cam        B_i -> R_base2gripper, t_base2gripper
    X   <- R_base2world, t_base2world      Y   <- R_gripper2cam, t_gripper2cam

(checked by tests/plugins/test_opencv.py: noise-free data are recovered to ~1e-12).

Option ``method``: ``"shah"`` (default; CALIB_ROBOT_WORLD_HAND_EYE_SHAH, Shah 2013: rotations from
the SVD of sum_i R_Bi kron R_Ai, then translations by least squares) or ``"li"``
(CALIB_ROBOT_WORLD_HAND_EYE_LI, Li, Wang, Wu 2010: rotations and translations together by least
squares on the Kronecker system, which is the paper's eq. 8 without normalisation). The method is
always passed to OpenCV by keyword. handeye's own NumPy `shah` and `li` plugins implement the same
methods (tests/plugins/test_shah_li.py checks equality to 1e-9 through this plugin).

Unit invariance is declared for method "shah" only: SHAH's rotations use the rotations only and
its translations enter linearly (measured with translations scaled by 1e-3 and 1e3: rotations
identical, translations equal to ~1e-13 of the data scale). LI is *not* unit invariant: OpenCV
does not normalise the translation rows, so data in mm or in m give different rotations
(measured: ~1e-3 rad apart on the shared suite's noisy case at s = 1e-3).

Rotations: OpenCV computes in float64 and its results are orthonormal to ~1e-15 in practice. A
result is re-projected onto SO(3) by SVD (`handeye.geometry.se3.project_to_so3`) only if its
|R^T R - I| exceeds `REPROJECT_ABOVE`; the names of re-projected unknowns are reported in
``diagnostics["reprojected"]`` (normally empty), so the answer is OpenCV's own whenever possible.

Problem ``axxb`` (A_i X = X B_i, relative motions; a second spec under the same name,
`SPEC_AXXB`) uses ``cv2.calibrateHandEye``. Option ``method``: ``"tsai"``, ``"park"`` (default),
``"horaud"``, ``"andreff"`` or ``"daniilidis"`` (CALIB_HAND_EYE_*; handeye's own `tsai`, `park`,
`horaud`, `andreff` and `daniilidis` solvers implement the same methods, equal to ~1e-13). OpenCV
takes absolute poses G_k = T_base_gripper (gripper2base) and C_k = T_cam_target (target2cam),
forms every pair i < j itself, A = inv(G_j) G_i and B = C_j inv(C_i), and returns X =
T_gripper_cam (cam2gripper). Given motions, `stations` rebuilds absolute poses whose pairs are
those motions, so that the answer equals OpenCV's on the user's own poses (measured <= 1e-13;
tests/plugins/test_classic_handeye.py checks 1e-9):
- motions of every pair of n stations in OpenCV's order (``motions(..., pairing="all")``, the
  default): the stations rebuilt by `AXXBData.stations` (G_0 = H_0 = I, G_j = inv(A_(0,j)),
  H_j = B_(0,j) from the first n - 1 motions, checked against all of them);
- otherwise the chain of `absolute_chain`: G_0 = H_0 = I, G_k = G_(k-1) inv(A_k),
  H_k = B_k H_(k-1), so that inv(G_k) G_(k-1) = A_k and H_k inv(H_(k-1)) = B_k. For motions built
  consecutively from absolute poses P_k, Q_k (``pairing="consecutive"``) the chain is
  G_k = inv(P_0) P_k, H_k = Q_k inv(Q_0), whose pairs are exactly the motions of the original
  poses. For any other set of motions OpenCV then also sees the products of consecutive ones,
  A_(i+1..j) (``diagnostics["stations"]`` says which way was used). Unit invariance is declared for tsai, park and horaud (rotation first, from rotations
only); andreff and daniilidis weigh rotation rows against translation rows and change with the
length unit on noisy data (docs/solvers/opencv.md).

Availability: backend ``"opencv"`` needs the module ``cv2`` (pip install opencv-python-headless)
*with* ``calibrateRobotWorldHandEye`` (OpenCV >= 4.5.x; opencv-python-headless 5.0.0.93's module no
longer has it), and for ``axxb`` with ``calibrateHandEye``. `check` / `check_hand_eye` report a
missing function as the reason the backend is unavailable; this module never imports cv2 at
import time, so the plugin always loads and ``handeye list`` shows the reason.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from handeye import SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import DegenerateDataError, SolverError
from handeye.framework.options import check_choice
from handeye.geometry.se3 import (
    inverse,
    make_pose,
    orthonormality_error,
    project_to_so3,
)
from handeye.problems.axxb import AXXBData
from handeye.problems.axyb import AXYBData

#: method option -> name of OpenCV's flag (looked up on cv2 only when solving)
METHODS = {"shah": "CALIB_ROBOT_WORLD_HAND_EYE_SHAH", "li": "CALIB_ROBOT_WORLD_HAND_EYE_LI"}
FUNCTION = "calibrateRobotWorldHandEye"
#: problem axxb: method option -> name of OpenCV's flag of cv2.calibrateHandEye
HAND_EYE_METHODS = {
    "tsai": "CALIB_HAND_EYE_TSAI", "park": "CALIB_HAND_EYE_PARK", "horaud": "CALIB_HAND_EYE_HORAUD",
    "andreff": "CALIB_HAND_EYE_ANDREFF", "daniilidis": "CALIB_HAND_EYE_DANIILIDIS",
}
HAND_EYE_FUNCTION = "calibrateHandEye"
#: methods of calibrateHandEye whose answer does not depend on the length unit (module docstring)
HAND_EYE_UNIT_INVARIANT = ("tsai", "park", "horaud")
#: |R^T R - I| of an OpenCV rotation above which it is re-projected onto SO(3) by SVD
REPROJECT_ABOVE = 1e-12


@dataclasses.dataclass(frozen=True)
class Options:
    method: str = "shah"

    def __post_init__(self) -> None:
        check_choice("method", self.method, tuple(METHODS))


@dataclasses.dataclass(frozen=True)
class HandEyeOptions:
    method: str = "park"

    def __post_init__(self) -> None:
        check_choice("method", self.method, tuple(HAND_EYE_METHODS))


def _missing(backend: str, names: tuple[str, ...], function: str) -> str | None:
    """Why OpenCV cannot run here: cv2 fails to import, or lacks one of `names`."""
    try:
        import cv2
    except ImportError as exc:  # present (find_spec found it) but broken
        return f"backend {backend!r} of solver 'opencv': importing cv2 failed: {exc}"
    missing = [name for name in names if not hasattr(cv2, name)]
    if missing:
        return (
            f"backend {backend!r} of solver 'opencv': this OpenCV ({getattr(cv2, '__version__', '?')}) "
            f"has no cv2.{', cv2.'.join(missing)}; install opencv-python-headless>=4.8,<5 "
            f"(5.0.0.93 dropped {function})"
        )
    return None


def check(backend: str) -> str | None:
    """Why OpenCV cannot run here (cv2 fails to import, or lacks calibrateRobotWorldHandEye)."""
    return _missing(backend, (FUNCTION, *METHODS.values()), FUNCTION)


def check_hand_eye(backend: str) -> str | None:
    """Why OpenCV cannot solve ``axxb`` here (cv2 fails to import, or lacks calibrateHandEye)."""
    return _missing(backend, (HAND_EYE_FUNCTION, *HAND_EYE_METHODS.values()), HAND_EYE_FUNCTION)


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


def absolute_chain(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute poses G, H: (m + 1, 4, 4) whose consecutive motions are A, B: (m, 4, 4):
    G_0 = H_0 = I, G_k = G_(k-1) inv(A_k), H_k = B_k H_(k-1) (module docstring)."""
    G, H = np.empty((len(A) + 1, 4, 4)), np.empty((len(B) + 1, 4, 4))
    G[0] = H[0] = np.eye(4)
    A_inv = inverse(A)
    for k in range(len(A)):
        G[k + 1] = G[k] @ A_inv[k]
        H[k + 1] = B[k] @ H[k]
    return G, H


def stations(data: AXXBData) -> tuple[np.ndarray, np.ndarray, str]:
    """Absolute poses G (gripper2base), H (target2cam) whose pairs, as OpenCV forms them, are the
    motions of `data`, and how they were found: "all pairs" (`AXXBData.stations`: G = A_abs,
    H = inv(B_abs)) or "chain" (`absolute_chain`); module docstring."""
    if data.stations is not None:
        A_abs, B_abs = data.stations
        return A_abs, inverse(B_abs), "all pairs"
    return (*absolute_chain(data.A, data.B), "chain")


def calibrate_hand_eye(G: np.ndarray, C: np.ndarray, method: str) -> np.ndarray:
    """X = cam2gripper: (4, 4), straight from cv2.calibrateHandEye on the absolute poses
    G = gripper2base, C = target2cam: (n, 4, 4) each (rotation block not re-projected)."""
    import cv2

    try:
        R, t = cv2.calibrateHandEye(
            list(np.ascontiguousarray(G[:, :3, :3])), list(np.ascontiguousarray(G[:, :3, 3:])),
            list(np.ascontiguousarray(C[:, :3, :3])), list(np.ascontiguousarray(C[:, :3, 3:])),
            method=getattr(cv2, HAND_EYE_METHODS[method]),
        )
    except cv2.error as exc:
        raise SolverError(f"cv2.calibrateHandEye (method {method!r}) failed: {' '.join(str(exc).split())}") from exc
    return make_pose(R, np.ravel(t))


def _output(unknowns: dict[str, np.ndarray], method: str) -> SolverOutput:
    """The unknowns OpenCV returned, checked finite, re-projected only when off SO(3)."""
    import cv2

    reprojected = []
    for name, T in unknowns.items():
        if not np.all(np.isfinite(T)):
            raise SolverError(f"OpenCV ({method}) returned a non-finite {name}: the poses do not "
                              "determine it (do they rotate about at least two different axes?); "
                              "try another method")
        if orthonormality_error(T[:3, :3]) > REPROJECT_ABOVE:
            unknowns[name] = make_pose(project_to_so3(T[:3, :3]), T[:3, 3])
            reprojected.append(name)
    return SolverOutput(
        unknowns=unknowns,
        status=Status.OPTIMAL,
        diagnostics={"method": method, "opencv_version": cv2.__version__, "reprojected": reprojected},
    )


def run(data: AXYBData, options: Options, backend: str) -> SolverOutput:
    return _output(dict(zip(("X", "Y"), calibrate(data.A, data.B, options.method))), options.method)


def run_hand_eye(data: AXXBData, options: HandEyeOptions, backend: str) -> SolverOutput:
    G, H, how = stations(data)
    X = calibrate_hand_eye(G, H, options.method)
    if options.method == "tsai" and np.array_equal(X, np.eye(4)):  # OpenCV's "no answer" (it only logs)
        raise DegenerateDataError(
            "OpenCV's Tsai found fewer than 2 motion pairs rotating by 17.3 to 116.4 deg and returned no "
            "answer: record motions with larger rotations, or use another method"
        )
    output = _output({"X": X}, options.method)
    output.diagnostics["stations"] = how
    return output


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


SPEC_AXXB = SolverSpec(
    name="opencv",
    problems=("axxb",),
    run=run_hand_eye,
    backends={"opencv": ("cv2",)},
    default_backend="opencv",
    options=HandEyeOptions,
    summary="reference: OpenCV's calibrateHandEye, method 'park' (default), 'tsai', 'horaud', 'andreff' "
            "or 'daniilidis'",
    citation="OpenCV calib3d calibrateHandEye; Tsai & Lenz 1989; Park & Martin 1994; Horaud & Dornaika 1995; "
             "Andreff, Horaud & Espiau 1999; Daniilidis 1999",
    unit_invariant=lambda options: options.method in HAND_EYE_UNIT_INVARIANT,
    exact=True,
    check=check_hand_eye,
    variants=("method", ("tsai", "park", "horaud", "andreff", "daniilidis")),
)


@hookimpl
def register_solvers(register):
    register(SPEC)
    register(SPEC_AXXB)
