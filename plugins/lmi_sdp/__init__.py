"""`lmi-sdp`: the paper's method (Pan et al., IEEE T-ASE 2022, Sec. III.A, eqs. 5-14), for ``axyb``,
and its analogues for ``axxb`` and ``axbycz``. This package registers the three specs (the hook
`register_solvers`, entry point ``lmi-sdp``) and re-exports the names other modules import from
``handeye.plugins.lmi_sdp``.

Layout, each module importing only modules listed above it (no import cycle):
- `casadi`: backend ``casadi``, the three costs under exact SO(3) with IPOPT;
- `clarabel`: backend ``clarabel``, the three SDPs in Clarabel's own API;
- `common`: the options (`Options`, `AXXBOptions`), orthogonalisers, settings shared by the
  problems' SDPs, and how a backend's solve becomes a status and diagnostics;
- `axyb`: eq. 14 (the paper's LMI; `ScaledLMI`, `solve_lmi`) on clarabel, cvxpy and picos, and
  `run` for ``axyb``;
- `axxb`: the AX = XB SDP (|vec R_X|^2 = 3) and `run` for ``axxb``;
- `axbycz`: the AXB = YCZ SDP (|r|^2 = 12) or eq. 14 on the lifted system, `AXBYCZOptions`, and
  `run` for ``axbycz``;
- this ``__init__``: the three specs and the hook.
The backend scaffolding (cached cvxpy problems, solving with cvxpy, picos or Clarabel, option
``cvxpy_solver``) is `handeye.plugins._sdp_backends`, shared with `so3-sdp`.

Backends:
- ``clarabel`` (default): eq. 14 (`axyb`) in Clarabel's own API, its constant structure built once
  per n (`handeye.plugins.lmi_sdp.clarabel`): ~0.8 ms per solve at n = 24, 2-3x faster than
  ``cvxpy`` with the same Clarabel and the same answer (docs/solvers/lmi-sdp.md).
- ``cvxpy``: solver ``cvxpy_solver`` (default Clarabel; any installed cvxpy solver that
  handles PSD constraints). The problem is built ONCE per cvxpy solver with R, q, rest as
  Parameters (DPP: after the first solve cvxpy skips canonicalisation and only re-applies the
  parameters) and cached at module level; a lock per cached problem serialises its solves
  (`handeye.plugins._sdp_backends`).
- ``picos``: the same LMI through PICOS and CVXOPT. PICOS has no parameters for general
  constants, so its problem is rebuilt per call (13-20 ms per solve, ~10 ms of it CVXOPT).
- ``casadi``: NOT this LMI, an extension beyond the paper: the eq. 8 cost under exact SO(3)
  constraints, solved by IPOPT (`handeye.plugins.lmi_sdp.casadi.solve_casadi`); its options
  ``multistart``, ``seed``, ``ipopt_options`` apply to it alone, ``cvxpy_solver`` to cvxpy alone
  (InputError otherwise). Its rotations are exactly in SO(3), so ``orthogonalize`` leaves them
  unchanged, and its translations are already the least squares given its rotations, so
  ``translations="resolve"`` gives the same.

Options: ``orthogonalize="gram-schmidt"`` (the paper's) or ``"svd"`` (nearest rotation,
`project_to_so3`); ``translations="beta"`` (the paper's) or ``"resolve"`` (eqs. 20-21 given the
orthogonalised rotations); ``normalize=False`` (the paper works in the data's units; the answer
then depends on the length unit, so `unit_invariant` says False for it). With
``normalize=True`` translations are divided by the data's RMS translation before eq. 8 is built
and multiplied back afterwards: the answer is unit invariant (tested to 1e-9). With
``normalize=True`` the translations in beta are poorly determined (the rotation rows dominate);
combine it with ``translations="resolve"``.

Problem ``axxb`` (A_i X = X B_i): a second spec, `SPEC_AXXB`, runs `handeye.plugins.lmi_sdp.axxb`:
the same cost with the scale constraint |vec R_X|^2 = 3 that AX = XB needs (its rotation rows are
homogeneous), as a tight SDP over a 10 x 10 Z; same backends and options, plus ``polish``
(docs/solvers/lmi-sdp.md, section AX = XB).

Problem ``axbycz`` (A_i X B_i = Y C_i Z): a third spec, `SPEC_AXBYCZ`, runs
`handeye.plugins.lmi_sdp.axbycz` on the lifted Kronecker system of
`handeye.problems.axbycz.kronecker`: the scale of the lifted rotations fixed by |r|^2 = 12 as a
tight SDP (default, from 10 triples) or eq. 14 as it is (``scale="translations"``, from 15
triples); its options live there (`AXBYCZOptions`: defaults normalize=True,
translations="resolve").

Statuses: solver optimal -> optimal; optimal_inaccurate (Clarabel's AlmostSolved) ->
optimal_inaccurate; anything else (infeasible, unbounded, iteration limit, solver error) raises
`SolverError` naming the status.
On data whose translations are (near) zero eq. 8 cannot fix the scale of the rotations (its
rotation rows are homogeneous): a failure there raises `SolverError` saying so and naming
solver ``auto`` (`small_translations`), never a matrix of NaN.
"""

