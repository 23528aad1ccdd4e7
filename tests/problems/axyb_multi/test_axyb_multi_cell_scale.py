"""A cell of several cameras from its files, with monocular cameras (``camera_scale: [names]`` in
the cell file, ``--camera-scale cam0,cam2`` on the command line): each camera's scale recovered
and printed with its 1-sigma, the residuals and exports in the robot's unit; the intrinsics of an
image cell's cameras in its JSON; the report and auto's warning naming observations by station,
camera and target; the solve's validated data used for the residuals (validated once).

Figures (simulate_cell, 15 stations, 3 fixed cameras, 3 markers, noise A 0.0002 rad / 0.05 mm,
B 0.002 rad / 0.5 mm; measured): scales 2.5 and 0.4 recovered to 0.05% (1-sigma 0.03%),
translation residuals 0.73 mm median in the robot's unit; the same poses on the monocular
cameras' own translations would leave residuals of hundreds of mm.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.base.errors import InputError
from handeye.cli import main
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.host.registry import get_registry
from handeye.problems.axyb_multi import AXYBMultiData, simulate_cell
from handeye.problems.axyb_multi.example_files import _xyz_rotvec
from handeye.workflow.cell import Cell
from handeye.workflow.report_plots import observation_ticks

SCALES = {"cam0": 2.5, "cam2": 0.4}
STATIONS = 15
NOISE = {"A": (0.0002, 0.05), "B": (0.002, 0.5)}


def write_cell(folder: Path, *, setup: str = "eye-to-hand", scales=SCALES, gross: float = 0.0,
               camera_scale: bool = True):
    """A simulated cell (3 cameras, 3 targets) as robot.csv, obs.csv (station, camera, target,
    tvec, rvec; mm) and cell.yaml (with `camera_scale` naming the monocular cameras)."""
    folder.mkdir(parents=True, exist_ok=True)
    cell = simulate_cell(STATIONS, seed=5, setup=setup, cameras=3, markers=3, noise=NoiseModel(NOISE),
                         camera_scales=scales, gross=gross)
    d = cell.data
    names = [f"s{k:02d}" for k in range(STATIONS)]
    lines = ["name,x,y,z,qx,qy,qz,qw"]
    for s in range(STATIONS):
        A = d["A"][int(np.flatnonzero(cell.station == s)[0])]
        q = Rotation.from_matrix(A[:3, :3]).as_quat()
        lines.append(",".join([names[s], *(f"{v:.17g}" for v in (*A[:3, 3], *q))]))
    (folder / "robot.csv").write_text("\n".join(lines) + "\n")
    rows, labels = ["station,camera,target,x,y,z,rx,ry,rz"], []
    for i, B in enumerate(d["B"]):
        x, y = d["x_names"][d["x_index"][i]], d["y_names"][d["y_index"][i]]
        camera, target = (y, x) if setup == "eye-to-hand" else (x, y)
        T_cam_target = B if setup == "eye-to-hand" else inverse(B)
        rows.append(",".join([names[int(cell.station[i])], camera, target, *_xyz_rotvec(T_cam_target, 17)]))
        labels.append((names[int(cell.station[i])], camera, target))
    (folder / "obs.csv").write_text("\n".join(rows) + "\n")
    (folder / "cell.yaml").write_text(
        f"setup: {setup}\nproblem: axyb-multi\nrobot: {{file: robot.csv, format: xyz-quat-xyzw, unit: mm}}\n"
        "observations:\n  - {file: obs.csv, format: opencv-rvec, unit: mm}\n"
        + (f"camera_scale: [{', '.join(scales)}]\n" if camera_scale else ""))
    return cell, labels


def metric_residuals(cell, result, scales) -> np.ndarray:
    """The translation residuals of the result's poses on the simulated cell's data with each
    monocular camera's translations times its scale in `scales` ({name: s}), in the files' order."""
    d = dict(cell.data)
    B = np.array(d["B"])
    eye_to_hand = "cam0" in d["y_names"]
    names, index = (d["y_names"], d["y_index"]) if eye_to_hand else (d["x_names"], d["x_index"])
    for name, s in scales.items():
        B[np.asarray(index) == names.index(name), :3, 3] *= s
    problem = get_registry().problem("axyb-multi")
    data = problem.validate(**{**{k: v for k, v in d.items() if k != "camera_scale"}, "B": B})
    # the files' names sort as the simulator's (cam0 < cam1 < cam2), so the stacks align
    assert list(result.names["X"]) == list(d["x_names"]) and list(result.names["Y"]) == list(d["y_names"])
    return problem.residuals(data, result.unknowns)["translation"]


def test_monocular_cameras_from_the_cell_file(tmp_path):
    cell, _ = write_cell(tmp_path)
    result = handeye.calibrate(Cell.from_file(tmp_path / "cell.yaml"))
    assert result.usable and result.cell.camera_scale == ("cam0", "cam2")
    scales = result.to_dict()["camera_scales"]
    assert sorted(scales) == ["cam0", "cam2"]
    for name, s in SCALES.items():
        got = scales[name]
        assert 0 < got["std"] < 1e-3 * s
        assert abs(got["scale"] - s) < max(4 * got["std"], 1e-3 * s), name
    # the residuals in the robot's unit: each camera's translations times its own estimated scale
    trans = np.asarray(result.residuals["translation"])
    estimated = {name: s["scale"] for name, s in scales.items()}
    np.testing.assert_allclose(trans, metric_residuals(cell, result, estimated), rtol=1e-9, atol=1e-9)
    # ... and as large as on the metric data (true scales): equal for the metric camera cam1's
    # observations, within the scales' error (|s - s_true| |t_B| up to ~0.8 mm) for the others
    truth = metric_residuals(cell, result, SCALES)
    metric = np.array([label[1] == "cam1" for label in result.observation_labels])
    np.testing.assert_allclose(trans[metric], truth[metric], rtol=1e-9)
    assert abs(np.median(trans) - np.median(truth)) < 0.3 and np.max(np.abs(trans - truth)) < 1.0  # 0.2, 0.8
    assert 0.3 < np.median(trans) < 1.5 and trans.max() < 4
    # on the cameras' own translations the same poses would be hundreds of mm off
    raw = get_registry().problem("axyb-multi").residuals(result.solution.data, result.unknowns)
    assert np.median(raw["translation"]) > 100
    per_pair = {(row["X"], row["Y"]): row for row in result.pair_table}
    assert max(row["translation_rms"] for row in per_pair.values()) < 2
    # the report lists each camera's scale with its 1-sigma
    from handeye.workflow.report_layout import diag_rows

    rows = dict(diag_rows(result.report_data()))
    for name in SCALES:
        assert rows[f"camera scale of {name}"] == (f"{scales[name]['scale']:.6g} (1-sigma {scales[name]['std']:.2g}): "
                                                   "its translations times this are in mm")


def test_monocular_wrist_cameras_through_the_cli(tmp_path, capsys):
    cell, _ = write_cell(tmp_path, setup="eye-in-hand", camera_scale=False)
    code = main(["calibrate", "--config", str(tmp_path / "cell.yaml"), "--camera-scale", "cam0,cam2",
                 "-o", str(tmp_path / "r.json")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "camera scales (each monocular camera's translations times its s are in mm" in out
    r = json.loads((tmp_path / "r.json").read_text())
    for name, s in SCALES.items():
        got = r["camera_scales"][name]
        assert abs(got["scale"] - s) < max(4 * got["std"], 1e-3 * s), name
        assert f"  {name:<14} s = {got['scale']:.6g} (1-sigma {got['std']:.2g})" in out
    assert r["residuals"]["translation"]["rms"] < 2  # mm, the robot's unit
    # every pose in mm near the truth (measured: within 0.07 deg and 0.33 mm)
    d = cell.data
    for names, truth in ((d["x_names"], cell.truth["X"]), (d["y_names"], cell.truth["Y"])):
        for name, T in zip(names, truth):
            D = inverse(T) @ np.array(r["transforms"][name]["matrix"])
            assert np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1))) < 0.2, name
            assert np.linalg.norm(D[:3, 3]) < 1.0, name


def test_camera_scale_settings_refused_in_one_line(tmp_path, capsys):
    write_cell(tmp_path, camera_scale=False)
    base = Cell.from_file(tmp_path / "cell.yaml")
    with pytest.raises(InputError, match=r"`camera_scale: unknown` does not say which of the cell's cameras"):
        base.replace(camera_scale="unknown")
    with pytest.raises(InputError, match="names 'cam0' twice"):
        base.replace(camera_scale=["cam0", "cam0"])
    with pytest.raises(InputError, match=r"names 'marker0', which is not a camera of the observations \(their "
                                         r"cameras: cam0, cam1, cam2\)"):
        handeye.calibrate(base.replace(camera_scale=["marker0"]))
    code = main(["calibrate", "--config", str(tmp_path / "cell.yaml"), "--camera-scale", "unknown"])
    err = capsys.readouterr().err
    assert code == 2 and "name them, e.g. --camera-scale cam0,cam2" in err and len(err.strip().splitlines()) == 1
    one = Cell.from_dict({"setup": "eye-in-hand", "robot": {"file": "r.csv", "format": "fanuc-wpr"},
                          "camera": {"file": "b.csv", "format": "opencv-rvec", "unit": "mm"}})
    with pytest.raises(InputError, match="names the monocular cameras of a cell of several cameras"):
        one.replace(camera_scale=["cam0"])
    # the names round-trip through the cell file, as a list
    named = base.replace(camera_scale=["cam0", "cam2"])
    assert Cell.from_dict(named.to_dict()).camera_scale == ("cam0", "cam2")
    assert "camera_scale: [cam0, cam2]" in named.to_yaml()


def test_outliers_named_by_station_camera_and_target(tmp_path):
    cell, labels = write_cell(tmp_path, gross=0.03)
    result = handeye.calibrate(Cell.from_file(tmp_path / "cell.yaml"))
    gross = ["station {} ({}, {})".format(*labels[i]) for i in cell.gross]
    assert len(gross) == 4
    left_out = sorted(int(o["index"]) for o in result.solution.diagnostics["outliers"])
    assert left_out == sorted(cell.gross.tolist())
    (warning,) = [w for w in result.warnings if "far off the others" in w]
    for i, name in zip(cell.gross, gross):
        assert f"(index {i}: {name})" in warning
    report = result.report_data()
    from handeye.workflow.report_layout import advice, diag_rows

    (what,) = [a for a, _ in advice(report) if "far off the others" in a]
    assert what.startswith("observations of " + ", ".join(gross))
    assert dict(diag_rows(report))["outlying observations (left out)"] == ", ".join(gross)
    # the bar plot's ticks name every outlier by station, camera and target
    ticks, texts = observation_ticks(report["labels"], set(report["outliers"]), 4)
    for i in cell.gross:
        assert texts[ticks.index(int(i))] == " ".join(labels[i])
    assert not {t + 1 for t in ticks} & set(cell.gross.tolist()) - set(ticks)


def test_the_residuals_use_the_solves_validated_data(tmp_path, monkeypatch):
    """calibrate validates a cell's data once (in the solve; Solution.data) unless a camera's
    translations are scaled into the robot's unit first."""
    write_cell(tmp_path, scales=SCALES, camera_scale=False)
    problem = get_registry().problem("axyb-multi")
    calls = []
    original = type(problem).validate
    monkeypatch.setattr(type(problem), "validate", lambda self, **d: calls.append(1) or original(self, **d))
    cell = Cell.from_file(tmp_path / "cell.yaml")
    result = handeye.calibrate(cell.replace(checks=False))  # the monocular cameras unnamed: metric
    assert len(calls) == 1 and isinstance(result.solution.data, AXYBMultiData)
    assert result.solution.data.m == len(result.residuals["rotation"])
    calls.clear()
    handeye.calibrate(cell.replace(camera_scale=["cam0", "cam2"]))
    assert len(calls) == 2


