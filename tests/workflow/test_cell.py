"""`handeye.Cell` (handeye.workflow.cell) and its YAML file (handeye.workflow.cell_file): checks on
construction with one-line messages naming the setting, the same messages in the command line's
flags, the file's round trip with paths relative to its folder, unknown keys, bounded reading,
and ``handeye calibrate --write-config`` / ``--config``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import handeye
from handeye.cli import build_parser
from handeye.cli._cell_flags import cell_words, flag_settings, merged
from handeye.cli._common import in_cli_words
from handeye.workflow.cell import (
    CameraStream,
    Cell,
    Images,
    Matching,
    Outputs,
    PoseStream,
)
from handeye.workflow.cell_file import MAX_CELL_FILE_BYTES
from tests.conftest import run_cli

ROBOT = PoseStream("robot.csv", format="fanuc-wpr")
CAMERA = CameraStream("board.csv", format="opencv-rvec", unit="mm")


def cell(**changes):
    return Cell(**{"robot": ROBOT, "camera": CAMERA, "setup": "eye-in-hand", **changes})


# ----------------------------------------------------------------------------- construction


def test_a_cell_has_the_command_lines_defaults():
    """The flags give no default of their own: a cell built from the fewest flags equals the
    cell built in Python from the same three settings, field by field."""
    args = build_parser().parse_args(["calibrate", "--robot", "robot.csv", "--robot-format", "fanuc-wpr", "--camera",
                                      "board.csv", "--camera-format", "opencv-rvec", "--camera-unit", "mm",
                                      "--setup", "eye-in-hand"])
    from_flags = Cell.from_dict(flag_settings(args, None))
    assert from_flags == cell()
    m = from_flags.matching
    assert (m.method, m.max_dt, m.time_offset, m.max_offset, m.min_speed, m.max_pairs) == ("row", None, "auto", 1.0,
                                                                                           1.0, 300)
    assert (from_flags.problem, from_flags.solver, from_flags.checks, from_flags.camera.poses) == (
        "axyb", None, True, "board-in-camera")
    # every calibrate flag not given is None: no flag has a default of its own
    given = {"robot", "robot_format", "camera", "camera_format", "camera_unit", "setup", "command", "run", "json",
             "force"}
    assert {k: v for k, v in vars(args).items() if k not in given and v is not None} == {}


@pytest.mark.parametrize("changes, message", [
    ({"setup": "sideways"}, "`setup` must be one of eye-in-hand, eye-to-hand, got 'sideways'"),
    ({"problem": "axbycz"}, "`problem` must be one of axxb, axyb (the registered problems a cell's stations"),
    ({"robot": PoseStream("r.csv", format="fanuc")}, "`robot.format`: unknown pose format 'fanuc'"),
    ({"robot": PoseStream("r.csv", unit="cm")}, "`robot.unit` must be one of mm, m, got 'cm'"),
    ({"robot": PoseStream(None, format="fanuc-wpr")}, "`robot.file: FILE` is required"),
    ({"camera": None}, "give the camera's side: `camera.file: FILE` `camera.format: FORMAT` (board poses) or "
                       "`images.folder: DIR` `images.board: SPEC`"),
    ({"images": Images("imgs", "chessboard:9x6:25mm")}, "`images` replaces `camera` and `camera.format`"),
    ({"camera": None, "images": Images("imgs")}, "`images` needs `images.board: SPEC`"),
    ({"images": Images(board="chessboard:9x6:25mm")}, "`images.board` applies to `images.folder: DIR`"),
    ({"camera": None, "images": Images("imgs", "c:1"), "matching": Matching("interpolate")},
     "`matching.method: interpolate` applies to pose streams"),
    ({"camera": None, "images": Images("imgs", "c:1"), "camera_scale": "unknown"},
     "`camera_scale: unknown` does not apply to `images`"),
    ({"matching": Matching("row", max_dt=0.1)}, "`matching.max_dt` applies to `matching.method: time`; drop it"),
    ({"matching": Matching("time", max_gap=0.1)}, "`matching.max_gap` apply to `matching.method: interpolate`"),
    ({"matching": Matching("interpolate", max_dt=0.1)}, "with `matching.method: interpolate` use `matching.max_gap`"),
    ({"matching": Matching("interpolate", max_pairs=5)}, "`matching.max_pairs` must be a whole number >= 10"),
    ({"matching": Matching("interpolate", max_offset=-1.0)}, "`matching.max_offset` must be a finite number of "
                                                             "seconds > 0, got -1.0"),
    ({"matching": Matching("nearest")}, "`matching.method` must be one of row, index, name, time, interpolate"),
    ({"pairing": "all"}, "`pairing` applies to `problem: axxb`"),
    ({"frame_ids": "tool0"}, "`frame_ids` expects PARENT,CHILD (two frame ids), got 'tool0'"),
    ({"frame_ids": "tool0,camera link"}, "`frame_ids`: 'camera link' is not a ROS frame id"),
    ({"tz_X": 1.0, "options": {"tz_X": 2.0}}, "`tz_X` is given twice: as `tz_X` and in `options`"),
    ({"time_limit": -1.0}, "`time_limit` must be a finite number of seconds (0: no limit) >= 0, got -1.0"),
    ({"checks": "no"}, "`checks` must be true or false, got 'no'"),
    ({"camera": CameraStream("b.csv", "opencv-rvec", poses="camera-to-board")}, "`camera.poses` must be one of "
                                                                                "board-in-camera, camera-in-board"),
    ({"robot": {"file": "r.csv"}}, "`robot` must be a handeye.workflow.cell.PoseStream, got dict (a mapping: build "
                                   "the cell with Cell.from_dict)"),
])
def test_a_wrong_cell_is_one_line_naming_the_setting(changes, message):
    with pytest.raises(handeye.InputError) as info:
        cell(**changes)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)
    assert isinstance(info.value, ValueError)


def test_time_offset_and_columns_are_read_from_text():
    assert Matching("interpolate", time_offset="-0.02").time_offset == -0.02
    assert Matching("interpolate", time_offset=" AUTO ").time_offset == "auto"
    with pytest.raises(handeye.InputError, match=r"`matching.time_offset` must be 'auto' or a number of seconds, "
                                                 r"got 'later'"):
        Matching("interpolate", time_offset="later")
    assert PoseStream("r.csv", "xyz-quat-xyzw", columns="qw, qx,qy,qz,x,y,z").columns == (
        "qw", "qx", "qy", "qz", "x", "y", "z")
    assert Cell(robot=ROBOT, images=Images(Path("imgs"), "chessboard:9x6:25mm"), setup="eye-to-hand",
                camera=CameraStream()).camera is None  # an empty camera section says nothing


@pytest.mark.parametrize("library, flags", [
    ("`robot.unit` must be one of mm, m", "--robot-unit must be one of mm, m"),
    ("`matching.method: time`: `camera` 'c.csv' has no time stamp", "--match time: --camera 'c.csv' has no time stamp"),
    ("`images` needs `images.board: SPEC` (e.g. `images.board: chessboard:9x6:25mm`",
     "--images needs --board SPEC (e.g. --board chessboard:9x6:25mm"),
    ("(`checks: false` skips them; `orthonormalize: true` reads them)", "(--no-checks skips them; --orthonormalize "
                                                                          "reads them)"),
    ("`options` ['A'] clash", "--option ['A'] clash"),
    ("`outputs.json`, `outputs.yaml` and `outputs.report`", "-o, --yaml and --report"),
    ("`tz_X` is given twice: as `tz_X` and in `options`", "--tz-X is given twice: as --tz-X and in --option"),
    ("`solver: reprojection` forces it", "--solver reprojection forces it"),
    ("`not.a.setting` stays", "`not.a.setting` stays"),
])
def test_the_command_line_names_its_flags(library, flags):
    assert cell_words(library) == flags
    assert in_cli_words(library) == flags


# ----------------------------------------------------------------------------- the file


def full_cell(folder: Path) -> Cell:
    return Cell(robot=PoseStream(folder / "data" / "robot.csv", "euler:ZYX:deg", "mm", columns="name,x,y,z,a,b,c"),
                camera=CameraStream(folder / "data" / "board.csv", "opencv-rvec", "m", poses="camera-in-board"),
                setup="eye-to-hand", matching=Matching("interpolate", time_offset=0.25, max_gap=0.05, max_pairs=120),
                problem="axxb", pairing="consecutive", solver="refine", options={"loss": "huber", "outliers": "keep"},
                tz_X=12.5, orthonormalize=True, checks=False, frame_ids=("tool0", "camera_color_optical_frame"),
                time_limit=30.0, outputs=Outputs(json=folder / "out" / "result.json", report="/abs/report.html"))


def test_the_file_round_trips_with_paths_relative_to_its_folder(tmp_path, monkeypatch):
    folder = tmp_path / "cell"
    folder.mkdir()
    original = full_cell(folder)
    written = original.to_file(folder / "cell.yaml")
    text = written.read_text()
    assert text.startswith("# handeye cell file") and "relative to this file's folder" in text
    doc = yaml.safe_load(text)
    assert doc["robot"] == {"file": "data/robot.csv", "format": "euler:ZYX:deg", "unit": "mm",
                            "columns": ["name", "x", "y", "z", "a", "b", "c"]}
    assert doc["outputs"] == {"json": "out/result.json", "report": "/abs/report.html"}
    assert doc["matching"] == {"method": "interpolate", "time_offset": 0.25, "max_gap": 0.05, "max_pairs": 120}
    assert "images" not in doc and "backend" not in doc and "tz_Y" not in doc  # defaults are left out
    monkeypatch.chdir(tmp_path.parent)  # read from elsewhere: the paths are the file folder's
    read = Cell.from_file(folder / "cell.yaml")
    assert read == original
    assert read.robot.file == str(folder / "data" / "robot.csv")
    # the same cell read from a relative path to the file
    monkeypatch.chdir(tmp_path)
    assert Cell.from_file(Path("cell") / "cell.yaml").robot.file == str(Path("cell") / "data" / "robot.csv")
    # a file outside the cell's folder is written absolute
    other = original.replace(camera=CameraStream(tmp_path / "elsewhere.csv", "opencv-rvec", "m"))
    assert yaml.safe_load(other.to_yaml(relative_to=folder))["camera"]["file"] == str(tmp_path / "elsewhere.csv")
    # an existing file is kept without force
    with pytest.raises(handeye.InputError, match="the file exists"):
        original.to_file(folder / "cell.yaml")
    assert original.to_file(folder / "cell.yaml", force=True).read_text() == text


def test_a_minimal_file_and_the_board_file_relative_to_it(tmp_path):
    (tmp_path / "cell.yaml").write_text("setup: eye-in-hand\nrobot: {file: poses, format: xyz-quat-xyzw, unit: m}\n"
                                        "images: {folder: images, board: board.yaml, intrinsics: ~/cam.yaml}\n")
    read = Cell.from_file(tmp_path / "cell.yaml")
    assert read.images == Images(str(tmp_path / "images"), str(tmp_path / "board.yaml"),
                                 str(Path("~/cam.yaml").expanduser()))
    assert read.matching == Matching() and read.problem == "axyb" and read.camera is None


@pytest.mark.parametrize("text, message", [
    ("setup: eye-in-hand\nrobot: {file: r.csv, fromat: matrix}\n",
     "unknown key 'robot.fromat'; the keys of 'robot' are 'file', 'format', 'unit', 'columns', 'topic'"),
    ("setup: eye-in-hand\nrobots: {file: r.csv}\n", "unknown key 'robots'; known keys: 'robot', 'setup', 'camera', "
                                                    "'images', 'matching', 'problem', 'pairing', 'solver', 'backend', "
                                                    "'options', 'tz_X', 'tz_Y', 'camera_scale'"),
    ("setup: eye-in-hand\nrobot: r.csv\n", "'robot' must be a mapping of 'file', 'format', 'unit', 'columns', "
                                           "'topic'; got 'r.csv'"),
    ("- setup\n", "expected a mapping of settings"),
    ("setup: eye-in-hand\nsetup: eye-to-hand\n", "duplicate key"),
    ("setup: [unclosed\n", "invalid YAML at line"),
    ("setup: eye-in-hand\nrobot: {file: r.csv, unit: cm}\ncamera: {file: c.csv}\n",
     "'robot.unit' must be one of mm, m, got 'cm'"),
    ("robot: {file: r.csv}\ncamera: {file: c.csv}\n", "'setup' must be one of eye-in-hand, eye-to-hand, got None"),
])
def test_a_wrong_file_is_one_line_naming_the_file_and_its_key(tmp_path, text, message):
    path = tmp_path / "cell.yaml"
    path.write_text(text)
    with pytest.raises(handeye.InputError) as info:
        Cell.from_file(path)
    text = str(info.value)
    assert text.startswith(f"cell file {str(path)!r}") and message in text and "\n" not in text, text
    assert "`" not in text  # the file's keys, in quotes: the command line does not turn them into flags
    assert in_cli_words(text) == text


def test_reading_is_bounded(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * MAX_CELL_FILE_BYTES + "\nsetup: eye-in-hand\n")
    with pytest.raises(handeye.InputError, match="bytes long; a cell file holds a few settings"):
        Cell.from_file(big)
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")))
    with pytest.raises(handeye.InputError, match="alias"):
        Cell.from_file(bomb)
    with pytest.raises(handeye.InputError, match="cell file .* not found"):
        Cell.from_file(tmp_path / "missing.yaml")


def test_flags_override_the_files_values():
    base = {"setup": "eye-in-hand", "problem": "axxb", "pairing": "consecutive",
            "robot": {"file": "/cell/r.csv", "format": "fanuc-wpr"}, "camera": {"file": "/cell/c.csv", "unit": "mm"},
            "matching": {"method": "interpolate", "time_offset": 0.1}, "options": {"loss": "huber", "a": 1}}
    flags = {"robot": {"file": "today.csv"}, "options": {"a": 2}, "matching": {"method": "time", "max_dt": 0.01}}
    out = merged(base, flags)
    assert out["robot"] == {"file": "today.csv", "format": "fanuc-wpr"}
    assert out["options"] == {"loss": "huber", "a": 2} and out["matching"] == {"method": "time", "max_dt": 0.01}
    assert "camera" not in merged(base, {"images": {"folder": "imgs"}})
    assert "pairing" not in merged(base, {"problem": "axyb"}) and base["pairing"] == "consecutive"


# ----------------------------------------------------------------------------- the command line


def test_write_config_writes_the_cell_and_nothing_else(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = ["calibrate", "--robot", "robot.csv", "--robot-format", "fanuc-wpr", "--camera", "board.csv",
            "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand", "--solver", "kron-lstsq",
            "--option", "normalize=true", "--no-checks", "-o", "result.json", "--report", "report.html"]
    code, out, err = run_cli(capsys, *argv, "--write-config", "cells/cell.yaml")
    assert code == 2 and "--write-config 'cells/cell.yaml'" in err  # the folder does not exist
    (tmp_path / "cells").mkdir()
    code, out, err = run_cli(capsys, *argv, "--write-config", "cells/cell.yaml")
    assert code == 0 and out == "wrote cells/cell.yaml\n" and err == ""
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["cell.yaml", "cells"]  # read nothing, wrote nothing else
    doc = yaml.safe_load((tmp_path / "cells" / "cell.yaml").read_text())
    assert doc == {"setup": "eye-in-hand", "problem": "axyb",
                   "robot": {"file": str(tmp_path / "robot.csv"), "format": "fanuc-wpr"},
                   "camera": {"file": str(tmp_path / "board.csv"), "format": "opencv-rvec", "unit": "mm"},
                   "matching": {"method": "row"}, "solver": "kron-lstsq", "options": {"normalize": True},
                   "checks": False, "outputs": {"json": str(tmp_path / "result.json"),
                                                "report": str(tmp_path / "report.html")}}
    assert Cell.from_file(tmp_path / "cells" / "cell.yaml") == Cell.from_dict(
        flag_settings(build_parser().parse_args(argv), {"normalize": True}), base=tmp_path)
    code, _, err = run_cli(capsys, *argv, "--write-config", "cells/cell.yaml")
    assert code == 2 and "--write-config 'cells/cell.yaml': the file exists; pass --force" in err
    code, _, err = run_cli(capsys, *argv, "--write-config", "robot.csv")
    assert code == 2 and "is the input file" in err
    # a wrong setting is refused before anything is written, in the flags' words
    code, _, err = run_cli(capsys, *argv, "--pairing", "all", "--write-config", "other.yaml")
    assert code == 2 and "--pairing applies to --problem axxb" in err and not (tmp_path / "other.yaml").exists()


def test_config_needs_no_flags_and_flags_are_required_without_it(tmp_path, capsys):
    code, _, err = run_cli(capsys, "calibrate", "--camera", "c.csv")
    assert code == 2 and "--robot FILE and --setup are required (or --config CELL.yaml" in err
    code, _, err = run_cli(capsys, "calibrate", "--config", tmp_path / "none.yaml")
    assert code == 2 and "cell file" in err and "not found" in err and err.count("\n") == 1
    (tmp_path / "cell.yaml").write_text("setup: eye-in-hand\nrobot: {file: r.csv, format: fanuc-wpr, unit: cm}\n"
                                        "camera: {file: c.csv, format: opencv-rvec}\n")
    code, _, err = run_cli(capsys, "calibrate", "--config", tmp_path / "cell.yaml")
    assert code == 2 and "'robot.unit' must be one of mm, m, got 'cm'" in err and "--robot-unit" not in err


def test_a_config_run_writes_the_outputs_it_names(tmp_path, capsys):
    """A cell file's outputs are relative to it; --json beside --config prints the result."""
    from test_calibrate import cell as simulated_cell

    robot, camera, truth = simulated_cell(tmp_path)
    (tmp_path / "cell.yaml").write_text(
        f"setup: eye-in-hand\nrobot: {{file: {robot.name}, format: fanuc-wpr}}\n"
        f"camera: {{file: {camera.name}, format: opencv-rvec, unit: mm}}\n"
        "outputs: {json: out.json, yaml: out.yaml}\n")
    code, out, err = run_cli(capsys, "calibrate", "--config", tmp_path / "cell.yaml", "--json")
    assert code == 0, err
    assert f"wrote {tmp_path / 'out.json'}" in err and f"wrote {tmp_path / 'out.yaml'}" in err
    printed = json.loads(out)
    assert printed == json.loads((tmp_path / "out.json").read_text()) == yaml.safe_load(
        (tmp_path / "out.yaml").read_text())
    np.testing.assert_allclose(printed["X"], truth["X"], atol=1e-6)


