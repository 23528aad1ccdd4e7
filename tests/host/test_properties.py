"""Property tests (hypothesis) of the contract of `handeye.solve`, over every registered problem,
solver and backend, and the reliability campaign's bound on confident wrong answers.

The contract (`check_contract`), for any input whatever:

- the call returns a `Solution` or raises one of handeye's own errors (`HandEyeError`, the
  ``ValueError`` subclass every exported error derives from): never a bare numpy / scipy /
  casadi / cvxpy exception, ``TypeError``, ``ZeroDivisionError``, ``RecursionError`` or
  ``MemoryError``; the message of the error, and of every warning, is one non-empty line;
- the caller's inputs are not modified (compared with deep copies taken before the call);
- every unknown returned is exactly in SE(3): finite, R^T R = I to 1e-9, det R = +1, last row
  exactly [0, 0, 0, 1];
- the status agrees with the host's self-check (`handeye.checks.self_check`): an answer the
  self-check finds unreliable never has a usable status (optimal, optimal_inaccurate,
  uncertified) and carries the self-check's "self-check failed" warning; status ``unreliable``
  comes with its reason as the first warning.

It is checked on valid data (`test_contract_on_simulated_data`: the problem's own simulator at
hypothesis-drawn pair counts, seeds and noise), on corrupted data (`test_contract_on_corrupted_data`:
every variant of each of `CORRUPTIONS`: wrong shapes, NaN/inf, huge values, non-rotations, too few
or mismatched pairs, wrong types, sequences, missing and extra fields, degenerate and mismatched
data; hypothesis draws the data, field, pose and sizes), with every option of every solver set to
each of `GARBAGE` (`test_option_values_keep_the_contract`) or to an array, and on the campaign's
data. Every hypothesis test is derandomised with a bounded number of examples
(`PROPERTY_SETTINGS`), so CI runs the same examples every time.

`test_no_confident_wrong_answer_in_the_campaign` solves the seeded reliability campaign
(`handeye.harness.campaign`: heavy noise, pure rotation, tiny cell, weak excitation, planar,
outliers) with every solver of "axyb" and "axxb" and bounds the error of every answer reported
as usable without a self-check warning.

Findings are strict xfails naming what is wrong (`ARRAY_OPTION_FINDINGS`, the last section): the
suite stays green, and fixing one makes its test fail until the mark goes.
"""

from __future__ import annotations

import copy
import dataclasses
import decimal
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

import handeye
from handeye import Status
from handeye.base.errors import HandEyeError
from handeye.checks.self_check import (
    DISTANCE_WARN,
    PRECISION_ROTATION_DEG,
    PRECISION_TRANSLATION,
)
from handeye.estimation.kronecker import translation_rms
from handeye.estimation.noise import NoiseModel
from handeye.harness.campaign import KINDS, cases, solver_runs

#: statuses under which a user may use the answer (the self-check turns them into unreliable)
USABLE = (Status.OPTIMAL, Status.OPTIMAL_INACCURATE, Status.UNCERTIFIED)
#: first words of the reason for status unreliable: the host's self-check (handeye.solve), or the
#: plausibility checks of `handeye calibrate` / `handeye solve` (handeye.workflow.plausibility)
UNRELIABLE_REASONS = ("self-check failed", "implausible fit")
#: keyword names of `handeye.solve` itself (a data field or option cannot take them)
SOLVE_KEYWORDS = ("problem", "solver", "backend")

#: derandomised (the same examples on every run: CI is deterministic; no example database), no
#: deadline (the machine is shared; an SDP solve takes 0.1-0.5 s)
PROPERTY_SETTINGS: dict[str, Any] = {
    "deadline": None, "derandomize": True, "database": None,
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.filter_too_much],
}
#: examples per (problem, solver, backend): the default backend of a solver, and its other backends
#: (slower SDP front ends, cvxpy / picos, which solve the same formulation as the default)
EXAMPLES_VALID = {"default": 25, "other": 6}
EXAMPLES_CORRUPTED = {"default": 2, "other": 1}


def _run(case) -> tuple[str, str, str]:
    return case.problem, case.name, case.backend


def examples(case, budget: dict[str, int]) -> int:
    return budget["default" if case.backend == case.spec.default_backend else "other"]


# --------------------------------------------------------------------------- the contract


