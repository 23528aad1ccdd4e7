"""The shared solver suite: every registered solver of every problem, on every backend.

Parametrised from the registry at collection time (fixture ``solver_backend`` in conftest.py, ids
"problem:solver/backend"), so a new plugin, including an installed third-party one, is tested
for free, and so is a solver name that serves a new problem. Unavailable backends are skipped
with the solver's own reason. Bounds come from tolerances.py.

The reference cases come from each problem's own simulator: noise-free data at random unknowns
(`Problem.random_unknowns`), and one noisy case per problem (`tolerances.NOISY`; a problem not listed there
gets noise on every data stack). Per solver/backend the suite runs 8 solves (3 noise-free, 1
noisy shared by four tests, 2 for the untouched-input / list-input check, 2 rescaled for unit
invariance), plus 3 for each option variant of the unit-invariance test (`invariance_variants`:
at most 1 per solver), so that even SDP solvers keep the suite within its time budget.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from tolerances import (
    DEFAULT,
    STATUS,
    TOLERANCES,
    clean_on_noisy,
    distance_bound,
    noisy_bound,
    noisy_case,
    tolerance,
)

import handeye
from handeye.base.errors import InputError, UnknownPluginError
from handeye.framework.solution import USABLE
from handeye.geometry.se3 import rotation_angle

NOISE_FREE_SEEDS = (11, 12, 13)
NOISE_FREE_PAIRS = 12
UNIT_SCALES = (1e-3, 1e3)
#: Option sets of the unit-invariance test besides the defaults and the other value of a bool
#: ``normalize`` option: the options a solver's declaration is known to depend on.
EXTRA_INVARIANCE_VARIANTS: dict[tuple[str, str], tuple[dict, ...]] = {("axyb", "opencv"): ({"method": "li"},)}
#: Where a solver declares the answer NOT unit invariant, it must change by more than this at one
#: of UNIT_SCALES (rotation [rad] or translation relative to the data scale), so that a wrong
#: declaration fails either way. Measured on the axyb noisy case, normalize=False / method "li":
#: 1.4e-3 .. 2.3e-3 rad at s = 1e-3 (only ~1e-7 at s = 1e3, where translations dominate already).
NOT_INVARIANT_CHANGE = 1e-6


def is_pose_stack(value) -> bool:
    """Whether a data field is a stack of poses (the others, e.g. the board's image observations
    of `reprojection` or the indices of `axyb-multi`, are passed through, and rescaled by their
    own `scaled` where they have one)."""
    return not hasattr(value, "scaled") and np.ndim(value) == 3 and np.shape(value)[1:] == (4, 4)


def rescaled(value, s: float):
    """A data field that is not a pose stack, with its lengths divided by s where it has any."""
    return value.scaled(s) if hasattr(value, "scaled") else value


def poses(T: np.ndarray) -> np.ndarray:
    """An unknown as a stack of poses: (1, 4, 4) for one pose, (k, 4, 4) for a stack."""
    return np.asarray(T).reshape(-1, 4, 4)


def fresh_arrays(data: dict) -> dict:
    """Writable copies of the pose stacks of `data`; other fields as they are."""
    return {k: np.array(v) if is_pose_stack(v) else v for k, v in data.items()}


def problem_of(case) -> handeye.Problem:
    return handeye.get_registry().problem(case.problem)


def noise_free_case(problem: handeye.Problem, seed: int, simulate_options=None):
    """Noise-free data with random unknowns; simulate_options: the solver's (SolverSpec)."""
    truth = problem.random_unknowns(np.random.default_rng(seed))
    return problem.simulate(pairs=NOISE_FREE_PAIRS, seed=seed, **truth, **(simulate_options or {}))


@pytest.fixture
def noisy(solver_case):
    return noisy_case(problem_of(solver_case), solver_case.spec.simulate_options)


@pytest.fixture
def noisy_solution(solver_case, solve_once, noisy):
    data, _ = noisy
    return solve_once("noisy", solver_case, data)


