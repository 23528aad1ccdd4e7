"""handeye.io: NPZ/JSON round trips (exact), metadata, and clear errors for bad files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.io.data_files import load_data, load_file, save_data, supported_extensions
from handeye.problems.axyb import PROBLEM


@pytest.fixture(scope="module")
def simulated():
    return PROBLEM.simulate(pairs=6, seed=3, noise=NoiseModel.on("B", 0.01, 0.5))


@pytest.mark.parametrize("ext", [".npz", ".json"])
def test_roundtrip_is_exact_with_truth_and_metadata(tmp_path, simulated, ext):
    data, truth = simulated
    before = {k: v.copy() for k, v in data.items()}
    path = save_data(tmp_path / f"d{ext}", data, truth, metadata={"units": "mm", "setup": "eye-to-hand"})
    loaded = load_file(path)
    for k in ("A", "B"):
        np.testing.assert_array_equal(loaded.data[k], data[k])
        np.testing.assert_array_equal(data[k], before[k])  # input untouched
    for k in ("X", "Y"):
        np.testing.assert_array_equal(loaded.truth[k], truth[k])
    assert loaded.metadata == {"units": "mm", "setup": "eye-to-hand"}
    assert loaded.data["A"].shape == (6, 4, 4) and loaded.truth["X"].shape == (4, 4)


@pytest.mark.parametrize("ext", [".npz", ".json"])
def test_roundtrip_without_truth(tmp_path, simulated, ext):
    data, _ = simulated
    path = save_data(tmp_path / f"d{ext}", data)
    loaded, truth = load_data(path)
    assert truth is None
    np.testing.assert_array_equal(loaded["B"], data["B"])


def test_npz_written_under_the_given_name(tmp_path, simulated):
    path = save_data(tmp_path / "data.NPZ", simulated[0])
    assert path.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["data.NPZ"]


def test_json_layout_documented_in_formats_md(tmp_path, simulated):
    data, truth = simulated
    path = save_data(tmp_path / "d.json", data, truth, metadata={"units": "mm"})
    obj = json.loads(path.read_text())
    assert set(obj) == {"A", "B", "truth", "units"}
    assert np.shape(obj["A"]) == (6, 4, 4) and np.shape(obj["truth"]["X"]) == (4, 4)


def test_hand_written_json_is_read(tmp_path):
    eye = np.eye(4).tolist()
    rot = [[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]
    (tmp_path / "h.json").write_text(json.dumps({"A": [eye, rot, eye], "B": [eye, rot, rot], "units": "m"}))
    data, truth = load_data(tmp_path / "h.json")
    assert truth is None
    np.testing.assert_array_equal(data["A"][1], rot)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_data(tmp_path / "nope.json")


def test_unsupported_extension_lists_supported(tmp_path):
    (tmp_path / "d.csv").write_text("1,2,3\n")
    with pytest.raises(InputError, match=r"unsupported file extension '\.csv'.*\.json, \.npz"):
        load_data(tmp_path / "d.csv")
    with pytest.raises(InputError, match="unsupported"):
        save_data(tmp_path / "d.yaml", {"A": np.eye(4)[None], "B": np.eye(4)[None]})
    assert supported_extensions() == [".json", ".npz"]


def test_bad_json_names_line_and_column(tmp_path):
    (tmp_path / "d.json").write_text('{"A": [1, 2,\n  }')
    with pytest.raises(InputError, match=r"invalid JSON at line 2"):
        load_data(tmp_path / "d.json")


def test_json_not_an_object(tmp_path):
    (tmp_path / "d.json").write_text("[1, 2, 3]")
    with pytest.raises(InputError, match="expected a JSON object"):
        load_data(tmp_path / "d.json")


def test_missing_key_names_it_and_expected_keys(tmp_path, simulated):
    data, _ = simulated
    (tmp_path / "d.json").write_text(json.dumps({"A": data["A"].tolist(), "b": data["B"].tolist()}))
    with pytest.raises(InputError, match=r"missing data key\(s\) \['B'\].*found \['A', 'b'\]"):
        load_data(tmp_path / "d.json")
    np.savez(tmp_path / "d.npz", A=data["A"])
    with pytest.raises(InputError, match=r"missing data key\(s\) \['B'\].*X_true"):
        load_data(tmp_path / "d.npz")


def test_unexpected_keys_and_bad_metadata(tmp_path, simulated):
    data, _ = simulated
    base = {"A": data["A"].tolist(), "B": data["B"].tolist()}
    cases = [({**base, "unit": "mm"}, "unexpected key"),
             ({**base, "units": "furlong"}, r"units must be one of \['m', 'cm', 'mm'\]"),
             ({**base, "setup": "hand-in-eye"}, "setup must be one of"),
             ({**base, "truth": {"X": np.eye(4).tolist()}}, r"missing \['Y'\]"),
             ({**base, "truth": {"X": np.eye(4).tolist(), "Y": np.eye(3).tolist()}}, "one 4x4 pose"),
             ({**base, "C": base["A"]}, r"unexpected data key\(s\) \['C'\]")]
    for obj, message in cases:
        (tmp_path / "d.json").write_text(json.dumps(obj))
        with pytest.raises(InputError, match=message):
            load_data(tmp_path / "d.json")


def test_poses_are_validated_with_file_name(tmp_path, simulated):
    data, _ = simulated
    A = data["A"].copy()
    A[2, :3, :3] *= 1.1  # not a rotation
    path = tmp_path / "d.npz"
    np.savez(path, A=A, B=data["B"])
    with pytest.raises(InputError, match=r"d\.npz.*A: rotation block is not orthonormal.*pose\(s\) 2"):
        load_data(path)
    np.savez(path, A=data["A"][:, :3, :], B=data["B"])
    with pytest.raises(InputError, match=r"shape \(m, 4, 4\)"):
        load_data(path)


def test_not_an_npz(tmp_path):
    (tmp_path / "d.npz").write_bytes(b"this is not a zip file")
    with pytest.raises(InputError, match="not a readable NPZ"):
        load_data(tmp_path / "d.npz")


def test_save_validates_before_writing(tmp_path, simulated):
    data, _ = simulated
    bad = {"A": data["A"], "B": np.full_like(data["B"], np.nan)}
    with pytest.raises(InputError, match="NaN"):
        save_data(tmp_path / "d.json", bad)
    assert not (tmp_path / "d.json").exists()


# --- problem axxb: relative motions or the stations' absolute poses ------------------------------

@pytest.fixture(scope="module")
def stations():
    """8 noise-free eye-in-hand stations: robot poses T_base_flange, camera poses T_cam_target, X."""
    from handeye.geometry.se3 import inverse
    from handeye.problems.axxb import simulate_stations

    poses, truth = simulate_stations(8, seed=5)
    return {"robot_poses": poses["A"], "camera_poses": inverse(poses["B"])}, {"X": truth["X"]}


@pytest.mark.parametrize("ext", [".npz", ".json"])
def test_axxb_absolute_poses_round_trip_and_become_motions(tmp_path, stations, ext):
    from handeye.problems.axxb import motions

    poses, truth = stations
    path = save_data(tmp_path / f"s{ext}", poses, truth, problem="axxb",
                     metadata={"setup": "eye-in-hand", "units": "mm"})
    loaded = load_file(path, "axxb")
    assert loaded.metadata == {"setup": "eye-in-hand", "units": "mm", "pairing": "all"}
    for name in ("robot_poses", "camera_poses"):
        np.testing.assert_array_equal(loaded.poses[name], poses[name])
    expected = motions(poses["robot_poses"], poses["camera_poses"], "eye-in-hand", "all")
    for name in ("A", "B"):
        np.testing.assert_array_equal(loaded.data[name], expected[name])
    X = loaded.truth["X"]
    assert set(loaded.truth) == {"X"}
    assert np.abs(loaded.data["A"] @ X - X @ loaded.data["B"]).max() < 1e-9  # A_i X = X B_i
    data, _ = load_data(path, "axxb", pairing="consecutive")  # the caller's pairing wins
    assert data["A"].shape == (7, 4, 4)
    raw = json.loads(path.read_text()) if ext == ".json" else dict(np.load(path))
    assert set(raw) >= {"robot_poses", "camera_poses", "setup", "pairing"} and "A" not in raw


def test_axxb_setup_from_the_caller_and_from_poses(stations):
    from handeye.io.data_files import from_poses

    poses, _ = stations
    hand = from_poses(poses["robot_poses"], poses["camera_poses"], "axxb", setup="eye-in-hand", pairing="consecutive")
    fixed = from_poses(poses["robot_poses"], poses["camera_poses"], "axxb", setup="eye-to-hand")
    assert hand.metadata == {"setup": "eye-in-hand", "pairing": "consecutive"} and len(hand.data["A"]) == 7
    assert fixed.metadata["pairing"] == "all" and len(fixed.data["A"]) == 28
    assert not np.allclose(hand.data["A"][0], fixed.data["A"][0])  # eye-to-hand inverts the robot poses
    pairs = from_poses(poses["robot_poses"], poses["camera_poses"], "axyb", setup="eye-in-hand")
    assert len(pairs.data["A"]) == 8 and pairs.metadata == {"setup": "eye-in-hand"}


def test_axxb_motion_file_round_trip(tmp_path):
    from handeye.problems.axxb import PROBLEM as AXXB

    data, truth = AXXB.simulate(pairs=5, seed=2)
    path = save_data(tmp_path / "m.json", data, truth, problem="axxb", metadata={"pairing": "all"})
    loaded = load_file(path, "axxb")
    assert loaded.poses is None and loaded.metadata == {"pairing": "all"}
    np.testing.assert_array_equal(loaded.data["B"], data["B"])
    np.testing.assert_array_equal(loaded.truth["X"], truth["X"])


def test_axxb_bad_files_say_what_is_wrong(tmp_path, stations):
    poses, _ = stations
    robot, camera = poses["robot_poses"].tolist(), poses["camera_poses"].tolist()
    base = {"robot_poses": robot, "camera_poses": camera, "setup": "eye-in-hand"}
    cases = [
        ({"robot_poses": robot, "setup": "eye-in-hand"}, r"need both robot_poses and camera_poses; missing \['camera_poses'\]"),
        ({**base, "A": robot[1:], "B": camera[1:]}, r"both data field\(s\) \['A', 'B'\] and absolute poses"),
        ({**base, "setup": "hand-on-eye"}, r"setup must be one of \['eye-in-hand', 'eye-to-hand'\]"),
        ({**base, "pairing": "every"}, r"pairing must be one of \['consecutive', 'all'\]"),
        ({**base, "camera_poses": camera[:-1]}, r"same length.*'robot_poses': 8, 'camera_poses': 7"),
        ({k: v for k, v in base.items() if k != "setup"}, r"need the setup \(eye-in-hand or eye-to-hand\)"),
        ({"A": robot, "B": camera, "truth": {"X": np.eye(4).tolist(), "Y": np.eye(4).tolist()}},
         r"truth must hold exactly the unknowns \['X'\]"),
        ({"A": robot}, r"missing data key\(s\) \['B'\].*or the absolute poses robot_poses, camera_poses"),
    ]
    for obj, message in cases:
        (tmp_path / "d.json").write_text(json.dumps(obj))
        with pytest.raises(InputError, match=message):
            load_data(tmp_path / "d.json", "axxb")
    (tmp_path / "d.json").write_text(json.dumps({**base, "setup": "eye-to-hand"}))
    with pytest.raises(InputError, match="setup must be one of"):
        load_data(tmp_path / "d.json", "axxb", setup="upside-down")
    (tmp_path / "m.json").write_text(json.dumps({"A": robot, "B": camera}))
    with pytest.raises(InputError, match="pairing applies to a file of absolute poses"):
        load_data(tmp_path / "m.json", "axxb", pairing="all")
    (tmp_path / "y.json").write_text(json.dumps({"A": robot, "B": camera, "robot_poses": robot}))
    with pytest.raises(InputError, match=r"both data field\(s\) \['A', 'B'\] and absolute poses"):
        load_data(tmp_path / "y.json", "axyb")
    (tmp_path / "s.json").write_text(json.dumps(base))
    with pytest.raises(InputError, match="pairing applies to problems that form motions"):
        load_data(tmp_path / "s.json", "axyb", pairing="all")
    with pytest.raises(InputError, match="need the setup"):
        save_data(tmp_path / "s.npz", poses, problem="axxb")


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_one_file_of_stations_serves_axyb_and_axxb_with_the_cells_truth(tmp_path, stations, setup):
    """A file of absolute poses reads as AX=YB pairs (A = robot poses, B = camera poses^-1
    eye-in-hand, as they are eye-to-hand) and as AX=XB motions; its truth, the cell's X and Y of
    AX=YB, gives axxb's X = X eye-in-hand and Y eye-to-hand (docs/conventions.md)."""
    from handeye.geometry.se3 import inverse

    poses, _ = stations
    X, Y = np.eye(4), np.eye(4)
    X[:3, 3], Y[:3, 3] = (1.0, 2.0, 3.0), (4.0, 5.0, 6.0)
    path = save_data(tmp_path / "s.json", poses, {"X": X, "Y": Y}, metadata={"setup": setup})
    pairs = load_file(path, "axyb")
    np.testing.assert_array_equal(pairs.data["A"], poses["robot_poses"])
    expected_B = inverse(poses["camera_poses"]) if setup == "eye-in-hand" else poses["camera_poses"]
    np.testing.assert_allclose(pairs.data["B"], expected_B)
    assert set(pairs.truth) == {"X", "Y"} and "pairing" not in pairs.metadata
    motions = load_file(path, "axxb")
    assert len(motions.data["A"]) == 28 and motions.metadata["pairing"] == "all"
    np.testing.assert_array_equal(motions.truth["X"], X if setup == "eye-in-hand" else Y)
