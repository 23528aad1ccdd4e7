"""A cell of several cameras and targets calibrated from its files: a table of observations (CSV,
JSON, NPZ) or one pose file per camera, with a robot pose file, through ``handeye.calibrate`` and
``handeye calibrate --config``; every X and Y printed, exported (JSON, YAML, ROS 2, URDF, xacro)
and reported by name; bad tables refused in one line (exit 2); the bundled example reproducible.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from handeye.base.errors import InputError
from handeye.geometry.se3 import make_pose
from handeye.io.examples import multi_camera_example_dir
from handeye.problems.axyb_multi.example_files import (
    _xyz_rotvec,
    example_cell,
    write_example,
)
from handeye.workflow.cell import Cell, ObservationStream, PoseStream
from tests.conftest import run_cli


def relative_error(T: np.ndarray, truth: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(T) - truth)) / max(1.0, np.max(np.abs(truth))))


def truth_of(folder: Path) -> dict[str, np.ndarray]:
    raw = json.loads((folder / "truth.json").read_text())
    return {k: np.array(v) for k, v in raw.items() if k != "units"}


def check_named(result: handeye.CalibrationResult, truth: dict[str, np.ndarray], tol: float = 1e-9) -> None:
    named = result.named_poses()
    assert sorted(p.name for p in named) == sorted(truth)
    for p in named:
        assert relative_error(p.T, truth[p.name]) < tol, p.name


@pytest.fixture
def exact_cell(tmp_path) -> Path:
    """The example cell (3 cameras, 4 markers, 25 stations) without noise, 17 digits."""
    write_example(tmp_path, digits=17, noise=False)
    return tmp_path


def per_camera_cell(folder: Path, setup: str = "eye-in-hand") -> Path:
    """A noise-free cell of one pose file per camera (station, target, x, y, z, rx, ry, rz) and a
    cell file listing them; returns the cell file. Truth in truth.json."""
    cell = example_cell(setup=setup, cameras=2, markers=3, stations=12, seed=4, noise=False)
    lines = ["name,x,y,z,qx,qy,qz,qw"]
    for name, T in cell["robot"].items():
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        lines.append(",".join([name, *(f"{v:.17g}" for v in (*T[:3, 3], *q))]))
    (folder / "robot.csv").write_text("\n".join(lines) + "\n")
    cameras = sorted({c for _, c, _, _ in cell["rows"]})
    entries = []
    for c in cameras:
        rows = ["station,target,x,y,z,rx,ry,rz"]
        rows += [",".join([s, t, *_xyz_rotvec(T, 17)]) for s, cam, t, T in cell["rows"] if cam == c]
        (folder / f"{c}.csv").write_text("\n".join(rows) + "\n")
        entries.append(f"  - {{camera: {c}, file: {c}.csv, format: opencv-rvec, unit: mm}}")
    (folder / "cell.yaml").write_text(f"setup: {setup}\nproblem: axyb-multi\n"
                                      "robot: {file: robot.csv, format: xyz-quat-xyzw, unit: mm}\n"
                                      "observations:\n" + "\n".join(entries) + "\n")
    (folder / "truth.json").write_text(json.dumps({k: v.tolist() for k, v in cell["truth"].items()}))
    return folder / "cell.yaml"


# ----------------------------------------------------------------------------- the right observations


def test_table_recovers_every_pose_by_name(exact_cell):
    result = handeye.calibrate(Cell.from_file(exact_cell / "cell.yaml"))
    assert result.usable and result.cell.problem == "axyb-multi"
    check_named(result, truth_of(exact_cell))
    assert result.names == {"X": ("marker0", "marker1", "marker2", "marker3"), "Y": ("cam0", "cam1", "cam2")}
    assert float(np.max(result.residuals["rotation"])) < 1e-9


def test_per_camera_files_eye_in_hand(tmp_path):
    """One file per camera, the camera named in the cell file; eye-in-hand B = inverse of solvePnP's."""
    result = handeye.calibrate(Cell.from_file(per_camera_cell(tmp_path, "eye-in-hand")))
    truth = truth_of(tmp_path)
    check_named(result, truth)
    assert result.names["X"] == ("cam0", "cam1")  # eye in hand: the cameras are the X's
    assert {p.parent for p in result.named_poses()} == {"flange", "base"}


