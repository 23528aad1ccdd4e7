"""`so3-sdp`: Kronecker costs minimised under exact SO(3) constraints, with a certificate of global
optimality (docs/solvers/so3-sdp.md). This package registers its specs (the hook
`register_solvers`, entry point ``so3-sdp``) and re-exports the names other modules import from
``handeye.plugins.so3_sdp``.

Layout:
- `single`: ``axyb`` (eq. 8, two rotations) and ``axxb`` (one rotation), one pose per unknown;
  the SDP backends (clarabel, cvxpy, picos), `Options` and the shared pipeline
  `solve_relaxation` (local minimum and its certificate first, the SDP when that fails);
- `multi`: ``axyb-multi`` (stacks of X's and Y's), the same pipeline per connected component of
  the observation graph over its nX + nY rotations. Registered only when that problem is.

Settings and caches live in `single`: patch them there (``so3_sdp.single.CLARABEL_SETTINGS``),
since a name re-exported here is a second reference, not the one the pipeline reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from handeye import hookimpl
from handeye.estimation.rotation_cost import (
    RotationCost,
    eliminate_translations,
    rotations_vector,
)
from handeye.estimation.so3_relaxation import (
    GAP_THRESHOLD,
    RATIO_THRESHOLD,
    constraint_matrices,
)
from handeye.plugins.so3_sdp import multi, single
from handeye.plugins.so3_sdp.single import (
    CLARABEL_CACHE,
    CLARABEL_SETTINGS,
    CVXPY_CACHE,
    CVXPY_SETTINGS,
    SPEC,
    SPEC_AXXB,
    Options,
    clarabel_problem,
    cvxpy_problem,
    run,
    run_axxb,
    solve_relaxation,
)

__all__ = ["CLARABEL_CACHE", "CLARABEL_SETTINGS", "CVXPY_CACHE", "CVXPY_SETTINGS", "GAP_THRESHOLD",
           "RATIO_THRESHOLD", "SPEC", "SPEC_AXXB", "SPEC_MULTI", "Options", "RotationCost", "clarabel_problem",
           "constraint_matrices", "cvxpy_problem", "eliminate_translations", "multi", "rotations_vector", "run",
           "run_axxb", "run_multi", "single", "solve_relaxation"]

#: ``axyb-multi``: `handeye.plugins.so3_sdp.multi`
SPEC_MULTI = multi.SPEC
run_multi = multi.run



@hookimpl
def register_solvers(register: Any, problems: Mapping[str, Any]) -> None:
    register(SPEC)
    register(SPEC_AXXB)
    if multi.PROBLEM in problems:  # a problem of another plugin, which may be absent
        register(SPEC_MULTI)
