"""Problem ``axyb-multi`` (A_i X_{x_i} = Y_{y_i} B_i): its conventions from named frames, the
validation of the indices and names, what the observation graph determines (refusals and
warnings), the residual table and the outliers by pair, the model's closed-form normal equations,
and the simulator."""

from __future__ import annotations

import numpy as np
import pytest
from multi_cells import cell, concatenate, observe, stations_about_one_axis

import handeye
from handeye import DegenerateDataError, InputError
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import random_flange_poses
from handeye.geometry.se3 import inverse, random_poses
from handeye.problems.axyb_multi import PROBLEM, errors_per_pose, simulate_cell
from handeye.problems.axyb_multi.geometry import AXYBMultiModel, poses_of

NOISE = NoiseModel(PROBLEM.study_noise)


def relative_error(sol, truth) -> float:
    """Largest pose error over both stacks: rotation (rad) or translation / 1000 mm."""
    errors = errors_per_pose(sol.unknowns, truth)
    return max(max(e["rotation"], e["translation"] / 1000.0) for e in errors.values())


# --------------------------------------------------------------------------- conventions

def test_fixed_cameras_watching_flange_markers_from_named_frames():
    """Eye to hand: B = T_cam_marker as solvePnP returns it; X_j = T_flange_marker_j, Y_k =
    T_base_cam_k (docs/conventions.md)."""
    rng = np.random.default_rng(5)
    T_flange_marker = random_poses(3, rng, 100.0)
    T_base_cam = random_poses(2, rng, 1500.0)
    T_base_flange = random_flange_poses(12, rng)
    station, marker, cam = np.meshgrid(np.arange(12), np.arange(3), np.arange(2), indexing="ij")
    station, marker, cam = station.ravel(), marker.ravel(), cam.ravel()
    T_cam_marker = inverse(T_base_cam[cam]) @ T_base_flange[station] @ T_flange_marker[marker]
    sol = handeye.solve("axyb-multi", A=T_base_flange[station], B=T_cam_marker, x_index=marker, y_index=cam,
                        x_names=["m0", "m1", "m2"], y_names=["left", "right"])
    assert sol.status is handeye.Status.OPTIMAL
    assert relative_error(sol, {"X": T_flange_marker, "Y": T_base_cam}) < 1e-9
    assert sol.X.shape == (3, 4, 4) and sol.Y.shape == (2, 4, 4)


def test_wrist_cameras_watching_boards_from_named_frames():
    """Eye in hand: B = T_board_cam, the inverse of solvePnP's board pose; X_j = T_flange_cam_j,
    Y_k = T_base_board_k."""
    rng = np.random.default_rng(6)
    T_flange_cam = random_poses(2, rng, 100.0)
    T_base_board = random_poses(3, rng, 800.0)
    T_base_flange = random_flange_poses(10, rng)
    station, cam, board = (a.ravel() for a in np.meshgrid(np.arange(10), np.arange(2), np.arange(3), indexing="ij"))
    T_cam_board = inverse(T_flange_cam[cam]) @ inverse(T_base_flange[station]) @ T_base_board[board]  # solvePnP's
    sol = handeye.solve("axyb-multi", A=T_base_flange[station], B=inverse(T_cam_board), x_index=cam, y_index=board)
    assert relative_error(sol, {"X": T_flange_cam, "Y": T_base_board}) < 1e-9


@pytest.mark.parametrize("setup", PROBLEM.setups)
def test_simulated_cells_follow_the_frames(setup):
    """The simulator's B_i is Y_k^-1 A_i X_j exactly without noise, for both setups, and the
    default cell (8 cameras, 16 markers) is recovered to 1e-9 by auto."""
    sim = simulate_cell(12, seed=2, setup=setup)
    d, t = sim.data, sim.truth
    expected = inverse(t["Y"][d["y_index"]]) @ d["A"] @ t["X"][d["x_index"]]
    assert np.abs(d["B"] - expected).max() < 1e-9 * 1000
    sol = handeye.solve("axyb-multi", **d)
    assert sol.status is handeye.Status.OPTIMAL
    assert relative_error(sol, t) < 1e-9


# --------------------------------------------------------------------------- validation

