"""`fu-dq`: the two-step dual-quaternion method for A_i X B_i = Y C_i Z (paper Sec. I and III.C, [23]).

Fu et al., "A Dual Quaternion-Based Approach for Coordinate Calibration of Dual Robots
in Collaborative Motion", IEEE Robotics and Automation Letters, 2020. The method needs the phase protocol: one stretch
of the recording with robot 2 holding still (C_i = C constant) while robot 1 moves.

Step 1 (X, from AX=XB). While C is constant, A_i X B_i = Y C Z is the same pose K for every
triple of the phase, so A_i X B_i = A_j X B_j, i.e.

    (A_j^-1 A_i) X = X (B_j B_i^-1)        (every pair i < j of the phase),

which is AX=XB (problem ``axxb``): the motions are `handeye.problems.axxb.relative_motions` of
the absolute poses A_k and B_k^-1 (A_k X = K B_k^-1 is its A_k X = Y B_k form). It is solved by
the registered ``axxb`` solver ``daniilidis`` (dual quaternions, Daniilidis 1999) by default.

Step 2 (Y and Z, from AX=YB). With X known, D_i = A_i X B_i is a measured pose for EVERY triple
and D_i = Y C_i Z reads

    C_i Z = Y^-1 D_i,

which is AX=YB (problem ``axyb``) with data (C_i, D_i) and unknowns (Z, Y^-1). It is solved by
the registered ``axyb`` solver ``dual-quaternion`` (the paper's eqs. 22-26) by default. Triples of
the phase (constant C) take part too; the rotations of C must vary elsewhere (robot 2 moving),
which ``axyb``'s validation checks.

Both steps run through the registry (`SolverSpec.run` of the named solvers on data validated by
their problems), so the axxb and axyb code is reused, not copied; the options ``step1`` and
``step2`` name other registered solvers of those problems (e.g. ``park``, ``auto``).

Phase detection. Triples i, j hold robot 2 "still" when C_i and C_j differ by at most
``still_rotation`` (rad, the angle of C_i^-1 C_j) and ``still_translation`` times the data's RMS
translation (`AXBYCZData.translation_scale`: relative, so the test does not depend on the unit).
The phase is the triple with the most still partners together with those partners; fewer than
`MIN_PHASE` triples is a one-line `InputError` (free-motion data). Defaults: 0.05 rad (2.9 deg) and
0.01 (7 mm on the simulator's cell, whose RMS translation is ~700 mm); simulated noise of
0.002 rad / 0.2 mm per axis on C moves a "still" pose by ~0.005 rad / 0.5 mm, and a robot that
moves at all moves far more than either bound.

Units. With ``normalize=True`` (default) every translation is divided by the data's RMS
translation before both steps and the answer scaled back, so the result does not depend on the
length unit (``daniilidis`` alone weighs rotation rows against translation rows by the unit).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from handeye import Solution, SolverOutput, SolverSpec, Status, hookimpl
from handeye.base.errors import (
    DegenerateDataError,
    HandEyeError,
    InputError,
    shown,
)
from handeye.framework.options import check_bool, check_positive
from handeye.geometry.se3 import inverse
from handeye.problems.axbycz import AXBYCZData
from handeye.problems.axxb import relative_motions

#: fewest triples of a phase: 3 stations give 3 motions, the least AX=XB needs (two rotation axes)
MIN_PHASE = 3
#: `still_pairs` tests the rotations of this many candidate pairs at a time (2 x 72 MB)
PAIRS_PER_CHUNK = 1_000_000
#: worst to best: the combined status of the two steps is the worst of theirs
_STATUS_ORDER = (Status.OPTIMAL, Status.UNCERTIFIED, Status.OPTIMAL_INACCURATE, Status.NOT_CONVERGED,
                 Status.FAILED)


@dataclasses.dataclass(frozen=True)
class Options:
    still_rotation: float = 0.05  # rad: C_i, C_j this close in rotation ...
    still_translation: float = 0.01  # ... and in translation (times the data's RMS translation) are "still"
    step1: str = "daniilidis"  # registered axxb solver for X
    step2: str = "dual-quaternion"  # registered axyb solver for (Z, Y^-1)
    normalize: bool = True

    def __post_init__(self) -> None:
        check_positive("still_rotation", self.still_rotation)
        check_positive("still_translation", self.still_translation)
        check_bool("normalize", self.normalize)
        for name, problem in (("step1", "axxb"), ("step2", "axyb")):
            _check_solver_name(name, getattr(self, name), problem)


def _check_solver_name(option: str, value: Any, problem: str) -> None:
    from handeye.host.registry import get_registry

    names = get_registry().solver_names(problem)
    if not isinstance(value, str) or value not in names:
        raise InputError(f"option {option}={shown(value)} is not a registered {problem} solver; use one of {', '.join(names)}")


def still_pairs(T: np.ndarray, rotation_tol: float, translation_tol: float) -> np.ndarray:
    """(k, 2) int: the pairs i < j (sorted) of poses T_i, T_j: (m, 4, 4) within rotation_tol (rad,
    angle of R_i^T R_j) and translation_tol (|t_i - t_j|, data units) of each other.

    A k-d tree on the translations proposes the pairs within translation_tol and the rotation
    angle decides, so time and memory grow with m and the pairs found, not with m^2 (the (m, m)
    tables took 58 ms at m = 1000, most of `auto`'s time on free motion, where this start is
    tried and refuses the data, and 2.4 GB at m = 10,000)."""
    from scipy.spatial import cKDTree

    R, t = T[:, :3, :3], T[:, :3, 3]
    pairs = cKDTree(t).query_pairs(translation_tol, output_type="ndarray")
    if not len(pairs):
        return np.empty((0, 2), dtype=np.intp)
    keep = np.empty(len(pairs), dtype=bool)
    for start in range(0, len(pairs), PAIRS_PER_CHUNK):  # bounded memory where one robot holds still long
        i, j = pairs[start:start + PAIRS_PER_CHUNK].T
        # angle of R_i^T R_j from its trace: tr = sum_kl R_i[k,l] R_j[k,l]
        keep[start:start + PAIRS_PER_CHUNK] = (np.einsum("nkl,nkl->n", R[i], R[j]) - 1.0) / 2.0 >= np.cos(rotation_tol)
    pairs = pairs[keep]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def find_phase(T: np.ndarray, rotation_tol: float, translation_tol: float) -> np.ndarray:
    """Indices (sorted) of the largest set of poses of T: (m, 4, 4) still with one of them: the
    pose with the most still partners (the first such) and those partners (`still_pairs`)."""
    pairs = still_pairs(T, rotation_tol, translation_tol)
    m = len(T)
    counts = np.bincount(pairs.ravel(), minlength=m)  # partners of each pose (itself not counted)
    best = int(np.argmax(counts))
    partners = np.concatenate([pairs[pairs[:, 0] == best, 1], pairs[pairs[:, 1] == best, 0], [best]])
    return np.sort(partners)


def _run_registered(problem: str, solver: str, step: str, advice: str, **fields: np.ndarray) -> Solution:
    """`solver` of `problem` (default options and backend) on the fields, validated by `problem`.
    Its errors say which step of fu-dq raised them; for degenerate data the first sentence of
    the problem's reason is kept and `advice` (what to record) replaces its own (which speaks of
    that problem's data and options, not of fu-dq's)."""
    from handeye import get_registry, run_registered

    try:
        data = get_registry().problem(problem).validate(**fields)
        return run_registered(solver, data, problem=problem)
    except DegenerateDataError as exc:
        reason = str(exc).split(". ")[0].rstrip(".")
        raise DegenerateDataError(f"fu-dq {step} ({problem}, solver {solver!r}): {reason}; {advice}") from None
    except HandEyeError as exc:
        raise type(exc)(f"fu-dq {step} ({problem}, solver {solver!r}): {exc}") from None


def _worst(*statuses: Status) -> Status:
    return max((Status(s) for s in statuses), key=lambda s: _STATUS_ORDER.index(s) if s in _STATUS_ORDER else 0)


def run(data: AXBYCZData, options: Options, backend: str) -> SolverOutput:
    scale = data.translation_scale if options.normalize else 1.0
    work = data.scaled(scale) if options.normalize else data
    phase = find_phase(work.C, float(options.still_rotation),
                       float(options.still_translation) * work.translation_scale)
    if len(phase) < MIN_PHASE:
        raise InputError(
            f"fu-dq needs >= {MIN_PHASE} triples with robot 2 holding still (C equal to within "
            f"{options.still_rotation:g} rad and {options.still_translation:g} x the RMS translation), "
            f"but at most {len(phase)} share one C: record robot 1 moving while robot 2 holds still "
            "(protocol 'phases'), or use solver 'wang' for free motion"
        )
    # step 1: (A_j^-1 A_i) X = X (B_j B_i^-1) over the pairs of the phase (module docstring)
    A1, B1 = relative_motions(work.A[phase], inverse(work.B[phase]), "all")
    first = _run_registered("axxb", options.step1, "step 1 (X from AX=XB)",
                            "record robot 1 rotating about at least two different axes while robot 2 holds still",
                            A=A1, B=B1)
    X = np.asarray(first.unknowns["X"], dtype=float)
    # step 2: C_i Z = Y^-1 (A_i X B_i), AX=YB in (Z, Y^-1)
    D = work.A @ X @ work.B
    second = _run_registered("axyb", options.step2, "step 2 (Y, Z from AX=YB)",
                             "record robot 2 rotating about at least two different axes (while robot 1 holds still)",
                             A=work.C, B=D)
    Z = np.array(second.unknowns["X"], dtype=float)
    Y = inverse(np.asarray(second.unknowns["Y"], dtype=float))
    X = X.copy()
    for T in (X, Y, Z):
        T[:3, 3] *= scale
    warnings = [f"fu-dq step 1 ({options.step1}): {w}" for w in first.diagnostics.get("warnings", [])]
    warnings += [f"fu-dq step 2 ({options.step2}): {w}" for w in second.diagnostics.get("warnings", [])]
    moving = len(data.A) - len(phase)
    return SolverOutput(
        unknowns={"X": X, "Y": Y, "Z": Z},
        status=_worst(first.status, second.status),
        diagnostics={
            "phase_triples": phase.tolist(),
            "step1_motions": len(A1),
            "step2_triples": data.m,
            "other_triples": moving,
            "step1": {"solver": options.step1, "status": str(first.status),
                      **{k: v for k, v in first.diagnostics.items() if k != "warnings"}},
            "step2": {"solver": options.step2, "status": str(second.status),
                      **{k: v for k, v in second.diagnostics.items() if k != "warnings"}},
            "normalize": options.normalize,
            "warnings": warnings,
        },
    )


SPEC = SolverSpec(
    name="fu-dq",
    problems=("axbycz",),
    run=run,
    options=Options,
    summary="two-step dual quaternions: X by AX=XB from a phase with robot 2 still, then Y, Z by AX=YB",
    citation="Fu et al., IEEE RA-L 2020 (the paper's [23]); Daniilidis, IJRR 18(3), 1999; Pan et al., IEEE T-ASE 2022, Sec. III.C",
    unit_invariant=lambda options: options.normalize,
    simulate_options={"protocol": "phases"},
)


@hookimpl
def register_solvers(register):
    register(SPEC)
