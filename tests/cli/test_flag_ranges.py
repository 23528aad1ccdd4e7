"""Every number flag of every command, fed numbers out of range (huge, negative, zero, nan, inf,
beyond float64): a one-line error and exit 2, or a run that ends (exit 0 or 1), never an internal
error (`handeye.cli._common.finite_number`, `whole_number`, `seed_number` and each command's own
checks)."""

from __future__ import annotations

import pytest
from test_planning import write_camera
from test_watch_cli import write_pair

from handeye.problems.axyb import PROBLEM
from tests.conftest import run_cli

VALUES = ("99999999999999999999999", "-5", "0", "nan", "inf", "1e400", "-inf")
NUMBER_FLAGS = {
    "simulate": ("--pairs", "--stations", "--noise-rot", "--noise-trans", "--seed"),
    "solve": ("--time-limit", "--tz-X"),
    "plan": ("--count", "--seed", "--max-tilt", "--max-angle", "--pixel-noise"),
    "compare": ("--folds", "--seed", "--timeout"),
    "calibrate": ("--time-limit", "--max-dt"),
    "watch": ("--pixel-noise", "--suggest", "--interval", "--max-tilt"),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("flags")
    data, _ = PROBLEM.simulate(pairs=10, seed=4)
    pair = write_pair(folder, data["A"], data["B"])
    write_camera(folder / "cam.yaml")
    return folder, pair


def _base(command: str, folder, pair) -> list:
    return {
        "simulate": ["simulate", "-o", folder / "sim.json", "--force"],
        "solve": ["solve", "--example"],
        "plan": ["plan", "--setup", "eye-in-hand", "--x", "60,-20,100,17.19,0,0", "--y", "600,0,0,0,0,180",
                 "--board", "chessboard:9x6:30mm", "--intrinsics", folder / "cam.yaml", "--count", "3",
                 "--workspace", "200,-500,50,1000,500,1000", "--max-tilt", "70", "-o", folder / "plan.csv", "--force"],
        "compare": ["compare", "--example", "eth-robot-arm", "-o", folder / "cmp", "--force", "--no-progress",
                    "--solvers", "shah"],
        "calibrate": ["calibrate", *pair, "--match", "row"],
        "watch": ["watch", *pair, "--once"],
    }[command]


@pytest.mark.parametrize("command, flag", [(c, f) for c, flags in NUMBER_FLAGS.items() for f in flags])
def test_numbers_out_of_range_never_end_in_an_internal_error(files, capsys, command, flag):
    folder, pair = files
    for value in VALUES:
        code, _, err = run_cli(capsys, *_base(command, folder, pair), flag, value)
        assert "internal error" not in err and code in (0, 1, 2), (flag, value, code, err)
        if code == 2 and not err.startswith("usage:"):
            assert len(err.strip().splitlines()) == 1, (flag, value, err)