def test_one_camera_cell_validates_once(tmp_path, monkeypatch):
    from test_calibrate import cell as simulated_cell

    robot, camera, truth = simulated_cell(tmp_path)
    problem = get_registry().problem("axyb")
    calls = []
    original = type(problem).validate
    monkeypatch.setattr(type(problem), "validate", lambda self, **d: calls.append(1) or original(self, **d))
    result = handeye.calibrate(Cell.from_dict({"setup": "eye-in-hand",
                                               "robot": {"file": str(robot), "format": "fanuc-wpr"},
                                               "camera": {"file": str(camera), "format": "opencv-rvec",
                                                          "unit": "mm"}, "checks": False}))
    assert len(calls) == 1 and result.solution.data is not None
    np.testing.assert_allclose(result.X, truth["X"], atol=1e-6)


def test_image_cell_json_has_each_cameras_intrinsics(tmp_path):
    from multi_images import CAMERA, CELL_YAML
    from multi_images import write_cell as render_cell

    render_cell(tmp_path, 8)
    (tmp_path / "cell.yaml").write_text(CELL_YAML.replace(", intrinsics: cam1.json", ""))
    result = handeye.calibrate(Cell.from_file(tmp_path / "cell.yaml"))
    cameras = result.to_dict()["cameras"]
    assert sorted(cameras) == ["cam0", "cam1"]
    given, calibrated = cameras["cam0"], cameras["cam1"]
    assert given["source"].endswith("cam0.json") and "rms_px" not in given
    np.testing.assert_allclose(given["K"], CAMERA.K)
    assert given["image_size"] == [640, 480]
    assert calibrated["source"] == "calibrated" and calibrated["image_size"] == [640, 480]
    assert 0 < calibrated["rms_px"] < 0.2 and calibrated["views"] >= 12
    K = np.array(calibrated["K"])
    assert abs(K[0, 0] - 600) < 6 and abs(K[0, 2] - 320) < 6 and abs(K[1, 2] - 240) < 6
    assert all(0 < v < 6 for v in calibrated["std_px"].values())
    assert json.loads(result.to_json())["cameras"]["cam1"]["model"] == calibrated["model"]


def test_solve_a_data_file_with_named_monocular_cameras(tmp_path, capsys):
    """handeye solve of an axyb-multi data file: --camera-scale cam0 gives cam0's scale and the
    residuals in the robot's unit (0.74 mm median; on cam0's own translations 7.7 mm median and
    111 mm RMS, measured)."""
    cell = simulate_cell(STATIONS, seed=5, cameras=3, markers=3, noise=NoiseModel(NOISE),
                         camera_scales={"cam0": 2.5})
    np.savez(tmp_path / "m.npz", **{k: np.asarray(v) for k, v in cell.data.items() if k != "camera_scale"})
    assert main(["solve", str(tmp_path / "m.npz"), "--problem", "axyb-multi", "--camera-scale", "cam0"]) == 0
    out = capsys.readouterr().out
    assert "camera scales (each monocular camera's translations times its s are in the robot's unit" in out
    assert main(["solve", str(tmp_path / "m.npz"), "--problem", "axyb-multi", "--camera-scale", "cam0", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert abs(r["diagnostics"]["camera_scales"]["cam0"] - 2.5) < 0.005
    assert r["residuals"]["translation"]["rms"] < 1.5
