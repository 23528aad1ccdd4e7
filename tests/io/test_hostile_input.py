"""Hostile and lenient input files: decompression and alias bombs, duplicate keys, numbers written
the wrong way, shapes that fit only by flattening, symbolic link loops, damaged ROS bags.

Each is refused with a one-line `InputError` naming the file (the CLI: exit 2, one line on
stderr), before the harm: an NPZ bomb before any member is inflated, a YAML alias bomb while the
document is composed.
"""

from __future__ import annotations

import io
import json
import random
import zipfile
from pathlib import Path

import numpy as np
import pytest

from handeye.base.errors import HandEyeError, InputError
from handeye.cli import main
from handeye.geometry.se3 import make_pose, random_poses, so3_exp
from handeye.io import npz
from handeye.io.data_files import load_data, save_data
from handeye.io.input_files import MAX_ALIAS_NODES, load_json, load_yaml
from handeye.io.npz import load_npz
from handeye.io.pose_readers import PoseStack, poses_from_rows, read_poses
from handeye.io.pose_writers import write_poses
from handeye.vision.boards import parse_board
from handeye.vision.image_set import image_stamp
from handeye.vision.intrinsics import load_camera

QUAT = "xyz-quat-xyzw"


def refused(call, *words: str) -> str:
    """Assert `call()` raises InputError in one line holding every one of `words`; the message."""
    with pytest.raises(InputError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, (word, message)
    return message


def cli_error(capsys, argv: list, *words: str) -> str:
    """Run the CLI; assert exit 2 with one line ``handeye: error: ...`` holding `words`."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("handeye: error: "), err
    for word in words:
        assert word in err, (word, err)
    return err


def stations(n: int = 12, seed: int = 0) -> np.ndarray:
    """n robot poses in mm."""
    rng = np.random.default_rng(seed)
    return make_pose(so3_exp(rng.uniform(-0.6, 0.6, (n, 3))), rng.uniform(-300, 300, (n, 3)))


# ----------------------------------------------------------------------------- NPZ bombs (item 2a)


def no_inflating(monkeypatch) -> None:
    """Make opening any zip member, or numpy.load, fail the test: what is refused must be refused
    from the archive's directory alone."""
    def opened(*args, **kwargs):
        raise AssertionError("a member was opened (data read) before the archive was refused")

    monkeypatch.setattr(zipfile.ZipFile, "open", opened)
    monkeypatch.setattr(np, "load", opened)


def declare_size(path: Path, member: str, size: int) -> None:
    """Rewrite the uncompressed size of `member` in the zip's central directory (a 4-byte field,
    offset 24 of the entry) to `size`, as a crafted archive would declare it."""
    data = bytearray(path.read_bytes())
    at = data.find(b"PK\x01\x02")
    while at >= 0:
        name_len = int.from_bytes(data[at + 28:at + 30], "little")
        if data[at + 46:at + 46 + name_len] == member.encode():
            data[at + 24:at + 28] = size.to_bytes(4, "little")
            path.write_bytes(bytes(data))
            return
        at = data.find(b"PK\x01\x02", at + 4)
    raise AssertionError(f"no member {member}")


def test_npz_declaring_gigabytes_is_refused_before_any_member_is_opened(tmp_path, monkeypatch):
    """A member whose directory entry declares 4 GB (the real limits, no allocation here)."""
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, A=np.zeros((2, 4, 4)), B=np.zeros((2, 4, 4)))
    declare_size(path, "A.npy", 0xF0000000)
    no_inflating(monkeypatch)
    refused(lambda: load_npz(path, "'bomb.npz'"), "'bomb.npz'", "member 'A'", "declares 4.03 GB", "256 MB")
    refused(lambda: load_data(path), "bomb.npz", "4.03 GB")
    refused(lambda: read_poses(path, "matrix", unit="mm"), "bomb.npz", "4.03 GB")


