"""`kron-lstsq`: closed-form least squares on the Kronecker systems of the problems
(docs/solvers/kron-lstsq.md). This package registers its specs (the hook `register_solvers`, entry
point ``kron-lstsq``) and re-exports the names other modules import from
``handeye.plugins.kron_lstsq``.

Layout:
- `single`: ``axyb`` (eq. 8), ``axxb`` (the sphere |vec R_X|^2 = 3), ``axbycz`` (the lifted
  system), each with one pose per unknown, and their planar mode; `Options` (``normalize``);
- `multi`: ``axyb-multi`` (several cameras and targets, stacked unknowns), per connected
  component of the observation graph; no options. Registered only when that problem is.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from handeye import hookimpl
from handeye.plugins.kron_lstsq import multi
from handeye.plugins.kron_lstsq.single import (
    SPEC,
    SPEC_AXBYCZ,
    SPEC_AXXB,
    Options,
    run,
    run_axbycz,
    run_axxb,
)

__all__ = ["SPEC", "SPEC_AXBYCZ", "SPEC_AXXB", "SPEC_MULTI", "Options", "run", "run_axbycz", "run_axxb",
           "run_multi"]

#: ``axyb-multi``: `handeye.plugins.kron_lstsq.multi`
SPEC_MULTI = multi.SPEC
run_multi = multi.run


@hookimpl
def register_solvers(register: Any, problems: Mapping[str, Any]) -> None:
    register(SPEC)
    register(SPEC_AXXB)
    register(SPEC_AXBYCZ)
    if multi.PROBLEM in problems:  # a problem of another plugin, which may be absent
        register(SPEC_MULTI)
