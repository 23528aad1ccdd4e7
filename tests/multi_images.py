"""A small synthetic cell of several cameras and boards, as images: two fixed cameras watching two
ChArUco boards (disjoint marker ids) on the flange, eye-to-hand, rendered at a few robot stations
(`handeye.vision.render.render_boards`), with the robot's pose file, the cameras' intrinsics and a
cell file; the truth (X per board = T_flange_board, Y per camera = T_base_cam) returned with it.
Shared by tests/problems/axyb_multi/test_axyb_multi_images.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from handeye.geometry.se3 import inverse, make_pose
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera
from handeye.vision.render import render_boards

#: the boards on the flange, by name: one ChArUco print each, markers 0..16 and 17..33
BOARDS = {"board0": "charuco:5x7:30mm:22mm:DICT_4X4_50", "board1": "charuco:5x7:30mm:22mm:DICT_4X4_50:first=17"}
CAMERAS = ("cam0", "cam1")
#: 640 x 480 pixels, fx = fy = 600 px, no distortion; the boards ~550 mm away
CAMERA = Camera(np.array([[600.0, 0, 320], [0, 600.0, 240], [0, 0, 1]]), np.zeros(5), size=(640, 480))
#: per image, the noise and blur the renders get (grey levels, px)
NOISE, BLUR = 1.5, 0.6


def pose(rotvec_deg, xyz) -> np.ndarray:
    return make_pose(Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix(), np.asarray(xyz, dtype=float))


def truth() -> dict[str, np.ndarray]:
    """X per board (T_flange_board) and Y per camera (T_base_cam), mm."""
    T_flange_F = pose((5, -8, 30), (10, -20, 120))  # the boards' plate on the flange
    X = {"board0": T_flange_F @ pose((0, 0, 0), (-165, -105, 0)),
         "board1": T_flange_F @ pose((0, 0, 0), (15, -105, 0))}
    T_base_F = pose((150, 20, 10), (900, 100, 600))  # the plate's nominal pose
    Y = {"cam0": T_base_F @ inverse(pose((0, 0, 0), (0, 0, 560))),
         "cam1": T_base_F @ inverse(pose((0, 28, 0), (-40, 0, 600)))}
    return {"X": X, "Y": Y, "T_flange_F": T_flange_F, "T_base_F": T_base_F}


def stations(n: int, seed: int = 7) -> np.ndarray:
    """(n, 4, 4) T_base_flange: the plate turned up to ~15 deg and moved ~50 mm about its nominal pose."""
    t = truth()
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        wiggle = pose(rng.uniform(-22, 22, 3), rng.uniform([-50, -40, -60], [50, 40, 60]))
        out.append(t["T_base_F"] @ wiggle @ inverse(t["T_flange_F"]))
    return np.array(out)


def write_cell(folder: Path, n: int = 8, hide: dict[tuple[str, int], tuple[str, ...]] | None = None,
               seed: int = 7) -> dict[str, np.ndarray]:
    """Render the cell's images into `folder` (images/cam0/00.png, ...), write robot.csv (name,
    x, y, z, qx, qy, qz, qw; mm), cam0.json / cam1.json (intrinsics) and cell.yaml; `hide` leaves
    boards out of some images ((camera, station) -> board names). Returns the truth."""
    t = truth()
    A = stations(n, seed)
    boards = {name: parse_board(spec) for name, spec in BOARDS.items()}
    rng = np.random.default_rng(seed + 1)
    hide = hide or {}
    for cam in CAMERAS:
        (folder / "images" / cam).mkdir(parents=True, exist_ok=True)
        (folder / f"{cam}.json").write_text(json.dumps({"camera_matrix": CAMERA.K.tolist(),
                                                        "distortion_coefficients": CAMERA.dist.tolist(),
                                                        "image_width": 640, "image_height": 480}))
        for i, T_base_flange in enumerate(A):
            scene = [(boards[b], inverse(t["Y"][cam]) @ T_base_flange @ t["X"][b]) for b in BOARDS
                     if b not in hide.get((cam, i), ())]
            image = render_boards(scene, CAMERA, blur=BLUR, noise=NOISE, rng=rng)
            cv2.imwrite(str(folder / "images" / cam / f"{i:02d}.png"), image)
    rows = ["name,x,y,z,qx,qy,qz,qw"]
    for i, T in enumerate(A):
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        rows.append(",".join([f"{i:02d}", *(f"{v:.17g}" for v in (*T[:3, 3], *q))]))
    (folder / "robot.csv").write_text("\n".join(rows) + "\n")
    (folder / "cell.yaml").write_text(CELL_YAML)
    return t


CELL_YAML = """\
setup: eye-to-hand
problem: axyb-multi
robot: {file: robot.csv, format: xyz-quat-xyzw, unit: mm}
observations:
  - {camera: cam0, images: images/cam0, intrinsics: cam0.json}
  - {camera: cam1, images: images/cam1, intrinsics: cam1.json}
targets:
  board0: charuco:5x7:30mm:22mm:DICT_4X4_50
  board1: charuco:5x7:30mm:22mm:DICT_4X4_50:first=17
matching: {method: name}
"""