from __future__ import annotations

import dataclasses

from handeye import SolverSpec, hookimpl
from handeye.plugins._sdp_backends import sdp_cvxpy_solvers
from handeye.plugins.lmi_sdp import axbycz, axxb
from handeye.plugins.lmi_sdp.axbycz import AXBYCZOptions
from handeye.plugins.lmi_sdp.axyb import (
    CVXPY_CACHE,
    CVXPY_MAX_C,
    CVXPY_SETTINGS,
    SMALL_TRANSLATION,
    CvxpyLMI,
    ScaledLMI,
    SDPResult,
    cvxpy_problem,
    run,
    small_translations,
    solve_lmi,
)
from handeye.plugins.lmi_sdp.common import (
    BACKEND_ONLY_OPTIONS,
    ORTHOGONALIZERS,
    PICOS_SETTINGS,
    TRANSLATIONS,
    AXXBOptions,
    Options,
)

#: what ``handeye.plugins.lmi_sdp`` offers other modules (as the single-module plugin did)
__all__ = [
    "BACKEND_ONLY_OPTIONS", "CVXPY_CACHE", "CVXPY_MAX_C", "CVXPY_SETTINGS", "ORTHOGONALIZERS", "PICOS_SETTINGS",
    "SMALL_TRANSLATION", "SPEC", "SPEC_AXBYCZ", "SPEC_AXXB", "TRANSLATIONS", "AXBYCZOptions", "AXXBOptions",
    "CvxpyLMI", "Options", "SDPResult", "ScaledLMI", "cvxpy_problem", "register_solvers", "run",
    "sdp_cvxpy_solvers", "small_translations", "solve_lmi",
]

SPEC = SolverSpec(
    name="lmi-sdp",
    problems=("axyb",),
    run=run,
    backends={"clarabel": ("clarabel",), "cvxpy": ("cvxpy", "clarabel"), "picos": ("picos", "cvxopt"),
              "casadi": ("casadi",)},
    default_backend="clarabel",
    options=Options,
    summary="the paper's LMI-SDP (its optimum is the linear least squares of kron-lstsq), Gram-Schmidt; "
            "casadi: that least squares under exact SO(3)",
    citation="Pan et al., Toward Simultaneous Coordinate Calibrations of AX=YB Problem by the "
             "LMI-SDP Optimization, IEEE T-ASE 2022, eqs. 5-14",
    unit_invariant=lambda options: options.normalize,  # the paper-faithful default is not (docstring)
)

#: ``axxb``: the same cost, SDP lifted with the scale constraint |vec R_X|^2 = 3 (plugins/lmi_sdp/axxb.py),
#: the same options and backends.
SPEC_AXXB = dataclasses.replace(
    SPEC,
    problems=("axxb",),
    run=axxb.run,
    options=AXXBOptions,
    summary="the paper's LMI-SDP carried over to AX=XB: Kronecker cost with |vec R_X|^2 = 3 as a "
            "tight SDP (rank one), Gram-Schmidt; casadi: the cost under exact SO(3)",
    citation="Pan et al., IEEE T-ASE 2022, eqs. 5-14, carried over to AX=XB (docs/solvers/lmi-sdp.md)",
)

#: ``axbycz``: the lifted Kronecker system (plugins/lmi_sdp/axbycz.py), the same backends.
SPEC_AXBYCZ = dataclasses.replace(
    SPEC,
    problems=("axbycz",),
    run=axbycz.run,
    options=AXBYCZOptions,
    summary="the paper's LMI-SDP carried over to AXB=YCZ: lifted Kronecker cost with |r|^2 = 12 as a "
            "tight SDP (or the paper's unconstrained LMI), rank-one extraction, Gram-Schmidt; casadi: the cost under exact SO(3)",
    citation="Pan et al., IEEE T-ASE 2022, eqs. 5-14, carried over to AXB=YCZ on the lifting of Wu et al., "
             "IEEE T-RO 32(2), 2016 (docs/solvers/lmi-sdp.md)",
    simulate_options={"protocol": "free"},
)


@hookimpl
def register_solvers(register):
    register(SPEC)
    register(SPEC_AXXB)
    register(SPEC_AXBYCZ)
