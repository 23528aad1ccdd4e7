"""`pairwise`: the baseline of a cell with several cameras and targets (``axyb-multi``): solve each
(X, Y) pair alone as ``axyb`` and average (docs/solvers/pairwise.md).

For every observed pair (X_j, Y_k) its observations A_i X_j = Y_k B_i are validated by the registry's
``axyb`` problem and solved by the registered ``axyb`` solver `Options.pair_solver` (default
``auto``) through the host (`handeye.run_registered`, which applies that solver's checks and
options). A pair is skipped when it has fewer observations than ``axyb`` needs, when its data are
degenerate alone (e.g. robot poses that rotate about one axis only), or when its solve fails or
returns an answer its solver does not stand behind (not_converged, failed); the reasons are in
``diagnostics["pairs"]``. Then each X_j is the average of the X_j of the pairs that gave one: the
chordal L2 mean of the rotations (the SVD projection of their sum: Hartley et al., "Rotation
Averaging", IJCV 2013, Sec. 5.3) and the mean of the translations, each pair counting once; each
Y_k likewise. An unknown that no pair determines alone is the cell's joint fit's (`JOINT_SOLVER`),
with a warning naming it and why its pairs did not; DegenerateDataError only where that fails too.

Only a baseline: a pair alone ignores what the other pairs say about its X and Y (an X seen by
three cameras is fitted three times from a third of the data each, and an X or Y whose pairs are
each degenerate alone stays undetermined although the cell determines it jointly), and the plain
mean weighs a pair of 4 observations as much as one of 400. Solving the cell jointly (``auto``,
``kron-lstsq``, ``refine`` for ``axyb-multi``) uses every observation once, for every unknown.

Units: rotations are averaged unit-free and translations linearly, so the answer is unit
invariant exactly when the pair solver is (``auto`` and ``kron-lstsq`` are).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from handeye import (
    DegenerateDataError,
    HandEyeError,
    InputError,
    SolverOutput,
    SolverSpec,
    Status,
    hookimpl,
    run_registered,
)
from handeye.base.errors import shown
from handeye.framework.solution import USABLE
from handeye.geometry.se3 import make_pose, project_to_so3, rotation_angle

if TYPE_CHECKING:
    from handeye.problems.axyb_multi.data import AXYBMultiData

#: the problem it solves and the problem each pair is solved as
PROBLEM = "axyb-multi"
PAIR_PROBLEM = "axyb"
#: the solver of the whole cell, for the unknowns no pair determines alone
JOINT_SOLVER = "auto"


@dataclasses.dataclass(frozen=True)
class Options:
    """pair_solver: the registered ``axyb`` solver each pair is solved with (default ``auto``: the
    best each pair allows alone, so that a comparison with the joint solve shows what solving
    jointly adds; ``kron-lstsq`` is ~10x faster)."""

    pair_solver: str = "auto"

    def __post_init__(self) -> None:
        if not isinstance(self.pair_solver, str):
            raise InputError(f"option pair_solver={shown(self.pair_solver)} must be the name of a registered "
                             f"{PAIR_PROBLEM} solver, not a {type(self.pair_solver).__name__}")
        _pair_spec(self.pair_solver)


def _pair_spec(name: str) -> Any:
    """The pair solver's spec for ``axyb`` (UnknownPluginError listing the axyb solvers)."""
    from handeye.host.registry import get_registry

    return get_registry().solver(name, PAIR_PROBLEM)


def _short(exc: BaseException) -> str:
    """The gist of an error's message, on one line: up to its first full stop, parenthesis or
    ", so" (the whole message is kept in the pair's record as ``error``)."""
    text = " ".join(str(exc).split())
    for stop in (". ", " (", ", so "):
        text = text.split(stop)[0]
    return text.rstrip(".")


def solve_pairs(data: AXYBMultiData, options: Options) -> tuple[list[dict[str, Any]], dict[tuple[int, int], Any]]:
    """Each observed (j, k) solved alone: (a record per pair for the diagnostics, {(j, k): Solution}
    of the pairs used)."""
    from handeye.host.registry import get_registry

    axyb = get_registry().problem(PAIR_PROBLEM)
    records, answers = [], {}
    keys, counts = np.unique(np.stack([data.x_index, data.y_index], axis=1), axis=0, return_counts=True)
    for (j, k), count in zip(keys.tolist(), counts.tolist()):
        record: dict[str, Any] = {"X": data.x_names[j], "Y": data.y_names[k], "observations": count}
        records.append(record)
        if count < axyb.min_pairs:
            record.update(used=False, reason=f"{count} observation{'s' if count > 1 else ''}, "
                                             f"{PAIR_PROBLEM} needs at least {axyb.min_pairs}")
            continue
        rows = data.observations_of(x=j, y=k)
        try:
            pair_data = axyb.validate(A=data.A[rows], B=data.B[rows])
        except HandEyeError as exc:  # degenerate alone (one rotation axis), motion within the noise, ...
            record.update(used=False, reason=f"degenerate alone: {_short(exc)}", error=" ".join(str(exc).split()))
            continue
        try:
            solution = run_registered(options.pair_solver, pair_data, problem=PAIR_PROBLEM)
        except HandEyeError as exc:
            record.update(used=False, reason=f"{options.pair_solver} failed: {_short(exc)}",
                          error=" ".join(str(exc).split()))
            continue
        if solution.status not in USABLE:  # an unusable pair's answer is skipped, not averaged
            record.update(used=False, reason=f"{options.pair_solver} returned status {solution.status.value}")
            continue
        record.update(used=True, status=solution.status.value)
        answers[(j, k)] = solution
    return records, answers


