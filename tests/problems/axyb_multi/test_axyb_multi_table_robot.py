"""The robot's poses inside the table of observations (``robot_*`` columns, or ``robot_poses`` in
JSON), instead of a robot pose file: the same answer as with the file, to the last digit; rows of
one station whose robot poses differ, a table without them and no robot file, or both given, are
one-line errors (exit 2)."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest

import handeye
from handeye.base.errors import InputError
from handeye.cli import main
from handeye.io.examples import multi_camera_example_dir
from handeye.workflow.observation_cell import read_tables

KEYS = ("x", "y", "z", "qx", "qy", "qz", "qw")
CELL = ("setup: eye-to-hand\nrobot: {format: xyz-quat-xyzw, unit: mm}\nobservations:\n"
        "  - {file: obs.csv, format: opencv-rvec, unit: mm}\n")


@pytest.fixture
def table_cell(tmp_path):
    """The bundled example's observations with each row's robot pose appended; the cell file."""
    folder = multi_camera_example_dir()
    robot = {r["name"]: r for r in csv.DictReader(open(folder / "robot.csv"))}
    rows = list(csv.DictReader(open(folder / "observations.csv")))
    with open(tmp_path / "obs.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow([*rows[0], *(f"robot_{k}" for k in KEYS)])
        for r in rows:
            out.writerow([*r.values(), *(robot[r["station"]][k] for k in KEYS)])
    (tmp_path / "cell.yaml").write_text(CELL)
    return tmp_path


def test_robot_columns_give_the_answer_of_the_robot_file(table_cell):
    inside = handeye.calibrate(handeye.Cell.from_file(table_cell / "cell.yaml"))
    apart = handeye.calibrate(handeye.Cell.from_file(multi_camera_example_dir() / "cell.yaml"))
    assert inside.status == apart.status and inside.usable
    for p, q in zip(inside.named_poses(), apart.named_poses()):
        assert p.name == q.name and np.array_equal(p.T, q.T)
    robot = inside.to_dict()["inputs"]["robot"]
    assert robot["poses"] == 25 and robot["file"].endswith("obs.csv")


def test_robot_poses_in_a_json_table(table_cell, tmp_path):
    table = read_tables(handeye.Cell.from_file(table_cell / "cell.yaml"), "mm")[0]
    doc = {"station": list(table.station), "camera": list(table.camera), "target": list(table.target),
           "camera_poses": table.poses.poses.tolist(), "robot_poses": table.robot.poses.tolist(), "units": "mm"}
    (tmp_path / "obs.json").write_text(json.dumps(doc))
    (tmp_path / "json.yaml").write_text("setup: eye-to-hand\nobservations: [{file: obs.json}]\n")
    result = handeye.calibrate(handeye.Cell.from_file(tmp_path / "json.yaml"))
    assert result.usable and len(result.stations.robot_file) == 25


def spoil(folder, line: int, column: str, delta: float) -> None:
    rows = list(csv.reader(open(folder / "obs.csv")))
    k = rows[0].index(column)
    rows[line - 1][k] = repr(float(rows[line - 1][k]) + delta)
    with open(folder / "obs.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)


def test_two_robot_poses_for_one_station_are_one_line_error(table_cell, capsys):
    spoil(table_cell, 5, "robot_x", 2.5)
    with pytest.raises(InputError, match=r"station 's00': the robot pose of '.*obs.csv' line 5 differs from "
                                         r"'.*obs.csv' line 2's by .* deg and 2.5 mm; one station is one robot pose"):
        handeye.calibrate(handeye.Cell.from_file(table_cell / "cell.yaml"))
    code = main(["calibrate", "--config", str(table_cell / "cell.yaml")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("case", ["robot file too", "no robot at all"])
def test_robot_poses_given_twice_or_not_at_all(case, table_cell, capsys):
    folder = multi_camera_example_dir()
    if case == "robot file too":
        args = ["--robot", str(folder / "robot.csv")]
        message = "carries robot poses and the cell names the robot pose file"
        config = table_cell / "cell.yaml"
    else:
        args = []
        message = "has no robot pose columns .* and the cell names no robot pose file"
        config = table_cell / "plain.yaml"
        config.write_text(CELL.replace("obs.csv", str(folder / "observations.csv")))
    code = main(["calibrate", "--config", str(config), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert re.search(message, err), err


def test_cli_observations_without_robot_file(table_cell, capsys):
    code = main(["calibrate", "--observations", str(table_cell / "obs.csv"), "--camera-format", "opencv-rvec",
                 "--camera-unit", "mm", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm", "--setup",
                 "eye-to-hand"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "262 observations of 3 cameras and 4 targets at 25" in out
