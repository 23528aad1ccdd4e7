"""Speed of ``handeye calibrate`` on large pose files: the plausibility check's hypotheses.

The calibrate workflow (`handeye.workflow.calibration`) ends with
`handeye.workflow.plausibility.check` on the robot and camera streams: it fits every usual setup
mistake (inverted poses, the other setup, pairs shifted, the camera unit, 11 other Euler
sequences of the robot file, 11 of the camera file's when it holds Euler angles). This script
writes a simulated cell of N stations (robot file ``yaskawa``: x, y, z, rx, ry, rz in mm, extrinsic
xyz; camera file ``opencv-rvec`` in mm; the accuracy study's noise), runs
``handeye calibrate --problem axxb`` on it through the command line, and reports per N the
whole command's time, the time of the check inside it, and its verdict. ``--mistake`` writes the
cell with one mistake (the verdict must then name it).

Each N is run twice in the same process: with the screening of the hypotheses on a subsample of
the stations (`plausibility.SCREEN_STATIONS`, the default) and with every hypothesis given its
deciding fit (on at most `plausibility.FULL_STATIONS` stations: the behaviour without the
screening), so the two columns are measured under the same load; the verdicts must agree.

    python bench/large_files.py --stations 50,500               # AX=XB, every two stations paired
    python bench/large_files.py --stations 2000 --pairing consecutive   # all pairs: > 1,400 refused
    python bench/large_files.py --stations 500 --mistake camera-inverted --problem axyb
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

MISTAKES = ("none", "camera-inverted", "robot-inverted", "euler", "shift", "unit")


def write_cell(folder: Path, stations: int, mistake: str, seed: int) -> list[str]:
    """Robot and camera files of a simulated cell with `mistake`; the calibrate arguments that read them."""
    from handeye.estimation.noise import NoiseModel
    from handeye.geometry.se3 import inverse
    from handeye.io.pose_writers import write_poses
    from handeye.problems.axxb import simulate_stations

    noise = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})
    st, _ = simulate_stations(stations + (mistake == "shift"), seed=seed, noise=noise)
    robot, camera = np.array(st["A"]), inverse(st["B"])
    robot_format, camera_unit = "yaskawa", "mm"
    if mistake == "camera-inverted":
        camera = inverse(camera)
    elif mistake == "robot-inverted":
        robot = inverse(robot)
    elif mistake == "euler":
        robot_format = "staubli"
    elif mistake == "shift":
        robot, camera = robot[:-1], camera[1:]
    elif mistake == "unit":
        camera_unit = "m"
    r = write_poses(folder / "robot.csv", robot, "yaskawa", unit="mm")
    c = write_poses(folder / "camera.csv", camera, "opencv-rvec", unit="mm")
    return ["--robot", str(r), "--robot-format", robot_format, "--camera", str(c), "--camera-format",
            "opencv-rvec", "--camera-unit", camera_unit, "--setup", "eye-in-hand"]


@contextlib.contextmanager
def timed_check(seconds: list[float]) -> Iterator[None]:
    """Append the time of each plausibility check the calibrate workflow runs to `seconds`."""
    from handeye.workflow import calibration

    original = calibration.check

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            seconds.append(time.perf_counter() - start)

    calibration.check = wrapper
    try:
        yield
    finally:
        calibration.check = original


def calibrate_once(arguments: list[str], screen: bool) -> dict[str, Any]:
    """One ``handeye calibrate`` (screening on or off): seconds of the command and of the check, verdict."""
    from handeye.cli import main
    from handeye.workflow import plausibility

    saved = getattr(plausibility, "SCREEN_STATIONS", None)  # None: a version without the screening
    if saved is not None:
        plausibility.SCREEN_STATIONS = saved if screen else 0
    seconds: list[float] = []
    out, err = io.StringIO(), io.StringIO()
    try:
        with timed_check(seconds), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            start = time.perf_counter()
            code = main(["calibrate", *arguments, "--json"])
            total = time.perf_counter() - start
    finally:
        if saved is not None:
            plausibility.SCREEN_STATIONS = saved
    if not out.getvalue().strip():  # refused before solving: say why
        raise SystemExit(f"bench/large_files.py: calibrate failed: {err.getvalue().strip()}")
    checks = json.loads(out.getvalue()).get("checks") or {}
    best = checks.get("explanation")
    return {"code": code, "total": total, "check": sum(seconds), "plausible": checks.get("plausible"),
            "explanation": None if best is None else best["description"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--stations", default="50,500", help="station counts (default 50,500)")
    parser.add_argument("--mistake", default="none", choices=MISTAKES)
    parser.add_argument("--problem", default="axxb", choices=("axxb", "axyb"))
    parser.add_argument("--pairing", choices=("all", "consecutive"), default=None,
                        help="AX=XB's pairing of the stations (calibrate's default: all, up to ~1,400 stations)")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--no-full", action="store_true", help="skip the run without screening (slow at large N)")
    args = parser.parse_args(argv)
    print("| N | mistake | calibrate s (screened) | check s (screened) | calibrate s (all stations) | "
          "check s (all stations) | check speed-up | verdict (screened) | same verdict |")
    print("|---|---|---|---|---|---|---|---|---|")
    same_everywhere = True
    extra = ["--problem", args.problem] + (["--pairing", args.pairing] if args.pairing else [])
    with tempfile.TemporaryDirectory() as tmp:  # warm-up: imports and first calls, not timed
        calibrate_once(write_cell(Path(tmp), 12, "none", args.seed) + extra, screen=True)
    for n in (int(v) for v in args.stations.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            arguments = write_cell(Path(tmp), n, args.mistake, args.seed) + extra
            fast = calibrate_once(arguments, screen=True)
            full = None if args.no_full else calibrate_once(arguments, screen=False)
        verdict = ("no check (the solve itself failed)" if fast["plausible"] is None else "plausible"
                   if fast["plausible"] else f"implausible: {fast['explanation'] or 'no explanation'}")
        same = full is None or all(fast[k] == full[k] for k in ("code", "plausible", "explanation"))
        same_everywhere &= same
        cols = ["-", "-", "-"] if full is None else [f"{full['total']:.2f}", f"{full['check']:.2f}",
                                                     f"{full['check'] / fast['check']:.1f}x" if fast["check"] else "-"]
        print(f"| {n} | {args.mistake} | {fast['total']:.2f} | {fast['check']:.2f} | {cols[0]} | {cols[1]} | "
              f"{cols[2]} | {verdict} | {'yes' if same else 'NO'} |", flush=True)
    return 0 if same_everywhere else 1


if __name__ == "__main__":
    sys.exit(main())
