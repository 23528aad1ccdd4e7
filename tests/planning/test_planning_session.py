"""The live session (`handeye.planning.session`): its answer and 1-sigma against the full solve,
the target, a gross station, suggestions that respect the views and the workspace."""

from __future__ import annotations

import math

import numpy as np
import pytest

import handeye
from handeye.estimation.noise import NoiseModel
from handeye.geometry import so3_fast
from handeye.geometry.se3 import inverse, make_pose
from handeye.host.registry import get_registry
from handeye.planning import design, live_fit, views
from handeye.planning.plan import Noise, plan, planners
from handeye.planning.session import Session, SessionError, Tolerance
from handeye.planning.stations import Workspace
from handeye.problems.axyb import PROBLEM
from handeye.problems.axyb import planning as axyb_planning
from handeye.vision.boards import parse_board
from handeye.vision.observations import Camera

NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})


def simulated(pairs: int, seed: int) -> dict[str, np.ndarray]:
    return PROBLEM.simulate(pairs=pairs, seed=seed, noise=NOISE)[0]


def gap(T: np.ndarray, U: np.ndarray) -> tuple[float, float]:
    """Rotation (deg) and translation between two poses."""
    D = inverse(T) @ U
    return math.degrees(float(np.linalg.norm(so3_fast.log(D[None, :3, :3])[0]))), float(np.linalg.norm(T[:3, 3] - U[:3, 3]))


def run(session: Session, data: dict[str, np.ndarray]) -> list:
    return [session.add(a, b) for a, b in zip(data["A"], data["B"])]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_answer_and_std_agree_with_the_full_solve(seed):
    """Warm-started fits only (no full solve after the first): the last answer is handeye.solve's
    on the same stations to a small fraction of the 1-sigma, and so is its 1-sigma (the self-check's)."""
    data = simulated(40, seed)
    session = Session("axyb", setup="eye-in-hand", solve_every=0)
    last = run(session, data)[-1]
    keep = session.kept
    solution = handeye.solve("axyb", A=data["A"][keep], B=data["B"][keep])
    reference = solution.diagnostics["self_check"]["std"]
    assert last.noise == "estimated" and last.used == keep.sum() >= 38
    for name in ("X", "Y"):
        rot, trans = gap(solution.unknowns[name], last.unknowns[name])
        assert rot < 0.02 * reference[name]["rotation_deg"]
        assert trans < 0.02 * reference[name]["translation"]
        for part in ("rotation_deg", "translation"):
            assert last.std[name][part] == pytest.approx(reference[name][part], rel=0.2)


def test_final_is_the_checked_solve():
    data = simulated(20, 3)
    session = Session("axyb", setup="eye-in-hand")
    last = run(session, data)[-1]
    final = session.final()
    assert final.status.value == "optimal" and "self_check" in final.diagnostics
    for name in ("X", "Y"):
        rot, trans = gap(final.unknowns[name], last.unknowns[name])
        assert rot < 0.05 * last.std[name]["rotation_deg"] and trans < 0.05 * last.std[name]["translation"]


def test_enough_fires_when_the_std_crosses_the_tolerance():
    data = simulated(40, 4)
    probe = run(Session("axyb", setup="eye-in-hand"), data)
    # a tolerance between the 1-sigma at 10 stations and at 40
    mid = {k: math.sqrt(probe[9].std["X"][k] * probe[-1].std["X"][k]) for k in ("rotation_deg", "translation")}
    tolerance = Tolerance(mid["rotation_deg"], mid["translation"] * 10)  # the rotation decides
    updates = run(Session("axyb", setup="eye-in-hand", target=tolerance), data)
    within = [u.std is not None and all(s["rotation_deg"] <= tolerance.rotation_deg
                                        and s["translation"] <= tolerance.translation for s in u.std.values())
              for u in updates]
    assert [u.enough for u in updates] == within
    assert not within[9] and within[-1]
    first = within.index(True)
    assert updates[first - 1].std["X"]["rotation_deg"] > tolerance.rotation_deg >= updates[first].std["X"]["rotation_deg"]


