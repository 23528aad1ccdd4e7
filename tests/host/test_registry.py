"""The plugin registry: entry points, run-time plugins, duplicate and invalid registrations, the
autoload switch, and errors that list the known names."""

from __future__ import annotations

import sys
import tomllib

import numpy as np
import pytest
from conftest import ROOT, SolverPlugin
from conftest import identity_run as _run

import handeye
from handeye import PluginRegistrationError, SolverSpec, UnknownPluginError, hookimpl
from handeye.host import registry
from handeye.problems.axyb import AXYB


class ProblemPlugin:
    def __init__(self, *problems):
        self.problems = problems

    @hookimpl
    def register_problems(self, register):
        for problem in self.problems:
            register(problem)


class OtherProblem(AXYB):
    name = "test-other-problem"


def _own_entry_points() -> dict[str, str]:
    with open(ROOT / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["project"]["entry-points"]["handeye"]


def test_list_problems_and_solvers():
    assert "axyb" in handeye.list_problems()
    solvers = handeye.list_solvers("axyb")
    assert "kron-lstsq" in solvers and solvers == sorted(solvers)
    assert set(solvers) <= set(handeye.list_solvers())
    assert handeye.list_solvers("axyb") == handeye.get_registry().solver_names("axyb")


def test_every_builtin_entry_point_is_loaded_as_a_plugin():
    reg = handeye.get_registry()
    for name in _own_entry_points():
        info = reg.plugins[name]
        assert (info.distribution.lower(), info.version) == ("handeye", handeye.__version__)


def test_provider_of_a_builtin_solver():
    info = handeye.get_registry().provider("kron-lstsq")
    assert (info.name, info.distribution, info.version) == ("kron-lstsq", "handeye", handeye.__version__)
    assert handeye.get_registry().problem("axyb").name == "axyb"


def test_runtime_plugin_is_listed_and_removed(runtime_plugins):
    runtime_plugins(SolverPlugin(SolverSpec("test-runtime", ("axyb",), _run)), "test-runtime-plugin")
    assert "test-runtime" in handeye.list_solvers("axyb")
    info = handeye.get_registry().provider("test-runtime")
    assert info.name == "test-runtime-plugin" and info.distribution == "(registered at run time)"
    registry.unregister_plugin("test-runtime-plugin")
    assert "test-runtime" not in handeye.list_solvers("axyb")


def test_duplicate_solver_names_both_plugins(runtime_plugins):
    runtime_plugins(SolverPlugin(SolverSpec("test-dup", ("axyb",), _run)), "first-plugin")
    with pytest.raises(PluginRegistrationError, match="solver 'test-dup' for problem 'axyb' is registered by both") as info:
        runtime_plugins(SolverPlugin(SolverSpec("test-dup", ("axyb",), _run)), "second-plugin")
    assert "'first-plugin'" in str(info.value) and "'second-plugin'" in str(info.value)


def test_duplicate_of_a_builtin_solver(runtime_plugins):
    with pytest.raises(PluginRegistrationError, match="'kron-lstsq'") as info:
        runtime_plugins(SolverPlugin(SolverSpec("kron-lstsq", ("axyb",), _run)), "impostor")
    assert "'impostor'" in str(info.value)


def test_duplicate_problem(runtime_plugins):
    with pytest.raises(PluginRegistrationError, match="problem 'axyb' is registered by both plugin 'axyb'"):
        runtime_plugins(ProblemPlugin(AXYB()), "second-axyb")


def test_failed_registration_is_rolled_back(runtime_plugins):
    runtime_plugins(SolverPlugin(SolverSpec("test-good", ("axyb",), _run)), "good-plugin")
    with pytest.raises(PluginRegistrationError):
        runtime_plugins(SolverPlugin(SolverSpec("kron-lstsq", ("axyb",), _run),
                                     SolverSpec("test-bad", ("axyb",), _run)), "impostor")
    reg = handeye.get_registry()  # usable at once, without the invalid plugin
    assert "impostor" not in reg.plugins and "test-bad" not in reg.solvers
    assert {"kron-lstsq", "test-good"} <= set(reg.solvers)
    assert reg.provider("kron-lstsq").distribution == "handeye"


def test_runtime_plugin_name_taken(runtime_plugins):
    with pytest.raises(PluginRegistrationError, match="a plugin named 'kron-lstsq' is already loaded"):
        runtime_plugins(SolverPlugin(SolverSpec("test-x", ("axyb",), _run)), "kron-lstsq")
    assert "test-x" not in handeye.list_solvers()


def test_entry_point_name_taken_by_another_distribution(example_dist, monkeypatch):
    """A third-party package whose entry point reuses a built-in plugin name is skipped with a
    warning naming both distributions; the built-in keeps the name and every command works."""
    (entry_points,) = example_dist.glob("*.dist-info/entry_points.txt")
    entry_points.write_text("[handeye]\nkron-lstsq = handeye_example_solver\n")
    monkeypatch.syspath_prepend(str(example_dist))
    try:
        with pytest.warns(handeye.PluginLoadWarning, match="entry point name 'kron-lstsq'") as record:
            reg = registry.reload()
        message = str(record[0].message)
        assert "'handeye'" in message and "handeye-example-solver" in message
        assert reg.provider("kron-lstsq").distribution == "handeye"
        assert "example-kron" not in reg.solvers  # the clashing plugin is not loaded at all
        assert [f.distribution for f in reg.failed.values()] == ["handeye-example-solver"]
    finally:
        monkeypatch.undo()
        sys.modules.pop("handeye_example_solver", None)
        registry.reload()


def test_solver_claiming_unknown_problem(runtime_plugins):
    with pytest.raises(PluginRegistrationError, match="claims problem 'axbyczw'") as info:
        runtime_plugins(SolverPlugin(SolverSpec("test-claims", ("axyb", "axbyczw"), _run)), "claimer")
    assert "'claimer'" in str(info.value) and "'axyb'" in str(info.value)  # the known problems


@pytest.mark.parametrize("bad", [object(), "kron-lstsq", {"name": "x"}])
def test_registering_a_non_spec(runtime_plugins, bad):
    with pytest.raises(PluginRegistrationError, match="not a handeye.SolverSpec"):
        runtime_plugins(SolverPlugin(bad), "bad-plugin")


def test_registering_a_non_problem(runtime_plugins):
    with pytest.raises(PluginRegistrationError, match="not a handeye.Problem"):
        runtime_plugins(ProblemPlugin("axyb"), "bad-problem-plugin")


def test_solver_spec_declaration_errors():
    with pytest.raises(ValueError, match="default_backend 'gpu' is not one of its backends"):
        SolverSpec("x", ("axyb",), _run, backends={"numpy": ()}, default_backend="gpu")
    with pytest.raises(ValueError, match="options must be a dataclass"):
        SolverSpec("x", ("axyb",), _run, options=dict)


def test_unknown_names_list_the_known():
    reg = handeye.get_registry()
    with pytest.raises(UnknownPluginError, match="unknown problem 'axxxb'; known problems: 'axbycz', 'axxb', 'axyb'"):
        reg.problem("axxxb")
    with pytest.raises(UnknownPluginError, match="unknown problem 'nope'"):
        handeye.list_solvers("nope")
    with pytest.raises(UnknownPluginError, match="unknown solver 'kron' for problem 'axyb'") as info:
        reg.solver("kron", "axyb")
    assert info.value.known == handeye.list_solvers("axyb")
    assert "'kron-lstsq'" in str(info.value)
    with pytest.raises(UnknownPluginError, match="unknown solver 'kron'"):
        reg.solver("kron")


def test_solver_of_another_problem_is_explained(runtime_plugins):
    runtime_plugins(ProblemPlugin(OtherProblem()), "other-problem")
    runtime_plugins(SolverPlugin(SolverSpec("test-other", ("test-other-problem",), _run)), "other-solver")
    reg = handeye.get_registry()
    assert reg.solver("test-other", "test-other-problem").name == "test-other"
    assert "test-other" not in reg.solver_names("axyb")
    with pytest.raises(UnknownPluginError, match=r"exists but solves only \['test-other-problem'\]"):
        reg.solver("test-other", "axyb")
    problems = handeye.list_problems()
    assert {"axyb", "test-other-problem"} <= set(problems) and problems == sorted(problems)


def _run_other(data, options, backend):
    return handeye.SolverOutput({"X": 2 * np.eye(4) - np.eye(4), "Y": np.eye(4)}, diagnostics={"which": "other"})


def test_one_name_two_specs_for_two_problems(runtime_plugins):
    """One spec per (name, problem): each problem gets its own run function and provider."""
    runtime_plugins(ProblemPlugin(OtherProblem()), "other-problem")
    runtime_plugins(SolverPlugin(SolverSpec("test-shared", ("axyb",), _run)), "shared-a")
    runtime_plugins(SolverPlugin(SolverSpec("test-shared", ("test-other-problem",), _run_other)), "shared-b")
    reg = handeye.get_registry()
    assert reg.solver_problems("test-shared") == ["axyb", "test-other-problem"]
    assert reg.solver("test-shared", "axyb").run is _run
    assert reg.solver("test-shared", "test-other-problem").run is _run_other
    assert (reg.provider("test-shared", "axyb").name, reg.provider("test-shared", "test-other-problem").name) == (
        "shared-a", "shared-b")
    assert "test-shared" in reg.solver_names("axyb") and "test-shared" in reg.solver_names("test-other-problem")
    with pytest.raises(handeye.InputError, match="serves several problems .*name the problem"):
        reg.solver("test-shared")
    data, _ = OtherProblem().simulate(pairs=5, seed=1)
    assert handeye.solve("test-other-problem", solver="test-shared", **data).diagnostics["which"] == "other"


def test_one_spec_for_several_problems(runtime_plugins):
    runtime_plugins(ProblemPlugin(OtherProblem()), "other-problem")
    spec = SolverSpec("test-both", ("axyb", "test-other-problem"), _run)
    runtime_plugins(SolverPlugin(spec), "both")
    reg = handeye.get_registry()
    assert reg.solver("test-both", "axyb") is spec and reg.solver("test-both", "test-other-problem") is spec
    with pytest.raises(PluginRegistrationError, match="'test-both' for problem 'axyb' is registered by both"):
        runtime_plugins(SolverPlugin(SolverSpec("test-both", ("axyb",), _run)), "again")


def test_builtin_names_serve_both_problems():
    reg = handeye.get_registry()
    for name in ("auto", "refine", "kron-lstsq", "so3-sdp", "lmi-sdp", "opencv"):
        if name in reg.solvers:
            assert {"axyb", "axxb"} <= set(reg.solver_problems(name)), name


def test_autoload_switch_keeps_builtins(monkeypatch):
    monkeypatch.setenv(registry.AUTOLOAD_ENV, "1")
    try:
        reg = registry.reload()
        assert "kron-lstsq" in reg.solvers
        assert {info.distribution.lower() for info in reg.plugins.values()} == {"handeye"}
        assert set(reg.plugins) == set(_own_entry_points())
    finally:
        monkeypatch.delenv(registry.AUTOLOAD_ENV)
        registry.reload()


def test_autoload_switch_hides_third_party(installed_example, monkeypatch):
    assert "example-kron" in registry.reload().solvers
    monkeypatch.setenv(registry.AUTOLOAD_ENV, "1")
    reg = registry.reload()
    assert "example-kron" not in reg.solvers and "example-solver" not in reg.plugins
    assert "kron-lstsq" in reg.solvers  # built-ins still load
    monkeypatch.delenv(registry.AUTOLOAD_ENV)
    assert "example-kron" in registry.reload().solvers


def test_reload_returns_a_fresh_registry():
    first = handeye.get_registry()
    assert handeye.get_registry() is first
    second = registry.reload()
    assert second is not first and second.solver_names() == first.solver_names()
