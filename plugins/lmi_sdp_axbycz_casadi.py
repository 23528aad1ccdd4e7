"""Backend ``casadi`` of `lmi-sdp` for ``axbycz``: the lifted Kronecker cost under EXACT SO(3)
constraints on R_X, R_Y, R_Z, as a CasADi NLP solved by IPOPT (what `lmi_sdp_casadi` does for
``axyb`` and ``axxb``). A helper module, not an entry point (`handeye.plugins.lmi_sdp_axbycz`).

1. Cost. |H beta(v) - w|^2 of the lifted system (`handeye.problems.axbycz.kronecker`) at the
   structured beta(v) of v = [vec R_X; vec R_Y; vec R_Z; t_X; t_Y; t_Z] (36): beta's lifted
   entries are the products vec R_Y vec R_Z^T, vec R_Y t_Z^T of v. At such a beta the cost is
   sum_i |top(A_i X B_i - Y C_i Z)|_F^2, the algebraic error of the equation over its 3 x 4 top
   rows (translations in the units of ``normalize``). It is quartic in v, given to the NLP as
   beta^T N beta - 2 g^T beta with N: (132, 132), g the normal equations (O(m) sums, passed as
   the NLP's parameters): one `nlpsol` serves every m and data set and is built once per IPOPT
   option set (cached). The translations are the NLP's variables in units of the data's RMS
   translation whatever ``normalize`` says (a change of variables, N -> D N D: the minimiser is
   unchanged and the variables are of order 1).
2. Constraints per rotation, columns c1, c2, c3: |c1|^2 = |c2|^2 = 1, c1.c2 = 0, c3 = c1 x c2 (6
   equations, exactly SO(3), independent on it: `lmi_sdp_casadi` point 2).
3. IPOPT from the `kron-lstsq` answer (|r|^2 = 12 least squares, rank-one extraction, SVD
   projection, translations of eq. 38) plus ``multistart`` seeded random rotations (translations
   by eq. 38 for them); the lowest cost of the converged starts wins. The cost is divided by the
   largest eigenvalue of D N D (Hessian of order 1). Statuses as `lmi_sdp_casadi` point 4.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import Any

import numpy as np

from handeye import SolverOutput
from handeye.framework.errors import InputError
from handeye.geometry.se3 import (
    make_pose,
    orthonormality_error,
    project_to_so3,
    random_rotations,
)
from handeye.plugins.lmi_sdp_casadi import (
    IPOPT_DEFAULTS,
    _captured_stdout,
    _constraint_violation,
    _option_key,
    check_starts,
    run_starts,
)
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axbycz import kronecker as lifted

_CACHE: dict[tuple, Any] = {}
_LOCK = threading.Lock()
N_BETA = lifted.N_BETA


def nlp_solver(ipopt_options: Mapping[str, Any] | None = None):
    """The CasADi IPOPT `nlpsol` of point 1 (x: v (36,); p: [vec N (column-major); g]; g: the 18
    SO(3) equations), built once per IPOPT option set and cached."""
    key, options = _option_key(ipopt_options)
    with _LOCK:
        solver = _CACHE.get(key)
        if solver is None:
            solver = _build(options)
            _CACHE[key] = solver
    return solver


def _build(options: Mapping[str, Any]):
    import casadi as ca

    v = ca.MX.sym("v", 36)
    p = ca.MX.sym("p", N_BETA * N_BETA + N_BETA)
    N = ca.reshape(p[:N_BETA * N_BETA], N_BETA, N_BETA)
    g_vec = p[N_BETA * N_BETA:]
    x, y, z, tX, tY, tZ = v[0:9], v[9:18], v[18:27], v[27:30], v[30:33], v[33:36]
    beta = ca.vertcat(x, ca.reshape(ca.mtimes(y, z.T), 81, 1), tX, ca.reshape(ca.mtimes(y, tZ.T), 27, 1), y, tY)
    f = ca.dot(beta, ca.mtimes(N, beta)) - 2 * ca.dot(g_vec, beta)
    g = []
    for k in range(0, 27, 9):
        c1, c2, c3 = v[k:k + 3], v[k + 3:k + 6], v[k + 6:k + 9]
        g += [ca.dot(c1, c1) - 1, ca.dot(c2, c2) - 1, ca.dot(c1, c2), c3 - ca.cross(c1, c2)]
    nlp = {"x": v, "p": p, "f": f, "g": ca.vertcat(*g)}
    opts = {"print_time": False, "error_on_fail": False, "show_eval_warnings": False, "calc_lam_p": False}
    opts.update({f"ipopt.{k}": value for k, value in options.items()})
    with _captured_stdout() as printed:
        try:
            return ca.nlpsol("lmi_sdp_axbycz_casadi", "ipopt", nlp, opts)
        except RuntimeError as exc:
            error = exc
    lines = [line.strip() for line in printed[0].splitlines() if line.strip()] or [str(error).strip().splitlines()[-1]]
    given = {k: value for k, value in options.items() if IPOPT_DEFAULTS.get(k, object()) != value}
    raise InputError(f"lmi-sdp/casadi: IPOPT rejected ipopt_options {given}: {lines[0]}")


def _beta(v: np.ndarray) -> np.ndarray:
    y = v[9:18]
    return np.concatenate([v[:9], np.outer(y, v[18:27]).ravel(order="F"), v[27:30],
                           np.outer(y, v[33:36]).ravel(order="F"), y, v[30:33]])


def _start(data: AXBYCZData, rotations: tuple[np.ndarray, ...], unit: float) -> np.ndarray:
    t = lifted.solve_translations(data, *rotations)
    return np.concatenate([R.ravel(order="F") for R in rotations] + [t[0] / unit, t[1] / unit, t[2] / unit])


def solve_casadi_axbycz(data: AXBYCZData, *, normalize: bool, multistart: int = 0, seed: int | None = None,
                        ipopt_options: Mapping[str, Any] | None = None) -> SolverOutput:
    """Minimise the lifted cost over SE(3)^3 with IPOPT (module docstring).

    data: validated `AXBYCZData` (at least 10 triples, rotations determined: the caller checks).
    normalize: the cost with translations divided by the data's RMS translation (unit invariant)
    or in the data's units. multistart (0 to 1000), seed (None or >= 0): extra random starts.
    Returns X, Y, Z exactly in SE(3), the chosen start's status and diagnostics as
    `lmi_sdp_casadi.solve_casadi` (``cost``: the lifted cost at the answer, normalised units when
    normalize). SolverError when no start gave an iterate.
    """
    check_starts(multistart, seed)
    unit = data.translation_scale
    scale = unit if normalize else 1.0
    N, g, ww = lifted.normal_equations(data, scale)
    D = np.ones(N_BETA)
    for block in (lifted.T_X, lifted.Q_YZ, lifted.T_Y):
        D[block] = unit / scale  # the NLP's translations in units of the RMS translation
    N, g = N * np.outer(D, D), g * D
    weight = float(np.linalg.eigvalsh(N)[-1]) or 1.0
    params = np.concatenate([N.ravel(order="F"), g]) / weight

    cost = lifted.LiftedCost.from_normal_equations(*lifted.normal_equations(data, scale))
    estimate = lifted.extract_rotations(lifted.sphere_least_squares(cost).x, cost)
    starts = [_start(data, estimate.rotations, unit)]
    if multistart:
        R = random_rotations(3 * int(multistart), np.random.default_rng(seed))
        starts += [_start(data, tuple(R[3 * j:3 * j + 3]), unit) for j in range(int(multistart))]

    def value(v: np.ndarray) -> float:
        b = _beta(v)
        return float(b @ N @ b - 2 * g @ b + ww)

    v_raw, status, diagnostics = run_starts(nlp_solver(ipopt_options), starts, params, value)
    Rs = [project_to_so3(v_raw[k:k + 9].reshape(3, 3, order="F")) for k in (0, 9, 18)]
    v = np.concatenate([R.ravel(order="F") for R in Rs] + [v_raw[27:]])
    t = v[27:] * unit
    return SolverOutput(
        unknowns={"X": make_pose(Rs[0], t[:3]), "Y": make_pose(Rs[1], t[3:6]), "Z": make_pose(Rs[2], t[6:])},
        status=status,
        diagnostics={
            **diagnostics,
            "cost": value(v),
            "constraint_violation": _constraint_violation(v_raw[:27]),
            "orthonormality_error": float(max(orthonormality_error(R) for R in Rs)),
            "translation_scale": scale,
            "normalized": bool(normalize),
        },
    )
