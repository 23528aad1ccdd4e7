"""The reprojection-error solver (plugins/reprojection.py) on simulated board images
(`handeye.problems.axyb.images`: 9 x 6 corners, 1280 x 960 camera with distortion, B = the PnP
poses of the noisy corners). The shared suite (test_solvers.py) runs it too, through the
simulator option its SolverSpec declares."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import handeye
from handeye.base.errors import InputError
from handeye.estimation.nlls import retract
from handeye.estimation.noise import NoiseModel
from handeye.vision.observations import Camera

PROBLEM = handeye.get_registry().problem("axyb")
SETUPS = ("eye-in-hand", "eye-to-hand")
#: a start a few degrees and centimetres off the truth
OFFSET_X = np.array([0.05, -0.03, 0.02, 30.0, -15.0, 20.0])
OFFSET_Y = np.array([-0.02, 0.04, 0.01, 15.0, 25.0, -30.0])


def cell(setup: str, seed: int, noisy: bool = True, pairs: int = 20, pixel_noise: float = 0.3):
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    noise = NoiseModel.on("B", 1.0, 1.0) if noisy else None  # noise on B = pixel noise on the corners
    return PROBLEM.simulate(pairs=pairs, seed=seed, noise=noise, images={"setup": setup, "pixel_noise": pixel_noise},
                            **truth)


def error(solution, truth) -> dict:
    return PROBLEM.errors(solution.unknowns, truth)


@pytest.mark.parametrize("setup", SETUPS)
def test_exact_corners_are_recovered_from_a_start_off_by_degrees_and_centimetres(setup):
    data, truth = cell(setup, seed=3, noisy=False, pairs=8)
    sol = handeye.solve("axyb", solver="reprojection", **data, init_X=retract(truth["X"], OFFSET_X),
                        init_Y=retract(truth["Y"], OFFSET_Y))
    assert sol.status is handeye.Status.OPTIMAL and sol.diagnostics["self_check"]["reliable"]
    for e in error(sol, truth).values():
        assert e["rotation"] < 1e-10 and e["translation"] < 1e-8  # mm, lever arm ~500 mm
    assert sol.diagnostics["rms_px"] < 1e-9 and sol.diagnostics["initial_rms_px"] > 10


@pytest.mark.parametrize("setup", SETUPS)
def test_noisy_corners_beat_the_pose_based_answer_and_reach_the_floor(setup):
    """0.3 px on the corners, 20 stations, 4 seeds: the reprojection fit equals the fit started
    from the truth (same minimum) and its error is below auto's on the PnP poses (summed over
    the seeds: measured 0.3-0.5x in rotation, 0.1-0.5x in translation)."""
    sums = np.zeros((2, 4))
    for seed in range(4):
        data, truth = cell(setup, seed)
        sol = handeye.solve("axyb", solver="reprojection", **data)
        floor = handeye.solve("axyb", solver="reprojection", **data, init_X=truth["X"], init_Y=truth["Y"])
        auto = handeye.solve("axyb", solver="auto", A=data["A"], B=data["B"])
        for name in ("X", "Y"):
            np.testing.assert_allclose(sol.unknowns[name], floor.unknowns[name], atol=1e-7)
        for row, s in enumerate((sol, auto)):
            e = error(s, truth)
            sums[row] += [e["X"]["rotation"], e["X"]["translation"], e["Y"]["rotation"], e["Y"]["translation"]]
        assert sol.status is handeye.Status.OPTIMAL and sol.diagnostics["self_check"]["reliable"]
        assert 0.28 < sol.diagnostics["rms_px"] / np.sqrt(2) < 0.32  # 2-D RMS of 0.3 px per axis, less the fit
        assert sol.diagnostics["robot_misfit"] < 1.1 and not sol.warnings
    assert np.all(sums[0] < sums[1]), sums


def test_one_sigma_matches_the_spread_of_the_errors():
    """Over 12 seeds the RMS error of each unknown is within a factor 2 of the reported 1-sigma
    (the root of the three axes' variances, as every solver reports it)."""
    errs, stds = [], []
    for seed in range(12):
        data, truth = cell("eye-to-hand", seed=100 + seed)
        sol = handeye.solve("axyb", solver="reprojection", **data)
        e = error(sol, truth)
        errs.append([e[n][k] for n in ("X", "Y") for k in ("rotation", "translation")])
        stds.append([sol.diagnostics["std"][n][k] for n in ("X", "Y") for k in ("rotation", "translation")])
    ratio = np.sqrt(np.mean(np.square(errs), axis=0)) / np.median(stds, axis=0)
    assert np.all((0.5 < ratio) & (ratio < 2.0)), ratio


def test_cauchy_loss_shrugs_off_corners_twenty_pixels_off():
    data, truth = cell("eye-in-hand", seed=7)
    images = data["images"]
    pixels = [np.array(u) for u in images.image_points]
    for i in (2, 9, 15):
        pixels[i][:5] += 20.0
    bad = dict(data, images=dataclasses.replace(images, image_points=tuple(pixels)))
    clean = handeye.solve("axyb", solver="reprojection", **data)
    robust = handeye.solve("axyb", solver="reprojection", **bad, loss="cauchy", loss_scale=1.0)
    plain = handeye.solve("axyb", solver="reprojection", **bad)
    e_clean, e_robust, e_plain = (error(s, truth) for s in (clean, robust, plain))
    for name in ("X", "Y"):
        assert e_robust[name]["rotation"] < 1.5 * e_clean[name]["rotation"] + 1e-5
        assert e_robust[name]["translation"] < 1.5 * e_clean[name]["translation"] + 0.01
    assert max(e_plain[n]["translation"] for n in ("X", "Y")) > 3 * max(e_robust[n]["translation"] for n in ("X", "Y"))
    assert robust.diagnostics["outlier_corners"] == 15 and "down-weighted" in " ".join(robust.warnings)


def test_refine_intrinsics_recovers_a_camera_off_by_two_percent():
    data, truth = cell("eye-in-hand", seed=8, pairs=25, pixel_noise=0.1)
    images = data["images"]
    K = images.camera.K.copy()
    K[0, 0] *= 1.02
    K[1, 1] *= 0.98
    K[:2, 2] += (6.0, -5.0)
    wrong = dict(data, images=dataclasses.replace(images, camera=Camera(K, images.camera.dist * 0.7, images.camera.size)))
    sol = handeye.solve("axyb", solver="reprojection", **wrong, refine_intrinsics=True)
    refined = np.array(sol.diagnostics["camera"]["K"])
    np.testing.assert_allclose(refined, images.camera.K, atol=1.5)  # px, from 20 px off
    e = error(sol, truth)
    assert e["X"]["rotation"] < 1e-3 and e["X"]["translation"] < 0.5


def test_millimetres_and_metres_give_the_same_answer_scaled():
    data, _ = cell("eye-to-hand", seed=9)
    mm = handeye.solve("axyb", solver="reprojection", **data)
    metres = {k: (np.array(v) * [1, 1, 1, 1e-3] if k != "images" else v.scaled(1e3)) for k, v in data.items()}
    for k in ("A", "B"):
        metres[k][:, 3, 3] = 1.0
    m = handeye.solve("axyb", solver="reprojection", **metres)
    for name in ("X", "Y"):
        np.testing.assert_allclose(m.unknowns[name][:3, :3], mm.unknowns[name][:3, :3], atol=1e-9)
        np.testing.assert_allclose(m.unknowns[name][:3, 3] * 1e3, mm.unknowns[name][:3, 3], atol=1e-6)


def test_without_images_or_with_the_wrong_count_it_says_what_to_give():
    data, _ = cell("eye-in-hand", seed=10, noisy=False, pairs=6)
    with pytest.raises(InputError, match="needs the board's image observations") as info:
        handeye.solve("axyb", solver="reprojection", A=data["A"], B=data["B"])
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="images hold 5 stations but the poses 6"):
        handeye.solve("axyb", solver="reprojection", **dict(data, images=data["images"].take(range(5))))
    with pytest.raises(InputError, match="BoardObservations"):
        handeye.solve("axyb", solver="reprojection", **dict(data, images=[[1, 2]]))


