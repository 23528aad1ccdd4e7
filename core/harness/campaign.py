"""The reliability campaign: seeded data sets of the kinds that break calibration solvers.

Each `Case` is one recording of an eye-in-hand cell (robot poses A_k = T_base_flange, camera poses
B_k with A_k X = Y B_k) in one of the `KINDS`, given to ``axyb`` as stations and to ``axxb`` as
their motions (every pair of stations). The kinds are the data an audit found solvers answering
confidently and wrongly on:

- ``heavy-noise``: 3-6 stations, 0.01-0.05 rad and 2-5 mm of noise on both stacks;
- ``pure-rotation``: the robot turns about its flange origin (translations of A zero);
- ``tiny-cell``: every translation 10^4 times smaller than usual (a 0.03 mm cell);
- ``weak-excitation``: every robot rotation within 0.02 rad of one orientation, 0.5 mm noise;
- ``planar``: a SCARA-like robot turning about its base z only (the translation of X along z is
  not determined);
- ``outliers``: the usual simulation with 10-30% of the camera poses replaced by random ones.

`run_campaign` solves every case with every registered solver and tabulates error, status and
warnings beside `auto`'s error, which is what the target of a confident wrong answer is measured
against (docs/reliability.md).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from handeye.base.errors import InputError
from handeye.estimation.noise import NoiseModel
from handeye.geometry.kinematics import PAPER_X, PAPER_Y, random_flange_poses
from handeye.geometry.se3 import inverse, make_pose, random_rotations, so3_exp

KINDS = ("heavy-noise", "pure-rotation", "tiny-cell", "weak-excitation", "planar", "outliers")


@dataclasses.dataclass(frozen=True)
class Case:
    """One recording: kind, seed, stations A (robot), B (camera) and the truth X, Y (mm)."""

    kind: str
    seed: int
    A: np.ndarray
    B: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    outliers: tuple[int, ...] = ()

    def data(self, problem: str) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """The problem's data fields and truth, made from the case's eye-in-hand stations by the
        problem's `StationReader` (A X = Y B: the stations; A X = X B: the motions of every pair)."""
        from handeye.host.registry import get_registry

        reader = get_registry().problem(problem).station_reader
        if reader is None:
            raise InputError(f"problem {problem!r} cannot be made from a cell's stations (it has no station "
                             "reader), so the campaign's cases do not apply to it")
        fields = reader.convert(self.A, inverse(self.B), setup="eye-in-hand",
                                pairing="all" if reader.pairing else None)
        cell = {"X": self.X, "Y": self.Y}
        names = reader.cell_truth["eye-in-hand"] if reader.cell_truth else {name: name for name in cell}
        return dict(fields), {unknown: cell[name] for unknown, name in names.items()}


