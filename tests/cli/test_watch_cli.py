"""``handeye watch``: one line per station from a pose file pair, the final answer, suggestions
written for the robot, following a growing pair, and bad input (exit 2)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest

from handeye.cli import main
from handeye.estimation.noise import NoiseModel
from handeye.geometry import so3_fast
from handeye.geometry.se3 import inverse, make_pose
from handeye.io.pose_readers import PoseStack, read_poses
from handeye.io.pose_writers import write_poses
from handeye.planning.plan import plan
from handeye.problems.axyb import PROBLEM
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def write_pair(folder, A, B, *, gross: int | None = None, rows: slice = slice(None)):
    """robot.csv (kuka-abc, mm) and camera.csv (opencv-rvec, T_cam_target) of eye-in-hand stations."""
    names = tuple(f"s{i + 1:02d}" for i in range(len(A)))[rows]
    camera = inverse(B)
    if gross is not None:
        camera = camera.copy()
        camera[gross] = make_pose(so3_fast.exp(np.array([math.radians(5.0), 0, 0])), np.zeros(3)) @ camera[gross]
    robot_file, camera_file = folder / "robot.csv", folder / "camera.csv"
    write_poses(robot_file, PoseStack(A[rows], unit="mm", format="kuka-abc", names=names), "kuka-abc")
    write_poses(camera_file, PoseStack(camera[rows], unit="mm", format="opencv-rvec", names=names), "opencv-rvec")
    return ["--robot", str(robot_file), "--robot-format", "kuka-abc", "--camera", str(camera_file),
            "--camera-format", "opencv-rvec", "--camera-unit", "mm", "--setup", "eye-in-hand"]


@pytest.fixture
def stations():
    data, _ = PROBLEM.simulate(pairs=14, seed=2, noise=NOISE)
    return data["A"], data["B"]


def test_once_prints_one_line_per_station_and_the_final_answer(tmp_path, stations, capsys):
    flags = write_pair(tmp_path, *stations, gross=10)
    assert main(["watch", *flags, "--once", "--target", "0.5deg,5mm"]) == 0
    out = capsys.readouterr().out.splitlines()
    lines = [line for line in out if line.startswith("s")]
    assert [line.split(":")[0] for line in lines] == [f"s{i + 1:02d}" for i in range(14)]
    assert "not determined yet" in lines[0] and "X " in lines[8] and "Y " in lines[8]
    assert "DISAGREES" in lines[10] and "left out" in lines[10]
    assert sum("DISAGREES" in line for line in lines) == 1
    assert lines[-1].startswith("s14: 13/14 stations") and "enough" in lines[-1]
    assert out[len(lines)].startswith("final: 13 stations, status optimal")


def test_json_lines(tmp_path, stations, capsys):
    flags = write_pair(tmp_path, *stations)
    assert main(["watch", *flags, "--once", "--json", "--camera-noise", "0.1deg,0.5mm"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(records) == 15 and records[-1]["final"]["status"] == "optimal"
    assert records[3]["noise"] == "expected" and records[-2]["noise"] == "estimated"
    assert records[-2]["std"]["X"]["rotation_deg"] > 0 and records[-2]["unit"] == "mm"


def test_camera_pose_only(tmp_path, stations, capsys):
    """--problem axxb: the camera's pose alone, its 1-sigma the same as A X = Y B's X on the same
    stations (the same fit), and the final answer of the motions."""
    flags = write_pair(tmp_path, *stations)
    assert main(["watch", *flags, "--once", "--json", "--problem", "axxb"]) == 0
    camera = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert main(["watch", *flags, "--once", "--json"]) == 0
    both = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert set(camera[-2]["std"]) == set(camera[-2]["unknowns"]) == {"X"}
    assert camera[-2]["std"]["X"]["translation"] == pytest.approx(both[-2]["std"]["X"]["translation"], rel=1e-9)
    assert set(camera[-1]["final"]["unknowns"]) == {"X"} and camera[-1]["final"]["status"] == "optimal"


def test_suggestions_in_the_robot_format(tmp_path, capsys):
    board = parse_board("chessboard:9x6:25mm")
    camera = Camera(np.array([[1000.0, 0, 640], [0, 1000, 512], [0, 0, 1]]), np.zeros(0), (1280, 1024))
    X = make_pose(np.eye(3), np.array([0.0, 50.0, 80.0]))
    Y = make_pose(np.diag([1.0, -1.0, -1.0]), np.array([600.0, 0.0, 0.0]))
    p = plan("axyb", setup="eye-in-hand", X=X, Y=Y, camera=camera, board=board, count=6, pool=1000, seed=2)
    flags = write_pair(tmp_path, p.A, p.B)
    intrinsics = tmp_path / "camera.json"
    intrinsics.write_text(json.dumps({"camera_matrix": camera.K.tolist(), "distortion_coefficients": [0, 0, 0, 0, 0],
                                      "image_width": 1280, "image_height": 1024}))
    out_file = tmp_path / "next.csv"
    code = main(["watch", *flags, "--once", "--intrinsics", str(intrinsics), "--board", "chessboard:9x6:25mm",
                 "--suggest", "2", "--workspace", "200,-500,100,1000,500,1200", "--max-tilt", "60",
                 "--next-out", str(out_file)])
    assert code == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("s")]
    assert len(lines) == 6 and "| next: x=" in lines[-1] and " a=" in lines[-1]
    suggested = read_poses(out_file, "kuka-abc")
    assert len(suggested) == 2 and suggested.names == ("next1", "next2")
    t = suggested.poses[:, :3, 3]
    assert np.all((t >= [200, -500, 100]) & (t <= [1000, 500, 1200]))


def watch_while(flags: list[str], idle: float, *changes) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``handeye watch`` in its own process, polling every 0.2 s
    and ending after `idle` s without a new station, while `changes` ((station, function) pairs)
    rewrite its files, each once watch has printed that station's line (not after a fixed time:
    a loaded machine starts the process slowly)."""
    import threading

    command = "import sys; from handeye.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", command, "watch", *flags, "--interval", "0.2", "--idle", str(idle)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()
    try:
        for station, change in changes:
            deadline = time.monotonic() + 60
            while not any(line.startswith(f"{station}:") for line in list(lines)) and time.monotonic() < deadline:
                time.sleep(0.05)
            change()
        proc.wait(timeout=60)  # not communicate(): it would take the lines the reader is reading
    finally:
        proc.kill()
    reader.join(5)
    return proc.returncode, "".join(lines), proc.stderr.read()


