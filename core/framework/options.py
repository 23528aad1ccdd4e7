"""Solver options: each solver declares a frozen dataclass; unknown keys are errors.

`parse_options` builds that dataclass from keyword arguments and names the known options when a
key is wrong and refuses a non-bool for an option whose default is a bool; `check_choice`,
`check_positive` and `check_int` are small validators for ``__post_init__``.

The number validators take real numbers only (int, float and their numpy types): a string such
as ``"1e-8"`` is refused rather than converted, so that every solver sees the type it declares
(a solver doing ``tol * cost`` on a string fails deep inside), and a bool is refused as a number
(``max_iter=True`` would otherwise mean 1 iteration). The command line parses ``--option
tol=1e-8`` as JSON, so it passes numbers, not strings.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Collection, Mapping
from typing import Any, TypeVar

import numpy as np

from handeye.base.errors import InputError, UnknownPluginError, shown

T = TypeVar("T")


@dataclasses.dataclass(frozen=True)
class NoOptions:
    """Options of a solver that takes none."""


def parse_options(cls: type[T], values: Mapping[str, Any], solver: str) -> T:
    """Instantiate the options dataclass `cls` from `values`; unknown keys raise, listing known.

    An option whose default is a bool must be given a bool (`check_bool`), for every solver,
    third parties' included: ``"False"`` would otherwise mean True."""
    if not values:  # nothing to check: the defaults (twice a solve: the solver's and its start's)
        return cls()
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
    """Raise InputError unless `value` is one of `allowed` (compared as a plain value: an array
    or other container is refused, not compared element-wise)."""
    if not isinstance(value, (str, int, float, bool, type(None))) or value not in allowed:
        listing = ", ".join(repr(a) for a in allowed)
        raise InputError(f"option {name}={shown(value)} is not one of {listing}")


def check_positive(name: str, value: Any, *, allow_zero: bool = False) -> None:
    """Raise InputError unless `value` is a finite real number > 0 (or >= 0 with allow_zero);
    strings and bools are refused, not converted (module docstring)."""
    bound = ">= 0" if allow_zero else "> 0"
    _check_real(name, value, f"a finite number {bound}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond float64
        x = math.inf
    if not (math.isfinite(x) and (x >= 0 if allow_zero else x > 0)):
        raise InputError(f"option {name}={shown(value)} must be a finite number {bound}")


def check_int(name: str, value: Any, *, minimum: int | None = None, maximum: int | None = None) -> None:
    """Raise InputError unless `value` is an integer (int or numpy integer, not a bool, not a
    float such as 2.0 or 2.5) in [minimum, maximum] (either bound optional)."""
    if minimum is not None and maximum is not None:
        expected = f"an integer from {minimum} to {maximum}"
    elif minimum is not None:
        expected = f"an integer >= {minimum}"
    elif maximum is not None:
        expected = f"an integer <= {maximum}"
    else:
        expected = "an integer"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise _type_error(name, value, expected)
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise InputError(f"option {name}={shown(value)} must be {expected}")


def _check_real(name: str, value: Any, expected: str) -> None:
    """InputError unless `value` is a real number of Python or numpy (not a bool, not a string)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.integer, np.floating)):
        raise _type_error(name, value, expected)


def _type_error(name: str, value: Any, expected: str) -> InputError:
    hint = " (pass the number itself, not its text)" if isinstance(value, str) else ""
    return InputError(f"option {name}={shown(value)} must be {expected}, not a {type(value).__name__}{hint}")


def check_bool(name: str, value: Any) -> None:
    """Raise InputError unless `value` is a bool (``True``/``False``, or a numpy bool).

    Strings are refused rather than interpreted: ``"False"`` is truthy, so accepting it would
    silently mean True. The command line turns ``true``/``false`` (any case) into bools itself.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(
            f"option {name}={shown(value)} must be True or False (a bool), not a {type(value).__name__}"
        )