def _same(a: Any, b: Any, seen: set[int] | None = None) -> bool:
    """Whether `a` (after the call) equals `b` (its deep copy before): NaN equal to NaN, arrays by
    value, dtype and shape, sequences and mappings item by item (a sequence that contains itself
    once)."""
    seen = set() if seen is None else seen
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)):
            return False
        if a.dtype != b.dtype or a.shape != b.shape:
            return False
        if isinstance(a, np.ma.MaskedArray) and not np.array_equal(np.ma.getmaskarray(a), np.ma.getmaskarray(b)):
            return False
        if a.dtype.kind in "fc":
            return bool(np.array_equal(a, b, equal_nan=True))
        return bool(np.array_equal(a, b)) if a.dtype != object else _same(a.tolist(), b.tolist(), seen)
    if isinstance(a, (list, tuple, dict)):
        if id(a) in seen:
            return True
        seen.add(id(a))
        if isinstance(a, dict):
            return type(b) is dict and a.keys() == b.keys() and all(_same(a[k], b[k], seen) for k in a)
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y, seen) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if type(a).__eq__ is object.__eq__:  # no value to compare (a plain object): its type
        return type(a) is type(b)
    return bool(a == b)


def _copy(value: Any) -> Any:
    """A deep copy of `value` to compare with after the call; `value` itself when it has none (a
    generator: it is consumed, not modified)."""
    try:
        return copy.deepcopy(value)
    except TypeError:
        return value


def _one_line(text: str, what: str) -> None:
    assert isinstance(text, str) and text.strip(), f"{what} is empty: {text!r}"
    assert "\n" not in text and "\r" not in text, f"{what} is not one line: {text!r}"


