"""The plugin manager and the registry of problems and solvers built from it.

Plugins are loaded from the entry-point group ``handeye``. Setting the environment variable
``HANDEYE_DISABLE_PLUGIN_AUTOLOAD`` (to anything non-empty) loads only the entry points of the
handeye distribution itself, i.e. the built-in problems and solvers.

A third-party plugin that cannot be used is skipped as a whole, so that it breaks no command that
does not use it: a module that raises on import (a missing dependency, a bug), an entry point
whose name another distribution already declares, a ``register_problems`` / ``register_solvers``
hook that raises, or registrations the host refuses (not a Problem / SolverSpec, a solver for an
unknown problem, a name that a built-in or an earlier plugin already holds, such as ``auto``).
The other plugins load, a `PluginLoadWarning` names it, its distribution and the error, the
registry keeps it in `Registry.failed` (shown by ``handeye list``), and an unknown problem or
solver name mentions it, since the name may be one the broken plugin would have registered.

Built-in plugins (handeye's own entry points) register first, and their faults still raise: that
is a bug in handeye, not in the user's environment, and hiding it would turn it into a missing
solver. So do the faults of a plugin registered at run time with `register_plugin`: its caller
asked for it and gets the error (the registry is rolled back).
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import os
import threading
import types
import warnings
from collections.abc import Iterable
from typing import Any

import pluggy

from handeye.base.errors import (
    InputError,
    PluginLoadWarning,
    PluginRegistrationError,
    UnknownPluginError,
)
from handeye.framework import hookspecs
from handeye.framework.problem import Problem
from handeye.framework.solver import SolverSpec

ENTRY_POINT_GROUP = "handeye"
AUTOLOAD_ENV = "HANDEYE_DISABLE_PLUGIN_AUTOLOAD"
OWN_DISTRIBUTION = "handeye"
#: the distribution shown for a plugin registered with `register_plugin`
RUNTIME = "(registered at run time)"


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
        #: `problem_of`'s answers by data type (asked ~9 times a solve); emptied when problems change
        self._problem_of_type: dict[type, Problem] = {}
        self._collect()

    def _collect(self) -> None:
        """Call every plugin's hooks, built-ins first; a third-party plugin whose hook raises or
        registers what the host refuses is dropped whole (module docstring)."""
        hook = self.plugin_manager.hook
        for name, add in (("register_problems", self._add_problem), ("register_solvers", self._add_solver)):
            impls = getattr(hook, name).get_hookimpls()  # in registration order
            for impl in sorted(impls, key=lambda i: not self._strict(i.plugin_name)):
                owner = impl.plugin_name
                if owner in self.failed:
                    continue
                staged: list[Any] = []
                given = {"register": staged.append, "problems": types.MappingProxyType(self.problems)}
                try:
                    impl.function(**{arg: given[arg] for arg in impl.argnames})
                    for item in staged:
                        add(item, owner)
                except (Exception, SystemExit) as exc:
                    if self._strict(owner):
                        raise
                    self._drop(owner, exc)

    def _strict(self, owner: str) -> bool:
        """Whether a fault of plugin `owner` raises (a built-in, or registered at run time)
        instead of skipping the plugin."""
        info = self.plugins.get(owner)
        return info is None or info.distribution == RUNTIME or _normalise(info.distribution) == OWN_DISTRIBUTION

    def _drop(self, owner: str, exc: BaseException) -> None:
        """Remove everything plugin `owner` registered (and the solvers of its problems) and
        record it as failed, with a warning."""
        mine = [name for name, who in self._problem_owner.items() if who == owner]
        for name in mine:
            del self.problems[name], self._problem_owner[name]
        self._problem_of_type.clear()
        for key, who in list(self._solver_owner.items()):
            if who == owner or key[1] in mine:
                del self._solver_owner[key]
                specs = self.solvers[key[0]]
                del specs[key[1]]
                if not specs:
                    del self.solvers[key[0]]
        info = self.plugins.pop(owner)
        self.failed[owner] = _skip_broken(info, exc)

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
        self._problem_of_type.clear()

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
            if (spec.name, problem) in self._solver_owner and not self._replaces(spec.name, problem, owner):
                raise PluginRegistrationError(
                    f"solver {spec.name!r} for problem {problem!r} is registered by both plugin "
                    f"{self._solver_owner[spec.name, problem]!r} and plugin {owner!r}"
                )
        for problem in spec.problems:
            self.solvers.setdefault(spec.name, {})[problem] = spec
            self._solver_owner[spec.name, problem] = owner

    def _replaces(self, solver: str, problem: str, owner: str) -> bool:
        """Whether plugin `owner` may replace the spec of `solver` for `problem` that another plugin
        registered: a problem's own plugin may put its own solver in place of one that serves
        every problem (e.g. its own ``auto`` instead of the shared one)."""
        return self._problem_owner.get(problem) == owner != self._solver_owner[solver, problem]

    def problem(self, name: str) -> Problem:
        try:
            return self.problems[name]
        except KeyError:
            raise UnknownPluginError("problem", name, self.problems, self._failed_hint()) from None

    def default_problem(self) -> str:
        """The name of the problem solved when none is named: the registered problem whose
        ``default`` is set (the first registered, when none or several claim it)."""
        if not self.problems:
            raise UnknownPluginError("problem", "(default)", [])
        claimed = [name for name, p in self.problems.items() if p.default]
        return (claimed or list(self.problems))[0]

    def cell_problem(self) -> str:
        """The problem whose data are a cell's stations as recorded: one pair (A, B) per station,
        its unknowns the cell's X and Y (a `StationReader` without pairing or renamed unknowns:
        A_i X = Y B_i). Fits of a cell's raw stations (a clock offset's profile) solve it. The
        default problem when it is one; InputError when none is registered."""
        def fits(p: Problem) -> bool:
            reader = p.station_reader
            return (reader is not None and not reader.pairing and reader.cell_truth is None
                    and tuple(p.unknowns) == ("X", "Y") and tuple(p.data_fields) == ("A", "B"))

        default = self.default_problem()
        names = [default] + [n for n in self.problems if n != default]
        for name in names:
            if fits(self.problems[name]):
                return name
        raise InputError("no registered problem solves a cell's stations as recorded (A_i X = Y B_i)")

    def problem_of(self, data: Any) -> Problem:
        """The registered problem whose validated data `data` are (`Problem.data_type`, the
        most specific class first); InputError when no problem claims them."""
        known = self._problem_of_type.get(type(data))
        if known is not None:
            return known
        for cls in type(data).__mro__:
            for problem in self.problems.values():
                if problem.data_type is cls:
                    self._problem_of_type[type(data)] = problem
                    return problem
        raise InputError(f"{type(data).__name__} are not the validated data of a registered problem "
                         f"({', '.join(sorted(self.problems))}); validate them with the problem first")

    def solver(self, name: str, problem: str | None = None) -> SolverSpec:
        """The spec of solver `name` for `problem`. Without a problem the name must serve exactly
        one (else an `UnknownPluginError` asks for it)."""
        by_problem = self.solvers.get(name)
        if by_problem is not None and problem in by_problem and problem in self.problems:
            return by_problem[problem]  # the usual case, without sorting every name (3 times a solve)
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
        return self.plugins.get(owner, PluginInfo(owner, RUNTIME, ""))

    def problem_provider(self, problem: str) -> PluginInfo:
        """The plugin (and distribution) that registered `problem`."""
        owner = self._problem_owner[problem]
        return self.plugins.get(owner, PluginInfo(owner, RUNTIME, ""))

    def problem_is_builtin(self, problem: str) -> bool:
        """Whether `problem` comes from handeye itself."""
        return _normalise(self.problem_provider(problem).distribution) == OWN_DISTRIBUTION

    def is_builtin(self, solver: str, problem: str) -> bool:
        """Whether `solver` for `problem` comes from handeye itself (not a third party's plugin,
        nor one registered at run time)."""
        return _normalise(self.provider(solver, problem).distribution) == OWN_DISTRIBUTION


def _entry_points(include_third_party: bool) -> list[tuple[importlib.metadata.EntryPoint, str | None]]:
    """The entry points of group ``handeye``, handeye's own first, each with None or, for a
    third party's whose name another distribution already declares, why it is skipped."""
    out: list[tuple[importlib.metadata.EntryPoint, str | None]] = []
    seen: dict[str, str] = {}  # entry-point name -> distribution declaring it
    found = importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
    for ep in sorted(found, key=lambda e: _normalise(_dist_name(e)) != OWN_DISTRIBUTION):
        dist = _dist_name(ep)
        if not include_third_party and _normalise(dist) != OWN_DISTRIBUTION:
            continue
        if ep.name in seen:
            if _normalise(seen[ep.name]) == _normalise(dist):
                continue  # the same distribution visible twice on sys.path
            out.append((ep, f"its entry point name {ep.name!r} is already declared by distribution "
                            f"{seen[ep.name]!r}; plugin names must be unique: rename it (or uninstall one package)"))
            continue
        seen[ep.name] = dist
        out.append((ep, None))
    return out


