"""Problem ``axbycz`` (A_i X B_i = Y C_i Z, problems/axbycz/) and its least-squares model
(problems/axbycz/geometry.py): validation and degeneracy, residuals, the simulator's protocols,
the analytic Jacobian, identifiability, the self-check hooks, `refine` and `auto` on it, and the
harness's protocol sweeps. The shared suite (test_solvers.py) runs every axbycz solver as well."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye.base.errors import (
    BackendUnavailableError,
    DegenerateDataError,
    InputError,
)
from handeye.estimation.nlls import retract_all
from handeye.estimation.noise import NoiseModel
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.problems.axbycz import PROBLEM
from handeye.problems.axbycz import geometry as G

NOISE = NoiseModel.on(("A", "B", "C"), 0.002, 0.2)
UNKNOWNS = ("X", "Y", "Z")


def case(seed: int, protocol: str = "free", pairs: int = 12, noise: NoiseModel | None = None):
    truth = PROBLEM.random_unknowns(np.random.default_rng(seed))
    return PROBLEM.simulate(pairs=pairs, seed=seed, noise=noise, protocol=protocol, **truth)


def exact_B(A, C, truth):
    return inverse(truth["X"]) @ inverse(A) @ truth["Y"] @ C @ truth["Z"]


def perturbed(T, rng, rot=0.05, trans=20.0):
    return make_pose(T[:3, :3] @ so3_exp(rot * rng.standard_normal(3)), T[:3, 3] + trans * rng.standard_normal(3))


def one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


# --------------------------------------------------------------------------- validation

@pytest.mark.parametrize(("change", "kind", "match"), [
    (lambda d: d.pop("C"), InputError, r"needs data \['A', 'B', 'C'\]; missing \['C'\]"),
    (lambda d: d.update(D=d["A"]), InputError, r"takes data \['A', 'B', 'C'\], not \['D'\]"),
    (lambda d: d.update(C=d["C"][:-1]), InputError, "same length"),
    (lambda d: d.update(B=d["B"][:, :3]), InputError, r"shape \(m, 4, 4\)"),
    (lambda d: d.update(A=np.where(np.arange(16).reshape(4, 4) == 3, np.nan, d["A"])), InputError, "NaN or inf"),
    (lambda d: d.update(A=d["A"][:2], B=d["B"][:2], C=d["C"][:2]), InputError, "at least 3"),
])
def test_bad_input_is_one_line_of_its_type(change, kind, match):
    data, _ = case(1)
    data = {k: np.array(v) for k, v in data.items()}
    change(data)
    with pytest.raises(kind, match=match) as info:
        PROBLEM.validate(**data)
    one_line(info)


def test_rotation_that_is_not_a_rotation_is_refused():
    data, _ = case(1)
    C = np.array(data["C"])
    C[4, :3, :3] *= 1.1
    with pytest.raises(InputError, match="C") as info:
        PROBLEM.validate(A=data["A"], B=data["B"], C=C)
    one_line(info)


def degenerate(what: str):
    """Exact data whose stack `what` is deficient, with the rest of a free-motion recording."""
    data, truth = case(3)
    A, C = np.array(data["A"]), np.array(data["C"])
    if what == "C same":
        C[:] = C[0]
    elif what == "A same":
        A[:] = A[0]
    elif what == "A one axis":
        A[:, :3, :3] = so3_exp(np.outer(np.linspace(0.1, 1.0, len(A)), [0.0, 0.0, 1.0]))
    elif what == "C translates":
        C[:, :3, :3] = C[0, :3, :3]
    B = exact_B(A, C, truth)
    if what == "B same":  # the robots move in lockstep: the camera always sees the marker alike
        B[:] = B[0]
        C = inverse(truth["Y"]) @ A @ truth["X"] @ B @ inverse(truth["Z"])
    return {"A": A, "B": B, "C": C}


@pytest.mark.parametrize(("what", "match"), [
    ("C same", (r"robot 2's flange poses \(C\) are the same pose in all 12 triples, so only Y C Z is determined: "
                r"these triples do not determine the rotations and translations of Y and Z separately\. Record robot 2")),
    ("A same", r"robot 1's flange poses \(A\) are the same pose .* only Y\^-1 A X .* of X and Y separately"),
    ("B same", r"the marker's poses in the camera \(B\) are the same pose .* of X and Z separately.*lockstep"),
    ("A one axis", (r"robot 1's flange poses \(A\) rotate about one axis only \(11 of 12 poses rotated from the first, "
                    r"axis spread 0 deg\): these triples do not determine the translations of X and Y along that axis")),
    ("C translates", (r"robot 2's flange poses \(C\) do not rotate \(they only translate\): these triples do not "
                      r"determine the translations of Y and Z separately")),
])
def test_degenerate_data_say_what_is_undetermined_and_what_to_record(what, match):
    with pytest.raises(DegenerateDataError, match=match) as info:
        PROBLEM.validate(**degenerate(what))
    assert "Record" in one_line(info)


def local_rank_ratio(data, truth) -> float:
    """sigma_min / sigma_max of the model's Jacobian at the truth, translations in units of the
    data's scale (18 columns: X, Y, Z)."""
    d = PROBLEM.validate(**data)
    model = G.AXBYCZModel(d)
    poses = tuple(truth[k] for k in UNKNOWNS)
    J = model.jacobian(poses, model.residuals(poses))
    J[:, 3:, :] /= d.translation_scale
    for j in range(3):
        J[:, :, 6 * j + 3:6 * j + 6] *= d.translation_scale
    s = np.linalg.svd(J.reshape(-1, 18), compute_uv=False)
    return s[-1] / s[0]