def test_gross_station_is_flagged_as_it_arrives_and_left_out():
    data = simulated(30, 5)
    B = data["B"].copy()
    B[20] = B[20] @ make_pose(so3_fast.exp(np.array([0.0, math.radians(5.0), 0.0])), np.zeros(3))
    session = Session("axyb", setup="eye-in-hand")
    updates = run(session, {"A": data["A"], "B": B})
    flagged = [u.station for u in updates if u.disagreement is not None]
    assert flagged == [20]
    d = updates[20].disagreement
    assert d.station == 20 and d.name == "station 21" and 4.0 < d.rotation_deg < 6.0 and d.p_value < 1e-10
    assert updates[20].used == 20 and updates[-1].used == 29 and updates[-1].stations == 30
    assert not session.kept[20] and session.left_out[0].station == 20 and len(session.names) == 30
    clean = handeye.solve("axyb", A=np.delete(data["A"], 20, axis=0), B=np.delete(B, 20, axis=0))
    rot, trans = gap(clean.unknowns["X"], updates[-1].unknowns["X"])
    assert rot < 0.05 * updates[-1].std["X"]["rotation_deg"]


def test_no_station_is_flagged_on_clean_data():
    for seed in range(6, 10):
        updates = run(Session("axyb", setup="eye-to-hand"), simulated(30, seed))
        assert all(u.disagreement is None for u in updates)


def test_station_noise_from_the_information_is_the_problems():
    """The station's own noise under the expected noise, recovered from the problem's station
    information and the model's Jacobian (`live_fit.residual_covariance`), is the residual
    covariance A X = Y B's planner builds the information from."""
    data, truth = PROBLEM.simulate(pairs=8, seed=12)  # noise free: the residuals vanish at the truth
    A, B, X, Y = data["A"], data["B"], truth["X"], truth["Y"]
    cov = np.broadcast_to(np.diag([0.002**2] * 3 + [0.5**2] * 3), (8, 6, 6))
    expected = axyb_planning.residual_covariance(A, B, X, Y, (0.0002, 0.05), cov)
    information = PROBLEM.station_information(A, B, {"X": X, "Y": Y}, (0.0002, 0.05), cov, "eye-in-hand")[0]
    _, J = live_fit.residual(live_fit.model_of(PROBLEM, A, B), X, Y)
    for i in range(8):
        got = live_fit.residual_covariance(J[i], information[i])
        scale = np.sqrt(np.outer(np.diag(expected[i]), np.diag(expected[i])))
        assert np.max(np.abs(got - expected[i]) / scale) < 1e-8


def test_gross_station_is_flagged_under_the_expected_noise():
    """Before 8 stations (no noise estimate yet) a station 1 deg off is flagged with the stated
    camera and robot noise (the simulation's: the default robot noise is a real arm's, 15x more);
    clean stations are not."""
    data = simulated(12, 5)
    B = data["B"].copy()
    B[5] = B[5] @ make_pose(so3_fast.exp(np.array([0.0, math.radians(1.0), 0.0])), np.zeros(3))
    stated = {"camera_sigma": (0.002, 0.5), "noise": Noise(robot=NOISE.sigmas["A"])}
    updates = run(Session("axyb", setup="eye-in-hand", **stated), {"A": data["A"], "B": B})
    assert [u.station for u in updates if u.disagreement is not None] == [5]
    assert updates[5].noise == "expected" and updates[5].disagreement.chi2 > 2 * live_fit.chi2_threshold(1e-4)
    for seed in range(20, 25):
        clean = run(Session("axyb", setup="eye-in-hand", **stated), simulated(12, seed))
        assert all(u.disagreement is None for u in clean) and clean[6].noise == "expected"


def test_unit_scales_the_robot_noise():
    """The same stations in m and in mm: the default robot noise (1.5 mm) follows the unit, so
    the expected 1-sigma is the same in rotation and 1000 times smaller in translation."""
    data = simulated(6, 13)
    in_m = {k: v.copy() for k, v in data.items()}
    for T in in_m.values():
        T[:, :3, 3] *= 1e-3
    mm = run(Session("axyb", setup="eye-in-hand", camera_sigma=(0.002, 0.5)), data)[-1]
    m = run(Session("axyb", setup="eye-in-hand", camera_sigma=(0.002, 0.5e-3), unit="m"), in_m)[-1]
    assert mm.noise == m.noise == "expected"
    for name in ("X", "Y"):
        assert m.std[name]["rotation_deg"] == pytest.approx(mm.std[name]["rotation_deg"], rel=1e-6)
        assert m.std[name]["translation"] == pytest.approx(1e-3 * mm.std[name]["translation"], rel=1e-6)
    wrong = run(Session("axyb", setup="eye-in-hand", camera_sigma=(0.002, 0.5e-3), unit="mm"), in_m)[-1]
    assert wrong.std["X"]["translation"] > 10 * m.std["X"]["translation"]  # 1.5 m of robot noise
    assert Session(setup="eye-in-hand", camera=CAMERA, board=BOARD.in_unit("m")).unit == "m"
    assert Session(setup="eye-in-hand").problem == get_registry().cell_problem()


