"""Structured input nested thousands deep (a cell, arm, board, intrinsics or pose file; YAML, JSON,
OpenCV's FileStorage YAML and XML) is refused in one line naming the file, in well under a
second: the parsers and whatever walks their result would recurse once per level. So is a value
of the wrong type where a unit is named (a list or a mapping: "unhashable type" before)."""

from __future__ import annotations

import pytest

from handeye.base.errors import InputError
from handeye.io.arm_files import read_arm
from handeye.io.pose_readers import read_poses
from handeye.vision.boards import parse_board
from handeye.vision.intrinsics import load_camera
from handeye.workflow.cell import Cell

LEVELS = 5000
YAML_LIST = "[" * LEVELS + "]" * LEVELS
JSON_LIST = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize("name, text, read", [
    ("cell.yaml", f"setup: eye-in-hand\nrobot: {YAML_LIST}\n", Cell.from_file),
    ("cell.json", f'{{"setup": "eye-in-hand", "robot": {JSON_LIST}}}', Cell.from_file),
    ("arm.yaml", f"dh: {YAML_LIST}\n", read_arm),
    ("arm.json", f'{{"dh": {JSON_LIST}}}', read_arm),
    ("board.yaml", f"kind: {YAML_LIST}\n", parse_board),
    ("camera.yaml", f"camera_matrix: {YAML_LIST}\n", load_camera),
    ("camera.json", f'{{"camera_matrix": {JSON_LIST}}}', load_camera),
    ("storage.yaml", f"%YAML:1.0\n---\ncamera_matrix: {YAML_LIST}\n", load_camera),
    ("storage.xml", "<?xml version='1.0'?><opencv_storage><camera_matrix>" + "<_>" * LEVELS + "</_>" * LEVELS
     + "</camera_matrix></opencv_storage>", load_camera),
    ("poses.yaml", f"poses: {YAML_LIST}\n", lambda path: read_poses(path, "matrix")),
    ("poses.json", JSON_LIST, lambda path: read_poses(path, "matrix")),
])
def test_deeply_nested_files_are_refused_in_one_line(tmp_path, name, text, read):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match="nested more than 64 levels deep") as caught:
        read(str(path) if name.startswith("board") else path)
    assert "\n" not in str(caught.value) and name in str(caught.value)


@pytest.mark.parametrize("name, text, read", [
    ("arm.yaml", "convention: standard-dh\nlength_unit: [mm]\nangle_unit: deg\njoints: []\n", read_arm),
    ("arm.yaml", "convention: standard-dh\nlength_unit: mm\nangle_unit: {deg: 1}\njoints: []\n", read_arm),
    ("board.yaml", "kind: chessboard\ncols: 9\nrows: 6\nspacing: 30\nunit: [mm]\n", parse_board),
])
def test_a_unit_of_the_wrong_type_is_refused_in_one_line(tmp_path, name, text, read):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match="unit") as caught:
        read(str(path) if name.startswith("board") else path)
    assert "\n" not in str(caught.value)