def test_robot_errors_larger_than_the_pixel_noise_are_named():
    """Robot poses with 1 mm / 0.1 deg of error (far above what 0.3 px allows): the corners fit
    the robot-constrained model several times worse than each image alone, and with the robot's
    poses taken as exact the warning says that the robot's errors dominate and what models them."""
    truth = PROBLEM.random_unknowns(np.random.default_rng(11))
    data, _ = PROBLEM.simulate(pairs=20, seed=11, noise=NoiseModel({"A": (0.002, 1.0), "B": (1.0, 1.0)}),
                               images={"setup": "eye-in-hand"}, **truth)
    sol = handeye.solve("axyb", solver="reprojection", robot_noise="none", **data)
    assert sol.diagnostics["robot_misfit"] > 1.5
    assert any("robot's pose errors" in w and "robot_noise='estimated' or solver 'auto'" in w for w in sol.warnings)
    modelled = handeye.solve("axyb", solver="reprojection", **data)  # the default estimates them: nothing to warn of
    assert not any("robot's pose errors" in w for w in modelled.warnings)


@pytest.mark.parametrize("rms, pnp, dominate", [
    (0.063, 0.03, False),  # a rendered set with exact robot poses: ratio 2.1, but 0.055 px added
    (1.7, 0.19, True),  # the real circle-grid set: the robot adds 1.69 px
    (0.25, 0.2, False),  # ratio 1.25
    (0.5, 0.2, True),
])
def test_robot_errors_dominate_only_beyond_a_tenth_of_a_pixel(rms, pnp, dominate):
    from handeye.plugins.reprojection import robot_errors_dominate

    assert robot_errors_dominate({"rms_px": rms, "pnp_rms_px": pnp, "robot_misfit": rms / pnp}) is dominate