def _truth(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return PAPER_X.copy(), PAPER_Y.copy()


def _observe(A: np.ndarray, X: np.ndarray, Y: np.ndarray, noise: NoiseModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    B = inverse(Y) @ A @ X
    return noise.apply("A", A, rng), noise.apply("B", B, rng)


def make_case(kind: str, seed: int) -> Case:
    """The recording of `kind` (one of `KINDS`) drawn from `seed`."""
    rng = np.random.default_rng([KINDS.index(kind), seed])
    X, Y = _truth(rng)
    outliers: tuple[int, ...] = ()
    if kind == "heavy-noise":
        n = int(rng.integers(3, 7))
        A = random_flange_poses(n, rng)
        noise = NoiseModel.on(("A", "B"), rng.uniform(0.01, 0.05), rng.uniform(2.0, 5.0))
    elif kind == "pure-rotation":
        n = int(rng.integers(6, 16))
        A = random_flange_poses(n, rng)
        A[:, :3, 3] = 0.0
        noise = NoiseModel.on(("A", "B"), 1e-3, 0.1)
    elif kind == "tiny-cell":
        n = int(rng.integers(6, 16))
        A = random_flange_poses(n, rng)
        A[:, :3, 3] *= 1e-4
        X, Y = X.copy(), Y.copy()
        X[:3, 3] *= 1e-4
        Y[:3, 3] *= 1e-4
        noise = NoiseModel.on(("A", "B"), 1e-3, 1e-5)
    elif kind == "weak-excitation":
        n = int(rng.integers(8, 21))
        R0 = random_rotations(1, rng)[0]
        R = R0 @ so3_exp(0.02 * rng.standard_normal((n, 3)) / np.sqrt(3))
        t = np.array([300.0, 0.0, 400.0]) + rng.uniform(-150.0, 150.0, (n, 3))
        A = np.stack([make_pose(R[k], t[k]) for k in range(n)])
        noise = NoiseModel.on(("A", "B"), 1e-4, 0.5)
    elif kind == "planar":
        n = int(rng.integers(8, 21))
        theta = rng.uniform(-np.pi, np.pi, n)
        R = so3_exp(np.outer(theta, [0.0, 0.0, 1.0])) @ np.diag([1.0, -1.0, -1.0])  # tool pointing down
        t = np.column_stack([rng.uniform(200, 500, n), rng.uniform(-200, 200, n), rng.uniform(100, 250, n)])
        A = np.stack([make_pose(R[k], t[k]) for k in range(n)])
        noise = NoiseModel.on(("A", "B"), rng.uniform(2e-4, 2e-3), rng.uniform(0.05, 0.5))
    elif kind == "outliers":
        n = int(rng.integers(10, 26))
        A = random_flange_poses(n, rng)
        noise = NoiseModel.on(("A", "B"), 2e-3, 0.5)
    else:
        raise ValueError(f"kind {kind!r} is not one of {', '.join(KINDS)}")
    A, B = _observe(A, X, Y, noise, rng)
    if kind == "outliers":
        k = max(1, int(round(rng.uniform(0.1, 0.3) * n)))
        outliers = tuple(sorted(rng.choice(n, k, replace=False).tolist()))
        for i in outliers:
            B[i] = make_pose(random_rotations(1, rng)[0], B[i, :3, 3] + rng.normal(0.0, 200.0, 3))
    return Case(kind, seed, A, B, X, Y, outliers)


def cases(runs: int, kinds: Iterable[str] = KINDS, seed: int = 0) -> Iterator[Case]:
    """`runs` cases spread evenly over `kinds` (seeds seed, seed + 1, ... per kind)."""
    kinds = tuple(kinds)
    for k in range(runs):
        yield make_case(kinds[k % len(kinds)], seed + k // len(kinds))


def solver_runs(problem: str) -> list[tuple[str, str]]:
    """(solver, backend) of every registered solver of `problem` that can run here: the default
    backend, and every other backend of a solver whose backends solve different formulations
    (lmi-sdp's casadi)."""
    from handeye.host.registry import get_registry

    reg = get_registry()
    out = []
    for name in reg.solver_names(problem):
        spec = reg.solver(name, problem)
        for backend in spec.backends:
            if backend != spec.default_backend and not (name == "lmi-sdp" and backend == "casadi"):
                continue
            if spec.unavailable_reason(backend) is None:
                out.append((name, backend))
    return out


def run_case(case: Case, problem: str, runs: list[tuple[str, str]]) -> list[dict[str, Any]]:
    """One row per (solver, backend): error (largest rotation deg and translation mm over the
    unknowns), status, number of warnings, or the error type when it raised."""
    import warnings

    from handeye.base.errors import HandEyeError
    from handeye.host.api import solve
    from handeye.host.registry import get_registry

    prob = get_registry().problem(problem)
    data, truth = case.data(problem)
    rows = []
    for name, backend in runs:
        row: dict[str, Any] = {"kind": case.kind, "seed": case.seed, "problem": problem, "solver": name,
                               "backend": backend}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sol = solve(problem, solver=name, backend=backend, **data)
        except HandEyeError as exc:
            row.update(status="raised", error=type(exc).__name__, message=str(exc))
            rows.append(row)
            continue
        err = prob.errors(sol.unknowns, truth)
        row.update(status=sol.status.value, warnings=len(sol.warnings),
                   rotation_deg=max(np.degrees(e["rotation"]) for e in err.values()),
                   translation=max(e["translation"] for e in err.values()),
                   self_check=sol.diagnostics.get("self_check"))
        rows.append(row)
    return rows