def test_indices_and_names_are_validated_in_one_line():
    raw, _ = cell(1)
    bad = {
        "x_index is required": {k: v for k, v in raw.items() if k != "x_index"},
        "must hold integers": {**raw, "x_index": raw["x_index"] + 0.5},
        "must be >= 0": {**raw, "y_index": raw["y_index"] - 1},
        "one index per observation": {**raw, "y_index": raw["y_index"][:-1]},
        "skips": {**raw, "y_index": np.where(raw["y_index"] == 1, 2, raw["y_index"])},
        "non-empty names": {**raw, "x_names": ["a"]},
        "given twice": {**raw, "y_names": ["c", "c", "d"]},
        "list of 2 names": {**raw, "x_names": "ab"},
    }
    for message, data in bad.items():
        with pytest.raises(InputError, match=message) as info:
            handeye.solve("axyb-multi", solver="kron-lstsq", **data)
        assert "\n" not in str(info.value)


def test_integral_float_indices_and_names_from_a_file_are_accepted():
    raw, truth = cell(2)
    data = PROBLEM.validate(**{**raw, "x_index": raw["x_index"].astype(float),
                               "x_names": np.array(["a", "b"]), "y_names": ["p", "q", "r"]})
    assert data.x_index.dtype == np.int64 and data.x_names == ("a", "b") and data.y_names == ("p", "q", "r")
    assert not data.A.flags.writeable and not data.x_index.flags.writeable


# --------------------------------------------------------------------------- what the graph determines

def test_separate_components_are_solved_separately_with_a_warning():
    rng = np.random.default_rng(3)
    first, truth1 = cell(3, nX=2, nY=2)
    X2, Y2 = random_poses(1, rng, 100.0), random_poses(1, rng, 1000.0)
    robot = random_flange_poses(8, rng)
    second = observe(robot, X2, Y2, np.zeros(8, dtype=int), np.zeros(8, dtype=int))
    second["x_index"] += 2
    second["y_index"] += 2
    sol = handeye.solve("axyb-multi", **concatenate(first, second))
    truth = {"X": np.concatenate([truth1["X"], X2]), "Y": np.concatenate([truth1["Y"], Y2])}
    assert relative_error(sol, truth) < 1e-9
    assert any("2 separate groups" in w and "solved separately" in w for w in sol.warnings), sol.warnings
    assert len(sol.diagnostics["data"]["components"]) == 2


def test_a_group_seen_at_one_station_is_refused_naming_it():
    rng = np.random.default_rng(4)
    first, truth = cell(4, nX=2, nY=2)
    X2, Y2 = random_poses(2, rng, 100.0), random_poses(1, rng, 1000.0)
    robot = np.repeat(random_flange_poses(1, rng), 2, axis=0)
    second = observe(robot, X2, Y2, np.array([0, 1]), np.zeros(2, dtype=int))
    second["x_index"] += 2
    second["y_index"] += 2
    data = concatenate(first, second)
    with pytest.raises(DegenerateDataError, match=r"X2, X3, Y2 .*one station only") as info:
        handeye.solve("axyb-multi", **data)
    assert "\n" not in str(info.value)


def test_a_cell_whose_robot_turns_about_one_axis_is_refused():
    rng = np.random.default_rng(7)
    X, Y = random_poses(2, rng, 100.0), random_poses(2, rng, 1000.0)
    robot = stations_about_one_axis(10, rng)
    s, j, k = (a.ravel() for a in np.meshgrid(np.arange(10), np.arange(2), np.arange(2), indexing="ij"))
    with pytest.raises(DegenerateDataError, match="rotate about one axis"):
        handeye.solve("axyb-multi", **observe(robot[s], X, Y, j, k))


def test_an_unknown_resting_on_one_observation_is_determined_with_a_warning():
    """One observation ties a further Y exactly (Y = A X B^-1) but leaves it unchecked."""
    rng = np.random.default_rng(8)
    raw, truth = cell(8, nX=2, nY=2)
    Y_new = random_poses(1, rng, 1000.0)
    extra = observe(raw["A"][:1], truth["X"], Y_new, np.array([0]), np.array([0]))
    extra["y_index"] += 2
    sol = handeye.solve("axyb-multi", **concatenate(raw, extra))
    assert relative_error(sol, {"X": truth["X"], "Y": np.concatenate([truth["Y"], Y_new])}) < 1e-9
    assert any("Y2 rests on a single observation" in w for w in sol.warnings), sol.warnings