def test_npz_bomb_of_savez_compressed_is_refused_before_reading(tmp_path, monkeypatch):
    """np.savez_compressed of a zero array: consistent headers, ratio about 1000. The caps are
    lowered so that a 1 MB array stands for the 4.8 GB one."""
    path = tmp_path / "zeros.npz"
    np.savez_compressed(path, A=np.zeros((8000, 4, 4)), B=np.zeros((1, 4, 4)))
    assert path.stat().st_size < 5000  # 1 MB of zeros in a few kB
    assert load_npz(path, "'zeros.npz'")["A"].shape == (8000, 4, 4)  # under the limits: read
    with monkeypatch.context() as patch:
        patch.setattr(npz, "MAX_MEMBER_BYTES", 500_000)
        no_inflating(patch)
        refused(lambda: load_npz(path, "'zeros.npz'"), "member 'A'", "declares 1.02 MB", "500 kB")
    with monkeypatch.context() as patch:
        patch.setattr(npz, "RATIO_FLOOR", 500_000)
        no_inflating(patch)
        refused(lambda: load_npz(path, "'zeros.npz'"), "member 'A'", "inflates", "decompression bomb")
    with monkeypatch.context() as patch:
        patch.setattr(npz, "MAX_ARCHIVE_BYTES", 1_000_000)
        no_inflating(patch)
        refused(lambda: load_npz(path, "'zeros.npz'"), "declare 1.02 MB uncompressed together")


def sizes(*members: tuple[int, int]) -> list[zipfile.ZipInfo]:
    """Directory entries of (uncompressed, compressed) sizes, deflated."""
    infos = []
    for k, (size, packed) in enumerate(members):
        info = zipfile.ZipInfo(f"m{k}.npy")
        info.compress_type, info.file_size, info.compress_size = zipfile.ZIP_DEFLATED, size, packed
        infos.append(info)
    return infos


STACK = 10**6 * 16 * 8 + 128  # one (10^6, 4, 4) float64 stack with its .npy header