@pytest.mark.parametrize(("protocol", "pairs"), [("free", 3), ("free", 4), ("phases", 5), ("phases", 6)])
def test_accepted_data_determine_every_unknown(protocol, pairs):
    """What validate accepts is locally identifiable: the 6m x 18 Jacobian at the truth has full
    rank (free motion from 3 triples, the phase protocol from 5: 3 poses of each robot while the
    other holds still). Measured over 200 seeds: smallest ratio 3e-8 (free, m = 3: a square system,
    near singular on a thin set), >= 7e-3 for the others."""
    ratios = [local_rank_ratio(*case(seed, protocol, pairs)) for seed in range(20)]
    assert min(ratios) > 1e-10, ratios


def test_jacobian_is_singular_exactly_where_validate_refuses():
    """The refused stacks leave a gauge freedom: the Jacobian at the truth is rank deficient."""
    for what in ("C same", "A same", "A one axis", "C translates"):
        data = degenerate(what)
        _, truth = case(3)
        d = type(PROBLEM.validate(**case(3)[0]))(*(np.asarray(data[k]) for k in ("A", "B", "C")))
        model = G.AXBYCZModel(d)
        poses = tuple(truth[k] for k in UNKNOWNS)
        s = np.linalg.svd(model.jacobian(poses, model.residuals(poses)).reshape(-1, 18), compute_uv=False)
        assert s[-1] / s[0] < 1e-10, what


def test_phases_with_fewer_than_three_poses_per_robot_are_refused():
    data, _ = case(4, "phases", pairs=4)  # robot 1: poses A_0, A_1 only (one motion)
    with pytest.raises(DegenerateDataError, match="robot 1's flange poses .* rotate about one axis only"):
        PROBLEM.validate(**data)
    PROBLEM.validate(**case(4, "phases", pairs=5)[0])


# --------------------------------------------------------------------------- residuals and simulator

@pytest.mark.parametrize("protocol", ["free", "phases"])
def test_residuals_vanish_on_exact_data_and_match_the_model(protocol):
    data, truth = case(2, protocol, pairs=10)
    d = PROBLEM.validate(**data)
    res = PROBLEM.residuals(d, truth)
    assert res["rotation"].max() < 1e-12 and res["translation"].max() < 1e-9 * d.translation_scale
    noisy, truth = case(2, protocol, pairs=10, noise=NOISE)
    d = PROBLEM.validate(**noisy)
    res = PROBLEM.residuals(d, truth)
    e = G.AXBYCZModel(d).residuals(tuple(truth[k] for k in UNKNOWNS))
    np.testing.assert_allclose(np.linalg.norm(e[:, :3], axis=1), res["rotation"], rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(e[:, 3:], axis=1), res["translation"], rtol=1e-12)
    assert res["rotation"].min() > 0 and res["translation"].min() > 0


