"""What a comparison study is: solvers to compare, the data to compare them on, and how often.

A `Study` is pure data (frozen, picklable, JSON-able): the problem, a list of `Spec` entries
(solver + backend + options, with a label), a base `handeye.estimation.noise.NoiseModel`, one or more
`Sweep` grids (noise levels x pair counts), the number of trials per cell and a master seed.
A noise *level* is a multiplier of the base model's standard deviations (so with a base of
1 rad and 1 mm a level is the paper's sigma_N, Sec. IV-A); a sweep may carry its own base model
instead, which is how explicit noise models are expressed.

Nothing here is specific to one problem: the unknowns (X and Y for ``axyb``, X for ``axxb``)
come from the registered problem, the data from its simulator (``Study.simulation`` passes extra
options to it, e.g. the pairing of ``axxb``'s motions), the contenders from the registry.

Studies come from Python, from CLI flags or from a TOML file (`handeye.harness.study_files`:
`parse_specs`, `parse_floats`, `load_study`; format in docs/harness.md). `paper_study` is the paper's Sec. IV-A (Fig. 3, Fig. 4,
Table I), `sweep_study` the default noise and pair-count sweeps of ``handeye compare`` and
`accuracy_study` the accuracy study of any problem with its ground-truth "oracle" hook. A problem
whose solvers need different data protocols (``axbycz``: free motion, or phases with one robot
still) gets its built-in sweeps once per protocol (`PROTOCOLS`, `Sweep.simulation`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from handeye.base.errors import InputError, UnknownPluginError
from handeye.base.vocabulary import LENGTH_UNITS, millimetres_per
from handeye.estimation.noise import NoiseModel
from handeye.host.registry import get_registry

#: length units the harness can hand the data to the solvers in; the simulator works in mm, and
#: `Study.units = "m"` divides every translation (data and truth) by 1000 before solving.
UNITS = {unit: millimetres_per(unit) for unit in LENGTH_UNITS}
TRUTHS = ("paper", "random")
#: what the figures draw over the trials of a cell: the median with the interquartile range, or
#: the mean with +- one standard deviation (the paper plots means over its five trials)
CENTERS = ("median", "mean")
#: fields of a `Study` that change only its figures and tables, never a record: left out of
#: `Study.fingerprint`, so that a resumed run may relabel its figures
PRESENTATION_FIELDS = ("level_label", "center")


@dataclasses.dataclass(frozen=True)
class Spec:
    """One contender of a study: a registered solver, a backend, options, and a label.

    solver: registered solver name; backend: one of its backends (None: the solver's default).
    options: keyword options passed to `handeye.solve` (JSON-able values).
    label: the name rows, plots and tables use (default ``solver`` or ``solver/backend``).
    init_from_truth: pass the ground truth, the problem's unknowns (``{"X": 4x4, "Y": 4x4}`` for
        ``axyb``, ``{"X": 4x4}`` for ``axxb``) in the data's units, as the option named
        `truth_option` (default ``init``): the "oracle" of a refinement started at the truth, i.e.
        the accuracy floor of the data. A solver that does not accept it is recorded as failed,
        with the reason.
    """

    solver: str
    backend: str | None = None
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    label: str = ""
    init_from_truth: bool = False
    truth_option: str = "init"

    def __post_init__(self) -> None:
        if not self.solver:
            raise InputError("a study spec needs a solver name")
        if not isinstance(self.options, Mapping):
            raise InputError(f"spec {self.solver!r}: options must be a table/dict, got {self.options!r}")
        object.__setattr__(self, "options", dict(self.options))
        if not self.label:
            label = self.solver if self.backend is None else f"{self.solver}/{self.backend}"
            object.__setattr__(self, "label", label)

    def __hash__(self) -> int:  # options is a dict: hash by its JSON text
        return hash((self.solver, self.backend, json.dumps(self.options, sort_keys=True, default=str),
                     self.label, self.init_from_truth, self.truth_option))

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A grid of cells: every noise level x every pair count.

    name: used in file names and the ``sweep`` column. levels: multipliers of the base noise
    (>= 0). pairs: numbers of pairs m (>= 1). noise: this sweep's base model (None: the study's).
    simulation: simulator options of this sweep, over the study's (`Study.simulation`), e.g.
    ``{"protocol": "phases"}`` for ``axbycz`` data where one robot holds still at a time.
    """

    name: str
    levels: tuple[float, ...] = (1.0,)
    pairs: tuple[int, ...] = (16,)
    noise: NoiseModel | None = None
    simulation: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.simulation, Mapping):
            raise InputError(f"sweep {self.name!r}: simulation must be a table/dict of simulator options, "
                             f"got {self.simulation!r}")
        object.__setattr__(self, "simulation", dict(self.simulation))
        levels = tuple(float(v) for v in self.levels)
        pairs = tuple(int(v) for v in self.pairs)
        if not self.name or not all(c.isalnum() or c in "-_." for c in self.name):
            raise InputError(f"sweep name must be non-empty letters, digits, '-', '_' or '.', got {self.name!r}")
        if not levels or any(not math.isfinite(v) or v < 0 for v in levels):
            raise InputError(f"sweep {self.name!r}: noise levels must be finite numbers >= 0, got {self.levels}")
        if not pairs or any(p < 1 for p in pairs) or any(p != v for p, v in zip(pairs, self.pairs)):
            raise InputError(f"sweep {self.name!r}: pair counts must be integers >= 1, got {self.pairs}")
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "pairs", pairs)


