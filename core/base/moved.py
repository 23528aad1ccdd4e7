"""Old places of moved code keep working until `REMOVAL_DATE`, with a DeprecationWarning naming
the new place: the module paths (`handeye._MOVED`) and names moved out of a module that stays
(`moved_names`, a module's ``__getattr__``). docs/changelog.md lists both."""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Mapping
from typing import Any

#: the day the old paths stop importing (docs/changelog.md)
REMOVAL_DATE = "2027-06-01"


def moved_names(module: str, names: Mapping[str, str]) -> Callable[[str], Any]:
    """A ``__getattr__`` for `module` whose names `names` (name -> the module it now lives in)
    moved: the name from its new module, with a DeprecationWarning saying where."""

    def __getattr__(name: str) -> Any:
        new = names.get(name)
        if new is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} is now {new}.{name}: import it from there (the old name goes on "
                      f"{REMOVAL_DATE})", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(new), name)

    return __getattr__