def check_contract(problem: str, solver: str, backend: str, data: dict[str, Any]) -> handeye.Solution | None:
    """Solve `data` (fields and options) of `problem` with `solver` on `backend`; assert the
    contract of the module docstring; return the solution, or None when handeye refused the
    input with one of its own errors."""
    before = {k: _copy(v) for k, v in data.items()}
    writeable = {k: v.flags.writeable for k, v in data.items() if isinstance(v, np.ndarray)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numerical libraries' own warnings are not the contract
            sol = handeye.solve(problem, solver=solver, backend=backend, **data)
    except HandEyeError as exc:
        _one_line(str(exc), f"{type(exc).__name__} message")
        sol = None
    # anything else propagates: a bare numpy/scipy/casadi/cvxpy error, TypeError, ZeroDivisionError,
    # RecursionError, MemoryError ... fails the test with its traceback
    for k, v in data.items():
        assert _same(v, before[k]), f"input {k!r} was modified in place"
        assert not isinstance(v, np.ndarray) or v.flags.writeable == writeable[k], f"the flags of input {k!r} changed"
    if sol is None:
        return None
    assert set(sol.unknowns) == set(handeye.get_registry().problem(problem).unknowns)
    for name, T in sol.unknowns.items():
        assert isinstance(T, np.ndarray) and T.shape[-2:] == (4, 4) and T.ndim in (2, 3), (name, T)
        assert T.dtype == np.float64 and np.all(np.isfinite(T)), (name, T)
        for P in T.reshape(-1, 4, 4):  # one pose, or a stack (`Problem.stack_sizes`)
            R = P[:3, :3]
            assert np.abs(R.T @ R - np.eye(3)).max() <= 1e-9, (name, T)
            assert abs(np.linalg.det(R) - 1.0) <= 1e-9, (name, T)
            assert P[3].tolist() == [0.0, 0.0, 0.0, 1.0], (name, T)
    assert isinstance(sol.status, Status)
    for w in sol.warnings:
        _one_line(w, "warning")
    check = sol.diagnostics["self_check"]
    if not check["reliable"]:
        assert sol.status not in USABLE, (sol.status, check["failures"])
        assert any(w.startswith("self-check failed") for w in sol.warnings), sol.warnings
    if sol.status is Status.UNRELIABLE:
        assert sol.warnings and sol.warnings[0].startswith(UNRELIABLE_REASONS), sol.warnings[:1]
    return sol


def _pairs_range(problem) -> tuple[int, int]:
    """Pair counts to simulate: from the problem's minimum (at least 3: an axxb simulation of n
    stations gives n (n - 1) / 2 motions) to a few more than the paper's 16."""
    return max(3, problem.min_pairs), 20


@dataclasses.dataclass(frozen=True)
class Simulated:
    """The simulation parameters of one example (shown by hypothesis when a property fails)."""

    pairs: int
    seed: int
    rot: float
    trans: float

    def data(self, problem) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        noise = NoiseModel.on(problem.data_fields, self.rot, self.trans)
        return problem.simulate(pairs=self.pairs, seed=self.seed, noise=noise)


def simulations(problem) -> st.SearchStrategy[Simulated]:
    low, high = _pairs_range(problem)
    return st.builds(Simulated, pairs=st.integers(low, high), seed=st.integers(0, 2**32 - 1),
                     rot=st.floats(0.0, 0.05), trans=st.floats(0.0, 5.0))


def test_contract_on_simulated_data(solver_case):
    problem = handeye.get_registry().problem(solver_case.problem)

    @settings(max_examples=examples(solver_case, EXAMPLES_VALID), **PROPERTY_SETTINGS)
    @given(simulations(problem))
    def check(sim: Simulated) -> None:
        data, _ = sim.data(problem)
        writable = {k: np.array(v) for k, v in data.items()}  # the user's own writable arrays
        check_contract(*_run(solver_case), writable)

    check()


# --------------------------------------------------------------------------- corruptions


@dataclasses.dataclass(frozen=True)
class Corruption:
    """A kind of bad input: its variants (each tested for every solver), and apply(variant, draw,
    data, problem, spec) -> the keyword arguments of `handeye.solve` made from valid `data`, with
    any further choice (field, pose, size, value) drawn by hypothesis from `draw`."""

    kind: str
    variants: tuple[str, ...]
    apply: Callable[[str, st.DataObject, dict[str, np.ndarray], Any, Any], dict[str, Any]]


CORRUPTIONS: dict[str, Corruption] = {}


def corruption(*variants: str):
    def register(fn):
        kind = fn.__name__.replace("_", "-")
        CORRUPTIONS[kind] = Corruption(kind, variants, fn)
        return fn

    return register


def _field(draw: st.DataObject, problem) -> str:
    return draw.draw(st.sampled_from(problem.data_fields), label="field")


def _pose(draw: st.DataObject, stack: Any) -> int:
    return draw.draw(st.integers(0, len(stack) - 1), label="pose")


SHAPES: dict[str, Callable[[np.ndarray], Any]] = {
    "(m, 4, 3)": lambda T: T[:, :, :3], "(m, 3, 4)": lambda T: T[:, :3, :], "(m, 3, 3)": lambda T: T[:, :3, :3],
    "(4, 4, m)": lambda T: np.moveaxis(T, 0, -1), "(m, 16)": lambda T: T.reshape(len(T), 16),
    "(4, 4)": lambda T: T[0], "(1, m, 4, 4)": lambda T: T[None], "(0, 4, 4)": lambda T: T[:0],
    "(m, 4, 4, 1)": lambda T: T[..., None], "()": lambda T: np.float64(1.0), "(m,)": lambda T: T[:, 0, 0],
    "(m, 5, 5)": lambda T: np.pad(T, ((0, 0), (0, 1), (0, 1))), "(0,)": lambda T: np.empty(0),
    "(m, 4, 4) Fortran order": lambda T: np.asfortranarray(T), "(m, 4, 4) strided": lambda T: np.repeat(T, 2, 0)[::2],
}


@corruption(*SHAPES)
def wrong_shape(variant, draw, data, problem, spec):
    name = _field(draw, problem)
    return {**data, name: SHAPES[variant](data[name])}


@corruption("nan", "inf", "-inf")
def non_finite(variant, draw, data, problem, spec):
    name = _field(draw, problem)
    T = data[name].copy()
    T[_pose(draw, T), draw.draw(st.integers(0, 3), label="row"), draw.draw(st.integers(0, 3), label="column")] = \
        float(variant)
    return {**data, name: T}


@corruption("translation", "everything")
def huge(variant, draw, data, problem, spec):
    """Finite entries whose squares or sums overflow float64."""
    name = _field(draw, problem)
    T = data[name].copy()
    factor = draw.draw(st.sampled_from([1e150, 1e200, 1e300, 1.7e308]), label="factor")
    i = _pose(draw, T)
    with np.errstate(over="ignore"):  # the largest factors overflow some entries to inf: also bad input
        if variant == "translation":
            T[i, :3, 3] *= factor
        else:
            T[:, :3, 3] *= factor
    return {**data, name: T}


@corruption("scaled", "reflection", "shear", "zero", "perturbed", "last-row", "projective")
def not_a_rotation(variant, draw, data, problem, spec):
    name = _field(draw, problem)
    T = data[name].copy()
    i = _pose(draw, T)
    eps = 10.0 ** draw.draw(st.floats(-12.0, -1.0), label="log10 size")
    if variant == "scaled":
        T[i, :3, :3] *= draw.draw(st.floats(0.0, 3.0), label="scale")
    elif variant == "reflection":
        T[i, :3, draw.draw(st.integers(0, 2), label="column")] *= -1.0
    elif variant == "shear":
        T[i, 0, 1] += eps
    elif variant == "zero":
        T[i, :3, :3] = 0.0
    elif variant == "perturbed":  # all over, around the orthonormality tolerance: some pass validation
        T[:, :3, :3] += eps * np.random.default_rng(draw.draw(st.integers(0, 2**32 - 1), label="seed")) \
            .standard_normal((len(T), 3, 3))
    elif variant == "last-row":
        T[i, 3, draw.draw(st.integers(0, 3), label="last-row column")] += eps
    else:
        T[i, 3] = (eps, 0.0, 0.0, 1.0 + eps)
    return {**data, name: T}


@corruption("both", "one")
def few_pairs(variant, draw, data, problem, spec):
    """0 pairs up to a few more than the minimum (the smallest accepted counts reach the solver),
    in every field or in one (mismatched lengths)."""
    k = draw.draw(st.integers(0, problem.min_pairs + 2), label="pairs")
    if variant == "both":
        return {name: T[:k] for name, T in data.items()}
    name = _field(draw, problem)
    return {**data, name: data[name][:min(k, len(data[name]) - 1)]}


def _dtype_variant(variant: str, T: np.ndarray, i: int) -> Any:
    if variant == "str":
        return T.astype(str)
    if variant == "bytes":
        return T.astype(bytes)
    if variant == "text":
        return "A.csv"
    if variant == "object":
        return T.astype(object)
    if variant == "object-None":
        value = T.astype(object)
        value[i, 0, 0] = None
        return value
    if variant == "object-text":
        value = T.astype(object)
        value[i, 0, 3] = "12.5 mm"
        return value
    if variant == "decimal":
        return [[[decimal.Decimal(repr(float(x))) for x in row] for row in P] for P in T]
    if variant == "bool":
        return T > 0.5
    if variant == "int":
        return np.rint(T).astype(np.int64)
    if variant == "uint8":
        return np.abs(T).astype(np.uint8)
    if variant in ("float32", "float16", "longdouble", "complex"):
        return T.astype({"float32": np.float32, "float16": np.float16, "longdouble": np.longdouble,
                         "complex": complex}[variant])
    if variant == "complex-imag":
        value = T.astype(complex)
        value[i, 0, 3] += 1e-3j
        return value
    if variant == "datetime":
        return np.zeros(T.shape, dtype="datetime64[s]")
    if variant == "void":
        return np.zeros(T.shape, dtype="V8")
    if variant == "structured":
        return np.zeros(T.shape, dtype=[("x", float), ("y", float)])
    if variant == "masked":
        value = np.ma.masked_array(T.copy(), mask=np.zeros(T.shape, bool))
        value[i, 0, 3] = np.ma.masked
        return value
    if variant == "masked-nothing":  # a masked array with nothing masked is an ordinary array
        return np.ma.masked_array(T.copy())
    if variant == "matrices":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PendingDeprecationWarning)  # numpy's view of np.matrix
            return [np.asmatrix(P) for P in T]
    if variant == "read-only":
        value = T.copy()
        value.setflags(write=False)
        return value
    raise AssertionError(variant)


