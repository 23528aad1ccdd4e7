"""handeye.io.pose_readers / handeye.io.pose_formats: every preset against an explicit product of
elementary rotations, round trips through every file type, the real FANUC export, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from handeye.base.errors import InputError
from handeye.geometry.se3 import random_poses
from handeye.io.pose_formats import PRESETS, format_names, parse_format
from handeye.io.pose_readers import (
    MAX_CORRECTION,
    poses_from_rows,
    read_poses,
)
from handeye.io.pose_writers import write_poses

FANUC_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "robcalib_axyb_fanuc_poses"


def Rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def axis_angle(v):
    """Rodrigues' formula written out (independent of scipy)."""
    v = np.asarray(v, float)
    th = np.linalg.norm(v)
    k = v / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def quat_wxyz(w, x, y, z):
    """Hamilton unit quaternion to matrix, written out."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


D = np.deg2rad
A1, A2, A3 = 30.0, -50.0, 110.0  # three angles in degrees, distinct so that any mix-up shows
Q = np.array([0.8, 0.2, -0.4, 0.4]) / np.linalg.norm([0.8, 0.2, -0.4, 0.4])  # w, x, y, z
RV = np.array([0.3, -1.1, 0.7])

#: format -> (one row, expected rotation from the vendor's convention, expected translation)
REFERENCE = {
    "fanuc-wpr": ([1, 2, 3, A1, A2, A3], Rz(D(A3)) @ Ry(D(A2)) @ Rx(D(A1)), [1, 2, 3]),
    "yaskawa": ([1, 2, 3, A1, A2, A3], Rz(D(A3)) @ Ry(D(A2)) @ Rx(D(A1)), [1, 2, 3]),
    "kuka-abc": ([1, 2, 3, A1, A2, A3], Rz(D(A1)) @ Ry(D(A2)) @ Rx(D(A3)), [1, 2, 3]),
    "staubli": ([1, 2, 3, A1, A2, A3], Rx(D(A1)) @ Ry(D(A2)) @ Rz(D(A3)), [1, 2, 3]),
    "abb-quat": ([1, 2, 3, *Q], quat_wxyz(*Q), [1, 2, 3]),
    "xyz-quat-wxyz": ([1, 2, 3, *Q], quat_wxyz(*Q), [1, 2, 3]),
    "xyz-quat-xyzw": ([1, 2, 3, *Q[1:], Q[0]], quat_wxyz(*Q), [1, 2, 3]),
    "xyz-rotvec": ([1, 2, 3, *RV], axis_angle(RV), [1, 2, 3]),
    "ur-rotvec": ([1, 2, 3, *RV], axis_angle(RV), [1, 2, 3]),
    "opencv-rvec": ([*RV, 1, 2, 3], axis_angle(RV), [1, 2, 3]),
    "euler:xyz:deg": ([1, 2, 3, A1, A2, A3], Rz(D(A3)) @ Ry(D(A2)) @ Rx(D(A1)), [1, 2, 3]),
    "euler:ZYX:rad": ([1, 2, 3, D(A1), D(A2), D(A3)], Rz(D(A1)) @ Ry(D(A2)) @ Rx(D(A3)), [1, 2, 3]),
    "euler:ZYZ:deg": ([1, 2, 3, A1, A2, A3], Rz(D(A1)) @ Ry(D(A2)) @ Rz(D(A3)), [1, 2, 3]),
}


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_preset_matches_its_documented_convention(name):
    row, R, t = REFERENCE[name]
    stack = poses_from_rows([row], name, unit="mm")
    np.testing.assert_allclose(stack.poses[0, :3, :3], R, atol=1e-12)
    np.testing.assert_allclose(stack.poses[0, :3, 3], t, atol=1e-12)
    assert not stack.poses.flags.writeable


def test_every_preset_has_a_reference():
    assert set(PRESETS) - {"matrix", "matrix34"} <= set(REFERENCE)


def test_vendor_units_and_angles():
    assert {n: (PRESETS[n].unit, PRESETS[n].degrees) for n in ("fanuc-wpr", "kuka-abc", "staubli", "yaskawa", "ur-rotvec")} == {
        "fanuc-wpr": ("mm", True), "kuka-abc": ("mm", True), "staubli": ("mm", True), "yaskawa": ("mm", True),
        "ur-rotvec": ("m", False)}
    assert read_unit_default("ur-rotvec") == "m" and read_unit_default("abb-quat") == "mm"


def read_unit_default(name):
    return poses_from_rows([REFERENCE[name][0]], name).unit


FILE_NAMES = ["a.csv", "a.tsv", "a.txt", "a.json", "a.yaml", "a.npz"]


@pytest.mark.parametrize("fmt", [*PRESETS, "euler:ZXY:deg", "euler:yzx:rad"])
@pytest.mark.parametrize("fname", FILE_NAMES)
def test_round_trip(tmp_path, fmt, fname):
    T = random_poses(5, np.random.default_rng(7), translation_scale=300.0)
    before = T.copy()
    path = write_poses(tmp_path / fname, T, fmt, unit="mm")
    stack = read_poses(path, fmt, unit="mm")  # text files do not record their unit
    np.testing.assert_allclose(stack.poses, T, atol=1e-9)
    np.testing.assert_array_equal(T, before)
    assert stack.unit == "mm" and stack.format == parse_format(fmt).name


def test_round_trip_keeps_names_and_stamps(tmp_path):
    rows = [[f"P{i}", 0.5 * i, 1, 2, 3, 10, 20, 30 + i] for i in range(4)]
    path = tmp_path / "p.csv"
    path.write_text("name,time,x,y,z,w,p,r\n" + "\n".join(",".join(map(str, r)) for r in rows))
    stack = read_poses(path, "fanuc-wpr")
    assert stack.names == ("P0", "P1", "P2", "P3")
    np.testing.assert_array_equal(stack.stamps, [0, 0.5, 1.0, 1.5])
    for fname in ("q.json", "q.npz", "q.csv"):
        again = read_poses(write_poses(tmp_path / fname, stack, "fanuc-wpr"), "fanuc-wpr")
        assert again.names == stack.names
        np.testing.assert_allclose(again.stamps, stack.stamps)
        np.testing.assert_allclose(again.poses, stack.poses, atol=1e-12)


@pytest.mark.skipif(not FANUC_DIR.is_dir(), reason="shared data set robcalib_axyb_fanuc_poses not present")
def test_real_fanuc_export_reads_to_se3():
    """RobCalib_AXYB's FANUC TCP poses (index,x_mm,...,r_deg; and the tab-aligned RobotDatas.txt)."""
    s16 = read_poses(FANUC_DIR / "ExperimentData" / "robot_tcp.csv", "fanuc-wpr")
    s31 = read_poses(FANUC_DIR / "ExperimentData1" / "robot_tcp.csv", "fanuc-wpr")
    txt = read_poses(FANUC_DIR / "ExperimentData1" / "RobotDatas.txt", "fanuc-wpr")
    assert (len(s16), len(s31), len(txt)) == (16, 31, 31)
    assert s16.names[:3] == ("1", "2", "3") and s16.unit == "mm" and txt.names is None
    np.testing.assert_allclose(txt.poses, s31.poses, atol=1e-9)
    # first pose by hand: 392.557, 6.488, 22.209, W -152.293, P -24.2, R -53.975
    R = Rz(D(-53.975)) @ Ry(D(-24.2)) @ Rx(D(-152.293))
    np.testing.assert_allclose(s16.poses[0, :3, :3], R, atol=1e-12)
    np.testing.assert_allclose(s16.poses[0, :3, 3], [392.557, 6.488, 22.209])
    for s in (s16, s31):
        reach = np.linalg.norm(s.poses[:, :3, 3], axis=1)
        assert 300 < reach.min() and reach.max() < 800  # mm: a cell of a small arm
        assert (s.poses[:, 2, 2] < -0.5).all()  # the tool (camera) z axis points down at the board
        np.testing.assert_allclose(np.linalg.det(s.poses[:, :3, :3]), 1.0, atol=1e-12)


