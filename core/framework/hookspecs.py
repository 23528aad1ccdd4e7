"""Hook specifications of handeye (project name ``handeye`` for pluggy).

A plugin is any module or object with functions decorated by `handeye.hookimpl`; it is found
through the entry-point group ``handeye`` (the built-in problems and solvers are registered that
way too) or registered explicitly with `handeye.host.registry.register_plugin`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pluggy

hookspec = pluggy.HookspecMarker("handeye")
hookimpl = pluggy.HookimplMarker("handeye")


@hookspec
def register_problems(register: Callable) -> None:
    """Register calibration problems.

    :param register: call ``register(problem)`` once per problem, with an instance of a
        `handeye.framework.problem.Problem` subclass. A name another plugin already registered raises
        `PluginRegistrationError` naming both plugins.

    Called once, when the registry is first used (or rebuilt by `handeye.host.registry.reload`).
    """


@hookspec
def register_solvers(register: Callable, problems: Mapping[str, Any]) -> None:
    """Register solvers.

    :param register: call ``register(spec)`` once per solver spec, with a `handeye.SolverSpec`.
        Each spec names the problems it solves; a problem that no plugin registered is an error
        at registration time. One name may serve several problems: one spec naming them all,
        or one spec per problem under the same name. The same (name, problem) registered twice
        raises `PluginRegistrationError` naming both plugins.
    :param problems: every registered problem by name (read-only), for a solver that serves any
        problem offering what it needs (``refine`` and ``auto`` serve every problem with a
        `Problem.pose_model`). A hook may leave this parameter out.

    Called once, after every plugin's ``register_problems``.
    """