@dataclasses.dataclass(frozen=True)
class GridPoint:
    """One (sweep, level, pairs) point with its indices (sweep, pairs and trial seed the data) and
    the sweep's own simulator options (`Sweep.simulation`)."""

    sweep: str
    sweep_index: int
    level: float
    level_index: int
    pairs: int
    pairs_index: int
    noise: NoiseModel
    simulation: Mapping[str, Any] = dataclasses.field(default_factory=dict, compare=False, hash=False)


@dataclasses.dataclass(frozen=True)
class Study:
    """A comparison study; see the module docstring and docs/harness.md.

    specs: empty means every registered solver of `problem` with its default backend plus every
        other available backend of ``lmi-sdp`` (`default_specs`), resolved at run time.
    noise: the base model the levels multiply. truth: ``"paper"`` (the paper's X, Y) or
        ``"random"`` (new X, Y per trial). units: ``"mm"`` or ``"m"`` (see `UNITS`).
    warmup: solve once per spec and worker process (on the first unit's data, answer thrown
        away) before timing, so that one-off costs (imports, compiled-problem caches) do not land
        in the first trial's time. level_label: x-axis label of the error-vs-noise figures.
        center: ``"median"`` (figures: median and interquartile band) or ``"mean"`` (mean +- std).
    timeout: seconds one solve may take before it is stopped and recorded as failed
        (`handeye.harness.runner.time_limit`: process workers and ``jobs=1``, not dask); None: no limit.
    simulation: extra keyword options of the problem's simulator (JSON-able), e.g.
        ``{"pairing": "all"}`` for ``axxb``'s motions; empty: its defaults.
    """

    name: str = "study"
    problem: str | None = None
    specs: tuple[Spec, ...] = ()
    noise: NoiseModel = dataclasses.field(default_factory=lambda: paper_noise(1.0))
    sweeps: tuple[Sweep, ...] = (Sweep("grid", (0.0, 0.02, 0.05, 0.1), (16,)),)
    trials: int = 5
    seed: int = 0
    truth: str = "paper"
    units: str = "mm"
    warmup: bool = True
    level_label: str = "noise level (multiplier of the base noise)"
    center: str = "median"
    timeout: float | None = 30.0
    simulation: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "problem", self.problem or get_registry().default_problem())
        object.__setattr__(self, "specs", tuple(self.specs))
        if not isinstance(self.simulation, Mapping):
            raise InputError(f"simulation must be a table/dict of simulator options, got {self.simulation!r}")
        object.__setattr__(self, "simulation", dict(self.simulation))
        object.__setattr__(self, "sweeps", tuple(self.sweeps))
        if isinstance(self.trials, bool) or not isinstance(self.trials, int) or self.trials < 1:
            raise InputError(f"trials must be an integer >= 1, got {self.trials!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.truth not in TRUTHS:
            raise InputError(f"truth must be one of {TRUTHS}, got {self.truth!r}")
        if self.units not in UNITS:
            raise InputError(f"units must be one of {sorted(UNITS)}, got {self.units!r}")
        if self.center not in CENTERS:
            raise InputError(f"center must be one of {CENTERS}, got {self.center!r}")
        if self.timeout is not None and (isinstance(self.timeout, bool) or not isinstance(self.timeout, (int, float))
                                         or not self.timeout > 0 or not math.isfinite(self.timeout)):
            raise InputError(f"timeout must be a number of seconds > 0 (or none), got {self.timeout!r}")
        if not self.sweeps:
            raise InputError("a study needs at least one sweep")
        names = [s.name for s in self.sweeps]
        if len(set(names)) != len(names):
            raise InputError(f"sweep names must be unique, got {names}")
        labels = [s.label for s in self.specs]
        if len(set(labels)) != len(labels):
            raise InputError(f"spec labels must be unique, got {labels}; give duplicates a label")

    def cells(self) -> Iterator[GridPoint]:
        """Every cell of every sweep, in a fixed order."""
        for si, sweep in enumerate(self.sweeps):
            base = sweep.noise if sweep.noise is not None else self.noise
            for li, level in enumerate(sweep.levels):
                for pi, m in enumerate(sweep.pairs):
                    yield GridPoint(sweep.name, si, level, li, m, pi, scale_noise(base, level), sweep.simulation)

    def resolved_specs(self) -> tuple[Spec, ...]:
        """`specs` (or `default_specs(problem)` when empty) with default backends filled in;
        raises `UnknownPluginError` for an unknown solver or backend."""
        registry = get_registry()
        out = []
        for spec in self.specs or default_specs(self.problem):
            solver = registry.solver(spec.solver, self.problem)  # raises UnknownPluginError
            if spec.backend is None:
                spec = dataclasses.replace(spec, backend=solver.default_backend)
            elif spec.backend not in solver.backends:
                raise UnknownPluginError("backend", spec.backend, solver.backends, owner=f"of solver {spec.solver!r}")
            out.append(spec)
        return tuple(out)

    def replace(self, **changes: Any) -> Study:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the same fields as the TOML format)."""
        return {
            "name": self.name, "problem": self.problem, "trials": self.trials, "seed": self.seed,
            "truth": self.truth, "units": self.units, "warmup": self.warmup, "level_label": self.level_label,
            "center": self.center, "timeout": self.timeout, "simulation": dict(self.simulation),
            "noise": _noise_dict(self.noise),
            "sweeps": [{"name": s.name, "levels": list(s.levels), "pairs": list(s.pairs),
                        **({"noise": _noise_dict(s.noise)} if s.noise is not None else {}),
                        **({"simulation": dict(s.simulation)} if s.simulation else {})}
                       for s in self.sweeps],
            "solvers": [s.to_dict() for s in self.specs],
        }

    def fingerprint(self, specs: Sequence[Spec] | None = None) -> str:
        """A hash (16 hex digits) of everything that decides the study's records: the definition
        (`to_dict`, without the `PRESENTATION_FIELDS`) with `specs` (default `resolved_specs()`,
        so an empty spec list stands for the solvers registered here, default backends filled
        in). A run's journal carries it, so that only the same study resumes the run: the same
        fingerprint means the same units, seeds and solvers, hence the same rows but for times."""
        doc = self.to_dict()
        for name in PRESENTATION_FIELDS:
            doc.pop(name)
        doc["solvers"] = [s.to_dict() for s in (self.resolved_specs() if specs is None else specs)]
        text = json.dumps(doc, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def scale_noise(noise: NoiseModel, level: float) -> NoiseModel:
    """The model with every standard deviation multiplied by `level`."""
    return NoiseModel({k: (rot * level, trans * level) for k, (rot, trans) in noise.sigmas.items()})


def _noise_dict(noise: NoiseModel) -> dict[str, list[float]]:
    return {k: [float(r), float(t)] for k, (r, t) in sorted(noise.sigmas.items())}


# --------------------------------------------------------------------------------------------
# defaults and the two built-in studies

#: mm of translation noise per rad of rotation noise in the reading of the paper's sigma_N
#: (docs/reproducing-the-paper.md explains the choice): sigma_N rad and sigma_N mm.
PAPER_MM_PER_RAD = 1.0
#: pairs of the paper's noise sweep (Fig. 3); the paper does not state m, its experiment uses 16.
PAPER_PAIRS = 16


def paper_noise(level: float = 1.0, mm_per_rad: float = PAPER_MM_PER_RAD,
                stacks: tuple[str, ...] = ("A", "B")) -> NoiseModel:
    """Our reading of the paper's sigma_N: `level` rad on rotations and ``level * mm_per_rad`` mm
    on translations, on both A and B ("injected into the (A_i, B_i)", Sec. IV-A, Step 2)."""
    return NoiseModel.on(stacks, level, level * mm_per_rad)


def default_specs(problem: str | None = None) -> tuple[Spec, ...]:
    """Every registered solver of `problem` with its default backend, plus every other backend of
    ``lmi-sdp`` (the paper's method: its backends are part of the comparison) and, where a solver
    wraps several methods behind an option (`SolverSpec.variants`: OpenCV's five AX=XB methods),
    one spec per method; `problem` defaults to the default problem. Backends that cannot run here are left out, and so are solvers that fit
    board images (`SolverSpec.fits_images`: ``reprojection``), which
    pose data cannot feed (bench/reprojection_study.py is their study)."""
    registry = get_registry()
    problem = problem or registry.default_problem()
    return tuple(spec for name in registry.solver_names(problem)
                 if not registry.solver(name, problem).fits_images
                 for spec in _solver_specs(name, registry.solver(name, problem)))


def _solver_specs(name: str, solver: Any, options: Mapping[str, Any] | None = None,
                  suffix: str = "") -> list[Spec]:
    """Specs of registered solver `name` on its default backend, or for ``lmi-sdp`` on every
    backend (default first, labelled ``lmi-sdp/<backend>``), leaving out backends that cannot run
    here; one spec per value of its `SolverSpec.variants` (labelled ``name (value)``);
    `suffix` is appended to every label."""
    if name == "lmi-sdp":
        backends = sorted(solver.backends, key=lambda b: b != solver.default_backend)
    else:
        backends = [solver.default_backend]
    variants: list[tuple[str, dict[str, Any]]] = [("", dict(options or {}))]
    if solver.variants is not None:
        key, values = solver.variants
        variants = [(f" ({value})", {**(options or {}), key: value}) for value in values]
    specs = []
    for backend in backends:
        if solver.unavailable_reason(backend) is None:
            label = f"{name}/{backend}" if name == "lmi-sdp" and len(solver.backends) > 1 else name
            specs += [Spec(name, backend, opts, label=label + variant + suffix) for variant, opts in variants]
    return specs


#: the three methods the paper compares (Sec. III-IV): LMI-SDP (eq. 14), iterative (eqs. 15-21),
#: dual quaternions (eqs. 22-26)
PAPER_METHODS = ("lmi-sdp", "iterative", "dual-quaternion")


#: options that make a paper method run as the paper has it: the dual-quaternion SVD on the data
#: in their own units (mm), without our translation normalisation
PAPER_OPTIONS: dict[str, dict[str, Any]] = {"dual-quaternion": {"normalize": False}}


def paper_specs(problem: str | None = None) -> tuple[Spec, ...]:
    """The default contenders of `paper_study`: `PAPER_METHODS` as the paper runs them (every
    available backend of ``lmi-sdp``; `PAPER_OPTIONS`, label suffix ``(raw)``), then every other
    registered solver of `problem` (ours and third parties') with its defaults and default
    backend. `missing_paper_methods` tells which of the paper's methods are not registered."""
    registry = get_registry()
    problem = problem or registry.default_problem()
    known = registry.solver_names(problem)
    specs = []
    for name in [n for n in PAPER_METHODS if n in known] + [n for n in known if n not in PAPER_METHODS]:
        solver = registry.solver(name, problem)
        fields = {f.name for f in dataclasses.fields(solver.options)} if dataclasses.is_dataclass(solver.options) else set()
        options = PAPER_OPTIONS.get(name, {})
        options = {k: v for k, v in options.items() if k in fields}  # a replacement plugin may lack them
        specs += _solver_specs(name, solver, options, " (raw)" if options else "")
    return tuple(specs)


def missing_paper_methods(problem: str | None = None) -> list[str]:
    """The paper's methods (`PAPER_METHODS`) that no installed plugin registers."""
    registry = get_registry()
    known = set(registry.solver_names(problem or registry.default_problem()))
    return [name for name in PAPER_METHODS if name not in known]


def paper_study(*, trials: int = 5, seed: int = 0, pairs: int = PAPER_PAIRS,
                mm_per_rad: float = PAPER_MM_PER_RAD, specs: Sequence[Spec] = ()) -> Study:
    """Sec. IV-A: sigma_N = 0, 0.01, ..., 0.1 at m = `pairs` (Fig. 3) and m = 10, 20, ..., 100 at
    sigma_N = 0.05 (Fig. 4), `trials` trials per cell (the paper: 5), the paper's X and Y, mm.
    specs: default `paper_specs()` (the paper's three methods, then every other registered solver)."""
    return Study(
        name="paper", specs=tuple(specs) or paper_specs(), noise=paper_noise(1.0, mm_per_rad),
        sweeps=(Sweep("noise", tuple(round(0.01 * i, 2) for i in range(11)), (pairs,)),
                Sweep("pairs", (0.05,), tuple(range(10, 101, 10)))),
        trials=trials, seed=seed, center="mean", timeout=PAPER_TIMEOUT,
        level_label=("sigma_N  (rotations: sigma_N rad, translations: "
                     f"{'' if mm_per_rad == 1 else f'{mm_per_rad:g} '}sigma_N mm)"),
    )


#: seconds one solve of the paper study may take (solves take ~1-100 ms here, the paper's slowest
#: 0.5 s); a solver stuck past it is recorded as failed and the study goes on
PAPER_TIMEOUT = 10.0

#: realistic noise of a robot (A) and a camera (B) ten times noisier, rad and mm: the accuracy
#: study's for A X = Y B and A X = X B (`Problem.study_noise`)
ACCURACY_NOISE = NoiseModel({"A": (0.0002, 0.05), "B": (0.002, 0.5)})
#: the accuracy study's noise on every data stack of a problem that states none: a camera's
CAMERA_NOISE = (0.002, 0.5)
#: pair counts of the accuracy study
ACCURACY_PAIRS = (8, 16, 50)


def accuracy_noise(problem: str) -> NoiseModel:
    """The accuracy study's noise of `problem`: its `Problem.study_noise`, else `CAMERA_NOISE` on
    every data stack."""
    spec = get_registry().problem(problem)
    levels = spec.study_noise or {name: CAMERA_NOISE for name in spec.data_fields}
    return NoiseModel(dict(levels))


def protocol_sweeps(problem: str, sweeps: Sequence[Sweep], protocols: Sequence[str] | None = None) -> tuple[Sweep, ...]:
    """`sweeps` once per data protocol of `problem` (`Problem.protocols`; `protocols` to choose):
    for a problem without protocols the sweeps themselves, else each sweep per protocol, named
    ``<sweep>-<protocol>`` and simulated with ``{"protocol": ...}`` (the first protocol keeps the
    plain name)."""
    registry = get_registry()
    known = tuple(registry.problem(problem).protocols)
    if not known:
        if protocols:
            having = sorted(name for name, p in registry.problems.items() if p.protocols)
            raise InputError(f"problem {problem!r} has no data protocols; --protocol applies to {having}")
        return tuple(sweeps)
    chosen = tuple(protocols) if protocols else known
    unknown = [p for p in chosen if p not in known]
    if unknown:
        raise InputError(f"protocol {unknown[0]!r} is not one of {', '.join(known)} (problem {problem!r})")
    return tuple(dataclasses.replace(s, name=s.name if p == known[0] else f"{s.name}-{p}", simulation={"protocol": p})
                 for p in chosen for s in sweeps)


def accuracy_study(*, problem: str | None = None, trials: int = 20, seed: int = 0, specs: Sequence[Spec] = (),
                   oracle: bool | None = None, units: str = "mm", pairs: Sequence[int] = ACCURACY_PAIRS,
                   protocols: Sequence[str] | None = None) -> Study:
    """The accuracy study of `problem` (default: the default problem): its realistic noise
    (`accuracy_noise`) and ten times that, m = 8, 16, 50 (`ACCURACY_PAIRS`), random unknowns
    per trial, every registered solver (`default_specs`); for a problem with data protocols
    (`Problem.protocols`: ``axbycz``'s free motion and phases) the sweep once per protocol. With
    `oracle` (default: when ``refine`` solves `problem`) an extra spec ``oracle`` runs ``refine``
    started at the ground truth (`Spec.init_from_truth`: init = the problem's unknowns, e.g.
    ``{"X": ..., "Y": ...}`` for ``axyb``, ``{"X": ...}`` for ``axxb``). Named ``accuracy`` for
    the default problem, else ``accuracy-<problem>``."""
    registry = get_registry()
    problem = problem or registry.default_problem()
    specs = tuple(specs) or default_specs(problem)
    if oracle is None:
        oracle = "refine" in registry.solver_names(problem)
    if oracle:
        specs += (Spec("refine", label="oracle", init_from_truth=True),)
    sweeps = protocol_sweeps(problem, (Sweep("accuracy", (1.0, 10.0), tuple(pairs)),), protocols)
    name = "accuracy" if problem == registry.default_problem() else f"accuracy-{problem}"
    return Study(name=name, problem=problem, specs=specs, noise=accuracy_noise(problem), sweeps=sweeps,
                 trials=trials, seed=seed, truth="random", units=units)


#: the default sweeps of `sweep_study`: noise levels (the paper's sigma_N reading) at m = 16, and
#: pair counts at level 0.05
SWEEP_LEVELS = (0.0, 0.02, 0.05, 0.1)
SWEEP_PAIRS = (8, 16, 32, 64)
SWEEP_LEVEL = 0.05


def sweep_study(problem: str | None = None, *, name: str = "study", specs: Sequence[Spec] = (),
                noise: NoiseModel | None = None, protocols: Sequence[str] | None = None) -> Study:
    """``handeye compare``'s default study of `problem`: a noise sweep (`SWEEP_LEVELS` at m = 16)
    and a pair-count sweep (m = `SWEEP_PAIRS` at level `SWEEP_LEVEL`), noise on every data stack
    (default the paper's reading, `paper_noise`: sigma_N rad and sigma_N mm on A and B, for
    ``axxb`` on the robot and camera poses, for ``axbycz`` on A, B and C), every registered
    solver of `problem` by default; both sweeps once per data protocol of the problem
    (`protocol_sweeps`: ``axbycz``'s free motion and phases)."""
    problem = problem or get_registry().default_problem()
    fields = tuple(get_registry().problem(problem).data_fields)
    sweeps = protocol_sweeps(problem, (Sweep("noise", SWEEP_LEVELS, (PAPER_PAIRS,)),
                                       Sweep("pairs", (SWEEP_LEVEL,), SWEEP_PAIRS)), protocols)
    return Study(name=name, problem=problem, specs=tuple(specs), noise=noise or paper_noise(1.0, stacks=fields),
                 sweeps=sweeps,
                 level_label=("sigma_N  (rotations: sigma_N rad, translations: sigma_N mm)" if noise is None
                              else "noise level (multiplier of the base noise)"))


# --------------------------------------------------------------------------------------------
# parsing: CLI strings and TOML files