@pytest.mark.parametrize("seed", NOISE_FREE_SEEDS)
def test_noise_free_recovery(solver_case, seed):
    problem = problem_of(solver_case)
    data, truth = noise_free_case(problem, seed, solver_case.spec.simulate_options)
    scale = problem.validate(**data).translation_scale
    sol = solver_case.solve(**data)
    if solver_case.spec.exact:
        assert tolerance(solver_case.name, "noise_free", solver_case.problem) == DEFAULT["noise_free"], (
            f"{solver_case.name} declares exact=True but tolerances.py loosens its noise_free bounds; "
            "declare exact=False or meet the default"
        )
    tol = tolerance(solver_case.name, "noise_free", solver_case.problem)
    assert sol.diagnostics["self_check"]["reliable"], sol.warnings[:1]  # exact data: every check passes
    errors = problem.errors(sol.unknowns, truth)
    for name in problem.unknowns:
        assert errors[name]["rotation"] < tol["rotation"], (name, errors)
        assert errors[name]["translation"] < tol["translation_rel"] * scale, (name, errors, scale)
    residuals = problem.residuals(problem.validate(**data), sol.unknowns)
    assert np.max(residuals["rotation"]) < 4 * tol["rotation"]
    assert np.max(residuals["translation"]) < 4 * tol["translation_rel"] * scale


def test_noisy_accuracy(solver_case, noisy_solution, noisy):
    """Errors within the solver's own measured bounds (tolerances.noisy_bound: 2.5x its worst
    over 11 seeds; a solver not measured: the problem's default), the self-check's distance
    within its measured bound, and a solver whose answers were clean there stays clean."""
    _, truth = noisy
    case = (solver_case.problem, solver_case.name, solver_case.backend)
    tol = tolerance(solver_case.name, "noisy", solver_case.problem)
    expected = STATUS.get((solver_case.problem, solver_case.name, "noisy"))
    if expected is None:
        assert noisy_solution.status in USABLE, noisy_solution.warnings[:1]
    else:
        assert noisy_solution.status == expected
    # `suboptimal` exactly where the self-check says a fit of the same data is far better supported
    better = bool(noisy_solution.diagnostics["self_check"].get("better_fit"))
    assert not better or noisy_solution.status is not handeye.Status.OPTIMAL  # never optimal beside that warning
    assert better or noisy_solution.status is not handeye.Status.SUBOPTIMAL
    assert not better or any("standard deviations from the best fit" in w for w in noisy_solution.warnings)
    errors = problem_of(solver_case).errors(noisy_solution.unknowns, truth)
    for name in truth:
        for kind in ("rotation", "translation"):
            bound = noisy_bound(*case, name, kind)
            bound = tol[kind] if bound is None else min(bound, tol[kind])
            assert errors[name][kind] < bound, (name, kind, errors[name][kind], bound)
    check = noisy_solution.diagnostics["self_check"]
    distance = distance_bound(*case)
    if distance is not None:
        assert check.get("distance_sigmas", 0.0) <= max(distance, 1e-6), (check.get("distance_sigmas"), distance)
    if clean_on_noisy(*case):
        assert check["reliable"], check["failures"]
        assert not [w for w in noisy_solution.warnings if w.startswith("self-check:")], noisy_solution.warnings


def test_output_is_exactly_se3(solver_case, noisy_solution, noisy):
    assert set(noisy_solution.unknowns) == set(problem_of(solver_case).unknowns)
    sizes = problem_of(solver_case).stack_sizes(problem_of(solver_case).validate(**noisy[0]))
    for name, T in noisy_solution.unknowns.items():
        assert T is getattr(noisy_solution, name)
        shape = (sizes[name], 4, 4) if name in sizes else (4, 4)
        assert isinstance(T, np.ndarray) and T.dtype == np.float64 and T.shape == shape
        for P in poses(T):
            R = P[:3, :3]
            np.testing.assert_allclose(R.T @ R, np.eye(3), rtol=0, atol=1e-9)
            assert abs(np.linalg.det(R) - 1.0) < 1e-9
            assert P[3].tolist() == [0.0, 0.0, 0.0, 1.0]  # exactly
        assert np.all(np.isfinite(T))
        assert not T.flags.writeable
        with pytest.raises(ValueError):
            T[..., 0, 3] = 1.0


def test_status_timing_and_names(solver_case, noisy_solution, noisy):
    assert isinstance(noisy_solution.status, handeye.Status)
    assert noisy_solution.seconds > 0
    assert noisy_solution.solver == solver_case.name
    assert noisy_solution.backend == solver_case.backend
    assert noisy_solution.problem == solver_case.problem
    assert isinstance(noisy_solution.warnings, list)
    assert noisy_solution.diagnostics["data"]["pairs"] == len(noisy[0]["A"])