def test_observations_to_the_right_data(exact_cell):
    """The mapping per setup: eye-to-hand B = T_cam_marker, X per target, Y per camera."""
    from handeye.framework.problem_cell import Observations
    from handeye.problems.axyb_multi.cell_files import from_observations

    cell = example_cell(noise=False)
    rows = cell["rows"]
    obs = Observations(tuple(r[0] for r in rows), tuple(r[1] for r in rows), tuple(r[2] for r in rows),
                       np.stack([cell["robot"][r[0]] for r in rows]), np.stack([r[3] for r in rows]))
    made = from_observations(obs, "eye-to-hand")
    f = made.fields
    X = np.stack([cell["truth"][n] for n in made.names["X"]])
    Y = np.stack([cell["truth"][n] for n in made.names["Y"]])
    np.testing.assert_allclose(f["A"] @ X[f["x_index"]], Y[f["y_index"]] @ f["B"], rtol=0, atol=1e-5)  # the truth: SO(3) to ~1e-9
    inverse = from_observations(obs, "eye-in-hand")
    assert inverse.names == {"X": made.names["Y"], "Y": made.names["X"]}


@pytest.mark.parametrize("ext", ["json", "npz"])
def test_json_and_npz_tables(exact_cell, ext):
    cell = example_cell(noise=False)
    rows = cell["rows"]
    arrays = {"station": [r[0] for r in rows], "camera": [r[1] for r in rows], "target": [r[2] for r in rows],
              "camera_poses": np.stack([r[3] for r in rows]), "units": "mm"}
    path = exact_cell / f"observations.{ext}"
    if ext == "json":
        path.write_text(json.dumps({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in arrays.items()}))
    else:
        np.savez(path, **{k: np.array(v) for k, v in arrays.items()})
    base = Cell.from_file(exact_cell / "cell.yaml")
    result = handeye.calibrate(base.replace(observations=(ObservationStream(file=str(path)),)))
    check_named(result, truth_of(exact_cell), tol=1e-8)


def test_cell_file_round_trip(tmp_path):
    path = per_camera_cell(tmp_path)
    cell = Cell.from_file(path)
    again = Cell.from_file(cell.to_file(tmp_path / "again.yaml"))
    assert again == cell
    assert [s.camera for s in again.observations] == ["cam0", "cam1"]


# ----------------------------------------------------------------------------- the command, exports, report


def test_cli_prints_exports_and_reports_every_name(exact_cell, capsys):
    out_json, out_yaml, report = exact_cell / "r.json", exact_cell / "r.yaml", exact_cell / "report.md"
    code, out, err = run_cli(capsys, "calibrate", "--config", exact_cell / "cell.yaml", "-o", out_json,
                             "--yaml", out_yaml, "--report", report)
    assert code == 0, err
    truth = truth_of(exact_cell)
    for name in truth:
        assert f" {name} = T_" in out  # printed by name with its frame
    for path, load in ((out_json, json.loads), (out_yaml, yaml.safe_load)):
        r = load(path.read_text())
        assert sorted(r["transforms"]) == sorted(truth)
        for name, entry in r["transforms"].items():
            assert relative_error(np.array(entry["matrix"]), truth[name]) < 1e-9
            x, q = entry["xyz_quat"][:3], entry["xyz_quat"][3:]
            assert relative_error(make_pose(Rotation.from_quat(q).as_matrix(), x), truth[name]) < 1e-9
        ids = {(t["frame_id"], t["child_frame_id"]) for t in r["ros"]["transforms"]}
        assert ("base", "cam0") in ids and ("flange", "marker3") in ids
        assert len(r["observations"]["per_pair"]) == 12
        assert r["observations"]["cameras"] == ["cam0", "cam1", "cam2"]  # the cameras, not the markers too
    assert "--frame-id base --child-frame-id cam2" in out
    text = report.read_text()
    assert "Residuals per pair" in text and "| marker0 | cam0 |" in text
    assert (exact_cell / "report_graph.png").read_bytes()[:4] == b"\x89PNG"
    assert "report_graph.png" in text


def test_html_report_embeds_the_graph(exact_cell):
    result = handeye.calibrate(Cell.from_file(exact_cell / "cell.yaml"))
    path = result.write_report(exact_cell / "report.html")[0]
    html = path.read_text()
    assert "Residuals per pair" in html and html.count("data:image/png;base64,") >= 3
    assert "the graph of cameras and targets" in html