def test_a_pair_undetermined_alone_is_determined_by_the_cell():
    """Camera 1 sees marker 1 only at stations that turn about one axis (degenerate for that
    pair alone, refused as axyb); marker 1 and camera 1 are also tied to well-spread pairs."""
    rng = np.random.default_rng(9)
    X, Y = random_poses(2, rng, 100.0), random_poses(2, rng, 1000.0)
    spread = random_flange_poses(12, rng)
    planar = stations_about_one_axis(8, rng)
    parts = [observe(spread, X, Y, np.full(12, j), np.full(12, k)) for j, k in ((0, 0), (1, 0), (0, 1))]
    parts.append(observe(planar, X, Y, np.ones(8, dtype=int), np.ones(8, dtype=int)))
    with pytest.raises(DegenerateDataError):
        handeye.solve("axyb", A=parts[-1]["A"], B=parts[-1]["B"])
    sol = handeye.solve("axyb-multi", **concatenate(*parts))
    assert relative_error(sol, {"X": X, "Y": Y}) < 1e-9


# --------------------------------------------------------------------------- tables, outliers, precision

def test_residual_table_per_pair_and_gross_observations_named():
    sim = simulate_cell(30, seed=11, noise=NOISE, gross=0.02)
    sol = handeye.solve("axyb-multi", **sim.data)
    data = PROBLEM.validate(**sim.data)
    table = PROBLEM.residual_table(data, sol.unknowns)
    assert sum(row["observations"] for row in table) == data.m
    assert len(table) == len(data.pair_index[0])
    assert all(row["X"].startswith("marker") and row["Y"].startswith("cam") for row in table)
    outliers = PROBLEM.outliers(data, sol.unknowns)
    assert sorted(o["index"] for o in outliers) == sorted(sim.gross.tolist())
    assert all(o["station"] == sim.station[o["index"]] for o in outliers)
    # auto left them out, named by pair and station in its warning
    assert sorted(o["index"] for o in sol.diagnostics["outliers"]) == sorted(sim.gross.tolist())
    first = sim.gross[0]
    name = f"{data.x_names[data.x_index[first]]} with {data.y_names[data.y_index[first]]} at station {sim.station[first]}"
    assert any(name in w for w in sol.warnings), sol.warnings


def test_one_sigma_per_unknown_covers_the_errors():
    """refine's 1-sigma per pose against the errors of its 24 poses over 5 seeds: z-scores
    (error / 1-sigma) with an RMS in [0.7, 1.4]."""
    z = []
    for seed in range(5):
        sim = simulate_cell(40, seed=seed, noise=NOISE)
        sol = handeye.solve("axyb-multi", solver="refine", **sim.data)
        std = sol.diagnostics["std"]
        errors = errors_per_pose(sol.unknowns, sim.truth)
        for key, e in errors.items():
            z += [e["rotation"] / std[key]["rotation"], e["translation"] / std[key]["translation"]]
    z = np.array(z)
    # std is the RMS of a pose's error norm (the root of its covariance block's trace)
    assert 0.7 < np.sqrt(np.mean(z**2)) < 1.4, np.sqrt(np.mean(z**2))


# --------------------------------------------------------------------------- model

@pytest.mark.parametrize("m_stations", (6, 40))
def test_normal_equations_from_sums_equal_those_of_the_jacobian(m_stations):
    sim = simulate_cell(m_stations, seed=4, noise=NOISE)
    data = PROBLEM.validate(**sim.data)
    model = AXYBMultiModel(data)
    poses = poses_of(sim.truth)
    e = model.residuals(poses)
    J = model.jacobian(poses, e)
    d = np.random.default_rng(0).uniform(0.5, 1.5, data.m)
    wr, wt = 2.0, 0.3
    w = np.array([wr] * 3 + [wt] * 3)
    Hw = np.einsum("nai,na,nbj,nab->ij", J, d[:, None] * w, J, np.broadcast_to(np.eye(6), (data.m, 6, 6)))
    g_rot = np.einsum("nai,n,na->i", J[:, :3], d * wr, e[:, :3])
    g_trans = np.einsum("nai,n,na->i", J[:, 3:], d * wt, e[:, 3:])
    s_rot, s_trans, s_H = model.normal_equations(poses, e, wr, wt, d)
    scale = np.abs(Hw).max()
    assert np.abs(s_H - Hw).max() < 1e-12 * scale
    assert np.abs(s_rot - g_rot).max() < 1e-12 * max(np.abs(g_rot).max(), 1.0)
    assert np.abs(s_trans - g_trans).max() < 1e-12 * max(np.abs(g_trans).max(), 1.0)


# --------------------------------------------------------------------------- simulator