def _dist_name(ep: importlib.metadata.EntryPoint) -> str:
    return ep.dist.name if ep.dist is not None else ""


def _normalise(name: str) -> str:
    return name.lower().replace("_", "-")


def _build(extra_plugins: Iterable[tuple[str, Any]]) -> Registry:
    pm = pluggy.PluginManager(ENTRY_POINT_GROUP)
    pm.add_hookspecs(hookspecs)
    plugins: dict[str, PluginInfo] = {}
    failed: dict[str, FailedPlugin] = {}
    autoload = not os.environ.get(AUTOLOAD_ENV)
    for ep, clash in _entry_points(include_third_party=autoload):
        dist = ep.dist
        info = PluginInfo(ep.name, dist.name if dist else "?", dist.version if dist else "?")
        if clash is not None:
            failed[f"{ep.name} ({info.distribution})"] = _skip_broken(info, PluginRegistrationError(clash))
            continue
        if pm.get_plugin(ep.name) is not None:
            continue
        try:
            pm.register(ep.load(), name=ep.name)
        except (Exception, SystemExit) as exc:  # SystemExit: a module that exits on import
            if _normalise(info.distribution) == OWN_DISTRIBUTION:
                raise  # a built-in plugin: our bug, not the user's environment (module docstring)
            failed[ep.name] = _skip_broken(info, exc)
            continue
        plugins[ep.name] = info
    for name, plugin in extra_plugins:
        if pm.get_plugin(name) is not None:
            raise PluginRegistrationError(
                f"a plugin named {name!r} is already loaded (from {plugins[name].distribution}); "
                "register the run-time plugin under another name"
            )
        pm.register(plugin, name=name)
        plugins[name] = PluginInfo(name, RUNTIME, "")
    return Registry(pm, plugins, failed)


def _skip_broken(info: PluginInfo, exc: BaseException) -> FailedPlugin:
    """Record a third-party plugin that cannot be used (module docstring), and warn about it."""
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
    registry = _registry  # built: no lock to take (~15 calls a solve)
    if registry is not None:
        return registry
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
