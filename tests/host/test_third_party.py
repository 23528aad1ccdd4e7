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
import json
import sys

import numpy as np
import pytest
from conftest import example_entry_points, example_project

import handeye
from handeye.host import registry
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


@pytest.mark.parametrize("seed", [4, 5])
def test_one_name_serves_both_problems(installed_example, seed):
    """The example registers a second spec under the same name for axxb: the registry keeps
    one per (name, problem), and each solves its own problem."""
    from handeye.problems.axxb import PROBLEM as AXXB

    reg = registry.reload()
    assert reg.solver_problems(SOLVER) == ["axyb", "axxb"]
    assert reg.provider(SOLVER, "axxb").distribution == "handeye-example-solver"
    truth = AXXB.random_unknowns(np.random.default_rng(seed))
    data, truth = AXXB.simulate(pairs=8, seed=seed, **truth)
    sol = handeye.solve("axxb", solver=SOLVER, **data)
    errors = AXXB.errors(sol.unknowns, truth)
    scale = AXXB.validate(**data).translation_scale
    assert errors["X"]["rotation"] < 1e-9 and errors["X"]["translation"] < 1e-9 * scale
    assert set(sol.unknowns) == {"X"}
    with pytest.raises(handeye.InputError, match="serves several problems"):
        reg.solver(SOLVER)


def test_listed_by_the_cli(installed_example, capsys):
    import handeye.cli as cli

    registry.reload()
    assert cli.main(["list"]) == 0
    out = capsys.readouterr().out
    assert f"{SOLVER:<16} [axyb, axxb]" in out
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


# ---------------------------------------------------------------------------------------------
# a broken third-party plugin: its module raises ImportError on import

BROKEN_MODULE = "handeye_broken_plugin"
BROKEN_DIST = "handeye-broken-plugin"


@pytest.fixture
def broken_plugin(tmp_path, monkeypatch):
    """A distribution on sys.path whose ``handeye`` entry point ``broken`` names a module that
    raises ImportError (a missing dependency); afterwards off sys.path and the registry rebuilt."""
    site = tmp_path / "site"
    site.mkdir()
    (site / f"{BROKEN_MODULE}.py").write_text("import handeye_no_such_dependency  # noqa: F401\n")
    dist_info = site / f"{BROKEN_MODULE}-0.3.0.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {BROKEN_DIST}\nVersion: 0.3.0\n")
    (dist_info / "entry_points.txt").write_text(f"[handeye]\nbroken = {BROKEN_MODULE}\n")
    monkeypatch.syspath_prepend(str(site))
    yield site
    monkeypatch.undo()
    sys.modules.pop(BROKEN_MODULE, None)
    registry.reload()


def test_broken_plugin_is_skipped_with_one_warning(broken_plugin):
    with pytest.warns(handeye.PluginLoadWarning) as record:
        reg = registry.reload()
    assert len(record) == 1
    message = str(record[0].message)
    assert "'broken'" in message and BROKEN_DIST in message and "handeye_no_such_dependency" in message
    assert "kron-lstsq" in reg.solvers and "axyb" in reg.problems  # the others still load
    failed = reg.failed["broken"]
    assert (failed.distribution, failed.version) == (BROKEN_DIST, "0.3.0")
    assert failed.error.startswith("ModuleNotFoundError: ")
    data, _ = PROBLEM.simulate(pairs=6, seed=1)
    assert handeye.solve("axyb", solver="kron-lstsq", **data).status is handeye.Status.OPTIMAL


def test_unknown_solver_error_names_the_broken_plugin(broken_plugin):
    with pytest.warns(handeye.PluginLoadWarning):
        registry.reload()
    data, _ = PROBLEM.simulate(pairs=6, seed=1)
    with pytest.raises(handeye.UnknownPluginError, match="unknown solver 'broken-solver' for problem 'axyb'") as info:
        handeye.solve("axyb", solver="broken-solver", **data)
    assert "failed to load" in str(info.value) and f"'broken' (from {BROKEN_DIST} 0.3.0" in str(info.value)


def test_cli_lists_the_broken_plugin(broken_plugin, capsys):
    from handeye.cli import main

    with pytest.warns(handeye.PluginLoadWarning):
        registry.reload()
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "plugins that failed to load" in out and "kron-lstsq" in out
    (line,) = [x for x in out.splitlines() if x.strip().startswith("broken ")]
    assert f"from {BROKEN_DIST} 0.3.0: ModuleNotFoundError:" in line
    assert main(["list", "--json"]) == 0
    (entry,) = json.loads(capsys.readouterr().out)["failed_plugins"]
    assert entry["name"] == "broken" and entry["distribution"] == BROKEN_DIST


def test_broken_builtin_plugin_still_raises(broken_plugin, monkeypatch):
    """A built-in entry point failing to import is handeye's bug: it is not hidden. (Simulated by
    declaring the broken distribution to be handeye's own.)"""
    monkeypatch.setattr(registry, "OWN_DISTRIBUTION", BROKEN_DIST)
    with pytest.raises(ImportError, match="handeye_no_such_dependency"):
        registry.reload()
