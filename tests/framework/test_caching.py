"""`handeye.framework.caching.cached_property`: computed once per instance, as functools'."""

from __future__ import annotations

import dataclasses

import pytest

from handeye.framework.caching import cached_property


@dataclasses.dataclass(frozen=True)
class _Data:
    x: float

    @cached_property
    def twice(self) -> float:
        """The doubled value (counted)."""
        _Data.calls += 1
        return 2 * self.x


def test_computed_once_per_instance_on_a_frozen_dataclass():
    _Data.calls = 0
    a, b = _Data(1.5), _Data(2.0)
    assert (a.twice, a.twice, b.twice) == (3.0, 3.0, 4.0)
    assert _Data.calls == 2
    assert "twice" in vars(a)
    assert dataclasses.replace(a, x=3.0).twice == 6.0  # a new instance computes its own
    assert _Data.__dict__["twice"].__doc__ == "The doubled value (counted)."
    assert isinstance(_Data.twice, type(_Data.__dict__["twice"]))  # read on the class: the descriptor


def test_one_property_under_two_names_is_refused():
    prop = cached_property(lambda self: 1)
    with pytest.raises((TypeError, RuntimeError)):
        type("Twice", (), {"a": prop, "b": prop})
