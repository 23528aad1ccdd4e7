"""Numerical reproducers of an adversarial campaign: data that once gave a confident wrong answer,
or took memory that grows with the square of a recording.

- Half the pairs gross (random camera poses): never `optimal` more than 5 deg off; the answer is
  `unreliable` because the data determine it only beyond 2 deg / 10% of the lever arm.
- The same station recorded again and again, with noise: refused (no motion beyond the noise).
- A 15,000-station recording: the duplicate-station check in bounded memory; a 12,000-station
  recording matched by time calibrates (with its report) in bounded memory and time.
"""

from __future__ import annotations

import subprocess
import sys
import time
import tracemalloc

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.checks.stations import duplicate_stations, station_warnings
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import (
    inverse,
    largest_relative_angle,
    make_pose,
    random_poses,
    rotation_angle,
    so3_exp,
)
from handeye.problems.axxb import motions, simulate_stations
from handeye.problems.axyb import PROBLEM as AXYB

#: the accuracy study's noise
NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def _gross(fraction: float, seed: int, m: int = 30) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    data, truth = AXYB.simulate(pairs=m, seed=seed, noise=NOISE)
    rng = np.random.default_rng(seed + 999)
    B = data["B"].copy()
    for i in rng.choice(m, round(fraction * m), replace=False):
        B[i] = random_poses(1, rng, 300.0)[0]
    return {"A": data["A"], "B": B}, truth


@pytest.mark.parametrize("fraction", [0.3, 0.4])
def test_gross_pairs_short_of_half_are_left_out(fraction):
    """Measured before: at 40% random camera poses auto was `optimal` 20 of 40 times and
    `unreliable` (10-45 deg off) the rest; its robust step now also starts from the largest group
    of pairs that agree with each other, and the self-check compares fits the same way."""
    for seed in range(6):
        data, truth = _gross(fraction, seed)
        sol = handeye.solve("axyb", **data)
        errors = AXYB.errors(sol.unknowns, truth)
        assert sol.status is handeye.Status.OPTIMAL, (seed, sol.warnings[:1])
        assert np.degrees(errors["X"]["rotation"]) < 0.3 and errors["X"]["translation"] < 3.0, (seed, errors)
        assert len(sol.diagnostics["outliers"]) == round(fraction * 30)


@pytest.mark.parametrize("fraction", [0.5, 0.6])
def test_gross_pairs_past_the_breakdown_are_never_a_confident_answer(fraction):
    """Measured before: at 50%, `optimal` in 40 of 40 solves, 37 more than 5 deg off (up to
    51 deg). Now `unreliable`: no majority of consistent pairs exists, whatever the solver."""
    for seed in range(4):
        data, _ = _gross(fraction, seed)
        for solver in ("auto", "shah"):
            sol = handeye.solve("axyb", solver=solver, **data)
            assert sol.status is handeye.Status.UNRELIABLE, (seed, solver)
            assert sol.warnings[0].startswith("self-check failed, do not use this answer: no majority of consistent "
                                              "pairs exists"), sol.warnings[0]


@pytest.mark.parametrize("fraction", [0.0, 0.3, 0.4, 0.5])
def test_the_agreeing_group_is_the_clean_pairs(fraction):
    """Without X or Y: pairs whose robot and camera rotations between them agree."""
    data, _ = _gross(fraction, 3)
    validated = AXYB.validate(**data)
    rng = np.random.default_rng(3 + 999)
    gross = rng.choice(30, round(fraction * 30), replace=False)
    expected = np.ones(30, dtype=bool)
    expected[gross] = False
    np.testing.assert_array_equal(validated.agreeing_group, expected)
    assert validated.agreeing_share == pytest.approx(1 - fraction)


def test_clean_noisy_data_agree():
    for factor in (1, 10):
        noise = NoiseModel({"A": (0.0002 * factor, 0.05 * factor), "B": (0.002 * factor, 0.5 * factor)})
        for m in (8, 50):
            assert AXYB.validate(**AXYB.simulate(pairs=m, seed=m, noise=noise)[0]).agreeing_group.all()


