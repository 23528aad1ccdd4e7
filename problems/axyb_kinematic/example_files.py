"""The example cell of axyb-kinematic as files: a SIMULATED eye-in-hand cell whose arm is off its
nominal DH table (`AXYBKinematic.simulate`), written as the files a real cell records: the joint
readings (``joints.csv``, degrees), the camera's board poses (``camera.csv``, solvePnP's tvec and
rvec), the controller's nominal DH table (``arm.yaml``), a cell file (``cell.yaml``) and the truth
(``truth.json``), so that the bundled example (``handeye/data/kinematic_cell/``,
`handeye.io.examples.kinematic_example_dir`) is reproducible and tests can write noise-free cells.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import LR_MATE_200ID, LR_MATE_SIM_JOINTS
from handeye.geometry.se3 import inverse, make_pose
from handeye.io.arm_files import ArmModel, arm_yaml
from handeye.problems.axyb_kinematic.problem import PROBLEM, random_errors

#: the bundled example: stations, seed, noise on the joint readings (rad) and the camera's poses
#: (rad, mm)
EXAMPLE = {"stations": 40, "seed": 26, "joint_noise": math.radians(0.005), "camera_noise": (0.0005, 0.1)}
NAMES = ("J1", "J2", "J3", "J4", "J5", "J6")


#: the example's camera on the flange (T_flange_cam: 60 mm off its axis, 90 mm out, looking along
#: it) and board (T_base_target: on a panel 850 mm in front of the base and 1.2 m up, tilted
#: 45 deg toward the arm, its printed face (the board's -z) to the camera), mm
CAMERA_ON_FLANGE = make_pose(np.eye(3), [0.0, -60.0, 90.0])
_S = math.sqrt(0.5)
BOARD_IN_BASE = make_pose(np.array([[0.0, -_S, _S], [1.0, 0.0, 0.0], [0.0, _S, _S]]), [850.0, 0.0, 1200.0])
#: a station's view of the board: its distance (mm) and the largest angle (deg) between the
#: optical axis and the direction to the board, and between the board's normal and the camera
VIEW_DISTANCE = (300.0, 900.0)
VIEW_ANGLE_DEG = 25.0
FACING_DEG = 50.0


def viewing_joints(stations: int, rng: np.random.Generator) -> np.ndarray:
    """(stations, 6) joints (rad) in the simulator's box at which the camera (`CAMERA_ON_FLANGE`)
    of the nominal arm sees the board (`BOARD_IN_BASE`) in front of it, near the image's centre
    and facing it: a station a person would record (a joint draw alone put the board behind the
    camera at 37 of 40 stations)."""
    box = LR_MATE_SIM_JOINTS
    found: list[np.ndarray] = []
    while sum(len(f) for f in found) < stations:
        q = rng.uniform(box[:, 0], box[:, 1], size=(20_000, 6))
        T = inverse(LR_MATE_200ID.forward(q) @ CAMERA_ON_FLANGE) @ BOARD_IN_BASE  # board in the camera
        t = T[:, :3, 3]
        distance = np.linalg.norm(t, axis=1)
        ahead = t[:, 2] / np.maximum(distance, 1e-9)  # cos of the board's direction off the optical axis
        facing = np.einsum("mi,mi->m", T[:, :3, 2], t) / np.maximum(distance, 1e-9)  # printed face (-z) to camera
        ok = ((distance >= VIEW_DISTANCE[0]) & (distance <= VIEW_DISTANCE[1])
              & (ahead >= math.cos(math.radians(VIEW_ANGLE_DEG))) & (facing >= math.cos(math.radians(FACING_DEG))))
        found.append(q[ok])
    return np.concatenate(found)[:stations]


def example_cell(*, stations: int = EXAMPLE["stations"], seed: int = EXAMPLE["seed"],
                 noise: bool = True) -> dict[str, Any]:
    """The simulated cell: ``q`` (m, 6) joint readings (rad), ``camera`` (m, 4, 4) T_cam_target
    (mm), ``names`` of the stations, ``errors`` (6, 4) the arm's DH errors (a, alpha, d, offset;
    mm, rad; on the identifiable parameters), ``truth`` X = T_flange_cam, Y = T_base_target. The
    stations view the board as a person would record them (`viewing_joints`)."""
    rng = np.random.default_rng(seed)
    errors = random_errors(LR_MATE_200ID.table, rng)
    q = viewing_joints(stations, rng)
    model = NoiseModel({"A": (EXAMPLE["joint_noise"], 0.0), "B": EXAMPLE["camera_noise"]}) if noise else None
    data, truth = PROBLEM.simulate(pairs=stations, seed=seed, noise=model, errors=errors, q=q,
                                   X=CAMERA_ON_FLANGE, Y=BOARD_IN_BASE)
    return {"q": np.asarray(data["q"]), "camera": inverse(np.asarray(data["B"])),
            "names": [f"s{k:02d}" for k in range(stations)], "errors": errors, "truth": truth}


def _g(v: float, digits: int) -> str:
    text = f"{v:.{digits}g}"
    return "0" if text in ("0", "-0") else text


def write_example(folder: str | Path, *, digits: int = 10, **options: Any) -> dict[str, Path]:
    """Write the example cell (`example_cell`, its `options`) to `folder` with `digits`
    significant digits: ``joints.csv`` (name, J1..J6 in deg), ``camera.csv`` (name, then
    solvePnP's tvec (mm) and rvec: format opencv-rvec's columns x, y, z, rx, ry, rz), ``arm.yaml``
    (the nominal LR Mate 200iD-like table, mm and deg), ``cell.yaml`` and ``truth.json`` (X, Y
    4x4 in mm and the true DH table, mm and deg). Returns the paths by name. The bundled example
    is ``write_example(folder)`` with the defaults."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cell = example_cell(**options)
    paths = {name: folder / file for name, file in (("joints", "joints.csv"), ("camera", "camera.csv"),
                                                     ("arm", "arm.yaml"), ("cell", "cell.yaml"),
                                                     ("truth", "truth.json"))}
    lines = ["name," + ",".join(NAMES)]
    lines += [",".join([n, *(_g(v, digits) for v in np.degrees(q))]) for n, q in zip(cell["names"], cell["q"])]
    paths["joints"].write_text("\n".join(lines) + "\n", encoding="utf-8")
    lines = ["name,x,y,z,rx,ry,rz"]
    for n, T in zip(cell["names"], cell["camera"]):
        rv = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        lines.append(",".join([n, *(_g(v, digits) for v in (*T[:3, 3], *rv))]))
    paths["camera"].write_text("\n".join(lines) + "\n", encoding="utf-8")
    paths["arm"].write_text(arm_yaml(ArmModel(LR_MATE_200ID, "mm", NAMES, "deg"), header=(
        "SIMULATED example: the nominal DH table of an LR Mate 200iD-like arm (handeye.geometry.kinematics),\n"
        "the controller's model; the simulated arm is off it by the errors in truth.json")), encoding="utf-8")
    paths["cell"].write_text(
        "# handeye cell file: a SIMULATED eye-in-hand cell whose arm is off its nominal DH table, "
        f"{len(cell['names'])} stations\n"
        "# (handeye.problems.axyb_kinematic.example_files.write_example). Run:\n"
        "#   handeye calibrate --config cell.yaml --arm-out corrected_arm.yaml\n"
        "setup: eye-in-hand\n"
        "problem: axyb-kinematic\n"
        "joints:\n  file: joints.csv\n  unit: deg\n"
        "arm: arm.yaml\n"
        "camera:\n  file: camera.csv\n  format: opencv-rvec\n  unit: mm\n"
        "matching:\n  method: name\n", encoding="utf-8")
    true_table = LR_MATE_200ID.table + cell["errors"]
    truth = {"description": "SIMULATED: the truth of handeye's kinematic example cell (mm, deg)",
             "X": np.round(cell["truth"]["X"], 12).tolist(), "Y": np.round(cell["truth"]["Y"], 12).tolist(),
             "dh": [{"name": n, "a": float(r[0]), "alpha": math.degrees(r[1]), "d": float(r[2]),
                     "offset": math.degrees(r[3])} for n, r in zip(NAMES, true_table)]}
    paths["truth"].write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    return paths


__all__ = ["EXAMPLE", "example_cell", "write_example"]