@corruption("str", "bytes", "text", "object", "object-None", "object-text", "decimal", "bool", "int", "uint8",
            "float32", "float16", "longdouble", "complex", "complex-imag", "datetime", "void", "structured",
            "masked", "masked-nothing", "matrices", "read-only")
def wrong_dtype(variant, draw, data, problem, spec):
    name = _field(draw, problem)
    return {**data, name: _dtype_variant(variant, data[name], _pose(draw, data[name]))}


def _sequence_variant(variant: str, T: np.ndarray, i: int) -> Any:
    lists = T.tolist()
    if variant == "lists":  # valid
        return lists
    if variant == "tuples":  # valid
        return tuple(tuple(tuple(r) for r in P) for P in lists)
    if variant == "list-of-arrays":  # valid
        return [np.array(P) for P in T]
    if variant == "ragged-pose":
        return lists[:i] + [lists[i][:3]] + lists[i + 1:]
    if variant == "ragged-row":
        lists[i][1] = lists[i][1][:3]
        return lists
    if variant == "nested-deeper":
        lists[i][0][0] = [lists[i][0][0]]
        return lists
    if variant == "generator":
        return (P for P in T)
    if variant == "set":
        return {1.0, 2.0}
    if variant == "dict":
        return {"x": 1.0, "y": 2.0}
    if variant == "dict-of-poses":
        return {str(k): P for k, P in enumerate(lists)}
    if variant == "none":
        return None
    if variant == "empty-list":
        return []
    if variant == "list-with-none":
        return lists[:i] + [None] + lists[i + 1:]
    if variant == "range":
        return range(len(T))
    if variant == "self-containing":
        value: list[Any] = []
        value.append(value)
        return value
    raise AssertionError(variant)