def test_simulator_protocols():
    free, truth = PROBLEM.simulate(pairs=9, seed=5)
    phases, _ = PROBLEM.simulate(pairs=9, seed=5, protocol="phases")
    for k in ("X", "Y", "Z"):
        assert truth[k].shape == (4, 4)
    assert len({free["C"][i].tobytes() for i in range(9)}) == 9
    C, A = phases["C"], phases["A"]
    assert all(np.array_equal(C[i], C[0]) for i in range(5))  # robot 2 still for ceil(9 / 2) triples ...
    assert all(np.array_equal(A[i], A[0]) for i in range(5, 9))  # ... then robot 1, at its first pose
    assert len({A[i].tobytes() for i in range(5)}) == 5 and len({C[i].tobytes() for i in range(4, 9)}) == 5
    # the noise comes from its own stream: the same seed gives the same poses at every noise level
    noisy, _ = PROBLEM.simulate(pairs=9, seed=5, noise=NoiseModel.on("B", 0.01, 1.0))
    np.testing.assert_array_equal(noisy["A"], free["A"])
    np.testing.assert_array_equal(noisy["C"], free["C"])
    assert not np.array_equal(noisy["B"], free["B"])


@pytest.mark.parametrize(("options", "match"), [
    ({"protocol": "lockstep"}, "protocol='lockstep' is not one of free, phases"),
    ({"pairing": "all"}, r"unknown simulate option\(s\) \['pairing'\]"),
    ({"pairs": 0}, "pairs must be >= 1"),
    ({"X": np.eye(3)}, "X"),
])
def test_simulator_refuses_bad_options(options, match):
    with pytest.raises(InputError, match=match):
        PROBLEM.simulate(**{"pairs": 5, **options})


def test_still_groups_and_diagnose():
    data, _ = case(6, "phases", pairs=14, noise=NOISE)
    d = PROBLEM.validate(**data)
    assert [g.tolist() for g in d.still_groups("C")] == [list(range(7))]
    assert [g.tolist() for g in d.still_groups("A")] == [[0, *range(7, 14)]]  # robot 1 back at its first pose
    figures = PROBLEM.diagnose(d)
    assert figures["protocol"] == "phases" and figures["pairs"] == 14 and figures["warnings"] == []
    assert set(figures["axis_spread_deg"]) == {"A", "B", "C"}
    free = PROBLEM.validate(**case(6, "free", pairs=14, noise=NOISE)[0])
    assert PROBLEM.diagnose(free)["protocol"] == "free" and free.still_groups("A") == []


# --------------------------------------------------------------------------- model

@pytest.mark.parametrize("protocol", ["free", "phases"])
def test_analytic_jacobian_matches_central_differences(protocol):
    """At a point with large residuals (noise 0.3 rad / 30 mm), so that the inverse Jacobians of
    SO(3) matter."""
    data, truth = case(7, protocol, pairs=10, noise=NoiseModel.on(("A", "B", "C"), 0.3, 30.0))
    model = G.AXBYCZModel(PROBLEM.validate(**data))
    poses = tuple(truth[k] for k in UNKNOWNS)
    J = model.jacobian(poses, model.residuals(poses))
    h = 1e-6
    numeric = np.empty_like(J)
    for k in range(18):
        xi = np.zeros(18)
        xi[k] = h
        numeric[:, :, k] = (model.residuals(retract_all(poses, xi)) - model.residuals(retract_all(poses, -xi))) / (2 * h)
    assert np.abs(J - numeric).max() < 1e-6 * np.abs(J).max()


@pytest.mark.parametrize("protocol", ["free", "phases"])
def test_refine_from_a_perturbed_truth_recovers_noise_free_data(protocol):
    data, truth = case(8, protocol, pairs=10)
    rng = np.random.default_rng(8)
    init = {f"init_{k}": perturbed(truth[k], rng) for k in UNKNOWNS}
    sol = handeye.solve("axbycz", solver="refine", **init, **data)
    scale = PROBLEM.validate(**data).translation_scale
    assert sol.status == handeye.Status.OPTIMAL and sol.diagnostics["init"] == "given"
    for name, err in PROBLEM.errors(sol.unknowns, truth).items():
        assert err["rotation"] < 1e-9 and err["translation"] < 1e-9 * scale, (name, err)


