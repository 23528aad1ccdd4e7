"""Shared fixtures of the test suite.

- ``solver_backend``: any test that asks for it is parametrised over EVERY (problem, solver,
  backend) registered when the tests are collected (ids "problem:solver/backend"), so a new
  plugin, built in or installed by a third party, is tested without writing a test; a test that
  also asks for ``axyb_only`` gets only the problem "axyb".
- ``solver_case``: the problem, `SolverSpec` and backend of that parameter; skips when the
  backend is not available here, giving the solver's own reason.
- ``solve_once``: memoised `handeye.solve` for the deterministic reference cases, so the suite
  solves each case once per problem/solver/backend however many tests look at the answer.
- ``runtime_plugins``: registers plugin objects at run time and removes them (and rebuilds the
  registry) after the test, even when the registration itself failed.
- ``example_dist``: a directory holding the third-party example solver of
  docs/examples/handeye-example-solver as an "installed" distribution (module + dist-info with real
  entry-point metadata), built without pip, ready to put on sys.path.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import sys
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import settings

#: the suite never reads or writes the user's detection cache (~/.cache/handeye); a test that wants
#: a cache removes this and sets HANDEYE_CACHE_DIR to a temporary folder
os.environ["HANDEYE_NO_CACHE"] = "1"

#: the tests mirror the layers (tests/<layer>/, tests/problems/<name>/) and share helpers by module
#: name (`from test_streams import cell`): every folder of tests/ is importable from any test
for _folder in sorted({path.parent for path in Path(__file__).parent.rglob("test_*.py")}, reverse=True):
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))

import handeye
from handeye import SolverOutput, hookimpl
from handeye.host import registry

# property tests: enough examples to find edge cases, few enough for the suite's time budget;
# no deadline (the machine is shared, timings vary)
settings.register_profile("handeye", max_examples=60, deadline=None)
settings.load_profile("handeye")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_DIR = ROOT / "docs" / "examples" / "handeye-example-solver"
PROBLEM_EXAMPLE_DIR = ROOT / "docs" / "examples" / "handeye-example-problem"


@dataclasses.dataclass(frozen=True)
class SolverCase:
    problem: str
    name: str
    backend: str
    spec: handeye.SolverSpec

    @property
    def id(self) -> str:
        return f"{self.problem}:{self.name}/{self.backend}"

    def solve(self, **data_and_options: Any) -> handeye.Solution:
        return handeye.solve(self.problem, solver=self.name, backend=self.backend, **data_and_options)


def registered_backends(problem: str | None = None) -> list[tuple[str, str, str]]:
    """(problem, solver, backend) for every solver registered now (of `problem` if given), sorted."""
    reg = handeye.get_registry()
    problems = [problem] if problem else sorted(reg.problems)
    return [(p, name, backend) for p in problems for name in reg.solver_names(p)
            for backend in reg.solver(name, p).backends]


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "solver_backend" in metafunc.fixturenames:
        cases = registered_backends("axyb" if "axyb_only" in metafunc.fixturenames else None)
        metafunc.parametrize("solver_backend", cases, ids=[f"{p}:{s}/{b}" for p, s, b in cases])


@pytest.fixture
def axyb_only() -> None:
    """Marker fixture: parametrise ``solver_backend`` over the solvers of problem "axyb" only."""


@pytest.fixture
def solver_case(solver_backend: tuple[str, str, str]) -> SolverCase:
    problem, name, backend = solver_backend
    spec = handeye.get_registry().solver(name, problem)
    reason = spec.unavailable_reason(backend)
    if reason:
        pytest.skip(f"{name}/{backend} unavailable: {reason}")
    return SolverCase(problem, name, backend, spec)


@pytest.fixture(scope="session")
def solve_once() -> Callable[..., Any]:
    """solve_once(case_key, case, data, **options): handeye.solve, memoised on (case_key, case.id)."""
    cache: dict[tuple[Any, str], handeye.Solution] = {}

    def solve(key: Any, case: SolverCase, data: dict[str, Any], **options: Any) -> handeye.Solution:
        k = (key, case.id)
        if k not in cache:
            cache[k] = case.solve(**data, **options)
        return cache[k]

    return solve


@pytest.fixture
def runtime_plugins() -> Iterator[Callable[[Any, str], None]]:
    """register(plugin, name): `handeye.host.registry.register_plugin`, undone after the test."""
    names: list[str] = []

    def register(plugin: Any, name: str) -> None:
        names.append(name)
        registry.register_plugin(plugin, name)

    yield register
    for name in reversed(names):
        try:
            registry.unregister_plugin(name)
        except handeye.PluginRegistrationError:
            pass  # a plugin still registered is invalid; removed in a later round of the loop
    registry.reload()


def example_entry_points(folder: Path = EXAMPLE_DIR) -> dict[str, str]:
    """The ``handeye`` entry points declared in an example's real pyproject.toml."""
    return dict(example_project(folder)["entry-points"]["handeye"])


