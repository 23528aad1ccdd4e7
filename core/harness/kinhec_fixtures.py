"""KinHEC sequences as regression fixtures: `export_fixture` writes one sequence's keyframe data,
exactly as KinHEC's benchmark protocol hands them to the solvers, to a small compressed NPZ.

Why: the fixtures of tests/data/kinhec/ (docs/kinhec.md, "Regression fixtures") let handeye's
tests solve KinHEC sequences without KinHEC installed and without regenerating its dataset, and
the truth and KinHEC's reference errors stored beside the data give them something to compare
against. Needs KinHEC (``pip install "handeye[kinhec]"``), as the benchmark run does.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.harness.kinhec import import_kinhec
from handeye.harness.kinhec_report import REFERENCE


def export_fixture(data_dir: str | Path, sequence_id: str, path: str | Path, sync: str = "oracle",
                   extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Save sequence `sequence_id` of the KinHEC dataset `data_dir` as the protocol hands it to the
    solvers (the absolute keyframe poses A, B in metres) with its truth (X_true, Y_true), its
    identity (tier, seeds, track, robot, ...) and the X errors of KinHEC's shah+lm on it (KinHEC's
    code: the same whatever handeye's version), plus the fields of `extra` (e.g. what a benchmark
    run recorded for handeye's solvers), to the compressed NPZ `path`; return the saved fields.

    sync: for an asynchronous sequence, pair the streams at the true clock offset (``oracle``) or
    at the one KinHEC estimates from them (``estimated``, its ``estimate_time_offset``), as the
    protocol's two modes; a synchronous sequence is paired row by row either way. Uses
    ``kinhec.benchmark._keyframe_data``: KinHEC's own keyframe selection, so the fixture holds
    exactly what `handeye.harness.kinhec.adaptor` gets.
    """
    benchmark = import_kinhec()
    from kinhec.io import load_sequence
    from kinhec.metrics import calibration_errors

    if sync not in ("oracle", "estimated"):
        raise InputError(f"sync must be 'oracle' or 'estimated', got {sync!r}")
    root = Path(data_dir)
    seq = load_sequence(root, sequence_id)
    offset = None
    if not seq.synchronous:
        offset = seq.time_offset
        if sync == "estimated":
            from kinhec.solvers import estimate_time_offset

            offset, _ = estimate_time_offset(seq.robot.t, seq.robot.T_base_ee_meas, seq.camera.t,
                                             seq.camera.T_cam_target_meas)
    else:
        sync = "oracle"
    data = benchmark._keyframe_data(seq, offset)
    if data is None:
        raise InputError(f"{sequence_id}: fewer than 3 paired frames; KinHEC's protocol solves nothing on it")
    ref = calibration_errors(benchmark.SOLVERS[REFERENCE](data, np.random.default_rng(0))["X"], seq.X)
    info = json.loads((root / "generation_info.json").read_text(encoding="utf-8"))
    m = seq.manifest
    fields: dict[str, Any] = {
        "A": data[0], "B": data[1], "X_true": seq.X, "Y_true": seq.Y, "units": "m",
        "setup": "eye-in-hand" if seq.eye_in_hand else "eye-to-hand",
        "sequence_id": sequence_id, "track": m["track"], "level": m["level"], "robot": m["robot"],
        "configuration": m["configuration"], "family": m["family"],
        "eval_sync": sync, "time_offset_s": float(m["time_offset_s"]),
        "time_offset_used_s": math.nan if offset is None else float(offset),
        "kinhec_version": str(info.get("generator_version", "")), "tier": str(info.get("tier", "")),
        "global_seed": int(info.get("global_seed", -1)), "seed": int(seq.config.seed) if seq.config else -1,
        "ref_solver": REFERENCE, "ref_X_rot_deg": ref["X_rot_err_deg"], "ref_X_trans_mm": ref["X_trans_err_mm"],
        **dict(extra or {}),
    }
    np.savez_compressed(path, **{k: np.asarray(v) for k, v in fields.items()})
    return fields
