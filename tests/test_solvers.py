"""The shared solver suite: every registered solver of problem "axyb", on every backend.

Parametrised from the registry at collection time (fixture ``solver_backend`` in conftest.py, ids
"solver/backend"), so a new plugin, including an installed third-party one, is tested for free.
Unavailable backends are skipped with the solver's own reason. Bounds come from tolerances.py.

Per solver/backend this suite runs 8 solves (3 noise-free, 1 noisy shared by four tests, 2 for
the untouched-input / list-input check, 2 rescaled for unit invariance), plus 3 for each option
variant of the unit-invariance test (`invariance_variants`: at most 1 per solver), so that even
SDP solvers keep the whole project suite within its time budget.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from tolerances import DEFAULT, TOLERANCES, tolerance

import handeye
from handeye.errors import InputError, UnknownPluginError
from handeye.noise import NoiseModel
from handeye.problems.axyb import PROBLEM, random_truth
from handeye.se3 import rotation_angle

NOISE_FREE_SEEDS = (11, 12, 13)
NOISE_FREE_PAIRS = 12
NOISY_SEED = 2026
NOISY_PAIRS = 30
NOISY_MODEL = NoiseModel.on("B", 0.005, 0.5)
UNIT_SCALES = (1e-3, 1e3)
#: Option sets of the unit-invariance test besides the defaults and the other value of a bool
#: ``normalize`` option: the options a solver's declaration is known to depend on.
EXTRA_INVARIANCE_VARIANTS: dict[str, tuple[dict, ...]] = {"opencv": ({"method": "li"},)}
#: Where a solver declares the answer NOT unit invariant, it must change by more than this at one
#: of UNIT_SCALES (rotation [rad] or translation relative to the data scale), so that a wrong
#: declaration fails either way. Measured on the noisy case, normalize=False / method "li":
#: 1.4e-3 .. 2.3e-3 rad at s = 1e-3 (only ~1e-7 at s = 1e3, where translations dominate already).
NOT_INVARIANT_CHANGE = 1e-6


def _noise_free_case(seed: int):
    truth = random_truth(np.random.default_rng(seed))
    return PROBLEM.simulate(pairs=NOISE_FREE_PAIRS, seed=seed, X=truth["X"], Y=truth["Y"])


def _noisy_case():
    return PROBLEM.simulate(pairs=NOISY_PAIRS, seed=NOISY_SEED, noise=NOISY_MODEL)


@pytest.fixture(scope="module")
def noisy():
    return _noisy_case()


@pytest.fixture
def noisy_solution(solver_case, solve_once, noisy):
    data, _ = noisy
    return solve_once("noisy", solver_case, data)


@pytest.mark.parametrize("seed", NOISE_FREE_SEEDS)
def test_noise_free_recovery(solver_case, seed):
    data, truth = _noise_free_case(seed)
    scale = PROBLEM.validate(**data).translation_scale
    sol = handeye.solve("axyb", solver=solver_case.name, backend=solver_case.backend, **data)
    if solver_case.spec.exact:
        assert (solver_case.name, "noise_free") not in TOLERANCES, (
            f"{solver_case.name} declares exact=True but tolerances.py loosens its noise_free bounds; "
            "declare exact=False or meet the default"
        )
        tol = DEFAULT["noise_free"]
    else:
        tol = tolerance(solver_case.name, "noise_free")
    errors = PROBLEM.errors(sol.unknowns, truth)
    for name in ("X", "Y"):
        assert errors[name]["rotation"] < tol["rotation"], (name, errors)
        assert errors[name]["translation"] < tol["translation_rel"] * scale, (name, errors, scale)
    residuals = PROBLEM.residuals(PROBLEM.validate(**data), sol.unknowns)
    assert np.max(residuals["rotation"]) < 4 * tol["rotation"]
    assert np.max(residuals["translation"]) < 4 * tol["translation_rel"] * scale


def test_noisy_accuracy(solver_case, noisy_solution, noisy):
    _, truth = noisy
    tol = tolerance(solver_case.name, "noisy")
    assert noisy_solution.status in (handeye.Status.OPTIMAL, handeye.Status.OPTIMAL_INACCURATE,
                                     handeye.Status.UNCERTIFIED)
    errors = PROBLEM.errors(noisy_solution.unknowns, truth)
    for name in ("X", "Y"):
        assert errors[name]["rotation"] < tol["rotation"], (name, errors)
        assert errors[name]["translation"] < tol["translation"], (name, errors)


def test_output_is_exactly_se3(noisy_solution):
    assert set(noisy_solution.unknowns) == {"X", "Y"}
    for name, T in noisy_solution.unknowns.items():
        assert T is getattr(noisy_solution, name)
        assert isinstance(T, np.ndarray) and T.dtype == np.float64 and T.shape == (4, 4)
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), rtol=0, atol=1e-9)
        assert abs(np.linalg.det(R) - 1.0) < 1e-9
        assert T[3].tolist() == [0.0, 0.0, 0.0, 1.0]  # exactly
        assert np.all(np.isfinite(T))
        assert not T.flags.writeable
        with pytest.raises(ValueError):
            T[0, 3] = 1.0


def test_status_timing_and_names(solver_case, noisy_solution):
    assert isinstance(noisy_solution.status, handeye.Status)
    assert noisy_solution.seconds > 0
    assert noisy_solution.solver == solver_case.name
    assert noisy_solution.backend == solver_case.backend
    assert noisy_solution.problem == "axyb"
    assert isinstance(noisy_solution.warnings, list)
    assert noisy_solution.diagnostics["data"]["pairs"] == NOISY_PAIRS


def test_inputs_untouched_and_lists_accepted(solver_case, noisy, noisy_solution):
    data, _ = noisy
    A, B = np.array(data["A"]), np.array(data["B"])  # fresh writable arrays
    A_before, B_before = A.copy(), B.copy()
    sol = handeye.solve("axyb", solver=solver_case.name, backend=solver_case.backend, A=A, B=B)
    np.testing.assert_array_equal(A, A_before)
    np.testing.assert_array_equal(B, B_before)
    assert A.flags.writeable and B.flags.writeable  # the caller's arrays keep their flags
    A_list, B_list = A.tolist(), B.tolist()  # lists of 4x4 nested lists
    from_lists = handeye.solve("axyb", solver=solver_case.name, backend=solver_case.backend,
                               A=A_list, B=B_list)
    assert A_list == A_before.tolist() and B_list == B_before.tolist()
    for name in ("X", "Y"):
        np.testing.assert_allclose(from_lists.unknowns[name], sol.unknowns[name], rtol=0, atol=1e-9)
        np.testing.assert_allclose(sol.unknowns[name], noisy_solution.unknowns[name], rtol=0, atol=1e-9)


def invariance_variants(spec: handeye.SolverSpec) -> list[dict]:
    """Options the unit-invariance test tries: the defaults, the other value of a bool
    ``normalize`` option, and the solver's EXTRA_INVARIANCE_VARIANTS."""
    variants: list[dict] = [{}]
    normalize = {f.name: f for f in dataclasses.fields(spec.options)}.get("normalize")
    if normalize is not None and isinstance(normalize.default, bool):
        variants.append({"normalize": not normalize.default})
    return variants + list(EXTRA_INVARIANCE_VARIANTS.get(spec.name, ()))