@corruption("lists", "tuples", "list-of-arrays", "ragged-pose", "ragged-row", "nested-deeper", "generator", "set",
            "dict", "dict-of-poses", "none", "empty-list", "list-with-none", "range", "self-containing")
def sequences(variant, draw, data, problem, spec):
    name = _field(draw, problem)
    return {**data, name: _sequence_variant(variant, data[name], _pose(draw, data[name]))}


@corruption("missing", "extra", "renamed", "only-one", "none-given")
def fields(variant, draw, data, problem, spec):
    """A missing field, an unknown one (taken as an option, refused), a field in lower case."""
    name = _field(draw, problem)
    if variant == "missing":
        return {k: v for k, v in data.items() if k != name}
    if variant == "extra":
        extra = draw.draw(st.text("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_", min_size=1, max_size=8)
                          .filter(lambda s: s not in data and s not in SOLVE_KEYWORDS and s not in spec.option_names()),
                          label="extra field")
        return {**data, extra: data[name]}
    if variant == "renamed":
        return {**{k: v for k, v in data.items() if k != name}, name.lower(): data[name]}
    if variant == "only-one":
        return {name: data[name]}
    return {}


@corruption("identical-poses", "no-rotation", "one-axis", "no-translation", "identity", "swapped", "same-stack",
            "shuffled", "inverted", "unit-mm-to-m", "duplicated")
def degenerate(variant, draw, data, problem, spec):
    """Well-formed data that cannot determine the unknowns, or pairs that do not belong together."""
    first, second = problem.data_fields[:2]
    A, B = data[first].copy(), data[second].copy()
    rng = np.random.default_rng(draw.draw(st.integers(0, 2**32 - 1), label="seed"))
    if variant == "identical-poses":
        A[:], B[:] = A[0], B[0]
    elif variant == "no-rotation":
        A[:, :3, :3] = np.eye(3)
        B[:, :3, :3] = np.eye(3)
    elif variant == "one-axis":  # every rotation about z, on both sides
        for S in (A, B):
            theta = rng.uniform(-np.pi, np.pi, len(S))
            S[:, :3, :3] = 0.0
            S[:, 0, 0], S[:, 0, 1], S[:, 1, 0], S[:, 1, 1], S[:, 2, 2] = (np.cos(theta), -np.sin(theta),
                                                                          np.sin(theta), np.cos(theta), 1.0)
    elif variant == "no-translation":
        A[:, :3, 3] = 0.0
        B[:, :3, 3] = 0.0
    elif variant == "identity":
        A[:], B[:] = np.eye(4), np.eye(4)
    elif variant == "swapped":
        A, B = B, A
    elif variant == "same-stack":
        B = A.copy()
    elif variant == "shuffled":
        B = B[rng.permutation(len(B))]
    elif variant == "inverted":
        B = np.linalg.inv(B)
        B[:, 3] = (0.0, 0.0, 0.0, 1.0)
    elif variant == "unit-mm-to-m":
        B[:, :3, 3] *= 1e-3
    else:
        A, B = np.concatenate([A, A]), np.concatenate([B, B])
    return {**data, first: A, second: B}


