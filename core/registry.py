"""The plugin manager and the registry of problems and solvers built from it.

Plugins are loaded from the entry-point group ``handeye``. Setting the environment variable
``HANDEYE_DISABLE_PLUGIN_AUTOLOAD`` (to anything non-empty) loads only the entry points of the
handeye distribution itself, i.e. the built-in problems and solvers.

A third-party plugin whose module raises on import (a missing dependency, a bug) is skipped: the
other plugins load, a `PluginLoadWarning` names it, its distribution and the error, the registry
keeps it in `Registry.failed` (shown by ``handeye list``), and an unknown problem or solver name
mentions it, since the name may be one the broken plugin would have registered. A built-in
plugin (one of handeye's own entry points) failing to import still raises: that is a bug in
handeye, not in the user's environment, and hiding it would turn it into a missing solver.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import os
import threading
import warnings
from collections.abc import Iterable
from typing import Any

import pluggy

from . import hookspecs
from .errors import (
    InputError,
    PluginLoadWarning,
    PluginRegistrationError,
    UnknownPluginError,
)
from .problem import Problem
from .solver import SolverSpec

ENTRY_POINT_GROUP = "handeye"
AUTOLOAD_ENV = "HANDEYE_DISABLE_PLUGIN_AUTOLOAD"
OWN_DISTRIBUTION = "handeye"


@dataclasses.dataclass(frozen=True)
class PluginInfo:
    """Where a plugin came from: its registered name and the distribution that provides it."""

    name: str
    distribution: str
    version: str


@dataclasses.dataclass(frozen=True)
class FailedPlugin:
    """A third-party entry point that could not be loaded: where it came from and why."""

    name: str
    distribution: str
    version: str
    error: str  # "ExceptionType: message"

    def describe(self) -> str:
        return f"{self.name!r} (from {self.distribution} {self.version}: {self.error})"


class Registry:
    """Problems and solvers registered by every loaded plugin; `failed`: the third-party plugins
    that could not be loaded (name -> `FailedPlugin`).

    A solver name may serve several problems (``refine`` solves ``axyb`` and ``axxb``): the
    registry keeps one `SolverSpec` per (solver name, problem). A spec whose ``problems`` tuple
    names several problems serves each of them with the same run function; a plugin that needs
    other options or code per problem registers one spec per problem under the same name. Two
    specs for the same (name, problem) are an error naming both plugins; different plugins may
    share a name for different problems (a third-party problem plugin can offer its own
    ``auto``), each pair keeping its own provider.
    """

    def __init__(self, plugin_manager: pluggy.PluginManager, plugins: dict[str, PluginInfo],
                 failed: dict[str, FailedPlugin] | None = None) -> None:
        self.plugin_manager = plugin_manager
        self.plugins = plugins
        self.failed = dict(failed or {})
        self.problems: dict[str, Problem] = {}
        #: solver name -> problem -> spec
        self.solvers: dict[str, dict[str, SolverSpec]] = {}
        self._problem_owner: dict[str, str] = {}
        self._solver_owner: dict[tuple[str, str], str] = {}
        self._collect()

    def _collect(self) -> None:
        hook = self.plugin_manager.hook
        for impl in hook.register_problems.get_hookimpls():
            impl.function(register=lambda p, _owner=impl.plugin_name: self._add_problem(p, _owner))
        for impl in hook.register_solvers.get_hookimpls():
            impl.function(register=lambda s, _owner=impl.plugin_name: self._add_solver(s, _owner))

    def _add_problem(self, problem: Problem, owner: str) -> None:
        if not isinstance(problem, Problem):
            raise PluginRegistrationError(
                f"plugin {owner!r} registered {problem!r}, which is not a handeye.Problem instance"
            )
        if problem.name in self.problems:
            raise PluginRegistrationError(
                f"problem {problem.name!r} is registered by both plugin "
                f"{self._problem_owner[problem.name]!r} and plugin {owner!r}"
            )
        self.problems[problem.name] = problem
        self._problem_owner[problem.name] = owner

    def _add_solver(self, spec: SolverSpec, owner: str) -> None:
        if not isinstance(spec, SolverSpec):
            raise PluginRegistrationError(
                f"plugin {owner!r} registered {spec!r}, which is not a handeye.SolverSpec"
            )
        if not spec.problems:
            raise PluginRegistrationError(f"solver {spec.name!r} of plugin {owner!r} names no problem")
        for problem in spec.problems:
            if problem not in self.problems:
                raise PluginRegistrationError(
                    f"solver {spec.name!r} of plugin {owner!r} claims problem {problem!r}, which no "
                    f"plugin registered (known: {sorted(self.problems)})"
                )
            if (spec.name, problem) in self._solver_owner:
                raise PluginRegistrationError(
                    f"solver {spec.name!r} for problem {problem!r} is registered by both plugin "
                    f"{self._solver_owner[spec.name, problem]!r} and plugin {owner!r}"
                )
        for problem in spec.problems:
            self.solvers.setdefault(spec.name, {})[problem] = spec
            self._solver_owner[spec.name, problem] = owner

    def problem(self, name: str) -> Problem:
        try:
            return self.problems[name]
        except KeyError:
            raise UnknownPluginError("problem", name, self.problems, self._failed_hint()) from None

    def solver(self, name: str, problem: str | None = None) -> SolverSpec:
        """The spec of solver `name` for `problem`. Without a problem the name must serve exactly
        one (else an `UnknownPluginError` asks for it)."""
        known = self.solver_names(problem)
        if name not in known:
            if name in self.solvers and problem is not None:
                hint = f"solver {name!r} exists but solves only {self.solver_problems(name)}"
            else:
                hint = self._failed_hint()
            raise UnknownPluginError(
                "solver", name, known, hint, owner="" if problem is None else f"for problem {problem!r}"
            )
        by_problem = self.solvers[name]
        if problem is None:
            if len(by_problem) > 1:
                raise InputError(f"solver {name!r} serves several problems ({', '.join(by_problem)}): "
                                 "name the problem too")
            return next(iter(by_problem.values()))
        return by_problem[problem]

    def solver_names(self, problem: str | None = None) -> list[str]:
        if problem is not None:
            self.problem(problem)
        return sorted(n for n, specs in self.solvers.items() if problem is None or problem in specs)

    def solver_problems(self, name: str) -> list[str]:
        """The problems solver `name` serves, in the order they were registered."""
        return list(self.solvers.get(name, {}))

    def _failed_hint(self) -> str:
        """For unknown-name errors: the plugins that failed to load (one may hold the name)."""
        if not self.failed:
            return ""
        listing = "; ".join(f.describe() for f in self.failed.values())
        return (f"Plugin(s) that failed to load, which may provide it: {listing}; fix or "
                "reinstall the distribution (see handeye list)")

    def provider(self, solver: str, problem: str | None = None) -> PluginInfo:
        """The plugin (and distribution) that registered `solver` for `problem` (default: the
        first problem it was registered for)."""
        problem = problem if problem is not None else self.solver_problems(solver)[0]
        owner = self._solver_owner[solver, problem]
        return self.plugins.get(owner, PluginInfo(owner, "(registered at run time)", ""))


def _entry_points(include_third_party: bool) -> Iterable[importlib.metadata.EntryPoint]:
    seen: dict[str, str] = {}  # entry-point name -> distribution declaring it
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist.name if ep.dist is not None else ""
        if not include_third_party and _normalise(dist) != OWN_DISTRIBUTION:
            continue
        if ep.name in seen:
            if _normalise(seen[ep.name]) == _normalise(dist):
                continue  # the same distribution visible twice on sys.path
            raise PluginRegistrationError(
                f"entry point {ep.name!r} of group {ENTRY_POINT_GROUP!r} is declared by both "
                f"distribution {seen[ep.name]!r} and distribution {dist!r}; plugin names must be "
                "unique: rename one of them (or uninstall one package)"
            )
        seen[ep.name] = dist
        yield ep


def _normalise(name: str) -> str:
    return name.lower().replace("_", "-")


def _build(extra_plugins: Iterable[tuple[str, Any]]) -> Registry:
    pm = pluggy.PluginManager(ENTRY_POINT_GROUP)
    pm.add_hookspecs(hookspecs)
    plugins: dict[str, PluginInfo] = {}
    failed: dict[str, FailedPlugin] = {}
    autoload = not os.environ.get(AUTOLOAD_ENV)
    for ep in _entry_points(include_third_party=autoload):
        if pm.get_plugin(ep.name) is not None:
            continue
        dist = ep.dist
        info = PluginInfo(ep.name, dist.name if dist else "?", dist.version if dist else "?")
        try:
            plugin = ep.load()
        except Exception as exc:
            if _normalise(info.distribution) == OWN_DISTRIBUTION:
                raise  # a built-in plugin: our bug, not the user's environment (module docstring)
            failed[ep.name] = _skip_broken(info, exc)
            continue
        pm.register(plugin, name=ep.name)
        plugins[ep.name] = info
    for name, plugin in extra_plugins:
        if pm.get_plugin(name) is not None:
            raise PluginRegistrationError(
                f"a plugin named {name!r} is already loaded (from {plugins[name].distribution}); "
                "register the run-time plugin under another name"
            )
        pm.register(plugin, name=name)
        plugins[name] = PluginInfo(name, "(registered at run time)", "")
    return Registry(pm, plugins, failed)


def _skip_broken(info: PluginInfo, exc: Exception) -> FailedPlugin:
    """Record a third-party plugin whose entry point raised on loading, and warn about it."""
    failed = FailedPlugin(info.name, info.distribution, info.version,
                          f"{type(exc).__name__}: {' '.join(str(exc).split())}")
    warnings.warn(
        f"handeye plugin {failed.describe()} failed to load and is skipped; the other plugins "
        f"work. Fix or reinstall {info.distribution}, or set {AUTOLOAD_ENV}=1 to load only the "
        "built-in plugins",
        PluginLoadWarning,
        stacklevel=2,
    )
    return failed


_lock = threading.Lock()
_registry: Registry | None = None
_extra: list[tuple[str, Any]] = []


def get_registry() -> Registry:
    """The registry, built on first use from the entry points (and any run-time plugins)."""
    global _registry
    with _lock:
        if _registry is None:
            _registry = _build(_extra)
        return _registry


def reload() -> Registry:
    """Rebuild the registry, e.g. after installing a plugin or changing the autoload variable."""
    global _registry
    with _lock:
        _registry = None
    return get_registry()


def register_plugin(plugin: Any, name: str | None = None) -> None:
    """Register a plugin object (module or instance with hookimpls) at run time, then rebuild."""
    name = name or getattr(plugin, "__name__", None) or repr(plugin)
    _extra.append((name, plugin))
    try:
        reload()
    except Exception:  # an invalid plugin must not leave the registry broken: roll back
        _extra.pop()
        reload()
        raise


def unregister_plugin(name: str) -> None:
    """Remove a plugin registered with `register_plugin`, then rebuild."""
    _extra[:] = [(n, p) for n, p in _extra if n != name]
    reload()


def list_problems() -> list[str]:
    """Names of the registered problems."""
    return sorted(get_registry().problems)


def list_solvers(problem: str | None = None) -> list[str]:
    """Names of the registered solvers, or of those that solve `problem`."""
    return get_registry().solver_names(problem)