def test_simulator_is_seeded_and_checks_its_options():
    a, b = simulate_cell(10, seed=1, noise=NOISE), simulate_cell(10, seed=1, noise=NOISE)
    assert all(np.array_equal(a.data[k], b.data[k]) for k in ("A", "B", "x_index", "y_index"))
    clean = simulate_cell(10, seed=1)
    assert np.array_equal(clean.data["x_index"], a.data["x_index"])  # same visibility at every noise level
    per_station = np.bincount(a.station * 8 + a.data["y_index"])
    assert per_station.min() >= 3 and per_station.max() <= 6  # each camera sees 3-6 markers
    gross = simulate_cell(10, seed=1, noise=NOISE, gross=0.1)
    assert len(gross.gross) == round(0.1 * len(gross.data["B"]))
    for options, message in (({"visible": (4, 2)}, "fewest <= most"), ({"gross": 1.0}, r"in \[0, 1\)"),
                             ({"cameras": 0}, "integer >= 1"), ({"setup": "both"}, "not one of")):
        with pytest.raises(InputError, match=message):
            simulate_cell(10, **options)


def test_errors_that_strike_one_camera_or_marker_are_not_left_out_as_gross():
    """A camera whose poses are in metres among millimetres, or two markers given one name,
    makes most of that camera's or marker's observations outliers: auto must not answer from
    what is left of them (a wrong pose with status optimal), but say which one is wrong; random
    gross observations (10% here) are still left out."""
    sim = simulate_cell(20, seed=1, noise=NOISE)
    d = sim.data
    B = d["B"].copy()
    B[d["y_index"] == 2, :3, 3] /= 1000.0
    metres = handeye.solve("axyb-multi", **{**d, "B": B})
    assert metres.status is not handeye.Status.OPTIMAL
    assert any("something wrong with cam2 itself" in w for w in metres.warnings), metres.warnings
    x = d["x_index"].copy()
    x[x == 3] = 4
    x[x > 3] -= 1
    merged = handeye.solve("axyb-multi", **{**d, "x_index": x, "x_names": [n for n in d["x_names"] if n != "marker3"]})
    assert merged.status is not handeye.Status.OPTIMAL
    assert any("something wrong with marker4 itself" in w for w in merged.warnings), merged.warnings
    gross = simulate_cell(20, seed=1, noise=NOISE, gross=0.1)
    sol = handeye.solve("axyb-multi", **gross.data)
    assert sol.status is handeye.Status.OPTIMAL and relative_error(sol, gross.truth) < 0.01
    assert sorted(o["index"] for o in sol.diagnostics["outliers"]) == sorted(gross.gross.tolist())


def test_the_self_checks_far_off_observations_are_named_by_camera_and_marker():
    """An answer that kept gross observations (outliers="keep") fails the self-check, which lists
    them by camera, marker and station, as auto's warning does."""
    from handeye.estimation.noise import NoiseModel
    from handeye.problems.axyb_multi import simulate_cell

    cell = simulate_cell(20, seed=1, gross=0.03, noise=NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)}))
    sol = handeye.solve("axyb-multi", **cell.data, outliers="keep")
    failure = next(f for f in sol.diagnostics["self_check"]["failures"] if "far off the others" in f)
    first = int(sorted(cell.gross)[0])
    assert f"no. {first + 1} (index {first}: {cell.data['x_names'][cell.data['x_index'][first]]} with " in failure


def test_a_pair_off_as_a_whole_is_named_as_the_pair_not_its_camera():
    """Every observation of one marker-camera pair 20 deg off (a marker misread by one camera, as
    one pair of a real rig of 8 cameras and 16 tags is): auto leaves them out and names that pair,
    not the camera, and the others stay as accurate as without it."""
    from handeye.geometry.se3 import make_pose, so3_exp

    sim = simulate_cell(20, seed=1, noise=NOISE)
    d = dict(sim.data)
    pair = (d["x_index"] == 1) & (d["y_index"] == 2)
    B = d["B"].copy()
    B[pair] = B[pair] @ make_pose(so3_exp(np.array([0.35, 0.0, 0.0])), np.zeros(3))
    sol = handeye.solve("axyb-multi", **{**d, "B": B})
    clean = handeye.solve("axyb-multi", **d)
    name = f"{d['x_names'][1]} with {d['y_names'][2]}"
    named = [w for w in sol.warnings if f"every observation of {name} (all {int(pair.sum())})" in w]
    assert len(named) == 1 and "not its camera or marker" in named[0], sol.warnings[:2]
    assert not any("something wrong with" in w for w in sol.warnings)
    assert relative_error(sol, sim.truth) < 2 * relative_error(clean, sim.truth) + 1e-3
