"""Each command fed a recording with one mistake in it (a value of the wrong type, NaN, a row
duplicated, the rows of one file reordered, a unit mis-stated): it must end in a one-line error
(exit 2), in an answer its checks refuse (exit 1, with the warning that says why), or in an
answer within its stated 1-sigma of the truth (4 of them) - never a confident wrong answer, never
an internal error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.io.pose_readers import PoseStack
from handeye.io.pose_writers import write_poses
from handeye.problems.axyb import PROBLEM
from tests.conftest import run_cli

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})
MISTAKES = ("wrong type", "nan", "duplicated row", "reordered rows", "camera unit")


def _cell(folder, seed: int):
    """A simulated eye-in-hand cell of 14 stations: robot.csv (kuka-abc, mm), camera.csv
    (opencv-rvec, T_cam_target, mm), and its truth."""
    data, truth = PROBLEM.simulate(pairs=14, seed=seed, noise=NOISE)
    names = tuple(f"s{i:02d}" for i in range(14))
    write_poses(folder / "robot.csv", PoseStack(data["A"], unit="mm", format="kuka-abc", names=names), "kuka-abc")
    write_poses(folder / "camera.csv", PoseStack(inverse(data["B"]), unit="mm", format="opencv-rvec", names=names),
                "opencv-rvec")
    return truth


def _mistake(folder, kind: str, row: int, column: int) -> None:
    which = folder / ("camera.csv" if kind in ("nan", "camera unit") or row % 2 else "robot.csv")
    lines = which.read_text().splitlines()
    head, body = [line for line in lines if not line[:1].isalnum() or line.startswith("name")], \
        [line for line in lines if line[:1].isalnum() and not line.startswith("name")]
    row %= len(body)
    parts = body[row].split(",")
    column = 1 + column % (len(parts) - 1)
    if kind == "wrong type":
        parts[column] = "abc"
    elif kind == "nan":
        parts[column] = "nan"
    body[row] = ",".join(parts)
    if kind == "duplicated row":
        body.insert(row, body[row])
    elif kind == "reordered rows":
        body[row], body[(row + 1) % len(body)] = body[(row + 1) % len(body)], body[row]
    which.write_text("\n".join([*head, *body]) + "\n")


def _flags(folder, kind: str) -> list:
    unit = "m" if kind == "camera unit" else "mm"
    return ["--robot", folder / "robot.csv", "--robot-format", "kuka-abc", "--camera", folder / "camera.csv",
            "--camera-format", "opencv-rvec", "--camera-unit", unit, "--setup", "eye-in-hand"]


def _within(result: dict, truth: dict) -> bool:
    for name in ("X", "Y"):
        T, G = np.array(result[name]), truth[name]
        std = result["std"][name]
        angle = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(G[:3, :3].T @ T[:3, :3]) - 1) / 2))))
        if angle > 4 * std["rotation_deg"] or np.linalg.norm(T[:3, 3] - G[:3, 3]) > 4 * std["translation"]:
            return False
    return True


@pytest.mark.parametrize("command", ["calibrate", "watch"])
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(MISTAKES), row=st.integers(0, 40), column=st.integers(0, 6), seed=st.integers(0, 50))
def test_a_recording_with_one_mistake_is_refused_flagged_or_right(tmp_path_factory, capsys, command, kind, row, column,
                                                                  seed):
    import json

    capsys.readouterr()
    folder = tmp_path_factory.mktemp("mistake")
    truth = _cell(folder, seed)
    _mistake(folder, kind, row, column)
    if command == "calibrate":
        code, out, err = run_cli(capsys, "calibrate", *_flags(folder, kind), "--json")
    else:
        code, out, err = run_cli(capsys, "watch", *_flags(folder, kind), "--once", "--json")
    assert "internal error" not in err and code in (0, 1, 2), (kind, code, err)
    if code == 2:
        assert len(err.strip().splitlines()) == 1, err
        return
    if command == "calibrate":
        result = json.loads(out)
        if code == 0:  # usable: right within its 1-sigma, or saying what is off
            assert _within(result, truth) or result["warnings"], (kind, result["warnings"])
        else:
            assert result["warnings"], kind
    else:
        final = json.loads(out.strip().splitlines()[-1])["final"]
        if final is not None and code == 0:
            answer = {name: final["unknowns"][name] for name in ("X", "Y")}
            answer["std"] = final["std"]
            assert _within(answer, truth) or final["warnings"], (kind, final["warnings"])
