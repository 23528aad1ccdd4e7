"""`pairwise` for ``axyb-multi`` (plugins/pairwise.py): each (X, Y) pair solved alone as ``axyb``
and averaged. Noise-free data recovered exactly; a pair degenerate alone (or with too few
observations) is skipped and its unknowns answered by their other pairs; an unknown no pair
determines raises naming it; options and registration. Cells from multi_cells.py; through
`handeye.solve` once the problem is registered.
"""

from __future__ import annotations

import numpy as np
import pytest
from multi_cells import (
    PROBLEM,
    cell,
    concatenate,
    errors,
    observe,
    stations_about_one_axis,
    validated_cell,
)

import handeye
from handeye.plugins import pairwise
from handeye.plugins.kron_lstsq import multi

registered = pytest.mark.skipif(PROBLEM not in handeye.list_problems(),
                                reason=f"problem {PROBLEM!r} is not registered (yet)")


def solve(data, **options) -> handeye.SolverOutput:
    return pairwise.run(data, pairwise.Options(**options), "numpy")


def assert_exact(unknowns, truth, scale):
    for name, (rotation, translation) in errors(unknowns, truth).items():
        assert rotation < 1e-9 and translation < 1e-9 * scale, (name, rotation, translation)


@pytest.mark.parametrize("pair_solver", ["auto", "kron-lstsq"])
def test_noise_free_exact(pair_solver):
    raw, truth = cell(1, nX=2, nY=3)
    data = validated_cell(raw)
    out = solve(data, pair_solver=pair_solver)
    assert_exact(out.unknowns, truth, data.translation_scale)
    d = out.diagnostics
    assert d["pair_solver"] == pair_solver and d["pairs_used"] == 6 and not d["warnings"]
    assert all(r["used"] for r in d["pairs"])
    assert d["spread"]["X"]["X0"]["pairs"] == 3 and d["spread"]["Y"]["Y2"]["pairs"] == 2
    assert d["spread"]["X"]["X0"]["rotation_deg"] < 1e-9


def one_axis_pair(seed: int, truth, j: int, k: int, n: int = 8) -> dict:
    """n observations of (X_j, Y_k) at robot poses turning about one axis: degenerate alone."""
    index = np.full(n, 1)
    return observe(stations_about_one_axis(n, np.random.default_rng(seed)), truth["X"], truth["Y"],
                   index * j, index * k)


def test_a_pair_degenerate_alone_is_skipped_and_its_unknowns_come_from_other_pairs():
    """(X0, Y1) is seen only at robot poses turning about one axis; X0 is answered by (X0, Y0) and
    Y1 by (X1, Y1). (X1, Y0) has 2 observations, fewer than axyb needs."""
    raw, truth = cell(2, nX=2, nY=2, pairs=[(0, 0), (1, 1)])
    few = observe(raw["A"][:2], truth["X"], truth["Y"], np.array([1, 1]), np.array([0, 0]))
    data = validated_cell(concatenate(raw, one_axis_pair(3, truth, 0, 1), few))
    out = solve(data)
    assert_exact(out.unknowns, truth, data.translation_scale)
    records = {(r["X"], r["Y"]): r for r in out.diagnostics["pairs"]}
    assert records[("X0", "Y1")]["used"] is False
    assert records[("X0", "Y1")]["reason"] == "degenerate alone: all robot motions rotate about one axis"
    assert "DegenerateDataError" not in records[("X0", "Y1")]["reason"] and records[("X0", "Y1")]["error"]
    assert records[("X1", "Y0")] == {"X": "X1", "Y": "Y0", "observations": 2, "used": False,
                                     "reason": "2 observations, axyb needs at least 3"}
    assert records[("X0", "Y0")]["used"] and records[("X1", "Y1")]["used"]
    assert out.diagnostics["pairs_used"] == 2
    [warning] = out.diagnostics["warnings"]
    assert warning.startswith("pairwise: 2 of 4 (X, Y) pairs skipped")


def test_an_unknown_no_pair_determines_comes_from_the_joint_fit_named():
    """X 'marker 3' is seen by one camera only, at robot poses turning about one axis: no pair
    determines it alone. The cell is answered all the same (it refused the whole cell): the pairs
    that can give their averages, marker 3 is the joint fit's (solver auto: exact here, as
    kron-lstsq's joint solve is), and a warning names it and why its pair did not."""
    raw, truth = cell(4, nX=2, nY=2, pairs=[(0, 0), (0, 1)])
    data = validated_cell({**concatenate(raw, one_axis_pair(5, truth, 1, 0)), "x_names": ["marker 0", "marker 3"],
                           "y_names": ["cam 0", "cam 1"]})
    out = solve(data)
    assert_exact(out.unknowns, truth, data.translation_scale)
    [warning] = [w for w in out.diagnostics["warnings"] if "no pair alone determines" in w]
    assert ("X 'marker 3' (with Y 'cam 0': degenerate alone: all robot motions rotate about one axis): taken from "
            "the cell's joint fit (solver auto)") in warning
    assert_exact(multi.run(data, None, "numpy").unknowns, truth, data.translation_scale)


def test_noisy_answers_are_the_averages_of_the_pairs():
    """With noise each pair gives its own answer: the result is their chordal / arithmetic mean."""
    raw, truth = cell(7, nX=2, nY=2, noise=(0.002, 0.2))
    data = validated_cell(raw)
    out = solve(data, pair_solver="kron-lstsq")
    X0 = []
    for k in range(2):
        rows = data.observations_of(x=0, y=k)
        X0.append(handeye.solve("axyb", solver="kron-lstsq", A=data.A[rows], B=data.B[rows]).X)
    mean, _ = pairwise.average(X0)
    np.testing.assert_allclose(out.unknowns["X"][0], mean, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mean[:3, 3], (X0[0][:3, 3] + X0[1][:3, 3]) / 2, rtol=0, atol=1e-12)
    assert out.diagnostics["spread"]["X"]["X0"]["rotation_deg"] > 0
    err = errors(out.unknowns, truth)
    assert max(e[0] for e in err.values()) < 5e-3 and max(e[1] for e in err.values()) < 5.0, err


def test_options():
    with pytest.raises(handeye.UnknownPluginError, match="no-such-solver"):
        pairwise.Options(pair_solver="no-such-solver")
    with pytest.raises(handeye.InputError, match="pair_solver"):
        pairwise.Options(pair_solver=3)
    assert pairwise.SPEC.is_unit_invariant()  # auto is
    assert pairwise.SPEC.is_unit_invariant({"pair_solver": "kron-lstsq"})


def test_registered_only_with_axyb_multi():
    specs: list = []
    pairwise.register_solvers(specs.append, {"axyb": object()})
    assert specs == []
    pairwise.register_solvers(specs.append, {"axyb": object(), PROBLEM: object()})
    assert specs == [pairwise.SPEC] and pairwise.SPEC.problems == (PROBLEM,)


@registered
def test_through_solve():
    raw, truth = cell(8, nX=2, nY=2)
    sol = handeye.solve(PROBLEM, solver="pairwise", pair_solver="kron-lstsq", **raw)
    assert sol.status == handeye.Status.OPTIMAL, sol.warnings
    assert_exact(sol.unknowns, truth, validated_cell(raw).translation_scale)
    assert "pairwise" in handeye.list_solvers(PROBLEM)
