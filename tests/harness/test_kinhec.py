"""``handeye bench --kinhec``: handeye's solvers registered into KinHEC's benchmark protocol
(handeye.harness.kinhec, docs/kinhec.md).

KinHEC is an optional extra (``pip install "handeye[kinhec]"``), so the CLI path without it and the
registration / adaptor logic are tested against a FAKE minimal ``kinhec`` module (a SOLVERS dict and
a run_benchmark that calls the registered solvers on sequences from handeye's own simulator, the way
KinHEC's protocol does); one more test runs the real protocol on two generated smoke sequences when
KinHEC is installed.
"""

from __future__ import annotations

import csv
import importlib.util
import math
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse
from handeye.harness import kinhec as _kinhec
from handeye.problems.axyb import PROBLEM
from tests.conftest import run_cli


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _angle_deg(R1: np.ndarray, R2: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R1.T @ R2) - 1) / 2, -1, 1))))


def _sequence(kind: str) -> dict:
    """One fake KinHEC sequence: keyframe data as KinHEC's protocol hands it to the solvers
    (A_abs, B_abs, consecutive A_rel, B_rel) and the truth. "good": handeye's simulator with noise;
    "translations": a robot that never rotates (every solver must refuse it)."""
    data, truth = PROBLEM.simulate(pairs=15, seed=3, noise=NoiseModel.on(("A", "B"), 0.001, 0.1))
    A, B = np.asarray(data["A"]), np.asarray(data["B"])
    if kind == "translations":
        A = A.copy()
        A[:, :3, :3] = np.eye(3)
        B = inverse(truth["Y"]) @ A @ truth["X"]
    A_rel = inverse(A[:-1]) @ A[1:]
    B_rel = inverse(B[:-1]) @ B[1:]
    sid = "noise-000000" if kind == "good" else "motion-000000"
    return {"id": sid, "track": sid.split("-")[0], "data": (A, B, A_rel, B_rel), "X": truth["X"], "Y": truth["Y"]}


def make_fake_kinhec() -> tuple[types.ModuleType, types.ModuleType, dict]:
    """A minimal ``kinhec`` / ``kinhec.benchmark`` pair with KinHEC's extension point (SOLVERS,
    SOLVER_DOCS), an evaluate_sequence that calls the solvers and records failures as rows, and a
    run_benchmark over two simulated sequences. `seen` records what the run saw."""
    kinhec = types.ModuleType("kinhec")
    kinhec.__version__ = "1.1.0"
    bm = types.ModuleType("kinhec.benchmark")
    kinhec.benchmark = bm
    seen: dict = {}

    def shah_lm(data, rng):
        import handeye

        sol = handeye.solve("axyb", A=data[0], B=data[1], solver="shah")
        return {"X": np.array(sol.X), "Y": np.array(sol.Y)}

    bm.SOLVERS = {"shah+lm": shah_lm, "park_martin": lambda data, rng: {"X": np.eye(4)}}
    bm.SOLVER_DOCS = {"shah+lm": "Shah + LM", "park_martin": "Park & Martin"}

    def evaluate_sequence(seq, solver_names, sync="oracle", rng=None):
        rows = []
        for name in solver_names:
            row = {"sequence_id": seq["id"], "track": seq["track"], "level": "x=1", "robot": "sim",
                   "configuration": "eye_in_hand", "eval_sync": sync, "solver": name, "ok": False, "error": "",
                   "runtime_ms": math.nan, "n_motions": len(seq["data"][2])}
            try:
                t0 = time.perf_counter()
                out = bm.SOLVERS[name](seq["data"], rng)
                row["runtime_ms"] = 1000 * (time.perf_counter() - t0)
                row["X_rot_err_deg"] = _angle_deg(out["X"][:3, :3], seq["X"][:3, :3])
                row["X_trans_err_mm"] = float(np.linalg.norm(out["X"][:3, 3] - seq["X"][:3, 3]))
                row["ok"] = True
            except Exception as e:  # noqa: BLE001 - as KinHEC: a failure is a row
                row["error"] = f"{type(e).__name__}: {e}"
            rows.append(row)
        return rows

    def run_benchmark(root, out_dir=None, solver_names=None, tracks=None, max_sequences=None, sync_modes=None,
                      progress=True, workers=1):
        seen.update(solvers=list(bm.SOLVERS), names=list(solver_names), docs=dict(bm.SOLVER_DOCS),
                    wrapped=bm.evaluate_sequence is not evaluate_sequence, tracks=tracks, workers=workers)
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        rows = []
        for kind in ("good", "translations"):
            seq = _sequence(kind)
            if tracks is None or seq["track"] in tracks:
                rows += bm.evaluate_sequence(seq, solver_names, rng=np.random.default_rng(0))
        (out / "results.csv").write_text("fake\n")
        (out / "leaderboard.md").write_text("# fake\n")
        return rows  # a list of rows (the real one returns a DataFrame): both are read

    bm.evaluate_sequence = evaluate_sequence
    bm.run_benchmark = run_benchmark
    return kinhec, bm, seen


