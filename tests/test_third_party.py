"""Third-party proof: the example package docs/examples/handeye-example-solver is discovered
through real entry-point metadata, solves through `handeye.solve`, shows in `handeye list`, and
stays out when HANDEYE_DISABLE_PLUGIN_AUTOLOAD is set.

Installation without pip: the fixture ``installed_example`` (conftest.py) copies the example's
module into a temporary directory next to a ``handeye_example_solver-<version>.dist-info`` whose
METADATA and entry_points.txt are written from the example's pyproject.toml (parsed with
tomllib), i.e. what an installer would write, and puts that directory on sys.path.
"""

from __future__ import annotations

import importlib.metadata
import sys

import numpy as np
import pytest
from conftest import example_entry_points, example_project

import handeye
from handeye import registry
from handeye.problems.axyb import PROBLEM, random_truth

SOLVER = "example-kron"


def _installed() -> bool:
    try:
        importlib.metadata.distribution("handeye-example-solver")
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


#: someone pip-installed the example into this environment: the absence checks cannot hold
PREINSTALLED = _installed()
needs_clean_env = pytest.mark.skipif(
    PREINSTALLED, reason="handeye-example-solver is installed in this environment (pip install); "
    "the tests of its absence need an environment without it")


def test_pyproject_declares_the_entry_point():
    project = example_project()
    assert project["name"] == "handeye-example-solver"
    assert "handeye" in project["dependencies"]
    assert example_entry_points() == {"example-solver": "handeye_example_solver"}


@needs_clean_env
def test_not_visible_before_installation():
    assert SOLVER not in handeye.list_solvers()


@needs_clean_env
def test_discovered_through_entry_point_metadata(installed_example):
    dist = importlib.metadata.distribution("handeye-example-solver")
    assert dist.version == example_project()["version"]
    (ep,) = [e for e in dist.entry_points if e.group == "handeye"]
    assert (ep.name, ep.value) == ("example-solver", "handeye_example_solver")

    reg = registry.reload()
    assert SOLVER in handeye.list_solvers("axyb")
    info = reg.provider(SOLVER)
    assert (info.name, info.distribution, info.version) == ("example-solver", "handeye-example-solver", "0.1.0")
    module = sys.modules["handeye_example_solver"]
    assert module.__file__.startswith(str(installed_example))  # the copy, not the docs source


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_solves_noise_free_data(installed_example, seed):
    registry.reload()
    truth = random_truth(np.random.default_rng(seed))
    data, truth = PROBLEM.simulate(pairs=10, seed=seed, X=truth["X"], Y=truth["Y"])
    sol = handeye.solve("axyb", solver=SOLVER, **data)
    assert sol.solver == SOLVER and sol.backend == "numpy" and sol.status is handeye.Status.OPTIMAL
    scale = PROBLEM.validate(**data).translation_scale
    errors = PROBLEM.errors(sol.unknowns, truth)
    for name in ("X", "Y"):
        assert errors[name]["rotation"] < 1e-9
        assert errors[name]["translation"] < 1e-9 * scale
    assert sol.diagnostics["singular_values_over_m"][0] == pytest.approx(1.0, abs=1e-12)


def test_listed_by_the_cli(installed_example, capsys):
    cli = pytest.importorskip("handeye.cli", reason="handeye.cli (the CLI, written separately) is not importable yet")
    registry.reload()
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert SOLVER in out
    assert "handeye-example-solver 0.1.0" in out


@needs_clean_env
def test_not_loaded_when_autoload_disabled(installed_example, monkeypatch):
    monkeypatch.setenv(registry.AUTOLOAD_ENV, "1")
    reg = registry.reload()
    assert SOLVER not in reg.solvers
    assert "handeye_example_solver" not in sys.modules
    assert "kron-lstsq" in reg.solvers
    with pytest.raises(handeye.UnknownPluginError, match=f"'{SOLVER}'"):
        reg.solver(SOLVER, "axyb")


@needs_clean_env
def test_registry_restored_afterwards():
    """Runs after the tests above (file order): the temporary distribution is gone again."""
    assert SOLVER not in registry.reload().solvers
    assert not any(d.metadata["Name"] == "handeye-example-solver" for d in importlib.metadata.distributions())