def test_covariance_predicts_the_spread_of_the_estimate():
    """Over seeds, the squared Mahalanobis distance of refine's estimate from the truth (18
    parameters, with the covariance refine reports) averages ~18: the covariance is neither too
    small nor too large. Measured: 17.1 over these 40 seeds."""
    from handeye.checks.self_check import _difference

    d2 = []
    for seed in range(40):
        data, truth = case(100 + seed, "free", pairs=30, noise=NOISE)
        sol = handeye.solve("axbycz", solver="refine", init=truth, **data)
        cov = np.asarray(sol.diagnostics["covariance_XYZ"])
        assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0
        delta = np.concatenate([_difference(truth[k], sol.unknowns[k]) for k in UNKNOWNS])
        d2.append(float(delta @ np.linalg.solve(cov, delta)))
    assert 12.0 < np.mean(d2) < 26.0, np.mean(d2)


@pytest.mark.parametrize("solver", ["refine", "auto"])
def test_inputs_are_not_modified(solver):
    data, _ = case(9, "phases", pairs=14, noise=NOISE)
    arrays = {k: np.array(v) for k, v in data.items()}
    before = {k: v.copy() for k, v in arrays.items()}
    d = PROBLEM.validate(**arrays)
    PROBLEM.diagnose(d)
    sol = handeye.solve("axbycz", solver=solver, **arrays)
    PROBLEM.residuals(d, sol.unknowns)
    for k, array in arrays.items():
        np.testing.assert_array_equal(array, before[k])
        assert array.flags.writeable
    assert not d.A.flags.writeable


# --------------------------------------------------------------------------- self-check hooks

def test_expected_rotation_residual_needs_both_phases():
    """None on free motion; on phases an upper bound of the truth's median residual (module
    docstring: sqrt(4/3) = 1.15 x with equal noise on A, B, C, plus the pitch term), measured
    from ~30 motions, so per data set within 0.8-2.0 x (40 seeds), 1.37 x on average."""
    free = PROBLEM.validate(**case(10, "free", pairs=30, noise=NOISE)[0])
    assert PROBLEM.expected_rotation_residual(free) is None
    ratios = []
    for seed in range(20):
        data, truth = case(seed, "phases", pairs=30, noise=NOISE)
        d = PROBLEM.validate(**data)
        ratios.append(PROBLEM.expected_rotation_residual(d) / float(np.median(PROBLEM.residuals(d, truth)["rotation"])))
    assert 0.6 < min(ratios) and max(ratios) < 3.0 and 1.0 < np.mean(ratios) < 2.0, ratios


def test_self_check_flags_a_wrong_answer_and_passes_the_best_fit():
    from handeye.checks.self_check import assess

    data, _ = case(11, "phases", pairs=30, noise=NOISE)
    d = PROBLEM.validate(**data)
    good = handeye.solve("axbycz", **data)
    assert good.diagnostics["self_check"]["reliable"] and good.diagnostics["self_check"]["distance_sigmas"] < 1e-3
    wrong = dict(good.unknowns)
    wrong["Z"] = make_pose(wrong["Z"][:3, :3] @ so3_exp([0.0, 0.2, 0.0]), wrong["Z"][:3, 3])
    check = assess(PROBLEM, d, wrong, {})
    assert not check.reliable and "the answer leaves a median rotation residual" in check.failures[0]


def test_rotation_axes_name_a_robot_turning_mostly_about_one_axis():
    data, truth = case(12, "free", pairs=12)
    A = np.array(data["A"])
    A[:, :3, :3] = so3_exp(np.outer(np.linspace(0.1, 1.5, 12), [0.0, 0.0, 1.0])
                           + 0.02 * np.random.default_rng(1).standard_normal((12, 3)))
    d = PROBLEM.validate(A=A, B=exact_B(A, data["C"], truth), C=data["C"])
    axes = PROBLEM.rotation_axes(d)
    assert abs(axes["Y"][2]) > 0.95  # robot 1's axis in its base frame: z
    assert "Z" not in axes  # robot 2 turns about many axes