def test_ros_urdf_xacro_parse_back(exact_cell):
    result = handeye.calibrate(Cell.from_file(exact_cell / "cell.yaml"))
    truth = truth_of(exact_cell)
    lines = result.ros2_static_transform().splitlines()
    assert len(lines) == len(truth)
    for line in lines:
        words = line.split()
        value = {words[k][2:]: words[k + 1] for k in range(len(words) - 1) if words[k].startswith("--")}
        T = make_pose(Rotation.from_quat([float(value[k]) for k in ("qx", "qy", "qz", "qw")]).as_matrix(),
                      [1000 * float(value[k]) for k in "xyz"])
        assert relative_error(T, truth[value["child-frame-id"]]) < 1e-8
    for text in (f"<robot>{result.urdf_joint()}</robot>", result.xacro()):
        root = ET.fromstring(text)
        joints = root.iter("joint")
        seen = {}
        for joint in joints:
            child = joint.find("child").get("link")
            origin = joint.find("origin")
            xyz = [1000 * float(v) for v in origin.get("xyz").split()]
            rpy = [float(v) for v in origin.get("rpy").split()]
            seen[child] = make_pose(Rotation.from_euler("xyz", rpy).as_matrix(), xyz)
        assert sorted(seen) == sorted(truth)
        for name, T in seen.items():
            assert relative_error(T, truth[name]) < 1e-8


def test_names_that_one_frame_id_would_merge_are_published_apart(exact_cell):
    """Cameras "cam 0", "cam-0" and "cam_0" all become the ROS frame id ``cam_0``: published as
    three frames and URDF links (``cam_0``, ``cam_0_2``, ``cam_0_3``), with a warning naming them."""
    table = exact_cell / "observations.csv"
    text = table.read_text()
    for old, new in ((",cam1,", ",cam-0,"), (",cam2,", ",cam 0,"), (",cam0,", ",cam_0,")):
        text = text.replace(old, new)
    table.write_text(text)
    result = handeye.calibrate(Cell.from_file(exact_cell / "cell.yaml"))
    children = [line.split("--child-frame-id ")[1].split()[0] for line in result.ros2_static_transform().splitlines()]
    assert len(children) == len(set(children)) == 7
    links = [j.find("child").get("link") for j in ET.fromstring(f"<robot>{result.urdf_joint()}</robot>").iter("joint")]
    assert sorted(c for c in links if c.startswith("cam")) == ["cam_0", "cam_0_2", "cam_0_3"]
    warned = [w for w in result.warnings if "share one frame" in w]
    assert len(warned) == 1 and "'cam-0'" in warned[0] and "'cam 0'" in warned[0], warned


# ----------------------------------------------------------------------------- bad input


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, count))


def bad_unknown_camera(folder: Path) -> None:
    """A per-camera file whose row names another camera."""
    text = (folder / "cam0.csv").read_text().splitlines()
    text[0] = "station,camera,target," + text[0].split(",", 2)[2]
    text[1:] = [f"{r.split(',', 1)[0]},{'cam7' if k == 2 else 'cam0'},{r.split(',', 1)[1]}" for k, r in
                enumerate(text[1:], 1)]
    (folder / "cam0.csv").write_text("\n".join(text) + "\n")


def bad_missing_column(folder: Path) -> None:
    _edit(folder / "cam0.csv", "station,target,", "station,tgt,")


def bad_duplicate(folder: Path) -> None:
    lines = (folder / "cam0.csv").read_text().splitlines()
    (folder / "cam0.csv").write_text("\n".join([*lines, lines[1]]) + "\n")


def bad_station(folder: Path) -> None:
    lines = (folder / "robot.csv").read_text().splitlines()
    first_station = (folder / "cam0.csv").read_text().splitlines()[1].split(",")[0]
    (folder / "robot.csv").write_text("\n".join(r for r in lines if not r.startswith(first_station + ",")) + "\n")


@pytest.mark.parametrize("spoil, words", [
    (bad_unknown_camera, "names camera 'cam7'"),
    (bad_missing_column, "missing column 'target'"),
    (bad_duplicate, "repeats line"),
    (bad_station, "is not in the robot file"),
], ids=["unknown-camera", "missing-column", "duplicate", "station-missing"])
def test_bad_tables_one_line_and_exit_2(tmp_path, capsys, spoil, words):
    path = per_camera_cell(tmp_path)
    spoil(tmp_path)
    with pytest.raises(InputError) as caught:
        handeye.calibrate(Cell.from_file(path))
    assert words in str(caught.value) and "\n" not in str(caught.value)
    code, out, err = run_cli(capsys, "calibrate", "--config", path)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1


