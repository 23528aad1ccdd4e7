"""Studies from text: the contenders, noise levels and pair counts of ``handeye compare``'s flags
(`parse_specs`, `parse_floats`, `parse_ints`) and study files in TOML (`load_study`,
`study_from_dict`; the format in docs/harness.md). What a study is: `handeye.harness.study`."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from handeye.base.errors import InputError, UnknownPluginError
from handeye.estimation.noise import NoiseModel
from handeye.harness.study import Spec, Study, Sweep, default_specs
from handeye.host.registry import get_registry


def parse_specs(text: str, problem: str | None = None) -> tuple[Spec, ...]:
    """Specs from a comma-separated list: ``name`` (default backend), ``name/backend``,
    ``name/*`` (every available backend) or ``all`` (= `default_specs`), for `problem` (default:
    the default problem)."""
    registry = get_registry()
    problem = problem or registry.default_problem()
    specs: list[Spec] = []
    for item in (part.strip() for part in text.split(",")):
        if not item:
            continue
        if item == "all":
            specs.extend(default_specs(problem))
            continue
        name, _, backend = item.partition("/")
        solver = registry.solver(name, problem)
        if backend == "*":
            for b in solver.backends:
                if solver.unavailable_reason(b) is None:
                    specs.append(Spec(name, b, label=f"{name}/{b}"))
        elif backend:
            if backend not in solver.backends:
                raise UnknownPluginError("backend", backend, solver.backends, owner=f"of solver {name!r}")
            specs.append(Spec(name, backend, label=item))
        else:
            specs.append(Spec(name, solver.default_backend, label=name))
    if not specs:
        raise InputError(f"no solvers in {text!r}; known: {registry.solver_names(problem)}")
    seen: dict[str, Spec] = {}
    for spec in specs:
        seen.setdefault(spec.label, spec)
    return tuple(seen.values())


def parse_floats(text: str, what: str) -> tuple[float, ...]:
    """``"0,0.01,0.02"`` or a range ``"0:0.1:0.01"`` (start:stop:step, stop included)."""
    text = text.strip()
    try:
        if ":" in text:
            start, stop, step = (float(v) for v in text.split(":"))
            if step <= 0:
                raise ValueError
            n = math.floor((stop - start) / step + 1e-9) + 1
            return tuple(round(start + i * step, 12) for i in range(n))
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise InputError(f"{what} must be numbers separated by commas or start:stop:step, got {text!r}") from None


def parse_ints(text: str, what: str) -> tuple[int, ...]:
    values = parse_floats(text, what)
    if any(v != int(v) for v in values):
        raise InputError(f"{what} must be integers, got {text!r}")
    return tuple(int(v) for v in values)


_STUDY_KEYS = {"name", "problem", "trials", "seed", "truth", "units", "warmup", "level_label", "center", "timeout", "noise", "levels",
               "pairs", "sweep", "solver", "simulation"}
_SWEEP_KEYS = {"name", "levels", "pairs", "noise", "simulation"}
_SOLVER_KEYS = {"name", "backend", "options", "label", "init_from_truth", "truth_option"}


def load_study(path: str | Path) -> Study:
    """Read a study file (TOML; docs/harness.md). Unknown keys are errors."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            doc = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"study file {path}: not valid TOML ({exc})") from None
    return study_from_dict(doc, source=str(path))


def study_from_dict(doc: Mapping[str, Any], source: str = "study") -> Study:
    """A `Study` from the parsed TOML structure (see docs/harness.md)."""
    _check_keys(doc, _STUDY_KEYS, source)
    kwargs: dict[str, Any] = {k: doc[k] for k in ("name", "problem", "trials", "seed", "truth", "units", "warmup", "level_label", "center", "timeout",
                                                   "simulation")
                              if k in doc}
    if kwargs.get("timeout") == 0:  # TOML has no null: 0 means no time limit
        kwargs["timeout"] = None
    if "noise" in doc:
        kwargs["noise"] = _noise_from(doc["noise"], f"{source}: [noise]")
    sweeps = []
    if "levels" in doc or "pairs" in doc:
        sweeps.append(Sweep("grid", tuple(doc.get("levels", (1.0,))), tuple(doc.get("pairs", (16,)))))
    for i, table in enumerate(doc.get("sweep", [])):
        where = f"{source}: [[sweep]] #{i + 1}"
        _check_keys(table, _SWEEP_KEYS, where)
        noise = _noise_from(table["noise"], where + " noise") if "noise" in table else None
        sweeps.append(Sweep(table.get("name", f"sweep{i + 1}"), tuple(table.get("levels", (1.0,))),
                            tuple(table.get("pairs", (16,))), noise, table.get("simulation", {})))
    if sweeps:
        kwargs["sweeps"] = tuple(sweeps)
    specs = []
    for i, table in enumerate(doc.get("solver", [])):
        where = f"{source}: [[solver]] #{i + 1}"
        _check_keys(table, _SOLVER_KEYS, where)
        if "name" not in table:
            raise InputError(f"{where} needs name = \"<registered solver>\"")
        specs.append(Spec(table["name"], table.get("backend"), table.get("options", {}), table.get("label", ""),
                          bool(table.get("init_from_truth", False)), table.get("truth_option", "init")))
    kwargs["specs"] = tuple(specs)
    return Study(**kwargs)


def _noise_from(table: Any, where: str) -> NoiseModel:
    if not isinstance(table, Mapping):
        raise InputError(f"{where} must be a table like {{ B = [0.002, 0.5] }} (rad, data units)")
    sigmas = {}
    for name, pair in table.items():
        if not isinstance(pair, Sequence) or len(pair) != 2:
            raise InputError(f"{where}: {name} must be [sigma_rot_rad, sigma_trans], got {pair!r}")
        sigmas[name] = (float(pair[0]), float(pair[1]))
    return NoiseModel(sigmas)


def _check_keys(table: Mapping[str, Any], known: Iterable[str], where: str) -> None:
    unknown = set(table) - set(known)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {sorted(unknown)}; known: {sorted(known)}")
