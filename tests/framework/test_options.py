"""Solver options (handeye.framework.options): the shared validators, and bool options of every solver."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import handeye
from handeye.framework.options import check_bool, parse_options


def bool_options() -> list[tuple[str, str, str]]:
    """(solver, problem, option) for every option of a registered solver whose default is a bool."""
    reg = handeye.get_registry()
    return [(name, problem, f.name) for name, specs in sorted(reg.solvers.items())
            for problem, spec in specs.items()
            for f in dataclasses.fields(spec.options) if isinstance(f.default, bool)]


@pytest.mark.parametrize("value", [True, False, np.bool_(True), np.bool_(False)])
def test_check_bool_accepts_bools(value):
    check_bool("normalize", value)


@pytest.mark.parametrize("value", ["False", "true", "", 0, 1, None, 1.0])
def test_check_bool_rejects_everything_else_naming_option_and_value(value):
    with pytest.raises(handeye.InputError, match="option normalize=.* must be True or False") as info:
        check_bool("normalize", value)
    assert repr(value) in str(info.value)


def test_the_bool_options_we_know_of_are_all_found():
    assert {("kron-lstsq", "normalize"), ("li", "normalize"), ("dual-quaternion", "normalize"),
            ("lmi-sdp", "normalize"), ("so3-sdp", "normalize"), ("so3-sdp", "redundant"),
            ("so3-sdp", "polish")} <= {(s, o) for s, _, o in bool_options()}


@pytest.mark.parametrize("solver, problem, option", bool_options(),
                         ids=[f"{s}:{p}:{o}" for s, p, o in bool_options()])
def test_every_bool_option_rejects_a_string(solver, problem, option):
    """"False" is truthy: accepted, it would silently mean True. Every solver refuses it."""
    spec = handeye.get_registry().solver(solver, problem)
    with pytest.raises(handeye.InputError, match=f"option {option}='False' must be True or False"):
        parse_options(spec.options, {option: "False"}, solver)
    parse_options(spec.options, {option: False}, solver)  # the bool itself is fine


def test_solve_refuses_string_normalize_before_solving():
    data, _ = handeye.get_registry().problem("axyb").simulate(pairs=6, seed=1)
    with pytest.raises(handeye.InputError, match="normalize='False'"):
        handeye.solve("axyb", solver="kron-lstsq", normalize="False", **data)


def test_parse_options_checks_the_bool_options_of_any_solver():
    """The check sits in parse_options, so a third party's options class gets it without code."""

    @dataclasses.dataclass(frozen=True)
    class ThirdPartyOptions:
        verbose: bool = False
        level: int = 1

    with pytest.raises(handeye.InputError, match="option verbose='yes' must be True or False"):
        parse_options(ThirdPartyOptions, {"verbose": "yes"}, "third-party")
    assert parse_options(ThirdPartyOptions, {"verbose": True, "level": 2}, "third-party") == ThirdPartyOptions(True, 2)