def unit_change(solver_case, data: dict, base: handeye.Solution, s: float,
                options: dict) -> tuple[float, float]:
    """(rotation [rad], translation / data scale): the largest difference over X and Y between
    `base` and the answer for `data` with every translation multiplied by s (divided back)."""
    scaled = {k: np.array(v) for k, v in data.items()}
    for T in scaled.values():
        T[:, :3, 3] *= s
    sol = handeye.solve("axyb", solver=solver_case.name, backend=solver_case.backend, **scaled, **options)
    scale = PROBLEM.validate(**data).translation_scale
    new, old = sol.unknowns, base.unknowns
    angle = max(float(rotation_angle(new[n][:3, :3] @ old[n][:3, :3].T)) for n in ("X", "Y"))
    dt = max(float(np.linalg.norm(new[n][:3, 3] / s - old[n][:3, 3])) for n in ("X", "Y"))
    return angle, dt / scale


@dataclasses.dataclass(frozen=True)
class NormalizeOptions:
    normalize: bool = True


def test_is_unit_invariant_reads_a_bool_or_a_callable():
    def spec(unit_invariant):
        return handeye.SolverSpec(name="probe", problems=("axyb",), run=lambda *a: None,
                                  options=NormalizeOptions, unit_invariant=unit_invariant)

    assert spec(True).is_unit_invariant({"normalize": False}) is True  # a bool is the answer
    by_option = spec(lambda options: options.normalize)
    assert by_option.is_unit_invariant() is True  # None: the defaults
    assert by_option.is_unit_invariant({"normalize": False}) is False  # keywords, as for solve
    assert by_option.is_unit_invariant(NormalizeOptions(normalize=False)) is False  # an instance
    with pytest.raises(UnknownPluginError, match="normalise"):
        by_option.is_unit_invariant({"normalise": False})
    with pytest.raises(ValueError, match="unit_invariant must be a bool or a callable"):
        spec("yes")


def test_unit_invariance(solver_case, noisy, noisy_solution):
    """Invariant exactly where `is_unit_invariant(options)` says so, for each of the solver's
    `invariance_variants`: to the tolerance where declared, a real change where not."""
    data, _ = noisy
    tol = tolerance(solver_case.name, "unit_invariance")
    spec = solver_case.spec
    for options in invariance_variants(spec):
        base = noisy_solution if not options else handeye.solve(
            "axyb", solver=solver_case.name, backend=solver_case.backend, **data, **options)
        changes = {s: unit_change(solver_case, data, base, s, options) for s in UNIT_SCALES}
        if spec.is_unit_invariant(options):
            for s, (angle, dt) in changes.items():
                assert angle < tol["rotation"] and dt < tol["translation_rel"], (options, s, angle, dt)
        else:
            assert max(max(change) for change in changes.values()) > NOT_INVARIANT_CHANGE, (
                f"{solver_case.name} with options {options} is declared not unit invariant, but its "
                f"answer does not change with the unit: {changes}")


def test_bad_input_raises_right_type(solver_case, noisy):
    data, _ = noisy
    A, B = np.array(data["A"]), np.array(data["B"])
    run = dict(solver=solver_case.name, backend=solver_case.backend)
    A_nan = A.copy()
    A_nan[2, 0, 3] = np.nan
    with pytest.raises(InputError, match="NaN or inf"):
        handeye.solve("axyb", A=A_nan, B=B, **run)
    with pytest.raises(InputError, match="same length"):
        handeye.solve("axyb", A=A, B=B[:-1], **run)
    with pytest.raises(InputError, match=r"shape \(m, 4, 4\)"):
        handeye.solve("axyb", A=A[:, :3], B=B, **run)
    with pytest.raises(UnknownPluginError, match="no_such_option") as info:
        handeye.solve("axyb", A=A, B=B, no_such_option=1, **run)
    for option in solver_case.spec.option_names():
        assert repr(option) in str(info.value)
    np.testing.assert_array_equal(A, data["A"])
    np.testing.assert_array_equal(B, data["B"])