@pytest.fixture
def fake_kinhec(monkeypatch, tmp_path):
    kinhec, bm, seen = make_fake_kinhec()
    monkeypatch.setitem(sys.modules, "kinhec", kinhec)
    monkeypatch.setitem(sys.modules, "kinhec.benchmark", bm)
    data = tmp_path / "data"
    data.mkdir()
    (data / "sequences.parquet").write_bytes(b"")  # what marks a KinHEC dataset folder
    (data / "sequences.csv").write_text("sequence_id,track\nnoise-000000,noise\nmotion-000000,motion\n")
    return bm, seen, data


def test_without_kinhec_exits_2_naming_the_extra(capsys, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "kinhec", None)  # import kinhec raises ImportError
    monkeypatch.setitem(sys.modules, "kinhec.benchmark", None)
    code, out, err = run_cli(capsys, "bench", "--kinhec", tmp_path)
    assert code == 2 and out == ""
    assert err.startswith("handeye: error: ") and err.count("\n") == 1
    assert 'pip install "handeye[kinhec]"' in err


def test_kinhec_flags_need_kinhec_and_exclude_the_timing_flags(capsys, fake_kinhec):
    _, _, data = fake_kinhec
    code, _, err = run_cli(capsys, "bench", "--tracks", "noise")
    assert code == 2 and "--tracks applies to handeye bench --kinhec" in err
    code, _, err = run_cli(capsys, "bench", "--kinhec", data, "--pairs", "16")
    assert code == 2 and "--pairs does not apply to --kinhec" in err
    code, _, err = run_cli(capsys, "bench", "--kinhec", data.parent)
    assert code == 2 and "not a KinHEC dataset folder" in err
    code, _, err = run_cli(capsys, "bench", "--kinhec", data, "--tracks", "nosuch")
    assert code == 2 and "holds no track 'nosuch'" in err and "motion, noise" in err
    code, _, err = run_cli(capsys, "bench", "--kinhec", data, "--solvers", "handeye:nosuch")
    assert code == 2 and "'handeye:nosuch' is not a KinHEC solver" in err


def test_old_kinhec_is_refused(capsys, fake_kinhec):
    _, _, data = fake_kinhec
    sys.modules["kinhec"].__version__ = "1.0.3"
    code, _, err = run_cli(capsys, "bench", "--kinhec", data)
    assert code == 2 and "kinhec 1.0.3 is older than 1.1" in err and "handeye[kinhec]" in err


