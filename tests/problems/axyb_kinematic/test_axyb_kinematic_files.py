"""A kinematic calibration from the files a cell records (issue 26): joint readings (CSV in deg or
rad, or a ROS bag's JointState), the arm's nominal DH table (YAML) and the camera's poses, through
``handeye.calibrate`` and ``handeye calibrate``; the corrections printed and exported, the
corrected table read back; units; bad files refused in one line (exit 2); the bundled example
reproducible byte for byte.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.base.errors import InputError
from handeye.geometry.kinematics import LR_MATE_200ID
from handeye.io.arm_files import ArmModel, arm_yaml, read_arm
from handeye.io.examples import kinematic_example_dir
from handeye.io.joint_files import read_joints
from handeye.problems.axyb_kinematic import model
from handeye.problems.axyb_kinematic.example_files import (
    NAMES,
    example_cell,
    write_example,
)
from handeye.workflow.cell import Cell, JointStream
from tests.conftest import run_cli

IDENTIFIABLE = [model.parameter_name(k) for k in model.structural(LR_MATE_200ID.table).identifiable]


@pytest.fixture(scope="module")
def exact(tmp_path_factory) -> Path:
    """The example cell without noise, 17 digits."""
    folder = tmp_path_factory.mktemp("exact")
    write_example(folder, digits=17, noise=False)
    return folder


def truth_of(folder: Path) -> dict:
    raw = json.loads((folder / "truth.json").read_text())
    return {"X": np.array(raw["X"]), "Y": np.array(raw["Y"]), "dh": raw["dh"]}


def true_corrections(truth: dict) -> dict[str, float]:
    """{"J2 a": true - nominal} in mm and deg."""
    nominal = ArmModel(LR_MATE_200ID, "mm", NAMES, "deg")
    out = {}
    for j, row in enumerate(truth["dh"]):
        for c, kind in enumerate(("a", "alpha", "d", "offset")):
            value = nominal.dh.table[j, c] if c in (0, 2) else math.degrees(nominal.dh.table[j, c])
            out[f"J{j + 1} {kind}"] = row[kind] - value
    return out


def check_recovered(X, Y, kinematics: dict, truth: dict, scale: float = 1.0, tol: float = 1e-9) -> None:
    """X, Y and every identifiable correction against the truth (mm and deg; lengths times
    `scale`), to `tol` (rotation matrices, corrections; translations to 10 tol)."""
    assert np.abs(X[:3, :3] - truth["X"][:3, :3]).max() < tol
    assert np.abs(Y[:3, :3] - truth["Y"][:3, :3]).max() < tol
    assert np.abs(X[:3, 3] - truth["X"][:3, 3] * scale).max() < tol * 10 * scale  # 1e-8 mm
    assert np.abs(Y[:3, 3] - truth["Y"][:3, 3] * scale).max() < tol * 10 * scale
    found = {p["name"]: p for p in kinematics["parameters"]}
    assert sorted(found) == sorted(IDENTIFIABLE) and len(found) == 17
    expected = true_corrections(truth)
    for name, p in found.items():
        s = scale if p["parameter"] in ("a", "d") else 1.0
        assert abs(p["correction"] - expected[name] * s) < tol * s, (name, p)  # 1e-9 mm or deg
        assert p["std"] < 1e-7 * s


# ----------------------------------------------------------------------------- the library


def test_library_recovers_x_y_and_the_dh_corrections_noise_free(exact):
    result = handeye.calibrate(Cell.from_file(exact / "cell.yaml"))
    assert result.status is handeye.Status.OPTIMAL and result.usable
    truth = truth_of(exact)
    r = result.to_dict()
    k = r["kinematics"]
    check_recovered(result.X, result.Y, k, truth)
    assert k["used"] and k["length_unit"] == "mm" and k["angle_unit"] == "deg"
    assert sorted(k["not_identifiable"]) == ["J1 d", "J1 offset", "J3 d", "J6 a", "J6 alpha", "J6 d", "J6 offset"]
    assert "absorbed in Y" in k["not_identifiable_why"] and "parallel axes" in k["not_identifiable_why"]
    assert sorted(r["poses"]) == ["X", "Y"]  # the fitted links are the DH table, not printed as poses
    assert r["matching"]["method"] == "name" and r["stations"] == 40
    assert r["residuals"]["translation"]["max"] < 1e-8
    # the corrected table read back: the truth on the identifiable parameters, nominal elsewhere
    arm_path = exact / "corrected.yaml"
    arm_path.write_text(result.arm_yaml())
    corrected = read_arm(arm_path)
    true_table = np.array([[row["a"], math.radians(row["alpha"]), row["d"], math.radians(row["offset"])]
                           for row in truth["dh"]])
    ident = list(model.structural(LR_MATE_200ID.table).identifiable)
    flat = corrected.dh.table.ravel()
    assert np.abs(flat[ident] - true_table.ravel()[ident]).max() < 1e-9
    others = [i for i in range(24) if i not in ident]
    np.testing.assert_array_equal(flat[others], LR_MATE_200ID.table.ravel()[others])
    assert corrected.names == NAMES and corrected.unit == "mm"


def test_units_deg_rad_mm_m_give_the_same_answer_scaled(exact, tmp_path):
    """Joints in rad, the arm in m and rad, the camera in m: X, Y and the corrections in m."""
    cell = example_cell(noise=False)
    lines = ["t," + ",".join(NAMES)]  # stamps instead of names: matched by time
    lines += [",".join([f"{10 + 0.5 * i:.17g}", *(f"{v:.17g}" for v in q)]) for i, q in enumerate(cell["q"])]
    (tmp_path / "joints.csv").write_text("\n".join(lines) + "\n")
    lines = ["t,x,y,z,rx,ry,rz"]
    for i, T in enumerate(cell["camera"]):
        rv = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        lines.append(",".join([f"{10 + 0.5 * i + 0.001:.17g}", *(f"{v:.17g}" for v in (*T[:3, 3] / 1000, *rv))]))
    (tmp_path / "camera.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "arm.yaml").write_text(arm_yaml(ArmModel(LR_MATE_200ID, "mm", NAMES, "rad").in_unit("m"), digits=17))
    metres = handeye.calibrate(Cell(setup="eye-in-hand", joints=JointStream(tmp_path / "joints.csv", unit="rad"),
                                    arm=tmp_path / "arm.yaml",
                                    camera=handeye.workflow.cell.CameraStream(tmp_path / "camera.csv",
                                                                              format="opencv-rvec", unit="m"),
                                    matching=handeye.workflow.cell.Matching(method="time", max_dt=0.01)))
    k = metres.to_dict()["kinematics"]
    assert metres.unit == "m" and k["length_unit"] == "m" and k["angle_unit"] == "rad"
    truth = truth_of(exact)
    for p in k["parameters"]:  # back to deg for the check
        if p["parameter"] in ("alpha", "offset"):
            p.update({key: math.degrees(p[key]) for key in ("nominal", "estimate", "correction", "std")})
    check_recovered(metres.X, metres.Y, k, truth, scale=1e-3)
    millimetres = handeye.calibrate(Cell.from_file(exact / "cell.yaml"))
    np.testing.assert_allclose(metres.X[:3, 3] * 1000, millimetres.X[:3, 3], atol=1e-8)
    np.testing.assert_allclose(metres.Y[:3, :3], millimetres.Y[:3, :3], atol=1e-12)


def test_joint_columns_are_put_in_the_arms_order_by_name(exact, tmp_path):
    text = (exact / "joints.csv").read_text().splitlines()
    rows = [line.split(",") for line in text]
    order = [0, 3, 1, 6, 2, 5, 4]  # name, J3, J1, J6, J2, J5, J4
    (tmp_path / "joints.csv").write_text("\n".join(",".join(r[i] for i in order) for r in rows) + "\n")
    stack = read_joints(tmp_path / "joints.csv", "deg").ordered(NAMES)
    np.testing.assert_array_equal(stack.q, read_joints(exact / "joints.csv", "deg").q)
    assert stack.joints == NAMES and stack.names[:2] == ("s00", "s01")


def test_the_cell_file_round_trips_its_joints_and_arm(exact, tmp_path):
    cell = Cell.from_file(exact / "cell.yaml")
    assert cell.problem == "axyb-kinematic" and cell.joints.unit == "deg" and cell.robot.file is None
    data = cell.to_dict(relative_to=exact)
    assert data["joints"] == {"file": "joints.csv", "unit": "deg"} and data["arm"] == "arm.yaml"
    assert "robot" not in data
    (exact / "copy.yaml").write_text(cell.to_yaml(relative_to=exact))
    assert Cell.from_file(exact / "copy.yaml") == cell


# ----------------------------------------------------------------------------- the command line


def test_cli_flags_print_and_export_the_corrections(exact, tmp_path, capsys):
    out_json, out_arm = tmp_path / "result.json", tmp_path / "arm_corrected.yaml"
    code, out, err = run_cli(capsys, "calibrate", "--joints", exact / "joints.csv", "--joints-unit", "deg",
                             "--arm", exact / "arm.yaml", "--camera", exact / "camera.csv", "--camera-format",
                             "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand", "--match", "name",
                             "-o", out_json, "--arm-out", out_arm)
    assert code == 0, err
    assert "17 DH parameters identified and used in the answer" in out
    assert "not identifiable from hand-eye data, kept nominal: J1 d, J1 offset" in out
    assert f"wrote {out_arm}" in out
    r = json.loads(out_json.read_text())
    check_recovered(np.array(r["X"]), np.array(r["Y"]), r["kinematics"], truth_of(exact))
    assert r["inputs"]["robot"]["file"] == str(exact / "joints.csv")
    back = read_arm(out_arm)
    rows = np.array([[row["a"], math.radians(row["alpha"]), row["d"], math.radians(row["offset"])]
                     for row in r["kinematics"]["dh"]])
    np.testing.assert_allclose(back.dh.table, rows, rtol=1e-13, atol=1e-13)


def test_cli_write_config_then_config(exact, tmp_path, capsys):
    config = tmp_path / "cell.yaml"
    code, out, err = run_cli(capsys, "calibrate", "--joints", exact / "joints.csv", "--joints-unit", "deg",
                             "--arm", exact / "arm.yaml", "--camera", exact / "camera.csv", "--camera-format",
                             "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand", "--write-config", config)
    assert code == 0, err
    text = config.read_text()
    assert "joints:" in text and "arm:" in text and "problem: axyb-kinematic" in text
    code, out, err = run_cli(capsys, "calibrate", "--config", config, "--json")
    assert code == 0, err
    check_recovered(np.array(json.loads(out)["X"]), np.array(json.loads(out)["Y"]), json.loads(out)["kinematics"],
                    truth_of(exact))


def _bad_arm(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad_arm.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("case, expected", [
    ("no-unit", "--joints-unit is required (deg or rad)"),
    ("rad-but-degrees", "(the readings look like degrees): give --joints-unit deg"),
    ("arm-key", "unknown key 'lenght_unit'"),
    ("arm-modified", "modified (Craig) DH tables are not read yet"),
    ("arm-urdf", "robot.urdf' holds no joints"),
    ("arm-prismatic", "joint 'slide' is prismatic; only revolute (and continuous) joints are read"),
    ("arm-joints", "5 joint columns"),
    ("no-arm", "--arm FILE is required with --joints"),
    ("robot-too", "drop --robot"),
    ("joint-text", "column 'J2': 'abc' is not a finite number"),
    ("interpolate", "does not apply to --joints"),
])
def test_bad_inputs_are_one_line_errors_with_exit_2(exact, tmp_path, capsys, case, expected):
    joints, arm, unit = exact / "joints.csv", exact / "arm.yaml", "deg"
    extra: list = []
    good_arm = (exact / "arm.yaml").read_text()
    if case == "no-unit":
        unit = None
    elif case == "rad-but-degrees":
        unit = "rad"
    elif case == "arm-key":
        arm = _bad_arm(tmp_path, good_arm.replace("length_unit", "lenght_unit"))
    elif case == "arm-modified":
        arm = _bad_arm(tmp_path, good_arm.replace("standard-dh", "modified-dh"))
    elif case == "arm-urdf":
        pytest.importorskip("yourdfpy")  # without it: "pip install 'handeye[urdf]'" (test_urdf_needs_its_extra)
        arm = tmp_path / "robot.urdf"
        arm.write_text("<robot name='r'/>")
    elif case == "arm-joints":
        joints = tmp_path / "joints.csv"
        joints.write_text("\n".join(",".join(line.split(",")[:6]) for line in (exact / "joints.csv").read_text()
                                    .splitlines()) + "\n")
        joints.write_text(joints.read_text().replace("J1", "K1").replace("J2", "K2"))
    elif case == "arm-prismatic":
        pytest.importorskip("yourdfpy")
        arm = tmp_path / "robot.urdf"
        arm.write_text('<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
                       '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
                       '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
                       '<joint name="slide" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="1 0 0"/>'
                       '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    elif case == "no-arm":
        arm = None
    elif case == "robot-too":
        extra = ["--robot", exact / "camera.csv", "--robot-format", "opencv-rvec"]
    elif case == "joint-text":
        joints = tmp_path / "joints.csv"
        lines = (exact / "joints.csv").read_text().splitlines()
        cells = lines[3].split(",")
        cells[2] = "abc"
        lines[3] = ",".join(cells)
        joints.write_text("\n".join(lines) + "\n")
    elif case == "interpolate":
        extra = ["--match", "interpolate"]
    argv = ["calibrate", "--joints", joints, "--camera", exact / "camera.csv", "--camera-format", "opencv-rvec",
            "--camera-unit", "mm", "--setup", "eye-in-hand", *extra]
    argv += ["--joints-unit", unit] if unit else []
    argv += ["--arm", arm] if arm else []
    code, out, err = run_cli(capsys, *argv)
    assert code == 2, (out, err)
    assert expected in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_library_errors_are_input_errors(exact):
    with pytest.raises(InputError, match="`arm: FILE` is required with `joints`"):
        Cell(setup="eye-in-hand", joints=JointStream(exact / "joints.csv", unit="deg"),
             camera=handeye.workflow.cell.CameraStream(exact / "camera.csv", format="opencv-rvec"))
    with pytest.raises(InputError, match="`joints.unit` must be one of deg, rad"):
        Cell(setup="eye-in-hand", joints=JointStream(exact / "joints.csv", unit="degrees"), arm=exact / "arm.yaml",
             camera=handeye.workflow.cell.CameraStream(exact / "camera.csv", format="opencv-rvec"))
    with pytest.raises(InputError, match="made from the robot's joint readings"):
        Cell(setup="eye-in-hand", problem="axyb-kinematic", robot=handeye.workflow.cell.PoseStream(
            exact / "camera.csv", format="opencv-rvec"),
             camera=handeye.workflow.cell.CameraStream(exact / "camera.csv", format="opencv-rvec"))
    assert issubclass(InputError, ValueError)


# ----------------------------------------------------------------------------- ROS bags


def test_joint_states_of_a_ros_bag(tmp_path):
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState, Header = store.types["sensor_msgs/msg/JointState"], store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    q = np.random.default_rng(3).uniform(-2, 2, (5, 6))
    path = tmp_path / "joints_bag"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conn = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k in (3, 1, 0, 4, 2):  # out of order, and the joints named in another order each time
            perm = np.roll(np.arange(6), k)
            msg = JointState(header=Header(stamp=Time(sec=100 + k, nanosec=0), frame_id=""),
                             name=[f"joint_{i + 1}" for i in perm], position=q[k][perm],
                             velocity=np.zeros(0), effort=np.zeros(0))
            writer.write(conn, (100 + k) * 10**9, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    stack = read_joints(path, topic="/joint_states")
    order = [stack.joints.index(f"joint_{i + 1}") for i in range(6)]
    np.testing.assert_allclose(stack.q[:, order], q, atol=0)
    np.testing.assert_array_equal(stack.stamps, [100, 101, 102, 103, 104])
    with pytest.raises(InputError, match="not in it; the joint readings are a sensor_msgs/msg/JointState topic"):
        read_joints(path, topic="/nope")
    with pytest.raises(InputError, match="hold radians"):
        read_joints(path, "deg", topic="/joint_states")


def test_calibrate_from_a_bag_of_joint_states_matched_by_time(exact, tmp_path):
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState, Header = store.types["sensor_msgs/msg/JointState"], store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    cell = example_cell(noise=False)
    path = tmp_path / "run_bag"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conn = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k, q in enumerate(cell["q"]):
            perm = [5, 0, 4, 1, 3, 2]  # the arm's joints, named, in another order
            msg = JointState(header=Header(stamp=Time(sec=50 + k, nanosec=0), frame_id=""),
                             name=[NAMES[i] for i in perm], position=q[perm], velocity=np.zeros(0),
                             effort=np.zeros(0))
            writer.write(conn, (50 + k) * 10**9, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    camera = (exact / "camera.csv").read_text().splitlines()
    lines = ["t" + camera[0][4:]] + [f"{50 + k + 0.002:.3f}" + line[3:] for k, line in enumerate(camera[1:])]
    (tmp_path / "camera.csv").write_text("\n".join(lines) + "\n")
    result = handeye.calibrate(Cell(setup="eye-in-hand", joints=JointStream(path, topic="/joint_states"),
                                    arm=exact / "arm.yaml",
                                    camera=handeye.workflow.cell.CameraStream(tmp_path / "camera.csv",
                                                                              format="opencv-rvec", unit="mm"),
                                    matching=handeye.workflow.cell.Matching(method="time", max_dt=0.01)))
    assert result.to_dict()["matching"]["matched"] == 40
    check_recovered(result.X, result.Y, result.to_dict()["kinematics"], truth_of(exact))


# ----------------------------------------------------------------------------- the bundled example


def test_bundled_example_is_reproducible_and_calibrates(tmp_path):
    folder = kinematic_example_dir()
    write_example(tmp_path)
    for name in ("joints.csv", "camera.csv", "arm.yaml", "cell.yaml", "truth.json"):
        assert (tmp_path / name).read_bytes() == (folder / name).read_bytes(), name
    assert sum((folder / n).stat().st_size for n in ("joints.csv", "camera.csv", "arm.yaml", "cell.yaml",
                                                     "truth.json")) < 50_000
    result = handeye.calibrate(Cell.from_file(folder / "cell.yaml"))
    assert result.usable
    k = result.to_dict()["kinematics"]
    assert k["used"]
    expected = true_corrections(truth_of(folder))
    within = [abs(p["correction"] - expected[p["name"]]) < 3 * p["std"] for p in k["parameters"]]
    assert sum(within) >= 15, k["parameters"]  # the 1-sigma are honest
    truth = truth_of(folder)
    assert np.linalg.norm(result.X[:3, 3] - truth["X"][:3, 3]) < 0.5  # mm, with 0.1 mm camera noise


# ----------------------------------------------------------------------------- URDF


def urdf_of(arm, base: np.ndarray, tool: np.ndarray, seed: int) -> tuple[str, np.ndarray]:
    """A URDF of the DH arm `arm` behind `base`, with tool0 at `tool` after its last frame, each
    link's frame turned by a random rotation G_j (so the joint axes are not the links' z): joint j's
    origin G_{j-1}^-1 C_{j-1} G_j, axis G_j^-1 z (C_0 = base). Returns (text, T_root_tool0 at q = 0)."""
    rng = np.random.default_rng(seed)
    C = [base, *arm.links()]
    G = [np.eye(4)] + [np.eye(4) for _ in range(arm.joints)]
    for g in G[1:]:
        g[:3, :3] = Rotation.random(random_state=rng).as_matrix()

    def origin(T):
        xyz = " ".join(f"{v:.17g}" for v in T[:3, 3])
        rpy = " ".join(f"{v:.17g}" for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
        return f'<origin xyz="{xyz}" rpy="{rpy}"/>'

    links = ["base_link", *(f"link_{j + 1}" for j in range(arm.joints)), "tool0"]
    parts = [f'<link name="{name}"/>' for name in links]
    for j in range(arm.joints):
        T = np.linalg.inv(G[j]) @ C[j] @ G[j + 1]
        axis = " ".join(f"{v:.17g}" for v in G[j + 1][:3, :3].T @ [0.0, 0.0, 1.0])
        parts.append(f'<joint name="joint_{j + 1}" type="revolute"><parent link="{links[j]}"/><child '
                     f'link="{links[j + 1]}"/>{origin(T)}<axis xyz="{axis}"/><limit lower="-3" upper="3" effort="1" '
                     'velocity="1"/></joint>')
    parts.append(f'<joint name="tool_joint" type="fixed"><parent link="{links[-2]}"/><child link="tool0"/>'
                 f'{origin(np.linalg.inv(G[-1]) @ C[-1] @ tool)}</joint>')
    return '<robot name="arm">' + "".join(parts) + "</robot>", base @ arm.forward(np.zeros((1, arm.joints)))[0] @ tool


def test_a_urdf_is_an_exact_dh_table_with_base_and_tool(tmp_path):
    pytest.importorskip("yourdfpy")
    from handeye.io.urdf_arm import urdf_pose

    base = np.eye(4)
    base[:3, :3], base[:3, 3] = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), [0.05, -0.02, 0.1]
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = Rotation.from_rotvec([0.0, 0.4, 0.1]).as_matrix(), [0.01, 0.0, 0.03]
    text, _ = urdf_of(LR_MATE_200ID.scaled(1000.0), base, tool, seed=5)
    (tmp_path / "arm.urdf").write_text(text)
    arm = read_arm(tmp_path / "arm.urdf")
    assert arm.names == tuple(f"joint_{j}" for j in range(1, 7)) and arm.frames == ("base_link", "tool0")
    q = np.random.default_rng(2).uniform(-2.5, 2.5, (6, 6))
    truth = LR_MATE_200ID.scaled(1000.0)
    for qi in q:
        np.testing.assert_allclose(arm.forward(qi[None])[0], base @ truth.forward(qi[None])[0] @ tool, atol=1e-12)
        np.testing.assert_allclose(urdf_pose(tmp_path / "arm.urdf", qi), arm.forward(qi[None])[0], atol=1e-12)
    # the same identifiable set as the DH table it came from (joints 2 and 3 parallel)
    assert len(model.structural(arm.dh.table).identifiable) == 17
    # written as an arm file with base and tool, read back: the same model
    (tmp_path / "arm.yaml").write_text(arm_yaml(arm))
    back = read_arm(tmp_path / "arm.yaml")
    np.testing.assert_allclose(back.forward(q), arm.forward(q), atol=1e-12)


def test_calibrate_with_a_urdf_gives_x_and_y_in_its_frames(exact, tmp_path):
    """The example cell (its arm's DH errors in a URDF's own frames are not representable as the
    nominal table plus errors, so the truth here is the URDF's nominal arm): X in tool0, Y in
    base_link, to 1e-9."""
    pytest.importorskip("yourdfpy")
    base = np.eye(4)
    base[:3, :3], base[:3, 3] = Rotation.from_rotvec([0.0, 0.0, 0.7]).as_matrix(), [0.1, 0.2, -0.05]
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = Rotation.from_rotvec([0.3, 0.0, 0.0]).as_matrix(), [0.0, 0.0, 0.02]
    arm_m = LR_MATE_200ID.scaled(1000.0)
    text, _ = urdf_of(arm_m, base, tool, seed=9)
    (tmp_path / "robot.urdf").write_text(text)
    cell = example_cell(noise=False)
    X, Y = np.array(cell["truth"]["X"]), np.array(cell["truth"]["Y"])
    X[:3, 3] /= 1000
    Y[:3, 3] /= 1000
    X_tool, Y_base = np.linalg.inv(tool) @ X, base @ Y  # the cell's truth in the URDF's frames
    A = base @ arm_m.forward(cell["q"]) @ tool
    T_cam_target = np.linalg.inv(np.linalg.inv(Y_base) @ A @ X_tool)
    lines = ["name," + ",".join(f"joint_{j}" for j in range(1, 7))]
    lines += [",".join([n, *(f"{v:.17g}" for v in q)]) for n, q in zip(cell["names"], cell["q"])]
    (tmp_path / "joints.csv").write_text("\n".join(lines) + "\n")
    lines = ["name,x,y,z,rx,ry,rz"]
    for n, T in zip(cell["names"], T_cam_target):
        lines.append(",".join([n, *(f"{v:.17g}" for v in (*T[:3, 3], *Rotation.from_matrix(T[:3, :3]).as_rotvec()))]))
    (tmp_path / "camera.csv").write_text("\n".join(lines) + "\n")
    result = handeye.calibrate(Cell(setup="eye-in-hand", joints=JointStream(tmp_path / "joints.csv", unit="rad"),
                                    arm=tmp_path / "robot.urdf", solver="kinematic-lm",
                                    camera=handeye.workflow.cell.CameraStream(tmp_path / "camera.csv",
                                                                              format="opencv-rvec", unit="m"),
                                    matching=handeye.workflow.cell.Matching(method="name")))
    np.testing.assert_allclose(result.X, X_tool, atol=1e-9)
    np.testing.assert_allclose(result.Y, Y_base, atol=1e-9)
    k = result.to_dict()["kinematics"]
    assert k["frames"] == ["base_link", "tool0"] and k["length_unit"] == "m"
    assert max(abs(p["correction"]) for p in k["parameters"]) < 1e-9
    corrected = read_arm((tmp_path / "corrected.yaml", (tmp_path / "corrected.yaml").write_text(result.arm_yaml()))[0])
    np.testing.assert_allclose(corrected.forward(cell["q"]), A, atol=1e-12)


def test_urdf_needs_its_extra(tmp_path, monkeypatch):
    """Without yourdfpy (handeye[urdf]) a URDF arm is refused in one line naming the extra."""
    import sys

    from handeye.io.arm_files import read_arm

    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # import yourdfpy now raises ImportError
    arm = tmp_path / "robot.urdf"
    arm.write_text("<robot name='r'/>")
    with pytest.raises(InputError, match=r"needs the package yourdfpy \(pip install 'handeye\[urdf\]'\)") as caught:
        read_arm(arm)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("case, says", [
    ("revolute", "is the child of joints 'j1', 'j4'"),
    ("fixed", "is the child of joints 'j2', 'j4'"),
    ("detached", "joints 'j1', 'j2' form a loop"),
])
def test_a_urdf_whose_joints_loop_is_refused_at_once(tmp_path, case, says):
    """Joints that form a loop (through revolute or fixed joints, or a loop beside the arm with no
    root) are refused in one line naming them, instead of followed for ever (it hung at 2.2 GB, or
    ended in RecursionError)."""
    pytest.importorskip("yourdfpy")

    def joint(name, kind, parent, child):
        return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/>'
                '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')

    body = {"revolute": [("j1", "revolute", "base", "a"), ("j2", "revolute", "a", "b"), ("j3", "revolute", "b", "c"),
                         ("j4", "revolute", "c", "a")],
            "fixed": [("j1", "revolute", "base", "a"), ("j2", "revolute", "a", "b"), ("j3", "fixed", "b", "c"),
                      ("j4", "fixed", "c", "b")],
            "detached": [("j1", "fixed", "b", "c"), ("j2", "fixed", "c", "b")]}[case]
    links = "".join(f'<link name="{name}"/>' for name in ("base", "a", "b", "c"))
    (tmp_path / "loop.urdf").write_text(f'<robot name="r">{links}{"".join(joint(*j) for j in body)}</robot>')
    with pytest.raises(InputError, match=says) as caught:
        read_arm(tmp_path / "loop.urdf")
    assert "\n" not in str(caught.value)


def _rad_arm(folder):
    import re

    text = (folder / "arm.yaml").read_text()
    for key in ("alpha", "offset"):
        text = re.sub(rf"{key}: (-?\d+)", lambda m: f"{m.group(0).split(':')[0]}: {math.radians(float(m.group(1))):.6f}",
                      text)
    (folder / "arm.yaml").write_text(text)


def _camera_m(folder):
    (folder / "cell.yaml").write_text((folder / "cell.yaml").read_text().replace("  unit: mm", "  unit: m"))


def _joints_swapped(folder):
    lines = (folder / "joints.csv").read_text().splitlines()
    rows = [lines[0]]
    for line in lines[1:]:
        parts = line.split(",")
        parts[2], parts[3] = parts[3], parts[2]
        rows.append(",".join(parts))
    (folder / "joints.csv").write_text("\n".join(rows) + "\n")


def _board_long(folder):
    lines = (folder / "camera.csv").read_text().splitlines()
    rows = [lines[0]]
    for line in lines[1:]:
        parts = line.split(",")
        parts[1:4] = [repr(float(v) * 1.02) for v in parts[1:4]]
        rows.append(",".join(parts))
    (folder / "camera.csv").write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("mistake, says", [
    (_rad_arm, "beyond what a real arm is off its model"),
    (_camera_m, "if the camera file is in mm, not m"),
    (_joints_swapped, "check the joint readings' unit and order"),
    (_board_long, "best when multiplied by 0.98"),
])
def test_the_users_mistakes_are_not_absorbed_into_dh_corrections(tmp_path, mistake, says):
    """The bundled kinematic cell with a user's mistake: the arm file's angles in radians under
    `angle_unit: deg` (X was 20 m off), the camera poses' unit m on a file in mm (30 m off, J2's
    a corrected by +330 m), two joint columns swapped (Y 314 mm off), the board 2% long (Y 27 mm,
    87 of its 1-sigma): each was `optimal`. Now `unreliable`, with a warning naming the mistake
    (the pose cell's plausibility and scale checks on the nominal arm, and corrections beyond a
    real arm's); the cell as bundled stays `optimal` and quiet."""
    from handeye.io.examples import kinematic_example_dir

    shutil.copytree(kinematic_example_dir(), tmp_path, dirs_exist_ok=True)
    clean = handeye.calibrate(Cell.from_file(tmp_path / "cell.yaml"))
    assert clean.solution.status.value == "optimal"
    assert not any("beyond what a real arm" in w or "implausible" in w or "multiplied by" in w for w in clean.warnings)
    mistake(tmp_path)
    result = handeye.calibrate(Cell.from_file(tmp_path / "cell.yaml"))
    assert result.solution.status.value == "unreliable" and not result.usable
    assert any(says in w for w in result.warnings), [w[:120] for w in result.warnings]


def test_an_arm_in_metres_shows_its_corrections_in_millimetres():
    """A URDF's lengths are in m, so were its corrections (J2 a +0.00073): shown in mm, as an arm's
    errors are read, with the unit said."""
    from handeye.workflow.joint_cell import kinematics_lines

    k = {"length_unit": "m", "angle_unit": "deg", "arm": "robot.urdf", "frames": ("base_link", "tool0"), "used": True,
         "not_identifiable": [], "not_identifiable_why": "",
         "parameters": [{"name": "joint_2 a", "unit": "m", "nominal": 0.33, "estimate": 0.33073, "correction": 0.00073,
                         "std": 0.0001},
                        {"name": "joint_2 alpha", "unit": "deg", "nominal": 0.0, "estimate": 0.3, "correction": 0.3,
                         "std": 0.014}]}
    lines = kinematics_lines(k)
    row = next(line for line in lines if line.strip().startswith("joint_2 a "))
    assert "+0.73" in row and row.split()[-1] == "0.1"
    assert next(line for line in lines if line.strip().startswith("joint_2 alpha")).split()[-2] == "+0.3"
    assert "corrections of lengths and their 1-sigma in mm" in lines[-1]