def corrupted_bases(problem) -> st.SearchStrategy[Simulated]:
    """The valid data a corruption starts from: few pairs (so that what reaches a solver is cheap),
    noise-free or with the paper's noise."""
    low, _ = _pairs_range(problem)
    return st.builds(Simulated, pairs=st.integers(low, 8), seed=st.integers(0, 2**32 - 1),
                     rot=st.sampled_from([0.0, 0.002]), trans=st.sampled_from([0.0, 0.2]))


def _check_variant(case, kind: str, variant: str) -> None:
    """The contract on `examples` hypothesis examples of one variant of a corruption."""
    problem = handeye.get_registry().problem(case.problem)

    @settings(max_examples=examples(case, EXAMPLES_CORRUPTED), **PROPERTY_SETTINGS)
    @given(base=corrupted_bases(problem), draw=st.data())
    def check(base: Simulated, draw: st.DataObject) -> None:
        note(f"corruption {kind}: {variant}")
        data, _ = base.data(problem)
        data = {k: np.array(v) for k, v in data.items()}
        check_contract(*_run(case), CORRUPTIONS[kind].apply(variant, draw, data, problem, case.spec))

    check()


@pytest.mark.parametrize("kind", sorted(CORRUPTIONS))
def test_contract_on_corrupted_data(solver_case, kind):
    """Every variant of the corruption `kind` (a loop, so that each is tried), on data and with
    choices drawn by hypothesis."""
    for variant in CORRUPTIONS[kind].variants:
        _check_variant(solver_case, kind, variant)


# --------------------------------------------------------------------------- option values


#: values of a solver option: every option of every solver must solve (a valid value) or refuse
#: them with our one-line error (`test_option_values_keep_the_contract`)
GARBAGE = {
    "none": None, "true": True, "false": False, "zero": 0, "negative": -1, "huge-int": 10**400,
    "nan": math.nan, "inf": math.inf, "-inf": -math.inf, "tiny": 5e-324, "float": 0.5, "large": 1e300,
    "text": "yes", "number-text": "1e-8", "empty-text": "", "list": [1, 2], "array-of-one": np.zeros(1),
    "dict": {"a": 1}, "complex": 1 + 2j, "float32": np.float32(0.5), "int64": np.int64(3),
    "bool_": np.bool_(True), "decimal": decimal.Decimal("0.1"), "object": object(),
}
#: an array of several values, refused with our one-line error (`test_an_array_option_value_is_refused`)
ARRAY = np.zeros((2, 2))


#: Findings (strict xfails, see `option_cases`): (solver, option) -> what is wrong; none open.
ARRAY_OPTION_FINDINGS: dict[tuple[str, str], str] = {}


def option_cases(findings: dict[tuple[str, str], str] | None = None) -> list[Any]:
    """(problem, solver, backend, option) for every option of every registered solver, on every
    backend (an option of another backend must be refused too); strict xfail where `findings`
    (keyed by (solver, option)) names a finding."""
    reg = handeye.get_registry()
    findings = findings or {}
    return [pytest.param(p, n, b, o, id=f"{p}:{n}/{b}-{o}",
                         marks=[pytest.mark.xfail(strict=True, reason=findings[n, o])] if (n, o) in findings else [])
            for p in sorted(reg.problems) for n in reg.solver_names(p) for b in reg.solver(n, p).backends
            for o in reg.solver(n, p).option_names()]


def _option_data(problem: str) -> dict[str, np.ndarray]:
    data, _ = handeye.get_registry().problem(problem).simulate(pairs=4, seed=0, noise=NoiseModel.on("B", 0.002, 0.2))
    return data


def _skip_unavailable(problem: str, solver: str, backend: str) -> None:
    reason = handeye.get_registry().solver(solver, problem).unavailable_reason(backend)
    if reason:
        pytest.skip(f"{solver}/{backend} unavailable: {reason}")


@pytest.mark.parametrize(("problem", "solver", "backend", "option"), option_cases())
def test_option_values_keep_the_contract(problem, solver, backend, option):
    """Each of `GARBAGE` as the option's value: solved (a valid value) or refused with our error."""
    _skip_unavailable(problem, solver, backend)
    data = _option_data(problem)
    for value in GARBAGE.values():
        check_contract(problem, solver, backend, {**data, option: value})