def test_the_documented_cell_file_is_a_cell_with_every_key():
    """docs/calibrate.md's full cell file reads as a cell, lists every key of every section, and
    states the defaults the classes have."""
    import dataclasses
    import re

    text = (Path(__file__).resolve().parents[2] / "docs" / "calibrate.md").read_text(encoding="utf-8")
    block = re.search(r"Every key, with its default.*?```yaml\n(.*?)```", text, re.S).group(1)
    doc = yaml.safe_load(block)
    read = Cell.from_dict(doc, base="/cell")
    assert read.robot.file == "/cell/data/robot.csv" and read.camera.poses == "board-in-camera"
    assert set(doc) == {f.name for f in dataclasses.fields(Cell)} - {"images"}  # images: the commented section
    images = yaml.safe_load(re.sub(r"(?m)^# ", "", block[block.index("# images:"):block.index("matching:")]))
    assert set(images["images"]) == {f.name for f in dataclasses.fields(Images)}
    for section, kind in (("robot", PoseStream), ("camera", CameraStream), ("matching", Matching),
                          ("outputs", Outputs)):
        assert set(doc[section]) == {f.name for f in dataclasses.fields(kind)}, section
    assert read.matching == Matching() and read.replace(robot=ROBOT, camera=CAMERA, outputs=Outputs(),
                                                        frame_ids=None) == cell()