def test_follows_a_growing_file_pair(tmp_path, stations):
    A, B = stations
    flags = write_pair(tmp_path, A, B, rows=slice(0, 5))
    code, out, err = watch_while(flags, 3, ("s05", lambda: write_pair(tmp_path, A, B, rows=slice(0, 9))),
                                 ("s09", lambda: write_pair(tmp_path, A, B)))
    assert code == 0, err
    lines = [line for line in out.splitlines() if line.startswith("s")]
    assert [line.split(":")[0] for line in lines] == [f"s{i + 1:02d}" for i in range(14)]
    assert out.splitlines()[14].startswith("final: 14 stations")


@pytest.mark.parametrize("extra, message", [
    (["--target", "0.1deg"], "--target needs a rotation and a translation"),
    (["--target", "fast"], "--target expects a rotation and a translation"),
    (["--workspace", "1,2,3"], "--workspace expects six numbers"),
    (["--board", "chessboard:9x6:25mm"], "--intrinsics and --board go together"),
    (["--camera-intrinsics", "camera.yaml"], "--intrinsics and --board go together"),  # the older name
    (["--match", "time"], "invalid choice"),
    (["--problem", "axbycz"], "--problem 'axbycz' cannot plan stations"),
])
def test_bad_flags_exit_2(tmp_path, stations, capsys, extra, message):
    flags = write_pair(tmp_path, *stations)
    assert main(["watch", *flags, "--once", *extra]) == 2
    assert message in capsys.readouterr().err