# --------------------------------------------------------------------------- a planned cell

BOARD = parse_board("chessboard:9x6:25mm")
CAMERA = Camera(np.array([[1000.0, 0, 640], [0, 1000, 512], [0, 0, 1]]), np.zeros(0), (1280, 1024))
X_TRUE = make_pose(np.eye(3), np.array([0.0, 50.0, 80.0]))  # camera on the flange, looking along the tool axis
Y_TRUE = make_pose(np.diag([1.0, -1.0, -1.0]), np.array([600.0, 0.0, 0.0]))  # board on the table, face up
WORKSPACE = Workspace((200, -500, 100), (1000, 500, 1200), max_tilt_deg=60)


def recorded(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Planned stations with noise on the robot's and the camera's poses (own frames)."""
    p = plan("axyb", setup="eye-in-hand", X=X_TRUE, Y=Y_TRUE, camera=CAMERA, board=BOARD, count=count,
             workspace=WORKSPACE, pool=1500, seed=seed)
    rng = np.random.default_rng(seed)

    def noisy(T: np.ndarray, rot: float, trans: float) -> np.ndarray:
        return T @ make_pose(so3_fast.exp(rng.normal(0, rot, 3)), rng.normal(0, trans, 3))

    return (np.stack([noisy(a, 0.0002, 0.05) for a in p.A]), np.stack([noisy(b, 0.0003, 0.05) for b in p.B]))


def test_suggestions_respect_the_views_and_the_workspace():
    A, B = recorded(14, 1)
    session = Session("axyb", setup="eye-in-hand", camera=CAMERA, board=BOARD, workspace=WORKSPACE, suggest=3)
    seen = 0
    for a, b in zip(A, B):
        update = session.add(a, b)
        if update.unknowns is None:
            assert update.suggestions is None
            continue
        s = update.suggestions
        assert s is not None and len(s.A) == 3 and not update.warnings
        assert views.usable(BOARD, CAMERA, s.views, session.limits).all()
        box, tilt = WORKSPACE.holds(s.A)
        assert box.all() and tilt.all()
        # the suggested robot poses show the suggested views through the answer (A X = Y B)
        X, Y = update.unknowns["X"], update.unknowns["Y"]
        for a_s, b_s in zip(s.A, s.B):
            rot, trans = gap(a_s @ X, Y @ b_s)
            assert rot < 0.5 and trans < 10.0
        # they sharpen the answer: the predicted 1-sigma after them is below the current one
        assert s.std["X"]["rotation_deg"] < update.std["X"]["rotation_deg"]
        seen += 1
    assert seen == len(A) - 2


def test_suggestions_are_the_d_optimal_design():
    """The suggestions are `design.greedy`'s choice from the pool, added to the information of
    the 1-sigma reported (ridge once); for A X = X B on the camera's pose alone (the board's a
    nuisance). No random set of as many candidates does better."""
    A, B = recorded(10, 2)
    rng = np.random.default_rng(0)
    for problem, mask in (("axyb", None), ("axxb", np.repeat([True, False], 6))):
        session = Session(problem, setup="eye-in-hand", camera=CAMERA, board=BOARD, workspace=WORKSPACE, suggest=3)
        for a, b in zip(A, B):
            update = session.add(a, b)
        pool, prior = session._pool, session._noise()[1]
        chosen = design.greedy(pool.information, 3, prior=prior, interest=mask)
        assert np.array_equal(update.suggestions.A, pool.A[chosen])
        best = design.criterion(prior + pool.information[chosen].sum(axis=0), mask)
        others = [design.criterion(prior + pool.information[rng.choice(len(pool.A), 3, replace=False)].sum(axis=0),
                                   mask) for _ in range(300)]
        assert best > max(others)
        assert set(update.suggestions.std) == set(update.std) == ({"X", "Y"} if mask is None else {"X"})


def test_axxb_eye_to_hand_reports_the_camera():
    """Eye to hand, A X = X B's X is the camera's pose T_base_cam: A X = Y B's Y on the stations."""
    data = simulated(20, 14)
    both = run(Session("axyb", setup="eye-to-hand"), data)[-1]
    camera = run(Session("axxb", setup="eye-to-hand"), data)[-1]
    assert set(camera.unknowns) == set(camera.std) == {"X"}
    rot, trans = gap(camera.unknowns["X"], both.unknowns["Y"])
    assert rot < 1e-9 and trans < 1e-9
    for part in ("rotation_deg", "translation"):
        assert camera.std["X"][part] == pytest.approx(both.std["Y"][part], rel=1e-9)