# --------------------------------------------------------------------------- refine and auto

def test_refine_options_of_three_poses():
    data, truth = case(13)
    with pytest.raises(InputError, match="init_X and init_Y and init_Z must be given together"):
        handeye.solve("axbycz", solver="refine", init_X=truth["X"], **data)
    with pytest.raises(InputError, match=r"\{'X': 4x4, 'Y': 4x4, 'Z': 4x4\}"):
        handeye.solve("axbycz", solver="refine", init={"X": truth["X"], "Y": truth["Y"]}, **data)
    sol = handeye.solve("axbycz", solver="refine", init=truth, **data)
    assert sol.diagnostics["init"] == "given"


def test_refine_without_any_start_asks_for_start_poses(monkeypatch):
    data, _ = case(14)
    monkeypatch.setattr(type(PROBLEM), "starts", ("no-such-solver",))
    with pytest.raises(BackendUnavailableError, match=r"none of its start solvers \(no-such-solver\).*init_X, init_Y, init_Z"):
        handeye.solve("axbycz", solver="refine", **data)


def test_refine_when_no_start_solves_the_data_says_why():
    data, truth = case(15, pairs=3)  # too few triples for every start
    with pytest.raises(InputError, match=r"no start solver of refine solves these data \(wang: .*; give the start poses") as info:
        handeye.solve("axbycz", solver="refine", **data)
    one_line(info)
    # given poses (and stated weights: 18 equations for 18 unknowns leave no noise to estimate;
    # for the same reason the host's self-check cannot fit them and calls any answer unreliable)
    rng = np.random.default_rng(15)
    init = {k: perturbed(truth[k], rng, 0.01, 5.0) for k in UNKNOWNS}
    sol = handeye.solve("axbycz", solver="refine", init=init, sigma_rot=1e-3, sigma_trans=0.1, **data)
    assert max(e["rotation"] for e in PROBLEM.errors(sol.unknowns, truth).values()) < 1e-9


@pytest.mark.parametrize(("protocol", "second"), [("free", "kron-lstsq"), ("phases", "fu-dq")])
def test_auto_two_starts_noise_free_and_noisy(protocol, second):
    data, truth = case(16, protocol, pairs=12)
    sol = handeye.solve("axbycz", **data)
    assert sol.solver == "auto" and sol.diagnostics["pipeline"] == [f"wang | {second}", "refine", "best"]
    scale = PROBLEM.validate(**data).translation_scale
    for name, err in PROBLEM.errors(sol.unknowns, truth).items():
        assert err["rotation"] < 1e-9 and err["translation"] < 1e-9 * scale, (name, err)
    data, truth = case(16, protocol, pairs=30, noise=NOISE)
    sol = handeye.solve("axbycz", **data)
    oracle = handeye.solve("axbycz", solver="refine", init=truth, **data)
    for name, err in PROBLEM.errors(sol.unknowns, oracle.unknowns).items():
        assert err["rotation"] < 1e-8 and err["translation"] < 1e-6, (name, err)
    assert sol.status == handeye.Status.OPTIMAL and sol.warnings == []


def test_auto_leaves_out_gross_triples():
    data, truth = case(17, "free", pairs=30, noise=NOISE)
    clean = handeye.solve("axbycz", **data)
    assert clean.diagnostics["outliers"] == []
    B = np.array(data["B"])
    B[[4, 19], :3, :3] = B[[4, 19], :3, :3] @ so3_exp([0.0, 0.0, 0.2])  # ~11 deg: wrong marker pose
    sol = handeye.solve("axbycz", A=data["A"], B=B, C=data["C"])
    assert [o["index"] for o in sol.diagnostics["outliers"]] == [4, 19]
    assert any("triples no. 5 (index 4), no. 20 (index 19) are far off the others" in w for w in sol.warnings)
    for name, err in PROBLEM.errors(sol.unknowns, truth).items():
        assert err["rotation"] < 0.01, (name, err)


# --------------------------------------------------------------------------- harness