@pytest.mark.parametrize(("problem", "solver", "backend", "option"), option_cases(ARRAY_OPTION_FINDINGS))
def test_an_array_option_value_is_refused(problem, solver, backend, option):
    """No option takes a 2x2 array: it is refused with our one-line error (strict xfail where
    `ARRAY_OPTION_FINDINGS` names a finding: fixing it makes these tests fail until the entry goes)."""
    _skip_unavailable(problem, solver, backend)
    assert check_contract(problem, solver, backend, {**_option_data(problem), option: ARRAY}) is None


# --------------------------------------------------------------------------- the campaign

#: Cases of the campaign per problem (5 of each of its 6 kinds), and its seed.
CAMPAIGN_RUNS = 30
CAMPAIGN_SEED = 0
#: The bound on a confident answer (usable status, reliable, no self-check warning), in degrees:
#: its largest rotation error over the unknowns must stay below both
#:  - ABSOLUTE_LIMIT_DEG, 4 x `PRECISION_ROTATION_DEG`: the self-check stays silent only where
#:    the data determine every rotation to 0.25 deg (1-sigma) or better, so a silent answer
#:    1 deg off is at least 4 sigma off in the worst direction; and
#:  - RELATIVE_LIMIT (5 x auto's error + 3 x auto's 1-sigma on the same case): "wrong" measured
#:    against what the data allow (the campaign's own target; docs of handeye.harness.campaign).
#: Measured (axyb: 11 solver runs, axxb: 12): over this test's 30 cases the worst silent answer is
#: 0.13 deg (pure-rotation, lmi-sdp/casadi) and the largest error / relative limit 0.50; over
#: 240 further cases (seed 100) 0.30 deg and 0.80. A silent answer beyond either limit is what
#: the self-check exists to prevent.
ABSOLUTE_LIMIT_DEG = 4 * PRECISION_ROTATION_DEG
RELATIVE_LIMIT = (5.0, 3.0)
#: The same bound on the translations, as a fraction of the data's lever arm (their RMS
#: translation, `translation_scale`): 4 x `PRECISION_TRANSLATION` (a silent answer is determined
#: to 1% of it, so 4% off is 4 sigma off), and 5 x auto's error + 3 x auto's 1-sigma.
#: Measured: over this test's 30 cases the worst silent
#: answer is 0.28% of the lever arm (axyb; axxb 0.21%), the largest error / limit 0.49 (axxb
#: 0.34); over 240 further cases (seed 100) 3.3% and 0.93 (axxb 0.87% and 0.60).
ABSOLUTE_LIMIT_TRANSLATION = 4 * PRECISION_TRANSLATION
#: warnings of the self-check that are not failures: the distance from the best fit, and the
#: precision the data give (handeye.checks.self_check._local_fit / _precision)
SELF_CHECK_WARNINGS = ("self-check:", "the data determine the rotation", "the data determine the translation")
#: fewest confident answers per problem for the bound to mean something (measured: 86 for axyb,
#: 113 for axxb; planar cases are now refused by every solver without the unobservable offsets)
MIN_CONFIDENT = 50


def _self_check_warned(sol: handeye.Solution) -> bool:
    """Whether the self-check warned about `sol`: by its words, or by its figures (distance from
    the best fit beyond DISTANCE_WARN, a rotation's 1-sigma beyond PRECISION_ROTATION_DEG), so that
    rewording a warning does not make this test count a warned answer as confident."""
    check = sol.diagnostics["self_check"]
    return (any(w.startswith(SELF_CHECK_WARNINGS) for w in sol.warnings)
            or check.get("distance_sigmas", 0.0) > DISTANCE_WARN or _rotation_sigma_deg(sol) > PRECISION_ROTATION_DEG)


def _translation_sigma(sol: handeye.Solution) -> float:
    """The largest 1-sigma (data unit, worst direction) of the translations for `sol`."""
    return max((s["translation"] for s in sol.diagnostics["self_check"].get("std", {}).values()), default=0.0)


def _lever_arm(data: dict) -> float:
    """The data's lever arm: the RMS translation of A and B (`translation_rms`, what validated
    data call `translation_scale`)."""
    return float(translation_rms(np.asarray(data["A"], dtype=float), np.asarray(data["B"], dtype=float)))


def _rotation_sigma_deg(sol: handeye.Solution) -> float:
    """The largest 1-sigma (deg, worst direction) of the rotations the self-check gives for `sol`."""
    return max((s["rotation_deg"] for s in sol.diagnostics["self_check"].get("std", {}).values()), default=0.0)


