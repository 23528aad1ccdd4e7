"""Output files: complete or absent, created exclusively, never written through an input.

`handeye.io.output_files` writes to a temporary file in the target's folder and links or renames
it into place. Checked here: a writer killed with SIGKILL at random moments never leaves a
partial target (and the rerun is not blocked); a full disk names the file and leaves nothing;
two writers of one name without --force: exactly one wins, the other is told; --force replaces
the name, not a file that another name (a hard link to an input) shares; a markdown report's
PNGs are not overwritten without --force; a long benchmark fails at once on an unwritable
--json; the ROS line and the markdown report quote what comes from the user.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from handeye import InputError
from handeye.cli import main
from handeye.io import output_files
from handeye.io.output_files import new_file, write_text

ROOT = Path(__file__).resolve().parents[2]
ETH = ROOT / "core" / "data"

WRITER = textwrap.dedent("""
    import sys, time
    from handeye.io.output_files import new_file
    with new_file(sys.argv[1], force=True) as fh:
        for k in range(100000):
            fh.write("%06d " % k * 20 + "\\n")
            if k % 2000 == 0:
                fh.flush()
                time.sleep(0.002)
    print("done", flush=True)
""")


def test_a_writer_killed_at_any_moment_leaves_no_partial_file(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("the complete earlier file\n")
    rng = np.random.default_rng(0)
    for delay in rng.uniform(0.2, 0.9, size=6):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target)], stdout=subprocess.PIPE)
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        text = target.read_text()
        # either the earlier file, or a complete new one: never a truncated one
        assert text == "the complete earlier file\n" or len(text.splitlines()) == 100000
    # and without a kill the writer completes
    subprocess.run([sys.executable, "-c", WRITER, str(target)], check=True, capture_output=True)
    assert len(target.read_text().splitlines()) == 100000


def test_a_killed_cli_run_does_not_block_the_rerun(tmp_path):
    """``handeye simulate -o`` killed at moments spread over its run (about 2 s: simulating,
    then writing 51 MB): the file is absent (and the rerun proceeds) or complete."""
    for k, delay in enumerate((0.6, 1.2, 1.6, 2.0)):
        target = tmp_path / f"big{k}.npz"
        proc = subprocess.Popen([sys.executable, "-c", "from handeye.cli import console_main; console_main()",
                                 "simulate", "--pairs", "200000", "-o", str(target)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if target.exists():
            assert np.load(target)["A"].shape == (200000, 4, 4)
        else:
            assert main(["simulate", "--pairs", "20", "-o", str(target)]) == 0
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(target.name)] == [target.name]


def test_disk_full_names_the_file_and_leaves_nothing(tmp_path, monkeypatch):
    target = tmp_path / "result.json"

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError, match=f"cannot write '{target}': No space left on device"):
        write_text(target, "{}")
    assert list(tmp_path.iterdir()) == []


def test_two_writers_of_one_name_one_wins_the_other_is_told(tmp_path):
    target = tmp_path / "x.json"
    results: list[str] = []
    barrier = threading.Barrier(2)

    def write(text: str) -> None:
        with new_file(target, flag="-o") as fh:
            fh.write(text)
            barrier.wait()  # both have written their temporary file: now both commit
        results.append(text)

    def run(text: str) -> None:
        try:
            write(text)
        except InputError as exc:
            results.append(str(exc))

    threads = [threading.Thread(target=run, args=(t,)) for t in ("first", "second")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wins = [r for r in results if r in ("first", "second")]
    losses = [r for r in results if "the file exists (another run may have written it meanwhile)" in r]
    assert len(wins) == 1 and len(losses) == 1
    assert target.read_text() == wins[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.json"]  # no temporary file left


def test_the_created_file_has_the_usual_permissions(tmp_path):
    mask = os.umask(0o022)
    os.umask(mask)
    path = write_text(tmp_path / "a.txt", "x")
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask


def test_force_replaces_the_name_not_a_hard_linked_input(tmp_path):
    source = tmp_path / "data.txt"
    source.write_text("input\n")
    link = tmp_path / "out.txt"
    os.link(source, link)
    write_text(link, "output\n", force=True)
    assert source.read_text() == "input\n" and link.read_text() == "output\n"


def _calibrate_args(tmp_path: Path) -> list[str]:
    robot, camera = tmp_path / "robot.csv", tmp_path / "camera.csv"
    rng = np.random.default_rng(1)
    from scipy.spatial.transform import Rotation

    from handeye.problems.axyb import PROBLEM

    data, _ = PROBLEM.simulate(pairs=12, seed=int(rng.integers(100)))
    for path, T in ((robot, data["A"]), (camera, np.linalg.inv(data["B"]))):
        q = Rotation.from_matrix(T[:, :3, :3]).as_quat()
        np.savetxt(path, np.column_stack([T[:, :3, 3], q]), delimiter=",", header="x,y,z,qx,qy,qz,qw", comments="")
    return ["calibrate", "--robot", str(robot), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm",
            "--camera", str(camera), "--camera-format", "xyz-quat-xyzw", "--camera-unit", "mm",
            "--camera-poses", "board-in-camera", "--setup", "eye-in-hand"]


def test_an_output_that_is_a_hard_link_to_an_input_is_refused(tmp_path, capsys):
    args = _calibrate_args(tmp_path)
    out = tmp_path / "out.yaml"
    os.link(tmp_path / "robot.csv", out)
    before = (tmp_path / "robot.csv").read_bytes()
    assert main([*args, "--yaml", str(out), "--force"]) == 2
    assert "is the input file" in capsys.readouterr().err
    assert (tmp_path / "robot.csv").read_bytes() == before


def test_a_markdown_report_does_not_overwrite_its_plots(tmp_path, capsys):
    args = _calibrate_args(tmp_path)
    plot = tmp_path / "r_residuals.png"
    plot.write_bytes(b"someone's picture")
    assert main([*args, "--report", str(tmp_path / "r.md")]) == 2
    assert "r_residuals.png' exists; pass --force" in capsys.readouterr().err
    assert plot.read_bytes() == b"someone's picture" and not (tmp_path / "r.md").exists()
    assert main([*args, "--report", str(tmp_path / "r.md"), "--force"]) == 0
    assert plot.read_bytes().startswith(b"\x89PNG")


def test_bench_json_in_an_unwritable_folder_fails_before_the_benchmark(capsys):
    start = time.perf_counter()
    assert main(["bench", "--json", "/proc/handeye-bench.json", "--no-progress"]) == 2
    assert time.perf_counter() - start < 10
    assert "cannot write in the folder '/proc'" in capsys.readouterr().err


def test_check_writable_leaves_nothing(tmp_path):
    output_files.check_writable("--json", tmp_path / "a.json")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="does not exist"):
        output_files.check_writable("--json", tmp_path / "no" / "a.json")


# ----------------------------------------------------------------------------- user text in outputs

@pytest.mark.parametrize("ids", ["tool0;touch${IFS}/tmp/x;#,cam", "tool0,cam$(id)", "tool 0,cam", "/tool0,cam",
                                 "tool0,cam`id`", "tool0,cam'"])
def test_frame_ids_must_be_ros_names(tmp_path, capsys, ids):
    assert main([*_calibrate_args(tmp_path), "--frame-ids", ids]) == 2
    assert "is not a ROS frame id" in capsys.readouterr().err


def test_ros_names_are_taken_and_printed_as_they_are(tmp_path, capsys):
    assert main([*_calibrate_args(tmp_path), "--frame-ids", "robot1/tool0,camera_color_optical_frame"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "static_transform_publisher" in x)
    assert line.endswith("--frame-id robot1/tool0 --child-frame-id camera_color_optical_frame")


def test_the_markdown_report_quotes_file_names(tmp_path):
    hostile = tmp_path / "<img src=x onerror=alert(1)>[a](b)"
    hostile.mkdir()
    args = _calibrate_args(hostile)
    assert main([*args, "--report", str(tmp_path / "r.md")]) == 0
    text = (tmp_path / "r.md").read_text()
    assert "<img src=x" not in text and "&lt;img src=x onerror=alert(1)&gt;" in text
    assert "[a](b)" not in text and r"\[a\](b)" in text