def _copies(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Fifteen copies of one station, each with the accuracy study's noise."""
    stations, _ = simulate_stations(15, seed=seed)
    rng = np.random.default_rng(seed)

    def noisy(T: np.ndarray, rot: float, trans: float) -> np.ndarray:
        return np.stack([make_pose(so3_exp(rng.normal(0, rot, 3)), rng.normal(0, trans, 3)) @ T[0] for _ in T])

    return noisy(stations["A"][:1].repeat(15, 0), 0.0002, 0.05), noisy(stations["B"][:1].repeat(15, 0), 0.002, 0.5)


@pytest.mark.parametrize("seed", range(3))
def test_copies_of_one_station_are_refused(seed):
    """Measured before: AX=XB `optimal` in 5 of 6 seeds, 53-176 deg off."""
    A, B = _copies(seed)
    with pytest.raises(handeye.DegenerateDataError, match="do not move beyond their noise"):
        handeye.solve("axxb", **motions(A, inverse(B), setup="eye-in-hand"))
    with pytest.raises(handeye.DegenerateDataError, match="the stations do not move beyond their noise"):
        handeye.solve("axyb", A=A, B=B)


def test_small_but_real_motions_are_not_refused():
    """Stations 5 deg apart with the accuracy study's noise move well beyond it: solved."""
    stations, truth = simulate_stations(12, seed=2)
    rng = np.random.default_rng(2)
    A = np.stack([make_pose(so3_exp(rng.normal(size=3) / np.sqrt(3) * np.deg2rad(5)), rng.normal(size=3))
                  @ stations["A"][0] for _ in range(12)])
    B = inverse(truth["Y"]) @ A @ truth["X"]
    B = np.stack([make_pose(so3_exp(rng.normal(0, 0.002, 3)), rng.normal(0, 0.5, 3)) @ T for T in B])
    sol = handeye.solve("axyb", A=A, B=B)  # no DegenerateDataError
    assert sol.status in (handeye.Status.OPTIMAL, handeye.Status.UNRELIABLE)


# ----------------------------------------------------------------------------- long recordings

def test_duplicate_stations_of_a_long_recording_in_linear_memory():
    """15,000 stations: the pairwise check took 9.8 GB (n^2); now a k-d tree, a few MB."""
    robot = AXYB.simulate(pairs=15000, seed=1)[0]["A"]
    robot[9000] = robot[17]  # one repeated station, found and named by its rows
    tracemalloc.start()
    try:
        start = time.perf_counter()
        warnings = station_warnings(robot, "mm")
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6, peak
    assert seconds < 10, seconds
    assert len(warnings) == 1 and "rows 18 and 9001" in warnings[0]


def test_duplicate_stations_agree_with_the_pairwise_definition():
    rng = np.random.default_rng(5)
    poses = random_poses(60, rng, 10.0)
    poses[[7, 30, 31]] = poses[3]
    poses[44] = make_pose(so3_exp([0, 0, 1e-4]), [0, 0, 0.001]) @ poses[12]
    poses[50] = make_pose(so3_exp([0, 0, 0.01]), [0, 0, 0.0]) @ poses[12]  # turned too far: not a duplicate
    i, j = np.triu_indices(60, k=1)
    angle = rotation_angle(np.swapaxes(poses[i, :3, :3], 1, 2) @ poses[j, :3, :3])
    near = np.linalg.norm(poses[i, :3, 3] - poses[j, :3, 3], axis=1) <= 0.01
    expected = [(int(a), int(b)) for a, b in zip(i[near & (angle < 1e-3)], j[near & (angle < 1e-3)])]
    assert duplicate_stations(poses, 0.01, 1e-3, limit=100) == expected == [(3, 7), (3, 30), (3, 31), (7, 30),
                                                                            (7, 31), (12, 44), (30, 31)]
    assert duplicate_stations(poses, 0.01, 1e-3, limit=2) == expected[:2]


def test_largest_relative_angle_in_chunks():
    R = random_poses(300, np.random.default_rng(1))[:, :3, :3]
    pairwise = rotation_angle(np.einsum("iab,jac->ijbc", R, R)).max()
    assert largest_relative_angle(R, chunk=7) == pytest.approx(pairwise, abs=1e-7)


def test_a_12000_station_recording_matched_by_time_calibrates_in_bounded_memory(tmp_path):
    """Measured before: 12,000 stations took 9.8 GB in the station check, and the report alone
    12.5 GB and 140 s (a bar per pair, a pairwise rotation table)."""
    data, _ = AXYB.simulate(pairs=12000, seed=1, noise=NOISE)
    stamps = np.arange(12000) / 30.0
    jitter = np.random.default_rng(0).normal(0, 1e-3, 12000)
    files = []
    for name, T, t in (("robot", data["A"], stamps), ("camera", data["B"], stamps + jitter)):
        q = Rotation.from_matrix(T[:, :3, :3]).as_quat()
        path = tmp_path / f"{name}.csv"
        np.savetxt(path, np.column_stack([t, T[:, :3, 3], q]), delimiter=",", header="t,x,y,z,qx,qy,qz,qw",
                   comments="")
        files.append(path)
    args = ["calibrate", "--robot", str(files[0]), "--robot-format", "xyz-quat-xyzw", "--robot-unit", "mm",
            "--camera", str(files[1]), "--camera-format", "xyz-quat-xyzw", "--camera-unit", "mm",
            "--camera-poses", "camera-in-board", "--setup", "eye-in-hand", "--match", "time",
            "--report", str(tmp_path / "r.html")]
    # the command in its own process, which reports its peak resident memory when done
    child = ("import resource, sys\nfrom handeye.cli import main\ncode = main(sys.argv[1:])\n"
             "print('peak-rss-kb', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\nsys.exit(code)")
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", child, *args], capture_output=True, text=True, timeout=300)
    seconds = time.perf_counter() - start
    assert done.returncode == 0 and "status optimal" in done.stdout, done.stderr
    assert "matched 12000 of 12000" in done.stdout
    peak = int(done.stdout.split("peak-rss-kb")[1]) * 1024
    assert peak < 1.5e9, peak  # measured 0.52 GB (Python, numpy, matplotlib included)
    assert seconds < 60, seconds  # measured 6-9 s


def test_all_pairs_of_a_long_recording_are_refused_with_the_way_out():
    stations, _ = simulate_stations(1500, seed=1)
    with pytest.raises(handeye.InputError, match="1500 stations make 1,124,250 motions.*problem axyb"):
        motions(stations["A"], inverse(stations["B"]), setup="eye-in-hand")
    assert len(motions(stations["A"], inverse(stations["B"]), setup="eye-in-hand", pairing="consecutive")["A"]) == 1499