def test_registers_every_pose_solver_runs_the_protocol_and_restores_kinhec(capsys, fake_kinhec):
    bm, seen, data = fake_kinhec
    before_solvers, before_docs, before_eval = dict(bm.SOLVERS), dict(bm.SOLVER_DOCS), bm.evaluate_sequence
    out_dir = data / "out"
    code, out, err = run_cli(capsys, "bench", "--kinhec", data, "--kinhec-out", out_dir, "--no-progress")
    assert code == 0, err

    # registered during the run: axyb solvers as handeye:NAME (auto first), axxb ones as handeye-axxb:NAME,
    # beside the references; solvers needing more than poses (reprojection: images) left out
    from handeye.host.registry import get_registry

    registry = get_registry()
    axyb = {f"handeye:{n}" for n in registry.solver_names("axyb")} - {"handeye:reprojection"}
    axxb = {f"handeye-axxb:{n}" for n in registry.solver_names("axxb")}
    assert axyb | axxb <= set(seen["names"]) and "shah+lm" in seen["names"] and "park_martin" in seen["names"]
    assert "handeye:reprojection" not in seen["solvers"] and "handeye:reprojection" in out
    assert next(n for n in seen["solvers"] if n.startswith("handeye:")) == "handeye:auto"
    assert "handeye:auto" in seen["docs"] and seen["wrapped"] and seen["workers"] == 1
    # ... and removed afterwards
    assert bm.SOLVERS == before_solvers and bm.SOLVER_DOCS == before_docs and bm.evaluate_sequence is before_eval

    # head-to-head: auto vs shah+lm per sequence, with auto's status; a refused solve is recorded as raised
    pairs = {p["sequence_id"]: p for p in read_csv(out_dir / "handeye_head_to_head.csv")}
    good, bad = pairs["noise-000000"], pairs["motion-000000"]
    assert good["auto_status"] == "optimal" and good["auto_ok"] == "True"
    assert float(good["auto_X_rot_deg"]) < 0.5 and float(good["trans_ratio"]) > 0 and float(good["time_ratio"]) > 0
    assert bad["auto_status"] == "raised" and bad["auto_ok"] == "False" and "DegenerateDataError" in bad["auto_note"]
    # per-track summary: every solver, success and usable rates
    tracks = read_csv(out_dir / "handeye_tracks.csv")
    noise = {r["solver"]: r for r in tracks if r["track"] == "noise"}
    assert axyb | axxb | {"shah+lm", "park_martin"} <= set(noise)
    assert noise["handeye:auto"]["success_rate"] == "1.0" and noise["handeye:auto"]["usable_rate"] == "1.0"
    assert noise["park_martin"]["usable_rate"] == ""  # KinHEC's references have no status
    motion = {r["solver"]: r for r in tracks if r["track"] == "motion"}
    assert motion["handeye:auto"]["success_rate"] == "0.0"
    for name in _kinhec.HANDEYE_FILES:
        assert (out_dir / name).is_file()
    assert "handeye:auto against the best KinHEC reference" in out and "| noise | oracle | 1 | 100% |" in out

    # results are not overwritten without --force
    code, _, err = run_cli(capsys, "bench", "--kinhec", data, "--kinhec-out", out_dir, "--no-progress")
    assert code == 2 and "--force" in err
    code, _, _ = run_cli(capsys, "bench", "--kinhec", data, "--kinhec-out", out_dir, "--no-progress", "--force",
                         "--solvers", "handeye-axxb:park", "--tracks", "noise")
    assert code == 0
    assert seen["tracks"] == ["noise"] and set(seen["names"]) == {"handeye:auto", "shah+lm", "handeye-axxb:park"}


def test_adaptor_passes_poses_or_motions_and_keeps_the_status():
    seq = _sequence("good")
    entries, _ = _kinhec.handeye_entries(probe=False)
    by = {e.name: e for e in entries}
    axyb = _kinhec.adaptor(by["handeye:shah"])(seq["data"], None)
    assert axyb["Y"].shape == (4, 4) and _angle_deg(axyb["X"][:3, :3], seq["X"][:3, :3]) < 0.5
    axxb = _kinhec.adaptor(by["handeye-axxb:park"])(seq["data"], None)
    assert axxb["Y"] is None and _angle_deg(axxb["X"][:3, :3], seq["X"][:3, :3]) < 0.5
    assert _kinhec._OUTCOMES["handeye-axxb:park"]["handeye_status"] == "optimal"
    with pytest.raises(Exception, match="rotate about fewer than two"):
        _kinhec.adaptor(by["handeye:auto"])(_sequence("translations")["data"], None)
    assert _kinhec._OUTCOMES["handeye:auto"]["handeye_status"] == "raised"
    _kinhec._OUTCOMES.clear()