def test_built_in_studies_run_each_protocol():
    from handeye.harness import Spec, accuracy_study, run_study, sweep_study

    study = sweep_study("axbycz")
    assert [s.name for s in study.sweeps] == ["noise", "pairs", "noise-phases", "pairs-phases"]
    assert [s.simulation for s in study.sweeps][2] == {"protocol": "phases"}
    assert set(study.noise.sigmas) == {"A", "B", "C"}
    acc = accuracy_study(problem="axbycz", trials=1, pairs=(8,), protocols=("phases",),
                         specs=(Spec("fu-dq"), Spec("wu")))
    assert set(acc.noise.sigmas) == {"A", "B", "C"} and [s.name for s in acc.sweeps] == ["accuracy-phases"]
    result = run_study(acc.replace(sweeps=(acc.sweeps[0].__class__("accuracy-phases", (1.0,), (8,),
                                                                    simulation={"protocol": "phases"}),)),
                       jobs=1, progress=False)
    by_label = {r["label"]: r for r in result.records}
    assert by_label["fu-dq"]["status"] in ("optimal", "suboptimal") and by_label["oracle"]["status"] == "optimal"
    assert by_label["oracle"]["err_rot_Z"] < 0.05
    with pytest.raises(InputError, match="protocol 'lockstep' is not one of free, phases"):
        sweep_study("axbycz", protocols=("lockstep",))
    with pytest.raises(InputError, match="has no data protocols"):
        sweep_study("axyb", protocols=("phases",))


# --------------------------------------------------------------------------- conventions (docs/conventions.md)

@pytest.mark.parametrize("cell", [1, 2])
def test_the_two_cells_of_the_conventions(cell):
    """Both cells of docs/conventions.md built from named frames: the poses as the controllers
    and solvePnP give them, mapped as the tables say, give back the named transforms."""
    from handeye.geometry.kinematics import random_flange_poses
    from handeye.geometry.se3 import random_poses

    rng = np.random.default_rng(20 + cell)
    T_world_base1, T_world_base2 = random_poses(2, rng, 800.0)
    T_flange1_tool1, T_flange2_tool2 = random_poses(2, rng, 100.0)  # camera or marker on each flange
    T_base1_flange1 = random_flange_poses(12, rng)
    T_base2_flange2 = random_flange_poses(12, rng)
    T_world_tool1 = T_world_base1 @ T_base1_flange1 @ T_flange1_tool1
    T_world_tool2 = T_world_base2 @ T_base2_flange2 @ T_flange2_tool2
    if cell == 1:  # camera on robot 1 (tool1), marker on robot 2 (tool2)
        T_cam_marker = inverse(T_world_tool1) @ T_world_tool2  # what solvePnP returns
        B = T_cam_marker
    else:  # marker on robot 1 (tool1), camera on robot 2 (tool2)
        T_cam_marker = inverse(T_world_tool2) @ T_world_tool1
        B = inverse(T_cam_marker)
    sol = handeye.solve("axbycz", A=T_base1_flange1, B=B, C=T_base2_flange2)
    expected = {"X": T_flange1_tool1, "Y": inverse(T_world_base1) @ T_world_base2, "Z": T_flange2_tool2}
    for name, err in PROBLEM.errors(sol.unknowns, expected).items():
        assert err["rotation"] < 1e-9 and err["translation"] < 1e-7, (name, err)


def test_a_sweep_carries_its_own_simulator_options():
    from handeye.harness.study_files import study_from_dict

    doc = {"problem": "axbycz", "sweep": [{"name": "ph", "pairs": [10], "simulation": {"protocol": "phases"}},
                                          {"name": "fr", "pairs": [10]}]}
    study = study_from_dict(doc)
    assert [s.simulation for s in study.sweeps] == [{"protocol": "phases"}, {}]
    assert study.to_dict()["sweeps"][0]["simulation"] == {"protocol": "phases"}
    assert "simulation" not in study.to_dict()["sweeps"][1]
    assert study_from_dict({**doc, "name": "again"}).sweeps == study.sweeps
    assert [c.simulation for c in study.cells()] == [{"protocol": "phases"}, {}]
    with pytest.raises(InputError, match="simulation must be a table"):
        study_from_dict({"problem": "axbycz", "sweep": [{"name": "x", "simulation": "phases"}]})