def test_headerless_time_column_becomes_stamps(tmp_path):
    path = tmp_path / "eth.csv"
    path.write_text("1491754391.84618, 0.1, -0.05, 0.87, -0.97365417022617451, -0.037093982444961066, "
                    "0.061324769653462861, 0.21647370716671938\n")
    s = read_poses(path, "xyz-quat-xyzw", unit="m")
    assert s.stamps[0] == pytest.approx(1491754391.84618) and s.names is None


def test_explicit_columns_by_name_and_index(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("id;qw;qx;qy;qz;tx;ty;tz;junk\n7;1;0;0;0;10;20;30;x\n")
    s = read_poses(path, "xyz-quat-wxyz", unit="mm")
    np.testing.assert_array_equal(s.poses[0, :3, 3], [10, 20, 30])
    assert s.names == ("7",)
    s2 = read_poses(path, "xyz-quat-wxyz", unit="mm", columns=["TX", "ty", "tz", 1, 2, 3, 4])
    np.testing.assert_array_equal(s2.poses, s.poses)


def rounded_matrix_file(tmp_path, decimals, name="m.csv"):
    T = random_poses(4, np.random.default_rng(1), 100.0)
    path = tmp_path / name
    path.write_text("\n".join(" ".join(f"{v:.{decimals}f}" for v in P.ravel()) for P in T))
    return path, T


def test_orthonormalize_is_required_then_reported(tmp_path):
    path, T = rounded_matrix_file(tmp_path, 3)
    with pytest.raises(InputError, match=r"orthonormalize=True \(CLI --orthonormalize\)") as exc:
        read_poses(path, "matrix", unit="mm")
    assert "largest |R^T R - I| = " in str(exc.value)
    s = read_poses(path, "matrix", unit="mm", orthonormalize=True)
    assert 0 < s.max_correction < 5e-3
    np.testing.assert_allclose(s.poses[:, :3, :3].transpose(0, 2, 1) @ s.poses[:, :3, :3], np.eye(3)[None].repeat(4, 0), atol=1e-14)
    np.testing.assert_allclose(s.poses, T, atol=2e-3)


def test_orthonormalize_refuses_more_than_rounding(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("1.1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(InputError, match="not rounding"):
        read_poses(path, "matrix", unit="m", orthonormalize=True)
    assert MAX_CORRECTION == 0.01


def test_unnormalised_quaternions(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0.7071,0.7071\n")
    with pytest.raises(InputError, match="orthonormalize=True"):
        read_poses(path, "xyz-quat-xyzw", unit="m")
    s = read_poses(path, "xyz-quat-xyzw", unit="m", orthonormalize=True)
    assert s.max_correction == pytest.approx(abs(np.hypot(0.7071, 0.7071) - 1))


@pytest.mark.parametrize("content, fmt, kw, match", [
    ("1,2,3,4,5\n", "fanuc-wpr", {}, r"5 columns, but format fanuc-wpr has 6"),
    ("x,y,z,w,p,r\n1,2,3,4,5,6\n1,2,abc,4,5,6\n", "fanuc-wpr", {}, r"line 3, column 3 \(z\): 'abc' is not a number"),
    ("1,2,3,4,5,nan\n", "fanuc-wpr", {}, r"line 1, column 6: 'nan' is not finite"),
    ("1,2,3,4,5,inf\n", "fanuc-wpr", {}, "not finite"),
    ("", "fanuc-wpr", {}, "no poses"),
    ("# only a comment\n\n", "fanuc-wpr", {}, "no poses"),
    ("x,y,z,w,p,r\n", "fanuc-wpr", {}, "a header line .* but no poses"),
    ("1,2,3,4,5,6\n1,2,3,4,5\n", "fanuc-wpr", {}, "line 2 has 5 cells, line 1 has 6"),
    ("1,2,3,4,5,6\n", "fanuc-xyz", {}, r"unknown pose format 'fanuc-xyz'; known: matrix, matrix34, .*euler:SEQ"),
    ("1,2,3,4,5,6\n", "euler:xyq", {}, "SEQ three of"),
    ("1,2,3,4,5,6\n", "euler:xYz:deg", {}, "mixes cases"),
    ("1,2,3,4,5,6\n", "euler:xyz", {"unit": "mm"}, "does not say its angle unit"),
    ("1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n", "matrix", {}, r"unit='mm' or unit='m' \(CLI --unit\)"),
    ("1,2,3,4,5,6\n", "fanuc-wpr", {"unit": "cm"}, r"unit must be one of \['mm', 'm'\]"),
    ("1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,2\n", "matrix", {"unit": "m"}, "last row is not 0 0 0 1"),
    ("-1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n", "matrix", {"unit": "m"}, "reflection"),
    ("1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1\n", "matrix", {"unit": "m", "degrees": True}, "degrees applies"),
    ("x,y,z,w,p\n1,2,3,4,5\n", "fanuc-wpr", {}, "names some columns of fanuc-wpr but not r"),
    ("1,2,3,4,5,6\n", "fanuc-wpr", {"columns": ["x", "y"]}, "columns must list the 6 columns"),
    ("1,2,3,4,5,6\n", "fanuc-wpr", {"columns": [0, 1, 2, 3, 4, 9]}, "out of range"),
    ("0,0,0,0,0,0,0\n", "xyz-quat-xyzw", {"unit": "m"}, "quaternion is zero"),
])
def test_bad_text_input_is_one_line_input_error(tmp_path, content, fmt, kw, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(InputError, match=match) as exc:
        read_poses(path, fmt, **kw)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("name, content, match", [
    ("a.json", "{\"poses\": []}", "pose list is empty"),
    ("a.json", "{\"rows\": [[1,2,3,4,5,6]]}", "under the key 'poses'"),
    ("a.json", "[[1,2,3,4,5,6], [1,2,3]]", "pose 2 has 3 numbers"),
    ("a.json", "[[1,2,3,4,5,\"x\"]]", r"pose 1, column 6: 'x' is not a number"),
    ("a.json", "[[1,2,3,4,5,true]]", "not a number"),
    ("a.json", "[1,2", "invalid JSON at line 1"),
    ("a.json", "{\"units\": \"cm\", \"poses\": [[1,2,3,4,5,6]]}", "unit must be one of"),
    ("a.yaml", "poses: [[1, 2, 3, 4, 5, .nan]]", "not finite"),
    ("a.yaml", "- [1, 2, 3\n", "invalid YAML"),
    ("a.yaml", "", "empty"),
    ("a.xlsx", "", "unsupported pose file extension '.xlsx'"),
])
def test_bad_structured_input(tmp_path, name, content, match):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(InputError, match=match) as exc:
        read_poses(path, "fanuc-wpr")
    assert "\n" not in str(exc.value)


def test_json_shapes_and_units(tmp_path):
    T = random_poses(3, np.random.default_rng(2), 1.0)
    (tmp_path / "m.json").write_text(json.dumps({"units": "m", "poses": T.tolist()}))
    s = read_poses(tmp_path / "m.json", "matrix")
    np.testing.assert_array_equal(s.poses, T)
    assert s.unit == "m" and s.in_unit("mm").poses[0, 0, 3] == pytest.approx(1000 * T[0, 0, 3])
    with pytest.raises(InputError, match="the file says units 'm' but unit='mm'"):
        read_poses(tmp_path / "m.json", "matrix", unit="mm")
    (tmp_path / "m34.json").write_text(json.dumps(T[:, :3].tolist()))
    with pytest.raises(InputError, match="12 columns, but format matrix has 16"):
        read_poses(tmp_path / "m34.json", "matrix", unit="m")
    np.testing.assert_array_equal(read_poses(tmp_path / "m34.json", "matrix34", unit="m").poses, T)


def test_npz_refuses_pickles(tmp_path):
    np.savez(tmp_path / "o.npz", poses=np.array([[1, "a"]], dtype=object))
    with pytest.raises(InputError, match="NPZ"):
        read_poses(tmp_path / "o.npz", "fanuc-wpr")


def test_missing_file_and_format_listing(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_poses(tmp_path / "none.csv", "fanuc-wpr")
    assert format_names()[-1] == "euler:SEQ[:deg|rad]" and "opencv-rvec" in format_names()
    assert parse_format("FANUC-WPR") is PRESETS["fanuc-wpr"]


def test_explicit_delimiter(tmp_path):
    path = tmp_path / "d.txt"
    path.write_text("# exported\n1;2;3;0;0;90\n")
    assert read_poses(path, "fanuc-wpr", delimiter=";").poses[0, 1, 0] == pytest.approx(1.0)
    with pytest.raises(InputError, match="check the delimiter"):
        read_poses(path, "fanuc-wpr", delimiter=",")
    with pytest.raises(InputError, match="delimiter must be one of"):
        read_poses(path, "fanuc-wpr", delimiter="|")
    (tmp_path / "d.json").write_text("[[1, 2, 3, 0, 0, 90]]")
    with pytest.raises(InputError, match="delimiter applies to text files"):
        read_poses(tmp_path / "d.json", "fanuc-wpr", delimiter=",")


@pytest.mark.parametrize("extra, message", [
    ({"names": np.array("one")}, "'names' must be a 1-D array"),
    ({"stamps": np.array(["a", "b", "c"])}, "'stamps' must be a 1-D array of finite numbers"),
    ({"stamps": np.array([0.0, np.nan, 2.0])}, "'stamps' must be a 1-D array of finite numbers"),
    ({"units": np.array(["mm", "m"])}, "'units' must be one string"),
])
def test_malformed_npz_side_arrays_are_input_errors(tmp_path, extra, message):
    path = tmp_path / "poses.npz"
    np.savez(path, poses=np.tile(np.eye(4), (3, 1, 1)).reshape(3, 16), **extra)
    with pytest.raises(InputError, match=message) as info:
        read_poses(path, "matrix", unit="mm")
    assert "\n" not in str(info.value)