def test_inputs_untouched_and_lists_accepted(solver_case, noisy, noisy_solution):
    data, _ = noisy
    arrays = {k: v for k, v in fresh_arrays(data).items() if is_pose_stack(v)}  # fresh writable arrays
    others = {k: v for k, v in data.items() if k not in arrays}
    before = {k: v.copy() for k, v in arrays.items()}
    sol = solver_case.solve(**arrays, **others)
    for k in arrays:
        np.testing.assert_array_equal(arrays[k], before[k])
        assert arrays[k].flags.writeable  # the caller's arrays keep their flags
    lists = {k: v.tolist() for k, v in arrays.items()}  # lists of 4x4 nested lists
    from_lists = solver_case.solve(**lists, **others)
    for k in lists:
        assert lists[k] == before[k].tolist()
    for name in sol.unknowns:
        np.testing.assert_allclose(from_lists.unknowns[name], sol.unknowns[name], rtol=0, atol=1e-9)
        np.testing.assert_allclose(sol.unknowns[name], noisy_solution.unknowns[name], rtol=0, atol=1e-9)


def invariance_variants(case) -> list[dict]:
    """Options the unit-invariance test tries: the defaults, the other value of a bool
    ``normalize`` option, and the solver's EXTRA_INVARIANCE_VARIANTS."""
    variants: list[dict] = [{}]
    normalize = {f.name: f for f in dataclasses.fields(case.spec.options)}.get("normalize")
    if normalize is not None and isinstance(normalize.default, bool):
        variants.append({"normalize": not normalize.default})
    return variants + list(EXTRA_INVARIANCE_VARIANTS.get((case.problem, case.name), ()))


def unit_change(case, data: dict, base: handeye.Solution, s: float, options: dict) -> tuple[float, float]:
    """(rotation [rad], translation / data scale): the largest difference over the unknowns
    between `base` and the answer for `data` with every translation multiplied by s (divided back)."""
    scaled = {k: np.array(v) if is_pose_stack(v) else rescaled(v, 1.0 / s) for k, v in data.items()}
    for T in filter(is_pose_stack, scaled.values()):
        T[:, :3, 3] *= s
    sol = case.solve(**scaled, **options)
    problem = problem_of(case)
    scale = problem.validate(**data).translation_scale
    new, old = sol.unknowns, base.unknowns
    angle = max(float(rotation_angle(poses(new[n])[:, :3, :3] @ np.swapaxes(poses(old[n])[:, :3, :3], 1, 2)).max())
                for n in problem.unknowns)
    dt = max(float(np.linalg.norm(poses(new[n])[:, :3, 3] / s - poses(old[n])[:, :3, 3], axis=1).max())
             for n in problem.unknowns)
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
    tol = tolerance(solver_case.name, "unit_invariance", solver_case.problem)
    spec = solver_case.spec
    for options in invariance_variants(solver_case):
        base = noisy_solution if not options else solver_case.solve(**data, **options)
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
    first, second = problem_of(solver_case).data_fields[:2]
    arrays = fresh_arrays(data)
    nan = dict(arrays)
    nan[first] = arrays[first].copy()
    nan[first][1, 0, 3] = np.nan
    with pytest.raises(InputError, match="NaN or inf"):
        solver_case.solve(**nan)
    with pytest.raises(InputError, match="same length"):
        solver_case.solve(**{**arrays, second: arrays[second][:-1]})
    with pytest.raises(InputError, match=r"shape \(m, 4, 4\)"):
        solver_case.solve(**{**arrays, first: arrays[first][:, :3]})
    with pytest.raises(UnknownPluginError, match="no_such_option") as info:
        solver_case.solve(**arrays, no_such_option=1)
    for option in solver_case.spec.option_names():
        assert repr(option) in str(info.value)
    for k in data:
        np.testing.assert_array_equal(arrays[k], data[k])


def test_huge_translations_raise_input_error(solver_case):
    """Translations ~1e160 overflow the sums over the pairs: every solver reports it as bad input
    (ours), never as a bare numpy/scipy ValueError, FloatingPointError or LinAlgError."""
    data, _ = problem_of(solver_case).simulate(pairs=10, seed=1, **solver_case.spec.simulate_options)
    huge = fresh_arrays(data)
    for T in filter(is_pose_stack, huge.values()):
        T[:, :3, 3] *= 1e160
    with pytest.raises(handeye.InputError, match="overflow float64.*larger unit"):
        solver_case.solve(**huge)


def test_tolerance_overrides_name_registered_solvers():
    """A line of tolerances.py for a solver that no longer exists is a stale override."""
    reg = handeye.get_registry()
    for problem, solver, _ in TOLERANCES:
        assert solver in reg.solver_names(problem), (problem, solver)