@pytest.mark.parametrize("members", [
    [(STACK, STACK)] * 2,                          # np.savez of 10^6 pose pairs (stored)
    [(STACK, STACK // 14 * 10)] * 2,               # savez_compressed of random poses (1.4:1)
    [(STACK, STACK // 293)] * 2,                   # one pose repeated 10^6 times (293:1, measured)
    [(8 * 10**6, 8 * 10**6 // 900), (STACK, STACK)],  # 10^6 zero stamps (900:1) and a stack
])
def test_the_size_rules_admit_10_to_the_6_pose_pairs(members):
    npz._check_sizes(sizes(*members), "'cell.npz'")


@pytest.mark.parametrize("members, words", [
    ([(4_800_000_128, 4_665_455)], "declares 4.8 GB"),            # the 4.7 MB file of the review
    ([(STACK, STACK // 1020)], "inflates 1020 times"),            # 128 MB of zeros, under the cap
    ([(200 * 10**6, 200 * 10**6)] * 3, "600 MB uncompressed together"),
])
def test_the_size_rules_refuse_bombs(members, words):
    refused(lambda: npz._check_sizes(sizes(*members), "'cell.npz'"), "'cell.npz'", words)


def test_npz_members_compressed_with_bzip2_are_refused(tmp_path, monkeypatch):
    """bzip2 / lzma members inflate without bound before zipfile cuts them at the declared size."""
    buffer = io.BytesIO()
    np.save(buffer, np.zeros((2, 4, 4)))
    path = tmp_path / "bz.npz"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_BZIP2) as archive:
        archive.writestr("A.npy", buffer.getvalue())
    no_inflating(monkeypatch)
    refused(lambda: load_npz(path, "'bz.npz'"), "member 'A'", "bzip2", "numpy.savez")


# ----------------------------------------------------------------------------- YAML (items 2b, 15)


def billion_laughs(levels: int = 9) -> str:
    """A few hundred bytes of nested aliases expanding to 9^levels scalars."""
    lines = ["a: &a [x, x, x, x, x, x, x, x, x]"]
    for prev, name in zip("abcdefghijklmn", "bcdefghijklmn"[:levels - 1]):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def yaml_readers(tmp_path: Path) -> dict[str, tuple[Path, object]]:
    """The four readers of YAML: name -> (the file they read, a call reading it)."""
    pose = tmp_path / "poses.yaml"
    board = tmp_path / "board.yaml"
    camera = tmp_path / "camera.yaml"
    stamp = tmp_path / "img_7.yaml"
    return {
        "poses": (pose, lambda: read_poses(pose, QUAT, unit="mm")),
        "board": (board, lambda: parse_board(str(board))),
        "intrinsics": (camera, lambda: load_camera(camera)),
        "stamp": (stamp, lambda: image_stamp(tmp_path / "img_7.png")),
    }


@pytest.mark.parametrize("reader", ["poses", "board", "intrinsics", "stamp"])
def test_yaml_alias_bomb_is_refused_at_once_by_every_reader(tmp_path, reader):
    path, call = yaml_readers(tmp_path)[reader]
    text = billion_laughs() + "poses: *i\n"
    assert len(text) < 400
    path.write_text(text)
    refused(call, path.name, "line 6", "aliases (*name) expand the document", f"{MAX_ALIAS_NODES:,} nodes")


def test_aliases_used_sparingly_still_read(tmp_path):
    T = stations(3)
    row = json.dumps(T[0].ravel().tolist())
    (tmp_path / "p.yaml").write_text(f"units: mm\nposes:\n- &home {row}\n- *home\n- *home\n")
    stack = read_poses(tmp_path / "p.yaml", "matrix")
    np.testing.assert_array_equal(stack.poses, np.repeat(T[:1], 3, axis=0))
    (tmp_path / "board.yaml").write_text("defaults: &d {kind: chessboard, unit: mm}\n"
                                         "board:\n  <<: *d\n  cols: 9\n  rows: 6\n  spacing: 25\n")
    board = parse_board(str(tmp_path / "board.yaml"))
    assert (board.kind, board.cols, board.rows, board.unit) == ("chessboard", 9, 6, "mm")
    # a document whose aliases add just under the bound reads; one node more is refused
    width = (MAX_ALIAS_NODES - 1) // 100  # a list of `width` scalars has width + 1 nodes
    block = "a: &a [" + ", ".join(["1"] * width) + "]\nb: [" + ", ".join(["*a"] * 100) + "]\n"
    assert len(load_yaml(block, "'big.yaml'")["b"]) == 100
    refused(lambda: load_yaml(block + "c: *a\n", "'big.yaml'"), "'big.yaml'", "line 3", "alias")


def test_yaml_alias_inside_its_own_anchor_is_refused():
    refused(lambda: load_yaml("poses: &p [[1, 2, 3], *p]\n", "'p.yaml'"), "'p.yaml'", "line 1",
            "refers to the node that contains it")


@pytest.mark.parametrize("reader, text, line", [
    ("poses", "units: mm\nposes: [[1, 2, 3, 0, 0, 0, 1]]\nunits: m\n", "line 3"),
    ("poses", "- {x: 1, y: 2, z: 3, qx: 0, qy: 0, qz: 0, qw: 1,\n   x: 5}\n", "line 2"),
    ("board", "kind: chessboard\ncols: 9\nrows: 6\ncols: 7\nspacing: 25\n", "line 4"),
    ("intrinsics", "intrinsics:\n  fx: 500.0\n  fy: 500.0\n  cx: 320.0\n  fx: 600.0\n  cy: 240.0\n", "line 5"),
    ("stamp", "stamp: 12.5\nstamp: 13.0\n", "line 2"),
])
def test_yaml_duplicate_keys_are_refused_by_every_reader(tmp_path, reader, text, line):
    path, call = yaml_readers(tmp_path)[reader]
    path.write_text(text)
    refused(call, path.name, line, "duplicate key", "first at line")


@pytest.mark.parametrize("text, value", [
    ("1:30", "1:30"),        # YAML 1.1 sexagesimal 90: stays text
    ("1_000", "1_000"),      # YAML 1.1 int 1000: stays text
    ("0x1F", "0x1F"),        # hex: text
    ("017", 17),             # YAML 1.1 octal 15: decimal 17
    ("1e3", 1000.0),         # YAML 1.1 text (no dot): a float
    ("-.5", -0.5),
    ("+12", 12),
    ("2.5e-3", 0.0025),
    ("'12'", "12"),          # quoted: text
])
def test_yaml_numbers_are_read_by_the_yaml_1_2_core_schema(text, value):
    read = load_yaml(f"x: {text}\n", "'n.yaml'")["x"]
    assert read == value and type(read) is type(value)


def test_yaml_sexagesimal_and_underscore_numbers_are_not_numbers_in_a_pose_file(tmp_path):
    good = "x: 1\ny: 2\nz: 3\nqx: 0\nqy: 0\nqz: 0\nqw: 1\n"
    (tmp_path / "0.yaml").write_text(good)
    assert read_poses(tmp_path / "0.yaml", QUAT, unit="mm").poses[0, 0, 3] == 1.0
    for bad, shown in (("1:30", "'1:30' is not a number"), ("1_000", "'1_000' is not a number")):
        (tmp_path / "0.yaml").write_text(good.replace("x: 1", f"x: {bad}"))
        refused(lambda: read_poses(tmp_path / "0.yaml", QUAT, unit="mm"), "0.yaml", "pose 1, column 1 (x)", shown)


# ----------------------------------------------------------------------------- numbers (item 15)


@pytest.mark.parametrize("cell, words", [
    ("1_000", ["'1_000' is not a number as written", "without digit separators"]),
    ("１２３", ["'１２３' is not a number as written", "ASCII digits"]),
    ("٣", ["'٣' is not a number as written"]),   # Arabic-Indic three
    ("12abc", ["'12abc' is not a number"]),
])
def test_csv_cells_that_only_python_float_reads_are_refused(tmp_path, cell, words):
    path = tmp_path / "robot.csv"
    write_poses(path, stations(3), QUAT, unit="mm")
    lines = path.read_text().splitlines()
    lines[3] = cell + lines[3][lines[3].index(","):]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    refused(lambda: read_poses(path, QUAT, unit="mm"), "robot.csv", "line 4, column 1 (x)", *words)


def test_csv_plain_decimal_forms_still_read(tmp_path):
    path = tmp_path / "robot.csv"
    path.write_text("x,y,z,w,p,r\n1e3,-.5,+2.,0,0,90\n")
    pose = read_poses(path, "fanuc-wpr").poses[0]
    np.testing.assert_array_equal(pose[:3, 3], [1000.0, -0.5, 2.0])


def test_json_pose_file_numbers_written_as_text_or_bool_are_refused(tmp_path):
    path = tmp_path / "robot.json"
    write_poses(path, stations(3), QUAT, unit="mm")
    doc = json.loads(path.read_text())
    doc["poses"][1]["y"] = str(doc["poses"][1]["y"])
    path.write_text(json.dumps(doc))
    refused(lambda: read_poses(path, QUAT), "robot.json", "pose 2, column 2 (y)", "is text, not a number",
            "write numbers without quotes")
    path.write_text(json.dumps({"units": "mm", "poses": [[1, 2, 3, 0, 0, 0, True]]}))
    refused(lambda: read_poses(path, QUAT), "robot.json", "pose 1, column 7", "True is not a number")


def test_json_data_file_numbers_written_as_text_or_bool_are_refused(tmp_path):
    """handeye solve FILE: a pose of A or of the truth holding "303.5" or true."""
    rng = np.random.default_rng(3)
    path = save_data(tmp_path / "cell.json", {"A": random_poses(6, rng, 100.0), "B": random_poses(6, rng, 100.0)},
                     {"X": np.eye(4), "Y": np.eye(4)})
    doc = json.loads(path.read_text())
    doc["A"][2][0][3] = "303.5"
    path.write_text(json.dumps(doc))
    refused(lambda: load_data(path), "cell.json", 'A[2][0][3] is "303.5", not a number', "without quotes")
    doc["A"][2][0][3] = 303.5
    doc["truth"]["Y"][3][3] = True
    path.write_text(json.dumps(doc))
    refused(lambda: load_data(path), "cell.json", "truth Y[3][3] is true, not a number")


@pytest.mark.parametrize("text, line", [
    ('{"units": "mm", "poses": [[1, 2, 3, 0, 0, 0, 1]], "units": "m"}', "line 1"),
    (('[{"x": 1, "y": 2, "z": 3, "qx": 0, "qy": 0, "qz": 0, "qw": 1},\n'
      ' {"x": 1, "y": 2, "z": 3, "qx": 0, "qy": 0, "qz": 0, "qw": 1,\n  "x": 5}]'), "line 2"),
])
def test_json_duplicate_keys_are_refused_in_pose_files(tmp_path, text, line):
    path = tmp_path / "robot.json"
    path.write_text(text)
    refused(lambda: read_poses(path, QUAT, unit="mm"), "robot.json", "duplicate key", f"in the object at {line}")


def test_json_duplicate_keys_are_refused_in_data_files(tmp_path):
    rng = np.random.default_rng(4)
    path = save_data(tmp_path / "cell.json", {"A": random_poses(6, rng, 1.0), "B": random_poses(6, rng, 1.0)},
                     metadata={"units": "m"})
    text = path.read_text().replace('"units": "m"', '"units": "mm",\n  "units": "m"')
    path.write_text(text)
    refused(lambda: load_data(path), "cell.json", "duplicate key 'units'", "line 1")


def test_json_integers_beyond_the_digit_limit_and_bad_utf8_are_input_errors(tmp_path):
    path = tmp_path / "robot.json"
    path.write_text("[[" + "1" * 5000 + ", 2, 3, 0, 0, 0, 1]]")
    refused(lambda: read_poses(path, QUAT, unit="mm"), "robot.json", "invalid JSON")
    path.write_text("[[" + "1" * 400 + ", 2, 3, 0, 0, 0, 1]]")  # beyond float64, within the digit limit
    refused(lambda: read_poses(path, QUAT, unit="mm"), "robot.json", "pose 1, column 1", "... is not finite")
    (tmp_path / "robot.yaml").write_text("- [" + "1" * 5000 + ", 2, 3, 0, 0, 0, 1]\n")
    refused(lambda: read_poses(tmp_path / "robot.yaml", QUAT, unit="mm"), "robot.yaml", "an integer of 5000 digits")
    path.write_bytes(b"[[1, 2, 3, 0, 0, 0, 1]] \xff\xfe")
    refused(lambda: read_poses(path, QUAT, unit="mm"), "robot.json", "not UTF-8 text")
    refused(lambda: load_json('{"a": 1, "a": 1}', "'x.json'"), "'x.json'", "duplicate key 'a'")


# ----------------------------------------------------------------------------- shapes (item 15)


@pytest.mark.parametrize("shape", [(15, 2, 3), (15, 6, 1), (15, 4, 4, 1), (15, 1, 6), (15, 16, 1)])
def test_npz_pose_arrays_that_fit_only_by_flattening_are_refused(tmp_path, shape):
    np.savez(tmp_path / "p.npz", poses=np.zeros(shape))
    refused(lambda: read_poses(tmp_path / "p.npz", "xyz-rotvec", unit="mm"), "p.npz", f"poses of shape {shape}",
            "(n, 4, 4) / (n, 3, 4)")
    refused(lambda: poses_from_rows(np.zeros(shape), "xyz-rotvec", unit="mm"), f"poses of shape {shape}")


def test_npz_pose_arrays_of_documented_shapes_read(tmp_path):
    T = stations(15)
    for name, array, fmt in (("rows", T.reshape(15, 16), "matrix"), ("m44", T, "matrix"),
                             ("m34", T[:, :3], "matrix34")):
        np.savez(tmp_path / f"{name}.npz", poses=array)
        np.testing.assert_allclose(read_poses(tmp_path / f"{name}.npz", fmt, unit="mm").poses, T, atol=1e-12)
    np.savez(tmp_path / "bool.npz", poses=np.ones((3, 6), bool))
    refused(lambda: read_poses(tmp_path / "bool.npz", "xyz-rotvec", unit="mm"), "holds bool values")


def test_json_poses_nested_other_than_4x4_or_3x4_are_refused(tmp_path):
    path = tmp_path / "p.json"
    path.write_text("[[[1, 2, 3], [0, 0, 0]]]")
    refused(lambda: read_poses(path, "xyz-rotvec", unit="mm"), "p.json", "pose 1 is a list of lists that is not a "
            "4x4 or 3x4 matrix")
    path.write_text("[[1, 2, [3, 0], 0, 0]]")
    refused(lambda: read_poses(path, "xyz-rotvec", unit="mm"), "p.json", "pose 1")
    path.write_text(json.dumps(stations(2)[:, :3].tolist()))
    assert len(read_poses(path, "matrix34", unit="mm")) == 2


# ----------------------------------------------------------------------------- exit codes (item 14)


def test_cli_symlink_loop_is_bad_input(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_poses("camera.csv", stations(6, seed=1), QUAT, unit="mm")
    Path("loop.csv").symlink_to("loop.csv")
    Path("loop.json").symlink_to("loop.json")
    argv = ["calibrate", "--robot", "loop.csv", "--robot-format", QUAT, "--robot-unit", "mm", "--camera",
            "camera.csv", "--camera-format", QUAT, "--camera-unit", "mm", "--setup", "eye-in-hand"]
    cli_error(capsys, argv, "'loop.csv'", "symbolic link that loops")
    cli_error(capsys, [*argv, "-o", "out.json"], "'loop.csv'", "symbolic link that loops")
    cli_error(capsys, ["solve", "loop.json"], "'loop.json'", "symbolic link that loops")
    refused(lambda: read_poses("loop.csv", QUAT, unit="mm"), "pose file 'loop.csv'")


def write_test_bag(path: Path, kind: str, n: int = 40) -> Path:
    """A bag of n PoseStamped messages on /pose (the writers of tests/io/test_bag_readers.py)."""
    pytest.importorskip("rosbags")
    from test_bag_readers import POSE, store, write_bag

    m = store(kind)
    stamps = [(100 + k, 0) for k in range(n)]
    T = PoseStack(stations(n), "mm", "matrix").in_unit("m").poses
    return write_bag(path, kind, {"/pose": (POSE, [(s, m.message(POSE, s, T[k])) for k, s in enumerate(stamps)])})


def storage_file(bag: Path) -> Path:
    """The file holding a bag's messages (the bag itself for ROS 1)."""
    return bag if bag.is_file() else next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))


@pytest.mark.parametrize("kind, words", [
    ("ros1", ["could not be read as a ROS bag"]),
    ("sqlite3", ["is truncated", "SQLite header records"]),
    ("mcap", ["is truncated", "MCAP end marker"]),
])
def test_cli_truncated_bag_is_bad_input(tmp_path, capsys, kind, words):
    bag = write_test_bag(tmp_path / ("robot.bag" if kind == "ros1" else "robot"), kind)
    data = storage_file(bag).read_bytes()
    storage_file(bag).write_bytes(data[:int(len(data) * 0.999)])
    camera = tmp_path / "camera.csv"
    write_poses(camera, PoseStack(stations(5), "mm", "matrix", stamps=np.arange(5.0) + 101), QUAT)
    argv = ["calibrate", "--robot", bag, "--robot-topic", "/pose", "--camera", camera, "--camera-format", QUAT,
            "--camera-unit", "mm", "--setup", "eye-in-hand", "--match", "interpolate"]
    cli_error(capsys, argv, str(bag), *words)


def test_cli_sqlite_bag_with_a_damaged_page_is_bad_input(tmp_path, capsys):
    """A whole-length .db3 whose last table page has a zeroed cell pointer: sqlite finds it while
    the messages are read ("database disk image is malformed", apsw.CorruptError)."""
    bag = write_test_bag(tmp_path / "robot", "sqlite3")
    file = storage_file(bag)
    data = bytearray(file.read_bytes())
    page = int.from_bytes(data[16:18], "big")
    leaves = [k for k in range(1, len(data) // page) if data[k * page] == 0x0D]  # b-tree table leaf pages
    data[leaves[-1] * page + 8:leaves[-1] * page + 10] = b"\0\0"
    file.write_bytes(bytes(data))
    camera = tmp_path / "camera.csv"
    write_poses(camera, PoseStack(stations(5), "mm", "matrix", stamps=np.arange(5.0) + 101), QUAT)
    argv = ["calibrate", "--robot", bag, "--robot-topic", "/pose", "--camera", camera, "--camera-format", QUAT,
            "--camera-unit", "mm", "--setup", "eye-in-hand", "--match", "interpolate"]
    cli_error(capsys, argv, str(bag), "could not be read as a ROS bag", "malformed")


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_damaged_bags_give_poses_or_input_errors(tmp_path, kind):
    """Random bytes overwritten in a bag (fixed seeds): rosbags raises a dozen kinds of errors on
    such files; every one must come out as an InputError naming the bag."""
    from handeye.io.bag_readers import read_bag_poses

    bag = write_test_bag(tmp_path / ("robot.bag" if kind == "ros1" else "robot"), kind, n=10)
    file = storage_file(bag)
    data = file.read_bytes()
    rng = random.Random(7)
    outcomes = set()
    for _ in range(30):
        damaged = bytearray(data)
        for _ in range(rng.choice([1, 2, 5])):
            damaged[rng.randrange(len(data))] = rng.randrange(256)
        file.write_bytes(bytes(damaged))
        try:
            outcomes.add(type(read_bag_poses(bag, "/pose")).__name__)
        except HandEyeError as exc:
            assert isinstance(exc, InputError) and "\n" not in str(exc) and str(bag) in str(exc), exc
            outcomes.add("InputError")
    assert "InputError" in outcomes


# ----------------------------------------------------------------------------- image sidecars, boards, intrinsics

@pytest.mark.parametrize("name, text", [("0.txt", "1_000"), ("0.txt", "１２３"), ("0.json", '{"stamp": "12.5"}'),
                                        ("0.json", '{"stamp": 1, "stamp": 2}'), ("0.yaml", "stamp: 1:30")])
def test_image_time_stamps_are_read_strictly(tmp_path, name, text):
    (tmp_path / "0.png").write_bytes(b"")
    (tmp_path / name).write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match="time stamp file"):
        image_stamp(tmp_path / "0.png")


def test_image_time_stamps_in_plain_numbers_read(tmp_path):
    (tmp_path / "0.png").write_bytes(b"")
    (tmp_path / "0.json").write_text('{"stamp": {"sec": 12, "nanosec": 500000000}}')
    assert image_stamp(tmp_path / "0.png") == 12.5


def test_board_and_intrinsics_json_refuse_duplicate_keys(tmp_path):
    board = tmp_path / "board.json"
    board.write_text('{"kind": "chessboard", "cols": 9, "cols": 8, "rows": 6, "square": 0.025}')
    with pytest.raises(InputError, match="duplicate key 'cols'"):
        parse_board(str(board))
    camera = tmp_path / "camera.json"
    camera.write_text('{"camera_matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], "camera_matrix": [],'
                      ' "distortion_coefficients": [0, 0, 0, 0, 0], "image_width": 640, "image_height": 480}')
    with pytest.raises(InputError, match="duplicate key 'camera_matrix'"):
        load_camera(camera)


def test_board_sizes_written_as_text_are_refused(tmp_path):
    board = tmp_path / "board.yaml"
    board.write_text("kind: chessboard\ncols: 9\nrows: 6\nspacing: 2_5\n")
    with pytest.raises(InputError, match="board spacing must be a number"):
        parse_board(str(board))