def test_axxb_session_reports_the_camera_and_final_solves_the_motions():
    data = simulated(20, 11)
    session = Session("axxb", setup="eye-in-hand")
    last = run(session, data)[-1]
    assert set(last.unknowns) == {"X"} and set(last.std) == {"X"}
    final = session.final()
    assert final.problem == "axxb"
    rot, trans = gap(final.unknowns["X"], last.unknowns["X"])
    assert rot < 3 * last.std["X"]["rotation_deg"] and trans < 3 * last.std["X"]["translation"]


def test_bad_input_raises_session_errors():
    with pytest.raises(SessionError, match="serves problems " + ", ".join(planners()) + ", got 'axbycz'"):
        Session("axbycz", setup="eye-in-hand")
    with pytest.raises(SessionError, match="unit"):
        Session("axyb", setup="eye-in-hand", unit="inch")
    with pytest.raises(SessionError, match="setup"):
        Session("axyb", setup="sideways")
    with pytest.raises(SessionError, match="together"):
        Session("axyb", setup="eye-in-hand", camera=CAMERA)
    with pytest.raises(SessionError, match="positive"):
        Tolerance(-0.1, 0.5)
    session = Session("axyb", setup="eye-in-hand")
    with pytest.raises(SessionError, match="4x4"):
        session.add(np.eye(3), np.eye(4))
    with pytest.raises(ValueError):
        session.add(np.full((4, 4), np.nan), np.eye(4))
    assert len(session.names) == 0
    with pytest.raises(SessionError, match="at least 3"):
        session.final()


def test_chi_square_helpers():
    assert live_fit.chi2_threshold(1e-4) == pytest.approx(27.8563, abs=1e-3)
    assert live_fit.chi2_p_value(12.5916) == pytest.approx(0.05, rel=1e-4)


def test_a_repeated_station_adds_nothing_and_never_makes_enough():
    """One station recorded 30 times after 3 others: the robot's error at that pose is the same each
    time, so the repeats are left out with a warning naming the station they repeat; the 1-sigma
    never shrinks to ``enough`` (it said enough at 0.043 deg with X 0.24 deg off), and the answer
    rests on the 4 distinct stations."""
    data = simulated(4, 6)
    session = Session("axyb", setup="eye-in-hand", target=Tolerance(1.0, 10.0))
    updates = run(session, data)
    for _ in range(30):
        updates.append(session.add(data["A"][3], data["B"][3]))
    assert int(sum(session.kept)) == 4 and not any(u.enough for u in updates)
    assert "station 5 repeats station 4" in updates[4].warnings[0] and updates[-1].used == 4


def test_a_station_beyond_any_robot_cell_is_refused():
    """A translation of 1e300 (or 2 km) is no robot cell's: refused at once, naming the station,
    before it spoils the fit and every later station's test."""
    data = simulated(12, 7)
    session = Session("axyb", setup="eye-in-hand")
    run(session, {k: v[:6] for k, v in data.items()})
    far = data["B"][6].copy()
    far[:3, 3] = [1e300, 0.0, 0.0]
    with pytest.raises(SessionError, match="camera pose B of station 7 is 1e\\+300 mm from its origin, beyond any"):
        session.add(data["A"][6], far)
    far[:3, 3] = [2e6, 0.0, 0.0]
    with pytest.raises(SessionError, match="beyond any robot cell"):
        session.add(data["A"][6], far)
    assert session.add(data["A"][6], data["B"][6]).disagreement is None  # the session goes on