def test_cell_settings_refused(tmp_path):
    robot = PoseStream(file="robot.csv", format="xyz-quat-xyzw", unit="mm")
    table = ObservationStream(file="o.csv", format="opencv-rvec")
    with pytest.raises(InputError, match="name each file's camera"):
        Cell(robot=robot, setup="eye-to-hand", observations=(table, table))
    with pytest.raises(InputError, match="camera 'a' is named by two"):
        Cell(robot=robot, setup="eye-to-hand", observations=(ObservationStream(file="a", format="matrix", camera="a"),
                                                              ObservationStream(file="b", format="matrix", camera="a")))
    with pytest.raises(InputError, match="problem"):
        Cell(robot=robot, setup="eye-to-hand", problem="axyb", observations=(table,))
    with pytest.raises(InputError, match="`frame_ids` names one camera's frames"):
        Cell(robot=robot, setup="eye-to-hand", observations=(table,), frame_ids="base_link,cam")
    with pytest.raises(InputError, match="`observations` replace `images`"):
        Cell.from_dict({"setup": "eye-to-hand", "robot": {"file": "r.csv"}, "images": {"folder": "i"},
                        "observations": [{"file": "o.csv", "format": "opencv-rvec"}]})
    assert Cell(robot=robot, setup="eye-to-hand", observations=table).problem == "axyb-multi"


# ----------------------------------------------------------------------------- the bundled example


def test_bundled_example_is_reproducible_and_calibrates(tmp_path):
    folder = multi_camera_example_dir()
    write_example(tmp_path)
    for name in ("robot.csv", "observations.csv", "cell.yaml", "truth.json"):
        assert (tmp_path / name).read_text() == (folder / name).read_text(), name
    assert sum(p.stat().st_size for p in folder.iterdir()) < 100_000
    result = handeye.calibrate(Cell.from_file(folder / "cell.yaml"))
    assert result.usable
    truth = truth_of(folder)
    for p in result.named_poses():  # realistic noise: within a few tenths of a degree and a few mm
        R = p.T[:3, :3] @ truth[p.name][:3, :3].T
        assert np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))) < 0.2
        assert np.linalg.norm(p.T[:3, 3] - truth[p.name][:3, 3]) < 3.0


def test_cli_flags_and_write_config(exact_cell, capsys):
    """--observations [CAMERA=]FILE beside --robot, and --write-config keeps them."""
    flags = ["--robot", exact_cell / "robot.csv", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm",
             "--observations", exact_cell / "observations.csv", "--camera-format", "opencv-rvec", "--camera-unit",
             "mm", "--setup", "eye-to-hand"]
    code, out, err = run_cli(capsys, "calibrate", *flags, "--json")
    assert code == 0, err
    r = json.loads(out)
    truth = truth_of(exact_cell)
    for name, entry in r["transforms"].items():
        assert relative_error(np.array(entry["matrix"]), truth[name]) < 1e-9
    code, out, err = run_cli(capsys, "calibrate", *flags, "--write-config", exact_cell / "again.yaml")
    assert code == 0, err
    again = Cell.from_file(exact_cell / "again.yaml")
    assert again.observations[0].file == str(exact_cell / "observations.csv") and "matching" not in (
        exact_cell / "again.yaml").read_text()
    code, out, err = run_cli(capsys, "calibrate", *flags[:6], "--observations", f"cam0={exact_cell / 'x.csv'}",
                             "--setup", "eye-to-hand")
    assert code == 2 and "not found" in err


def test_a_large_cell_is_drawn_as_a_table_of_its_pairs():
    """73 observed pairs (a real rig's 8 cameras and 16 markers) as a graph of crossing edges were
    unreadable: beyond GRAPH_MAX_EDGES the report draws a table of markers and cameras instead,
    each cell a pair's RMS rotation residual and observations."""
    import io

    import matplotlib.image

    from handeye.workflow.report_plots import GRAPH_MAX_EDGES, graph_plot, pair_matrix

    rng = np.random.default_rng(0)
    pairs = sorted(set(zip(rng.integers(0, 16, 200).tolist(), rng.integers(0, 8, 200).tolist())))[:73]
    rows = [{"X": f"tag{x}", "Y": f"cam{y}", "observations": int(rng.integers(2, 120)),
             "rotation_rms_deg": float(rng.uniform(0.2, 3.0)), "translation_rms": float(rng.uniform(5, 40))}
            for x, y in pairs]
    assert len(rows) > GRAPH_MAX_EDGES
    cell = {"pair_table": rows, "unit": "mm", "frames": {}}
    png = graph_plot(cell)
    image = matplotlib.image.imread(io.BytesIO(png))
    assert png == pair_matrix(cell) and image.shape[0] > 500 and image.shape[1] > 500
