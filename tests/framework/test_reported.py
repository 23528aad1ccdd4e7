"""What core reads of a solver's diagnostics (handeye.framework.reported): typed, with defaults
for what a solver leaves out, auto's entries under ``refine`` read too."""

from __future__ import annotations

import handeye
from handeye.framework.reported import Reported


def test_absent_entries_take_their_defaults_and_no_two_readings_share_a_dict():
    first, second = Reported.of({}), Reported.of({})
    assert first == Reported() and first.outliers is None and first.left_out == set()
    assert first.fitted_to == "poses" and first.held_out_best is None and not first.scales_fitted
    first.camera_scales["cam0"] = 2.0  # a caller's change stays its own
    assert second.camera_scales == {} and Reported.of({}).camera_scales == {}


def test_entries_are_read_typed_and_auto_s_refine_entries_count():
    d = {"warnings": ["w"], "outliers": [{"index": 3, "rotation_deg": 1.0}, "junk"], "held_out": {"best": True},
         "drift_held_out": {"drift_agrees": True}, "formulation": "stations", "camera_scale": 1.002,
         "camera_scale_std": 1e-4, "refine": {"std": {"X": {"rotation": 1e-3, "translation": 0.2}},
                                               "noise_model": "sources"}}
    r = Reported.of(d)
    assert r.warnings == ("w",) and r.left_out == {3} and len(r.outliers) == 1
    assert r.held_out_best == {"best": True} and r.drift_agrees and r.on_stations
    assert r.camera_scale == 1.002 and r.camera_scale_std == 1e-4 and r.scales_fitted
    assert r.noise_model == "sources" and r.std["X"]["translation"] == 0.2
    assert Reported.of({"held_out": {"best": False}}).held_out_best is None


def test_a_solve_s_own_diagnostics_read_as_the_solver_wrote_them():
    problem = handeye.get_registry().problem("axyb")
    data, _ = problem.simulate(pairs=12, seed=4)
    sol = handeye.solve("axyb", solver="refine", **data)
    r = Reported.of(sol.diagnostics)
    assert set(r.std) == {"X", "Y"} and r.std == sol.diagnostics["std"]
    assert r.warnings == tuple(sol.warnings)
