"""Solver options: each solver declares a frozen dataclass; unknown keys are errors.

`parse_options` builds that dataclass from keyword arguments and names the known options when a
key is wrong and refuses a non-bool for an option whose default is a bool; `check_choice` /
`check_positive` are small validators for ``__post_init__``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from typing import Any, TypeVar

import numpy as np

from .errors import InputError, UnknownPluginError

T = TypeVar("T")


@dataclasses.dataclass(frozen=True)
class NoOptions:
    """Options of a solver that takes none."""


def parse_options(cls: type[T], values: Mapping[str, Any], solver: str) -> T:
    """Instantiate the options dataclass `cls` from `values`; unknown keys raise, listing known.

    An option whose default is a bool must be given a bool (`check_bool`), for every solver,
    third parties' included: ``"False"`` would otherwise mean True."""
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    for key, value in values.items():
        if key not in fields:
            raise UnknownPluginError(
                "option", key, fields, owner=f"of solver {solver!r}",
                hint="Data fields and options are passed as keyword arguments to handeye.solve",
            )
        if isinstance(fields[key].default, bool):
            check_bool(key, value)
    return cls(**values)


def check_choice(name: str, value: Any, allowed: Collection[Any]) -> None:
    """Raise InputError unless `value` is one of `allowed`."""
    if value not in allowed:
        listing = ", ".join(repr(a) for a in allowed)
        raise InputError(f"option {name}={value!r} is not one of {listing}")


def check_positive(name: str, value: Any, *, allow_zero: bool = False) -> None:
    """Raise InputError unless `value` is a finite number > 0 (or >= 0 with allow_zero)."""
    try:
        ok = float(value) >= 0 if allow_zero else float(value) > 0
    except (TypeError, ValueError):
        ok = False
    if not ok or value != value or value in (float("inf"),):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"option {name}={value!r} must be a finite number {bound}")


def check_bool(name: str, value: Any) -> None:
    """Raise InputError unless `value` is a bool (``True``/``False``, or a numpy bool).

    Strings are refused rather than interpreted: ``"False"`` is truthy, so accepting it would
    silently mean True. The command line turns ``true``/``false`` (any case) into bools itself.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(
            f"option {name}={value!r} must be True or False (a bool), not a {type(value).__name__}"
        )
