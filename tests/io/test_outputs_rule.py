"""One rule for every command's output files (`handeye.cli._common.check_outputs`): no output is
an input of the same run or another of its outputs, whatever the flags (``--force`` included),
checked before any work; an existing output needs ``--force``. Exit 2 with one line naming both."""

from __future__ import annotations

import shutil

import pytest
from test_planning import write_camera
from test_watch_cli import write_pair

from handeye.io.examples import image_example_dir
from tests.conftest import run_cli

PLAN = ["plan", "--setup", "eye-in-hand", "--x", "60,-20,100,17.19,0,0", "--y", "600,0,0,0,0,180",
        "--board", "chessboard:9x6:30mm", "--count", "4", "--workspace", "200,-500,50,1000,500,1000",
        "--max-tilt", "70", "--unit", "mm"]


def _refused(capsys, *argv, says: str) -> None:
    code, _, err = run_cli(capsys, *argv)
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, (code, err)


def test_watch_never_writes_over_the_recording_it_watches(tmp_path, capsys):
    from handeye.problems.axyb import PROBLEM

    data, _ = PROBLEM.simulate(pairs=8, seed=2)
    flags = write_pair(tmp_path, data["A"], data["B"])
    before = (tmp_path / "robot.csv").read_bytes()
    _refused(capsys, "watch", *flags, "--once", "--next-out", tmp_path / "robot.csv", "--force",
             says="is the input")
    assert (tmp_path / "robot.csv").read_bytes() == before


def test_calibrate_never_writes_over_its_cell_file(tmp_path, capsys):
    folder = tmp_path / "rct"
    shutil.copytree(image_example_dir(), folder)
    cell = tmp_path / "cell.yaml"
    cell.write_text(f"setup: eye-in-hand\nrobot: {{file: {folder / 'poses'}, format: xyz-quat-xyzw, unit: m}}\n"
                    f"images: {{folder: {folder / 'images'}, board: 'circlegrid:10x10:25.4mm'}}\n"
                    "matching: {method: name}\n")
    before = cell.read_bytes()
    for flag in ("-o", "--yaml", "--write-config"):
        _refused(capsys, "calibrate", "--config", cell, flag, cell, "--force", says="is the input")
    assert cell.read_bytes() == before


def test_plan_never_writes_over_its_intrinsics_nor_two_outputs_to_one_file(tmp_path, capsys):
    write_camera(tmp_path / "cam.yaml")
    before = (tmp_path / "cam.yaml").read_bytes()
    intrinsics = ["--intrinsics", tmp_path / "cam.yaml"]
    _refused(capsys, *PLAN, *intrinsics, "-o", tmp_path / "cam.yaml", "--force", says="is the input")
    assert (tmp_path / "cam.yaml").read_bytes() == before
    _refused(capsys, *PLAN, *intrinsics, "-o", tmp_path / "plan.csv", "--json", tmp_path / "plan.csv",
             says="name the same file")
    assert not (tmp_path / "plan.csv").exists()


@pytest.mark.parametrize("force", [False, True])
def test_an_existing_output_needs_force_and_an_input_never_becomes_one(tmp_path, capsys, force):
    """simulate's -o: an existing file is refused without --force and written with it."""
    target = tmp_path / "sim.json"
    target.write_text("{}")
    code, _, err = run_cli(capsys, "simulate", "--pairs", "6", "--seed", "1", "-o", target,
                           *(["--force"] if force else []))
    assert (code == 0) == force and (force or "--force" in err)


def test_outputs_are_checked_before_any_work(tmp_path, capsys):
    """A figure in a format matplotlib cannot write, or an output in a folder that does not exist:
    refused before the plan is computed, so no stations file is left behind for a run that failed."""
    write_camera(tmp_path / "cam.yaml")
    stations = tmp_path / "plan.csv"
    common = [*PLAN, "--intrinsics", tmp_path / "cam.yaml", "-o", stations]
    _refused(capsys, *common, "--figure", tmp_path / "plan.xyz", says="cannot draw a figure as 'xyz'")
    _refused(capsys, *common, "--json", tmp_path / "missing" / "plan.json", says="does not exist")
    assert not stations.exists()


def test_an_output_over_a_file_of_an_input_folder_is_refused(tmp_path, capsys):
    """calibrate reads every image of --images and every pose file of a pose folder: an output
    naming one of them is refused even with --force (it would overwrite an image or a pose)."""
    folder = tmp_path / "rct"
    shutil.copytree(image_example_dir(), folder)
    flags = ["calibrate", "--images", folder / "images", "--board", "circlegrid:10x10:25.4mm", "--robot",
             folder / "poses", "--robot-format", "xyz-quat-xyzw", "--robot-unit", "m", "--match", "name",
             "--setup", "eye-in-hand"]
    image = sorted((folder / "images").iterdir())[0]
    pose = sorted((folder / "poses").iterdir())[0]
    before = image.read_bytes(), pose.read_bytes()
    _refused(capsys, *flags, "-o", image, "--force", says="a file the run reads from the input folder")
    _refused(capsys, *flags, "--yaml", pose, "--force", says="a file the run reads from the input folder")
    assert (image.read_bytes(), pose.read_bytes()) == before
