"""handeye.io: NPZ/JSON round trips (exact), metadata, and clear errors for bad files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from handeye.errors import InputError
from handeye.io import load_data, load_file, save_data, supported_extensions
from handeye.noise import NoiseModel
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