def example_project(folder: Path = EXAMPLE_DIR) -> dict[str, Any]:
    with open(folder / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["project"]


def install_example(folder: Path, site: Path) -> Path:
    """The example package in `folder` made to look installed in directory `site` (module +
    dist-info), as an installer writes it: METADATA (Name, Version) and entry_points.txt, both
    taken from the example's pyproject.toml, so discovery goes through real entry-point metadata."""
    project = example_project(folder)
    site.mkdir(exist_ok=True)
    with open(folder / "pyproject.toml", "rb") as f:
        (module,) = tomllib.load(f)["tool"]["setuptools"]["py-modules"]
    shutil.copy(folder / f"{module}.py", site / f"{module}.py")
    dist_info = site / f"{module}-{project['version']}.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n"
    )
    lines = ["[handeye]"] + [f"{name} = {target}" for name, target in example_entry_points(folder).items()]
    (dist_info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return site


@pytest.fixture
def example_dist(tmp_path: Path) -> Path:
    """A sys.path directory where the example solver looks installed (`install_example`)."""
    return install_example(EXAMPLE_DIR, tmp_path / "site")


@pytest.fixture
def installed_example(example_dist: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """`example_dist` on sys.path for the test; afterwards off it, its module forgotten, and the
    registry rebuilt without it."""
    import sys

    monkeypatch.syspath_prepend(str(example_dist))
    yield example_dist
    monkeypatch.undo()
    sys.modules.pop("handeye_example_solver", None)
    registry.reload()


@pytest.fixture
def installed_problem(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """The example problem package (docs/examples/handeye-example-problem) installed on sys.path
    for the test, the registry rebuilt with it (found through its entry point); yields its
    module. Afterwards off the path, forgotten, the registry rebuilt without it."""
    import importlib
    import sys

    site = install_example(PROBLEM_EXAMPLE_DIR, tmp_path / "problem-site")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delenv("HANDEYE_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    registry.reload()
    yield importlib.import_module("handeye_example_problem")
    monkeypatch.undo()
    sys.modules.pop("handeye_example_problem", None)
    registry.reload()


def identity_run(data: Any, options: Any, backend: str) -> SolverOutput:
    """A solver body for registration tests: returns identity X, Y whatever the data."""
    return SolverOutput({"X": np.eye(4), "Y": np.eye(4)})


class SolverPlugin:
    """A plugin object registering the given solver specs (each instance is a distinct plugin)."""

    def __init__(self, *specs: Any) -> None:
        self.specs = specs

    @hookimpl
    def register_solvers(self, register: Callable[[Any], None]) -> None:
        for spec in self.specs:
            register(spec)


def run_cli(capsys: pytest.CaptureFixture[str], *argv: Any) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``handeye`` with `argv` (each turned into a string)."""
    from handeye.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err