@pytest.mark.parametrize("problem", ["axyb", "axxb"])
def test_no_confident_wrong_answer_in_the_campaign(problem):
    """Every solver on the campaign's cases: the contract, and no answer beyond the limits above
    that is reported usable (status optimal, optimal_inaccurate or uncertified), reliable and
    without a self-check warning. (The loop is `campaign.run_case`'s, keeping each Solution.)"""
    prob = handeye.get_registry().problem(problem)
    runs = solver_runs(problem)
    assert ("auto", "numpy") in runs
    kinds, confident_wrong, checked = set(), [], 0
    for case in cases(CAMPAIGN_RUNS, KINDS, CAMPAIGN_SEED):
        kinds.add(case.kind)
        data, truth = case.data(problem)
        solutions = {run: check_contract(problem, *run, data) for run in runs}
        auto = solutions[("auto", "numpy")]
        relative = relative_trans = math.inf  # auto refused the data (e.g. planar ones, without the unobservable offsets)
        if auto is not None:
            auto_error = max(math.degrees(e["rotation"]) for e in prob.errors(auto.unknowns, truth).values())
            relative = RELATIVE_LIMIT[0] * auto_error + RELATIVE_LIMIT[1] * _rotation_sigma_deg(auto)
            auto_trans = max(e["translation"] for e in prob.errors(auto.unknowns, truth).values())
            relative_trans = RELATIVE_LIMIT[0] * auto_trans + RELATIVE_LIMIT[1] * _translation_sigma(auto)
        lever = _lever_arm(data)
        for (name, backend), sol in solutions.items():
            if sol is None or sol.status not in USABLE or not sol.diagnostics["self_check"]["reliable"]:
                continue
            if _self_check_warned(sol):
                continue
            checked += 1
            errors = prob.errors(sol.unknowns, truth).values()
            error = max(math.degrees(e["rotation"]) for e in errors)
            limit = ABSOLUTE_LIMIT_DEG if name == "auto" else min(ABSOLUTE_LIMIT_DEG, relative)
            if error > limit:
                confident_wrong.append((case.kind, case.seed, name, backend, sol.status.value, round(error, 3),
                                        round(limit, 3), "deg"))
            trans = max(e["translation"] for e in errors)
            trans_limit = ABSOLUTE_LIMIT_TRANSLATION * lever
            trans_limit = trans_limit if name == "auto" else min(trans_limit, relative_trans)
            if trans > trans_limit:
                confident_wrong.append((case.kind, case.seed, name, backend, sol.status.value, round(trans, 3),
                                        round(trans_limit, 3), "translation"))
    assert kinds == set(KINDS)
    assert checked >= MIN_CONFIDENT, f"only {checked} confident answers: the bound is hardly tested"
    assert not confident_wrong, ("answers reported usable, without a self-check warning, beyond the limit "
                                 f"(kind, seed, solver, backend, status, error, limit, unit): {confident_wrong}")


# --------------------------------------------------------------------------- found on valid data
# Not breaches of the contract above (the status said "do not use" and why), but the default
# solver's status on valid simulated data that it solves correctly: exact data at 3 pairs ran to
# max_iter (now: stop at rounding, `handeye.estimation.nlls.ROUNDING`); rotation-exact data with noisy
# translations failed check 1 (now: the rotation a fit trades for translation noise counts).


def test_auto_converges_on_exact_data_with_three_pairs():
    problem = handeye.get_registry().problem("axyb")
    data, truth = problem.simulate(pairs=3, seed=9)
    sol = handeye.solve("axyb", **data)
    assert max(e["rotation"] for e in problem.errors(sol.unknowns, truth).values()) < 1e-9
    assert sol.status is Status.OPTIMAL, sol.warnings[:1]


def test_auto_is_reliable_on_axxb_data_without_rotation_noise():
    problem = handeye.get_registry().problem("axxb")
    data, truth = problem.simulate(pairs=3, seed=0, noise=NoiseModel.on(("A", "B"), 0.0, 0.5))
    sol = handeye.solve("axxb", **data)
    assert math.degrees(problem.errors(sol.unknowns, truth)["X"]["rotation"]) < 0.05
    assert sol.status is Status.OPTIMAL, sol.warnings[:1]