def average(poses: list[np.ndarray]) -> tuple[np.ndarray, dict[str, float]]:
    """The chordal L2 mean of the rotations and the mean of the translations of 4x4 poses, and how far
    the poses are from it: the largest rotation angle (deg) and translation distance (data units)."""
    T = np.stack(poses)
    mean = make_pose(project_to_so3(T[:, :3, :3].sum(axis=0)), T[:, :3, 3].mean(axis=0))
    spread = {"rotation_deg": float(np.degrees(rotation_angle(T[:, :3, :3] @ mean[:3, :3].T).max())),
              "translation": float(np.linalg.norm(T[:, :3, 3] - mean[:3, 3], axis=1).max())}
    return mean, spread


def run(data: AXYBMultiData, options: Options, backend: str) -> SolverOutput:
    records, answers = solve_pairs(data, options)
    unknowns, spreads, undetermined, joint = {}, {}, [], None
    for kind, names, index in (("X", data.x_names, 0), ("Y", data.y_names, 1)):
        stack, spreads[kind] = [], {}
        for u, name in enumerate(names):
            poses = [sol.unknowns[kind] for key, sol in answers.items() if key[index] == u]
            if poses:
                pose, spread = average(poses)
                stack.append(pose)
                spreads[kind][name] = {"pairs": len(poses), **spread}
                continue
            # no pair alone determines it: the cell's joint fit does, from every observation
            why = "; ".join(f"with {'Y' if kind == 'X' else 'X'} {r['Y' if kind == 'X' else 'X']!r}: {r['reason']}"
                            for r in records if r[kind] == name)
            joint = joint or _joint_fit(data, f"{kind} {name!r} is undetermined by every pair alone ({why})")
            stack.append(np.asarray(joint.unknowns[kind][u], dtype=float))
            undetermined.append(f"{kind} {name!r} ({why})")
        unknowns[kind] = np.stack(stack)
    skipped = [r for r in records if not r["used"]]
    warnings = []
    if undetermined:
        warnings.append(f"pairwise: no pair alone determines {', '.join(undetermined)}: taken from the cell's joint fit "
                        f"(solver {JOINT_SOLVER}), which uses every observation")
    if skipped:
        warnings.append(f"pairwise: {len(skipped)} of {len(records)} (X, Y) pairs skipped (" + "; ".join(
            f"X {r['X']!r} with Y {r['Y']!r}: {r['reason']}" for r in skipped[:3])
            + ("; ..." if len(skipped) > 3 else "") + "); diagnostics['pairs'] says why")
    return SolverOutput(
        unknowns=unknowns,
        status=Status.OPTIMAL,
        diagnostics={"pair_solver": options.pair_solver, "pairs": records, "pairs_used": len(answers),
                     "spread": spreads, "warnings": warnings},
    )


def _joint_fit(data: AXYBMultiData, why: str) -> Any:
    """The cell solved jointly (`JOINT_SOLVER`), for what no pair determines alone; the reason
    `why` in the error where that fails too."""
    try:
        solution = run_registered(JOINT_SOLVER, data, problem=PROBLEM)
    except HandEyeError as exc:
        raise DegenerateDataError(f"pairwise: {why}, and the cell's joint fit failed too ({_short(exc)})") from None
    if solution.status not in USABLE:
        raise DegenerateDataError(f"pairwise: {why}, and the cell's joint fit is {solution.status.value}")
    return solution


def _unit_invariant(options: Options) -> bool:
    """As the pair solver's own declaration (with its default options)."""
    try:
        return _pair_spec(options.pair_solver).is_unit_invariant()
    except HandEyeError:
        return False


SPEC = SolverSpec(
    name="pairwise",
    problems=(PROBLEM,),
    run=run,
    options=Options,
    summary="baseline: each (X, Y) pair solved alone as axyb (pair_solver, default auto), then each X and Y "
            "averaged over its pairs (chordal mean of rotations, mean of translations)",
    citation="the per-pair baseline of docs/solvers/pairwise.md; chordal mean: Hartley et al., IJCV 2013",
    unit_invariant=_unit_invariant,
    exact=True,
)


@hookimpl
def register_solvers(register: Any, problems: Mapping[str, Any]) -> None:
    if PROBLEM in problems and PAIR_PROBLEM in problems:
        register(SPEC)