def test_scale_aware_variants_solve_a_camera_known_up_to_scale():
    """Every solver that takes camera_scale='unknown' is registered twice, the second time as
    NAME+scale with the scale unknown (like KinHEC's andreff_scale): on poses whose camera
    translations are 3x too large it finds X (the data's noise: 0.001 rad / 0.1 mm)."""
    from handeye.host.registry import get_registry

    entries, _ = _kinhec.handeye_entries(probe=False)
    by = {e.name: e for e in entries}
    registry = get_registry()
    for problem, prefix in (("axyb", "handeye:"), ("axxb", "handeye-axxb:")):
        scale_aware = {n for n in registry.solver_names(problem) if registry.solver(n, problem).camera_scale_mode}
        assert scale_aware and {f"{prefix}{n}+scale" for n in scale_aware} <= set(by)
        assert all(by[f"{prefix}{n}+scale"].camera_scale == "unknown" for n in scale_aware)
    seq = _sequence("good")
    A, B, A_rel, B_rel = (np.array(x) for x in seq["data"])
    for T in (B, B_rel):
        T[:, :3, 3] *= 3.0
    for name in ("handeye:auto+scale", "handeye-axxb:auto+scale"):
        X = _kinhec.adaptor(by[name])((A, B, A_rel, B_rel), None)["X"]
        assert _angle_deg(X[:3, :3], seq["X"][:3, :3]) < 0.2, name
        assert np.linalg.norm(X[:3, 3] - seq["X"][:3, 3]) < 0.02 * np.linalg.norm(seq["X"][:3, 3]), name
    _kinhec._OUTCOMES.clear()


@pytest.mark.skipif(importlib.util.find_spec("kinhec") is None, reason='kinhec not installed (pip install "handeye[kinhec]")')
def test_real_kinhec_protocol_on_two_smoke_sequences(capsys, tmp_path):
    import kinhec
    from kinhec.pipeline import generate_dataset

    # the tier by path: kinhec reads a folder named like the tier in the working directory as the tier
    tier = Path(kinhec.__file__).parent / "configs" / "smoke.yaml"
    t0 = time.perf_counter()
    generate_dataset(str(tier), tmp_path / "data", tracks=["noise"], limit=2, work_dir=tmp_path / "work",
                     write_card=False, progress=False)
    if time.perf_counter() - t0 > 20:
        pytest.skip("generating 2 KinHEC sequences took more than 20 s on this machine")
    code, _, err = run_cli(capsys, "bench", "--kinhec", tmp_path / "data", "--kinhec-out", tmp_path / "out",
                           "--no-progress", "--solvers", "handeye,kinhec,handeye-axxb:park")
    assert code == 0, err
    results = read_csv(tmp_path / "out" / "results.csv")
    assert {r["sequence_id"] for r in results} == {"noise-000000", "noise-000001"}
    auto = [r for r in results if r["solver"] == "handeye:auto"]
    assert len(auto) == 2 and all(r["ok"] == "True" and r["handeye_status"] == "optimal" for r in auto)
    pairs = read_csv(tmp_path / "out" / "handeye_head_to_head.csv")
    assert len(pairs) == 2
    for p in pairs:  # auto is KinHEC's shah+lm's equal on these (both are the maximum-likelihood X, Y)
        assert float(p["auto_X_trans_mm"]) < 1.5 * float(p["shah_lm_X_trans_mm"]) + 0.5
    assert "handeye:auto" in (tmp_path / "out" / "protocol.json").read_text()
    assert "handeye-axxb:park" in (tmp_path / "out" / "leaderboard.md").read_text()