def test_bad_files_exit_2_with_one_line(tmp_path, stations, capsys):
    flags = write_pair(tmp_path, *stations)
    (tmp_path / "camera.csv").write_text("name,rx,ry,rz,x,y,z\ns01,1,2,3\n")
    assert main(["watch", *flags, "--once"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("handeye: error:") and "camera" in err[0]
    flags[flags.index("--robot") + 1] = str(tmp_path / "missing.csv")
    assert main(["watch", *flags, "--once"]) == 2
    assert "not found" in capsys.readouterr().err


def test_a_line_being_written_is_read_when_complete(tmp_path, stations):
    """The robot file ends in half a line for longer than a poll: not an error, the station
    follows once the line is complete."""
    A, B = stations
    flags = write_pair(tmp_path, A, B, rows=slice(0, 6))
    robot = tmp_path / "robot.csv"
    text = robot.read_text()
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    robot.write_text(text[:len(text) - len(last) - 1] + last[:10])  # station 6 half written
    command = "import sys; from handeye.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", command, "watch", *flags, "--interval", "0.2", "--idle", "2.5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(1.5)
        robot.write_text(text)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert [line.split(":")[0] for line in out.splitlines() if line.startswith("s")] == [f"s0{i}" for i in range(1, 7)]


def test_a_rewritten_recording_is_noticed_and_followed_from_its_start(tmp_path, stations):
    """The recorder restarts and rewrites the files (the board moved 60 mm): the stations read
    before are not this recording's. The pair says so at the next poll (also for a file cut
    short), and `restart` follows the new recording from its first station."""
    from handeye.workflow.cell import CameraStream, PoseStream
    from handeye.workflow.watch_source import PoseFilePair, RecordingRewritten

    A, B = stations
    write_pair(tmp_path, A, B, rows=slice(0, 12))
    source = PoseFilePair(PoseStream(str(tmp_path / "robot.csv"), "kuka-abc"),
                          CameraStream(str(tmp_path / "camera.csv"), "opencv-rvec", "mm"), "eye-in-hand")
    assert len(source.poll()) == 12 and source.poll() == []
    moved = make_pose(np.eye(3), [60.0, 0.0, 0.0])
    write_pair(tmp_path, A, B @ moved)  # B = T_target_cam eye in hand: the board 60 mm away, 14 stations
    with pytest.raises(RecordingRewritten, match="station s01 .* is no longer the pose it was"):
        source.poll()
    source.restart()
    assert [s.name for s in source.poll()] == [f"s{i + 1:02d}" for i in range(14)]
    write_pair(tmp_path, A, B @ moved, rows=slice(0, 5))  # cut short
    with pytest.raises(RecordingRewritten, match="station s06 .* is no longer in the files"):
        source.poll()


def test_watch_starts_over_when_the_recording_is_rewritten(tmp_path, stations):
    """watch, following files a restarted recorder rewrites, says so and starts over: the final
    answer is the new recording's, from its 14 stations, not the old ones'."""
    A, B = stations
    flags = write_pair(tmp_path, A, B, rows=slice(0, 10))
    code, out, err = watch_while(flags, 2.5, ("s10", lambda: write_pair(tmp_path, A, B @ make_pose(np.eye(3),
                                                                                                  [60.0, 0.0, 0.0]))))
    assert code == 0, err
    assert "the recording was rewritten" in out and "starting over with the new recording (10 stations" in out
    assert "final: 14 stations" in out


def test_the_final_line_carries_the_answers_warnings(tmp_path, stations, capsys):
    """The camera's translations 2% short: the final answer warns of the camera scale, as
    calibrate does on the same files, instead of a bare `status optimal`."""
    A, B = stations
    short = B.copy()
    short[:, :3, 3] *= 0.98
    flags = write_pair(tmp_path, A, short)
    assert main(["watch", *flags, "--once"]) in (0, 1)
    out = capsys.readouterr().out
    final = out[out.index("final:"):]
    assert "warning:" in final and "scale" in final, final


def test_the_first_stations_say_why_there_is_no_answer_yet(tmp_path, capsys):
    """Stations that only translate the flange: each line says why there is no answer yet (the
    rotations about fewer than two axes, and what to record), not a bare "not determined yet"."""
    data, truth = PROBLEM.simulate(pairs=10, seed=2)
    A = data["A"].copy()
    for i in range(1, 5):
        A[i] = A[0].copy()
        A[i][:3, 3] += [50.0 * i, 0.0, 0.0]
    B = np.array([inverse(truth["Y"]) @ a @ truth["X"] for a in A])
    flags = write_pair(tmp_path, A, B)
    assert main(["watch", *flags, "--once"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "(an answer needs 3 stations)" in lines[0]
    assert "no answer from the 3 stations yet" in lines[2] and "rotate about at least two different axes" in lines[2]


def test_watch_draws_the_recording_at_the_end(tmp_path, stations, capsys):
    """--figure: the recording in 3D at the answer (the stations, the one left out grey, the
    camera and board), written once watch ends; a format matplotlib cannot write is refused first."""
    A, B = stations
    flags = write_pair(tmp_path, A, B, gross=10)
    assert main(["watch", *flags, "--once", "--figure", str(tmp_path / "cell.png")]) == 0
    out = capsys.readouterr().out
    assert f"figure: {tmp_path / 'cell.png'}" in out
    assert (tmp_path / "cell.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["watch", *flags, "--once", "--figure", str(tmp_path / "cell.xyz")]) == 2
    assert "cannot draw a figure as 'xyz'" in capsys.readouterr().err
