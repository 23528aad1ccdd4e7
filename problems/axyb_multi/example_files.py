"""The example cell of axyb-multi as files: a simulated cell (`simulate_cell`) written as a robot
pose file, a table of observations, a cell file and its truth (`write_example`), so that the
bundled example (``handeye/data/multi_camera_cell/``, `handeye.io.examples.multi_camera_example_dir`)
is reproducible and tests can write noise-free cells of any size.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.problems.axyb_multi.simulation import simulate_cell

#: the bundled example cell: setup, cameras, markers, stations, seed, noise (rad, mm) on the robot
#: (A) and on the camera poses (B)
EXAMPLE = {"setup": "eye-to-hand", "cameras": 3, "markers": 4, "stations": 25, "seed": 7,
           "noise": {"A": (0.0002, 0.05), "B": (0.002, 0.5)}}


def example_cell(*, setup: str = EXAMPLE["setup"], cameras: int = EXAMPLE["cameras"],
                 markers: int = EXAMPLE["markers"], stations: int = EXAMPLE["stations"],
                 seed: int = EXAMPLE["seed"], noise: bool = True) -> dict[str, Any]:
    """A simulated cell (`simulate_cell`) as the rows its files hold: ``robot`` (station name ->
    T_base_flange, mm), ``rows`` (station, camera, target, T_cam_target per observation, as
    solvePnP gives it), ``truth`` (name -> its pose: T_flange_marker / T_base_cam eye-to-hand)."""
    model = NoiseModel(dict(EXAMPLE["noise"])) if noise else NoiseModel()
    cell = simulate_cell(stations, seed=seed, noise=model, setup=setup, cameras=cameras, markers=markers)
    data = cell.data
    A, B = np.asarray(data["A"]), np.asarray(data["B"])
    x_names, y_names = data["x_names"], data["y_names"]
    names = [f"s{k:02d}" for k in range(stations)]
    robot = {names[int(s)]: A[i] for i, s in enumerate(cell.station)}
    rows = []
    for i in range(len(B)):
        x, y = x_names[data["x_index"][i]], y_names[data["y_index"][i]]
        camera, target = (y, x) if setup == "eye-to-hand" else (x, y)
        T_cam_target = B[i] if setup == "eye-to-hand" else inverse(B[i])
        rows.append((names[int(cell.station[i])], camera, target, T_cam_target))
    truth = {**dict(zip(x_names, cell.truth["X"])), **dict(zip(y_names, cell.truth["Y"]))}
    return {"setup": setup, "robot": robot, "rows": rows, "truth": truth}


def _xyz_rotvec(T: np.ndarray, digits: int) -> list[str]:
    rv = Rotation.from_matrix(T[:3, :3]).as_rotvec()
    return [f"{v:.{digits}g}" for v in (*T[:3, 3], *rv)]


def write_example(folder: str | Path, *, digits: int = 10, **options: Any) -> dict[str, Path]:
    """Write the example cell (`example_cell`, its `options`) to `folder`: ``robot.csv`` (name,
    x, y, z, qx, qy, qz, qw, mm), ``observations.csv`` (station, camera, target, then solvePnP's
    tvec (mm) and rvec: format opencv-rvec's columns x, y, z, rx, ry, rz), ``cell.yaml`` and
    ``truth.json`` (every X and Y by name, 4x4, mm), numbers with `digits` significant digits.
    Returns the paths by name. The bundled example (``handeye/data/multi_camera_cell/``) is
    ``write_example(folder)`` with the defaults."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cell = example_cell(**options)
    lines = ["name,x,y,z,qx,qy,qz,qw"]
    for name, T in cell["robot"].items():
        q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
        lines.append(",".join([name, *(f"{v:.{digits}g}" for v in (*T[:3, 3], *q))]))
    paths = {"robot": folder / "robot.csv", "observations": folder / "observations.csv",
             "cell": folder / "cell.yaml", "truth": folder / "truth.json"}
    paths["robot"].write_text("\n".join(lines) + "\n", encoding="utf-8")
    table = ["station,camera,target,x,y,z,rx,ry,rz"]
    table += [",".join([s, c, t, *_xyz_rotvec(T, digits)]) for s, c, t, T in cell["rows"]]
    paths["observations"].write_text("\n".join(table) + "\n", encoding="utf-8")
    paths["cell"].write_text(
        f"# handeye cell file: a simulated {cell['setup']} cell, {len(set(r[1] for r in cell['rows']))} cameras and "
        f"{len(set(r[2] for r in cell['rows']))} targets\n"
        "# (handeye.problems.axyb_multi.example_files.write_example). Run:\n"
        "#   handeye calibrate --config cell.yaml\n"
        f"setup: {cell['setup']}\n"
        "problem: axyb-multi\n"
        "robot: {file: robot.csv, format: xyz-quat-xyzw, unit: mm}\n"
        "observations:\n"
        "  - {file: observations.csv, format: opencv-rvec, unit: mm}\n", encoding="utf-8")
    paths["truth"].write_text(json.dumps({"units": "mm", **{k: np.round(v, 12).tolist() for k, v in
                                                             cell["truth"].items()}}, indent=1) + "\n",
                              encoding="utf-8")
    return paths
