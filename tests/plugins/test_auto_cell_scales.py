"""auto on a cell whose cameras or markers fit the robot at another scale (`_auto_scales`): a
factor for those groups only where held-out stations are predicted better, the fewest factors
that do, the self-check judging the answer with them, and its advice following the comparison.

Figures (simulate_cell, 30 stations, 8 cameras, 16 markers, noise A 0.0002 rad / 0.05 mm, B 0.002
rad / 0.5 mm; cam3's translations 0.3% long; measured): refine's Y[3] 3.6-3.8 mm off the truth,
auto's 0.14-0.22 mm; cam3's factor 0.9969-0.9972 (truth 0.99701, 1-sigma 0.00014); held-out median
translation 0.80 against 0.84 mm without the factor.
"""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.checks.scale_checks import _scales_advice
from handeye.estimation.noise import NoiseModel
from handeye.problems.axyb_multi import simulate_cell

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def lengthened(B: np.ndarray, factor: float, rows: np.ndarray) -> np.ndarray:
    out = np.array(B)
    out[rows, :3, 3] *= factor
    return out


@pytest.mark.parametrize("seed", range(2))
def test_a_camera_a_little_long_gets_its_factor_where_held_out_stations_agree(seed):
    cell = simulate_cell(30, seed=seed, noise=NOISE)
    rows = np.asarray(cell.data["y_index"]) == 3
    data = {**cell.data, "B": lengthened(cell.data["B"], 1.003, rows)}
    sol = handeye.solve("axyb-multi", **data)
    held = sol.diagnostics["camera_scales_held_out"]
    assert held["chosen"] == "named" and held["models"]["named"]["names"] == ["cam3"]
    assert held["models"]["named"]["translation"] < 0.97 * held["models"]["none"]["translation"]
    (name, s), = sol.diagnostics["camera_scales"].items()
    assert name == "cam3"
    assert s == pytest.approx(1 / 1.003, abs=4 * sol.diagnostics["camera_scales_std"]["cam3"])
    off = np.linalg.norm(sol.Y[3][:3, 3] - cell.truth["Y"][3][:3, 3])
    plain = handeye.solve("axyb-multi", solver="refine", **data)
    plain_off = np.linalg.norm(plain.Y[3][:3, 3] - cell.truth["Y"][3][:3, 3])
    assert off < 0.5 and plain_off > 3.0, (off, plain_off)
    assert sol.status is handeye.Status.OPTIMAL
    assert sum("factor of their own for 'cam3'" in w for w in sol.warnings) == 1, sol.warnings
    # the self-check judged the answer with cam3's factor free: no scale left to name
    assert "camera_scales" not in sol.diagnostics["self_check"]


def test_exact_cameras_are_not_compared_at_all():
    cell = simulate_cell(30, seed=0, noise=NOISE)
    sol = handeye.solve("axyb-multi", **cell.data)
    assert "camera_scales_held_out" not in sol.diagnostics
    assert "camera_scales" not in sol.diagnostics


def test_the_advice_follows_a_held_out_comparison_that_kept_no_factor():
    held = {"blocks": 5, "chosen": "none", "models": {
        "none": {"names": [], "translation": 30.0, "rotation_deg": 1.0},
        "named": {"names": ["tag1"], "translation": 30.5, "rotation_deg": 1.0},
        "every_x": {"names": ["tag1", "tag2"], "translation": 29.8, "rotation_deg": 1.0}}}
    text = _scales_advice(["tag1"], held)
    assert "camera_scale=" not in text
    assert "29.8 with factors for tag1, tag2, 30 without" in text
    assert _scales_advice(["tag1"], None) == "camera_scale=['tag1'] fits their factors"
    assert _scales_advice(["tag1"], {**held, "chosen": "named"}) == "camera_scale=['tag1'] fits their factors"
