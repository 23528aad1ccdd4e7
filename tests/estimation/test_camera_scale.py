"""Camera translations known only up to scale (``camera_scale="unknown"``, handeye.estimation.camera_scale):
every solver that honours it, on A X = Y B and A X = X B."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import handeye
from handeye import InputError, Status
from handeye.checks import scale_checks
from handeye.estimation.noise import NoiseModel
from handeye.harness import ACCURACY_NOISE
from handeye.problems.axxb import PROBLEM as AXXB
from handeye.problems.axyb import PROBLEM as AXYB

PROBLEMS = {"axyb": AXYB, "axxb": AXXB}
SCALE = 0.37  # the camera's translations are its metric ones divided by this
NOISE_FREE_TOL = 1e-9


def scale_aware(problem: str) -> list[str]:
    registry = handeye.get_registry()
    return [n for n in registry.solver_names(problem) if registry.solver(n, problem).camera_scale_mode]


def camera_in_own_unit(data: dict, s: float = SCALE) -> dict:
    B = np.array(data["B"])
    B[:, :3, 3] /= s
    return {"A": data["A"], "B": B}


def simulate(problem: str, seed: int, noise=None, pairs: int = 12) -> tuple[dict, dict]:
    P = PROBLEMS[problem]
    return P.simulate(pairs=pairs, seed=seed, noise=noise, **P.random_unknowns(np.random.default_rng(100 + seed)))


def scale_of(sol: handeye.Solution) -> float:
    return sol.diagnostics["camera_scale"]


def test_solvers_that_honour_an_unknown_scale():
    assert scale_aware("axyb") == scale_aware("axxb") == ["auto", "refine", "so3-sdp"]


@pytest.mark.parametrize("problem", ["axyb", "axxb"])
@pytest.mark.parametrize("solver", ["auto", "refine", "so3-sdp"])
def test_noise_free_data_recover_the_unknowns_and_the_scale(problem, solver):
    data, truth = simulate(problem, seed=1)
    sol = handeye.solve(problem, solver=solver, camera_scale="unknown", **camera_in_own_unit(data))
    assert sol.status is Status.OPTIMAL
    # (refine on every pair of 12 stations says that auto solves the stations themselves)
    assert not [w for w in sol.diagnostics["warnings"] if "share their noise" not in w]
    assert scale_of(sol) == pytest.approx(SCALE, rel=NOISE_FREE_TOL)
    scale = PROBLEMS[problem].validate(**data).translation_scale
    for name, e in PROBLEMS[problem].errors(sol.unknowns, truth).items():
        assert e["rotation"] < NOISE_FREE_TOL and e["translation"] < NOISE_FREE_TOL * scale, (name, e)


@pytest.mark.parametrize("problem", ["axyb", "axxb"])
def test_the_scale_and_its_uncertainty_on_noisy_data(problem):
    """20 data sets with the accuracy study's noise: the scale's error in standard deviations has
    an RMS near 1 (the stated uncertainty is right); X's translation, which the unknown scale
    confounds, is within 2.5x as accurate as with the scale known (measured 1.6-1.8x with these
    random unknowns, 1.2x with the paper's)."""
    z, unknown, known = [], [], []
    for seed in range(20):
        data, truth = simulate(problem, seed, ACCURACY_NOISE, pairs=20)
        sol = handeye.solve(problem, camera_scale="unknown", **camera_in_own_unit(data))
        assert sol.status is Status.OPTIMAL, sol.diagnostics["warnings"]
        z.append((scale_of(sol) - SCALE) / sol.diagnostics["camera_scale_std"])
        unknown.append(PROBLEMS[problem].errors(sol.unknowns, truth)["X"]["translation"])
        known.append(PROBLEMS[problem].errors(handeye.solve(problem, **data).unknowns, truth)["X"]["translation"])
    assert 0.5 < float(np.sqrt(np.mean(np.square(z)))) < 2.0, z
    assert np.median(unknown) < 2.5 * np.median(known)


def test_units():
    """The robot's unit sets the answer's; the camera's unit only the scale."""
    data, _ = simulate("axyb", seed=2, noise=ACCURACY_NOISE)
    camera = camera_in_own_unit(data)
    base = handeye.solve("axyb", camera_scale="unknown", **camera)
    robot_in_m = {"A": np.array(camera["A"]), "B": camera["B"]}
    robot_in_m["A"][:, :3, 3] /= 1000.0
    metres = handeye.solve("axyb", camera_scale="unknown", **robot_in_m)
    assert scale_of(metres) == pytest.approx(scale_of(base) / 1000.0, rel=1e-9)
    camera_x1000 = camera_in_own_unit(camera, 1e-3)  # the camera's translations times 1000
    x1000 = handeye.solve("axyb", camera_scale="unknown", **camera_x1000)
    assert scale_of(x1000) == pytest.approx(scale_of(base) / 1000.0, rel=1e-9)
    for name in ("X", "Y"):
        np.testing.assert_allclose(metres.unknowns[name][:3, :3], base.unknowns[name][:3, :3], atol=1e-9)
        np.testing.assert_allclose(metres.unknowns[name][:3, 3] * 1000.0, base.unknowns[name][:3, 3], rtol=1e-8)
        np.testing.assert_allclose(x1000.unknowns[name], base.unknowns[name], rtol=1e-8, atol=1e-9)


def test_refusals_say_what_to_do():
    data, _ = simulate("axyb", seed=3)
    camera = camera_in_own_unit(data)
    with pytest.raises(InputError, match="use one of auto, refine, so3-sdp"):
        handeye.solve("axyb", solver="shah", camera_scale="unknown", **camera)
    with pytest.raises(InputError, match="camera_scale='maybe' must be 'known'"):
        handeye.solve("axyb", camera_scale="maybe", **camera)
    with pytest.raises(InputError, match="not as a covariance"):
        handeye.solve("axyb", solver="refine", camera_scale="unknown", covariance=np.eye(6), **camera)
    with pytest.raises(InputError, match="use init='so3-sdp'"):
        handeye.solve("axyb", solver="refine", init="kron-lstsq", camera_scale="unknown", **camera)


def test_camera_translations_all_zero_leave_the_scale_undetermined():
    data, _ = simulate("axyb", seed=4)
    B = np.array(data["B"])
    B[:, :3, 3] = 0.0
    with pytest.raises(handeye.DegenerateDataError):
        handeye.solve("axyb", solver="so3-sdp", camera_scale="unknown", A=data["A"], B=B)


def test_command_line(tmp_path, capsys):
    """handeye solve --camera-scale unknown: the scale printed, the residuals in the robot's unit;
    a solver that cannot take it is bad input (exit 2)."""
    from handeye.cli import main
    from handeye.io.data_files import save_data

    data, _ = simulate("axyb", seed=5)
    path = save_data(tmp_path / "monocular.json", camera_in_own_unit(data))
    assert main(["solve", str(path), "--camera-scale", "unknown"]) == 0
    out = capsys.readouterr().out
    assert f"camera scale s = {SCALE:.6g}" in out
    assert main(["solve", str(path), "--camera-scale", "unknown", "--solver", "shah"]) == 2
    assert "use one of auto, refine, so3-sdp" in capsys.readouterr().err


@pytest.mark.parametrize("factor, status, says", [
    (1.0, Status.OPTIMAL, None),
    (1.02, Status.OPTIMAL, "check the board's size and the camera's focal length"),  # a warning
    (1e-3, Status.UNRELIABLE, "are both in one length unit"),  # camera in m, robot in mm
    (SCALE, Status.UNRELIABLE, "give camera_scale='unknown'"),  # a monocular camera taken as metric
])
def test_the_self_check_notices_camera_translations_in_another_unit(factor, status, says):
    """Check 5 of handeye.checks.self_check: the camera's translations must fit the robot's at scale 1
    (here judging refine's answer: auto estimates the scale where the data demand it, below)."""
    data, _ = simulate("axyb", seed=6, noise=ACCURACY_NOISE, pairs=8)
    sol = handeye.solve("axyb", solver="refine", **camera_in_own_unit(data, 1.0 / factor))
    check = sol.diagnostics["self_check"]["camera_scale"]
    assert sol.status is status
    assert check["scale"] == pytest.approx(1.0 / factor, rel=0.01)
    if says is None:
        assert abs(check["sigmas"]) < 3 and not sol.warnings
    else:
        assert any("fit the robot's best when multiplied by" in w and says in w for w in sol.warnings), sol.warnings
    if status is Status.OPTIMAL and says:
        assert handeye.solve("axyb", camera_scale="unknown", **camera_in_own_unit(data, 1.0 / factor)).warnings == []


def test_no_scale_verdict_where_the_robot_does_not_translate():
    """A robot turning about its flange origin (no translations in A) does not fix the camera's
    scale: check 5 says nothing."""
    from handeye.harness import campaign

    data, _ = campaign.make_case("pure-rotation", 4).data("axyb")
    assert "camera_scale" not in handeye.solve("axyb", **data).diagnostics["self_check"]


@pytest.mark.parametrize("problem", ["axyb", "axxb"])
@pytest.mark.parametrize("factor", [SCALE, 1e-3])
def test_auto_estimates_the_scale_where_the_data_demand_it(problem, factor):
    """A camera in another unit, or monocular, taken as metric: auto fits the scale (with a
    warning) and its answer is as if camera_scale='unknown' had been given."""
    data, truth = simulate(problem, seed=7, noise=ACCURACY_NOISE, pairs=12)
    camera = camera_in_own_unit(data, factor)
    sol = handeye.solve(problem, **camera)
    told = handeye.solve(problem, camera_scale="unknown", **camera)
    assert sol.status is Status.OPTIMAL and sol.warnings[0].startswith("auto: the camera's translations fit")
    assert scale_of(sol) == pytest.approx(scale_of(told), rel=1e-9) == pytest.approx(factor, rel=0.01)
    for name in sol.unknowns:
        np.testing.assert_allclose(sol.unknowns[name], told.unknowns[name], rtol=1e-9, atol=1e-9)
    assert PROBLEMS[problem].errors(sol.unknowns, truth)["X"]["translation"] < 2.0  # mm
    assert "camera_scale_test" in sol.diagnostics


KINHEC = Path(__file__).parents[1] / "data" / "kinhec"
#: check 6's warning and failure (handeye.checks.self_check._camera_scale_noise)
BIAS_WARNING = "too small, "
BIAS_FAILURE = "the data do not determine the camera's scale"


def kinhec(name: str) -> dict:
    with np.load(KINHEC / f"{name}.npz", allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def noise_figures(sol: handeye.Solution) -> dict:
    return sol.diagnostics["self_check"]["camera_scale_noise"]


def flagged(sol: handeye.Solution) -> bool:
    texts = sol.warnings + sol.diagnostics["self_check"]["failures"]
    return any(BIAS_WARNING in t or BIAS_FAILURE in t for t in texts)


@pytest.mark.parametrize("solver", ["refine", "so3-sdp", "auto"])
def test_noise_in_the_camera_translations_biasing_the_scale_is_flagged(solver):
    """KinHEC mixed-000015 (UR3e, 190 keyframes, a perfect robot, a camera with 3.3 mm lateral
    and 13.7 mm depth noise looking at a target from nearly constant distance), metric but given
    camera_scale='unknown': the fitted scale 0.928 +- 0.010 is 7 sigma short of the truth 1 and
    X 26 mm off at a stated 3.7 mm. Noise in a regressor shrinks its factor (errors in
    variables); check 6 bounds the shrinkage by kappa = n (std/s)^2 = 0.071 (6.3 sigma), which
    is the shortfall measured (0.072), and warns."""
    z = kinhec("mixed-000015")
    sol = handeye.solve("axyb", solver=solver, camera_scale="unknown", A=z["A"], B=z["B"])
    f = noise_figures(sol)
    assert f["bias"] == pytest.approx(0.071, abs=0.005) and 5.5 < f["bias_sigmas"] < 7.5, f
    assert 1.0 - f["scale"] == pytest.approx(f["bias"], abs=0.01)  # the bound is the bias here
    warning = [w for w in sol.warnings if BIAS_WARNING in w]
    assert sol.status is not Status.OPTIMAL or warning, sol.warnings
    if sol.status is Status.OPTIMAL:
        assert "may be up to 7.1% too small" in warning[0] and "solve with the scale known" in warning[0]
    # with the scale known (the data's truth) the check does not apply, and X is 2.5 mm off
    known = handeye.solve("axyb", solver="refine", A=z["A"], B=z["B"])
    assert "camera_scale_noise" not in known.diagnostics["self_check"]
    assert np.linalg.norm(known.unknowns["X"][:3, 3] - z["X_true"][:3, 3]) < 0.004


@pytest.mark.parametrize("name", ["mixed-000066", "motion-000061", "outliers-000024"])
def test_a_scale_the_data_do_not_determine_is_unreliable(name):
    """Metric KinHEC sequences given camera_scale='unknown' whose translation residuals could be
    noise spanning all of the camera translations' spread (IRB 120 with DH errors and 8 deg
    rotations; wrist-only motions; half the pairs gross outliers): the fitted scale (0.37, 0.003,
    0.09) is meaningless and X 53, 118, 423 mm off at a stated 2, 1, 17 mm; check 6 fails them
    (kappa 2.2, 2077, 12.3). Judged against the truth, not against the figures: the scale is
    far from the true 1 and X's error many times its stated 1-sigma."""
    z = kinhec(name)
    sol = handeye.solve("axyb", solver="refine", camera_scale="unknown", A=z["A"], B=z["B"])
    f = noise_figures(sol)
    assert f["bias"] > scale_checks.NOISE_BIAS_FAIL
    assert abs(f["scale"] - 1.0) > 0.5  # the true scale is 1: metric data
    error = np.linalg.norm(sol.unknowns["X"][:3, 3] - z["X_true"][:3, 3])
    stated = sol.diagnostics["std"]["X"]["translation"]
    assert error > 5 * stated, (error, stated)
    assert sol.status is Status.UNRELIABLE
    assert any(f.startswith(BIAS_FAILURE) for f in sol.diagnostics["self_check"]["failures"])


#: the genuinely monocular KinHEC sequences (camera translations scaled by 0.5 or 2; three mixed
#: ones at 7.2, 7.5 and 0.56, with DH errors, joint noise or VO drift): measured at most 2.24
#: standard deviations (monocular-000003) and 2.94 (mixed-000142), against the threshold 4
MONOCULAR = sorted(p.stem for p in KINHEC.glob("monocular-*.npz")) + ["mixed-000003", "mixed-000023", "mixed-000142"]


def test_monocular_kinhec_sequences_are_not_flagged():
    worst = 0.0
    for name in MONOCULAR:
        z = kinhec(name)
        sol = handeye.solve("axyb", solver="refine", camera_scale="unknown", A=z["A"], B=z["B"])
        f = noise_figures(sol)
        assert not flagged(sol), (name, f)
        assert f["bias_sigmas"] < (2.5 if name.startswith("monocular-") else 3.2), (name, f)
        worst = max(worst, f["bias_sigmas"])
    assert worst > 2.0  # the figures are computed, not all zero


@pytest.mark.parametrize("problem", ["axyb", "axxb"])
@pytest.mark.parametrize("noise", [ACCURACY_NOISE, NoiseModel({"B": (0.01, 5.0)})], ids=["accuracy", "camera-5mm"])
def test_simulated_monocular_data_are_not_flagged(problem, noise):
    """The paper's arm, the camera's translations scaled by 0.5, 2 and 1e-3, m = 8 to 190 pairs:
    no flag; the bias bound is at most 0.12 (accuracy noise) and 0.97 (camera noise 5 mm, 0.01
    rad) standard deviations (measured, seeds 0-3), against the threshold 4."""
    limit = 0.25 if noise is ACCURACY_NOISE else 1.5
    for m, factor in [(8, 0.5), (20, 2.0), (50, 1e-3), (190, 0.5)]:
        data, _ = simulate(problem, seed=m, noise=noise, pairs=m)
        sol = handeye.solve(problem, solver="refine", camera_scale="unknown", **camera_in_own_unit(data, factor))
        assert sol.status is Status.OPTIMAL and not flagged(sol), (m, factor, sol.warnings)
        assert noise_figures(sol)["bias_sigmas"] < limit, (m, factor, noise_figures(sol))


def test_the_bias_bound_is_the_bias_when_the_noise_is_the_camera_s():
    """Camera translations with 40 mm noise (the robot exact), m = 190, scale 0.5: the fitted
    scale falls short by 9.3% on average (7-11%, six seeds measured), the bound says 9-10.5%;
    the self-check warns."""
    shortfall, bound = [], []
    for seed in range(3):
        data, _ = simulate("axyb", seed=seed, noise=NoiseModel({"B": (0.002, 40.0)}), pairs=190)
        sol = handeye.solve("axyb", solver="refine", camera_scale="unknown", **camera_in_own_unit(data, 0.5))
        assert sol.status is Status.OPTIMAL and flagged(sol), sol.warnings
        shortfall.append(1.0 - scale_of(sol) / 0.5)
        bound.append(noise_figures(sol)["bias"])
    assert np.mean(bound) == pytest.approx(0.099, abs=0.01)
    assert np.mean(shortfall) == pytest.approx(np.mean(bound), abs=0.02)


def test_a_solver_or_start_that_takes_the_translations_as_metric_is_refused_with_the_one_that_can():
    """The host and refine ask the same capability check (SolverSpec.cannot_solve) and name the
    solvers (or the start) that can solve the data instead."""
    data, _ = simulate("axyb", seed=3)
    with pytest.raises(InputError, match=r"^solver 'shah' takes the camera's translations as metric.*use one of "
                                         r".*so3-sdp"):
        handeye.solve("axyb", solver="shah", camera_scale="unknown", **data)
    with pytest.raises(InputError, match=r"^init solver 'shah' takes .* as metric.*use init='so3-sdp'$"):
        handeye.solve("axyb", solver="refine", init="shah", camera_scale="unknown", **data)
